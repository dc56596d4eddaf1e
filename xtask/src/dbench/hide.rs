//! Hiding a catalogue effect in a truth: from the effect's name (the catalogue is enumerated, so
//! every effect it has is tried) to a physical [`Hidden`] effect of `tfs_origami` with drawn
//! parameters, placed on a drawn element, its strength set so that its force is a drawn share of
//! the RMS acceleration of the baseline's motion (the pilot). Also says which start-library
//! terms the effect's presence removes and which answers count as correct.

use anyhow::Result;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde_json::{Value, json};
use tfs::origami::oscillator::felt_input;
use tfs::origami::{Hidden, On, Placed};

use super::truth::{BaseSystem, Baseline, Clean, Kind, log_uniform, rms, std_dev};

/// An effect hidden in a truth.
#[derive(Debug, Clone)]
pub struct Hide {
    /// The catalogue name.
    pub effect: String,
    /// Effects acting on the structure.
    pub placed: Vec<Placed>,
    /// Effects acting through the input (delay, filter).
    pub exciter: Vec<Hidden>,
    /// Terms removed from the start library (per DOF equation: the term's text).
    pub drop: Vec<String>,
    /// The DOFs whose equation may name it (`effect@dof` for chains).
    pub dofs: Vec<String>,
    /// The acceleration channel its size is measured on (a DOF index).
    pub dof: usize,
    /// Drawn parameters, for the report.
    pub params: Value,
}

/// The baseline's own polynomial coefficient of `h^p` in cell `cell`, per unit mass, if it has
/// one.
fn own_power(b: &Baseline, cell: usize, p: u32) -> Option<f64> {
    match &b.system {
        BaseSystem::Osc(o) => o.restoring.iter().find(|(q, _)| *q == p).map(|(_, c)| *c),
        BaseSystem::Cells(c) => match c.cells()[cell].force_law() {
            tfs::origami::CellForce::Surrogate(s) => s
                .spec
                .powers
                .iter()
                .position(|&q| q == p)
                .map(|i| -s.coefs[i] / c.cells()[cell].mass()),
            tfs::origami::CellForce::Truss(_) => None,
        },
    }
}

/// The baseline's own linear damping coefficient of cell `cell`, per unit mass (the force is
/// `−c·v`).
fn own_damping(b: &Baseline, cell: usize) -> f64 {
    match &b.system {
        BaseSystem::Osc(o) => o.damping,
        BaseSystem::Cells(c) => c.cells()[cell].damping() / c.cells()[cell].mass(),
    }
}

/// Hiding one of the baseline's own terms (`term`, coefficient `coef` per unit mass): it is
/// removed from the start library, its size is the baseline's.
fn own_term(name: &str, term: String, coef: f64, dofs: Vec<String>, cell: usize) -> Hide {
    Hide {
        effect: name.into(),
        placed: vec![],
        exciter: vec![],
        drop: vec![term.clone()],
        dofs,
        dof: cell,
        params: json!({"own_term": term, "coef": coef}),
    }
}

/// The coordinate (and its velocity) of cell `i` along the pilot.
fn coordinate(m: &Clean, on: On) -> (Vec<f64>, Vec<f64>) {
    let x = &m.motion.x;
    let v = &m.motion.v;
    match on {
        On::Cell(0) | On::Mass(0) => (x[0].clone(), v[0].clone()),
        On::Cell(i) => (
            x[i].iter().zip(&x[i - 1]).map(|(a, b)| a - b).collect(),
            v[i].iter().zip(&v[i - 1]).map(|(a, b)| a - b).collect(),
        ),
        On::Mass(i) => (x[i].clone(), v[i].clone()),
    }
}

