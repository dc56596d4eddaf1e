//! `tfs identify`: records in, a sparse model (tfs-model/1 JSON) and the criteria trace out.

use std::path::PathBuf;

use anyhow::{Result, bail};
pub use tfs::identify::Method;
use tfs::identify::{Identification, IdentifyOptions, Plan, Tie, identify, plan};
use tfs::report::{OffsetsReport, RecordOffsets, RefineReport};

use super::trace_view::{print_summary, print_trace};
use super::{
    DataArgs, Offsets, prepare_output, print_json, read_records, records_from, with_spinner,
    write_model,
};

/// Arguments of `tfs identify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// CSV records (header `t`, displacement columns, input columns); several are stacked.
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Library spec, e.g. "x^1..7, x', xb_acc" (default: degree-7 restoring terms, linear
    /// damping and every input column; relative coordinates for chains).
    #[arg(long)]
    pub library: Option<String>,
    /// Identification method.
    #[arg(long, value_enum, default_value_t = Method::Tfs)]
    pub method: Method,
    /// Displacement columns (DOFs), comma-separated (default: `x` or `x1`, `x2`, … found in the file).
    #[arg(long, value_delimiter = ',')]
    pub dofs: Vec<String>,
    /// Fixed sparsity threshold (default: chosen on held-out data).
    #[arg(long)]
    pub threshold: Option<f64>,
    /// Re-estimate the coefficients of the chosen structure by simulation error (Levenberg–Marquardt
    /// with multiple shooting) on the training records.
    #[arg(long)]
    pub refine: bool,
    /// Held-out records used with --refine to keep whichever fit (equation- or simulation-error)
    /// predicts them better.
    #[arg(long = "validate", requires = "refine")]
    pub validate: Vec<PathBuf>,
    /// Chains: tie each element's force law between the two DOFs it connects (Newton's third
    /// law, the paper's Eq. 18): a term of a relative coordinate `(x2-x1)` in both DOFs'
    /// libraries gets one unknown, entering x1'' with −m2/m1 times its coefficient in x2''. The
    /// partner equation then need not find the coupling on its own among collinear columns.
    /// This is the default for chains (the default libraries put each coupling in both
    /// equations); `--tie` insists on it. Coefficient intervals as usual; no term test.
    #[arg(long, conflicts_with = "no_tie")]
    pub tie: bool,
    /// Chains: fit each DOF's equation on its own (the partner equation must then find the
    /// coupling among collinear columns, which needs far cleaner and richer records).
    #[arg(long)]
    pub no_tie: bool,
    /// Tied chains: the masses in the tie factors — `equal` (default, identical cells),
    /// `estimate` (each DOF's mass relative to the first, scanned on held-out records), or one
    /// positive number per DOF (`1,0.5`; only ratios matter).
    #[arg(long, conflicts_with = "no_tie", default_value = "equal")]
    pub masses: String,
    /// Where to write the model (tfs-model/1 JSON).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the model and trace as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Print the whole criteria trace (κ, kept bands, every setting tried and why, the
    /// assembly steps, offsets per record, time per stage) instead of the summary.
    #[arg(short, long)]
    pub verbose: bool,
    /// DC offsets of the DOF and input channels: `remove` subtracts each record's mean from
    /// them, `keep` uses the records as they are, `constant-term` keeps them and adds the term
    /// `1` to the library; `auto` (default) with force-like inputs (`u`, `force`, `voltage`)
    /// identifies the records both ways (`constant-term`, `remove`) and removes the means only
    /// when that law predicts the held-out rows as well with fewer terms, and is `keep`
    /// otherwise (base excitation `xb_*`, or no input).
    /// The choice and the offsets are in the trace and the model file.
    #[arg(long, value_enum, default_value_t = Offsets::Auto)]
    pub offsets: Offsets,
    #[command(flatten)]
    pub data_args: DataArgs,
}

