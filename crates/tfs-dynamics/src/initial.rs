//! Initial states of a simulation estimated from noisy measurements: the model's own response
//! fitted to the first periods of the record (the usual practice of system identification when a
//! model is compared with data), instead of a derivative of the first few samples.
//!
//! Why it matters: at 20 dB SNR the first five samples of a displacement give a velocity off by
//! several times the signal's own velocity scale, and a multi-stable model started there can jump
//! into the other well and stay in it: the paper's own cell, simulated with its *true* equation,
//! then showed a test R-MSE of 33 % against a noise floor of 1 %.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::{DynError, Integrator, Result, SampledInput, SecondOrderSystem, Trajectory};

/// How a simulation of a measured record chooses its initial state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InitialState {
    /// `x(t₀)` is the first sample; `v(t₀)` comes from the record's velocity column or from a
    /// least-squares quadratic through the first few samples ([`crate::initial_velocity`]).
    /// Exact on clean data; on noisy data the velocity carries the noise amplified by `1/dt`.
    FirstSamples,
    /// Starts from [`InitialState::FirstSamples`]' state and from a smoothed one (a quadratic
    /// through the first quarter period), then fits the displacements and velocities of the
    /// measured DOFs by Levenberg–Marquardt so that the model's simulation matches the measured
    /// displacements over the first `periods` periods of the record (period: from crossings of
    /// the displacement about its mean, with hysteresis so noise does not count). The best of the
    /// two fits is used. The default, with `periods = 2`.
    Fitted {
        /// Length of the fitted stretch in periods of the displacement (> 0).
        periods: f64,
    },
}

impl Default for InitialState {
    fn default() -> Self {
        Self::Fitted { periods: 2.0 }
    }
}

/// Result of [`fit_initial_state`].
#[derive(Debug, Clone, PartialEq)]
pub struct InitialFit {
    /// Fitted initial displacements (all DOFs of the system; unmeasured ones as given).
    pub x0: Vec<f64>,
    /// Fitted initial velocities (all DOFs of the system; unmeasured ones as given).
    pub v0: Vec<f64>,
    /// Mean squared scaled misfit over the stretch from the given start (`+∞` if it blew up).
    pub cost_start: f64,
    /// The same for the fitted start; never above `cost_start`.
    pub cost: f64,
    /// Whether the fit ended at a minimum: no step could remove a share √ε of the cost. False
    /// when it stopped at its iteration limit, where the Jacobian could not be taken, or where
    /// the start blew up.
    pub converged: bool,
}

/// Least-squares quadratic through the first `m` samples of `y` (a line for `m = 2`), in
/// orthogonal polynomials on the sample grid: its value and slope (per second) at the first
/// sample. Exact for quadratics.
pub(crate) fn start_of(y: &[f64], dt: f64, m: usize) -> (f64, f64) {
    let m = m.min(y.len()).max(1);
    if m == 1 {
        return (y[0], 0.0);
    }
    let s_bar = (m - 1) as f64 / 2.0;
    let p1: Vec<f64> = (0..m).map(|k| k as f64 - s_bar).collect();
    let mean = y[..m].iter().sum::<f64>() / m as f64;
    let a1 =
        p1.iter().zip(y).map(|(p, y)| p * y).sum::<f64>() / p1.iter().map(|p| p * p).sum::<f64>();
    let (mut value, mut slope) = (mean + a1 * (-s_bar), a1);
    if m >= 3 {
        let c = p1.iter().map(|p| p * p).sum::<f64>() / m as f64;
        let p2: Vec<f64> = p1.iter().map(|p| p * p - c).collect();
        let a2 = p2.iter().zip(y).map(|(p, y)| p * y).sum::<f64>()
            / p2.iter().map(|p| p * p).sum::<f64>();
        // At s = 0: (s − s̄)² − c = s̄² − c, and its derivative is −2 s̄.
        value += a2 * (s_bar * s_bar - c);
        slope += a2 * (-2.0 * s_bar);
    }
    (value, slope / dt)
}