/// A memory effect's internal state along a velocity history (RK4, 10 sub-steps per sample on
/// the linearly interpolated velocity, from rest).
fn state_along(h: &Hidden, v: &[f64], dt: f64) -> Vec<f64> {
    let sub = 10;
    let s = dt / sub as f64;
    let mut z = 0.0;
    let mut out = vec![z];
    for w in v.windows(2) {
        let dv = (w[1] - w[0]) / dt;
        for k in 0..sub {
            let v0 = w[0] + dv * k as f64 * s;
            let k1 = h.rate(v0, z);
            let k2 = h.rate(v0 + 0.5 * dv * s, z + 0.5 * s * k1);
            let k3 = h.rate(v0 + 0.5 * dv * s, z + 0.5 * s * k2);
            let k4 = h.rate(v0 + dv * s, z + s * k3);
            z += s / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        out.push(z);
    }
    out
}

/// The dominant period of a velocity history: the inverse of its power-weighted mean frequency.
fn period(v: &[f64], dt: f64) -> f64 {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let c: Vec<f64> = v.iter().map(|x| x - m).collect();
    let Ok((f, a)) = tfs::signal::amplitude_spectrum(&c, dt) else {
        return 1.0;
    };
    let (mut num, mut den) = (0.0, 0.0);
    for (fi, ai) in f.iter().zip(&a) {
        num += fi * ai * ai;
        den += ai * ai;
    }
    if num > 0.0 { den / num } else { 1.0 }
}

/// Bisection for the exciter parameter `p` in `(0, hi]` whose size `size(p)` (increasing from
/// 0) is `target`.
fn solve(size: impl Fn(f64) -> f64, target: f64, hi: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, hi);
    if size(hi) < target {
        return hi;
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if size(mid) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

fn sign(rng: &mut ChaCha8Rng) -> f64 {
    if rng.random::<bool>() { 1.0 } else { -1.0 }
}

fn power_name(v: &str, p: u32) -> String {
    if p == 1 {
        v.to_string()
    } else {
        format!("{v}^{p}")
    }
}

/// Hides the catalogue effect `name` in baseline `b` with a force of `target` times the RMS
/// acceleration of the `pilot` motion (the baseline alone under the first training record).
/// `None` when the benchmark has no truth for that effect or it does not apply to `b`.
pub fn hide(
    name: &str,
    b: &Baseline,
    pilot: &Clean,
    target: f64,
    rng: &mut ChaCha8Rng,
) -> Result<Option<Hide>> {
    let n = b.dofs.len();
    // The element: a chain draws its cell (the ground cell, or the coupling).
    let cell = if n > 1 { rng.random_range(0..n) } else { 0 };
    let on = On::Cell(cell);
    let dofs: Vec<String> = if cell == 0 {
        vec![b.dofs[0].clone()]
    } else {
        vec![b.dofs[cell - 1].clone(), b.dofs[cell].clone()]
    };
    let a_rms = std_dev(&pilot.motion.a[cell]);
    let mass = b.masses[cell];
    let (h, hv) = coordinate(pilot, on);
    // Strength so that the unit law's force along the pilot varies by the target share (its
    // mean only moves the rest state).
    let strength = |unit: &[f64]| target * a_rms * mass / std_dev(unit).max(f64::MIN_POSITIVE);
    let coord = if cell == 0 {
        b.dofs[0].clone()
    } else {
        format!("({}-{})", b.dofs[cell], b.dofs[cell - 1])
    };
    let placed = |effect: Hidden| vec![Placed { on, effect }];
    let mut drop = Vec::new();
    let (placed, exciter, params): (Vec<Placed>, Vec<Hidden>, Value) = match name {
        "dry-friction" => {
            let eps = log_uniform(rng, 0.005, 0.05) * rms(&hv);
            let unit: Vec<f64> = hv.iter().map(|v| (v / eps).tanh()).collect();
            let force = strength(&unit);
            (
                placed(Hidden::DryFriction { force, eps }),
                vec![],
                json!({"force": force, "eps": eps}),
            )
        }
        "quadratic-damping" => {
            let unit: Vec<f64> = hv.iter().map(|v| v * v.abs()).collect();
            let c = strength(&unit);
            (placed(Hidden::Quadratic(c)), vec![], json!({"c": c}))
        }
        "cubic-damping" => {
            let unit: Vec<f64> = hv.iter().map(|v| v * v * v).collect();
            let c = strength(&unit);
            (placed(Hidden::CubicDamping(c)), vec![], json!({"c": c}))
        }
        "amplitude-damping" => {
            let unit: Vec<f64> = h.iter().zip(&hv).map(|(x, v)| x * x * v).collect();
            let c = strength(&unit);
            (placed(Hidden::AmplitudeDamping(c)), vec![], json!({"c": c}))
        }
        "offset" => {
            if b.kind == Kind::Rig {
                return Ok(None); // the raw-unit library has the constant already
            }
            // On one mass (gravity, a preload).
            let f = sign(rng) * target * a_rms * mass;
            let p = vec![Placed {
                on: On::Mass(cell),
                effect: Hidden::Offset(f),
            }];
            return Ok(Some(Hide {
                effect: name.into(),
                placed: p,
                exciter: vec![],
                drop,
                dofs: vec![b.dofs[cell].clone()],
                dof: cell,
                params: json!({"force": f, "mass": b.dofs[cell]}),
            }));
        }
        "maxwell" => {
            let tau = log_uniform(rng, 0.05, 1.0) * period(&hv, b.dt);
            let unit = state_along(&Hidden::Maxwell { k: 1.0, tau }, &hv, b.dt);
            let k = strength(&unit);
            (
                placed(Hidden::Maxwell { k, tau }),
                vec![],
                json!({"k": k, "tau": tau}),
            )
        }
        "hysteresis" => {
            let x = std_dev(&h).max(f64::MIN_POSITIVE);
            let a = log_uniform(rng, 0.3, 5.0) / x;
            let bb = a * (-0.8 + 1.6 * rng.random::<f64>());
            let law = |k| Hidden::BoucWen {
                k,
                a,
                b: bb,
                nu: 1.0,
            };
            let unit = state_along(&law(1.0), &hv, b.dt);
            let k = strength(&unit);
            (
                placed(law(k)),
                vec![],
                json!({"k": k, "a": a, "b": bb, "nu": 1.0, "a_times_rms": a * x}),
            )
        }
        "stop" => {
            let mut sorted = h.clone();
            sorted.sort_by(f64::total_cmp);
            let q = 0.01 + 0.07 * rng.random::<f64>();
            let at = sorted[((q * sorted.len() as f64) as usize).min(sorted.len() - 1)];
            let unit: Vec<f64> = h.iter().map(|x| (at - x).max(0.0)).collect();
            let k = strength(&unit);
            (
                placed(Hidden::Stop { k, at }),
                vec![],
                json!({"k": k, "at": at, "quantile": q}),
            )
        }
        "linear-damping" => {
            // The baseline's own dashpot, removed from the start library: its size is the
            // baseline's, not drawn.
            let term = format!("{coord}'");
            let coef = -own_damping(b, cell);
            return Ok(Some(own_term(name, term, coef, dofs, cell)));
        }
        "input-delay" | "input-filter" => {
            let sig = &b.excitations[0];
            let delay = name == "input-delay";
            let make = |p: f64| {
                if delay {
                    Hidden::Delay(p)
                } else {
                    Hidden::InputFilter(p)
                }
            };
            let size = |p: f64| {
                let felt = felt_input(&[make(p)], &pilot.u, b.dt, &|t| sig.value(t));
                let d: Vec<f64> = felt.iter().zip(&pilot.u).map(|(f, u)| f - u).collect();
                b.gain.abs() * rms(&d) / a_rms
            };
            let p = solve(size, target, 0.5 * period(&pilot.u, b.dt));
            let key = if delay { "delay" } else { "tau" };
            return Ok(Some(Hide {
                effect: name.into(),
                placed: vec![],
                exciter: vec![make(p)],
                drop,
                dofs: b.dofs.clone(),
                dof: 0,
                params: json!({ key: p, "samples": p / b.dt }),
            }));
        }
        other => {
            let Some(p) = other
                .strip_prefix("stiffness-x^")
                .and_then(|s| s.parse::<u32>().ok())
            else {
                return Ok(None);
            };
            let term = power_name(&coord, p);
            let in_library = b.libraries.iter().any(|l| {
                tfs::library::Library::parse(
                    l,
                    &b.dofs.iter().map(String::as_str).collect::<Vec<_>>(),
                )
                .map(|lib| lib.terms().iter().any(|t| t.to_string() == term))
                .unwrap_or(false)
            });
            if let Some(own) = own_power(b, cell, p) {
                // The baseline's own term, removed from the start library: its size is the
                // baseline's, not drawn.
                return Ok(Some(own_term(name, term, own, dofs, cell)));
            }
            if in_library {
                drop.push(term.clone());
            }
            // Odd powers stiffen (restore), even ones break the symmetry either way.
            let unit: Vec<f64> = h.iter().map(|x| x.powi(p as i32)).collect();
            let coef = -strength(&unit) * if p % 2 == 1 { 1.0 } else { sign(rng) };
            (
                placed(Hidden::Stiffness { power: p, coef }),
                vec![],
                json!({"power": p, "coef": coef}),
            )
        }
    };
    Ok(Some(Hide {
        effect: name.into(),
        placed,
        exciter,
        drop,
        dofs,
        dof: cell,
        params,
    }))
}
