//! Numerical differentiation of uniformly sampled signals: central differences (2nd and 4th
//! order), Savitzky–Golay smoothing derivatives and FFT-based spectral derivatives with a cut-off.
//!
//! All routines return a sequence of the same length as the input; `deriv` is the derivative
//! order (0 returns a copy where supported) and results are per second (`/dt^deriv`).

use crate::fft::{irfft_into, rfft_in_place};
use crate::{Complex, Result, check_dt, check_signal, invalid};
use faer::Mat;
use faer::linalg::solvers::SolveLstsq;
use std::f64::consts::PI;

/// Finite-difference weights (Fornberg 1988) for derivatives `0..=m` at point `z` on `nodes`.
/// Returns `c[k][j]`: weight of node `j` for derivative `k`.
fn fornberg(z: f64, nodes: &[f64], m: usize) -> Vec<Vec<f64>> {
    let n = nodes.len();
    let mut c = vec![vec![0.0; n]; m + 1];
    let mut c1 = 1.0;
    let mut c4 = nodes[0] - z;
    c[0][0] = 1.0;
    for i in 1..n {
        let mn = i.min(m);
        let mut c2 = 1.0;
        let c5 = c4;
        c4 = nodes[i] - z;
        for j in 0..i {
            let c3 = nodes[i] - nodes[j];
            c2 *= c3;
            if j == i - 1 {
                for k in (1..=mn).rev() {
                    c[k][i] = c1 * (k as f64 * c[k - 1][i - 1] - c5 * c[k][i - 1]) / c2;
                }
                c[0][i] = -c1 * c5 * c[0][i - 1] / c2;
            }
            for k in (1..=mn).rev() {
                c[k][j] = (c4 * c[k][j] - k as f64 * c[k - 1][j]) / c3;
            }
            c[0][j] = c4 * c[0][j] / c3;
        }
        c1 = c2;
    }
    c
}

/// Finite differences of accuracy order `accuracy` (2 or 4): centred stencils of `accuracy+1`
/// points in the interior, one-sided stencils of `accuracy+deriv` points (same accuracy order)
/// near the ends.
fn finite_difference(x: &[f64], dt: f64, deriv: usize, accuracy: usize) -> Result<Vec<f64>> {
    check_dt(dt)?;
    if deriv > 2 {
        return Err(invalid(
            "deriv",
            deriv,
            "central differences support derivative orders 0, 1 and 2; use Savitzky–Golay or spectral for higher orders",
        ));
    }
    if deriv == 0 {
        check_signal("central difference input", x, 1)?;
        return Ok(x.to_vec());
    }
    let h = accuracy / 2;
    let one_sided = accuracy + deriv;
    let needed = (2 * h + 1).max(one_sided);
    check_signal("central difference input", x, needed)?;
    let n = x.len();
    let scale = dt.powi(deriv as i32);
    let central_nodes: Vec<f64> = (0..=2 * h).map(|j| j as f64).collect();
    let central = fornberg(h as f64, &central_nodes, deriv)[deriv].clone();
    let side_nodes: Vec<f64> = (0..one_sided).map(|j| j as f64).collect();
    let mut out = vec![0.0; n];
    for (i, o) in out.iter_mut().enumerate().take(n - h).skip(h) {
        *o = central
            .iter()
            .zip(&x[i - h..=i + h])
            .map(|(c, v)| c * v)
            .sum::<f64>()
            / scale;
    }
    for i in 0..h {
        // Left end: nodes 0..one_sided, evaluated at i.
        let wl = &fornberg(i as f64, &side_nodes, deriv)[deriv];
        out[i] = wl
            .iter()
            .zip(&x[..one_sided])
            .map(|(c, v)| c * v)
            .sum::<f64>()
            / scale;
        // Right end (mirror): nodes n-one_sided..n, evaluated at n-1-i.
        let wr = &fornberg((one_sided - 1 - i) as f64, &side_nodes, deriv)[deriv];
        out[n - 1 - i] = wr
            .iter()
            .zip(&x[n - one_sided..])
            .map(|(c, v)| c * v)
            .sum::<f64>()
            / scale;
    }
    Ok(out)
}

