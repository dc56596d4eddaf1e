//! The noise floor of a spectrum: a power law `N̂_k = A·k^β` fitted to the medians of sub-bands
//! of the spectrum's upper half (oversampled vibration data carry only noise there), and the
//! cut-off that balances the noise let in against the signal thrown away.

use statrs::distribution::{ContinuousCDF, Normal};

/// Sub-bands of the upper half of the spectrum whose medians fit the noise floor.
pub const FLOOR_SUBBANDS: usize = 16;

/// Median of a χ²₁ variable of unit mean: a bin of the transform of an even (mirror-extended)
/// signal is real up to a phase, so a noise bin carries one squared Gaussian.
pub const CHI2_1_MEDIAN: f64 = 0.454_936_4;

/// Chooses the cut-off bin of a power spectrum `p` (bins 0..=K) of a mirror-extended (even) signal.
///
/// The noise floor is modelled as a power law `N̂_k = A·k^β` fitted (least squares in log–log)
/// to the medians of sixteen sub-bands of the upper half of the spectrum, each median divided by
/// 0.4549 — the median of a χ²₁ variable of unit mean (the transform of an even extension is
/// real up to a phase, so a noise bin carries one squared Gaussian). β is set to 0 unless it differs from 0 by more than three standard errors, and clamped to
/// [−2, 0.5] ([`NoiseFloor::fit`]): white noise gives β ≈ 0, pink noise β ≈ −1, and the fitted slope extrapolates the floor into
/// the signal band. The cut-off `k_c` then minimises the estimated reconstruction error
/// `Σ_{k≤k_c} N̂_k + Σ_{k>k_c} (P_k − N̂_k)_+` (noise let in below the cut plus signal thrown away
/// above it), with `k_c ≥ min_bin`. Returns `k_c`, the floor at `k_c` and `Σ_{1≤k≤k_c} N̂_k`.
pub fn choose_cutoff(p: &[f64], min_bin: usize) -> (usize, f64, f64) {
    let ff = NoiseFloor::fit(p);
    let fl = ff.values(p.len());
    choose_cutoff_on(p, &ff, &fl, min_bin)
}

/// [`choose_cutoff`] on the floor `ff` already fitted to `p`, whose value at every bin of `p` is
/// `fl` ([`NoiseFloor::values`]): the band-limited reconstruction fits the floor once and shares
/// its values between the cut-off and its cost ([`cutoff_cost_on`]).
pub(crate) fn choose_cutoff_on(
    p: &[f64],
    ff: &NoiseFloor,
    fl: &[f64],
    min_bin: usize,
) -> (usize, f64, f64) {
    let k = p.len();
    debug_assert_eq!(fl.len(), k);
    let floor = |i: usize| fl[i];
    // The signal thrown away above each bin (summed from the top down) and the noise let in up
    // to it (from `start` up): two running sums, each in its own order, walked in one loop so
    // that neither waits for the other.
    let start = min_bin.min(k - 1);
    let mut head: f64 = (0..start).map(floor).sum();
    // The sums go to this thread's buffers, kept between calls: a spectrum's worth of fresh,
    // zeroed memory per call cost more than the sums themselves. Every entry read is written
    // first (`heads` from `start` up).
    let best = SUMS.with_borrow_mut(|(tail, heads)| {
        tail.resize(k + 1, 0.0);
        heads.resize(k, 0.0);
        tail[k] = 0.0;
        for (i, h) in heads[..k].iter_mut().enumerate() {
            let j = k - 1 - i;
            tail[j] = tail[j + 1] + (p[j] - floor(j)).max(0.0);
            if i >= start {
                head += floor(i);
                *h = head;
            }
        }
        let mut best = (start, f64::INFINITY, 0.0);
        for kc in start..k {
            let cost = heads[kc] + tail[kc + 1];
            if cost < best.1 {
                best = (kc, cost, heads[kc] - floor(0));
            }
        }
        best
    });
    // Harmonics: a nonlinear response has energy at multiples of the drive band that may be
    // worth less than the noise between them in total, yet each rises clearly above the local
    // floor. Extend the cut-off to the last block of `m` bins whose mean power exceeds the floor
    // by `HARMONIC_EXCESS` *and* by a one-sided test at family-wise level `HARMONIC_LEVEL` over
    // all the blocks tested, whose spread combines the block mean's own scatter (a mean of m χ²₁
    // bins has a log-spread of √(2/m)) with the standard error of the floor extrapolated there.
    // Noise-dominated bins inside the band are excluded later, in the regression.
    let mut kc = best.0;
    let mut noise = best.2;
    let m = HARMONIC_BLOCK;
    let blocks = ((k / 2).saturating_sub(kc + 1) / m).max(1);
    let z = Normal::standard().inverse_cdf(1.0 - HARMONIC_LEVEL / blocks as f64);
    let block_var = 2.0 / m as f64;
    let first = kc + 1;
    // Every block's power and floor sums (each in its own order), taken before the scan.
    let sums = block_sums(p, fl, first, m, (k / 2).saturating_sub(first) / m);
    let mut a0 = first;
    while a0 + m <= k / 2 {
        let (sp, sf) = sums[(a0 - first) / m];
        let mean = sp / m as f64;
        let fl = sf / m as f64;
        let se = ff.log_se(a0 + m / 2);
        let need = HARMONIC_EXCESS.ln() + z * (block_var + se * se).sqrt();
        if mean > 0.0 && fl > 0.0 && (mean / fl).ln() > need {
            for i in kc + 1..a0 + m {
                noise += floor(i);
            }
            kc = a0 + m - 1;
        }
        a0 += m;
    }
    (kc, floor(kc), noise.max(0.0))
}

