//! What the judge simulates for a candidate: its own equation, the partner equations of a
//! coupling, and — for an effect whose parameter `refit` chooses by simulation — a short list of
//! its variants.
//!
//! The equation error scores every variant of an effect and keeps the one with the lowest
//! held-out residual. For most effects that is also the model `refit --add` returns. Not for
//! a stop: the smoothing that makes the equation error usable spreads a contact's force over the
//! samples around it, so the residual's best position can lie well inside the true one, and
//! `refit` chooses the position among those with the lowest residual by how well the model
//! simulates the records ([`crate::effects::Effect::parameter_by_simulation`]). The judge then
//! judges what `refit` will return: the variants with the [`SHORTLIST`] lowest held-out residuals
//! are each simulated, and the one that predicts the held-out data best speaks for the effect.
//! Its significance is still the equation error's (the tests over blocks are corrected over every
//! variant scanned, so choosing among a few of them adds no test).

use tfs_library::{Model, Term};

use crate::Result;
use crate::design::Design;
use crate::design::{
    Cv, FoldEquation, compress_blocks, cross_validate, design, full_fit, partner_columns,
};
use crate::effects::{EffectColumn, Variant};
use crate::explain::{DofSetup, Raw, Scored, score_variant};
use crate::judge::{Choice, Heldout};
use crate::prepare::{DiagnoseOptions, Layout, RecordStates};
use crate::stats::bootstrap_interval;

/// How many variants, lowest held-out residual first, the judge simulates for an effect whose
/// parameter is chosen by simulation.
pub(crate) const SHORTLIST: usize = 3;

/// A variant beside the best one by equation error, with the coefficient of its main column in
/// its full-data fit and that coefficient's block-bootstrap interval (what the report shows when
/// the judge chooses it).
pub(crate) struct Alternative {
    /// The variant scored.
    pub scored: Scored,
    /// The main column's coefficient.
    pub coef: f64,
    /// Its 95 % block-bootstrap interval.
    pub interval: [f64; 2],
}

/// The variants of `variants` other than `chosen`, scored on the equation of DOF `idx` with the
/// terms `terms`, the [`SHORTLIST`]` − 1` with the lowest held-out residual first (ties in the
/// catalogue's order), each with its main coefficient and interval.
pub(crate) fn alternatives(
    states: &[RecordStates],
    layout: &Layout,
    idx: usize,
    terms: &[Term],
    (variants, chosen): (&[Variant], &Variant),
    opts: &DiagnoseOptions,
) -> Result<Vec<Alternative>> {
    use rayon::prelude::*;
    let mut scored: Vec<Scored> = variants
        .par_iter()
        .filter(|v| *v != chosen)
        .map(|v| score_variant(states, layout, idx, terms, v).map(Scored::lean))
        .collect::<Result<_>>()?;
    scored.retain(|s| s.cv_rss.is_finite());
    scored.sort_by(|a, b| a.cv_rss.total_cmp(&b.cv_rss));
    scored.truncate(SHORTLIST.saturating_sub(1));
    scored
        .into_iter()
        .map(|s| {
            let fit = full_fit(&s.blocks)?;
            let (coef, interval) = main_coefficient(&s, &fit, opts)?;
            Ok(Alternative {
                scored: s,
                coef,
                interval,
            })
        })
        .collect()
}

/// The partner equations of a candidate (DOF `idx`, variant scored as `s`) whose variant acts
/// on a coupling: per partner DOF, the start equation with the same variant and its
/// cross-validation — a coupling force acts on both masses, and `refit` puts it into both
/// equations, so the judge simulates both. A partner whose design cannot be made is left as it
/// is.
pub(crate) fn partner_equations(
    model: &Model,
    (idx, s): (usize, &Scored),
    states: &[RecordStates],
    layout: &Layout,
) -> Vec<(usize, Vec<EffectColumn>, Cv)> {
    let mut out = Vec::new();
    for (pi, cols) in partner_columns(model, &model.dofs[idx], &s.variant) {
        let cv = design(states, pi, &cols)
            .and_then(|d| compress_blocks(&d, layout))
            .and_then(|b| cross_validate(&b, layout));
        if let Ok(cv) = cv {
            out.push((pi, cols, cv));
        }
    }
    out
}

/// The equations the judge simulates for a candidate (DOF `idx`, variant scored as `s`): its
/// own, then its partners' ([`partner_equations`]); anchored on the model's own coefficients
/// when [`crate::design::anchored`] says so.
pub(crate) fn fold_equations<'a>(
    model: &Model,
    setups: &'a [DofSetup],
    (idx, s): (usize, &'a Scored),
    partners: &'a [(usize, Vec<EffectColumn>, Cv)],
) -> Vec<FoldEquation<'a>> {
    let anchored = crate::design::anchored(model);
    let anchor = |i: usize| setups[i].anchor(anchored);
    let mut eqs = vec![FoldEquation {
        idx,
        cols: &s.cols,
        cv: &s.cv,
        anchor: anchor(idx),
    }];
    eqs.extend(partners.iter().map(|(i, cols, cv)| FoldEquation {
        idx: *i,
        cols,
        cv,
        anchor: anchor(*i),
    }));
    eqs
}

/// The judge's held-out error of the candidate `raw` under `choice` (piece length `horizon`):
/// of its best variant by equation error, or, when it has [`Raw::alternatives`], of whichever of
/// them predicts the held-out data best (a failed simulation counts as worst; the first of
/// equals). Returns the error, and the alternative when one of them was chosen.
pub(crate) fn heldout<'a>(
    model: &Model,
    setups: &[DofSetup],
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
    (choice, horizon): (&Choice, usize),
    raw: &'a Raw,
) -> (Option<Heldout>, Option<&'a Alternative>) {
    let judge = |s: &Scored| {
        let partners = partner_equations(model, (raw.dof_idx, s), states, layout);
        let eqs = fold_equations(model, setups, (raw.dof_idx, s), &partners);
        crate::judge::heldout_error(choice, model, &eqs, states, layout, opts, horizon)
    };
    let mut best = (judge(&raw.scored), None);
    for a in &raw.alternatives {
        let h = judge(&a.scored);
        let lower = match (&h, &best.0) {
            (Some(a), Some(b)) => a.mean < b.mean,
            (Some(_), None) => true,
            (None, _) => false,
        };
        if lower {
            best = (h, Some(a));
        }
    }
    best
}

impl Scored {
    /// The same without its design (a matrix of the usable rows of every record per column):
    /// what is read after a variant is scored — the columns, blocks, cross-validation — is
    /// small, and a scan keeps many scored variants (the shortlist of a stop's positions, every
    /// effect's best until the ranking).
    pub(crate) fn lean(self) -> Self {
        Self {
            design: Design::empty(),
            ..self
        }
    }
}

/// The coefficient of the main effect column of `s` in its full-data fit `coef` and its block
/// bootstrap interval (NaN when the variant has no main column).
pub(crate) fn main_coefficient(
    s: &Scored,
    coef: &[f64],
    opts: &DiagnoseOptions,
) -> Result<(f64, [f64; 2])> {
    Ok(match s.main {
        Some(m) => (
            coef[m],
            bootstrap_interval(&s.blocks, m, opts.bootstrap, opts.seed)?,
        ),
        None => (f64::NAN, [f64::NAN, f64::NAN]),
    })
}
