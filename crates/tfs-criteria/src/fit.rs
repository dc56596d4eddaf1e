//! The fit of a chosen structure: STLSQ with the support picked on a λ path scored on held-out
//! rows, the constant term estimated in the time domain, the settings chosen again for the
//! selected terms' coefficients, and the final least squares on the support corrected for errors
//! in variables ([`crate::eiv`]).

use faer::Mat;
use tfs_regress::{
    Compressed, InfoCriterion, PathOptions, Regressor, Stlsq, lambda_path, lstsq_support,
};

use crate::criterion3::settings::{BlockRows, held_out_scores, merged};
use crate::eiv::{Correction, Moments, corrected_fit, noise_moments};
use crate::error::{CriteriaError, Result};
use crate::pipeline::DofContext;

/// The constant term's coefficient, from time-domain blocks `(Θ, x'')`: the frequency-domain rows
/// leave out DC (bins are kept where the acceleration is strong), so a constant column is all but
/// zero there. The constant is the mean equation residual of the other terms, kept only where it
/// stands out from the spread of the residual means of 16 contiguous chunks per block (more than
/// 4 standard errors); otherwise 0, so a library offering `1` does not gain a noise constant.
pub(crate) fn fill_constant<'a>(
    coef: &mut [f64],
    cj: usize,
    blocks: impl IntoIterator<Item = &'a (Mat<f64>, Vec<f64>)>,
    keep: &[usize],
) {
    let mut chunk_means = Vec::new();
    let (mut total, mut n) = (0.0, 0usize);
    for (a, y) in blocks {
        let m = y.len();
        if m == 0 {
            continue;
        }
        let g = m.clamp(1, 16);
        let len = m / g;
        for c in 0..g {
            let (s, e) = (c * len, if c + 1 == g { m } else { (c + 1) * len });
            let mut sum = 0.0;
            for i in s..e {
                let mut r = y[i];
                for (j, &cf) in coef.iter().enumerate() {
                    if j != cj && cf != 0.0 {
                        r -= cf * a[(i, keep[j])];
                    }
                }
                sum += r;
            }
            total += sum;
            n += e - s;
            chunk_means.push(sum / (e - s) as f64);
        }
    }
    coef[cj] = 0.0;
    let g = chunk_means.len();
    if g < 3 || n == 0 {
        return;
    }
    let mean = total / n as f64;
    let cm = chunk_means.iter().sum::<f64>() / g as f64;
    let sd = (chunk_means.iter().map(|v| (v - cm).powi(2)).sum::<f64>() / (g - 1) as f64).sqrt();
    if mean.is_finite() && mean.abs() > 4.0 * sd / (g as f64).sqrt() {
        coef[cj] = mean;
    }
}

/// `‖A_keep·coef − y‖² / ‖y‖²` on a time-domain block `(A, y)` (full library; `keep` maps
/// the coefficients to its columns), summed over the non-zero coefficients only: a selected
/// model has a handful of terms, so this costs a few passes over the rows instead of a QR of
/// the block.
pub(crate) fn held_out_relative_rss(
    block: &(Mat<f64>, Vec<f64>),
    keep: &[usize],
    coef: &[f64],
) -> Result<f64> {
    let (a, y) = block;
    if let Some(j) = coef.iter().position(|c| !c.is_finite()) {
        return Err(CriteriaError::Numerics(format!(
            "held-out score: coefficient {j} of the fitted model is {}",
            coef[j]
        )));
    }
    let mut r = y.clone();
    for (&j, &c) in keep.iter().zip(coef) {
        if c == 0.0 {
            continue;
        }
        for (ri, aij) in r.iter_mut().zip(a.col_as_slice(j)) {
            *ri -= c * aij;
        }
    }
    let rss: f64 = r.iter().map(|v| v * v).sum();
    let yy: f64 = y.iter().map(|v| v * v).sum();
    Ok(rss / yy.max(f64::MIN_POSITIVE))
}

