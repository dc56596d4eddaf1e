//! Equilibria, wells and barriers of a one-degree-of-freedom restoring force.
//!
//! Convention: the unforced dynamics are `m x'' = −f(x) − (damping)`, with the restoring force
//! `f = V'`. A root of `f` where `f` changes sign from negative to positive is stable (a minimum
//! of `V`), from positive to negative unstable (a maximum of `V`: a wall between wells). A root where `f` touches zero
//! without changing sign (found only on scan points, such as `x = 0` of a polynomial whose lowest
//! power is even) is an inflection of `V`: neither a well's bottom nor a wall. It lies inside a
//! well, whose walls are the maxima on either side; a start that creeps towards it from above
//! can never leave that well and is labelled with its state.
//!
//! The roots come from `tfs_dynamics::equilibria` (sign scan on 20 000 intervals, then Brent).

use std::sync::Arc;

use crate::error::{BasinError, Result, invalid};
use tfs_dynamics::SecondOrderSystem;

/// A shared scalar function `f64 → f64`.
pub type ScalarFn = Arc<dyn Fn(f64) -> f64 + Send + Sync>;

/// Number of samples of the sign scan used to find the roots of the restoring force.
const SCAN_SAMPLES: usize = 20_000;
/// Relative safety margin subtracted from every barrier (of the well depth).
const BARRIER_MARGIN: f64 = 1e-6;

/// One potential well: the interval between the unstable equilibria (or search-range ends)
/// around a stable equilibrium, and the lowest energy that can leave it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Well {
    /// The stable equilibrium at the bottom of the well.
    pub bottom: f64,
    /// Left wall: an unstable equilibrium, or where no saddle lies to the left in the search
    /// range, a point at or below its lower end out to which the potential keeps rising.
    pub lo: f64,
    /// Right wall: an unstable equilibrium, or at or above the search range's upper end where
    /// the potential keeps rising out to it.
    pub hi: f64,
    /// `min(V(lo), V(hi))` minus a tiny safety margin: a trajectory inside `(lo, hi)` with
    /// energy below this can never leave (for non-negative damping).
    pub barrier: f64,
}

/// Equilibria, wells and energy barriers of a 1-DOF system, with the force and potential used.
#[derive(Clone)]
pub struct WellInfo {
    stable: Vec<f64>,
    unstable: Vec<f64>,
    wells: Vec<Well>,
    search: (f64, f64),
    mass: f64,
    force: ScalarFn,
    potential: ScalarFn,
}

impl std::fmt::Debug for WellInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WellInfo")
            .field("stable", &self.stable)
            .field("unstable", &self.unstable)
            .field("wells", &self.wells)
            .field("search", &self.search)
            .field("mass", &self.mass)
            .finish()
    }
}

