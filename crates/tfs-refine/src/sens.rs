//! Term-level model evaluation with analytic state Jacobians, and the augmented
//! (state + forward-sensitivity) second-order system integrated by RK4.

use std::sync::Mutex;

use tfs_dynamics::SecondOrderSystem;
use tfs_library::{CompiledModel, Model};

use crate::Result;

/// The model's structure (terms in DOF order, then equation order), compiled by tfs-library.
/// Coefficients and internal-state parameters are kept outside so they can be varied.
///
/// Unknowns of a refinement: the `P` coefficients, then the `R` refinable parameters of the
/// model's internal states ([`CompiledModel::state_params`]); the system has `n` DOFs and `m`
/// internal states, `nn = n + m` second-order coordinates (a state is the velocity of an
/// auxiliary coordinate, see [`CompiledModel`]).
#[derive(Debug, Clone)]
pub(crate) struct Structure {
    pub n: usize,
    /// Internal states.
    pub m: usize,
    /// Coordinates of the second-order system, `n + m`.
    pub nn: usize,
    pub inputs: usize,
    compiled: CompiledModel,
    /// Equation (DOF index) of each coefficient.
    eqs: Vec<usize>,
    /// Internal state of each state parameter.
    state_of: Vec<usize>,
}

impl Structure {
    /// Resolves `model`'s terms. Returns the structure and the start values of the unknowns
    /// (coefficients, then state parameters).
    pub fn new(model: &Model) -> Result<(Self, Vec<f64>)> {
        let compiled = model.compile()?;
        let mut start = compiled.coefficients();
        start.extend(compiled.state_params());
        let eqs = (0..compiled.n_terms())
            .map(|j| compiled.equation_of(j))
            .collect();
        Ok((
            Self {
                n: compiled.dofs(),
                m: compiled.states(),
                nn: compiled.system_dofs(),
                inputs: compiled.inputs(),
                state_of: compiled.state_of_param(),
                compiled,
                eqs,
            },
            start,
        ))
    }

    /// Number of unknowns of the model: coefficients and state parameters.
    pub fn params(&self) -> usize {
        self.eqs.len() + self.state_of.len()
    }

    /// Number of coefficients.
    pub fn n_coefs(&self) -> usize {
        self.eqs.len()
    }

    /// Equation (DOF index) of coefficient `j`.
    pub fn eq_of(&self, j: usize) -> usize {
        self.eqs[j]
    }

    /// Internal state of state parameter `r`.
    pub fn state_of(&self, r: usize) -> usize {
        self.state_of[r]
    }

    /// Unknowns per shooting segment: `x0`, `v0` of the DOFs and the start of every state.
    pub fn seg_states(&self) -> usize {
        2 * self.n + self.m
    }

    /// The compiled model with the state parameters `sp`; `None` when they are invalid (a
    /// non-positive time constant).
    pub fn with_state_params(&self, sp: &[f64]) -> Option<CompiledModel> {
        if sp.is_empty() {
            return Some(self.compiled.clone());
        }
        self.compiled.with_state_params(sp).ok()
    }

    /// The laws of `model`'s internal states with the state parameters `sp`.
    pub fn laws(&self, sp: &[f64]) -> Option<Vec<tfs_library::StateLaw>> {
        self.with_state_params(sp).map(|c| c.state_laws())
    }
}

impl Structure {
    /// Evaluates `a = Σ c_j θ_j`, the regressors `θ_j`, and the Jacobians
    /// `ax[i·nn+k] = ∂a_i/∂x_k`, `av[i·nn+k] = ∂a_i/∂v_k` over the system's `nn` coordinates
    /// with the start state parameters ([`CompiledModel::eval_jacobian`]).
    #[cfg(test)]
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
    /// `∂z_j'/∂(state parameter r)`.
    dg: Vec<f64>,
}

/// The model plus its forward sensitivities as one second-order system.
///
/// Positions are `[x (nn), S_x (nn·Q)]`, velocities `[v, S_v]`, with sensitivity column `q`
/// stored at `nn + q·nn ..`. Columns `0..P` are the scaled coefficients (`∂/∂p_j` with
/// `c_j = scale_j · p_j`), columns `P..P+R` the scaled state parameters, the rest the scaled
/// initial state of the segment (`x0`, `v0` of the DOFs, the states' start). The variational
/// equation `S_x'' = A_x S_x + A_v S_x' + F` is itself second order (an internal state's row is
/// the derivative of its rate, its sensitivity the velocity of the auxiliary coordinate), so the
/// tfs-dynamics RK4 step applies unchanged, and because every RK4 stage of the sensitivities
/// uses the Jacobians at the corresponding stage state, the result is the exact derivative of
/// the discrete RK4 map.
pub(crate) struct Augmented<'a> {
    pub st: &'a Structure,
    /// The model with the current state parameters.
    compiled: CompiledModel,
    pub coefs: &'a [f64],
    pub pscale: &'a [f64],
    /// Number of sensitivity columns (0 = plain simulation).
    pub q: usize,
    scratch: Mutex<Scratch>,
}

impl<'a> Augmented<'a> {
    /// The augmented system for coefficients `coefs` and state parameters `sp`; `None` when
    /// the state parameters are invalid.
    pub fn new(
        st: &'a Structure,
        coefs: &'a [f64],
        sp: &[f64],
        pscale: &'a [f64],
        q: usize,
    ) -> Option<Self> {
        let nn = st.nn;
        Some(Self {
            st,
            compiled: st.with_state_params(sp)?,
            coefs,
            pscale,
            q,
            scratch: Mutex::new(Scratch {
                a: vec![0.0; nn],
                theta: vec![0.0; st.n_coefs()],
                ax: vec![0.0; nn * nn],
                av: vec![0.0; nn * nn],
                dg: vec![0.0; st.params() - st.n_coefs()],
            }),
        })
    }
}

impl SecondOrderSystem for Augmented<'_> {
    fn dofs(&self) -> usize {
        self.st.nn * (1 + self.q)
    }
    fn inputs(&self) -> usize {
        self.st.inputs
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], out: &mut [f64]) {
        let nn = self.st.nn;
        let mut guard = match self.scratch.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        let s = &mut *guard;
        self.compiled.eval_jacobian(
            self.coefs,
            &x[..nn],
            &v[..nn],
            u,
            &mut s.a,
            &mut s.theta,
            &mut s.ax,
            &mut s.av,
        );
        out[..nn].copy_from_slice(&s.a);
        let pc = self.st.n_coefs();
        let p = self.st.params();
        if p > pc && self.q > pc {
            self.compiled
                .state_param_gradient(&x[..nn], &v[..nn], u, &mut s.dg);
        }
        for q in 0..self.q {
            let sx = &x[nn + q * nn..nn + (q + 1) * nn];
            let sv = &v[nn + q * nn..nn + (q + 1) * nn];
            let o = &mut out[nn + q * nn..nn + (q + 1) * nn];
            for (i, oi) in o.iter_mut().enumerate() {
                let (axr, avr) = (&s.ax[i * nn..(i + 1) * nn], &s.av[i * nn..(i + 1) * nn]);
                *oi = axr
                    .iter()
                    .zip(sx)
                    .zip(avr.iter().zip(sv))
                    .map(|((a, x), (b, y))| a * x + b * y)
                    .sum();
            }
            if q < pc {
                let i = self.st.eq_of(q);
                o[i] += s.theta[q] * self.pscale[q];
            } else if q < p {
                let r = q - pc;
                o[self.st.n + self.st.state_of(r)] += s.dg[r] * self.pscale[q];
            }
        }
    }
}
