//! Base-excited dynamics of one cell and of serial chains of cells, as
//! [`tfs_dynamics::SecondOrderSystem`]s.
//!
//! Coordinates are displacements relative to the base (`x_0 ≡ 0`), `h_i = x_i − x_{i−1}`. Cell `i`
//! (mass `m_i` on its top, damping `c_i` on `h_i'`) pushes masses `i` and `i−1` apart; the base
//! acceleration `u[0] = xb_acc` enters every mass as `−xb_acc` (base frame):
//!
//! `x_i'' = −(c_i h_i' + F_i(h_i))/m_i + (c_{i+1} h_{i+1}' + F_{i+1}(h_{i+1}))/m_i − xb_acc`.

use serde::{Deserialize, Serialize};
use std::sync::Arc;
use tfs_dynamics::SecondOrderSystem;

use crate::cell::KreslingCell;
use crate::truth::{CellForce, Surrogate, SurrogateSpec, Truth};
use crate::{OrigamiError, Result};

/// One cell on a moving base: `x'' = −(c/m)x' − F(x)/m − xb_acc`, with `x = h`.
#[derive(Debug, Clone)]
pub struct CellSystem {
    force: CellForce,
    m: f64,
    c: f64,
}

impl CellSystem {
    /// The cell under `truth`, with the cell's own mass and damping (surrogate: default spec).
    pub fn new(cell: Arc<KreslingCell>, truth: Truth) -> Result<Self> {
        let (m, c) = (cell.params().m, cell.params().c);
        Ok(Self {
            force: CellForce::new(cell, truth)?,
            m,
            c,
        })
    }

    /// The cell with a surrogate fitted by `spec`.
    pub fn with_surrogate(cell: &KreslingCell, spec: &SurrogateSpec) -> Result<Self> {
        Ok(Self {
            force: CellForce::Surrogate(Surrogate::fit(cell, spec)?),
            m: cell.params().m,
            c: cell.params().c,
        })
    }

    /// A cell from an explicit force law, mass `m > 0` and damping `c ≥ 0`.
    pub fn from_force(force: CellForce, m: f64, c: f64) -> Result<Self> {
        if !(m.is_finite() && m > 0.0) {
            return Err(OrigamiError::Param(format!("'m' = {m} must be > 0")));
        }
        if !(c.is_finite() && c >= 0.0) {
            return Err(OrigamiError::Param(format!("'c' = {c} must be >= 0")));
        }
        Ok(Self { force, m, c })
    }

    /// The force law.
    pub fn force_law(&self) -> &CellForce {
        &self.force
    }

    /// Mass.
    pub fn mass(&self) -> f64 {
        self.m
    }

    /// Damping coefficient.
    pub fn damping(&self) -> f64 {
        self.c
    }

    /// Truth label (`"truss"` or e.g. `"surrogate{5,6,7}"`).
    pub fn truth_name(&self) -> String {
        self.force.label()
    }

    /// Total energy `½ m v² + V(x)` of the unforced cell.
    pub fn energy(&self, x: f64, v: f64) -> f64 {
        0.5 * self.m * v * v + self.force.potential(x)
    }
}

/// The per-mass acceleration shared by [`CellSystem`] and [`Chain`] (so a one-cell chain
/// reproduces a cell bit for bit).
#[inline]
fn mass_accel(own: (&CellSystem, f64, f64), above: Option<(&CellSystem, f64, f64)>, u: f64) -> f64 {
    let (cell, h, hv) = own;
    let mut a = -(cell.c / cell.m) * hv - cell.force.force(h) / cell.m;
    if let Some((up, h2, hv2)) = above {
        a += (up.c * hv2 + up.force.force(h2)) / cell.m;
    }
    a - u
}

impl SecondOrderSystem for CellSystem {
    fn dofs(&self) -> usize {
        1
    }
    fn inputs(&self) -> usize {
        1
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        a[0] = mass_accel((self, x[0], v[0]), None, u[0]);
    }
}

/// One equilibrium of a chain: each cell at one of its equilibria.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChainEquilibrium {
    /// Relative heights `h_i`.
    pub h: Vec<f64>,
    /// Displacements relative to the base `x_i = Σ_{j≤i} h_j`.
    pub x: Vec<f64>,
    /// True when every cell sits at a stable state (a stable equilibrium of the chain).
    pub stable: bool,
    /// Total potential `Σ V_i(h_i)`.
    pub potential: f64,
}

