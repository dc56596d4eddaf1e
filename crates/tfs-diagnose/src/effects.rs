//! The open catalogue of physical effects: the [`Effect`] trait, the built-in effects, the
//! [`Catalogue`] registry, and [`ComputedColumn`]s for input effects that the term grammar
//! cannot express.
//!
//! An effect offers, for one DOF's equation, a list of [`Variant`]s: one per value of its scanned
//! nonlinear parameter (or a single variant). A variant adds columns to the equation and may
//! replace existing terms (an input delay replaces the input by its delayed copy).
//!
//! Memory effects (a hidden Maxwell element, Bouc–Wen hysteresis, Dahl friction) are internal
//! states of the term grammar (`maxwell(x', τ)`, `bouc_wen(x', a, b)`, `dahl(x', κ)`): the law
//! and its parameters are part of the term, so a refitted model carries them, and every command
//! simulates them with the motion, started at rest ([`memory`]).
//!
//! Computed columns are model inputs with a documented name, so a refitted model stays a plain
//! `tfs-model/1` file:
//! * `<input>_delay_<δ>`: the input column delayed by δ seconds;
//! * `<input>_lowpass_<τ>`: the input column low-pass filtered with time constant τ seconds.
//!
//! Coordinates: every effect is offered on the DOF's own coordinate and on each relative
//! coordinate `(a-b)`, `(a-b)'` its equation already uses (chain couplings, motion relative to a
//! moving base); the scan keeps the best. Raw units: when the equation has the constant term `1`
//! (the displacement's origin is an arbitrary sensor offset absorbed by the constant),
//! displacement powers are offered about the mean position, `(x − x̄)^k`, and expanded into plain
//! powers in the model ([`EffectColumn::centred`]), so a DC offset does not change the effect.
//!
//! Numbers are written with `p` for the decimal point (`0.35` → `0p35`). Simulating a model with
//! such columns needs `simulate.rs` (delays and filters are computed from the record).

mod computed;
mod input;
pub mod memory;

pub(crate) use computed::round3;
pub use computed::{ComputedColumn, computed_columns, delayed, lowpass, upgrade_legacy};
pub use input::{CONTRACT_INPUTS, InputDelay, InputFilter, lost_inputs};
pub(crate) use input::{input_variant, linear_inputs};
pub use memory::{DahlFriction, Hysteresis, Maxwell};

use tfs_library::{Factor, Model, Term, Var};

use crate::{DiagnoseError, Result};

/// One column an effect adds: a term of the grammar, and how to compute it when it names a
/// computed input column.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectColumn {
    /// The term as it will appear in the model (for a centred column: its leading power).
    pub term: Term,
    /// Set when the term is a computed input column.
    pub computed: Option<ComputedColumn>,
    /// Set for a column centred on an operating point: `(dof, m)` — the term's factor
    /// `dof^k` is evaluated as `(dof − m)^k`. One coefficient multiplies the whole column; in the
    /// model it is expanded into plain powers (see [`EffectColumn::expansion`]), so the model
    /// stays a `tfs-model/1` polynomial. Used in raw units, where the displacement's origin is
    /// an arbitrary sensor offset: `(x − m)^3` is the cubic stiffness about the mean position,
    /// whereas `x^3` of the raw signal is a different, shift-dependent family.
    pub centre: Option<(String, f64)>,
}

impl EffectColumn {
    /// A plain grammar term.
    pub fn term(term: Term) -> Self {
        Self {
            term,
            computed: None,
            centre: None,
        }
    }

    /// A computed column used linearly.
    pub fn computed(c: ComputedColumn) -> Self {
        Self {
            term: Term::var(Var::Input(c.name())),
            computed: Some(c),
            centre: None,
        }
    }

    /// `term` with its factor `dof^k` centred on `m` (a plain term when `term` has no such
    /// factor or `m` is 0).
    pub fn centred(term: Term, dof: &str, m: f64) -> Self {
        let has = term
            .factors()
            .iter()
            .any(|f| matches!(f, Factor::Pow(Var::Disp(d), _) if d == dof));
        Self {
            term,
            computed: None,
            centre: (has && m != 0.0 && m.is_finite()).then(|| (dof.to_string(), m)),
        }
    }

