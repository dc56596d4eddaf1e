//! Integrator tests against closed forms, conserved quantities and each other.

use std::f64::consts::PI;
use tfs_dynamics::{
    Dopri5, DynError, FnSystem, Integrator, Interpolation, Rk4, SampledInput, SecondOrderSystem,
    rmse_ratio,
};

/// Free damped oscillator x'' + 2ζω x' + ω² x = 0 with its closed-form solution.
struct Damped {
    z: f64,
    w: f64,
}

impl Damped {
    fn exact(&self, t: f64, x0: f64, v0: f64) -> f64 {
        let wd = self.w * (1.0 - self.z * self.z).sqrt();
        let s = self.z * self.w;
        (-s * t).exp() * (x0 * (wd * t).cos() + (v0 + s * x0) / wd * (wd * t).sin())
    }
}

fn damped_sys(z: f64, w: f64) -> impl SecondOrderSystem {
    FnSystem::new(
        1,
        0,
        move |_t, x: &[f64], v: &[f64], _u: &[f64], a: &mut [f64]| {
            a[0] = -2.0 * z * w * v[0] - w * w * x[0]
        },
    )
}

#[test]
fn rk4_is_fourth_order_on_linear_oscillator() {
    let osc = Damped { z: 0.05, w: 3.0 };
    let sys = damped_sys(osc.z, osc.w);
    let t_end = 6.0;
    let err = |h: f64| {
        let tr = Rk4::new(h)
            .integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.5], &[0.0, t_end])
            .unwrap();
        (tr.x[0][1] - osc.exact(t_end, 1.0, 0.5)).abs()
    };
    let (e1, e2, e3) = (err(0.04), err(0.02), err(0.01));
    let p1 = (e1 / e2).log2();
    let p2 = (e2 / e3).log2();
    eprintln!("rk4 observed orders {p1:.3} {p2:.3}");
    assert!((3.7..4.3).contains(&p1), "observed order {p1}");
    assert!((3.7..4.3).contains(&p2), "observed order {p2}");
}

#[test]
fn dopri5_error_follows_tolerance_and_order_five() {
    let osc = Damped { z: 0.02, w: 2.0 };
    let sys = damped_sys(osc.z, osc.w);
    let t: Vec<f64> = (0..=200).map(|k| k as f64 * 0.1).collect();
    let run = |tol: f64| {
        let tr = Dopri5::with_tol(tol, tol)
            .integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.0], &[0.0, 20.0])
            .unwrap();
        let e = (tr.x[0][1] - osc.exact(20.0, 1.0, 0.0)).abs();
        (e, tr.stats.steps as f64)
    };
    let (e_lo, n_lo) = run(1e-6);
    let (e_hi, n_hi) = run(1e-11);
    // Global error stays within a modest multiple of the tolerance.
    assert!(e_lo < 1e-4 && e_hi < 1e-9, "{e_lo:e} {e_hi:e}");
    // Error versus work has slope about −5 for a fifth-order method.
    let slope = (e_hi / e_lo).ln() / (n_hi / n_lo).ln();
    eprintln!("dopri5 err {e_lo:e} ({n_lo} steps) / {e_hi:e} ({n_hi} steps), slope {slope:.3}");
    assert!((-6.0..-4.0).contains(&slope), "slope {slope}");
    // Output at many times matches the closed form too.
    let tr = Dopri5::with_tol(1e-10, 1e-12)
        .integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.0], &t)
        .unwrap();
    for (k, &tk) in t.iter().enumerate() {
        assert!((tr.x[0][k] - osc.exact(tk, 1.0, 0.0)).abs() < 1e-8);
    }
}

/// x'' + 2ζω0 x' + ω0² x = A sin(Ω t), sampled at 10 samples per forcing period, started on the
/// closed-form steady state.
fn forced_case(interp: Interpolation, integrator: &impl Integrator) -> f64 {
    let (z, w0, amp) = (0.05, 2.0 * PI, 3.0);
    let big_w = w0; // at resonance: the hardest case for phase errors
    let dt = 2.0 * PI / big_w / 10.0;
    let n = 300; // 30 periods
    let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    let u: Vec<f64> = t.iter().map(|&t| amp * (big_w * t).sin()).collect();
    let input = SampledInput::with_interpolation(0.0, dt, vec![u], interp).unwrap();
    let re = w0 * w0 - big_w * big_w;
    let im = 2.0 * z * w0 * big_w;
    let gain = amp / (re * re + im * im).sqrt();
    let phi = im.atan2(re);
    let xs = |t: f64| gain * (big_w * t - phi).sin();
    let vs = |t: f64| gain * big_w * (big_w * t - phi).cos();
    let sys = FnSystem::new(
        1,
        1,
        move |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
            a[0] = u[0] - 2.0 * z * w0 * v[0] - w0 * w0 * x[0]
        },
    );
    let tr = integrator
        .integrate(&sys, &input, &[xs(0.0)], &[vs(0.0)], &t)
        .unwrap();
    let exact: Vec<f64> = t.iter().map(|&t| xs(t)).collect();
    rmse_ratio(&exact, &tr.x[0]).unwrap()
}

