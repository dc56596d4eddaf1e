//! Is a record's free-run simulation error informative about the model? [`input_noise_spread`]
//! measures how far the noise on the measured input alone moves a simulation.
//!
//! A simulation is driven by the *measured* input, noise included. For a linear or mildly
//! nonlinear system that noise is filtered away; for a multi-stable one swept through its
//! snap-through range it can decide when (and whether) the structure jumps between wells, so
//! even the true equation simulates far from the measurement. Such a record cannot rank models by
//! free-run error, and fitting coefficients to it (simulation-error refinement) fits that noise:
//! on the paper's cell at 20 dB the refinement turned a model within 1 % of the truth into one
//! with twice its stiffness, because it lowered the free-run error by hedging between wells.

use rayon::prelude::*;
use tfs_data::Record;
use tfs_dynamics::{
    Integrator, SampledInput, SimulateOptions, Trajectory, range_band, simulate_model_on_record,
};
use tfs_library::Model;
use tfs_signal::band::{band_guarded, noise_draw_with};

use crate::Result;

/// Noise draws of [`input_noise_spread`] (their mean square is used).
const DRAWS: u64 = 2;

/// A record's free-run error `E` is taken as dominated by its input noise when the spread `S`
/// that one fresh draw of that noise causes satisfies `2·S² + σ² ≥ E²`, with `σ²` the
/// displacement's own measurement-noise variance: what is left of `E²` once measurement noise
/// is taken out is at least half input-noise response (`S²` estimates the response to the noise
/// the measured input already carries). Fitting coefficients by simulation error then trades
/// model error against that response — it attenuates the model where the noise drives it,
/// the output-error form of errors in variables — instead of correcting the model.
pub const NOISE_SHARE: f64 = 0.5;

/// How far the noise on a record's measured inputs moves the simulation of `model`: per DOF,
/// the RMS difference between the simulation under the measured inputs and under the same
/// inputs plus a fresh draw of their estimated noise (root mean square over two draws).
///
/// Each input's noise is estimated from its own spectrum: the power-law floor that
/// `tfs_signal::band` fits to the upper half of the spectrum (white or coloured), drawn over
/// the whole band. An input whose spectrum reaches into that half (a broadband excitation) has no
/// noise-only floor and is left unperturbed; `Ok(None)` when no input could be perturbed or the
/// model has no inputs. Input columns the record lacks are a simulation error.
///
/// Errors: the simulation under the measured inputs fails (blow-up, missing column); a failure
/// under a perturbed input counts as an infinite spread.
pub fn input_noise_spread(
    model: &Model,
    record: &Record,
    opts: &SimulateOptions,
) -> Result<Option<Vec<f64>>> {
    let base = simulate_model_on_record(model, record, opts)?;
    input_noise_spread_from(model, record, opts, &base)
}

