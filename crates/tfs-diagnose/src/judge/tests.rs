//! Unit tests of the judges: vetoes, ties, and where the free run starts.

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

/// Most of a model's error is read above the noise's floor. At 40 dB the measured record's
/// noise alone leaves an R-MSE of about 1e-4 to any model, the true one included; a start model
/// at 3.75e-4 whose refit with the missing effect reaches 1.28e-4 (a Duffing oscillator with a
/// hidden Maxwell element of 1.2 % of the force) takes away 91 % of its own error, yet only 42 %
/// of the RMS of the whole, noise included, and 1.0 % of the motion's RMS: read on the whole
/// R-MSE it is neither large on the motion nor most of the error. A model that only fits the
/// noise, already at the floor, gains nothing above it.
#[test]
fn most_of_the_error_is_read_above_the_noise_floor() {
    let score = |mean: f64| Heldout {
        mean,
        parts: vec![mean],
    };
    let better = |b: f64, a: f64, floor: f64| {
        predicts_better_by(
            Judge::FreeRun,
            (&score(b), &score(a)),
            (0.0, floor),
            0.01,
            0.02,
        )
    };
    assert!(better(3.75e-4, 1.28e-4, 0.0).is_none());
    let drop = better(3.75e-4, 1.28e-4, 1.0e-4).expect("most of the model's own error");
    assert!((drop - ((2.75e-4f64).sqrt() - (0.28e-4f64).sqrt())).abs() < 1e-15);
    // Less than half of the model's own error taken away is not most of it.
    assert!(better(3.75e-4, 2.5e-4, 1.0e-4).is_none());
    // At or below the floor before: no error of the model's own to take away.
    assert!(better(1.0e-4, 0.9e-4, 1.0e-4).is_none());
    assert!(better(1.1e-4, 0.9e-4, 1.2e-4).is_none());
}

/// The floor of the free run: the displacement's measurement noise over its variance, which the
/// tool's noise estimate recovers from a record at 40 dB to within its own spread.
#[test]
fn the_measurement_floor_is_the_records_noise_share() {
    use tfs_data::Record;
    let model = Model::from_json_str(
        r#"{"format":"tfs-model/1","dofs":["x"],"inputs":["u"],"equations":[{"dof":"x","terms":[{"term":"x","coef":-39.5},{"term":"x'","coef":-0.6},{"term":"u","coef":1.0}]}]}"#,
    )
    .unwrap();
    let dt = 0.005;
    let n = 8000;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    let u: Vec<f64> = t
        .iter()
        .map(|t| (3.0 * t).sin() + (11.0 * t).sin())
        .collect();
    // A smooth motion (two tones), measured with white noise at 40 dB.
    let clean: Vec<f64> = t
        .iter()
        .map(|t| 0.3 * (3.0 * t).sin() + 0.05 * (11.0 * t).sin())
        .collect();
    let x =
        tfs_signal::noise::add_noise_seeded(&clean, 40.0, tfs_signal::NoiseKind::White, 3).unwrap();
    let rec = Record::new("r", t, vec![("x".to_string(), x), ("u".to_string(), u)]).unwrap();
    let opts = DiagnoseOptions::default();
    let states = vec![RecordStates::new(&model, &rec, &opts).unwrap()];
    let floor = measurement_floor(&model, &states);
    // 40 dB: noise variance 1e-4 of the signal's.
    assert!(floor > 0.5e-4 && floor < 2.0e-4, "floor {floor}");
}

