//! Unit checks against closed forms and an independent simulator.

mod common;

use common::*;
use proptest::prelude::*;
use tfs_diagnose::effects::{ComputedColumn, delayed, lowpass};
use tfs_diagnose::{paired_p_value, simulate};
use tfs_dynamics::rmse_ratio;
use tfs_library::{Library, Model};

#[test]
fn lowpass_matches_the_ramp_closed_form() {
    // τ y' + y = t with y(0) = 0: y = t − τ(1 − e^{−t/τ}); exact for piecewise-linear input.
    let (dt, tau) = (0.01, 0.3);
    let t: Vec<f64> = (0..500).map(|k| k as f64 * dt).collect();
    let y = lowpass(&t, dt, tau);
    for (tk, yk) in t.iter().zip(&y) {
        let exact = tk - tau * (1.0 - (-tk / tau).exp());
        assert!((yk - exact).abs() < 1e-12, "{tk}: {yk} vs {exact}");
    }
}

#[test]
fn delay_by_whole_samples_is_a_shift() {
    let v: Vec<f64> = (0..50).map(|k| (k as f64 * 0.3).sin()).collect();
    let d = delayed(&v, 0.01, 0.03);
    for (a, b) in d[3..].iter().zip(&v) {
        assert!((a - b).abs() < 1e-12);
    }
    assert_eq!(d[0], v[0]);
}

#[test]
fn a_fractional_delay_keeps_a_sampled_sine_at_ten_samples_a_period() {
    // Linear interpolation between samples is off by up to 4.9 % of the amplitude here.
    let (dt, omega) = (0.001, 2.0 * std::f64::consts::PI * 100.0);
    let v: Vec<f64> = (0..600).map(|k| (omega * k as f64 * dt).sin()).collect();
    for frac in [0.5, 0.37, 2.81] {
        let d = delayed(&v, dt, frac * dt);
        let worst = (20..580)
            .map(|k| (d[k] - (omega * (k as f64 - frac) * dt).sin()).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-3, "delay {frac} samples: error {worst}");
    }
}

#[test]
fn paired_p_value_behaves() {
    let noise: Vec<f64> = (0..40)
        .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    assert!((paired_p_value(&noise) - 0.5).abs() < 1e-9);
    let up: Vec<f64> = (0..40).map(|k| 1.0 + 0.1 * (k as f64).sin()).collect();
    assert!(paired_p_value(&up) < 1e-10);
    let down: Vec<f64> = up.iter().map(|v| -v).collect();
    assert!(paired_p_value(&down) > 0.999);
}

