//! A soft one-sided stop between the positions the stop effect's scan tries (issue #33). The scan
//! offers five positions per end of the data's range (1, 2, 5, 10 and 20 % of the span in from
//! the extreme); a contact between two of them, a grid gap of several percent of the span away,
//! leaves its kink where the data have none. The diagnosis refines the position between the
//! scanned ones: the stop candidate's position must land at most three quarters as far from the
//! truth as the nearest scanned position (without the refinement it is a scanned position). Not
//! on the truth: on smoothed states a contact's acceleration spike is spread over the smoothing
//! window, which pulls the equation error's best position inward the stiffer the contact is
//! (after `refit`, the facade re-scans a stop by T-F-S for that reason).

mod common;

use common::*;
use tfs_diagnose::{Catalogue, DiagnoseOptions, explain, refit};

/// The smallest and largest value of `x`.
fn range(x: &[f64]) -> (f64, f64) {
    x.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// The range of the motion of the three training sweeps of `truth` (noise-free; the diagnosis
/// reads it from the smoothed states): the range the scan sees.
fn scanned_range(truth: &Truth, sweep: (f64, f64, f64)) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..3 {
        let a = sweep.2 * (0.8 + 0.2 * i as f64);
        let (_, x) = clean(truth, sweep.0, sweep.1, a, 30.0, 0.01);
        let (l, h) = range(&x);
        (lo, hi) = (lo.min(l), hi.max(h));
    }
    (lo, hi)
}

/// A Duffing oscillator with a contact spring of stiffness `k_share` × the linear one, placed a
/// share `r_at` of the span in from the lower extreme of the motion it leaves (found by fixed
/// point: the stop shortens the motion it bounds); 40 dB records.
fn check(label: &str, amp: f64, k_share: f64, r_at: f64, seed: u64) {
    let base = Truth {
        restoring: duffing_restoring(),
        damping: 0.63,
        hidden: vec![],
        x0: 0.0,
    };
    let sweep = (0.3, 3.0, amp);
    let k = -k_share * duffing_restoring()[0].1;
    let with_stop = |at: f64| Truth {
        hidden: vec![Hidden::Stop { k, at }],
        ..base.clone()
    };
    let (lo0, hi0) = scanned_range(&base, sweep);
    let mut at = lo0 + r_at * (hi0 - lo0);
    for _ in 0..6 {
        let (l, h) = scanned_range(&with_stop(at), sweep);
        at = l + r_at * (h - l);
    }
    let truth = with_stop(at);
    let (lo, hi) = scanned_range(&truth, sweep);
    let span = hi - lo;
    let grid_gap = [0.01, 0.02, 0.05, 0.1, 0.2]
        .iter()
        .map(|r| (lo + r * span - at).abs())
        .fold(f64::INFINITY, f64::min);
    assert!(
        grid_gap >= 0.02 * span,
        "{label}: the stop at {at:.4} lies within {grid_gap:.4} of a scanned position (span {span:.4}); the case does not test the refinement"
    );
    let (train, _) = train_and_test(&truth, sweep, seed);
    let opts = DiagnoseOptions::default();
    let start = refit(&structure("x, x^3, x', xb_acc"), &train, &opts).unwrap();
    let ex = explain(&start, &train, &Catalogue::standard(7), &opts).unwrap();
    let stop = ex
        .ranked
        .iter()
        .find(|r| r.name == "stop")
        .expect("the stop is scanned");
    let found = stop.parameter.as_ref().map_or(f64::NAN, |p| p.1);
    println!(
        "{label}: stop at {at:.4} (range {lo:.4}..{hi:.4}, nearest scanned {grid_gap:.4} away), found {found:.4}; ranked first: {} ({})",
        ex.ranked[0].name, ex.verdict
    );
    assert!(
        (found - at).abs() <= 0.75 * grid_gap,
        "{label}: position {found:.4} vs truth {at:.4}; the nearest scanned position is {grid_gap:.4} away"
    );
    assert_eq!(ex.ranked[0].name, "stop", "{label}: {}", ex.verdict);
}

#[test]
fn a_stop_between_the_scanned_positions_is_placed_between_them() {
    check("soft, 15 % in", 4.0, 1.0, 0.15, 10);
    check("stiffer, 7.5 % in", 3.0, 3.0, 0.075, 40);
}
