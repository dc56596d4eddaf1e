//! Sequentially thresholded least squares (STLSQ) with column scaling, ridge and unbiased refit.

use crate::compress::Compressed;
use crate::error::{RegressError, Result, check_param};
use crate::fit::{Fit, Regressor, subset_solve};
use std::collections::HashMap;

/// STLSQ: fit, zero every coefficient whose scaled magnitude is below `threshold`, refit on
/// the remaining columns, repeat until the support stops changing.
///
/// **Scaling.** With `scale_columns`, thresholding and the ridge penalty act on the problem
/// with unit-norm columns *and* unit-norm target: the scaled coefficient of column `j` is
/// `ξ_j·‖A[:,j]‖/‖b‖`, the share of the target's norm that term carries. Then `threshold`
/// and `ridge` are dimensionless and independent of the number of rows. Without scaling the
/// threshold compares `|ξ_j|` directly and `ridge` is in the units of `AᵀA`.
/// Coefficients are always reported in the original units.
///
/// **Unbiased refit.** With `unbiased_refit` the final coefficients are plain least squares
/// (no ridge) on the final support.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stlsq {
    /// Threshold on (scaled) coefficient magnitude, ≥ 0.
    pub threshold: f64,
    /// Ridge penalty used in the thresholding iterations, ≥ 0.
    pub ridge: f64,
    /// Maximum number of threshold/refit rounds (≥ 1).
    pub max_iter: usize,
    /// Scale columns (and target) to unit norm before thresholding.
    pub scale_columns: bool,
    /// Refit by plain least squares on the final support.
    pub unbiased_refit: bool,
}

impl Default for Stlsq {
    /// threshold 0.05, ridge 0, 20 iterations, scaling and unbiased refit on.
    fn default() -> Self {
        Self {
            threshold: 0.05,
            ridge: 0.0,
            max_iter: 20,
            scale_columns: true,
            unbiased_refit: true,
        }
    }
}

/// Per-column scales to go from the original problem to the scaled one: column `j` is
/// multiplied by `1/‖a_j‖` and `b` by `1/‖b‖` (all 1 when not scaling). A zero column gets
/// scale 0, which excludes it.
pub(crate) fn scales(p: &Compressed, scale_columns: bool) -> (Vec<f64>, f64) {
    if !scale_columns {
        return (vec![1.0; p.ncols()], 1.0);
    }
    let colscale = p
        .column_norms()
        .iter()
        .map(|&v| if v > 0.0 { 1.0 / v } else { 0.0 })
        .collect();
    let bn = p.b_norm2().sqrt();
    (colscale, if bn > 0.0 { 1.0 / bn } else { 1.0 })
}

impl Stlsq {
    fn validate(&self) -> Result<()> {
        check_param(
            "Stlsq.threshold",
            self.threshold,
            self.threshold >= 0.0,
            "must be finite and >= 0",
        )?;
        check_param(
            "Stlsq.ridge",
            self.ridge,
            self.ridge >= 0.0,
            "must be finite and >= 0",
        )?;
        if self.max_iter == 0 {
            return Err(RegressError::InvalidParameter {
                name: "Stlsq.max_iter",
                value: "0".into(),
                reason: "must be at least 1",
            });
        }
        Ok(())
    }

    /// The scaled coefficients of the first (all-column, ridge) fit, used to place a
    /// threshold grid. Zero columns get 0.
    pub fn initial_scaled_coef(&self, p: &Compressed) -> Vec<f64> {
        let (cs, bs) = scales(p, self.scale_columns);
        let cols: Vec<usize> = (0..p.ncols()).filter(|&j| cs[j] != 0.0).collect();
        subset_solve(p, &cols, &cs, bs, self.ridge).0
    }
}

/// Memo of subset solves keyed by (columns, ridge used): STLSQ on one problem at many thresholds
/// revisits the same supports (every threshold starts from the full one), so a λ path solves each
/// distinct support once. Supports of up to 128 columns are keyed by a bit mask and looked up
/// without allocating (a λ path makes thousands of look-ups).
#[derive(Default)]
pub(crate) struct SolveCache {
    index: HashMap<SupportKey, usize>,
    solves: Vec<(Vec<f64>, Vec<usize>)>,
}

/// A support (strictly increasing columns) and whether the solve used the ridge.
#[derive(Hash, PartialEq, Eq)]
enum SupportKey {
    Mask(u128, bool),
    Columns(Vec<usize>, bool),
}