impl Args {
    /// The identification options these flags ask for.
    pub fn options(&self) -> IdentifyOptions {
        IdentifyOptions {
            library: self.library.clone(),
            method: self.method,
            dofs: self.dofs.clone(),
            threshold: self.threshold,
            refine: self.refine,
            tie: match (self.tie, self.no_tie) {
                (true, _) => Tie::On,
                (_, true) => Tie::Off,
                _ => Tie::Auto,
            },
            masses: self.masses.clone(),
            offsets: self.offsets,
        }
    }
}

/// Refuses `--dofs` that name the time column or a column `file` does not have.
fn check_dofs(dofs: &[String], time_column: &str, columns: &[String], file: &str) -> Result<()> {
    if dofs.iter().any(|d| d == time_column) {
        bail!(
            "--dofs {time_column}: '{time_column}' is the time column, not a displacement; name the displacement columns among the file's others ({})",
            columns.join(", ")
        );
    }
    for d in dofs {
        if !columns.contains(d) {
            bail!(
                "--dofs {d}: {file} has no column '{d}' (its columns: {}); give the displacement columns by their names",
                columns.join(", ")
            );
        }
    }
    Ok(())
}

/// Refuses a library column that is a velocity written the way other tools spell it (`xdot`,
/// `x_dot`, `x_vel`): it would be read as an input column of that name, which the file does
/// not have; the error points to the grammar's `x'`.
fn check_velocity_spelling(plan: &Plan, columns: &[String], file: &str) -> Result<()> {
    for c in plan.required.iter().filter(|c| !columns.contains(c)) {
        let stem = ["_dot", "dot", "_vel", "_v"]
            .iter()
            .find_map(|suffix| c.strip_suffix(suffix))
            .filter(|s| plan.dofs.iter().any(|d| d == s));
        if let Some(stem) = stem {
            bail!(
                "--library: '{c}' is not a column of {file}; the velocity of '{stem}' is written {stem}' (e.g. \"{stem}^1..7, {stem}', xb_acc\")"
            );
        }
    }
    Ok(())
}

/// `--json`: the model, the criteria trace, the refinement and offsets reports, the warnings and
/// (for a chain) every cell's states.
fn print_json_report(identified: &Identification, is_chain: bool) -> Result<()> {
    let offsets_report = &identified.offsets;
    let refine_report = &identified.refine;
    print_json(&serde_json::json!({
        "model": identified.model.to_json_value()?,
        "trace": serde_json::to_value(&identified.trace)?,
        "refine": refine_report.as_ref().map(RefineReport::to_json),
        "offsets": offsets_report.to_json(),
        "warnings": identified.warnings,
        "cells": if is_chain { chain_cells_json(&identified.model) } else { serde_json::Value::Null },
    }))?;
    Ok(())
}

/// One screen: the equation, its fit, the verdict and what to do next.
fn print_screen(args: &Args, identified: &Identification, is_chain: bool) -> Result<()> {
    let offsets_report = &identified.offsets;
    let refine_report = &identified.refine;
    super::print_warnings(&identified.warnings);
    println!("{}", identified.model.equation_string());
    if is_chain {
        print_chain_cells(&identified.model)?;
    }
    print_summary(&identified.trace, &identified.model);
    if offsets_report.mode != tfs::records::Offsets::Keep {
        println!(
            "offsets: {} ({})",
            offsets_report.mode.name(),
            offsets_report.why
        );
    }
    for line in refine_report.iter().flat_map(RefineReport::lines) {
        println!("{line}");
    }
    println!("{}", next_steps(args.out.as_deref()));
    if let Some(out) = &args.out {
        println!("model written to {}", out.display());
    }
    Ok(())
}