#[test]
fn maxwell_simulation_matches_an_independent_state_space_model() {
    // Truth: x'' = −k x − k x³ − c x' − xb_acc − k_m z, z' = x' − z/τ (integrated as its own state
    // by the truth simulator). Model: the internal state y = maxwell(x', τ) (y' = (x' − y)/τ, so
    // y = z/τ), coefficient −k_m τ.
    let (km, tau) = (20.0, 0.3);
    let truth = Truth {
        restoring: duffing_restoring(),
        damping: 0.63,
        hidden: vec![Hidden::Maxwell { k: km, tau }],
        x0: 0.0,
    };
    let (rec, x_true) = clean(&truth, 0.3, 3.0, 4.0, 10.0, 0.01);
    let k = 4.0 * std::f64::consts::PI.powi(2);
    let lib = Library::parse(&format!("x, x^3, x', xb_acc, maxwell(x', {tau})"), &["x"]).unwrap();
    let model =
        Model::from_coefficients(&lib, &[vec![-k, -k, -0.63, -1.0, -km * tau]], "truth").unwrap();
    let tr = simulate(&model, &rec).unwrap();
    let err = rmse_ratio(&x_true, &tr.x[0]).unwrap();
    assert!(err < 1e-4, "R-MSE {err}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn computed_column_names_round_trip(tau in 1e-3f64..1e3, delay in 1e-4f64..10.0) {
        let dofs = vec!["x".to_string(), "x2".to_string()];
        for c in [
            ComputedColumn::Delayed { input: "xb_acc".into(), delay },
            ComputedColumn::Lowpass { input: "u".into(), tau },
        ] {
            let back = ComputedColumn::parse(&c.name()).unwrap();
            prop_assert_eq!(back.name(), c.name());
            let (a, b) = match (&c, &back) {
                (ComputedColumn::Delayed { delay: a, .. }, ComputedColumn::Delayed { delay: b, .. }) => (*a, *b),
                (ComputedColumn::Lowpass { tau: a, .. }, ComputedColumn::Lowpass { tau: b, .. }) => (*a, *b),
                _ => return Err(TestCaseError::fail("kind changed")),
            };
            prop_assert!((a - b).abs() <= 5e-3 * a, "{} vs {}", a, b);
            // The name is a valid grammar identifier.
            prop_assert!(tfs_library::Term::parse(&c.name(), &dofs).is_ok());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// A centred column's binomial expansion evaluates to `(x − m)^k · rest` (independent: the
    /// power of the shifted value), and a centred column with m = 0 is the plain term.
    #[test]
    fn centred_expansion_is_the_shifted_power(
        k in 1u32..8,
        m in -3.0f64..3.0,
        x in -4.0f64..4.0,
        v in -2.0f64..2.0,
        with_vel in proptest::bool::ANY,
    ) {
        use tfs_diagnose::EffectColumn;
        use tfs_library::{Factor, Term, Var};
        let mut factors = vec![Factor::Pow(Var::Disp("x".into()), k)];
        if with_vel {
            factors.push(Factor::Pow(Var::Vel("x".into()), 1));
        }
        let c = EffectColumn::centred(Term::new(factors), "x", m);
        let sum: f64 = c
            .expansion()
            .iter()
            .map(|(t, w)| {
                let mut val = *w;
                for f in t.factors() {
                    val *= match f.var() {
                        Var::Disp(_) => f.apply(x),
                        _ => f.apply(v),
                    };
                }
                val
            })
            .sum();
        let exact = (x - m).powi(k as i32) * if with_vel { v } else { 1.0 };
        prop_assert!((sum - exact).abs() <= 1e-9 * (1.0 + exact.abs() + (x.abs() + m.abs()).powi(k as i32)));
        let plain = EffectColumn::centred(c.term.clone(), "x", 0.0);
        prop_assert_eq!(plain.expansion(), vec![(c.term.clone(), 1.0)]);
    }
}

/// A model file written when a Maxwell element was a computed input column
/// (`maxwell_x_tau_0p3`) is read as the internal state it stood for and simulates the same way.
#[test]
fn legacy_maxwell_columns_become_internal_states() {
    let legacy = Model::from_json_str(
        r#"{"format":"tfs-model/1","dofs":["x"],"inputs":["xb_acc","maxwell_x_tau_0p3"],
            "equations":[{"dof":"x","terms":[{"term":"x","coef":-39.48},{"term":"x'","coef":-0.63},
            {"term":"xb_acc","coef":-1},{"term":"maxwell_x_tau_0p3","coef":-6}]}]}"#,
    )
    .unwrap();
    let m = tfs_diagnose::effects::upgrade_legacy(&legacy).unwrap();
    assert_eq!(m.inputs, ["xb_acc"]);
    assert!(
        m.equation_string().contains("6.000·maxwell(x', 0.3)"),
        "{}",
        m.equation_string()
    );
    let plain = structure("x, x', xb_acc");
    assert_eq!(
        tfs_diagnose::effects::upgrade_legacy(&plain).unwrap(),
        plain
    );
}

#[test]
fn catalogue_remove_drops_one_effect_and_names_unknown_ones() {
    let mut c = tfs_diagnose::Catalogue::standard(7);
    let n = c.names().len();
    c.remove("hysteresis").unwrap();
    assert_eq!(c.names().len(), n - 1);
    assert!(!c.names().contains(&"hysteresis".to_string()));
    let e = c.remove("hysteresis").unwrap_err().to_string();
    assert!(
        e.contains("unknown effect 'hysteresis'") && e.contains("maxwell"),
        "{e}"
    );
}
