//! Excitation signals for driving simulations: linear and logarithmic sweeps, sines, random-phase
//! multisines and band-limited noise bursts, all evaluable at any time `t` (seconds) so that ODE
//! integrators can sample them between grid points.

use crate::{Result, invalid};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::f64::consts::PI;

/// A deterministic input signal `u(t)`.
pub trait Excitation {
    /// Value at time `t` in seconds.
    fn value(&self, t: f64) -> f64;
    /// Values at each time in `t`.
    fn sample(&self, t: &[f64]) -> Vec<f64> {
        t.iter().map(|&s| self.value(s)).collect()
    }
}

impl<E: Excitation + ?Sized> Excitation for &E {
    fn value(&self, t: f64) -> f64 {
        (**self).value(t)
    }
}

impl<E: Excitation + ?Sized> Excitation for Box<E> {
    fn value(&self, t: f64) -> f64 {
        (**self).value(t)
    }
}

fn check_finite(name: &'static str, v: f64) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(invalid(name, v, "must be a finite number"))
    }
}

fn check_positive(name: &'static str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(name, v, "must be a finite positive number"))
    }
}

fn check_nonneg(name: &'static str, v: f64) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(name, v, "must be a finite number ≥ 0"))
    }
}

fn check_ramp(ramp: f64, duration: f64) -> Result<()> {
    check_nonneg("ramp", ramp)?;
    if 2.0 * ramp > duration {
        return Err(invalid(
            "ramp",
            ramp,
            format!("ramp-in plus ramp-out (2·ramp) must fit in the duration {duration} s"),
        ));
    }
    Ok(())
}

/// Trapezoidal envelope: 0 outside `[0, T]`, linear ramps of `ramp` seconds at both ends, 1 between.
fn envelope(t: f64, duration: f64, ramp: f64) -> f64 {
    if !(0.0..=duration).contains(&t) {
        return 0.0;
    }
    if ramp <= 0.0 {
        return 1.0;
    }
    (t / ramp).min((duration - t) / ramp).min(1.0)
}

/// Frequency law of a [`Sweep`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SweepKind {
    /// Instantaneous frequency `f0 + (f1 − f0)·t/T`.
    Linear,
    /// Instantaneous frequency `f0·(f1/f0)^{t/T}` (exponential); needs `f0, f1 > 0`, `f0 ≠ f1`.
    Log,
}

/// A frequency sweep from `f0` to `f1` Hz over `duration` seconds with amplitude `amplitude`,
/// multiplied by a trapezoidal envelope with linear ramps of `ramp` seconds; zero outside `[0, T]`.
/// Linear: `u(t) = a·env(t)·sin(2π(f0 t + (f1 − f0) t²/(2T)))`.
/// Log: `u(t) = a·env(t)·sin(2π f0 T (r^{t/T} − 1)/ln r)`, `r = f1/f0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sweep {
    kind: SweepKind,
    f0: f64,
    f1: f64,
    duration: f64,
    amplitude: f64,
    ramp: f64,
}

impl Sweep {
    /// Validated sweep: `duration > 0`; frequencies ≥ 0 (linear) or > 0 and distinct (log);
    /// finite amplitude; `0 ≤ 2·ramp ≤ duration`.
    pub fn new(
        kind: SweepKind,
        f0: f64,
        f1: f64,
        duration: f64,
        amplitude: f64,
        ramp: f64,
    ) -> Result<Self> {
        check_positive("duration", duration)?;
        check_finite("amplitude", amplitude)?;
        match kind {
            SweepKind::Linear => {
                check_nonneg("f0", f0)?;
                check_nonneg("f1", f1)?;
            }
            SweepKind::Log => {
                check_positive("f0", f0)?;
                check_positive("f1", f1)?;
                if f0 == f1 {
                    return Err(invalid(
                        "f1",
                        f1,
                        "a log sweep needs f1 ≠ f0; use a Sine or a linear sweep for a constant frequency",
                    ));
                }
            }
        }
        check_ramp(ramp, duration)?;
        Ok(Self {
            kind,
            f0,
            f1,
            duration,
            amplitude,
            ramp,
        })
    }

    /// Sweep kind.
    pub fn kind(&self) -> SweepKind {
        self.kind
    }
    /// Start frequency in Hz.
    pub fn f0(&self) -> f64 {
        self.f0
    }
    /// End frequency in Hz.
    pub fn f1(&self) -> f64 {
        self.f1
    }
    /// Duration in seconds.
    pub fn duration(&self) -> f64 {
        self.duration
    }
    /// Amplitude.
    pub fn amplitude(&self) -> f64 {
        self.amplitude
    }
    /// Ramp length in seconds.
    pub fn ramp(&self) -> f64 {
        self.ramp
    }

