//! A compiled model: index-resolved terms for fast, allocation-free acceleration evaluation.

use crate::model::Model;
use crate::state::StateLaw;
use crate::term::{Coord, Factor, Var, pow_u, sign0};
use crate::{LibraryError, Result};

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
    /// Internal state `j`: `v[n + j]`.
    Z(usize),
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    Pow(u32),
    Abs,
    Sign,
    Tanh(f64),
    /// `max(0, c − s)`.
    Below(f64),
    /// `max(0, s − c)`.
    Above(f64),
}

/// A term that is one power of a displacement, velocity or input (`coef·s^k`, most terms of a
/// polynomial model), evaluated without the general factor loop; `Other` for the rest.
#[derive(Debug, Clone, Copy)]
enum Mono {
    X(usize, u32),
    V(usize, u32),
    U(usize, u32),
    Other,
}

#[derive(Debug, Clone, Copy)]
struct CFactor {
    src: Src,
    kind: Kind,
}

/// One internal state: its drive (a velocity coordinate) and its law.
#[derive(Debug, Clone, Copy)]
struct CState {
    drive: Src,
    law: StateLaw,
}

/// A model with every name resolved to an index: `accel` does no allocation and no lookups.
///
/// Build with [`Model::compile`]. States `x`, `v` are in the model's DOF order, inputs `u` in
/// [`CompiledModel::input_names`] order (`xb`, `xb_vel` for relative coordinates to the base
/// are inputs too).
///
/// **Internal states.** A model whose terms use `m` internal states ([`Model::internal_states`]
/// order) is a system of `n + m` second-order coordinates ([`CompiledModel::system_dofs`]):
/// internal state `j` is the *velocity* `v[n + j]` of an auxiliary coordinate, and its
/// acceleration `out[n + j]` is the state's rate `z_j' = g_j(q', z_j)`. The auxiliary
/// positions `x[n + j]` are not used. So any integrator of second-order systems integrates the
/// states with the motion; a simulation starts them at 0.
#[derive(Debug, Clone)]
pub struct CompiledModel {
    dof_names: Vec<String>,
    input_names: Vec<String>,
    factors: Vec<CFactor>,
    /// Per term: (coefficient, first factor, end factor).
    terms: Vec<(f64, usize, usize)>,
    /// Per term: its form when it is one power of a plain coordinate.
    mono: Vec<Mono>,
    /// Per equation: range into `terms`.
    equations: Vec<(usize, usize)>,
    /// Internal states, in [`Model::internal_states`] order.
    states: Vec<CState>,
}