/// [`input_noise_spread`] around a simulation of `model` under `record`'s measured inputs that
/// the caller already has (`base`, from `simulate_model_on_record` with the same `opts`): the
/// same numbers without simulating the record a second time.
///
/// Errors: a perturbed input that cannot be set on the record; a failure under a perturbed
/// input counts as an infinite spread.
pub fn input_noise_spread_from(
    model: &Model,
    record: &Record,
    opts: &SimulateOptions,
    base: &Trajectory,
) -> Result<Option<Vec<f64>>> {
    let dt = record.dt();
    // Each input's noise band, found once (the band a reconstruction would use, without the
    // reconstruction): the draws differ only in their seeds.
    let bands: Vec<Option<_>> = model
        .inputs
        .iter()
        .map(|name| {
            record.column(name).and_then(|col| {
                let mut band = band_guarded(col, dt, None, 0.0);
                // The whole band: a draw of the noise the raw channel carries, not its in-band
                // part.
                band.floor_is_noise_only().then(|| {
                    band.cutoff_hz = f64::INFINITY;
                    band
                })
            })
        })
        .collect();
    // One draw: the record with each input's noise added (its other columns shared, not
    // copied), and whether any input could be perturbed.
    let draw_record = |draw: u64| -> Result<(Record, bool)> {
        let mut r = record.clone();
        let mut perturbed = false;
        for (ci, (name, band)) in model.inputs.iter().zip(&bands).enumerate() {
            let (Some(col), Some(band)) = (record.column(name), band) else {
                continue;
            };
            let seed = 0x5eed_0000 + 97 * ci as u64 + draw;
            // The draw's samples only: its derivatives are not used.
            let Some(noise) = noise_draw_with(band, col.len(), seed, false) else {
                continue;
            };
            let v: Vec<f64> = col.iter().zip(&noise.x).map(|(a, b)| a + b).collect();
            r.set_column(name, v)?;
            perturbed = true;
        }
        Ok((r, perturbed))
    };
    // Without a perturbable input in the first draw there is no spread to measure.
    let (first, perturbed) = draw_record(0)?;
    if !perturbed {
        return Ok(None);
    }
    // The draws are simulated side by side, each run reduced to its per-DOF mean squared
    // difference from `base` as soon as it ends (no trajectory outlives its draw), and summed in
    // draw order (the same sums on any number of threads).
    let mean_squares = |r: &Record| -> Option<Vec<f64>> {
        let tr = simulate_model_on_record(model, r, opts).ok()?;
        Some(
            (0..model.dofs.len())
                .map(|i| {
                    let n = tr.x[i].len().max(1) as f64;
                    tr.x[i]
                        .iter()
                        .zip(&base.x[i])
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum::<f64>()
                        / n
                })
                .collect(),
        )
    };
    let runs: Vec<Option<Vec<f64>>> = (0..DRAWS)
        .into_par_iter()
        .map(|draw| {
            let r = match draw {
                0 => first.clone(),
                _ => draw_record(draw)?.0,
            };
            Ok(mean_squares(&r))
        })
        .collect::<Result<_>>()?;
    drop(first);
    let mut sums = vec![0.0; model.dofs.len()];
    for run in runs {
        match run {
            Some(ms) => {
                for (s, m) in sums.iter_mut().zip(ms) {
                    *s += m;
                }
            }
            None => return Ok(Some(vec![f64::INFINITY; model.dofs.len()])),
        }
    }
    Ok(Some(
        sums.into_iter()
            .map(|s| (s / DRAWS as f64).sqrt())
            .collect(),
    ))
}

