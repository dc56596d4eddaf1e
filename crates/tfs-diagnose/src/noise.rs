//! What measurement noise can explain of an equation residual. The tool's own noise estimate —
//! the power-law floor that `tfs_signal::band` fits to the upper half of each channel's
//! spectrum — is carried through what the diagnosis does to the records: the displacement's
//! noise differentiated twice and low-passed at the cut-off, plus each input's noise through its
//! coefficient. A residual is called noise only when this says it is the size of the noise.

use serde::Serialize;
use tfs_library::{Factor, Model, Var};
use tfs_signal::band::{Band, reconstruct};

use crate::prepare::RecordStates;

/// Below this estimated noise power (relative to the displacement's variance: 80 dB) the records
/// are called clean.
pub const CLEAN_SNR_DB: f64 = 80.0;

/// The noise estimate of one DOF's equation residual over the records.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseEstimate {
    /// RMS of the residual that measurement noise alone would leave (units of `x''`).
    pub residual_rms: f64,
    /// Estimated SNR of the displacement (dB; the lowest over the records, `+∞` with no floor).
    pub snr_db: f64,
    /// True when every channel's floor was fitted on noise alone; otherwise the spectrum of some
    /// channel reaches into the band the floor is fitted on, and the estimate is an upper bound.
    pub noise_only: bool,
}

impl NoiseEstimate {
    /// True when the estimated noise is at least 80 dB below the displacement.
    pub fn clean(&self) -> bool {
        self.snr_db >= CLEAN_SNR_DB
    }
}

/// `2·∫₀^fc PSD(f)·(2πf)^(2·order) df` over the band's bins: the variance of the noise after
/// `order` derivatives and a low-pass at `fc`.
fn band_variance(band: &Band, dt: f64, fc: f64, order: i32) -> f64 {
    if band.bin_hz <= 0.0 {
        return 0.0;
    }
    let kc = (fc / band.bin_hz).floor() as usize;
    (1..=kc)
        .map(|k| {
            let f = k as f64 * band.bin_hz;
            band.noise_psd(f, dt) * (2.0 * std::f64::consts::PI * f).powi(2 * order)
        })
        .sum::<f64>()
        * 2.0
        * band.bin_hz
}

/// The noise estimate of the residual of DOF `idx` of `model` on `states` (see the module docs).
pub(crate) fn estimate(model: &Model, idx: usize, states: &[RecordStates]) -> NoiseEstimate {
    let dof = &model.dofs[idx];
    // The plain input terms of the equation and their coefficients.
    let inputs: Vec<(&str, f64)> = model.equations[idx]
        .terms
        .iter()
        .filter_map(|t| match t.term.factors() {
            [Factor::Pow(Var::Input(n), 1)] => Some((n.as_str(), t.coef)),
            _ => None,
        })
        .collect();
    let (mut var_sum, mut rows) = (0.0, 0usize);
    let mut snr_db = f64::INFINITY;
    let mut noise_only = true;
    for s in states {
        let dt = s.record.dt();
        let fc = s.cutoff_hz;
        let Some(x) = s.record.column(dof) else {
            continue;
        };
        let band = reconstruct(x, dt, None).band;
        noise_only &= band.floor_is_noise_only();
        let mut var = band_variance(&band, dt, fc, 2);
        let mean = x.iter().sum::<f64>() / x.len().max(1) as f64;
        let signal = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / x.len().max(1) as f64;
        let noise = band.total_noise_var();
        if noise > 0.0 && signal > 0.0 {
            snr_db = snr_db.min(10.0 * (signal / noise).log10());
        }
        for (name, c) in &inputs {
            if let Some(u) = s.record.column(name) {
                let ub = reconstruct(u, dt, None).band;
                noise_only &= ub.floor_is_noise_only();
                var += c * c * band_variance(&ub, dt, fc, 0);
            }
        }
        let n = s.usable();
        var_sum += var * n as f64;
        rows += n;
    }
    NoiseEstimate {
        residual_rms: if rows > 0 {
            (var_sum / rows as f64).sqrt()
        } else {
            0.0
        },
        snr_db,
        noise_only,
    }
}
