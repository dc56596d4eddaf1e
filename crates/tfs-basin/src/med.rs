//! Minimum-energy deployment (paper Eq. 17): the least input energy
//! `E_in = ½ m v0² + V(x0) − V(x_S1)` over starts that end in S2, found on the basin boundary.
//!
//! Method: scan the map for cells labelled S2 next to cells labelled S1 (admissible starts only:
//! for S-DOF, `x0` inside S1's well); take the lowest-energy ones; for each, locate the boundary
//! along rays from S1 (in axis-scaled coordinates) by bisection between an S1-ending and an
//! S2-ending start, and minimise the boundary energy over the ray angle by golden-section
//! search around the cell's angle. The best boundary point evaluated is returned (its S2 side).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tfs_dynamics::SecondOrderSystem;

use crate::chain::{ChainWells, Slice, check_chain, classify_chain};
use crate::error::{BasinError, Result, invalid};
use crate::grid::{BasinConfig, BasinMap, Label, classify_sdof};
use crate::wells::WellInfo;

/// Number of lowest-energy boundary cells refined.
const CANDIDATES: usize = 6;
/// Golden-section iterations per candidate.
const GOLDEN_ITERS: usize = 24;
/// Bisection iterations along a ray.
const BISECT_ITERS: usize = 48;

/// The minimum-energy deployment of a 1-DOF system.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Med {
    /// Initial displacement of the MED start (on the S2 side of the boundary).
    pub x0: f64,
    /// Initial velocity of the MED start.
    pub v0: f64,
    /// `E_in = ½ m v0² + V(x0) − V(x_S1)`.
    pub energy: f64,
    /// Kinetic part `½ m v0²`.
    pub kinetic: f64,
    /// Potential part `V(x0) − V(x_S1)`.
    pub potential: f64,
    /// Quasi-static barrier `V(x_u) − V(x_S1)` between the two states.
    pub quasi_static_barrier: f64,
}

/// The minimum-energy deployment of a chain on a slice.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChainMed {
    /// First slice coordinate of the MED start (e.g. Δx).
    pub c0: f64,
    /// Second slice coordinate (e.g. v0).
    pub c1: f64,
    /// Initial displacements.
    pub x: Vec<f64>,
    /// Initial velocities.
    pub v: Vec<f64>,
    /// `E_in = Σ ½ m_i v_i² + V(x) − V(S1)`.
    pub energy: f64,
    /// Lowest saddle energy minus `V(S1)`, when the caller gave the saddle energy.
    pub quasi_static_barrier: Option<f64>,
}

/// A 2-D plane of starts with a classifier and an energy.
struct Plane<'a> {
    classify: &'a (dyn Fn(f64, f64) -> Label + Sync),
    energy: &'a (dyn Fn(f64, f64) -> f64 + Sync),
    admissible: &'a (dyn Fn(f64, f64) -> bool + Sync),
    origin: (f64, f64),
    scale: (f64, f64),
    bounds: ((f64, f64), (f64, f64)),
    step: f64,
    from: usize,
    to: usize,
}

/// A boundary point: the S2-side start and its energy.
#[derive(Debug, Clone, Copy)]
struct Hit {
    p: (f64, f64),
    energy: f64,
}

/// Keeps `h` if it is finite and strictly lower than the best so far (so the first of equal
/// hits stays).
fn keep(h: Option<Hit>, best: &mut Option<Hit>) {
    if let Some(h) = h {
        if h.energy.is_finite() && best.is_none_or(|b| h.energy < b.energy) {
            *best = Some(h);
        }
    }
}

