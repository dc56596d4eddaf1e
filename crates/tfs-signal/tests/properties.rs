//! Property tests: differentiation exactness and accuracy, noise SNR and spectrum, window
//! derivatives, the derivative-transfer identity and sweep frequency laws.

use proptest::prelude::*;
use std::f64::consts::PI;
use tfs_signal::noise::{self, NoiseKind};
use tfs_signal::{
    Complex, Differentiator, Excitation, SpectralEnds, SpectrumPlanner, Sweep, SweepKind, Window,
    central_difference, central_difference4, savitzky_golay, spectral_derivative,
    spectral_derivative_with,
};

/// Polynomial value and derivatives 0..=2 at t (coefficients c[k] of t^k).
fn poly(c: &[f64], t: f64, d: usize) -> f64 {
    c.iter()
        .enumerate()
        .filter(|(k, _)| *k >= d)
        .map(|(k, ck)| {
            let fall: f64 = (0..d).map(|j| (k - j) as f64).product();
            ck * fall * t.powi((k - d) as i32)
        })
        .sum()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn central_differences_exact_on_polynomials(
        c in prop::collection::vec(-3.0f64..3.0, 5),
        n in 6usize..40,
        dt in 0.01f64..0.5,
        t0 in -2.0f64..2.0,
    ) {
        let t: Vec<f64> = (0..n).map(|k| t0 + k as f64 * dt).collect();
        for d in 1..=2 {
            // 2nd order: exact on quadratics everywhere (ends included).
            let q = &c[..3];
            let x: Vec<f64> = t.iter().map(|&s| poly(q, s, 0)).collect();
            let want: Vec<f64> = t.iter().map(|&s| poly(q, s, d)).collect();
            let got = central_difference(&x, dt, d).unwrap();
            let scale = 1.0 + want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let tol = 1e-9 * scale * (1.0 + (t0.abs() + n as f64 * dt).powi(2)) / dt.powi(d as i32);
            prop_assert!(max_abs_diff(&got, &want) < tol, "d={} err={}", d, max_abs_diff(&got, &want));
            // 4th order: exact on quartics everywhere.
            let x4: Vec<f64> = t.iter().map(|&s| poly(&c, s, 0)).collect();
            let want4: Vec<f64> = t.iter().map(|&s| poly(&c, s, d)).collect();
            let got4 = central_difference4(&x4, dt, d).unwrap();
            let scale4 = 1.0 + x4.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            prop_assert!(max_abs_diff(&got4, &want4) < 1e-9 * scale4 / dt.powi(d as i32), "d={} err={}", d, max_abs_diff(&got4, &want4));
        }
    }

    #[test]
    fn savitzky_golay_exact_on_polynomials_including_ends(
        c in prop::collection::vec(-2.0f64..2.0, 6),
        h in 2usize..7,
        p_raw in 1usize..6,
        extra in 0usize..20,
        dt in 0.02f64..0.3,
    ) {
        let p = p_raw.min(2 * h);
        let n = 2 * h + 1 + extra;
        let t: Vec<f64> = (0..n).map(|k| -0.5 + k as f64 * dt).collect();
        let coef = &c[..=p];
        let x: Vec<f64> = t.iter().map(|&s| poly(coef, s, 0)).collect();
        let scale = 1.0 + x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for d in 0..=p.min(2) {
            let want: Vec<f64> = t.iter().map(|&s| poly(coef, s, d)).collect();
            let got = savitzky_golay(&x, dt, h, p, d).unwrap();
            let tol = 1e-8 * scale / (dt * h as f64).powi(d as i32);
            prop_assert!(max_abs_diff(&got, &want) < tol, "h={} p={} d={} err={} tol={}", h, p, d, max_abs_diff(&got, &want), tol);
        }
    }

    #[test]
    fn spectral_derivative_of_periodic_sine(m in 1usize..20, n in 64usize..300, phase in 0.0f64..6.3, dt in 0.001f64..0.1) {
        let big_t = n as f64 * dt;
        let w = 2.0 * PI * m as f64 / big_t;
        let x: Vec<f64> = (0..n).map(|k| (w * k as f64 * dt + phase).sin()).collect();
        let d1 = spectral_derivative_with(&x, dt, 1, None, SpectralEnds::Periodic).unwrap();
        let d2 = spectral_derivative_with(&x, dt, 2, None, SpectralEnds::Periodic).unwrap();
        for k in 0..n {
            let t = k as f64 * dt;
            prop_assert!((d1[k] / w - (w * t + phase).cos()).abs() < 1e-8);
            prop_assert!((d2[k] / (w * w) + (w * t + phase).sin()).abs() < 1e-8);
        }
    }

    #[test]
    fn differentiators_close_on_non_periodic_sines(f in 0.3f64..2.0, phase in 0.0f64..6.3) {
        // 10 s at 200 Hz: ~100–400 samples per period, non-integer number of periods.
        let dt = 0.005;
        let n = 2001;
        let w = 2.0 * PI * f;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let x: Vec<f64> = t.iter().map(|&s| (w * s + phase).sin()).collect();
        let v: Vec<f64> = t.iter().map(|&s| w * (w * s + phase).cos()).collect();
        let a: Vec<f64> = t.iter().map(|&s| -w * w * (w * s + phase).sin()).collect();
        // Central differences: truncation error w³dt²/6 (velocity), w⁴dt²/12 (acceleration) in the
        // interior; one-sided ends are ≤ 4× / 11× worse.
        let cd1 = central_difference(&x, dt, 1).unwrap();
        let cd2 = central_difference(&x, dt, 2).unwrap();
        prop_assert!(max_abs_diff(&cd1, &v) < 4.0 * w.powi(3) * dt * dt / 3.0 + 1e-9);
        prop_assert!(max_abs_diff(&cd2, &a) < 11.0 * w.powi(4) * dt * dt / 12.0 + 1e-6);
        // Interior of the 4th-order scheme: w⁵dt⁴/30.
        let c4 = central_difference4(&x, dt, 1).unwrap();
        prop_assert!(max_abs_diff(&c4[2..n - 2], &v[2..n - 2]) < w.powi(5) * dt.powi(4) / 30.0 + 1e-9);
        // Savitzky–Golay, quartic over 21 samples (half-width H = 10·dt seconds): the centred fit
        // is exact to degree 5, so the interior error is O((ωH)⁴); the asymmetric end fits are exact
        // to degree 4, so the end error is O((ωH)³). Constants: a few times the Taylor-term size.
        let sg = Differentiator::SavitzkyGolay { half_window: 10, poly_order: 4 }.apply(&x, dt, 2).unwrap();
        let wh = w * 10.0 * dt;
        let rel: Vec<f64> = sg.iter().zip(&a).map(|(p, q)| (p - q).abs() / (w * w)).collect();
        let interior = rel[10..n - 10].iter().cloned().fold(0.0, f64::max);
        let all = rel.iter().cloned().fold(0.0, f64::max);
        prop_assert!(interior < 0.01 * wh.powi(4), "sg interior {}", interior);
        prop_assert!(all < 0.25 * wh.powi(3), "sg all {}", all);
        // Spectral with detrend + odd extension: relative error below 1e-5 away from the last
        // 5 % at each end; first derivative below 5e-2 everywhere. (The odd extension forces the
        // second derivative to zero at the two end samples: documented end effect.)
        for (d, want) in [(1usize, &v), (2, &a)] {
            let sp = spectral_derivative(&x, dt, d, None).unwrap();
            let m = n / 20;
            let scale = w.powi(d as i32);
            prop_assert!(max_abs_diff(&sp[m..n - m], &want[m..n - m]) < 1e-5 * scale, "d={} interior err {}", d, max_abs_diff(&sp[m..n - m], &want[m..n - m]) / scale);
            if d == 1 {
                prop_assert!(max_abs_diff(&sp, want) < 5e-2 * scale, "d={} err {}", d, max_abs_diff(&sp, want) / scale);
            }
        }
    }

    #[test]
    fn noise_hits_requested_snr(snr in 0.0f64..80.0, seed in 0u64..1000, pink in any::<bool>(), n in 16usize..2000, amp in 0.01f64..100.0) {
        let x: Vec<f64> = (0..n).map(|k| amp * ((k as f64 * 0.037).sin() + 0.3)).collect();
        let kind = if pink { NoiseKind::Pink } else { NoiseKind::White };
        let nz = noise::noise_for(&x, snr, kind, seed).unwrap();
        let realised = noise::snr_db(&x, &nz).unwrap();
        prop_assert!((realised - snr).abs() < 0.1);
        prop_assert!((realised - snr).abs() < 1e-9);
        let y = noise::add_noise_seeded(&x, snr, kind, seed).unwrap();
        let resid: Vec<f64> = y.iter().zip(&x).map(|(a, b)| a - b).collect();
        prop_assert!((noise::snr_db(&x, &resid).unwrap() - snr).abs() < 1e-6);
    }

    #[test]
    fn window_derivatives_match_finite_differences(which in 0usize..6, s in 0.01f64..0.99) {
        let win = [Window::Hann, Window::HannSquared, Window::Tukey { alpha: 0.4 }, Window::Bump { p: 3 }, Window::Bump { p: 5 }, Window::Tukey { alpha: 1.0 }][which];
        // Avoid the Tukey kinks in w'' at the taper joints.
        if let Window::Tukey { alpha } = win {
            prop_assume!((s - alpha / 2.0).abs() > 1e-3 && (s - 1.0 + alpha / 2.0).abs() > 1e-3);
        }
        let h = 1e-5;
        let (_, d, dd) = win.eval_unit(s);
        let (wp, dp, _) = win.eval_unit(s + h);
        let (wm, dm, _) = win.eval_unit(s - h);
        prop_assert!((d - (wp - wm) / (2.0 * h)).abs() < 1e-6 * (1.0 + d.abs()));
        prop_assert!((dd - (dp - dm) / (2.0 * h)).abs() < 1e-5 * (1.0 + dd.abs()));
    }
}

