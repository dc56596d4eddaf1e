//! Units (issue #32): T-F-S SINDy's model does not depend on the units the record is written in.
//!
//! With `T = s·t`, `X = a·x` and `U = b·u` (time, displacement and base-acceleration input in
//! other units), the equation `x'' = Σ c_k x^k + c_v x' + g·u` becomes
//! `X'' = Σ c_k a^(1−k)/s² X^k + (c_v/s) X' + g·a/(b·s²) U`. Every coefficient identified in the
//! new units, multiplied back by the inverse factor, must equal the base-unit one to rounding,
//! the same terms must be kept, and every interval must map the same way.
//!
//! Test systems: the surrogate Kresling cell `x'' + c x' + a5 x⁵ + a6 x⁶ + a7 x⁷ = −xb_acc`
//! (two parameter sets: the paper's Table 1 row and a softer cell), simulated under base
//! acceleration sweeps with white measurement noise at 60 and 30 dB; and the repository's
//! 30 dB Kresling fixture in millimetres, the record the issue measured.

mod common;

use std::sync::OnceLock;

use common::synthetic::{NoiseSpec, Surrogate, SweepSpec, surrogate_record};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use tfs_criteria::{IdentifySpec, identify_tfs};
use tfs_data::Record;
use tfs_library::{Model, Term};
use tfs_signal::NoiseKind;

/// The library (the CLI's default for one DOF with a base input).
const LIB: &str = "x^1..7, x', xb_acc";
/// Relative tolerance of the mapping: rounding, amplified by the conditioning of the fits.
const TOL: f64 = 1e-8;

/// The test systems: (system, SNR in dB).
fn cases() -> [(Surrogate, f64); 3] {
    let table1 = Surrogate {
        c: 1.99,
        a: [12.12, -18.03, 6.56],
    };
    let soft = Surrogate {
        c: 1.2,
        a: [8.0, -13.5, 5.2],
    };
    [(table1, 60.0), (table1, 30.0), (soft, 30.0)]
}

/// Two 80 s sweeps of the base acceleration at 100 Hz, noisy, in base units.
fn base_records(case: usize) -> &'static [Record] {
    static DATA: OnceLock<Vec<Vec<Record>>> = OnceLock::new();
    &DATA.get_or_init(|| {
        cases()
            .iter()
            .enumerate()
            .map(|(c, &(sys, snr))| {
                [(0.05, 1.5, 4.0), (0.1, 1.2, 5.0)]
                    .iter()
                    .enumerate()
                    .map(|(i, &(f0, f1, amplitude))| {
                        let sweep = SweepSpec {
                            f0,
                            f1,
                            duration: 80.0,
                            amplitude,
                        };
                        let noise = NoiseSpec {
                            snr_db: snr,
                            kind: NoiseKind::White,
                            seed: 40 + 10 * c as u64 + i as u64,
                        };
                        surrogate_record(&format!("r{i}"), &sys, sweep, 100.0, Some(noise)).unwrap()
                    })
                    .collect()
            })
            .collect()
    })[case]
}

/// `records` with time scaled by `s`, `x` by `a` and `xb_acc` by `b`.
fn rescaled(records: &[Record], (s, a, b): (f64, f64, f64)) -> Vec<Record> {
    records
        .iter()
        .map(|r| {
            let col = |n: &str, k: f64| r.column(n).unwrap().iter().map(|v| v * k).collect();
            Record::new(
                r.source(),
                r.t().iter().map(|v| v * s).collect(),
                vec![
                    ("x".into(), col("x", a)),
                    ("xb_acc".into(), col("xb_acc", b)),
                ],
            )
            .unwrap()
        })
        .collect()
}

/// The factor that maps a coefficient of `term` identified in units `(s, a, b)` back to base
/// units (the inverse of the scaling law in the module docs).
fn to_base(term: &Term, (s, a, b): (f64, f64, f64)) -> f64 {
    match term.to_string().as_str() {
        "1" => s * s / a,
        "x'" => s,
        "xb_acc" => s * s * b / a,
        _ => {
            let k = term.degree().expect("a power of x") as i32;
            s * s * a.powi(k - 1)
        }
    }
}

/// One kept term: name, coefficient, interval, inclusion probability.
type Kept = (String, f64, Option<[f64; 2]>, Option<f64>);

/// The kept terms of `model`, mapped back to base units from `units`.
fn kept_in_base_units(model: &Model, units: (f64, f64, f64)) -> Vec<Kept> {
    model.equations[0]
        .terms
        .iter()
        .map(|t| {
            let f = to_base(&t.term, units);
            let iv = t.interval.map(|[lo, hi]| {
                let (p, q) = (lo * f, hi * f);
                [p.min(q), p.max(q)]
            });
            (t.term.to_string(), t.coef * f, iv, t.inclusion)
        })
        .collect()
}

fn identify(records: &[Record]) -> Model {
    identify_tfs(records, &IdentifySpec::new(&["x"], LIB))
        .unwrap()
        .model
}

/// The base-unit model of each case, identified once.
fn reference(case: usize) -> &'static [Kept] {
    static REF: OnceLock<Vec<Vec<Kept>>> = OnceLock::new();
    &REF.get_or_init(|| {
        (0..cases().len())
            .map(|c| kept_in_base_units(&identify(base_records(c)), (1.0, 1.0, 1.0)))
            .collect()
    })[case]
}

