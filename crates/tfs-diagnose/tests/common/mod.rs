//! Shared data generation for the diagnosis tests: truths with one hidden effect (the
//! `tfs_origami::oscillator` simulators), simulated under base-acceleration sweeps and measured
//! with 40 dB white noise.
#![allow(dead_code)]

pub mod bouc_wen;

use tfs_data::Record;
use tfs_library::{Library, Model};
use tfs_signal::{Excitation, Sweep, SweepKind};

pub use tfs_origami::Hidden;
use tfs_origami::Oscillator;
use tfs_origami::oscillator::{measured, simulate_record};

/// A base-excited 1-DOF truth `x'' = restoring(x) − c x' − xb_acc + hidden effects`, the
/// restoring force a polynomial `(power, coefficient)`.
#[derive(Clone)]
pub struct Truth {
    pub restoring: Vec<(u32, f64)>,
    pub damping: f64,
    pub hidden: Vec<Hidden>,
    pub x0: f64,
}

impl Truth {
    fn oscillator(&self) -> Oscillator {
        Oscillator {
            restoring: self.restoring.clone(),
            damping: self.damping,
            gain: -1.0,
            hidden: self.hidden.clone(),
        }
    }
}

fn k() -> f64 {
    4.0 * std::f64::consts::PI.powi(2)
}

/// `−k x − k x³` with `k = 4π²`.
pub fn duffing_restoring() -> Vec<(u32, f64)> {
    vec![(1, -k()), (3, -k())]
}

/// A hardening degree-7 restoring force `−k(x + x³/2 + x⁵/4 + x⁷/8)`, `k = 4π²`.
pub fn degree_seven_restoring() -> Vec<(u32, f64)> {
    let k = k();
    vec![(1, -k), (3, -0.5 * k), (5, -0.25 * k), (7, -0.125 * k)]
}

/// `−k x`.
pub fn duffing_linear_only() -> Vec<(u32, f64)> {
    vec![(1, -k())]
}

/// The paper's surrogate cell force `−12.12 x^5 + 18.03 x^6 − 6.56 x^7`.
pub fn kresling_restoring() -> Vec<(u32, f64)> {
    vec![(5, -12.12), (6, 18.03), (7, -6.56)]
}

/// The clean displacement of `truth` under a linear sweep f0→f1 Hz of base acceleration with
/// `amp`, `secs` long at `dt`, and the sweep's samples.
fn simulate(truth: &Truth, f0: f64, f1: f64, amp: f64, secs: f64, dt: f64) -> (Vec<f64>, Vec<f64>) {
    let n = (secs / dt).round() as usize + 1;
    let t = tfs_signal::time_grid(n, dt);
    let sweep = Sweep::new(SweepKind::Linear, f0, f1, secs, amp, 1.0).unwrap();
    let u = sweep.sample(&t);
    let osc = truth.oscillator();
    let felt = osc.felt_input(&u, dt, &|s| sweep.value(s));
    let x = simulate_record(&osc, &felt, dt, truth.x0, (1e-8, 1e-10)).unwrap();
    assert_eq!(x.len(), n);
    (x, u)
}

/// Simulates one record: a linear sweep f0→f1 Hz of base acceleration with `amp`, `secs` long at
/// `dt`, 40 dB white noise on `x` and on `xb_acc` (seeded).
#[allow(clippy::too_many_arguments)]
pub fn record(
    truth: &Truth,
    name: &str,
    f0: f64,
    f1: f64,
    amp: f64,
    secs: f64,
    dt: f64,
    seed: u64,
) -> Record {
    let (x, u) = simulate(truth, f0, f1, amp, secs, dt);
    measured(name, dt, ("x", &x), ("xb_acc", &u), Some(40.0), seed).unwrap()
}

/// A model with the given library spec and placeholder coefficients (refitted by the tests).
pub fn structure(spec: &str) -> Model {
    let lib = Library::parse(spec, &["x"]).unwrap();
    Model::from_coefficients(&lib, &[vec![1.0; lib.len()]], "test").unwrap()
}

/// The noise-free record of a truth and its `x`.
pub fn clean(truth: &Truth, f0: f64, f1: f64, amp: f64, secs: f64, dt: f64) -> (Record, Vec<f64>) {
    clean_named(truth, "clean", f0, f1, amp, secs, dt)
}

/// [`clean`] with a record name.
pub fn clean_named(
    truth: &Truth,
    name: &str,
    f0: f64,
    f1: f64,
    amp: f64,
    secs: f64,
    dt: f64,
) -> (Record, Vec<f64>) {
    let (x, u) = simulate(truth, f0, f1, amp, secs, dt);
    let rec = measured(name, dt, ("x", &x), ("xb_acc", &u), None, 0).unwrap();
    (rec, x)
}

/// Three training records (sweeps f0→f1 Hz at 0.8, 1.0 and 1.2 × `amp`) and a held-out one
/// (0.9 × `amp`), 30 s at 100 Hz with 40 dB noise, noise seeds drawn from `seed`.
pub fn train_and_test(truth: &Truth, sweep: (f64, f64, f64), seed: u64) -> (Vec<Record>, Record) {
    let (f0, f1, amp) = sweep;
    let dt = 0.01;
    let train = (0..3)
        .map(|i| {
            let a = amp * (0.8 + 0.2 * i as f64);
            record(truth, &format!("train{i}"), f0, f1, a, 30.0, dt, seed + i)
        })
        .collect();
    let test = record(truth, "test", f0, f1, amp * 0.9, 30.0, dt, seed + 50);
    (train, test)
}
