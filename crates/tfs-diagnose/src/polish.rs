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
//!
//! An input effect (a delayed or low-pass filtered input) is refined the same way in its one
//! parameter: the scan's delays are whole samples, a true delay rarely is.

use tfs_library::{Factor, StateLaw, Term};

use crate::Result;
use crate::effects::{ComputedColumn, EffectColumn, Variant, input_variant, round3};
use crate::prepare::{Layout, RecordStates};
use crate::score::{Scored, score_variant};

/// Scores every variant of one effect on the equation of DOF `idx` (terms `base`) and returns
/// the best (lowest held-out RSS), an internal state's parameters then refined locally by the
/// same criterion ([`polish`]). The variants are scored side by side (an effect with
/// many variants was otherwise the scan's serial tail), the choice the same as in order
/// ([`crate::stats::first_lowest`]).
pub(crate) fn best_variant(
    states: &[RecordStates],
    layout: &Layout,
    idx: usize,
    base: &[Term],
    variants: &[Variant],
) -> Result<Option<Scored>> {
    Ok(best_variant_with(states, layout, idx, base, variants, false)?.0)
}

/// [`best_variant`], and with `keep` every variant's score too ([`Scored::lean`], in the order
/// of `variants`; empty without `keep`): what the shortlist of an effect whose parameter is
/// chosen by simulation is taken from ([`crate::score::alternatives`]), so no variant is scored
/// twice.
pub(crate) fn best_variant_with(
    states: &[RecordStates],
    layout: &Layout,
    idx: usize,
    base: &[Term],
    variants: &[Variant],
    keep: bool,
) -> Result<(Option<Scored>, Vec<Scored>)> {
    let score = |v: &Variant| score_variant(states, layout, idx, base, v);
    let (best, scanned) = if keep {
        use rayon::prelude::*;
        let all: Vec<Result<Scored>> = variants.par_iter().map(score).collect();
        // The first error in order, as `first_lowest` returns it.
        let mut all = all.into_iter().collect::<Result<Vec<Scored>>>()?;
        let keys: Vec<f64> = all.iter().map(|s| s.cv_rss).collect();
        let best = first_lowest_index(&keys).map(|k| {
            let lean = all[k].lean_copy();
            std::mem::replace(&mut all[k], lean)
        });
        let scanned = all.into_iter().map(Scored::lean).collect();
        (best, scanned)
    } else {
        let best = crate::stats::first_lowest(variants, &score, |s: &Scored| s.cv_rss)?;
        (best, Vec::new())
    };
    let Some(best) = best else {
        return Ok((None, scanned));
    };
    // Every variant scored as fitting nothing (each a stop pulling into its contact,
    // `crate::score::score_variant`): the effect has no best variant.
    if best.cv_rss == f64::INFINITY {
        return Ok((None, scanned));
    }
    let dt = states.first().map_or(0.0, |s| s.record.dt());
    Ok((Some(polish(best, variants, &score, dt)?), scanned))
}

/// The index [`crate::stats::first_lowest`] chooses among items with these keys: the first,
/// unless a later one's key is strictly lower; among the later ones the first of the lowest, a
/// number lower than NaN there (but not against the first). `None` for no keys.
fn first_lowest_index(keys: &[f64]) -> Option<usize> {
    let (&first, rest) = keys.split_first()?;
    let mut tail: Option<usize> = None;
    for (k, &b) in rest.iter().enumerate() {
        let replaces = |a: f64| b < a || (a.is_nan() && !b.is_nan());
        if tail.is_none_or(|t| replaces(rest[t])) {
            tail = Some(k);
        }
    }
    Some(match tail {
        Some(t) if rest[t] < first => t + 1,
        _ => 0,
    })
}

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
/// scoring a variant; other variants are returned as they are. A Maxwell element's τ is not
/// taken below the sampling interval `dt`: a relaxation faster than the sampling is not resolved
/// by the data, and there the state is a dashpot (with a little stiffness) standing in for
/// `linear-damping` or the model's own `x'`.
pub(crate) fn polish(
    best: Scored,
    variants: &[Variant],
    score: &dyn Fn(&Variant) -> Result<Scored>,
    dt: f64,
) -> Result<Scored> {
    if let Some(input) = InputFamily::of(&best.variant) {
        return polish_input(best, &input, variants, score);
    }
    let Some((_, law)) = state_of(&best.variant) else {
        return Ok(best);
    };
    let Some(u) = to_coords(&law) else {
        return Ok(best);
    };
    // Half a grid step: the grids scan factors of about three (ln 3 / 2); b/a in steps of 1/2.
    let step: Vec<f64> = (0..u.len())
        .map(|k| if k == 0 { 0.55 } else { 0.25 })
        .collect();
    let Some(mut bounds) = scan_bounds(&best.variant, variants, &step) else {
        return Ok(best);
    };
    if matches!(law, StateLaw::Maxwell { .. }) && dt > 0.0 {
        bounds[0].0 = bounds[0].0.max(dt.ln());
    }
    let make = |v: &Variant, u: &[f64]| from_coords(&law, u).and_then(|l| with_law(v, l));
    pattern_search(best, variants, u, step, &bounds, &make, score)
}

