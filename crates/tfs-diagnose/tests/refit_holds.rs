//! A refit never ends worse than where it started: when every fit of the added effect predicts
//! the fit records worse than the start model, `add_effect` keeps (close to) the start model.

mod common;

use common::*;
use tfs_data::Record;
use tfs_diagnose::{Catalogue, DiagnoseOptions, add_effect, add_effect_fit, hold_start, r_mse};
use tfs_library::{Library, Model};

/// The geometric mean of `model`'s free-run R-MSE over `records` (as the refit's choice weighs
/// them).
fn geo_r_mse(model: &Model, records: &[Record]) -> f64 {
    let logs: Vec<f64> = records
        .iter()
        .map(|r| r_mse(model, r).unwrap().ln())
        .collect();
    (logs.iter().sum::<f64>() / logs.len() as f64).exp()
}

/// The start model is the truth itself (a Duffing oscillator, its exact coefficients); the
/// added high power is not in the truth, so each of its equation-error fits (held, ridge, free)
/// moves the model away from the truth by what the noise and the smoothing put into the new
/// column, and predicts the fit records worse than the start (checked: the premise). The refit
/// then searches the step toward its best fit: it predicts the fit records no worse than the
/// start model, at a step short of the full fit; when it keeps the start, its equations are the
/// start's and nothing is listed as added. Before the step search, the best anchor was kept
/// however much worse than the start it predicted.
#[test]
fn a_refit_whose_every_anchor_is_worse_keeps_the_start_model() {
    let truth = Truth {
        restoring: duffing_restoring(),
        damping: 0.63,
        hidden: vec![],
        x0: 0.0,
    };
    let train: Vec<Record> = (0..3)
        .map(|i| {
            record(
                &truth,
                &format!("r{i}"),
                0.3,
                3.0,
                4.0 * (0.8 + 0.2 * i as f64),
                30.0,
                0.01,
                70 + i as u64,
            )
        })
        .collect();
    let k = 4.0 * std::f64::consts::PI.powi(2);
    let lib = Library::parse("x, x^3, x', xb_acc", &["x"]).unwrap();
    let start = Model::from_coefficients(&lib, &[vec![-k, -k, -0.63, -1.0]], "test").unwrap();
    let before = geo_r_mse(&start, &train);
    for effect in ["stiffness-x^5", "stiffness-x^7"] {
        let after = add_effect(&start, effect, &train).unwrap();
        // The same search made on the unsearched fit by a caller that changes it first (the
        // facade's ties and stop re-scans) ends at the same model.
        let opts = DiagnoseOptions::default();
        let cat = Catalogue::standard(opts.max_power);
        let fit = add_effect_fit(&start, effect, &train, &cat, &opts).unwrap();
        assert!(geo_r_mse(&fit, &train) > before, "{effect}: the premise");
        let held = hold_start(&start, &fit, &train, &opts).unwrap();
        assert_eq!(held.equations, after.equations, "{effect}");
        let (h, a) = (held.history.last().unwrap(), after.history.last().unwrap());
        assert_eq!(h.added, a.added, "{effect}");
        let v = |e: &tfs_library::HistoryEntry, k: &str| e.details["variants"][0][k].clone();
        assert_eq!(v(h, "anchor"), v(a, "anchor"), "{effect}");
        assert_eq!(v(h, "step"), v(a, "step"), "{effect}");
        assert_eq!(h.r_mse, a.r_mse, "{effect}");
        let step = after.history.last().unwrap();
        let details = &step.details["variants"][0];
        // Every anchor the refit tried, and the start model, on the fit records.
        let tried = details["train_r_mse"].as_array().unwrap();
        let geo = |v: &serde_json::Value| {
            let v: Vec<f64> = v
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            (v.iter().map(|x| x.ln()).sum::<f64>() / v.len() as f64).exp()
        };
        let anchors: Vec<(String, f64)> = tried
            .iter()
            .map(|e| (e[0].as_str().unwrap().to_string(), geo(&e[1])))
            .filter(|(l, _)| ["held", "ridge", "free"].iter().any(|a| l.starts_with(a)))
            .filter(|(l, _)| !l.contains("step"))
            .collect();
        let kept = geo_r_mse(&after, &train);
        println!(
            "{effect}: start {before:.6e}, kept {kept:.6e} ({} at step {}), anchors {anchors:?}",
            details["anchor"], details["step"]
        );
        // The case this test is about: every anchor predicts the fit records worse.
        assert!(
            anchors.len() >= 6 && anchors.iter().all(|(_, g)| *g > before),
            "{effect}: {anchors:?} vs start {before}"
        );
        assert!(
            kept <= before * (1.0 + 1e-9),
            "{effect}: {kept} > start {before}"
        );
        let s = details["step"].as_f64().unwrap();
        assert!((0.0..1.0).contains(&s), "{effect}: step {s}");
        if s == 0.0 {
            assert_eq!(after.equations, start.equations, "{effect}");
            assert!(step.added.is_empty(), "{effect}: {:?}", step.added);
        } else {
            assert!(!step.added.is_empty(), "{effect}");
        }
    }
}
