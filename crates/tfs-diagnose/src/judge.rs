//! How a candidate's refitted model is judged on held-out data, and by which judge.
//!
//! The free-run simulation under the measured input is the judge the user sees (`compare`), and
//! the default. It cannot rank models when a fresh draw of the measured input's own noise moves
//! the simulation about as far as the model's error (a multi-stable structure swept through
//! chaotic snap-through: which well it is in decides the error, and the noise decides the well;
//! `tfs_refine::noise_dominated`). Then the candidates are judged by **short-horizon
//! prediction**: held-out data cut into pieces of two dominant periods, each simulated from the
//! smoothed measured state at its start (internal states from the record), the squared error
//! summed over the pieces — the model's error over a horizon the input noise cannot take over.
//! That judge vetoes a candidate that predicts worse; the significant ones are then ordered by
//! their held-out equation error (`explain`), as chaotic divergence over the pieces is too coarse
//! to order candidates that all predict better.
//! When neither can be simulated the equation error alone decides.

use rayon::prelude::*;
use serde::Serialize;
use tfs_dynamics::{Dopri5, Integrator, SampledInput, SimulateOptions};
use tfs_library::{Factor, Model, Term, evaluate_term};

use crate::effects::EffectColumn;
use crate::explain::{Cv, with_equation};
use crate::prepare::{DiagnoseOptions, Layout, RecordStates};
use crate::simulate::BaseRun;

/// What ranked the held-out predictions of the candidates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Judge {
    /// R-MSE of the free-run simulation under the measured input.
    FreeRun,
    /// R-MSE of simulations over pieces of two dominant periods, each from the measured state.
    ShortHorizon,
    /// Held-out equation error only (nothing could be simulated).
    EquationError,
}

impl Judge {
    /// In words, for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Judge::FreeRun => "free-run simulation",
            Judge::ShortHorizon => "short-horizon prediction",
            Judge::EquationError => "equation error",
        }
    }
}

/// The judge for `model` on `states`: short-horizon prediction when on most records the free-run
/// error is dominated by the input's own noise, free-run otherwise; with the reason in words.
/// `runs` are the model's own simulations of the records ([`crate::simulate::base_runs`]).
pub(crate) fn choose(
    model: &Model,
    states: &[RecordStates],
    opts: &DiagnoseOptions,
    runs: &[BaseRun],
) -> (Judge, String) {
    let sim = SimulateOptions::default();
    let verdicts: Vec<Option<bool>> = states
        .par_iter()
        .zip(runs)
        .map(|(s, run)| {
            let rec = crate::simulate::augment_record(model, &s.record, opts).ok()?;
            let tr = run.as_ref()?.as_ref().ok()?;
            let err: Vec<f64> = model
                .dofs
                .iter()
                .enumerate()
                .map(|(i, d)| {
                    rec.column(d)
                        .and_then(|m| tfs_dynamics::rms_error(m, &tr.x[i]).ok())
                        .unwrap_or(f64::INFINITY)
                })
                .collect();
            let spread = tfs_refine::input_noise_spread_from(model, &rec, &sim, tr).ok()??;
            let noise = tfs_refine::displacement_noise_var(model, &rec);
            Some(tfs_refine::noise_dominated(&spread, &err, &noise))
        })
        .collect();
    let dominated = verdicts.iter().filter(|v| **v == Some(true)).count();
    if 2 * dominated > states.len() {
        (
            Judge::ShortHorizon,
            format!(
                "free-run simulation cannot rank models on these records: on {dominated} of {} a fresh draw of the measured input's noise moves it about as far as the model's error",
                states.len()
            ),
        )
    } else {
        (
            Judge::FreeRun,
            "free-run simulation under the measured input".to_string(),
        )
    }
}

/// The held-out error of the per-fold models of equation `dof_idx` with columns `cols` under
/// `judge` (mean over held-out units of the R-MSE; `None` when a simulation fails or the judge
/// is the equation error). `horizon` is the piece length of the short-horizon judge (samples).
#[allow(clippy::too_many_arguments)]
pub(crate) fn heldout_error(
    judge: Judge,
    model: &Model,
    dof_idx: usize,
    cols: &[EffectColumn],
    cv: &Cv,
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
    horizon: usize,
) -> Option<f64> {
    match judge {
        Judge::FreeRun => heldout_r_mse(model, dof_idx, cols, cv, states, layout, opts),
        Judge::ShortHorizon => {
            short_horizon(model, dof_idx, cols, cv, states, layout, opts, horizon)
        }
        Judge::EquationError => None,
    }
}

