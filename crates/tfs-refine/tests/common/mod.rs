//! Shared data generators for the integration tests.
#![allow(dead_code)]

use faer::Mat;
use faer::linalg::solvers::Solve;
use tfs_data::Record;
use tfs_dynamics::{SimulateOptions, rms_error, simulate_model_on_record};
use tfs_library::{Equation, Model, ModelTerm, Term};
use tfs_signal::{Excitation, NoiseKind};

pub fn term(s: &str) -> Term {
    Term::parse(s, &["x"]).unwrap()
}

/// `x'' = Σ coef · term` over the given (term, coef) pairs.
pub fn model(terms: &[(&str, f64)]) -> Model {
    Model::new(
        vec!["x".into()],
        vec![Equation {
            dof: "x".into(),
            terms: terms
                .iter()
                .map(|(t, c)| ModelTerm::new(term(t), *c))
                .collect(),
        }],
        "test",
    )
    .unwrap()
}

/// Simulates `truth` (Dopri5, spline input) under `u` from rest, adds white noise at `snr_db`
/// to both `x` and `u` (seeded), and adds DC offsets `(x_off, u_off)` (raw "volts").
pub fn measure(
    name: &str,
    truth: &Model,
    u: Vec<f64>,
    dt: f64,
    snr_db: f64,
    offsets: (f64, f64),
    seed: u64,
) -> Record {
    let n = u.len();
    let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
    let clean = Record::new(
        "gen",
        t.clone(),
        vec![("x".into(), vec![0.0; n]), ("u".into(), u.clone())],
    )
    .unwrap();
    let tr = simulate_model_on_record(truth, &clean, &SimulateOptions::default()).unwrap();
    let x = tfs_signal::noise::add_noise_seeded(&tr.x[0], snr_db, NoiseKind::White, seed).unwrap();
    let um =
        tfs_signal::noise::add_noise_seeded(&u, snr_db, NoiseKind::White, seed + 1000).unwrap();
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

pub fn sample(e: &impl Excitation, n: usize, dt: f64) -> Vec<f64> {
    (0..n).map(|k| e.value(k as f64 * dt)).collect()
}

/// RMS simulation error of `m` on `r` (infinite on blow-up).
pub fn sim_rms(m: &Model, r: &Record) -> f64 {
    match simulate_model_on_record(m, r, &SimulateOptions::default()) {
        Ok(tr) => rms_error(r.column("x").unwrap(), &tr.x[0]).unwrap_or(f64::INFINITY),
        Err(_) => f64::INFINITY,
    }
}

pub fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// Equation-error least squares `x'' ≈ Σ c_j θ_j` for the given terms of `x, x', u`, with
/// derivatives by 2nd-order central differences of the (noisy) record.
pub fn equation_error_fit(r: &Record, terms: &[&str]) -> Model {
    let x = r.column("x").unwrap();
    let u = r.column("u").unwrap();
    let dt = r.dt();
    let v = tfs_signal::diff::central_difference(x, dt, 1).unwrap();
    let a = tfs_signal::diff::central_difference(x, dt, 2).unwrap();
    let cols: Vec<Vec<f64>> = terms
        .iter()
        .map(|t| match *t {
            "x" => x.to_vec(),
            "x'" => v.clone(),
            "u" => u.to_vec(),
            "x^3" => x.iter().map(|v| v * v * v).collect(),
            other => panic!("unsupported term {other}"),
        })
        .collect();
    let n = x.len();
    let p = terms.len();
    let scale: Vec<f64> = cols.iter().map(|c| rms(c)).collect();
    let amat = Mat::<f64>::from_fn(n, p, |i, j| cols[j][i] / scale[j]);
    let b = Mat::<f64>::from_fn(n, 1, |i, _| a[i]);
    let ata = amat.transpose() * &amat;
    let atb = amat.transpose() * &b;
    let z = ata.llt(faer::Side::Lower).unwrap().solve(&atb);
    let pairs: Vec<(&str, f64)> = terms
        .iter()
        .enumerate()
        .map(|(j, t)| (*t, z[(j, 0)] / scale[j]))
        .collect();
    model(&pairs)
}