/// A serial chain of cells on a moving base (paper §3.2, Eq. 18), DOFs `x_1..x_N`.
#[derive(Debug, Clone)]
pub struct Chain {
    cells: Vec<CellSystem>,
}

impl Chain {
    /// A chain from the base upwards; needs at least one cell.
    pub fn new(cells: Vec<CellSystem>) -> Result<Self> {
        if cells.is_empty() {
            return Err(OrigamiError::Param(
                "a chain needs at least one cell".into(),
            ));
        }
        Ok(Self { cells })
    }

    /// The cells, base first.
    pub fn cells(&self) -> &[CellSystem] {
        &self.cells
    }

    /// Truth labels joined by commas, base cell first.
    pub fn truth_name(&self) -> String {
        let v: Vec<String> = self.cells.iter().map(|c| c.truth_name()).collect();
        v.join(",")
    }

    /// Relative heights `h_i = x_i − x_{i−1}`.
    pub fn relative(&self, x: &[f64]) -> Vec<f64> {
        (0..x.len())
            .map(|i| x[i] - if i == 0 { 0.0 } else { x[i - 1] })
            .collect()
    }

    /// Total energy `Σ ½ m_i v_i² + Σ V_i(h_i)` (absolute velocities in the base frame).
    pub fn energy(&self, x: &[f64], v: &[f64]) -> f64 {
        let h = self.relative(x);
        self.cells
            .iter()
            .enumerate()
            .map(|(i, c)| 0.5 * c.m * v[i] * v[i] + c.force.potential(h[i]))
            .sum()
    }

    /// Every equilibrium: the product of the cells' own equilibria (serial, no gravity, no
    /// external load: each cell carries zero force). Stable ones first.
    pub fn equilibria(&self) -> Vec<ChainEquilibrium> {
        let per: Vec<Vec<(f64, bool)>> = self
            .cells
            .iter()
            .map(|c| {
                let (s, u) = c.force.equilibria();
                let mut all: Vec<(f64, bool)> = s.into_iter().map(|h| (h, true)).collect();
                all.extend(u.into_iter().map(|h| (h, false)));
                all.sort_by(|a, b| a.0.total_cmp(&b.0));
                all
            })
            .collect();
        let mut out: Vec<ChainEquilibrium> = Vec::new();
        let mut idx = vec![0usize; per.len()];
        if per.iter().any(|p| p.is_empty()) {
            return out;
        }
        loop {
            let h: Vec<f64> = idx.iter().zip(&per).map(|(&k, p)| p[k].0).collect();
            let stable = idx.iter().zip(&per).all(|(&k, p)| p[k].1);
            let mut acc = 0.0;
            let x = h
                .iter()
                .map(|&hi| {
                    acc += hi;
                    acc
                })
                .collect();
            let potential = h
                .iter()
                .zip(&self.cells)
                .map(|(&hi, c)| c.force.potential(hi))
                .sum();
            out.push(ChainEquilibrium {
                h,
                x,
                stable,
                potential,
            });
            // Odometer increment.
            let mut d = 0;
            loop {
                if d == idx.len() {
                    out.sort_by_key(|e| !e.stable);
                    return out;
                }
                idx[d] += 1;
                if idx[d] < per[d].len() {
                    break;
                }
                idx[d] = 0;
                d += 1;
            }
        }
    }
}

impl SecondOrderSystem for Chain {
    fn dofs(&self) -> usize {
        self.cells.len()
    }
    fn inputs(&self) -> usize {
        1
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        let n = self.cells.len();
        let rel = |i: usize| -> (f64, f64) {
            if i == 0 {
                (x[0], v[0])
            } else {
                (x[i] - x[i - 1], v[i] - v[i - 1])
            }
        };
        let mut cur = rel(0);
        for (i, ai) in a.iter_mut().enumerate().take(n) {
            let above = (i + 1 < n).then(|| rel(i + 1));
            *ai = mass_accel(
                (&self.cells[i], cur.0, cur.1),
                above.map(|(h, hv)| (&self.cells[i + 1], h, hv)),
                u[0],
            );
            if let Some(next) = above {
                cur = next;
            }
        }
    }
}
