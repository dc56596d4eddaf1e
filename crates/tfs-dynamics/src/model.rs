//! Adapter from `tfs_library` models to this crate: simulate a fitted model on a measured record.

use crate::initial::{InitialState, choose_initial_state, start_of, warm_initial_state};
use crate::memo::{self, KeyHasher, StartKey};
use crate::range::{Ranged, range_band};
use crate::{
    Dopri5, DynError, Integrator, Result, SampledInput, SecondOrderSystem, Trajectory,
    rmse_variance,
};
use tfs_data::Record;
use tfs_library::{CompiledModel, Factor, Model, StateLaw};

impl SecondOrderSystem for CompiledModel {
    fn dofs(&self) -> usize {
        CompiledModel::system_dofs(self)
    }
    fn internal_states(&self) -> usize {
        CompiledModel::states(self)
    }
    fn inputs(&self) -> usize {
        CompiledModel::inputs(self)
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        CompiledModel::accel(self, x, v, u, a)
    }
    #[inline(always)]
    fn accel_lanes(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        CompiledModel::accel_lanes(self, x, v, u, a)
    }
}

/// A compiled model whose start-state fit takes its Jacobian from the variational equation
/// along each run ([`SecondOrderSystem::accel_jacobian`], [`CompiledModel::accel_jacobian`])
/// when the model is smooth ([`smooth`]); otherwise the fit takes differences of whole runs.
struct Differentiable<'a> {
    compiled: &'a CompiledModel,
    smooth: bool,
}

/// Whether `model`'s accelerations have a continuous derivative in the state, so that the
/// variational equation stepped from sample to sample gives its runs' sensitivities to the
/// fit's precision: no `sign(·)` (a jump: Coulomb friction), `|·|`, `below`/`above` (a kink:
/// a stop's contact, whose crossing between two samples the sampled Jacobians do not place)
/// and no Bouc–Wen or Dahl state (whose rates have `|q'|`). Powers, `tanh` and Maxwell
/// elements are smooth.
fn smooth(model: &Model) -> bool {
    model.equations.iter().flat_map(|e| &e.terms).all(|t| {
        t.term.factors().iter().all(|f| match f {
            Factor::Pow(..) | Factor::Tanh(..) => true,
            Factor::State(_, law) => matches!(law, StateLaw::Maxwell { .. }),
            Factor::Sign(_) | Factor::Abs(_) | Factor::Below(..) | Factor::Above(..) => false,
        })
    })
}

impl SecondOrderSystem for Differentiable<'_> {
    fn dofs(&self) -> usize {
        self.compiled.system_dofs()
    }
    fn internal_states(&self) -> usize {
        self.compiled.states()
    }
    fn inputs(&self) -> usize {
        self.compiled.inputs()
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        self.compiled.accel(x, v, u, a)
    }
    fn accel_jacobian(
        &self,
        _t: f64,
        x: &[f64],
        v: &[f64],
        u: &[f64],
        a: &mut [f64],
        ax: &mut [f64],
        av: &mut [f64],
    ) -> bool {
        if !self.smooth {
            return false;
        }
        self.compiled.accel_jacobian(x, v, u, a, ax, av);
        true
    }
}

/// Options of [`simulate_model_on_record`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulateOptions {
    /// The integrator (default: [`Dopri5::default`], rtol 1e-8, atol 1e-10).
    pub integrator: Dopri5,
    /// Samples used to estimate the initial velocity when the record has no velocity column
    /// (default 5; at least 2).
    pub velocity_window: usize,
    /// Take the initial velocity from the column `"<dof>'"` when the record has one (default true).
    pub use_velocity_column: bool,
    /// How the initial state is chosen (default [`InitialState::Fitted`] over two periods: the
    /// first-samples state, refined by fitting the model's response to the start of the record).
    pub initial_state: InitialState,
    /// How far a run may go past its record (default [`RANGE_SPANS`]): the run stops with
    /// [`DynError::LeftRange`] at the first sample where a measured displacement leaves the
    /// record's own span widened by this many spans on each side (a constant column, a
    /// generator's start at rest, bounds nothing). `None` lets it run on until it blows up or
    /// exhausts the integrator's step budget.
    pub range: Option<f64>,
}

/// Default [`SimulateOptions::range`]: three spans of the record on each side. A run that far
/// out has no skill on the record (while there, every sample's error is at least three spans,
/// several times the motion's standard deviation), and a model with high powers of a
/// displacement stiffens there, so an explicit integrator would crawl at its stability limit for
/// minutes per run before it blows up or settles in a well the record never visits.
pub const RANGE_SPANS: f64 = 3.0;

