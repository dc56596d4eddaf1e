//! Adaptive Dormand–Prince 5(4) with FSAL, error control and exact stops at output and input
//! sample times.

use crate::integrate::{blowup_limit, check_args, check_limit, check_state};
use crate::{DynError, Integrator, Result, SampledInput, SecondOrderSystem, Stats, Trajectory};

// Butcher tableau of Dormand & Prince (1980), RK5(4)7M.
const C: [f64; 7] = [0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];
const A: [[f64; 6]; 7] = [
    [0.0; 6],
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [
        19372.0 / 6561.0,
        -25360.0 / 2187.0,
        64448.0 / 6561.0,
        -212.0 / 729.0,
        0.0,
        0.0,
    ],
    [
        9017.0 / 3168.0,
        -355.0 / 33.0,
        46732.0 / 5247.0,
        49.0 / 176.0,
        -5103.0 / 18656.0,
        0.0,
    ],
    [
        35.0 / 384.0,
        0.0,
        500.0 / 1113.0,
        125.0 / 192.0,
        -2187.0 / 6784.0,
        11.0 / 84.0,
    ],
];
/// Difference between the 5th- and 4th-order weights (error estimate).
const E: [f64; 7] = [
    71.0 / 57600.0,
    0.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
];

/// Default [`Dopri5::steps_per_stop`]: attempted steps allowed per forced stop of a run.
pub const STEPS_PER_STOP: usize = 1000;

/// Attempted steps every run may take besides [`Dopri5::steps_per_stop`] per stop (a free run
/// with few output times still gets this many).
pub const BUDGET_BASE: usize = 100_000;

/// Adaptive Dormand–Prince 5(4) settings.
///
/// The local error of each step is kept below `atol + rtol·|y|` in the RMS norm over all `x` and
/// `v` components (Hairer, Nørsett & Wanner, *Solving ODEs I*, II.4). Steps end exactly at output
/// times and at input sample times, so the interpolated input is smooth inside each step.
///
/// ```
/// use tfs_dynamics::{Dopri5, FnSystem, Integrator, SampledInput};
/// let sys = FnSystem::new(1, 0, |_t, x: &[f64], _v: &[f64], _u: &[f64], a: &mut [f64]| a[0] = -x[0]);
/// let t: Vec<f64> = (0..=10).map(|k| k as f64 * 0.5).collect();
/// let tr = Dopri5::default().integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.0], &t).unwrap();
/// assert!((tr.x[0][10] - 5.0f64.cos()).abs() < 1e-7);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dopri5 {
    /// Relative tolerance (> 0).
    pub rtol: f64,
    /// Absolute tolerance (> 0).
    pub atol: f64,
    /// First step size (s); `None` picks one from the initial derivatives.
    pub h_init: Option<f64>,
    /// Largest step size (s); `f64::INFINITY` for no limit.
    pub h_max: f64,
    /// Largest number of attempted steps per run, whatever its length.
    pub max_steps: usize,
    /// The step budget of [`Integrator::integrate`], sized from the run: at most this many
    /// attempted steps per forced stop (each output time and each input sample time inside the
    /// run) plus [`BUDGET_BASE`]. A smooth model takes one to a few steps per stop; a model that
    /// needs thousands is too stiff or discontinuous for an explicit method at this tolerance
    /// and would otherwise run for hours (see [`DynError::TooManySteps`]).
    pub steps_per_stop: usize,
    /// Largest allowed |x| or |v| before the run is declared blown up; `None` = automatic
    /// (`1e6 · max(1, |x0|, |v0|)`).
    pub blowup_limit: Option<f64>,
}

impl Default for Dopri5 {
    fn default() -> Self {
        Self {
            rtol: 1e-8,
            atol: 1e-10,
            h_init: None,
            h_max: f64::INFINITY,
            max_steps: 10_000_000,
            steps_per_stop: STEPS_PER_STOP,
            blowup_limit: None,
        }
    }
}

impl Dopri5 {
    /// Default settings with the given tolerances.
    pub fn with_tol(rtol: f64, atol: f64) -> Self {
        Self {
            rtol,
            atol,
            ..Self::default()
        }
    }

