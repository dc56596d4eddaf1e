//! Single-DOF truths with memory and other effects, for testing what a diagnosis finds:
//!
//! * [`BoucWenOscillator`]: `m x'' + c x' + k x + z = u` with the Bouc–Wen hysteretic force
//!   `z' = α x' − β(γ|x'||z|^(ν−1) z + δ x' |z|^ν)`, in the form of the nonlinear
//!   system-identification benchmark (Noël & Schoukens), whose published parameters are
//!   [`BoucWenOscillator::benchmark`]. Force input `u`, displacement `x`.
//! * [`Oscillator`]: `x'' = Σ k_p x^p − c x' + g·u + hidden effects` per unit mass (a Duffing
//!   oscillator, single or double well, driven by a force or a base acceleration), with any
//!   [`Hidden`] effects the truth has and a model may lack: friction, damping laws, stiffness,
//!   an offset, a stop, memory (Maxwell, Bouc–Wen, Dahl) and exciter dynamics (delay, filter).
//!
//! Memory states are auxiliary coordinates whose velocity is the state (so they integrate with
//! the motion under any `tfs_dynamics` integrator, [`SecondOrderSystem::internal_states`]);
//! they start at rest. [`simulate_record`] drives either under a sampled input and returns the
//! clean displacement; [`measured`] adds white measurement noise at an SNR to a channel.

use tfs_data::Record;
use tfs_dynamics::{Dopri5, Integrator, SampledInput, SecondOrderSystem};
use tfs_signal::NoiseKind;
use tfs_signal::noise::add_noise_seeded;

use crate::{OrigamiError, Result};

/// The Bouc–Wen hysteretic oscillator in the benchmark's force form (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoucWenOscillator {
    /// Mass (kg).
    pub m: f64,
    /// Viscous damping (N s/m).
    pub c: f64,
    /// Linear stiffness (N/m).
    pub k: f64,
    /// Hysteretic stiffness α (N/m).
    pub alpha: f64,
    /// β (1/m for ν = 1).
    pub beta: f64,
    /// γ (dimensionless).
    pub gamma: f64,
    /// δ (dimensionless).
    pub delta: f64,
    /// ν ≥ 1.
    pub nu: f64,
}

impl BoucWenOscillator {
    /// The benchmark's published parameters: m = 2, c = 10, k = 5e4, α = 5e4, β = 1e3,
    /// γ = 0.8, δ = −1.1, ν = 1.
    pub fn benchmark() -> Self {
        Self {
            m: 2.0,
            c: 10.0,
            k: 5e4,
            alpha: 5e4,
            beta: 1e3,
            gamma: 0.8,
            delta: -1.1,
            nu: 1.0,
        }
    }

    /// Checks the parameters (positive mass, finite values, ν ≥ 1).
    pub fn validate(&self) -> Result<()> {
        let all = [
            ("m", self.m),
            ("c", self.c),
            ("k", self.k),
            ("alpha", self.alpha),
            ("beta", self.beta),
            ("gamma", self.gamma),
            ("delta", self.delta),
            ("nu", self.nu),
        ];
        if let Some((n, v)) = all.iter().find(|(_, v)| !v.is_finite()) {
            return Err(OrigamiError::Param(format!(
                "Bouc-Wen {n} = {v}: every parameter must be finite"
            )));
        }
        if self.m <= 0.0 || self.nu < 1.0 {
            return Err(OrigamiError::Param(format!(
                "Bouc-Wen m = {}, nu = {}: the mass must be positive and nu at least 1",
                self.m, self.nu
            )));
        }
        Ok(())
    }

    /// The hysteretic force's rate `z'` at velocity `v` and force `z`.
    #[inline]
    pub fn z_rate(&self, v: f64, z: f64) -> f64 {
        let p = if self.nu == 1.0 {
            1.0
        } else {
            z.abs().powf(self.nu - 1.0)
        };
        self.alpha * v - self.beta * (self.gamma * v.abs() * p * z + self.delta * v * p * z.abs())
    }
}

impl SecondOrderSystem for BoucWenOscillator {
    fn dofs(&self) -> usize {
        2
    }
    fn inputs(&self) -> usize {
        1
    }
    fn internal_states(&self) -> usize {
        1
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        let z = v[1];
        a[0] = (u[0] - self.c * v[0] - self.k * x[0] - z) / self.m;
        a[1] = self.z_rate(v[0], z);
    }
}

