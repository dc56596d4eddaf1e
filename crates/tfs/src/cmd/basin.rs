//! `tfs basin`: basin-of-attraction map of a 1-DOF model, optionally against a truth.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Result, anyhow, bail};
use serde_json::json;
use tfs::basin::{
    BasinConfig, BasinError, BasinMap, Label, WellInfo, basin_sdof, compare, relabel_to_nearest,
    step_limit_sdof,
};
use tfs::dynamics::SecondOrderSystem;

use tfs::records::read_model;
use tfs::sdof::{default_search, model_sdof, truth_sdof};

use super::chain_basin::{DEFAULT_DX, chain_map, report_basin};
use super::{parse_grid, parse_range, print_json, progress};

/// Arguments of `tfs basin`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model (tfs-model/1 JSON): one DOF, or a chain (`x1`, `x2`, …; mapped on the slice
    /// x_i(0) = x_i(S1) + Δx, every velocity v0).
    #[arg(long)]
    pub model: PathBuf,
    /// Grid size NxM (x0 nodes × v0 nodes).
    #[arg(long, default_value = "200x200")]
    pub grid: String,
    /// Initial-displacement range A:B (the model's displacement unit) [default: 0:2; for a
    /// chain the shift Δx of every displacement from S1, -1.2:1].
    #[arg(long, allow_hyphen_values = true)]
    pub x: Option<String>,
    /// Initial-velocity range A:B (the model's displacement unit per second).
    #[arg(long, default_value = "-3:3", allow_hyphen_values = true)]
    pub v: String,
    /// Truth to compare with: kresling, kresling:surrogate or kresling:truss.
    #[arg(long)]
    pub truth: Option<String>,
    /// Fixed RK4 step of the unforced runs (s); a step too long for the model is refused.
    #[arg(long, default_value_t = 0.01)]
    pub dt: f64,
    /// Time cap (s); starts not settled by then are labelled unsettled.
    #[arg(long, default_value_t = 100.0)]
    pub t_max: f64,
    /// Range searched for equilibria A:B (default: the --x range widened by half its width; for
    /// a chain, the range of every cell's height, -0.05:2.2).
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
        let figures = super::paths::figure_files(out);
        super::paths::check_outputs(out, &figures, &[args.model.as_path()], "--out")?;
    }
    let (nx, ny) = parse_grid(&args.grid)?;
    let v_range = parse_range(&args.v, "--v")?;
    let model = read_model(&args.model)?;
    if model.dofs.len() > 1 {
        if args.truth.is_some() {
            bail!(
                "--truth: the truths are single Kresling cells; a chain model's map is not compared with one (drop --truth)"
            );
        }
        let dx = parse_range(args.x.as_deref().unwrap_or(DEFAULT_DX), "--x")?;
        let mut cfg = BasinConfig::new(nx, ny, dx, v_range);
        cfg.dt = args.dt;
        cfg.t_max = args.t_max;
        let label = args.model.display().to_string();
        let c = chain_map(&label, &model, args.search.as_deref(), cfg)?;
        return report_basin(
            &c,
            &format!("Basins of attraction: {label}"),
            args.out.as_deref(),
            args.json,
        );
    }
    let x_range = parse_range(args.x.as_deref().unwrap_or("0:2"), "--x")?;
    let search = match &args.search {
        Some(s) => parse_range(s, "--search")?,
        None => default_search(x_range),
    };
    let sdof = model_sdof(&args.model.display().to_string(), &model, search)?;
    // The concrete compiled model (not the boxed system): its batched evaluation is then
    // inlined into the SIMD blocks that integrate the starts.
    let compiled = model.compile()?;
    let mut cfg = BasinConfig::new(nx, ny, x_range, v_range);
    cfg.dt = args.dt;
    cfg.t_max = args.t_max;
    let map = run_map(&compiled, &sdof.wells, &cfg, "model")?;
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
        "integrated": map.integrated,
        "seconds": map.seconds,
    });
    let mut disagree = None;
    if let Some(spec) = &args.truth {
        let truth = truth_sdof(spec, search)?;
        let tmap = run_map(&*truth.system, &truth.wells, &cfg, "truth")?;
        // States are compared by index, which only means the same thing when both have the
        // same stable states; otherwise each model state counts as the truth state nearest it.
        let cmp = if map.states.len() == tmap.states.len() {
            compare(&map, &tmap)?
        } else {
            let (renamed, to) = relabel_to_nearest(&map, &tmap.states);
            let pairs: Vec<String> = to
                .iter()
                .enumerate()
                .map(|(k, t)| {
                    format!(
                        "model S{} (x = {:.4}) as truth S{} (x = {:.4})",
                        k + 1,
                        sdof.wells.stable()[k],
                        t + 1,
                        truth.wells.stable()[*t]
                    )
                })
                .collect();
            out["state_matching"] = json!(format!(
                "the model has {} stable state{} and the truth {}: each model state is counted as the truth state nearest it ({})",
                map.states.len(),
                if map.states.len() == 1 { "" } else { "s" },
                tmap.states.len(),
                pairs.join("; ")
            ));
            compare(&renamed, &tmap)?
        };
        out["boa_error"] = json!(cmp.error);
        out["truth"] = json!({"spec": spec, "label": truth.label, "stable": truth.wells.stable(),
            "shares": tmap.shares, "seconds": tmap.seconds});
        out["seconds"] = json!(map.seconds + tmap.seconds);
        disagree = Some(cmp.disagree);
    }
    let mut files = Vec::new();
    if let Some(path) = &args.out {
        files = super::plots::basin_figure(
            &map,
            &format!("Basins of attraction: {}", args.model.display()),
            disagree.as_deref(),
            path,
        )?;
        out["files"] = json!(files);
    }
    if args.json {
        return print_json(&out);
    }
    let xs = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.4}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    println!(
        "stable states x = {}; unstable x = {}",
        xs(sdof.wells.stable()),
        xs(sdof.wells.unstable())
    );
    for (k, s) in map.shares.iter().enumerate() {
        println!(
            "basin of S{} (x = {:.4}): {:.2} %",
            k + 1,
            sdof.wells.stable()[k],
            100.0 * s
        );
    }
    println!(
        "{} × {} starts, {} integrated ({:.1} %), the rest labelled from agreeing neighbours; {:.2} s",
        nx,
        ny,
        map.integrated,
        100.0 * map.integrated as f64 / (nx * ny) as f64,
        map.seconds
    );
    if map.unsettled_count + map.diverged_count > 0 {
        println!(
            "unsettled: {}, diverged: {} (a start is unsettled when it is not trapped in a well of the \
             search range {:.4}:{:.4} by --t-max {}: a longer --t-max or a wider --search may settle it)",
            map.unsettled_count, map.diverged_count, search.0, search.1, args.t_max
        );
    }
    if let Some(note) = out.get("state_matching").and_then(|n| n.as_str()) {
        println!("{note}");
    }
    if let Some(e) = out.get("boa_error").and_then(|e| e.as_f64()) {
        println!(
            "BOA error vs {}: {:.3} %",
            args.truth.as_deref().unwrap_or(""),
            100.0 * e
        );
    }
    if !files.is_empty() {
        println!("written: {}", files.join(", "));
    }
    Ok(())
}

