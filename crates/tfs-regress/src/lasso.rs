//! Lasso by cyclic coordinate descent on the Gram matrix of the compressed problem.

use crate::compress::Compressed;
use crate::error::{RegressError, Result, check_param};
use crate::fit::{Fit, Regressor};

/// Lasso: `min (1/(2m))‖Aξ − b‖² + λ‖ξ‖₁` in the raw column units (no intercept, no scaling;
/// scale columns beforehand if wanted). Solved by cyclic coordinate descent on
/// `G = RᵀR`, `q = Rᵀc`, so the cost per sweep is O(n²) regardless of `m`.
///
/// Converged when the largest coefficient change in one sweep, measured as its effect on the
/// fit `|Δξ_j|·‖A[:,j]‖`, is at most `tol·‖b‖`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lasso {
    /// Penalty λ ≥ 0.
    pub lambda: f64,
    /// Relative convergence tolerance (> 0).
    pub tol: f64,
    /// Maximum coordinate-descent sweeps (≥ 1).
    pub max_iter: usize,
}

impl Default for Lasso {
    /// λ = 0.01, tol 1e-12, 10 000 sweeps.
    fn default() -> Self {
        Self {
            lambda: 0.01,
            tol: 1e-12,
            max_iter: 10_000,
        }
    }
}

/// The smallest λ for which the lasso solution is all zeros: `max_j |a_jᵀb| / m`.
pub fn lasso_lambda_max(p: &Compressed) -> f64 {
    let (_, q) = p.gram();
    q.iter().fold(0.0_f64, |a, v| a.max(v.abs())) / p.nrows().max(1) as f64
}

fn soft(z: f64, t: f64) -> f64 {
    if z > t {
        z - t
    } else if z < -t {
        z + t
    } else {
        0.0
    }
}

impl Regressor for Lasso {
    fn fit_compressed(&self, p: &Compressed) -> Result<Fit> {
        check_param(
            "Lasso.lambda",
            self.lambda,
            self.lambda >= 0.0,
            "must be finite and >= 0",
        )?;
        check_param(
            "Lasso.tol",
            self.tol,
            self.tol > 0.0,
            "must be finite and > 0",
        )?;
        if self.max_iter == 0 {
            return Err(RegressError::InvalidParameter {
                name: "Lasso.max_iter",
                value: "0".into(),
                reason: "must be at least 1",
            });
        }
        if p.nrows() == 0 {
            return Err(RegressError::Empty {
                what: "lasso needs at least one row of data",
            });
        }
        let n = p.ncols();
        let m = p.nrows() as f64;
        let (g, q) = p.gram();
        let t = self.lambda * m;
        let stop = self.tol * p.b_norm2().sqrt();
        let mut x = vec![0.0; n];
        // grad_j = (Gx − q)_j maintained incrementally.
        let mut gx = vec![0.0; n];
        let mut converged = false;
        let mut iterations = 0;
        while iterations < self.max_iter {
            iterations += 1;
            let mut max_change = 0.0_f64;
            for j in 0..n {
                let gjj = g[(j, j)];
                if gjj <= 0.0 {
                    continue;
                }
                let zj = q[j] - (gx[j] - gjj * x[j]);
                let new = soft(zj, t) / gjj;
                let d = new - x[j];
                if d != 0.0 {
                    for k in 0..n {
                        gx[k] += g[(k, j)] * d;
                    }
                    x[j] = new;
                    max_change = max_change.max(d.abs() * gjj.sqrt());
                }
            }
            if max_change <= stop {
                converged = true;
                break;
            }
        }
        Fit::from_coef(p, x, Vec::new(), iterations, converged)
    }
}
