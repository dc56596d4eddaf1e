//! A user's own short record: one 20 s record at 100 Hz of a forced textbook oscillator (a few
//! forcing cycles, starting away from rest), columns `t, x, force`, identified with the default
//! options from a library holding the true terms and a spurious one.
//!
//! Two things used to bias such records: the default offsets policy removed the record's mean
//! from `x` (the mean of a short transient record is motion, and removing it turns `x^3` into
//! `x^2` and `x` terms), and the reconstruction's mirror extension put a kink at each end of a
//! record that does not end at rest, whose spectral tail set the band far above the signal's
//! (the noise of that band then hid the damping and the input term). The family below varies
//! the oscillator, the forcing and the noise draw — and one displacement sensor with an offset,
//! whose constant the fit must carry in every stage (a constant left out of the jackknife or the
//! errors-in-variables equations put its leakage into the stiffness and lost every true term);
//! noise-free records must come out exact, and at
//! 40 dB every true term must be kept, close to its value, with no spurious term whose interval
//! excludes zero.

use tfs::data::Record;
use tfs::dynamics::{InitialState, SimulateOptions, simulate_model_on_record};
use tfs::identify::{IdentifyOptions, identify, plan};
use tfs::library::Model;
use tfs::signal::NoiseKind;
use tfs::signal::noise::add_noise_seeded;

/// One oscillator of the family: its true terms, forcing and start.
struct Case {
    name: &'static str,
    /// True terms `(term, coefficient)` of `x'' = Σ c·θ`.
    terms: &'static [(&'static str, f64)],
    /// The library offered (the true terms and at least one spurious one).
    library: &'static str,
    /// Forcing `amp·cos(w·t)`.
    amp: f64,
    w: f64,
    /// Initial displacement (released at rest).
    x0: f64,
    /// A sensor offset added to the measured `x` (0: none). With one, a constant term is
    /// the offset seen through the stiffness, not a spurious term.
    offset: f64,
}

const CASES: &[Case] = &[
    Case {
        name: "hardening Duffing, slow forcing",
        terms: &[("x", -1.0), ("x^3", -0.5), ("x'", -0.1), ("force", 1.0)],
        library: "x, x^2, x^3, x', force",
        amp: 0.3,
        w: 1.2,
        x0: 1.0,
        offset: 0.0,
    },
    Case {
        name: "hardening Duffing, faster and stronger forcing",
        terms: &[("x", -1.0), ("x^3", -0.5), ("x'", -0.1), ("force", 1.0)],
        library: "x, x^2, x^3, x', force",
        amp: 0.8,
        w: 2.0,
        x0: 0.5,
        offset: 0.0,
    },
    Case {
        name: "softening spring",
        terms: &[("x", -2.0), ("x^3", 0.4), ("x'", -0.05), ("force", 1.0)],
        library: "x, x^2, x^3, x', force",
        amp: 0.5,
        w: 0.9,
        x0: 1.0,
        offset: 0.0,
    },
    Case {
        name: "Helmholtz oscillator (quadratic, asymmetric spring)",
        terms: &[("x", -1.0), ("x^2", -0.6), ("x'", -0.08), ("force", 1.0)],
        library: "x, x^2, x^3, x', force",
        amp: 0.15,
        w: 0.9,
        x0: 0.3,
        offset: 0.0,
    },
    Case {
        name: "Rayleigh oscillator (cubic velocity damping, self-excited)",
        terms: &[("x", -1.0), ("x'", 0.3), ("x'^3", -0.3), ("force", 1.0)],
        library: "x, x^3, x', x'^3, force",
        amp: 0.2,
        w: 1.1,
        x0: 0.5,
        offset: 0.0,
    },
    Case {
        name: "linear oscillator started at rest",
        terms: &[("x", -4.0), ("x'", -0.2), ("force", 1.0)],
        library: "x, x^2, x^3, x', force",
        amp: 1.0,
        w: 1.5,
        x0: 0.0,
        offset: 0.0,
    },
    Case {
        name: "forced Van der Pol",
        terms: &[("x", -1.0), ("x'", 0.5), ("x^2*x'", -0.5), ("force", 1.0)],
        library: "x, x^2, x^3, x', x^2*x', force",
        amp: 0.4,
        w: 1.5,
        x0: 1.5,
        offset: 0.0,
    },
    Case {
        name: "linear oscillator from rest, displacement sensor with an offset",
        terms: &[("x", -6.0), ("x'", -0.3), ("force", 1.0)],
        library: "x, x^2, x^3, x', force",
        amp: 1.0,
        w: 2.0,
        x0: 0.0,
        offset: 0.25,
    },
];

/// The record `t, x, force` of `case`: 20 s at 100 Hz, noise at `snr_db` on `x` (`None`: clean).
fn record(case: &Case, snr_db: Option<f64>, seed: u64) -> Record {
    record_of(case, 2001, snr_db, seed)
}

