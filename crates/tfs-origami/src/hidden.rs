//! Hidden effects on any structure: a [`WithHidden`] system adds [`Hidden`] effects to a base
//! system (a [`crate::Chain`] of Kresling cells, a truss or surrogate [`crate::CellSystem`], an
//! [`crate::Oscillator`]), each placed on one element of it, so that a diagnosis can be tested on
//! truths it has never seen: friction, damping laws, extra stiffness, a stop or a memory effect in
//! a chain's coupling, a preload on one mass.
//!
//! An effect on [`On::Cell`] `i` acts in the element between mass `i` and mass `i − 1` (the base
//! for `i = 0`): its coordinate is `h_i = x_i − x_{i−1}` (`x_{−1} ≡ 0`), its force `F` pushes mass
//! `i` by `F/m_i` and mass `i − 1` by `−F/m_{i−1}` (action and reaction). An effect on
//! [`On::Mass`] `i` acts on that mass alone, with the coordinate `x_i`. Forces are in the base
//! system's units (per unit mass for an oscillator: masses 1). Memory effects (Maxwell, Bouc–Wen,
//! Dahl) add one internal state each after the base system's coordinates; exciter effects (delay,
//! input filter) act through the input, [`crate::oscillator::felt_input`].
//!
//! [`simulate_motion`] drives such a system from rest and returns every motion coordinate's
//! displacement, velocity and acceleration at the samples, and each placed effect's force.

use tfs_dynamics::{Dopri5, Integrator, SampledInput, SecondOrderSystem};

use crate::oscillator::Hidden;
use crate::{OrigamiError, Result};

/// Where a hidden effect acts (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum On {
    /// The element between mass `i` and mass `i − 1` (the base for `i = 0`).
    Cell(usize),
    /// Mass `i` alone.
    Mass(usize),
}

/// A hidden effect and where it acts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placed {
    /// Where.
    pub on: On,
    /// What.
    pub effect: Hidden,
}

/// A base system plus hidden effects (see the module docs).
#[derive(Debug, Clone)]
pub struct WithHidden<S> {
    base: S,
    masses: Vec<f64>,
    placed: Vec<Placed>,
    /// Motion coordinates of the base (its DOFs less its internal states).
    motion: usize,
    /// Slot of each placed effect's internal state (None for stateless ones).
    slots: Vec<Option<usize>>,
}

impl<S: SecondOrderSystem> WithHidden<S> {
    /// `base` with `placed` effects; `masses` has one positive mass per motion coordinate.
    pub fn new(base: S, masses: Vec<f64>, placed: Vec<Placed>) -> Result<Self> {
        let motion = base.dofs() - base.internal_states();
        if masses.len() != motion || masses.iter().any(|m| !(m.is_finite() && *m > 0.0)) {
            return Err(OrigamiError::Param(format!(
                "hidden effects: {} masses given for {motion} moving coordinates; give one positive mass each",
                masses.len()
            )));
        }
        let mut next = base.dofs();
        let mut slots = Vec::with_capacity(placed.len());
        for p in &placed {
            let i = match p.on {
                On::Cell(i) | On::Mass(i) => i,
            };
            if i >= motion {
                return Err(OrigamiError::Param(format!(
                    "hidden effect {:?} placed on coordinate {i}, but the system has {motion}",
                    p.effect
                )));
            }
            slots.push(p.effect.has_state().then(|| {
                next += 1;
                next - 1
            }));
        }
        Ok(Self {
            base,
            masses,
            placed,
            motion,
            slots,
        })
    }

    /// The base system.
    pub fn base(&self) -> &S {
        &self.base
    }

    /// The placed effects.
    pub fn placed(&self) -> &[Placed] {
        &self.placed
    }

    /// Number of motion coordinates (measured displacements).
    pub fn motion(&self) -> usize {
        self.motion
    }

    /// The coordinate and its velocity an effect at `on` sees.
    fn coordinate(&self, on: On, x: &[f64], v: &[f64]) -> (f64, f64) {
        match on {
            On::Cell(0) | On::Mass(0) => (x[0], v[0]),
            On::Cell(i) => (x[i] - x[i - 1], v[i] - v[i - 1]),
            On::Mass(i) => (x[i], v[i]),
        }
    }

    /// The force of each placed effect at a state (`x`, `v` over every coordinate, internal
    /// states included).
    pub fn effect_forces(&self, x: &[f64], v: &[f64]) -> Vec<f64> {
        self.placed
            .iter()
            .zip(&self.slots)
            .map(|(p, slot)| {
                let (h, hv) = self.coordinate(p.on, x, v);
                p.effect.force(h, hv, slot.map_or(0.0, |s| v[s]))
            })
            .collect()
    }
}

impl<S: SecondOrderSystem> SecondOrderSystem for WithHidden<S> {
    fn dofs(&self) -> usize {
        self.base.dofs() + self.slots.iter().flatten().count()
    }
    fn inputs(&self) -> usize {
        self.base.inputs()
    }
    fn internal_states(&self) -> usize {
        self.base.internal_states() + self.slots.iter().flatten().count()
    }
    fn accel(&self, t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        let nb = self.base.dofs();
        self.base.accel(t, &x[..nb], &v[..nb], u, &mut a[..nb]);
        for (p, slot) in self.placed.iter().zip(&self.slots) {
            let (h, hv) = self.coordinate(p.on, x, v);
            let z = slot.map_or(0.0, |s| v[s]);
            let f = p.effect.force(h, hv, z);
            match p.on {
                On::Cell(i) => {
                    a[i] += f / self.masses[i];
                    if i > 0 {
                        a[i - 1] -= f / self.masses[i - 1];
                    }
                }
                On::Mass(i) => a[i] += f / self.masses[i],
            }
            if let Some(s) = slot {
                a[*s] = p.effect.rate(hv, z);
            }
        }
    }
}

