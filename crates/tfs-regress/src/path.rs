//! A threshold (λ) path for STLSQ with model selection on held-out rows.

use crate::compress::Compressed;
use crate::error::{RegressError, Result, check_param};
use crate::stlsq::Stlsq;
use std::collections::HashMap;

/// How to score a model on held-out rows. With `m_val` validation rows, `k` non-zero terms
/// and `RSS_val` the validation residual sum of squares, the information criteria are
/// `m_val·ln(RSS_val/m_val) + penalty(k)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InfoCriterion {
    /// penalty `2k`.
    Aic,
    /// penalty `2k + 2k(k+1)/(m_val − k − 1)` (+∞ when `m_val ≤ k + 1`).
    #[default]
    Aicc,
    /// penalty `k·ln(m_val)`.
    Bic,
    /// Plain validation RSS (no penalty).
    ValidationRss,
}

impl InfoCriterion {
    /// The criterion value. `rss_val` is floored at the smallest positive normal `f64` so an
    /// exact fit gives a large negative finite value rather than −∞.
    pub fn score(self, rss_val: f64, m_val: usize, k: usize) -> f64 {
        let m = m_val as f64;
        let kf = k as f64;
        let fit = || m * (rss_val.max(f64::MIN_POSITIVE) / m).ln();
        match self {
            Self::Aic => fit() + 2.0 * kf,
            Self::Bic => fit() + kf * m.ln(),
            Self::Aicc => {
                if m_val <= k + 1 {
                    f64::INFINITY
                } else {
                    fit() + 2.0 * kf + 2.0 * kf * (kf + 1.0) / (m - kf - 1.0)
                }
            }
            Self::ValidationRss => rss_val,
        }
    }
}

/// Options of [`lambda_path`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathOptions {
    /// STLSQ settings; its `threshold` is replaced by each grid value and its refit is
    /// always unbiased on the path.
    pub stlsq: Stlsq,
    /// Number of thresholds in the geometric grid (≥ 1).
    pub n_thresholds: usize,
    /// Smallest threshold as a fraction of the largest, in (0, 1].
    pub min_ratio: f64,
    /// Selection rule.
    pub criterion: InfoCriterion,
    /// With scaled columns, when the largest scaled coefficient exceeds 1 (columns that cancel
    /// one another), go on with the same step down to `min_ratio` itself (see
    /// [`lambda_path`]). Off by default: the plain grid of the SINDy literature.
    pub extend_when_cancelling: bool,
}

impl Default for PathOptions {
    /// Default STLSQ, 40 thresholds down to 1e-4 of the largest, AICc, no extension.
    fn default() -> Self {
        Self {
            stlsq: Stlsq::default(),
            n_thresholds: 40,
            min_ratio: 1e-4,
            criterion: InfoCriterion::Aicc,
            extend_when_cancelling: false,
        }
    }
}

/// One point of the path.
#[derive(Debug, Clone, PartialEq)]
pub struct PathPoint {
    /// Threshold used (scaled units when `stlsq.scale_columns`).
    pub threshold: f64,
    /// Support found by STLSQ at this threshold.
    pub support: Vec<bool>,
    /// Unbiased least-squares coefficients on that support, original units.
    pub coef: Vec<f64>,
    /// Number of terms.
    pub n_terms: usize,
    /// Training RSS.
    pub rss_train: f64,
    /// Validation RSS.
    pub rss_val: f64,
    /// Criterion value on the validation rows.
    pub criterion: f64,
}

/// The whole path and the chosen point.
#[derive(Debug, Clone, PartialEq)]
pub struct LambdaPath {
    /// Points from the largest threshold down.
    pub points: Vec<PathPoint>,
    /// Index into `points` of the selected model (lowest criterion; ties go to fewer terms,
    /// then to the larger threshold).
    pub selected: usize,
    /// The criterion used.
    pub criterion: InfoCriterion,
    /// Rows in the validation set.
    pub m_val: usize,
}

impl LambdaPath {
    /// The selected point.
    pub fn best(&self) -> &PathPoint {
        &self.points[self.selected]
    }
}

