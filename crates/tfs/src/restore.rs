//! A restoring force that selection removed, put back when the records simulate better with it.
//!
//! T-F-S selects terms by their equation error in the frequency band the records excite, and
//! backward elimination removes terms that are not distinguishable from zero there. A structure
//! that sits about an operating point away from zero (a Kresling cell in its deployed well) and
//! is driven mostly above its own resonance shows its stiffness only weakly in that band: the
//! restoring force is a few per cent of the acceleration, and it lives in nearly collinear powers
//! of the coordinate. The selection can then keep no displacement term at all. Such a model has
//! no stiffness and no equilibria: simulated, it drifts away, although a restoring force from the
//! library would hold it — its simulations can be tens to hundreds of times worse.
//!
//! When that happens to a DOF of a T-F-S model with a data-chosen threshold, the library's
//! displacement terms of that DOF are fitted back beside the terms the model kept (the same
//! T-F-S stages, every term kept, no elimination), and the result replaces the DOF's equation
//! when the model then simulates every training record and each of them better than without
//! (free-run R-MSE, the score `tfs compare` prints). The equation error cannot decide this, the
//! simulation can; the trace says what was done and with which errors, and the support verdict
//! is the refitted equation's own (its terms one by one fail the term test, so it still says the
//! data do not pin them down).

use tfs_criteria::{Identified, IdentifySpec, identify_tfs};
use tfs_data::Record;
use tfs_library::Term;

use crate::error::Result;

/// The training records' free-run R-MSE of `model` (mean over its DOFs, on each DOF's
/// variance), `None` for a record it cannot simulate.
fn free_runs(model: &tfs_library::Model, records: &[Record]) -> Vec<Option<f64>> {
    records
        .iter()
        .map(|r| tfs_diagnose::r_mse(model, r).ok().filter(|v| v.is_finite()))
        .collect()
}

/// Does `after` simulate every record and each better than `before` (a record `before` cannot
/// simulate counts as improved)?
fn better_on_every_record(before: &[Option<f64>], after: &[Option<f64>]) -> bool {
    before.iter().zip(after).all(|(b, a)| match (b, a) {
        (_, None) => false,
        (None, Some(_)) => true,
        (Some(b), Some(a)) => a < b,
    })
}

/// Formats per-record errors for the trace.
fn errors(v: &[Option<f64>]) -> String {
    v.iter()
        .map(|e| e.map_or("fails".to_string(), |e| format!("{e:.4e}")))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Puts back the displacement terms of every DOF of `id` (identified on `records` with `spec`)
/// that kept none although its library offers some, when the records simulate better with
/// them (see the module documentation). Returns one line per DOF whose terms came back, for the
/// warnings; `id` is changed only then.
pub(crate) fn restore_displacement(
    id: &mut Identified,
    records: &[Record],
    spec: &IdentifySpec,
) -> Result<Vec<String>> {
    let offered = spec.libraries()?;
    let mut lost: Vec<usize> = Vec::new();
    let mut libs: Vec<String> = Vec::with_capacity(spec.dofs.len());
    for (i, dof) in spec.dofs.iter().enumerate() {
        let eq = id.model.equation(dof)?;
        let kept: Vec<&Term> = eq.terms.iter().map(|t| &t.term).collect();
        let offers = offered[i]
            .terms()
            .iter()
            .any(|t| t.involves_displacement_of(dof));
        let keeps = kept.iter().any(|t| t.involves_displacement_of(dof));
        let terms: Vec<String> = if offers && !keeps && !kept.is_empty() {
            lost.push(i);
            offered[i]
                .terms()
                .iter()
                .filter(|t| kept.contains(t) || t.involves_displacement_of(dof))
                .map(|t| t.to_string())
                .collect()
        } else if !kept.is_empty() {
            // Not spliced back: its kept terms are enough to run the pass.
            kept.iter().map(|t| t.to_string()).collect()
        } else {
            offered[i].names()
        };
        libs.push(terms.join(", "));
    }
    if lost.is_empty() {
        return Ok(Vec::new());
    }
    let mut again = spec.clone();
    again.dof_libraries = libs;
    again.tfs.fit.threshold = Some(0.0);
    again.tfs.uncertainty.elimination_rounds = 0;
    let Ok(back) = identify_tfs(records, &again) else {
        return Ok(Vec::new());
    };
    let mut candidate = id.model.clone();
    for &i in &lost {
        let dof = &spec.dofs[i];
        let (Some(a), Some(b)) = (
            candidate.equations.iter().position(|e| &e.dof == dof),
            back.model.equations.iter().position(|e| &e.dof == dof),
        ) else {
            return Ok(Vec::new());
        };
        candidate.equations[a] = back.model.equations[b].clone();
    }
    let before = free_runs(&id.model, records);
    let after = free_runs(&candidate, records);
    if !better_on_every_record(&before, &after) {
        return Ok(Vec::new());
    }
    let mut lines = Vec::new();
    for &i in &lost {
        let dof = &spec.dofs[i];
        let terms: Vec<String> = back
            .model
            .equation(dof)?
            .terms
            .iter()
            .filter(|t| t.term.involves_displacement_of(dof))
            .map(|t| t.term.to_string())
            .collect();
        let line = format!(
            "{dof}: no displacement (restoring-force) term survived selection, so the model had no stiffness and no equilibria; {} fitted back beside the kept terms (every term kept, no elimination), because the model simulates every training record better with them (free-run R-MSE {} without, {} with)",
            terms.join(", "),
            errors(&before),
            errors(&after)
        );
        let (Some(a), Some(b)) = (
            id.trace.dofs.iter().position(|d| &d.dof == dof),
            back.trace.dofs.iter().position(|d| &d.dof == dof),
        ) else {
            return Ok(Vec::new());
        };
        let mut trace = back.trace.dofs[b].clone();
        if trace.library.len() != offered[i].len() {
            trace.offered_library = Some(offered[i].names());
        }
        trace.settings.why.insert(0, line.clone());
        id.trace.dofs[a] = trace;
        lines.push(line);
    }
    id.model = candidate;
    Ok(lines)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A record the start model cannot simulate counts as improved; one the candidate cannot
    /// simulate, or any record it does not improve, rejects it.
    #[test]
    fn the_candidate_must_simulate_every_record_better() {
        let s = |v: &[f64]| v.iter().map(|x| Some(*x)).collect::<Vec<_>>();
        assert!(better_on_every_record(&s(&[1.0, 2.0]), &s(&[0.5, 1.0])));
        assert!(!better_on_every_record(&s(&[1.0, 2.0]), &s(&[0.5, 3.0])));
        assert!(better_on_every_record(&[None, Some(2.0)], &s(&[0.5, 1.0])));
        assert!(!better_on_every_record(&s(&[1.0, 2.0]), &[Some(0.5), None]));
    }
}