impl Plane<'_> {
    fn point(&self, theta: f64, r: f64) -> (f64, f64) {
        (
            self.origin.0 + r * theta.cos() * self.scale.0,
            self.origin.1 + r * theta.sin() * self.scale.1,
        )
    }
    fn usable(&self, p: (f64, f64)) -> bool {
        let ((x0, x1), (y0, y1)) = self.bounds;
        p.0 >= x0 && p.0 <= x1 && p.1 >= y0 && p.1 <= y1 && (self.admissible)(p.0, p.1)
    }
    fn is(&self, p: (f64, f64), k: usize) -> bool {
        (self.classify)(p.0, p.1) == Label::State(k)
    }

    /// First from→to crossing along the ray at `theta`, searching outward from near `r_guess`.
    fn boundary(&self, theta: f64, r_guess: f64) -> Option<Hit> {
        // Find a radius ending in `from` at or below the guess.
        let mut back = 4.0 * self.step;
        let mut r_lo = loop {
            let r = (r_guess - back).max(0.0);
            let p = self.point(theta, r);
            if r == 0.0 || (self.usable(p) && self.is(p, self.from)) {
                break r;
            }
            back *= 2.0;
        };
        // March outward until the start ends in `to`.
        let mut r = r_lo;
        let r_hi = loop {
            r += self.step;
            let p = self.point(theta, r);
            if !self.usable(p) {
                return None;
            }
            match (self.classify)(p.0, p.1) {
                Label::State(k) if k == self.to => break r,
                Label::State(k) if k == self.from => r_lo = r,
                _ => {}
            }
        };
        let mut hi = r_hi;
        for _ in 0..BISECT_ITERS {
            let mid = 0.5 * (r_lo + hi);
            let p = self.point(theta, mid);
            if self.usable(p) && self.is(p, self.to) {
                hi = mid;
            } else {
                r_lo = mid;
            }
        }
        let p = self.point(theta, hi);
        Some(Hit {
            p,
            energy: (self.energy)(p.0, p.1),
        })
    }

    /// The lowest boundary hit of one candidate cell at `p`: golden-section search over the
    /// ray angle around the cell's, each angle's boundary found by bisection.
    fn refine_candidate(&self, p: (f64, f64)) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let (sx, sy) = (
            (p.0 - self.origin.0) / self.scale.0,
            (p.1 - self.origin.1) / self.scale.1,
        );
        let r0 = sx.hypot(sy);
        if r0 == 0.0 {
            return None;
        }
        let theta0 = sy.atan2(sx);
        let half = (3.0 * self.step / r0).min(0.5);
        let eval = |theta: f64, best: &mut Option<Hit>| -> f64 {
            let h = self.boundary(theta, r0);
            keep(h, best);
            h.map_or(f64::INFINITY, |h| h.energy)
        };
        let _ = eval(theta0, &mut best);
        // Golden-section search on [theta0 - half, theta0 + half].
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let (mut a, mut b) = (theta0 - half, theta0 + half);
        let mut c = b - g * (b - a);
        let mut d = a + g * (b - a);
        let mut fc = eval(c, &mut best);
        let mut fd = eval(d, &mut best);
        for _ in 0..GOLDEN_ITERS {
            if fc <= fd {
                b = d;
                d = c;
                fd = fc;
                c = b - g * (b - a);
                fc = eval(c, &mut best);
            } else {
                a = c;
                c = d;
                fc = fd;
                d = a + g * (b - a);
                fd = eval(d, &mut best);
            }
        }
        best
    }

    fn search(&self, map: &BasinMap) -> Result<Hit> {
        // Boundary cells: `to` cells (admissible) with a `from` 4-neighbour.
        let (nx, ny) = (map.nx, map.ny);
        let mut cells = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                if map.label(i, j) != Label::State(self.to) {
                    continue;
                }
                let p = (map.x_at(i), map.y_at(j));
                if !(self.admissible)(p.0, p.1) {
                    continue;
                }
                let near_from = [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
                    .iter()
                    .any(|&(di, dj)| {
                        let (a, b) = (i as i64 + di, j as i64 + dj);
                        a >= 0
                            && b >= 0
                            && (a as usize) < nx
                            && (b as usize) < ny
                            && map.label(a as usize, b as usize) == Label::State(self.from)
                    });
                if near_from {
                    cells.push(((self.energy)(p.0, p.1), p));
                }
            }
        }
        if cells.is_empty() {
            return Err(BasinError::NoBoundary {
                from: self.from,
                to: self.to,
            });
        }
        cells.sort_by(|a, b| a.0.total_cmp(&b.0));
        // The candidates are independent searches: run them in parallel and keep, in candidate
        // order, the first lowest hit (what one search after the other would keep).
        let per_candidate: Vec<Option<Hit>> = cells
            .iter()
            .take(CANDIDATES)
            .collect::<Vec<_>>()
            .par_iter()
            .map(|&&(_, p)| self.refine_candidate(p))
            .collect();
        let mut best: Option<Hit> = None;
        for h in per_candidate {
            keep(h, &mut best);
        }
        best.ok_or(BasinError::NoBoundary {
            from: self.from,
            to: self.to,
        })
    }
}

