//! Shared data generation for the diagnosis tests: truths with one hidden effect, simulated under
//! base-acceleration sweeps and measured with 40 dB white noise.
#![allow(dead_code)]

use tfs_data::Record;
use tfs_dynamics::{Dopri5, FnSystem, Integrator, SampledInput};
use tfs_library::{Library, Model};
use tfs_signal::noise::add_noise_seeded;
use tfs_signal::{Excitation, NoiseKind, Sweep, SweepKind};

/// A hidden effect added to the truth's acceleration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Hidden {
    None,
    DryFriction {
        force: f64,
        eps: f64,
    },
    Quadratic(f64),
    CubicDamping(f64),
    Cubic(f64),
    Offset(f64),
    /// Maxwell element: force −k·z with z' = x' − z/τ.
    Maxwell {
        k: f64,
        tau: f64,
    },
    /// The structure feels the recorded input δ seconds late.
    Delay(f64),
    /// The structure feels the recorded input through a first-order low-pass of time constant τ.
    InputFilter(f64),
    /// A one-sided stop below `at`: contact force `k·max(0, at − x)`.
    Stop {
        k: f64,
        at: f64,
    },
}

impl Hidden {
    fn force(&self, x: f64, v: f64, z: f64) -> f64 {
        match *self {
            Hidden::None => 0.0,
            Hidden::DryFriction { force, eps } => -force * (v / eps).tanh(),
            Hidden::Quadratic(c) => -c * v * v.abs(),
            Hidden::CubicDamping(c) => -c * v * v * v,
            Hidden::Cubic(k3) => -k3 * x.powi(3),
            Hidden::Offset(f) => f,
            Hidden::Maxwell { k, .. } => -k * z,
            Hidden::Delay(_) | Hidden::InputFilter(_) => 0.0,
            Hidden::Stop { k, at } => k * (at - x).max(0.0),
        }
    }
}

/// A base-excited 1-DOF truth `x'' = restoring(x) − c x' − xb_acc + hidden effects`.
#[derive(Clone)]
pub struct Truth {
    pub restoring: fn(f64) -> f64,
    pub damping: f64,
    pub hidden: Vec<Hidden>,
    pub x0: f64,
}

pub fn duffing_restoring(x: f64) -> f64 {
    let k = 4.0 * std::f64::consts::PI.powi(2);
    -k * x - k * x * x * x
}

pub fn duffing_linear_only(x: f64) -> f64 {
    let k = 4.0 * std::f64::consts::PI.powi(2);
    -k * x
}

pub fn kresling_restoring(x: f64) -> f64 {
    -12.12 * x.powi(5) + 18.03 * x.powi(6) - 6.56 * x.powi(7)
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
    let n = (secs / dt).round() as usize + 1;
    let t = tfs_signal::time_grid(n, dt);
    let sweep = Sweep::new(SweepKind::Linear, f0, f1, secs, amp, 1.0).unwrap();
    let u = sweep.sample(&t);
    let maxwell = truth.hidden.iter().find_map(|h| match h {
        Hidden::Maxwell { tau, .. } => Some(*tau),
        _ => None,
    });
    let hidden = truth.hidden.clone();
    let restoring = truth.restoring;
    let c = truth.damping;
    // DOF 0: x; DOF 1: auxiliary p with p' = z (Maxwell state), p'' = x' − z/τ.
    let sys = FnSystem::new(
        2,
        1,
        move |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
            let mut f = restoring(x[0]) - c * v[0] - u[0];
            for h in &hidden {
                f += h.force(x[0], v[0], v[1]);
            }
            a[0] = f;
            a[1] = match maxwell {
                Some(tau) => v[0] - v[1] / tau,
                None => 0.0,
            };
        },
    );
    let felt = match truth.hidden.iter().find_map(|h| match h {
        Hidden::Delay(d) => Some(*d),
        _ => None,
    }) {
        Some(d) => t.iter().map(|&tk| sweep.value((tk - d).max(0.0))).collect(),
        None => u.clone(),
    };
    // A first-order low-pass τ y' + y = u, integrated independently of the crate's filter:
    // fine RK4 steps on the linearly interpolated input.
    let felt = match truth.hidden.iter().find_map(|h| match h {
        Hidden::InputFilter(tau) => Some(*tau),
        _ => None,
    }) {
        Some(tau) => {
            let sub = 20;
            let h = dt / sub as f64;
            let mut y = felt[0];
            let mut out = vec![y];
            for w in felt.windows(2) {
                let du = (w[1] - w[0]) / dt;
                for s in 0..sub {
                    let u0 = w[0] + du * s as f64 * h;
                    let f = |uu: f64, yy: f64| (uu - yy) / tau;
                    let k1 = f(u0, y);
                    let k2 = f(u0 + 0.5 * du * h, y + 0.5 * h * k1);
                    let k3 = f(u0 + 0.5 * du * h, y + 0.5 * h * k2);
                    let k4 = f(u0 + du * h, y + h * k3);
                    y += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
                }
                out.push(y);
            }
            out
        }
        None => felt,
    };
    let input = SampledInput::new(0.0, dt, vec![felt]).unwrap();
    let tr = Dopri5::default()
        .integrate(&sys, &input, &[truth.x0, 0.0], &[0.0, 0.0], &t)
        .unwrap();
    let x = add_noise_seeded(&tr.x[0], 40.0, NoiseKind::White, seed).unwrap();
    let un = add_noise_seeded(&u, 40.0, NoiseKind::White, seed + 1000).unwrap();
    Record::new(name, t, vec![("x".into(), x), ("xb_acc".into(), un)]).unwrap()
}

/// A model with the given library spec and placeholder coefficients (refitted by the tests).
pub fn structure(spec: &str) -> Model {
    let lib = Library::parse(spec, &["x"]).unwrap();
    Model::from_coefficients(&lib, &[vec![1.0; lib.len()]], "test").unwrap()
}

/// The noise-free record of a truth (Maxwell state integrated in its own coordinate) and its `x`.
pub fn clean(truth: &Truth, f0: f64, f1: f64, amp: f64, secs: f64, dt: f64) -> (Record, Vec<f64>) {
    let n = (secs / dt).round() as usize + 1;
    let t = tfs_signal::time_grid(n, dt);
    let sweep = Sweep::new(SweepKind::Linear, f0, f1, secs, amp, 1.0).unwrap();
    let u = sweep.sample(&t);
    let hidden = truth.hidden.clone();
    let restoring = truth.restoring;
    let c = truth.damping;
    let tau = hidden.iter().find_map(|h| match h {
        Hidden::Maxwell { tau, .. } => Some(*tau),
        _ => None,
    });
    let sys = FnSystem::new(
        2,
        1,
        move |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
            let mut f = restoring(x[0]) - c * v[0] - u[0];
            for h in &hidden {
                f += h.force(x[0], v[0], v[1]);
            }
            a[0] = f;
            a[1] = tau.map_or(0.0, |tau| v[0] - v[1] / tau);
        },
    );
    let input = SampledInput::new(0.0, dt, vec![u.clone()]).unwrap();
    let tr = Dopri5::default()
        .integrate(&sys, &input, &[truth.x0, 0.0], &[0.0, 0.0], &t)
        .unwrap();
    assert_eq!(tr.x[0].len(), n);
    let rec = Record::new(
        "clean",
        t,
        vec![("x".into(), tr.x[0].clone()), ("xb_acc".into(), u)],
    )
    .unwrap();
    (rec, tr.x[0].clone())
}