#[test]
fn forced_oscillator_at_ten_samples_per_period_matches_steady_state() {
    let tight = Dopri5::with_tol(1e-10, 1e-12);
    let r_spline = forced_case(Interpolation::CubicSpline, &tight);
    assert!(r_spline < 1e-6, "R-MSE with spline {r_spline:e}");
    // RK4 with a few steps per sample interval reaches the same accuracy.
    let r_rk4 = forced_case(Interpolation::CubicSpline, &Rk4::new(0.01));
    assert!(r_rk4 < 1e-6, "R-MSE RK4 {r_rk4:e}");
    // Linear interpolation of the same samples is far worse: the interpolation matters.
    let r_lin = forced_case(Interpolation::Linear, &tight);
    eprintln!(
        "forced 10 samples/period R-MSE: spline+dopri5 {r_spline:e}, spline+rk4 {r_rk4:e}, linear {r_lin:e}"
    );
    assert!(
        r_lin > 100.0 * r_spline,
        "linear {r_lin:e} vs spline {r_spline:e}"
    );
}

#[test]
fn duffing_energy_is_conserved_by_dopri5() {
    // x'' = −x − x³, E = v²/2 + x²/2 + x⁴/4.
    let sys = FnSystem::new(
        1,
        0,
        |_t, x: &[f64], _v: &[f64], _u: &[f64], a: &mut [f64]| a[0] = -x[0] - x[0] * x[0] * x[0],
    );
    let energy = |x: f64, v: f64| 0.5 * v * v + 0.5 * x * x + 0.25 * x.powi(4);
    // The period is below 2π (hardening spring), so 100 periods fit in 100·2π.
    let t: Vec<f64> = (0..=1000).map(|k| k as f64 * 0.2 * PI).collect();
    let tr = Dopri5::with_tol(1e-13, 1e-13)
        .integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.0], &t)
        .unwrap();
    let e0 = energy(1.0, 0.0);
    let drift = (0..t.len())
        .map(|k| ((energy(tr.x[0][k], tr.v[0][k]) - e0) / e0).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "duffing relative energy drift {drift:e} ({} steps)",
        tr.stats.steps
    );
    assert!(drift < 1e-8, "relative energy drift {drift:e}");
}

/// Complete elliptic integral of the first kind K(k) by the arithmetic–geometric mean.
fn ellip_k(k: f64) -> f64 {
    let (mut a, mut g) = (1.0_f64, (1.0 - k * k).sqrt());
    for _ in 0..40 {
        let an = 0.5 * (a + g);
        g = (a * g).sqrt();
        a = an;
    }
    PI / (2.0 * a)
}

#[test]
fn blow_up_reports_time_and_state() {
    // x'' = x³ from x = 1, v = 0 reaches infinity at t* = √2 ∫₁^∞ dx/√(x⁴−1) = K(1/√2).
    let t_star = ellip_k(0.5f64.sqrt());
    let sys = FnSystem::new(
        1,
        0,
        |_t, x: &[f64], _v: &[f64], _u: &[f64], a: &mut [f64]| a[0] = x[0] * x[0] * x[0],
    );
    for result in [
        Dopri5::default().integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.0], &[0.0, 5.0]),
        Rk4::new(1e-3).integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.0], &[0.0, 5.0]),
    ] {
        match result {
            Err(DynError::BlowUp { t, x, v }) => {
                eprintln!("blow-up at t = {t} (t* = {t_star}), x = {x:?}");
                assert!(
                    t < t_star + 1e-3 && t > t_star - 1e-2,
                    "t = {t}, t* = {t_star}"
                );
                assert!(x[0].abs() > 1e6 || !x[0].is_finite() || v[0].abs() > 1e6);
                let msg = DynError::BlowUp { t, x, v }.to_string();
                assert!(msg.starts_with("simulation blew up at t = "), "{msg}");
                assert!(msg.contains("the model is unstable for this input"));
            }
            other => panic!("expected blow-up, got {other:?}"),
        }
    }
    // A user limit is honoured: with limit 10 the run stops where |x| or |v| first exceeds 10.
    // Along this orbit v² / 2 − x⁴ / 4 = −1/4, so v ≈ x² / √2 exceeds 10 first (x ≈ 3.76), about
    // √2 / x ≈ 0.38 s before t*. The reported state must lie on the orbit.
    let d = Dopri5 {
        blowup_limit: Some(10.0),
        ..Dopri5::default()
    };
    match d.integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.0], &[0.0, 5.0]) {
        Err(DynError::BlowUp { t, x, v }) => {
            assert!(
                v[0] > 10.0 && v[0] < 20.0 && x[0] < 10.0,
                "x = {x:?}, v = {v:?}"
            );
            let h = 0.5 * v[0] * v[0] - 0.25 * x[0].powi(4);
            assert!((h + 0.25).abs() < 1e-5, "invariant {h}");
            assert!(t < t_star - 0.25 && t > t_star - 0.5, "t = {t}");
        }
        other => panic!("expected blow-up, got {other:?}"),
    }
}