    /// Phase `φ(t)` in radians (so that `u = a·env·sin φ`).
    pub fn phase(&self, t: f64) -> f64 {
        let big_t = self.duration;
        match self.kind {
            SweepKind::Linear => {
                2.0 * PI * (self.f0 * t + (self.f1 - self.f0) * t * t / (2.0 * big_t))
            }
            SweepKind::Log => {
                let lr = (self.f1 / self.f0).ln();
                2.0 * PI * self.f0 * big_t * ((lr * t / big_t).exp() - 1.0) / lr
            }
        }
    }

    /// Instantaneous frequency `φ'(t)/2π` in Hz.
    pub fn instantaneous_frequency(&self, t: f64) -> f64 {
        match self.kind {
            SweepKind::Linear => self.f0 + (self.f1 - self.f0) * t / self.duration,
            SweepKind::Log => self.f0 * (self.f1 / self.f0).powf(t / self.duration),
        }
    }
}

impl Excitation for Sweep {
    fn value(&self, t: f64) -> f64 {
        let e = envelope(t, self.duration, self.ramp);
        if e == 0.0 {
            0.0
        } else {
            self.amplitude * e * self.phase(t).sin()
        }
    }
}

/// `u(t) = a·min(1, t/ramp)·sin(2πft + phase)` for `t ≥ 0`, zero before; a linear ramp-in only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sine {
    freq: f64,
    amplitude: f64,
    phase: f64,
    ramp: f64,
}

impl Sine {
    /// Validated sine: `freq ≥ 0`, finite amplitude and phase (radians), `ramp ≥ 0` seconds.
    pub fn new(freq: f64, amplitude: f64, phase: f64, ramp: f64) -> Result<Self> {
        check_nonneg("freq", freq)?;
        check_finite("amplitude", amplitude)?;
        check_finite("phase", phase)?;
        check_nonneg("ramp", ramp)?;
        Ok(Self {
            freq,
            amplitude,
            phase,
            ramp,
        })
    }
    /// Frequency in Hz.
    pub fn freq(&self) -> f64 {
        self.freq
    }
}

impl Excitation for Sine {
    fn value(&self, t: f64) -> f64 {
        if t < 0.0 {
            return 0.0;
        }
        let e = if self.ramp > 0.0 {
            (t / self.ramp).min(1.0)
        } else {
            1.0
        };
        self.amplitude * e * (2.0 * PI * self.freq * t + self.phase).sin()
    }
}

/// Random-phase multisine: `n_tones` equal-amplitude tones equally spaced over
/// `[f_lo, f_hi]` Hz with phases uniform in `[0, 2π)` from a seeded `ChaCha8Rng`, scaled so
/// the RMS (over whole common periods) equals `rms`; trapezoidal envelope over `[0, duration]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Multisine {
    freqs: Vec<f64>,
    phases: Vec<f64>,
    tone_amplitude: f64,
    duration: f64,
    ramp: f64,
}