/// Period of `y` in samples from its crossings of the mean with hysteresis: half its standard
/// deviation, or three times the sample-to-sample noise of `y` ([`sample_noise`]) when that is
/// larger, so that noise does not add crossings (white noise alone passes from above `+3σ` to
/// below `−3σ` a few times in ten thousand samples); `None` with fewer than two crossings or a
/// constant signal.
pub(crate) fn period_samples(y: &[f64]) -> Option<f64> {
    let n = y.len() as f64;
    if y.len() < 4 {
        return None;
    }
    let mean = y.iter().sum::<f64>() / n;
    let sd = (y.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt();
    if !(sd > 0.0 && sd.is_finite()) {
        return None;
    }
    let band = (0.5 * sd).max(3.0 * sample_noise(y));
    let (hi, lo) = (mean + band, mean - band);
    let mut state = 0i8;
    let mut crossings = 0usize;
    let (mut first, mut last) = (0usize, 0usize);
    for (k, &v) in y.iter().enumerate() {
        let s = if v > hi {
            1
        } else if v < lo {
            -1
        } else {
            continue;
        };
        if state != 0 && s != state {
            if crossings == 0 {
                first = k;
            }
            crossings += 1;
            last = k;
        }
        state = s;
    }
    // Two crossings per period, measured between the first and the last one.
    (crossings >= 3).then(|| 2.0 * (last - first) as f64 / (crossings - 1) as f64)
}

/// The standard deviation of white noise on `y` that its second differences allow:
/// `√(mean((y[k+1] − 2y[k] + y[k−1])²)/6)` (white noise of variance σ² gives second differences
/// of mean square 6σ²). Motion sampled finely has small second differences, so this is the
/// noise's level on a well-sampled record and an upper bound otherwise; it only sets how far
/// `period_samples` makes a crossing go.
pub(crate) fn sample_noise(y: &[f64]) -> f64 {
    if y.len() < 3 {
        return 0.0;
    }
    let ss: f64 = y
        .windows(3)
        .map(|w| {
            let d = w[2] - 2.0 * w[1] + w[0];
            d * d
        })
        .sum();
    (ss / (y.len() - 2) as f64 / 6.0).sqrt()
}

/// Samples of the fitted stretch for [`InitialState::Fitted`]: `periods` periods of the
/// measured displacement with the most crossings (`period_samples`), or a tenth of the record
/// when none oscillates; at least 16 samples (or the whole record if shorter).
pub fn fit_horizon(measured: &[&[f64]], periods: f64) -> usize {
    let n = measured.iter().map(|m| m.len()).min().unwrap_or(0);
    let period = measured
        .iter()
        .filter_map(|m| period_samples(m))
        .fold(f64::INFINITY, f64::min);
    let h = if period.is_finite() {
        (periods * period).round() as usize
    } else {
        n / 10
    };
    h.max(16).min(n)
}

/// Fits the initial displacements and velocities of the first `measured.len()` DOFs of `sys` so
/// that its simulation under `input` matches `measured` at the times `t` (one slice per DOF, each
/// at least `t.len()` long): Levenberg–Marquardt on residuals scaled by each DOF's standard
/// deviation, Marquardt's damping ladder and NL2SOL's secant estimate of the Hessian's
/// second-order part (the residuals of a wrong model are as large as the motion), starting from
/// `(x0, v0)` (all DOFs; the others stay as given). When the system has the Jacobian of its
/// acceleration ([`SecondOrderSystem::accel_jacobian`]), the residuals' Jacobian comes from the
/// variational equation integrated along the samples of the run it is taken at (two
/// evaluations of the acceleration's Jacobian per sample), so an iteration costs its trial runs
/// and little more; otherwise by forward differences (two more whole runs per fitted DOF and
/// iteration). It ends where a step's fall, actual or predicted, is below a share √ε (1.49e-8)
/// of the cost. A start that blows up has cost `+∞` and is returned unchanged.
///
/// Errors: `measured` longer than the system's DOFs, or a slice shorter than `t`; a run that
/// exhausts the integrator's step budget ([`DynError::TooManySteps`]: the model is too stiff or
/// discontinuous to simulate) stops the fit with that error.
#[allow(clippy::too_many_arguments)]
pub fn fit_initial_state<S: SecondOrderSystem + ?Sized, I: Integrator + Sync>(
    sys: &S,
    integrator: &I,
    input: &SampledInput,
    measured: &[&[f64]],
    t: &[f64],
    x0: &[f64],
    v0: &[f64],
) -> Result<InitialFit> {
    let fit = StartFit::new(sys, integrator, input, measured, t, x0, v0)?;
    let derivatives = if fit.has_sensitivities() {
        Derivatives::Sensitivities
    } else {
        Derivatives::Differences
    };
    fit.solve(derivatives)
}

/// How [`StartFit`] takes the Jacobian of its residuals.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Derivatives {
    /// The variational equation along the run's own samples ([`StartFit::along`]).
    Sensitivities,
    /// Forward differences of whole runs ([`StartFit::differences`]).
    Differences,
}

/// One start-state fit of [`fit_initial_state`]: the system, the stretch it is fitted on, and
/// the scales of its unknowns (each fitted displacement by its DOF's standard deviation over the
/// stretch, each velocity by the same over the stretch's duration).
pub(crate) struct StartFit<'a, S: ?Sized, I> {
    sys: &'a S,
    integrator: &'a I,
    input: &'a SampledInput,
    measured: &'a [&'a [f64]],
    t: &'a [f64],
    x0: &'a [f64],
    v0: &'a [f64],
    sx: Vec<f64>,
    sv: Vec<f64>,
    /// A run that exhausted its step budget: the model cannot be simulated at this tolerance
    /// (stiff or discontinuous), whatever its start, so the fit stops and returns that error at
    /// once rather than spending a budget on every trial start.
    over_budget: std::sync::Mutex<Option<DynError>>,
}