    /// The plain terms and weights this column stands for: `[(term, 1)]`, or for a centred
    /// column `Σ_j C(k, j)(−m)^(k−j) · dof^j · rest` (binomial expansion; `j = 0` is `rest`, the
    /// constant `1` when the term is a pure power).
    pub fn expansion(&self) -> Vec<(Term, f64)> {
        let Some((dof, m)) = &self.centre else {
            return vec![(self.term.clone(), 1.0)];
        };
        let mut k = 0;
        let mut rest = Vec::new();
        for f in self.term.factors() {
            match f {
                Factor::Pow(Var::Disp(d), p) if d == dof => k = *p,
                other => rest.push(other.clone()),
            }
        }
        let mut out = Vec::with_capacity(k as usize + 1);
        let mut binom = 1.0;
        for j in (0..=k).rev() {
            // binom = C(k, j), built from j = k downwards.
            let w = binom * (-m).powi((k - j) as i32);
            let mut factors = rest.clone();
            if j > 0 {
                factors.push(Factor::Pow(Var::Disp(dof.clone()), j));
            }
            out.push((Term::new(factors), w));
            binom = binom * j as f64 / (k - j + 1) as f64;
        }
        out
    }

    /// How the column reads in reports: the term, or `(x-m)^k·rest` when centred.
    pub fn label(&self) -> String {
        match &self.centre {
            None => self.term.to_string(),
            Some((dof, m)) => {
                let k = self
                    .term
                    .factors()
                    .iter()
                    .find_map(|f| match f {
                        Factor::Pow(Var::Disp(d), p) if d == dof => Some(*p),
                        _ => None,
                    })
                    .unwrap_or(1);
                let rest: Vec<String> = self
                    .term
                    .factors()
                    .iter()
                    .filter(|f| !matches!(f, Factor::Pow(Var::Disp(d), _) if d == dof))
                    .map(|f| Term::new(vec![f.clone()]).to_string())
                    .collect();
                let base = if k == 1 {
                    format!("({dof}-{})", round3(*m))
                } else {
                    format!("({dof}-{})^{k}", round3(*m))
                };
                std::iter::once(base)
                    .chain(rest)
                    .collect::<Vec<_>>()
                    .join("*")
            }
        }
    }
}

/// One member of an effect's family: a value of its scanned parameter and the columns it brings.
#[derive(Debug, Clone, PartialEq)]
pub struct Variant {
    /// The scanned parameter `(name, value)`, if the effect has one.
    pub parameter: Option<(String, f64)>,
    /// Columns added to the equation.
    pub add: Vec<EffectColumn>,
    /// Existing terms replaced by new columns (same coefficient slot).
    pub replace: Vec<(Term, EffectColumn)>,
}

impl Variant {
    /// A variant that only adds columns.
    pub fn adding(parameter: Option<(String, f64)>, add: Vec<EffectColumn>) -> Self {
        Self {
            parameter,
            add,
            replace: Vec::new(),
        }
    }

    /// The column whose coefficient is reported as the effect's size (first added, else first
    /// replacement).
    pub fn main_term(&self) -> Option<&Term> {
        self.add
            .first()
            .or(self.replace.first().map(|(_, c)| c))
            .map(|c| &c.term)
    }
}

/// What the catalogue's effects are told about the data of one DOF's equation (see
/// [`EffectContext`]), measured over the usable rows of every record (`prepare.rs`).
#[derive(Debug, Clone)]
pub(crate) struct DataScales {
    /// RMS of the DOF's smoothed velocity.
    pub velocity: f64,
    /// Median over records of the dominant period of the DOF's displacement (s).
    pub period: f64,
    /// Mean of the DOF's smoothed displacement.
    pub mean: f64,
    /// Smallest and largest value of each displacement coordinate of the equation (its own, then
    /// the relative ones its terms use).
    pub ranges: Vec<(tfs_library::Var, f64, f64)>,
    /// RMS about its mean of each of those coordinates.
    pub rms: Vec<(tfs_library::Var, f64)>,
    /// Duration of the shortest record (s).
    pub shortest_record: f64,
    /// Median over records of the RMS-frequency period (`prepare::rms_frequency_period`) of the
    /// smoothed inputs the equation uses linearly, else of its lost inputs (s); NaN without
    /// either.
    pub input_period: f64,
    /// The inputs every record carries that the model lost ([`lost_inputs`]),
    /// when this equation uses no input linearly; empty otherwise.
    pub lost_inputs: Vec<String>,
}

