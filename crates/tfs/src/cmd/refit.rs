//! `tfs refit`: add named physical effects to a model one by one, refit by equation error on the
//! records, keep the history, and print the error ladder.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use serde_json::json;
use tfs::diagnose::{add_effect, error_ladder, ladder_table};

use super::{
    DataArgs, Offsets, measured_columns, offsets_for_model, print_json, read_model, read_records,
};

/// Arguments of `tfs refit`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model (tfs-model/1 JSON).
    #[arg(long)]
    pub model: PathBuf,
    /// An effect to add (catalogue name, e.g. dry-friction, quadratic-damping, cubic-damping,
    /// stiffness-x^3, offset, maxwell, input-delay, input-filter, stop; `name@dof` for one
    /// DOF of a chain; `tfs diagnose` lists them all). Repeat to add several.
    #[arg(long = "add", required = true)]
    pub add: Vec<String>,
    /// CSV records with the model's displacement and input columns.
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Where to write the refitted model.
    #[arg(long)]
    pub out: PathBuf,
    /// Write the error ladder (R-MSE per step, log scale) as SVG and PNG into this directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Print the ladder and the model as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// DC offsets of the DOF and input channels: `auto` (default) does what `tfs identify` did
    /// for this model (its trace says so), `remove` subtracts each record's mean, `keep` uses
    /// the records as they are.
    #[arg(long, value_enum, default_value_t = Offsets::Auto)]
    pub offsets: Offsets,
    /// After adding the effects, re-estimate the coefficients of the resulting structure by
    /// simulation error (Levenberg–Marquardt with multiple shooting) on the records.
    #[arg(long)]
    pub refine: bool,
    /// Held-out records used with --refine: whichever fit (equation- or simulation-error)
    /// predicts them better is kept.
    #[arg(long = "validate", requires = "refine")]
    pub validate: Vec<PathBuf>,
    #[command(flatten)]
    pub data_args: DataArgs,
}

/// Appends the model's input-derived computed columns (delayed or filtered inputs) to each
/// record so the model can be simulated under them. State-dependent ones (Maxwell) cannot be
/// precomputed from measurements: refinement refuses them with a clear error.
fn with_computed_inputs(
    model: &tfs::library::Model,
    records: &mut [tfs::data::Record],
) -> Result<()> {
    for c in tfs::diagnose::effects::computed_columns(model) {
        if !c.from_input() {
            bail!(
                "--refine: the model has the state-dependent column '{}' (a hidden Maxwell \
                 element); simulation-error refinement supports input-derived columns only — \
                 refine before adding it, or drop --refine",
                c.name()
            );
        }
        for r in records.iter_mut() {
            let v = c
                .compute(r, r.dt())
                .with_context(|| format!("{}: computing '{}'", r.source(), c.name()))?;
            r.set_column(c.name(), v)
                .with_context(|| format!("{}: adding column '{}'", r.source(), c.name()))?;
        }
    }
    Ok(())
}

/// What the error ladder says against the steps just taken: an added effect under which some
/// record's simulation fails, or one that makes the mean R-MSE worse than the step before it
/// (the records do not support it; `tfs diagnose` tests that before anything is added).
fn ladder_warnings(ladder: &[tfs::diagnose::LadderStep]) -> Vec<String> {
    let mut out = Vec::new();
    for pair in ladder.windows(2) {
        let (before, after) = (&pair[0], &pair[1]);
        if after.incomplete() {
            out.push(format!(
                "after '{}', the simulation fails on {} of {} record(s) ({}); the model is not \
                 usable on them. `tfs diagnose` says which effects the records support",
                after.step,
                after.failed.len(),
                after.failed.len() + after.r_mse.len(),
                after.failed[0]
            ));
        } else if !before.incomplete()
            && before.mean_r_mse.is_finite()
            && after.mean_r_mse > before.mean_r_mse
        {
            out.push(format!(
                "'{}' made the mean R-MSE worse ({:.4e} -> {:.4e}): the records do not support \
                 it. `tfs diagnose` says which effects they do",
                after.step, before.mean_r_mse, after.mean_r_mse
            ));
        }
    }
    out
}