    fn validate(&self) -> Result<()> {
        let pos = |name: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(DynError::InvalidParameter {
                    name,
                    reason: format!("{v} must be positive and finite"),
                })
            }
        };
        pos("rtol", self.rtol)?;
        pos("atol", self.atol)?;
        if let Some(h) = self.h_init {
            pos("h_init", h)?;
        }
        if self.h_max.is_nan() || self.h_max <= 0.0 {
            return Err(DynError::InvalidParameter {
                name: "h_max",
                reason: format!(
                    "{} must be positive (f64::INFINITY for no limit)",
                    self.h_max
                ),
            });
        }
        if self.max_steps == 0 || self.steps_per_stop == 0 {
            return Err(DynError::InvalidParameter {
                name: if self.max_steps == 0 {
                    "max_steps"
                } else {
                    "steps_per_stop"
                },
                reason: "must be at least 1".into(),
            });
        }
        check_limit(self.blowup_limit)
    }

    /// The attempted steps [`Integrator::integrate`] allows a run to `t_out` under `input`:
    /// [`BUDGET_BASE`] plus [`Dopri5::steps_per_stop`] per forced stop (the output times or the
    /// input sample times inside the run, whichever are more), at most [`Dopri5::max_steps`].
    pub fn budget(&self, input: &SampledInput, t_out: &[f64]) -> usize {
        let (a, b) = (t_out[0], t_out[t_out.len() - 1]);
        let samples = if input.is_time_varying() && input.dt() > 0.0 {
            let lo = ((a - input.t0()) / input.dt()).max(0.0);
            let hi = ((b - input.t0()) / input.dt()).clamp(0.0, input.len() as f64);
            (hi - lo).max(0.0).ceil() as usize
        } else {
            0
        };
        // Input samples and output times mostly coincide (a record's own grid): the larger count.
        let stops = t_out.len().max(samples);
        stops
            .saturating_mul(self.steps_per_stop)
            .saturating_add(BUDGET_BASE)
            .min(self.max_steps)
    }

    /// A stepping solver started at time `t0` from `(x0, v0)`; call
    /// [`Dopri5Solver::advance_to`] to move it forward (useful for early stopping).
    pub fn solver<'a, S: SecondOrderSystem + ?Sized>(
        &self,
        sys: &'a S,
        input: &'a SampledInput,
        t0: f64,
        x0: &[f64],
        v0: &[f64],
    ) -> Result<Dopri5Solver<'a, S>> {
        self.validate()?;
        check_args(sys, input, x0, v0, &[t0])?;
        Ok(Dopri5Solver::new(*self, sys, input, t0, x0, v0))
    }
}

impl Dopri5 {
    /// A whole run, asking `keep_going` after each output time (see
    /// [`Integrator::integrate_until`]): the trajectory so far and whether it reached the end.
    fn run<S: SecondOrderSystem + ?Sized, F: FnMut(usize, &[f64]) -> bool>(
        &self,
        sys: &S,
        input: &SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
        mut keep_going: F,
    ) -> Result<(Trajectory, bool)> {
        self.validate()?;
        check_args(sys, input, x0, v0, t_out)?;
        let mut opts = *self;
        opts.max_steps = self.budget(input, t_out);
        let mut s = Dopri5Solver::new(opts, sys, input, t_out[0], x0, v0);
        let mut traj = Trajectory::with_capacity(sys.dofs(), t_out.len());
        traj.push(t_out[0], x0, v0);
        if !keep_going(0, x0) {
            return Ok((traj, false));
        }
        for (k, &tn) in t_out.iter().enumerate().skip(1) {
            s.advance_to(tn)?;
            traj.push(tn, s.x(), s.v());
            if !keep_going(k, s.x()) {
                return Ok((traj, false));
            }
        }
        traj.stats = s.stats();
        Ok((traj, true))
    }
}

impl Integrator for Dopri5 {
    fn integrate<S: SecondOrderSystem + ?Sized>(
        &self,
        sys: &S,
        input: &SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
    ) -> Result<Trajectory> {
        Ok(self.run(sys, input, x0, v0, t_out, |_, _| true)?.0)
    }

    fn integrate_until<S: SecondOrderSystem + ?Sized, F: FnMut(usize, &[f64]) -> bool>(
        &self,
        sys: &S,
        input: &SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
        keep_going: F,
    ) -> Result<Option<Trajectory>> {
        let (traj, whole) = self.run(sys, input, x0, v0, t_out, keep_going)?;
        Ok(whole.then_some(traj))
    }
}

