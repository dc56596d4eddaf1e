//! A base acceleration that reaches the structure late (issue #33): on base-excited oscillators
//! with high-degree restoring forces, several delays, parameter sets and noise draws, the hidden
//! delay must rank first and significant, its estimate must be near the truth, and adding it must
//! cut the held-out simulation error. The delayed input takes the input's place: the scan's
//! delays are measured against the input's own period, not the response's (a cell drifting in
//! its well has its displacement spectrum's peak at the record's length). A delay of about one
//! sample through a snap-through whose timing the input's noise decides is found too, judged
//! by short-horizon prediction.

mod common;

use common::*;
use tfs_diagnose::{Catalogue, DiagnoseOptions, Judge, add_effect, explain, r_mse, refit};

/// Three training sweeps and a held-out one, 100 Hz, 40 dB on `x` and `xb_acc`.
fn check(label: &str, truth: &Truth, spec: &str, sweep: (f64, f64, f64), seed: u64) {
    let Some(Hidden::Delay(delay)) = truth.hidden.first().cloned() else {
        panic!("{label}: the truth must hide a delay");
    };
    let (train, test) = train_and_test(truth, sweep, seed);
    let opts = DiagnoseOptions::default();
    let start = refit(&structure(spec), &train, &opts).unwrap();
    let ex = explain(&start, &train, &Catalogue::standard(7), &opts).unwrap();
    let top = &ex.ranked[0];
    println!(
        "{label}: {} {:?} p={:.2e} delta={:.3} sim {:?} -> {:?}",
        top.name, top.parameter, top.p_value, top.delta_heldout, top.r_mse_before, top.r_mse_after
    );
    assert_eq!(top.name, "input-delay", "{label}: {}", ex.verdict);
    assert!(top.significant, "{label}: {}", ex.verdict);
    assert!(top.delta_heldout > 0.5, "{label}: {}", top.reason);
    let found = top.parameter.as_ref().map(|p| p.1).unwrap_or(f64::NAN);
    assert!(
        (found - delay).abs() <= 0.15 * delay,
        "{label}: delay {found} vs {delay}"
    );
    let after = add_effect(&start, "input-delay", &train).unwrap();
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
        after.inputs.iter().all(|i| i != "xb_acc"),
        "{label}: the delayed input replaces xb_acc"
    );
}

fn kresling(damping: f64, delay: f64) -> Truth {
    Truth {
        restoring: kresling_restoring(),
        damping,
        hidden: vec![Hidden::Delay(delay)],
        x0: 1.582,
    }
}

/// The case: the Kresling surrogate cell (x^5..7), the base acceleration 40 ms late.
#[test]
fn kresling_cell_40_ms() {
    check(
        "kresling/40ms",
        &kresling(1.99, 0.04),
        "x^5..7, x', xb_acc",
        (0.2, 2.5, 3.0),
        10,
    );
}

/// Another damping, amplitude, noise draw and a delay between whole samples.
#[test]
fn kresling_cell_27_ms() {
    check(
        "kresling/27ms",
        &kresling(1.6, 0.027),
        "x^5..7, x', xb_acc",
        (0.2, 2.5, 3.6),
        40,
    );
}

/// A hardening oscillator with a degree-7 restoring force `−k(x + x³/2 + x⁵/4 + x⁷/8)`, 55 ms.
#[test]
fn degree_seven_oscillator_55_ms() {
    let truth = Truth {
        restoring: degree_seven_restoring(),
        damping: 0.5,
        hidden: vec![Hidden::Delay(0.055)],
        x0: 0.0,
    };
    check(
        "degree7/55ms",
        &truth,
        "x, x^3, x^5, x^7, x', xb_acc",
        (0.3, 3.0, 3.0),
        70,
    );
}

/// A delay of about one sample on the surrogate cell released from its deployed well: the sweep
/// snaps it into the folded well, and once the model holds the delay, when that snap happens is
/// decided by the input's own noise — the start model, which absorbed the delay into its
/// coefficients, snaps at a time the noise does not move. Its worse free run then says which way
/// the noise tipped it, not that the delay is wrong, so the free run cannot judge the candidates:
/// the late input must still be found (input-delay first, or input-filter first with input-delay
/// reported as indistinguishable from it), significant, judged by short-horizon prediction.
/// Before the judge looked at the candidates' own free runs, one of these draws named nothing
/// and the other a Maxwell element; since the judge also reads a run's own divergence, the second
/// draw's start model already parts from itself on one record and the candidates are not asked.
#[test]
fn kresling_cell_one_sample_through_snap_through() {
    for (c, delay, amp, seed) in [(2.4, 0.011, 3.2, 50), (1.7, 0.014, 2.6, 60)] {
        let label = format!("kresling/{delay}s/c={c}");
        let truth = kresling(c, delay);
        let (train, _) = train_and_test(&truth, (0.2, 2.5, amp), seed);
        let opts = DiagnoseOptions::default();
        let start = refit(&structure("x^5..7, x', xb_acc"), &train, &opts).unwrap();
        let ex = explain(&start, &train, &Catalogue::standard(7), &opts).unwrap();
        let top = &ex.ranked[0];
        println!(
            "{label}: {} judged by {:?}: {}",
            top.name, ex.judges[0].judge, ex.verdict
        );
        assert!(top.significant, "{label}: {}", ex.verdict);
        let delay_named = top.name == "input-delay"
            || (top.name == "input-filter"
                && ex
                    .ranked
                    .iter()
                    .any(|r| r.name == "input-delay" && r.tied_with_top));
        assert!(delay_named, "{label}: {}", ex.verdict);
        assert_eq!(
            ex.judges[0].judge,
            Judge::ShortHorizon,
            "{label}: {}",
            ex.judges[0].why
        );
        // Either a candidate's own free run was found dominated, or already the start model's
        // run parts from itself (its own divergence, `noise_probe`): the free run is not asked.
        assert!(
            ex.judges[0].why.contains("free run of the model with")
                || ex.judges[0].why.contains("its own divergence"),
            "{label}: {}",
            ex.judges[0].why
        );
    }
}
