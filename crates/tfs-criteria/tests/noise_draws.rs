//! Over repeated noise draws of the peers records (the paper's cell, four base-acceleration
//! sweeps at 200 Hz, 20 dB white noise on `x` and `xb_acc`), with the 9-column library:
//! spurious terms do not survive, and the 95 % intervals of the true terms cover the truth at
//! about the stated rate without being needlessly wide. One draw proves little either way;
//! sixteen separate an honest method from one that is overconfident (intervals from a plain
//! sandwich on GLS-weighted rows covered 56 of 80 true coefficients, and spurious low powers
//! stayed in 2 of the 16 models; the cluster jackknife with t on its clusters less one covered
//! 70 of 80, on each coefficient's effective degrees of freedom 79).
//! Also: a model that no input drives is flagged, not presented as identified.

#[path = "common/synthetic.rs"]
mod synthetic;

use synthetic::{NoiseSpec, Surrogate, SweepSpec, surrogate_record};
use tfs_criteria::{IdentifySpec, identify_tfs};
use tfs_signal::NoiseKind;

/// The peers system: m = 1, c = 2, the surrogate force 12.145h⁵ − 18.0618h⁶ + 6.5625h⁷.
const SYS: Surrogate = Surrogate {
    c: 2.0,
    a: [12.145, -18.0618, 6.5625],
};

/// The four training sweeps of the peers benchmark: (f0 Hz, f1 Hz, T s, amplitude).
const SWEEPS: [(f64, f64, f64, f64); 4] = [
    (0.05, 1.5, 100.0, 3.0),
    (0.05, 1.5, 60.0, 4.0),
    (0.1, 1.2, 80.0, 5.0),
    (0.05, 2.0, 120.0, 6.0),
];

#[test]
fn no_spurious_terms_and_honest_intervals_over_noise_draws_at_20_db() {
    let truth: [(&str, f64); 5] = [
        ("x^5", -SYS.a[0]),
        ("x^6", -SYS.a[1]),
        ("x^7", -SYS.a[2]),
        ("x'", -SYS.c),
        ("xb_acc", -1.0),
    ];
    let spec = IdentifySpec::new(&["x"], "x^1..7, x', xb_acc");
    let draws = 16;
    let (mut covered, mut total, mut spurious) = (0, 0, Vec::new());
    // Σ (error / half-width)²: about 0.4² per interval for honest t intervals on 3–6 degrees
    // of freedom, far less for intervals made wide to be safe.
    let mut z2 = 0.0;
    // True terms that bootstrap resampling keeps in fewer than 90 % of resamples.
    let mut low_inclusion = Vec::new();
    for seed in 0..draws {
        let recs: Vec<_> = SWEEPS
            .iter()
            .enumerate()
            .map(|(i, &(f0, f1, duration, amplitude))| {
                surrogate_record(
                    &format!("r{i}"),
                    &SYS,
                    SweepSpec {
                        f0,
                        f1,
                        duration,
                        amplitude,
                    },
                    200.0,
                    Some(NoiseSpec {
                        snr_db: 20.0,
                        kind: NoiseKind::White,
                        seed: 1000 * seed + 17 * i as u64,
                    }),
                )
                .unwrap()
            })
            .collect();
        let id = identify_tfs(&recs, &spec).unwrap();
        let eq = &id.model.equations[0];
        let extra: Vec<String> = eq
            .terms
            .iter()
            .map(|t| t.term.to_string())
            .filter(|n| !truth.iter().any(|(m, _)| m == n))
            .collect();
        if !extra.is_empty() {
            spurious.push(format!("seed {seed}: {}", id.model.equation_string()));
        }
        for (name, want) in truth {
            let Some(t) = eq.terms.iter().find(|t| t.term.to_string() == name) else {
                continue;
            };
            let [lo, hi] = t.interval.expect("every kept term has an interval");
            let p = t
                .inclusion
                .expect("every kept term has an inclusion probability");
            if p < 0.9 {
                low_inclusion.push(format!("seed {seed}: {name} {p:.2}"));
            }
            total += 1;
            covered += usize::from(lo <= want && want <= hi);
            z2 += ((t.coef - want) / (0.5 * (hi - lo))).powi(2);
        }
    }
    let rms = (z2 / total.max(1) as f64).sqrt();
    eprintln!("coverage {covered}/{total}, rms error/half-width {rms:.2}; spurious: {spurious:?}");
    assert!(
        spurious.len() <= 1,
        "spurious terms survived in {} of {draws} models: {spurious:#?}",
        spurious.len()
    );
    assert!(
        total >= 4 * draws as usize,
        "true terms missing: only {total} found in {draws} models"
    );
    let rate = covered as f64 / total as f64;
    // 95 % within the sampling error of 80 intervals (72/80 is about its lower 5 % point).
    assert!(
        rate >= 0.9,
        "95% intervals covered the truth in only {covered}/{total}"
    );
    // Inclusion from STLSQ at the selection's own threshold (picked on the first records of
    // Criterion 4) put damping and the input below 0.9 in 3 of these 16 models (0.00 in one).
    assert!(
        low_inclusion.is_empty(),
        "true terms rarely kept under resampling: {low_inclusion:?}"
    );
    assert!(
        rms >= 0.25,
        "intervals needlessly wide: rms error/half-width {rms:.2}"
    );
}

/// Driven records, and a library whose only input is a channel unrelated to the motion: the
/// model keeps no input term, and the trace says the data do not support the library rather
/// than presenting an undriven model as identified. With the true input offered as well, that
/// rule stays quiet.
#[test]
fn a_model_that_no_input_drives_is_flagged() {
    let recs: Vec<_> = SWEEPS
        .iter()
        .enumerate()
        .map(|(i, &(f0, f1, duration, amplitude))| {
            let r = surrogate_record(
                &format!("r{i}"),
                &SYS,
                SweepSpec {
                    f0,
                    f1,
                    duration: 0.5 * duration,
                    amplitude,
                },
                200.0,
                Some(NoiseSpec {
                    snr_db: 40.0,
                    kind: NoiseKind::White,
                    seed: 7 + i as u64,
                }),
            )
            .unwrap();
            let acc = r.column("xb_acc").unwrap();
            // A channel of the same power, unrelated to the motion.
            let u =
                tfs_signal::noise::noise_for(acc, 0.0, NoiseKind::White, 99 + i as u64).unwrap();
            let mut cols: Vec<(String, Vec<f64>)> = r
                .names()
                .iter()
                .map(|n| (n.clone(), r.column(n).unwrap().to_vec()))
                .collect();
            cols.push(("u".into(), u));
            tfs_data::Record::new(r.source(), r.t().to_vec(), cols).unwrap()
        })
        .collect();
    let rule = "no input term survives selection";
    let verdict = |lib: &str| {
        let id = identify_tfs(&recs, &IdentifySpec::new(&["x"], lib)).unwrap();
        let d = &id.trace.dofs[0];
        let c1 = d.criterion1.as_ref().unwrap();
        (
            id.model.equation_string(),
            c1.support.is_supported(),
            d.assembly_verdict.to_string(),
        )
    };
    let (eq, supported, text) = verdict("x^5..7, x', u");
    assert!(!eq.contains('u'), "the unrelated channel was kept: {eq}");
    assert!(!supported && text.contains(rule), "{eq}: {text}");
    let (eq, _, text) = verdict("x^5..7, x', xb_acc, u");
    assert!(
        eq.contains("xb_acc") && !text.contains(rule),
        "{eq}: {text}"
    );
}
