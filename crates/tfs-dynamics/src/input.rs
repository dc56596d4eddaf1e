//! Uniformly sampled inputs, interpolated between samples by a not-a-knot cubic spline.
//!
//! A measured excitation is known only at the sample times `t0 + k·dt`. Integrators need it at
//! arbitrary stage times, so it is interpolated. Linear interpolation has an `O(dt²)` error that
//! is far too large at ~10 samples per period; the not-a-knot cubic spline used here is exact for
//! cubics and has an `O(dt⁴)` error everywhere, including the ends (a natural spline would be
//! only `O(dt²)` near the ends). Outside `[t0, t_last]` the input is held at its end values.
//! The spline is `C²`: its third derivative jumps at the samples, so the integrators in this
//! crate stop at every sample time instead of stepping across one.

use crate::{DynError, Result};

/// How a [`SampledInput`] is interpolated between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// Not-a-knot cubic spline (default): `O(dt⁴)` error, exact for cubic polynomials.
    #[default]
    CubicSpline,
    /// Piecewise linear: `O(dt²)` error; only for comparison or piecewise-linear excitations.
    Linear,
}

/// A multi-channel input sampled at `t0 + k·dt`, `k = 0..len`, evaluated anywhere by interpolation.
///
/// ```
/// use tfs_dynamics::SampledInput;
/// // A cubic is reproduced exactly by the not-a-knot spline.
/// let f = |t: f64| 1.0 - t + 0.5 * t * t * t;
/// let samples: Vec<f64> = (0..8).map(|k| f(0.25 * k as f64)).collect();
/// let u = SampledInput::new(0.0, 0.25, vec![samples]).unwrap();
/// let mut out = [0.0];
/// u.eval(0.6, &mut out);
/// assert!((out[0] - f(0.6)).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct SampledInput {
    t0: f64,
    dt: f64,
    len: usize,
    interp: Interpolation,
    channels: Vec<Vec<f64>>,
    /// Spline second derivatives per channel (empty for linear interpolation).
    m: Vec<Vec<f64>>,
    /// `dt² / 6`, the spline's curvature weight, computed once instead of at every evaluation
    /// (the same expression, so the same value).
    h2: f64,
}

impl SampledInput {
    /// Builds a cubic-spline input; every channel must have the same length `≥ 1` and finite
    /// values, and `dt` must be positive and finite.
    pub fn new(t0: f64, dt: f64, channels: Vec<Vec<f64>>) -> Result<Self> {
        Self::with_interpolation(t0, dt, channels, Interpolation::CubicSpline)
    }

    /// Like [`SampledInput::new`] with an explicit interpolation method.
    pub fn with_interpolation(
        t0: f64,
        dt: f64,
        channels: Vec<Vec<f64>>,
        interp: Interpolation,
    ) -> Result<Self> {
        if !t0.is_finite() {
            return Err(DynError::InvalidParameter {
                name: "t0",
                reason: format!("start time {t0} is not finite; give a finite start time"),
            });
        }
        if !(dt.is_finite() && dt > 0.0) {
            return Err(DynError::InvalidParameter {
                name: "dt",
                reason: format!("sampling interval {dt} must be positive and finite"),
            });
        }
        let len = channels.first().map_or(1, Vec::len);
        for (c, ch) in channels.iter().enumerate() {
            if ch.len() != len {
                return Err(DynError::InvalidParameter {
                    name: "channels",
                    reason: format!(
                        "channel {c} has {} samples but channel 0 has {len}; give every channel the same length",
                        ch.len()
                    ),
                });
            }
            if ch.is_empty() {
                return Err(DynError::InvalidParameter {
                    name: "channels",
                    reason: format!("channel {c} is empty; give at least one sample"),
                });
            }
            if let Some(k) = ch.iter().position(|x| !x.is_finite()) {
                return Err(DynError::InvalidParameter {
                    name: "channels",
                    reason: format!(
                        "channel {c}, sample {k} is {}; remove or fill non-finite samples",
                        ch[k]
                    ),
                });
            }
        }
        let m = match interp {
            Interpolation::CubicSpline => channels
                .iter()
                .map(|y| spline_second_derivatives(y, dt))
                .collect(),
            Interpolation::Linear => Vec::new(),
        };
        Ok(Self {
            t0,
            dt,
            len,
            interp,
            channels,
            m,
            h2: dt * dt / 6.0,
        })
    }