impl WellInfo {
    /// Finds the equilibria of the restoring force `force` (`= V'`) on `search = (lo, hi)` and
    /// builds the wells (an end where the force is exactly zero is moved out by 1 % of the width,
    /// so that equilibrium can be classified). `potential` is `V` (any additive constant); `mass` multiplies `½v²`.
    ///
    /// Checks that `potential` is an antiderivative of `force` (central differences at a few
    /// points) and that at least one stable equilibrium exists.
    pub fn from_force(
        force: impl Fn(f64) -> f64 + Send + Sync + 'static,
        potential: impl Fn(f64) -> f64 + Send + Sync + 'static,
        search: (f64, f64),
        mass: f64,
    ) -> Result<Self> {
        let (lo, hi) = search;
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(invalid(
                "search",
                format!("range ({lo}, {hi}) must be finite with lo < hi"),
            ));
        }
        if !(mass.is_finite() && mass > 0.0) {
            return Err(invalid(
                "mass",
                format!("{mass} must be finite and positive"),
            ));
        }
        let force: ScalarFn = Arc::new(force);
        let potential: ScalarFn = Arc::new(potential);
        // An equilibrium exactly at an end of the range (a round range around a round model,
        // such as the double well ±1 searched on [−1, 3]) cannot be classified from one side;
        // move that end out by 1 % of the width so the equilibrium is interior.
        let (lo, hi) = (
            if force(lo) == 0.0 {
                lo - 0.01 * (hi - lo)
            } else {
                lo
            },
            if force(hi) == 0.0 {
                hi + 0.01 * (hi - lo)
            } else {
                hi
            },
        );
        let search = (lo, hi);
        check_antiderivative(&*force, &*potential, search)?;
        let eq = tfs_dynamics::equilibria(&*force, lo, hi, SCAN_SAMPLES)?;
        let stable: Vec<f64> = eq.iter().filter(|e| e.stable).map(|e| e.x).collect();
        let unstable: Vec<f64> = eq
            .iter()
            .filter(|e| !e.stable && is_wall(&*force, e.x, (hi - lo) / SCAN_SAMPLES as f64))
            .map(|e| e.x)
            .collect();
        if stable.is_empty() {
            return Err(BasinError::NoStableEquilibrium { lo, hi });
        }
        let wells = build_wells(&stable, &unstable, search, &*force, &*potential);
        Ok(Self {
            stable,
            unstable,
            wells,
            search,
            mass,
            force,
            potential,
        })
    }

    /// Wells of a [`Polynomial1Dof`] on `search`.
    pub fn from_polynomial(model: &Polynomial1Dof, search: (f64, f64)) -> Result<Self> {
        let f = model.clone();
        let p = model.clone();
        Self::from_force(move |x| f.force(x), move |x| p.potential(x), search, 1.0)
    }

    /// Stable equilibria, ascending. Basin labels index into this list.
    pub fn stable(&self) -> &[f64] {
        &self.stable
    }
    /// Unstable equilibria that are maxima of the potential (the walls between wells),
    /// ascending. A root where the force touches zero without changing sign is in neither list.
    pub fn unstable(&self) -> &[f64] {
        &self.unstable
    }
    /// One well per stable equilibrium, in the same order.
    pub fn wells(&self) -> &[Well] {
        &self.wells
    }
    /// The search range the equilibria were looked for in.
    pub fn search(&self) -> (f64, f64) {
        self.search
    }
    /// Mass multiplying `½v²`.
    pub fn mass(&self) -> f64 {
        self.mass
    }
    /// Restoring force `f(x) = V'(x)`.
    pub fn force(&self, x: f64) -> f64 {
        (self.force)(x)
    }
    /// Potential `V(x)`.
    pub fn potential(&self, x: f64) -> f64 {
        (self.potential)(x)
    }
    /// Mechanical energy `½ m v² + V(x)`.
    pub fn energy(&self, x: f64, v: f64) -> f64 {
        0.5 * self.mass * v * v + (self.potential)(x)
    }
    /// Index of the well whose open interval `(lo, hi)` contains `x`.
    pub fn well_of(&self, x: f64) -> Option<usize> {
        self.wells.iter().position(|w| x > w.lo && x < w.hi)
    }
    /// The well index if the state `(x, v)` is provably trapped: inside a well with energy below
    /// its barrier. Valid for non-negative damping (energy never increases).
    #[inline]
    pub fn trapped(&self, x: f64, v: f64) -> Option<usize> {
        let k = self.well_of(x)?;
        (self.energy(x, v) < self.wells[k].barrier).then_some(k)
    }
    /// Quasi-static barrier from stable state `from` to stable state `to`: the highest potential
    /// at the unstable equilibria between them minus `V(stable[from])`.
    pub fn quasi_static_barrier(&self, from: usize, to: usize) -> Result<f64> {
        self.check_index("from", from)?;
        self.check_index("to", to)?;
        let (a, b) = if from < to {
            (self.stable[from], self.stable[to])
        } else {
            (self.stable[to], self.stable[from])
        };
        let top = self
            .unstable
            .iter()
            .filter(|&&u| u > a && u < b)
            .map(|&u| self.potential(u))
            .fold(f64::NEG_INFINITY, f64::max);
        if !top.is_finite() {
            return Err(invalid(
                "to",
                format!(
                    "states {from} and {to} are the same state or not separated by an unstable equilibrium"
                ),
            ));
        }
        Ok(top - self.potential(self.stable[from]))
    }

    pub(crate) fn check_index(&self, name: &'static str, k: usize) -> Result<()> {
        if k >= self.stable.len() {
            return Err(invalid(
                name,
                format!(
                    "state index {k} out of range: there are {} stable states ({:?})",
                    self.stable.len(),
                    self.stable
                ),
            ));
        }
        Ok(())
    }

    /// Checks on a `samples × samples` grid over `x_range × v_range` that the unforced `sys`
    /// never gains energy: `dE/dt = v (m a + f(x)) ≤ 0` up to rounding. Required for the
    /// early-exit proof; also catches a force/potential that does not match the model.
    pub fn check_dissipative<S: SecondOrderSystem + ?Sized>(
        &self,
        sys: &S,
        x_range: (f64, f64),
        v_range: (f64, f64),
        samples: usize,
    ) -> Result<()> {
        if sys.dofs() != 1 {
            return Err(invalid(
                "sys",
                format!(
                    "a 1-DOF system is required, this one has {} DOFs",
                    sys.dofs()
                ),
            ));
        }
        let u = vec![0.0; sys.inputs()];
        let n = samples.max(2);
        let mut a = [0.0];
        for i in 0..n {
            let x = x_range.0 + (x_range.1 - x_range.0) * i as f64 / (n - 1) as f64;
            let f = self.force(x);
            for j in 0..n {
                let v = v_range.0 + (v_range.1 - v_range.0) * j as f64 / (n - 1) as f64;
                sys.accel(0.0, &[x], &[v], &u, &mut a);
                let ma = self.mass * a[0];
                let rate = v * (ma + f);
                let scale = v.abs() * (ma.abs() + f.abs()) + f64::MIN_POSITIVE;
                if rate > 1e-7 * scale + 1e-12 || !rate.is_finite() {
                    return Err(BasinError::NotDissipative {
                        x,
                        v,
                        rate,
                        mass: self.mass,
                    });
                }
            }
        }
        Ok(())
    }
}

