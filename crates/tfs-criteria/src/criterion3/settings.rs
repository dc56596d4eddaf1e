//! Criterion 3's settings: the frequency-domain rows of every (window count, δ) compressed per
//! record, and each setting's mean held-out error with each record left out in turn; the setting
//! with the lowest is chosen.

use faer::Mat;
use rayon::prelude::*;
use tfs_regress::Compressed;

use super::Transforms;
use super::rows::{WindowTransform, rows_for_band};
use crate::error::Result;
use crate::fit::{fill_constant, held_out_relative_rss};
use crate::options::TfsOptions;
use crate::trace::SettingScore;

/// One block's frequency-domain rows at one setting.
#[derive(Clone)]
pub(crate) struct BlockRows {
    /// The rows, compressed.
    pub rows: Compressed,
    /// How many rows.
    pub count: usize,
    /// The kept bins' frequencies (Hz).
    pub freqs: Vec<f64>,
}

/// The settings `(window count index, δ index)` in grid order (window counts outer).
pub(crate) fn grid(opt: &TfsOptions) -> Vec<(usize, usize)> {
    (0..opt.criterion3.window_counts.len())
        .flat_map(|wi| (0..opt.criterion3.deltas.len()).map(move |di| (wi, di)))
        .collect()
}

/// The compressed rows of `blocks` merged into one problem (by reference, no copies).
pub(crate) fn merged<'a>(blocks: impl IntoIterator<Item = &'a BlockRows>) -> Result<Compressed> {
    let parts: Vec<(&Compressed, usize)> = blocks.into_iter().map(|b| (&b.rows, 1)).collect();
    Ok(Compressed::merge_counted(&parts)?)
}

/// The frequency-domain rows of every window count, δ and record (`transforms[wi][record]`)
/// over the columns `keep`, compressed: `out[wi][di][record]`. The bins kept at a smaller δ
/// include those kept at a larger one, so each window is compressed once, from the largest δ
/// down, appending only the rows each smaller δ adds.
pub(crate) fn compress_settings(
    transforms: &Transforms,
    opt: &TfsOptions,
    keep: &[usize],
    nb: usize,
) -> Result<Vec<Vec<Vec<BlockRows>>>> {
    let mut order: Vec<usize> = (0..opt.criterion3.deltas.len()).collect();
    order.sort_by(|&a, &b| opt.criterion3.deltas[b].total_cmp(&opt.criterion3.deltas[a]));
    // One window layout of one block, compressed at every δ (indexed like `opt.criterion3.deltas`): one
    // factor per block, to which each smaller δ appends the rows it adds in every window.
    let compress_block = |wins: &[WindowTransform]| -> Result<Vec<BlockRows>> {
        let mut out: Vec<Option<BlockRows>> = vec![None; opt.criterion3.deltas.len()];
        let mut state = Compressed::empty(keep.len());
        let mut rows = 0;
        let mut freqs = Vec::new();
        let mut hi = f64::INFINITY;
        for &di in &order {
            let lo = opt.criterion3.deltas[di];
            for w in wins {
                let (a, y, f) = rows_for_band(w, lo, hi, keep);
                if a.nrows() == 0 {
                    continue;
                }
                rows += a.nrows();
                freqs.extend(f);
                state.append(a.as_ref(), &y)?;
            }
            hi = lo;
            out[di] = Some(BlockRows {
                rows: state.clone(),
                count: rows,
                freqs: freqs.clone(),
            });
        }
        Ok(out
            .into_iter()
            .map(|o| o.expect("every δ visited"))
            .collect())
    };
    let pairs: Vec<(usize, usize)> = (0..opt.criterion3.window_counts.len())
        .flat_map(|wi| (0..nb).map(move |b| (wi, b)))
        .collect();
    let mut per_pair: Vec<Vec<BlockRows>> = pairs
        .par_iter()
        .with_max_len(1)
        .map(|&(wi, b)| compress_block(&transforms[wi][b]))
        .collect::<Result<_>>()?;
    let mut compressed: Vec<Vec<Vec<BlockRows>>> =
        vec![
            vec![Vec::with_capacity(nb); opt.criterion3.deltas.len()];
            opt.criterion3.window_counts.len()
        ];
    for (&(wi, _), by_delta) in pairs.iter().zip(per_pair.iter_mut()) {
        for (di, br) in std::mem::take(by_delta).into_iter().enumerate() {
            compressed[wi][di].push(br);
        }
    }
    Ok(compressed)
}

