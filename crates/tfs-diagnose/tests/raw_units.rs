//! The catalogue in raw units (issue #11): a force-driven Duffing oscillator recorded in volts
//! (coefficients of order 1e5), DC offsets kept on both channels, 50 dB noise, 10 samples per
//! resonance period, a multisine for training and a growing noise burst for validation. The
//! model `1, x, x', u` absorbs the offsets in its constant; the missing cubic stiffness must rank
//! first and adding it must cut the validation RMS error (volts) at least 10×.

use tfs_data::Record;
use tfs_diagnose::{Catalogue, DiagnoseOptions, add_effect, explain, refit};
use tfs_dynamics::{SimulateOptions, rms_error, simulate_model_on_record};
use tfs_library::{Library, Model};
use tfs_signal::noise::add_noise_seeded;
use tfs_signal::{Excitation, Multisine, NoiseBurst, NoiseKind};

const DT: f64 = 1e-3;
const FN: f64 = 100.0;

fn truth() -> Model {
    let w = 2.0 * std::f64::consts::PI * FN;
    let lib = Library::parse("x, x', x^3, u", &["x"]).unwrap();
    Model::from_coefficients(
        &lib,
        &[vec![-w * w, -2.0 * 0.03 * w, -3.0e4, 8.0e4]],
        "truth",
    )
    .unwrap()
}

fn measure(name: &str, u: Vec<f64>, offsets: (f64, f64), seed: u64) -> Record {
    let n = u.len();
    let t: Vec<f64> = (0..n).map(|k| k as f64 * DT).collect();
    let clean = Record::new(
        name,
        t.clone(),
        vec![("x".into(), vec![0.0; n]), ("u".into(), u.clone())],
    )
    .unwrap();
    let tr = simulate_model_on_record(&truth(), &clean, &SimulateOptions::default()).unwrap();
    let x = add_noise_seeded(&tr.x[0], 50.0, NoiseKind::White, seed).unwrap();
    let um = add_noise_seeded(&u, 50.0, NoiseKind::White, seed + 1000).unwrap();
    Record::new(
        name,
        t,
        vec![
            ("x".into(), x.iter().map(|v| v + offsets.0).collect()),
            ("u".into(), um.iter().map(|v| v + offsets.1).collect()),
        ],
    )
    .unwrap()
}

fn sim_rms(m: &Model, r: &Record) -> f64 {
    let tr = tfs_diagnose::simulate(m, r).unwrap();
    rms_error(r.column("x").unwrap(), &tr.x[0]).unwrap()
}

#[test]
fn force_driven_duffing_with_offsets_kept() {
    let (n_train, n_val) = (20_000, 8_000);
    let ms = Multisine::new(5.0, 200.0, 150, 1.0, n_train as f64 * DT, 0.2, 7).unwrap();
    let nb = NoiseBurst::new(5.0, 200.0, 1.6, n_val as f64 * DT, 200, 11).unwrap();
    let offsets = (0.31, -0.12);
    let train = measure(
        "train",
        (0..n_train).map(|k| ms.value(k as f64 * DT)).collect(),
        offsets,
        1,
    );
    let val = measure(
        "validation",
        (0..n_val).map(|k| nb.value(k as f64 * DT)).collect(),
        offsets,
        2,
    );
    let opts = DiagnoseOptions::default();
    let lib = Library::parse("1, x, x', u", &["x"]).unwrap();
    let placeholder = Model::from_coefficients(&lib, &[vec![1.0; 4]], "start").unwrap();
    let train = [train];
    let start = refit(&placeholder, &train, &opts).unwrap();
    println!("start: {}", start.equation_string());
    let ex = explain(&start, &train, &Catalogue::standard(7), &opts).unwrap();
    for r in ex.ranked.iter().take(4) {
        println!(
            "raw: {:<20} sig={} delta={:.4} p={:.2e} share={:.4} terms={:?} rmse {:?} -> {:?}",
            r.name,
            r.significant,
            r.delta_heldout,
            r.p_value,
            r.share,
            r.terms,
            r.r_mse_before,
            r.r_mse_after
        );
    }
    assert_eq!(ex.ranked[0].name, "stiffness-x^3", "{}", ex.verdict);
    assert!(ex.ranked[0].significant);
    let after = add_effect(&start, "stiffness-x^3", &train).unwrap();
    println!("after: {}", after.equation_string());
    let (b, a) = (sim_rms(&start, &val), sim_rms(&after, &val));
    println!(
        "raw units: validation RMS error {b:.4e} V -> {a:.4e} V, factor {:.1}",
        b / a
    );
    assert!(b / a >= 10.0, "{b} -> {a}");
}

#[test]
fn raw_units_control_reports_nothing_significant() {
    // The complete raw-unit structure (the cubic about the offset position expands into
    // 1, x, x^2, x^3): nothing is missing, and coefficients of order 1e5 must not fool the tests.
    let n = 20_000;
    let ms = Multisine::new(5.0, 200.0, 150, 1.0, n as f64 * DT, 0.2, 9).unwrap();
    let train = [measure(
        "train",
        (0..n).map(|k| ms.value(k as f64 * DT)).collect(),
        (0.31, -0.12),
        5,
    )];
    let opts = DiagnoseOptions::default();
    let lib = Library::parse("1, x, x^2, x^3, x', u", &["x"]).unwrap();
    let placeholder = Model::from_coefficients(&lib, &[vec![1.0; 6]], "start").unwrap();
    let start = refit(&placeholder, &train, &opts).unwrap();
    let ex = explain(&start, &train, &Catalogue::standard(7), &opts).unwrap();
    for r in ex.ranked.iter().take(3) {
        println!(
            "raw control: {:<20} sig={} delta={:.4} p={:.2e} share={:.4} terms={:?}",
            r.name, r.significant, r.delta_heldout, r.p_value, r.share, r.terms
        );
    }
    println!("raw control: {}", ex.verdict);
    assert!(ex.ranked.iter().all(|r| !r.significant), "{}", ex.verdict);
}
