//! Transforms over overlapping windows of a record: the layout of the windows, the angular
//! frequencies of their bins, and the transform of a signal times the periodic `sin⁴` window
//! ([`crate::Window::HannSquared`], [`crate::Window::sample_periodic`]) at chosen bins, plain or
//! in the weak (derivative-transfer) form of its first or second derivative.

use crate::Complex;
use crate::fft::{smooth_len, with_fft};

/// Start indices and length of `count` windows with 50 % overlap covering `n` samples (the
/// length is rounded down to a fast FFT size).
pub fn window_layout(n: usize, count: usize) -> (Vec<usize>, usize) {
    let count = count.max(1);
    let len = smooth_len((2 * n / (count + 1)).min(n)).max(8).min(n);
    let hop = if count > 1 {
        (n - len) / (count - 1)
    } else {
        0
    };
    ((0..count).map(|i| i * hop).collect(), len)
}

/// Angular frequencies (rad/s) of the bins `0..=len/2` of a window of `len` samples.
pub fn bin_omegas(len: usize, dt: f64) -> Vec<f64> {
    let t = len as f64 * dt;
    (0..=len / 2)
        .map(|k| 2.0 * std::f64::consts::PI * k as f64 / t)
        .collect()
}

/// FFT (bins 0..=len/2) of `f ⊙ w` over one window, scaled by `dt` (a Riemann sum of the
/// integral): the direct form of [`windowed_bins`]' `Weighting::Plain`, kept as its reference.
#[cfg(test)]
pub(crate) fn windowed_fft(f: &[f64], w: &[f64], dt: f64) -> Vec<Complex<f64>> {
    with_fft(f, Some(w), dt, <[Complex<f64>]>::to_vec)
}

/// What [`windowed_bins`] transforms: the windowed signal, or the weak form of its first or
/// second derivative (the derivatives moved onto the window).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Weighting {
    /// `F[f·w]`.
    Plain,
    /// The weak form of `f'`: `−(F[f·w'] − iω·F[f·w])`.
    First,
    /// The weak form of `f''`: `F[f·w''] − 2iω·F[f·w'] − ω²·F[f·w]`.
    Second,
}

