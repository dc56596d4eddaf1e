//! `tfs identify`: records in, a sparse model (tfs-model/1 JSON) and the criteria trace out.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::ValueEnum;
use tfs::criteria::{
    IdentifySpec, MassChoice, TieOptions, identify_sindy, identify_tfs, identify_tfs_tied,
};

use super::{
    DataArgs, Offsets, apply_offsets, guess_dofs, guess_inputs, peek_columns, print_json,
    read_records,
};

/// Identification method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Method {
    /// T-F-S SINDy: criteria 1–4 with frequency-domain (weak-form) regression (default).
    Tfs,
    /// Classical SINDy: numerical derivatives and time-domain STLSQ (the baseline).
    Sindy,
}

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
    /// Coefficient intervals as usual; no term test (see the trace).
    #[arg(long)]
    pub tie: bool,
    /// With --tie: the masses in the tie factors — `equal` (default, identical cells),
    /// `estimate` (each DOF's mass relative to the first, scanned on held-out records), or one
    /// positive number per DOF (`1,0.5`; only ratios matter).
    #[arg(long, requires = "tie", default_value = "equal")]
    pub masses: String,
    /// Where to write the model (tfs-model/1 JSON).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the model and trace as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// DC offsets of the DOF and input channels: `remove` subtracts each record's mean from
    /// them, `keep` uses the records as they are, `constant-term` keeps them and adds the term
    /// `1` to the library; `auto` (default) removes them when every input is force-like (`u`,
    /// `force`, `voltage`: a rig in raw units) and keeps them otherwise (base excitation `xb_*`,
    /// or no input). The choice and the offsets are in the trace and the model file.
    #[arg(long, value_enum, default_value_t = Offsets::Auto)]
    pub offsets: Offsets,
    #[command(flatten)]
    pub data_args: DataArgs,
}

/// The default library for the given DOFs and inputs: per DOF, the cell's own relative coordinate
/// (and the next cell's, in a chain) to powers 1..7, their relative velocities, and the inputs.
pub fn default_libraries(dofs: &[String], inputs: &[String]) -> Vec<String> {
    let rel = |i: usize| -> String {
        if i == 0 {
            dofs[0].clone()
        } else {
            format!("({}-{})", dofs[i], dofs[i - 1])
        }
    };
    (0..dofs.len())
        .map(|i| {
            let mut parts = vec![format!("{}^1..7", rel(i)), format!("{}'", rel(i))];
            if i + 1 < dofs.len() {
                parts.push(format!("{}^1..7", rel(i + 1)));
                parts.push(format!("{}'", rel(i + 1)));
            }
            parts.extend(inputs.iter().cloned());
            parts.join(", ")
        })
        .collect()
}

/// `--masses`: `equal`, `estimate` (candidate ratios 0.25..4) or one positive mass per DOF.
fn parse_masses(text: &str, n: usize) -> Result<MassChoice> {
    match text.trim() {
        "equal" => Ok(MassChoice::Equal),
        "estimate" => Ok(MassChoice::Estimate {
            candidates: vec![0.25, 0.33, 0.5, 0.67, 0.8, 1.0, 1.25, 1.5, 2.0, 3.0, 4.0],
        }),
        list => {
            let m: Vec<f64> = list
                .split(',')
                .map(|v| v.trim().parse::<f64>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| {
                    anyhow::anyhow!(
                        "--masses '{text}': expected 'equal', 'estimate' or {n} comma-separated numbers"
                    )
                })?;
            if m.len() != n || m.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                bail!("--masses '{text}': give one positive mass per DOF ({n})");
            }
            Ok(MassChoice::Given(m))
        }
    }
}

