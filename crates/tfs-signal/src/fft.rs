//! The one FFT planner of tfs and thin helpers over `realfft`: cached plans shared by every
//! thread, per-thread work buffers, forward/inverse real transforms, fast transform lengths,
//! frequency axes, amplitude spectra and band masks.
//!
//! Conventions: [`SpectrumPlanner::rfft`] is unnormalised (`X_k = Σ x_j e^{−2πijk/n}`, `n/2+1`
//! bins); [`SpectrumPlanner::irfft`] divides by `n`, so `irfft(rfft(x)) = x`.

use std::sync::{Arc, Mutex, OnceLock};

use crate::{Complex, Result, SignalError, check_dt, check_signal, invalid};
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};

/// Plans of at most this many points are kept for the whole process: the windows, blocks and
/// short records a fit transforms thousands of times, a few megabytes in all.
const KEEP_LEN: usize = 1 << 16;

/// Estimated bytes of the longer plans kept at once ([`plan_bytes`]): a plan's tables grow with
/// its length (about 24 bytes per point of a mixed-radix plan, 25 per point of the power-of-two
/// inner transform of a Bluestein plan), so a record of 640,000 samples has plans of 15–50 MB
/// each, and keeping every length a diagnosis met held 133 MB of them. This keeps the two or
/// three lengths a record's stage works with at that size and every plan of records up to about
/// 100,000 samples.
const LONG_BUDGET: usize = 48 << 20;

/// Plans longer than [`KEEP_LEN`] of one direction: (length, plan, estimated bytes, last use).
struct Long<P: ?Sized>(Vec<(usize, Arc<P>, usize, u64)>);

impl<P: ?Sized> Long<P> {
    fn bytes(&self) -> usize {
        self.0.iter().map(|k| k.2).sum()
    }

    /// The kept plan of length `n`, its last use set to `now`.
    fn get(&mut self, n: usize, now: u64) -> Option<Arc<P>> {
        let slot = self.0.iter_mut().find(|k| k.0 == n)?;
        slot.3 = now;
        Some(slot.1.clone())
    }

    /// The last use of the least recently used plan.
    fn oldest(&self) -> Option<u64> {
        self.0.iter().map(|k| k.3).min()
    }

    fn drop_oldest(&mut self) {
        if let Some(i) = (0..self.0.len()).min_by_key(|&i| self.0[i].3) {
            self.0.remove(i);
        }
    }
}

/// Process-wide caches of FFT plans: planning a length costs several transforms of it, and the
/// same lengths are transformed many times (records, windows, noise draws), from several
/// threads. Plans of up to [`KEEP_LEN`] points are kept for the process. Longer ones are held to
/// [`LONG_BUDGET`] estimated bytes ([`plan_bytes`]), both directions together: the least
/// recently used are dropped first, and a plan larger than the whole budget is made for its
/// caller and not kept. Each long plan is made by a planner of its own, dropped with it, so that
/// no sub-plan outlives the plans using it; a plan made again is the same algorithm with the
/// same tables, so its transforms are the same to the bit.
struct Plans {
    short: RealFftPlanner<f64>,
    forward: Long<dyn RealToComplex<f64>>,
    inverse: Long<dyn ComplexToReal<f64>>,
    /// Uses of long plans so far (the recency of each).
    clock: u64,
}

impl Plans {
    /// Makes room for `bytes` more within the budget; false when they exceed it alone.
    fn room_for(&mut self, bytes: usize) -> bool {
        if bytes > LONG_BUDGET {
            return false;
        }
        while self.forward.bytes() + self.inverse.bytes() + bytes > LONG_BUDGET {
            match (self.forward.oldest(), self.inverse.oldest()) {
                (Some(f), Some(i)) if i < f => self.inverse.drop_oldest(),
                (Some(_), _) => self.forward.drop_oldest(),
                (None, Some(_)) => self.inverse.drop_oldest(),
                (None, None) => break,
            }
        }
        true
    }

    fn tick(&mut self) -> u64 {
        self.clock += 1;
        self.clock
    }
}

/// A plan's estimated bytes: 24 per point of its complex transform (about `n/2` points: the
/// twiddle tables of a mixed-radix plan and of the real-to-complex step) and 16 per complex
/// point of its scratch (a Bluestein plan's scratch is its power-of-two inner transform, whose
/// tables dominate). At 640,000 points within 15 % of what a heap profile shows.
fn plan_bytes(n: usize, scratch: usize) -> usize {
    24 * (n / 2 + 1) + 16 * scratch
}