impl Default for SimulateOptions {
    fn default() -> Self {
        Self {
            integrator: Dopri5::default(),
            velocity_window: 5,
            use_velocity_column: true,
            initial_state: InitialState::default(),
            range: Some(RANGE_SPANS),
        }
    }
}

/// Estimates `y'(t_0)` from the first `m` samples: least-squares quadratic fit (a line for
/// `m = 2`) in orthogonal polynomials on the sample grid, differentiated at the first sample.
/// Exact for quadratics; averaging over `m` samples suppresses measurement noise.
pub fn initial_velocity(y: &[f64], dt: f64, m: usize) -> Result<f64> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(DynError::InvalidParameter {
            name: "dt",
            reason: format!("{dt} must be positive and finite"),
        });
    }
    let m = m.min(y.len());
    if m < 2 {
        return Err(DynError::InvalidParameter {
            name: "velocity_window",
            reason: format!(
                "needs at least 2 samples to estimate a velocity but only {m} are available"
            ),
        });
    }
    Ok(start_of(y, dt, m).1)
}

/// Simulates `model` under the input columns of `record` at the record's sample times.
///
/// * Inputs: one column per name in [`CompiledModel::input_names`] (e.g. `xb_acc`), interpolated
///   by a cubic spline ([`SampledInput`]); a missing column is a [`DynError::MissingColumn`].
/// * Initial state: `x(t_0)` from each DOF's displacement column (named like the DOF);
///   `v(t_0)` from the column `"<dof>'"` if present and allowed, otherwise from a least-squares
///   quadratic fit to the first `velocity_window` samples ([`initial_velocity`]); then, by
///   default ([`InitialState::Fitted`]), refined so that the model's own response matches the
///   measured displacements over the first periods of the record (noise in the first samples
///   otherwise decides the start, and with it the well a multi-stable model ends up in).
/// * Internal states (`maxwell(x', τ)`, `bouc_wen(x', a, b)`, `dahl(x', κ)` terms) start at 0
///   and are integrated with the motion; the trajectory holds the model's DOFs only.
/// * Blow-up gives [`DynError::BlowUp`] with the time and state.
///
/// A run from the same model's equations, the same columns and the same options starts from
/// the state fitted the first time (kept in a process-wide memo of start states; the fit is a
/// pure function of them, so the run is the same to the bit).
pub fn simulate_model_on_record(
    model: &Model,
    record: &Record,
    opts: &SimulateOptions,
) -> Result<Trajectory> {
    simulate_on_record(model, record, opts, true)
}

/// The R-MSE of a run of `model` on `record` ([`simulate_model_on_record`]) for each DOF of the
/// model, in its DOF order: [`rmse_variance`] of the run against the record's displacement. A
/// run with a fitted start ([`InitialState::Fitted`]) keeps its scores in the memo of
/// [`simulate_model_on_record`] (as does every such run of that function), so the same model on
/// the same columns with the same options is scored again without a run: the same numbers to
/// the bit, or the same error.
pub fn r_mse_on_record(model: &Model, record: &Record, opts: &SimulateOptions) -> Result<Vec<f64>> {
    scored(Run::new(model, record, opts, true, None)?, opts)
}

/// [`simulate_model_on_record`] for a model close to `near` (a refit of it, one of its fold
/// models): the start-state fit begins at `near`'s fitted start on the same record and options
/// (from the memo, or fitted now and kept there) and fits once from it
/// ([`crate::warm_initial_state`]), falling back to the two cold starts when that fit does not
/// end at a minimum. Where `near` cannot warm the fit (its equations are `model`'s, its DOFs
/// differ, the record lacks its inputs, or the start is not fitted), the run is
/// [`simulate_model_on_record`]'s. A warm run is remembered under its own key (`near`'s
/// equations included), apart from the cold run of the same model.
pub fn simulate_model_on_record_warm(
    model: &Model,
    record: &Record,
    opts: &SimulateOptions,
    near: &Model,
) -> Result<Trajectory> {
    Run::new(model, record, opts, true, Some(near))?.trajectory(opts)
}

/// [`r_mse_on_record`] of a run warmed by `near`'s fitted start
/// ([`simulate_model_on_record_warm`]); its scores are kept in the memo as a cold run's are.
pub fn r_mse_on_record_warm(
    model: &Model,
    record: &Record,
    opts: &SimulateOptions,
    near: &Model,
) -> Result<Vec<f64>> {
    scored(Run::new(model, record, opts, true, Some(near))?, opts)
}

