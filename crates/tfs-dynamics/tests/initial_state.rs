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

/// A model that blows up within the fit horizon (here `x'' = 25 x`, unstable from any start)
/// still gets a fitted start from a shorter stretch, not the first samples' noisy velocity:
/// the simulation then fails where the model does, not a few samples in.
#[test]
fn a_model_that_blows_up_still_starts_from_a_fitted_state() {
    use tfs_dynamics::{Dopri5, FnSystem, SampledInput, choose_initial_state, fit_horizon};
    let sys = FnSystem::new(
        1,
        0,
        |_t, x: &[f64], _v: &[f64], _u: &[f64], a: &mut [f64]| {
            a[0] = 25.0 * x[0];
        },
    );
    let dt = 0.01;
    let n = 4000;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    // The truth from x = 1, v = 0 is cosh(5 t) (the record saturates at 1e9, where a sensor
    // would clip; the simulation counts as blown up at 1e6, after ≈ 2.9 s).
    let clean: Vec<f64> = t.iter().map(|&s| (5.0 * s).cosh().min(1e9)).collect();
    let y: Vec<f64> = clean
        .iter()
        .enumerate()
        .map(|(k, c)| c + 0.02 * if k % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let measured = [&y[..]];
    // The horizon (n/10 samples = 4 s) reaches far past where the model blows up (≈ 2.9 s).
    assert!(fit_horizon(&measured, 2.0) as f64 * dt > 3.0);
    let input = SampledInput::zero(0);
    let first_v = tfs_dynamics::initial_velocity(&y, dt, 5).unwrap();
    let (x0, v0) = choose_initial_state(
        InitialState::default(),
        &sys,
        &Dopri5::default(),
        &input,
        &measured,
        &t,
        vec![y[0]],
        vec![first_v],
    )
    .unwrap();
    assert!(
        (x0[0] - 1.0).abs() < 0.01 && v0[0].abs() < 0.1,
        "start ({}, {}) against the truth (1, 0); the first samples gave velocity {first_v}",
        x0[0],
        v0[0]
    );
}

/// A record is simulated on its own clock: the same samples with the time column shifted by
/// 10⁶ s (absolute time stamps) give the same motion (to rounding of the shifted times
/// themselves), at the record's own times, in about the same number of steps.
#[test]
fn a_time_column_shifted_by_a_million_seconds_simulates_the_same() {
    let (_, rec) = record(40.0, 3);
    let shifted = Record::new(
        "shifted",
        rec.t().iter().map(|t| t + 1e6).collect(),
        vec![
            ("x".into(), rec.column("x").unwrap().to_vec()),
            ("u".into(), rec.column("u").unwrap().to_vec()),
        ],
    )
    .unwrap();
    let opts = SimulateOptions::default();
    let a = simulate_model_on_record(&duffing(), &rec, &opts).unwrap();
    let b = simulate_model_on_record(&duffing(), &shifted, &opts).unwrap();
    assert_eq!(b.t, shifted.t());
    let scale = a.x[0].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let worst = a.x[0]
        .iter()
        .zip(&b.x[0])
        .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
    assert!(
        worst <= 1e-6 * scale,
        "largest difference {worst:e} of {scale:e}"
    );
    assert!(
        b.stats.steps <= 2 * a.stats.steps + 10,
        "{} steps shifted against {}",
        b.stats.steps,
        a.stats.steps
    );
}

/// An integrator that runs every trial to its end: Dormand–Prince without its early stop
/// (`Integrator::integrate_until`'s default, the whole run then the question).
struct WholeRuns(tfs_dynamics::Dopri5);

impl tfs_dynamics::Integrator for WholeRuns {
    fn integrate<S: tfs_dynamics::SecondOrderSystem + ?Sized>(
        &self,
        sys: &S,
        input: &tfs_dynamics::SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
    ) -> tfs_dynamics::Result<tfs_dynamics::Trajectory> {
        self.0.integrate(sys, input, x0, v0, t_out)
    }
}

/// The start-state fit gives up a trial step once its misfit is sure to exceed the current one,
/// and so ends exactly where the fit that simulates every trial to its end does (the same
/// start and cost to the bit) with fewer evaluations of the model.
#[test]
fn trial_steps_stop_early_with_the_same_fit() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use tfs_dynamics::{Dopri5, FnSystem, SampledInput, fit_initial_state};
    let (_, rec) = record(30.0, 3);
    let n = 120;
    let t = &rec.t()[..n];
    let u = rec.column("u").unwrap().to_vec();
    let input = SampledInput::new(0.0, rec.dt(), vec![u]).unwrap();
    let evals = AtomicUsize::new(0);
    let sys = FnSystem::new(
        1,
        1,
        |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
            evals.fetch_add(1, Ordering::Relaxed);
            a[0] = x[0] - x[0] * x[0] * x[0] - 0.3 * v[0] + u[0];
        },
    );
    let measured = [&rec.column("x").unwrap()[..n]];
    // A start in the other well: some trial steps overshoot and are rejected.
    let fit = |early: bool| {
        evals.store(0, Ordering::Relaxed);
        let f = if early {
            fit_initial_state(
                &sys,
                &Dopri5::default(),
                &input,
                &measured,
                t,
                &[-1.0],
                &[0.0],
            )
        } else {
            let whole = WholeRuns(Dopri5::default());
            fit_initial_state(&sys, &whole, &input, &measured, t, &[-1.0], &[0.0])
        };
        (f.unwrap(), evals.load(Ordering::Relaxed))
    };
    let (early, early_evals) = fit(true);
    let (whole, whole_evals) = fit(false);
    assert_eq!(early.x0[0].to_bits(), whole.x0[0].to_bits());
    assert_eq!(early.v0[0].to_bits(), whole.v0[0].to_bits());
    assert_eq!(early.cost.to_bits(), whole.cost.to_bits());
    assert!(early.cost < 0.1 * early.cost_start, "{early:?}");
    assert!(
        early_evals < whole_evals,
        "{early_evals} evaluations with early stops, {whole_evals} without"
    );
}