impl Multisine {
    /// Validated multisine; `0 ≤ f_lo ≤ f_hi`, `n_tones ≥ 1` (`f_lo < f_hi` when `n_tones > 1`),
    /// `rms` finite, `duration > 0`, `0 ≤ 2·ramp ≤ duration`.
    pub fn new(
        f_lo: f64,
        f_hi: f64,
        n_tones: usize,
        rms: f64,
        duration: f64,
        ramp: f64,
        seed: u64,
    ) -> Result<Self> {
        check_nonneg("f_lo", f_lo)?;
        check_nonneg("f_hi", f_hi)?;
        if f_hi < f_lo || (n_tones > 1 && f_hi == f_lo) {
            return Err(invalid(
                "f_hi",
                f_hi,
                format!("must exceed f_lo = {f_lo} (equal only for a single tone)"),
            ));
        }
        if n_tones == 0 {
            return Err(invalid("n_tones", 0, "a multisine needs at least one tone"));
        }
        check_finite("rms", rms)?;
        check_positive("duration", duration)?;
        check_ramp(ramp, duration)?;
        let freqs: Vec<f64> = if n_tones == 1 {
            vec![f_lo]
        } else {
            (0..n_tones)
                .map(|k| f_lo + (f_hi - f_lo) * k as f64 / (n_tones - 1) as f64)
                .collect()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let phases = (0..n_tones)
            .map(|_| rng.random::<f64>() * 2.0 * PI)
            .collect();
        Ok(Self {
            freqs,
            phases,
            tone_amplitude: rms * (2.0 / n_tones as f64).sqrt(),
            duration,
            ramp,
        })
    }
    /// Tone frequencies in Hz.
    pub fn frequencies(&self) -> &[f64] {
        &self.freqs
    }
}

impl Excitation for Multisine {
    fn value(&self, t: f64) -> f64 {
        let e = envelope(t, self.duration, self.ramp);
        if e == 0.0 {
            return 0.0;
        }
        let s: f64 = self
            .freqs
            .iter()
            .zip(&self.phases)
            .map(|(f, p)| (2.0 * PI * f * t + p).sin())
            .sum();
        e * self.tone_amplitude * s
    }
}

/// Band-limited Gaussian-like noise whose amplitude grows linearly from 0 at `t = 0` to `rms`
/// at `t = duration` (zero outside). Realised as a sum of `components` cosines/sines at random
/// frequencies uniform in `[f_lo, f_hi]` with independent Gaussian coefficients of variance
/// `1/components` (a unit-variance stationary process in the band, by the central limit
/// theorem), all from a seeded `ChaCha8Rng`, so it is defined at every `t`.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseBurst {
    freqs: Vec<f64>,
    a: Vec<f64>,
    b: Vec<f64>,
    rms: f64,
    duration: f64,
}

impl NoiseBurst {
    /// Validated burst: `0 ≤ f_lo < f_hi`, `components ≥ 1`, `rms` finite, `duration > 0`.
    pub fn new(
        f_lo: f64,
        f_hi: f64,
        rms: f64,
        duration: f64,
        components: usize,
        seed: u64,
    ) -> Result<Self> {
        check_nonneg("f_lo", f_lo)?;
        check_positive("f_hi", f_hi)?;
        if f_hi <= f_lo {
            return Err(invalid("f_hi", f_hi, format!("must exceed f_lo = {f_lo}")));
        }
        if components == 0 {
            return Err(invalid(
                "components",
                0,
                "use at least one component (a few hundred give Gaussian-like statistics)",
            ));
        }
        check_finite("rms", rms)?;
        check_positive("duration", duration)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let sd = (1.0 / components as f64).sqrt();
        let mut freqs = Vec::with_capacity(components);
        let mut a = Vec::with_capacity(components);
        let mut b = Vec::with_capacity(components);
        for _ in 0..components {
            freqs.push(f_lo + (f_hi - f_lo) * rng.random::<f64>());
            a.push(sd * rng.sample::<f64, _>(StandardNormal));
            b.push(sd * rng.sample::<f64, _>(StandardNormal));
        }
        Ok(Self {
            freqs,
            a,
            b,
            rms,
            duration,
        })
    }
}