/// Estimated bytes of the long plans kept now.
#[cfg(test)]
fn kept_bytes() -> usize {
    let pl = plans();
    pl.forward.bytes() + pl.inverse.bytes()
}

/// Whether a forward plan of length `n` is kept now.
#[cfg(test)]
fn forward_kept(n: usize) -> bool {
    plans().forward.0.iter().any(|k| k.0 == n)
}

fn plans() -> std::sync::MutexGuard<'static, Plans> {
    static PLANS: OnceLock<Mutex<Plans>> = OnceLock::new();
    // A poisoned lock only means another thread panicked while planning; the cache is still valid.
    PLANS
        .get_or_init(|| {
            Mutex::new(Plans {
                short: RealFftPlanner::new(),
                forward: Long(Vec::new()),
                inverse: Long(Vec::new()),
                clock: 0,
            })
        })
        .lock()
        .unwrap_or_else(|e| e.into_inner())
}

/// The long plan of length `n` kept in `side` of the cache, or made by `make` (outside the lock,
/// so that other threads' plans are not held up by a long one) and kept if the budget allows.
fn long_plan<P: ?Sized>(
    n: usize,
    side: fn(&mut Plans) -> &mut Long<P>,
    make: impl FnOnce() -> (Arc<P>, usize),
) -> Arc<P> {
    {
        let mut pl = plans();
        let now = pl.tick();
        if let Some(hit) = side(&mut pl).get(n, now) {
            return hit;
        }
    }
    let (made, scratch) = make();
    let bytes = plan_bytes(n, scratch);
    let mut pl = plans();
    let now = pl.tick();
    if side(&mut pl).get(n, now).is_none() && pl.room_for(bytes) {
        side(&mut pl).0.push((n, made.clone(), bytes, now));
    }
    made
}

/// The (cached) forward real FFT of length `n`: plans of up to 65,536 points are kept for the
/// process, longer ones within a budget of their estimated size, least recently used dropped first.
pub fn plan_forward(n: usize) -> Arc<dyn RealToComplex<f64>> {
    if n <= KEEP_LEN {
        return plans().short.plan_fft_forward(n);
    }
    long_plan(
        n,
        |p| &mut p.forward,
        || {
            let p = RealFftPlanner::new().plan_fft_forward(n);
            let scratch = p.get_scratch_len();
            (p, scratch)
        },
    )
}

/// The (cached) inverse real FFT of length `n` (kept as [`plan_forward`] says).
pub fn plan_inverse(n: usize) -> Arc<dyn ComplexToReal<f64>> {
    if n <= KEEP_LEN {
        return plans().short.plan_fft_inverse(n);
    }
    long_plan(
        n,
        |p| &mut p.inverse,
        || {
            let p = RealFftPlanner::new().plan_fft_inverse(n);
            let scratch = p.get_scratch_len();
            (p, scratch)
        },
    )
}

/// Per-thread work buffers of the transforms (real signal, half spectrum, FFT scratch). A fresh
/// buffer of a record's length is fresh memory from the operating system, and touching it costs
/// more than the FFT itself (measured: 0.9 ms of page faults against 0.37 ms of transform at
/// 100,000 points), so the buffers are kept between calls, up to [`KEEP_WORK`] elements.
#[derive(Default)]
pub(crate) struct Work {
    pub real: Vec<f64>,
    pub spec: Vec<Complex<f64>>,
    pub scratch: Vec<Complex<f64>>,
}

thread_local! {
    static WORK: std::cell::RefCell<Work> = std::cell::RefCell::new(Work::default());
}

/// Work buffers of more than this many elements (2–4 MB) are freed when the call that needed
/// them ends: each thread keeps its buffers, and a record of 640,000 samples grew them to 20 MB
/// a thread for the rest of the process. Allocating them afresh costs little against the
/// transforms of that length.
const KEEP_WORK: usize = 1 << 18;

impl Work {
    /// Frees the buffers longer than [`KEEP_WORK`].
    fn trim(&mut self) {
        if self.real.capacity() > KEEP_WORK {
            self.real = Vec::new();
        }
        if self.spec.capacity() > KEEP_WORK {
            self.spec = Vec::new();
        }
        if self.scratch.capacity() > KEEP_WORK {
            self.scratch = Vec::new();
        }
    }
}

/// Runs `f` with this thread's work buffers (those grown past [`KEEP_WORK`] freed after it).
pub(crate) fn with_work<R>(f: impl FnOnce(&mut Work) -> R) -> R {
    WORK.with_borrow_mut(|w| {
        let out = f(w);
        w.trim();
        out
    })
}

