//! Library terms: variables, factors and their products, with canonical printing.

use std::cmp::Ordering;
use std::fmt;

use crate::Result;
use crate::state::StateLaw;

/// The second operand of a relative coordinate `(a-b)`: another DOF or a base input such as `xb`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Coord {
    /// A degree of freedom (its velocity column is `"<name>'"`).
    Dof(String),
    /// An input column such as the base displacement `xb` (its velocity column is `"<name>_vel"`).
    Input(String),
}

impl Coord {
    /// The coordinate's name.
    pub fn name(&self) -> &str {
        match self {
            Coord::Dof(n) | Coord::Input(n) => n,
        }
    }

    /// Name of the column holding this coordinate's velocity (`x1'` for a DOF, `xb_vel` for an input).
    pub fn velocity_column(&self) -> String {
        match self {
            Coord::Dof(n) => format!("{n}'"),
            Coord::Input(n) => format!("{n}_vel"),
        }
    }
}

/// A scalar signal a factor is built from.
///
/// The variant order is the canonical print order inside a product (displacements first).
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Var {
    /// Displacement of a DOF, printed `x`.
    Disp(String),
    /// Relative displacement `(a-b)` of DOF `a` with respect to a DOF or input `b`.
    RelDisp(String, Coord),
    /// Velocity of a DOF, printed `x'` (column `"x'"`).
    Vel(String),
    /// Relative velocity `(a-b)'`.
    RelVel(String, Coord),
    /// An input column by name (`xb_acc`, `u`, `force`, …).
    Input(String),
}

impl Var {
    /// True for `x'` and `(a-b)'`.
    pub fn is_velocity(&self) -> bool {
        matches!(self, Var::Vel(_) | Var::RelVel(..))
    }

    /// True for `x` and `(a-b)`.
    pub fn is_displacement(&self) -> bool {
        matches!(self, Var::Disp(_) | Var::RelDisp(..))
    }

    /// The displacement whose time derivative this velocity is (`x'` → `x`), if a velocity.
    pub fn integral(&self) -> Option<Var> {
        match self {
            Var::Vel(d) => Some(Var::Disp(d.clone())),
            Var::RelVel(a, b) => Some(Var::RelDisp(a.clone(), b.clone())),
            _ => None,
        }
    }

    /// The velocity of this displacement (`x` → `x'`), if a displacement.
    pub fn derivative(&self) -> Option<Var> {
        match self {
            Var::Disp(d) => Some(Var::Vel(d.clone())),
            Var::RelDisp(a, b) => Some(Var::RelVel(a.clone(), b.clone())),
            _ => None,
        }
    }

    /// Column names needed to evaluate this variable, in order.
    pub fn required_columns(&self) -> Vec<String> {
        match self {
            Var::Disp(d) => vec![d.clone()],
            Var::Vel(d) => vec![format!("{d}'")],
            Var::RelDisp(a, b) => vec![a.clone(), b.name().to_string()],
            Var::RelVel(a, b) => vec![format!("{a}'"), b.velocity_column()],
            Var::Input(n) => vec![n.clone()],
        }
    }
}

/// A column name as the term grammar writes it: as it is when it is an identifier (`xb_acc`),
/// else in double quotes with a quote inside doubled (`"acc [m/s2]"`), which parses back to the
/// same name.
pub fn quote_name(name: &str) -> std::borrow::Cow<'_, str> {
    let mut chars = name.chars();
    let plain = chars.next().is_some_and(|c| c.is_alphabetic() || c == '_')
        && chars.all(|c| c.is_alphanumeric() || c == '_');
    if plain {
        std::borrow::Cow::Borrowed(name)
    } else {
        std::borrow::Cow::Owned(format!("\"{}\"", name.replace('"', "\"\"")))
    }
}

impl fmt::Display for Var {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let q = quote_name;
        match self {
            Var::Disp(d) => write!(f, "{}", q(d)),
            Var::Vel(d) => write!(f, "{}'", q(d)),
            Var::RelDisp(a, b) => write!(f, "({}-{})", q(a), q(b.name())),
            Var::RelVel(a, b) => write!(f, "({}-{})'", q(a), q(b.name())),
            Var::Input(n) => write!(f, "{}", q(n)),
        }
    }
}