#[test]
fn sampled_window_time_derivatives_match_differences() {
    for win in [Window::Hann, Window::HannSquared, Window::Bump { p: 4 }] {
        let (n, dt) = (4001, 0.0025);
        let ws = win.sample(n, dt).unwrap();
        let d1 = central_difference4(&ws.w, dt, 1).unwrap();
        let d2 = central_difference4(&ws.w, dt, 2).unwrap();
        let s1 = ws.dw.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let s2 = ws.ddw.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(max_abs_diff(&d1, &ws.dw) < 1e-7 * s1, "{win:?}");
        assert!(max_abs_diff(&d2, &ws.ddw) < 1e-6 * s2, "{win:?}");
        assert!(win.supports_derivative_transfer());
        assert_eq!(ws.w[0], 0.0);
        assert!(ws.w[n - 1].abs() < 1e-30 && ws.dw[0].abs() < 1e-30 && ws.dw[n - 1].abs() < 1e-12);
    }
    assert!(!Window::Rectangular.supports_derivative_transfer());
    assert!(Window::Tukey { alpha: 1.5 }.sample(10, 0.1).is_err());
    assert!(Window::Hann.sample(1, 0.1).is_err());
    assert!(Window::Hann.sample(10, -0.1).is_err());
}

#[test]
fn derivative_transfer_identity() {
    // Smooth, non-periodic x(t) with analytic x''; FFT(x''·w) ≈ FFT(x·(w'' − 2iωw' − ω²w)).
    let (n, dt) = (8000, 1e-3);
    let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    let (w1, w2) = (2.0 * PI * 3.1, 2.0 * PI * 7.7);
    let x: Vec<f64> = t
        .iter()
        .map(|&s| (w1 * s).sin() + 0.4 * (w2 * s + 0.3).cos() + 0.2 * s * s)
        .collect();
    let xdd: Vec<f64> = t
        .iter()
        .map(|&s| -w1 * w1 * (w1 * s).sin() - 0.4 * w2 * w2 * (w2 * s + 0.3).cos() + 0.4)
        .collect();
    for win in [Window::Hann, Window::HannSquared, Window::Bump { p: 3 }] {
        let ws = win.sample(n, dt).unwrap();
        let mut p = SpectrumPlanner::new();
        let mul = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, v)| u * v).collect::<Vec<f64>>();
        let lhs = p.rfft(&mul(&xdd, &ws.w)).unwrap();
        let f0 = p.rfft(&mul(&x, &ws.w)).unwrap();
        let f1 = p.rfft(&mul(&x, &ws.dw)).unwrap();
        let f2 = p.rfft(&mul(&x, &ws.ddw)).unwrap();
        let freqs = tfs_signal::frequencies(n, dt).unwrap();
        let scale = lhs.iter().fold(0.0f64, |m, c| m.max(c.norm()));
        for k in 0..200 {
            let om = 2.0 * PI * freqs[k];
            let rhs = f2[k] - Complex::new(0.0, 2.0 * om) * f1[k] - om * om * f0[k];
            assert!(
                (lhs[k] - rhs).norm() < 1e-4 * scale,
                "{win:?} bin {k}: {} vs {}",
                lhs[k],
                rhs
            );
        }
    }
}