/// What an effect knows about the equation it is offered to.
#[derive(Debug, Clone)]
pub struct EffectContext<'a> {
    /// The model being diagnosed.
    pub model: &'a Model,
    /// The DOF whose equation is extended.
    pub dof: &'a str,
    /// The equation's current terms.
    pub terms: Vec<Term>,
    /// RMS of the DOF's (smoothed) velocity over the data.
    pub velocity_scale: f64,
    /// Dominant period of the DOF's response (s).
    pub period: f64,
    /// Sampling interval (s).
    pub dt: f64,
    /// Highest stiffness power offered.
    pub max_power: u32,
    /// Mean of the DOF's (smoothed) displacement over the data: the operating point about which
    /// displacement-dependent effects are offered when the equation has a constant term.
    pub displacement_mean: f64,
    /// Smallest and largest value over the data of each displacement coordinate of the equation
    /// (see [`EffectContext::displacement_vars`]): where a stop can be.
    pub displacement_ranges: Vec<(Var, f64, f64)>,
    /// RMS about its mean of each displacement coordinate of the equation: the scale of a
    /// hysteresis or friction state driven by its velocity.
    pub displacement_rms: Vec<(Var, f64)>,
    /// Duration of the shortest record (s): an internal state started at rest must forget its
    /// start within it.
    pub shortest_record: f64,
    /// RMS-frequency period of the inputs the equation uses linearly (s): `1/f_rms`, where
    /// `‖u'‖ = 2π f_rms ‖u‖`. The scale of the input effects: a delay or a filter changes the
    /// input on the time scale of the input, whatever the response does (a cell drifting
    /// between wells has its spectral peak at the record's length). NaN without an input.
    pub input_period: f64,
    /// Inputs the records carry that the model lost (no equation uses them; see
    /// [`lost_inputs`]), offered back by the input effects when this equation uses no input
    /// linearly; empty otherwise.
    pub lost_inputs: Vec<String>,
}

/// The coordinates of an equation with terms `terms` that `keep` selects: `own` first, then
/// every one the terms use, in order of first appearance.
pub(crate) fn coordinates(own: Var, terms: &[Term], keep: fn(&Var) -> bool) -> Vec<Var> {
    let mut out = vec![own];
    for t in terms {
        for v in t.vars() {
            if keep(v) && !out.contains(v) {
                out.push(v.clone());
            }
        }
    }
    out
}

impl<'a> EffectContext<'a> {
    /// The context of `dof`'s equation (terms `terms`) of `model`, with the data's scales.
    pub(crate) fn new(
        model: &'a Model,
        dof: &'a str,
        terms: Vec<Term>,
        scales: &DataScales,
        dt: f64,
        max_power: u32,
    ) -> Self {
        Self {
            model,
            dof,
            terms,
            velocity_scale: scales.velocity,
            period: scales.period,
            dt,
            max_power,
            displacement_mean: scales.mean,
            displacement_ranges: scales.ranges.clone(),
            displacement_rms: scales.rms.clone(),
            shortest_record: scales.shortest_record,
            input_period: scales.input_period,
            lost_inputs: scales.lost_inputs.clone(),
        }
    }

    /// The RMS about its mean of the displacement coordinate `v` over the data, if the equation
    /// uses it and it moves.
    pub fn displacement_rms(&self, v: &Var) -> Option<f64> {
        self.displacement_rms
            .iter()
            .find(|(w, _)| w == v)
            .map(|(_, r)| *r)
            .filter(|r| *r > 0.0 && r.is_finite())
    }

