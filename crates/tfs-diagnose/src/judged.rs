//! What the judge simulates for a candidate: its own equation, the partner equations of a
//! coupling, and — for an effect whose parameter `refit` chooses by simulation — each variant of
//! its shortlist ([`crate::score::alternatives`]), the one whose model predicts the held-out
//! data best speaking for the effect.

use tfs_library::Model;

use crate::design::{Cv, FoldEquation, compress_blocks, cross_validate, design, partner_columns};
use crate::effects::EffectColumn;
use crate::judge::{Choice, Heldout};
use crate::prepare::{DiagnoseOptions, Layout, RecordStates};
use crate::scan::{DofSetup, Raw};
use crate::score::Scored;

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
/// equals). Returns the error, and the alternative's index when one of them was chosen.
pub(crate) fn heldout(
    model: &Model,
    setups: &[DofSetup],
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
    (choice, horizon): (&Choice, usize),
    raw: &Raw,
) -> (Option<Heldout>, Option<usize>) {
    let judge = |s: &Scored| {
        let partners = partner_equations(model, (raw.dof_idx, s), states, layout);
        let eqs = fold_equations(model, setups, (raw.dof_idx, s), &partners);
        crate::judge::heldout_error(choice, model, &eqs, states, layout, opts, horizon)
    };
    let mut best = (judge(&raw.scored), None);
    for (k, a) in raw.alternatives.iter().enumerate() {
        let h = judge(&a.scored);
        let lower = match (&h, &best.0) {
            (Some(a), Some(b)) => a.mean < b.mean,
            (Some(_), None) => true,
            (None, _) => false,
        };
        if lower {
            best = (h, Some(k));
        }
    }
    best
}
