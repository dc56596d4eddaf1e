//! Unit tests of the judges: vetoes and ties.

use super::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Exp1};

/// Pieces of chaotic prediction error: heavy-tailed (exponential) around `scale`, per
/// piece one shared draw (the piece's own difficulty) times a model factor.
fn pieces(n: usize, factor: f64, noise: f64, seed: u64) -> (Heldout, Heldout) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for _ in 0..n {
        let hard: f64 = Exp1.sample(&mut rng);
        let ea: f64 = Exp1.sample(&mut rng);
        let eb: f64 = Exp1.sample(&mut rng);
        a.push(hard * (1.0 + noise * ea));
        b.push(factor * hard * (1.0 + noise * eb));
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    (
        Heldout {
            mean: mean(&a),
            parts: a,
        },
        Heldout {
            mean: mean(&b),
            parts: b,
        },
    )
}

#[test]
fn short_horizon_vetoes_only_a_worsening_the_pieces_bear_out() {
    // The same model quality, noisy pieces: a higher mean by chance is not a veto. Over 40
    // draws at alpha 0.01 (two looks), at most a few may say "worse" (expected 0.8).
    let vetoed = (0..40)
        .filter(|s| {
            let (before, after) = pieces(60, 1.0, 1.0, *s);
            predicts_worse(Judge::ShortHorizon, &before, &after, 0.0, 0.01)
        })
        .count();
    assert!(vetoed <= 4, "{vetoed} of 40 equal models vetoed");
    // The mean comparison the judge used before vetoes about half of them.
    let by_mean = (0..40)
        .filter(|s| {
            let (before, after) = pieces(60, 1.0, 1.0, *s);
            after.mean >= before.mean
        })
        .count();
    assert!(by_mean >= 10, "{by_mean}");
    // A model twice as wrong on every piece is vetoed.
    let (before, after) = pieces(60, 2.0, 0.3, 7);
    assert!(predicts_worse(
        Judge::ShortHorizon,
        &before,
        &after,
        0.0,
        0.01
    ));
    assert!(!predicts_worse(
        Judge::ShortHorizon,
        &after,
        &before,
        0.0,
        0.01
    ));
}

#[test]
fn free_run_vetoes_only_beyond_its_resolution() {
    let score = |mean: f64| Heldout {
        mean,
        parts: vec![mean],
    };
    // Within what a fresh draw of the input's noise moves the score: no veto.
    assert!(!predicts_worse(
        Judge::FreeRun,
        &score(0.70),
        &score(0.96),
        0.4,
        0.01
    ));
    // Beyond it, or with a judge that resolves everything: vetoed.
    assert!(predicts_worse(
        Judge::FreeRun,
        &score(0.70),
        &score(1.2),
        0.4,
        0.01
    ));
    assert!(predicts_worse(
        Judge::FreeRun,
        &score(0.70),
        &score(0.71),
        0.0,
        0.01
    ));
    // Two free runs without skill (both worse than the mean position): no veto, however
    // far apart; a run that loses the start model's skill is still vetoed.
    assert!(!predicts_worse(
        Judge::FreeRun,
        &score(3.46),
        &score(5.42),
        0.0,
        0.01
    ));
    assert!(predicts_worse(
        Judge::FreeRun,
        &score(0.99),
        &score(5.42),
        0.0,
        0.01
    ));
    // The equation error vetoes nothing.
    assert!(!predicts_worse(
        Judge::EquationError,
        &score(0.1),
        &score(9.0),
        0.0,
        0.01
    ));
}

#[test]
fn a_tie_goes_to_the_model_better_on_most_pieces_not_to_the_one_lucky_in_the_worst() {
    // Over 40 draws of 36 heavy-tailed pieces: model `b` errs half as much as `a` on every
    // piece, but loses the motion on one piece where `a` keeps it (50 times its usual error;
    // the mean over the pieces then favours `a`). The geometric mean picks `b` every time.
    let mut mean_picks_a = 0;
    for seed in 0..40 {
        let (a, mut b) = pieces(36, 0.5, 0.3, seed);
        b.parts[7] = 50.0 * a.parts.iter().sum::<f64>();
        let pick = lowest_geometric_mean(&[&a.parts, &b.parts]);
        assert_eq!(pick, Some(1), "draw {seed}");
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        mean_picks_a += usize::from(mean(&a.parts) < mean(&b.parts));
    }
    assert_eq!(mean_picks_a, 40, "the worst piece should dominate the mean");
    assert_eq!(lowest_geometric_mean(&[]), None);
}