    /// True if the equation already has `term`.
    pub fn has(&self, term: &Term) -> bool {
        self.terms.contains(term)
    }
    fn disp(&self) -> Var {
        Var::Disp(self.dof.to_string())
    }
    fn vel(&self) -> Var {
        Var::Vel(self.dof.to_string())
    }
    /// The velocity coordinates an effect may act on: the DOF's own velocity first, then every
    /// relative velocity `(a-b)'` the equation already uses (the couplings of a chain, or the
    /// motion relative to a moving base), in order of first appearance.
    pub fn velocity_vars(&self) -> Vec<Var> {
        self.coordinate_vars(self.vel(), Var::is_velocity)
    }
    /// The displacement coordinates: the DOF's own displacement first, then every relative
    /// displacement `(a-b)` the equation uses.
    pub fn displacement_vars(&self) -> Vec<Var> {
        self.coordinate_vars(self.disp(), Var::is_displacement)
    }
    fn coordinate_vars(&self, own: Var, keep: fn(&Var) -> bool) -> Vec<Var> {
        coordinates(own, &self.terms, keep)
    }
    /// True when the equation has the constant term `1`: the displacement's origin is then
    /// arbitrary (raw units with a sensor offset, absorbed by the constant), and powers of the
    /// displacement are offered about [`EffectContext::displacement_mean`].
    pub fn raw_origin(&self) -> bool {
        self.has(&Term::constant())
    }
    /// A displacement-dependent column: centred on the mean position in raw units (see
    /// [`EffectContext::raw_origin`]), plain otherwise.
    pub fn displacement_column(&self, term: Term) -> EffectColumn {
        if self.raw_origin() {
            EffectColumn::centred(term, self.dof, self.displacement_mean)
        } else {
            EffectColumn::term(term)
        }
    }
}

impl Variant {
    /// The other DOFs this variant's columns couple `own` to: the far end of every relative
    /// coordinate `(a-b)` or `(a-b)'` between `own` and another DOF. A force on a coupling acts
    /// on both masses, so such a variant belongs in the partner's equation too.
    pub fn partners(&self, own: &str) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for c in self.add.iter().chain(self.replace.iter().map(|(_, c)| c)) {
            for v in c.term.vars() {
                if let Var::RelDisp(a, tfs_library::Coord::Dof(b))
                | Var::RelVel(a, tfs_library::Coord::Dof(b)) = v
                {
                    let other = if a == own {
                        b
                    } else if b == own {
                        a
                    } else {
                        continue;
                    };
                    if !out.contains(other) {
                        out.push(other.clone());
                    }
                }
            }
        }
        out
    }
}

/// A named physical effect. Implement it in any crate and [`Catalogue::register`] it.
pub trait Effect: Send + Sync {
    /// The name `--add` accepts (lower case, no spaces).
    fn name(&self) -> String;
    /// One line on the physics.
    fn description(&self) -> String;
    /// The family offered to one equation; empty when the effect does not apply (e.g. the term
    /// is already in the equation).
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant>;
    /// True when `refit` chooses this effect's scanned parameter by how well the model
    /// simulates the records, among the variants with the lowest held-out residual, rather
    /// than by the residual alone (a stop's position); the diagnosis's judge then simulates
    /// those variants too (`judged.rs`).
    fn parameter_by_simulation(&self) -> bool {
        false
    }
}

fn single(ctx: &EffectContext<'_>, term: Term) -> Vec<Variant> {
    if ctx.has(&term) {
        Vec::new()
    } else {
        vec![Variant::adding(None, vec![EffectColumn::term(term)])]
    }
}

/// Like `single`, for a displacement-dependent term: centred on the mean position in raw units.
fn single_displacement(ctx: &EffectContext<'_>, term: Term) -> Vec<Variant> {
    if ctx.has(&term) {
        Vec::new()
    } else {
        vec![Variant::adding(None, vec![ctx.displacement_column(term)])]
    }
}

