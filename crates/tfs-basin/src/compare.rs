//! BOA error between two maps on the same grid, and the disagreement mask for plots.

use serde::{Deserialize, Serialize};

use crate::error::{BasinError, Result};
use crate::grid::{BasinMap, Label};

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

/// `map` with each of its stable states counted as the nearest of `states` (Euclidean distance
/// over the coordinates), for comparing a model whose stable states differ in number from the
/// truth's: a spurious shallow well inside one of the truth's wells then counts as that well,
/// which is what the map is read for (where a start ends up), instead of shifting every later
/// index. Returns the renamed map (its `states` are `states`, shares recounted) and, for each of
/// the map's own states, the index it was given. Unsettled and diverged cells stay as they are.
pub fn relabel_to_nearest(map: &BasinMap, states: &[Vec<f64>]) -> (BasinMap, Vec<usize>) {
    let dist = |a: &[f64], b: &[f64]| -> f64 {
        a.iter().zip(b).map(|(p, q)| (p - q).powi(2)).sum::<f64>()
    };
    let to: Vec<usize> = map
        .states
        .iter()
        .map(|s| {
            (0..states.len())
                .min_by(|&i, &j| dist(s, &states[i]).total_cmp(&dist(s, &states[j])))
                .unwrap_or(0)
        })
        .collect();
    let mut out = map.clone();
    for l in &mut out.labels {
        if let Label::State(k) = *l
            && let Some(&t) = to.get(k)
        {
            *l = Label::State(t);
        }
    }
    out.states = states.to_vec();
    let n = out.labels.len().max(1) as f64;
    out.shares = (0..states.len())
        .map(|k| out.labels.iter().filter(|l| **l == Label::State(k)).count() as f64 / n)
        .collect();
    (out, to)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(labels: Vec<Label>, states: Vec<Vec<f64>>) -> BasinMap {
        let n = labels.len();
        BasinMap {
            labels,
            nx: n,
            ny: 1,
            x_range: (0.0, 1.0),
            y_range: (0.0, 1.0),
            x_name: "x0".into(),
            y_name: "v0".into(),
            shares: vec![0.0; states.len()],
            states,
            unsettled_count: 0,
            diverged_count: 0,
            seconds: 0.0,
            integrated: n,
        }
    }

    /// A model with a spurious well at 0.16 (inside the truth's folded well at 0): by index its
    /// map disagrees with the truth on most starts; counted by nearest state, only where a start
    /// really ends in the other well.
    #[test]
    fn an_extra_state_counts_as_the_truth_state_it_sits_by() {
        use Label::*;
        let model = map(
            vec![State(1), State(1), State(2), State(0), Unsettled, State(2)],
            vec![vec![-0.0002], vec![0.16], vec![1.574]],
        );
        let truth = map(
            vec![State(0), State(0), State(1), State(0), Unsettled, State(0)],
            vec![vec![0.0], vec![1.582]],
        );
        assert!((boa_error(&model, &truth).unwrap() - 4.0 / 6.0).abs() < 1e-12);
        let (renamed, to) = relabel_to_nearest(&model, &truth.states);
        assert_eq!(to, [0, 0, 1]);
        assert_eq!(
            renamed.labels,
            [State(0), State(0), State(1), State(0), Unsettled, State(1)]
        );
        assert_eq!(renamed.shares, [0.5, 2.0 / 6.0]);
        // Only the last start ends in another well than the truth's.
        let e = boa_error(&renamed, &truth).unwrap();
        assert!((e - 1.0 / 6.0).abs() < 1e-12, "{e}");
    }
}
