//! The benchmark's truths: six baselines whose parameters and excitations are drawn per case,
//! simulated with hidden effects (`tfs_origami::hidden`) and measured with white noise.

use anyhow::{Context, Result, bail};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{Value, json};
use tfs::data::Record;
use tfs::dynamics::SecondOrderSystem;
use tfs::origami::oscillator::felt_input;
use tfs::origami::{
    CellSpec, Chain, Hidden, KreslingParams, Motion, Oscillator, Placed, SystemSpec, Truth,
    WithHidden, build_system, simulate_motion,
};
use tfs::records::Offsets;
use tfs::signal::noise::{SnrReference, noise_with};
use tfs::signal::{Excitation, Multisine, NoiseKind, Sweep, SweepKind};

pub use crate::common::rms;

/// The baselines.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Kind {
    /// Hardening Duffing oscillator on a moving base.
    Duffing,
    /// Double-well Duffing oscillator on a moving base, swept through chaotic snap-through.
    DoubleWell,
    /// Kresling cell with the polynomial surrogate force `{h^5, h^6, h^7}`.
    Surrogate,
    /// Kresling cell with the truss force itself, in its deployed well.
    Truss,
    /// Two surrogate cells in series.
    Chain,
    /// A force-driven Duffing rig in raw units (volts, offsets kept), ~10 samples per period.
    Rig,
}

impl Kind {
    /// Every baseline, in report order.
    pub const ALL: [Kind; 6] = [
        Kind::Duffing,
        Kind::DoubleWell,
        Kind::Surrogate,
        Kind::Truss,
        Kind::Chain,
        Kind::Rig,
    ];

    /// Short key.
    pub fn key(self) -> &'static str {
        match self {
            Kind::Duffing => "duffing",
            Kind::DoubleWell => "double-well",
            Kind::Surrogate => "surrogate",
            Kind::Truss => "truss",
            Kind::Chain => "chain",
            Kind::Rig => "rig",
        }
    }

    /// One line for the report.
    pub fn describe(self) -> &'static str {
        match self {
            Kind::Duffing => {
                "hardening Duffing x'' = −k x − k3 x³ − c x' − xb_acc, sweeps of base acceleration, 100 Hz, 30 s; start library x, x^3, x', xb_acc"
            }
            Kind::DoubleWell => {
                "double-well Duffing x'' = k x − k3 x³ − c x' − xb_acc swept through chaotic snap-through, 100 Hz, 30 s; start library x, x^3, x', xb_acc"
            }
            Kind::Surrogate => {
                "Kresling cell, surrogate force {h^5, h^6, h^7} (γ0 and c drawn), sweeps of base acceleration, 100 Hz, 30 s; start library x^5..7, x', xb_acc"
            }
            Kind::Truss => {
                "Kresling cell, truss force, moving in its deployed well, 100 Hz, 30 s; start library x^1..7, x', xb_acc"
            }
            Kind::Chain => {
                "two surrogate cells in series, 100 Hz, 40 s; start libraries x1^5..7, x1', (x2-x1)^5..7, (x2-x1)', xb_acc and (x2-x1)^5..7, (x2-x1)', xb_acc"
            }
            Kind::Rig => {
                "force-driven Duffing rig in raw units (f_n 80–120 Hz at 1 kHz, offsets on both channels kept), random-phase multisines, 6 s; start library 1, x, x^2, x^3, x', u"
            }
        }
    }
}

/// The structure under the hidden effects.
#[derive(Debug, Clone)]
pub enum BaseSystem {
    /// A polynomial oscillator (per unit mass).
    Osc(Oscillator),
    /// Kresling cells (a one-cell chain for a single cell).
    Cells(Chain),
}