impl<'a, S: SecondOrderSystem + ?Sized, I: Integrator + Sync> StartFit<'a, S, I> {
    /// Checks the dimensions and sets the scales.
    pub(crate) fn new(
        sys: &'a S,
        integrator: &'a I,
        input: &'a SampledInput,
        measured: &'a [&'a [f64]],
        t: &'a [f64],
        x0: &'a [f64],
        v0: &'a [f64],
    ) -> Result<Self> {
        let m = measured.len();
        if m > sys.dofs() || x0.len() != sys.dofs() || v0.len() != sys.dofs() {
            return Err(DynError::Dimension {
                name: "measured",
                got: m,
                expected: sys.dofs(),
                hint: "give at most one measured displacement per DOF and a full initial state",
            });
        }
        if let Some(short) = measured.iter().find(|y| y.len() < t.len()) {
            return Err(DynError::Dimension {
                name: "measured",
                got: short.len(),
                expected: t.len(),
                hint: "every measured displacement needs a sample at every fitted time",
            });
        }
        // Scales: each DOF's standard deviation over the stretch (its mean magnitude if
        // constant); velocities by the same over the stretch's duration.
        let dur = (t.last().copied().unwrap_or(0.0) - t.first().copied().unwrap_or(0.0))
            .max(f64::MIN_POSITIVE);
        let sx: Vec<f64> = measured
            .iter()
            .map(|y| {
                let y = &y[..t.len()];
                let n = y.len() as f64;
                let mean = y.iter().sum::<f64>() / n;
                let sd = (y.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt();
                if sd > 0.0 && sd.is_finite() {
                    sd
                } else {
                    mean.abs().max(1.0)
                }
            })
            .collect();
        let sv: Vec<f64> = sx.iter().map(|s| s * std::f64::consts::TAU / dur).collect();
        Ok(Self {
            sys,
            integrator,
            input,
            measured,
            t,
            x0,
            v0,
            sx,
            sv,
            over_budget: std::sync::Mutex::new(None),
        })
    }

    /// Whether the system gives the Jacobian of its acceleration (asked at the given start).
    pub(crate) fn has_sensitivities(&self) -> bool {
        let n = self.sys.dofs();
        if n == 0 || self.t.len() < 2 {
            return false;
        }
        let mut u = vec![0.0; self.input.channels()];
        self.input.eval(self.t[0], &mut u);
        let (mut a, mut ax, mut av) = (vec![0.0; n], vec![0.0; n * n], vec![0.0; n * n]);
        self.sys
            .accel_jacobian(self.t[0], self.x0, self.v0, &u, &mut a, &mut ax, &mut av)
    }

    /// Fitted DOFs.
    fn m(&self) -> usize {
        self.measured.len()
    }

    /// The full initial state of the scaled unknowns `p`.
    fn to_state(&self, p: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let m = self.m();
        let (mut x, mut v) = (self.x0.to_vec(), self.v0.to_vec());
        for i in 0..m {
            x[i] = p[i] * self.sx[i];
            v[i] = p[m + i] * self.sv[i];
        }
        (x, v)
    }

    /// The scaled unknowns of the given start.
    fn start(&self) -> Vec<f64> {
        let m = self.m();
        (0..m)
            .map(|i| self.x0[i] / self.sx[i])
            .chain((0..m).map(|i| self.v0[i] / self.sv[i]))
            .collect()
    }

    /// The scaled residuals of the run from `p` and the run, or `None` when it fails or when
    /// its mean squared residual is sure to reach `bound` (a trial step's current cost;
    /// infinite for the runs that are always used whole): the sum of squares only grows, so a
    /// trial is given up at the first sample where one DOF's running sum reaches it, with the
    /// same accept/reject as the whole run would get (the cost's sum runs DOF by DOF, each from
    /// the one before, so it is at least any one DOF's running sum).
    pub(crate) fn run(&self, p: &[f64], bound: f64) -> Option<(Vec<f64>, Trajectory)> {
        match self.over_budget.lock() {
            Ok(e) if e.is_none() => {}
            _ => return None,
        }
        let (m, t, measured, sx) = (self.m(), self.t, self.measured, &self.sx);
        let nr = (m * t.len()).max(1) as f64;
        let (x, v) = self.to_state(p);
        let run = if bound.is_finite() {
            let mut sums = vec![0.0f64; m];
            let keep_going = |k: usize, x: &[f64]| {
                for (i, s) in sums.iter_mut().enumerate() {
                    let r = (x[i] - measured[i][k]) / sx[i];
                    *s += r * r;
                    if *s / nr >= bound {
                        return false;
                    }
                }
                true
            };
            self.integrator
                .integrate_until(self.sys, self.input, &x, &v, t, keep_going)
        } else {
            self.integrator
                .integrate(self.sys, self.input, &x, &v, t)
                .map(Some)
        };
        let tr = match run {
            Ok(Some(tr)) => tr,
            Ok(None) => return None,
            Err(e @ DynError::TooManySteps { .. }) => {
                if let Ok(mut slot) = self.over_budget.lock() {
                    slot.get_or_insert(e);
                }
                return None;
            }
            Err(_) => return None,
        };
        let mut r = Vec::with_capacity(m * t.len());
        for i in 0..m {
            for (a, b) in tr.x[i].iter().zip(measured[i]) {
                r.push((a - b) / sx[i]);
            }
        }
        r.iter().all(|v| v.is_finite()).then_some((r, tr))
    }

    /// The forward-difference Jacobian at `p` (residuals `r`): its columns' runs side by side
    /// (a fit is otherwise the last, serial, piece of work while a core idles).
    pub(crate) fn differences(&self, p: &[f64], r: &[f64]) -> Option<DMatrix<f64>> {
        let np = p.len();
        let columns: Vec<Option<(f64, Vec<f64>)>> = (0..np)
            .into_par_iter()
            .map(|j| {
                let mut q = p.to_vec();
                let h = STEP * p[j].abs().max(1.0);
                q[j] += h;
                self.run(&q, f64::INFINITY).map(|(rq, _)| (h, rq))
            })
            .collect();
        let columns = columns.into_iter().collect::<Option<Vec<_>>>()?;
        let mut jac = DMatrix::<f64>::zeros(r.len(), np);
        for (j, (h, rq)) in columns.into_iter().enumerate() {
            for (k, (a, b)) in rq.iter().zip(r).enumerate() {
                jac[(k, j)] = (a - b) / h;
            }
        }
        Some(jac)
    }

    /// The Jacobian of the residuals of the run `tr` (from the unknowns `p`) by the variational
    /// equation along its own samples: the sensitivities `S = ∂(x, v)/∂p` start as the scales
    /// of the unknowns in their coordinates and go from sample to sample by the classical
    /// Runge–Kutta step of `S' = [[0, I], [A_x, A_v]]·S`, the acceleration's Jacobians
    /// ([`SecondOrderSystem::accel_jacobian`]) taken at the run's samples and at the midpoint
    /// state of the cubic through the two samples' states and accelerations (Hermite's: an
    /// error of the fourth order in the sample interval). No run beyond the run itself: per
    /// sample two evaluations of the Jacobians, where forward differences take two more whole
    /// runs (each several evaluations of the acceleration per sample) per fitted DOF. `None`
    /// when a sensitivity is not finite.
    pub(crate) fn along(&self, tr: &Trajectory) -> Option<DMatrix<f64>> {
        let (m, t) = (self.m(), self.t);
        let n = self.sys.dofs();
        let (len, q, n2) = (t.len(), 2 * m, 2 * n);
        let mut jac = DMatrix::<f64>::zeros(m * len, q);
        // S row-major, 2n rows (displacements, then velocities) by q columns.
        let mut s = vec![0.0; n2 * q];
        for i in 0..m {
            s[i * q + i] = self.sx[i];
            s[(n + i) * q + m + i] = self.sv[i];
        }
        let mut u = vec![0.0; self.input.channels()];
        // The Jacobians at the interval's start, middle and end; the accelerations at its ends.
        let mut jx = [vec![0.0; n * n], vec![0.0; n * n], vec![0.0; n * n]];
        let mut jv = [vec![0.0; n * n], vec![0.0; n * n], vec![0.0; n * n]];
        let (mut a0, mut a1, mut am) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let (mut x, mut v) = (vec![0.0; n], vec![0.0; n]);
        let state = |k: usize, x: &mut [f64], v: &mut [f64]| {
            for d in 0..n {
                x[d] = tr.x[d][k];
                v[d] = tr.v[d][k];
            }
        };
        state(0, &mut x, &mut v);
        self.input.eval(t[0], &mut u);
        let [jx0, jxm, jx1] = &mut jx;
        let [jv0, jvm, jv1] = &mut jv;
        if !self.sys.accel_jacobian(t[0], &x, &v, &u, &mut a0, jx0, jv0) {
            return None;
        }
        // One stage of the linear system: `out = M(jx, jv)·(s + c·k)`.
        let stage =
            |jx: &[f64], jv: &[f64], base: &[f64], k: Option<(&[f64], f64)>, out: &mut [f64]| {
                let at = |r: usize, c: usize| match k {
                    Some((k, h)) => base[r * q + c] + h * k[r * q + c],
                    None => base[r * q + c],
                };
                for c in 0..q {
                    for i in 0..n {
                        out[i * q + c] = at(n + i, c);
                        let mut acc = 0.0;
                        for d in 0..n {
                            acc += jx[i * n + d] * at(d, c) + jv[i * n + d] * at(n + d, c);
                        }
                        out[(n + i) * q + c] = acc;
                    }
                }
            };
        let (mut k1, mut k2, mut k3, mut k4) = (
            vec![0.0; n2 * q],
            vec![0.0; n2 * q],
            vec![0.0; n2 * q],
            vec![0.0; n2 * q],
        );
        let (mut xm, mut vm) = (vec![0.0; n], vec![0.0; n]);
        let (mut x1, mut v1) = (vec![0.0; n], vec![0.0; n]);
        for k in 0..len {
            for i in 0..m {
                for c in 0..q {
                    jac[(i * len + k, c)] = s[i * q + c] / self.sx[i];
                }
            }
            if k + 1 == len {
                break;
            }
            let h = t[k + 1] - t[k];
            // The next sample's state, acceleration and Jacobians.
            state(k + 1, &mut x1, &mut v1);
            self.input.eval(t[k + 1], &mut u);
            self.sys
                .accel_jacobian(t[k + 1], &x1, &v1, &u, &mut a1, jx1, jv1);
            // The midpoint of the cubic Hermite interpolant of the run between them.
            for d in 0..n {
                xm[d] = 0.5 * (x[d] + x1[d]) + h / 8.0 * (v[d] - v1[d]);
                vm[d] = 0.5 * (v[d] + v1[d]) + h / 8.0 * (a0[d] - a1[d]);
            }
            let tm = t[k] + 0.5 * h;
            self.input.eval(tm, &mut u);
            self.sys.accel_jacobian(tm, &xm, &vm, &u, &mut am, jxm, jvm);
            stage(jx0, jv0, &s, None, &mut k1);
            stage(jxm, jvm, &s, Some((&k1, 0.5 * h)), &mut k2);
            stage(jxm, jvm, &s, Some((&k2, 0.5 * h)), &mut k3);
            stage(jx1, jv1, &s, Some((&k3, h)), &mut k4);
            for (e, si) in s.iter_mut().enumerate() {
                *si += h / 6.0 * (k1[e] + 2.0 * k2[e] + 2.0 * k3[e] + k4[e]);
            }
            std::mem::swap(jx0, jx1);
            std::mem::swap(jv0, jv1);
            std::mem::swap(&mut a0, &mut a1);
            std::mem::swap(&mut x, &mut x1);
            std::mem::swap(&mut v, &mut v1);
        }
        jac.iter().all(|v| v.is_finite()).then_some(jac)
    }

    /// The fit from the given start, its Jacobian taken as `derivatives` says.
    pub(crate) fn solve(self, derivatives: Derivatives) -> Result<InitialFit> {
        let p = self.start();
        let over = |slot: std::sync::Mutex<Option<DynError>>| -> Result<()> {
            match slot.into_inner() {
                Ok(Some(e)) => Err(e),
                _ => Ok(()),
            }
        };
        let Some((r, tr)) = self.run(&p, f64::INFINITY) else {
            over(self.over_budget)?;
            return Ok(InitialFit {
                x0: self.x0.to_vec(),
                v0: self.v0.to_vec(),
                cost_start: f64::INFINITY,
                cost: f64::INFINITY,
                converged: false,
            });
        };
        let cost_start = r.iter().map(|v| v * v).sum::<f64>() / r.len().max(1) as f64;
        let run = |q: &[f64], bound: f64| self.run(q, bound);
        let (p, cost, converged) = match derivatives {
            Derivatives::Sensitivities => minimise(p, r, tr, &run, &|_, _, tr| self.along(tr)),
            Derivatives::Differences => minimise(p, r, tr, &run, &|p, r, _| self.differences(p, r)),
        };
        let (x, v) = self.to_state(&p);
        over(self.over_budget)?;
        Ok(InitialFit {
            x0: x,
            v0: v,
            cost_start,
            cost,
            converged,
        })
    }
}

