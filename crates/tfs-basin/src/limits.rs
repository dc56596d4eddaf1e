//! The longest RK4 step a map can use: the fastest linearised rate of the system on the states
//! its starts can reach, from finite-difference Jacobians at the equilibria, across the grid and
//! (1-DOF) at the turning points of the highest energy on the grid.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use tfs_dynamics::SecondOrderSystem;

use crate::chain::{ChainWells, Slice};
use crate::error::{BasinError, Result};
use crate::grid::BasinConfig;
use crate::wells::WellInfo;

/// Classical RK4 is stable for `dt · |λ| ≤ 2.78` on the negative real axis and `≤ 2.83` on the
/// imaginary one; a step is refused beyond this (a little inside both).
pub const RK4_STABLE: f64 = 2.5;
/// Samples per axis of the grid and of the reachable displacement range.
const SAMPLES: usize = 17;

/// The fastest linearised rate of a system on the states a map can reach, and the longest RK4
/// step that is stable there.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepLimit {
    /// Largest `|λ|` (1/s) of the Jacobian of `(x, v) ↦ (v, a(x, v))` over the sampled states.
    pub rate: f64,
    /// Displacements where it was found.
    pub at_x: Vec<f64>,
    /// Velocities where it was found.
    pub at_v: Vec<f64>,
}

impl StepLimit {
    /// The longest stable step, `RK4_STABLE / rate` (infinite for a system with no dynamics).
    pub fn max_dt(&self) -> f64 {
        RK4_STABLE / self.rate
    }
    /// Refuses a step above [`StepLimit::max_dt`] with [`BasinError::StepTooLong`].
    pub fn check(&self, dt: f64) -> Result<()> {
        if dt > self.max_dt() {
            return Err(BasinError::StepTooLong {
                dt,
                rate: self.rate,
                max_dt: self.max_dt(),
                at_x: self.at_x.clone(),
                at_v: self.at_v.clone(),
            });
        }
        Ok(())
    }
}

/// One derivative by central differences at two step sizes; a value that grows as the step
/// shrinks is a jump (dry friction at zero velocity, say), not a rate, and counts as 0.
fn derivative(f: &mut dyn FnMut(f64) -> f64, at: f64) -> f64 {
    let h = 1e-6 * at.abs().max(1.0);
    let d = |f: &mut dyn FnMut(f64) -> f64, h: f64| (f(at + h) - f(at - h)) / (2.0 * h);
    let (fine, coarse) = (d(f, h), d(f, 10.0 * h));
    if !(fine.is_finite() && coarse.is_finite()) {
        return 0.0;
    }
    let scale = fine.abs().max(coarse.abs());
    if (fine - coarse).abs() <= 0.5 * scale {
        fine
    } else {
        0.0
    }
}

/// The largest `|λ|` of the first-order Jacobian `[[0, I], [∂a/∂x, ∂a/∂v]]` at `(x, v)`; the
/// system's internal states (coordinates beyond those given) at rest.
fn rate_at<S: SecondOrderSystem + ?Sized>(sys: &S, x: &[f64], v: &[f64]) -> f64 {
    let n = sys.dofs();
    let (mut x, mut v) = (x.to_vec(), v.to_vec());
    x.resize(n, 0.0);
    v.resize(n, 0.0);
    let (x, v) = (x.as_slice(), v.as_slice());
    let u = vec![0.0; sys.inputs()];
    let mut jac = DMatrix::<f64>::zeros(2 * n, 2 * n);
    for i in 0..n {
        jac[(i, n + i)] = 1.0;
    }
    let (mut xs, mut vs, mut a) = (x.to_vec(), v.to_vec(), vec![0.0; n]);
    for k in 0..2 * n {
        for i in 0..n {
            let mut f = |p: f64| {
                if k < n {
                    xs[k] = p;
                } else {
                    vs[k - n] = p;
                }
                sys.accel(0.0, &xs, &vs, &u, &mut a);
                xs.copy_from_slice(x);
                vs.copy_from_slice(v);
                a[i]
            };
            let at = if k < n { x[k] } else { v[k - n] };
            jac[(n + i, k)] = derivative(&mut f, at);
        }
    }
    if n == 1 {
        // Closed form: λ = (a_v ± √(a_v² + 4 a_x)) / 2.
        let (ax, av) = (jac[(1, 0)], jac[(1, 1)]);
        let disc = av * av + 4.0 * ax;
        return if disc >= 0.0 {
            0.5 * (av.abs() + disc.sqrt())
        } else {
            (-ax).sqrt()
        };
    }
    jac.complex_eigenvalues()
        .iter()
        .map(|l| l.norm())
        .fold(0.0, f64::max)
}

/// The fastest rate over `points` (pairs of displacement and velocity vectors).
fn fastest<S: SecondOrderSystem + ?Sized>(sys: &S, points: &[(Vec<f64>, Vec<f64>)]) -> StepLimit {
    let mut best = StepLimit {
        rate: 0.0,
        at_x: vec![0.0; sys.dofs()],
        at_v: vec![0.0; sys.dofs()],
    };
    for (x, v) in points {
        let r = rate_at(sys, x, v);
        if r > best.rate {
            best = StepLimit {
                rate: r,
                at_x: x.clone(),
                at_v: v.clone(),
            };
        }
    }
    best
}

fn spread((a, b): (f64, f64), n: usize) -> impl Iterator<Item = f64> {
    (0..n).map(move |k| a + (b - a) * k as f64 / (n - 1) as f64)
}

/// [`StepLimit`] of a 1-DOF map: the Jacobian at every equilibrium, on a 17 × 17 sample of the
/// grid, and at rest and at full speed across the displacements the highest energy on the grid
/// can reach (energy never grows, so no trajectory leaves them).
pub fn step_limit_sdof<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &WellInfo,
    cfg: &BasinConfig,
) -> Result<StepLimit> {
    let mut points = Vec::new();
    for &e in wells.stable().iter().chain(wells.unstable()) {
        points.push((vec![e], vec![0.0]));
    }
    let mut top = f64::NEG_INFINITY;
    for x in spread(cfg.x_range, SAMPLES) {
        for v in spread(cfg.v_range, SAMPLES) {
            points.push((vec![x], vec![v]));
            top = top.max(wells.energy(x, v));
        }
    }
    let (slo, shi) = wells.search();
    let span = (slo.min(cfg.x_range.0), shi.max(cfg.x_range.1));
    for x in spread(span, 8 * SAMPLES) {
        let kinetic = top - wells.potential(x);
        if kinetic >= 0.0 {
            let vmax = (2.0 * kinetic / wells.mass()).sqrt();
            points.push((vec![x], vec![0.0]));
            points.push((vec![x], vec![vmax]));
            points.push((vec![x], vec![-vmax]));
        }
    }
    Ok(fastest(sys, &points))
}

/// [`StepLimit`] of a chain map on `slice`: the Jacobian at every stable state and on a
/// 17 × 17 sample of the slice's grid.
pub fn step_limit_chain<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &ChainWells,
    slice: &Slice,
    cfg: &BasinConfig,
) -> Result<StepLimit> {
    let n = sys.dofs();
    let mut points: Vec<(Vec<f64>, Vec<f64>)> = wells
        .stable()
        .iter()
        .map(|s| (s.clone(), vec![0.0; n]))
        .collect();
    for c0 in spread(cfg.x_range, SAMPLES) {
        for c1 in spread(cfg.v_range, SAMPLES) {
            points.push(slice.state(c0, c1));
        }
    }
    Ok(fastest(sys, &points))
}
