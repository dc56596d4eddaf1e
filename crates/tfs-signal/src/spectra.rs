//! The mirror spectra a band search transforms (the signal itself and the remainder after each
//! end trend tried), with the noise floor fitted to each, and the cut-off chosen on one of them.
//! A search can keep them ([`Spectra`]) so that a second search on the same signal — another
//! cut-off, the same end trends — transforms none of them again: the spectra and floors it reads
//! are the same values, so it finds the same band to the bit.

use std::sync::Arc;

use crate::Complex;
use crate::ends::EndTrend;
use crate::fft::{fast_even_len, plan_forward, with_work};
use crate::floor::{NoiseFloor, choose_cutoff_on, cutoff_cost_on};

/// Mirror-extended spectrum of `x`: the even extension `x, reversed x` (length 2N, continuous at
/// both ends), lengthened to the fast FFT length `M = fast_even_len(2N)` by holding the end values
/// `x_{N−1}` and `x_0` for `(M − 2N)/2` samples at each join (the extension stays even). For
/// record lengths like 50,005 samples, 2N has large prime factors and the transform is ~3× slower;
/// the hold adds well under 1 % to the length and touches only the reconstruction's last and
/// first few samples. Returns the spectrum (bins 0..=M/2) and M.
pub(crate) fn mirror_spectrum(x: &[f64]) -> (Vec<Complex<f64>>, usize) {
    let n = x.len();
    let m = fast_even_len(2 * n);
    let pad = (m - 2 * n) / 2;
    let fft = plan_forward(m);
    let mut spec = fft.make_output_vec();
    with_work(|w| {
        let buf = &mut w.real;
        buf.resize(m, 0.0);
        buf[..n].copy_from_slice(x);
        buf[n..n + pad].fill(x[n - 1]);
        for i in 0..n {
            buf[n + pad + n - 1 - i] = x[i];
        }
        buf[2 * n + pad..].fill(x[0]);
        w.scratch
            .resize(fft.get_scratch_len(), Complex::new(0.0, 0.0));
        fft.process_with_scratch(buf, &mut spec, &mut w.scratch)
            .expect("buffer sizes come from the plan");
    });
    (spec, m)
}

/// One signal's mirror spectrum with its fitted noise floor: what does not depend on the
/// cut-off.
pub(crate) struct Core {
    /// Bins 0..=M/2 of the mirror extension.
    pub spec: Vec<Complex<f64>>,
    /// Their power.
    pub power: Vec<f64>,
    /// The extension's length M.
    pub nn: usize,
    /// The fitted noise floor.
    pub floor_model: NoiseFloor,
    /// Its value at every bin ([`NoiseFloor::values`]).
    pub fl: Vec<f64>,
}

impl Core {
    /// The mirror spectrum of `x` and its floor.
    fn of(x: &[f64]) -> Self {
        let (spec, nn) = mirror_spectrum(x);
        let power: Vec<f64> = spec.iter().map(|c| c.norm_sqr()).collect();
        let floor_model = NoiseFloor::fit(&power);
        let fl = floor_model.values(power.len());
        Self {
            spec,
            power,
            nn,
            floor_model,
            fl,
        }
    }
}

/// One signal's mirror spectrum with its noise floor and the cut-off chosen on it (or given).
pub(crate) struct Spectrum {
    /// The spectrum and its floor.
    pub core: Arc<Core>,
    /// The cut-off bin (before any guard band).
    pub kc: usize,
    /// The floor at the cut-off the spectrum chose (`None` for a given cut-off: see
    /// [`Spectrum::floor`]).
    floor: Option<f64>,
    /// The floor summed over bins 1..=kc.
    pub noise_sum: f64,
    /// The estimated reconstruction error at that cut-off ([`cutoff_cost`](crate::floor::cutoff_cost)).
    pub cost: f64,
}

impl Spectrum {
    /// The floor at the cut-off the spectrum's own search chooses (with the harmonic search
    /// from bin 0 when the cut-off was given: computed only for the spectrum a band search
    /// keeps, not for every candidate).
    pub fn floor(&self) -> f64 {
        self.floor.unwrap_or_else(|| {
            let c = &self.core;
            choose_cutoff_on(&c.power, &c.floor_model, &c.fl, 0).1
        })
    }