impl SecondOrderSystem for BaseSystem {
    fn dofs(&self) -> usize {
        match self {
            BaseSystem::Osc(o) => o.dofs(),
            BaseSystem::Cells(c) => c.dofs(),
        }
    }
    fn inputs(&self) -> usize {
        1
    }
    fn internal_states(&self) -> usize {
        match self {
            BaseSystem::Osc(o) => o.internal_states(),
            BaseSystem::Cells(c) => c.internal_states(),
        }
    }
    fn accel(&self, t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        match self {
            BaseSystem::Osc(o) => o.accel(t, x, v, u, a),
            BaseSystem::Cells(c) => c.accel(t, x, v, u, a),
        }
    }
}

/// A continuous-time excitation.
#[derive(Debug, Clone)]
pub enum Signal {
    /// A sine sweep.
    Sweep(Sweep),
    /// A random-phase multisine.
    Multisine(Multisine),
}

impl Signal {
    /// The value at `t`.
    pub fn value(&self, t: f64) -> f64 {
        match self {
            Signal::Sweep(s) => s.value(t),
            Signal::Multisine(m) => m.value(t),
        }
    }
}

/// A baseline drawn for one case: structure, excitations, sampling and the start library.
#[derive(Debug, Clone)]
pub struct Baseline {
    /// Which baseline.
    pub kind: Kind,
    /// DOF columns.
    pub dofs: Vec<String>,
    /// Input column (`xb_acc` or `u`).
    pub input: String,
    /// Sampling interval (s).
    pub dt: f64,
    /// Record length (s).
    pub secs: f64,
    /// Mass of each DOF.
    pub masses: Vec<f64>,
    /// How the input enters each equation, per unit mass (`−1` for base acceleration).
    pub gain: f64,
    /// Initial displacements.
    pub x0: Vec<f64>,
    /// Start library per DOF.
    pub libraries: Vec<String>,
    /// Offsets policy of `identify`.
    pub offsets: Offsets,
    /// DC levels added to the measured DOF and input channels (raw units), or none.
    pub dc: Option<(Vec<f64>, f64)>,
    /// The structure.
    pub system: BaseSystem,
    /// Three training excitations and a held-out one.
    pub excitations: Vec<Signal>,
    /// Drawn parameters, for the report.
    pub params: Value,
}

fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

/// Log-uniform draw in `[lo, hi]`.
pub fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    (lo.ln() + (hi.ln() - lo.ln()) * rng.random::<f64>()).exp()
}

fn sweeps(rng: &mut ChaCha8Rng, f: (f64, f64), secs: f64, amp: f64) -> Result<Vec<Signal>> {
    (0..4)
        .map(|_| {
            let a = amp * uniform(rng, 0.8, 1.2);
            Ok(Signal::Sweep(Sweep::new(
                SweepKind::Linear,
                f.0,
                f.1,
                secs,
                a,
                1.0,
            )?))
        })
        .collect()
}

fn cells(gammas: &[f64], c: f64) -> Result<Chain> {
    let spec = |g: f64| CellSpec {
        params: KreslingParams {
            gamma0_deg: g,
            c,
            ..Default::default()
        },
        truth: Truth::Surrogate,
        ..Default::default()
    };
    let system = if gammas.len() == 1 {
        SystemSpec::Kresling(spec(gammas[0]))
    } else {
        SystemSpec::Chain {
            cells: gammas.iter().map(|&g| spec(g)).collect(),
        }
    };
    Ok(build_system(&system)?)
}

/// The deployed stable state of every cell of `chain` (as displacements relative to the base).
fn deployed(chain: &Chain) -> Result<Vec<f64>> {
    let mut x = Vec::new();
    let mut acc = 0.0;
    for c in chain.cells() {
        let (stable, _) = c.force_law().equilibria();
        let Some(h) = stable
            .iter()
            .copied()
            .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))))
        else {
            bail!("a cell without a stable state");
        };
        acc += h;
        x.push(acc);
    }
    Ok(x)
}

fn osc(restoring: Vec<(u32, f64)>, damping: f64, gain: f64) -> BaseSystem {
    BaseSystem::Osc(Oscillator {
        restoring,
        damping,
        gain,
        hidden: Vec::new(),
    })
}

