//! Error metrics between a measured and a simulated signal.

use crate::{DynError, Result};

fn check(measured: &[f64], predicted: &[f64]) -> Result<()> {
    if measured.is_empty() {
        return Err(DynError::InvalidParameter {
            name: "measured",
            reason: "no samples; give at least one".into(),
        });
    }
    if measured.len() != predicted.len() {
        return Err(DynError::Dimension {
            name: "predicted",
            expected: measured.len(),
            got: predicted.len(),
            hint: "compare signals sampled at the same times",
        });
    }
    for (name, s) in [("measured", measured), ("predicted", predicted)] {
        if let Some(k) = s.iter().position(|z| !z.is_finite()) {
            return Err(DynError::InvalidParameter {
                name,
                reason: format!("sample {k} is {}; remove non-finite samples", s[k]),
            });
        }
    }
    Ok(())
}

/// `num / den` for sums of squares of `measured` and `predicted`; when the sums leave the
/// normal range of `f64` (a record of amplitude 1e-160 squares to below the smallest normal
/// number, 1e200 above the largest) the ratio is taken again on both signals divided by their
/// largest magnitude, which it does not depend on. Signals in the normal range get the plain
/// ratio, to the bit.
fn scaled_ratio(
    measured: &[f64],
    predicted: &[f64],
    sums: impl Fn(&[f64], &[f64]) -> (f64, f64),
) -> (f64, f64) {
    let (num, den) = sums(measured, predicted);
    let normal = |v: f64| v == 0.0 || v.is_normal();
    if normal(num) && normal(den) && (num / den).is_finite() {
        return (num, den);
    }
    let scale = measured
        .iter()
        .chain(predicted)
        .fold(0.0_f64, |m, v| m.max(v.abs()));
    if !(scale > 0.0 && scale.is_finite()) {
        return (num, den);
    }
    let a: Vec<f64> = measured.iter().map(|v| v / scale).collect();
    let b: Vec<f64> = predicted.iter().map(|v| v / scale).collect();
    sums(&a, &b)
}

/// `Σ (x − x̂)²`.
fn sum_sq_error(measured: &[f64], predicted: &[f64]) -> f64 {
    measured
        .iter()
        .zip(predicted)
        .map(|(x, p)| (x - p) * (x - p))
        .sum()
}

/// R-MSE of the paper's Appendix B: `mean((x − x̂)²) / mean(x²)` with `x` the measured and `x̂`
/// the predicted signal (for zero-mean responses this is the MSE over the response variance).
/// 0 is a perfect match; 1 is as bad as predicting zero.
///
/// ```
/// let r = tfs_dynamics::rmse_ratio(&[1.0, -1.0], &[0.9, -1.1]).unwrap();
/// assert!((r - 0.01).abs() < 1e-12);
/// ```
pub fn rmse_ratio(measured: &[f64], predicted: &[f64]) -> Result<f64> {
    check(measured, predicted)?;
    let (num, den) = scaled_ratio(measured, predicted, |m, p| {
        (sum_sq_error(m, p), m.iter().map(|x| x * x).sum())
    });
    if den == 0.0 {
        return Err(DynError::InvalidParameter {
            name: "measured",
            reason: "signal is identically zero, so R-MSE is undefined; use rms_error instead"
                .into(),
        });
    }
    Ok(num / den)
}

/// Root-mean-square error `sqrt(mean((x − x̂)²))`, in the signal's own units.
pub fn rms_error(measured: &[f64], predicted: &[f64]) -> Result<f64> {
    check(measured, predicted)?;
    let num = sum_sq_error(measured, predicted);
    Ok((num / measured.len() as f64).sqrt())
}

/// R-MSE on the variance: `mean((x − x̂)²) / var(x)`, the measured signal's mean removed from the
/// denominator. Unlike [`rmse_ratio`] (the paper's Appendix B, over the mean square) it does not
/// depend on where the record's zero is: a displacement measured about another origin (a sensor
/// offset, a DC level) scores the same model error the same. 0 is a perfect match; 1 is as bad as
/// predicting the record's own mean.
///
/// ```
/// let x = [1.0, -1.0, 1.0, -1.0];
/// let p = [0.9, -1.1, 0.9, -1.1];
/// let r = tfs_dynamics::rmse_variance(&x, &p).unwrap();
/// assert!((r - 0.01).abs() < 1e-12);
/// // The same error on the same record shifted by 100 scores the same.
/// let shift = |v: &[f64]| v.iter().map(|z| z + 100.0).collect::<Vec<_>>();
/// let r2 = tfs_dynamics::rmse_variance(&shift(&x), &shift(&p)).unwrap();
/// assert!((r2 - r).abs() < 1e-9);
/// ```
pub fn rmse_variance(measured: &[f64], predicted: &[f64]) -> Result<f64> {
    check(measured, predicted)?;
    let n = measured.len() as f64;
    let (num, den) = scaled_ratio(measured, predicted, |m, p| {
        let mean = m.iter().sum::<f64>() / n;
        (
            sum_sq_error(m, p),
            m.iter().map(|x| (x - mean) * (x - mean)).sum(),
        )
    });
    if den == 0.0 {
        return Err(DynError::InvalidParameter {
            name: "measured",
            reason:
                "signal is constant, so R-MSE on its variance is undefined; use rms_error instead"
                    .into(),
        });
    }
    Ok(num / den)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Appendix B's ratio moves with the record's DC level; the variance ratio does not.
    #[test]
    fn variance_ratio_ignores_the_dc_level() {
        let x: Vec<f64> = (0..200).map(|k| (0.1 * k as f64).sin()).collect();
        let p: Vec<f64> = x.iter().map(|v| 0.8 * v).collect();
        let shift = |v: &[f64], c: f64| v.iter().map(|z| z + c).collect::<Vec<_>>();
        let (a, b) = (
            rmse_ratio(&x, &p).unwrap(),
            rmse_ratio(&shift(&x, 100.0), &shift(&p, 100.0)).unwrap(),
        );
        assert!(b < 1e-3 * a, "Appendix B: {a} vs shifted {b}");
        let (c, d) = (
            rmse_variance(&x, &p).unwrap(),
            rmse_variance(&shift(&x, 100.0), &shift(&p, 100.0)).unwrap(),
        );
        assert!((c - d).abs() < 1e-9 * c, "{c} vs {d}");
        assert!((c - 0.04).abs() < 2e-3, "{c}");
        assert!(rmse_variance(&[2.0; 8], &[2.0; 8]).is_err());
    }

    /// Signals so small (or large) that their squares leave the range of `f64` get the ratio
    /// they have at unit scale, not NaN.
    #[test]
    fn ratios_do_not_depend_on_the_scale() {
        let x: Vec<f64> = (0..200).map(|k| (0.1 * k as f64).sin()).collect();
        let p: Vec<f64> = x.iter().map(|v| 0.8 * v + 0.01).collect();
        let at = |s: f64| -> Vec<f64> { x.iter().map(|v| v * s).collect() };
        let pt = |s: f64| -> Vec<f64> { p.iter().map(|v| v * s).collect() };
        let (r, rb) = (rmse_variance(&x, &p).unwrap(), rmse_ratio(&x, &p).unwrap());
        for s in [1e-160, 1e-300, 1e160] {
            let (a, b) = (
                rmse_variance(&at(s), &pt(s)).unwrap(),
                rmse_ratio(&at(s), &pt(s)).unwrap(),
            );
            assert!((a - r).abs() < 1e-9 * r, "scale {s}: {a} vs {r}");
            assert!((b - rb).abs() < 1e-9 * rb, "scale {s}: {b} vs {rb}");
        }
    }
}
