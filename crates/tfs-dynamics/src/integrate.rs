//! The common integrator entry point, trajectories, argument checks and blow-up detection.

use crate::{DynError, Result, SampledInput, SecondOrderSystem};

/// Counters of integrator work.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Accepted steps.
    pub steps: usize,
    /// Rejected steps (adaptive integrators only).
    pub rejected: usize,
    /// Calls of [`SecondOrderSystem::accel`].
    pub evals: usize,
}

/// A simulated trajectory at the requested output times.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Output times (s), equal to the requested `t_out`.
    pub t: Vec<f64>,
    /// Displacements per degree of freedom: `x[dof][k]` at time `t[k]`.
    pub x: Vec<Vec<f64>>,
    /// Velocities per degree of freedom: `v[dof][k]` at time `t[k]`.
    pub v: Vec<Vec<f64>>,
    /// Work counters.
    pub stats: Stats,
}

impl Trajectory {
    /// An empty trajectory for `dofs` degrees of freedom with room for `n` samples.
    pub fn with_capacity(dofs: usize, n: usize) -> Self {
        Self {
            t: Vec::with_capacity(n),
            x: (0..dofs).map(|_| Vec::with_capacity(n)).collect(),
            v: (0..dofs).map(|_| Vec::with_capacity(n)).collect(),
            stats: Stats::default(),
        }
    }

    /// Appends the state `(x, v)` at time `t`.
    pub fn push(&mut self, t: f64, x: &[f64], v: &[f64]) {
        self.t.push(t);
        for (col, xi) in self.x.iter_mut().zip(x) {
            col.push(*xi);
        }
        for (col, vi) in self.v.iter_mut().zip(v) {
            col.push(*vi);
        }
    }

    /// Number of output samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True if there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Number of degrees of freedom.
    pub fn dofs(&self) -> usize {
        self.x.len()
    }
}

/// An integrator for [`SecondOrderSystem`]s under a [`SampledInput`].
///
/// `t_out` lists the output times in non-decreasing order; the simulation starts at `t_out[0]`
/// from `(x0, v0)`, and the returned trajectory has one sample per entry of `t_out` (the first
/// being the initial state). Integrators never step across an input sample time: they stop at
/// each one, so the interpolated input is smooth inside every step.
pub trait Integrator {
    /// Simulates `sys` under `input` from `(x0, v0)` and returns the states at `t_out`.
    fn integrate<S: SecondOrderSystem + ?Sized>(
        &self,
        sys: &S,
        input: &SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
    ) -> Result<Trajectory>;

    /// [`Integrator::integrate`] that may stop early: `keep_going(k, x)` is called with the
    /// displacements at each output time `t_out[k]` in order (`k = 0` the initial state), and
    /// the run ends with `Ok(None)` at the first `false`. Every sample before the stop is the
    /// one [`Integrator::integrate`] gives, bit for bit; a run that is not stopped returns its
    /// trajectory. A caller that rejects a run once a running misfit is too large so spends
    /// nothing on the rest of it. The default integrates the whole run, then asks.
    ///
    /// Errors: those of [`Integrator::integrate`] met before the stop.
    fn integrate_until<S: SecondOrderSystem + ?Sized, F: FnMut(usize, &[f64]) -> bool>(
        &self,
        sys: &S,
        input: &SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
        mut keep_going: F,
    ) -> Result<Option<Trajectory>> {
        let tr = self.integrate(sys, input, x0, v0, t_out)?;
        let mut x = vec![0.0; tr.dofs()];
        for k in 0..tr.len() {
            for (xi, col) in x.iter_mut().zip(&tr.x) {
                *xi = col[k];
            }
            if !keep_going(k, &x) {
                return Ok(None);
            }
        }
        Ok(Some(tr))
    }
}

/// Checks the arguments shared by every integrator.
pub(crate) fn check_args<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    input: &SampledInput,
    x0: &[f64],
    v0: &[f64],
    t_out: &[f64],
) -> Result<()> {
    let n = sys.dofs();
    if x0.len() != n {
        return Err(DynError::Dimension {
            name: "x0",
            expected: n,
            got: x0.len(),
            hint: "give one initial displacement per degree of freedom",
        });
    }
    if v0.len() != n {
        return Err(DynError::Dimension {
            name: "v0",
            expected: n,
            got: v0.len(),
            hint: "give one initial velocity per degree of freedom",
        });
    }
    if input.channels() != sys.inputs() {
        return Err(DynError::Dimension {
            name: "input channels",
            expected: sys.inputs(),
            got: input.channels(),
            hint: "give one input channel per system input (SampledInput::zero(k) for a free run)",
        });
    }
    if let Some(i) = x0.iter().chain(v0).position(|z| !z.is_finite()) {
        return Err(DynError::InvalidParameter {
            name: "x0/v0",
            reason: format!("initial state entry {i} is not finite; give a finite initial state"),
        });
    }
    if t_out.is_empty() {
        return Err(DynError::InvalidParameter {
            name: "t_out",
            reason: "no output times; give at least the start time".into(),
        });
    }
    for (k, w) in t_out.windows(2).enumerate() {
        if w[1].is_nan() || w[0].is_nan() || w[1] < w[0] {
            return Err(DynError::InvalidParameter {
                name: "t_out",
                reason: format!(
                    "output time {} at index {} is before {} at index {k}; sort the output times",
                    w[1],
                    k + 1,
                    w[0]
                ),
            });
        }
    }
    if let Some(k) = t_out.iter().position(|t| !t.is_finite()) {
        return Err(DynError::InvalidParameter {
            name: "t_out",
            reason: format!("output time at index {k} is not finite"),
        });
    }
    Ok(())
}

/// Default blow-up limit: `1e6 · max(1, max|x0|, max|v0|)`.
pub(crate) fn blowup_limit(user: Option<f64>, x0: &[f64], v0: &[f64]) -> f64 {
    user.unwrap_or_else(|| {
        let scale = x0.iter().chain(v0).fold(1.0_f64, |m, z| m.max(z.abs()));
        1e6 * scale
    })
}

/// Validates a user-set blow-up limit.
pub(crate) fn check_limit(user: Option<f64>) -> Result<()> {
    match user {
        Some(l) if !(l.is_finite() && l > 0.0) => Err(DynError::InvalidParameter {
            name: "blowup_limit",
            reason: format!("{l} must be positive and finite (or None for the automatic limit)"),
        }),
        _ => Ok(()),
    }
}

/// Returns a [`DynError::BlowUp`] if any entry of `x` or `v` is non-finite or above `limit`.
pub(crate) fn check_state(t: f64, x: &[f64], v: &[f64], limit: f64) -> Result<()> {
    let bad = x.iter().chain(v).any(|z| !z.is_finite() || z.abs() > limit);
    if bad {
        return Err(DynError::BlowUp {
            t,
            x: x.to_vec(),
            v: v.to_vec(),
        });
    }
    Ok(())
}
