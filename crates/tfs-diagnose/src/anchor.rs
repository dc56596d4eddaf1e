//! Refitting an equation with an added effect toward the start model.
//!
//! The equation-error least squares of all columns at once (the "free" fit) re-estimates the
//! model's own terms on the smoothed states as well: where they are nearly collinear with each
//! other or with the added column (neighbouring powers of a displacement that stays on one side
//! of zero; a damper beside a friction law), noise and the smoothing move them along the
//! collinear direction, which costs little equation error inside the records' range and
//! changes the force a lot outside it. The start model's coefficients came from a fit that
//! already weighed that (the identification's own criteria), and its free runs were checked. So
//! the refit also considers the *held* fit — the model's own terms at their start values, only
//! the new columns estimated on what they leave — and fits in between, ridge-regularised
//! toward the start values (each deviation weighted by its column's norm, so the penalty does
//! not depend on units), and keeps the one that simulates the fit records best.

use faer::Mat;
use tfs_library::Model;
use tfs_regress::{Compressed, LeastSquares, Regressor};

use crate::Result;
use crate::effects::EffectColumn;

/// The relative ridge weights between the held and the free fits: a deviation `δ_j` from the
/// start value of column `j` costs `λ·‖a_j‖²·δ_j²`, equation error's own cost of moving the
/// column's force by that much when the columns are orthogonal. A decade apart, from a penalty
/// that barely restrains a well-determined column to one that holds even weakly collinear
/// ones.
pub const RIDGE: [f64; 4] = [1e-3, 1e-2, 1e-1, 1.0];

/// One way of refitting: how far the model's own terms may leave their start values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Anchor {
    /// The model's own terms at their start values; only the new columns are estimated.
    Held,
    /// Ridge toward the start values with relative weight λ ([`RIDGE`]).
    Ridge(f64),
    /// Every column estimated freely (plain least squares).
    Free,
}

impl Anchor {
    /// Every anchor, from the most held to the free fit.
    pub fn all() -> Vec<Anchor> {
        let mut v = vec![Anchor::Held];
        v.extend(RIDGE.iter().rev().map(|&l| Anchor::Ridge(l)));
        v.push(Anchor::Free);
        v
    }

    /// A short label for the history's details.
    pub fn label(&self) -> String {
        match self {
            Anchor::Held => "held".into(),
            Anchor::Ridge(l) => format!("ridge {l:e}"),
            Anchor::Free => "free".into(),
        }
    }
}

/// Per column of `cols`, the start value when it is one of the model's own terms of DOF `idx`
/// as it stands (a plain term, not computed, not centred), else `None` (a new column).
pub(crate) fn start_values(model: &Model, idx: usize, cols: &[EffectColumn]) -> Vec<Option<f64>> {
    cols.iter()
        .map(|c| {
            if c.computed.is_some() || c.centre.is_some() {
                return None;
            }
            model.equations[idx]
                .terms
                .iter()
                .find(|t| t.term == c.term)
                .map(|t| t.coef)
        })
        .collect()
}

/// The coefficients of the merged compressed problem `p` under `anchor`, with `start` from
/// [`start_values`]. A column without a start value is always free; without any start value
/// every anchor is the free fit.
pub(crate) fn fit(p: &Compressed, start: &[Option<f64>], anchor: Anchor) -> Result<Vec<f64>> {
    let n = p.ncols();
    let free_fit = || -> Result<Vec<f64>> { Ok(LeastSquares.fit_compressed(p)?.coef) };
    if start.iter().all(Option::is_none) || anchor == Anchor::Free {
        return free_fit();
    }
    let r = p.r();
    let c = p.c();
    match anchor {
        Anchor::Held => {
            let free: Vec<usize> = (0..n).filter(|&j| start[j].is_none()).collect();
            let mut coef: Vec<f64> = start.iter().map(|s| s.unwrap_or(0.0)).collect();
            if free.is_empty() {
                return Ok(coef);
            }
            // ‖R x − c‖ with the held columns moved to the target.
            let target: Vec<f64> = (0..n)
                .map(|i| {
                    c[i] - (0..n)
                        .filter_map(|j| start[j].map(|s| r[(i, j)] * s))
                        .sum::<f64>()
                })
                .collect();
            let a = Mat::from_fn(n, free.len(), |i, k| r[(i, free[k])]);
            let sub = LeastSquares.fit_compressed(&Compressed::from_rows(a.as_ref(), &target)?)?;
            for (k, &j) in free.iter().enumerate() {
                coef[j] = sub.coef[k];
            }
            Ok(coef)
        }
        Anchor::Ridge(lambda) => {
            let norms = p.column_norms();
            let held: Vec<usize> = (0..n).filter(|&j| start[j].is_some()).collect();
            let rows = n + held.len();
            let mut a = Mat::<f64>::zeros(rows, n);
            let mut b = vec![0.0; rows];
            for i in 0..n {
                for j in i..n {
                    a[(i, j)] = r[(i, j)];
                }
                b[i] = c[i];
            }
            for (k, &j) in held.iter().enumerate() {
                let w = lambda.sqrt() * norms[j];
                a[(n + k, j)] = w;
                b[n + k] = w * start[j].unwrap_or(0.0);
            }
            Ok(LeastSquares
                .fit_compressed(&Compressed::from_rows(a.as_ref(), &b)?)?
                .coef)
        }
        Anchor::Free => free_fit(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two nearly collinear columns and a new one: the held fit keeps the start values and
    /// fits the new column on what they leave; the ridge fits move from the held fit toward
    /// the free fit as λ falls; the free fit is plain least squares.
    #[test]
    fn anchors_run_from_the_start_values_to_least_squares() {
        let n = 200;
        let x: Vec<f64> = (0..n).map(|i| 1.0 + i as f64 / n as f64).collect();
        let noise = |i: usize| ((i * 7919 % 101) as f64 / 101.0 - 0.5) * 1e-3;
        let a = Mat::from_fn(n, 3, |i, j| match j {
            0 => x[i].powi(5),
            1 => x[i].powi(6),
            _ => (i as f64 * 0.3).sin(),
        });
        let b: Vec<f64> = (0..n)
            .map(|i| -2.0 * a[(i, 0)] + 1.0 * a[(i, 1)] + 0.5 * a[(i, 2)] + noise(i))
            .collect();
        let p = Compressed::from_rows(a.as_ref(), &b).unwrap();
        let start = [Some(-2.1), Some(1.05), None];
        let held = fit(&p, &start, Anchor::Held).unwrap();
        assert_eq!(&held[..2], &[-2.1, 1.05]);
        let free = fit(&p, &start, Anchor::Free).unwrap();
        assert!(
            (free[0] + 2.0).abs() < 0.05 && (free[2] - 0.5).abs() < 1e-2,
            "{free:?}"
        );
        let mut last = 0.0;
        for l in RIDGE.iter().rev() {
            let r = fit(&p, &start, Anchor::Ridge(*l)).unwrap();
            let d = (r[0] + 2.1).abs();
            assert!(d >= last - 1e-12, "λ {l}: {r:?}");
            last = d;
        }
        let no_start = fit(&p, &[None, None, None], Anchor::Held).unwrap();
        assert_eq!(no_start, free);
    }
}