/// Inverse transform of `spec` (overwritten) into `out` (length `m`) with the thread's scratch.
pub(crate) fn inverse_with(
    inv: &Arc<dyn ComplexToReal<f64>>,
    spec: &mut [Complex<f64>],
    out: &mut [f64],
    scratch: &mut Vec<Complex<f64>>,
) {
    scratch.resize(inv.get_scratch_len(), Complex::new(0.0, 0.0));
    inv.process_with_scratch(spec, out, scratch)
        .expect("buffer sizes come from the plan");
}

/// The FFT (bins 0..=len/2) of `f ⊙ w` over one window of `len = f.len()` samples (`w = None`:
/// no window), scaled by `dt` (a Riemann sum of the integral), handed to `read` in the thread's
/// work buffer (a fit makes thousands of these, and fresh buffers for each cost more in
/// allocation, zeroing and page faults than the transform).
pub(crate) fn with_fft<R>(
    f: &[f64],
    w: Option<&[f64]>,
    dt: f64,
    read: impl FnOnce(&[Complex<f64>]) -> R,
) -> R {
    let fft = plan_forward(f.len());
    with_work(|work| {
        let Work {
            real: input,
            spec,
            scratch,
        } = work;
        input.clear();
        match w {
            Some(w) => input.extend(f.iter().zip(w).map(|(a, b)| a * b * dt)),
            None => input.extend(f.iter().map(|a| a * dt)),
        }
        spec.resize(f.len() / 2 + 1, Complex::new(0.0, 0.0));
        scratch.resize(fft.get_scratch_len(), Complex::new(0.0, 0.0));
        fft.process_with_scratch(input, spec, scratch)
            .expect("buffer sizes come from the plan");
        read(spec)
    })
}

/// The smallest even `m ≥ n` whose only prime factors are 2, 3, 5 and 7 (fast FFT lengths).
pub fn fast_even_len(n: usize) -> usize {
    let mut m = n.max(2);
    loop {
        if m % 2 == 0 {
            let mut r = m;
            for p in [2, 3, 5, 7] {
                while r % p == 0 {
                    r /= p;
                }
            }
            if r == 1 {
                return m;
            }
        }
        m += 1;
    }
}

/// The largest `m ≤ n` whose only prime factors are 2, 3 and 5 (fast FFT lengths).
pub fn smooth_len(n: usize) -> usize {
    let mut m = n.max(1);
    loop {
        let mut r = m;
        for p in [2, 3, 5] {
            while r % p == 0 {
                r /= p;
            }
        }
        if r == 1 {
            return m;
        }
        m -= 1;
    }
}

/// Forward and inverse real transforms through the shared plan cache (see [`plan_forward`]).
pub struct SpectrumPlanner {
    _cache: (),
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
    /// A handle on the shared plan cache.
    pub fn new() -> Self {
        Self { _cache: () }
    }

    /// Forward real FFT of `x` (unnormalised), returning `x.len()/2 + 1` bins.
    pub fn rfft(&mut self, x: &[f64]) -> Result<Vec<Complex<f64>>> {
        check_signal("rfft input", x, 1)?;
        rfft_in_place(&mut x.to_vec())
    }