/// One factor of a product term.
#[derive(Debug, Clone, PartialEq)]
pub enum Factor {
    /// `v^k` with `k ≥ 1` (printed `v` for `k = 1`).
    Pow(Var, u32),
    /// `abs(v)`.
    Abs(Var),
    /// `sign(v)` with `sign(0) = 0`.
    Sign(Var),
    /// `tanh(v/ε)` with `ε > 0` (smoothed dry friction).
    Tanh(Var, f64),
    /// `below(v, c) = max(0, c − v)`: how far `v` is below `c` (a one-sided stop from below:
    /// `k·below(x, c)` with `k > 0` is a contact spring that pushes `x` back up to `c`).
    Below(Var, f64),
    /// `above(v, c) = max(0, v − c)`: how far `v` is above `c` (a stop from above).
    Above(Var, f64),
    /// An internal state `z` driven by the velocity coordinate `v` under a law
    /// (`maxwell(v, τ)`, `bouc_wen(v, a, b)`, `dahl(v, κ)`; see [`crate::state`]): its value is
    /// `z`, a function of the drive's history, not of its current value.
    State(Var, StateLaw),
}

impl Factor {
    /// The variable this factor is a function of.
    pub fn var(&self) -> &Var {
        match self {
            Factor::Pow(v, _)
            | Factor::Abs(v)
            | Factor::Sign(v)
            | Factor::Tanh(v, _)
            | Factor::Below(v, _)
            | Factor::Above(v, _)
            | Factor::State(v, _) => v,
        }
    }

    /// The internal-state law, for a state factor.
    pub fn state_law(&self) -> Option<&StateLaw> {
        match self {
            Factor::State(_, law) => Some(law),
            _ => None,
        }
    }

    fn kind_rank(&self) -> u8 {
        match self {
            Factor::Pow(..) => 0,
            Factor::Abs(_) => 1,
            Factor::Sign(_) => 2,
            Factor::Tanh(..) => 3,
            Factor::Below(..) => 4,
            Factor::Above(..) => 5,
            Factor::State(..) => 6,
        }
    }

    fn canonical_cmp(&self, other: &Factor) -> Ordering {
        self.var()
            .cmp(other.var())
            .then(self.kind_rank().cmp(&other.kind_rank()))
            .then_with(|| match (self, other) {
                (Factor::Pow(_, a), Factor::Pow(_, b)) => a.cmp(b),
                (Factor::Tanh(_, a), Factor::Tanh(_, b))
                | (Factor::Below(_, a), Factor::Below(_, b))
                | (Factor::Above(_, a), Factor::Above(_, b)) => a.total_cmp(b),
                (Factor::State(_, a), Factor::State(_, b)) => {
                    a.name().cmp(b.name()).then_with(|| {
                        let (pa, pb) = (law_key(a), law_key(b));
                        pa.iter()
                            .zip(&pb)
                            .map(|(x, y)| x.total_cmp(y))
                            .find(|o| *o != Ordering::Equal)
                            .unwrap_or(Ordering::Equal)
                    })
                }
                _ => Ordering::Equal,
            })
    }

    /// Evaluates the factor at a value `v` of its variable. A state factor has no value at one
    /// point (it depends on the drive's history): `apply` gives 0, its value on a structure that
    /// has been at rest; evaluate it on a record with [`crate::evaluate_term`].
    #[inline]
    pub fn apply(&self, v: f64) -> f64 {
        match self {
            Factor::Pow(_, k) => pow_u(v, *k),
            Factor::Abs(_) => v.abs(),
            Factor::Sign(_) => sign0(v),
            Factor::Tanh(_, eps) => (v / eps).tanh(),
            Factor::Below(_, c) => (c - v).max(0.0),
            Factor::Above(_, c) => (v - c).max(0.0),
            Factor::State(..) => 0.0,
        }
    }

    /// The factor's derivative with respect to its variable at `v` (`abs`: `sign(v)`; `sign`:
    /// 0; `below`/`above`: the side's slope, 0 on the free side and at the contact point; a
    /// state factor: 0, see [`Factor::apply`]).
    #[inline]
    pub fn derivative(&self, v: f64) -> f64 {
        match self {
            Factor::Pow(_, 0) => 0.0,
            Factor::Pow(_, k) => f64::from(*k) * pow_u(v, k - 1),
            Factor::Abs(_) => sign0(v),
            Factor::Sign(_) => 0.0,
            Factor::Tanh(_, eps) => {
                let t = (v / eps).tanh();
                (1.0 - t * t) / eps
            }
            Factor::Below(_, c) => {
                if v < *c {
                    -1.0
                } else {
                    0.0
                }
            }
            Factor::Above(_, c) => {
                if v > *c {
                    1.0
                } else {
                    0.0
                }
            }
            Factor::State(..) => 0.0,
        }
    }
}