fn close(p: f64, q: f64) -> bool {
    p == q || (p - q).abs() <= TOL * q.abs().max(p.abs())
}

/// Same terms in the same order, every coefficient, interval end and inclusion probability
/// equal to the relative tolerance.
fn assert_same(got: &[Kept], want: &[Kept], what: &str) {
    let names = |k: &[Kept]| k.iter().map(|t| t.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(got), names(want), "{what}: kept terms differ");
    for (g, w) in got.iter().zip(want) {
        assert!(close(g.1, w.1), "{what}: '{}' {} vs {}", g.0, g.1, w.1);
        match (g.2, w.2) {
            (Some(gi), Some(wi)) => assert!(
                close(gi[0], wi[0]) && close(gi[1], wi[1]),
                "{what}: interval of '{}' {gi:?} vs {wi:?}",
                g.0
            ),
            (None, None) => {}
            _ => panic!("{what}: interval of '{}' {:?} vs {:?}", g.0, g.2, w.2),
        }
        match (g.3, w.3) {
            (Some(a), Some(b)) => assert!(
                (a - b).abs() <= 1e-12,
                "{what}: inclusion of '{}' {a} vs {b}",
                g.0
            ),
            (None, None) => {}
            _ => panic!("{what}: inclusion of '{}' {:?} vs {:?}", g.0, g.3, w.3),
        }
    }
}

/// The base identifications are physically right, so the property is not vacuous: damping
/// and input gain within 10 %, and the restoring terms x⁵…x⁷ kept.
#[test]
fn base_identifications_recover_the_cell() {
    for (c, (sys, snr)) in cases().iter().enumerate() {
        let r = reference(c);
        let coef = |n: &str| r.iter().find(|t| t.0 == n).map(|t| t.1);
        let damping = coef("x'").map(|v| -v);
        assert!(
            damping.is_some_and(|d| (d - sys.c).abs() < 0.1 * sys.c),
            "case {c} ({snr} dB): damping {damping:?} vs {}",
            sys.c
        );
        let gain = coef("xb_acc");
        assert!(
            gain.is_some_and(|g| (g + 1.0).abs() < 0.1),
            "case {c} ({snr} dB): input gain {gain:?} vs -1"
        );
        for k in ["x^5", "x^6", "x^7"] {
            assert!(
                coef(k).is_some(),
                "case {c} ({snr} dB): {k} not kept: {r:?}"
            );
        }
    }
}

proptest! {
    // A fixed seed: the same cases on every run (no flaky CI), still drawn at random. Each case
    // is one identification of two 8000-sample records.
    #![proptest_config(ProptestConfig {
        cases: 24,
        failure_persistence: None,
        rng_seed: RngSeed::Fixed(32),
        ..ProptestConfig::default()
    })]

    /// Rescaling time (10⁻² … 10²), displacement (10⁻⁴ … 10⁴) and input (10⁻⁴ … 10⁴) units
    /// keeps the same terms, and every coefficient and interval maps back by the scaling law.
    #[test]
    fn rescaling_time_amplitude_and_input_units(
        case in 0usize..3, ls in -2.0f64..2.0, la in -4.0f64..4.0, lb in -4.0f64..4.0
    ) {
        let units = (10f64.powf(ls), 10f64.powf(la), 10f64.powf(lb));
        let model = identify(&rescaled(base_records(case), units));
        assert_same(
            &kept_in_base_units(&model, units),
            reference(case),
            &format!("case {case}, (s, a, b) = {units:?}"),
        );
    }
}

/// The two training records of the 30 dB Kresling fixture (columns `t`, `x`, `xb_acc`).
fn fixture() -> Vec<Record> {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures");
    ["train-1", "train-2"]
        .iter()
        .map(|n| {
            let r = tfs_data::read_csv(format!("{root}/kresling-30db-{n}.csv")).unwrap();
            rescaled(&[r], (1.0, 1.0, 1.0)).remove(0)
        })
        .collect()
}

/// The record: the 30 dB fixture with `x` and `xb_acc` in thousandths (and the
/// powers of two around them, where scaling is exact in floating point).
#[test]
fn fixture_in_other_units_gives_the_same_model() {
    let recs = fixture();
    let want = kept_in_base_units(&identify(&recs), (1.0, 1.0, 1.0));
    for units in [
        (1.0, 1e-3, 1e-3),
        (1.0, 0.0009765625, 1.0),
        (60.0, 1e3, 1.0),
        (1.0, 1.0, 1e4),
    ] {
        let got = kept_in_base_units(&identify(&rescaled(&recs, units)), units);
        assert_same(&got, &want, &format!("fixture in units {units:?}"));
    }
}

/// The fixture's settings search is a near-tie (two settings within 0.004 % of each other): the
/// trace says the decision was close, and says it in every unit system.
#[test]
fn fixture_trace_says_the_settings_choice_was_close() {
    let recs = fixture();
    for units in [(1.0, 1.0, 1.0), (1.0, 1e-3, 1e-3)] {
        let id = identify_tfs(&rescaled(&recs, units), &IdentifySpec::new(&["x"], LIB)).unwrap();
        let why = &id.trace.dofs[0].settings.why;
        assert!(
            why.iter()
                .any(|w| w.starts_with("close decision") && w.contains("selecting the terms")),
            "units {units:?}: {why:#?}"
        );
    }
}
