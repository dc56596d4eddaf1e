//! The records' own measurement-noise estimate, and what it becomes through a processing step.
//!
//! There is one noise estimate per channel of a record: the power-law floor that
//! [`crate::band`] fits to the upper half of the channel's spectrum ([`Band`]). Everything the
//! tool says about noise is derived from it here, one way:
//!
//! * [`snr_db`]: the SNR of a channel over a set of records — total signal power over total
//!   noise power, a lower bound where a record's spectrum shows no noise floor;
//! * [`filtered_noise_var`]: the variance the noise leaves after a linear filter (derivatives,
//!   a band limit, a combination of channels' terms), `2·Σ_k PSD(f_k)·|H(f_k)|²·Δf`.
//!
//! Identification (Criterion 1's cause of a low κ) and the diagnosis (the residual's verdict)
//! both call these, so the SNR and the noise shares they print are the same numbers.
//!
//! ```
//! use tfs_signal::band::reconstruct;
//! use tfs_signal::estimate::{filtered_noise_var, snr_db};
//! use tfs_signal::noise::{NoiseKind, add_noise_seeded};
//! let dt = 0.01;
//! let clean: Vec<f64> = (0..4096).map(|i| (0.5 * i as f64 * dt).sin()).collect();
//! let x = add_noise_seeded(&clean, 40.0, NoiseKind::White, 7).unwrap();
//! let band = reconstruct(&x, dt, None).band;
//! let snr = snr_db([(x.as_slice(), &band)]).unwrap();
//! assert!((snr.db - 40.0).abs() < 2.0 && !snr.lower_bound);
//! // Through no filter at all, the noise's whole variance.
//! let all = filtered_noise_var(&band, dt, f64::INFINITY, |_| (1.0, 0.0));
//! assert!((all / band.total_noise_var() - 1.0).abs() < 1e-9);
//! ```

use std::fmt;

use serde::Serialize;

use crate::band::Band;

/// A channel's SNR estimated from the records' noise floors: a value, or a lower bound when
/// some record shows no noise floor at all.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SnrEstimate {
    /// The SNR (dB).
    pub db: f64,
    /// True when some record's spectrum shows no noise floor (its upper half falls like the
    /// signal's own tail, steeper than any noise floor): `db` then comes from white noise at the
    /// lowest level that spectrum reaches, so the SNR is at least `db` if the noise is white
    /// (noise confined to low frequencies, like drift, cannot be seen there).
    pub lower_bound: bool,
}

impl SnrEstimate {
    /// The SNR (dB) above which records are called clean (the noise 80 dB below the signal).
    pub const CLEAN_DB: f64 = 80.0;

    /// True when the noise is estimated at least [`SnrEstimate::CLEAN_DB`] below the signal.
    pub fn clean(&self) -> bool {
        self.db >= Self::CLEAN_DB
    }
}

impl fmt::Display for SnrEstimate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.lower_bound {
            write!(
                f,
                "at least {:.1} dB if the noise is white; the spectrum shows no noise floor, so the data are clean or their noise sits at low frequencies",
                self.db
            )
        } else {
            write!(f, "{:.1} dB", self.db)
        }
    }
}

/// The variance of one record's channel noise by its floor (`band`), and whether it is an upper
/// bound: where the spectrum shows no noise floor, white noise at the lowest level the spectrum
/// reaches (an extrapolated floor would read clean records as 25–45 dB).
pub fn noise_var(band: &Band) -> (f64, bool) {
    if band.floor_is_signal_tail {
        (band.white_noise_var_bound(), true)
    } else {
        (band.total_noise_var(), false)
    }
}

/// The SNR of one channel over a set of records, each given as its samples and its band:
/// total signal power (each record's variance less its noise) over total noise power, records
/// weighted by their length. `None` without a noise estimate or without signal.
pub fn snr_db<'a>(records: impl IntoIterator<Item = (&'a [f64], &'a Band)>) -> Option<SnrEstimate> {
    let (mut sig, mut noise, mut lower_bound) = (0.0, 0.0, false);
    for (x, band) in records {
        if x.is_empty() {
            continue;
        }
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        let (nv, bound) = noise_var(band);
        lower_bound |= bound;
        sig += n * (var - nv).max(0.0);
        noise += n * nv;
    }
    (noise > 0.0 && sig > 0.0).then(|| SnrEstimate {
        db: 10.0 * (sig / noise).log10(),
        lower_bound,
    })
}

/// The variance the channel noise of `band` (sampled at `dt`) leaves after a linear filter
/// whose response at `f` Hz is `response(f)` = (re, im), over the bins up to `up_to_hz`:
/// `2·Σ_k PSD(f_k)·|H(f_k)|²·Δf` on the band's mirror spectrum. 0 without a floor model.
pub fn filtered_noise_var(
    band: &Band,
    dt: f64,
    up_to_hz: f64,
    response: impl Fn(f64) -> (f64, f64),
) -> f64 {
    if band.bin_hz <= 0.0 || band.mirror_len < 2 {
        return 0.0;
    }
    let last = band.mirror_len / 2;
    let kc = if up_to_hz.is_finite() {
        ((up_to_hz / band.bin_hz).floor().max(0.0) as usize).min(last)
    } else {
        last
    };
    (1..=kc)
        .map(|k| {
            let f = k as f64 * band.bin_hz;
            let (re, im) = response(f);
            band.noise_psd(f, dt) * (re * re + im * im)
        })
        .sum::<f64>()
        * 2.0
        * band.bin_hz
}

