//! Thin helpers over `realfft`: cached plans, forward/inverse real transforms, frequency axes,
//! amplitude spectra and band-limited reconstruction.
//!
//! Conventions: [`SpectrumPlanner::rfft`] is unnormalised (`X_k = Σ x_j e^{−2πijk/n}`, `n/2+1`
//! bins); [`SpectrumPlanner::irfft`] divides by `n`, so `irfft(rfft(x)) = x`.

use crate::{Complex, Result, SignalError, check_dt, check_signal, invalid};
use realfft::RealFftPlanner;

/// Caches `realfft` plans by length; reuse one planner for many transforms of equal length.
pub struct SpectrumPlanner {
    planner: RealFftPlanner<f64>,
}

impl Default for SpectrumPlanner {
    fn default() -> Self {
        Self::new()
    }
}

impl std::fmt::Debug for SpectrumPlanner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SpectrumPlanner")
    }
}

impl SpectrumPlanner {
    /// A planner with an empty plan cache.
    pub fn new() -> Self {
        Self {
            planner: RealFftPlanner::new(),
        }
    }

    /// Forward real FFT of `x` (unnormalised), returning `x.len()/2 + 1` bins.
    pub fn rfft(&mut self, x: &[f64]) -> Result<Vec<Complex<f64>>> {
        check_signal("rfft input", x, 1)?;
        let plan = self.planner.plan_fft_forward(x.len());
        let mut input = x.to_vec();
        let mut out = plan.make_output_vec();
        // Lengths match by construction, so the transform cannot fail.
        plan.process(&mut input, &mut out)
            .expect("rfft buffers sized by the plan");
        Ok(out)
    }

    /// Inverse real FFT to `n` samples, normalised by `1/n`. `spectrum` must hold `n/2 + 1` bins;
    /// the imaginary parts of the DC bin (and of the Nyquist bin for even `n`) are ignored.
    pub fn irfft(&mut self, spectrum: &[Complex<f64>], n: usize) -> Result<Vec<f64>> {
        if n == 0 {
            return Err(SignalError::TooShort {
                what: "irfft output length",
                needed: 1,
                got: 0,
            });
        }
        if spectrum.len() != n / 2 + 1 {
            return Err(SignalError::LengthMismatch {
                what: "irfft spectrum bins vs n/2+1",
                left: spectrum.len(),
                right: n / 2 + 1,
            });
        }
        if let Some((index, v)) = spectrum
            .iter()
            .enumerate()
            .find(|(_, c)| !(c.re.is_finite() && c.im.is_finite()))
        {
            return Err(SignalError::NonFinite {
                what: "irfft spectrum",
                index,
                value: if v.re.is_finite() { v.im } else { v.re },
            });
        }
        let plan = self.planner.plan_fft_inverse(n);
        let mut input = spectrum.to_vec();
        input[0].im = 0.0;
        if n % 2 == 0 {
            input[n / 2].im = 0.0;
        }
        let mut out = plan.make_output_vec();
        plan.process(&mut input, &mut out)
            .expect("irfft buffers sized by the plan, edge bins real");
        let scale = 1.0 / n as f64;
        out.iter_mut().for_each(|v| *v *= scale);
        Ok(out)
    }

    /// Zeroes every bin whose frequency is outside all `bands` (closed intervals in Hz) and
    /// transforms back: a band-limited reconstruction of `x`.
    pub fn band_limit(&mut self, x: &[f64], dt: f64, bands: &[(f64, f64)]) -> Result<Vec<f64>> {
        check_dt(dt)?;
        for &(lo, hi) in bands {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo >= 0.0) {
                return Err(invalid(
                    "bands",
                    format!("({lo}, {hi})"),
                    "each band must be a finite (low, high) pair in Hz with 0 ≤ low ≤ high",
                ));
            }
        }
        let freqs = frequencies(x.len(), dt)?;
        let mask: Vec<bool> = freqs
            .iter()
            .map(|f| bands.iter().any(|&(lo, hi)| *f >= lo && *f <= hi))
            .collect();
        self.band_limit_mask(x, &mask)
    }

    /// Keeps the bins where `mask` is true (length `x.len()/2 + 1`), zeroes the rest and transforms back.
    pub fn band_limit_mask(&mut self, x: &[f64], mask: &[bool]) -> Result<Vec<f64>> {
        let mut spec = self.rfft(x)?;
        if mask.len() != spec.len() {
            return Err(SignalError::LengthMismatch {
                what: "band mask vs rfft bins (n/2+1)",
                left: mask.len(),
                right: spec.len(),
            });
        }
        for (c, &keep) in spec.iter_mut().zip(mask) {
            if !keep {
                *c = Complex::new(0.0, 0.0);
            }
        }
        self.irfft(&spec, x.len())
    }
}

