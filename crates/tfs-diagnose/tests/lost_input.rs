//! A fitted model that lost the input its records carry (issue #33): when the base acceleration
//! reaches the structure late or filtered, the plain input can correlate so poorly with the
//! response that `identify` drops it, and the model has no input term left for an input effect
//! to act on. The input effects then offer the input the records carry — delayed or filtered —
//! as an added column. On oscillators of several restoring forces, delays, time constants,
//! sweeps and noise draws, the hidden input effect must rank first and significant, its
//! parameter must be near the truth, and adding it must cut the held-out simulation error.

mod common;

use common::*;
use tfs_diagnose::{Catalogue, DiagnoseOptions, add_effect, explain, r_mse, refit};

/// Three training sweeps and a held-out one, 100 Hz, 40 dB on `x` and `xb_acc`; the start model
/// `spec` has no input term.
fn check(label: &str, truth: &Truth, spec: &str, sweep: (f64, f64, f64), seed: u64) {
    let (effect, parameter, value) = match truth.hidden.first() {
        Some(Hidden::Delay(d)) => ("input-delay", "delay", *d),
        Some(Hidden::InputFilter(t)) => ("input-filter", "tau", *t),
        _ => panic!("{label}: the truth must hide an input effect"),
    };
    let (train, test) = train_and_test(truth, sweep, seed);
    let opts = DiagnoseOptions::default();
    let start = refit(&structure(spec), &train, &opts).unwrap();
    assert!(
        start.inputs.is_empty(),
        "{label}: the start model has no input"
    );
    let ex = explain(&start, &train, &Catalogue::standard(7), &opts).unwrap();
    let top = &ex.ranked[0];
    println!(
        "{label}: {} {:?} p={:.2e} delta={:.3} sim {:?} -> {:?}",
        top.name, top.parameter, top.p_value, top.delta_heldout, top.r_mse_before, top.r_mse_after
    );
    assert_eq!(top.name, effect, "{label}: {}", ex.verdict);
    assert!(top.significant, "{label}: {}", ex.verdict);
    let found = top.parameter.as_ref().map(|p| p.1).unwrap_or(f64::NAN);
    assert_eq!(
        top.parameter.as_ref().map(|p| p.0.as_str()),
        Some(parameter)
    );
    assert!(
        (found - value).abs() <= 0.2 * value,
        "{label}: {parameter} {found} vs {value}"
    );
    let after = add_effect(&start, effect, &train).unwrap();
    let (before_err, after_err) = (r_mse(&start, &test).unwrap(), r_mse(&after, &test).unwrap());
    println!(
        "{label}: {} held-out R-MSE {before_err:.4e} -> {after_err:.4e}",
        after.equation_string()
    );
    assert!(
        after_err * 5.0 < before_err,
        "{label}: {before_err} -> {after_err}"
    );
    assert!(
        after.inputs.len() == 1 && after.inputs[0].starts_with("xb_acc_"),
        "{label}: the refitted model takes the input back through the effect: {:?}",
        after.inputs
    );
}

fn duffing(damping: f64, hidden: Hidden) -> Truth {
    Truth {
        restoring: duffing_restoring(),
        damping,
        hidden: vec![hidden],
        x0: 0.0,
    }
}

/// A hardening Duffing oscillator whose base acceleration arrives 150 ms late (about a seventh
/// of its linear period), fitted without the input.
#[test]
fn duffing_lost_input_delayed_150_ms() {
    check(
        "duffing/delay150ms",
        &duffing(0.5, Hidden::Delay(0.15)),
        "x, x^3, x'",
        (0.3, 2.0, 2.0),
        110,
    );
}

/// A degree-7 restoring force, another damping, sweep and noise draw, 90 ms.
#[test]
fn degree_seven_lost_input_delayed_90_ms() {
    let truth = Truth {
        restoring: degree_seven_restoring(),
        damping: 0.8,
        hidden: vec![Hidden::Delay(0.09)],
        x0: 0.0,
    };
    check(
        "degree7/delay90ms",
        &truth,
        "x, x^3, x^5, x^7, x'",
        (0.3, 3.0, 3.0),
        130,
    );
}

/// The base acceleration low-pass filtered with a 120 ms time constant.
#[test]
fn duffing_lost_input_filtered_120_ms() {
    check(
        "duffing/filter120ms",
        &duffing(0.6, Hidden::InputFilter(0.12)),
        "x, x^3, x'",
        (0.3, 2.0, 2.5),
        150,
    );
}