/// An effect a truth [`Oscillator`] has (forces per unit mass; `x`, `x'` its displacement and
/// velocity).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Hidden {
    /// Smoothed Coulomb friction `−force·tanh(x'/eps)`.
    DryFriction {
        /// Friction force per unit mass.
        force: f64,
        /// Smoothing velocity.
        eps: f64,
    },
    /// `−c·x'|x'|`.
    Quadratic(f64),
    /// `−c·x'^3`.
    CubicDamping(f64),
    /// `−c·x²x'`.
    AmplitudeDamping(f64),
    /// An extra stiffness power `coef·x^power`.
    Stiffness {
        /// The power.
        power: u32,
        /// Its coefficient (force per unit mass).
        coef: f64,
    },
    /// A constant force.
    Offset(f64),
    /// A Maxwell element: force `−k·z` with `z' = x' − z/τ`.
    Maxwell {
        /// Spring of the element per unit mass.
        k: f64,
        /// Relaxation time (s).
        tau: f64,
    },
    /// Bouc–Wen hysteresis: force `−k·z` with `z' = x' − a|x'||z|^(ν−1) z − b x'|z|^ν`.
    BoucWen {
        /// Hysteretic stiffness per unit mass.
        k: f64,
        /// a.
        a: f64,
        /// b.
        b: f64,
        /// ν ≥ 1.
        nu: f64,
    },
    /// Dahl friction: force `−force·z` with `z' = κ(x' − |x'| z)`.
    Dahl {
        /// Friction force per unit mass.
        force: f64,
        /// Inverse presliding displacement.
        kappa: f64,
    },
    /// A one-sided stop below `at`: contact force `k·max(0, at − x)`.
    Stop {
        /// Contact stiffness per unit mass.
        k: f64,
        /// Stop position.
        at: f64,
    },
    /// The structure feels the recorded input δ seconds late.
    Delay(f64),
    /// The structure feels the recorded input through a first-order low-pass of time constant τ.
    InputFilter(f64),
}

impl Hidden {
    /// True for the effects carried by an internal state.
    pub fn has_state(&self) -> bool {
        matches!(
            self,
            Hidden::Maxwell { .. } | Hidden::BoucWen { .. } | Hidden::Dahl { .. }
        )
    }

    /// The force at `(x, x')` with internal state `z` (0 for stateless effects and for the
    /// exciter effects, which act through the input: [`felt_input`]).
    pub fn force(&self, x: f64, v: f64, z: f64) -> f64 {
        match *self {
            Hidden::DryFriction { force, eps } => -force * (v / eps).tanh(),
            Hidden::Quadratic(c) => -c * v * v.abs(),
            Hidden::CubicDamping(c) => -c * v * v * v,
            Hidden::AmplitudeDamping(c) => -c * x * x * v,
            Hidden::Stiffness { power, coef } => coef * x.powi(power as i32),
            Hidden::Offset(f) => f,
            Hidden::Maxwell { k, .. } | Hidden::BoucWen { k, .. } => -k * z,
            Hidden::Dahl { force, .. } => -force * z,
            Hidden::Stop { k, at } => k * (at - x).max(0.0),
            Hidden::Delay(_) | Hidden::InputFilter(_) => 0.0,
        }
    }

    /// The internal state's rate at velocity `v` and state `z` (0 for stateless effects).
    pub fn rate(&self, v: f64, z: f64) -> f64 {
        match *self {
            Hidden::Maxwell { tau, .. } => v - z / tau,
            Hidden::BoucWen { a, b, nu, .. } => {
                let p = if nu == 1.0 {
                    1.0
                } else {
                    z.abs().powf(nu - 1.0)
                };
                v - a * v.abs() * p * z - b * v * p * z.abs()
            }
            Hidden::Dahl { kappa, .. } => kappa * (v - v.abs() * z),
            _ => 0.0,
        }
    }
}

/// A 1-DOF truth `x'' = Σ k_p x^p − c x' + g·u + Σ hidden` (per unit mass; see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Oscillator {
    /// Restoring polynomial: `(power, coefficient)` pairs, e.g. a double well
    /// `[(1, k), (3, −k3)]` with `k, k3 > 0`.
    pub restoring: Vec<(u32, f64)>,
    /// Linear damping per unit mass.
    pub damping: f64,
    /// Input gain: `−1` for a base acceleration `xb_acc` in the relative coordinate, `1/m` for
    /// a force.
    pub gain: f64,
    /// The effects a model may be missing.
    pub hidden: Vec<Hidden>,
}

impl Oscillator {
    fn stateful(&self) -> impl Iterator<Item = &Hidden> {
        self.hidden.iter().filter(|h| h.has_state())
    }

    /// The input the structure feels, from the recorded one sampled every `dt` seconds (see
    /// [`felt_input`]).
    pub fn felt_input(&self, recorded: &[f64], dt: f64, delayed: &dyn Fn(f64) -> f64) -> Vec<f64> {
        felt_input(&self.hidden, recorded, dt, delayed)
    }
}

/// The input a structure with the exciter effects among `hidden` feels, from the recorded one
/// sampled every `dt` seconds: delayed by a [`Hidden::Delay`] (the excitation `delayed(t)`
/// evaluated at `t − δ`, held at its start value before 0), then filtered by a
/// [`Hidden::InputFilter`] (RK4 at 20 steps per sample on the linearly interpolated input, from
/// the first value). Without either it is the recorded input.
pub fn felt_input(
    hidden: &[Hidden],
    recorded: &[f64],
    dt: f64,
    delayed: &dyn Fn(f64) -> f64,
) -> Vec<f64> {
    let t = |k: usize| k as f64 * dt;
    let mut felt = match hidden.iter().find_map(|h| match h {
        Hidden::Delay(d) => Some(*d),
        _ => None,
    }) {
        Some(d) => (0..recorded.len())
            .map(|k| delayed((t(k) - d).max(0.0)))
            .collect(),
        None => recorded.to_vec(),
    };
    if let Some(tau) = hidden.iter().find_map(|h| match h {
        Hidden::InputFilter(tau) => Some(*tau),
        _ => None,
    }) {
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
        felt = out;
    }
    felt
}

