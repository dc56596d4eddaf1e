//! `tfs basin`: basin-of-attraction map of a 1-DOF model, optionally against a truth.

use std::path::PathBuf;

use anyhow::{Context, Result};
use serde_json::json;
use tfs::basin::{BasinConfig, BasinMap, Label, basin_sdof, compare};

use tfs::records::read_model;
use tfs::sdof::{Sdof, default_search, model_sdof, truth_sdof};

use super::{parse_grid, parse_range, print_json, progress};

/// Arguments of `tfs basin`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model (tfs-model/1 JSON, 1 DOF).
    #[arg(long)]
    pub model: PathBuf,
    /// Grid size NxM (x0 nodes × v0 nodes).
    #[arg(long, default_value = "200x200")]
    pub grid: String,
    /// Initial-displacement range A:B.
    #[arg(long, default_value = "0:2", allow_hyphen_values = true)]
    pub x: String,
    /// Initial-velocity range A:B.
    #[arg(long, default_value = "-3:3", allow_hyphen_values = true)]
    pub v: String,
    /// Truth to compare with: kresling, kresling:surrogate or kresling:truss.
    #[arg(long)]
    pub truth: Option<String>,
    /// Fixed RK4 step of the unforced runs.
    #[arg(long, default_value_t = 0.01)]
    pub dt: f64,
    /// Time cap; starts not settled by then are labelled unsettled.
    #[arg(long, default_value_t = 100.0)]
    pub t_max: f64,
    /// Range searched for equilibria A:B (default: the --x range widened by half its width).
    #[arg(long, allow_hyphen_values = true)]
    pub search: Option<String>,
    /// Output image (PNG; an SVG is written beside it).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Runs `tfs basin`.
pub fn run(args: Args) -> Result<()> {
    if let Some(out) = &args.out {
        super::prepare_output(out, &[args.model.as_path()], "--out")?;
    }
    let (nx, ny) = parse_grid(&args.grid)?;
    let x_range = parse_range(&args.x, "--x")?;
    let v_range = parse_range(&args.v, "--v")?;
    let search = match &args.search {
        Some(s) => parse_range(s, "--search")?,
        None => default_search(x_range),
    };
    let model = read_model(&args.model)?;
    let sdof = model_sdof(&args.model.display().to_string(), &model, search)?;
    let mut cfg = BasinConfig::new(nx, ny, x_range, v_range);
    cfg.dt = args.dt;
    cfg.t_max = args.t_max;
    cfg.validate().context("basin settings")?;
    let map = run_map(&sdof, &cfg, "model")?;
    let mut out = json!({
        "model": args.model.display().to_string(),
        "grid": [nx, ny],
        "x_range": [x_range.0, x_range.1],
        "v_range": [v_range.0, v_range.1],
        "stable": sdof.wells.stable(),
        "unstable": sdof.wells.unstable(),
        "shares": map.shares,
        "unsettled": map.unsettled_count,
        "diverged": map.diverged_count,
        "seconds": map.seconds,
    });
    let mut disagree = None;
    if let Some(spec) = &args.truth {
        let truth = truth_sdof(spec, search)?;
        let tmap = run_map(&truth, &cfg, "truth")?;
        let cmp = compare(&map, &tmap)?;
        out["boa_error"] = json!(cmp.error);
        out["truth"] = json!({"spec": spec, "label": truth.label, "stable": truth.wells.stable(),
            "shares": tmap.shares, "seconds": tmap.seconds});
        out["seconds"] = json!(map.seconds + tmap.seconds);
        disagree = Some(cmp.disagree);
    }
    if let Some(path) = &args.out {
        let files = super::plots::basin_figure(
            &map,
            &format!("Basins of attraction: {}", args.model.display()),
            disagree.as_deref(),
            path,
        )?;
        out["files"] = json!(files);
    }
    if args.json {
        print_json(&out)?;
    } else {
        println!(
            "stable states: {:?}; unstable: {:?}",
            sdof.wells.stable(),
            sdof.wells.unstable()
        );
        for (k, s) in map.shares.iter().enumerate() {
            println!(
                "basin of S{} (x = {:.4}): {:.2}%",
                k + 1,
                sdof.wells.stable()[k],
                100.0 * s
            );
        }
        println!(
            "unsettled: {}, diverged: {}, time: {:.2} s",
            map.unsettled_count, map.diverged_count, map.seconds
        );
        if let Some(e) = out.get("boa_error") {
            println!(
                "BOA error vs {}: {:.3}%",
                args.truth.as_deref().unwrap_or(""),
                100.0 * e.as_f64().unwrap_or(f64::NAN)
            );
        }
        if let Some(f) = out.get("files") {
            println!("written: {f}");
        }
    }
    Ok(())
}

/// Computes a basin map with a progress bar on a terminal.
pub fn run_map(sdof: &Sdof, cfg: &BasinConfig, what: &str) -> Result<BasinMap> {
    let pb = progress(cfg.ny as u64, what);
    let tick = |_row: usize| pb.inc(1);
    let map = basin_sdof(&*sdof.system, &sdof.wells, cfg, Some(&tick))
        .with_context(|| format!("basin map of the {what}"))?;
    pb.finish_and_clear();
    Ok(map)
}

/// Label index for plots: stable state k → k, unsettled → n, diverged → n + 1.
pub fn label_index(l: Label, n_states: usize) -> u8 {
    match l {
        Label::State(k) => k as u8,
        Label::Unsettled => n_states as u8,
        Label::Diverged => n_states as u8 + 1,
    }
}