/// Leave-one-record-out errors of `settings` settings over `nb` records: for every setting `g`
/// and held-out record `f`, `fit` makes coefficients from the other records' rows
/// (`rows(g, k)`, merged) and the held-out rows, and `score(g, f, coef)` scores them; returns
/// each setting's mean over `f`. Every (setting, held-out record) pair is its own task: a
/// setting's folds differ in cost, and whole settings as tasks left one thread idle at the end.
pub(crate) fn loo_errors<'r>(
    settings: usize,
    nb: usize,
    rows: &(dyn Fn(usize, usize) -> &'r Compressed + Sync),
    fit: &(dyn Fn(&Compressed, &Compressed) -> Result<Vec<f64>> + Sync),
    score: &(dyn Fn(usize, usize, Vec<f64>) -> Result<f64> + Sync),
) -> Result<Vec<f64>> {
    if nb == 0 {
        return Ok(vec![f64::NAN; settings]);
    }
    let jobs: Vec<(usize, usize)> = (0..settings)
        .flat_map(|g| (0..nb).map(move |f| (g, f)))
        .collect();
    let errs: Vec<f64> = jobs
        .par_iter()
        .with_max_len(1)
        .map(|&(g, f)| -> Result<f64> {
            let train: Vec<(&Compressed, usize)> = (0..nb)
                .filter(|&k| k != f)
                .map(|k| (rows(g, k), 1))
                .collect();
            let train = Compressed::merge_counted(&train)?;
            let coef = fit(&train, rows(g, f))?;
            score(g, f, coef)
        })
        .collect::<Result<_>>()?;
    Ok(errs
        .chunks(nb)
        .map(|e| e.iter().fold(0.0, |a, v| a + v) / nb as f64)
        .collect())
}

/// Mean relative time-domain residual on each record in turn (its block of `td`), of the model
/// `fit` makes from the other records' compressed rows (training rows, held-out rows), at every
/// setting `(wi, di)` of `grid`; `const_j` is the constant's position in `keep`, if offered.
pub(crate) fn held_out_scores(
    compressed: &[Vec<Vec<BlockRows>>],
    grid: &[(usize, usize)],
    td: &[(Mat<f64>, Vec<f64>)],
    keep: &[usize],
    const_j: Option<usize>,
    fit: &(dyn Fn(&Compressed, &Compressed) -> Result<Vec<f64>> + Sync),
) -> Result<Vec<f64>> {
    let nb = td.len();
    let rows = |g: usize, k: usize| {
        let (wi, di) = grid[g];
        &compressed[wi][di][k].rows
    };
    let score = |_: usize, f: usize, mut coef: Vec<f64>| {
        if let Some(cj) = const_j {
            let rest = (0..nb).filter(|&k| k != f).map(|k| &td[k]);
            fill_constant(&mut coef, cj, rest, keep);
        }
        held_out_relative_rss(&td[f], keep, &coef)
    };
    loo_errors(grid.len(), nb, &rows, fit, &score)
}

/// The candidate settings with their held-out scores (grid order), and the best among the
/// `eligible` ones (all when none is): its error and `(window count index, δ index)` (the first
/// of equal scores).
pub(crate) fn choose_setting(
    grid: &[(usize, usize)],
    scores: &[f64],
    eligible: &[bool],
    opt: &TfsOptions,
) -> (Vec<SettingScore>, f64, (usize, usize)) {
    let mut candidates = Vec::new();
    let mut best: Option<(f64, usize, usize)> = None;
    for (g, (&(wi, di), &err)) in grid.iter().zip(scores).enumerate() {
        candidates.push(SettingScore {
            delta: opt.criterion3.deltas[di],
            windows: opt.criterion3.window_counts[wi],
            held_out_error: err,
        });
        if eligible.get(g).copied().unwrap_or(true) && best.is_none_or(|b| err < b.0) {
            best = Some((err, wi, di));
        }
    }
    if best.is_none() {
        // No setting can be resampled: the lowest error among all of them.
        for (&(wi, di), &err) in grid.iter().zip(scores) {
            if best.is_none_or(|b| err < b.0) {
                best = Some((err, wi, di));
            }
        }
    }
    let (err, wi, di) = best.expect("at least one setting");
    (candidates, err, (wi, di))
}

/// How many independent clusters of bins (those of the intervals and the term test) each
/// setting (grid order) gives over the records' windows at its window count and δ.
pub(crate) fn cluster_counts(
    grid: &[(usize, usize)],
    transforms: &Transforms,
    opt: &TfsOptions,
) -> Vec<usize> {
    grid.iter()
        .map(|&(wi, di)| {
            let rows: Vec<(usize, usize, &WindowTransform)> = transforms[wi]
                .iter()
                .enumerate()
                .flat_map(|(r, wins)| wins.iter().enumerate().map(move |(w, t)| (r, w, t)))
                .collect();
            crate::uncertainty::cluster_count(&rows, opt.criterion3.deltas[di])
        })
        .collect()
}