/// Relative forward-difference step of [`StartFit::differences`] in the scaled unknowns.
const STEP: f64 = 1e-6;

/// Levenberg–Marquardt on the scaled unknowns `p` of [`fit_initial_state`], from the residuals
/// `r` of `p` and the run `tr` they come from: `run(q, bound)` simulates from `q` (`None` when
/// the run fails or its mean squared residual is sure to reach `bound`), `jacobian(p, r, tr)`
/// gives the Jacobian at `p`. Marquardt's damping ladder (÷3 after an accepted step, ×4 after a
/// rejected one) on the model Hessian of [`Secant`]; it ends where no step could remove
/// [`END_FALL`] of the cost, or after 50 iterations. Returns the last point, its mean squared
/// residual, and whether it ended at a minimum (not at the iteration limit, nor where the
/// Jacobian could not be taken, nor with the ladder's damping exhausted).
fn minimise<R, J, T>(
    mut p: Vec<f64>,
    mut r: Vec<f64>,
    mut tr: T,
    run: &R,
    jacobian: &J,
) -> (Vec<f64>, f64, bool)
where
    R: Fn(&[f64], f64) -> Option<(Vec<f64>, T)>,
    J: Fn(&[f64], &[f64], &T) -> Option<DMatrix<f64>>,
{
    let nr = r.len().max(1) as f64;
    let cost_of = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>() / nr;
    let mut cost = cost_of(&r);
    let np = p.len();
    let mut mu = 1e-3;
    let mut secant = Secant::new(np);
    for _ in 0..50 {
        let Some(jac) = jacobian(&p, &r, &tr) else {
            return (p, cost, false);
        };
        let rv = DVector::from_column_slice(&r);
        let g = jac.transpose() * &rv;
        let jtj = jac.transpose() * &jac;
        let hessian = secant.model(&p, &jac, &rv, &g, &jtj);
        let d: Vec<f64> = (0..np).map(|j| jtj[(j, j)].max(1e-12)).collect();
        let mut accepted = false;
        let mut ended = false;
        while mu < 1e12 {
            let mut a = hessian.clone();
            for j in 0..np {
                a[(j, j)] += mu * d[j];
            }
            let Some(ch) = a.cholesky() else {
                mu *= 4.0;
                continue;
            };
            let step = ch.solve(&(-&g));
            // The fall of the mean squared misfit that the model predicts for this step,
            // (μ·hᵀDh − hᵀg)/N, shrinks as μ grows: once it is below the end's share of the
            // cost, no higher rung could pass the end either, and the fit is at its minimum.
            let predicted =
                (mu * (0..np).map(|j| d[j] * step[j] * step[j]).sum::<f64>() - step.dot(&g)) / nr;
            if predicted.is_nan() || predicted <= END_FALL * cost {
                ended = !predicted.is_nan();
                break;
            }
            let q: Vec<f64> = p.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            match run(&q, cost) {
                Some((rq, tq)) if cost_of(&rq) < cost => {
                    let c = cost_of(&rq);
                    mu = (mu / 3.0).max(1e-12);
                    secant.accepted(&p, jac, g, jtj, 0.5 * nr * (cost - c));
                    accepted = (cost - c) / cost.max(f64::MIN_POSITIVE) > END_FALL;
                    ended = !accepted;
                    p = q;
                    r = rq;
                    tr = tq;
                    cost = c;
                    break;
                }
                _ => mu *= 4.0,
            }
        }
        if !accepted {
            return (p, cost, ended);
        }
    }
    (p, cost, false)
}

