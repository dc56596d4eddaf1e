//! `tfs refit`: add named physical effects to a model one by one (or let the diagnosis loop add
//! the top significant effect round after round until none remains), refit by equation error on
//! the records, keep the history, and print the error ladder.

use std::path::PathBuf;

use anyhow::{Context, Result};
use serde_json::json;
use tfs::diagnose::ladder_table;
use tfs::report::RefineReport;

use tfs::records::{measured_columns, read_model};

use super::{DataArgs, ModelOffsets, offsets_for_model, print_json, read_records};

/// Arguments of `tfs refit`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model (tfs-model/1 JSON).
    #[arg(long)]
    pub model: PathBuf,
    /// An effect to add (catalogue name, e.g. dry-friction, quadratic-damping, cubic-damping,
    /// stiffness-x^3, offset, maxwell, input-delay, input-filter, stop; `name@dof` for one
    /// DOF of a chain; `tfs diagnose` lists them all). Repeat to add several.
    #[arg(long = "add", required_unless_present = "until_clean")]
    pub add: Vec<String>,
    /// After the --add effects, run the diagnosis loop: each round adds the effect `tfs
    /// diagnose` names (the same decision), until it names none (at most N rounds, default 5).
    #[arg(long, value_name = "N", num_args = 0..=1, default_missing_value = "5")]
    pub until_clean: Option<usize>,
    /// CSV records with the model's displacement and input columns.
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Where to write the refitted model.
    #[arg(long)]
    pub out: PathBuf,
    /// Write the error ladder (R-MSE per step, log scale) and the force–displacement loop
    /// (before and after) as SVG and PNG into this directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Print the ladder and the model as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Print more: the loop's notes per round and why each stop was re-scanned (the default
    /// is the rounds, the model, the error ladder and its verdict).
    #[arg(short, long)]
    pub verbose: bool,
    /// DC offsets of the DOF and input channels: `auto` (default) does what `tfs identify` did
    /// for this model (its trace says so), `remove` subtracts each record's mean, `keep` uses
    /// the records as they are.
    #[arg(long, value_enum, default_value_t = ModelOffsets::Auto)]
    pub offsets: ModelOffsets,
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

/// Runs `tfs refit`.
pub fn run(args: Args) -> Result<()> {
    let inputs: Vec<&std::path::Path> = std::iter::once(&args.model)
        .chain(&args.data)
        .chain(&args.validate)
        .map(PathBuf::as_path)
        .collect();
    super::prepare_output(&args.out, &inputs, "--out")?;
    super::columns::refuse_repeated("--add", &args.add)?;
    if let Some(dir) = &args.plots {
        super::paths::check_plots_for(dir, &args.model, &args.data, Some(&args.out))?;
    }
    tfs::records::refuse_repeated(&inputs[1..])?;
    let model = read_model(&args.model)?;
    let required = measured_columns(&model);
    let mut records = super::columns::read_model_records(
        &args.data,
        &args.model,
        &model,
        &required,
        &args.data_args,
    )?;
    let offsets_report = offsets_for_model(&mut records, &model, &required, args.offsets.into())?;
    let mut held_out = Vec::new();
    if args.refine && !args.validate.is_empty() {
        held_out = read_records(&args.validate, &required, &args.data_args)?;
        offsets_for_model(&mut held_out, &model, &required, args.offsets.into())?;
    }
    let start = model.clone();
    let req = tfs::refit::RefitRequest {
        add: args.add.clone(),
        until_clean: args.until_clean,
        refine: args.refine,
        held_out,
    };
    let refitted = super::with_spinner("adding the effects and refitting", || {
        tfs::refit::refit_with(&model, &records, &req, &offsets_report)
    })?;
    let rounds = refitted.rounds;
    let stops = refitted.stops;
    let (model, ladder, warnings) = (refitted.model, refitted.ladder, refitted.warnings);
    let refine_report = refitted.refine;
    super::write_model(&model, &args.out, "--out")?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    if !args.json
        && let Some(note) = super::state_offsets_note(&model, &offsets_report, &records)
    {
        eprintln!("note: {note}");
    }
    if let Some(dir) = &args.plots {
        let chart = tfs::plot::BarChart {
            title: "Error ladder: geometric-mean R-MSE of the records after each step".into(),
            x_label: "step".into(),
            y_label: "R-MSE (dimensionless, log scale)".into(),
            labels: ladder.iter().map(|s| s.step.clone()).collect(),
            values: ladder.iter().map(|s| s.geo_mean_r_mse).collect(),
            log_y: true,
            color: None,
        };
        tfs::plot::Figure::from(chart)
            .save(&dir.join("ladder"))
            .with_context(|| format!("--plots {}", dir.display()))?;
        super::plots::loop_figures(dir, &[("before", &start), ("after", &model)], &records[0])
            .with_context(|| format!("--plots {}", dir.display()))?;
    }
    if args.json {
        print_json(&json!({
            "out": args.out.display().to_string(),
            "ladder": ladder,
            "model": model.to_json_value()?,
            "offsets": offsets_report.to_json(),
            "refine": refine_report.as_ref().map(RefineReport::to_json),
            "rounds": rounds,
            "stops": stops,
            "warnings": warnings,
        }))?;
    } else {
        for r in &rounds {
            match &r.added {
                Some(name) => println!("round {}: added {name} ({})", r.round, r.verdict),
                None => println!("round {}: {}; the loop stops", r.round, r.verdict),
            }
            if args.verbose {
                println!("  decision: {}", r.reason);
            }
            if let Some(note) = r.note.as_ref().filter(|_| args.verbose) {
                println!("  {note}");
            }
        }
        if args.until_clean.is_some() && rounds.last().is_some_and(|r| r.added.is_some()) {
            println!(
                "the loop stopped after {} rounds with effects still significant; run it again to continue",
                rounds.len()
            );
        }
        for s in &stops {
            if args.verbose {
                println!("stop {} -> {}: {}", s.from, s.to, s.why);
            } else {
                println!(
                    "stop {} -> {} (re-scanned by T-F-S; -v says why)",
                    s.from, s.to
                );
            }
        }
        println!("{}", model.equation_string());
        print!("{}", ladder_table(&ladder));
        println!("{}", tfs::report::ladder_verdict(&ladder).sentence);
        for line in refine_report.iter().flat_map(RefineReport::lines) {
            println!("{line}");
        }
        println!("wrote {}", args.out.display());
    }
    Ok(())
}
