//! Classical fourth-order Runge–Kutta: the single step used by other crates and a fixed-step
//! integrator.

use crate::integrate::{blowup_limit, check_args, check_limit, check_state};
use crate::{DynError, Integrator, Result, SampledInput, SecondOrderSystem, Trajectory};

/// Scratch buffers for [`rk4_step`], sized once for a system so the hot loop never allocates.
#[derive(Debug, Clone)]
pub struct Rk4Scratch {
    k: [Vec<f64>; 8],
    xt: Vec<f64>,
    vt: Vec<f64>,
}

impl Rk4Scratch {
    /// Buffers for a system with `dofs` degrees of freedom.
    pub fn new(dofs: usize) -> Self {
        Self {
            k: std::array::from_fn(|_| vec![0.0; dofs]),
            xt: vec![0.0; dofs],
            vt: vec![0.0; dofs],
        }
    }
}

/// One classical fourth-order Runge–Kutta step of length `h` from time `t`, in place.
/// `u0`, `u_mid`, `u1` are the inputs at `t`, `t + h/2` and `t + h`.
#[allow(clippy::too_many_arguments)]
pub fn rk4_step<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    t: f64,
    h: f64,
    x: &mut [f64],
    v: &mut [f64],
    u0: &[f64],
    u_mid: &[f64],
    u1: &[f64],
    s: &mut Rk4Scratch,
) {
    let n = x.len();
    let [a1, a2, a3, a4, v2, v3, v4, _] = &mut s.k;
    // Stage 1.
    sys.accel(t, x, v, u0, a1);
    // Stage 2.
    for i in 0..n {
        s.xt[i] = x[i] + 0.5 * h * v[i];
        v2[i] = v[i] + 0.5 * h * a1[i];
    }
    sys.accel(t + 0.5 * h, &s.xt, v2, u_mid, a2);
    // Stage 3.
    for i in 0..n {
        s.xt[i] = x[i] + 0.5 * h * v2[i];
        v3[i] = v[i] + 0.5 * h * a2[i];
    }
    sys.accel(t + 0.5 * h, &s.xt, v3, u_mid, a3);
    // Stage 4.
    for i in 0..n {
        s.xt[i] = x[i] + h * v3[i];
        v4[i] = v[i] + h * a3[i];
    }
    sys.accel(t + h, &s.xt, v4, u1, a4);
    for i in 0..n {
        x[i] += h / 6.0 * (v[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i]);
        s.vt[i] = v[i] + h / 6.0 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i]);
    }
    v.copy_from_slice(&s.vt);
}

/// Fixed-step classical RK4.
///
/// Between consecutive break points (output times and input sample times) the interval is split
/// into the fewest equal steps no longer than `h`. The state is checked for blow-up after every
/// step (limit `blowup_limit`, or `1e6 · max(1, |x0|, |v0|)` when `None`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rk4 {
    /// Largest step (s).
    pub h: f64,
    /// Largest allowed |x| or |v| before the run is declared blown up; `None` = automatic.
    pub blowup_limit: Option<f64>,
}

impl Rk4 {
    /// RK4 with step `h` and the automatic blow-up limit.
    pub fn new(h: f64) -> Self {
        Self {
            h,
            blowup_limit: None,
        }
    }
}

impl Integrator for Rk4 {
    fn integrate<S: SecondOrderSystem + ?Sized>(
        &self,
        sys: &S,
        input: &SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
    ) -> Result<Trajectory> {
        if !(self.h.is_finite() && self.h > 0.0) {
            return Err(DynError::InvalidParameter {
                name: "h",
                reason: format!("RK4 step {} must be positive and finite", self.h),
            });
        }
        check_limit(self.blowup_limit)?;
        check_args(sys, input, x0, v0, t_out)?;
        let limit = blowup_limit(self.blowup_limit, x0, v0);
        let n = sys.dofs();
        let k = input.channels();
        let (mut u0, mut um, mut u1) = (vec![0.0; k], vec![0.0; k], vec![0.0; k]);
        let mut scratch = Rk4Scratch::new(n);
        let mut x = x0.to_vec();
        let mut v = v0.to_vec();
        let mut traj = Trajectory::with_capacity(n, t_out.len());
        let mut t = t_out[0];
        traj.push(t, &x, &v);
        for &tn in &t_out[1..] {
            while t < tn {
                let stop = input.next_sample_after(t).map_or(tn, |s| s.min(tn));
                let len = stop - t;
                let steps = ((len / self.h) * (1.0 - 1e-12)).ceil().max(1.0) as usize;
                let h = len / steps as f64;
                for j in 0..steps {
                    let ts = t + j as f64 * h;
                    input.eval(ts, &mut u0);
                    input.eval(ts + 0.5 * h, &mut um);
                    input.eval(ts + h, &mut u1);
                    rk4_step(sys, ts, h, &mut x, &mut v, &u0, &um, &u1, &mut scratch);
                    traj.stats.steps += 1;
                    traj.stats.evals += 4;
                    check_state(ts + h, &x, &v, limit)?;
                }
                t = stop;
            }
            traj.push(tn, &x, &v);
        }
        Ok(traj)
    }
}