/// Forward real FFT with a one-off planner (see [`SpectrumPlanner::rfft`]).
pub fn rfft(x: &[f64]) -> Result<Vec<Complex<f64>>> {
    SpectrumPlanner::new().rfft(x)
}

/// Inverse real FFT with a one-off planner (see [`SpectrumPlanner::irfft`]).
pub fn irfft(spectrum: &[Complex<f64>], n: usize) -> Result<Vec<f64>> {
    SpectrumPlanner::new().irfft(spectrum, n)
}

/// Bin frequencies in Hz of an `n`-sample rfft: `f_k = k/(n·dt)`, `k = 0..=n/2`.
pub fn frequencies(n: usize, dt: f64) -> Result<Vec<f64>> {
    check_dt(dt)?;
    if n == 0 {
        return Err(SignalError::TooShort {
            what: "frequency axis length",
            needed: 1,
            got: 0,
        });
    }
    let df = 1.0 / (n as f64 * dt);
    Ok((0..=n / 2).map(|k| k as f64 * df).collect())
}

/// Single-sided amplitude spectrum: returns `(frequencies in Hz, amplitudes)` where a sine of
/// amplitude `a` on a bin centre shows amplitude `a` (`2|X_k|/n`, DC and Nyquist `|X_k|/n`).
pub fn amplitude_spectrum(x: &[f64], dt: f64) -> Result<(Vec<f64>, Vec<f64>)> {
    let freqs = frequencies(x.len(), dt)?;
    let spec = rfft(x)?;
    let n = x.len();
    let amps = spec
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let edge = k == 0 || (n % 2 == 0 && k == n / 2);
            c.norm() * if edge { 1.0 } else { 2.0 } / n as f64
        })
        .collect();
    Ok((freqs, amps))
}

/// Band-limited reconstruction with a one-off planner (see [`SpectrumPlanner::band_limit`]).
pub fn band_limit(x: &[f64], dt: f64, bands: &[(f64, f64)]) -> Result<Vec<f64>> {
    SpectrumPlanner::new().band_limit(x, dt, bands)
}

/// Mask-based band limiting with a one-off planner (see [`SpectrumPlanner::band_limit_mask`]).
pub fn band_limit_mask(x: &[f64], mask: &[bool]) -> Result<Vec<f64>> {
    SpectrumPlanner::new().band_limit_mask(x, mask)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roundtrip_and_sine_amplitude() {
        let n = 200;
        let dt = 0.01;
        // 5 Hz is bin 10 exactly (df = 0.5 Hz).
        let x: Vec<f64> = (0..n)
            .map(|k| 1.5 * (2.0 * std::f64::consts::PI * 5.0 * k as f64 * dt).sin() + 0.25)
            .collect();
        let mut p = SpectrumPlanner::new();
        let spec = p.rfft(&x).unwrap();
        let back = p.irfft(&spec, n).unwrap();
        for (a, b) in x.iter().zip(&back) {
            assert!((a - b).abs() < 1e-12);
        }
        let (f, a) = amplitude_spectrum(&x, dt).unwrap();
        assert!((f[10] - 5.0).abs() < 1e-12);
        assert!((a[10] - 1.5).abs() < 1e-12);
        assert!((a[0] - 0.25).abs() < 1e-12);
        assert!(a[11] < 1e-12);
    }

    #[test]
    fn band_limit_removes_out_of_band_component() {
        let n = 400;
        let dt = 0.01; // df = 0.25 Hz
        let tw = 2.0 * std::f64::consts::PI;
        let low: Vec<f64> = (0..n).map(|k| (tw * 2.0 * k as f64 * dt).sin()).collect();
        let x: Vec<f64> = (0..n)
            .map(|k| low[k] + 0.3 * (tw * 30.0 * k as f64 * dt).cos())
            .collect();
        let y = band_limit(&x, dt, &[(1.0, 3.0)]).unwrap();
        for (a, b) in y.iter().zip(&low) {
            assert!((a - b).abs() < 1e-10);
        }
        assert!(band_limit(&x, dt, &[(3.0, 1.0)]).is_err());
        assert!(band_limit_mask(&x, &[true; 3]).is_err());
    }

    #[test]
    fn errors_on_bad_input() {
        assert!(rfft(&[]).is_err());
        assert!(rfft(&[1.0, f64::NAN]).is_err());
        assert!(frequencies(10, 0.0).is_err());
        assert!(irfft(&[Complex::new(1.0, 0.0)], 5).is_err());
    }
}
