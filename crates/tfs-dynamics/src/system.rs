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

    /// Accelerations of many states at once (all at time `t`, sharing the inputs `u`), stored
    /// component-major: with `m = x.len() / dofs()` states, `x[i * m + l]` is DOF `i` of state `l`
    /// (likewise `v` and `a`). The default calls [`SecondOrderSystem::accel`] state by state; a
    /// system may override it with loops across states that vectorise, and must then give each
    /// state exactly what `accel` gives it (basin maps rely on that).
    fn accel_lanes(&self, t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        let n = self.dofs();
        if n == 0 {
            return;
        }
        let m = x.len() / n;
        // Up to 8 DOFs on the stack (no allocation per call), more on the heap.
        let (mut xs, mut vs, mut as_) = ([0.0; 8], [0.0; 8], [0.0; 8]);
        let (mut xh, mut vh, mut ah) = (Vec::new(), Vec::new(), Vec::new());
        let (xl, vl, al): (&mut [f64], &mut [f64], &mut [f64]) = if n <= 8 {
            (&mut xs[..n], &mut vs[..n], &mut as_[..n])
        } else {
            xh.resize(n, 0.0);
            vh.resize(n, 0.0);
            ah.resize(n, 0.0);
            (&mut xh, &mut vh, &mut ah)
        };
        for l in 0..m {
            for i in 0..n {
                xl[i] = x[i * m + l];
                vl[i] = v[i * m + l];
            }
            self.accel(t, xl, vl, u, al);
            for i in 0..n {
                a[i * m + l] = al[i];
            }
        }
    }

    /// How many of the `dofs()` coordinates, the last ones, carry internal states rather than
    /// motion: a first-order state `z' = g(…)` held as the velocity of an auxiliary coordinate
    /// (its acceleration is the state's rate, its position is not used), not measured and
    /// started at 0 (a Maxwell element, Bouc–Wen hysteresis, Dahl friction; see
    /// `tfs_library::CompiledModel`). Default 0.
    fn internal_states(&self) -> usize {
        0
    }

    /// The accelerations `a` that [`SecondOrderSystem::accel`] gives (to rounding) and their
    /// Jacobians over the system's `N = dofs()` coordinates, row-major: `ax[i * N + k] =
    /// ∂a_i/∂x_k`, `av[i * N + k] = ∂a_i/∂v_k` (`ax`, `av` hold `N²` entries). Returns `false`,
    /// writing nothing, when the system has no analytic derivative (the default): callers then
    /// take differences of whole runs. A system returns `true` only where its acceleration is
    /// continuous in the state (a kink such as a stop's contact or `|v|` is fine: the flow's
    /// derivative is still the variational equation's solution; a jump such as `sign(v)` is
    /// not, since crossing it moves the run by a step the derivative does not see).
    #[allow(clippy::too_many_arguments)]
    fn accel_jacobian(
        &self,
        _t: f64,
        _x: &[f64],
        _v: &[f64],
        _u: &[f64],
        _a: &mut [f64],
        _ax: &mut [f64],
        _av: &mut [f64],
    ) -> bool {
        false
    }
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
