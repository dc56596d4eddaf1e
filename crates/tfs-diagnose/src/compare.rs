//! Compare: simulate the model under each record's measured input; R-MSE per record and per time
//! window, measured vs model amplitude spectra with the drive's harmonics the model misses, and
//! phase-portrait data.

use rayon::prelude::*;
use serde::Serialize;
use tfs_data::Record;
use tfs_dynamics::{Trajectory, rms_error, rmse_ratio, rmse_variance};
use tfs_library::Model;
use tfs_signal::amplitude_spectrum;

use crate::Result;
use crate::prepare::{DiagnoseOptions, check_records, missing};
use crate::simulate::BaseRun;

/// R-MSE over one time window.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WindowScore {
    /// Window start (s).
    pub t0: f64,
    /// Window end (s).
    pub t1: f64,
    /// Mean squared error inside the window over the record's variance (mean over DOFs): the
    /// windows of a record compare with each other and average to its R-MSE.
    pub r_mse: f64,
}

/// One harmonic band of the drive.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Harmonic {
    /// Harmonic order k (band k·[f_lo, f_hi]).
    pub order: usize,
    /// Band limits (Hz), without the drive band itself.
    pub band: (f64, f64),
    /// RMS amplitude of the measured spectrum in the band.
    pub measured: f64,
    /// RMS amplitude of the model's spectrum in the band.
    pub model: f64,
    /// Measured clearly above the noise floor and the model below half of it.
    pub missing: bool,
}

/// Measured vs model amplitude spectra of one DOF.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SpectrumComparison {
    /// The DOF.
    pub dof: String,
    /// Frequencies (Hz).
    pub freqs: Vec<f64>,
    /// Measured amplitudes.
    pub measured: Vec<f64>,
    /// Model amplitudes.
    pub model: Vec<f64>,
    /// Drive band (Hz): where the input spectrum is at least 10 % of its peak.
    pub drive_band: (f64, f64),
    /// Harmonic bands 2..=5 of the drive.
    pub harmonics: Vec<Harmonic>,
}

/// Phase-portrait data of one DOF (at most 4000 points, evenly decimated).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhasePortrait {
    /// The DOF.
    pub dof: String,
    /// Measured (x, x') with the smoothed velocity.
    pub measured: Vec<(f64, f64)>,
    /// Simulated (x, x').
    pub model: Vec<(f64, f64)>,
}

/// The comparison of a model with one record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordComparison {
    /// The record's source.
    pub record: String,
    /// R-MSE per DOF on the measured variance, `mean((x − x̂)²) / var(x)` (None if the
    /// simulation failed).
    pub r_mse: Option<Vec<f64>>,
    /// R-MSE per DOF as the paper's Appendix B defines it, over the mean square
    /// `mean((x − x̂)²) / mean(x²)`, which moves with the record's DC level.
    pub r_mse_mean_square: Option<Vec<f64>>,
    /// RMS error per DOF, in the record's units.
    pub rms_error: Option<Vec<f64>>,
    /// R-MSE per time window.
    pub windows: Vec<WindowScore>,
    /// Spectra per DOF.
    #[serde(skip)]
    pub spectra: Vec<SpectrumComparison>,
    /// Phase portraits per DOF.
    #[serde(skip)]
    pub phase: Vec<PhasePortrait>,
    /// Harmonic orders the model misses, per DOF (`"x: 2, 3"`).
    pub missing_harmonics: Vec<String>,
    /// The simulation error, if it failed (e.g. blow-up).
    pub error: Option<String>,
}

fn band_rms(f: &[f64], a: &[f64], lo: f64, hi: f64, exclude: (f64, f64)) -> (f64, usize) {
    let mut s = 0.0;
    let mut n = 0;
    for (fi, ai) in f.iter().zip(a) {
        if *fi >= lo && *fi <= hi && !(*fi >= exclude.0 && *fi <= exclude.1) {
            s += ai * ai;
            n += 1;
        }
    }
    if n == 0 {
        (0.0, 0)
    } else {
        ((s / n as f64).sqrt(), n)
    }
}

/// Compares `model` with every record.
pub fn compare(
    model: &Model,
    records: &[Record],
    opts: &DiagnoseOptions,
) -> Result<Vec<RecordComparison>> {
    check_records(model, records)?;
    records
        .par_iter()
        .map(|r| compare_one(model, r, opts, None))
        .collect()
}

/// [`compare`] with the model's own simulations of the records ([`crate::simulate::base_runs`]).
pub(crate) fn compare_with_runs(
    model: &Model,
    records: &[Record],
    opts: &DiagnoseOptions,
    runs: &[BaseRun],
) -> Result<Vec<RecordComparison>> {
    check_records(model, records)?;
    records
        .par_iter()
        .zip(runs)
        .map(|(r, run)| compare_one(model, r, opts, run.as_ref()))
        .collect()
}