#[test]
fn rk4_and_dopri5_agree_on_forced_two_dof_nonlinear_chain() {
    // Two masses, cubic springs, base input: an independent check of the multi-DOF path.
    let sys = FnSystem::new(
        2,
        1,
        |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
            let s1 = x[0] - u[0];
            let s2 = x[1] - x[0];
            let f1 = s1 + 0.5 * s1 * s1 * s1;
            let f2 = 2.0 * s2 + s2 * s2 * s2;
            a[0] = -f1 + f2 - 0.1 * v[0];
            a[1] = -f2 - 0.1 * v[1];
        },
    );
    let dt = 0.05;
    let t: Vec<f64> = (0..400).map(|k| k as f64 * dt).collect();
    let u: Vec<f64> = t
        .iter()
        .map(|&t| 0.3 * (1.3 * t).sin() + 0.1 * (3.1 * t).cos())
        .collect();
    let input = SampledInput::new(0.0, dt, vec![u]).unwrap();
    let a = Dopri5::with_tol(1e-11, 1e-12)
        .integrate(&sys, &input, &[0.1, -0.2], &[0.0, 0.3], &t)
        .unwrap();
    let b = Rk4::new(0.005)
        .integrate(&sys, &input, &[0.1, -0.2], &[0.0, 0.3], &t)
        .unwrap();
    for d in 0..2 {
        for k in 0..t.len() {
            assert!((a.x[d][k] - b.x[d][k]).abs() < 1e-8, "dof {d} k {k}");
            assert!((a.v[d][k] - b.v[d][k]).abs() < 1e-8);
        }
    }
}

#[test]
fn bad_arguments_give_clear_errors() {
    let sys = damped_sys(0.1, 1.0);
    let z = SampledInput::zero(0);
    let e = Dopri5::default()
        .integrate(&sys, &z, &[1.0, 2.0], &[0.0], &[0.0, 1.0])
        .unwrap_err();
    assert!(e.to_string().contains("`x0` has length 2 but 1"), "{e}");
    let e = Dopri5::default()
        .integrate(&sys, &SampledInput::zero(1), &[1.0], &[0.0], &[0.0, 1.0])
        .unwrap_err();
    assert!(e.to_string().contains("input channels"), "{e}");
    let e = Rk4::new(0.1)
        .integrate(&sys, &z, &[1.0], &[0.0], &[1.0, 0.5])
        .unwrap_err();
    assert!(e.to_string().contains("sort the output times"), "{e}");
    let e = Dopri5::with_tol(-1.0, 1e-9)
        .integrate(&sys, &z, &[1.0], &[0.0], &[0.0, 1.0])
        .unwrap_err();
    assert!(e.to_string().contains("rtol"), "{e}");
    let d = Dopri5 {
        max_steps: 5,
        ..Dopri5::default()
    };
    let e = d
        .integrate(&sys, &z, &[1.0], &[0.0], &[0.0, 100.0])
        .unwrap_err();
    assert!(matches!(e, DynError::TooManySteps { .. }), "{e}");
}

#[test]
fn solver_stepping_matches_integrate() {
    let osc = Damped { z: 0.1, w: 1.5 };
    let sys = damped_sys(osc.z, osc.w);
    let z = SampledInput::zero(0);
    let d = Dopri5::with_tol(1e-10, 1e-12);
    let mut s = d.solver(&sys, &z, 0.0, &[0.4], &[-0.2]).unwrap();
    for k in 1..=10 {
        s.advance_to(k as f64).unwrap();
        assert!((s.x()[0] - osc.exact(k as f64, 0.4, -0.2)).abs() < 1e-8);
    }
    assert!(s.advance_to(5.0).is_err());
}

mod props {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn dopri5_matches_closed_form_for_random_oscillators(
            z in 0.0f64..0.5, w in 0.3f64..5.0, x0 in -2.0f64..2.0, v0 in -2.0f64..2.0
        ) {
            let osc = Damped { z, w };
            let sys = damped_sys(z, w);
            let t_end = 10.0 / w;
            let tr = Dopri5::with_tol(1e-10, 1e-12)
                .integrate(&sys, &SampledInput::zero(0), &[x0], &[v0], &[0.0, t_end])
                .unwrap();
            let scale = x0.abs().max(v0.abs() / w).max(1e-3);
            prop_assert!((tr.x[0][1] - osc.exact(t_end, x0, v0)).abs() < 1e-7 * scale);
        }
    }
}
