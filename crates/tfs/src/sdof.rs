//! Turning a model or a truth spec into a simulable 1-DOF system with its wells (for basins and
//! the minimum-energy deployment).

use std::sync::Arc;

use tfs_basin::WellInfo;
use tfs_dynamics::SecondOrderSystem;
use tfs_library::{CompiledModel, Model};
use tfs_origami::{CellSystem, KreslingCell, KreslingParams, Truth};

use crate::error::{Context, Result};
use crate::invalid;

/// A 1-DOF system (model or truth) with its potential wells.
pub struct Sdof {
    /// What it is, for messages and JSON.
    pub label: String,
    /// The dynamics (autonomous runs pass zero inputs).
    pub system: Box<dyn SecondOrderSystem + Send>,
    /// Equilibria, wells and energy.
    pub wells: WellInfo,
}

/// A 1-DOF model as a system (`label` names it in messages, e.g. its file); its restoring terms
/// must be functions of the displacement only.
pub fn model_sdof(label: &str, model: &Model, search: (f64, f64)) -> Result<Sdof> {
    if model.dofs.len() != 1 {
        invalid!(
            "{}: the model has {} DOFs ({}); basin and med need a 1-DOF model",
            label,
            model.dofs.len(),
            model.dofs.join(", ")
        );
    }
    let dof = model.dofs[0].clone();
    let restoring = model
        .restoring(&dof)
        .with_context(|| format!("{}: restoring force of '{dof}'", label))?;
    let r2 = restoring.clone();
    let wells = WellInfo::from_force(
        move |x| restoring.force(x),
        move |x| r2.potential(x),
        search,
        1.0,
    )
    .with_context(|| format!("{}: equilibria of the model on {search:?}", label))?;
    let compiled: CompiledModel = model.compile()?;
    Ok(Sdof {
        label: label.to_string(),
        system: Box::new(compiled),
        wells,
    })
}

/// A truth spec: `kresling` / `kresling:surrogate` (the paper's polynomial surrogate of the truss
/// force) or `kresling:truss` (the truss force with its folded stop), with the default §3.1 cell.
pub fn truth_sdof(spec: &str, search: (f64, f64)) -> Result<Sdof> {
    cell_sdof(spec, KreslingParams::default(), search)
}

/// A truth spec as [`truth_sdof`] reads it, for the Kresling cell of the given geometry.
pub fn cell_sdof(spec: &str, params: KreslingParams, search: (f64, f64)) -> Result<Sdof> {
    let (kind, variant) = spec.split_once(':').unwrap_or((spec, "surrogate"));
    if kind != "kresling" {
        invalid!(
            "--truth '{spec}': unknown truth; use kresling, kresling:surrogate or kresling:truss"
        );
    }
    let truth = match variant {
        "surrogate" => Truth::Surrogate,
        "truss" => Truth::Truss,
        other => invalid!("--truth '{spec}': unknown variant '{other}'; use surrogate or truss"),
    };
    let cell = Arc::new(KreslingCell::new(params)?);
    let sys = CellSystem::new(cell, truth)?;
    let m = sys.mass();
    let law = sys.force_law().clone();
    let law2 = law.clone();
    let wells = WellInfo::from_force(move |x| law.force(x), move |x| law2.potential(x), search, m)?;
    Ok(Sdof {
        label: format!("truth {}", sys.truth_name()),
        system: Box::new(sys),
        wells,
    })
}

/// The range searched for equilibria when none is given: the initial-displacement range widened
/// by half its width on each side.
pub fn default_search(x_range: (f64, f64)) -> (f64, f64) {
    let w = x_range.1 - x_range.0;
    (x_range.0 - 0.5 * w, x_range.1 + 0.5 * w)
}

/// Checks that `sdof` is bistable on `search` and that `from` and `to` (1-based) are two
/// different stable states of it, as the minimum-energy deployment needs; `what` names the system.
pub fn check_med_states(
    sdof: &Sdof,
    what: &str,
    search: (f64, f64),
    from: usize,
    to: usize,
) -> Result<()> {
    let n = sdof.wells.stable().len();
    if n < 2 {
        invalid!("{what}: {n} stable state(s) on {search:?}; MED needs a bistable system");
    }
    if from == 0 || to == 0 || from > n || to > n || from == to {
        invalid!("--from {from} --to {to}: give two different states between 1 and {n}");
    }
    Ok(())
}
