//! Equilibria of 1-DOF restoring forces, their stability, potentials and energy barriers.
//!
//! Sign convention: a 1-DOF model is written `x'' = −F(x) − (damping) + (input)`, with `F` the
//! restoring force per unit mass. Equilibria are the zeros of `F`. An equilibrium is stable when
//! `F` changes sign from negative (left) to positive (right), i.e. `F'(x) > 0` for a simple root;
//! the sign change also classifies degenerate roots such as `F = x⁵` at 0, where `F'(0) = 0`.
//! The potential is `V(x) = ∫ F`, so stable equilibria are minima of `V`.

use crate::{DynError, Result};

/// An equilibrium `F(x) = 0` of a 1-DOF restoring force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Equilibrium {
    /// Position.
    pub x: f64,
    /// True when `F` changes sign from − to + across `x` (a minimum of the potential).
    pub stable: bool,
    /// `F'(x)` by a central difference (linearised stiffness per unit mass; ~0 for multiple roots).
    pub stiffness: f64,
}

/// Finds the equilibria of `force` in `[lo, hi]`.
///
/// `F` is sampled on `n_grid + 1` equally spaced points; each sign change is refined by Brent's
/// method to near machine precision, and an exact zero on the grid is kept as is. Roots of even
/// multiplicity (where `F` touches zero without changing sign) are found only if they fall on a
/// grid point; they are reported as not stable. Two roots closer than one grid spacing can hide
/// each other: choose `n_grid` so the spacing is below the smallest expected root separation.
///
/// ```
/// use tfs_dynamics::equilibria;
/// let eq = equilibria(|x| x * (x - 1.0) * (x - 2.0), -0.5, 2.5, 300).unwrap();
/// let xs: Vec<f64> = eq.iter().map(|e| e.x).collect();
/// assert!((xs[0] - 0.0).abs() < 1e-12 && (xs[1] - 1.0).abs() < 1e-12 && (xs[2] - 2.0).abs() < 1e-12);
/// assert_eq!(eq.iter().map(|e| e.stable).collect::<Vec<_>>(), vec![true, false, true]);
/// ```
pub fn equilibria(
    force: impl Fn(f64) -> f64,
    lo: f64,
    hi: f64,
    n_grid: usize,
) -> Result<Vec<Equilibrium>> {
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(DynError::InvalidParameter {
            name: "lo/hi",
            reason: format!("search interval [{lo}, {hi}] must be finite with lo < hi"),
        });
    }
    if n_grid < 2 {
        return Err(DynError::InvalidParameter {
            name: "n_grid",
            reason: format!("{n_grid} grid intervals are too few; use at least 2 (typically 200+)"),
        });
    }
    let step = (hi - lo) / n_grid as f64;
    let xs: Vec<f64> = (0..=n_grid)
        .map(|k| {
            if k == n_grid {
                hi
            } else {
                lo + k as f64 * step
            }
        })
        .collect();
    let mut fs = Vec::with_capacity(xs.len());
    for &x in &xs {
        let f = force(x);
        if !f.is_finite() {
            return Err(DynError::InvalidParameter {
                name: "force",
                reason: format!(
                    "F({x}) = {f} is not finite; restrict [lo, hi] to where the force is defined"
                ),
            });
        }
        fs.push(f);
    }
    let delta = 1e-3 * step;
    let sign_at = |x: f64| force(x).signum();
    let mut out = Vec::new();
    for k in 0..xs.len() {
        if fs[k] == 0.0 {
            let left = if k > 0 { sign_at(xs[k] - delta) } else { 0.0 };
            let right = if k < n_grid {
                sign_at(xs[k] + delta)
            } else {
                0.0
            };
            out.push(make(&force, xs[k], left < 0.0 && right > 0.0, step));
        }
        if k < n_grid {
            // The interval's ends, each moved in by `delta` from an exact zero on the grid:
            // a sign change there is a root of its own (a force touching zero at a grid point,
            // e.g. `x^4` at 0, with a contact's root a fraction of a step away).
            let (mut a, mut b) = ((xs[k], fs[k]), (xs[k + 1], fs[k + 1]));
            if a.1 == 0.0 {
                a = (a.0 + delta, force(a.0 + delta));
            }
            if b.1 == 0.0 {
                b = (b.0 - delta, force(b.0 - delta));
            }
            if a.1 != 0.0 && b.1 != 0.0 && (a.1 < 0.0) != (b.1 < 0.0) {
                let x = brent(&force, a.0, b.0, a.1, b.1);
                out.push(make(&force, x, a.1 < 0.0, step));
            }
        }
    }
    Ok(out)
}

fn make(force: &impl Fn(f64) -> f64, x: f64, stable: bool, step: f64) -> Equilibrium {
    let d = (1e-5 * x.abs().max(1.0)).min(1e-2 * step).max(1e-7 * step);
    let stiffness = (force(x + d) - force(x - d)) / (2.0 * d);
    Equilibrium {
        x,
        stable,
        stiffness,
    }
}