/// The pattern search of the module docs from `best` at coordinates `u`: each coordinate moved
/// by ± its step within `bounds`, `make` building the variant at new coordinates. A variant
/// scored before — one of the `scanned` variants `best` was chosen from, or a point the search
/// already tried (a step back to where it came from) — is counted as an evaluation but not
/// scored again: its held-out RSS is not below the best's (the best is the lowest of everything
/// scored so far, and a point is taken only when strictly lower), so it would not be taken.
fn pattern_search(
    best: Scored,
    scanned: &[Variant],
    mut u: Vec<f64>,
    mut step: Vec<f64>,
    bounds: &[(f64, f64)],
    make: &dyn Fn(&Variant, &[f64]) -> Option<Variant>,
    score: &dyn Fn(&Variant) -> Result<Scored>,
) -> Result<Scored> {
    let mut best = best;
    let mut evals = 0;
    let mut seen: Vec<Variant> = scanned.to_vec();
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
                    let Some(v) = make(&best.variant, &trial) else {
                        continue;
                    };
                    evals += 1;
                    if seen.contains(&v) {
                        continue;
                    }
                    let s = score(&v)?;
                    seen.push(v);
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

/// An input effect's variant: every replacement a computed column of the same kind with the same
/// parameter (`"delay"` or `"tau"`), nothing added — or, for an input the model lost, every
/// added column such a computed column, nothing replaced (`added`).
struct InputFamily {
    inputs: Vec<String>,
    parameter: &'static str,
    value: f64,
    added: bool,
}

impl InputFamily {
    fn of(v: &Variant) -> Option<Self> {
        let added = v.replace.is_empty();
        let cols: Vec<&EffectColumn> = if added {
            v.add.iter().collect()
        } else if v.add.is_empty() {
            v.replace.iter().map(|(_, c)| c).collect()
        } else {
            return None;
        };
        let mut inputs = Vec::new();
        let mut kind: Option<(&'static str, f64)> = None;
        for c in cols {
            let this = match c.computed.as_ref()? {
                ComputedColumn::Delayed { input, delay } => {
                    inputs.push(input.clone());
                    ("delay", *delay)
                }
                ComputedColumn::Lowpass { input, tau } => {
                    inputs.push(input.clone());
                    ("tau", *tau)
                }
            };
            if kind.is_some_and(|k| k != this) {
                return None;
            }
            kind = Some(this);
        }
        let (parameter, value) = kind?;
        (value > 0.0 && value.is_finite()).then_some(Self {
            inputs,
            parameter,
            value,
            added,
        })
    }
}

/// Refines the delay or time constant of an input effect between the scanned values, on a log
/// scale: the first step is half the wider log-gap to the scanned neighbours of the best value,
/// and the search stays within the scanned range widened by that step. Values are rounded to 3 significant digits, as the
/// computed column's name writes them.
fn polish_input(
    best: Scored,
    family: &InputFamily,
    variants: &[Variant],
    score: &dyn Fn(&Variant) -> Result<Scored>,
) -> Result<Scored> {
    let mut scanned: Vec<f64> = variants
        .iter()
        .filter_map(InputFamily::of)
        .filter(|f| {
            f.parameter == family.parameter && f.inputs == family.inputs && f.added == family.added
        })
        .map(|f| f.value.ln())
        .collect();
    scanned.sort_by(f64::total_cmp);
    scanned.dedup();
    let u0 = family.value.ln();
    let below = scanned.iter().rev().find(|&&x| x < u0).map(|x| u0 - x);
    let above = scanned.iter().find(|&&x| x > u0).map(|x| x - u0);
    let step = match (below, above) {
        (None, None) => return Ok(best),
        (a, b) => 0.5 * a.unwrap_or(0.0).max(b.unwrap_or(0.0)),
    };
    let (lo, hi) = (scanned[0] - step, scanned[scanned.len() - 1] + step);
    let inputs = family.inputs.clone();
    let (parameter, added) = (family.parameter, family.added);
    let make = move |_: &Variant, u: &[f64]| {
        let value = round3(u[0].exp());
        (value > 0.0).then(|| input_variant(&inputs, parameter, value, added))
    };
    pattern_search(
        best,
        variants,
        vec![u0],
        vec![step],
        &[(lo, hi)],
        &make,
        score,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::{Cv, Design};

    /// The index chosen from the keys is the item `first_lowest` returns, over ties, NaN first,
    /// NaN later, infinities and one item.
    #[test]
    fn the_first_lowest_index_is_first_lowest_s_choice() {
        let nan = f64::NAN;
        let cases: Vec<Vec<f64>> = vec![
            vec![3.0, 1.0, 2.0, 1.0],
            vec![1.0, 1.0, 0.5, 0.5],
            vec![nan, 2.0, 1.0],
            vec![2.0, nan, 3.0, nan, 1.5],
            vec![nan, nan, 4.0, 4.0],
            vec![f64::INFINITY, f64::INFINITY, 7.0],
            vec![5.0],
            vec![0.5, 0.7, nan],
        ];
        for keys in cases {
            let items: Vec<usize> = (0..keys.len()).collect();
            let score = |&i: &usize| -> std::result::Result<usize, ()> { Ok(i) };
            let want = crate::stats::first_lowest(&items, &score, |&i| keys[i]).unwrap();
            assert_eq!(first_lowest_index(&keys), want, "{keys:?}");
        }
        assert_eq!(first_lowest_index(&[]), None);
    }

    /// The pattern search never scores a variant twice, nor one of the scanned variants it
    /// started from, and still ends at the lowest point of a bowl in `ln τ` (a step back to
    /// where it came from is counted but not scored).
    #[test]
    fn the_pattern_search_scores_each_variant_once() {
        let maxwell = |tau: f64| {
            let term = Term::new(vec![Factor::State(
                tfs_library::Var::Vel("x".into()),
                StateLaw::Maxwell { tau },
            )]);
            Variant::adding(Some(("tau".into(), tau)), vec![EffectColumn::term(term)])
        };
        let target = 2.5f64.ln();
        let scored = std::sync::Mutex::new(Vec::<Variant>::new());
        let score = |v: &Variant| -> Result<Scored> {
            scored.lock().unwrap().push(v.clone());
            let tau = v.parameter.as_ref().unwrap().1;
            Ok(Scored {
                variant: v.clone(),
                cols: v.add.clone(),
                main: Some(0),
                blocks: Vec::new(),
                design: Design::empty(),
                cv: Cv {
                    coefs: Vec::new(),
                    heldout: Vec::new(),
                },
                cv_rss: (tau.ln() - target).powi(2),
            })
        };
        let grid: Vec<Variant> = [0.3, 1.0, 3.0, 10.0].into_iter().map(maxwell).collect();
        let best = score(&grid[2]).unwrap();
        scored.lock().unwrap().clear();
        let out = polish(best, &grid, &score, 0.01).unwrap();
        let scored = scored.into_inner().unwrap();
        for (i, v) in scored.iter().enumerate() {
            assert!(!grid.contains(v), "a scanned variant scored again: {v:?}");
            assert!(!scored[..i].contains(v), "scored twice: {v:?}");
        }
        assert!(!scored.is_empty());
        let tau = out.variant.parameter.unwrap().1;
        assert!((tau.ln() - target).abs() < 0.07, "ends at {tau}");
    }

    /// A stop whose fit pulls into its contact is refused by the scoring, so the stop effect has
    /// no best variant on data whose force past the stop pulls further out (a softening kink).
    #[test]
    fn a_pulling_stop_leaves_the_stop_effect_without_a_best_variant() {
        let (base, stop) = crate::score::tests::stop_above();
        let (states, layout) = crate::score::tests::oscillator(0.6);
        let best = best_variant(&states, &layout, 0, &base, std::slice::from_ref(&stop)).unwrap();
        assert!(best.is_none(), "the stop effect has no best variant");
        let (states, layout) = crate::score::tests::oscillator(-5.0);
        let best = best_variant(&states, &layout, 0, &base, std::slice::from_ref(&stop)).unwrap();
        assert!(
            best.is_some(),
            "a pushing stop is the effect's best variant"
        );
    }
}