/// `-v`: the equation and everything the identification measured (the criteria trace, offsets,
/// refinement).
fn print_verbose(
    args: &Args,
    opts: &IdentifyOptions,
    identified: &Identification,
    is_chain: bool,
) -> Result<()> {
    let offsets_report = &identified.offsets;
    let refine_report = &identified.refine;
    // The data cannot support the library: say so before anything else.
    super::print_warnings(&identified.warnings);
    println!("{}", identified.model.equation_string());
    if args.data.len() == 1 {
        if let Some(d) = identified.trace.dofs.first() {
            let parts: Vec<&str> = d
                .bins
                .iter()
                .map(|b| b.record.as_str())
                .filter(|r| r.contains('#'))
                .collect();
            if parts.len() > 1 {
                println!(
                    "one record given: it was split into {} halves ({}) so that the settings can be chosen on held-out data",
                    parts.len(),
                    parts.join(", ")
                );
            }
        }
    }
    if opts.tie == Tie::Auto && identified.trace.tied.is_some() {
        println!(
            "chain: each element's force law is tied between the two equations it enters (the default for a chain; --no-tie fits each equation on its own)"
        );
    }
    if is_chain {
        print_chain_cells(&identified.model)?;
    }
    print_trace(&identified.trace);
    print_offsets(offsets_report);
    for line in refine_report.iter().flat_map(RefineReport::lines) {
        println!("{line}");
    }
    if let Some(out) = &args.out {
        println!("model written to {}", out.display());
    }
    Ok(())
}

/// Runs `tfs identify`.
pub fn run(args: Args) -> Result<()> {
    let opts = args.options();
    let inputs: Vec<&std::path::Path> = args
        .data
        .iter()
        .chain(&args.validate)
        .map(PathBuf::as_path)
        .collect();
    if let Some(out) = &args.out {
        prepare_output(out, &inputs, "--out")?;
    }
    tfs::records::refuse_repeated(&inputs)?;
    // Each file is read once: the first one's header chooses the DOFs and inputs, then every
    // table is validated with the columns the libraries need.
    let tables = tfs::records::read_tables(&args.data)?;
    let time_column = &args.data_args.time_column;
    let columns: Vec<String> = tables[0]
        .names()
        .iter()
        .filter(|c| *c != time_column)
        .cloned()
        .collect();
    let file = args.data[0].display().to_string();
    check_dofs(&args.dofs, time_column, &columns, &file)?;
    let plan = plan(&opts, &columns, &file)?;
    if let Some(spec) = &args.library {
        for w in duplicate_terms(spec, &plan.dofs) {
            eprintln!("note: {w}");
        }
    }
    check_velocity_spelling(&plan, &columns, &file)?;
    let records = records_from(tables, &plan.required, &args.data_args)?;
    super::columns::check_identify_rows(&records)?;
    if let Some(note) = super::columns::unused_columns_note(
        &file,
        &columns,
        &plan.dofs,
        &plan.required,
        args.library.is_some(),
    ) {
        eprintln!("note: {note}");
    }
    let held_out = if args.validate.is_empty() {
        Vec::new()
    } else {
        read_records(&args.validate, &plan.required, &args.data_args)?
    };
    let identified = if opts.refine {
        with_spinner("identifying and refining by simulation error", || {
            identify(records, held_out, &opts, &plan)
        })?
    } else {
        identify(records, held_out, &opts, &plan)?
    };
    if let Some(out) = &args.out {
        write_model(&identified.model, out, "--out")?;
    }
    let is_chain = plan.dofs.len() > 1 && !tfs::criteria::chain_ties(&plan.spec)?.is_empty();
    if args.json {
        print_json_report(&identified, is_chain)?;
    } else if !args.verbose {
        print_screen(&args, &identified, is_chain)?;
    } else {
        print_verbose(&args, &opts, &identified, is_chain)?;
    }
    Ok(())
}

/// What to run next on the model just identified (and how to see the whole trace).
fn next_steps(out: Option<&std::path::Path>) -> String {
    match out {
        Some(p) => format!(
            "next: `tfs compare --model {0} HELD-OUT.csv` scores it on a record it was not fitted on; `tfs diagnose --model {0} RECORDS.csv` names a missing effect; -v prints the whole trace",
            p.display()
        ),
        None => "next: add `--out model.json` to keep the model, then `tfs compare --model model.json HELD-OUT.csv` scores it on a record it was not fitted on; -v prints the whole trace".into(),
    }
}

