//! BOA error between two maps on the same grid, and the disagreement mask for plots.

use serde::{Deserialize, Serialize};

use crate::error::{BasinError, Result};
use crate::grid::BasinMap;

/// Cell-by-cell comparison of two basin maps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoaComparison {
    /// Share of cells whose labels differ (see [`boa_error`] for how unsettled cells count).
    pub error: f64,
    /// `true` where the labels differ, row-major like [`BasinMap::labels`].
    pub disagree: Vec<bool>,
    /// Nodes along the first axis.
    pub nx: usize,
    /// Nodes along the second axis.
    pub ny: usize,
}

fn same_range(a: (f64, f64), b: (f64, f64)) -> bool {
    let tol = 1e-12 * (a.0.abs() + a.1.abs() + 1.0);
    (a.0 - b.0).abs() <= tol && (a.1 - b.1).abs() <= tol
}

/// Compares `a` and `b` node by node. Fails if the grids differ (size or ranges).
pub fn compare(a: &BasinMap, b: &BasinMap) -> Result<BoaComparison> {
    if (a.nx, a.ny) != (b.nx, b.ny) || a.labels.len() != b.labels.len() {
        return Err(BasinError::MapMismatch {
            what: "grid size",
            a: format!("{}×{}", a.nx, a.ny),
            b: format!("{}×{}", b.nx, b.ny),
        });
    }
    if !same_range(a.x_range, b.x_range) || !same_range(a.y_range, b.y_range) {
        return Err(BasinError::MapMismatch {
            what: "grid ranges",
            a: format!("{:?} × {:?}", a.x_range, a.y_range),
            b: format!("{:?} × {:?}", b.x_range, b.y_range),
        });
    }
    let disagree: Vec<bool> = a
        .labels
        .iter()
        .zip(&b.labels)
        .map(|(p, q)| p != q)
        .collect();
    let wrong = disagree.iter().filter(|&&d| d).count();
    Ok(BoaComparison {
        error: wrong as f64 / disagree.len() as f64,
        disagree,
        nx: a.nx,
        ny: a.ny,
    })
}

/// BOA error: the share of grid cells labelled differently in `a` and `b`.
///
/// Unsettled and diverged cells are labels like any other: a cell unsettled in one map and
/// settled in the other counts as a disagreement; unsettled in both counts as agreement. State
/// indices are compared as-is, so both maps must number their stable states the same way
/// (true when both come from wells sorted by position with the same count).
pub fn boa_error(a: &BasinMap, b: &BasinMap) -> Result<f64> {
    Ok(compare(a, b)?.error)
}