impl SecondOrderSystem for Oscillator {
    fn dofs(&self) -> usize {
        // A memoryless truth keeps one auxiliary coordinate (at rest) so every truth integrates
        // the same way.
        1 + self.stateful().count().max(1)
    }
    fn inputs(&self) -> usize {
        1
    }
    fn internal_states(&self) -> usize {
        self.dofs() - 1
    }
    fn accel(&self, _t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        let mut f = -self.damping * v[0] + self.gain * u[0];
        for &(p, c) in &self.restoring {
            f += c * x[0].powi(p as i32);
        }
        let mut j = 1;
        for h in &self.hidden {
            if h.has_state() {
                f += h.force(x[0], v[0], v[j]);
                a[j] = h.rate(v[0], v[j]);
                j += 1;
            } else {
                f += h.force(x[0], v[0], 0.0);
            }
        }
        if j == 1 {
            a[1] = 0.0;
        }
        a[0] = f;
    }
}

/// Simulates a 1-DOF system `sys` (its first coordinate is the displacement; the others are
/// internal states, started at rest) under `input` sampled every `dt` seconds from `t = 0`,
/// starting at `x0` at rest; returns the displacement at the sample times. Dormand–Prince with
/// tolerances `rtol`, `atol` on the cubic-spline interpolated input; a blow-up is an error.
pub fn simulate_record<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    input: &[f64],
    dt: f64,
    x0: f64,
    tol: (f64, f64),
) -> Result<Vec<f64>> {
    let n = input.len();
    let t = tfs_signal::time_grid(n, dt);
    let u =
        SampledInput::new(0.0, dt, vec![input.to_vec()]).map_err(|e| OrigamiError::Simulation {
            record: 0,
            source: e,
        })?;
    let d = sys.dofs();
    let mut x = vec![0.0; d];
    x[0] = x0;
    let tr = Dopri5::with_tol(tol.0, tol.1)
        .integrate(sys, &u, &x, &vec![0.0; d], &t)
        .map_err(|e| OrigamiError::Simulation {
            record: 0,
            source: e,
        })?;
    Ok(tr.x[0].clone())
}

/// A measured record `t, <x_name>, <u_name>` from clean channels: white noise at `snr_db`
/// (seeded `seed` on the displacement, `seed + 1000` on the input) or none (`None`).
pub fn measured(
    name: &str,
    dt: f64,
    (x_name, x): (&str, &[f64]),
    (u_name, u): (&str, &[f64]),
    snr_db: Option<f64>,
    seed: u64,
) -> Result<Record> {
    let t = tfs_signal::time_grid(x.len(), dt);
    let (x, u) = match snr_db {
        Some(snr) => (
            add_noise_seeded(x, snr, NoiseKind::White, seed)?,
            add_noise_seeded(u, snr, NoiseKind::White, seed + 1000)?,
        ),
        None => (x.to_vec(), u.to_vec()),
    };
    Ok(Record::new(
        name,
        t,
        vec![(x_name.into(), x), (u_name.into(), u)],
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// In the benchmark's force form and in the per-unit-mass form of [`Hidden::BoucWen`]
    /// (`z_F = α z`, `a = βγ`, `b = βδ`, force `α/m · z`) the oscillator is the same system.
    #[test]
    fn force_form_equals_per_unit_mass_form() {
        let bw = BoucWenOscillator::benchmark();
        let osc = Oscillator {
            restoring: vec![(1, -bw.k / bw.m)],
            damping: bw.c / bw.m,
            gain: 1.0 / bw.m,
            hidden: vec![Hidden::BoucWen {
                k: bw.alpha / bw.m,
                a: bw.beta * bw.gamma,
                b: bw.beta * bw.delta,
                nu: 1.0,
            }],
        };
        let dt = 1.0 / 750.0;
        let u: Vec<f64> = (0..3000)
            .map(|k| 50.0 * (2.0 * std::f64::consts::PI * 30.0 * k as f64 * dt).sin())
            .collect();
        let a = simulate_record(&bw, &u, dt, 0.0, (1e-10, 1e-14)).unwrap();
        let b = simulate_record(&osc, &u, dt, 0.0, (1e-10, 1e-14)).unwrap();
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(scale > 1e-4, "the benchmark moves: {scale}");
        for (p, q) in a.iter().zip(&b) {
            assert!((p - q).abs() < 1e-6 * scale, "{p} vs {q}");
        }
        assert!(
            BoucWenOscillator {
                nu: 0.5,
                ..BoucWenOscillator::benchmark()
            }
            .validate()
            .is_err()
        );
    }
}