/// Draws the baseline `kind` for one case.
pub fn draw(kind: Kind, rng: &mut ChaCha8Rng) -> Result<Baseline> {
    let two_pi = 2.0 * std::f64::consts::PI;
    let one = |s: &str| vec![s.to_string()];
    let base_excited = |system, libraries, x0: Vec<f64>, excitations, params, secs| Baseline {
        kind,
        dofs: if x0.len() == 1 {
            one("x")
        } else {
            (1..=x0.len()).map(|i| format!("x{i}")).collect()
        },
        input: "xb_acc".into(),
        dt: 0.01,
        secs,
        masses: vec![1.0; x0.len()],
        gain: -1.0,
        x0,
        libraries,
        offsets: Offsets::Auto,
        dc: None,
        system,
        excitations,
        params,
    };
    Ok(match kind {
        Kind::Duffing => {
            let fnat = uniform(rng, 0.8, 1.25);
            let k = (two_pi * fnat).powi(2);
            let k3 = k * uniform(rng, 0.5, 2.0);
            let zeta = uniform(rng, 0.02, 0.06);
            let c = 2.0 * zeta * two_pi * fnat;
            let ex = sweeps(rng, (0.3 * fnat, 3.0 * fnat), 30.0, 0.1 * k)?;
            base_excited(
                osc(vec![(1, -k), (3, -k3)], c, -1.0),
                one("x, x^3, x', xb_acc"),
                vec![0.0],
                ex,
                json!({"f_n": fnat, "k": k, "k3": k3, "zeta": zeta}),
                30.0,
            )
        }
        Kind::DoubleWell => {
            // Wells at ±1 (k3 = k); small oscillations in a well at f_w = sqrt(2k)/2π.
            let fw = uniform(rng, 0.8, 1.2);
            let k = (two_pi * fw).powi(2) / 2.0;
            let zeta = uniform(rng, 0.03, 0.08);
            let c = 2.0 * zeta * two_pi * fw;
            let amp = k * uniform(rng, 0.5, 0.8);
            let ex = sweeps(rng, (0.2 * fw, 2.0 * fw), 30.0, amp)?;
            base_excited(
                osc(vec![(1, k), (3, -k)], c, -1.0),
                one("x, x^3, x', xb_acc"),
                vec![1.0],
                ex,
                json!({"f_well": fw, "k": k, "k3": k, "zeta": zeta}),
                30.0,
            )
        }
        Kind::Surrogate | Kind::Truss => {
            let g = uniform(rng, 27.0, 31.0);
            let c = uniform(rng, 1.5, 2.5);
            let chain = if kind == Kind::Truss {
                build_system(&SystemSpec::Kresling(CellSpec {
                    params: KreslingParams {
                        gamma0_deg: g,
                        c,
                        ..Default::default()
                    },
                    truth: Truth::Truss,
                    ..Default::default()
                }))?
            } else {
                cells(&[g], c)?
            };
            let x0 = deployed(&chain)?;
            let (lib, amp) = if kind == Kind::Truss {
                ("x^1..7, x', xb_acc", uniform(rng, 0.8, 1.2))
            } else {
                ("x^5..7, x', xb_acc", uniform(rng, 2.5, 4.0))
            };
            let ex = sweeps(rng, (0.2, 2.5), 30.0, amp)?;
            base_excited(
                BaseSystem::Cells(chain),
                one(lib),
                x0,
                ex,
                json!({"gamma0_deg": g, "c": c, "amplitude": amp}),
                30.0,
            )
        }
        Kind::Chain => {
            let (g1, g2) = (uniform(rng, 26.0, 30.0), uniform(rng, 26.0, 30.0));
            let c = uniform(rng, 1.5, 2.5);
            let chain = cells(&[g1, g2], c)?;
            let x0 = deployed(&chain)?;
            let amp = uniform(rng, 1.5, 2.5);
            let ex = sweeps(rng, (0.1, 2.0), 40.0, amp)?;
            base_excited(
                BaseSystem::Cells(chain),
                vec![
                    "x1^5..7, x1', (x2-x1)^5..7, (x2-x1)', xb_acc".into(),
                    "(x2-x1)^5..7, (x2-x1)', xb_acc".into(),
                ],
                x0,
                ex,
                json!({"gamma0_deg": [g1, g2], "c": c, "amplitude": amp}),
                40.0,
            )
        }
        Kind::Rig => rig(rng)?,
    })
}