/// Runs `tfs refit`.
pub fn run(args: Args) -> Result<()> {
    let mut model = read_model(&args.model)?;
    let required = measured_columns(&model);
    let mut records = read_records(&args.data, &required, &args.data_args)?;
    let offsets_report = offsets_for_model(&mut records, &model, &required, args.offsets)?;
    if args.add.is_empty() {
        bail!("--add: give at least one effect name");
    }
    for name in &args.add {
        model = add_effect(&model, name, &records).with_context(|| format!("--add {name}"))?;
    }
    let mut refine_report = serde_json::Value::Null;
    if args.refine {
        let mut train = records.clone();
        with_computed_inputs(&model, &mut train)?;
        let refined = tfs::refine::refine(&model, &train, &tfs::refine::RefineOptions::default())
            .context("--refine")?;
        refine_report = json!({
            "initial_cost": refined.initial_cost,
            "final_cost": refined.final_cost,
            "iterations": refined.iterations,
            "converged": refined.converged,
            "message": refined.message,
            "per_record": refined.per_record,
            "noise_dominated": refined.noise_dominated,
        });
        if args.validate.is_empty() {
            model = refined.model;
        } else {
            let mut held_out = read_records(&args.validate, &required, &args.data_args)?;
            offsets_for_model(&mut held_out, &model, &required, args.offsets)?;
            with_computed_inputs(&model, &mut held_out)?;
            let (chosen, scores) =
                tfs::refine::choose_by_validation(&model, &refined.model, &held_out)
                    .context("--validate")?;
            refine_report["validation"] = json!({
                "equation_error_fit": scores.eq_score,
                "simulation_error_fit": scores.refined_score,
                "chose_refined": scores.chose_refined,
                "per_record": scores.per_record,
                "noise_dominated": scores.noise_dominated,
            });
            model = chosen;
        }
    }
    // The refitted model was fitted on records treated this way: say so in its trace, so that
    // `compare` and `diagnose` treat them the same.
    if let Some(obj) = model.trace.as_object_mut() {
        obj.insert("offsets".into(), offsets_report.clone());
    } else {
        model.trace = json!({"offsets": offsets_report.clone()});
    }
    model
        .write_path(&args.out)
        .with_context(|| format!("--out {}", args.out.display()))?;
    let ladder = error_ladder(&model);
    let warnings = ladder_warnings(&ladder);
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    if let Some(dir) = &args.plots {
        let chart = tfs::plot::BarChart {
            title: "Error ladder: mean R-MSE of the records after each step".into(),
            x_label: "step".into(),
            y_label: "R-MSE (log scale)".into(),
            labels: ladder.iter().map(|s| s.step.clone()).collect(),
            values: ladder.iter().map(|s| s.mean_r_mse).collect(),
            log_y: true,
            color: None,
        };
        tfs::plot::Figure::from(chart)
            .save(&dir.join("ladder"))
            .with_context(|| format!("--plots {}", dir.display()))?;
    }
    if args.json {
        print_json(&json!({
            "out": args.out.display().to_string(),
            "ladder": ladder,
            "model": model.to_json_value()?,
            "offsets": offsets_report,
            "refine": refine_report,
            "warnings": warnings,
        }))?;
    } else {
        println!("{}", model.equation_string());
        print!("{}", ladder_table(&ladder));
        if !refine_report.is_null() {
            println!("refinement by simulation error: {refine_report}");
        }
        println!("wrote {}", args.out.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use tfs::diagnose::LadderStep;
    use tfs::library::RecordScore;

    fn step(name: &str, scores: &[f64], failed: &[&str]) -> LadderStep {
        let r_mse: Vec<RecordScore> = scores
            .iter()
            .map(|&v| RecordScore {
                record: "r".into(),
                r_mse: v,
            })
            .collect();
        LadderStep {
            step: name.into(),
            added: Vec::new(),
            mean_r_mse: if r_mse.is_empty() {
                f64::NAN
            } else {
                scores.iter().sum::<f64>() / scores.len() as f64
            },
            r_mse,
            failed: failed.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// An added effect that makes the error worse, or under which a record's simulation fails,
    /// is warned about; one that lowers it is not.
    #[test]
    fn warns_when_an_added_effect_does_not_help() {
        let good = [step("start", &[0.02], &[]), step("add a", &[0.01], &[])];
        assert!(ladder_warnings(&good).is_empty());
        let worse = [step("start", &[0.01], &[]), step("add a", &[0.02], &[])];
        let w = ladder_warnings(&worse);
        assert_eq!(w.len(), 1);
        assert!(w[0].contains("'add a' made the mean R-MSE worse"), "{w:?}");
        let broke = [
            step("start", &[0.01, 0.01], &[]),
            step("add a", &[0.01], &["r1: blew up"]),
        ];
        let w = ladder_warnings(&broke);
        assert_eq!(w.len(), 1);
        assert!(
            w[0].contains("fails on 1 of 2") && w[0].contains("blew up"),
            "{w:?}"
        );
    }
}