/// The weak-form selection's λ path: `n` thresholds down to 1e-4 of the largest share, BIC,
/// and the grid goes on below it where the library's columns cancel one another (the truss
/// cell's monomials about its offset; see `docs/DECISIONS.md`).
pub(crate) fn path_opts(n: usize) -> PathOptions {
    PathOptions {
        stlsq: Stlsq::default(),
        n_thresholds: n.max(2),
        min_ratio: 1e-4,
        criterion: InfoCriterion::Bic,
        extend_when_cancelling: true,
    }
}

/// Coefficients and the STLSQ threshold that selected their support.
pub(crate) type Selection = (Vec<f64>, f64);

/// Fits on `train`, choosing the support on the λ path scored on `val` (or with a fixed threshold).
pub(crate) fn fit_select(
    train: &Compressed,
    val: &Compressed,
    threshold: Option<f64>,
    n_thr: usize,
) -> Result<(Vec<f64>, f64)> {
    if let Some(t) = threshold {
        let f = Stlsq {
            threshold: t,
            ..Stlsq::default()
        }
        .fit_compressed(train)?;
        return Ok((f.coef, t));
    }
    let path = lambda_path(train, val, &path_opts(n_thr))?;
    let b = path.best();
    Ok((b.coef.clone(), support_threshold(&path)))
}

/// The threshold that stands for the selected support of a λ path: the geometric middle of the
/// range of path thresholds that give that support (from the smallest such threshold up to the
/// next larger point, whose support is smaller), rather than the path's own choice at the edge of
/// the range (see `docs/DECISIONS.md`). The coefficients do not depend on it (least squares on
/// the support).
fn support_threshold(path: &tfs_regress::LambdaPath) -> f64 {
    let b = path.best();
    threshold_for_support(path, &b.support, None).unwrap_or(b.threshold)
}

/// The geometric middle of the range of `path`'s thresholds that give `support` (from the
/// smallest such threshold up to the next larger point), or `None` if no point gives it. Column
/// `ignore` (the constant, which is estimated in the time domain) is not compared.
pub(crate) fn threshold_for_support(
    path: &tfs_regress::LambdaPath,
    support: &[bool],
    ignore: Option<usize>,
) -> Option<f64> {
    let same: Vec<usize> = (0..path.points.len())
        .filter(|&i| {
            let p = &path.points[i].support;
            p.len() == support.len()
                && (0..p.len()).all(|j| Some(j) == ignore || p[j] == support[j])
        })
        .collect();
    let first = *same.iter().min()?;
    let lo = same
        .iter()
        .map(|&i| path.points[i].threshold)
        .fold(f64::INFINITY, f64::min);
    let hi = if first > 0 {
        path.points[first - 1].threshold
    } else {
        path.points[first].threshold
    };
    (lo > 0.0 && hi >= lo).then(|| (lo * hi).sqrt())
}

/// The position among the regression columns `keep` of the constant term, if the library offers
/// one (it is estimated in the time domain: see [`fill_constant`]).
pub(crate) fn constant_position(lib: &tfs_library::Library, keep: &[usize]) -> Option<usize> {
    (0..keep.len()).find(|&j| lib.terms()[keep[j]].is_constant())
}

/// The settings chosen again for the selected terms' coefficients: the setting whose least
/// squares on the support of `chosen` has the lowest held-out residual, that residual and every
/// setting's (grid order).
pub(crate) struct Reselected {
    /// `(window count index, δ index)`.
    pub setting: (usize, usize),
    /// Its held-out error.
    pub error: f64,
    /// Every setting's held-out error, in grid order.
    pub scores: Vec<f64>,
    /// `(clusters, coefficients)` when a kept term failed the term test at the lowest-error
    /// setting, whose clusters did not outnumber the kept coefficients, and `setting` is the
    /// best one whose clusters do.
    pub retested: Option<(usize, usize)>,
}