/// The scores of `run`: from the memo, or from its trajectory.
fn scored(run: Run<'_>, opts: &SimulateOptions) -> Result<Vec<f64>> {
    if let Some(scores) = run.key.as_ref().and_then(memo::get_scores) {
        return scores;
    }
    let tr = run.trajectory(opts)?;
    run.scores(&tr)
}

/// [`simulate_model_on_record`], reading and filling the memo of fitted starts only with
/// `memo` (the tests compare the two).
fn simulate_on_record(
    model: &Model,
    record: &Record,
    opts: &SimulateOptions,
    memo: bool,
) -> Result<Trajectory> {
    Run::new(model, record, opts, memo, None)?.trajectory(opts)
}

/// A run of a model on a record, its inputs resolved: the compiled model, the input, the
/// first-samples state, the measured displacements, and the memo's key when the memo is used
/// and the start is fitted.
struct Run<'r> {
    compiled: CompiledModel,
    /// The record's own times.
    t_abs: &'r [f64],
    /// The times from 0 at the first sample (the run's clock).
    t_local: Vec<f64>,
    input: SampledInput,
    x0: Vec<f64>,
    v0: Vec<f64>,
    measured: Vec<&'r [f64]>,
    key: Option<StartKey>,
    /// Whether the model is smooth ([`smooth`]).
    smooth: bool,
    /// The run of the model whose fitted start warms this run's fit, when there is one.
    near: Option<Box<Run<'r>>>,
}

impl<'r> Run<'r> {
    /// The run of `model` on `record`; with `near`, warmed by `near`'s fitted start where it
    /// can be ([`simulate_model_on_record_warm`]).
    fn new(
        model: &Model,
        record: &'r Record,
        opts: &SimulateOptions,
        memo: bool,
        near: Option<&Model>,
    ) -> Result<Self> {
        let compiled = model
            .compile()
            .map_err(|e| DynError::Model(e.to_string()))?;
        let missing = |column: &str| DynError::MissingColumn {
            record: record.source().to_string(),
            column: column.to_string(),
            available: record.names().join(", "),
        };
        if record.len() < 2 {
            return Err(DynError::InvalidParameter {
                name: "record",
                reason: format!(
                    "{} has {} samples; at least 2 are needed to simulate",
                    record.source(),
                    record.len()
                ),
            });
        }
        let dt = record.dt();
        // The model is autonomous but for its input, so the record is simulated on its own
        // clock, from 0 at its first sample: a time column of absolute time stamps (10⁶ s, or a
        // Unix time) would otherwise cost the integrator's times their last digits, and the same
        // measurement would simulate differently with its time column shifted. The trajectory
        // keeps the record's times. (A record that starts at 0 is simulated exactly as before.)
        let t_abs = record.t();
        let t_local: Vec<f64> = t_abs.iter().map(|&v| v - t_abs[0]).collect();
        let t = &t_local[..];
        let mut channels = Vec::with_capacity(compiled.inputs());
        for name in compiled.input_names() {
            let col = record.column(name).ok_or_else(|| missing(name))?;
            channels.push(col.to_vec());
        }
        let input = SampledInput::new(0.0, dt, channels)?;
        let mut x0 = Vec::with_capacity(compiled.dofs());
        let mut v0 = Vec::with_capacity(compiled.dofs());
        for dof in compiled.dof_names() {
            let col = record.column(dof).ok_or_else(|| missing(dof))?;
            x0.push(col[0]);
            let vel_name = format!("{dof}'");
            let v = match record.column(&vel_name) {
                Some(vc) if opts.use_velocity_column => vc[0],
                _ => initial_velocity(col, dt, opts.velocity_window)?,
            };
            v0.push(v);
        }
        let measured: Vec<&[f64]> = compiled
            .dof_names()
            .iter()
            .map(|d| record.column(d).ok_or_else(|| missing(d)))
            .collect::<Result<_>>()?;
        check_resolved(
            record.source(),
            compiled.dof_names(),
            &measured,
            &opts.integrator,
        )?;
        // Internal states (the auxiliary coordinates after the DOFs) start at rest, z = 0.
        x0.resize(compiled.system_dofs(), 0.0);
        v0.resize(compiled.system_dofs(), 0.0);
        // A near model warms the fit when it differs from this one (the same equations fit the
        // same start cold), has the same DOFs and can run on the record.
        let fitted = matches!(opts.initial_state, InitialState::Fitted { .. });
        let near = near
            .filter(|n| fitted && n.equations != model.equations && n.dofs == model.dofs)
            .and_then(|n| Run::new(n, record, opts, memo, None).ok())
            .filter(|n| n.compiled.dof_names() == compiled.dof_names())
            .map(Box::new);
        // The fitted start is a pure function of what the fit reads, and the run of the start:
        // a run of the same model on the same columns with the same options starts from the
        // state fitted before, and scores what it scored before (`memo`).
        let key = (memo && fitted).then(|| {
            let mut h = KeyHasher::new();
            h.text(&format!(
                "{:?}|{:?}|{:?}|{:?}|{:?}",
                model.dofs,
                model.inputs,
                model.equations,
                compiled.dof_names(),
                opts
            ))
            .floats(t)
            .floats(&x0)
            .floats(&v0);
            for c in 0..input.channels() {
                h.floats(input.samples(c));
            }
            for m in &measured {
                h.floats(m);
            }
            // A warm run's start depends on the near model's: its key is part of this one.
            if let Some(k) = near.as_ref().and_then(|n| n.key) {
                h.text("warm").key_words(&k);
            }
            h.key()
        });
        Ok(Self {
            compiled,
            t_abs,
            t_local,
            input,
            x0,
            v0,
            measured,
            key,
            smooth: smooth(model),
            near,
        })
    }

