//! Memory effects: physics that depends on the motion's history, carried by an internal state of
//! the term grammar (`tfs_library::state`). Each is offered on the DOF's own velocity and on every
//! relative velocity its equation uses; the state is computed along the record's smoothed
//! velocity from rest for the equation-error scan, and integrated with the motion in simulation.

use tfs_library::{Factor, StateLaw, Term, Var};

use super::{Effect, EffectColumn, EffectContext, Variant, round3};

/// One variant adding the state `law` driven by `v`, unless the equation has it already.
fn state_variant(
    ctx: &EffectContext<'_>,
    v: &Var,
    law: StateLaw,
    parameter: (&str, f64),
) -> Option<Variant> {
    let term = Term::new(vec![Factor::State(v.clone(), law)]);
    (!ctx.has(&term)).then(|| {
        Variant::adding(
            Some((parameter.0.to_string(), parameter.1)),
            vec![EffectColumn::term(term)],
        )
    })
}

/// Viscoelastic relaxation: a hidden Maxwell element (a spring in series with a dashpot), the
/// velocity low-pass filtered with time constant τ, `maxwell(x', τ)`; τ scanned over
/// 0.02..2 dominant periods, keeping only τ with 3τ within half the shortest record (a state
/// started at rest must forget its start).
#[derive(Debug, Clone, Copy)]
pub struct Maxwell;
impl Effect for Maxwell {
    fn name(&self) -> String {
        "maxwell".into()
    }
    fn description(&self) -> String {
        "viscoelastic relaxation: hidden Maxwell element maxwell(x', tau), the velocity low-pass filtered with time constant tau (scanned 0.02..2 dominant periods)".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        if !(ctx.period.is_finite() && ctx.period > 0.0) {
            return Vec::new();
        }
        let mut out = Vec::new();
        for v in ctx.velocity_vars() {
            for r in [0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0] {
                let tau = round3(r * ctx.period);
                if tau > ctx.dt && 3.0 * tau <= 0.5 * ctx.shortest_record {
                    out.extend(state_variant(
                        ctx,
                        &v,
                        StateLaw::Maxwell { tau },
                        ("tau", tau),
                    ));
                }
            }
        }
        out
    }
}

/// Hysteresis (joints, wire-rope isolators, rubber mounts, bolted and bonded connections, folded
/// panels): a Bouc–Wen state `bouc_wen(x', a, b)` with ν = 1. In units of the coordinate's
/// displacement RMS `X`, `a·X` is scanned over 0.1..10 (below, the state is the displacement
/// itself; above, a friction-like jump) and `b/a` over −1.5..1 (softening to hardening loops).
#[derive(Debug, Clone, Copy)]
pub struct Hysteresis;

/// The scanned `a·X` of [`Hysteresis`].
const HYSTERESIS_A: [f64; 5] = [0.1, 0.3, 1.0, 3.0, 10.0];
/// The scanned `b/a` of [`Hysteresis`].
const HYSTERESIS_RATIO: [f64; 6] = [-1.5, -1.0, -0.5, 0.0, 0.5, 1.0];

impl Effect for Hysteresis {
    fn name(&self) -> String {
        "hysteresis".into()
    }
    fn description(&self) -> String {
        "Bouc-Wen hysteresis bouc_wen(x', a, b): z' = x' - a|x'|z - b x'|z|, a*X scanned over 0.1..10 and b/a over -1.5..1 (X the displacement RMS)".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        let mut out = Vec::new();
        for v in ctx.velocity_vars() {
            let Some(x) = v.integral().and_then(|d| ctx.displacement_rms(&d)) else {
                continue;
            };
            for abar in HYSTERESIS_A {
                let a = round3(abar / x);
                for r in HYSTERESIS_RATIO {
                    let b = round3(r * a);
                    let law = StateLaw::BoucWen { a, b, nu: 1.0 };
                    out.extend(state_variant(ctx, &v, law, ("a", a)));
                }
            }
        }
        out
    }
}

/// Dahl friction (presliding joints): `dahl(x', κ)`, a friction state that follows the
/// displacement over the presliding distance `1/κ` and saturates at ±1 beyond it; `κ·X` scanned
/// over 1..100 (X the displacement RMS).
#[derive(Debug, Clone, Copy)]
pub struct DahlFriction;
impl Effect for DahlFriction {
    fn name(&self) -> String {
        "dahl-friction".into()
    }
    fn description(&self) -> String {
        "Dahl friction dahl(x', kappa): z' = kappa (x' - |x'| z), presliding distance 1/kappa scanned over 1..100 % of the displacement RMS".into()
    }
    fn variants(&self, ctx: &EffectContext<'_>) -> Vec<Variant> {
        let mut out = Vec::new();
        for v in ctx.velocity_vars() {
            let Some(x) = v.integral().and_then(|d| ctx.displacement_rms(&d)) else {
                continue;
            };
            for kx in [1.0, 3.0, 10.0, 30.0, 100.0] {
                let kappa = round3(kx / x);
                out.extend(state_variant(
                    ctx,
                    &v,
                    StateLaw::Dahl { kappa },
                    ("kappa", kappa),
                ));
            }
        }
        out
    }
}