/// The smallest share of the cost an iteration of [`fit_initial_state`] must remove for the
/// fit to go on: MINPACK's relative tolerance, `√ε` (docs/DECISIONS.md, "Simulation").
const END_FALL: f64 = 1.490_116_119_384_765_6e-8;

/// The part of the misfit's Hessian that Gauss–Newton leaves out, `S ≈ Σ rᵢ ∇²rᵢ`, estimated
/// from the gradients along the accepted steps by the structured secant update of Dennis, Gay
/// and Welsch (NL2SOL), sized down where the residuals are small; as in NL2SOL, each step uses
/// `JᵀJ + S` only when that model predicted the last step's fall better than `JᵀJ` did. A
/// start-state fit of a wrong model has residuals of the size of the motion, where `JᵀJ`
/// alone misjudges the curvature and the steps overshoot.
struct Secant {
    s: DMatrix<f64>,
    augmented: bool,
    last: Option<LastStep>,
}

/// What [`Secant`] keeps of the point an accepted step left: the point, its Jacobian,
/// gradient and `JᵀJ`, and the step's actual fall of `½‖r‖²`.
struct LastStep {
    p: Vec<f64>,
    jac: DMatrix<f64>,
    g: DVector<f64>,
    jtj: DMatrix<f64>,
    fall: f64,
}

