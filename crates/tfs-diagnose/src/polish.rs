//! Local refinement of a memory effect's parameters after the scan.
//!
//! A scan on a coarse grid (a factor of three in time constants and scales) ranks effects, but a
//! grid point can sit far enough from the truth that a relative of the effect wins: a Bouc–Wen
//! loop with `b/a` between grid values fits the equation error no better than its `b = 0` member,
//! which is Dahl friction. So the best variant of an effect whose column is one internal state is
//! refined by a pattern search on the same held-out criterion: each parameter moved by ± a step
//! (positive scales on a log scale, starting at half a grid step; Bouc–Wen's `b` in units of
//! `a`, starting at a quarter), moves kept while they lower the held-out RSS, the step halved
//! when none does, at most [`MAX_EVALS`] evaluations. The search stays within the range the
//! effect's scan covered (plus half a step): a time constant far below the scan's shortest is a
//! different effect (a Maxwell element with τ → 0 is a plain damper).

use tfs_library::{Factor, StateLaw, Term};

use crate::Result;
use crate::effects::{EffectColumn, Variant};
use crate::explain::Scored;

/// Most variants a refinement scores.
pub const MAX_EVALS: usize = 12;

/// The variant with the state `law` in place of the single state column of `v`.
fn with_law(v: &Variant, law: StateLaw) -> Option<Variant> {
    let [col] = v.add.as_slice() else {
        return None;
    };
    let [Factor::State(drive, _)] = col.term.factors() else {
        return None;
    };
    let term = Term::new(vec![Factor::State(drive.clone(), law)]);
    let parameter = v
        .parameter
        .as_ref()
        .map(|(name, _)| (name.clone(), law.params()[0]));
    Some(Variant::adding(parameter, vec![EffectColumn::term(term)]))
}

/// The drive and law of `v`'s single state column, if it is one.
fn state_of(v: &Variant) -> Option<(&tfs_library::Var, StateLaw)> {
    match v.add.as_slice() {
        [col] if v.replace.is_empty() => match col.term.factors() {
            [Factor::State(drive, law)] => Some((drive, *law)),
            _ => None,
        },
        _ => None,
    }
}

/// Per coordinate, the range the scan covered: over the `variants` with the same drive and law
/// as `best`, widened by `pad[k]` on either side.
fn scan_bounds(best: &Variant, variants: &[Variant], pad: &[f64]) -> Option<Vec<(f64, f64)>> {
    let (drive, law) = state_of(best)?;
    let mut bounds: Vec<(f64, f64)> = pad
        .iter()
        .map(|_| (f64::INFINITY, f64::NEG_INFINITY))
        .collect();
    for v in variants {
        let Some((d, l)) = state_of(v) else { continue };
        if d != drive || l.name() != law.name() {
            continue;
        }
        let Some(u) = to_coords(&l) else { continue };
        for (b, x) in bounds.iter_mut().zip(u) {
            b.0 = b.0.min(x);
            b.1 = b.1.max(x);
        }
    }
    Some(
        bounds
            .into_iter()
            .zip(pad)
            .map(|((lo, hi), p)| (lo - p, hi + p))
            .collect(),
    )
}

/// Coordinates of the search for a law: `u` from the parameters and back (`None` when the law
/// is outside the search's domain, e.g. a Bouc–Wen `a ≤ 0`).
fn to_coords(law: &StateLaw) -> Option<Vec<f64>> {
    match *law {
        StateLaw::Maxwell { tau } => Some(vec![tau.ln()]),
        StateLaw::Dahl { kappa } => Some(vec![kappa.ln()]),
        StateLaw::BoucWen { a, b, .. } if a > 0.0 => Some(vec![a.ln(), b / a]),
        StateLaw::BoucWen { .. } => None,
    }
}

/// The law at coordinates `u`, its parameters rounded to 4 significant digits (readable terms;
/// a refinement by simulation error takes them further).
fn from_coords(law: &StateLaw, u: &[f64]) -> Option<StateLaw> {
    let r = |v: f64| {
        if v == 0.0 || !v.is_finite() {
            v
        } else {
            format!("{v:.3e}").parse().unwrap_or(v)
        }
    };
    let out = match *law {
        StateLaw::Maxwell { .. } => StateLaw::Maxwell { tau: r(u[0].exp()) },
        StateLaw::Dahl { .. } => StateLaw::Dahl {
            kappa: r(u[0].exp()),
        },
        StateLaw::BoucWen { nu, .. } => {
            let a = u[0].exp();
            StateLaw::BoucWen {
                a: r(a),
                b: r(u[1] * a),
                nu,
            }
        }
    };
    out.validate().ok().map(|()| out)
}

/// Refines `best`, the best of the scanned `variants` (see the module docs), with `score`
/// scoring a variant; other variants are returned as they are.
pub(crate) fn polish(
    best: Scored,
    variants: &[Variant],
    score: &dyn Fn(&Variant) -> Result<Scored>,
) -> Result<Scored> {
    let Some((_, law)) = state_of(&best.variant) else {
        return Ok(best);
    };
    let Some(mut u) = to_coords(&law) else {
        return Ok(best);
    };
    // Half a grid step: the grids scan factors of about three (ln 3 / 2); b/a in steps of 1/2.
    let mut step: Vec<f64> = (0..u.len())
        .map(|k| if k == 0 { 0.55 } else { 0.25 })
        .collect();
    let Some(bounds) = scan_bounds(&best.variant, variants, &step) else {
        return Ok(best);
    };
    let mut best = best;
    let mut evals = 0;
    for _level in 0..3 {
        loop {
            let mut improved = false;
            for k in 0..u.len() {
                for sign in [1.0, -1.0] {
                    if evals >= MAX_EVALS {
                        return Ok(best);
                    }
                    let mut trial = u.clone();
                    trial[k] += sign * step[k];
                    if !(bounds[k].0..=bounds[k].1).contains(&trial[k]) {
                        continue;
                    }
                    let Some(law) = from_coords(&law, &trial) else {
                        continue;
                    };
                    let Some(v) = with_law(&best.variant, law) else {
                        return Ok(best);
                    };
                    evals += 1;
                    let s = score(&v)?;
                    if s.cv_rss < best.cv_rss {
                        best = s;
                        u = trial;
                        improved = true;
                        break;
                    }
                }
            }
            if !improved {
                break;
            }
        }
        step.iter_mut().for_each(|s| *s *= 0.5);
    }
    Ok(best)
}