/// The comparison with one record; `run` is the model's simulation of it when already made.
fn compare_one(
    model: &Model,
    record: &Record,
    opts: &DiagnoseOptions,
    run: Option<&std::result::Result<Trajectory, String>>,
) -> Result<RecordComparison> {
    let dt = record.dt();
    let n = record.len();
    let record_aug = crate::simulate::augment_record(model, record, opts)?;
    let sim = match run {
        Some(run) => run.clone(),
        None => crate::simulate::simulate(model, &record_aug).map_err(|e| e.to_string()),
    };
    let mut out = RecordComparison {
        record: record.source().to_string(),
        r_mse: None,
        r_mse_mean_square: None,
        rms_error: None,
        windows: Vec::new(),
        spectra: Vec::new(),
        phase: Vec::new(),
        missing_harmonics: Vec::new(),
        error: None,
    };
    let tr = match sim {
        Ok(t) => t,
        Err(e) => {
            out.error = Some(e);
            return Ok(out);
        }
    };
    let meas: Vec<&[f64]> = model
        .dofs
        .iter()
        .map(|d| record.column(d).ok_or_else(|| missing(model, record, d)))
        .collect::<Result<_>>()?;
    let (mut r, mut ms, mut e) = (Vec::new(), Vec::new(), Vec::new());
    for (i, m) in meas.iter().enumerate() {
        r.push(rmse_variance(m, &tr.x[i])?);
        ms.push(rmse_ratio(m, &tr.x[i])?);
        e.push(rms_error(m, &tr.x[i])?);
    }
    out.r_mse = Some(r);
    out.r_mse_mean_square = Some(ms);
    out.rms_error = Some(e);
    let var: Vec<f64> = meas
        .iter()
        .map(|m| {
            let mean = m.iter().sum::<f64>() / n as f64;
            (m.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64)
                .max(f64::MIN_POSITIVE)
        })
        .collect();
    let w = opts.windows.min(n / 2).max(1);
    for k in 0..w {
        let (a, b) = (k * n / w, (k + 1) * n / w);
        let mut s = 0.0;
        for (i, m) in meas.iter().enumerate() {
            let num: f64 = (a..b).map(|j| (m[j] - tr.x[i][j]).powi(2)).sum();
            s += num / ((b - a) as f64 * var[i]);
        }
        out.windows.push(WindowScore {
            t0: record.t()[a],
            t1: record.t()[b - 1],
            r_mse: s / meas.len() as f64,
        });
    }
    // Drive band from the input with the largest RMS.
    let input = model
        .inputs
        .iter()
        .filter_map(|i| record_aug.column(i))
        .max_by(|a, b| crate::prepare::rms(a).total_cmp(&crate::prepare::rms(b)));
    let drive = match input {
        Some(u) => {
            let mean = u.iter().sum::<f64>() / n as f64;
            let c: Vec<f64> = u.iter().map(|v| v - mean).collect();
            let (f, a) = amplitude_spectrum(&c, dt)?;
            let peak = a.iter().cloned().fold(0.0, f64::max);
            let idx: Vec<usize> = (1..a.len()).filter(|&k| a[k] >= 0.1 * peak).collect();
            match (idx.first(), idx.last()) {
                (Some(&lo), Some(&hi)) if peak > 0.0 => Some((f[lo], f[hi])),
                _ => None,
            }
        }
        None => None,
    };
    for (i, m) in meas.iter().enumerate() {
        let dof = model.dofs[i].clone();
        let mean = m.iter().sum::<f64>() / n as f64;
        let mc: Vec<f64> = m.iter().map(|v| v - mean).collect();
        let smean = tr.x[i].iter().sum::<f64>() / n as f64;
        let sc: Vec<f64> = tr.x[i].iter().map(|v| v - smean).collect();
        let (f, am) = amplitude_spectrum(&mc, dt)?;
        let (_, asim) = amplitude_spectrum(&sc, dt)?;
        // The median amplitude of the upper half (the noise floor of `crate::prepare`).
        let floor = tfs_signal::NoiseFloor::fit_with(&am, 1, 1.0).at(1);
        let mut harmonics = Vec::new();
        let mut missing_orders = Vec::new();
        if let Some((lo, hi)) = drive {
            for k in 2..=5usize {
                let (blo, bhi) = (k as f64 * lo, k as f64 * hi);
                let (mr, cnt) = band_rms(&f, &am, blo, bhi, (lo, hi));
                if cnt == 0 {
                    continue;
                }
                let (sr, _) = band_rms(&f, &asim, blo, bhi, (lo, hi));
                let missing = mr > opts.floor_factor * floor && sr < 0.5 * mr;
                if missing {
                    missing_orders.push(k.to_string());
                }
                harmonics.push(Harmonic {
                    order: k,
                    band: (blo, bhi),
                    measured: mr,
                    model: sr,
                    missing,
                });
            }
        }
        if !missing_orders.is_empty() {
            out.missing_harmonics
                .push(format!("{dof}: {}", missing_orders.join(", ")));
        }
        out.spectra.push(SpectrumComparison {
            dof: dof.clone(),
            freqs: f,
            measured: am,
            model: asim,
            drive_band: drive.unwrap_or((f64::NAN, f64::NAN)),
            harmonics,
        });
        let fc = crate::prepare::choose_cutoff(m, dt, opts.floor_factor)?;
        let v = tfs_signal::spectral_derivative(m, dt, 1, Some(opts.cutoff_hz.unwrap_or(fc)))?;
        let step = n.div_ceil(4000).max(1);
        out.phase.push(PhasePortrait {
            dof,
            measured: (0..n).step_by(step).map(|j| (m[j], v[j])).collect(),
            model: (0..n)
                .step_by(step)
                .map(|j| (tr.x[i][j], tr.v[i][j]))
                .collect(),
        });
    }
    Ok(out)
}