/// A Dormand–Prince solver in progress (see [`Dopri5::solver`]).
#[derive(Debug)]
pub struct Dopri5Solver<'a, S: ?Sized> {
    opts: Dopri5,
    sys: &'a S,
    input: &'a SampledInput,
    n: usize,
    t: f64,
    /// State `[x, v]`.
    y: Vec<f64>,
    k: [Vec<f64>; 7],
    ytmp: Vec<f64>,
    ynew: Vec<f64>,
    u: Vec<f64>,
    /// Proposed next step size.
    h: f64,
    limit: f64,
    stats: Stats,
    attempts: usize,
}

/// Writes `dy/dt = [v, a(t, x, v, u(t))]` for `y = [x, v]`.
fn deriv<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    input: &SampledInput,
    u: &mut [f64],
    n: usize,
    t: f64,
    y: &[f64],
    out: &mut [f64],
) {
    input.eval(t, u);
    deriv_at(sys, u, n, t, y, out);
}

/// [`deriv`] with the input `u` already evaluated at `t`.
#[inline(always)]
fn deriv_at<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    u: &[f64],
    n: usize,
    t: f64,
    y: &[f64],
    out: &mut [f64],
) {
    out[..n].copy_from_slice(&y[n..]);
    let (x, v) = y.split_at(n);
    sys.accel(t, x, v, u, &mut out[n..]);
}

impl<'a, S: SecondOrderSystem + ?Sized> Dopri5Solver<'a, S> {
    fn new(
        opts: Dopri5,
        sys: &'a S,
        input: &'a SampledInput,
        t0: f64,
        x0: &[f64],
        v0: &[f64],
    ) -> Self {
        let n = sys.dofs();
        let mut y = Vec::with_capacity(2 * n);
        y.extend_from_slice(x0);
        y.extend_from_slice(v0);
        let mut s = Self {
            opts,
            sys,
            input,
            n,
            t: t0,
            y,
            k: std::array::from_fn(|_| vec![0.0; 2 * n]),
            ytmp: vec![0.0; 2 * n],
            ynew: vec![0.0; 2 * n],
            u: vec![0.0; input.channels()],
            h: 0.0,
            limit: blowup_limit(opts.blowup_limit, x0, v0),
            stats: Stats::default(),
            attempts: 0,
        };
        deriv(sys, input, &mut s.u, n, t0, &s.y, &mut s.k[0]);
        s.stats.evals += 1;
        s.h = match opts.h_init {
            Some(h) => h,
            None => s.initial_step(),
        }
        .min(opts.h_max);
        s
    }

    /// Hairer's starting-step heuristic for an order-5 method.
    fn initial_step(&mut self) -> f64 {
        let sc: Vec<f64> = self
            .y
            .iter()
            .map(|y| self.opts.atol + self.opts.rtol * y.abs())
            .collect();
        let rms = |v: &[f64]| {
            let m = v.len().max(1) as f64;
            (v.iter().zip(&sc).map(|(a, s)| (a / s).powi(2)).sum::<f64>() / m).sqrt()
        };
        let d0 = rms(&self.y);
        let d1 = rms(&self.k[0]);
        let h0 = if d0 < 1e-5 || d1 < 1e-5 {
            1e-6
        } else {
            0.01 * d0 / d1
        };
        for i in 0..2 * self.n {
            self.ytmp[i] = self.y[i] + h0 * self.k[0][i];
        }
        let (k0, rest) = self.k.split_at_mut(1);
        deriv(
            self.sys,
            self.input,
            &mut self.u,
            self.n,
            self.t + h0,
            &self.ytmp,
            &mut rest[0],
        );
        self.stats.evals += 1;
        let diff: Vec<f64> = rest[0].iter().zip(&k0[0]).map(|(a, b)| a - b).collect();
        let d2 = rms(&diff) / h0;
        let dmax = d1.max(d2);
        let h1 = if dmax <= 1e-15 {
            (h0 * 1e-3).max(1e-6)
        } else {
            (0.01 / dmax).powf(0.2)
        };
        let h = (100.0 * h0).min(h1);
        if h.is_finite() && h > 0.0 { h } else { 1e-6 }
    }

    /// Current time (s).
    pub fn t(&self) -> f64 {
        self.t
    }

    /// Current displacements.
    pub fn x(&self) -> &[f64] {
        &self.y[..self.n]
    }

    /// Current velocities.
    pub fn v(&self) -> &[f64] {
        &self.y[self.n..]
    }