/// A chain model's cells as `tfs basin` reads them (each cell's law from its own equation, on
/// the default search range), or why they could not be read.
fn print_chain_cells(model: &tfs::library::Model) -> Result<()> {
    let search = super::parse_range(super::chain_basin::DEFAULT_SEARCH, "--search")?;
    match tfs::chain::cell_states("the model", model, search) {
        Ok(cells) => {
            println!(
                "cells (each cell's force law from its own equation, heights h on {}..{}):",
                search.0, search.1
            );
            super::chain_basin::print_cells(&cells, tfs::chain::is_tied(model));
        }
        Err(e) => println!("cells: not read ({})", tfs::one_line(&e)),
    }
    Ok(())
}

/// A chain model's cells for `--json` (as [`print_chain_cells`] prints them): per cell the
/// stable and unstable heights, the next cell's force taken where it rests and the stable
/// heights for each of its states; a string saying why when they cannot be read.
fn chain_cells_json(model: &tfs::library::Model) -> serde_json::Value {
    let search = match super::parse_range(super::chain_basin::DEFAULT_SEARCH, "--search") {
        Ok(s) => s,
        Err(e) => return serde_json::json!(format!("not read ({e})")),
    };
    match tfs::chain::cell_states("the model", model, search) {
        Ok(cells) => serde_json::json!(cells.iter().map(|c| serde_json::json!({
            "stable": c.stable,
            "unstable": c.unstable,
            "coupling_at_rest": c.coupling_at_rest,
            "folded_undecided": super::chain_basin::folded_json(c),
            "rests_on_stop": c.on_stop,
            "stable_by_next_state": c.by_next.iter().map(|(z, h)| serde_json::json!({"next": z, "stable": h})).collect::<Vec<_>>(),
        })).collect::<Vec<_>>()),
        Err(e) => serde_json::json!(format!("not read ({})", tfs::one_line(&e))),
    }
}

/// Prints what was done with the channel offsets, one line per record.
fn print_offsets(report: &OffsetsReport) {
    println!("offsets: {} ({})", report.mode.name(), report.why);
    if report.constant_term_added == Some(true) {
        println!("  constant term 1 added to the library");
    }
    for r in &report.per_record {
        let (label, map) = match r {
            RecordOffsets::Removed { removed, .. } => ("removed", removed),
            RecordOffsets::Kept { mean, .. } => ("means kept", mean),
        };
        let list: Vec<String> = map.iter().map(|(c, v)| format!("{c} = {v:.4e}")).collect();
        println!("  {}: {label}: {}", r.record(), list.join(", "));
    }
}

/// Terms a library spec names more than once (e.g. `x^3` beside `x^1..7`): the library keeps
/// one copy; this says which, so that the spec can be cleaned up.
fn duplicate_terms(spec: &str, dofs: &[String]) -> Vec<String> {
    // top-level items: commas outside parentheses (poly(x, x'; 0..7), below(x, c))
    let mut items = Vec::new();
    let (mut depth, mut start) = (0i32, 0);
    for (i, ch) in spec.char_indices() {
        match ch {
            '(' => depth += 1,
            ')' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&spec[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items.push(&spec[start..]);
    let mut seen: Vec<(String, String)> = Vec::new();
    let mut out = Vec::new();
    for item in items.iter().map(|s| s.trim()).filter(|s| !s.is_empty()) {
        let Ok(lib) = tfs::library::Library::parse(item, dofs) else {
            continue;
        };
        for t in lib.terms() {
            let name = t.to_string();
            match seen.iter().find(|(n, _)| *n == name) {
                Some((_, first)) => out.push(format!(
                    "--library: term '{name}' is named twice ('{first}' and '{item}'); it is used once"
                )),
                None => seen.push((name, item.to_string())),
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::duplicate_terms;

    #[test]
    fn duplicate_library_terms_are_named() {
        let dofs = vec!["x".to_string()];
        let w = duplicate_terms("x^1..7, x', x^3, poly(x, x'; 0..1), xb_acc", &dofs);
        assert_eq!(w.len(), 3, "{w:?}"); // x^3 again, and poly's x and x'
        assert!(w[0].contains("'x^3'") && w[0].contains("'x^1..7'"), "{w:?}");
        assert!(duplicate_terms("x^1..7, x', xb_acc", &dofs).is_empty());
    }
}
