//! Small synthetic data for tests, examples and benchmarks: the single-cell surrogate
//! `x'' + c x' + a5 x⁵ + a6 x⁶ + a7 x⁷ = −xb_acc` under a linear sweep of the base acceleration,
//! integrated with [`tfs_dynamics::rk4_step`], with optional measurement noise on `x` and `xb_acc`.
//!
//! The coefficients are passed in by the caller ([`Surrogate`]); tfs-origami derives them from the
//! truss model, tests here use the paper's Table 1 row. Test support only (the tests, the
//! benchmark and the examples include this file); not part of the library.
#![allow(dead_code)]

use tfs_data::Record;
use tfs_dynamics::{Rk4Scratch, SecondOrderSystem, rk4_step};
use tfs_signal::{Excitation, NoiseKind, Sweep, SweepKind};

/// Errors of the generator (a bad sweep, a signal error, a record error).
pub type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// The surrogate single-cell system `x'' = −c x' − (a5 x⁵ + a6 x⁶ + a7 x⁷) − xb_acc`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surrogate {
    /// Damping per unit mass.
    pub c: f64,
    /// Coefficients of x⁵, x⁶, x⁷ in the restoring force.
    pub a: [f64; 3],
}

impl Surrogate {
    /// Restoring force per unit mass `F(h) = a5 h⁵ + a6 h⁶ + a7 h⁷`.
    pub fn force(&self, h: f64) -> f64 {
        h.powi(5) * (self.a[0] + h * (self.a[1] + h * self.a[2]))
    }
}

impl SecondOrderSystem for Surrogate {
    fn dofs(&self) -> usize {
        1
    }
    fn inputs(&self) -> usize {
        1
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        a[0] = -self.c * v[0] - self.force(x[0]) - u[0];
    }
}

/// A linear sweep of the base acceleration `a·sin(2π(f0 t + (f1−f0)t²/(2T)))` with 2 s ramps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepSpec {
    /// Start frequency (Hz).
    pub f0: f64,
    /// End frequency (Hz).
    pub f1: f64,
    /// Duration (s).
    pub duration: f64,
    /// Amplitude of the base acceleration.
    pub amplitude: f64,
}

/// Noise added to the measured `x` and `xb_acc`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseSpec {
    /// SNR in dB on mean-square power.
    pub snr_db: f64,
    /// White or pink.
    pub kind: NoiseKind,
    /// Seed.
    pub seed: u64,
}

/// Simulates one record (columns `x`, `xb_acc`) sampled at `fs` Hz, starting at rest at `x = 0`.
pub fn surrogate_record(
    name: &str,
    sys: &Surrogate,
    sweep: SweepSpec,
    fs: f64,
    noise: Option<NoiseSpec>,
) -> Result<Record> {
    if !(fs > 0.0 && sweep.duration > 4.0) {
        return Err(format!(
            "synthetic record '{name}': need fs > 0 and a sweep longer than its two 2 s ramps (fs = {fs}, duration = {})",
            sweep.duration
        )
        .into());
    }
    let ex = Sweep::new(
        SweepKind::Linear,
        sweep.f0,
        sweep.f1,
        sweep.duration,
        sweep.amplitude,
        2.0,
    )?;
    let dt = 1.0 / fs;
    let n = (sweep.duration * fs).round() as usize + 1;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
    let mut x = vec![0.0; n];
    let (mut xs, mut vs) = ([0.0], [0.0]);
    let mut sc = Rk4Scratch::new(1);
    for i in 1..n {
        let t0 = t[i - 1];
        let u = |s: f64| [ex.value(s)];
        rk4_step(
            sys,
            t0,
            dt,
            &mut xs,
            &mut vs,
            &u(t0),
            &u(t0 + 0.5 * dt),
            &u(t0 + dt),
            &mut sc,
        );
        x[i] = xs[0];
    }
    let mut acc = ex.sample(&t);
    if let Some(ns) = noise {
        let nx = tfs_signal::noise::noise_for(&x, ns.snr_db, ns.kind, ns.seed)?;
        let na =
            tfs_signal::noise::noise_for(&acc, ns.snr_db, ns.kind, ns.seed.wrapping_add(7919))?;
        x.iter_mut().zip(nx).for_each(|(a, b)| *a += b);
        acc.iter_mut().zip(na).for_each(|(a, b)| *a += b);
    }
    Ok(Record::new(
        name,
        t,
        vec![("x".into(), x), ("xb_acc".into(), acc)],
    )?)
}