    /// Work counters so far.
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// Integrates up to exactly `t_target` (which must not be before [`Dopri5Solver::t`]),
    /// stopping at every input sample time on the way.
    pub fn advance_to(&mut self, t_target: f64) -> Result<()> {
        if t_target.is_nan() || t_target < self.t {
            return Err(DynError::InvalidParameter {
                name: "t_target",
                reason: format!(
                    "{t_target} is before the current time {}; integrate forward only",
                    self.t
                ),
            });
        }
        while self.t < t_target {
            let stop = self
                .input
                .next_sample_after(self.t)
                .map_or(t_target, |s| s.min(t_target));
            self.advance_exactly(stop, t_target)?;
        }
        Ok(())
    }

    fn advance_exactly(&mut self, stop: f64, t_target: f64) -> Result<()> {
        let n2 = 2 * self.n;
        let mut last_nonfinite = false;
        loop {
            let remaining = stop - self.t;
            let tiny = 8.0 * f64::EPSILON * self.t.abs().max(stop.abs()).max(1e-300);
            if remaining <= tiny {
                self.t = stop;
                return Ok(());
            }
            if self.attempts >= self.opts.max_steps {
                return Err(DynError::TooManySteps {
                    t: self.t,
                    t_target,
                    max_steps: self.opts.max_steps,
                    h: self.h,
                });
            }
            if self.h < tiny {
                if last_nonfinite {
                    return Err(DynError::BlowUp {
                        t: self.t,
                        x: self.x().to_vec(),
                        v: self.v().to_vec(),
                    });
                }
                return Err(DynError::StepSizeUnderflow {
                    t: self.t,
                    h: self.h,
                });
            }
            self.attempts += 1;
            let proposed = self.h.min(self.opts.h_max);
            let clamped = proposed >= remaining || self.t + 1.01 * proposed >= stop;
            let h = if clamped { remaining } else { proposed };
            // Stages 2..7 (stage 1 is the FSAL derivative in k[0]).
            for s in 1..7 {
                for i in 0..n2 {
                    let mut acc = 0.0;
                    for (aj, kj) in A[s].iter().zip(&self.k).take(s) {
                        acc += aj * kj[i];
                    }
                    self.ytmp[i] = self.y[i] + h * acc;
                }
                let (_, rest) = self.k.split_at_mut(s);
                let ts = self.t + C[s] * h;
                // Stages 6 and 7 are at the same time (C[5] = C[6] = 1): the same input.
                if s != 6 {
                    self.input.eval(ts, &mut self.u);
                }
                deriv_at(self.sys, &self.u, self.n, ts, &self.ytmp, &mut rest[0]);
            }
            self.stats.evals += 6;
            // ytmp after stage 7 holds the 5th-order solution (A[6] are the b weights).
            self.ynew.copy_from_slice(&self.ytmp);
            let mut sum = 0.0;
            let mut finite = true;
            for i in 0..n2 {
                let mut e = 0.0;
                for (j, ej) in E.iter().enumerate() {
                    e += ej * self.k[j][i];
                }
                e *= h;
                let sc = self.opts.atol + self.opts.rtol * self.y[i].abs().max(self.ynew[i].abs());
                sum += (e / sc).powi(2);
                finite &= self.ynew[i].is_finite() && self.k[6][i].is_finite();
            }
            let err = (sum / n2.max(1) as f64).sqrt();
            if !finite || !err.is_finite() {
                last_nonfinite = true;
                self.stats.rejected += 1;
                self.h = 0.2 * h;
                continue;
            }
            last_nonfinite = false;
            let fac = step_factor(err);
            if err <= 1.0 {
                self.t = if clamped { stop } else { self.t + h };
                std::mem::swap(&mut self.y, &mut self.ynew);
                self.k.swap(0, 6); // FSAL: the last stage is the derivative at the new point.
                self.stats.steps += 1;
                let (x, v) = self.y.split_at(self.n);
                check_state(self.t, x, v, self.limit)?;
                self.h = if clamped {
                    proposed.max(h * fac)
                } else {
                    h * fac
                };
            } else {
                self.stats.rejected += 1;
                self.h = h * fac.min(1.0);
            }
        }
    }
}

