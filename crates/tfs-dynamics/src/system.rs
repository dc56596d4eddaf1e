//! The second-order system trait and a closure adapter.

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

/// A [`SecondOrderSystem`] built from a closure `f(t, x, v, u, a)`.
///
/// ```
/// use tfs_dynamics::{FnSystem, SecondOrderSystem};
/// // Linear oscillator x'' = -4 x.
/// let sys = FnSystem::new(1, 0, |_t, x: &[f64], _v: &[f64], _u: &[f64], a: &mut [f64]| a[0] = -4.0 * x[0]);
/// let mut a = [0.0];
/// sys.accel(0.0, &[0.5], &[0.0], &[], &mut a);
/// assert_eq!(a[0], -2.0);
/// ```
#[derive(Debug, Clone)]
pub struct FnSystem<F> {
    dofs: usize,
    inputs: usize,
    f: F,
}

impl<F> FnSystem<F>
where
    F: Fn(f64, &[f64], &[f64], &[f64], &mut [f64]) + Sync,
{
    /// Wraps `f` as a system with `dofs` degrees of freedom and `inputs` input channels.
    pub fn new(dofs: usize, inputs: usize, f: F) -> Self {
        Self { dofs, inputs, f }
    }
}

impl<F> SecondOrderSystem for FnSystem<F>
where
    F: Fn(f64, &[f64], &[f64], &[f64], &mut [f64]) + Sync,
{
    fn dofs(&self) -> usize {
        self.dofs
    }
    fn inputs(&self) -> usize {
        self.inputs
    }
    fn accel(&self, t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        (self.f)(t, x, v, u, a)
    }
}