/// The variance one channel's noise (floor `band`, sampled at `dt`) leaves in an equation
/// residual `own·x'' − Σ c·θ_k` over the bins up to `up_to_hz`: `own` when the channel is the
/// equation's own displacement (its second derivative is the target), `terms` the equation's
/// linear terms in this channel as (derivative order, coefficient), and `filter(order, f)` the
/// response through which the processing sees the channel's derivative of that order. The
/// channel's noise enters the target and the terms coherently, so they are combined before the
/// power is taken.
///
/// A nonlinear equation sees the noise through its local gains (its partial derivatives along
/// the records), which vary: `terms` then holds the gains' means, and `spread` the gains'
/// variances over the samples as (derivative order, variance). A gain `g(t) = ḡ + δ(t)` that
/// varies slowly beside the noise leaves `ḡ`'s share plus `var(δ)` times the noise through that
/// derivative alone (the cross term averages out), which is what is added.
pub fn residual_noise_var(
    band: &Band,
    dt: f64,
    own: bool,
    terms: &[(usize, f64)],
    spread: &[(usize, f64)],
    up_to_hz: f64,
    filter: impl Fn(usize, f64) -> (f64, f64),
) -> f64 {
    let mean = filtered_noise_var(band, dt, up_to_hz, |f| {
        let (mut re, mut im) = if own { filter(2, f) } else { (0.0, 0.0) };
        for &(order, c) in terms {
            let (r, i) = filter(order, f);
            re -= c * r;
            im -= c * i;
        }
        (re, im)
    });
    spread
        .iter()
        .filter(|&&(_, var)| var > 0.0)
        .fold(mean, |acc, &(order, var)| {
            acc + var * filtered_noise_var(band, dt, up_to_hz, |f| filter(order, f))
        })
}

/// Which signal a noise share is of, from the records' cut-offs (Hz, lowest and highest):
/// `band-limited at 2.933 Hz`, or `band-limited at 2.933–3.808 Hz` when they differ.
/// Identification and the diagnosis state their cut-offs this way, so that the shares they print
/// can be compared.
pub fn band_words([lo, hi]: [f64; 2]) -> String {
    // Four significant digits, whatever the size.
    let sig = |v: f64| {
        let digits = if v > 0.0 {
            (3 - v.log10().floor() as i32).clamp(0, 12) as usize
        } else {
            0
        };
        format!("{v:.digits$}")
    };
    if !lo.is_finite() || !hi.is_finite() {
        "band-limited".to_string()
    } else if (hi - lo).abs() <= 1e-9 * hi.abs() {
        format!("band-limited at {} Hz", sig(lo))
    } else {
        format!("band-limited at {}–{} Hz", sig(lo), sig(hi))
    }
}

/// The response of the `order`-th derivative (0, 1 or 2) at `f` Hz, as (re, im): `(i2πf)^order`.
pub fn derivative_response(order: usize, f: f64) -> (f64, f64) {
    let w = 2.0 * std::f64::consts::PI * f;
    match order {
        0 => (1.0, 0.0),
        1 => (0.0, w),
        _ => (-w * w, 0.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::band::reconstruct;
    use crate::noise::{NoiseKind, add_noise_seeded};

    /// White noise at a known level through the second derivative: the estimate follows the
    /// analytic variance `σ²·(2π)⁴·∫f⁴df·2dt` within the floor fit's scatter.
    #[test]
    fn second_derivative_of_white_noise_matches_the_analytic_variance() {
        let dt = 0.01;
        let n = 8192;
        let clean: Vec<f64> = (0..n).map(|i| (0.7 * i as f64 * dt).sin()).collect();
        let x = add_noise_seeded(&clean, 30.0, NoiseKind::White, 3).unwrap();
        let band = reconstruct(&x, dt, None).band;
        let sigma2: f64 = clean.iter().map(|v| v * v).sum::<f64>() / n as f64 * 1e-3;
        let fc = 5.0;
        let got = filtered_noise_var(&band, dt, fc, |f| derivative_response(2, f));
        let w4 = (2.0 * std::f64::consts::PI).powi(4);
        let want = 2.0 * sigma2 * dt * w4 * fc.powi(5) / 5.0;
        assert!(
            (got / want - 1.0).abs() < 0.25,
            "got {got:.4e}, want {want:.4e}"
        );
    }

    /// The SNR of a record set with no noise is a bound, never a noisy estimate.
    #[test]
    fn clean_records_give_a_bound() {
        let dt = 0.01;
        let x: Vec<f64> = (0..4096).map(|i| (0.3 * i as f64 * dt).sin()).collect();
        let band = reconstruct(&x, dt, None).band;
        let snr = snr_db([(x.as_slice(), &band)]).unwrap();
        assert!(snr.lower_bound && snr.db > 60.0, "{snr}");
    }
}