/// `integrate_until` gives `integrate`'s samples bit for bit up to where it is told to stop.
#[test]
fn integrate_until_follows_integrate_to_the_stop() {
    use tfs_dynamics::{Dopri5, FnSystem, Integrator, SampledInput};
    let (_, rec) = record(30.0, 1);
    let u = rec.column("u").unwrap().to_vec();
    let input = SampledInput::new(0.0, rec.dt(), vec![u]).unwrap();
    let sys = FnSystem::new(
        1,
        1,
        |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
            a[0] = x[0] - x[0] * x[0] * x[0] - 0.3 * v[0] + u[0];
        },
    );
    let t = &rec.t()[..300];
    let d = Dopri5::default();
    let whole = d.integrate(&sys, &input, &[0.9], &[0.1], t).unwrap();
    let all = d
        .integrate_until(&sys, &input, &[0.9], &[0.1], t, |_, _| true)
        .unwrap()
        .unwrap();
    assert_eq!(all, whole);
    let mut seen = Vec::new();
    let stopped = d
        .integrate_until(&sys, &input, &[0.9], &[0.1], t, |k, x| {
            seen.push(x[0]);
            k < 150
        })
        .unwrap();
    assert!(stopped.is_none());
    assert_eq!(seen.len(), 151);
    for (k, x) in seen.iter().enumerate() {
        assert_eq!(x.to_bits(), whole.x[0][k].to_bits(), "sample {k}");
    }
}

/// Counts the runs an integrator is asked for (whole or stopped early).
struct Counted<'a>(tfs_dynamics::Dopri5, &'a std::sync::atomic::AtomicUsize);

impl tfs_dynamics::Integrator for Counted<'_> {
    fn integrate<S: tfs_dynamics::SecondOrderSystem + ?Sized>(
        &self,
        sys: &S,
        input: &tfs_dynamics::SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
    ) -> tfs_dynamics::Result<tfs_dynamics::Trajectory> {
        self.1.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.0.integrate(sys, input, x0, v0, t_out)
    }

    fn integrate_until<
        S: tfs_dynamics::SecondOrderSystem + ?Sized,
        F: FnMut(usize, &[f64]) -> bool,
    >(
        &self,
        sys: &S,
        input: &tfs_dynamics::SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
        keep_going: F,
    ) -> tfs_dynamics::Result<Option<tfs_dynamics::Trajectory>> {
        self.1.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.0
            .integrate_until(sys, input, x0, v0, t_out, keep_going)
    }
}

