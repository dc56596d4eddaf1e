//! `tfs compare`: simulate a model under each record's measured input and score it (R-MSE of the
//! paper's Appendix B, and the RMS error in the record's own units).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use serde_json::json;
use tfs::dynamics::{rms_error, rmse_ratio};
use tfs::plot::{Figure, LineChart, Series};

use super::{
    DataArgs, Offsets, measured_columns, offsets_for_model, print_json, read_model, read_records,
};

/// Arguments of `tfs compare`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model (tfs-model/1 JSON).
    #[arg(long)]
    pub model: PathBuf,
    /// Held-out CSV records with the model's displacement and input columns.
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Write measured-vs-model time histories (SVG and PNG) into this directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Print the scores as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// DC offsets of the DOF and input channels: `auto` (default) does what `tfs identify` did
    /// for this model (its trace says so), `remove` subtracts each record's mean, `keep` uses
    /// the records as they are.
    #[arg(long, value_enum, default_value_t = Offsets::Auto)]
    pub offsets: Offsets,
    #[command(flatten)]
    pub data_args: DataArgs,
}

/// Runs `tfs compare`.
pub fn run(args: Args) -> Result<()> {
    let model = read_model(&args.model)?;
    // Columns that `tfs diagnose`/`refit` added as effects (delayed or filtered inputs, Maxwell
    // elements) are computed from the record, not read from it.
    let state_dependent = tfs::diagnose::effects::computed_columns(&model)
        .iter()
        .any(|c| !c.from_input());
    let required = measured_columns(&model);
    let mut records = read_records(&args.data, &required, &args.data_args)?;
    let offsets_report = offsets_for_model(&mut records, &model, &required, args.offsets)?;
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("--plots {}: cannot create the directory", dir.display()))?;
    }
    let mut files = Vec::new();
    for (path, rec) in args.data.iter().zip(&records) {
        // The same simulation as `diagnose` and `refit` score with: plain models go straight to
        // tfs-dynamics; computed input columns are added to the record, and each Maxwell element
        // is integrated as an extra state driven by the simulated velocity.
        let traj = tfs::diagnose::simulate(&model, rec)
            .with_context(|| format!("{}: simulating the model", path.display()))?;
        let mut dofs = Vec::new();
        let mut sum = 0.0;
        // How far a fresh draw of the input's own noise moves the simulation: an error no larger
        // than that is the measured input's doing, not the model's.
        // A Maxwell column is a state, not an input that could be perturbed: no spread then.
        let spread = if state_dependent {
            None
        } else {
            tfs::diagnose::augment_record(&model, rec, &Default::default())
                .ok()
                .and_then(|aug| {
                    tfs::refine::input_noise_spread(&model, &aug, &Default::default()).ok()
                })
                .flatten()
        };
        let mut errors = Vec::new();
        for (i, dof) in model.dofs.iter().enumerate() {
            let measured = rec.column(dof).context("column vanished")?;
            let r = rmse_ratio(measured, &traj.x[i])
                .with_context(|| format!("{}: column '{dof}'", path.display()))?;
            let rms = rms_error(measured, &traj.x[i])?;
            sum += r;
            errors.push(rms);
            let s = spread.as_ref().map(|s| s[i]).filter(|v| v.is_finite());
            dofs.push(json!({"dof": dof, "r_mse": r, "rms_error": rms, "input_noise_spread": s}));
            if let Some(dir) = &args.plots {
                let stem = dir.join(format!(
                    "{}-{dof}",
                    path.file_stem()
                        .and_then(|s| s.to_str())
                        .unwrap_or("record")
                ));
                let chart = LineChart {
                    title: format!("{}: measured vs model ({dof})", path.display()),
                    x_label: "t (s)".into(),
                    y_label: format!("{dof} (record units)"),
                    series: vec![
                        Series::line(
                            "measured",
                            rec.t()
                                .iter()
                                .copied()
                                .zip(measured.iter().copied())
                                .collect(),
                        ),
                        Series::dashed(
                            "model",
                            traj.t
                                .iter()
                                .copied()
                                .zip(traj.x[i].iter().copied())
                                .collect(),
                        ),
                    ],
                    ..LineChart::default()
                };
                Figure::from(chart).save(&stem)?;
            }
        }
        if model.dofs.is_empty() {
            bail!("{}: the model has no DOFs", args.model.display());
        }
        let r_mse = sum / model.dofs.len() as f64;
        let dominated = spread.as_ref().map(|s| {
            tfs::refine::noise_dominated(
                s,
                &errors,
                &tfs::refine::displacement_noise_var(&model, rec),
            )
        });
        files.push(
            json!({"path": path.display().to_string(), "r_mse": r_mse, "dofs": dofs,
            "error_is_input_noise": dominated}),
        );
    }
    if args.json {
        print_json(&json!({
            "model": args.model.display().to_string(),
            "files": files,
            "offsets": offsets_report,
        }))?;
    } else {
        println!(
            "offsets: {} ({})",
            offsets_report["mode"].as_str().unwrap_or("?"),
            offsets_report["why"].as_str().unwrap_or("")
        );
        println!(
            "{:<40} {:>12} {:>14} {:>14}",
            "file", "R-MSE", "RMS error", "input-noise spread"
        );
        for f in &files {
            for d in f["dofs"].as_array().into_iter().flatten() {
                println!(
                    "{:<40} {:>12.4e} {:>14.4e} {:>14}  ({})",
                    f["path"].as_str().unwrap_or(""),
                    d["r_mse"].as_f64().unwrap_or(f64::NAN),
                    d["rms_error"].as_f64().unwrap_or(f64::NAN),
                    d["input_noise_spread"]
                        .as_f64()
                        .map_or("—".into(), |v| format!("{v:.4e}")),
                    d["dof"].as_str().unwrap_or("")
                );
            }
            if f["error_is_input_noise"].as_bool() == Some(true) {
                println!(
                    "  {}: most of this error is the measured input's own noise (a fresh draw of it moves the simulation about as far): it cannot rank models",
                    f["path"].as_str().unwrap_or("")
                );
            }
        }
        println!(
            "(RMS error and spread in the record's units; the spread is how far a fresh draw of the input's estimated noise moves the simulation)"
        );
        if state_dependent {
            println!(
                "(no spread: the model's Maxwell column is a simulated state, not an input a noise draw could perturb)"
            );
        }
    }
    Ok(())
}