impl SupportKey {
    fn new(cols: &[usize], ridge: bool) -> Self {
        if cols.iter().all(|&j| j < 128) {
            Self::Mask(cols.iter().fold(0u128, |m, &j| m | (1u128 << j)), ridge)
        } else {
            Self::Columns(cols.to_vec(), ridge)
        }
    }
}

impl SolveCache {
    /// An empty memo.
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// The memoised `solve(cols)` (computed on first use).
    fn get(
        &mut self,
        cols: &[usize],
        ridge: bool,
        solve: impl FnOnce() -> (Vec<f64>, Vec<usize>),
    ) -> &(Vec<f64>, Vec<usize>) {
        let key = SupportKey::new(cols, ridge);
        let i = match self.index.get(&key) {
            Some(&i) => i,
            None => {
                self.solves.push(solve());
                self.index.insert(key, self.solves.len() - 1);
                self.solves.len() - 1
            }
        };
        &self.solves[i]
    }
}

impl Stlsq {
    /// [`Regressor::fit_compressed`] with a memo of subset solves shared across calls on the same
    /// problem `p` (same scaling); results are identical to an uncached fit.
    pub(crate) fn fit_cached(&self, p: &Compressed, cache: &mut SolveCache) -> Result<Fit> {
        let (x, dependent, iterations, converged) = self.coef_cached(p, cache)?;
        Fit::from_coef(p, x, dependent, iterations, converged)
    }

    /// [`Stlsq::fit_cached`] without the residual: (coefficients in original units, dependent
    /// columns, iterations, converged). A λ path needs the residual only once per distinct
    /// support, not at every threshold.
    pub(crate) fn coef_cached(
        &self,
        p: &Compressed,
        cache: &mut SolveCache,
    ) -> Result<(Vec<f64>, Vec<usize>, usize, bool)> {
        self.coef_scaled(p, cache, &scales(p, self.scale_columns))
    }

    /// [`Stlsq::coef_cached`] with the column and target scales of `p` already computed
    /// ([`scales`] with this fit's `scale_columns`): a λ path computes them once, not at every
    /// threshold.
    pub(crate) fn coef_scaled(
        &self,
        p: &Compressed,
        cache: &mut SolveCache,
        (cs, bs): &(Vec<f64>, f64),
    ) -> Result<(Vec<f64>, Vec<usize>, usize, bool)> {
        self.validate()?;
        let n = p.ncols();
        let (cs, bs) = (cs.as_slice(), *bs);
        // The memoised solve on `cols` copied into `x`; returns its dependent columns (almost
        // always none: an empty `Vec` does not allocate).
        let solve = |cols: &[usize], ridge: f64, cache: &mut SolveCache, x: &mut [f64]| {
            let (xs, dep) = cache.get(cols, ridge > 0.0, || subset_solve(p, cols, cs, bs, ridge));
            x.copy_from_slice(xs);
            dep.clone()
        };
        let mut dependent: Vec<usize> = (0..n).filter(|&j| cs[j] == 0.0).collect();
        let mut cols: Vec<usize> = (0..n).filter(|&j| cs[j] != 0.0).collect();
        let mut x = vec![0.0; n];
        let mut converged = false;
        let mut iterations = 0;
        let mut keep = Vec::with_capacity(n);
        while iterations < self.max_iter {
            iterations += 1;
            let dep = solve(&cols, self.ridge, cache, &mut x);
            keep.clear();
            keep.extend(
                cols.iter()
                    .copied()
                    .filter(|&j| x[j].abs() >= self.threshold && !dep.contains(&j)),
            );
            for j in dep {
                if !dependent.contains(&j) {
                    dependent.push(j);
                }
            }
            if keep.len() == cols.len() {
                converged = true;
                break;
            }
            std::mem::swap(&mut cols, &mut keep);
        }
        if !converged {
            // Out of iterations: x is the fit on the support before the last thresholding.
            // Honour the threshold on the returned model by fitting on the last support.
            solve(&cols, self.ridge, cache, &mut x);
        }
        if self.unbiased_refit {
            for j in solve(&cols, 0.0, cache, &mut x) {
                if !dependent.contains(&j) {
                    dependent.push(j);
                }
            }
        }
        for j in 0..n {
            if !cols.contains(&j) {
                x[j] = 0.0;
            }
            // Back to original units: ξ_j = x_j · cs_j / bs.
            x[j] *= cs[j] / bs;
        }
        dependent.sort_unstable();
        Ok((x, dependent, iterations, converged))
    }
}

impl Regressor for Stlsq {
    fn fit_compressed(&self, p: &Compressed) -> Result<Fit> {
        self.fit_cached(p, &mut SolveCache::new())
    }
}