/// The transform `weighting` of `f` over one window of `f.len()` samples (the periodic `sin⁴`
/// window), scaled by `dt`, at the bins `bins` (`om`: the window's bin frequencies,
/// [`bin_omegas`]).
///
/// The window and its derivatives are trigonometric polynomials of degree two on the window's
/// own transform grid: with `s = n/len` and `T = len·dt`,
/// `w = 3/8 − ½·cos 2πs + ⅛·cos 4πs`, `w' = (π/T)·(sin 2πs − ½·sin 4πs)` and
/// `w'' = (2π²/T²)·(cos 2πs − cos 4πs)`. Multiplying by `e^{±2πims}` shifts a transform by `∓m`
/// bins, so `F[f·w]`, `F[f·w']` and `F[f·w'']` at bin `k` are combinations of the plain
/// transform `F[f]` at bins `k−2 … k+2`: one transform of `f` serves all three. The results
/// equal those of the windowed transforms to rounding.
pub fn windowed_bins(
    f: &[f64],
    dt: f64,
    om: &[f64],
    bins: &[usize],
    weighting: Weighting,
) -> Vec<Complex<f64>> {
    let len = f.len();
    let t = len as f64 * dt;
    let pi = std::f64::consts::PI;
    let (c1, c2) = (pi / t, 2.0 * pi * pi / (t * t));
    with_fft(f, None, dt, |g| {
        // Bin `k` of the full (Hermitian) transform.
        let at = |k: isize| -> Complex<f64> {
            let k = k.rem_euclid(len as isize) as usize;
            if k < g.len() { g[k] } else { g[len - k].conj() }
        };
        // `z / (2i)`.
        let over_2i = |z: Complex<f64>| Complex::new(0.5 * z.im, -0.5 * z.re);
        bins.iter()
            .map(|&k| {
                let ki = k as isize;
                let (m2, m1, f0, p1, p2) = (at(ki - 2), at(ki - 1), at(ki), at(ki + 1), at(ki + 2));
                let w0 = f0 * 0.375 - (m1 + p1) * 0.25 + (m2 + p2) * 0.0625;
                if weighting == Weighting::Plain {
                    return w0;
                }
                let w1 = (over_2i(m1 - p1) - over_2i(m2 - p2) * 0.5) * c1;
                let iw = Complex::new(0.0, om[k]);
                match weighting {
                    Weighting::First => -(w1 - iw * w0),
                    _ => {
                        let w2 = ((m1 + p1) * 0.5 - (m2 + p2) * 0.5) * c2;
                        w2 - iw * w1 * 2.0 - w0 * (om[k] * om[k])
                    }
                }
            })
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Window, WindowSamples};

    /// Weak-form transform of `x''`: `F[x w''] − 2iω F[x w'] − ω² F[x w]`, by one windowed
    /// transform per window function (the direct form of [`windowed_bins`]' `Weighting::Second`,
    /// kept as its reference).
    fn weak_second_derivative(
        x: &[f64],
        win: &WindowSamples,
        om: &[f64],
        dt: f64,
    ) -> Vec<Complex<f64>> {
        let f0 = windowed_fft(x, &win.w, dt);
        let f1 = windowed_fft(x, &win.dw, dt);
        let f2 = windowed_fft(x, &win.ddw, dt);
        (0..om.len())
            .map(|k| f2[k] - Complex::new(0.0, 2.0 * om[k]) * f1[k] - om[k] * om[k] * f0[k])
            .collect()
    }

    /// Weak-form transform of `G'`: `−(F[G w'] − iω F[G w])`, by one windowed transform per window
    /// function (the direct form of [`windowed_bins`]' `Weighting::First`, kept as its reference).
    fn weak_first_derivative(
        g: &[f64],
        win: &WindowSamples,
        om: &[f64],
        dt: f64,
    ) -> Vec<Complex<f64>> {
        let f0 = windowed_fft(g, &win.w, dt);
        let f1 = windowed_fft(g, &win.dw, dt);
        (0..om.len())
            .map(|k| -(f1[k] - Complex::new(0.0, om[k]) * f0[k]))
            .collect()
    }

    /// The five-bin combinations of one plain transform equal the transforms of the signal times
    /// the window and its derivatives, at every bin (the ends of the spectrum included, where the
    /// combination wraps around through the conjugate bins).
    #[test]
    fn window_bins_equal_the_directly_windowed_transforms() {
        for (len, dt) in [(600usize, 0.02), (375, 0.05), (64, 1.0)] {
            let f: Vec<f64> = (0..len)
                .map(|i| {
                    let t = i as f64 * dt;
                    (0.7 * t).sin() + 0.3 * (5.1 * t + 0.4).cos() + 0.01 * ((i * i) % 7) as f64
                })
                .collect();
            let win = Window::HannSquared.sample_periodic(len, dt).unwrap();
            let om = bin_omegas(len, dt);
            let all: Vec<usize> = (0..om.len()).collect();
            for (got, want) in [
                (
                    windowed_bins(&f, dt, &om, &all, Weighting::Plain),
                    windowed_fft(&f, &win.w, dt),
                ),
                (
                    windowed_bins(&f, dt, &om, &all, Weighting::First),
                    weak_first_derivative(&f, &win, &om, dt),
                ),
                (
                    windowed_bins(&f, dt, &om, &all, Weighting::Second),
                    weak_second_derivative(&f, &win, &om, dt),
                ),
            ] {
                let scale = want.iter().fold(0.0f64, |m, c| m.max(c.norm()));
                for k in 0..om.len() {
                    assert!(
                        (got[k] - want[k]).norm() <= 1e-12 * scale,
                        "len {len}, bin {k}: {} vs {}",
                        got[k],
                        want[k]
                    );
                }
            }
            let some = [3usize, 1, len / 2];
            let at = windowed_bins(&f, dt, &om, &some, Weighting::Second);
            let full = windowed_bins(&f, dt, &om, &all, Weighting::Second);
            for (v, &k) in at.iter().zip(&some) {
                assert_eq!(*v, full[k]);
            }
        }
    }

    /// The weak transforms of x'' and x' equal the windowed transforms of the analytic derivatives.
    #[test]
    fn derivative_transfer_matches_analytic_derivatives() {
        let dt = 0.005;
        let n = 4001;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let x: Vec<f64> = t
            .iter()
            .map(|&t| (1.3 * t).sin() + 0.4 * (3.1 * t + 0.2).cos())
            .collect();
        let v: Vec<f64> = t
            .iter()
            .map(|&t| 1.3 * (1.3 * t).cos() - 1.24 * (3.1 * t + 0.2).sin())
            .collect();
        let a: Vec<f64> = t
            .iter()
            .map(|&t| -1.69 * (1.3 * t).sin() - 0.4 * 9.61 * (3.1 * t + 0.2).cos())
            .collect();
        let win = Window::HannSquared.sample_periodic(n, dt).unwrap();
        let om = bin_omegas(n, dt);

        let wa = weak_second_derivative(&x, &win, &om, dt);
        let fa = windowed_fft(&a, &win.w, dt);
        let wv = weak_first_derivative(&x, &win, &om, dt);
        let fv = windowed_fft(&v, &win.w, dt);
        let scale = fa.iter().fold(0.0f64, |m, c| m.max(c.norm()));
        for k in 0..40 {
            assert!(
                (wa[k] - fa[k]).norm() < 1e-5 * scale,
                "bin {k}: {} vs {}",
                wa[k],
                fa[k]
            );
            assert!((wv[k] - fv[k]).norm() < 1e-5 * scale, "bin {k}");
        }
    }

    #[test]
    fn window_layout_covers_the_record() {
        let (starts, len) = window_layout(1000, 5);
        assert_eq!(starts.len(), 5);
        assert!(starts[4] + len <= 1000 && starts[4] + len > 990);
        let ws = Window::HannSquared.sample_periodic(100, 0.1).unwrap();
        let (w, w1, w2) = (&ws.w, &ws.dw, &ws.ddw);
        assert!(w[0].abs() < 1e-15 && w1[0].abs() < 1e-15 && (w[50] - 1.0).abs() < 1e-12);
        // Periodic: the last samples lead back to zero at sample 100 like the first ones leave it.
        for i in 1..5 {
            assert!((w[100 - i] - w[i]).abs() < 1e-12);
            assert!((w1[100 - i] + w1[i]).abs() < 1e-9 && (w2[100 - i] - w2[i]).abs() < 1e-9);
        }
    }
}