/// Brent's root finder on a bracket `[a, b]` with `fa·fb < 0` (inverse quadratic interpolation,
/// secant and bisection; Brent 1973, ch. 4).
fn brent(f: &impl Fn(f64) -> f64, a0: f64, b0: f64, fa0: f64, fb0: f64) -> f64 {
    let (mut a, mut b, mut fa, mut fb) = (a0, b0, fa0, fb0);
    let (mut c, mut fc) = (a, fa);
    let mut d = b - a;
    let mut e = d;
    for _ in 0..200 {
        if (fb > 0.0) == (fc > 0.0) {
            c = a;
            fc = fa;
            d = b - a;
            e = d;
        }
        if fc.abs() < fb.abs() {
            a = b;
            b = c;
            c = a;
            fa = fb;
            fb = fc;
            fc = fa;
        }
        let tol = 2.0 * f64::EPSILON * b.abs() + 1e-300;
        let m = 0.5 * (c - b);
        if m.abs() <= tol || fb == 0.0 {
            return b;
        }
        if e.abs() >= tol && fa.abs() > fb.abs() {
            let s = fb / fa;
            let (mut p, mut q);
            if a == c {
                p = 2.0 * m * s;
                q = 1.0 - s;
            } else {
                let qa = fa / fc;
                let r = fb / fc;
                p = s * (2.0 * m * qa * (qa - r) - (b - a) * (r - 1.0));
                q = (qa - 1.0) * (r - 1.0) * (s - 1.0);
            }
            if p > 0.0 {
                q = -q;
            } else {
                p = -p;
            }
            if 2.0 * p < (3.0 * m * q - (tol * q).abs()).min((e * q).abs()) {
                e = d;
                d = p / q;
            } else {
                d = m;
                e = m;
            }
        } else {
            d = m;
            e = m;
        }
        a = b;
        fa = fb;
        b += if d.abs() > tol { d } else { tol.copysign(m) };
        fb = f(b);
    }
    b
}

/// The potential `V(x) = ∫_{x_ref}^{x} F(s) ds` by composite 5-point Gauss–Legendre quadrature
/// on 64 panels (exact for polynomial forces up to degree 9).
pub fn potential_from_force(force: impl Fn(f64) -> f64, x_ref: f64, x: f64) -> f64 {
    const NODES: [f64; 5] = [
        0.0,
        -0.538_469_310_105_683_1,
        0.538_469_310_105_683_1,
        -0.906_179_845_938_664,
        0.906_179_845_938_664,
    ];
    const WEIGHTS: [f64; 5] = [
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
        0.236_926_885_056_189_1,
    ];
    let panels = 64;
    let h = (x - x_ref) / panels as f64;
    let mut sum = 0.0;
    for p in 0..panels {
        let mid = x_ref + (p as f64 + 0.5) * h;
        for (n, w) in NODES.iter().zip(&WEIGHTS) {
            sum += w * force(mid + 0.5 * h * n);
        }
    }
    0.5 * h * sum
}

/// The energy barrier between two neighbouring stable equilibria.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Barrier {
    /// The stable equilibrium on the left.
    pub left: f64,
    /// The stable equilibrium on the right.
    pub right: f64,
    /// The unstable equilibrium between them with the highest potential.
    pub saddle: f64,
    /// `V(saddle) − V(left)`: energy needed to escape the left well to the right.
    pub height_left: f64,
    /// `V(saddle) − V(right)`: energy needed to escape the right well to the left.
    pub height_right: f64,
}

/// Barriers between each pair of neighbouring stable equilibria in `eq` under potential `V`.
/// Pairs with no unstable equilibrium between them are skipped.
///
/// ```
/// use tfs_dynamics::{barriers, equilibria};
/// // Double well V = x⁴/4 − x²/2, F = x³ − x: wells at ±1, saddle at 0, barrier 1/4.
/// let eq = equilibria(|x| x * x * x - x, -2.0, 2.0, 401).unwrap();
/// let b = barriers(|x| 0.25 * x.powi(4) - 0.5 * x * x, &eq);
/// assert_eq!(b.len(), 1);
/// assert!((b[0].height_left - 0.25).abs() < 1e-12);
/// ```
pub fn barriers(potential: impl Fn(f64) -> f64, eq: &[Equilibrium]) -> Vec<Barrier> {
    let mut sorted = eq.to_vec();
    sorted.sort_by(|a, b| a.x.total_cmp(&b.x));
    let stable: Vec<usize> = (0..sorted.len()).filter(|&i| sorted[i].stable).collect();
    let mut out = Vec::new();
    for w in stable.windows(2) {
        let (i, j) = (w[0], w[1]);
        let saddle = sorted[i + 1..j]
            .iter()
            .filter(|e| !e.stable)
            .map(|e| (e.x, potential(e.x)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((xs, vs)) = saddle {
            out.push(Barrier {
                left: sorted[i].x,
                right: sorted[j].x,
                saddle: xs,
                height_left: vs - potential(sorted[i].x),
                height_right: vs - potential(sorted[j].x),
            });
        }
    }
    out
}