/// Second-order finite differences: centred 3-point stencils in the interior
/// (`(x_{i+1} − x_{i−1})/2dt`, `(x_{i+1} − 2x_i + x_{i−1})/dt²`) and second-order one-sided
/// stencils at the ends (3 points for `deriv = 1`, 4 points for `deriv = 2`).
/// Exact on quadratics everywhere. `deriv ∈ {0, 1, 2}`.
pub fn central_difference(x: &[f64], dt: f64, deriv: usize) -> Result<Vec<f64>> {
    finite_difference(x, dt, deriv, 2)
}

/// Fourth-order finite differences: centred 5-point stencils in the interior and fourth-order
/// one-sided stencils (5 points for `deriv = 1`, 6 for `deriv = 2`) for the two samples at each end.
/// Exact on quartics everywhere. `deriv ∈ {0, 1, 2}`.
pub fn central_difference4(x: &[f64], dt: f64, deriv: usize) -> Result<Vec<f64>> {
    finite_difference(x, dt, deriv, 4)
}

fn check_sg(half_window: usize, poly_order: usize, deriv: usize) -> Result<()> {
    if half_window == 0 {
        return Err(invalid(
            "half_window",
            0,
            "the Savitzky–Golay half window must be at least 1 (window = 2·half_window + 1 samples)",
        ));
    }
    if poly_order > 2 * half_window {
        return Err(invalid(
            "poly_order",
            poly_order,
            format!(
                "must be below the window length {} (2·half_window + 1); raise half_window or lower poly_order",
                2 * half_window + 1
            ),
        ));
    }
    if poly_order > 12 {
        return Err(invalid(
            "poly_order",
            poly_order,
            "polynomial orders above 12 are ill-conditioned; use at most 12",
        ));
    }
    if deriv > poly_order {
        return Err(invalid(
            "deriv",
            deriv,
            format!("the derivative order cannot exceed poly_order = {poly_order}"),
        ));
    }
    Ok(())
}

/// Savitzky–Golay weights for a window of `2·half_window + 1` samples: the least-squares
/// polynomial of degree `poly_order` is fitted to the window and its `deriv`-th derivative is
/// evaluated at window index `position` (`half_window` = centre). The derivative at that point is
/// `Σ_j weights[j]·x_j / dt^deriv`. The fit is solved by a QR least-squares solve (faer) on the
/// Vandermonde matrix in the scaled variable `(j − position)/half_window`.
pub fn savitzky_golay_weights(
    half_window: usize,
    poly_order: usize,
    deriv: usize,
    position: usize,
) -> Result<Vec<f64>> {
    check_sg(half_window, poly_order, deriv)?;
    let len = 2 * half_window + 1;
    if position >= len {
        return Err(invalid(
            "position",
            position,
            format!("must index the window, i.e. be below {len}"),
        ));
    }
    let hs = half_window as f64;
    let v = Mat::<f64>::from_fn(len, poly_order + 1, |j, k| {
        ((j as f64 - position as f64) / hs).powi(k as i32)
    });
    let pinv = v.qr().solve_lstsq(Mat::<f64>::identity(len, len));
    let factorial: f64 = (1..=deriv).map(|k| k as f64).product();
    let scale = factorial / hs.powi(deriv as i32);
    Ok((0..len).map(|j| pinv[(deriv, j)] * scale).collect())
}

/// Savitzky–Golay smoothing derivative of order `deriv` with polynomial degree `poly_order`
/// over windows of `2·half_window + 1` samples. Near the ends the window is not centred: the
/// first/last full window is fitted and its polynomial evaluated at the off-centre sample
/// (asymmetric end fits), so the result is exact for polynomials of degree ≤ `poly_order`
/// everywhere, ends included.
pub fn savitzky_golay(
    x: &[f64],
    dt: f64,
    half_window: usize,
    poly_order: usize,
    deriv: usize,
) -> Result<Vec<f64>> {
    check_dt(dt)?;
    check_sg(half_window, poly_order, deriv)?;
    let len = 2 * half_window + 1;
    check_signal("Savitzky–Golay input", x, len)?;
    let n = x.len();
    let scale = dt.powi(deriv as i32);
    let apply = |w: &[f64], seg: &[f64]| w.iter().zip(seg).map(|(a, b)| a * b).sum::<f64>() / scale;
    let centre = savitzky_golay_weights(half_window, poly_order, deriv, half_window)?;
    let mut out = vec![0.0; n];
    for i in half_window..n - half_window {
        out[i] = apply(&centre, &x[i - half_window..=i + half_window]);
    }
    for i in 0..half_window {
        let wl = savitzky_golay_weights(half_window, poly_order, deriv, i)?;
        out[i] = apply(&wl, &x[..len]);
        let wr = savitzky_golay_weights(half_window, poly_order, deriv, len - 1 - i)?;
        out[n - 1 - i] = apply(&wr, &x[n - len..]);
    }
    Ok(out)
}