/// The flag a basin setting comes from, for messages.
fn flag(name: &str) -> &str {
    match name {
        "dt" => "--dt",
        "t_max" => "--t-max",
        "nx/ny" => "--grid",
        "x_range" => "--x",
        "v_range" => "--v",
        other => other,
    }
}

/// A basin error with the library's parameter names replaced by the CLI's flags.
fn with_flags(e: BasinError, what: &str) -> anyhow::Error {
    match e {
        BasinError::InvalidParameter { name, reason } => {
            anyhow!("{} ({what} basin map): {reason}", flag(name))
        }
        BasinError::StepTooLong { .. } => anyhow!("--dt ({what} basin map): {e}"),
        other => anyhow!("basin map of the {what}: {other}"),
    }
}

/// Computes a basin map, after checking the step and the work it asks for; a progress bar
/// appears on a terminal when the map is still running after two seconds.
pub fn run_map<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &WellInfo,
    cfg: &BasinConfig,
    what: &str,
) -> Result<BasinMap> {
    cfg.validate().map_err(|e| with_flags(e, what))?;
    step_limit_sdof(sys, wells, cfg)
        .and_then(|l| l.check(cfg.dt))
        .map_err(|e| with_flags(e, what))?;
    let cells = cfg.nx * cfg.ny;
    let pb = progress(cells as u64, what);
    let visible = !pb.is_hidden();
    pb.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    let start = Instant::now();
    let revealed = std::sync::OnceLock::new();
    let tick = |done: usize| {
        if visible && start.elapsed() > Duration::from_secs(2) {
            revealed.get_or_init(|| pb.set_draw_target(indicatif::ProgressDrawTarget::stderr()));
        }
        pb.set_position(done as u64);
    };
    let map = basin_sdof(sys, wells, cfg, Some(&tick)).map_err(|e| with_flags(e, what))?;
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
