//! Sparse and dense linear regression on faer matrices: least squares, ridge, STLSQ, lasso,
//! threshold paths with held-out selection, and bagging.
//!
//! Architecture invariant: pure numerics — matrices in, vectors out; nothing here knows what
//! a column means.
//!
//! A tall problem `(A, b)` is compressed **once** into [`Compressed`] (a thin QR of `[A | b]`),
//! with `‖Aξ − b‖² = ‖Rξ − c‖² + rss0` for every `ξ`; every regressor, path and bootstrap then
//! works on the small `n×n` factor. Compressed blocks can be appended to and merged.
//!
//! Every regressor implements [`Regressor`] (`fit_compressed`, plus `fit(A, b)` on raw rows,
//! `A: faer::MatRef<f64>`, `b: &[f64]`) and returns a [`Fit`].
//!
//! ```
//! use faer::Mat;
//! use tfs_regress::{Compressed, Regressor, Stlsq};
//!
//! // b = 2·x − 0.5·x³ exactly, library {1, x, x², x³}.
//! let m = 50;
//! let a = Mat::from_fn(m, 4, |i, j| (-1.0 + 2.0 * i as f64 / (m - 1) as f64).powi(j as i32));
//! let b: Vec<f64> = (0..m).map(|i| 2.0 * a[(i, 1)] - 0.5 * a[(i, 3)]).collect();
//! let p = Compressed::from_rows(a.as_ref(), &b).unwrap();
//! let fit = Stlsq { threshold: 0.05, ..Stlsq::default() }.fit_compressed(&p).unwrap();
//! assert_eq!(fit.support, vec![false, true, false, true]);
//! assert!((fit.coef[1] - 2.0).abs() < 1e-10 && (fit.coef[3] + 0.5).abs() < 1e-10);
//! assert!(fit.rss < 1e-20);
//! ```

#![warn(missing_docs)]

mod absorb;
mod bagging;
mod compress;
mod error;
mod fit;
mod kernels;
mod lasso;
mod path;
mod stlsq;

pub use bagging::{BagOptions, BagSummary, bagging, bagging_with_total};
pub use compress::Compressed;
pub use error::{RegressError, Result};
pub use fit::{Fit, LeastSquares, Regressor, Ridge, lstsq, lstsq_support};
pub use lasso::{Lasso, lasso_lambda_max};
pub use path::{InfoCriterion, LambdaPath, PathOptions, PathPoint, lambda_path};
pub use stlsq::Stlsq;