fn check_map_states(map: &BasinMap, n: usize, from: usize, to: usize) -> Result<()> {
    if map.states.len() != n {
        return Err(invalid(
            "map",
            format!(
                "the map has {} stable states but the wells have {n}; compute the map from the same model",
                map.states.len()
            ),
        ));
    }
    if from == to {
        return Err(invalid("to", "must differ from `from`"));
    }
    Ok(())
}

/// Minimum-energy deployment from stable state `from` (S1) to `to` (S2) of a 1-DOF system.
///
/// `map` must be the basin map of `sys` (its grid bounds the search); `cfg` supplies `dt`,
/// `t_max` and `early_exit` for the refining runs. Starts are restricted to `x0` inside S1's
/// well. Since energy never increases, the result is never below the quasi-static barrier; it
/// approaches it when the grid reaches the unstable equilibrium (a pure displacement input).
pub fn med_sdof<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &WellInfo,
    map: &BasinMap,
    cfg: &BasinConfig,
    from: usize,
    to: usize,
) -> Result<Med> {
    cfg.validate()?;
    wells.check_index("from", from)?;
    wells.check_index("to", to)?;
    check_map_states(map, wells.stable().len(), from, to)?;
    let barrier = wells.quasi_static_barrier(from, to)?;
    let s1 = wells.stable()[from];
    let v_s1 = wells.potential(s1);
    let classify = |x: f64, v: f64| classify_sdof(sys, wells, x, v, cfg);
    let energy = |x: f64, v: f64| wells.energy(x, v) - v_s1;
    let admissible = |x: f64, _v: f64| wells.well_of(x) == Some(from);
    let plane = Plane {
        classify: &classify,
        energy: &energy,
        admissible: &admissible,
        origin: (s1, 0.0),
        scale: (map.x_range.1 - map.x_range.0, map.y_range.1 - map.y_range.0),
        bounds: (map.x_range, map.y_range),
        step: 0.5 / (map.nx.max(map.ny) - 1) as f64,
        from,
        to,
    };
    let hit = plane.search(map)?;
    let (x0, v0) = hit.p;
    let kinetic = 0.5 * wells.mass() * v0 * v0;
    Ok(Med {
        x0,
        v0,
        energy: hit.energy,
        kinetic,
        potential: wells.potential(x0) - v_s1,
        quasi_static_barrier: barrier,
    })
}

/// Minimum-energy deployment of a chain on `slice` (whose base should be S1 = `from`, as in
/// [`Slice::paper`]): rays start at slice coordinates `(0, 0)`; every start in the map's box is
/// admissible. `E_in = Σ ½ m_i v_i² + V(x) − V(S1)`.
pub fn med_chain<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &ChainWells,
    slice: &Slice,
    map: &BasinMap,
    cfg: &BasinConfig,
    from: usize,
    to: usize,
) -> Result<ChainMed> {
    cfg.validate()?;
    check_chain(sys, wells, slice)?;
    let n_states = wells.stable().len();
    for (name, k) in [("from", from), ("to", to)] {
        if k >= n_states {
            return Err(invalid(
                name,
                format!(
                    "state index {k} (S{}) out of range: there are {n_states} stable states, S1..S{n_states} (indices 0..{})",
                    k + 1,
                    n_states.saturating_sub(1)
                ),
            ));
        }
    }
    check_map_states(map, n_states, from, to)?;
    let v_s1 = wells.potential(&wells.stable()[from]);
    let classify = |c0: f64, c1: f64| {
        let (x, v) = slice.state(c0, c1);
        classify_chain(sys, wells, &x, &v, cfg)
    };
    let energy = |c0: f64, c1: f64| {
        let (x, v) = slice.state(c0, c1);
        wells.energy(&x, &v) - v_s1
    };
    let admissible = |_: f64, _: f64| true;
    let plane = Plane {
        classify: &classify,
        energy: &energy,
        admissible: &admissible,
        origin: (0.0, 0.0),
        scale: (map.x_range.1 - map.x_range.0, map.y_range.1 - map.y_range.0),
        bounds: (map.x_range, map.y_range),
        step: 0.5 / (map.nx.max(map.ny) - 1) as f64,
        from,
        to,
    };
    let hit = plane.search(map)?;
    let (x, v) = slice.state(hit.p.0, hit.p.1);
    Ok(ChainMed {
        c0: hit.p.0,
        c1: hit.p.1,
        x,
        v,
        energy: hit.energy,
        quasi_static_barrier: wells.saddle_energy().map(|b| b - v_s1),
    })
}
