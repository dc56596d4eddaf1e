//! Raw units and offsets (issue #11), through the library API: a force-driven Duffing oscillator
//! `x'' + 2ζω x' + ω² x + k3 x³ = g·u` sampled at 10 samples per resonance period (60 dB noise,
//! broadband random-phase multisine) is identified with T-F-S SINDy from the library
//! `1, x, x^3, x', u`, then the same record is rescaled or shifted.
//!
//! With `T = s·t`, `X = a·x`, `U = b·u` the equation becomes
//! `X'' = −(c/s) X' − (k/s²) X − k3/(a² s²) X³ + g·a/(b s²) U`, so every coefficient must map back
//! to the base-unit one: `c1 → c1/s`, `k → k/s²`, `k3 → k3/(a² s²)`, `g → g·a/(b s²)`, constant
//! `→ a·const/s²`. Stated tolerance: relative 1e-6 (the pipeline is scale-free: the results agree
//! to rounding). Offsets: after per-channel offset removal (what `tfs identify --offsets remove`
//! does) a shifted record gives the same model; without removal an offset on the input only
//! moves the constant term.

use std::sync::OnceLock;

use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use tfs::criteria::{IdentifySpec, identify_tfs};
use tfs::data::Record;
use tfs::dynamics::{SimulateOptions, simulate_model_on_record};
use tfs::library::{Model, Term};
use tfs::signal::noise::add_noise_seeded;
use tfs::signal::{Excitation, Multisine, NoiseKind};

/// 1 kHz sampling, resonance at 100 Hz: 10 samples per period.
const DT: f64 = 1e-3;
const FN: f64 = 100.0;
const ZETA: f64 = 0.03;
/// Cubic stiffness and input gain in "volt" units (coefficients of order 1e4 … 1e5).
const K3: f64 = 3.0e4;
const G: f64 = 8.0e4;
const N: usize = 8192;
const LIBRARY: &str = "1, x, x^3, x', u";
const TERMS: [&str; 5] = ["1", "x", "x^3", "x'", "u"];
/// Relative tolerance of the rescaling property.
const RESCALE_TOL: f64 = 1e-6;

fn truth() -> Model {
    let w = 2.0 * std::f64::consts::PI * FN;
    let terms = [
        ("x", -w * w),
        ("x'", -2.0 * ZETA * w),
        ("x^3", -K3),
        ("u", G),
    ];
    let list: Vec<String> = terms
        .iter()
        .map(|(t, c)| format!(r#"{{"term":"{t}","coef":{c}}}"#))
        .collect();
    let json = format!(
        r#"{{"format":"tfs-model/1","dofs":["x"],"inputs":["u"],"equations":[{{"dof":"x","terms":[{}]}}],"method":"truth"}}"#,
        list.join(",")
    );
    Model::from_json_str(&json).unwrap()
}

/// The base measurement `(t, x, u)`: simulated from rest under a multisine (5–200 Hz, 150
/// tones), 60 dB white noise on both channels. Generated once.
fn base() -> &'static (Vec<f64>, Vec<f64>, Vec<f64>) {
    static DATA: OnceLock<(Vec<f64>, Vec<f64>, Vec<f64>)> = OnceLock::new();
    DATA.get_or_init(|| {
        let ms = Multisine::new(5.0, 200.0, 150, 1.0, N as f64 * DT, 0.2, 3).unwrap();
        let u: Vec<f64> = (0..N).map(|k| ms.value(k as f64 * DT)).collect();
        let t: Vec<f64> = (0..N).map(|k| k as f64 * DT).collect();
        let clean = Record::new(
            "gen",
            t.clone(),
            vec![("x".into(), vec![0.0; N]), ("u".into(), u.clone())],
        )
        .unwrap();
        let tr = simulate_model_on_record(&truth(), &clean, &SimulateOptions::default()).unwrap();
        let x = add_noise_seeded(&tr.x[0], 60.0, NoiseKind::White, 3).unwrap();
        let um = add_noise_seeded(&u, 60.0, NoiseKind::White, 1003).unwrap();
        (t, x, um)
    })
}

/// The base record with time scaled by `s`, `x ↦ a·x + cx`, `u ↦ b·u + cu`.
fn transformed(s: f64, a: f64, b: f64, cx: f64, cu: f64) -> Record {
    let (t, x, u) = base();
    Record::new(
        "rig",
        t.iter().map(|v| v * s).collect(),
        vec![
            ("x".into(), x.iter().map(|v| a * v + cx).collect()),
            ("u".into(), u.iter().map(|v| b * v + cu).collect()),
        ],
    )
    .unwrap()
}

/// Identified coefficients of [`TERMS`] (0 where a term was not selected).
fn identify(rec: Record, remove_offsets: bool) -> [f64; 5] {
    let mut rec = rec;
    if remove_offsets {
        rec.remove_offsets(&["x", "u"]).unwrap();
    }
    let spec = IdentifySpec::new(&["x"], LIBRARY);
    let m = identify_tfs(&[rec], &spec).unwrap().model;
    TERMS.map(|t| m.coef("x", &Term::parse(t, &["x"]).unwrap()).unwrap())
}

/// Factors mapping coefficients identified in units `(s, a, b)` back to base units.
fn to_base(s: f64, a: f64, b: f64) -> [f64; 5] {
    [s * s / a, s * s, a * a * s * s, s, b * s * s / a]
}

/// The base-unit model (no offsets), identified once.
fn reference() -> &'static [f64; 5] {
    static REF: OnceLock<[f64; 5]> = OnceLock::new();
    REF.get_or_init(|| identify(transformed(1.0, 1.0, 1.0, 0.0, 0.0), false))
}