impl Model {
    /// Compiles the model for fast evaluation (validates it first).
    pub fn compile(&self) -> Result<CompiledModel> {
        self.validate()?;
        let dof = |n: &str| self.dofs.iter().position(|d| d == n);
        let input = |n: &str| {
            self.inputs
                .iter()
                .position(|d| d == n)
                .ok_or_else(|| LibraryError::Invalid {
                    field: "inputs".into(),
                    message: format!("input '{n}' is needed but not listed"),
                })
        };
        let base_x = |c: &Coord| -> Result<Base> {
            match c {
                Coord::Dof(n) => dof(n).map(Base::X).ok_or_else(|| unknown(n)),
                Coord::Input(n) => input(n).map(Base::U),
            }
        };
        let base_v = |c: &Coord| -> Result<Base> {
            match c {
                Coord::Dof(n) => dof(n).map(Base::X).ok_or_else(|| unknown(n)),
                Coord::Input(_) => input(&c.velocity_column()).map(Base::U),
            }
        };
        let src_of = |var: &Var| -> Result<Src> {
            Ok(match var {
                Var::Disp(n) => Src::X(dof(n).ok_or_else(|| unknown(n))?),
                Var::Vel(n) => Src::V(dof(n).ok_or_else(|| unknown(n))?),
                Var::Input(n) => Src::U(input(n)?),
                Var::RelDisp(a, b) => Src::RelX(dof(a).ok_or_else(|| unknown(a))?, base_x(b)?),
                Var::RelVel(a, b) => Src::RelV(dof(a).ok_or_else(|| unknown(a))?, base_v(b)?),
            })
        };
        let internal = self.internal_states();
        let states = internal
            .iter()
            .map(|(v, law)| {
                Ok(CState {
                    drive: src_of(v)?,
                    law: *law,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let mut factors = Vec::new();
        let mut terms = Vec::new();
        let mut mono = Vec::new();
        let mut equations = Vec::new();
        for d in &self.dofs {
            let eq = self.equation(d)?;
            let t0 = terms.len();
            for mt in &eq.terms {
                let f0 = factors.len();
                for f in mt.term.factors() {
                    if let Factor::State(v, law) = f {
                        // The state's value is a coordinate of the system: a plain first power.
                        let j = internal
                            .iter()
                            .position(|(w, l)| w == v && l == law)
                            .ok_or_else(|| unknown(&f.to_string()))?;
                        factors.push(CFactor {
                            src: Src::Z(j),
                            kind: Kind::Pow(1),
                        });
                        continue;
                    }
                    let src = src_of(f.var())?;
                    let kind = match f {
                        Factor::Pow(_, k) => Kind::Pow(*k),
                        Factor::Abs(_) => Kind::Abs,
                        Factor::Sign(_) => Kind::Sign,
                        Factor::Tanh(_, eps) => Kind::Tanh(1.0 / eps),
                        Factor::Below(_, c) => Kind::Below(*c),
                        Factor::Above(_, c) => Kind::Above(*c),
                        Factor::State(..) => unreachable!("state factors are handled above"),
                    };
                    factors.push(CFactor { src, kind });
                }
                terms.push((mt.coef, f0, factors.len()));
                mono.push(match &factors[f0..] {
                    [
                        CFactor {
                            src,
                            kind: Kind::Pow(k),
                        },
                    ] => match *src {
                        Src::X(i) => Mono::X(i, *k),
                        Src::V(i) => Mono::V(i, *k),
                        Src::U(i) => Mono::U(i, *k),
                        _ => Mono::Other,
                    },
                    _ => Mono::Other,
                });
            }
            equations.push((t0, terms.len()));
        }
        Ok(CompiledModel {
            dof_names: self.dofs.clone(),
            input_names: self.inputs.clone(),
            factors,
            terms,
            mono,
            equations,
            states,
        })
    }
}

fn unknown(n: &str) -> LibraryError {
    LibraryError::Invalid {
        field: "dofs".into(),
        message: format!("term uses DOF '{n}' that the model does not declare"),
    }
}

/// The source values of lanes `l0 .. l0 + s.len()` of a component-major block of `m` states.
#[inline(always)]
/// The values of `src` for lanes `l0..l0 + s.len()` of a component-major block of `m` states
/// (`n` motion DOFs; an internal state `j` is the velocity of coordinate `n + j`).
fn lane_values(
    src: Src,
    x: &[f64],
    v: &[f64],
    u: &[f64],
    (m, n): (usize, usize),
    l0: usize,
    s: &mut [f64],
) {
    let w = s.len();
    let col = |i: usize| i * m + l0..i * m + l0 + w;
    match src {
        Src::Z(j) => s.copy_from_slice(&v[col(n + j)]),
        Src::X(i) => s.copy_from_slice(&x[col(i)]),
        Src::V(i) => s.copy_from_slice(&v[col(i)]),
        Src::U(k) => s.fill(u[k]),
        Src::RelX(i, Base::X(j)) => {
            for ((o, a), b) in s.iter_mut().zip(&x[col(i)]).zip(&x[col(j)]) {
                *o = a - b;
            }
        }
        Src::RelX(i, Base::U(k)) => {
            for (o, a) in s.iter_mut().zip(&x[col(i)]) {
                *o = a - u[k];
            }
        }
        Src::RelV(i, Base::X(j)) => {
            for ((o, a), b) in s.iter_mut().zip(&v[col(i)]).zip(&v[col(j)]) {
                *o = a - b;
            }
        }
        Src::RelV(i, Base::U(k)) => {
            for (o, a) in s.iter_mut().zip(&v[col(i)]) {
                *o = a - u[k];
            }
        }
    }
}

/// `p[l] *= factor(s[l])` for every lane, with [`CompiledModel::accel`]'s arithmetic (powers
/// above 3 by the same repeated squaring as `f64::powi`, checked bit for bit in the tests).
#[inline(always)]
fn apply_lanes<const W: usize>(kind: Kind, s: &[f64; W], p: &mut [f64; W]) {
    match kind {
        Kind::Pow(0) => p.iter_mut().for_each(|p| *p *= 1.0),
        Kind::Pow(1) => p.iter_mut().zip(s).for_each(|(p, s)| *p *= s),
        Kind::Pow(2) => p.iter_mut().zip(s).for_each(|(p, s)| *p *= s * s),
        Kind::Pow(3) => p.iter_mut().zip(s).for_each(|(p, s)| *p *= s * s * s),
        Kind::Pow(k) => {
            let (mut a, mut r, mut e) = (*s, [1.0f64; W], k);
            loop {
                if e & 1 == 1 {
                    r.iter_mut().zip(&a).for_each(|(r, a)| *r *= a);
                }
                e >>= 1;
                if e == 0 {
                    break;
                }
                a.iter_mut().for_each(|a| *a *= *a);
            }
            p.iter_mut().zip(&r).for_each(|(p, r)| *p *= r);
        }
        Kind::Abs => p.iter_mut().zip(s).for_each(|(p, s)| *p *= s.abs()),
        Kind::Sign => p.iter_mut().zip(s).for_each(|(p, s)| *p *= sign0(*s)),
        Kind::Tanh(inv) => p
            .iter_mut()
            .zip(s)
            .for_each(|(p, s)| *p *= (s * inv).tanh()),
        Kind::Below(c) => p
            .iter_mut()
            .zip(s)
            .for_each(|(p, s)| *p *= (c - s).max(0.0)),
        Kind::Above(c) => p
            .iter_mut()
            .zip(s)
            .for_each(|(p, s)| *p *= (s - c).max(0.0)),
    }
}

impl CompiledModel {
    /// Number of DOFs.
    pub fn dofs(&self) -> usize {
        self.dof_names.len()
    }

    /// Number of internal states `m` ([`Model::internal_states`]).
    pub fn states(&self) -> usize {
        self.states.len()
    }

    /// Coordinates of the second-order system: the DOFs, then one auxiliary coordinate per
    /// internal state (`n + m`; see the type's docs). The length of `x`, `v` and `out` in
    /// [`CompiledModel::accel`].
    pub fn system_dofs(&self) -> usize {
        self.dof_names.len() + self.states.len()
    }

    /// The refinable parameters of every internal state ([`StateLaw::params`]), state by state.
    pub fn state_params(&self) -> Vec<f64> {
        self.states.iter().flat_map(|s| s.law.params()).collect()
    }

    /// The laws of the internal states, in [`Model::internal_states`] order.
    pub fn state_laws(&self) -> Vec<StateLaw> {
        self.states.iter().map(|s| s.law).collect()
    }

    /// Number of refinable state parameters (the length of [`CompiledModel::state_params`]).
    pub fn n_state_params(&self) -> usize {
        self.states.iter().map(|s| s.law.param_names().len()).sum()
    }

    /// The internal state each entry of [`CompiledModel::state_params`] belongs to.
    pub fn state_of_param(&self) -> Vec<usize> {
        self.states
            .iter()
            .enumerate()
            .flat_map(|(j, s)| std::iter::repeat_n(j, s.law.param_names().len()))
            .collect()
    }

    /// A copy with the internal states' parameters replaced by `p` ([`CompiledModel::state_params`]
    /// order); errors on a wrong length or invalid values.
    pub fn with_state_params(&self, p: &[f64]) -> Result<Self> {
        if p.len() != self.n_state_params() {
            return Err(LibraryError::Invalid {
                field: "state parameters".into(),
                message: format!(
                    "{} values given for {} internal-state parameters",
                    p.len(),
                    self.n_state_params()
                ),
            });
        }
        let mut out = self.clone();
        let mut k = 0;
        for s in &mut out.states {
            let r = s.law.param_names().len();
            s.law = s.law.with_params(&p[k..k + r])?;
            k += r;
        }
        Ok(out)
    }

    /// `∂z_j'/∂p_r` for every refinable state parameter `r` ([`CompiledModel::state_params`]
    /// order; parameter `r` acts on state [`CompiledModel::state_of_param`]`[r]` only), at the
    /// system state `x`, `v` (length [`CompiledModel::system_dofs`]) and inputs `u`.
    pub fn state_param_gradient(&self, x: &[f64], v: &[f64], u: &[f64], out: &mut [f64]) {
        let n = self.dofs();
        let mut k = 0;
        for (j, s) in self.states.iter().enumerate() {
            let r = s.law.param_names().len();
            let q = Self::value(s.drive, x, v, u, n);
            s.law.rate_gradient(q, v[n + j], &mut out[k..k + r]);
            k += r;
        }
    }

    /// Number of inputs.
    pub fn inputs(&self) -> usize {
        self.input_names.len()
    }

    /// DOF names in state order.
    pub fn dof_names(&self) -> &[String] {
        &self.dof_names
    }

    /// Input names in `u` order.
    pub fn input_names(&self) -> &[String] {
        &self.input_names
    }

    /// Index of an input in `u`, if the model uses it.
    pub fn input_index(&self, name: &str) -> Option<usize> {
        self.input_names.iter().position(|n| n == name)
    }

    #[inline(always)]
    fn value(src: Src, x: &[f64], v: &[f64], u: &[f64], n: usize) -> f64 {
        match src {
            Src::Z(j) => v[n + j],
            Src::X(i) => x[i],
            Src::V(i) => v[i],
            Src::U(k) => u[k],
            Src::RelX(i, Base::X(j)) => x[i] - x[j],
            Src::RelX(i, Base::U(k)) => x[i] - u[k],
            Src::RelV(i, Base::X(j)) => v[i] - v[j],
            Src::RelV(i, Base::U(k)) => v[i] - u[k],
        }
    }

    /// Accelerations `out[i] = x_i''` for displacements `x`, velocities `v` (DOF order) and inputs
    /// `u` (input order); with internal states, `x`, `v` and `out` cover
    /// [`CompiledModel::system_dofs`] coordinates and `out[n + j]` is the rate of state `j`.
    ///
    /// # Panics
    /// If `x`, `v` or `out` are shorter than [`CompiledModel::system_dofs`] or `u` shorter than
    /// [`CompiledModel::inputs`] (a programming error; see [`CompiledModel::try_accel`]).
    #[inline]
    pub fn accel(&self, x: &[f64], v: &[f64], u: &[f64], out: &mut [f64]) {
        let n = self.dof_names.len();
        for (o, &(t0, t1)) in out.iter_mut().zip(&self.equations) {
            let mut acc = 0.0;
            for (&(coef, f0, f1), mono) in self.terms[t0..t1].iter().zip(&self.mono[t0..t1]) {
                // `coef · s^k` is the loop's `coef` times its one factor: the same bits.
                match *mono {
                    Mono::X(i, k) => {
                        acc += coef * pow_u(x[i], k);
                        continue;
                    }
                    Mono::V(i, k) => {
                        acc += coef * pow_u(v[i], k);
                        continue;
                    }
                    Mono::U(i, k) => {
                        acc += coef * pow_u(u[i], k);
                        continue;
                    }
                    Mono::Other => {}
                }
                let mut p = coef;
                for f in &self.factors[f0..f1] {
                    let s = Self::value(f.src, x, v, u, n);
                    p *= match f.kind {
                        Kind::Pow(k) => pow_u(s, k),
                        Kind::Abs => s.abs(),
                        Kind::Sign => sign0(s),
                        Kind::Tanh(inv) => (s * inv).tanh(),
                        Kind::Below(c) => (c - s).max(0.0),
                        Kind::Above(c) => (s - c).max(0.0),
                    };
                }
                acc += p;
            }
            *o = acc;
        }
        for (j, st) in self.states.iter().enumerate() {
            let q = Self::value(st.drive, x, v, u, n);
            out[n + j] = st.law.rate(q, v[n + j]);
        }
    }

    /// Accelerations of many states at once, component-major: with `m = x.len() / system_dofs()`
    /// states, `x[i * m + l]` is coordinate `i` of state `l` (likewise `v` and `out`; with
    /// internal states, rows `n + j` are their values and rates); the inputs `u` are shared by
    /// every state. Each state gets exactly what [`CompiledModel::accel`] gives it (the
    /// same operations in the same order), but the loops run across states, eight at a time, so
    /// they vectorise: basin maps integrate many starts side by side through this.
    ///
    /// # Panics
    /// If `v` or `out` are shorter than `x`, or `u` shorter than [`CompiledModel::inputs`].
    #[inline(always)]
    pub fn accel_lanes(&self, x: &[f64], v: &[f64], u: &[f64], out: &mut [f64]) {
        const W: usize = 8;
        let n = self.dofs();
        if n == 0 {
            return;
        }
        let m = x.len() / self.system_dofs();
        let mut l0 = 0;
        while l0 < m {
            let w = W.min(m - l0);
            for (i, &(t0, t1)) in self.equations.iter().enumerate() {
                let mut acc = [0.0f64; W];
                for &(coef, f0, f1) in &self.terms[t0..t1] {
                    let mut p = [coef; W];
                    for f in &self.factors[f0..f1] {
                        let mut s = [0.0f64; W];
                        lane_values(f.src, x, v, u, (m, n), l0, &mut s[..w]);
                        apply_lanes(f.kind, &s, &mut p);
                    }
                    for (a, p) in acc.iter_mut().zip(&p) {
                        *a += p;
                    }
                }
                out[i * m + l0..i * m + l0 + w].copy_from_slice(&acc[..w]);
            }
            // Internal states: each lane's rate, as `accel` computes it.
            for (j, st) in self.states.iter().enumerate() {
                let mut q = [0.0f64; W];
                lane_values(st.drive, x, v, u, (m, n), l0, &mut q[..w]);
                let k = (n + j) * m + l0;
                for (l, &ql) in q[..w].iter().enumerate() {
                    out[k + l] = st.law.rate(ql, v[k + l]);
                }
            }
            l0 += w;
        }
    }

    /// Number of terms over all equations (the length of [`CompiledModel::coefficients`]).
    pub fn n_terms(&self) -> usize {
        self.terms.len()
    }

    /// The coefficients of every term, equation by equation in DOF order.
    pub fn coefficients(&self) -> Vec<f64> {
        self.terms.iter().map(|t| t.0).collect()
    }

    /// The DOF index of the equation term `j` belongs to.
    ///
    /// # Panics
    /// If `j >= n_terms()`.
    pub fn equation_of(&self, j: usize) -> usize {
        self.equations
            .iter()
            .position(|&(t0, t1)| (t0..t1).contains(&j))
            .expect("term index below n_terms()")
    }

    /// Evaluates the model with the coefficients `coefs` (in place of the compiled ones, same order
    /// as [`CompiledModel::coefficients`]) and returns everything a sensitivity or Jacobian-based
    /// method needs, without allocating for terms of up to 8 factors:
    /// `a[i] = Σ_j coefs[j]·θ_j` for the terms of equation `i`, the regressors `theta[j] = θ_j`,
    /// and the state Jacobians `ax[i·N + k] = ∂a_i/∂x_k`, `av[i·N + k] = ∂a_i/∂v_k` (analytic,
    /// by the product rule over each term's factors; `|s|` has derivative `sign(s)`, `sign(s)`
    /// derivative 0, `below(s, c)` −1 below `c` and `above(s, c)` 1 above it, 0 elsewhere).
    /// `N` is [`CompiledModel::system_dofs`]: with internal states, rows `n + j` are the states'
    /// rates and their Jacobians (a state's value is `v[n + j]`, see the type's docs).
    ///
    /// # Panics
    /// On slices shorter than the model needs (`N` coordinates, `n_terms` coefficients, `N²`
    /// Jacobian entries): a programming error.
    #[allow(clippy::too_many_arguments)]
    pub fn eval_jacobian(
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
        let n0 = self.dofs();
        let n = self.system_dofs();
        a[..n].fill(0.0);
        ax[..n * n].fill(0.0);
        av[..n * n].fill(0.0);
        let mut vals = [0.0f64; 8];
        let mut ders = [0.0f64; 8];
        let mut big_vals = Vec::new();
        let mut big_ders = Vec::new();
        for (i, &(t0, t1)) in self.equations.iter().enumerate() {
            for j in t0..t1 {
                let (_, f0, f1) = self.terms[j];
                let fs = &self.factors[f0..f1];
                let nf = fs.len();
                let (fv, fd): (&mut [f64], &mut [f64]) = if nf <= 8 {
                    (&mut vals[..nf], &mut ders[..nf])
                } else {
                    big_vals.resize(nf, 0.0);
                    big_ders.resize(nf, 0.0);
                    (&mut big_vals[..], &mut big_ders[..])
                };
                let mut prod = 1.0;
                for (m, f) in fs.iter().enumerate() {
                    let (val, der) = factor_and_derivative(f.kind, Self::value(f.src, x, v, u, n0));
                    fv[m] = val;
                    fd[m] = der;
                    prod *= val;
                }
                theta[j] = prod;
                let c = coefs[j];
                a[i] += c * prod;
                for (m, f) in fs.iter().enumerate() {
                    if fd[m] == 0.0 {
                        continue;
                    }
                    let others: f64 = fv
                        .iter()
                        .enumerate()
                        .filter(|&(l, _)| l != m)
                        .map(|(_, w)| w)
                        .product();
                    let g = c * fd[m] * others;
                    add_derivative(f.src, g, (i, n, n0), ax, av);
                }
            }
        }
        self.state_rows((x, v, u), a, av);
    }

    /// The accelerations with the compiled coefficients, as [`CompiledModel::accel`] gives
    /// them (the same value to rounding: a power `s^k` is taken as `s^(k−1)·s`, beside its
    /// derivative `k·s^(k−1)`),
    /// and their Jacobians over the `N = system_dofs()` coordinates, row-major:
    /// `ax[i·N + k] = ∂a_i/∂x_k`, `av[i·N + k] = ∂a_i/∂v_k`, with the derivatives of
    /// [`CompiledModel::eval_jacobian`] (internal states' rows included). For integrating a
    /// run's sensitivities beside it, at every stage of every step: a term that is one power of
    /// a coordinate takes its value and derivative without the general factor loop, and nothing
    /// is kept of the regressors.
    ///
    /// # Panics
    /// On slices shorter than the model needs (`N` coordinates and accelerations, `N²`
    /// Jacobian entries): a programming error.
    #[inline]
    pub fn accel_jacobian(
        &self,
        x: &[f64],
        v: &[f64],
        u: &[f64],
        out: &mut [f64],
        ax: &mut [f64],
        av: &mut [f64],
    ) {
        let n0 = self.dofs();
        let n = self.system_dofs();
        ax[..n * n].fill(0.0);
        av[..n * n].fill(0.0);
        let power = |s: f64, k: u32| match k {
            0 => (1.0, 0.0),
            1 => (s, 1.0),
            _ => {
                let below = pow_u(s, k - 1);
                (below * s, k as f64 * below)
            }
        };
        for (i, &(t0, t1)) in self.equations.iter().enumerate() {
            let mut acc = 0.0;
            for (&(coef, f0, f1), mono) in self.terms[t0..t1].iter().zip(&self.mono[t0..t1]) {
                match *mono {
                    Mono::X(k, p) => {
                        let (val, der) = power(x[k], p);
                        acc += coef * val;
                        ax[i * n + k] += coef * der;
                        continue;
                    }
                    Mono::V(k, p) => {
                        let (val, der) = power(v[k], p);
                        acc += coef * val;
                        av[i * n + k] += coef * der;
                        continue;
                    }
                    Mono::U(k, p) => {
                        acc += coef * pow_u(u[k], p);
                        continue;
                    }
                    Mono::Other => {}
                }
                // Each factor's value and derivative; a factor's partial is the coefficient
                // times its derivative times the product of the others (before and after it).
                let fs = &self.factors[f0..f1];
                let mut vals = [0.0f64; 8];
                let mut ders = [0.0f64; 8];
                let mut big = Vec::new();
                let (fv, fd): (&mut [f64], &mut [f64]) = if fs.len() <= 8 {
                    (&mut vals[..fs.len()], &mut ders[..fs.len()])
                } else {
                    big.resize(2 * fs.len(), 0.0);
                    big.split_at_mut(fs.len())
                };
                let mut p = coef;
                for (m, f) in fs.iter().enumerate() {
                    let (val, der) = factor_and_derivative(f.kind, Self::value(f.src, x, v, u, n0));
                    fv[m] = val;
                    fd[m] = der;
                    p *= val;
                }
                acc += p;
                for (m, f) in fs.iter().enumerate() {
                    if fd[m] == 0.0 {
                        continue;
                    }
                    let mut g = coef * fd[m];
                    for (l, w) in fv.iter().enumerate() {
                        if l != m {
                            g *= w;
                        }
                    }
                    add_derivative(f.src, g, (i, n, n0), ax, av);
                }
            }
            out[i] = acc;
        }
        self.state_rows((x, v, u), out, av);
    }

    /// The internal states' rows of [`CompiledModel::eval_jacobian`] and
    /// [`CompiledModel::accel_jacobian`]: each state's rate into `out` and its derivatives
    /// over its own value and its drive's velocity into `av` (row-major, `N` columns).
    fn state_rows(&self, (x, v, u): (&[f64], &[f64], &[f64]), out: &mut [f64], av: &mut [f64]) {
        let n0 = self.dofs();
        let n = self.system_dofs();
        for (j, st) in self.states.iter().enumerate() {
            let r = n0 + j;
            let q = Self::value(st.drive, x, v, u, n0);
            let z = v[r];
            out[r] = st.law.rate(q, z);
            let (dq, dz) = st.law.rate_jacobian(q, z);
            av[r * n + r] += dz;
            match st.drive {
                Src::V(k) => av[r * n + k] += dq,
                Src::RelV(k, b) => {
                    av[r * n + k] += dq;
                    if let Base::X(l) = b {
                        av[r * n + l] -= dq;
                    }
                }
                // A drive is a velocity coordinate (checked when the term was parsed).
                _ => {}
            }
        }
    }

    /// Checked form of [`CompiledModel::accel`]: errors on wrong slice lengths.
    pub fn try_accel(&self, x: &[f64], v: &[f64], u: &[f64], out: &mut [f64]) -> Result<()> {
        let n = self.system_dofs();
        for (name, len, want) in [
            ("x", x.len(), n),
            ("v", v.len(), n),
            ("out", out.len(), n),
            ("u", u.len(), self.inputs()),
        ] {
            if len != want {
                return Err(LibraryError::Invalid {
                    field: name.into(),
                    message: format!("has length {len}, expected {want}"),
                });
            }
        }
        self.accel(x, v, u, out);
        Ok(())
    }
}

/// Adds `g`, the derivative of acceleration `i` through a factor read from `src`, to the
/// Jacobians `ax` (over positions) and `av` (over velocities and internal states), row-major
/// with `n` columns, `n0` the model's own DOFs; a relative coordinate's base gets `−g`.
#[inline(always)]
fn add_derivative(
    src: Src,
    g: f64,
    (i, n, n0): (usize, usize, usize),
    ax: &mut [f64],
    av: &mut [f64],
) {
    match src {
        Src::X(k) => ax[i * n + k] += g,
        Src::V(k) => av[i * n + k] += g,
        Src::Z(k) => av[i * n + n0 + k] += g,
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

/// A factor's value at `s` and its derivative there, as [`CompiledModel::eval_jacobian`] takes
/// them (`|s|` has derivative `sign(s)`, `sign(s)` derivative 0, a stop's derivative is 0 off
/// contact).
#[inline(always)]
fn factor_and_derivative(kind: Kind, s: f64) -> (f64, f64) {
    match kind {
        Kind::Pow(0) => (1.0, 0.0),
        Kind::Pow(1) => (s, 1.0),
        Kind::Pow(k) => (pow_u(s, k), k as f64 * pow_u(s, k - 1)),
        Kind::Abs => (s.abs(), sign0(s)),
        Kind::Sign => (sign0(s), 0.0),
        Kind::Tanh(inv) => {
            let th = (s * inv).tanh();
            (th, inv * (1.0 - th * th))
        }
        Kind::Below(c) => {
            if s < c {
                (c - s, -1.0)
            } else {
                (0.0, 0.0)
            }
        }
        Kind::Above(c) => {
            if s > c {
                (s - c, 1.0)
            } else {
                (0.0, 0.0)
            }
        }
    }
}