/// A wrong model's start-state fit (the residuals as large as the motion, as in every
/// diagnosis of a model that misses an effect) ends at its minimum in few runs: no start within
/// a thousandth of the motion's scale fits better by more than the fit's end share of the cost
/// (√ε, MINPACK's relative tolerance), and each fit takes at most 40 runs for its
/// two unknowns (Marquardt's damping ladder took 37–194 on these models, zigzagging across the
/// valley, and one of them stopped at the iteration limit short of the minimum).
#[test]
fn wrong_models_fit_to_their_minimum_in_few_runs() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use tfs_dynamics::{
        Dopri5, FnSystem, Integrator, SampledInput, fit_horizon, fit_initial_state,
    };
    let (_, rec) = record(40.0, 5);
    let x = rec.column("x").unwrap();
    let n = fit_horizon(&[x], 2.0);
    let t = &rec.t()[..n];
    let u = rec.column("u").unwrap().to_vec();
    let input = SampledInput::new(0.0, rec.dt(), vec![u]).unwrap();
    let measured = &x[..n];
    let mean = measured.iter().sum::<f64>() / n as f64;
    let sd = (measured.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
    let sv = sd * std::f64::consts::TAU / (t[n - 1] - t[0]);
    // Stiffness, cubic, damping and input gain of the double well's equation, each model off
    // in one or more of them.
    let models = [
        (0.6, -1.0, -0.3, 1.0),
        (1.0, -1.4, -0.05, 1.0),
        (1.5, -1.0, -0.8, 1.0),
        (1.0, -1.0, -0.3, 2.5),
        (0.3, -0.5, -0.1, 0.5),
        (1.2, -0.8, -0.6, 1.5),
    ];
    for (k1, k3, c, g) in models {
        let sys = FnSystem::new(
            1,
            1,
            move |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
                a[0] = k1 * x[0] + k3 * x[0] * x[0] * x[0] + c * v[0] + g * u[0];
            },
        );
        let runs = AtomicUsize::new(0);
        let counted = Counted(Dopri5::default(), &runs);
        let f = fit_initial_state(&sys, &counted, &input, &[measured], t, &[x[0]], &[0.0]).unwrap();
        let runs = runs.load(Ordering::Relaxed);
        let cost = |x0: f64, v0: f64| {
            let tr = Dopri5::default()
                .integrate(&sys, &input, &[x0], &[v0], t)
                .unwrap();
            tr.x[0]
                .iter()
                .zip(measured)
                .map(|(a, b)| ((a - b) / sd).powi(2))
                .sum::<f64>()
                / n as f64
        };
        assert!(
            f.cost > 1.0,
            "model ({k1}, {k3}, {c}, {g}) is not wrong enough: {f:?}"
        );
        let (x0, v0) = (f.x0[0], f.v0[0]);
        for (dx, dv) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)] {
            let near = cost(x0 + 1e-3 * sd * dx, v0 + 1e-3 * sv * dv);
            assert!(
                near >= f.cost * (1.0 - f64::EPSILON.sqrt()),
                "model ({k1}, {k3}, {c}, {g}): the start ({dx}, {dv})·1e-3 away fits better, {near:.10e} < {:.10e}",
                f.cost
            );
        }
        assert!(runs <= 40, "model ({k1}, {k3}, {c}, {g}): {runs} runs");
    }
}

/// The double well's equation with stiffness `k1`, cubic `k3`, damping `c` and input gain `g`.
fn well(k1: f64, k3: f64, c: f64, g: f64) -> impl tfs_dynamics::SecondOrderSystem {
    tfs_dynamics::FnSystem::new(
        1,
        1,
        move |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
            a[0] = k1 * x[0] + k3 * x[0] * x[0] * x[0] + c * v[0] + g * u[0];
        },
    )
}

/// The start of `sys` on `rec` (displacement `x`, input `u`) by the default two cold fits from
/// `first` and warmed by `warm` ([`tfs_dynamics::warm_initial_state`]), each with the runs it took.
#[allow(clippy::type_complexity)]
fn cold_and_warm(
    sys: &impl tfs_dynamics::SecondOrderSystem,
    rec: &Record,
    first: &(Vec<f64>, Vec<f64>),
    warm: (&[f64], &[f64]),
) -> (((Vec<f64>, Vec<f64>), usize), ((Vec<f64>, Vec<f64>), usize)) {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use tfs_dynamics::{Dopri5, SampledInput, choose_initial_state, warm_initial_state};
    let (t, x) = (rec.t(), rec.column("x").unwrap());
    let input = SampledInput::new(0.0, rec.dt(), vec![rec.column("u").unwrap().to_vec()]).unwrap();
    let how = InitialState::default();
    let (cold_runs, warm_runs) = (AtomicUsize::new(0), AtomicUsize::new(0));
    let cold = choose_initial_state(
        how,
        sys,
        &Counted(Dopri5::default(), &cold_runs),
        &input,
        &[x],
        t,
        first.0.clone(),
        first.1.clone(),
    )
    .unwrap();
    let warmed = warm_initial_state(
        how,
        sys,
        &Counted(Dopri5::default(), &warm_runs),
        &input,
        &[x],
        t,
        first.clone(),
        warm,
    )
    .unwrap();
    (
        (cold, cold_runs.load(Ordering::Relaxed)),
        (warmed, warm_runs.load(Ordering::Relaxed)),
    )
}

