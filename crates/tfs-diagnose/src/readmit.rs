//! Re-admitting start-library terms that `identify` left out because the missing effect hid
//! them.
//!
//! A model identified without an effect its data hold can lose more than that effect: the
//! effect's unexplained force is a large residual, and next to it a small true term (the linear
//! damping beside a hidden input filter or a missing linear stiffness) is not distinguishable
//! from zero, so the fit drops it. Adding the missing effect to that sparse equation alone
//! leaves a model without the dropped term (an undamped oscillator), whose simulations are worse
//! than the start model's although its equation error is far lower. So, once an effect's best
//! variant is found, every term of the start library that the equation lacks (the library is in
//! the model's trace) is offered again, one at a time: the one that lowers the held-out equation
//! error the most is kept when the one-sided paired block tests of that drop (the differences
//! and the log-ratios, Bonferroni over the two) put it below `alpha`, and the search repeats
//! with it. Then the terms still open are offered together, once, under the same test: about an
//! operating point away from zero a restoring force that vanishes there needs two or more
//! powers at once (the library has no constant), and no one of them lowers the error alone.
//! When any term is kept, the effect's variants are scanned again on the equation with the kept
//! terms.
//!
//! The kept terms are structure, not effect: the effect is then tested, sized and judged
//! against the start equation *with* the same terms (the reference), so a term the start model
//! lacks never makes an unrelated effect look significant.

use tfs_library::{Factor, Model, Term, Var};

use crate::Result;
use crate::effects::Variant;
use crate::polish::best_variant_with;
use crate::prepare::{Layout, RecordStates};
use crate::score::{Scored, score_variant};
use crate::stats::paired_drop_p_value;

/// The terms of the start library of DOF `idx` that its equation lacks, in library order: the
/// library the model's identify trace says was offered for that DOF
/// ([`Model::offered_library`]), so a term backward elimination removed can come back. Empty
/// when the model carries no library (a model written by hand or by another tool) or a library
/// term does not parse.
pub(crate) fn left_out(model: &Model, idx: usize) -> Vec<Term> {
    let Some(library) = model
        .dofs
        .get(idx)
        .and_then(|dof| model.offered_library(dof))
    else {
        return Vec::new();
    };
    let held: Vec<&Term> = model.equations[idx].terms.iter().map(|t| &t.term).collect();
    let mut out: Vec<Term> = Vec::new();
    for text in &library {
        let Ok(term) = Term::parse(text, &model.dofs) else {
            return Vec::new();
        };
        if !held.contains(&&term) && !out.contains(&term) {
            out.push(term);
        }
    }
    out
}

/// What [`readmit`] found for one effect.
pub(crate) struct Readmitted {
    /// The effect's best variant on the equation with the kept terms.
    pub scored: Scored,
    /// The kept terms (empty: nothing re-admitted, `scored` is the input's).
    pub terms: Vec<Term>,
    /// The start equation with the kept terms and no effect: what the effect is tested against
    /// (`None` when nothing was kept).
    pub reference: Option<Scored>,
    /// Asked for with `keep`: every one of the effect's variants scored on the equation with
    /// the kept terms ([`Scored::lean`], in the variants' order; empty otherwise).
    pub scanned: Vec<Scored>,
}

/// True when `term` may be offered beside variant `v`: not already one of its columns, and not
/// a plain input the variant replaces by a computed copy (a delayed or filtered input takes the
/// input's place, it is never put beside it).
pub(crate) fn offerable(term: &Term, s: &Scored) -> bool {
    if s.cols.iter().any(|c| c.term == *term) {
        return false;
    }
    let sources: Vec<String> = s
        .cols
        .iter()
        .filter_map(|c| c.computed.as_ref().map(|k| k.source()))
        .collect();
    !term
        .factors()
        .iter()
        .any(|f| matches!(f, Factor::Pow(Var::Input(n), _) if sources.contains(n)))
}

/// The best variant of an effect with `variants` on the equation of DOF `idx` (terms `base`),
/// with the module's re-admission of the `left_out` library terms at level `alpha`; `None` when
/// no variant could be scored. With `keep`, every variant's score on the final equation is
/// returned too ([`Readmitted::scanned`]).
pub(crate) fn best_with_library(
    states: &[RecordStates],
    layout: &Layout,
    (idx, base): (usize, &[Term]),
    variants: &[Variant],
    left_out: &[Term],
    (alpha, keep): (f64, bool),
) -> Result<Option<Readmitted>> {
    let (best, scanned) = best_variant_with(states, layout, idx, base, variants, keep)?;
    let Some(best) = best else {
        return Ok(None);
    };
    let mut kept: Vec<Term> = Vec::new();
    let mut current = best;
    loop {
        let mut pick: Option<(Term, Scored)> = None;
        for t in left_out {
            if kept.contains(t) || !offerable(t, &current) {
                continue;
            }
            let mut terms = base.to_vec();
            terms.extend(kept.iter().cloned());
            terms.push(t.clone());
            let s = score_variant(states, layout, idx, &terms, &current.variant)?;
            let better = pick.as_ref().is_none_or(|(_, p)| s.cv_rss < p.cv_rss);
            if s.cv_rss < current.cv_rss && better {
                pick = Some((t.clone(), s));
            }
        }
        let Some((t, s)) = pick else { break };
        if paired_drop_p_value(&current.cv.heldout, &s.cv.heldout) >= alpha {
            break;
        }
        kept.push(t);
        current = s;
    }
    // The group step (module docs).
    let rest: Vec<Term> = left_out
        .iter()
        .filter(|t| !kept.contains(t) && offerable(t, &current))
        .cloned()
        .collect();
    if rest.len() >= 2 {
        let mut terms = base.to_vec();
        terms.extend(kept.iter().cloned());
        terms.extend(rest.iter().cloned());
        let s = score_variant(states, layout, idx, &terms, &current.variant)?;
        let p = paired_drop_p_value(&current.cv.heldout, &s.cv.heldout);
        if s.cv_rss < current.cv_rss && p < alpha {
            kept.extend(rest);
            current = s;
        }
    }
    if kept.is_empty() {
        return Ok(Some(Readmitted {
            scored: current,
            terms: kept,
            reference: None,
            scanned,
        }));
    }
    let mut terms = base.to_vec();
    terms.extend(kept.iter().cloned());
    let (rescanned, scanned) = best_variant_with(states, layout, idx, &terms, variants, keep)?;
    let scored = match rescanned {
        Some(s) if s.cv_rss <= current.cv_rss => s,
        _ => current,
    };
    let reference = score_variant(
        states,
        layout,
        idx,
        &terms,
        &Variant::adding(None, Vec::new()),
    )?;
    Ok(Some(Readmitted {
        scored,
        terms: kept,
        reference: Some(reference),
        scanned,
    }))
}