/// The setting (grid position) with the lowest of `scores` among the `eligible` ones (all of
/// them when none is), and its score.
pub(crate) fn best_eligible(scores: &[f64], eligible: &[bool]) -> (usize, f64) {
    let any = eligible.iter().any(|&e| e);
    scores
        .iter()
        .enumerate()
        .fold((0, f64::INFINITY), |b, (k, &e)| {
            if (!any || eligible.get(k).copied().unwrap_or(true)) && e < b.1 {
                (k, e)
            } else {
                b
            }
        })
}

/// The settings were chosen for selecting terms from the whole library; the chosen terms'
/// coefficients are estimated with the setting that predicts held-out records best for that
/// structure (least squares on the support, each record left out in turn). `None` when not
/// asked for, with one setting only, or for an empty model.
pub(crate) fn reselect_for_support(
    ctx: &DofContext<'_>,
    reg: &crate::pipeline::Regression,
    compressed: &[Vec<Vec<BlockRows>>],
    eligible: &[bool],
    chosen: &[f64],
) -> Result<Option<Reselected>> {
    let opt = &ctx.spec.tfs;
    if !(opt.fit.reselect_for_support && ctx.grid.len() > 1 && chosen.iter().any(|v| *v != 0.0)) {
        return Ok(None);
    }
    let sup: Vec<bool> = chosen.iter().map(|v| *v != 0.0).collect();
    let scores = held_out_scores(
        compressed,
        &ctx.grid,
        &ctx.data.td,
        &reg.td_keep,
        reg.const_j,
        &|train, _| Ok(lstsq_support(train, &sup)?.coef),
    )?;
    // The lowest error among the settings whose coefficients can be resampled (all of them
    // when none can), as for the selection's setting.
    let (k, e) = best_eligible(&scores, eligible);
    Ok(Some(Reselected {
        setting: ctx.grid[k],
        error: e,
        scores,
        retested: None,
    }))
}

/// What the errors-in-variables correction of [`final_fit`] did.
pub(crate) enum EivOutcome {
    /// Moments estimated and the corrected equations tried on the regression columns `cols`
    /// (`draws` noise draws per record).
    Tried {
        /// The regression columns corrected (the support less the constant).
        cols: Vec<usize>,
        /// Applied, or too noisy to apply.
        correction: Correction,
        /// Noise draws per record.
        draws: usize,
    },
    /// Not corrected, and why.
    Skipped(String),
}

/// The final coefficients and what the correction did.
pub(crate) struct FinalFit {
    /// Coefficients per regression column.
    pub coef: Vec<f64>,
    /// The errors-in-variables correction.
    pub eiv: EivOutcome,
}

/// The setting a structure's coefficients are estimated at: its rows of every record
/// (`rows[record]`), the windows they came from (`transforms[record]`), the decimation per
/// record and δ.
pub(crate) struct Setting<'s> {
    /// Compressed rows per record.
    pub rows: &'s [BlockRows],
    /// Windowed transforms per record.
    pub transforms: &'s [Vec<crate::criterion3::rows::WindowTransform>],
    /// Decimation per record.
    pub qs: &'s [usize],
    /// The bin threshold δ.
    pub delta: f64,
}