/// One variant per coordinate: `make(v)` for every velocity (or displacement) coordinate `v` of
/// the equation, skipping terms already present. The DOF's own coordinate goes through `own`
/// (centred in raw units for displacement terms), relative ones are plain terms.
fn per_coordinate(
    ctx: &EffectContext<'_>,
    vars: Vec<Var>,
    make: impl Fn(&Var) -> Term,
    own: impl Fn(&EffectContext<'_>, Term) -> Vec<Variant>,
) -> Vec<Variant> {
    let mut out = Vec::new();
    for (i, v) in vars.iter().enumerate() {
        let term = make(v);
        if i == 0 {
            out.extend(own(ctx, term));
        } else if !ctx.has(&term) {
            out.push(Variant::adding(None, vec![EffectColumn::term(term)]));
        }
    }
    out
}

/// Dry (Coulomb) friction `tanh(x'/ε)`, ε scanned relative to the velocity RMS.
#[derive(Debug, Clone, Copy)]
pub struct DryFriction;
impl Effect for DryFriction {
    fn name(&self) -> String {
        "dry-friction".into()
    }
    fn description(&self) -> String {
        "Coulomb friction, smoothed: tanh(x'/eps), eps scanned over 0.3 %..30 % of the velocity RMS"
            .into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        if ctx.velocity_scale <= 0.0 {
            return Vec::new();
        }
        let mut out = Vec::new();
        for v in ctx.velocity_vars() {
            for eps in [0.003, 0.01, 0.03, 0.1, 0.3].map(|r| round3(r * ctx.velocity_scale)) {
                let term = Term::new(vec![Factor::Tanh(v.clone(), eps)]);
                if !ctx.has(&term) {
                    out.push(Variant::adding(
                        Some(("eps".into(), eps)),
                        vec![EffectColumn::term(term)],
                    ));
                }
            }
        }
        out
    }
}

/// Linear viscous damping `x'` (a dashpot, the loss of most materials and joints at small
/// amplitude) missing from the equation: offered on the DOF's own velocity and on every relative
/// velocity `(a-b)'` its equation uses, when the term is not there yet. Without it, a library
/// that omits `x'` gets the nearest nonlinear relative (quadratic damping, a hysteresis state
/// acting as a damper) instead of the plain term.
#[derive(Debug, Clone, Copy)]
pub struct LinearDamping;
impl Effect for LinearDamping {
    fn name(&self) -> String {
        "linear-damping".into()
    }
    fn description(&self) -> String {
        "linear viscous damping x' (dashpot) missing from the model".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        per_coordinate(ctx, ctx.velocity_vars(), |v| Term::var(v.clone()), single)
    }
}

/// Velocity-squared (quadratic, drag-like) damping `x'·|x'|`.
#[derive(Debug, Clone, Copy)]
pub struct QuadraticDamping;
impl Effect for QuadraticDamping {
    fn name(&self) -> String {
        "quadratic-damping".into()
    }
    fn description(&self) -> String {
        "velocity-squared damping x'*abs(x') (air drag, turbulent flow)".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        per_coordinate(
            ctx,
            ctx.velocity_vars(),
            |v| Term::new(vec![Factor::Pow(v.clone(), 1), Factor::Abs(v.clone())]),
            single,
        )
    }
}

/// Cubic damping `x'^3`.
#[derive(Debug, Clone, Copy)]
pub struct CubicDamping;
impl Effect for CubicDamping {
    fn name(&self) -> String {
        "cubic-damping".into()
    }
    fn description(&self) -> String {
        "cubic damping x'^3".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        per_coordinate(
            ctx,
            ctx.velocity_vars(),
            |v| Term::new(vec![Factor::Pow(v.clone(), 3)]),
            single,
        )
    }
}

/// Amplitude-dependent (van der Pol-like) damping `x²·x'`.
#[derive(Debug, Clone, Copy)]
pub struct AmplitudeDamping;
impl Effect for AmplitudeDamping {
    fn name(&self) -> String {
        "amplitude-damping".into()
    }
    fn description(&self) -> String {
        "amplitude-dependent damping x^2*x' (material damping growing with strain)".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        // Own coordinate: x^2*x'; a coupling: (a-b)^2*(a-b)'.
        let mut out = single_displacement(
            ctx,
            Term::new(vec![Factor::Pow(ctx.disp(), 2), Factor::Pow(ctx.vel(), 1)]),
        );
        for v in ctx.velocity_vars().into_iter().skip(1) {
            if let Some(d) = v.integral() {
                let term = Term::new(vec![Factor::Pow(d, 2), Factor::Pow(v, 1)]);
                if !ctx.has(&term) {
                    out.push(Variant::adding(None, vec![EffectColumn::term(term)]));
                }
            }
        }
        out
    }
}

/// A stiffness power `x^k` missing from the equation.
#[derive(Debug, Clone, Copy)]
pub struct StiffnessPower(pub u32);
impl Effect for StiffnessPower {
    fn name(&self) -> String {
        format!("stiffness-x^{}", self.0)
    }
    fn description(&self) -> String {
        format!("restoring-force power x^{} missing from the model", self.0)
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        if self.0 == 0 || self.0 > ctx.max_power {
            return Vec::new();
        }
        let k = self.0;
        per_coordinate(
            ctx,
            ctx.displacement_vars(),
            |v| Term::new(vec![Factor::Pow(v.clone(), k)]),
            single_displacement,
        )
    }
}

/// A constant offset `1` (gravity, preload, sensor offset).
#[derive(Debug, Clone, Copy)]
pub struct Offset;
impl Effect for Offset {
    fn name(&self) -> String {
        "offset".into()
    }
    fn description(&self) -> String {
        "constant force 1 (gravity, preload, sensor offset)".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        single(ctx, Term::constant())
    }
}

/// Whether a one-factor stop `term` (`below(q, c)` or `above(q, c)`) with coefficient `coef` in
/// the equation of DOF `dof` pushes its coordinate `q` back out of the contact: up below `c`,
/// down above it. `q` moves with `dof` (`dof`, `(dof-b)`) or against it (`(a-dof)`), so the
/// force on `dof` that does so has the sign of that motion. `None` when `term` is not a stop or
/// `q` does not move with `dof` (the rule does not apply); `Some(false)` for a zero or
/// non-finite coefficient. A stop that pulls into its contact is a kink the equation error
/// fitted, not a stop: every fit of a stop (the scan's, the refit's, the T-F-S re-scan's) keeps
/// only a stop for which this is not `Some(false)`.
pub fn stop_pushes_out(term: &Term, dof: &str, coef: f64) -> Option<bool> {
    let (v, below) = match term.factors() {
        [Factor::Below(v, _)] => (v, true),
        [Factor::Above(v, _)] => (v, false),
        _ => return None,
    };
    let moves = match v {
        Var::Disp(d) if d == dof => 1.0,
        Var::RelDisp(a, _) if a == dof => 1.0,
        Var::RelDisp(_, tfs_library::Coord::Dof(b)) if b == dof => -1.0,
        _ => return None,
    };
    let side = if below { 1.0 } else { -1.0 };
    Some(side * moves * coef > 0.0)
}

/// A one-sided stop (end stop, contact, a cell's folded state): `below(q, c)` for a stop the
/// coordinate `q` runs into from above, `above(q, c)` for one from below, the contact stiffness
/// the refitted coefficient. The position `c` is scanned inside either end of the range the data
/// cover (1–20 % of the span in from the extreme): a stiff stop holds the coordinate just beyond
/// its position, so the data's extreme lies a little past it. An end of a coordinate whose
/// equation already has a stop on that side (`below(q, ·)` at the lower end, `above(q, ·)` at the
/// upper) is not offered again: a second stop there re-describes the contact the first one
/// models (their columns are collinear wherever both act), so the scan looks at the other end.
#[derive(Debug, Clone, Copy)]
pub struct Stop;

/// Whether `terms` hold a one-factor stop on `v` on the side `below` says.
fn has_stop_on(terms: &[Term], v: &Var, below: bool) -> bool {
    terms.iter().any(|t| match t.factors() {
        [Factor::Below(w, _)] => below && w == v,
        [Factor::Above(w, _)] => !below && w == v,
        _ => false,
    })
}
impl Effect for Stop {
    fn name(&self) -> String {
        "stop".into()
    }
    fn description(&self) -> String {
        "one-sided stop (end stop, contact, folded state): k*below(x, c) or k*above(x, c), c scanned over 1 %..20 % of the displacement span in from either extreme".into()
    }
    fn parameter_by_simulation(&self) -> bool {
        true
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        let mut out = Vec::new();
        for (v, lo, hi) in &ctx.displacement_ranges {
            let span = hi - lo;
            if !(span > 0.0 && span.is_finite()) {
                continue;
            }
            let (has_below, has_above) = (
                has_stop_on(&ctx.terms, v, true),
                has_stop_on(&ctx.terms, v, false),
            );
            for r in [0.01, 0.02, 0.05, 0.1, 0.2] {
                let (below, above) = (round3(lo + r * span), round3(hi - r * span));
                let sides = [
                    (!has_below).then(|| (below, Factor::Below(v.clone(), below))),
                    (!has_above).then(|| (above, Factor::Above(v.clone(), above))),
                ];
                for (c, factor) in sides.into_iter().flatten() {
                    let term = Term::new(vec![factor]);
                    if !ctx.has(&term) {
                        out.push(Variant::adding(
                            Some(("c".into(), c)),
                            vec![EffectColumn::term(term)],
                        ));
                    }
                }
            }
        }
        out
    }
}

/// The registry of effects, in a fixed order.
pub struct Catalogue {
    effects: Vec<Box<dyn Effect>>,
}

impl std::fmt::Debug for Catalogue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.names()).finish()
    }
}

