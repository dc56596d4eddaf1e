//! The initial state of a simulation of noisy measurements: fitted to the start of the record
//! (default) against taken from the first samples.

use tfs_data::Record;
use tfs_dynamics::{InitialState, SimulateOptions, rmse_ratio, simulate_model_on_record};
use tfs_library::{Equation, Model, ModelTerm, Term};

/// Double-well Duffing `x'' = x − x³ − 0.3 x' + u`, wells at ±1.
fn duffing() -> Model {
    let dofs = ["x".to_string()];
    let t = |s: &str| Term::parse(s, &dofs).unwrap();
    Model::new(
        dofs.to_vec(),
        vec![Equation {
            dof: "x".into(),
            terms: vec![
                ModelTerm::new(t("x"), 1.0),
                ModelTerm::new(t("x^3"), -1.0),
                ModelTerm::new(t("x'"), -0.3),
                ModelTerm::new(t("u"), 1.0),
            ],
        }],
        "test",
    )
    .unwrap()
}

/// The true motion (rest in the well at +1, forced gently enough to stay there) and a record of
/// it with white noise at `snr_db` on the displacement.
fn record(snr_db: f64, seed: u64) -> (Vec<f64>, Record) {
    let dt = 0.05;
    let n = 2000;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    let u: Vec<f64> = t.iter().map(|t| 0.15 * (0.9 * t).sin()).collect();
    let start = Record::new(
        "gen",
        t.clone(),
        vec![("x".into(), vec![1.0; n]), ("u".into(), u.clone())],
    )
    .unwrap();
    let exact = SimulateOptions {
        initial_state: InitialState::FirstSamples,
        ..SimulateOptions::default()
    };
    // A constant displacement column starts the generator exactly at rest at x = 1.
    let clean = simulate_model_on_record(&duffing(), &start, &exact)
        .unwrap()
        .x[0]
        .clone();
    let x = tfs_signal::noise::add_noise_seeded(&clean, snr_db, tfs_signal::NoiseKind::White, seed)
        .unwrap();
    let rec = Record::new("noisy", t, vec![("x".into(), x), ("u".into(), u)]).unwrap();
    (clean, rec)
}

#[test]
fn fitted_start_tracks_the_truth_where_first_samples_do_not() {
    let mut worst_first = 0.0f64;
    for seed in 0..6 {
        let (clean, rec) = record(20.0, seed);
        let fitted =
            simulate_model_on_record(&duffing(), &rec, &SimulateOptions::default()).unwrap();
        let e_fit = rmse_ratio(&clean, &fitted.x[0]).unwrap();
        // The true model from a fitted start stays with the true motion (R-MSE of the
        // simulation against the noise-free displacement; the noise itself is 1 % in power).
        assert!(e_fit < 1e-3, "seed {seed}: fitted start R-MSE {e_fit}");
        let first = SimulateOptions {
            initial_state: InitialState::FirstSamples,
            ..SimulateOptions::default()
        };
        let e_first = simulate_model_on_record(&duffing(), &rec, &first)
            .map(|tr| rmse_ratio(&clean, &tr.x[0]).unwrap())
            .unwrap_or(f64::INFINITY);
        worst_first = worst_first.max(e_first);
    }
    // From the first samples, the velocity carries the noise times 1/dt, enough to throw the
    // model over the barrier into the other well in some of the draws.
    assert!(
        worst_first > 0.5,
        "first-samples start, worst R-MSE {worst_first}"
    );
}

#[test]
fn clean_records_keep_their_exact_start() {
    let (clean, rec) = record(300.0, 1);
    let tr = simulate_model_on_record(&duffing(), &rec, &SimulateOptions::default()).unwrap();
    assert!(rmse_ratio(&clean, &tr.x[0]).unwrap() < 1e-12);
}