    /// An input with `k` channels that are zero for all time (for autonomous runs use `zero(0)`).
    pub fn zero(k: usize) -> Self {
        Self {
            t0: 0.0,
            dt: 1.0,
            len: 1,
            interp: Interpolation::CubicSpline,
            channels: vec![vec![0.0]; k],
            m: vec![vec![0.0]; k],
            h2: 1.0 / 6.0,
        }
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.channels.len()
    }

    /// Number of samples per channel.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Always false: an input has at least one sample.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Time of the first sample (s).
    pub fn t0(&self) -> f64 {
        self.t0
    }

    /// Sampling interval (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Time of the last sample (s).
    pub fn t_end(&self) -> f64 {
        self.t0 + (self.len - 1) as f64 * self.dt
    }

    /// The samples of channel `c`.
    pub fn samples(&self, c: usize) -> &[f64] {
        &self.channels[c]
    }

    /// The interpolation method.
    pub fn interpolation(&self) -> Interpolation {
        self.interp
    }

    /// True when the input can vary in time (at least one channel and two samples); integrators
    /// then stop at every sample time.
    pub fn is_time_varying(&self) -> bool {
        !self.channels.is_empty() && self.len > 1
    }

    /// The first sample time strictly after `t` (with a relative tolerance), if any.
    pub fn next_sample_after(&self, t: f64) -> Option<f64> {
        if !self.is_time_varying() {
            return None;
        }
        let tol = 1e-9;
        let s = (t - self.t0) / self.dt;
        if s < -tol {
            return Some(self.t0);
        }
        let mut k = floor_nonneg(s + tol) + 1.0;
        // Far from t0 = 0 (a time column of absolute time stamps), `t − t0` loses more digits
        // than `tol` covers, and the sample found can be `t` itself: the integrator would then
        // stop there again and again. The next one is strictly later.
        while k <= (self.len - 1) as f64 && self.t0 + k * self.dt <= t {
            k += 1.0;
        }
        if k > (self.len - 1) as f64 {
            return None;
        }
        Some(self.t0 + k * self.dt)
    }

    /// Writes the interpolated value of every channel at time `t` into `out` (length
    /// [`SampledInput::channels`]). Outside the sampled range the end values are held.
    pub fn eval(&self, t: f64, out: &mut [f64]) {
        if self.len == 1 || self.channels.is_empty() {
            for (o, ch) in out.iter_mut().zip(&self.channels) {
                *o = ch[0];
            }
            return;
        }
        let s = (t - self.t0) / self.dt;
        let last = self.len - 1;
        if s.is_nan() || s <= 0.0 {
            for (o, ch) in out.iter_mut().zip(&self.channels) {
                *o = ch[0];
            }
            return;
        }
        if s >= (last as i64) as f64 {
            for (o, ch) in out.iter_mut().zip(&self.channels) {
                *o = ch[last];
            }
            return;
        }
        // `s` is positive, finite and below `last` here: truncation is its floor (a library call
        // otherwise), and through `i64` both conversions are single instructions (`usize`'s
        // take several on x86-64; the values are the same below 2^53).
        let i = ((s as i64) as usize).min(last - 1);
        let r = s - (i as i64) as f64;
        let q = 1.0 - r;
        match self.interp {
            Interpolation::Linear => {
                for (o, ch) in out.iter_mut().zip(&self.channels) {
                    *o = q * ch[i] + r * ch[i + 1];
                }
            }
            Interpolation::CubicSpline => {
                let h2 = self.h2;
                let wi = (q * q * q - q) * h2;
                let wj = (r * r * r - r) * h2;
                for ((o, ch), m) in out.iter_mut().zip(&self.channels).zip(&self.m) {
                    *o = q * ch[i] + r * ch[i + 1] + wi * m[i] + wj * m[i + 1];
                }
            }
        }
    }
}