/// How [`spectral_derivative_with`] treats the (generally non-periodic) ends of a record.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpectralEnds {
    /// Treat the record as one period (exact for band-limited periodic signals whose period
    /// divides `n·dt`; large wrap-around errors otherwise).
    Periodic,
    /// Subtract the straight line through the first and last samples (its derivative is added
    /// back analytically), then extend the remainder oddly about both ends to length `2(n−1)`.
    /// The extension is continuous with a continuous first derivative, so wrap-around error falls
    /// to a small end effect that decays quickly into the record. Known end effect: the odd
    /// extension has zero second derivative at the two end points, so a second derivative is
    /// pulled towards zero over the first and last few samples (first derivatives are accurate
    /// to a few percent there, interior values to near machine precision for smooth signals).
    #[default]
    DetrendOddExtension,
}

/// Spectral derivative with the default end treatment [`SpectralEnds::DetrendOddExtension`].
/// `cutoff_hz`: bins above this frequency are zeroed (a sharp low-pass); `None` keeps all bins.
pub fn spectral_derivative(
    x: &[f64],
    dt: f64,
    deriv: usize,
    cutoff_hz: Option<f64>,
) -> Result<Vec<f64>> {
    spectral_derivative_with(x, dt, deriv, cutoff_hz, SpectralEnds::default())
}

/// FFT-based derivative of order `deriv`: multiply bin `k` by `(iω_k)^deriv` (the Nyquist bin
/// is zeroed for odd orders), zero bins above `cutoff_hz`, transform back. See [`SpectralEnds`]
/// for the treatment of non-periodic ends.
pub fn spectral_derivative_with(
    x: &[f64],
    dt: f64,
    deriv: usize,
    cutoff_hz: Option<f64>,
    ends: SpectralEnds,
) -> Result<Vec<f64>> {
    check_dt(dt)?;
    check_signal("spectral derivative input", x, 2)?;
    if let Some(fc) = cutoff_hz {
        if !(fc.is_finite() && fc > 0.0) {
            return Err(invalid(
                "cutoff_hz",
                fc,
                "the spectral cut-off must be a finite positive frequency in Hz (or None)",
            ));
        }
    }
    if deriv > 16 {
        return Err(invalid(
            "deriv",
            deriv,
            "spectral derivatives are limited to order 16",
        ));
    }
    let n = x.len();
    match ends {
        SpectralEnds::Periodic => spectral_periodic(x.to_vec(), dt, deriv, cutoff_hz),
        SpectralEnds::DetrendOddExtension => {
            let slope = (x[n - 1] - x[0]) / ((n - 1) as f64 * dt);
            // The remainder and its odd extension, made in the one buffer the transforms then
            // work in (a record of 640,000 samples held five such buffers at once before).
            let mut ext = Vec::with_capacity(2 * (n - 1));
            ext.extend(
                x.iter()
                    .enumerate()
                    .map(|(k, v)| v - x[0] - slope * k as f64 * dt),
            );
            for i in (1..n - 1).rev() {
                ext.push(-ext[i]);
            }
            let mut out = spectral_periodic(ext, dt, deriv, cutoff_hz)?;
            out.truncate(n);
            out.shrink_to_fit();
            if deriv == 0 {
                for (k, o) in out.iter_mut().enumerate() {
                    *o += x[0] + slope * k as f64 * dt;
                }
            } else if deriv == 1 {
                out.iter_mut().for_each(|o| *o += slope);
            }
            Ok(out)
        }
    }
}