/// Asserts coefficient-wise agreement (`|p − q| ≤ tol·max(|q|, floor)` with `floor` a fraction
/// of the largest coefficient, for terms that are zero in both) and the same support.
fn assert_same(p: &[f64; 5], q: &[f64; 5], tol: f64, skip_constant: bool, what: &str) {
    for (j, term) in TERMS.iter().enumerate() {
        if skip_constant && j == 0 {
            continue;
        }
        assert_eq!(
            p[j] == 0.0,
            q[j] == 0.0,
            "{what}: support differs at '{term}': {p:?} vs {q:?}"
        );
        let rel = (p[j] - q[j]).abs() / q[j].abs().max(f64::MIN_POSITIVE);
        assert!(
            p[j] == q[j] || rel <= tol,
            "{what}: '{term}' {} vs {} (relative {rel:.2e} > {tol:.0e})",
            p[j],
            q[j]
        );
    }
}

/// The base identification is physically right, so the properties below are not vacuous.
#[test]
fn base_identification_recovers_the_duffing_coefficients() {
    let c = reference();
    let w = 2.0 * std::f64::consts::PI * FN;
    let truth = [0.0, -w * w, -K3, -2.0 * ZETA * w, G];
    for j in 1..5 {
        let rel = (c[j] - truth[j]).abs() / truth[j].abs();
        assert!(
            rel < 0.03,
            "'{}': {} vs {} ({rel:.3})",
            TERMS[j],
            c[j],
            truth[j]
        );
    }
}

/// Relative change allowed in the non-constant coefficients when an input offset is kept (rounding:
/// an offset of 10 standard deviations costs about one significant digit of the input).
const OFFSET_TOL: f64 = 1e-5;

proptest! {
    // A fixed seed: the cases are the same on every run (no flaky CI), still drawn at random.
    #![proptest_config(ProptestConfig { cases: 6, failure_persistence: None, rng_seed: RngSeed::Fixed(11), ..ProptestConfig::default() })]

    /// Rescaling time, amplitude (volts) and input units leaves the model physically unchanged.
    #[test]
    fn rescaling_time_amplitude_and_input_units(
        ls in -2.0f64..2.0, la in -3.0f64..4.0, lb in -3.0f64..4.0
    ) {
        let (s, a, b) = (10f64.powf(ls), 10f64.powf(la), 10f64.powf(lb));
        let c = identify(transformed(s, a, b, 0.0, 0.0), false);
        let f = to_base(s, a, b);
        let back: [f64; 5] = std::array::from_fn(|j| c[j] * f[j]);
        assert_same(&back, reference(), RESCALE_TOL, false, &format!("s = {s:.3e}, a = {a:.3e}, b = {b:.3e}"));
    }

    /// With per-channel offset removal, constant offsets on both channels (up to ten times the
    /// signal's standard deviation), on top of a rescaling, change nothing.
    #[test]
    fn offsets_removed_change_nothing(
        ox in -10.0f64..10.0, ou in -10.0f64..10.0, la in -3.0f64..4.0
    ) {
        let (_, x, u) = base();
        let (sx, su) = (std_dev(x), std_dev(u));
        let a = 10f64.powf(la);
        let plain = identify(transformed(1.0, a, 1.0, 0.0, 0.0), true);
        let shifted = identify(transformed(1.0, a, 1.0, ox * a * sx, ou * su), true);
        assert_same(&shifted, &plain, RESCALE_TOL, false, &format!("offsets ({ox:.2}, {ou:.2}) std"));
    }

    /// Without removal, an offset on the input is absorbed by the constant term only: every other
    /// coefficient stays where it was.
    #[test]
    fn input_offset_kept_moves_only_the_constant(ou in -10.0f64..10.0) {
        let su = std_dev(&base().2);
        let c = identify(transformed(1.0, 1.0, 1.0, 0.0, ou * su), false);
        assert_same(&c, reference(), OFFSET_TOL, true, &format!("input offset {ou:.2} std"));
    }
}

/// The frequency-domain rows never see DC, so T-F-S estimates the constant term in the time domain
/// (the mean equation residual of the other terms): an input offset `d` kept in the data becomes
/// `const = −g·d`.
#[test]
fn input_offset_kept_is_the_constant_term() {
    let su = std_dev(&base().2);
    let d = 2.0 * su;
    let c = identify(transformed(1.0, 1.0, 1.0, 0.0, d), false);
    let want = -reference()[4] * d;
    assert!(
        (c[0] - want).abs() <= 0.02 * want.abs(),
        "constant {} vs −g·d = {want}",
        c[0]
    );
}

/// The ends of the input-offset range of the property above (±10 standard deviations).
#[test]
fn input_offset_extremes_move_only_the_constant() {
    let su = std_dev(&base().2);
    for ou in [-10.0, 10.0] {
        let c = identify(transformed(1.0, 1.0, 1.0, 0.0, ou * su), false);
        assert_same(
            &c,
            reference(),
            OFFSET_TOL,
            true,
            &format!("input offset {ou} std"),
        );
    }
}

fn std_dev(x: &[f64]) -> f64 {
    let m = x.iter().sum::<f64>() / x.len() as f64;
    (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
}