#[test]
fn pink_noise_spectrum_slope_is_minus_one() {
    let n = 1 << 16;
    let x: Vec<f64> = (0..n).map(|k| (k as f64 * 0.01).sin()).collect();
    for seed in [1u64, 2, 3] {
        let nz = noise::noise_for(&x, 10.0, NoiseKind::Pink, seed).unwrap();
        let spec = tfs_signal::rfft(&nz).unwrap();
        // Average the periodogram in log-spaced bands, then fit log P = a + b log f.
        let (mut lx, mut ly) = (Vec::new(), Vec::new());
        let mut lo = 4usize;
        while lo < n / 2 {
            let hi = ((lo as f64 * 1.25) as usize).max(lo + 1).min(n / 2);
            let p: f64 = spec[lo..hi].iter().map(|c| c.norm_sqr()).sum::<f64>() / (hi - lo) as f64;
            let fc = ((lo as f64) * (hi as f64 - 1.0)).sqrt().max(lo as f64);
            lx.push(fc.ln());
            ly.push(p.ln());
            lo = hi;
        }
        let m = lx.len() as f64;
        let (mx, my) = (lx.iter().sum::<f64>() / m, ly.iter().sum::<f64>() / m);
        let sxy: f64 = lx.iter().zip(&ly).map(|(a, b)| (a - mx) * (b - my)).sum();
        let sxx: f64 = lx.iter().map(|a| (a - mx) * (a - mx)).sum();
        let slope = sxy / sxx;
        assert!((slope + 1.0).abs() < 0.15, "seed {seed}: slope {slope}");
        // White noise, same fit: slope ≈ 0.
        let wn = noise::noise_for(&x, 10.0, NoiseKind::White, seed).unwrap();
        let ws = tfs_signal::rfft(&wn).unwrap();
        let half = n / 4;
        let p_lo: f64 = ws[1..half].iter().map(|c| c.norm_sqr()).sum::<f64>() / (half - 1) as f64;
        let p_hi: f64 =
            ws[half..n / 2].iter().map(|c| c.norm_sqr()).sum::<f64>() / (n / 2 - half) as f64;
        assert!((p_lo / p_hi - 1.0).abs() < 0.1);
    }
}

