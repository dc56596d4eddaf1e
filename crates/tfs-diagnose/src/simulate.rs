//! Simulating models that use computed effect columns, and R-MSE helpers.
//!
//! A delayed or low-pass filtered input is an ordinary input computed from the record
//! ([`augment_record`]). Memory effects (`maxwell`, `bouc_wen`, `dahl` terms) are internal
//! states of the model itself: `tfs_dynamics` integrates them with the motion, started at rest.

use rayon::prelude::*;
use tfs_data::Record;
use tfs_dynamics::{
    SimulateOptions, Trajectory, r_mse_on_record, r_mse_on_record_warm, simulate_model_on_record,
};
use tfs_library::Model;

use crate::Result;
use crate::effects::computed_columns;
use crate::prepare::{DiagnoseOptions, missing};

/// Adds every input-derived column `model` needs (delayed or filtered inputs) to a copy of
/// `record` (existing columns are kept). `_opts` is kept for callers that pass their options.
pub fn augment_record(model: &Model, record: &Record, _opts: &DiagnoseOptions) -> Result<Record> {
    let mut out = record.clone();
    let dt = record.dt();
    for c in computed_columns(model) {
        if out.column(&c.name()).is_some() {
            continue;
        }
        if record.column(&c.source()).is_none() {
            return Err(missing(model, record, &c.source()));
        }
        let values = c.compute(record, dt)?;
        out.set_column(c.name(), values)?;
    }
    Ok(out)
}

/// Simulates `model` under `record`'s inputs at its sample times (input-derived columns are
/// computed first when the record lacks them; internal states start at rest).
pub fn simulate(model: &Model, record: &Record) -> Result<Trajectory> {
    simulate_with(model, record, &SimulateOptions::default())
}

/// [`simulate`] with the integrator settings `sim` (the judge's bounded runs).
pub(crate) fn simulate_with(
    model: &Model,
    record: &Record,
    sim: &SimulateOptions,
) -> Result<Trajectory> {
    let record = if computed_columns(model).is_empty() {
        std::borrow::Cow::Borrowed(record)
    } else {
        std::borrow::Cow::Owned(augment_record(model, record, &DiagnoseOptions::default())?)
    };
    Ok(simulate_model_on_record(model, &record, sim)?)
}

/// R-MSE of a simulation of `model` on `record` on each DOF's variance (its mean removed, so
/// the record's DC level does not flatter or penalise the score), averaged over the DOFs.
pub fn r_mse(model: &Model, record: &Record) -> Result<f64> {
    r_mse_with(model, record, &SimulateOptions::default())
}

/// [`r_mse`] with the integrator settings `sim`. The run's scores come from
/// [`tfs_dynamics::r_mse_on_record`], which keeps them: the same model scored again on the same
/// record (the start model under every candidate's refit, a refit kept by two decisions) is
/// not simulated again.
pub(crate) fn r_mse_with(model: &Model, record: &Record, sim: &SimulateOptions) -> Result<f64> {
    r_mse_near(model, record, sim, None)
}

/// [`r_mse_with`] for a model close to `near` (a refit of it, one of its fold models): the
/// run's start-state fit begins at `near`'s fitted start on the same record
/// ([`tfs_dynamics::r_mse_on_record_warm`]: one fit instead of two; the two cold ones when it
/// does not converge or ends above the record's own starts). `None` is [`r_mse_with`].
pub(crate) fn r_mse_near(
    model: &Model,
    record: &Record,
    sim: &SimulateOptions,
    near: Option<&Model>,
) -> Result<f64> {
    let augmented = if computed_columns(model).is_empty() {
        std::borrow::Cow::Borrowed(record)
    } else {
        std::borrow::Cow::Owned(augment_record(model, record, &DiagnoseOptions::default())?)
    };
    let each = match near {
        Some(near) => r_mse_on_record_warm(model, &augmented, sim, near)?,
        None => r_mse_on_record(model, &augmented, sim)?,
    };
    let mut s = 0.0;
    for (d, r) in model.dofs.iter().zip(each) {
        record.column(d).ok_or_else(|| missing(model, record, d))?;
        s += r;
    }
    Ok(s / model.dofs.len().max(1) as f64)
}