/// The step-size factor for a step of scaled error `err`: 0.9·err^(−1/5) clamped to [0.2, 5].
/// Below 1.8e-4 the power exceeds 5.04 and above 1900 it is below 0.199, so there the clamp
/// decides and the power is not taken (the margins keep the shortcut exact: the same factor to
/// the bit; `err = 0` gives 5).
fn step_factor(err: f64) -> f64 {
    if err < 1.8e-4 {
        5.0
    } else if err > 1900.0 {
        0.2
    } else {
        (0.9 * err.powf(-0.2)).clamp(0.2, 5.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stiff run (damping 1e12, which needs ~1e13 steps) stops at a budget sized from its
    /// length with the message that says why; a discontinuous one (`sign(x')`) likewise.
    #[test]
    fn step_budget_is_sized_from_the_run() {
        let t: Vec<f64> = (0..2000).map(|k| k as f64 * 0.01).collect();
        let stiff = crate::FnSystem::new(
            1,
            0,
            |_t, x: &[f64], v: &[f64], _u: &[f64], a: &mut [f64]| a[0] = -1e12 * v[0] - x[0],
        );
        let sign = crate::FnSystem::new(
            1,
            1,
            |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
                a[0] = u[0] - 4.0 * x[0] - 0.5 * v[0].signum() * (v[0] != 0.0) as u8 as f64
            },
        );
        let u = SampledInput::new(0.0, 0.01, vec![t.iter().map(|t| (1.1 * t).cos()).collect()])
            .unwrap();
        let d = Dopri5::default();
        let runs: [(&dyn SecondOrderSystem, &SampledInput); 2] =
            [(&stiff, &SampledInput::zero(0)), (&sign, &u)];
        for (sys, input) in runs {
            let e = d.integrate(sys, input, &[1.0], &[0.0], &t).unwrap_err();
            let DynError::TooManySteps { max_steps, .. } = e else {
                panic!("{e}")
            };
            assert_eq!(max_steps, BUDGET_BASE + 2000 * STEPS_PER_STOP);
            assert!(
                e.to_string()
                    .starts_with("the model is too stiff or discontinuous")
            );
        }
        // The budget follows the run's length, and a smooth run stays far inside it.
        assert_eq!(d.budget(&u, &t[..100]), BUDGET_BASE + 100 * STEPS_PER_STOP);
        let smooth = crate::FnSystem::new(
            1,
            1,
            |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
                a[0] = u[0] - 4.0 * x[0] - 0.5 * v[0]
            },
        );
        let tr = d.integrate(&smooth, &u, &[1.0], &[0.0], &t).unwrap();
        assert!(tr.stats.steps + tr.stats.rejected < 4 * t.len());
    }

    /// The shortcut gives the clamped power to the bit over every decade of errors.
    #[test]
    fn step_factor_is_the_clamped_power() {
        assert_eq!(step_factor(0.0), 5.0);
        for i in 0..=40_000 {
            let err = 10f64.powf(-12.0 + 18.0 * i as f64 / 40_000.0);
            let want = (0.9 * err.powf(-0.2)).clamp(0.2, 5.0);
            assert_eq!(step_factor(err).to_bits(), want.to_bits(), "err {err}");
        }
    }
    use crate::FnSystem;

    /// One fixed Dormand–Prince step (5th-order solution) for order testing.
    fn fixed_run(h: f64, t_end: f64) -> (f64, f64) {
        let sys = FnSystem::new(
            1,
            0,
            |_t, x: &[f64], v: &[f64], _u: &[f64], a: &mut [f64]| a[0] = -4.0 * x[0] - 0.2 * v[0],
        );
        let input = SampledInput::zero(0);
        let opts = Dopri5 {
            rtol: 1e3,
            atol: 1e3,
            h_init: Some(h),
            h_max: h,
            ..Dopri5::default()
        };
        let mut s = opts.solver(&sys, &input, 0.0, &[1.0], &[0.0]).unwrap();
        s.advance_to(t_end).unwrap();
        (s.x()[0], s.stats().steps as f64)
    }

    #[test]
    fn fixed_step_order_is_five() {
        // x'' + 0.2 x' + 4 x = 0, x(0) = 1, v(0) = 0.
        let (z, w0) = (0.05, 2.0);
        let wd = w0 * (1.0f64 - z * z).sqrt();
        let exact = |t: f64| (-z * w0 * t).exp() * ((wd * t).cos() + z * w0 / wd * (wd * t).sin());
        let t_end = 5.0;
        let e = |h: f64| (fixed_run(h, t_end).0 - exact(t_end)).abs();
        let (e1, e2) = (e(0.1), e(0.05));
        let order = (e1 / e2).log2();
        assert!(
            (4.6..5.6).contains(&order),
            "order {order} ({e1:e}, {e2:e})"
        );
    }
}