    /// The run's trajectory; with a key, its scores (or its error) are kept in the memo.
    fn trajectory(&self, opts: &SimulateOptions) -> Result<Trajectory> {
        let tr = self.integrate(opts);
        if let Some(key) = self.key {
            let scores = match &tr {
                Ok(tr) => self.scores(tr),
                Err(e) => Err(e.clone()),
            };
            memo::put_scores(key, &scores);
        }
        tr
    }

    /// The R-MSE of each DOF of trajectory `tr` against the measured displacements.
    fn scores(&self, tr: &Trajectory) -> Result<Vec<f64>> {
        self.measured
            .iter()
            .zip(&tr.x)
            .map(|(m, x)| rmse_variance(m, x))
            .collect()
    }

    /// The integrator bounded by the record's range ([`SimulateOptions::range`]).
    fn ranged<'o>(&self, opts: &'o SimulateOptions) -> Ranged<'o, Dopri5> {
        Ranged {
            inner: &opts.integrator,
            bands: match opts.range {
                Some(f) => self.measured.iter().map(|y| range_band(y, f)).collect(),
                None => Vec::new(),
            },
            names: self.compiled.dof_names().to_vec(),
        }
    }

    /// The fitted start: from the memo, or fitted now ([`choose_initial_state`], or
    /// [`warm_initial_state`] from the near model's start) and kept there under the run's key.
    fn start(&self, opts: &SimulateOptions) -> memo::Start {
        if let Some(start) = self.key.as_ref().and_then(memo::get) {
            return start;
        }
        let sys = Differentiable {
            compiled: &self.compiled,
            smooth: self.smooth,
        };
        let ranged = self.ranged(opts);
        let (t, input, measured) = (&self.t_local[..], &self.input, &self.measured[..]);
        let cold = (self.x0.clone(), self.v0.clone());
        let how = opts.initial_state;
        let start = match self.near.as_ref().map(|n| n.start(opts)) {
            Some(Ok((xn, vn))) => {
                warm_initial_state(how, &sys, &ranged, input, measured, t, cold, (&xn, &vn))
            }
            _ => choose_initial_state(how, &sys, &ranged, input, measured, t, cold.0, cold.1),
        };
        if let Some(key) = self.key {
            memo::put(key, &start);
        }
        start
    }

    /// Fits the start (or takes it from the memo) and integrates the record.
    fn integrate(&self, opts: &SimulateOptions) -> Result<Trajectory> {
        let t_abs = self.t_abs;
        let n = self.compiled.dofs();
        let ranged = self.ranged(opts);
        let (x0, v0) = self.start(opts).map_err(|e| e.on_clock(t_abs[0]))?;
        let mut tr = ranged
            .integrate(&self.compiled, &self.input, &x0, &v0, &self.t_local)
            .map_err(|e| e.on_clock(t_abs[0]))?;
        tr.x.truncate(n);
        tr.v.truncate(n);
        tr.t = t_abs.to_vec();
        Ok(tr)
    }
}

