//! Bagging over row blocks: coefficient means, percentile intervals, inclusion probabilities.

use crate::compress::Compressed;
use crate::error::{RegressError, Result, check_param};
use crate::fit::Regressor;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Options of [`bagging`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BagOptions {
    /// Number of bootstrap resamples (≥ 2).
    pub n_boot: usize,
    /// Central interval level in (0, 1), e.g. 0.9 for the 5 %–95 % percentiles.
    pub level: f64,
    /// RNG seed; draw `i` uses ChaCha8 stream `i` of this seed, so results do not depend on
    /// the number of threads.
    pub seed: u64,
}

impl Default for BagOptions {
    /// 200 resamples, 90 % intervals, seed 0.
    fn default() -> Self {
        Self {
            n_boot: 200,
            level: 0.9,
            seed: 0,
        }
    }
}

/// Bagging summary per coefficient.
#[derive(Debug, Clone, PartialEq)]
pub struct BagSummary {
    /// Mean over resamples (zeros included).
    pub mean: Vec<f64>,
    /// Lower percentile `(1 − level)/2`.
    pub lower: Vec<f64>,
    /// Upper percentile `(1 + level)/2`.
    pub upper: Vec<f64>,
    /// Share of resamples in which the coefficient was in the support.
    pub inclusion: Vec<f64>,
    /// Every resample's coefficients (`draws[i][j]`).
    pub draws: Vec<Vec<f64>>,
    /// Interval level used.
    pub level: f64,
}

/// Linear-interpolation percentile of sorted data, `p` in [0, 1].
fn percentile(sorted: &[f64], p: f64) -> f64 {
    let pos = p * (sorted.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo as f64)
}

/// Resample `blocks` (e.g. one compressed problem per record or window) with replacement,
/// merge each resample exactly (a block drawn k times counts k times), fit with `regressor`
/// and summarise the coefficients. Runs the resamples in parallel with rayon.
pub fn bagging<R: Regressor + Sync + ?Sized>(
    blocks: &[Compressed],
    regressor: &R,
    opts: &BagOptions,
) -> Result<BagSummary> {
    if blocks.is_empty() {
        return Err(RegressError::Empty {
            what: "bagging needs at least 2 blocks (records or windows) to resample",
        });
    }
    bagging_with_total(blocks, &Compressed::merge(blocks)?, regressor, opts)
}

/// [`bagging`] when the merge of all `blocks` (`Compressed::merge(blocks)`) is already at hand:
/// the resamples are weighted sums in its coordinates, so it is not merged again.
///
/// Errors: as [`bagging`], and `total` with another column count than the blocks.
pub fn bagging_with_total<R: Regressor + Sync + ?Sized>(
    blocks: &[Compressed],
    total: &Compressed,
    regressor: &R,
    opts: &BagOptions,
) -> Result<BagSummary> {
    if blocks.len() < 2 {
        return Err(RegressError::Empty {
            what: "bagging needs at least 2 blocks (records or windows) to resample",
        });
    }
    if opts.n_boot < 2 {
        return Err(RegressError::InvalidParameter {
            name: "BagOptions.n_boot",
            value: opts.n_boot.to_string(),
            reason: "must be at least 2",
        });
    }
    check_param(
        "BagOptions.level",
        opts.level,
        opts.level > 0.0 && opts.level < 1.0,
        "must be in (0, 1)",
    )?;
    let nb = blocks.len();
    let merger = crate::compress::CountedMerge::with_total(blocks, total)?;
    let draws: Vec<Result<(Vec<f64>, Vec<bool>)>> = (0..opts.n_boot)
        .into_par_iter()
        .with_max_len(1)
        .map(|i| {
            let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
            rng.set_stream(i as u64);
            let mut counts = vec![0usize; nb];
            for _ in 0..nb {
                counts[rng.random_range(0..nb)] += 1;
            }
            let merged = merger.merge(&counts)?;
            let fit = regressor.fit_compressed(&merged)?;
            Ok((fit.coef, fit.support))
        })
        .collect();
    let draws: Vec<(Vec<f64>, Vec<bool>)> = draws.into_iter().collect::<Result<_>>()?;
    let n = blocks[0].ncols();
    let nbf = opts.n_boot as f64;
    let mut mean = vec![0.0; n];
    let mut lower = vec![0.0; n];
    let mut upper = vec![0.0; n];
    let mut inclusion = vec![0.0; n];
    for j in 0..n {
        let mut col: Vec<f64> = draws.iter().map(|d| d.0[j]).collect();
        mean[j] = col.iter().sum::<f64>() / nbf;
        inclusion[j] = draws.iter().filter(|d| d.1[j]).count() as f64 / nbf;
        col.sort_by(f64::total_cmp);
        lower[j] = percentile(&col, (1.0 - opts.level) / 2.0);
        upper[j] = percentile(&col, (1.0 + opts.level) / 2.0);
    }
    Ok(BagSummary {
        mean,
        lower,
        upper,
        inclusion,
        draws: draws.into_iter().map(|d| d.0).collect(),
        level: opts.level,
    })
}