impl Secant {
    fn new(np: usize) -> Self {
        Self {
            s: DMatrix::zeros(np, np),
            augmented: false,
            last: None,
        }
    }

    /// The model Hessian at `p` (Jacobian `jac`, residuals `r`, gradient `g`, `jtj`), after
    /// updating `S` with the step that led here.
    fn model(
        &mut self,
        p: &[f64],
        jac: &DMatrix<f64>,
        r: &DVector<f64>,
        g: &DVector<f64>,
        jtj: &DMatrix<f64>,
    ) -> DMatrix<f64> {
        if let Some(last) = self.last.take() {
            let step = DVector::from_iterator(p.len(), p.iter().zip(&last.p).map(|(a, b)| a - b));
            let quad = |m: &DMatrix<f64>| step.dot(&(m * &step));
            let linear = -last.g.dot(&step);
            let gauss_newton = linear - 0.5 * quad(&last.jtj);
            let with_s = gauss_newton - 0.5 * quad(&self.s);
            self.augmented = (with_s - last.fall).abs() < (gauss_newton - last.fall).abs();
            let y = g - &last.g;
            let y_sharp = (jac - &last.jac).transpose() * r;
            let ys = y.dot(&step);
            if ys > 0.0 {
                let sss = quad(&self.s);
                if sss != 0.0 {
                    self.s *= (step.dot(&y_sharp).abs() / sss.abs()).min(1.0);
                }
                let w = &y_sharp - &self.s * &step;
                self.s += (&w * y.transpose() + &y * w.transpose()) / ys
                    - (&y * y.transpose()) * (w.dot(&step) / (ys * ys));
            }
        }
        if self.augmented {
            jtj + &self.s
        } else {
            jtj.clone()
        }
    }

    /// Records an accepted step from `p`, taken with these derivatives, and its actual fall.
    fn accepted(
        &mut self,
        p: &[f64],
        jac: DMatrix<f64>,
        g: DVector<f64>,
        jtj: DMatrix<f64>,
        fall: f64,
    ) {
        self.last = Some(LastStep {
            p: p.to_vec(),
            jac,
            g,
            jtj,
            fall,
        });
    }
}