/// Every parameter of a law (the fixed exponent ν of Bouc–Wen included), for ordering.
fn law_key(law: &StateLaw) -> Vec<f64> {
    match *law {
        StateLaw::BoucWen { a, b, nu } => vec![a, b, nu],
        other => other.params(),
    }
}

/// `v^k` by repeated multiplication for small `k`.
#[inline]
pub(crate) fn pow_u(v: f64, k: u32) -> f64 {
    match k {
        0 => 1.0,
        1 => v,
        2 => v * v,
        3 => v * v * v,
        _ => {
            // Binary exponentiation, the multiplications of `f64::powi` in its order (the same
            // bits), inline: `powi` with a run-time exponent is a library call per power, the
            // largest single cost of simulating a polynomial model.
            let (mut a, mut r, mut e) = (v, 1.0, k);
            loop {
                if e & 1 == 1 {
                    r *= a;
                }
                e >>= 1;
                if e == 0 {
                    return r;
                }
                a *= a;
            }
        }
    }
}

/// The sign function with `sign(0) = 0` (unlike `f64::signum`).
#[inline]
pub(crate) fn sign0(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Formats an `f64` so that parsing the text gives back the same value (shortest round-trip form).
pub(crate) fn fmt_num(x: f64) -> String {
    format!("{x}")
}

impl fmt::Display for Factor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Factor::Pow(v, 1) => write!(f, "{v}"),
            Factor::Pow(v, k) => write!(f, "{v}^{k}"),
            Factor::Abs(v) => write!(f, "abs({v})"),
            Factor::Sign(v) => write!(f, "sign({v})"),
            Factor::Tanh(v, eps) => write!(f, "tanh({v}/{})", fmt_num(*eps)),
            Factor::Below(v, c) => write!(f, "below({v}, {})", fmt_num(*c)),
            Factor::Above(v, c) => write!(f, "above({v}, {})", fmt_num(*c)),
            Factor::State(v, law) => {
                write!(f, "{}({v}", law.name())?;
                for p in law.params() {
                    write!(f, ", {}", fmt_num(p))?;
                }
                if let StateLaw::BoucWen { nu, .. } = law
                    && *nu != 1.0
                {
                    write!(f, ", {}", fmt_num(*nu))?;
                }
                write!(f, ")")
            }
        }
    }
}

/// A product of factors; the empty product is the constant `1`.
///
/// Terms built with [`Term::new`] are canonical: factors sorted (displacements, relative
/// displacements, velocities, relative velocities, inputs; within a variable `^k` before `abs`,
/// `sign`, `tanh`, `below`, `above`) and equal-variable powers merged, so `x'*x*x` becomes `x^2*x'`. Two terms
/// are equal exactly when their canonical names are equal.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Term {
    factors: Vec<Factor>,
}

/// A term that is an exact time derivative: `term = scale · d/dt (var^power)`.
///
/// `x^k*x'` gives `var = x`, `power = k + 1`, `scale = 1/(k+1)`. Used to move derivatives onto
/// windows in the weak (frequency-domain) regression.
#[derive(Debug, Clone, PartialEq)]
pub struct ExactDerivative {
    /// The displacement (`x` or `(a-b)`).
    pub var: Var,
    /// Power of `var` inside the derivative.
    pub power: u32,
    /// Multiplier `1/power`.
    pub scale: f64,
}

impl ExactDerivative {
    /// The antiderivative as a term, `var^power` (so `term = scale · d/dt antiderivative`).
    pub fn antiderivative(&self) -> Term {
        Term::new(vec![Factor::Pow(self.var.clone(), self.power)])
    }
}

impl Term {
    /// The constant term `1`.
    pub fn constant() -> Self {
        Self { factors: vec![] }
    }

    /// Builds a canonical term from factors (sorting and merging powers of the same variable).
    /// Factors `v^0` are dropped.
    pub fn new(mut factors: Vec<Factor>) -> Self {
        factors.retain(|f| !matches!(f, Factor::Pow(_, 0)));
        factors.sort_by(|a, b| a.canonical_cmp(b));
        let mut out: Vec<Factor> = Vec::with_capacity(factors.len());
        for f in factors {
            if let (Some(Factor::Pow(pv, pk)), Factor::Pow(v, k)) = (out.last_mut(), &f)
                && pv == v
            {
                *pk += *k;
                continue;
            }
            out.push(f);
        }
        Self { factors: out }
    }

