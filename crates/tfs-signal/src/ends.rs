//! The slopes of a record at its two ends, and the smooth trend that carries them, so that the
//! mirror (even) extension behind every band-limited reconstruction joins smoothly.
//!
//! The even extension `x, reversed x` is continuous at both joins, but its slope jumps from
//! `x'(T)` to `−x'(T)` (and from `−x'(0)` to `x'(0)`): unless the record starts and ends at
//! rest, the extension has a kink at each join, whose spectrum falls only as `1/f²` in
//! amplitude. On a short record of a few periods that tail rises above the noise floor for
//! decades of frequency; the cut-off chosen from the spectrum then follows the artefact, lets in
//! the noise of a band many times wider than the signal's, and its second derivative (a pair of
//! impulses at the joins) rings through the whole reconstruction. Subtracting the trend
//! `h(t) = s₀·t + (s₁ − s₀)·t²/(2T)`, whose slope is the record's own slope `s₀` at the start and
//! `s₁` at the end, leaves a remainder with zero slope at both ends, whose even extension is
//! smooth to first order; the trend is added back, with its exact derivatives, after the
//! reconstruction.

/// Slope at the first sample of `y` (sampled at `dt`): the derivative at `t = 0` of the
/// least-squares quadratic through its first `m` samples (`m ≥ 3`; fewer samples give 0).
fn start_slope(y: impl Iterator<Item = f64>, m: usize, dt: f64) -> f64 {
    // Normal equations of y ≈ a + b·i + c·i² over i = 0..m, solved by Cramer's rule on the
    // 3×3 system (moments of i are exact integers below 2^53 for any record length used here).
    if m < 3 {
        return 0.0;
    }
    let (mut s0, mut s1, mut s2, mut s3, mut s4) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let (mut t0, mut t1, mut t2) = (0.0f64, 0.0f64, 0.0f64);
    for (i, v) in y.take(m).enumerate() {
        let i = i as f64;
        let i2 = i * i;
        s0 += 1.0;
        s1 += i;
        s2 += i2;
        s3 += i2 * i;
        s4 += i2 * i2;
        t0 += v;
        t1 += v * i;
        t2 += v * i2;
    }
    let det3 = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let m3 = [[s0, s1, s2], [s1, s2, s3], [s2, s3, s4]];
    let d = det3(m3);
    if !(d.is_finite() && d > 0.0) {
        return 0.0;
    }
    let mb = [[s0, t0, s2], [s1, t1, s3], [s2, t2, s4]];
    let b = det3(mb) / d;
    if b.is_finite() { b / dt } else { 0.0 }
}

/// The slopes of `x` (sampled at `dt`) at its first and last sample, each from a least-squares
/// quadratic through the `m` samples at that end (`m` is clamped to `3..=len/2`).
pub fn end_slopes(x: &[f64], dt: f64, m: usize) -> (f64, f64) {
    let n = x.len();
    if n < 6 || dt.is_nan() || dt <= 0.0 {
        return (0.0, 0.0);
    }
    let m = m.clamp(3, n / 2);
    let s0 = start_slope(x.iter().copied(), m, dt);
    // The end read backwards: its slope at the reversed start is −x'(T).
    let s1 = -start_slope(x.iter().rev().copied(), m, dt);
    (s0, s1)
}

/// The trend `h(t) = s₀·t + (s₁ − s₀)·t²/(2T)` over `n` samples at `dt` (`T = (n−1)·dt`), with
/// `h'(0) = s₀` and `h'(T) = s₁`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndTrend {
    /// Slope at the first sample.
    pub s0: f64,
    /// Slope at the last sample.
    pub s1: f64,
    /// Length of the record in seconds between its first and last sample.
    pub span: f64,
}

impl EndTrend {
    /// The trend with slopes `s0` and `s1` over a record of `n` samples at `dt`.
    pub fn new(s0: f64, s1: f64, n: usize, dt: f64) -> Self {
        Self {
            s0,
            s1,
            span: (n.saturating_sub(1)) as f64 * dt,
        }
    }

    /// `h`, `h'` and `h''` at time `t` from the first sample.
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        if self.span <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let c = (self.s1 - self.s0) / self.span;
        (self.s0 * t + 0.5 * c * t * t, self.s0 + c * t, c)
    }

    /// `x − h` sampled at `dt`.
    pub fn remove(&self, x: &[f64], dt: f64) -> Vec<f64> {
        x.iter()
            .enumerate()
            .map(|(i, v)| v - self.at(i as f64 * dt).0)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slopes_of_a_quadratic_are_exact() {
        let dt = 0.01;
        let x: Vec<f64> = (0..200)
            .map(|i| {
                let t = i as f64 * dt;
                1.0 + 2.0 * t - 3.0 * t * t
            })
            .collect();
        let (s0, s1) = end_slopes(&x, dt, 10);
        assert!((s0 - 2.0).abs() < 1e-9, "{s0}");
        let t_end = 199.0 * dt;
        assert!((s1 - (2.0 - 6.0 * t_end)).abs() < 1e-9, "{s1}");
    }

    #[test]
    fn the_trend_carries_both_slopes_and_its_removal_leaves_flat_ends() {
        let dt = 0.01;
        let n = 500;
        let x: Vec<f64> = (0..n).map(|i| (1.3 * i as f64 * dt).sin()).collect();
        let (s0, s1) = end_slopes(&x, dt, 12);
        let h = EndTrend::new(s0, s1, n, dt);
        assert!((h.at(0.0).1 - s0).abs() < 1e-12);
        assert!((h.at(h.span).1 - s1).abs() < 1e-12);
        let r = h.remove(&x, dt);
        let (r0, r1) = end_slopes(&r, dt, 12);
        assert!(r0.abs() < 1e-9 && r1.abs() < 1e-9, "{r0} {r1}");
    }
}
