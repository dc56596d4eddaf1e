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