/// The force-driven rig: `x'' = −ω² x − 2ζω x' − k3 x³ + g u` in volts, ~10 samples per
/// resonance period; k3 drawn so the cubic force is 5–20 % of the linear one at the pilot's RMS.
fn rig(rng: &mut ChaCha8Rng) -> Result<Baseline> {
    let fnat = uniform(rng, 80.0, 120.0);
    let w = 2.0 * std::f64::consts::PI * fnat;
    let zeta = uniform(rng, 0.02, 0.05);
    let g = uniform(rng, 5e4, 1e5);
    let (dt, secs) = (1e-3, 6.0);
    let mut ex = Vec::new();
    for _ in 0..4 {
        let seed = rng.random::<u64>();
        ex.push(Signal::Multisine(Multisine::new(
            5.0, 200.0, 150, 1.0, secs, 0.2, seed,
        )?));
    }
    // The linear pilot's RMS sets the cubic's scale.
    let linear = osc(vec![(1, -w * w)], 2.0 * zeta * w, g);
    let u = sample(&ex[0], dt, secs);
    let sys = WithHidden::new(linear, vec![1.0], Vec::new())?;
    let m = simulate_motion(&sys, &u, dt, &[0.0], (1e-8, 1e-12))?;
    let xr = rms(&m.x[0]);
    let share = uniform(rng, 0.05, 0.2);
    let k3 = share * w * w / (xr * xr);
    let sign = |rng: &mut ChaCha8Rng| if rng.random::<bool>() { 1.0 } else { -1.0 };
    let dc_x = sign(rng) * uniform(rng, 0.5, 2.0) * xr;
    let dc_u = sign(rng) * uniform(rng, 0.05, 0.2);
    Ok(Baseline {
        kind: Kind::Rig,
        dofs: vec!["x".into()],
        input: "u".into(),
        dt,
        secs,
        masses: vec![1.0],
        gain: g,
        x0: vec![0.0],
        libraries: vec!["x, x^2, x^3, x', u".into()],
        offsets: Offsets::ConstantTerm,
        dc: Some((vec![dc_x], dc_u)),
        system: osc(vec![(1, -w * w), (3, -k3)], 2.0 * zeta * w, g),
        excitations: ex,
        params: json!({"f_n": fnat, "zeta": zeta, "g": g, "k3": k3, "dc_x": dc_x, "dc_u": dc_u}),
    })
}

/// `x` plus white noise at `snr` dB relative to its mean square or variance (`reference`), drawn
/// from a `ChaCha8Rng` seeded with `seed`; `x` itself when `snr` is `None`.
fn noisy(x: &[f64], snr: Option<f64>, reference: SnrReference, seed: u64) -> Result<Vec<f64>> {
    let Some(s) = snr else {
        return Ok(x.to_vec());
    };
    let e = noise_with(
        x,
        s,
        NoiseKind::White,
        reference,
        &mut ChaCha8Rng::seed_from_u64(seed),
    )?;
    Ok(x.iter().zip(&e).map(|(a, b)| a + b).collect())
}

