//! A library that omits the dashpot `x'` (issue #33): the catalogue's `linear-damping` must be
//! named first, significant, and adding it must cut the held-out simulation error — not a
//! nonlinear relative (quadratic damping, a hysteresis state) standing in for the plain term.
//! Two baselines, two damping levels each, their own noise draws.

mod common;

use common::*;
use tfs_diagnose::{Catalogue, DiagnoseOptions, add_effect, explain, r_mse, refit};

/// Three training sweeps and a held-out one, 100 Hz, 40 dB on `x` and `xb_acc`.
fn check(label: &str, truth: &Truth, spec: &str, sweep: (f64, f64, f64), seed: u64) {
    let (train, test) = train_and_test(truth, sweep, seed);
    let opts = DiagnoseOptions::default();
    let start = refit(&structure(spec), &train, &opts).unwrap();
    let ex = explain(&start, &train, &Catalogue::standard(7), &opts).unwrap();
    for r in ex.ranked.iter().take(3) {
        println!(
            "{label}: {} {:?} sig={} delta={:.3} sim {:?} -> {:?}",
            r.name, r.parameter, r.significant, r.delta_heldout, r.r_mse_before, r.r_mse_after
        );
    }
    let top = &ex.ranked[0];
    assert_eq!(top.name, "linear-damping", "{label}: {}", ex.verdict);
    assert!(top.significant, "{label}: {}", ex.verdict);
    // The fitted dashpot is the truth's, within 20 %.
    assert!(
        (top.coef + truth.damping).abs() < 0.2 * truth.damping,
        "{label}: c = {} vs {}",
        -top.coef,
        truth.damping
    );
    let after = add_effect(&start, "linear-damping", &train).unwrap();
    let (before_err, after_err) = (r_mse(&start, &test).unwrap(), r_mse(&after, &test).unwrap());
    println!(
        "{label}: {} held-out R-MSE {before_err:.4e} -> {after_err:.4e}",
        after.equation_string()
    );
    assert!(
        after_err * 3.0 < before_err,
        "{label}: {before_err} -> {after_err}"
    );
}

fn kresling(damping: f64) -> Truth {
    Truth {
        restoring: kresling_restoring(),
        damping,
        hidden: vec![],
        x0: 1.582,
    }
}

fn duffing(damping: f64) -> Truth {
    Truth {
        restoring: duffing_restoring(),
        damping,
        hidden: vec![],
        x0: 0.0,
    }
}

#[test]
fn kresling_cell_without_dashpot() {
    for (c, seed) in [(1.99, 10), (1.4, 30)] {
        check(
            &format!("kresling/c={c}"),
            &kresling(c),
            "x^5..7, xb_acc",
            (0.2, 2.5, 3.0),
            seed,
        );
    }
}

#[test]
fn duffing_without_dashpot() {
    for (c, seed) in [(0.63, 60), (0.3, 80)] {
        check(
            &format!("duffing/c={c}"),
            &duffing(c),
            "x, x^3, xb_acc",
            (0.3, 3.0, 4.0),
            seed,
        );
    }
}
