//! Scoring a model on held-out records as `tfs compare` and the Python package do: the model
//! simulated under each record's measured input, R-MSE (on the variance, and the paper's Appendix B
//! ratio over the mean square) and RMS error per DOF, and how far a fresh draw of the input's own
//! noise, or a start moved by the displacement's own noise, moves the simulation. Where either
//! decides the free run (snap-through timed by the noise, a chaotic motion), the record is also
//! scored by short-horizon predictions from the measured state
//! ([`tfs_diagnose::PredictionScore`]), a ruler that can still rank models there.

use serde_json::{Value, json};
use tfs_data::Record;
use tfs_dynamics::{Trajectory, rms_error, rmse_ratio, rmse_variance};
use tfs_library::Model;

use crate::error::{Context, Result};
use crate::invalid;

/// What `r_mse` is, for the output.
pub const R_MSE_DEFINITION: &str = "mean squared error over the measured variance (mean removed), so a DC level does not change it";

/// What `r_mse_mean_square` is, for the output.
pub const R_MSE_MEAN_SQUARE_DEFINITION: &str = "mean squared error over the measured mean square, the paper's Appendix B definition (a DC level in the record lowers it)";

/// One record's score.
#[derive(Debug, Clone)]
pub struct RecordScore {
    /// The record's source.
    pub record: String,
    /// Mean R-MSE over the DOFs, on each DOF's variance ([`R_MSE_DEFINITION`]).
    pub r_mse: f64,
    /// Mean R-MSE over the DOFs as the paper's Appendix B defines it
    /// ([`R_MSE_MEAN_SQUARE_DEFINITION`]).
    pub r_mse_mean_square: f64,
    /// Per DOF: `{"dof", "r_mse", "r_mse_mean_square", "rms_error", "input_noise_spread",
    /// "start_spread"}`.
    pub dofs: Vec<Value>,
    /// Whether most of the error is the measured input's own noise (`None`: not estimated).
    pub error_is_input_noise: Option<bool>,
    /// Whether, the input's noise not deciding, the run's own divergence from a start moved by
    /// the displacement's noise accounts for the error (`None`: not estimated).
    pub run_diverges: Option<bool>,
    /// Where the free run cannot rank models (either of the two): the piece length (samples) of the
    /// short-horizon predictions from the measured state, its length in seconds and their
    /// R-MSE.
    pub short_horizon: Option<(usize, f64, f64)>,
    /// The simulation.
    pub trajectory: Trajectory,
}

impl RecordScore {
    /// The score as JSON (the CLI's `files` entries, with `path` the record's source).
    pub fn to_json(&self) -> Value {
        json!({"path": self.record, "r_mse": self.r_mse,
            "r_mse_mean_square": self.r_mse_mean_square, "dofs": self.dofs,
            "error_is_input_noise": self.error_is_input_noise,
            "run_diverges": self.run_diverges,
            "short_horizon": self.short_horizon.map(|(h, secs, r)| json!({"samples": h, "seconds": secs, "r_mse": r}))})
    }
}

/// Simulates `model` on `record` (offsets already treated) and scores it.
pub fn score(model: &Model, record: &Record) -> Result<RecordScore> {
    score_with(model, record, None)
}

/// [`score`], with the short-horizon pieces `horizon` samples long on every record when given
/// (two models compared that way are scored by the same ruler); without, only where the free run
/// cannot rank models ([`tfs_refine::probe_free_run`]), their length chosen from the model.
pub fn score_with(model: &Model, record: &Record, horizon: Option<usize>) -> Result<RecordScore> {
    if horizon.is_some_and(|h| h < 2) {
        invalid!(
            "the short-horizon piece length (`horizon`; `--horizon` on the command line) must be at least 2 samples: a piece needs a start and a step"
        );
    }
    if model.dofs.is_empty() {
        invalid!("the model has no DOFs");
    }
    let src = record.source().to_string();
    // The same simulation as `diagnose` and `refit` score with: computed input columns are
    // added to the record, internal states (Maxwell elements, hysteresis, Dahl friction) start
    // at rest and are integrated with the motion.
    let traj = tfs_diagnose::simulate(model, record)
        .with_context(|| format!("{src}: simulating the model"))?;
    // Whether the record's own uncertainty moves the free run about as far as its error: a fresh
    // draw of the input's noise, or a start moved by the displacement's noise (the run's own
    // divergence). The same probe as `diagnose`'s judge and refinement's screen ask.
    let sim = tfs_dynamics::SimulateOptions::default();
    let probe = tfs_diagnose::augment_record(model, record, &Default::default())
        .ok()
        .and_then(|aug| {
            let run = tfs_dynamics::simulate_model_on_record(model, &aug, &sim).ok()?;
            tfs_refine::probe_free_run(model, &aug, &sim, &run)
        });
    let spread = probe.as_ref().and_then(|p| p.input_spread.clone());
    let start_spread = probe.as_ref().and_then(|p| p.start_spread.clone());
    let mut dofs = Vec::new();
    let (mut sum, mut sum_b) = (0.0, 0.0);
    for (i, dof) in model.dofs.iter().enumerate() {
        let Some(measured) = record.column(dof) else {
            invalid!("{src}: column '{dof}' needed by the model is missing");
        };
        let r = rmse_variance(measured, &traj.x[i])
            .with_context(|| format!("{src}: column '{dof}'"))?;
        let r_b =
            rmse_ratio(measured, &traj.x[i]).with_context(|| format!("{src}: column '{dof}'"))?;
        let rms = rms_error(measured, &traj.x[i])?;
        sum += r;
        sum_b += r_b;
        let s = spread.as_ref().map(|s| s[i]).filter(|v| v.is_finite());
        let s0 = start_spread
            .as_ref()
            .map(|s| s[i])
            .filter(|v| v.is_finite());
        dofs.push(json!({"dof": dof, "r_mse": r, "r_mse_mean_square": r_b,
            "rms_error": rms, "input_noise_spread": s, "start_spread": s0}));
    }
    // A ruler the record's uncertainty does not decide, where it decides the free run.
    let opts = tfs_diagnose::DiagnoseOptions::default();
    let ruler = match horizon {
        Some(h) => Ok(tfs_diagnose::PredictionScore {
            horizon: Some(h),
            why: "pieces of the length asked for".into(),
        }),
        // The same verdict as the probe's: pieces where the free run cannot rank models.
        None if probe
            .as_ref()
            .is_some_and(tfs_refine::FreeRunProbe::dominated) =>
        {
            tfs_diagnose::PredictionScore::pieces(model, record, &opts)
        }
        None => Ok(tfs_diagnose::PredictionScore::free_run()),
    };
    let short_horizon = ruler.ok().and_then(|s| {
        let h = s.horizon?;
        Some((
            h,
            h as f64 * record.dt(),
            s.r_mse(model, record, &opts).ok()?,
        ))
    });
    Ok(RecordScore {
        record: src,
        short_horizon,
        r_mse: sum / model.dofs.len() as f64,
        r_mse_mean_square: sum_b / model.dofs.len() as f64,
        dofs,
        error_is_input_noise: probe.as_ref().map(|p| p.by_input),
        run_diverges: probe.as_ref().map(|p| p.diverges),
        trajectory: traj,
    })
}