    /// A single variable to the first power.
    pub fn var(v: Var) -> Self {
        Self::new(vec![Factor::Pow(v, 1)])
    }

    /// Parses one term (no ranges, no `poly`); identifiers in `dofs` are DOFs, others inputs.
    ///
    /// ```
    /// use tfs_library::Term;
    /// let t = Term::parse("x' * x^2", &["x"]).unwrap();
    /// assert_eq!(t.to_string(), "x^2*x'");
    /// ```
    pub fn parse<S: AsRef<str>>(text: &str, dofs: &[S]) -> Result<Self> {
        let dofs: Vec<&str> = dofs.iter().map(|s| s.as_ref()).collect();
        crate::parse::parse_term(text, &dofs)
    }

    /// The factors, in canonical order.
    pub fn factors(&self) -> &[Factor] {
        &self.factors
    }

    /// True for the constant `1`.
    pub fn is_constant(&self) -> bool {
        self.factors.is_empty()
    }

    /// Product of the two terms (canonicalised).
    pub fn mul(&self, other: &Term) -> Term {
        let mut f = self.factors.clone();
        f.extend(other.factors.iter().cloned());
        Term::new(f)
    }

    /// Total polynomial degree if the term is a monomial (only `^k` factors), else `None`.
    pub fn degree(&self) -> Option<u32> {
        self.factors
            .iter()
            .map(|f| match f {
                Factor::Pow(_, k) => Some(*k),
                _ => None,
            })
            .sum()
    }

    /// True if some factor involves the displacement of `dof`: its own coordinate `x` or a
    /// relative coordinate `(x-…)` it leads (velocities and inputs do not count). A model whose
    /// equation of `dof` holds no such term has no restoring force along it.
    pub fn involves_displacement_of(&self, dof: &str) -> bool {
        self.vars().iter().any(|v| match v {
            Var::Disp(n) | Var::RelDisp(n, _) => n == dof,
            _ => false,
        })
    }

    /// True if the term depends on the displacement of `dof` alone (constant `1` included):
    /// a restoring (stiffness) term of a single-DOF model.
    pub fn is_position_only(&self, dof: &str) -> bool {
        self.factors
            .iter()
            .all(|f| matches!(f.var(), Var::Disp(d) if d == dof))
    }

    /// True if every factor is a function of displacements (absolute or relative) only; no
    /// velocities and no inputs. The constant `1` qualifies.
    pub fn is_displacement_only(&self) -> bool {
        self.factors.iter().all(|f| f.var().is_displacement())
    }

    /// The internal states the term uses: each state factor's drive and law, in factor order.
    pub fn states(&self) -> Vec<(&Var, &StateLaw)> {
        self.factors
            .iter()
            .filter_map(|f| match f {
                Factor::State(v, law) => Some((v, law)),
                _ => None,
            })
            .collect()
    }

    /// True if any factor involves a velocity (an internal state's drive included).
    pub fn uses_velocity(&self) -> bool {
        self.factors.iter().any(|f| f.var().is_velocity())
    }

    /// True if any factor involves an input column (directly or in a relative coordinate).
    pub fn uses_input(&self) -> bool {
        self.factors.iter().any(|f| {
            matches!(
                f.var(),
                Var::Input(_) | Var::RelDisp(_, Coord::Input(_)) | Var::RelVel(_, Coord::Input(_))
            )
        })
    }

    /// True if the term has the form `g(q)·v` with exactly one plain velocity factor `v` (power 1)
    /// and `g` a monomial in displacements (absolute or relative). `x'`, `x^2*x'`, `x1*x2'` qualify;
    /// `x'^3`, `x'*abs(x')`, `tanh(x'/0.01)` and `xb_acc*x'` do not.
    pub fn is_linear_in_velocity(&self) -> bool {
        let mut velocities = 0;
        for f in &self.factors {
            match f {
                Factor::Pow(v, 1) if v.is_velocity() => velocities += 1,
                Factor::Pow(v, _) if v.is_displacement() => {}
                _ => return false,
            }
        }
        velocities == 1
    }

