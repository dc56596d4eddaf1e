//! `tfs med`: minimum-energy deployment of a bistable 1-DOF model, beside the quasi-static barrier.

use std::path::PathBuf;

use anyhow::{Result, anyhow, bail};
use serde_json::json;
use tfs::basin::{BasinConfig, BasinError, Med, WellInfo, med_sdof};
use tfs::dynamics::SecondOrderSystem;

use super::basin::run_map;
use tfs::records::read_model;
use tfs::sdof::{check_med_states, default_search, model_sdof, truth_sdof};

use super::chain_basin::{DEFAULT_DX, chain_map, med as chain_med, report_med};
use super::{parse_grid, parse_range, print_json};

/// Arguments of `tfs med`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model (tfs-model/1 JSON with at least two stable states: one DOF, or a chain `x1`,
    /// `x2`, …).
    #[arg(long, required_unless_present = "truth", conflicts_with = "truth")]
    pub model: Option<PathBuf>,
    /// Compute the MED of a truth instead of a model: kresling, kresling:surrogate or
    /// kresling:truss.
    #[arg(long)]
    pub truth: Option<String>,
    /// Grid NxM of the basin map the search starts from.
    #[arg(long, default_value = "200x200")]
    pub grid: String,
    /// Initial-displacement range A:B of the search [default: 0:2; for a chain the shift Δx of
    /// every displacement from S1, -1.2:1].
    #[arg(long, allow_hyphen_values = true)]
    pub x: Option<String>,
    /// A chain: the range of every cell's height searched for equilibria A:B [default: -0.05:2.2].
    #[arg(long, allow_hyphen_values = true)]
    pub search: Option<String>,
    /// Initial-velocity range A:B of the search.
    #[arg(long, default_value = "-3:3", allow_hyphen_values = true)]
    pub v: String,
    /// Index (1-based) of the starting stable state S1.
    #[arg(long, default_value_t = 1)]
    pub from: usize,
    /// Index (1-based) of the target stable state S2.
    #[arg(long, default_value_t = 2)]
    pub to: usize,
    /// Fixed RK4 step of the basin map's unforced runs (s); a step too long for the model is
    /// refused.
    #[arg(long, default_value_t = 0.01)]
    pub dt: f64,
    /// Time cap of the basin map's runs (s); starts not settled by then are labelled unsettled.
    #[arg(long, default_value_t = 100.0)]
    pub t_max: f64,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Runs `tfs med`.
pub fn run(args: Args) -> Result<()> {
    let (nx, ny) = parse_grid(&args.grid)?;
    let v_range = parse_range(&args.v, "--v")?;
    if let Some(path) = &args.model {
        let model = read_model(path)?;
        if model.dofs.len() > 1 {
            let dx = parse_range(args.x.as_deref().unwrap_or(DEFAULT_DX), "--x")?;
            let label = path.display().to_string();
            let mut cfg = BasinConfig::new(nx, ny, dx, v_range);
            (cfg.dt, cfg.t_max) = (args.dt, args.t_max);
            let c = chain_map(&label, &model, args.search.as_deref(), cfg)?;
            let m = chain_med(&c, args.from, args.to)
                .map_err(|e| anyhow!("{label}: minimum-energy deployment: {e:#}"))?;
            return report_med(&c, &m, args.from, args.to, args.json);
        }
    }
    if args.search.is_some() {
        bail!("--search: for a chain model only (a 1-DOF search range follows --x)");
    }
    let x_range = parse_range(args.x.as_deref().unwrap_or("0:2"), "--x")?;
    let search = default_search(x_range);
    let (sdof, compiled, what) = match (&args.model, &args.truth) {
        (Some(path), _) => {
            let model = read_model(path)?;
            (
                model_sdof(&path.display().to_string(), &model, search)?,
                Some(model.compile()?),
                path.display().to_string(),
            )
        }
        (None, Some(spec)) => (truth_sdof(spec, search)?, None, spec.clone()),
        (None, None) => bail!("give --model FILE or --truth SPEC"),
    };
    check_med_states(&sdof, &what, search, args.from, args.to)?;
    let mut cfg = BasinConfig::new(nx, ny, x_range, v_range);
    (cfg.dt, cfg.t_max) = (args.dt, args.t_max);
    let (from, to) = (args.from - 1, args.to - 1);
    // A model runs as its concrete compiled form (its batched evaluation inlined into the SIMD
    // blocks), a truth as the boxed system; the search is the same.
    let med = match &compiled {
        Some(c) => med_of(c, &sdof.wells, &cfg, from, to, "model"),
        None => med_of(&*sdof.system, &sdof.wells, &cfg, from, to, "truth"),
    }
    .map_err(|e| match e.downcast_ref::<BasinError>() {
        // The library numbers states from 0; the flags and the output from 1.
        Some(BasinError::NoBoundary { .. }) => anyhow!(
            "{what}: no basin boundary between S{} and S{} on --x {} --v {} (--grid {}); widen \
             the ranges so the boundary lies inside them, or refine the grid",
            args.from,
            args.to,
            args.x.as_deref().unwrap_or("0:2"),
            args.v,
            args.grid
        ),
        _ => e,
    })?;
    if args.json {
        print_json(&json!({
            "system": what,
            "from": sdof.wells.stable()[from],
            "to": sdof.wells.stable()[to],
            "x0": med.x0, "v0": med.v0, "energy": med.energy,
            "kinetic": med.kinetic, "potential": med.potential,
            "quasi_static_barrier": med.quasi_static_barrier,
        }))?;
    } else {
        println!(
            "MED from S{} (x = {:.4}) to S{} (x = {:.4}): E_in = {:.5} at x0 = {:.4}, v0 = {:.4}",
            args.from,
            sdof.wells.stable()[from],
            args.to,
            sdof.wells.stable()[to],
            med.energy,
            med.x0,
            med.v0
        );
        println!(
            "  kinetic {:.5} + potential {:.5}; quasi-static barrier {:.5}",
            med.kinetic, med.potential, med.quasi_static_barrier
        );
    }
    Ok(())
}

/// The basin map and the MED search on it (`label`, "model" or "truth", names the map in
/// messages).
fn med_of<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &WellInfo,
    cfg: &BasinConfig,
    from: usize,
    to: usize,
    label: &str,
) -> Result<Med> {
    let map = run_map(sys, wells, cfg, label)?;
    Ok(med_sdof(sys, wells, &map, cfg, from, to)?)
}
