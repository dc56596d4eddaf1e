//! Signal processing for tfs: the one FFT planner, windows with analytic time derivatives and
//! windowed transforms, band-limited reconstruction with its noise floor, numerical
//! differentiation, noise at a given SNR and excitation signals.
//!
//! Architecture invariant: this crate does no I/O and knows nothing about models; every function
//! works on plain `&[f64]` sample slices with a uniform time step `dt` (seconds).
//!
//! * [`window`] — [`Window`] shapes sampled with analytic first and second time derivatives, as
//!   needed by the derivative-transfer (weak) form
//!   `∫ x'' w e^{−iωt} dt = ∫ x (w'' − 2iω w' − ω² w) e^{−iωt} dt`.
//! * [`fft`] — the shared plan cache and thin helpers over `realfft` ([`SpectrumPlanner`],
//!   [`rfft`], [`irfft`], [`frequencies`], [`band_limit`], fast lengths).
//! * [`windowed`] — overlapping windows and the transform of a signal times the periodic `sin⁴`
//!   window at chosen bins, plain or in the weak form of its derivatives ([`windowed_bins`]).
//! * [`floor`] — the noise floor of a spectrum ([`NoiseFloor`]) and the cut-off that balances
//!   noise let in against signal lost ([`choose_cutoff`]).
//! * [`band`] — band-limited reconstruction with spectral derivatives, the band chosen from the
//!   data ([`band::reconstruct`], [`Band`]), and draws of the noise it carries
//!   ([`band::noise_draw`]).
//! * [`estimate`] — the records' own measurement-noise estimate, one per channel (its floor),
//!   and what it becomes through a processing step: the SNR ([`estimate::snr_db`]) and the
//!   variance left after derivatives and band limits ([`estimate::filtered_noise_var`]).
//! * [`diff`] — central differences, Savitzky–Golay and spectral derivatives behind one
//!   [`Differentiator`] enum.
//! * [`noise`] — white and pink Gaussian noise scaled exactly to a requested SNR.
//! * [`excitation`] — linear/log sweeps, sines, multisines and growing noise bursts.
//!
//! ```
//! use tfs_signal::{Differentiator, NoiseKind, Sweep, SweepKind, Excitation, Window, noise};
//!
//! // A 2 s linear sweep 1 → 5 Hz sampled at 1 kHz.
//! let dt = 1e-3;
//! let t = tfs_signal::time_grid(2001, dt);
//! let sweep = Sweep::new(SweepKind::Linear, 1.0, 5.0, 2.0, 1.0, 0.1).unwrap();
//! let x = sweep.sample(&t);
//!
//! // Its second derivative by Savitzky–Golay (quartic fits over 21 points).
//! let sg = Differentiator::SavitzkyGolay { half_window: 10, poly_order: 4 };
//! let acc = sg.apply(&x, dt, 2).unwrap();
//! assert_eq!(acc.len(), x.len());
//!
//! // Pink noise at exactly 20 dB SNR (on mean-square signal power), reproducible by seed.
//! let n = noise::noise_for(&x, 20.0, NoiseKind::Pink, 7).unwrap();
//! let snr = noise::snr_db(&x, &n).unwrap();
//! assert!((snr - 20.0).abs() < 1e-9);
//!
//! // A window whose value and slope vanish at both ends, with analytic time derivatives.
//! let w = Window::HannSquared.sample(x.len(), dt).unwrap();
//! assert!(Window::HannSquared.supports_derivative_transfer());
//! assert_eq!(w.w[0], 0.0);
//! assert_eq!(w.dw.len(), x.len());
//! ```

#![warn(missing_docs)]

pub mod band;
pub mod diff;
pub mod ends;
pub mod estimate;
pub mod excitation;
pub mod fft;
pub mod floor;
pub mod noise;
pub mod spectra;
pub mod window;
pub mod windowed;

pub use band::{Band, NoiseSpectrum, Smoothed};
pub use diff::{
    Differentiator, SpectralEnds, central_difference, central_difference4, savitzky_golay,
    savitzky_golay_weights, spectral_derivative, spectral_derivative_with,
};
pub use excitation::{Excitation, Multisine, NoiseBurst, Sine, Sweep, SweepKind};
pub use fft::{
    SpectrumPlanner, amplitude_spectrum, band_limit, band_limit_mask, fast_even_len, frequencies,
    irfft, rfft, smooth_len,
};
pub use floor::{NoiseFloor, choose_cutoff};
pub use noise::{NoiseKind, SnrReference};
/// Complex numbers as used by the FFT helpers (re-exported from `realfft`'s `num_complex`).
pub use realfft::num_complex::Complex;
pub use window::{Window, WindowSamples};
pub use windowed::{Weighting, bin_omegas, window_layout, windowed_bins};

/// Errors raised by signal-processing routines; every message names the offending parameter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SignalError {
    /// An input sequence was empty or too short for the requested operation.
    #[error(
        "{what}: need at least {needed} samples, got {got}; supply a longer signal or reduce the stencil/window"
    )]
    TooShort {
        /// Which input or operation.
        what: &'static str,
        /// Minimum number of samples required.
        needed: usize,
        /// Number of samples given.
        got: usize,
    },
    /// A scalar parameter was out of its valid range.
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// The offending value, formatted.
        value: String,
        /// What is required instead.
        reason: String,
    },
    /// An input sample was NaN or infinite.
    #[error("{what}: sample {index} is not finite ({value}); clean or interpolate the data first")]
    NonFinite {
        /// Which input.
        what: &'static str,
        /// Index of the first bad sample.
        index: usize,
        /// The bad value.
        value: f64,
    },
    /// A signal has zero power (all zeros, or constant for a variance-based SNR).
    #[error(
        "{what}: signal power is zero, so an SNR-based noise level is undefined; give an absolute noise level instead"
    )]
    ZeroPower {
        /// Which input.
        what: &'static str,
    },
    /// Two inputs that must have the same length do not.
    #[error("{what}: lengths differ ({left} vs {right}); pass sequences of equal length")]
    LengthMismatch {
        /// Which inputs.
        what: &'static str,
        /// Length of the first.
        left: usize,
        /// Length of the second.
        right: usize,
    },
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, SignalError>;

/// Uniform time grid `t_k = k·dt`, `k = 0..n`.
pub fn time_grid(n: usize, dt: f64) -> Vec<f64> {
    (0..n).map(|k| k as f64 * dt).collect()
}

pub(crate) fn invalid(
    name: &'static str,
    value: impl std::fmt::Display,
    reason: impl Into<String>,
) -> SignalError {
    SignalError::InvalidParameter {
        name,
        value: value.to_string(),
        reason: reason.into(),
    }
}

/// Checks that `dt` is finite and positive.
pub(crate) fn check_dt(dt: f64) -> Result<()> {
    if dt.is_finite() && dt > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            "dt",
            dt,
            "the sample interval must be a finite positive number of seconds",
        ))
    }
}

/// Checks length ≥ `needed` and that every sample is finite.
pub(crate) fn check_signal(what: &'static str, x: &[f64], needed: usize) -> Result<()> {
    if x.len() < needed {
        return Err(SignalError::TooShort {
            what,
            needed,
            got: x.len(),
        });
    }
    if let Some((index, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(SignalError::NonFinite { what, index, value });
    }
    Ok(())
}
