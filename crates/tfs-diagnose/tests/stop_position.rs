//! The judge simulates a stop at the positions `refit` would choose among: of the variants with
//! the lowest held-out equation residual, the one whose model predicts the held-out data best.

mod common;

use common::*;
use tfs_diagnose::effects::Stop;
use tfs_diagnose::{Catalogue, DiagnoseOptions, Effect, EffectContext, RankedEffect, Variant};
use tfs_diagnose::{explain, refit};

/// One variant of the catalogue's stop (the `k`-th of its scan), as an effect of its own.
struct OneStop(usize);

impl Effect for OneStop {
    fn name(&self) -> String {
        format!("stop-{}", self.0)
    }
    fn description(&self) -> String {
        "one position of the stop's scan".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        Stop.variants(ctx)
            .into_iter()
            .nth(self.0)
            .into_iter()
            .collect()
    }
}

/// A hardening oscillator with a soft stop (1.65× its linear stiffness) that the response runs
/// a little way into: the equation residual's best position lies inside the stop, and a position
/// nearer the truth predicts the motion better. The scanned stop reports, and is judged by, the
/// best-predicting of the three positions with the lowest held-out residual — each position
/// diagnosed on its own gives the same residual and prediction — not the residual's best.
#[test]
fn a_stop_is_judged_at_the_position_that_predicts_best_among_the_residuals_best() {
    let k = 1.5 * 4.0 * std::f64::consts::PI.powi(2);
    let truth = Truth {
        restoring: vec![(1, -k), (3, -2.0 * k)],
        damping: 0.53,
        hidden: vec![Hidden::Stop {
            k: 1.65 * k,
            at: -0.675,
        }],
        x0: 0.0,
    };
    let (train, _) = train_and_test(&truth, (0.3, 3.0, 6.0), 10);
    let opts = DiagnoseOptions::default();
    let start = refit(&structure("x, x^3, x', xb_acc"), &train, &opts).unwrap();
    let diagnose = |effect: Box<dyn Effect>| -> Option<RankedEffect> {
        let mut cat = Catalogue::empty();
        cat.register(effect).unwrap();
        let ex = explain(&start, &train, &cat, &opts).unwrap();
        ex.ranked.into_iter().next()
    };
    let scanned = diagnose(Box::new(Stop)).unwrap();
    // Each position alone, lowest held-out residual (largest drop) first; a position whose fit
    // pulls into its contact is no stop and is not ranked (the scan refuses it the same way).
    let mut each: Vec<RankedEffect> = (0..10)
        .filter_map(|i| diagnose(Box::new(OneStop(i))))
        .collect();
    assert!(each.len() >= 3, "at least three positions are stops");
    each.sort_by(|a, b| b.delta_heldout.total_cmp(&a.delta_heldout));
    let key = |r: &RankedEffect| r.r_mse_after.unwrap_or(f64::INFINITY);
    let shortlist = &each[..3];
    let best = shortlist
        .iter()
        .reduce(|a, b| if key(b) < key(a) { b } else { a })
        .unwrap();
    for r in &each {
        println!(
            "{:?}: drop {:.4}, free run {:?}",
            r.parameter, r.delta_heldout, r.r_mse_after
        );
    }
    println!("scanned: {:?} {:?}", scanned.parameter, scanned.r_mse_after);
    // The case exercises the choice: the residual's best is not the best predictor.
    assert_ne!(best.parameter, each[0].parameter);
    assert!(key(best) < key(&each[0]));
    assert_eq!(scanned.parameter, best.parameter, "{}", scanned.reason);
    assert_eq!(scanned.r_mse_after, best.r_mse_after);
    assert!(scanned.reason.contains("predicts the held-out data best"));
    // Its significance is the scan's: the residual's best drop.
    assert_eq!(scanned.delta_heldout, each[0].delta_heldout);
}