/// The periodic spectral derivative of `x`, computed in `x`'s own buffer (returned).
fn spectral_periodic(
    mut x: Vec<f64>,
    dt: f64,
    deriv: usize,
    cutoff_hz: Option<f64>,
) -> Result<Vec<f64>> {
    let n = x.len();
    let mut spec = rfft_in_place(&mut x)?;
    // The bins' frequencies as [`crate::fft::frequencies`] makes them.
    let df = 1.0 / (n as f64 * dt);
    for (k, c) in spec.iter_mut().enumerate() {
        let f = k as f64 * df;
        let nyquist = n % 2 == 0 && k == n / 2;
        if cutoff_hz.is_some_and(|fc| f > fc) || (nyquist && deriv % 2 == 1) {
            *c = Complex::new(0.0, 0.0);
            continue;
        }
        let iw = Complex::new(0.0, 2.0 * PI * f);
        *c *= iw.powi(deriv as i32);
    }
    irfft_into(&mut spec, &mut x)?;
    Ok(x)
}

/// A choice of differentiation method with one entry point, [`Differentiator::apply`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Differentiator {
    /// [`central_difference`] (second order).
    CentralDifference,
    /// [`central_difference4`] (fourth order).
    CentralDifference4,
    /// [`savitzky_golay`] with the given window and degree.
    SavitzkyGolay {
        /// Half window; the window holds `2·half_window + 1` samples.
        half_window: usize,
        /// Degree of the local least-squares polynomial.
        poly_order: usize,
    },
    /// [`spectral_derivative`] (detrend + odd extension) with an optional cut-off in Hz.
    Spectral {
        /// Bins above this frequency are zeroed; `None` keeps all.
        cutoff_hz: Option<f64>,
    },
}

impl Differentiator {
    /// Derivative of order `deriv` of `x` sampled every `dt` seconds.
    pub fn apply(&self, x: &[f64], dt: f64, deriv: usize) -> Result<Vec<f64>> {
        match *self {
            Differentiator::CentralDifference => central_difference(x, dt, deriv),
            Differentiator::CentralDifference4 => central_difference4(x, dt, deriv),
            Differentiator::SavitzkyGolay {
                half_window,
                poly_order,
            } => savitzky_golay(x, dt, half_window, poly_order, deriv),
            Differentiator::Spectral { cutoff_hz } => spectral_derivative(x, dt, deriv, cutoff_hz),
        }
    }
}

