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
    let den: f64 = measured.iter().map(|x| x * x).sum();
    if den == 0.0 {
        return Err(DynError::InvalidParameter {
            name: "measured",
            reason: "signal is identically zero, so R-MSE is undefined; use rms_error instead"
                .into(),
        });
    }
    let num: f64 = measured
        .iter()
        .zip(predicted)
        .map(|(x, p)| (x - p) * (x - p))
        .sum();
    Ok(num / den)
}

/// Root-mean-square error `sqrt(mean((x − x̂)²))`, in the signal's own units.
pub fn rms_error(measured: &[f64], predicted: &[f64]) -> Result<f64> {
    check(measured, predicted)?;
    let num: f64 = measured
        .iter()
        .zip(predicted)
        .map(|(x, p)| (x - p) * (x - p))
        .sum();
    Ok((num / measured.len() as f64).sqrt())
}