impl Default for Catalogue {
    fn default() -> Self {
        Self::standard(7)
    }
}

impl Catalogue {
    /// An empty catalogue.
    pub fn empty() -> Self {
        Self {
            effects: Vec::new(),
        }
    }

    /// The built-in effects, with stiffness powers `x^1 … x^max_power`. Dahl friction
    /// ([`DahlFriction`]) is the `b = 0` member of the hysteresis family and is not a separate
    /// candidate here (it would tie with hysteresis whenever the best loop is symmetric); register
    /// it to test it on its own.
    pub fn standard(max_power: u32) -> Self {
        let mut c = Self::empty();
        let mut add = |e: Box<dyn Effect>| c.effects.push(e);
        add(Box::new(DryFriction));
        add(Box::new(LinearDamping));
        add(Box::new(QuadraticDamping));
        add(Box::new(CubicDamping));
        add(Box::new(AmplitudeDamping));
        for k in 1..=max_power {
            add(Box::new(StiffnessPower(k)));
        }
        add(Box::new(Offset));
        add(Box::new(Maxwell));
        add(Box::new(Hysteresis));
        add(Box::new(InputDelay));
        add(Box::new(InputFilter));
        add(Box::new(Stop));
        c
    }

    /// Adds an effect; its name must be new, non-empty and free of spaces, `@` and `,`.
    pub fn register(&mut self, effect: Box<dyn Effect>) -> Result<()> {
        let name = effect.name();
        if name.is_empty() || name.contains([' ', '@', ',']) {
            return Err(DiagnoseError::InvalidParameter {
                name: "effect name",
                reason: format!("'{name}' must be non-empty without spaces, '@' or ','"),
            });
        }
        if self.names().contains(&name) {
            return Err(DiagnoseError::InvalidParameter {
                name: "effect name",
                reason: format!("'{name}' is already registered; choose another name"),
            });
        }
        self.effects.push(effect);
        Ok(())
    }

