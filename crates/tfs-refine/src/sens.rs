//! Term-level model evaluation with analytic state Jacobians, and the augmented
//! (state + forward-sensitivity) second-order system integrated by RK4.

use std::sync::Mutex;

use tfs_dynamics::SecondOrderSystem;
use tfs_library::{Coord, Factor, Model, Var};

use crate::{RefineError, Result};

#[derive(Debug, Clone, Copy)]
enum Base {
    X(usize),
    U(usize),
}

#[derive(Debug, Clone, Copy)]
enum Src {
    X(usize),
    V(usize),
    U(usize),
    RelX(usize, Base),
    RelV(usize, Base),
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    Pow(u32),
    Abs,
    Sign,
    Tanh(f64),
}

#[derive(Debug, Clone)]
struct TermEval {
    eq: usize,
    factors: Vec<(Kind, Src)>,
}

/// The model's structure (terms in DOF order, then equation order), resolved to indices.
/// Coefficients are kept outside so they can be varied.
#[derive(Debug, Clone)]
pub(crate) struct Structure {
    pub n: usize,
    pub inputs: usize,
    terms: Vec<TermEval>,
}

impl Structure {
    /// Resolves `model`'s terms. Returns the structure and the coefficient vector.
    pub fn new(model: &Model) -> Result<(Self, Vec<f64>)> {
        model.validate()?;
        let dof = |n: &str| {
            model
                .dofs
                .iter()
                .position(|d| d == n)
                .ok_or_else(|| RefineError::Model(format!("term uses unknown DOF '{n}'")))
        };
        let input =
            |n: &str| {
                model.inputs.iter().position(|d| d == n).ok_or_else(|| {
                    RefineError::Model(format!("input '{n}' is needed but not listed"))
                })
            };
        let mut terms = Vec::new();
        let mut coefs = Vec::new();
        for (e, d) in model.dofs.iter().enumerate() {
            for mt in &model.equation(d)?.terms {
                let mut factors = Vec::new();
                for f in mt.term.factors() {
                    let src = match f.var() {
                        Var::Disp(n) => Src::X(dof(n)?),
                        Var::Vel(n) => Src::V(dof(n)?),
                        Var::Input(n) => Src::U(input(n)?),
                        Var::RelDisp(a, b) => Src::RelX(
                            dof(a)?,
                            match b {
                                Coord::Dof(n) => Base::X(dof(n)?),
                                Coord::Input(n) => Base::U(input(n)?),
                            },
                        ),
                        Var::RelVel(a, b) => Src::RelV(
                            dof(a)?,
                            match b {
                                Coord::Dof(n) => Base::X(dof(n)?),
                                Coord::Input(_) => Base::U(input(&b.velocity_column())?),
                            },
                        ),
                    };
                    let kind = match f {
                        Factor::Pow(_, k) => Kind::Pow(*k),
                        Factor::Abs(_) => Kind::Abs,
                        Factor::Sign(_) => Kind::Sign,
                        Factor::Tanh(_, eps) => Kind::Tanh(1.0 / eps),
                    };
                    factors.push((kind, src));
                }
                terms.push(TermEval { eq: e, factors });
                coefs.push(mt.coef);
            }
        }
        Ok((
            Self {
                n: model.dofs.len(),
                inputs: model.inputs.len(),
                terms,
            },
            coefs,
        ))
    }

    /// Number of coefficients.
    pub fn params(&self) -> usize {
        self.terms.len()
    }

    /// Equation (DOF index) of coefficient `j`.
    #[cfg(test)]
    pub fn eq_of(&self, j: usize) -> usize {
        self.terms[j].eq
    }

    /// Evaluates `a = Σ c_j θ_j`, the regressors `θ_j`, and the Jacobians `ax[i·n+k] = ∂a_i/∂x_k`,
    /// `av[i·n+k] = ∂a_i/∂v_k` (analytic: product rule over each term's factors).
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
        let n = self.n;
        a[..n].fill(0.0);
        ax[..n * n].fill(0.0);
        av[..n * n].fill(0.0);
        let mut vals = [0.0f64; 8];
        let mut ders = [0.0f64; 8];
        for (j, t) in self.terms.iter().enumerate() {
            let nf = t.factors.len();
            let mut prod = 1.0;
            // Small fixed buffers; terms with more than 8 factors fall back to a slower path.
            let mut big_vals = Vec::new();
            let mut big_ders = Vec::new();
            let (fv, fd): (&mut [f64], &mut [f64]) = if nf <= 8 {
                (&mut vals[..nf], &mut ders[..nf])
            } else {
                big_vals.resize(nf, 0.0);
                big_ders.resize(nf, 0.0);
                (&mut big_vals[..], &mut big_ders[..])
            };
            for (m, &(kind, src)) in t.factors.iter().enumerate() {
                let s = value(src, x, v, u);
                let (f, d) = match kind {
                    Kind::Pow(0) => (1.0, 0.0),
                    Kind::Pow(1) => (s, 1.0),
                    Kind::Pow(2) => (s * s, 2.0 * s),
                    Kind::Pow(3) => (s * s * s, 3.0 * s * s),
                    Kind::Pow(k) => (s.powi(k as i32), k as f64 * s.powi(k as i32 - 1)),
                    Kind::Abs => (s.abs(), sign0(s)),
                    Kind::Sign => (sign0(s), 0.0),
                    Kind::Tanh(inv) => {
                        let th = (s * inv).tanh();
                        (th, inv * (1.0 - th * th))
                    }
                };
                fv[m] = f;
                fd[m] = d;
                prod *= f;
            }
            theta[j] = prod;
            let c = coefs[j];
            let i = t.eq;
            a[i] += c * prod;
            for (m, &(_, src)) in t.factors.iter().enumerate() {
                if fd[m] == 0.0 {
                    continue;
                }
                let mut others = 1.0;
                for (l, f) in fv.iter().enumerate() {
                    if l != m {
                        others *= f;
                    }
                }
                let g = c * fd[m] * others;
                match src {
                    Src::X(k) => ax[i * n + k] += g,
                    Src::V(k) => av[i * n + k] += g,
                    Src::U(_) => {}
                    Src::RelX(k, b) => {
                        ax[i * n + k] += g;
                        if let Base::X(l) = b {
                            ax[i * n + l] -= g;
                        }
                    }
                    Src::RelV(k, b) => {
                        av[i * n + k] += g;
                        if let Base::X(l) = b {
                            av[i * n + l] -= g;
                        }
                    }
                }
            }
        }
    }
}

#[inline]
fn sign0(s: f64) -> f64 {
    if s > 0.0 {
        1.0
    } else if s < 0.0 {
        -1.0
    } else {
        0.0
    }
}

#[inline]
fn value(src: Src, x: &[f64], v: &[f64], u: &[f64]) -> f64 {
    match src {
        Src::X(i) => x[i],
        Src::V(i) => v[i],
        Src::U(k) => u[k],
        Src::RelX(i, Base::X(j)) => x[i] - x[j],
        Src::RelX(i, Base::U(k)) => x[i] - u[k],
        Src::RelV(i, Base::X(j)) => v[i] - v[j],
        Src::RelV(i, Base::U(k)) => v[i] - u[k],
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
                let i = self.st.terms[q].eq;
                o[i] += s.theta[q] * self.pscale[q];
            }
        }
    }
}