/// How far the simulation of `model` parts from itself when only its start moves by what the
/// record cannot resolve: per DOF, the RMS difference between `base` (the free run under the
/// measured inputs from its fitted start, from `simulate_model_on_record` with the same `opts`)
/// and a run under the same inputs from that start with each measured displacement moved by its
/// own measurement-noise standard deviation (`noise_var`, [`displacement_noise_var`]).
///
/// Why that distance: the record gives every displacement sample only to within its noise, so
/// two starts one noise standard deviation apart are equally consistent with it. A free run
/// whose error from the record is about the distance between the runs from two such starts
/// measures where that run's own divergence took it, not how good the model is (a chaotic
/// motion: nearby motions part by themselves, at any input-noise level). For a damped,
/// non-chaotic motion the difference decays and the spread stays well below the noise
/// itself. The distance is the record's own, not a chosen constant.
///
/// `Ok(None)` when no displacement has a noise-only floor (every `noise_var` zero: the record
/// sets no start uncertainty to probe with). A run from the moved start that fails or leaves
/// the record's range ([`SimulateOptions::range`]) counts as an infinite spread.
///
/// Errors: `model` does not compile, or `record` lacks one of its inputs.
pub fn start_spread_from(
    model: &Model,
    record: &Record,
    opts: &SimulateOptions,
    base: &Trajectory,
    noise_var: &[f64],
) -> Result<Option<Vec<f64>>> {
    let n = model.dofs.len();
    let shift: Vec<f64> = (0..n)
        .map(|i| {
            let v = noise_var.get(i).copied().unwrap_or(0.0);
            if v.is_finite() && v > 0.0 {
                v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    if shift.iter().all(|s| *s == 0.0) || base.x.len() < n || base.v.len() < n {
        return Ok(None);
    }
    let compiled = model.compile()?;
    let channels: Vec<Vec<f64>> = compiled
        .input_names()
        .iter()
        .map(|name| {
            record.column(name).map(<[f64]>::to_vec).ok_or_else(|| {
                crate::RefineError::MissingColumn {
                    record: record.source().to_string(),
                    column: name.clone(),
                    available: record.names().join(", "),
                }
            })
        })
        .collect::<Result<_>>()?;
    // The run's own clock and input, as `simulate_model_on_record` sets them: from 0 at the
    // record's first sample.
    let t = record.t();
    let Some(&t0) = t.first() else {
        return Ok(None);
    };
    let t_local: Vec<f64> = t.iter().map(|v| v - t0).collect();
    let input = SampledInput::new(0.0, record.dt(), channels)?;
    let mut x0: Vec<f64> = (0..n)
        .map(|i| base.x[i].first().copied().unwrap_or(0.0) + shift[i])
        .collect();
    let mut v0: Vec<f64> = (0..n)
        .map(|i| base.v[i].first().copied().unwrap_or(0.0))
        .collect();
    // Internal states start at rest, as in the free run.
    x0.resize(compiled.system_dofs(), 0.0);
    v0.resize(compiled.system_dofs(), 0.0);
    // The record's range, widened as the free run's is: a run that leaves it has parted from
    // the record entirely.
    let bands: Vec<(f64, f64)> = match opts.range {
        Some(f) => model
            .dofs
            .iter()
            .map(|d| {
                record
                    .column(d)
                    .map_or((f64::NEG_INFINITY, f64::INFINITY), |y| range_band(y, f))
            })
            .collect(),
        None => Vec::new(),
    };
    let inside = |_: usize, x: &[f64]| {
        bands
            .iter()
            .zip(x)
            .all(|((lo, hi), v)| *v >= *lo && *v <= *hi)
    };
    let run = opts
        .integrator
        .integrate_until(&compiled, &input, &x0, &v0, &t_local, inside);
    let Ok(Some(tr)) = run else {
        return Ok(Some(vec![f64::INFINITY; n]));
    };
    Ok(Some(
        (0..n)
            .map(|i| {
                let len = tr.x[i].len().max(1) as f64;
                (tr.x[i]
                    .iter()
                    .zip(&base.x[i])
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
                    / len)
                    .sqrt()
            })
            .collect(),
    ))
}

/// Per DOF: the variance of the displacement's measurement noise, from the power-law floor
/// that `tfs_signal::band` fits to the upper half of its spectrum (0 where the spectrum
/// reaches into that half, so no noise-only floor exists).
pub fn displacement_noise_var(model: &Model, record: &Record) -> Vec<f64> {
    model
        .dofs
        .iter()
        .map(|d| {
            record.column(d).map_or(0.0, |x| {
                let band = band_guarded(x, record.dt(), None, 0.0);
                if band.floor_is_noise_only() {
                    band.total_noise_var()
                } else {
                    0.0
                }
            })
        })
        .collect()
}

/// What one free run of a model on a record can say about the model: whether the record's own
/// uncertainty moves that run about as far as its error, so that its free-run error cannot rank
/// models or coefficients there ([`FreeRunProbe::dominated`]). One probe for every command that
/// asks (the diagnosis's judge, `compare`, refinement's held-out choice), so they give one
/// verdict on one record; refinement's training records are screened by the input's spread
/// alone (`refine.rs`).
#[derive(Debug, Clone, PartialEq)]
pub struct FreeRunProbe {
    /// Per DOF, the free run's RMS error against the measured displacement (infinite where it
    /// cannot be measured).
    pub error: Vec<f64>,
    /// Per DOF, [`input_noise_spread_from`]: how far a fresh draw of the measured inputs' noise
    /// moves the run; `None` when no input could be perturbed.
    pub input_spread: Option<Vec<f64>>,
    /// Per DOF, [`start_spread_from`]: how far a start moved by each displacement's noise
    /// standard deviation moves the run; `None` when not needed (the input's spread already
    /// decides) or no displacement has a noise-only floor.
    pub start_spread: Option<Vec<f64>>,
    /// Per DOF, [`displacement_noise_var`].
    pub noise_var: Vec<f64>,
    /// The input's noise accounts for the error ([`noise_dominated`]).
    pub by_input: bool,
    /// The run's own divergence accounts for it: in the DOFs whose runs ended farther apart
    /// than the start was moved, the start's spread satisfies [`noise_dominated`].
    pub diverges: bool,
}

impl FreeRunProbe {
    /// The free run cannot rank models on this record: the input's noise or the run's own
    /// divergence moves it about as far as its error.
    pub fn dominated(&self) -> bool {
        self.by_input || self.diverges
    }

    /// The spread that decided, per DOF: the input's when it dominates, else the start's when
    /// the run diverges, else the input's (or the start's when the input has none).
    pub fn spread(&self) -> Option<&[f64]> {
        if !self.by_input && self.diverges {
            return self.start_spread.as_deref();
        }
        self.input_spread
            .as_deref()
            .or(self.start_spread.as_deref())
    }
}

/// Probes the free run `run` of `model` on `record` (from `simulate_model_on_record` with the
/// same `opts`): the input's noise first ([`input_noise_spread_from`]), then, unless that
/// already accounts for the error, a start moved by each displacement's noise standard
/// deviation ([`start_spread_from`]). Only a DOF whose runs end farther apart than the start was
/// moved (RMS over the record above the noise standard deviation), and whose error exceeds that
/// noise, diverges: a damped or neutral run keeps its spread at or below that move, and a run
/// within the measurement noise of the record has no error for a divergence to account for (a
/// lightly damped oscillator on a clean record drifts in phase from a start 1e-8 away by ten
/// times that, and its exact model would otherwise be said not to rank).
///
/// `None` when `record` lacks one of the model's DOF columns, or neither spread can be measured
/// (no perturbable input and no displacement with a noise-only floor); a spread that cannot be
/// computed counts as not measured.
pub fn probe_free_run(
    model: &Model,
    record: &Record,
    opts: &SimulateOptions,
    run: &Trajectory,
) -> Option<FreeRunProbe> {
    let measured: Vec<&[f64]> = model
        .dofs
        .iter()
        .map(|d| record.column(d))
        .collect::<Option<_>>()?;
    let error: Vec<f64> = measured
        .iter()
        .zip(&run.x)
        .map(|(m, x)| tfs_dynamics::rms_error(m, x).unwrap_or(f64::INFINITY))
        .collect();
    let input_spread = input_noise_spread_from(model, record, opts, run)
        .ok()
        .flatten();
    let noise_var = displacement_noise_var(model, record);
    let by_input = input_spread
        .as_ref()
        .is_some_and(|s| noise_dominated(s, &error, &noise_var));
    let start_spread = if by_input {
        None
    } else {
        start_spread_from(model, record, opts, run, &noise_var)
            .ok()
            .flatten()
    };
    if input_spread.is_none() && start_spread.is_none() {
        return None;
    }
    let diverges = start_spread.as_ref().is_some_and(|s| {
        let grown: Vec<usize> = (0..s.len())
            .filter(|&i| s[i] * s[i] > noise_var[i] && error[i] * error[i] > noise_var[i])
            .collect();
        let pick = |v: &[f64]| grown.iter().map(|&i| v[i]).collect::<Vec<f64>>();
        noise_dominated(&pick(s), &pick(&error), &pick(&noise_var))
    });
    Some(FreeRunProbe {
        error,
        input_spread,
        start_spread,
        noise_var,
        by_input,
        diverges,
    })
}

/// True when in some DOF the input-noise spread `spread` ([`input_noise_spread`]) and the
/// displacement's measurement-noise variance `noise_var` ([`displacement_noise_var`]) account
/// for the simulation error `error` (same units) as [`NOISE_SHARE`] describes:
/// `S² ≥ NOISE_SHARE·(E² − σ²)`.
pub fn noise_dominated(spread: &[f64], error: &[f64], noise_var: &[f64]) -> bool {
    spread
        .iter()
        .zip(error)
        .zip(noise_var)
        .any(|((s, e), v)| s * s >= NOISE_SHARE * (e * e - v))
}