/// Held-out simulation R-MSE of the per-fold models (mean over held-out units; None on failure).
/// The units are simulated side by side and summed in fold order, so the mean is the same on
/// any number of threads; the first failure stops the units not yet started.
fn heldout_r_mse(
    model: &Model,
    dof_idx: usize,
    cols: &[EffectColumn],
    cv: &Cv,
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
) -> Option<f64> {
    // Per fold its model; per held-out unit (fold, record, rows: the whole record or a segment).
    let mut models = Vec::with_capacity(layout.folds);
    let mut units = Vec::new();
    for f in 0..layout.folds {
        models.push(with_equation(model, dof_idx, cols, &cv.coefs[f]).ok()?);
        if layout.by_record {
            for r in 0..states.len() {
                if layout.blocks.iter().any(|b| b.record == r && b.fold == f) {
                    units.push((f, r, None));
                }
            }
        } else {
            let bl: Vec<_> = layout.blocks.iter().filter(|b| b.fold == f).collect();
            let r = bl.first()?.record;
            let start = states[r].margin + bl.first()?.start;
            let end = states[r].margin + bl.last()?.start + bl.last()?.len;
            units.push((f, r, Some(start..end)));
        }
    }
    let scores: Vec<f64> = units
        .par_iter()
        .map(|(f, r, range)| {
            let m = &models[*f];
            let full = crate::simulate::augment_record(m, &states[*r].record, opts).ok()?;
            let u = match range {
                None => full,
                Some(range) => full.slice(range.clone()).ok()?,
            };
            crate::simulate::r_mse(m, &u).ok()
        })
        .collect::<Option<_>>()?;
    let mut sum = 0.0;
    for s in &scores {
        sum += s;
    }
    (!scores.is_empty()).then(|| sum / scores.len() as f64)
}

/// Short-horizon prediction R-MSE of the per-fold models on their held-out blocks (see the
/// module docs): per held-out unit (a record, or one record's held-out segment), the summed
/// squared error of the pieces over the summed squared deviation of the measured displacement
/// from its mean, averaged over DOFs and units.
#[allow(clippy::too_many_arguments)]
fn short_horizon(
    model: &Model,
    dof_idx: usize,
    cols: &[EffectColumn],
    cv: &Cv,
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
    horizon: usize,
) -> Option<f64> {
    let mut sum = 0.0;
    let mut count = 0usize;
    for f in 0..layout.folds {
        let m = with_equation(model, dof_idx, cols, &cv.coefs[f]).ok()?;
        for (r, s) in states.iter().enumerate() {
            let blocks: Vec<_> = layout
                .blocks
                .iter()
                .filter(|b| b.record == r && b.fold == f)
                .collect();
            let (Some(first), Some(last)) = (blocks.first(), blocks.last()) else {
                continue;
            };
            let range = s.margin + first.start..s.margin + last.start + last.len;
            sum += predict_pieces(&m, s, range, horizon, opts)?;
            count += 1;
        }
    }
    (count > 0).then(|| sum / count as f64)
}

/// R-MSE (mean over DOFs) of `model`'s predictions over pieces of `horizon` samples covering
/// `range` of the record behind `s`, each started from the smoothed measured state.
fn predict_pieces(
    model: &Model,
    s: &RecordStates,
    range: std::ops::Range<usize>,
    horizon: usize,
    opts: &DiagnoseOptions,
) -> Option<f64> {
    let rec = crate::simulate::augment_record(model, &s.record, opts).ok()?;
    let compiled = model.compile().ok()?;
    let t = rec.t();
    let channels: Vec<Vec<f64>> = compiled
        .input_names()
        .iter()
        .map(|n| rec.column(n).map(<[f64]>::to_vec))
        .collect::<Option<_>>()?;
    let input = if channels.is_empty() {
        SampledInput::zero(0)
    } else {
        SampledInput::new(t[0], rec.dt(), channels).ok()?
    };
    let n = compiled.dofs();
    let xs: Vec<&[f64]> = model
        .dofs
        .iter()
        .map(|d| tfs_data::Columns::column(s, d))
        .collect::<Option<_>>()?;
    let vs: Vec<&[f64]> = model
        .dofs
        .iter()
        .map(|d| tfs_data::Columns::column(s, &format!("{d}'")))
        .collect::<Option<_>>()?;
    let measured: Vec<&[f64]> = model
        .dofs
        .iter()
        .map(|d| rec.column(d))
        .collect::<Option<_>>()?;
    // The internal states along the smoothed motion, from rest at the record's start.
    let tracks: Vec<Vec<f64>> = model
        .internal_states()
        .into_iter()
        .map(|(v, law)| evaluate_term(&Term::new(vec![Factor::State(v, law)]), s).ok())
        .collect::<Option<_>>()?;
    let integrator = Dopri5::default();
    let (mut num, mut den) = (vec![0.0; n], vec![0.0; n]);
    let means: Vec<f64> = measured
        .iter()
        .map(|m| m[range.clone()].iter().sum::<f64>() / range.len().max(1) as f64)
        .collect();
    let mut k0 = range.start;
    while k0 + 1 < range.end {
        let k1 = (k0 + horizon).min(range.end);
        let mut x0: Vec<f64> = xs.iter().map(|x| x[k0]).collect();
        let mut v0: Vec<f64> = vs.iter().map(|v| v[k0]).collect();
        x0.resize(compiled.system_dofs(), 0.0);
        v0.extend(tracks.iter().map(|z| z[k0]));
        let tr = integrator
            .integrate(&compiled, &input, &x0, &v0, &t[k0..k1])
            .ok()?;
        for i in 0..n {
            for (j, k) in (k0..k1).enumerate() {
                num[i] += (tr.x[i][j] - measured[i][k]).powi(2);
                den[i] += (measured[i][k] - means[i]).powi(2);
            }
        }
        k0 = k1;
    }
    let r: f64 = num
        .iter()
        .zip(&den)
        .map(|(a, b)| a / b.max(f64::MIN_POSITIVE))
        .sum::<f64>()
        / n.max(1) as f64;
    r.is_finite().then_some(r)
}