/// Checks `V' ≈ f` by central differences at a handful of interior points.
fn check_antiderivative(
    force: &dyn Fn(f64) -> f64,
    potential: &dyn Fn(f64) -> f64,
    (lo, hi): (f64, f64),
) -> Result<()> {
    let width = hi - lo;
    let xs: Vec<f64> = (1..=15).map(|k| lo + width * k as f64 / 16.0).collect();
    // Scale of the force over the range: finite-difference errors are relative to it.
    let fscale = xs.iter().map(|&x| force(x).abs()).fold(0.0, f64::max);
    for &x in &xs {
        let h = 1e-5 * width.max(x.abs()).max(1e-3);
        let d = (potential(x + h) - potential(x - h)) / (2.0 * h);
        let f = force(x);
        if !d.is_finite() || !f.is_finite() {
            return Err(invalid(
                "potential",
                format!("force or potential is not finite at x = {x}"),
            ));
        }
        let rounding = 1e-12 * (potential(x).abs() + 1.0) / h;
        // The central difference of V is the mean of F over [x − h, x + h], so it must lie within
        // the range F takes there (sampled at both ends and the middle); this also holds at a
        // kink of F, such as the folded stop of a truss cell, where F' jumps.
        let (fl, fr) = (force(x - h), force(x + h));
        let (fmin, fmax) = (f.min(fl).min(fr), f.max(fl).max(fr));
        let tol = 1e-3 * (f.abs() + 1e-3 * fscale) + rounding + 1e-12;
        let outside = if d < fmin {
            fmin - d
        } else if d > fmax {
            d - fmax
        } else {
            0.0
        };
        if outside > tol {
            return Err(invalid(
                "potential",
                format!(
                    "V'(x) = {d:.6e} but f(x) = {f:.6e} at x = {x}; the potential must be an antiderivative of the restoring force"
                ),
            ));
        }
    }
    Ok(())
}