/// How many absolute tolerances a displacement must span (peak to peak) for its simulation to
/// mean anything: below that the integrator's error allowance is a noticeable part of the motion.
pub const RESOLVED_SPAN_ATOL: f64 = 1e3;

/// Refuses a record whose measured displacement moves, but spans less than
/// [`RESOLVED_SPAN_ATOL`] absolute tolerances of `integrator` (a record of amplitude 1e-160 in
/// metres): its simulation would be the tolerance's, and its R-MSE noise or NaN. A constant
/// column (a start at rest) is accepted.
fn check_resolved(
    record: &str,
    dofs: &[String],
    measured: &[&[f64]],
    integrator: &Dopri5,
) -> Result<()> {
    for (dof, col) in dofs.iter().zip(measured) {
        let (lo, hi) = col
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let span = hi - lo;
        // A constant column is a start at rest (a generator's convention), not a measurement.
        if span > 0.0 && span < RESOLVED_SPAN_ATOL * integrator.atol {
            return Err(DynError::Unresolved {
                record: record.to_string(),
                column: dof.clone(),
                span,
                atol: integrator.atol,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run whose fitted start comes from the memo is the run a fresh fit gives: the same
    /// model on the same record again is the first run to the bit, and a change to any one
    /// thing the fit reads (an input sample or a displacement sample inside the fitted stretch,
    /// a coefficient, the fitted periods) starts from its own fit, not
    /// from the remembered one. Each change moves the fitted start, so a key that left it out
    /// would return the wrong state.
    #[test]
    fn a_remembered_start_is_the_fresh_fit() {
        let model = |k: f64| {
            Model::from_json_str(&format!(
                r#"{{"format":"tfs-model/1","dofs":["x"],"equations":[{{"dof":"x","terms":[{{"term":"x","coef":{k}}},{{"term":"x^3","coef":-0.5}},{{"term":"x'","coef":-0.2}},{{"term":"u","coef":1.0}}]}}]}}"#
            ))
            .unwrap()
        };
        let dt = 0.05;
        let n = 600;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let u: Vec<f64> = t.iter().map(|t| 0.8 * (1.1 * t).sin()).collect();
        // A displacement the model does not quite reproduce (a wrong stiffness and a wobble),
        // so the fitted start is not the first sample.
        let x: Vec<f64> = t
            .iter()
            .map(|t| 0.6 * (1.1 * t - 0.4).sin() + 0.05 * (3.7 * t).cos() + 0.1)
            .collect();
        let rec = |x: &[f64], u: &[f64]| {
            Record::new(
                "r",
                t.clone(),
                vec![("x".into(), x.to_vec()), ("u".into(), u.to_vec())],
            )
            .unwrap()
        };
        let base = rec(&x, &u);
        let opts = SimulateOptions::default();
        let first = simulate_model_on_record(&model(-1.0), &base, &opts).unwrap();
        let again = simulate_model_on_record(&model(-1.0), &base, &opts).unwrap();
        let fresh = simulate_on_record(&model(-1.0), &base, &opts, false).unwrap();
        assert_eq!(first, again);
        assert_eq!(first, fresh);
        let start = |tr: &Trajectory| (tr.x[0][0], tr.v[0][0]);
        assert_ne!(
            first.x[0][0], x[0],
            "the start is fitted, not the first sample"
        );
        let mut x2 = x.clone();
        x2[20] += 0.01;
        let mut u2 = u.clone();
        u2[20] += 0.05;
        let two_and_half = SimulateOptions {
            initial_state: InitialState::Fitted { periods: 2.5 },
            ..opts
        };
        let cases: Vec<(&str, Model, Record, SimulateOptions)> = vec![
            ("displacement", model(-1.0), rec(&x2, &u), opts),
            ("input", model(-1.0), rec(&x, &u2), opts),
            ("coefficient", model(-1.1), base.clone(), opts),
            ("periods", model(-1.0), base.clone(), two_and_half),
        ];
        for (what, m, r, o) in cases {
            let remembered = simulate_model_on_record(&m, &r, &o).unwrap();
            let fresh = simulate_on_record(&m, &r, &o, false).unwrap();
            assert_ne!(
                start(&fresh),
                start(&first),
                "{what}: the change moves the start"
            );
            assert_eq!(start(&remembered), start(&fresh), "{what}");
            assert!(remembered == fresh, "{what}: the runs differ");
        }
    }

    /// A score from the memo is the fresh run's: the R-MSE of a run of the model on the record,
    /// to the bit, asked once or again; a changed displacement sample (the score reads every
    /// sample, the fit only the first periods) or coefficient scores its own run; a run that
    /// leaves the record's range gives its error again.
    #[test]
    fn a_remembered_score_is_the_fresh_run_s() {
        let model = |k: f64| {
            Model::from_json_str(&format!(
                r#"{{"format":"tfs-model/1","dofs":["x"],"equations":[{{"dof":"x","terms":[{{"term":"x","coef":{k}}},{{"term":"x'","coef":-0.3}},{{"term":"u","coef":1.0}}]}}]}}"#
            ))
            .unwrap()
        };
        let dt = 0.05;
        let t: Vec<f64> = (0..400).map(|k| k as f64 * dt).collect();
        let u: Vec<f64> = t.iter().map(|t| (0.9 * t).sin()).collect();
        let x: Vec<f64> = t
            .iter()
            .map(|t| 0.8 * (0.9 * t - 0.3).sin() + 0.04 * (2.9 * t).cos())
            .collect();
        let rec = |x: &[f64]| {
            Record::new(
                "r",
                t.clone(),
                vec![("x".into(), x.to_vec()), ("u".into(), u.clone())],
            )
            .unwrap()
        };
        let opts = SimulateOptions::default();
        let fresh = |m: &Model, r: &Record| {
            let tr = simulate_on_record(m, r, &opts, false).unwrap();
            vec![rmse_variance(r.column("x").unwrap(), &tr.x[0]).unwrap()]
        };
        let base = rec(&x);
        let want = fresh(&model(-1.0), &base);
        assert_eq!(r_mse_on_record(&model(-1.0), &base, &opts).unwrap(), want);
        assert_eq!(r_mse_on_record(&model(-1.0), &base, &opts).unwrap(), want);
        let mut late = x.clone();
        late[390] += 0.3;
        let moved = rec(&late);
        let other = fresh(&model(-1.0), &moved);
        assert_ne!(other, want);
        assert_eq!(r_mse_on_record(&model(-1.0), &moved, &opts).unwrap(), other);
        let stiffer = fresh(&model(-1.2), &base);
        assert_ne!(stiffer, want);
        assert_eq!(
            r_mse_on_record(&model(-1.2), &base, &opts).unwrap(),
            stiffer
        );
        // Negative stiffness: the run leaves the record's span.
        let away = model(2.0);
        let e = simulate_on_record(&away, &base, &opts, false).unwrap_err();
        assert!(matches!(e, DynError::LeftRange { .. }), "{e}");
        assert_eq!(r_mse_on_record(&away, &base, &opts).unwrap_err(), e);
        assert_eq!(r_mse_on_record(&away, &base, &opts).unwrap_err(), e);
    }

    /// Quadratics are covered by `initial::tests::start_of_is_exact_for_quadratics`, which this
    /// delegates to; here the two-sample line and the argument checks.
    #[test]
    fn initial_velocity_lines_and_bad_arguments() {
        let v = initial_velocity(&[1.0, 3.0], 0.5, 5).unwrap();
        assert!((v - 4.0).abs() < 1e-12);
        assert!(initial_velocity(&[1.0], 0.5, 5).is_err());
    }

    /// The models of [`sensitivities_are_the_runs_differences`] and
    /// [`sensitivities_reach_the_differences_optimum`]: a forced Duffing oscillator, a Maxwell
    /// element (an internal state) and a two-DOF chain with a relative cubic spring and smoothed
    /// dry friction, each with the record it is fitted to (a displacement the model does not
    /// quite reproduce, so the residuals are not small).
    fn differentiable_cases() -> Vec<(&'static str, Model, Record)> {
        let json = |dofs: &str, eqs: &str| {
            Model::from_json_str(&format!(
                r#"{{"format":"tfs-model/1","dofs":[{dofs}],"equations":[{eqs}]}}"#
            ))
            .unwrap()
        };
        let eq = |dof: &str, terms: &[(&str, f64)]| {
            let terms: Vec<String> = terms
                .iter()
                .map(|(t, c)| format!(r#"{{"term":"{t}","coef":{c}}}"#))
                .collect();
            format!(r#"{{"dof":"{dof}","terms":[{}]}}"#, terms.join(","))
        };
        let dt = 0.05;
        let t: Vec<f64> = (0..400).map(|k| k as f64 * dt).collect();
        let u: Vec<f64> = t.iter().map(|t| 0.8 * (1.1 * t).sin()).collect();
        let wave = |phase: f64| -> Vec<f64> {
            t.iter()
                .map(|t| 0.6 * (1.1 * t - phase).sin() + 0.05 * (3.7 * t).cos() + 0.1)
                .collect()
        };
        let rec = |cols: Vec<(&str, Vec<f64>)>| {
            let mut cols: Vec<(String, Vec<f64>)> =
                cols.into_iter().map(|(n, c)| (n.to_string(), c)).collect();
            cols.push(("u".into(), u.clone()));
            Record::new("r", t.clone(), cols).unwrap()
        };
        let one = rec(vec![("x", wave(0.4))]);
        vec![
            (
                "duffing",
                json(
                    r#""x""#,
                    &eq("x", &[("x", -1.0), ("x^3", -0.5), ("x'", -0.2), ("u", 1.0)]),
                ),
                one.clone(),
            ),
            (
                "maxwell",
                json(
                    r#""x""#,
                    &eq(
                        "x",
                        &[
                            ("x", -1.0),
                            ("maxwell(x', 0.7)", -0.6),
                            ("x'", -0.1),
                            ("u", 1.0),
                        ],
                    ),
                ),
                one,
            ),
            (
                "chain",
                json(
                    r#""x1","x2""#,
                    &format!(
                        "{},{}",
                        eq(
                            "x1",
                            &[
                                ("x1", -2.0),
                                ("(x2-x1)^3", 0.7),
                                ("tanh(x1'/0.3)", -0.3),
                                ("u", 1.0)
                            ]
                        ),
                        eq("x2", &[("(x2-x1)", -1.5), ("x2'", -0.15)])
                    ),
                ),
                rec(vec![("x1", wave(0.4)), ("x2", wave(0.9))]),
            ),
        ]
    }

    /// The Jacobian of a run's residuals by the variational equation along its samples is the
    /// one forward differences of whole runs give, on each of [`differentiable_cases`], at the
    /// first-samples start and away from it, to the differences' own error: their step, 1e-6 of
    /// the unknown, leaves a truncation error of about that share of the Jacobian (the runs are
    /// at a tolerance of 1e-12 here, so their rounding adds little), and the sampled variational
    /// equation's error is of the fourth order in the sample interval times the motion's
    /// frequency (0.05 s at about 1 rad/s: a few parts in a million).
    #[test]
    fn sensitivities_are_the_runs_differences() {
        use crate::initial::StartFit;
        let integrator = Dopri5::with_tol(1e-12, 1e-14);
        for (what, model, record) in differentiable_cases() {
            let run = Run::new(&model, &record, &SimulateOptions::default(), false, None).unwrap();
            let sys = Differentiable {
                compiled: &run.compiled,
                smooth: smooth(&model),
            };
            let t = &run.t_local[..120];
            let fit = StartFit::new(
                &sys,
                &integrator,
                &run.input,
                &run.measured,
                t,
                &run.x0,
                &run.v0,
            )
            .unwrap();
            assert!(fit.has_sensitivities(), "{what}");
            let m = run.measured.len();
            for shift in [0.0, 0.3] {
                let p: Vec<f64> = (0..2 * m).map(|j| shift * (j as f64 - 0.5)).collect();
                let (r, tr) = fit.run(&p, f64::INFINITY).unwrap();
                let jac = fit.along(&tr).unwrap();
                let fd = fit.differences(&p, &r).unwrap();
                let size = fd.amax();
                let worst = (&jac - &fd).amax();
                assert!(size > 0.1, "{what}: a Jacobian of size {size}");
                assert!(worst < 1e-5 * size, "{what} at {shift}: {worst} of {size}");
            }
        }
    }

    /// A start-state fit whose Jacobian comes from the runs' sensitivities ends where the
    /// fit by differences of runs ends, on each of [`differentiable_cases`] from a poor start,
    /// at the default tolerance: the same cost to a few parts in a million (both end once an
    /// iteration removes less than √ε of it), the same state to the fit's precision.
    #[test]
    fn sensitivities_reach_the_differences_optimum() {
        use crate::initial::{Derivatives, StartFit};
        let integrator = Dopri5::default();
        for (what, model, record) in differentiable_cases() {
            let run = Run::new(&model, &record, &SimulateOptions::default(), false, None).unwrap();
            let sys = Differentiable {
                compiled: &run.compiled,
                smooth: smooth(&model),
            };
            let t = &run.t_local[..200];
            let (mut x0, mut v0) = (run.x0.clone(), run.v0.clone());
            x0[0] += 0.2;
            v0[0] -= 0.3;
            let fit = |how| {
                StartFit::new(&sys, &integrator, &run.input, &run.measured, t, &x0, &v0)
                    .unwrap()
                    .solve(how)
                    .unwrap()
            };
            let (sens, diff) = (
                fit(Derivatives::Sensitivities),
                fit(Derivatives::Differences),
            );
            assert!(sens.cost < sens.cost_start, "{what}: {sens:?}");
            let rel = (sens.cost - diff.cost).abs() / diff.cost;
            assert!(
                rel < 1e-5,
                "{what}: cost {} against {}",
                sens.cost,
                diff.cost
            );
            for (a, b) in sens
                .x0
                .iter()
                .chain(&sens.v0)
                .zip(diff.x0.iter().chain(&diff.v0))
            {
                assert!(
                    (a - b).abs() < 1e-4 * (1.0 + b.abs()),
                    "{what}: {a} against {b}"
                );
            }
        }
    }

    /// A run warmed by a near model's fitted start ([`r_mse_on_record_warm`]) scores what the
    /// cold run scores, on each of [`differentiable_cases`] refitted (every coefficient 5 % off,
    /// warmed by the case's own model): both fits end at the same minimum, to the fit's
    /// precision, so the runs' R-MSE agree to a few parts in a million. The warm and the cold run
    /// of one model are remembered apart (each asked again is itself, to the bit), and a near
    /// model with the run's own equations leaves the run cold, to the bit.
    #[test]
    fn a_warm_run_scores_the_cold_run_s_r_mse() {
        let opts = SimulateOptions::default();
        for (what, model, record) in differentiable_cases() {
            let mut refit = model.clone();
            for e in &mut refit.equations {
                for term in &mut e.terms {
                    term.coef *= 1.05;
                }
            }
            let cold_run = simulate_on_record(&refit, &record, &opts, false).unwrap();
            let cold: Vec<f64> = refit
                .dofs
                .iter()
                .zip(&cold_run.x)
                .map(|(d, x)| rmse_variance(record.column(d).unwrap(), x).unwrap())
                .collect();
            let warm = r_mse_on_record_warm(&refit, &record, &opts, &model).unwrap();
            for (w, c) in warm.iter().zip(&cold) {
                assert!(
                    (w - c).abs() < 1e-5 * c,
                    "{what}: warm {w} against cold {c}"
                );
            }
            assert_eq!(
                r_mse_on_record_warm(&refit, &record, &opts, &model).unwrap(),
                warm
            );
            assert_eq!(
                r_mse_on_record(&refit, &record, &opts).unwrap(),
                cold,
                "{what}"
            );
            let own = r_mse_on_record(&model, &record, &opts).unwrap();
            assert_eq!(
                r_mse_on_record_warm(&model, &record, &opts, &model).unwrap(),
                own
            );
        }
    }

    /// A model with a `sign(·)` factor (a jump in its acceleration), a stop (a kink) or a
    /// Bouc–Wen state (`|q'|` in its rate) has no Jacobian for the fit, which then takes
    /// differences of runs; one of powers, `tanh` and a Maxwell element has.
    #[test]
    fn only_smooth_models_have_sensitivities() {
        let model = |term: &str| {
            Model::from_json_str(&format!(
                r#"{{"format":"tfs-model/1","dofs":["x"],"equations":[{{"dof":"x","terms":[{{"term":"x","coef":-1.0}},{{"term":"{term}","coef":-0.1}}]}}]}}"#
            ))
            .unwrap()
        };
        for (term, want) in [
            ("sign(x')", false),
            ("below(x, -0.3)", false),
            ("x'*abs(x')", false),
            ("bouc_wen(x', 0.5, 0.5)", false),
            ("x^3", true),
            ("tanh(x'/0.2)", true),
            ("maxwell(x', 0.5)", true),
        ] {
            let model = model(term);
            assert_eq!(smooth(&model), want, "{term}");
            let compiled = model.compile().unwrap();
            let sys = Differentiable {
                compiled: &compiled,
                smooth: smooth(&model),
            };
            let n = compiled.system_dofs();
            let (mut a, mut ax, mut av) = (vec![0.0; n], vec![0.0; n * n], vec![0.0; n * n]);
            let (x, v) = (vec![0.1; n], vec![0.2; n]);
            assert_eq!(
                sys.accel_jacobian(0.0, &x, &v, &[], &mut a, &mut ax, &mut av),
                want,
                "{term}"
            );
        }
    }
}