    /// The spectrum `core` (of a signal sampled at `dt`) cut by
    /// [`choose_cutoff`](crate::floor::choose_cutoff), or at `cutoff_hz`.
    fn cut(core: Arc<Core>, cutoff_hz: Option<f64>, dt: f64) -> Self {
        let df = 1.0 / (core.nn as f64 * dt);
        let (power, fl) = (&core.power, &core.fl);
        let (kc, floor, noise_sum) = match cutoff_hz {
            Some(f) => {
                let kc = ((f / df).round() as usize).min(core.spec.len() - 1);
                let s: f64 = (1..=kc).map(|k| fl[k]).sum();
                (kc, None, if s.is_finite() { s } else { 0.0 })
            }
            None => {
                let (kc, floor, noise) = choose_cutoff_on(power, &core.floor_model, fl, 1);
                (kc, Some(floor), noise)
            }
        };
        let cost = cutoff_cost_on(power, fl, kc);
        Self {
            core,
            kc,
            floor,
            noise_sum,
            cost,
        }
    }
}

/// The mirror spectra and noise floors one band search of a signal computed — of the signal
/// itself and of its remainder after each end trend tried — kept for another search on the same
/// signal (say, at the cut-off the first one found before its guard band). Such a search reads
/// them instead of transforming again and finds the same band and reconstruction, to the bit.
/// Spectra kept for another signal are not used: each search checks the signal's length, time
/// step and a fingerprint of its samples first, and transforms afresh when they differ.
#[derive(Default)]
pub struct Spectra {
    /// Length, time step and fingerprint of the signal the spectra are of.
    of: Option<(usize, u64, u64)>,
    /// Each spectrum with the end trend removed before it (`None`: the signal itself).
    entries: Vec<(Option<EndTrend>, Arc<Core>)>,
}

impl Spectra {
    /// No spectra kept.
    pub fn new() -> Self {
        Self::default()
    }

    /// How many spectra are kept.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when none are kept.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Readies the store for a search on `x` sampled at `dt`: what was kept for another signal
    /// is dropped.
    pub(crate) fn bind(&mut self, x: &[f64], dt: f64) {
        let id = (x.len(), dt.to_bits(), fingerprint(x));
        if self.of != Some(id) {
            self.entries.clear();
            self.of = Some(id);
        }
    }

    /// The spectrum of `x` less `trend` (`None`: of `x`), kept or computed (and then kept).
    fn get_or_make(&mut self, trend: Option<EndTrend>, make: impl FnOnce() -> Core) -> Arc<Core> {
        let same = |t: &Option<EndTrend>| match (t, &trend) {
            (None, None) => true,
            (Some(a), Some(b)) => {
                a.s0.to_bits() == b.s0.to_bits()
                    && a.s1.to_bits() == b.s1.to_bits()
                    && a.span.to_bits() == b.span.to_bits()
            }
            _ => false,
        };
        if let Some((_, c)) = self.entries.iter().find(|(t, _)| same(t)) {
            return Arc::clone(c);
        }
        let c = Arc::new(make());
        self.entries.push((trend, Arc::clone(&c)));
        c
    }
}

/// A 64-bit fingerprint of the samples' bits (a multiply–rotate mix over every sample, four
/// interleaved streams combined at the end): two different signals of one length share it only
/// by a chance of about 2⁻⁶⁴.
fn fingerprint(x: &[f64]) -> u64 {
    const K: u64 = 0x9E37_79B9_7F4A_7C15;
    let mix = |h: u64, v: f64| (h ^ v.to_bits()).wrapping_mul(K).rotate_left(29);
    let mut lanes = [1u64, 2, 3, 4];
    let chunks = x.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for (h, &v) in lanes.iter_mut().zip(c) {
            *h = mix(*h, v);
        }
    }
    let h = rest.iter().fold(0u64, |h, &v| mix(h, v));
    lanes.iter().fold(h, |acc, &l| mix(acc, f64::from_bits(l)))
}