/// Least squares on the first `used` records with the support of `chosen`, corrected for the
/// noise in the regressors (errors in variables) where the noise model allows; the constant is
/// re-estimated in the time domain.
pub(crate) fn final_fit(
    ctx: &DofContext<'_>,
    reg: &crate::pipeline::Regression,
    at: &Setting<'_>,
    chosen: &[f64],
    used: usize,
) -> Result<FinalFit> {
    let opt = &ctx.spec.tfs;
    let keep = &reg.keep;
    let support: Vec<bool> = chosen.iter().map(|v| *v != 0.0).collect();
    let rows = merged(&at.rows[..used])?;
    let mut f = lstsq_support(&rows, &support)?;
    let cols: Vec<usize> = (0..keep.len())
        .filter(|&j| support[j] && Some(j) != reg.const_j)
        .collect();
    let lib_cols: Vec<usize> = cols.iter().map(|&j| keep[j]).collect();
    let constant: Vec<usize> = reg.const_j.filter(|&cj| support[cj]).into_iter().collect();
    let moments = noise_moments(
        &ctx.preps[..used],
        &ctx.spec.dofs,
        ctx.d,
        ctx.lib,
        &lib_cols,
        &at.transforms[..used],
        &at.qs[..used],
        at.delta,
        opt,
        opt.fit.noise_correction_draws,
        ctx.shared.noise,
    )?;
    let eiv = match moments {
        Moments::Estimated(m) => match corrected_fit(&rows, &cols, &constant, &m) {
            Some(corr) => {
                if let Correction::Applied { coef, .. } = &corr {
                    for (&j, &v) in cols.iter().zip(coef) {
                        f.coef[j] = v;
                    }
                }
                EivOutcome::Tried {
                    cols,
                    correction: corr,
                    draws: m.draws,
                }
            }
            None => {
                EivOutcome::Skipped("the corrected normal equations could not be solved".into())
            }
        },
        Moments::Unavailable(why) => EivOutcome::Skipped(why),
    };
    if let Some(cj) = reg.const_j {
        fill_constant(&mut f.coef, cj, &ctx.data.td[..used], &reg.td_keep);
    }
    Ok(FinalFit { coef: f.coef, eiv })
}

/// The trace line of the errors-in-variables correction (`names`: the library's term names,
/// `keep`: the regression columns).
pub(crate) fn eiv_why(eiv: &EivOutcome, names: &[String], keep: &[usize]) -> String {
    match eiv {
        EivOutcome::Skipped(why) => format!("no errors-in-variables correction: {why}"),
        EivOutcome::Tried {
            cols,
            correction,
            draws,
        } => {
            let shares = |sh: &[f64]| -> String {
                cols.iter()
                    .zip(sh)
                    .map(|(&j, v)| format!("{} {:.2}%", names[keep[j]], 100.0 * v))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            match correction {
                Correction::Applied { share, .. } => format!(
                    "errors-in-variables correction applied: {draws} antithetic draws per record of its estimated noise, through the same reconstruction, windows, bins and weights, give the noise's share of each column's energy ({}), which is removed from the normal equations",
                    shares(share)
                ),
                Correction::TooNoisy { share } => format!(
                    "no errors-in-variables correction: the estimated noise carries half or more of the data's energy in some direction of the normal equations (column shares {}), beyond a first-order correction; the coefficients are plain least squares and biased towards zero",
                    shares(share)
                ),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The held-out score read straight off the rows equals the compressed problem's
    /// `rss / ‖y‖²` on the kept columns, zero coefficients skipped or not.
    #[test]
    fn held_out_score_matches_the_compressed_residual() {
        let m = 300;
        let a = Mat::<f64>::from_fn(m, 5, |i, j| ((i * (j + 3)) as f64 * 0.37).sin() + j as f64);
        let y: Vec<f64> = (0..m).map(|i| (i as f64 * 0.11).cos()).collect();
        let keep = [0, 2, 3, 4];
        let coef = [0.5, 0.0, -1.25, 0.3];
        let ak = Mat::<f64>::from_fn(m, keep.len(), |i, j| a[(i, keep[j])]);
        let c = Compressed::from_rows(ak.as_ref(), &y).unwrap();
        let want = c.rss(&coef).unwrap() / c.b_norm2();
        let got = held_out_relative_rss(&(a, y), &keep, &coef).unwrap();
        assert!((got - want).abs() <= 1e-12 * want, "{got} vs {want}");
    }

    #[test]
    fn held_out_score_rejects_non_finite_coefficients() {
        let a = Mat::<f64>::from_fn(10, 2, |i, j| (i + j) as f64);
        let y = vec![1.0; 10];
        let e = held_out_relative_rss(&(a, y), &[0, 1], &[1.0, f64::NAN]).unwrap_err();
        assert!(e.to_string().contains("coefficient 1"), "{e}");
    }
}
