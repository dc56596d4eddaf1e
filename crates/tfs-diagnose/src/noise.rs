//! What measurement noise can explain of an equation residual. The tool's own noise estimate —
//! the power-law floor that `tfs_signal::band` fits to the upper half of each channel's
//! spectrum, the same one identification uses — is carried through what the diagnosis does to
//! the records by `tfs_signal::estimate`: each channel's noise through the equation's linear
//! terms in that channel (the displacement's twice differentiated as the target), low-passed at
//! the cut-off. A residual is called noise only when this says it is the size of the noise.

use serde::Serialize;
use tfs_library::{Factor, Model, Var};
use tfs_signal::band::reconstruct;
use tfs_signal::estimate::{SnrEstimate, derivative_response, residual_noise_var, snr_db};

use crate::prepare::RecordStates;

/// Above this estimated SNR of the displacement (80 dB) the records are called clean.
pub const CLEAN_SNR_DB: f64 = SnrEstimate::CLEAN_DB;

/// The noise estimate of one DOF's equation residual over the records.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseEstimate {
    /// RMS of the residual that measurement noise alone would leave (units of `x''`).
    pub residual_rms: f64,
    /// Estimated SNR of the displacement over the records (dB; `+∞` without a noise estimate),
    /// as identification states it.
    pub snr_db: f64,
    /// True when some record's spectrum shows no noise floor: `snr_db` is then a lower bound.
    pub snr_is_bound: bool,
    /// True when every channel's floor was fitted on noise alone; otherwise the spectrum of some
    /// channel reaches into the band the floor is fitted on, and the estimate is an upper bound.
    pub noise_only: bool,
    /// The cut-offs the residual's `x''` was low-passed at (Hz, lowest and highest over the
    /// records).
    pub band_hz: [f64; 2],
}

impl NoiseEstimate {
    /// True when the estimated noise is at least 80 dB below the displacement.
    pub fn clean(&self) -> bool {
        self.snr_db >= CLEAN_SNR_DB
    }

    /// The displacement SNR in words, as identification prints it: `29.7 dB`, or `at least
    /// 108.5 dB` when it is a bound.
    pub fn snr_words(&self) -> String {
        let db = self.snr_db.min(999.0);
        if self.snr_is_bound {
            format!("at least {db:.1} dB")
        } else {
            format!("{db:.1} dB")
        }
    }
}

/// The linear terms of equation `idx` of `model` per channel, as (channel, [(derivative order,
/// coefficient)]): `x` and `x'` of every DOF, and every input to the first power.
fn linear_terms(model: &Model, idx: usize) -> Vec<(&str, Vec<(usize, f64)>)> {
    let mut out: Vec<(&str, Vec<(usize, f64)>)> = Vec::new();
    for t in &model.equations[idx].terms {
        let (name, order) = match t.term.factors() {
            [Factor::Pow(Var::Disp(n), 1)] | [Factor::Pow(Var::Input(n), 1)] => (n.as_str(), 0),
            [Factor::Pow(Var::Vel(n), 1)] => (n.as_str(), 1),
            _ => continue,
        };
        match out.iter_mut().find(|(n, _)| *n == name) {
            Some((_, v)) => v.push((order, t.coef)),
            None => out.push((name, vec![(order, t.coef)])),
        }
    }
    out
}

/// The noise estimate of the residual of DOF `idx` of `model` on `states` (see the module docs).
pub(crate) fn estimate(model: &Model, idx: usize, states: &[RecordStates]) -> NoiseEstimate {
    let dof = model.dofs[idx].as_str();
    let mut channels = linear_terms(model, idx);
    if !channels.iter().any(|(n, _)| *n == dof) {
        channels.push((dof, Vec::new()));
    }
    let (mut var_sum, mut rows) = (0.0, 0usize);
    let mut noise_only = true;
    let mut own: Vec<(&[f64], tfs_signal::Band)> = Vec::new();
    let mut band_hz = [f64::INFINITY, 0.0f64];
    for s in states {
        let dt = s.record.dt();
        let fc = s.cutoff_hz;
        band_hz = [band_hz[0].min(fc), band_hz[1].max(fc)];
        let mut var = 0.0;
        for (name, terms) in &channels {
            let Some(x) = s.record.column(name) else {
                continue;
            };
            let band = reconstruct(x, dt, None).band;
            noise_only &= band.floor_is_noise_only();
            var += residual_noise_var(&band, dt, *name == dof, terms, fc, derivative_response);
            if *name == dof {
                own.push((x, band));
            }
        }
        let n = s.usable();
        var_sum += var * n as f64;
        rows += n;
    }
    let snr = snr_db(own.iter().map(|(x, b)| (*x, b)));
    NoiseEstimate {
        residual_rms: if rows > 0 {
            (var_sum / rows as f64).sqrt()
        } else {
            0.0
        },
        snr_db: snr.map_or(f64::INFINITY, |s| s.db),
        snr_is_bound: snr.is_some_and(|s| s.lower_bound),
        noise_only,
        band_hz,
    }
}