/// True when the root `x` of `force` is a maximum of the potential: the force is positive just
/// left of it and negative just right (at a thousandth of the scan `step`, as the scan itself
/// classifies roots on its points). A root where the force keeps its sign is an inflection of
/// the potential, which no trajectory is held back by.
fn is_wall(force: &dyn Fn(f64) -> f64, x: f64, step: f64) -> bool {
    let delta = 1e-3 * step;
    force(x - delta) > 0.0 && force(x + delta) < 0.0
}

fn build_wells(
    stable: &[f64],
    unstable: &[f64],
    (lo, hi): (f64, f64),
    force: &dyn Fn(f64) -> f64,
    potential: &dyn Fn(f64) -> f64,
) -> Vec<Well> {
    stable
        .iter()
        .map(|&s| {
            let left = unstable
                .iter()
                .copied()
                .filter(|&u| u < s)
                .fold(lo, f64::max);
            let right = unstable
                .iter()
                .copied()
                .filter(|&u| u > s)
                .fold(hi, f64::min);
            // A wall at an end of the search range is moved out while the potential keeps
            // rising, up to the other wall's height when that one is a saddle.
            let cap = |w: f64, end: f64| {
                if w == end {
                    f64::INFINITY
                } else {
                    potential(w)
                }
            };
            let left = if left == lo {
                rising_wall(lo, -1.0, hi - lo, cap(right, hi), force, potential)
            } else {
                left
            };
            let right = if right == hi {
                rising_wall(hi, 1.0, hi - lo, cap(left, lo), force, potential)
            } else {
                right
            };
            let wall = potential(left).min(potential(right));
            let depth = (wall - potential(s)).abs();
            Well {
                bottom: s,
                lo: left,
                hi: right,
                barrier: wall - BARRIER_MARGIN * depth.max(f64::MIN_POSITIVE),
            }
        })
        .collect()
}

/// Walks a well's wall at a search-range end `end` outwards (`dir` −1 left, +1 right) in steps of
/// `width / SCAN_SAMPLES` (the equilibrium scan's resolution) while the force keeps pushing back
/// towards the well, so the potential keeps rising and no equilibrium is passed; stops once the
/// potential reaches `target` or after one `width`. A trajectory inside the walls with energy
/// below both walls' potential can then never leave, as between two saddles; with the end itself
/// as the wall, a well whose bottom sits near the end (the double well's −1 searched on [−1, 3])
/// had a barrier barely above its bottom and its starts were proven trapped only after decaying
/// almost to rest.
fn rising_wall(
    end: f64,
    dir: f64,
    width: f64,
    target: f64,
    force: &dyn Fn(f64) -> f64,
    potential: &dyn Fn(f64) -> f64,
) -> f64 {
    let dx = width / SCAN_SAMPLES as f64;
    let mut wall = end;
    for k in 1..=SCAN_SAMPLES {
        let x = end + dir * dx * k as f64;
        // Moving left the potential rises where V' = f < 0; moving right where f > 0.
        let pushes_back = dir * force(x) > 0.0;
        if !pushes_back || !potential(x).is_finite() {
            break;
        }
        wall = x;
        if potential(x) >= target {
            break;
        }
    }
    wall
}

/// The polynomial 1-DOF oscillator `x'' + ζ x' + Σ_k c_k x^k = 0` (unit mass), e.g. the paper's
/// Eq. 16 with Table 1 coefficients `ζ = 1.99`, `c_5 = 12.12`, `c_6 = −18.03`, `c_7 = 6.56`.
///
/// Evaluated as `x^p · (Horner over the nonzero span)`, so leading zero powers cost nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct Polynomial1Dof {
    damping: f64,
    coeffs: Vec<f64>,
    /// Lowest power with a nonzero coefficient.
    p0: u32,
    /// `coeffs[p0..=last nonzero]`.
    span: Vec<f64>,
    /// `coeffs[k] / (k + 1)` over the same span (potential).
    span_pot: Vec<f64>,
}