/// The initial state of a simulation of `sys` on measured displacements (`measured`, the first
/// DOFs of `sys`, sampled at `t`) by `how`: the first-samples state `(x0, v0)` as given, or for
/// [`InitialState::Fitted`] the better of the fits ([`fit_initial_state`]) from it and from a
/// smoothed start, over [`fit_horizon`] samples (halved while the model blows up from both
/// within it; the smoothed start if it does so even over 16 samples). DOFs beyond `measured`
/// keep their given state.
///
/// Errors: a non-positive `periods`, or the dimension errors of [`fit_initial_state`].
#[allow(clippy::too_many_arguments)]
pub fn choose_initial_state<S: SecondOrderSystem + ?Sized, I: Integrator + Sync>(
    how: InitialState,
    sys: &S,
    integrator: &I,
    input: &SampledInput,
    measured: &[&[f64]],
    t: &[f64],
    x0: Vec<f64>,
    v0: Vec<f64>,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let Some((periods, h)) = fitted_stretch(how, measured, t)? else {
        return Ok((x0, v0));
    };
    let (xs, vs) = smoothed_start(measured, t, periods, h, (&x0, &v0));
    // A model that blows up within the horizon from both guesses (one that is unstable for this
    // record) has no finite cost to fit there: the horizon is halved until it has one, so the
    // simulation starts from a fitted state and fails where the model does, not within a few
    // samples of a noisy first-samples velocity.
    let mut len = h;
    while len >= MIN_HORIZON.min(h) {
        let th = &t[..len];
        // The two fits are independent: side by side.
        let (a, b) = rayon::join(
            || fit_initial_state(sys, integrator, input, measured, th, &x0, &v0),
            || fit_initial_state(sys, integrator, input, measured, th, &xs, &vs),
        );
        let fits = [a?, b?];
        if let Some(f) = fits
            .into_iter()
            .filter(|f| f.cost.is_finite())
            .min_by(|a, b| a.cost.total_cmp(&b.cost))
        {
            return Ok((f.x0, f.v0));
        }
        len /= 2;
    }
    // No stretch could be fitted: the smoothed start is the better guess of the two.
    Ok((xs, vs))
}

/// The smoothed start of [`choose_initial_state`]: each measured DOF's value and slope at the
/// first sample of a quadratic through the first quarter period (at least 5 samples) of its
/// `h`-sample fitted stretch of `periods` periods; the other DOFs as in `(x0, v0)`.
fn smoothed_start(
    measured: &[&[f64]],
    t: &[f64],
    periods: f64,
    h: usize,
    (x0, v0): (&[f64], &[f64]),
) -> (Vec<f64>, Vec<f64>) {
    let dt = t[1] - t[0];
    let w = (h as f64 / (4.0 * periods)).round().max(5.0) as usize;
    let (mut xs, mut vs) = (x0.to_vec(), v0.to_vec());
    for (i, y) in measured.iter().enumerate() {
        let (a, b) = start_of(y, dt, w);
        xs[i] = a;
        vs[i] = b;
    }
    (xs, vs)
}

/// The initial state of a simulation of `sys` fitted from a warm start: `warm`, the fitted
/// start of a model close to `sys` on the same record (a refit of it, one of its fold models),
/// whose optimum is near this one's. One fit ([`fit_initial_state`]) from `warm` over
/// [`fit_horizon`] samples, where [`choose_initial_state`] fits from two starts; when that fit
/// does not end at a minimum (it blows up, stops at its iteration limit or cannot take its
/// Jacobian), or ends no lower than either cold start of [`choose_initial_state`] (the
/// first-samples start `(x0, v0)` and the smoothed start) already is before any fit, the two
/// cold fits decide as if there had been no warm start. That check costs a run of the stretch
/// from each cold start, each given up once its misfit reaches the warm fit's: a warm start
/// from a model that does not follow the record's start (a model missing an effect fits a start
/// far from the measured one) can end in a valley the record's own start is below. `warm` holds the measured DOFs' displacements and velocities (its
/// other entries are not read); DOFs beyond `measured` keep the state in `(x0, v0)`.
///
/// Errors: those of [`choose_initial_state`], and a `warm` shorter than `measured`.
#[allow(clippy::too_many_arguments)]
pub fn warm_initial_state<S: SecondOrderSystem + ?Sized, I: Integrator + Sync>(
    how: InitialState,
    sys: &S,
    integrator: &I,
    input: &SampledInput,
    measured: &[&[f64]],
    t: &[f64],
    (x0, v0): (Vec<f64>, Vec<f64>),
    warm: (&[f64], &[f64]),
) -> Result<(Vec<f64>, Vec<f64>)> {
    let cold = |x0, v0| choose_initial_state(how, sys, integrator, input, measured, t, x0, v0);
    let InitialState::Fitted { .. } = how else {
        return cold(x0, v0);
    };
    let m = measured.len();
    if warm.0.len() < m || warm.1.len() < m {
        return Err(DynError::Dimension {
            name: "warm",
            got: warm.0.len().min(warm.1.len()),
            expected: m,
            hint: "a warm start needs a displacement and a velocity per measured DOF",
        });
    }
    let Some((periods, h)) = fitted_stretch(how, measured, t)? else {
        return cold(x0, v0);
    };
    let (mut xw, mut vw) = (x0.clone(), v0.clone());
    if xw.len() < m || vw.len() < m {
        return cold(x0, v0);
    }
    xw[..m].copy_from_slice(&warm.0[..m]);
    vw[..m].copy_from_slice(&warm.1[..m]);
    let th = &t[..h];
    let f = fit_initial_state(sys, integrator, input, measured, th, &xw, &vw)?;
    if f.converged && f.cost.is_finite() {
        let smoothed = smoothed_start(measured, t, periods, h, (&x0, &v0));
        let warm_is_lower = |(x, v): (&[f64], &[f64])| -> Result<bool> {
            let fit = StartFit::new(sys, integrator, input, measured, th, x, v)?;
            Ok(fit.run(&fit.start(), f.cost).is_none())
        };
        if warm_is_lower((&x0, &v0))? && warm_is_lower((&smoothed.0, &smoothed.1))? {
            return Ok((f.x0, f.v0));
        }
    }
    cold(x0, v0)
}