    /// Inverse real FFT to `n` samples, normalised by `1/n`. `spectrum` must hold `n/2 + 1` bins;
    /// the imaginary parts of the DC bin (and of the Nyquist bin for even `n`) are ignored.
    pub fn irfft(&mut self, spectrum: &[Complex<f64>], n: usize) -> Result<Vec<f64>> {
        let mut out = vec![0.0; n];
        irfft_into(&mut spectrum.to_vec(), &mut out)?;
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

/// [`SpectrumPlanner::rfft`] of `x`, using `x` as the transform's work space (its values are
/// lost): no copy of a record-length signal. Errors on an empty or non-finite `x`.
pub(crate) fn rfft_in_place(x: &mut [f64]) -> Result<Vec<Complex<f64>>> {
    check_signal("rfft input", x, 1)?;
    let plan = plan_forward(x.len());
    let mut out = plan.make_output_vec();
    // Lengths match by construction, so the transform cannot fail.
    plan.process(x, &mut out)
        .expect("rfft buffers sized by the plan");
    Ok(out)
}

/// [`SpectrumPlanner::irfft`] of `spectrum` (used as work space, its values lost) into `out`,
/// whose length is the `n` transformed to: no copy of a record-length spectrum.
pub(crate) fn irfft_into(spectrum: &mut [Complex<f64>], out: &mut [f64]) -> Result<()> {
    let n = out.len();
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
    let plan = plan_inverse(n);
    spectrum[0].im = 0.0;
    if n % 2 == 0 {
        spectrum[n / 2].im = 0.0;
    }
    plan.process(spectrum, out)
        .expect("irfft buffers sized by the plan, edge bins real");
    let scale = 1.0 / n as f64;
    out.iter_mut().for_each(|v| *v *= scale);
    Ok(())
}

/// Forward real FFT through the shared plan cache (see [`SpectrumPlanner::rfft`]).
pub fn rfft(x: &[f64]) -> Result<Vec<Complex<f64>>> {
    SpectrumPlanner::new().rfft(x)
}

/// Inverse real FFT through the shared plan cache (see [`SpectrumPlanner::irfft`]).
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

/// Band-limited reconstruction by a mask of frequency bands (see [`SpectrumPlanner::band_limit`]).
pub fn band_limit(x: &[f64], dt: f64, bands: &[(f64, f64)]) -> Result<Vec<f64>> {
    SpectrumPlanner::new().band_limit(x, dt, bands)
}

/// Mask-based band limiting (see [`SpectrumPlanner::band_limit_mask`]).
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

    #[test]
    fn fast_lengths_are_the_smallest_even_7_smooth_ones() {
        let smooth = |mut m: usize| {
            for p in [2, 3, 5, 7] {
                while m % p == 0 {
                    m /= p;
                }
            }
            m == 1
        };
        for n in [1usize, 2, 7, 12_014, 40_002, 100_010] {
            let m = fast_even_len(n);
            assert!(m >= n && m % 2 == 0 && smooth(m), "{n} -> {m}");
            assert!(
                (n.max(2)..m).all(|k| k % 2 == 1 || !smooth(k)),
                "{n} -> {m}"
            );
        }
        assert_eq!(fast_even_len(100_010), 100_352);
    }

    /// Long plans are held within the budget, and a plan made again after it was dropped
    /// transforms to the bit what the first one did (and what a planner of its own makes).
    #[test]
    fn long_plans_are_bounded_and_made_again_to_the_bit() {
        let signal = |n: usize| -> Vec<f64> {
            (0..n)
                .map(|k| (0.37 * k as f64).sin() + 1e-3 * ((k * k) % 101) as f64)
                .collect()
        };
        // An odd length (a Bluestein plan) and an even one, both long.
        let (odd, even) = (70_001usize, 140_000usize);
        let first = (rfft(&signal(odd)).unwrap(), rfft(&signal(even)).unwrap());
        let spec = first.1.clone();
        let back = irfft(&spec, even).unwrap();
        // Lengths whose plans together exceed the budget push the first ones out.
        for n in [1_200_000usize, 1_260_000, 1_323_000, 1_400_000] {
            plan_forward(n);
            plan_inverse(n);
            assert!(kept_bytes() <= LONG_BUDGET, "{} bytes kept", kept_bytes());
        }
        let again = (rfft(&signal(odd)).unwrap(), rfft(&signal(even)).unwrap());
        let bits = |v: &[Complex<f64>]| -> Vec<(u64, u64)> {
            v.iter().map(|c| (c.re.to_bits(), c.im.to_bits())).collect()
        };
        assert_eq!(bits(&first.0), bits(&again.0));
        assert_eq!(bits(&first.1), bits(&again.1));
        let back_again = irfft(&spec, even).unwrap();
        assert!(
            back.iter()
                .zip(&back_again)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        let own = RealFftPlanner::new().plan_fft_forward(odd);
        let mut input = signal(odd);
        let mut out = own.make_output_vec();
        own.process(&mut input, &mut out).unwrap();
        assert_eq!(bits(&first.0), bits(&out));
        // A plan larger than the whole budget is made and used, not kept.
        let huge = 1 << 22;
        assert!(plan_bytes(huge, 0) > LONG_BUDGET);
        assert_eq!(plan_forward(huge).len(), huge);
        assert!(!forward_kept(huge));
    }

    /// A thread's work buffers grown past `KEEP_WORK` are freed when the call ends; smaller
    /// ones are kept for the next call.
    #[test]
    fn work_buffers_past_the_limit_are_freed() {
        with_work(|w| w.real.resize(1000, 0.0));
        with_work(|w| assert!(w.real.capacity() >= 1000));
        with_work(|w| {
            w.real.resize(KEEP_WORK + 1, 0.0);
            w.spec.resize(KEEP_WORK + 1, Complex::new(0.0, 0.0));
        });
        with_work(|w| {
            assert_eq!(w.real.capacity(), 0);
            assert_eq!(w.spec.capacity(), 0);
        });
    }
}