/// The spectrum of `x` less `trend` (sampled at `dt`) cut at `cutoff_hz` or at the chosen
/// cut-off, read from `kept` when it holds it (and kept there when it is computed); `kept` must
/// be bound to `x` ([`Spectra::bind`]).
pub(crate) fn spectrum(
    x: &[f64],
    dt: f64,
    trend: Option<EndTrend>,
    cutoff_hz: Option<f64>,
    kept: Option<&mut Spectra>,
) -> Spectrum {
    let make = || match trend {
        Some(t) => Core::of(&t.remove(x, dt)),
        None => Core::of(x),
    };
    let core = match kept {
        Some(k) => k.get_or_make(trend, make),
        None => Arc::new(make()),
    };
    Spectrum::cut(core, cutoff_hz, dt)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::band::{reconstruct, reconstruct_every, reconstruct_guarded, reconstruct_keeping};
    use crate::{Smoothed, noise};

    fn bits(s: &Smoothed) -> (Vec<u64>, Vec<u64>, Vec<u64>) {
        let b = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect();
        (b(&s.x), b(&s.v), b(&s.a))
    }

    /// A record that ends moving (so an end trend is searched for) in white noise.
    fn record(n: usize, dt: f64, seed: u64) -> Vec<f64> {
        let e = noise::standard_normal(n, seed);
        (0..n)
            .map(|i| {
                let t = i as f64 * dt;
                (2.0 * std::f64::consts::PI * (0.3 * t + 0.004 * t * t)).sin() + 0.02 * e[i]
            })
            .collect()
    }

    /// Keeping the spectra changes nothing: the guarded reconstruction is the same to the bit,
    /// the second search at the best cut-off is the plain one's to the bit and transforms
    /// nothing new when it tries the same end trends, and spectra kept for another signal are
    /// not read.
    #[test]
    fn kept_spectra_give_the_same_reconstructions_to_the_bit() {
        let dt = 0.005;
        for (n, seed) in [(6000, 3u64), (9001, 8)] {
            let x = record(n, dt, seed);
            let mut kept = Spectra::new();
            let guarded = reconstruct_keeping(&x, dt, (None, 0.5), &mut kept);
            let want = reconstruct_guarded(&x, dt, None, 0.5);
            assert_eq!(bits(&guarded), bits(&want));
            assert_eq!(guarded.band, want.band);
            assert!(kept.len() >= 2, "the signal and at least one trend");
            let before = kept.len();
            let cut = guarded.band.mse_cutoff_hz;
            let plain = reconstruct_keeping(&x, dt, (Some(cut), 0.0), &mut kept);
            let want = reconstruct(&x, dt, Some(cut));
            assert_eq!(bits(&plain), bits(&want));
            assert_eq!(plain.band, want.band);
            // The signal's own spectrum at least was read, not transformed again.
            assert!(kept.len() < 2 * before, "{} after {before}", kept.len());
            // Another signal of the same length: nothing kept for `x` is read.
            let mut y = x.clone();
            y[n / 2] += 1e-3;
            let other = reconstruct_keeping(&y, dt, (None, 0.5), &mut kept);
            assert_eq!(bits(&other), bits(&reconstruct_guarded(&y, dt, None, 0.5)));
        }
    }

    /// A reconstruction at every q-th sample is the full one's samples there (to rounding),
    /// trend included, in the same band to the bit, for steps that share factors with the
    /// transform length and one that does not.
    #[test]
    fn reconstruction_every_qth_sample_is_the_full_one_there() {
        let dt = 0.005;
        let x = record(12_000, dt, 5);
        let full = reconstruct_guarded(&x, dt, Some(3.0), 0.0);
        let scale = |v: &[f64]| v.iter().fold(0.0f64, |m, a| m.max(a.abs()));
        for q in [1usize, 3, 4, 6, 7] {
            let mut kept = Spectra::new();
            let every = reconstruct_every(&x, dt, (Some(3.0), 0.0), &mut kept, q);
            assert_eq!(every.band, full.band, "q = {q}");
            for (got, want) in [
                (&every.x, &full.x),
                (&every.v, &full.v),
                (&every.a, &full.a),
            ] {
                assert_eq!(got.len(), x.len().div_ceil(q), "q = {q}");
                let tol = 1e-12 * scale(want);
                for (m, (g, w)) in got.iter().zip(want.iter().step_by(q)).enumerate() {
                    assert!((g - w).abs() <= tol, "q = {q}, sample {m}: {g} vs {w}");
                }
            }
        }
    }

    /// A signal low-passed at every q-th sample is the fully low-passed signal's samples there.
    #[test]
    fn low_pass_every_qth_sample_is_the_full_low_pass_there() {
        use crate::band::{low_pass, low_pass_every};
        let dt = 0.005;
        let x = record(9000, dt, 4);
        for (q, cut) in [
            (1usize, 20.0),
            (3, 0.8 * 0.5 / (3.0 * dt)),
            (5, 30.0),
            (7, 10.0),
        ] {
            let full = low_pass(&x, dt, cut);
            let every = low_pass_every(&x, dt, cut, q);
            assert_eq!(every.len(), x.len().div_ceil(q));
            let scale = full.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (m, (g, w)) in every.iter().zip(full.iter().step_by(q)).enumerate() {
                assert!(
                    (g - w).abs() <= 1e-12 * scale,
                    "q = {q}, sample {m}: {g} vs {w}"
                );
            }
        }
    }
}
