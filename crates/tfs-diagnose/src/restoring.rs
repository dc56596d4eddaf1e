//! The force–displacement loop: the restoring force measured from a record against models'.
//!
//! For `x'' = Σ c·term`, the restoring force per unit mass is everything but the input:
//! `r = Σ_input c·u − x''` measured (smoothed `x''`, the inputs as recorded), and
//! `r_model = −Σ_other c·term` for a model (evaluated on the smoothed states, internal states
//! along the smoothed velocity). With a force input `u` of coefficient `1/m` the loop is drawn in
//! the units of `u` (times `m` of the last model given): the restoring force `u − m·x''`, a
//! hysteresis loop where the structure has memory, a line where it has none.

use serde::Serialize;
use tfs_data::{Columns, Record};
use tfs_library::{ColumnSet, Factor, Model, Var, evaluate_term};

use crate::prepare::{DiagnoseOptions, RecordStates, dominant_period};
use crate::{DiagnoseError, Result};

/// A restoring-force loop of one DOF over a window of one record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RestoringLoop {
    /// The DOF.
    pub dof: String,
    /// The record's source.
    pub record: String,
    /// What the force axis is, with its units.
    pub force_label: String,
    /// Start and end of the window (s).
    pub window: (f64, f64),
    /// Smoothed displacement over the window.
    pub x: Vec<f64>,
    /// Measured restoring force over the window.
    pub measured: Vec<f64>,
    /// Per model (its label): the model's restoring force over the window.
    pub models: Vec<(String, Vec<f64>)>,
}

/// The plain input terms of an equation: `(input name, coefficient)`.
fn input_terms(model: &Model, idx: usize) -> Vec<(String, f64)> {
    model.equations[idx]
        .terms
        .iter()
        .filter_map(|t| match t.term.factors() {
            [Factor::Pow(Var::Input(n), 1)] => Some((n.clone(), t.coef)),
            _ => None,
        })
        .collect()
}

/// The restoring force per unit mass of equation `idx` of `model` on every row of `s`.
fn model_force(model: &Model, idx: usize, s: &RecordStates) -> Result<Vec<f64>> {
    let set = ColumnSet::new(s);
    let mut out = vec![0.0; s.rows()];
    for t in &model.equations[idx].terms {
        if matches!(t.term.factors(), [Factor::Pow(Var::Input(_), 1)]) {
            continue;
        }
        for (o, v) in out.iter_mut().zip(evaluate_term(&t.term, &set)?) {
            *o -= t.coef * v;
        }
    }
    Ok(out)
}

/// The loop of DOF `dof` of the `models` (label, model; the last one sets the force scale) on
/// `record`, over three dominant periods around the largest excursion of the displacement.
pub fn restoring_loop(
    models: &[(&str, &Model)],
    record: &Record,
    dof: &str,
    opts: &DiagnoseOptions,
) -> Result<RestoringLoop> {
    let Some(&(_, last)) = models.last() else {
        return Err(DiagnoseError::InvalidParameter {
            name: "models",
            reason: "give at least one model to draw a restoring-force loop".into(),
        });
    };
    let idx =
        last.dofs
            .iter()
            .position(|d| d == dof)
            .ok_or_else(|| DiagnoseError::InvalidParameter {
                name: "dof",
                reason: format!(
                    "'{dof}' is not one of the model's DOFs [{}]",
                    last.dofs.join(", ")
                ),
            })?;
    let states: Vec<RecordStates> = models
        .iter()
        .map(|(_, m)| RecordStates::new(m, record, opts))
        .collect::<Result<_>>()?;
    let s = &states[states.len() - 1];
    let x = s.column(dof).unwrap_or(&[]).to_vec();
    let (lo, hi) = (s.margin, s.margin + s.usable());
    let dt = record.dt();
    // The window: three dominant periods around the largest excursion of the usable rows.
    let period = dominant_period(&x, dt)?;
    let half = ((1.5 * period / dt).round() as usize).max(8);
    let mean = x[lo..hi].iter().sum::<f64>() / (hi - lo).max(1) as f64;
    let peak = (lo..hi)
        .max_by(|&a, &b| (x[a] - mean).abs().total_cmp(&(x[b] - mean).abs()))
        .unwrap_or(lo);
    let a = peak.saturating_sub(half).max(lo);
    let b = (a + 2 * half).min(hi);
    let inputs = input_terms(last, idx);
    // The scale: the mass 1/c_u of a single force input, else per unit mass.
    let (scale, force_label) = match inputs.as_slice() {
        [(name, c)] if *c != 0.0 => (
            1.0 / c,
            format!(
                "restoring force {name} - m*{dof}'' (units of {name}; m = {:.4})",
                1.0 / c
            ),
        ),
        _ => (
            1.0,
            format!("restoring force per unit mass (units of {dof} per s^2)"),
        ),
    };
    let mut measured = vec![0.0; b - a];
    for (name, c) in &inputs {
        let u = record
            .column(name)
            .ok_or_else(|| crate::prepare::missing(last, record, name))?;
        for (m, v) in measured.iter_mut().zip(&u[a..b]) {
            *m += c * v;
        }
    }
    for (m, acc) in measured.iter_mut().zip(&s.acc[idx][a..b]) {
        *m = scale * (*m - acc);
    }
    let mut curves = Vec::with_capacity(models.len());
    for ((label, m), st) in models.iter().zip(&states) {
        let i = m.dofs.iter().position(|d| d == dof).unwrap_or(idx);
        let f = model_force(m, i, st)?;
        curves.push((
            label.to_string(),
            f[a..b].iter().map(|v| scale * v).collect(),
        ));
    }
    Ok(RestoringLoop {
        dof: dof.to_string(),
        record: record.source().to_string(),
        force_label,
        window: (record.t()[a], record.t()[b - 1]),
        x: x[a..b].to_vec(),
        measured,
        models: curves,
    })
}