    /// Removes the effect called `name` (an unknown name is an error listing the known ones).
    pub fn remove(&mut self, name: &str) -> Result<()> {
        self.get(name)?;
        self.effects.retain(|e| e.name() != name);
        Ok(())
    }

    /// The names, in catalogue order.
    pub fn names(&self) -> Vec<String> {
        self.effects.iter().map(|e| e.name()).collect()
    }

    /// The effects.
    pub fn effects(&self) -> &[Box<dyn Effect>] {
        &self.effects
    }

    /// Looks an effect up by name; an unknown name is an error listing the known ones.
    pub fn get(&self, name: &str) -> Result<&dyn Effect> {
        self.effects
            .iter()
            .find(|e| e.name() == name)
            .map(|e| e.as_ref())
            .ok_or_else(|| DiagnoseError::UnknownEffect {
                name: name.to_string(),
                known: self.names().join(", "),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stop's variants on a one-DOF equation with `terms`, over data from 0 to 2.
    fn stop_variants(terms: &[&str]) -> Vec<Term> {
        let model = Model::from_json_str(
            r#"{"format": "tfs-model/1", "dofs": ["x"], "inputs": [],
                "equations": [{"dof": "x", "terms": [{"term": "x", "coef": -1.0}]}]}"#,
        )
        .unwrap();
        let terms: Vec<Term> = terms
            .iter()
            .map(|t| Term::parse(t, &["x"]).unwrap())
            .collect();
        let x = Var::Disp("x".into());
        let ctx = EffectContext {
            model: &model,
            dof: "x",
            terms,
            velocity_scale: 1.0,
            period: 1.0,
            dt: 0.01,
            max_power: 3,
            displacement_mean: 1.0,
            displacement_ranges: vec![(x.clone(), 0.0, 2.0)],
            displacement_rms: vec![(x, 0.5)],
            shortest_record: 10.0,
            input_period: f64::NAN,
            lost_inputs: Vec::new(),
        };
        Stop.variants(&ctx)
            .into_iter()
            .map(|v| v.add[0].term.clone())
            .collect()
    }

    fn sides(terms: &[Term]) -> (usize, usize) {
        let below = terms
            .iter()
            .filter(|t| matches!(t.factors(), [Factor::Below(..)]))
            .count();
        (below, terms.len() - below)
    }

    /// A stop pushes its coordinate out of the contact: a positive coefficient below, a negative
    /// one above, on the equation's own coordinate; the other way round on a coupling's far end
    /// (`(x2-x1)` in `x1`'s equation); no rule for a coordinate the DOF does not move or a term
    /// that is not a stop.
    #[test]
    fn a_stop_pushes_out_of_its_contact() {
        let dofs = ["x1", "x2"];
        let t = |s: &str| Term::parse(s, &dofs).unwrap();
        assert_eq!(stop_pushes_out(&t("below(x1, 0.1)"), "x1", 3.0), Some(true));
        assert_eq!(
            stop_pushes_out(&t("below(x1, 0.1)"), "x1", -3.0),
            Some(false)
        );
        assert_eq!(
            stop_pushes_out(&t("above(x1, 0.1)"), "x1", -3.0),
            Some(true)
        );
        assert_eq!(
            stop_pushes_out(&t("above(x1, 0.1)"), "x1", 3.0),
            Some(false)
        );
        assert_eq!(
            stop_pushes_out(&t("above(x1, 0.1)"), "x1", 0.0),
            Some(false)
        );
        assert_eq!(
            stop_pushes_out(&t("above(x1, 0.1)"), "x1", f64::NAN),
            Some(false)
        );
        let cell = t("below((x2-x1), 0.1)");
        assert_eq!(stop_pushes_out(&cell, "x2", 3.0), Some(true));
        assert_eq!(stop_pushes_out(&cell, "x1", 3.0), Some(false));
        assert_eq!(stop_pushes_out(&cell, "x1", -3.0), Some(true));
        assert_eq!(stop_pushes_out(&t("below(x1, 0.1)"), "x2", 3.0), None);
        assert_eq!(stop_pushes_out(&t("x1^3"), "x1", 3.0), None);
    }

    /// Both ends are offered to an equation without a stop; an end that already has one is not
    /// offered again, whatever its position.
    #[test]
    fn a_stop_is_offered_only_at_an_end_without_one() {
        assert_eq!(sides(&stop_variants(&["x"])), (5, 5));
        let with_below = stop_variants(&["x", "below(x, 0.0003)"]);
        assert_eq!(sides(&with_below), (0, 5));
        assert!(with_below.contains(&Term::parse("above(x, 1.6)", &["x"]).unwrap()));
        assert_eq!(sides(&stop_variants(&["x", "above(x, 1.9)"])), (5, 0));
        assert!(stop_variants(&["below(x, 0.1)", "above(x, 1.9)"]).is_empty());
    }
}