/// Run STLSQ over a geometric grid of thresholds from the largest |scaled coefficient| of the
/// initial fit down to `min_ratio` times it; refit each distinct support by least squares on
/// `train` and score it on the held-out `val` rows (also compressed). Returns every point.
///
/// **Cancelling columns.** A scaled coefficient is the share of the target's norm its term
/// carries, so a largest one above 1 means columns that cancel one another (monomials of a
/// coordinate that moves little about a large offset reach shares of 10⁹). A grid anchored there
/// would stop far above the terms that carry a tenth of the target (a dashpot, the input) and
/// prune them at every point. With `extend_when_cancelling` and scaled columns the grid then
/// continues with the same geometric step until the threshold falls below `min_ratio` itself
/// (for at most `8·(n_thresholds − 1)` more points); below a largest share of 1 it is the
/// plain `n_thresholds`-point grid.
pub fn lambda_path(train: &Compressed, val: &Compressed, opts: &PathOptions) -> Result<LambdaPath> {
    if opts.n_thresholds == 0 {
        return Err(RegressError::InvalidParameter {
            name: "PathOptions.n_thresholds",
            value: "0".into(),
            reason: "must be at least 1",
        });
    }
    check_param(
        "PathOptions.min_ratio",
        opts.min_ratio,
        opts.min_ratio > 0.0 && opts.min_ratio <= 1.0,
        "must be in (0, 1]",
    )?;
    if val.ncols() != train.ncols() {
        return Err(RegressError::DimensionMismatch {
            what: "columns of validation set vs training set".into(),
            expected: train.ncols(),
            found: val.ncols(),
        });
    }
    if val.nrows() == 0 {
        return Err(RegressError::Empty {
            what: "validation set has no rows; hold out some rows (e.g. a record or window)",
        });
    }
    let base = Stlsq {
        unbiased_refit: true,
        ..opts.stlsq
    };
    let init = base.initial_scaled_coef(train);
    let top = init.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    if top == 0.0 {
        return Err(RegressError::Empty {
            what: "initial fit is identically zero (b = 0 or A = 0); nothing to select",
        });
    }
    let nt = opts.n_thresholds;
    let mut seen: HashMap<Vec<bool>, (Vec<f64>, f64, f64)> = HashMap::new();
    let mut cache = crate::stlsq::SolveCache::new();
    let sc = crate::stlsq::scales(train, base.scale_columns);
    let mut grid = Vec::with_capacity(nt);
    for i in 0..nt {
        let frac = if nt == 1 {
            0.0
        } else {
            i as f64 / (nt - 1) as f64
        };
        grid.push(top * opts.min_ratio.powf(frac));
    }
    // Cancelling columns (largest share above 1): go on with the same step down to
    // `min_ratio` itself, at most 8 grids' worth of points (a share of 10³² on the default grid).
    if opts.extend_when_cancelling
        && base.scale_columns
        && nt > 1
        && opts.min_ratio < 1.0
        && top.is_finite()
    {
        for i in nt..nt + 8 * (nt - 1) {
            let threshold = top * opts.min_ratio.powf(i as f64 / (nt - 1) as f64);
            if threshold < opts.min_ratio {
                break;
            }
            grid.push(threshold);
        }
    }
    let mut points = Vec::with_capacity(grid.len());
    for threshold in grid {
        // With the unbiased refit, STLSQ's coefficients are the least-squares ones on its
        // support: the residuals are computed once per distinct support.
        let (coef, ..) = Stlsq { threshold, ..base }.coef_scaled(train, &mut cache, &sc)?;
        let support: Vec<bool> = coef.iter().map(|&v| v != 0.0).collect();
        let (coef, rss_train, rss_val) = match seen.get(&support) {
            Some(v) => v.clone(),
            None => {
                let v = (coef.clone(), train.rss(&coef)?, val.rss(&coef)?);
                seen.insert(support.clone(), v.clone());
                v
            }
        };
        let n_terms = support.iter().filter(|&&s| s).count();
        let criterion = opts.criterion.score(rss_val, val.nrows(), n_terms);
        points.push(PathPoint {
            threshold,
            support,
            coef,
            n_terms,
            rss_train,
            rss_val,
            criterion,
        });
    }
    let mut selected = 0;
    for (i, p) in points.iter().enumerate() {
        let b = &points[selected];
        if p.criterion < b.criterion || (p.criterion == b.criterion && p.n_terms < b.n_terms) {
            selected = i;
        }
    }
    Ok(LambdaPath {
        points,
        selected,
        criterion: opts.criterion,
        m_val: val.nrows(),
    })
}