/// A start-state fit warmed by a near model's fitted start (the double well's own equation;
/// the fitted models are refits of it, off by 10–20 % in one or more coefficients, as a
/// candidate's refit or a fold model is) ends where the two cold fits end: the same misfit to
/// a few parts in a million (each ends once an iteration removes less than √ε of it) and the
/// same state to the fit's precision, from one fit instead of two, so in fewer runs.
#[test]
fn a_warm_fit_reaches_the_cold_optimum_in_fewer_runs() {
    use tfs_dynamics::{
        Dopri5, Integrator, SampledInput, choose_initial_state, fit_horizon, initial_velocity,
    };
    let (_, rec) = record(40.0, 2);
    let (t, x) = (rec.t(), rec.column("x").unwrap());
    let input = SampledInput::new(0.0, rec.dt(), vec![rec.column("u").unwrap().to_vec()]).unwrap();
    let how = InitialState::default();
    let first = (vec![x[0]], vec![initial_velocity(x, rec.dt(), 5).unwrap()]);
    let (xn, vn) = choose_initial_state(
        how,
        &well(1.0, -1.0, -0.3, 1.0),
        &Dopri5::default(),
        &input,
        &[x],
        t,
        first.0.clone(),
        first.1.clone(),
    )
    .unwrap();
    let n = fit_horizon(&[x], 2.0);
    for (k1, k3, c, g) in [
        (1.1, -1.0, -0.3, 1.0),
        (1.0, -0.85, -0.35, 1.0),
        (0.9, -1.1, -0.25, 1.15),
    ] {
        let sys = well(k1, k3, c, g);
        let ((cold, cr), (warm, wr)) = cold_and_warm(&sys, &rec, &first, (&xn, &vn));
        let misfit = |(x0, v0): &(Vec<f64>, Vec<f64>)| {
            let tr = Dopri5::default()
                .integrate(&sys, &input, x0, v0, &t[..n])
                .unwrap();
            tr.x[0]
                .iter()
                .zip(x)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
        };
        let (mc, mw) = (misfit(&cold), misfit(&warm));
        let what = format!("model ({k1}, {k3}, {c}, {g})");
        assert!(
            (mw - mc).abs() < 1e-5 * mc,
            "{what}: misfit {mw} against {mc}"
        );
        assert!(
            (warm.0[0] - cold.0[0]).abs() < 1e-4,
            "{what}: {warm:?} against {cold:?}"
        );
        assert!(
            (warm.1[0] - cold.1[0]).abs() < 1e-3,
            "{what}: {warm:?} against {cold:?}"
        );
        assert!(wr < cr, "{what}: {wr} runs warm against {cr} cold");
    }
}

/// A warm start the model cannot be fitted from gives way to the two cold fits, which decide
/// as if there had been no warm start (the same state to the bit, after the warm attempt's
/// runs): from a start a softening spring escapes from (it blows up at once: one run), and
/// from a start in the other well of the double well, whose fit settles there, above the
/// misfit the record's own start already has (the fit, then a run of the stretch from each
/// cold start, the first given up at the warm fit's misfit).
#[test]
fn a_warm_start_that_fails_falls_back_to_the_cold_fits() {
    use tfs_dynamics::initial_velocity;
    let (_, rec) = record(40.0, 4);
    let x = rec.column("x").unwrap();
    let first = (vec![x[0]], vec![initial_velocity(x, rec.dt(), 5).unwrap()]);
    // Stiffness 2 softened by a cubic: a barrier at |x| = 2, which the record's motion about
    // +1 stays inside; from x = 5 the run escapes in finite time. The double well itself,
    // started in its other well at -1.
    let cases = [
        ("escape", well(-2.0, 0.5, -0.3, 1.0), [5.0, 0.0]),
        ("other well", well(1.0, -1.0, -0.3, 1.0), [-1.0, 0.0]),
    ];
    for (what, sys, start) in cases {
        let ((cold, cr), (warm, wr)) =
            cold_and_warm(&sys, &rec, &first, (&start[..1], &start[1..]));
        assert!(
            cold.0[0] > 0.0 && cold.0[0] != first.0[0],
            "{what}: {cold:?}"
        );
        assert_eq!(warm.0[0].to_bits(), cold.0[0].to_bits(), "{what}");
        assert_eq!(warm.1[0].to_bits(), cold.1[0].to_bits(), "{what}");
        assert!(wr > cr, "{what}: {wr} runs warm against {cr} cold");
        if what == "escape" {
            assert_eq!(
                wr,
                cr + 1,
                "{what}: the warm fit's one run, then the cold fits'"
            );
        }
    }
}