/// `x.floor()` for `x ≥ 0` by truncation (exact below 2^52, where every `f64` with a fraction
/// lies), so the step loop does not call the library's `floor` at every step.
#[inline]
fn floor_nonneg(x: f64) -> f64 {
    if x < 4.0e15 {
        (x as u64) as f64
    } else {
        x.floor()
    }
}

/// Second derivatives `M_k` of the not-a-knot cubic spline through `y` on a uniform grid.
///
/// Interior rows: `M_{k-1} + 4 M_k + M_{k+1} = 6 (y_{k-1} − 2 y_k + y_{k+1}) / h²`. Not-a-knot
/// (continuous third derivative at the second and second-to-last samples) means `M_0 = 2 M_1 − M_2`
/// and `M_{n-1} = 2 M_{n-2} − M_{n-3}`; substituting turns the first and last interior rows into
/// `6 M_1 = r_1` and `6 M_{n-2} = r_{n-2}`. The remaining tridiagonal system is strictly
/// diagonally dominant and is solved by forward elimination and back substitution.
fn spline_second_derivatives(y: &[f64], h: f64) -> Vec<f64> {
    let n = y.len();
    let mut m = vec![0.0; n];
    if n < 3 {
        return m; // constant or linear
    }
    let r = |k: usize| 6.0 * (y[k - 1] - 2.0 * y[k] + y[k + 1]) / (h * h);
    if n == 3 {
        // The parabola through three points: constant second derivative.
        let c = r(1) / 6.0;
        return vec![c; 3];
    }
    // Unknowns M_1..M_{n-2}: p = n - 2 of them. The off-diagonals are 1 but for the first
    // row's upper and the last row's lower entry (0); the solution is written into `m[1..=p]`,
    // so the solve holds two vectors besides `m` (an input of 640k samples is 5 MB each).
    let p = n - 2;
    let lower = |j: usize| if j == p - 1 { 0.0 } else { 1.0 }; // multiplies M_{j-1} in row j
    let upper = |j: usize| if j == 0 { 0.0 } else { 1.0 }; // multiplies M_{j+1} in row j
    let mut diag = vec![4.0; p];
    let mut rhs: Vec<f64> = (1..=p).map(r).collect();
    diag[0] = 6.0;
    diag[p - 1] = 6.0;
    for j in 1..p {
        let w = lower(j) / diag[j - 1];
        diag[j] -= w * upper(j - 1);
        rhs[j] -= w * rhs[j - 1];
    }
    let sol = &mut m[1..=p];
    sol[p - 1] = rhs[p - 1] / diag[p - 1];
    for j in (0..p - 1).rev() {
        sol[j] = (rhs[j] - upper(j) * sol[j + 1]) / diag[j];
    }
    m[0] = 2.0 * m[1] - m[2];
    m[n - 1] = 2.0 * m[n - 2] - m[n - 3];
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spline_reproduces_cubics_and_hits_samples() {
        let f = |t: f64| 2.0 - 3.0 * t + 0.7 * t * t - 0.4 * t * t * t;
        for n in [4usize, 5, 9, 30] {
            let dt = 0.3;
            let y: Vec<f64> = (0..n).map(|k| f(1.0 + dt * k as f64)).collect();
            let u = SampledInput::new(1.0, dt, vec![y.clone()]).unwrap();
            let mut o = [0.0];
            for j in 0..200 {
                let t = 1.0 + (n - 1) as f64 * dt * j as f64 / 199.0;
                u.eval(t, &mut o);
                assert!((o[0] - f(t)).abs() < 1e-10, "n={n} t={t}");
            }
            for (k, yk) in y.iter().enumerate() {
                u.eval(1.0 + dt * k as f64, &mut o);
                assert!((o[0] - yk).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn spline_error_is_fourth_order() {
        // Max error on sin for dt and dt/2: ratio ≈ 16.
        let err = |dt: f64| {
            let n = (10.0 / dt).round() as usize + 1;
            let y: Vec<f64> = (0..n).map(|k| (dt * k as f64).sin()).collect();
            let u = SampledInput::new(0.0, dt, vec![y]).unwrap();
            let mut o = [0.0];
            let mut e: f64 = 0.0;
            for j in 0..5000 {
                let t = 10.0 * j as f64 / 4999.0;
                u.eval(t, &mut o);
                e = e.max((o[0] - t.sin()).abs());
            }
            e
        };
        let (e1, e2) = (err(0.2), err(0.1));
        let order = (e1 / e2).log2();
        assert!((3.6..4.4).contains(&order), "order {order}");
    }

    #[test]
    fn clamps_outside_and_linear_mode() {
        let u = SampledInput::with_interpolation(
            0.0,
            1.0,
            vec![vec![0.0, 2.0, 4.0, 1.0]],
            Interpolation::Linear,
        )
        .unwrap();
        let mut o = [0.0];
        u.eval(-5.0, &mut o);
        assert_eq!(o[0], 0.0);
        u.eval(10.0, &mut o);
        assert_eq!(o[0], 1.0);
        u.eval(2.5, &mut o);
        assert!((o[0] - 2.5).abs() < 1e-15);
    }

    #[test]
    fn next_sample_after_is_strict() {
        let u = SampledInput::new(1.0, 0.5, vec![vec![0.0; 5]]).unwrap();
        assert_eq!(u.next_sample_after(0.0), Some(1.0));
        assert_eq!(u.next_sample_after(1.0), Some(1.5));
        assert_eq!(u.next_sample_after(1.2), Some(1.5));
        assert_eq!(u.next_sample_after(2.9), Some(3.0));
        assert_eq!(u.next_sample_after(3.0), None);
        assert_eq!(SampledInput::zero(2).next_sample_after(0.0), None);
        // Absolute time stamps: every sample's successor is strictly later, whatever the
        // rounding of `t − t0` (the solver stopped at the same sample forever before).
        let t0 = 1.7e9;
        let dt = 0.01;
        let u = SampledInput::new(t0, dt, vec![vec![0.0; 2001]]).unwrap();
        for k in 0..2000 {
            let t = t0 + k as f64 * dt;
            let next = u.next_sample_after(t).unwrap();
            assert!(next > t, "sample {k}: {next} is not after {t}");
            assert!(
                next - t < 1.5 * dt,
                "sample {k}: {next} skips past the next sample"
            );
        }
    }

    #[test]
    fn floor_by_truncation_is_floor() {
        let mut x = 0.0f64;
        for k in 0..2000 {
            x = x * 1.37 + 0.011 * k as f64;
            let v = x % 5.0e15;
            for v in [v, v.fract(), -0.0, 0.0, 4.0e15, 1.0e17, f64::NAN] {
                let want = v.floor();
                assert!(floor_nonneg(v) == want || (v.is_nan() && floor_nonneg(v).is_nan()));
            }
        }
    }

    #[test]
    fn rejects_bad_input() {
        assert!(SampledInput::new(0.0, 0.0, vec![vec![1.0]]).is_err());
        assert!(SampledInput::new(0.0, 1.0, vec![vec![1.0], vec![1.0, 2.0]]).is_err());
        let e = SampledInput::new(0.0, 1.0, vec![vec![1.0, f64::NAN]]).unwrap_err();
        assert!(e.to_string().contains("sample 1"));
    }
}
