//! Term-level model evaluation with analytic state Jacobians, and the augmented
//! (state + forward-sensitivity) second-order system integrated by RK4.

use std::sync::Mutex;

use tfs_dynamics::SecondOrderSystem;
use tfs_library::{CompiledModel, Model};

use crate::Result;

/// The model's structure (terms in DOF order, then equation order), compiled by tfs-library.
/// Coefficients are kept outside so they can be varied.
#[derive(Debug, Clone)]
pub(crate) struct Structure {
    pub n: usize,
    pub inputs: usize,
    compiled: CompiledModel,
    /// Equation (DOF index) of each coefficient.
    eqs: Vec<usize>,
}

impl Structure {
    /// Resolves `model`'s terms. Returns the structure and the coefficient vector.
    pub fn new(model: &Model) -> Result<(Self, Vec<f64>)> {
        let compiled = model.compile()?;
        let coefs = compiled.coefficients();
        let eqs = (0..compiled.n_terms())
            .map(|j| compiled.equation_of(j))
            .collect();
        Ok((
            Self {
                n: compiled.dofs(),
                inputs: compiled.inputs(),
                compiled,
                eqs,
            },
            coefs,
        ))
    }

    /// Number of coefficients.
    pub fn params(&self) -> usize {
        self.eqs.len()
    }

    /// Equation (DOF index) of coefficient `j`.
    pub fn eq_of(&self, j: usize) -> usize {
        self.eqs[j]
    }

    /// Evaluates `a = Σ c_j θ_j`, the regressors `θ_j`, and the Jacobians `ax[i·n+k] = ∂a_i/∂x_k`,
    /// `av[i·n+k] = ∂a_i/∂v_k` ([`CompiledModel::eval_jacobian`]).
    #[allow(clippy::too_many_arguments)]
    pub fn eval(
        &self,
        coefs: &[f64],
        x: &[f64],
        v: &[f64],
        u: &[f64],
        a: &mut [f64],
        theta: &mut [f64],
        ax: &mut [f64],
        av: &mut [f64],
    ) {
        self.compiled
            .eval_jacobian(coefs, x, v, u, a, theta, ax, av);
    }
}

#[derive(Debug)]
struct Scratch {
    a: Vec<f64>,
    theta: Vec<f64>,
    ax: Vec<f64>,
    av: Vec<f64>,
}

/// The model plus its forward sensitivities as one second-order system.
///
/// Positions are `[x (n), S_x (n·Q)]`, velocities `[v, S_v]`, with sensitivity column `q`
/// stored at `n + q·n ..`. Columns `0..P` are the scaled coefficients (`∂/∂p_j` with
/// `c_j = scale_j · p_j`), columns `P..P+2n` the scaled initial state. The variational equation
/// `S_x'' = A_x S_x + A_v S_x' + Θ` is itself second order, so the tfs-dynamics RK4 step applies
/// unchanged, and because every RK4 stage of the sensitivities uses the Jacobians at the
/// corresponding stage state, the result is the exact derivative of the discrete RK4 map.
pub(crate) struct Augmented<'a> {
    pub st: &'a Structure,
    pub coefs: &'a [f64],
    pub pscale: &'a [f64],
    /// Number of sensitivity columns (0 = plain simulation).
    pub q: usize,
    scratch: Mutex<Scratch>,
}

impl<'a> Augmented<'a> {
    pub fn new(st: &'a Structure, coefs: &'a [f64], pscale: &'a [f64], q: usize) -> Self {
        let n = st.n;
        Self {
            st,
            coefs,
            pscale,
            q,
            scratch: Mutex::new(Scratch {
                a: vec![0.0; n],
                theta: vec![0.0; st.params()],
                ax: vec![0.0; n * n],
                av: vec![0.0; n * n],
            }),
        }
    }
}

impl SecondOrderSystem for Augmented<'_> {
    fn dofs(&self) -> usize {
        self.st.n * (1 + self.q)
    }
    fn inputs(&self) -> usize {
        self.st.inputs
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], out: &mut [f64]) {
        let n = self.st.n;
        let mut guard = match self.scratch.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        let s = &mut *guard;
        self.st.eval(
            self.coefs,
            &x[..n],
            &v[..n],
            u,
            &mut s.a,
            &mut s.theta,
            &mut s.ax,
            &mut s.av,
        );
        out[..n].copy_from_slice(&s.a);
        let p = self.st.params();
        for q in 0..self.q {
            let sx = &x[n + q * n..n + (q + 1) * n];
            let sv = &v[n + q * n..n + (q + 1) * n];
            let o = &mut out[n + q * n..n + (q + 1) * n];
            for (i, oi) in o.iter_mut().enumerate() {
                let (axr, avr) = (&s.ax[i * n..(i + 1) * n], &s.av[i * n..(i + 1) * n]);
                *oi = axr
                    .iter()
                    .zip(sx)
                    .zip(avr.iter().zip(sv))
                    .map(|((a, x), (b, y))| a * x + b * y)
                    .sum();
            }
            if q < p {
                let i = self.st.eq_of(q);
                o[i] += s.theta[q] * self.pscale[q];
            }
        }
    }
}