impl Excitation for NoiseBurst {
    fn value(&self, t: f64) -> f64 {
        if !(0.0..=self.duration).contains(&t) {
            return 0.0;
        }
        let s: f64 = self
            .freqs
            .iter()
            .zip(self.a.iter().zip(&self.b))
            .map(|(f, (a, b))| {
                let (sn, cs) = (2.0 * PI * f * t).sin_cos();
                a * cs + b * sn
            })
            .sum();
        self.rms * (t / self.duration) * s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation() {
        assert!(Sweep::new(SweepKind::Linear, 1.0, 5.0, -1.0, 1.0, 0.0).is_err());
        assert!(Sweep::new(SweepKind::Log, 1.0, 0.0, 1.0, 1.0, 0.0).is_err());
        assert!(Sweep::new(SweepKind::Log, 2.0, 2.0, 1.0, 1.0, 0.0).is_err());
        assert!(Sweep::new(SweepKind::Linear, 1.0, 5.0, 1.0, 1.0, 0.6).is_err());
        assert!(Sweep::new(SweepKind::Linear, 1.0, 5.0, 1.0, f64::NAN, 0.0).is_err());
        assert!(Sine::new(-1.0, 1.0, 0.0, 0.0).is_err());
        assert!(Multisine::new(5.0, 1.0, 4, 1.0, 1.0, 0.0, 1).is_err());
        assert!(Multisine::new(1.0, 5.0, 0, 1.0, 1.0, 0.0, 1).is_err());
        assert!(NoiseBurst::new(1.0, 1.0, 1.0, 1.0, 10, 1).is_err());
        let e = Sweep::new(SweepKind::Log, 0.0, 5.0, 1.0, 1.0, 0.0).unwrap_err();
        assert!(e.to_string().contains("f0"));
    }

    #[test]
    fn linear_sweep_closed_form_and_envelope() {
        let (f0, f1, big_t, a, r) = (0.5, 4.0, 10.0, 2.0, 1.0);
        let s = Sweep::new(SweepKind::Linear, f0, f1, big_t, a, r).unwrap();
        for &t in &[1.3, 5.0, 8.7] {
            let want = a * (2.0 * PI * (f0 * t + (f1 - f0) * t * t / (2.0 * big_t))).sin();
            assert!((s.value(t) - want).abs() < 1e-12);
        }
        // Ramp-in at half height and ramp-out.
        let t = 0.5;
        let want = 0.5 * a * (2.0 * PI * (f0 * t + (f1 - f0) * t * t / (2.0 * big_t))).sin();
        assert!((s.value(t) - want).abs() < 1e-12);
        assert_eq!(s.value(-0.1), 0.0);
        assert_eq!(s.value(10.1), 0.0);
        assert!(s.value(10.0).abs() < 1e-12);
    }

    #[test]
    fn log_sweep_phase_derivative_is_instantaneous_frequency() {
        let s = Sweep::new(SweepKind::Log, 1.0, 20.0, 5.0, 1.0, 0.0).unwrap();
        for &t in &[0.0, 1.0, 2.5, 4.9] {
            let h = 1e-6;
            let num = (s.phase(t + h) - s.phase(t - h)) / (2.0 * h) / (2.0 * PI);
            assert!(
                (num - s.instantaneous_frequency(t)).abs() < 1e-6 * s.instantaneous_frequency(t)
            );
        }
        assert!((s.instantaneous_frequency(5.0) - 20.0).abs() < 1e-12);
    }

    #[test]
    fn multisine_rms_and_sine_ramp() {
        // Integer tone frequencies: over 1 s every tone completes whole periods.
        let m = Multisine::new(1.0, 10.0, 10, 0.7, 100.0, 0.0, 4).unwrap();
        let n = 20000;
        let u: Vec<f64> = (0..n).map(|k| m.value(1.0 + k as f64 / n as f64)).collect();
        let rms = (u.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        assert!((rms - 0.7).abs() < 1e-9, "rms {rms}");
        let s = Sine::new(2.0, 3.0, 0.4, 2.0).unwrap();
        assert!((s.value(1.0) - 1.5 * (2.0 * PI * 2.0 + 0.4).sin()).abs() < 1e-12);
        assert_eq!(s.value(-1.0), 0.0);
        let boxed: Box<dyn Excitation> = Box::new(s);
        assert_eq!(boxed.sample(&[1.0]), vec![s.value(1.0)]);
    }

    #[test]
    fn noise_burst_grows_and_is_band_limited() {
        let dur = 200.0;
        let b = NoiseBurst::new(2.0, 4.0, 1.0, dur, 300, 11).unwrap();
        let dt = 0.02;
        let n = (dur / dt) as usize;
        let u: Vec<f64> = (0..n).map(|k| b.value(k as f64 * dt)).collect();
        let q = n / 4;
        let ms = |s: &[f64]| s.iter().map(|v| v * v).sum::<f64>() / s.len() as f64;
        // Mean square grows like t²: last quarter ≫ first quarter (ratio (7/8)²/(1/8)² ≈ 49 in expectation).
        assert!(ms(&u[3 * q..]) > 10.0 * ms(&u[..q]));
        // Remove the envelope and check the spectrum is confined to the band.
        let stat: Vec<f64> = (1..n)
            .map(|k| b.value(k as f64 * dt) / (k as f64 * dt / dur))
            .collect();
        let (f, a) = crate::amplitude_spectrum(&stat, dt).unwrap();
        let inband: f64 = f
            .iter()
            .zip(&a)
            .filter(|(f, _)| **f >= 1.9 && **f <= 4.1)
            .map(|(_, a)| a * a)
            .sum();
        let outband: f64 = f
            .iter()
            .zip(&a)
            .filter(|(f, _)| **f < 1.5 || **f > 4.5)
            .map(|(_, a)| a * a)
            .sum();
        assert!(outband < 0.01 * inband, "out {outband} in {inband}");
    }
}