/// A simulated motion at the sample times.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    /// Displacement of each motion coordinate.
    pub x: Vec<Vec<f64>>,
    /// Velocity of each motion coordinate.
    pub v: Vec<Vec<f64>>,
    /// Acceleration of each motion coordinate (the system evaluated at the sampled state).
    pub a: Vec<Vec<f64>>,
    /// The force of each placed effect along the motion.
    pub forces: Vec<Vec<f64>>,
}

/// Simulates `sys` under `input` (one channel, sampled every `dt` seconds from `t = 0`, cubic
/// spline between samples) from the displacements `x0` at rest, internal states at 0, with the
/// Dormand–Prince tolerances `tol = (rtol, atol)`. A blow-up is an error.
pub fn simulate_motion<S: SecondOrderSystem>(
    sys: &WithHidden<S>,
    input: &[f64],
    dt: f64,
    x0: &[f64],
    tol: (f64, f64),
) -> Result<Motion> {
    let n = input.len();
    let t = tfs_signal::time_grid(n, dt);
    let sim = |e| OrigamiError::Simulation {
        record: 0,
        source: e,
    };
    let u = SampledInput::new(0.0, dt, vec![input.to_vec()]).map_err(sim)?;
    let d = sys.dofs();
    let m = sys.motion();
    if x0.len() != m {
        return Err(OrigamiError::Param(format!(
            "{} initial displacements for {m} moving coordinates",
            x0.len()
        )));
    }
    let mut x = vec![0.0; d];
    x[..m].copy_from_slice(x0);
    let tr = Dopri5::with_tol(tol.0, tol.1)
        .integrate(sys, &u, &x, &vec![0.0; d], &t)
        .map_err(sim)?;
    let mut acc = vec![vec![0.0; n]; m];
    let mut forces = vec![vec![0.0; n]; sys.placed().len()];
    let (mut xs, mut vs, mut a) = (vec![0.0; d], vec![0.0; d], vec![0.0; d]);
    for k in 0..n {
        for j in 0..d {
            xs[j] = tr.x[j][k];
            vs[j] = tr.v[j][k];
        }
        sys.accel(t[k], &xs, &vs, &[input[k]], &mut a);
        for j in 0..m {
            acc[j][k] = a[j];
        }
        for (f, v) in forces.iter_mut().zip(sys.effect_forces(&xs, &vs)) {
            f[k] = v;
        }
    }
    Ok(Motion {
        x: tr.x[..m].to_vec(),
        v: tr.v[..m].to_vec(),
        a: acc,
        forces,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Oscillator;

    fn osc(hidden: Vec<Hidden>) -> Oscillator {
        Oscillator {
            restoring: vec![(1, -40.0), (3, -40.0)],
            damping: 0.5,
            gain: -1.0,
            hidden,
        }
    }

    /// An effect placed on the single cell of an oscillator is the oscillator with that effect
    /// built in (the same equations by two routes), for a stateless and a memory effect.
    #[test]
    fn placed_effect_equals_the_built_in_one() {
        let dt = 0.01;
        let u: Vec<f64> = (0..1500)
            .map(|k| 3.0 * (2.0 * std::f64::consts::PI * 0.9 * k as f64 * dt).sin())
            .collect();
        for h in [
            Hidden::DryFriction {
                force: 1.5,
                eps: 0.05,
            },
            Hidden::Maxwell { k: 20.0, tau: 0.3 },
        ] {
            let built =
                crate::oscillator::simulate_record(&osc(vec![h]), &u, dt, 0.1, (1e-10, 1e-12))
                    .unwrap();
            let sys = WithHidden::new(
                osc(vec![]),
                vec![1.0],
                vec![Placed {
                    on: On::Cell(0),
                    effect: h,
                }],
            )
            .unwrap();
            let m = simulate_motion(&sys, &u, dt, &[0.1], (1e-10, 1e-12)).unwrap();
            let scale = built.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (p, q) in built.iter().zip(&m.x[0]) {
                assert!((p - q).abs() < 1e-6 * scale, "{h:?}: {p} vs {q}");
            }
            // The recorded force is the effect's, and it is not negligible.
            assert!(m.forces[0].iter().any(|f| f.abs() > 0.1), "{h:?}");
        }
    }

    /// A force in a chain's coupling acts on both masses, opposite and divided by each mass; on
    /// a mass it acts there alone.
    #[test]
    fn coupling_forces_act_on_both_masses() {
        let base = tfs_dynamics::FnSystem::new(
            2,
            1,
            |_t, _x: &[f64], _v: &[f64], _u: &[f64], a: &mut [f64]| {
                a[0] = 0.0;
                a[1] = 0.0;
            },
        );
        let sys = WithHidden::new(
            base,
            vec![2.0, 0.5],
            vec![
                Placed {
                    on: On::Cell(1),
                    effect: Hidden::Offset(1.0),
                },
                Placed {
                    on: On::Mass(0),
                    effect: Hidden::Offset(4.0),
                },
            ],
        )
        .unwrap();
        let mut a = [0.0; 2];
        sys.accel(0.0, &[0.0, 0.0], &[0.0, 0.0], &[0.0], &mut a);
        assert_eq!(a, [-0.5 + 2.0, 2.0]);
        assert!(
            WithHidden::new(
                tfs_dynamics::FnSystem::new(
                    1,
                    1,
                    |_t, _x: &[f64], _v: &[f64], _u: &[f64], _a: &mut [f64]| {}
                ),
                vec![1.0],
                vec![Placed {
                    on: On::Cell(1),
                    effect: Hidden::Offset(1.0)
                }]
            )
            .is_err()
        );
    }
}