/// The periods and samples of the stretch a start state is fitted over for `how` on `measured`
/// (sampled at `t`): `None` where no fit is made (the first samples asked for, no measured DOF,
/// or a stretch under 2 samples).
///
/// Errors: a non-positive or non-finite `periods`.
fn fitted_stretch(
    how: InitialState,
    measured: &[&[f64]],
    t: &[f64],
) -> Result<Option<(f64, usize)>> {
    let InitialState::Fitted { periods } = how else {
        return Ok(None);
    };
    if !(periods.is_finite() && periods > 0.0) {
        return Err(DynError::InvalidParameter {
            name: "initial_state.periods",
            reason: format!("{periods} must be positive and finite"),
        });
    }
    let h = fit_horizon(measured, periods).min(t.len());
    Ok((h >= 2 && !measured.is_empty()).then_some((periods, h)))
}

/// Fewest samples a shortened fit horizon of [`choose_initial_state`] keeps.
const MIN_HORIZON: usize = 16;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Dopri5, FnSystem};

    #[test]
    fn start_of_is_exact_for_quadratics() {
        let dt = 0.01;
        let y: Vec<f64> = (0..12)
            .map(|k| {
                let t = 0.3 + k as f64 * dt;
                1.0 - 2.0 * t + 5.0 * t * t
            })
            .collect();
        for m in [3, 5, 12] {
            let (v, s) = start_of(&y, dt, m);
            assert!((v - (1.0 - 0.6 + 0.45)).abs() < 1e-12, "value {v}");
            assert!((s - (-2.0 + 3.0)).abs() < 1e-9, "slope {s}");
        }
    }

    #[test]
    fn period_ignores_noise_below_the_hysteresis() {
        // A 50-sample sine with ±1 % dither: period 50 samples.
        let y: Vec<f64> = (0..1000)
            .map(|k| {
                (std::f64::consts::TAU * k as f64 / 50.0).sin()
                    + 0.01 * if k % 2 == 0 { 1.0 } else { -1.0 }
            })
            .collect();
        let p = period_samples(&y).unwrap();
        assert!((p - 50.0).abs() < 0.5, "period {p}");
        assert_eq!(period_samples(&[1.0; 10]), None);
        assert_eq!(fit_horizon(&[&y], 2.0), 100);
    }

    #[test]
    fn period_ignores_white_noise_near_the_motion_s_size() {
        // A 100-sample sine under white noise at 7 dB (σ ≈ 0.32 of an amplitude of 1): with a
        // hysteresis of half the standard deviation the noise adds crossings about the mean
        // and the period came out near 80 samples; counted past three times the noise's
        // level, it is the sine's.
        use tfs_signal::NoiseKind;
        let clean: Vec<f64> = (0..3000)
            .map(|k| (std::f64::consts::TAU * k as f64 / 100.0).sin())
            .collect();
        for seed in 0..5 {
            let y =
                tfs_signal::noise::add_noise_seeded(&clean, 7.0, NoiseKind::White, seed).unwrap();
            let s = sample_noise(&y);
            assert!((s - 0.316).abs() < 0.03, "seed {seed}: noise level {s}");
            let p = period_samples(&y).unwrap();
            assert!((p - 100.0).abs() < 3.0, "seed {seed}: period {p}");
        }
    }

    #[test]
    fn fit_recovers_a_free_decay_start_from_a_bad_guess() {
        // x'' + 0.2 x' + x = 0 from (1, 0.5); the guess is off in both components.
        let sys = FnSystem::new(
            1,
            0,
            |_t, x: &[f64], v: &[f64], _u: &[f64], a: &mut [f64]| a[0] = -0.2 * v[0] - x[0],
        );
        let t: Vec<f64> = (0..200).map(|k| k as f64 * 0.05).collect();
        let input = SampledInput::zero(0);
        let truth = Dopri5::default()
            .integrate(&sys, &input, &[1.0], &[0.5], &t)
            .unwrap();
        let f = fit_initial_state(
            &sys,
            &Dopri5::default(),
            &input,
            &[&truth.x[0]],
            &t,
            &[0.7],
            &[-2.0],
        )
        .unwrap();
        assert!((f.x0[0] - 1.0).abs() < 1e-5, "x0 {}", f.x0[0]);
        assert!((f.v0[0] - 0.5).abs() < 1e-5, "v0 {}", f.v0[0]);
        assert!(f.cost < 1e-10 && f.cost_start > 0.1);
    }
}