impl Polynomial1Dof {
    /// `damping` is `ζ` (≥ 0 for the early-exit proof), `coeffs[k]` multiplies `x^k` in the
    /// restoring force (`coeffs[0]` is a constant force). All values must be finite.
    pub fn new(damping: f64, coeffs: Vec<f64>) -> Result<Self> {
        if !damping.is_finite() {
            return Err(invalid("damping", format!("{damping} must be finite")));
        }
        if let Some(k) = coeffs.iter().position(|c| !c.is_finite()) {
            return Err(invalid(
                "coeffs",
                format!("coefficient of x^{k} is not finite"),
            ));
        }
        let first = coeffs.iter().position(|&c| c != 0.0);
        let last = coeffs.iter().rposition(|&c| c != 0.0);
        let (p0, span, span_pot) = match (first, last) {
            (Some(a), Some(b)) => (
                a as u32,
                coeffs[a..=b].to_vec(),
                (a..=b).map(|k| coeffs[k] / (k + 1) as f64).collect(),
            ),
            _ => (0, Vec::new(), Vec::new()),
        };
        Ok(Self {
            damping,
            coeffs,
            p0,
            span,
            span_pot,
        })
    }
    /// The paper's Table 1 model identified at 60 dB SNR.
    pub fn table1_60db() -> Self {
        Self::new(1.99, vec![0.0, 0.0, 0.0, 0.0, 0.0, 12.12, -18.03, 6.56])
            .expect("finite coefficients")
    }
    /// Damping coefficient `ζ`.
    pub fn damping(&self) -> f64 {
        self.damping
    }
    /// Force coefficients, `coeffs()[k]` multiplying `x^k`.
    pub fn coeffs(&self) -> &[f64] {
        &self.coeffs
    }
    /// Restoring force `Σ c_k x^k`.
    #[inline]
    pub fn force(&self, x: f64) -> f64 {
        powu(x, self.p0) * horner(&self.span, x)
    }
    /// Accelerations of eight states (the first `vc.len()` of `xs` are used).
    #[inline(always)]
    fn accel_chunk<const W: usize>(&self, xs: &[f64; W], vc: &[f64], ac: &mut [f64]) {
        let mut pw = [0.0f64; W];
        powu_lanes(xs, self.p0, &mut pw);
        let hz = horner_lanes(&self.span, xs);
        for (((a, v), p), h) in ac.iter_mut().zip(vc).zip(&pw).zip(&hz) {
            *a = -self.damping * v - p * h;
        }
    }
    /// Potential `Σ c_k x^(k+1) / (k+1)`, zero at `x = 0`.
    #[inline]
    pub fn potential(&self, x: f64) -> f64 {
        powu(x, self.p0 + 1) * horner(&self.span_pot, x)
    }
}

/// Horner's rule, unrolled for spans of up to 8 coefficients (the hot case).
#[inline(always)]
fn horner(c: &[f64], x: f64) -> f64 {
    #[inline(always)]
    fn fixed<const N: usize>(c: &[f64], x: f64) -> f64 {
        let c: &[f64; N] = c.try_into().expect("span length checked by the caller");
        let mut acc = c[N - 1];
        for i in (0..N - 1).rev() {
            acc = acc * x + c[i];
        }
        acc
    }
    match c.len() {
        0 => 0.0,
        1 => c[0],
        2 => fixed::<2>(c, x),
        3 => fixed::<3>(c, x),
        4 => fixed::<4>(c, x),
        5 => fixed::<5>(c, x),
        6 => fixed::<6>(c, x),
        7 => fixed::<7>(c, x),
        8 => fixed::<8>(c, x),
        _ => c.iter().rev().fold(0.0, |acc, &c| acc * x + c),
    }
}