/// RMS about the mean.
pub fn std_dev(v: &[f64]) -> f64 {
    let m = v.iter().sum::<f64>() / v.len().max(1) as f64;
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// `signal` sampled every `dt` seconds over `secs`.
pub fn sample(signal: &Signal, dt: f64, secs: f64) -> Vec<f64> {
    let n = (secs / dt).round() as usize + 1;
    (0..n).map(|k| signal.value(k as f64 * dt)).collect()
}

/// One simulated record before measurement: the recorded input, the input the structure felt,
/// and the motion.
#[derive(Debug, Clone)]
pub struct Clean {
    /// The recorded input.
    pub u: Vec<f64>,
    /// The input the structure felt (delayed, filtered).
    pub felt: Vec<f64>,
    /// The motion.
    pub motion: Motion,
}

/// Simulates record `i` of `b` with the `placed` effects and the exciter effects `exciter`.
/// A motion that leaves a sane range (a blow-up or an escape to infinity) is an error.
pub fn simulate(b: &Baseline, i: usize, placed: &[Placed], exciter: &[Hidden]) -> Result<Clean> {
    let u = sample(&b.excitations[i], b.dt, b.secs);
    let sig = &b.excitations[i];
    let felt = felt_input(exciter, &u, b.dt, &|t| sig.value(t));
    let sys = WithHidden::new(b.system.clone(), b.masses.clone(), placed.to_vec())?;
    let motion = simulate_motion(&sys, &felt, b.dt, &b.x0, (1e-8, 1e-11))
        .with_context(|| format!("{} record {i}", b.kind.key()))?;
    for x in &motion.x {
        if x.iter().any(|v| !v.is_finite() || v.abs() > 1e3) {
            bail!(
                "{} record {i}: the truth's motion leaves |x| < 1000 (escapes)",
                b.kind.key()
            );
        }
    }
    Ok(Clean { u, felt, motion })
}

/// The measured record: white noise at `snr` dB (or none) on every DOF and the input, relative
/// to each channel's mean square or variance (`reference`), each channel its own stream of `seed`;
/// the rig's DC levels added after the noise.
pub fn measure(
    b: &Baseline,
    name: &str,
    c: &Clean,
    snr: Option<f64>,
    reference: SnrReference,
    seed: u64,
) -> Result<Record> {
    let n = c.u.len();
    let t = tfs::signal::time_grid(n, b.dt);
    let noisy = |x: &[f64], k: u64| noisy(x, snr, reference, seed + k);
    let mut cols = Vec::new();
    for (d, name) in b.dofs.iter().enumerate() {
        let mut x = noisy(&c.motion.x[d], d as u64)?;
        if let Some((dx, _)) = &b.dc {
            x.iter_mut().for_each(|v| *v += dx[d]);
        }
        cols.push((name.clone(), x));
    }
    let mut u = noisy(&c.u, 1000)?;
    if let Some((_, du)) = &b.dc {
        u.iter_mut().for_each(|v| *v += du);
    }
    cols.push((b.input.clone(), u));
    Ok(Record::new(name, t, cols)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A height of 1.57 moving ±0.05: under the mean square the noise is set by the height,
    /// under the variance by the motion, and the mean square is what the library's seeded noise
    /// gives (the benchmark's default, unchanged).
    #[test]
    fn the_noise_reference_is_the_motion_under_variance_and_the_height_under_mean_square() {
        let x: Vec<f64> = (0..4000)
            .map(|i| 1.57 + 0.05 * (0.013 * i as f64).sin())
            .collect();
        let motion = rms(&x.iter().map(|v| v - 1.57).collect::<Vec<_>>());
        let added = |y: &[f64]| rms(&y.iter().zip(&x).map(|(a, b)| a - b).collect::<Vec<_>>());
        let ms = noisy(&x, Some(40.0), SnrReference::MeanSquare, 7).unwrap();
        let var = noisy(&x, Some(40.0), SnrReference::Variance, 7).unwrap();
        assert_eq!(
            ms,
            tfs::signal::noise::add_noise_seeded(&x, 40.0, NoiseKind::White, 7).unwrap()
        );
        assert!((added(&ms) / rms(&x) - 0.01).abs() < 1e-9);
        assert!(
            (added(&var) / motion - 0.01).abs() < 2e-3,
            "{}",
            added(&var) / motion
        );
        assert!(added(&ms) > 20.0 * added(&var));
        assert_eq!(noisy(&x, None, SnrReference::Variance, 7).unwrap(), x);
    }
}
