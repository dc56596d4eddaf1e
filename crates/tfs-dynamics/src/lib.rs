//! Second-order dynamics: the system trait, integrators, simulation under a sampled input,
//! blow-up detection, and equilibria of 1-DOF restoring forces.
//!
//! (Contract: being implemented.)

/// A second-order system `x'' = a(t, x, x', u)` with `dofs()` degrees of freedom and `inputs()`
/// input channels. The one required method is [`SecondOrderSystem::accel`].
pub trait SecondOrderSystem: Sync {
    /// Number of degrees of freedom (length of `x`, `v` and `a`).
    fn dofs(&self) -> usize;
    /// Number of input channels (length of `u`); 0 for autonomous systems.
    fn inputs(&self) -> usize {
        0
    }
    /// Writes the accelerations for time `t`, displacements `x`, velocities `v`, inputs `u`.
    fn accel(&self, t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]);
}

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
