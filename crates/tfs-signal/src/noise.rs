//! Additive Gaussian noise (white or pink) scaled exactly to a requested signal-to-noise ratio.
//!
//! SNR is `10·log10(P_signal / P_noise)` dB, where by default ([`SnrReference::MeanSquare`]) both
//! powers are mean squares, `P = (1/n)·Σ v_k²`; [`SnrReference::Variance`] uses the signal's
//! variance instead (useful when the signal has a large offset). The generated noise sequence is
//! rescaled so its mean square equals `P_signal·10^(−SNR/10)` exactly, so the realised SNR equals
//! the request to rounding. Each channel of a multi-channel record gets its own SNR relative to its
//! own power ([`add_noise_channels`]). Generators are seeded `ChaCha8Rng`s: same seed, same noise.

use crate::fft::SpectrumPlanner;
use crate::{Complex, Result, SignalError, check_signal, invalid};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Spectral shape of the noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NoiseKind {
    /// Independent Gaussian samples (flat power spectrum).
    #[default]
    White,
    /// Gaussian noise with power spectral density ∝ 1/f (white noise shaped by `1/√f` in the
    /// frequency domain, DC removed).
    Pink,
}

/// Which signal power the SNR refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SnrReference {
    /// Mean square of the signal, `(1/n)Σx²` (the default).
    #[default]
    MeanSquare,
    /// Variance of the signal, `(1/n)Σ(x − x̄)²`.
    Variance,
}

/// Mean square `(1/n)Σ v²` of a slice (0 for an empty slice).
pub fn mean_square(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().map(|a| a * a).sum::<f64>() / v.len() as f64
    }
}

fn variance(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let m = v.iter().sum::<f64>() / v.len() as f64;
    v.iter().map(|a| (a - m) * (a - m)).sum::<f64>() / v.len() as f64
}

/// Signal power under the chosen reference.
pub fn signal_power(x: &[f64], reference: SnrReference) -> f64 {
    match reference {
        SnrReference::MeanSquare => mean_square(x),
        SnrReference::Variance => variance(x),
    }
}

/// Realised SNR in dB of `signal` against `noise` (mean-square powers).
pub fn snr_db(signal: &[f64], noise: &[f64]) -> Result<f64> {
    check_signal("SNR signal", signal, 1)?;
    check_signal("SNR noise", noise, 1)?;
    if signal.len() != noise.len() {
        return Err(SignalError::LengthMismatch {
            what: "signal vs noise",
            left: signal.len(),
            right: noise.len(),
        });
    }
    let pn = mean_square(noise);
    if pn == 0.0 {
        return Err(SignalError::ZeroPower {
            what: "noise for SNR",
        });
    }
    Ok(10.0 * (mean_square(signal) / pn).log10())
}

/// `n` samples of unscaled noise of the given kind (white: unit-variance Gaussian; pink: shaped).
pub fn raw_noise<R: Rng + ?Sized>(n: usize, kind: NoiseKind, rng: &mut R) -> Result<Vec<f64>> {
    if n == 0 {
        return Err(SignalError::TooShort {
            what: "noise length",
            needed: 1,
            got: 0,
        });
    }
    let white: Vec<f64> = (0..n)
        .map(|_| rng.sample::<f64, _>(StandardNormal))
        .collect();
    match kind {
        NoiseKind::White => Ok(white),
        NoiseKind::Pink => {
            if n < 2 {
                return Err(SignalError::TooShort {
                    what: "pink noise length",
                    needed: 2,
                    got: n,
                });
            }
            let mut planner = SpectrumPlanner::new();
            let mut spec = planner.rfft(&white)?;
            spec[0] = Complex::new(0.0, 0.0);
            // Bin index k is proportional to frequency; the scale is irrelevant after normalisation.
            for (k, c) in spec.iter_mut().enumerate().skip(1) {
                *c /= (k as f64).sqrt();
            }
            planner.irfft(&spec, n)
        }
    }
}

fn check_snr(snr_db: f64) -> Result<()> {
    if snr_db.is_finite() {
        Ok(())
    } else {
        Err(invalid(
            "snr_db",
            snr_db,
            "the signal-to-noise ratio must be a finite number of dB",
        ))
    }
}

/// Noise for `x` at `snr_db` under `reference`, drawn from `rng`, scaled exactly to the target power.
pub fn noise_with<R: Rng + ?Sized>(
    x: &[f64],
    snr_db: f64,
    kind: NoiseKind,
    reference: SnrReference,
    rng: &mut R,
) -> Result<Vec<f64>> {
    check_snr(snr_db)?;
    check_signal("signal for noise", x, 1)?;
    let ps = signal_power(x, reference);
    if ps == 0.0 {
        return Err(SignalError::ZeroPower {
            what: "signal for noise",
        });
    }
    let target = ps * 10f64.powf(-snr_db / 10.0);
    let mut noise = raw_noise(x.len(), kind, rng)?;
    let p = mean_square(&noise);
    if p == 0.0 {
        // Only possible for degenerate lengths (e.g. pink noise of length 2 hitting zero).
        return Err(SignalError::ZeroPower {
            what: "generated noise (signal too short)",
        });
    }
    let scale = (target / p).sqrt();
    noise.iter_mut().for_each(|v| *v *= scale);
    Ok(noise)
}