#[test]
fn linear_sweep_zero_crossings_follow_frequency_law() {
    let (f0, f1, big_t) = (2.0, 12.0, 20.0);
    let s = Sweep::new(SweepKind::Linear, f0, f1, big_t, 1.5, 0.0).unwrap();
    let dt = 1e-4;
    let n = (big_t / dt) as usize;
    let t: Vec<f64> = (0..=n).map(|k| k as f64 * dt).collect();
    let u = s.sample(&t);
    // Zero crossings by linear interpolation.
    let mut z = Vec::new();
    for k in 1..u.len() {
        if u[k - 1] != 0.0 && u[k - 1].signum() != u[k].signum() {
            z.push(t[k - 1] + dt * u[k - 1] / (u[k - 1] - u[k]));
        }
    }
    // Number of half-periods ≈ 2∫f dt = 2·(f0 + f1)/2·T.
    let expected = (f0 + f1) * big_t;
    assert!(
        (z.len() as f64 - expected).abs() <= 2.0,
        "{} crossings, expected {expected}",
        z.len()
    );
    for pair in z.windows(2) {
        let mid = 0.5 * (pair[0] + pair[1]);
        let f_est = 1.0 / (2.0 * (pair[1] - pair[0]));
        let f_law = f0 + (f1 - f0) * mid / big_t;
        assert!(
            (f_est - f_law).abs() < 1e-3 * f_law,
            "t={mid}: {f_est} vs {f_law}"
        );
    }
    // Log sweep: crossings per second grow geometrically.
    let l = Sweep::new(SweepKind::Log, 10.0, 160.0, 8.0, 1.0, 0.0).unwrap();
    let ul = l.sample(&t[..=(8.0 / dt) as usize]);
    let count = |a: usize, b: usize| {
        (a + 1..b)
            .filter(|&k| ul[k - 1].signum() != ul[k].signum() && ul[k - 1] != 0.0)
            .count() as f64
    };
    let sec = (1.0 / dt) as usize;
    // ∫ over [0,1] of 2f and over [4,5]: ratio 16^{4/8} = 4.
    let ratio = count(4 * sec, 5 * sec) / count(0, sec);
    assert!((ratio - 4.0).abs() < 0.25, "ratio {ratio}");
}