impl std::fmt::Display for Differentiator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Differentiator::CentralDifference => write!(f, "central differences (2nd order)"),
            Differentiator::CentralDifference4 => write!(f, "central differences (4th order)"),
            Differentiator::SavitzkyGolay {
                half_window,
                poly_order,
            } => write!(
                f,
                "Savitzky–Golay (window {}, degree {poly_order})",
                2 * half_window + 1
            ),
            Differentiator::Spectral {
                cutoff_hz: Some(fc),
            } => write!(f, "spectral (cut-off {fc} Hz)"),
            Differentiator::Spectral { cutoff_hz: None } => write!(f, "spectral (no cut-off)"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_parameters_are_errors() {
        let x = vec![1.0; 50];
        assert!(central_difference(&x[..3], 0.1, 2).is_err());
        assert!(central_difference(&x, 0.1, 3).is_err());
        assert!(central_difference(&x, f64::NAN, 1).is_err());
        assert!(savitzky_golay(&x, 0.1, 0, 1, 1).is_err());
        assert!(savitzky_golay(&x, 0.1, 2, 5, 1).is_err());
        assert!(savitzky_golay(&x, 0.1, 2, 2, 3).is_err());
        assert!(savitzky_golay(&x[..4], 0.1, 2, 2, 1).is_err());
        assert!(spectral_derivative(&x, 0.1, 1, Some(-1.0)).is_err());
        let e = savitzky_golay(&x, 0.1, 2, 5, 1).unwrap_err().to_string();
        assert!(e.contains("poly_order"), "{e}");
    }

    #[test]
    fn fornberg_reproduces_textbook_stencils() {
        let nodes = [0.0, 1.0, 2.0, 3.0, 4.0];
        let c = fornberg(2.0, &nodes, 2);
        let want1 = [1.0 / 12.0, -8.0 / 12.0, 0.0, 8.0 / 12.0, -1.0 / 12.0];
        let want2 = [
            -1.0 / 12.0,
            16.0 / 12.0,
            -30.0 / 12.0,
            16.0 / 12.0,
            -1.0 / 12.0,
        ];
        for j in 0..5 {
            assert!((c[1][j] - want1[j]).abs() < 1e-14);
            assert!((c[2][j] - want2[j]).abs() < 1e-14);
        }
        let one = fornberg(0.0, &nodes[..3], 1);
        assert!(
            (one[1][0] + 1.5).abs() < 1e-14
                && (one[1][1] - 2.0).abs() < 1e-14
                && (one[1][2] + 0.5).abs() < 1e-14
        );
    }

    #[test]
    fn savitzky_golay_centre_weights_match_classical_table() {
        // Classical 5-point quadratic smoothing weights (−3, 12, 17, 12, −3)/35.
        let w = savitzky_golay_weights(2, 2, 0, 2).unwrap();
        let want = [-3.0, 12.0, 17.0, 12.0, -3.0];
        for (a, b) in w.iter().zip(want) {
            assert!((a - b / 35.0).abs() < 1e-13);
        }
        // 5-point first derivative: (−2, −1, 0, 1, 2)/10.
        let d = savitzky_golay_weights(2, 2, 1, 2).unwrap();
        for (j, a) in d.iter().enumerate() {
            assert!((a - (j as f64 - 2.0) / 10.0).abs() < 1e-13);
        }
    }

    /// The spectral derivative made in one buffer is, to the bit, the one made with a copy per
    /// step (the extension, the forward transform's input, the spectrum's inverse), for both end
    /// treatments, orders 0–3, with and without a cut-off, even and odd lengths, short and long
    /// (a plan longer than the cached lengths).
    #[test]
    fn in_place_spectral_derivative_matches_the_copying_one_to_the_bit() {
        use crate::fft::{frequencies, irfft, rfft};
        let reference_periodic = |x: &[f64], dt: f64, deriv: usize, fc: Option<f64>| {
            let n = x.len();
            let mut spec = rfft(x).unwrap();
            let freqs = frequencies(n, dt).unwrap();
            for (k, (c, f)) in spec.iter_mut().zip(&freqs).enumerate() {
                let nyquist = n % 2 == 0 && k == n / 2;
                if fc.is_some_and(|fc| *f > fc) || (nyquist && deriv % 2 == 1) {
                    *c = Complex::new(0.0, 0.0);
                    continue;
                }
                *c *= Complex::new(0.0, 2.0 * PI * f).powi(deriv as i32);
            }
            irfft(&spec, n).unwrap()
        };
        let reference = |x: &[f64], dt: f64, deriv: usize, fc: Option<f64>| {
            let n = x.len();
            let slope = (x[n - 1] - x[0]) / ((n - 1) as f64 * dt);
            let rem: Vec<f64> = x
                .iter()
                .enumerate()
                .map(|(k, v)| v - x[0] - slope * k as f64 * dt)
                .collect();
            let mut ext = rem.clone();
            ext.extend(rem[1..n - 1].iter().rev().map(|v| -v));
            let d = reference_periodic(&ext, dt, deriv, fc);
            let mut out = d[..n].to_vec();
            if deriv == 0 {
                for (k, o) in out.iter_mut().enumerate() {
                    *o += x[0] + slope * k as f64 * dt;
                }
            } else if deriv == 1 {
                out.iter_mut().for_each(|o| *o += slope);
            }
            out
        };
        let bits = |v: &[f64]| v.iter().map(|a| a.to_bits()).collect::<Vec<_>>();
        let dt = 0.01;
        for n in [2usize, 3, 1000, 1001, 40_001] {
            let x: Vec<f64> = (0..n)
                .map(|k| {
                    let t = k as f64 * dt;
                    (2.1 * t).sin() + 0.3 * t + 1e-3 * ((k * 7919) % 113) as f64
                })
                .collect();
            for deriv in 0..4 {
                for fc in [None, Some(7.5)] {
                    let ends = SpectralEnds::DetrendOddExtension;
                    let got = spectral_derivative_with(&x, dt, deriv, fc, ends).unwrap();
                    assert_eq!(
                        bits(&got),
                        bits(&reference(&x, dt, deriv, fc)),
                        "{n} {deriv}"
                    );
                    assert_eq!(got.capacity(), n);
                    let ends = SpectralEnds::Periodic;
                    let got = spectral_derivative_with(&x, dt, deriv, fc, ends).unwrap();
                    let want = reference_periodic(&x, dt, deriv, fc);
                    assert_eq!(bits(&got), bits(&want), "periodic {n} {deriv}");
                }
            }
        }
    }
}
