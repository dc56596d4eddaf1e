//! Turning a model file or a truth spec into a simulable 1-DOF system with its wells.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use tfs::basin::WellInfo;
use tfs::dynamics::SecondOrderSystem;
use tfs::library::{CompiledModel, Model};
use tfs::origami::{CellSystem, KreslingCell, KreslingParams, Truth};

/// A 1-DOF system (model or truth) with its potential wells.
pub struct Sdof {
    /// What it is, for messages and JSON.
    pub label: String,
    /// The dynamics (autonomous runs pass zero inputs).
    pub system: Box<dyn SecondOrderSystem + Send>,
    /// Equilibria, wells and energy.
    pub wells: WellInfo,
}

/// A 1-DOF model file as a system; its restoring terms must be functions of the displacement only.
pub fn model_sdof(path: &Path, model: &Model, search: (f64, f64)) -> Result<Sdof> {
    if model.dofs.len() != 1 {
        bail!(
            "{}: the model has {} DOFs ({}); basin and med need a 1-DOF model",
            path.display(),
            model.dofs.len(),
            model.dofs.join(", ")
        );
    }
    let dof = model.dofs[0].clone();
    let restoring = model
        .restoring(&dof)
        .with_context(|| format!("{}: restoring force of '{dof}'", path.display()))?;
    let r2 = restoring.clone();
    let wells = WellInfo::from_force(
        move |x| restoring.force(x),
        move |x| r2.potential(x),
        search,
        1.0,
    )
    .with_context(|| format!("{}: equilibria of the model on {search:?}", path.display()))?;
    let compiled: CompiledModel = model.compile()?;
    Ok(Sdof {
        label: path.display().to_string(),
        system: Box::new(compiled),
        wells,
    })
}

/// A truth spec: `kresling` / `kresling:surrogate` (the paper's polynomial surrogate of the truss
/// force) or `kresling:truss` (the truss force with its folded stop), with the default §3.1 cell.
pub fn truth_sdof(spec: &str, search: (f64, f64)) -> Result<Sdof> {
    let (kind, variant) = spec.split_once(':').unwrap_or((spec, "surrogate"));
    if kind != "kresling" {
        bail!(
            "--truth '{spec}': unknown truth; use kresling, kresling:surrogate or kresling:truss"
        );
    }
    let truth = match variant {
        "surrogate" => Truth::Surrogate,
        "truss" => Truth::Truss,
        other => bail!("--truth '{spec}': unknown variant '{other}'; use surrogate or truss"),
    };
    let cell = Arc::new(KreslingCell::new(KreslingParams::default())?);
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