/// `x^n`: unrolled for small `n` (the hot case), repeated squaring beyond.
#[inline(always)]
fn powu(x: f64, n: u32) -> f64 {
    match n {
        0 => 1.0,
        1 => x,
        2 => x * x,
        3 => x * x * x,
        4 => {
            let x2 = x * x;
            x2 * x2
        }
        5 => {
            let x2 = x * x;
            x2 * x2 * x
        }
        6 => {
            let x3 = x * x * x;
            x3 * x3
        }
        7 => {
            let x3 = x * x * x;
            x3 * x3 * x
        }
        8 => {
            let x2 = x * x;
            let x4 = x2 * x2;
            x4 * x4
        }
        _ => powu_loop(x, n),
    }
}

/// `x^n` by repeated squaring.
fn powu_loop(mut x: f64, mut n: u32) -> f64 {
    let mut r = 1.0;
    while n > 0 {
        if n & 1 == 1 {
            r *= x;
        }
        x *= x;
        n >>= 1;
    }
    r
}

impl SecondOrderSystem for Polynomial1Dof {
    fn dofs(&self) -> usize {
        1
    }
    #[inline]
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], _u: &[f64], a: &mut [f64]) {
        a[0] = -self.damping * v[0] - self.force(x[0]);
    }
    /// Eight states at a time with [`Polynomial1Dof::accel`]'s arithmetic (so each state's
    /// value is the same to the bit), in loops across states that vectorise.
    #[inline(always)]
    fn accel_lanes(&self, _t: f64, x: &[f64], v: &[f64], _u: &[f64], a: &mut [f64]) {
        const W: usize = 8;
        let full = x.len() / W * W;
        for ((xc, vc), ac) in x[..full]
            .chunks_exact(W)
            .zip(v.chunks_exact(W))
            .zip(a.chunks_exact_mut(W))
        {
            self.accel_chunk::<W>(xc.try_into().expect("chunk of W"), vc, ac);
        }
        if full < x.len() {
            let mut xs = [0.0f64; W];
            for (s, x) in xs.iter_mut().zip(&x[full..]) {
                *s = *x;
            }
            self.accel_chunk(&xs, &v[full..], &mut a[full..]);
        }
    }
}

/// [`horner`] for eight values at once (the same operations in the same order).
#[inline(always)]
fn horner_lanes<const W: usize>(c: &[f64], x: &[f64; W]) -> [f64; W] {
    match c.len() {
        0 => [0.0; W],
        1 => [c[0]; W],
        n @ 2..=8 => {
            let mut acc = [c[n - 1]; W];
            for &ci in c[..n - 1].iter().rev() {
                acc.iter_mut().zip(x).for_each(|(a, x)| *a = *a * x + ci);
            }
            acc
        }
        _ => {
            let mut acc = [0.0; W];
            for &ci in c.iter().rev() {
                acc.iter_mut().zip(x).for_each(|(a, x)| *a = *a * x + ci);
            }
            acc
        }
    }
}

/// [`powu`] for eight values at once (the same operations in the same order).
#[inline(always)]
fn powu_lanes<const W: usize>(x: &[f64; W], n: u32, out: &mut [f64; W]) {
    match n {
        0 => *out = [1.0; W],
        1 => *out = *x,
        2 => out.iter_mut().zip(x).for_each(|(o, &x)| *o = x * x),
        3 => out.iter_mut().zip(x).for_each(|(o, &x)| *o = x * x * x),
        4 => out.iter_mut().zip(x).for_each(|(o, &x)| {
            let x2 = x * x;
            *o = x2 * x2
        }),
        5 => out.iter_mut().zip(x).for_each(|(o, &x)| {
            let x2 = x * x;
            *o = x2 * x2 * x
        }),
        6 => out.iter_mut().zip(x).for_each(|(o, &x)| {
            let x3 = x * x * x;
            *o = x3 * x3
        }),
        7 => out.iter_mut().zip(x).for_each(|(o, &x)| {
            let x3 = x * x * x;
            *o = x3 * x3 * x
        }),
        8 => out.iter_mut().zip(x).for_each(|(o, &x)| {
            let x2 = x * x;
            let x4 = x2 * x2;
            *o = x4 * x4
        }),
        _ => out
            .iter_mut()
            .zip(x)
            .for_each(|(o, &x)| *o = powu_loop(x, n)),
    }
}
