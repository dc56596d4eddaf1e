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

use crate::{DynError, Integrator, Result, SampledInput, SecondOrderSystem};

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
/// [`period_samples`] makes a crossing go.
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
/// measured displacement with the most crossings ([`period_samples`]), or a tenth of the record
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
/// deviation, Jacobian by forward differences, Marquardt's damping ladder and NL2SOL's secant
/// estimate of the Hessian's second-order part (the residuals of a wrong model are as large as
/// the motion), starting from `(x0, v0)` (all DOFs; the others stay as given). It ends where a
/// step's fall, actual or predicted, is below a share √ε (1.49e-8) of the cost. A start that blows
/// up has cost `+∞` and is returned unchanged.
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
    // Scales: each DOF's standard deviation over the stretch (its mean magnitude if constant);
    // velocities by the same over the stretch's duration.
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
    let to_state = |p: &[f64]| -> (Vec<f64>, Vec<f64>) {
        let (mut x, mut v) = (x0.to_vec(), v0.to_vec());
        for i in 0..m {
            x[i] = p[i] * sx[i];
            v[i] = p[m + i] * sv[i];
        }
        (x, v)
    };
    // A run that exhausts its step budget says the model cannot be simulated at this tolerance
    // (stiff or discontinuous), whatever its start: the fit stops and returns that error at
    // once rather than spending a budget on every trial start.
    let over_budget: std::sync::Mutex<Option<DynError>> = std::sync::Mutex::new(None);
    // The scaled residuals of the run from `p`, or `None` when it fails or when its mean squared
    // residual is sure to reach `bound` (a trial step's current cost; infinite for the runs that
    // are always used whole): the sum of squares only grows, so a trial is given up at the
    // first sample where one DOF's running sum reaches it, with the same accept/reject as the
    // whole run would get (`cost_of`'s sum runs DOF by DOF, each from the one before, so it is
    // at least any one DOF's running sum).
    let nr = (m * t.len()).max(1) as f64;
    let residuals = |p: &[f64], bound: f64| -> Option<Vec<f64>> {
        match over_budget.lock() {
            Ok(e) if e.is_none() => {}
            _ => return None,
        }
        let (x, v) = to_state(p);
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
            integrator.integrate_until(sys, input, &x, &v, t, keep_going)
        } else {
            integrator.integrate(sys, input, &x, &v, t).map(Some)
        };
        let tr = match run {
            Ok(Some(tr)) => tr,
            Ok(None) => return None,
            Err(e @ DynError::TooManySteps { .. }) => {
                if let Ok(mut slot) = over_budget.lock() {
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
        r.iter().all(|v| v.is_finite()).then_some(r)
    };
    let cost_of = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>() / r.len().max(1) as f64;
    let p: Vec<f64> = (0..m)
        .map(|i| x0[i] / sx[i])
        .chain((0..m).map(|i| v0[i] / sv[i]))
        .collect();
    let over = |slot: std::sync::Mutex<Option<DynError>>| -> Result<()> {
        match slot.into_inner() {
            Ok(Some(e)) => Err(e),
            _ => Ok(()),
        }
    };
    let Some(r) = residuals(&p, f64::INFINITY) else {
        over(over_budget)?;
        return Ok(InitialFit {
            x0: x0.to_vec(),
            v0: v0.to_vec(),
            cost_start: f64::INFINITY,
            cost: f64::INFINITY,
        });
    };
    let cost_start = cost_of(&r);
    let (p, cost) = minimise(p, r, &residuals);
    over(over_budget)?;
    let (x, v) = to_state(&p);
    Ok(InitialFit {
        x0: x,
        v0: v,
        cost_start,
        cost,
    })
}

/// Levenberg–Marquardt on the scaled unknowns `p` of [`fit_initial_state`], from the
/// residuals `r` of `p`: `residuals(q, bound)` simulates from `q` (`None` when the run fails or
/// its mean squared residual is sure to reach `bound`). Jacobians by forward differences,
/// Marquardt's damping ladder (÷3 after an accepted step, ×4 after a rejected one) on the
/// model Hessian of [`Secant`]; it ends where no step could remove [`END_FALL`] of the cost,
/// or after 50 iterations. Returns the last point and its mean squared residual.
fn minimise<R>(mut p: Vec<f64>, mut r: Vec<f64>, residuals: &R) -> (Vec<f64>, f64)
where
    R: Fn(&[f64], f64) -> Option<Vec<f64>> + Sync,
{
    let nr = r.len().max(1) as f64;
    let cost_of = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>() / nr;
    let mut cost = cost_of(&r);
    let np = p.len();
    let mut mu = 1e-3;
    let mut secant = Secant::new(np);
    const STEP: f64 = 1e-6;
    for _ in 0..50 {
        // Forward-difference Jacobian in the scaled parameters: its columns' simulations side
        // by side (a fit is otherwise the last, serial, piece of work while a core idles).
        let columns: Vec<Option<(f64, Vec<f64>)>> = (0..np)
            .into_par_iter()
            .map(|j| {
                let mut q = p.clone();
                let h = STEP * p[j].abs().max(1.0);
                q[j] += h;
                residuals(&q, f64::INFINITY).map(|rq| (h, rq))
            })
            .collect();
        let Some(columns) = columns.into_iter().collect::<Option<Vec<_>>>() else {
            break;
        };
        let mut jac = DMatrix::<f64>::zeros(r.len(), np);
        for (j, (h, rq)) in columns.into_iter().enumerate() {
            for (k, (a, b)) in rq.iter().zip(&r).enumerate() {
                jac[(k, j)] = (a - b) / h;
            }
        }
        let rv = DVector::from_column_slice(&r);
        let g = jac.transpose() * &rv;
        let jtj = jac.transpose() * &jac;
        let hessian = secant.model(&p, &jac, &rv, &g, &jtj);
        let d: Vec<f64> = (0..np).map(|j| jtj[(j, j)].max(1e-12)).collect();
        let mut accepted = false;
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
                break;
            }
            let q: Vec<f64> = p.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            match residuals(&q, cost) {
                Some(rq) if cost_of(&rq) < cost => {
                    let c = cost_of(&rq);
                    mu = (mu / 3.0).max(1e-12);
                    secant.accepted(&p, jac, g, jtj, 0.5 * nr * (cost - c));
                    accepted = (cost - c) / cost.max(f64::MIN_POSITIVE) > END_FALL;
                    p = q;
                    r = rq;
                    cost = c;
                    break;
                }
                _ => mu *= 4.0,
            }
        }
        if !accepted {
            break;
        }
    }
    (p, cost)
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
    let periods = match how {
        InitialState::FirstSamples => return Ok((x0, v0)),
        InitialState::Fitted { periods } => periods,
    };
    if !(periods.is_finite() && periods > 0.0) {
        return Err(DynError::InvalidParameter {
            name: "initial_state.periods",
            reason: format!("{periods} must be positive and finite"),
        });
    }
    let h = fit_horizon(measured, periods).min(t.len());
    if h < 2 || measured.is_empty() {
        return Ok((x0, v0));
    }
    let dt = t[1] - t[0];
    // The smoothed start: a quadratic through the first quarter period (at least 5 samples).
    let w = (h as f64 / (4.0 * periods)).round().max(5.0) as usize;
    let (mut xs, mut vs) = (x0.clone(), v0.clone());
    for (i, y) in measured.iter().enumerate() {
        let (a, b) = start_of(y, dt, w);
        xs[i] = a;
        vs[i] = b;
    }
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