/// An effect is large on the motion when its model's RMS prediction error is lower by at least
/// `min_share` of the motion's RMS, or by at least half of the error itself, beyond what the
/// judge resolves.
#[test]
fn a_small_force_counts_when_the_prediction_falls_by_min_share_or_by_half() {
    let score = |mean: f64| Heldout {
        mean,
        parts: vec![mean],
    };
    let better = |j, b: f64, a: f64, res| {
        predicts_better_by(j, (&score(b), &score(a)), (res, 0.0), 0.01, 0.02).is_some()
    };
    // √0.0468 − √0.00685 = 0.134: large; √0.0468 − √0.0420 = 0.011: under 2 %.
    assert!(better(Judge::FreeRun, 0.0468, 0.00685, 0.0));
    assert!(!better(Judge::FreeRun, 0.0468, 0.0420, 0.0));
    // A drop within the free run's resolution, or to a run without skill, is not evidence.
    assert!(!better(Judge::FreeRun, 0.0468, 0.00685, 0.05));
    assert!(!better(Judge::FreeRun, 4.0, 1.2, 0.0));
    // Worse is never better; the equation error judges nothing.
    assert!(!better(Judge::FreeRun, 0.00685, 0.0468, 0.0));
    assert!(!better(Judge::EquationError, 0.0468, 0.00685, 0.0));
    // The drop itself is returned: √0.0468 − √0.00685.
    let drop = predicts_better_by(
        Judge::FreeRun,
        (&score(0.0468), &score(0.00685)),
        (0.0, 0.0),
        0.01,
        0.02,
    );
    assert!((drop.unwrap() - (0.0468f64.sqrt() - 0.00685f64.sqrt())).abs() < 1e-15);
    // Under `min_share`, a drop to at most half the RMS prediction error is most of what a
    // close model misses: √1e-4 − √1e-6 = 0.009 counts, √1e-4 − √0.5e-4 = 0.0029 does not.
    assert!(better(Judge::FreeRun, 1e-4, 1e-6, 0.0));
    assert!(!better(Judge::FreeRun, 1e-4, 0.5e-4, 0.0));
    assert!(!better(Judge::FreeRun, 1e-4, 1e-6, 2e-4));
    // Short horizon: the pieces must bear the drop out, and it must be large enough.
    let short = |(b, a): &(Heldout, Heldout), min_share| {
        predicts_better_by(Judge::ShortHorizon, (b, a), (0.0, 0.0), 0.01, min_share).is_some()
    };
    let (before, after) = pieces(60, 0.3, 0.3, 7);
    assert!(short(&(before.clone(), after.clone()), 0.02));
    assert!(!short(&(after, before), 0.02));
    assert!(!short(&pieces(60, 1.0, 1.0, 3), 0.0));
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

/// A damped linear oscillator `x'' = −k x − c x' + u` under `u = f sin(Ωt)`, released from
/// `x0` at rest (closed form), sampled at 100 Hz for 30 s, as a record of `x` and `xb_acc`.
fn released(name: &str, x0: f64, f: f64) -> tfs_data::Record {
    let (w, zeta, big_w) = (std::f64::consts::TAU, 0.25, 0.6 * std::f64::consts::TAU);
    let (k, c) = (w * w, 2.0 * zeta * w);
    let d = (k - big_w * big_w).powi(2) + (c * big_w).powi(2);
    let (a, b) = (f * (k - big_w * big_w) / d, -f * c * big_w / d);
    let wd = w * (1.0 - zeta * zeta).sqrt();
    let c1 = x0 - b;
    let c2 = (zeta * w * c1 - a * big_w) / wd;
    let t: Vec<f64> = (0..3001).map(|i| i as f64 * 0.01).collect();
    let x = t
        .iter()
        .map(|&t| {
            (-zeta * w * t).exp() * (c1 * (wd * t).cos() + c2 * (wd * t).sin())
                + a * (big_w * t).sin()
                + b * (big_w * t).cos()
        })
        .collect();
    let u = t.iter().map(|&t| f * (big_w * t).sin()).collect();
    tfs_data::Record::new(
        name,
        t,
        vec![("x".to_string(), x), ("xb_acc".to_string(), u)],
    )
    .unwrap()
}

/// The two released records, their smoothed states for `model` (2 Hz cut-off) and their layout.
fn released_setup(
    model: &Model,
) -> (
    Vec<tfs_data::Record>,
    Vec<RecordStates>,
    Layout,
    DiagnoseOptions,
) {
    let opts = DiagnoseOptions {
        cutoff_hz: Some(2.0),
        ..Default::default()
    };
    let records = vec![released("a", 2.5, 8.0), released("b", -2.2, 9.0)];
    let states: Vec<RecordStates> = records
        .iter()
        .map(|r| RecordStates::new(model, r, &opts).unwrap())
        .collect();
    let layout = Layout::new(&states, &opts).unwrap();
    (records, states, layout, opts)
}

/// The judge `judge`, resolving every difference, simulating from the records' start
/// unless `from_fitted_rows`.
fn choice_of(judge: Judge, from_fitted_rows: bool) -> Choice {
    Choice {
        judge,
        why: String::new(),
        plain: false,
        resolution: 0.0,
        floor: 0.0,
        from_fitted_rows,
    }
}

#[test]
fn the_free_run_from_the_fitted_rows_scores_what_the_equations_were_fitted_on() {
    // Released from 2.5 and 2.2 (a transient that has decayed below 0.25 by the end of the
    // 1.5 s smoothing margin at a 2 Hz cut-off), then a steady response of about 0.3. The model
    // is the truth with a softening x^3 that is harmless below 0.3 but has its barrier at
    // 1.41: simulated from t = 0 it starts beyond the barrier and runs away (or, where its
    // initial-state fit settles inside the barrier, misses the transient). Over the fitted
    // rows alone, from the measured state there, the free run scores what the equation error
    // was fitted on.
    let k = std::f64::consts::TAU.powi(2);
    let c = 0.5 * std::f64::consts::TAU;
    let lib = tfs_library::Library::parse("x, x^3, x', xb_acc", &["x"]).unwrap();
    let model = Model::from_coefficients(&lib, &[vec![-k, 0.5 * k, -c, 1.0]], "test").unwrap();
    let (records, states, layout, opts) = released_setup(&model);
    assert!(states.iter().all(|s| s.margin == 150));
    let choice = |from_fitted_rows| choice_of(Judge::FreeRun, from_fitted_rows);
    // From t = 0 the first record's run is lost, and with it the score.
    let from_start = heldout_error(&choice(false), &model, &[], &states, &layout, &opts, 0);
    assert_eq!(from_start, None);
    let h = heldout_error(&choice(true), &model, &[], &states, &layout, &opts, 0)
        .expect("the held-out rows can be simulated");
    assert_eq!(h.parts.len(), 2);
    assert!(h.mean < 0.05, "held-out free-run R-MSE {}", h.mean);
    // Each record is its own fold (part r is record r's).
    for (r, part) in records.iter().zip(&h.parts) {
        let from_start = crate::simulate::r_mse(&model, r);
        println!(
            "{}: fitted rows {part:.3e}, from t = 0 {from_start:?}",
            r.source()
        );
        assert!(
            from_start.as_ref().map_or(true, |e| *e > 4.0 * part),
            "{}: a run from t = 0 should lose the record: {from_start:?}",
            r.source()
        );
    }
}

#[test]
fn a_prediction_that_leaves_the_records_range_far_behind_fails() {
    // Truth `x'' = −k x − c x' + u`; the other model has the linear spring's sign flipped and a
    // cubic spring that holds the motion at wells near ±500, far outside every record: every
    // run of it on a record stops as having left the record's range (the simulation's own
    // band), tied or not, and the judge scores it as failed; the truth stays in range.
    let (k, c) = (std::f64::consts::TAU.powi(2), 0.5 * std::f64::consts::TAU);
    let lib = tfs_library::Library::parse("x, x^3, x', xb_acc", &["x"]).unwrap();
    let mut truth = Model::from_coefficients(&lib, &[vec![-k, 0.0, -c, 1.0]], "test").unwrap();
    let mut away =
        Model::from_coefficients(&lib, &[vec![k, -k / 500f64.powi(2), -c, 1.0]], "test").unwrap();
    let (records, states, layout, opts) = released_setup(&truth);
    let judged = |judge, model: &Model| {
        heldout_error(
            &choice_of(judge, false),
            model,
            &[],
            &states,
            &layout,
            &opts,
            400,
        )
    };
    for r in &records {
        let e = crate::simulate::r_mse(&away, r).unwrap_err();
        assert!(
            matches!(
                e,
                crate::DiagnoseError::Dynamics(tfs_dynamics::DynError::LeftRange { .. })
            ),
            "{}: {e}",
            r.source()
        );
    }
    assert_eq!(judged(Judge::FreeRun, &away), None, "untied");
    let ties = serde_json::json!({"ties": [{"term": "x", "owner": "x", "partner": "x", "factor_in_partner": 1.0}]});
    away.trace = ties.clone();
    truth.trace = ties;
    assert!(crate::design::anchored(&away));
    for judge in [Judge::FreeRun, Judge::ShortHorizon] {
        assert_eq!(judged(judge, &away), None, "{judge:?}");
        let h = judged(judge, &truth).expect("the truth stays in range");
        assert!(h.mean < 0.05, "{judge:?}: {}", h.mean);
    }
}