    /// If the term is an exact time derivative `q^k·q'` (same coordinate `q`, `k ≥ 0`), returns
    /// `q`, `k+1` and `1/(k+1)`: `q^k·q' = d/dt (q^(k+1)) / (k+1)`.
    pub fn exact_derivative(&self) -> Option<ExactDerivative> {
        let mut vel: Option<&Var> = None;
        let mut disp: Option<(&Var, u32)> = None;
        for f in &self.factors {
            match f {
                Factor::Pow(v, 1) if v.is_velocity() && vel.is_none() => vel = Some(v),
                Factor::Pow(v, k) if v.is_displacement() && disp.is_none() => disp = Some((v, *k)),
                _ => return None,
            }
        }
        let q = vel?.integral()?;
        let k = match disp {
            None => 0,
            Some((v, k)) if *v == q => k,
            Some(_) => return None,
        };
        let power = k + 1;
        Some(ExactDerivative {
            var: q,
            power,
            scale: 1.0 / f64::from(power),
        })
    }

    /// The distinct variables the term uses, in canonical order.
    pub fn vars(&self) -> Vec<&Var> {
        let mut out: Vec<&Var> = Vec::new();
        for f in &self.factors {
            if !out.contains(&f.var()) {
                out.push(f.var());
            }
        }
        out
    }

    /// Column names needed to evaluate the term (`x`, `x'`, `xb`, `xb_vel`, `xb_acc`, …).
    pub fn required_columns(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for v in self.vars() {
            for c in v.required_columns() {
                if !out.contains(&c) {
                    out.push(c);
                }
            }
        }
        out
    }

    /// Input names (not DOFs) the term needs when the model is compiled: bare inputs, the
    /// base of a relative displacement and `<base>_vel` for a relative velocity.
    pub fn required_inputs(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for v in self.vars() {
            let name = match v {
                Var::Input(n) => n.clone(),
                Var::RelDisp(_, Coord::Input(b)) => b.clone(),
                Var::RelVel(_, b @ Coord::Input(_)) => b.velocity_column(),
                _ => continue,
            };
            if !out.contains(&name) {
                out.push(name);
            }
        }
        out
    }

    /// DOF names the term mentions (displacement or velocity), in canonical order.
    pub fn dofs(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        let mut push = |n: &str| {
            if !out.iter().any(|o| o == n) {
                out.push(n.to_string());
            }
        };
        for v in self.vars() {
            match v {
                Var::Disp(d) | Var::Vel(d) => push(d),
                Var::RelDisp(a, b) | Var::RelVel(a, b) => {
                    push(a);
                    if let Coord::Dof(b) = b {
                        push(b);
                    }
                }
                Var::Input(_) => {}
            }
        }
        out
    }
}

impl fmt::Display for Term {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.factors.is_empty() {
            return write!(f, "1");
        }
        for (i, fac) in self.factors.iter().enumerate() {
            if i > 0 {
                write!(f, "*")?;
            }
            write!(f, "{fac}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::pow_u;

    #[test]
    fn pow_u_has_the_bits_of_powi() {
        // Values over many magnitudes and both signs, including ones whose powers overflow or
        // underflow; every power up to 15.
        let mut vals = vec![0.0, -0.0, 1.0, -1.0, f64::MIN_POSITIVE, 1e300, -1e-300];
        let mut x = 0.123_456_789_f64;
        for i in 0..400 {
            x = (x * 3.987_654_321 + 0.314_159).fract();
            let scale = 10f64.powi((i % 41) - 20);
            vals.push(if i % 2 == 0 { x * scale } else { -x * scale });
        }
        for &v in &vals {
            for k in 0..=15u32 {
                let want = if k <= 3 {
                    pow_u(v, k)
                } else {
                    v.powi(k as i32)
                };
                assert_eq!(pow_u(v, k).to_bits(), want.to_bits(), "{v:e}^{k}");
            }
        }
    }

    /// Own and relative coordinates of the DOF involve its displacement; velocities, inputs
    /// and another DOF's coordinate do not.
    #[test]
    fn involves_displacement_of_reads_the_dofs_coordinates() {
        let dofs = ["x1".to_string(), "x2".to_string()];
        let t = |s: &str| super::Term::parse(s, &dofs).unwrap();
        assert!(t("x1^3").involves_displacement_of("x1"));
        assert!(t("(x1-x2)^2").involves_displacement_of("x1"));
        assert!(t("x1*x1'").involves_displacement_of("x1"));
        assert!(!t("x1'").involves_displacement_of("x1"));
        assert!(!t("x2^3").involves_displacement_of("x1"));
        assert!(!t("xb_acc").involves_displacement_of("x1"));
    }
}
