//! A swap step after the λ path: STLSQ's thresholds only visit supports that drop the terms with
//! the smallest scaled coefficients first, so where two library columns are nearly collinear
//! (`x'` and `x^2·x'` or `x'·|x'|` on a short record) the path can keep the stand-in and drop the
//! true term, and no threshold gives the support the held-out rows prefer. The swap step tries
//! replacing each kept term by each dropped one — least squares on the training rows, scored on
//! the held-out rows by the criterion the path itself uses (the same number of terms, so the
//! same penalty: the lower held-out residual wins) — and moves to the best swap while one lowers
//! it.

use tfs_regress::{Compressed, lstsq_support};

use crate::error::Result;
use crate::fit::fit_select;

/// At most this many swaps are made (each one strictly lowers the held-out residual, so the
/// search ends anyway; the bound keeps its cost to a few passes over the candidates).
const MAX_SWAPS: usize = 4;

/// [`fit_select`], then the swap step on the selected support (when the threshold is chosen on
/// the path, not given): `fixed` is a column neither swapped in nor out (the constant, which is
/// estimated in the time domain).
pub(crate) fn fit_select_swapped(
    train: &Compressed,
    val: &Compressed,
    threshold: Option<f64>,
    n_thr: usize,
    fixed: Option<usize>,
) -> Result<(Vec<f64>, f64)> {
    let (coef, thr) = fit_select(train, val, threshold, n_thr)?;
    if threshold.is_some() {
        return Ok((coef, thr));
    }
    Ok((swap(train, val, coef, fixed)?, thr))
}

/// The swap step on the coefficients `coef` fitted on `train` (see the module documentation).
pub(crate) fn swap(
    train: &Compressed,
    val: &Compressed,
    coef: Vec<f64>,
    fixed: Option<usize>,
) -> Result<Vec<f64>> {
    let n = coef.len();
    let mut support: Vec<bool> = coef.iter().map(|c| *c != 0.0).collect();
    if !support.iter().any(|&s| s) || support.iter().all(|&s| s) {
        return Ok(coef);
    }
    let pooled = std::cell::OnceCell::new();
    let pooled = || -> Result<&Compressed> {
        if pooled.get().is_none() {
            let _ = pooled.set(Compressed::merge_counted(&[(train, 1), (val, 1)])?);
        }
        Ok(pooled.get().expect("set above"))
    };
    let mut best = coef;
    let mut best_rss = val.rss(&best)?;
    for _ in 0..MAX_SWAPS {
        let mut found: Option<(f64, Vec<f64>, Vec<bool>)> = None;
        for out in (0..n).filter(|&j| support[j] && Some(j) != fixed) {
            for inn in (0..n).filter(|&j| !support[j] && Some(j) != fixed) {
                let mut s = support.clone();
                s[out] = false;
                s[inn] = true;
                let fit = lstsq_support(train, &s)?;
                // A dependent column comes back at zero: the swap would shrink the model.
                if fit.coef.iter().zip(&s).any(|(c, &k)| k && *c == 0.0) {
                    continue;
                }
                let rss = val.rss(&fit.coef)?;
                // The pooled rows are asked only about a swap that would be taken.
                if rss.is_finite()
                    && rss < found.as_ref().map_or(best_rss, |f| f.0)
                    && pooled_prefers(pooled()?, &support, out, inn)?
                {
                    found = Some((rss, fit.coef, s));
                }
            }
        }
        match found {
            Some((rss, c, s)) => {
                best_rss = rss;
                best = c;
                support = s;
            }
            None => break,
        }
    }
    Ok(best)
}

/// Does the least-squares fit on `pooled` rows of the support `support` with `inn` added give
/// `inn` a larger scaled coefficient (its share of the target's norm) than `out`? Of two nearly
/// collinear columns the fit on every row keeps the one the data carry more of.
fn pooled_prefers(pooled: &Compressed, support: &[bool], out: usize, inn: usize) -> Result<bool> {
    let mut s = support.to_vec();
    s[inn] = true;
    let fit = lstsq_support(pooled, &s)?;
    let norms = pooled.column_norms();
    Ok((fit.coef[inn] * norms[inn]).abs() > (fit.coef[out] * norms[out]).abs())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::lcg;
    use faer::Mat;

    /// Rows of `y = 2·c + 0.3·a + noise` over columns `a`, `b = a + 0.05·e`, `c` (`a`, `e`, `c`
    /// independent): `b` stands in for `a` nearly as well on any one draw of the noise.
    fn rows(m: usize, seed: u64) -> (Mat<f64>, Vec<f64>) {
        let mut s = seed;
        let mut cols = vec![[0.0; 3]; m];
        let mut y = vec![0.0; m];
        for i in 0..m {
            let (a, e, c, n) = (lcg(&mut s), lcg(&mut s), lcg(&mut s), lcg(&mut s));
            cols[i] = [a, a + 0.05 * e, c];
            y[i] = 2.0 * c + 0.3 * a + 0.02 * n;
        }
        (Mat::from_fn(m, 3, |i, j| cols[i][j]), y)
    }

    /// Started from the stand-in's support `{b, c}`, the step swaps `b` for `a` (the held-out
    /// rows prefer it) and returns the least-squares coefficients of `{a, c}` on the training
    /// rows; started from `{a, c}` it changes nothing, and a fixed column is never moved.
    #[test]
    fn a_stand_in_is_swapped_for_the_term_the_held_out_rows_prefer() {
        let (at, yt) = rows(400, 7);
        let (av, yv) = rows(400, 11);
        let train = Compressed::from_rows(at.as_ref(), &yt).unwrap();
        let val = Compressed::from_rows(av.as_ref(), &yv).unwrap();
        let stand_in = lstsq_support(&train, &[false, true, true]).unwrap().coef;
        let truth = lstsq_support(&train, &[true, false, true]).unwrap().coef;
        assert!(val.rss(&truth).unwrap() < val.rss(&stand_in).unwrap());
        let got = swap(&train, &val, stand_in.clone(), None).unwrap();
        assert_eq!(got, truth);
        assert!(
            (got[0] - 0.3).abs() < 0.01 && (got[2] - 2.0).abs() < 0.01,
            "{got:?}"
        );
        assert_eq!(swap(&train, &val, truth.clone(), None).unwrap(), truth);
        assert_eq!(
            swap(&train, &val, stand_in.clone(), Some(1)).unwrap(),
            stand_in
        );
    }
}