/// The record of [`record`] with `n` samples at 100 Hz.
fn record_of(case: &Case, n: usize, snr_db: Option<f64>, seed: u64) -> Record {
    let dt = 0.01;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    let force: Vec<f64> = t.iter().map(|&s| case.amp * (case.w * s).cos()).collect();
    let list: Vec<String> = case
        .terms
        .iter()
        .map(|(t, c)| format!(r#"{{"term":"{t}","coef":{c}}}"#))
        .collect();
    let truth = Model::from_json_str(&format!(
        r#"{{"format":"tfs-model/1","dofs":["x"],"inputs":["force"],"equations":[{{"dof":"x","terms":[{}]}}],"method":"truth"}}"#,
        list.join(",")
    ))
    .unwrap();
    let start = Record::new(
        "start",
        t.clone(),
        vec![
            ("x".into(), vec![case.x0; n]),
            ("x'".into(), vec![0.0; n]),
            ("force".into(), force.clone()),
        ],
    )
    .unwrap();
    let opts = SimulateOptions {
        initial_state: InitialState::FirstSamples,
        ..SimulateOptions::default()
    };
    let x = simulate_model_on_record(&truth, &start, &opts).unwrap().x[0].clone();
    let x = match snr_db {
        Some(db) => add_noise_seeded(&x, db, NoiseKind::White, seed).unwrap(),
        None => x,
    };
    let x: Vec<f64> = x.iter().map(|v| v + case.offset).collect();
    Record::new(
        format!("{}-{seed}.csv", case.name),
        t,
        vec![("x".into(), x), ("force".into(), force)],
    )
    .unwrap()
}

/// Identifies `rec` as `tfs identify rec.csv --library <case.library>` does (default options).
fn identify_default(case: &Case, rec: Record) -> Model {
    let opts = IdentifyOptions {
        library: Some(case.library.into()),
        ..IdentifyOptions::default()
    };
    let plan = plan(&opts, rec.names(), rec.source()).unwrap();
    identify(vec![rec], Vec::new(), &opts, &plan).unwrap().model
}

/// Checks `model` against `case`: every true term kept within `tol` (relative), and every other
/// term either absent or with an interval that covers zero. Returns the failures, worded.
fn check(case: &Case, model: &Model, tol: f64) -> Vec<String> {
    let eq = model.equation("x").unwrap();
    let mut bad = Vec::new();
    for (term, truth) in case.terms {
        match eq.terms.iter().find(|t| t.term.to_string() == *term) {
            None => bad.push(format!("{term} dropped")),
            Some(t) if ((t.coef - truth) / truth).abs() > tol => {
                bad.push(format!("{term} = {:.5} (truth {truth})", t.coef))
            }
            Some(_) => {}
        }
    }
    for t in &eq.terms {
        let name = t.term.to_string();
        if case.terms.iter().any(|(n, _)| *n == name) || (name == "1" && case.offset != 0.0) {
            continue;
        }
        let covers_zero = t.interval.is_some_and(|[lo, hi]| lo <= 0.0 && hi >= 0.0);
        if !covers_zero {
            bad.push(format!(
                "spurious {name} = {:.5} (interval {:?})",
                t.coef, t.interval
            ));
        }
    }
    bad
}

#[test]
fn noise_free_short_records_are_identified_exactly() {
    let mut failures = Vec::new();
    for case in CASES {
        let model = identify_default(case, record(case, None, 0));
        for f in check(case, &model, 1e-3) {
            failures.push(format!("{}: {f}", case.name));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn short_records_at_40_db_keep_every_true_term() {
    let mut failures = Vec::new();
    for case in CASES {
        for seed in 1..=3 {
            let model = identify_default(case, record(case, Some(40.0), seed));
            for f in check(case, &model, 0.15) {
                failures.push(format!("{} (noise seed {seed}): {f}", case.name));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A forced Duffing oscillator started from rest, its sensor without offset: the mean of a 20 s
/// record of it is motion (the response has not settled about zero). With a library closed
/// under shifts (`x, x^2, x^3`) the full library fits the accelerations as well with the mean
/// removed as without, and a choice by the full library removed it on some noise draws — which
/// turns the mean into an `x^2` term and drops the damping. The sparse laws tell them apart.
#[test]
fn a_record_without_offsets_keeps_its_mean() {
    let case = Case {
        name: "hardening Duffing from rest",
        terms: &[("x", -1.0), ("x^3", -0.5), ("x'", -0.05), ("force", 1.0)],
        library: "x, x^2, x^3, x', force",
        amp: 0.5,
        w: 1.4,
        x0: 0.0,
        offset: 0.0,
    };
    let mut removed = Vec::new();
    for seed in 1..=8 {
        let model = identify_default(&case, record(&case, Some(40.0), seed));
        if model.trace["offsets"]["mode"] == "remove" {
            removed.push(format!("seed {seed}: {}", model.equation_string()));
        }
    }
    assert!(
        removed.is_empty(),
        "the means were removed from records without offsets: {removed:#?}"
    );
}

/// A forced double well `x'' = a·x − b·x³ − c·x' + force` whose record stays in one well: its
/// mean is motion about the well's bottom, and over one well `1, x, x², x³` are nearly
/// collinear, so the constant of the `constant-term` treatment and `x²` can stand in for `x³`
/// (and the constant's own test, against the noise of the residual's mean, keeps it: all four
/// draws below did so before the law found without the constant was compared). Where that law
/// predicts the held-out half as well with fewer terms it is used; on one draw of four the
/// constant's law predicts the held-out half better and stays.
#[test]
fn a_record_in_one_well_keeps_its_cubic_and_gains_no_constant() {
    let case = Case {
        name: "double well, one well",
        terms: &[("x", 1.4), ("x^3", -1.2), ("x'", -0.11), ("force", 1.0)],
        library: "x, x^2, x^3, x', force",
        amp: 0.2,
        w: 1.2,
        x0: 1.4,
        offset: 0.0,
    };
    let clean = record(&case, None, 0);
    let low = clean
        .column("x")
        .unwrap()
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    assert!(low > 0.0, "the record leaves its well (min x = {low})");
    let mut wrong = Vec::new();
    for seed in 1..=4 {
        let model = identify_default(&case, record(&case, Some(40.0), seed));
        let eq = model.equation("x").unwrap();
        let constant = eq.terms.iter().any(|t| t.term.is_constant());
        let cubic = eq
            .terms
            .iter()
            .find(|t| t.term.to_string() == "x^3")
            .is_some_and(|t| ((t.coef + 1.2) / 1.2).abs() <= 0.15);
        if constant || !cubic {
            wrong.push(format!("seed {seed}: {}", model.equation_string()));
        }
    }
    assert!(
        wrong.len() <= 1,
        "a constant instead of the cubic on more than one draw: {wrong:#?}"
    );
}

/// A stiff forced Duffing oscillator (`k` 75, natural frequency 1.4 Hz) recorded for 8.5 s:
/// two halves of 4.25 s, where one window per half and a few strong bins can predict the
/// held-out half best. Those bins can form no more clusters than the four coefficients kept:
/// the jackknife's covariance is then rank-deficient, one cluster leads every coefficient's
/// variance, and the term test on two or three degrees of freedom removed a well-estimated
/// `x^3` (noise seed 5). A term that fails such a test is now tested again at the best setting
/// whose clusters outnumber the kept coefficients.
#[test]
fn a_short_stiff_record_keeps_its_cubic() {
    let case = Case {
        name: "stiff Duffing, 8.5 s",
        terms: &[("x", -75.0), ("x^3", -22.0), ("x'", -0.7), ("force", 1.0)],
        library: "x, x^2, x^3, x', force",
        amp: 19.0,
        w: 13.0,
        x0: 0.8,
        offset: 0.0,
    };
    let mut failures = Vec::new();
    for seed in 4..=9 {
        let model = identify_default(&case, record_of(&case, 851, Some(40.0), seed));
        for f in check(&case, &model, 0.15) {
            failures.push(format!("noise seed {seed}: {f}"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[path = "common/short_systems.rs"]
mod short_systems;

/// On a short record the damping `x'` and a velocity term of the library that is nearly collinear
/// with it (`x^2*x'`, `x'*abs(x')`) are hard to tell apart, and STLSQ's thresholds drop whichever
/// has the smaller scaled coefficient first: on some noise draws the path kept the stand-in and
/// dropped `x'`, a support no threshold corrects. The swap step after the path scores the swap on
/// the held-out rows. Over the family of `tests/common/short_systems.rs` with an `x'` term (five
/// oscillators, six parameter draws, six noise draws at 30 dB: 180 records) a stand-in whose true
/// value is zero replaced `x'` in 3 records without the step and in 1 with it.
#[test]
fn a_stand_in_rarely_replaces_the_damping_at_30_db() {
    let mut replaced = Vec::new();
    for kind in 0..short_systems::KINDS {
        for seed in 1..=6 {
            let sys = short_systems::draw(kind, seed);
            if !sys.terms.iter().any(|(t, _)| *t == "x'") {
                continue;
            }
            for ns in 1..=6 {
                let rec = sys.record(30.0, 1000 * seed + ns);
                let opts = IdentifyOptions {
                    library: Some(sys.library.into()),
                    ..IdentifyOptions::default()
                };
                let p = plan(&opts, rec.names(), rec.source()).unwrap();
                let Ok(id) = identify(vec![rec], Vec::new(), &opts, &p) else {
                    continue;
                };
                let kept: Vec<String> = id
                    .model
                    .equation("x")
                    .unwrap()
                    .terms
                    .iter()
                    .map(|t| t.term.to_string())
                    .collect();
                let has = |n: &str| kept.iter().any(|k| k == n);
                // A stand-in is a velocity term kept whose true value is zero.
                let stand_in = |n: &str| has(n) && !sys.terms.iter().any(|(t, _)| *t == n);
                if !has("x'") && (stand_in("x^2*x'") || stand_in("x'*abs(x')")) {
                    replaced.push(format!("{} seed {seed} noise {ns}: {kept:?}", sys.name));
                }
            }
        }
    }
    assert!(replaced.len() <= 1, "{replaced:#?}");
}
