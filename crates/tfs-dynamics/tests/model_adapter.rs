//! Simulating a `tfs_library::Model` on a record against the closed-form forced response.

use std::f64::consts::PI;
use tfs_data::Record;
use tfs_dynamics::{DynError, RANGE_SPANS, SimulateOptions, rmse_ratio, simulate_model_on_record};
use tfs_library::{Library, Model};

/// x'' = −4 x − 0.2 x' − xb_acc, with xb_acc = A sin(Ω t) sampled 20 times per period and x the
/// closed-form steady state.
fn case(with_velocity: bool) -> (Model, Record) {
    let lib = Library::parse("x, x', xb_acc", &["x"]).unwrap();
    let model = Model::from_coefficients(&lib, &[vec![-4.0, -0.2, -1.0]], "test").unwrap();
    let (w0, c, amp, big_w) = (2.0f64, 0.2, 1.5, 2.3);
    let re = w0 * w0 - big_w * big_w;
    let im = c * big_w;
    let gain = amp / (re * re + im * im).sqrt();
    let phi = im.atan2(re);
    let dt = 2.0 * PI / big_w / 20.0;
    let t: Vec<f64> = (0..600).map(|k| 0.7 + k as f64 * dt).collect();
    // Forcing is −xb_acc, so the response is −gain·sin(Ωt − φ).
    let x: Vec<f64> = t.iter().map(|t| -gain * (big_w * t - phi).sin()).collect();
    let v: Vec<f64> = t
        .iter()
        .map(|t| -gain * big_w * (big_w * t - phi).cos())
        .collect();
    let u: Vec<f64> = t.iter().map(|t| amp * (big_w * t).sin()).collect();
    let mut cols = vec![("x".to_string(), x), ("xb_acc".to_string(), u)];
    if with_velocity {
        cols.push(("x'".to_string(), v));
    }
    (model, Record::new("case.csv", t, cols).unwrap())
}

#[test]
fn model_on_record_matches_closed_form() {
    let (model, rec) = case(true);
    let tr = simulate_model_on_record(&model, &rec, &SimulateOptions::default()).unwrap();
    let r = rmse_ratio(rec.column("x").unwrap(), &tr.x[0]).unwrap();
    eprintln!("model on record R-MSE with x' column {r:e}");
    assert!(r < 1e-6, "R-MSE {r:e}");
    assert_eq!(tr.t, rec.t());
    // Without a velocity column the estimated v0 starts a small decaying transient.
    let (model, rec) = case(false);
    let tr = simulate_model_on_record(&model, &rec, &SimulateOptions::default()).unwrap();
    let r = rmse_ratio(rec.column("x").unwrap(), &tr.x[0]).unwrap();
    eprintln!("model on record R-MSE with estimated v0 {r:e}");
    assert!(r < 1e-2, "R-MSE {r:e}");
}

#[test]
fn missing_input_column_is_named() {
    let (model, rec) = case(true);
    let rec2 = Record::new(
        "short.csv",
        rec.t().to_vec(),
        vec![("x".to_string(), rec.column("x").unwrap().to_vec())],
    )
    .unwrap();
    let e = simulate_model_on_record(&model, &rec2, &SimulateOptions::default()).unwrap_err();
    assert!(matches!(e, DynError::MissingColumn { .. }));
    let msg = e.to_string();
    assert!(
        msg.contains("short.csv") && msg.contains("'xb_acc'"),
        "{msg}"
    );
}

/// A model that runs away from its record (negative damping, so its response grows without
/// bound under the same input) stops once x leaves the record's span widened by `RANGE_SPANS` spans, naming the record's
/// column, the time on the record's clock and the band; the record's own model is untouched by
/// the band, and without it the runaway goes on to the end of the record.
#[test]
fn a_run_that_leaves_its_records_range_stops_and_says_so() {
    let (good, rec) = case(false);
    let lib = Library::parse("x, x', xb_acc", &["x"]).unwrap();
    let runaway = Model::from_coefficients(&lib, &[vec![-4.0, 0.1, -1.0]], "test").unwrap();
    let e = simulate_model_on_record(&runaway, &rec, &SimulateOptions::default()).unwrap_err();
    let DynError::LeftRange { t, dof, x, lo, hi } = &e else {
        panic!("expected LeftRange, got {e}");
    };
    let col = rec.column("x").unwrap();
    let (mn, mx) = col
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    assert!(
        (hi - (mx + RANGE_SPANS * (mx - mn))).abs() < 1e-12
            && (lo - (mn - RANGE_SPANS * (mx - mn))).abs() < 1e-12
    );
    assert!(*x > *hi || *x < *lo);
    assert_eq!(dof, "x");
    assert!(
        rec.t().contains(t) && *t < rec.t()[rec.len() - 1],
        "t = {t}"
    );
    assert!(
        e.to_string().contains("left the range of the record"),
        "{e}"
    );
    let free = SimulateOptions {
        range: None,
        ..SimulateOptions::default()
    };
    let tr = simulate_model_on_record(&runaway, &rec, &free).unwrap();
    assert!(tr.x[0].iter().any(|v| v > hi || v < lo));
    let a = simulate_model_on_record(&good, &rec, &SimulateOptions::default()).unwrap();
    let b = simulate_model_on_record(&good, &rec, &free).unwrap();
    assert_eq!(a.x, b.x);
}
