//! `tfs compare`: simulate a model under each record's measured input and score it (R-MSE of the
//! paper's Appendix B, and the RMS error in the record's own units).

use std::path::PathBuf;

use anyhow::{Context, Result};
use serde_json::json;
use tfs::compare::score_with;
use tfs::plot::{Figure, LineChart, Series};
use tfs::records::{measured_columns, read_model};

use super::{DataArgs, ModelOffsets, offsets_for_model, print_json};

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
    /// Print more: the offsets and the definitions of the scores (the default is the table).
    #[arg(short, long)]
    pub verbose: bool,
    /// DC offsets of the DOF and input channels: `auto` (default) does what `tfs identify` did
    /// for this model (its trace says so), `remove` subtracts each record's mean, `keep` uses
    /// the records as they are.
    #[arg(long, value_enum, default_value_t = ModelOffsets::Auto)]
    pub offsets: ModelOffsets,
    /// Also score every record by predictions over pieces of this many samples, each started
    /// from the measured state (default: only where the input's noise decides the free run,
    /// with a length chosen from the model). Give two models the same value to compare them.
    #[arg(long, value_name = "SAMPLES")]
    pub horizon: Option<usize>,
    #[command(flatten)]
    pub data_args: DataArgs,
}

/// Runs `tfs compare`.
pub fn run(args: Args) -> Result<()> {
    let model = read_model(&args.model)?;
    // Columns that `tfs diagnose`/`refit` added as effects (delayed or filtered inputs) are
    // computed from the record, not read from it.
    let required = measured_columns(&model);
    let mut records = super::columns::read_model_records(
        &args.data,
        &args.model,
        &model,
        &required,
        &args.data_args,
    )?;
    let offsets_report = offsets_for_model(&mut records, &model, &required, args.offsets.into())?;
    let figure_names = match &args.plots {
        Some(dir) => super::paths::record_figures(dir, &args.model, &args.data, &model.dofs)?,
        None => Vec::new(),
    };
    let mut files = Vec::new();
    let pb = super::progress(records.len() as u64, "simulating");
    for (k, (path, rec)) in args.data.iter().zip(&records).enumerate() {
        pb.inc(1);
        let scored = score_with(&model, rec, args.horizon)?;
        if let Some(dir) = &args.plots {
            plot_record(
                dir,
                (path, &figure_names[k]),
                rec,
                &model.dofs,
                &scored.trajectory,
            )?;
        }
        files.push(scored.to_json());
    }
    pb.finish_and_clear();
    if args.json {
        print_json(&json!({
            "model": args.model.display().to_string(),
            "files": files,
            "offsets": offsets_report.to_json(),
            "r_mse_definition": tfs::compare::R_MSE_DEFINITION,
            "r_mse_mean_square_definition": tfs::compare::R_MSE_MEAN_SQUARE_DEFINITION,
        }))?;
    } else {
        if args.verbose {
            println!(
                "offsets: {} ({})",
                offsets_report.mode.name(),
                offsets_report.why
            );
        }
        if let Some(note) = super::state_offsets_note(&model, &offsets_report, &records) {
            println!("note: {note}");
        }
        println!(
            "{:<40} {:>12} {:>14} {:>14} {:>14}",
            "file", "R-MSE", "R-MSE (App. B)", "RMS error", "input-noise spread"
        );
        for f in &files {
            for d in f["dofs"].as_array().into_iter().flatten() {
                println!(
                    "{:<40} {:>12.4e} {:>14.4e} {:>14.4e} {:>14}  ({})",
                    f["path"].as_str().unwrap_or(""),
                    d["r_mse"].as_f64().unwrap_or(f64::NAN),
                    d["r_mse_mean_square"].as_f64().unwrap_or(f64::NAN),
                    d["rms_error"].as_f64().unwrap_or(f64::NAN),
                    d["input_noise_spread"]
                        .as_f64()
                        .map_or("—".into(), |v| format!("{v:.4e}")),
                    d["dof"].as_str().unwrap_or("")
                );
            }
            let path = f["path"].as_str().unwrap_or("");
            let sh = &f["short_horizon"];
            let pieces = match (
                sh["samples"].as_u64(),
                sh["seconds"].as_f64(),
                sh["r_mse"].as_f64(),
            ) {
                (Some(h), Some(secs), Some(r)) => Some(format!(
                    "over pieces of {h} samples ({secs:.4} s), each from the measured state: R-MSE {r:.4e}"
                )),
                _ => None,
            };
            let noise = f["error_is_input_noise"].as_bool() == Some(true);
            let diverges = f["run_diverges"].as_bool() == Some(true);
            let why = if noise {
                Some(
                    "most of this error is the measured input's own noise (a fresh draw of it moves the simulation about as far)",
                )
            } else if diverges {
                Some(
                    "the run parts from itself (run again from a start one displacement-noise standard deviation away, a start the record cannot tell apart, it ends about as far from this run as the record is)",
                )
            } else {
                None
            };
            match (why, pieces) {
                (Some(w), Some(p)) => {
                    println!("  {path}: {w}, so the free run cannot rank models; {p}")
                }
                (Some(w), None) => println!("  {path}: {w}: it cannot rank models"),
                (None, Some(p)) => println!("  {path}: {p}"),
                (None, None) => {}
            }
        }
        if args.verbose {
            println!(
                "(R-MSE: {}; App. B: {})",
                tfs::compare::R_MSE_DEFINITION,
                tfs::compare::R_MSE_MEAN_SQUARE_DEFINITION
            );
            println!(
                "(RMS error and spread in the record's units; the spread is how far a fresh draw of the input's estimated noise moves the simulation)"
            );
        } else {
            println!(
                "(R-MSE: mean squared error over the measured variance; -v for every definition)"
            );
        }
    }
    Ok(())
}

/// Writes the measured-vs-model time history of every DOF of one record (SVG and PNG).
fn plot_record(
    dir: &std::path::Path,
    (path, name): (&std::path::Path, &str),
    rec: &tfs::data::Record,
    dofs: &[String],
    traj: &tfs::dynamics::Trajectory,
) -> Result<()> {
    for (i, dof) in dofs.iter().enumerate() {
        let measured = rec.column(dof).context("column vanished")?;
        let stem = dir.join(format!("{name}-{dof}"));
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
    Ok(())
}