/// The model's own simulation of one record under its measured inputs: `None` when the
/// record's computed columns cannot be made, else the trajectory or the simulation's error in
/// words. Computed once per record and shared by everything that needs it (the judge's choice,
/// the input-noise spread, the comparison).
pub(crate) type BaseRun = Option<std::result::Result<Trajectory, String>>;

/// [`BaseRun`]s of `model` on every record, side by side, in record order.
pub(crate) fn base_runs(model: &Model, records: &[Record], opts: &DiagnoseOptions) -> Vec<BaseRun> {
    records
        .par_iter()
        .map(|r| {
            let rec = augment_record(model, r, opts).ok()?;
            Some(simulate(model, &rec).map_err(|e| e.to_string()))
        })
        .collect()
}

/// How the free run `run` of `model` on the augmented record `rec` reads against what the
/// record itself leaves uncertain, and whether it can rank models there. It cannot when in some
/// DOF one of two spreads accounts for its error from the measured displacement
/// ([`tfs_refine::noise_dominated`], the same inequality for both):
///
/// - the input's noise: how far a fresh draw of the measured input's own noise moves the run
///   ([`tfs_refine::input_noise_spread_from`]; a multi-stable structure the noise times through
///   its snap-through);
/// - its own divergence: how far the run from a start one displacement-noise standard deviation
///   away parts from it ([`tfs_refine::start_spread_from`]; a chaotic motion, whose nearby
///   motions part by themselves whatever the input-noise level, and which a lower input-noise
///   estimate alone would hand back to the free run). It counts only in a DOF where the two
///   runs end farther apart (RMS over the record) than the start was moved: a damped or
///   neutral run keeps its spread at or below that move and is not touched by this.
///
/// The probe is [`tfs_refine::probe_free_run`], which `compare` and refinement ask too; the
/// start's spread is computed only when the input's does not already decide. Also how far
/// the input's noise moves the R-MSE (the mean over DOFs of the squared spread over the
/// measured displacement's variance). `None` when a DOF's measured column is missing, or
/// neither spread can be had (no input can be perturbed and no displacement has a noise floor).
pub(crate) fn noise_probe(
    model: &Model,
    rec: &Record,
    run: &Trajectory,
    sim: &SimulateOptions,
) -> Option<NoiseProbe> {
    let p = tfs_refine::probe_free_run(model, rec, sim, run)?;
    let shift = p.input_spread.as_ref().map(|spread| {
        spread
            .iter()
            .zip(&model.dofs)
            .map(|(sp, d)| {
                let m = rec.column(d).unwrap_or(&[]);
                sp * sp / crate::prepare::variance(m).max(f64::MIN_POSITIVE)
            })
            .sum::<f64>()
            / spread.len().max(1) as f64
    });
    Some(NoiseProbe {
        dominated: p.dominated(),
        diverges: p.diverges,
        shift,
    })
}

/// What [`noise_probe`] reads from one free run.
#[derive(Debug, Clone, Copy)]
pub(crate) struct NoiseProbe {
    /// The free run cannot rank models: the input's noise, or its own divergence from a start
    /// the record cannot tell apart, moves it about as far as its error in some DOF.
    pub dominated: bool,
    /// Dominated by its own divergence (and not by the input's noise).
    pub diverges: bool,
    /// The R-MSE difference a fresh draw of the input's noise makes (`None` when no input can
    /// be perturbed).
    pub shift: Option<f64>,
}

/// True when the free run of `model` on `record` cannot rank models: dominated by the measured
/// input's own noise or by its own divergence ([`noise_probe`]). False when the record's
/// computed columns cannot be made, the simulation fails or neither spread can be had: the free
/// run then says what it says.
pub(crate) fn free_run_noise_dominated(
    model: &Model,
    record: &Record,
    opts: &DiagnoseOptions,
) -> bool {
    let Ok(rec) = augment_record(model, record, opts) else {
        return false;
    };
    let sim = SimulateOptions::default();
    let Ok(run) = simulate_model_on_record(model, &rec, &sim) else {
        return false;
    };
    noise_probe(model, &rec, &run, &sim).is_some_and(|p| p.dominated)
}