/// Runs `tfs identify`.
pub fn run(args: Args) -> Result<()> {
    let columns = peek_columns(&args.data[0])?;
    let dofs = if args.dofs.is_empty() {
        let d = guess_dofs(&columns);
        if d.is_empty() {
            bail!(
                "{}: no displacement column found (expected 'x' or 'x1', 'x2', …; the header has [{}]); name them with --dofs",
                args.data[0].display(),
                columns.join(", ")
            );
        }
        d
    } else {
        args.dofs.clone()
    };
    let inputs = guess_inputs(&columns);
    let mut spec = IdentifySpec::new(&dofs.iter().map(String::as_str).collect::<Vec<_>>(), "");
    match &args.library {
        Some(lib) => spec.library = lib.clone(),
        None => {
            let libs = default_libraries(&dofs, &inputs);
            spec.library = libs[0].clone();
            if dofs.len() > 1 {
                spec.dof_libraries = libs;
            }
        }
    }
    if let Some(th) = args.threshold {
        if !(th.is_finite() && th >= 0.0) {
            bail!("--threshold {th}: must be a finite number ≥ 0");
        }
        spec.tfs.threshold = Some(th);
        spec.sindy.threshold = Some(th);
    }
    // Every column the libraries name must be present in every file.
    let mut required: Vec<String> = dofs.clone();
    let libs = spec_libraries(&spec)?;
    for lib in &libs {
        for c in lib.required_columns() {
            if !c.ends_with('\'') && !required.contains(&c) {
                required.push(c);
            }
        }
    }
    let input_cols: Vec<String> = required
        .iter()
        .filter(|c| !dofs.contains(c))
        .cloned()
        .collect();
    let (mode, why) = resolve_offsets(args.offsets, &input_cols);
    let mut added_constant = false;
    if mode == Offsets::ConstantTerm {
        if spec.dof_libraries.is_empty() {
            if !libs[0].terms().iter().any(|t| t.is_constant()) {
                spec.library = format!("1, {}", spec.library);
                added_constant = true;
            }
        } else {
            for (s, lib) in spec.dof_libraries.iter_mut().zip(&libs) {
                if !lib.terms().iter().any(|t| t.is_constant()) {
                    *s = format!("1, {s}");
                    added_constant = true;
                }
            }
        }
    }
    let data_mode = if mode == Offsets::Remove {
        Offsets::Remove
    } else {
        Offsets::Keep
    };
    let channels: Vec<String> = dofs.iter().chain(&input_cols).cloned().collect();
    let mut records = read_records(&args.data, &required, &args.data_args)?;
    let mut offsets_report = apply_offsets(&mut records, &channels, data_mode, &why)?;
    offsets_report["requested"] = serde_json::json!(args.offsets.name());
    if mode == Offsets::ConstantTerm {
        offsets_report["mode"] = serde_json::json!(mode.name());
        offsets_report["constant_term_added"] = serde_json::json!(added_constant);
    }
    let mut identified = match (args.method, args.tie) {
        (Method::Tfs, false) => identify_tfs(&records, &spec)?,
        (Method::Tfs, true) => {
            let tie = TieOptions {
                masses: parse_masses(&args.masses, dofs.len())?,
            };
            if tfs::criteria::chain_ties(&spec)?.is_empty() {
                bail!(
                    "--tie: no term of a relative coordinate between two DOFs (e.g. '(x2-x1)^3') is in both DOFs' libraries, so nothing can be tied; put the coupling terms in both libraries or drop --tie"
                );
            }
            identify_tfs_tied(&records, &spec, &tie)?
        }
        (Method::Sindy, false) => identify_sindy(&records, &spec)?,
        (Method::Sindy, true) => {
            bail!("--tie works with --method tfs only (the tied fit is a T-F-S regression)")
        }
    };
    let mut refine_report = serde_json::Value::Null;
    if args.refine {
        let refined = tfs::refine::refine(
            &identified.model,
            &records,
            &tfs::refine::RefineOptions::default(),
        )?;
        refine_report = serde_json::json!({
            "initial_cost": refined.initial_cost,
            "final_cost": refined.final_cost,
            "iterations": refined.iterations,
            "converged": refined.converged,
            "message": refined.message,
            "per_record": refined.per_record,
            "noise_dominated": refined.noise_dominated,
        });
        if args.validate.is_empty() {
            identified.model = refined.model;
        } else {
            let mut held_out = read_records(&args.validate, &required, &args.data_args)?;
            apply_offsets(&mut held_out, &channels, data_mode, &why)?;
            let (chosen, scores) =
                tfs::refine::choose_by_validation(&identified.model, &refined.model, &held_out)?;
            refine_report["validation"] = serde_json::json!({
                "equation_error_fit": scores.eq_score,
                "simulation_error_fit": scores.refined_score,
                "chose_refined": scores.chose_refined,
                "per_record": scores.per_record,
                "noise_dominated": scores.noise_dominated,
            });
            identified.model = chosen;
        }
    }
    if let Some(obj) = identified.model.trace.as_object_mut() {
        obj.insert("offsets".into(), offsets_report.clone());
    } else {
        identified.model.trace = serde_json::json!({"offsets": offsets_report.clone()});
    }
    if let Some(out) = &args.out {
        identified.model.write_path(out)?;
    }
    if args.json {
        print_json(&serde_json::json!({
            "model": identified.model.to_json_value()?,
            "trace": serde_json::to_value(&identified.trace)?,
            "refine": refine_report,
            "offsets": offsets_report,
            "warnings": identified.trace.warnings(),
        }))?;
    } else {
        // The data cannot support the library: say so before anything else, on stderr too.
        for w in identified.trace.warnings() {
            eprintln!("warning: {w}");
            println!("WARNING {w}");
        }
        println!("{}", identified.model.equation_string());
        print_trace(&identified.trace);
        print_offsets(&offsets_report);
        if !refine_report.is_null() {
            println!("refinement by simulation error: {refine_report}");
        }
        if let Some(out) = &args.out {
            println!("model written to {}", out.display());
        }
    }
    Ok(())
}