/// `x` plus noise of `kind` at `snr_db` (mean-square reference), drawn from `rng`.
pub fn add_noise<R: Rng + ?Sized>(
    x: &[f64],
    snr_db: f64,
    kind: NoiseKind,
    rng: &mut R,
) -> Result<Vec<f64>> {
    let n = noise_with(x, snr_db, kind, SnrReference::MeanSquare, rng)?;
    Ok(x.iter().zip(&n).map(|(a, b)| a + b).collect())
}

/// The noise sequence (not the noisy signal) for `x` at `snr_db`, from a `ChaCha8Rng` seeded with `seed`.
pub fn noise_for(x: &[f64], snr_db: f64, kind: NoiseKind, seed: u64) -> Result<Vec<f64>> {
    noise_with(
        x,
        snr_db,
        kind,
        SnrReference::MeanSquare,
        &mut ChaCha8Rng::seed_from_u64(seed),
    )
}

/// `n` independent standard normal samples (mean 0, variance 1) from a `ChaCha8Rng` seeded with
/// `seed`: the raw material for noise of any other spectrum (shape it in the frequency domain).
pub fn standard_normal(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| rng.sample::<f64, _>(StandardNormal))
        .collect()
}

/// `x` plus noise at `snr_db`, from a `ChaCha8Rng` seeded with `seed`.
pub fn add_noise_seeded(x: &[f64], snr_db: f64, kind: NoiseKind, seed: u64) -> Result<Vec<f64>> {
    add_noise(x, snr_db, kind, &mut ChaCha8Rng::seed_from_u64(seed))
}

/// Adds noise to every channel at the same `snr_db`, each relative to its own power under
/// `reference`. Channel `c` uses stream `c` of a `ChaCha8Rng` seeded with `seed`, so channels are
/// independent and adding a channel does not change the noise of the others.
pub fn add_noise_channels(
    channels: &[Vec<f64>],
    snr_db: f64,
    kind: NoiseKind,
    reference: SnrReference,
    seed: u64,
) -> Result<Vec<Vec<f64>>> {
    channels
        .iter()
        .enumerate()
        .map(|(c, x)| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(c as u64);
            let n = noise_with(x, snr_db, kind, reference, &mut rng)?;
            Ok(x.iter().zip(&n).map(|(a, b)| a + b).collect())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors() {
        assert!(matches!(
            noise_for(&[], 10.0, NoiseKind::White, 1),
            Err(SignalError::TooShort { .. })
        ));
        assert!(matches!(
            noise_for(&[0.0; 8], 10.0, NoiseKind::White, 1),
            Err(SignalError::ZeroPower { .. })
        ));
        assert!(matches!(
            noise_for(&[1.0; 8], f64::NAN, NoiseKind::White, 1),
            Err(SignalError::InvalidParameter { .. })
        ));
        assert!(matches!(
            noise_for(&[1.0, f64::INFINITY], 10.0, NoiseKind::White, 1),
            Err(SignalError::NonFinite { .. })
        ));
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        assert!(
            noise_with(
                &[2.0; 8],
                10.0,
                NoiseKind::White,
                SnrReference::Variance,
                &mut rng
            )
            .is_err()
        );
    }

    #[test]
    fn reproducible_and_seed_dependent() {
        let x: Vec<f64> = (0..64).map(|k| (k as f64 * 0.3).sin()).collect();
        let a = noise_for(&x, 10.0, NoiseKind::Pink, 5).unwrap();
        let b = noise_for(&x, 10.0, NoiseKind::Pink, 5).unwrap();
        let c = noise_for(&x, 10.0, NoiseKind::Pink, 6).unwrap();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn variance_reference_ignores_offset() {
        let x: Vec<f64> = (0..1000).map(|k| 5.0 + (k as f64 * 0.1).sin()).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let n = noise_with(&x, 0.0, NoiseKind::White, SnrReference::Variance, &mut rng).unwrap();
        assert!((mean_square(&n) - variance(&x)).abs() < 1e-12 * variance(&x));
    }

    #[test]
    fn channels_are_independent_streams() {
        let ch = vec![vec![1.0, -1.0, 2.0, 0.5], vec![10.0, 3.0, -4.0, 1.0]];
        let y =
            add_noise_channels(&ch, 20.0, NoiseKind::White, SnrReference::MeanSquare, 9).unwrap();
        for (x, yy) in ch.iter().zip(&y) {
            let n: Vec<f64> = yy.iter().zip(x).map(|(a, b)| a - b).collect();
            assert!((snr_db(x, &n).unwrap() - 20.0).abs() < 1e-9);
        }
        let y1 = add_noise_channels(
            &ch[..1],
            20.0,
            NoiseKind::White,
            SnrReference::MeanSquare,
            9,
        )
        .unwrap();
        assert_eq!(y1[0], y[0]);
    }
}
