//! Simulating models that use computed effect columns, and R-MSE helpers.
//!
//! A delayed or low-pass filtered input is an ordinary input computed from the record ([`augment_record`]). A Maxwell
//! column depends on the *simulated* velocity, so [`simulate`] integrates each Maxwell filter as
//! an extra state: an auxiliary coordinate `p` with `p'' = (x' − p')/τ`, whose velocity `p'` is
//! the filtered velocity. Its initial value comes from the record's column (computed from the
//! measured, smoothed velocity by [`augment_record`]).

use tfs_data::Record;
use tfs_dynamics::{
    Dopri5, Integrator, SampledInput, SecondOrderSystem, SimulateOptions, Trajectory,
    choose_initial_state, initial_velocity, rmse_variance, simulate_model_on_record,
};
use tfs_library::{CompiledModel, Model};
use tfs_signal::spectral_derivative;

use crate::effects::{ComputedColumn, computed_columns};
use crate::prepare::{DiagnoseOptions, choose_cutoff, missing};
use crate::{DiagnoseError, Result};

/// Adds every computed column `model` needs to a copy of `record` (existing columns are kept).
/// Maxwell columns filter the velocity estimated with the spectral differentiator (cut-off from
/// `opts`, or chosen from the spectrum); delays shift the record's input column.
pub fn augment_record(model: &Model, record: &Record, opts: &DiagnoseOptions) -> Result<Record> {
    let mut out = record.clone();
    let dt = record.dt();
    for c in computed_columns(model) {
        if out.column(&c.name()).is_some() {
            continue;
        }
        let values = match &c {
            ComputedColumn::Maxwell { dof, .. } => {
                let x = record
                    .column(dof)
                    .ok_or_else(|| missing(model, record, dof))?;
                let fc = match opts.cutoff_hz {
                    Some(f) => f,
                    None => choose_cutoff(x, dt, opts.floor_factor)?,
                };
                let v = spectral_derivative(x, dt, 1, Some(fc))?;
                let tmp = Record::new("tmp", record.t().to_vec(), vec![(c.source(), v)])?;
                c.compute(&tmp, dt)?
            }
            ComputedColumn::Delayed { input, .. } | ComputedColumn::Lowpass { input, .. } => {
                if record.column(input).is_none() {
                    return Err(missing(model, record, input));
                }
                c.compute(record, dt)?
            }
        };
        out.set_column(c.name(), values)?;
    }
    Ok(out)
}

/// The model plus one first-order filter state per Maxwell column.
struct MaxwellSystem<'a> {
    inner: &'a CompiledModel,
    n: usize,
    /// Per auxiliary state: (DOF index, 1/τ, slot in the inner input vector).
    aux: Vec<(usize, f64, usize)>,
    /// Inner input slot of each external channel.
    external: Vec<usize>,
}

impl SecondOrderSystem for MaxwellSystem<'_> {
    fn dofs(&self) -> usize {
        self.n + self.aux.len()
    }
    fn inputs(&self) -> usize {
        self.external.len()
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        let k = self.inner.inputs();
        let mut stack = [0.0f64; 32];
        let mut heap;
        let ui: &mut [f64] = if k <= 32 {
            &mut stack[..k]
        } else {
            heap = vec![0.0; k];
            &mut heap
        };
        for (c, &slot) in self.external.iter().enumerate() {
            ui[slot] = u[c];
        }
        for (j, &(_, _, slot)) in self.aux.iter().enumerate() {
            ui[slot] = v[self.n + j];
        }
        self.inner
            .accel(&x[..self.n], &v[..self.n], ui, &mut a[..self.n]);
        for (j, &(d, inv_tau, _)) in self.aux.iter().enumerate() {
            a[self.n + j] = (v[d] - v[self.n + j]) * inv_tau;
        }
    }
}

/// Simulates `model` under `record`'s inputs at its sample times (the record is augmented with
/// computed columns first when they are missing, using default options). Models without
/// computed columns go straight to `tfs_dynamics::simulate_model_on_record`.
pub fn simulate(model: &Model, record: &Record) -> Result<Trajectory> {
    let computed = computed_columns(model);
    if computed.is_empty() {
        return Ok(simulate_model_on_record(
            model,
            record,
            &SimulateOptions::default(),
        )?);
    }
    let record = augment_record(model, record, &DiagnoseOptions::default())?;
    let compiled = model.compile()?;
    let n = compiled.dofs();
    let dt = record.dt();
    let t = record.t();
    if record.len() < 2 {
        return Err(DiagnoseError::TooShort {
            what: record.source().to_string(),
            got: record.len(),
            needed: 2,
        });
    }
    let mut aux = Vec::new();
    let mut external = Vec::new();
    let mut channels = Vec::new();
    let mut x0 = Vec::new();
    let mut v0 = Vec::new();
    for dof in compiled.dof_names() {
        let col = record
            .column(dof)
            .ok_or_else(|| missing(model, &record, dof))?;
        x0.push(col[0]);
        v0.push(initial_velocity(col, dt, 5)?);
    }
    let mut aux_v0 = Vec::new();
    for (slot, name) in compiled.input_names().iter().enumerate() {
        let col = record
            .column(name)
            .ok_or_else(|| missing(model, &record, name))?;
        match ComputedColumn::parse(name, &model.dofs) {
            Some(ComputedColumn::Maxwell { dof, tau }) => {
                let d = model.dofs.iter().position(|x| *x == dof).unwrap_or(0);
                aux.push((d, 1.0 / tau, slot));
                aux_v0.push(col[0]);
            }
            _ => {
                external.push(slot);
                channels.push(col.to_vec());
            }
        }
    }
    let sys = MaxwellSystem {
        inner: &compiled,
        n,
        aux,
        external,
    };
    let input = if channels.is_empty() {
        SampledInput::zero(0)
    } else {
        SampledInput::new(t[0], dt, channels)?
    };
    x0.extend(std::iter::repeat_n(0.0, aux_v0.len()));
    v0.extend(aux_v0);
    // The measured DOFs' start fitted to the record, as for models without a Maxwell column.
    let measured: Vec<&[f64]> = compiled
        .dof_names()
        .iter()
        .map(|d| record.column(d).ok_or_else(|| missing(model, &record, d)))
        .collect::<Result<_>>()?;
    let (x0, v0) = choose_initial_state(
        SimulateOptions::default().initial_state,
        &sys,
        &Dopri5::default(),
        &input,
        &measured,
        t,
        x0,
        v0,
    )?;
    let mut tr = Dopri5::default().integrate(&sys, &input, &x0, &v0, t)?;
    tr.x.truncate(n);
    tr.v.truncate(n);
    Ok(tr)
}

/// R-MSE of a simulation of `model` on `record` on each DOF's variance (its mean removed, so
/// the record's DC level does not flatter or penalise the score), averaged over the DOFs.
pub fn r_mse(model: &Model, record: &Record) -> Result<f64> {
    let tr = simulate(model, record)?;
    let mut s = 0.0;
    for (i, d) in model.dofs.iter().enumerate() {
        let m = record.column(d).ok_or_else(|| missing(model, record, d))?;
        s += rmse_variance(m, &tr.x[i])?;
    }
    Ok(s / model.dofs.len().max(1) as f64)
}