/// Resolves `--offsets auto` by the kind of the input columns; returns the mode and why.
fn resolve_offsets(requested: Offsets, inputs: &[String]) -> (Offsets, String) {
    if requested != Offsets::Auto {
        return (requested, "given with --offsets".to_string());
    }
    if inputs.is_empty() {
        (
            Offsets::Keep,
            "auto: no input column, records used as they are".to_string(),
        )
    } else if inputs.iter().any(|c| c.starts_with("xb")) {
        (
            Offsets::Keep,
            "auto: base-motion input, displacements are geometric coordinates whose origin matters; records used as they are".to_string(),
        )
    } else {
        (
            Offsets::Remove,
            format!(
                "auto: force-like input(s) [{}] (a rig in raw units): each record's mean removed from every DOF and input channel",
                inputs.join(", ")
            ),
        )
    }
}

/// Prints what was done with the channel offsets, one line per record.
fn print_offsets(report: &serde_json::Value) {
    println!(
        "offsets: {} ({})",
        report["mode"].as_str().unwrap_or("?"),
        report["why"].as_str().unwrap_or("")
    );
    if report["constant_term_added"] == serde_json::json!(true) {
        println!("  constant term 1 added to the library");
    }
    for r in report["per_record"].as_array().into_iter().flatten() {
        let (label, map) = match (r.get("removed"), r.get("mean")) {
            (Some(m), _) => ("removed", m),
            (_, Some(m)) => ("means kept", m),
            _ => continue,
        };
        let list: Vec<String> = map
            .as_object()
            .into_iter()
            .flatten()
            .map(|(c, v)| format!("{c} = {:.6e}", v.as_f64().unwrap_or(f64::NAN)))
            .collect();
        println!(
            "  {}: {label}: {}",
            r["record"].as_str().unwrap_or(""),
            list.join(", ")
        );
    }
}

fn spec_libraries(spec: &IdentifySpec) -> Result<Vec<tfs::library::Library>> {
    let specs: Vec<&String> = if spec.dof_libraries.is_empty() {
        vec![&spec.library]
    } else {
        spec.dof_libraries.iter().collect()
    };
    specs
        .into_iter()
        .map(|s| Ok(tfs::library::Library::parse(s, &spec.dofs)?))
        .collect()
}

/// Prints the criteria trace in a few readable lines.
pub fn print_trace(trace: &tfs::criteria::Trace) {
    let v = serde_json::to_value(trace).unwrap_or_default();
    println!("method: {}", trace.method);
    for d in &trace.dofs {
        let dv = serde_json::to_value(d).unwrap_or_default();
        println!("dof {}:", d.dof);
        if let Some(c1) = dv.get("criterion1") {
            println!("  criterion 1: {}", compact(c1));
        }
        if let Some(c2) = dv.get("pruning") {
            println!("  criterion 2: {}", compact(c2));
        }
        for b in &d.bins {
            println!(
                "  criterion 3: {}: {} bins kept, band {:.3}–{:.3} Hz",
                b.record, b.kept_bins, b.band_hz[0], b.band_hz[1]
            );
        }
        println!(
            "  settings: delta = {}, windows = {}, threshold = {:.3e}",
            d.settings.delta, d.settings.windows, d.settings.threshold
        );
        for why in &d.settings.why {
            println!("    {why}");
        }
        for s in &d.assembly {
            println!(
                "  criterion 4: after {:?}: mu = {:.3e}, sigma = {:.3e} ({} terms)",
                s.records, s.mu, s.sigma, s.n_terms
            );
        }
        println!("  assembly: {}", d.assembly_verdict);
    }
    if let Some(t) = v.get("timing_ms") {
        println!("timing (ms): {}", compact(t));
    }
}

fn compact(v: &serde_json::Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 300 {
        format!("{}…", s.chars().take(300).collect::<String>())
    } else {
        s
    }
}