/// Which settings (grid order, with the cluster counts `counts` of [`cluster_counts`]) give
/// `coefficients` coefficients that can be resampled and tested: at least [`MIN_CLUSTERS`]
/// clusters and, where some setting has them, more clusters than coefficients.
///
/// A setting with fewer than [`MIN_CLUSTERS`] — one window per record and a handful of strong
/// bins, on a short record — fits and scores, but its terms cannot be tested, so a spurious one
/// stays; it is chosen only when no setting can be resampled (`coefficients` 0: the settings
/// for selecting the terms and, first, for their coefficients). One with at least three
/// clusters but no more than coefficients gives a jackknife covariance of rank `C − 1`, below
/// the number of coefficients: a term that fails the test there is tested again at the best
/// setting with more clusters than the kept coefficients (`crate::pipeline`'s
/// `untestable_failure`; `docs/DECISIONS.md`).
pub(crate) fn eligible_by_clusters(counts: &[usize], coefficients: usize) -> Vec<bool> {
    let full = MIN_CLUSTERS.max(coefficients + 1);
    let need = if counts.iter().any(|&c| c >= full) {
        full
    } else {
        MIN_CLUSTERS
    };
    counts.iter().map(|&c| c >= need).collect()
}

/// The fewest clusters of bins that intervals and the term test are computed from.
pub(crate) const MIN_CLUSTERS: usize = 3;

/// Held-out errors within this relative distance of the lowest are closer than the held-out
/// records can tell apart: the trace says when the chosen setting won by less.
pub(crate) const CLOSE_MARGIN: f64 = 1e-3;

/// The best other setting of `scores` (grid order) when its error is within [`CLOSE_MARGIN`]
/// of the chosen setting `best`'s: its index and how far above it is (relative). Settings with
/// exactly the chosen error are left out (the same bins at another δ: the same rows).
pub(crate) fn close_runner_up(scores: &[f64], best: usize) -> Option<(usize, f64)> {
    let b = *scores.get(best)?;
    let (k, e) = scores
        .iter()
        .enumerate()
        .filter(|&(k, &e)| k != best && e != b && e.is_finite())
        .min_by(|x, y| x.1.total_cmp(y.1))?;
    let gap = (e - b) / b.abs().max(f64::MIN_POSITIVE);
    (gap.abs() <= CLOSE_MARGIN).then_some((k, gap))
}

/// The trace's notes on settings chosen by a hair: where another setting's held-out error is
/// within [`CLOSE_MARGIN`] of the chosen one's, for selecting the terms (`(scores, chosen)`) and
/// for their coefficients (`reselected`, if any), the choice rests on digits the held-out
/// records do not resolve and a tiny change to the data could pick the other.
pub(crate) fn close_calls(
    grid: &[(usize, usize)],
    opt: &TfsOptions,
    (scores, chosen): (&[f64], (usize, usize)),
    reselected: Option<(&[f64], (usize, usize))>,
) -> Vec<String> {
    let name = |g: usize| {
        let (wi, di) = grid[g];
        format!(
            "δ = {} and {} window(s)",
            opt.criterion3.deltas[di], opt.criterion3.window_counts[wi]
        )
    };
    let runner_up = |scores: &[f64], setting| {
        let g = grid.iter().position(|&s| s == setting)?;
        close_runner_up(scores, g)
    };
    let mut out = Vec::new();
    if let Some((k, gap)) = runner_up(scores, chosen) {
        out.push(format!(
            "close decision: {} scored only {:.3}% above the chosen setting for selecting the terms, closer than the held-out records can tell apart; it may select other terms",
            name(k),
            100.0 * gap
        ));
    }
    if let Some((k, gap)) = reselected.and_then(|(s, at)| runner_up(s, at)) {
        out.push(format!(
            "close decision: {} scored only {:.3}% above the setting chosen for the coefficients, closer than the held-out records can tell apart",
            name(k),
            100.0 * gap
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Settings need more clusters than coefficients where some setting has them, else at
    /// least three; with none at three, none is eligible (the caller then takes them all).
    #[test]
    fn eligibility_prefers_more_clusters_than_coefficients() {
        assert_eq!(
            eligible_by_clusters(&[3, 5, 6, 8], 5),
            [false, false, true, true]
        );
        assert_eq!(eligible_by_clusters(&[3, 5, 2], 5), [true, true, false]);
        assert_eq!(eligible_by_clusters(&[1, 2], 1), [false, false]);
        assert_eq!(eligible_by_clusters(&[3, 2], 1), [true, false]);
        assert_eq!(eligible_by_clusters(&[3, 2, 9], 0), [true, false, true]);
    }

    /// A runner-up within the margin is reported with its gap; one beyond it, an exact tie
    /// (the same rows at another δ) and a non-finite score are not.
    #[test]
    fn close_runner_up_within_the_margin_only() {
        let s = [0.070, 0.069_01, 0.069, 0.069];
        let (k, gap) = close_runner_up(&s, 2).expect("0.069 01 is within 0.1 %");
        assert_eq!(k, 1);
        assert!((gap - 0.01 / 69.0).abs() < 1e-12, "{gap}");
        assert_eq!(close_runner_up(&[0.070, 0.069, 0.069], 1), None);
        assert_eq!(close_runner_up(&[0.0692, 0.069, f64::NAN], 1), None);
        assert_eq!(close_runner_up(&[0.069], 0), None);
    }
}