/// The sums of `p` and of `fl` over each of `count` blocks of `m` bins from bin `first`, each
/// summed from its first bin up as `Iterator::sum` does (the same value to the bit); four blocks
/// go side by side, so that their sums do not wait for one another.
fn block_sums(p: &[f64], fl: &[f64], first: usize, m: usize, count: usize) -> Vec<(f64, f64)> {
    const SIDE: usize = 4;
    let mut out = Vec::with_capacity(count);
    let mut b = 0;
    while b + SIDE <= count {
        let base: [usize; SIDE] = std::array::from_fn(|l| first + (b + l) * m);
        let mut sp: [f64; SIDE] = std::array::from_fn(|l| p[base[l]]);
        let mut sf: [f64; SIDE] = std::array::from_fn(|l| fl[base[l]]);
        for i in 1..m {
            for l in 0..SIDE {
                sp[l] += p[base[l] + i];
                sf[l] += fl[base[l] + i];
            }
        }
        out.extend(sp.into_iter().zip(sf));
        b += SIDE;
    }
    for b in b..count {
        let a0 = first + b * m;
        out.push((
            p[a0..a0 + m].iter().sum::<f64>(),
            fl[a0..a0 + m].iter().sum::<f64>(),
        ));
    }
    out
}

thread_local! {
    /// The running sums of [`choose_cutoff_on`] (signal above, noise below each bin).
    static SUMS: std::cell::RefCell<(Vec<f64>, Vec<f64>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// Bins per block of the harmonic search of [`choose_cutoff`].
const HARMONIC_BLOCK: usize = 128;
/// Block mean power over the floor that marks a harmonic in [`choose_cutoff`].
const HARMONIC_EXCESS: f64 = 1.5;
/// Family-wise level of the harmonic test over all the blocks tested (see [`choose_cutoff`]).
const HARMONIC_LEVEL: f64 = 0.05;

/// Bins above this many times the floor (the 0.99 quantile of χ²₁) are left out of the pooled
/// level of [`NoiseFloor::pooled_level`].
pub const POOL_CLIP: f64 = 6.634_896_601_021_214;
/// At most this many passes of a skipped mean (it stops when the bins kept stop changing,
/// usually after two or three).
const POOL_ITERATIONS: usize = 20;

/// The mean of a unit-mean χ²₁ variable below [`POOL_CLIP`], `F₃(c)/F₁(c)` (as `x·f₁(x) =
/// f₃(x)`, with `F_ν` the χ²_ν distribution function; checked against `statrs` in the tests).
const POOL_KEPT_MEAN: f64 = 0.924_755_899_372_685_4;

/// The mean scale of `values` taken as χ²₁ bins of one mean `A`: the mean of the values at most
/// [`POOL_CLIP`]·`A`, divided by [`POOL_KEPT_MEAN`], iterated to its fixed point from
/// `A = start`. `None` when no value is kept or the start is not a positive number.
fn skipped_mean(values: impl Iterator<Item = f64> + Clone, start: f64) -> Option<f64> {
    if start.is_nan() || start <= 0.0 || start.is_infinite() {
        return None;
    }
    let mut a = start;
    let mut kept = usize::MAX;
    for _ in 0..POOL_ITERATIONS {
        let cut = POOL_CLIP * a;
        let (sum, n) = values
            .clone()
            .filter(|&v| v <= cut)
            .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
        if n == 0 || sum.is_nan() || sum <= 0.0 {
            return None;
        }
        a = sum / (n as f64 * POOL_KEPT_MEAN);
        if n == kept {
            break;
        }
        kept = n;
    }
    Some(a)
}

/// A power-law noise floor `ln N̂_k = log_a + beta·ln k` fitted to a spectrum (see
/// [`NoiseFloor::fit`]), with what its extrapolation error needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseFloor {
    /// `ln A` (−∞ when the spectrum is zero).
    pub log_a: f64,
    /// The slope β (0 unless clearly significant; 0 white, ≈ −1 pink).
    pub beta: f64,
    /// Residual standard deviation of the sub-band log medians about the unconstrained line.
    s: f64,
    /// Number of sub-bands.
    n: f64,
    /// Mean log bin of the sub-bands.
    mx: f64,
    /// Σ (ln k − mx)².
    sxx: f64,
    /// The unclamped slope is below −2 by more than three standard errors: the upper half falls
    /// faster than any noise floor the model admits.
    tail: bool,
    /// The kept slope was clamped to [−2, 0.5]: the model's shape does not follow the upper half.
    clamped: bool,
}

impl NoiseFloor {
    /// The floor of a mirror power spectrum `p` (bins 0..=K): its slope from the medians of
    /// [`FLOOR_SUBBANDS`] sub-bands of its upper half, each divided by [`CHI2_1_MEDIAN`], and a
    /// least-squares line through them in log–log (see [`NoiseFloor::fit_with`]); its level
    /// from every bin of the upper half pooled ([`NoiseFloor::pooled_level`]).
    ///
    /// The level is what the cut-off and every noise estimate rest on, and the median of χ²₁
    /// bins is a poor estimator of it: the log of a median of `n` bins scatters by 2.33/√n
    /// against √2/√n for their mean. On a short record (300 bins in the upper half) the median
    /// floor's log scatters by 0.13, about one draw in fifty is 25 % low, and the cut-off chosen
    /// on such a floor follows the noise bins above it out to many times the signal's band.
    pub fn fit(p: &[f64]) -> Self {
        Self::fit_with(p, FLOOR_SUBBANDS, CHI2_1_MEDIAN).pooled_level(p)
    }

    /// The floor with its level `A` re-estimated from every bin `k` of the upper half of the
    /// power spectrum `p`, each divided by the floor's shape `k^β`: the mean of those at most
    /// [`POOL_CLIP`] (the 0.99 quantile of χ²₁) times `A`, divided by the mean of a χ²₁ variable
    /// of unit mean below that quantile, iterated to its fixed point from the median fit's `A`.
    /// Under noise alone it is unbiased (one bin in a hundred is dropped, and the division
    /// accounts for it) and nearly as precise as the plain mean; a line in the upper half (a
    /// harmonic, an interference) more than 6.6 times the floor is left out as the medians
    /// left it out. Left as it is when the slope was clamped (the upper half does not follow
    /// the model: a signal tail, see [`NoiseFloor::is_signal_tail`]) or without a finite level.
    pub fn pooled_level(self, p: &[f64]) -> Self {
        let k = p.len();
        let lo = (k / 2).max(1);
        if !self.log_a.is_finite() || lo >= k || self.tail || self.clamped {
            return self;
        }
        // A flat floor reads the bins as they are (β = 0 divides each by exactly 1).
        let level = if self.beta == 0.0 {
            skipped_mean(p[lo..].iter().copied(), self.log_a.exp())
        } else {
            let r: Vec<f64> = (lo..k)
                .map(|i| p[i] / (self.beta * (i.max(1) as f64).ln()).exp())
                .collect();
            skipped_mean(r.iter().copied(), self.log_a.exp())
        };
        match level {
            Some(a) => Self {
                log_a: a.ln(),
                ..self
            },
            None => self,
        }
    }

    /// The floor of the spectrum `p` from the medians of `subbands` sub-bands of its upper half,
    /// each divided by `unit_median` (the median of one noise bin's value when its mean is 1).
    /// The slope is kept only when it differs from 0 by more than three standard errors, and
    /// clamped to [−2, 0.5]; with fewer than three sub-bands the floor is flat at their mean log
    /// median (one sub-band and `unit_median = 1`: the median of the upper half itself).
    pub fn fit_with(p: &[f64], subbands: usize, unit_median: f64) -> Self {
        let k = p.len();
        let lo = (k / 2).max(1);
        if lo >= k {
            return Self::flat(f64::NEG_INFINITY, 0.0, 0.0, 0.0);
        }
        let nsub = subbands.min(k - lo).max(1);
        let mut pts: Vec<(f64, f64)> = Vec::with_capacity(nsub);
        let mut band: Vec<f64> = Vec::new();
        for b in 0..nsub {
            let a0 = lo + b * (k - lo) / nsub;
            let a1 = (lo + (b + 1) * (k - lo) / nsub).max(a0 + 1).min(k);
            band.clear();
            band.extend_from_slice(&p[a0..a1]);
            let mid = band.len() / 2;
            let med = *band.select_nth_unstable_by(mid, f64::total_cmp).1 / unit_median;
            if med > 0.0 {
                pts.push(((0.5 * (a0 + a1) as f64).ln(), med.ln()));
            }
        }
        let cnt = pts.len() as f64;
        if pts.is_empty() {
            return Self::flat(f64::NEG_INFINITY, 0.0, 0.0, 0.0);
        }
        let mx = pts.iter().map(|p| p.0).sum::<f64>() / cnt;
        let my = pts.iter().map(|p| p.1).sum::<f64>() / cnt;
        let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
        let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
        if pts.len() < 3 || sxx <= 0.0 {
            return Self::flat(my, cnt, mx, sxx);
        }
        let b = sxy / sxx;
        // Keep the slope only if it is clearly significant (|β| > 3 standard errors), the scatter
        // of the points being at least what sampling gives: the log of the median of n χ²₁ bins
        // has a standard deviation of about 2.33/√n (see `docs/DECISIONS.md`).
        let rss: f64 = pts
            .iter()
            .map(|p| (p.1 - my - b * (p.0 - mx)).powi(2))
            .sum();
        let per_point = ((k - lo) as f64 / cnt).max(1.0);
        let s = (rss / (cnt - 2.0)).sqrt().max(2.33 / per_point.sqrt());
        let se = s / sxx.sqrt();
        let significant = b.abs() > 3.0 * se;
        let beta = if significant { b.clamp(-2.0, 0.5) } else { 0.0 };
        Self {
            log_a: my - beta * mx,
            beta,
            s,
            n: cnt,
            mx,
            sxx,
            tail: b + 3.0 * se < -2.0,
            clamped: significant && beta != b,
        }
    }

    /// A flat floor at `log_a` (no slope, no extrapolation error).
    fn flat(log_a: f64, n: f64, mx: f64, sxx: f64) -> Self {
        Self {
            log_a,
            beta: 0.0,
            s: 0.0,
            n,
            mx,
            sxx,
            tail: false,
            clamped: false,
        }
    }

    /// Does the upper half of the spectrum fall faster than a noise floor can (a slope below −2
    /// by more than three standard errors: steeper than pink or even integrated white noise)? Then it is the tail of
    /// the signal itself, the records show no noise floor, and the fitted floor (clamped to
    /// slope −2) is only an upper bound on the noise: clean or nearly clean data.
    pub fn is_signal_tail(&self) -> bool {
        self.tail
    }

    /// The floor at bin `k` (bin 0 counts as bin 1).
    pub fn at(&self, k: usize) -> f64 {
        (self.log_a + self.beta * (k.max(1) as f64).ln()).exp()
    }

    /// The floor at every bin `0..len`: [`NoiseFloor::at`] of each, to the bit, with one
    /// exponential for a flat floor (`β = 0` adds exactly zero to `ln A`) instead of a logarithm
    /// and an exponential per bin.
    pub fn values(&self, len: usize) -> Vec<f64> {
        if self.beta == 0.0 {
            vec![self.at(1); len]
        } else {
            (0..len).map(|k| self.at(k)).collect()
        }
    }

    /// Standard error of the fitted log floor at bin `k` (a prediction far below the fitted
    /// band carries the slope's uncertainty times the log distance).
    pub fn log_se(&self, k: usize) -> f64 {
        if self.n < 3.0 || self.sxx <= 0.0 {
            return 0.0;
        }
        let d = (k.max(1) as f64).ln() - self.mx;
        self.s * (1.0 / self.n + d * d / self.sxx).sqrt()
    }
}

/// The estimated reconstruction error of cutting the power spectrum `p` (bins 0..=K) at bin
/// `kc` under the floor `floor`: the noise let in below the cut plus the signal thrown away
/// above it, `Σ_{1≤k≤kc} N̂_k + Σ_{k>kc} (P_k − N̂_k)_+` — the quantity [`choose_cutoff`]
/// minimises, so that two spectra of the same record (say, with and without a trend removed)
/// can be compared at their own best cut-offs.
pub fn cutoff_cost(p: &[f64], floor: &NoiseFloor, kc: usize) -> f64 {
    cutoff_cost_on(p, &floor.values(p.len()), kc)
}

/// [`cutoff_cost`] with the floor's value at every bin of `p` given (`fl`,
/// [`NoiseFloor::values`]).
pub(crate) fn cutoff_cost_on(p: &[f64], fl: &[f64], kc: usize) -> f64 {
    let kc = kc.min(p.len().saturating_sub(1));
    let head: f64 = (1..=kc).map(|k| fl[k]).sum();
    let tail: f64 = (kc + 1..p.len()).map(|k| (p[k] - fl[k]).max(0.0)).sum();
    let c = head + tail;
    if c.is_finite() { c } else { f64::INFINITY }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With one sub-band and unit median the floor is the median of the upper half itself (the
    /// amplitude floor `tfs-diagnose` reads); with the defaults on white noise it is flat and
    /// near the bins' mean power.
    #[test]
    fn one_subband_is_the_median_of_the_upper_half() {
        let p: Vec<f64> = (0..101).map(|k| ((k * 37) % 101) as f64 + 1.0).collect();
        let mut upper = p[50..].to_vec();
        upper.sort_by(f64::total_cmp);
        let median = upper[upper.len() / 2];
        let f = NoiseFloor::fit_with(&p, 1, 1.0);
        assert_eq!(f.beta, 0.0);
        assert!(
            (f.at(7) / median - 1.0).abs() < 1e-15,
            "{} vs {median}",
            f.at(7)
        );
        assert_eq!(NoiseFloor::fit_with(&[0.0; 8], 1, 1.0).at(1), 0.0);
        assert_eq!(NoiseFloor::fit(&[1.0]).log_a, f64::NEG_INFINITY);
        let white: Vec<f64> = crate::noise::standard_normal(4000, 3)
            .iter()
            .map(|v| v * v)
            .collect();
        let w = NoiseFloor::fit(&white);
        assert_eq!(w.beta, 0.0);
        assert!((w.at(100) - 1.0).abs() < 0.2, "{}", w.at(100));
    }

    /// The pooled level's constants are the χ²₁ quantities they stand for, and on noise with a
    /// few strong lines the level is the noise's, the lines left out.
    #[test]
    fn pooled_level_constants_and_lines_left_out() {
        use statrs::distribution::ChiSquared;
        let chi1 = ChiSquared::new(1.0).unwrap();
        let chi3 = ChiSquared::new(3.0).unwrap();
        assert!((chi1.cdf(POOL_CLIP) - 0.99).abs() < 1e-12);
        let kept = chi3.cdf(POOL_CLIP) / chi1.cdf(POOL_CLIP);
        assert!((kept / POOL_KEPT_MEAN - 1.0).abs() < 1e-12, "{kept}");
        // 4000 bins of χ²₁ noise of mean 2, every 50th bin of the upper half a line 100× the
        // floor (40 lines): the pooled level within 6 % of 2 (the mean of 2000 bins scatters by
        // 3 %), where the plain mean of the upper half is three times too high.
        let z = crate::noise::standard_normal(4000, 21);
        let p: Vec<f64> = z
            .iter()
            .enumerate()
            .map(|(k, v)| 2.0 * v * v + if k >= 2000 && k % 50 == 0 { 200.0 } else { 0.0 })
            .collect();
        let f = NoiseFloor::fit(&p);
        assert_eq!(f.beta, 0.0);
        assert!((f.at(1) / 2.0 - 1.0).abs() < 0.06, "{}", f.at(1));
        let mean = p[2000..].iter().sum::<f64>() / 2000.0;
        assert!(mean > 5.0, "{mean}");
    }

    /// The floor's values at every bin are [`NoiseFloor::at`] to the bit, flat or sloped, so the
    /// cut-off and its cost on them are those of the per-bin formula.
    #[test]
    fn floor_values_are_the_per_bin_floor_to_the_bit() {
        for (beta, log_a) in [(0.0, 0.7), (0.0, -3.2), (-1.0, 2.5), (0.3, -0.4)] {
            let f = NoiseFloor {
                beta,
                ..NoiseFloor::flat(log_a, 16.0, 7.0, 3.0)
            };
            let v = f.values(500);
            for (k, x) in v.iter().enumerate() {
                assert_eq!(x.to_bits(), f.at(k).to_bits(), "β {beta}, bin {k}");
            }
        }
        // White and pink-like spectra: the cost on shared values is the per-bin sum.
        let noise = crate::noise::standard_normal(4000, 5);
        for tilt in [0.0, -1.0] {
            let p: Vec<f64> = noise
                .iter()
                .enumerate()
                .map(|(k, z)| {
                    z * z * ((k.max(1) as f64).powf(tilt)) + if k < 40 { 50.0 } else { 0.0 }
                })
                .collect();
            let ff = NoiseFloor::fit(&p);
            for kc in [0, 1, 37, 1999, 3999] {
                let kk = kc.min(p.len() - 1);
                let head: f64 = (1..=kk).map(|k| ff.at(k)).sum();
                let tail: f64 = (kk + 1..p.len()).map(|k| (p[k] - ff.at(k)).max(0.0)).sum();
                assert_eq!(cutoff_cost(&p, &ff, kc).to_bits(), (head + tail).to_bits());
            }
        }
    }

    /// The cut-off's two running sums walked in one loop give the bits of the plain form (the
    /// tail summed top-down, then the head bottom-up), on white and pink spectra.
    #[test]
    fn cutoff_scan_equals_the_plain_form_to_the_bit() {
        let noise = crate::noise::standard_normal(3000, 11);
        for tilt in [0.0, -1.0] {
            let p: Vec<f64> = noise
                .iter()
                .enumerate()
                .map(|(k, z)| {
                    let signal = if k < 200 { 100.0 } else { 0.0 };
                    z * z * (k.max(1) as f64).powf(tilt) + signal
                })
                .collect();
            let ff = NoiseFloor::fit(&p);
            let fl = ff.values(p.len());
            for min_bin in [0, 1, 5] {
                let k = p.len();
                let mut tail = vec![0.0; k + 1];
                for i in (0..k).rev() {
                    tail[i] = tail[i + 1] + (p[i] - fl[i]).max(0.0);
                }
                let start = min_bin.min(k - 1);
                let mut head: f64 = (0..start).map(|i| fl[i]).sum();
                let mut best = (start, f64::INFINITY, 0.0);
                for kc in start..k {
                    head += fl[kc];
                    let cost = head + tail[kc + 1];
                    if cost < best.1 {
                        best = (kc, cost, head - fl[0]);
                    }
                }
                // No harmonics above the band: the harmonic search leaves the cut-off.
                let (kc, _, noise_sum) = choose_cutoff_on(&p, &ff, &fl, min_bin);
                assert_eq!(kc, best.0, "tilt {tilt}, min_bin {min_bin}");
                assert_eq!(noise_sum.to_bits(), best.2.max(0.0).to_bits());
            }
        }
    }
}
