//! tfs automation. `cargo xtask reproduce-paper [--quick] [--out DIR]` rebuilds the paper's
//! numerical studies (§3.1 white and pink noise, §3.2 two-cell chain, Appendix B, §4 experiment-like
//! study) from the workspace's own simulators and prints our numbers beside the paper's;
//! `cargo xtask diagnose-bench [--quick]` scores the diagnosis loop on hidden-effect records;
//! `cargo xtask truss-loop` runs the loop on the Kresling truss cell and scores its force and basins.
//!
//! Orchestration and presentation only: every number comes from the `tfs` crates.

mod chain;
mod common;
mod dbench;
mod experiment;
mod peers;
mod peers_study;
mod report;
mod sdof;
mod truss_loop;

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};

use crate::common::Opts;
use crate::report::{Report, Study, verdict};

/// Command line.
#[derive(Debug, Parser)]
#[command(name = "xtask", about = "tfs automation")]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Debug, Subcommand)]
enum Cmd {
    /// Rebuild the paper's numerical studies: tables, figures, results.json, report.md, index.html.
    ReproducePaper {
        /// Smaller grids, shorter records (well under two minutes).
        #[arg(long)]
        quick: bool,
        /// Output folder.
        #[arg(long, default_value = "target/paper")]
        out: PathBuf,
        /// Run only these studies (keys: s1_white, s2_pink, s3_chain, s4_table_b1, s5_experiment,
        /// s6_peers).
        #[arg(long, value_delimiter = ',')]
        only: Vec<String>,
        /// Folder of a `cargo xtask peers` run to include (study 6); skipped with a note if absent.
        #[arg(long, default_value = "target/peers")]
        peers: PathBuf,
        /// Python virtual environment with pysindy 2.1 for Table B1's PySINDy row (used as it
        /// is, never created here: `cargo xtask peers` makes this default one). Without it the
        /// row says PySINDy was not run.
        #[arg(long, default_value = "target/peers/venv")]
        venv: PathBuf,
        /// Do not run PySINDy (Table B1's PySINDy row says so).
        #[arg(long)]
        no_python: bool,
    },
    /// tfs vs PySINDy (weak and classical) on the same CSVs, scored by one code path (a
    /// benchmark: creates a Python virtual environment; CI does not run it).
    Peers(peers::PeersArgs),
    /// The diagnosis loop scored like a classifier: every catalogue effect hidden in drawn
    /// truths of six baselines, at drawn sizes and noise levels, with controls and pairs
    /// (report.md, results.json, figures).
    DiagnoseBench(dbench::Args),
    /// The diagnosis loop on the Kresling truss cell as the CLI runs it (simulate, identify,
    /// refit --until-clean, basin), scored against the truss force and its basin map.
    TrussLoop(truss_loop::Args),
}

type StudyFn = fn(&mut Study, &Opts) -> Result<()>;

const STUDIES: [(&str, &str, StudyFn); 6] = [
    (
        "s1_white",
        "1. §3.1 bistable cell, white noise 60/30 dB (Table 1, Figs 3–4)",
        sdof::study_white,
    ),
    (
        "s2_pink",
        "2. §3.1 bistable cell, pink noise 30 dB (Fig. 5)",
        sdof::study_pink,
    ),
    (
        "s3_chain",
        "3. §3.2 two-cell chain, 60/30 dB (Table 2, Figs 6–7)",
        chain::study_chain,
    ),
    (
        "s4_table_b1",
        "4. Appendix B: T-F-S vs classical SINDy (Table B1)",
        sdof::study_table_b1,
    ),
    (
        "s5_experiment",
        "5. §4 experiment-like study (Table 3, Figs 9–10, MED)",
        experiment::study_experiment,
    ),
    (
        "s6_peers",
        "6. tfs vs PySINDy on the same records (from `cargo xtask peers`)",
        |st, o| peers_study::study_peers(st, &o.peers),
    ),
];

const PREAMBLE: &str = "Every number below is recomputed by the tfs crates (tfs-origami simulators, tfs-criteria identification, tfs-dynamics simulation, tfs-basin basins and MED). Each is judged against the truth it estimates (our simulators are the truth here), with the paper's number beside it and both differences: Table 1 coefficients within 2% (60 dB) and 5% (30 dB) of the truth with no extra terms; every BOA error below 3% of the grid; the chain's stable states within 0.05 of the truth's; T-F-S beats classical SINDy in test R-MSE and regresses on a smaller matrix (times are shown, not judged); all eight deployment tests predicted as the truth behaves. A failed check is listed under Verdict and makes `cargo xtask reproduce-paper` exit with status 1. Rows without a check are informational (verdict `info`).";

fn main() {
    let cli = Cli::parse();
    match cli.cmd {
        Cmd::ReproducePaper {
            quick,
            out,
            only,
            peers,
            venv,
            no_python,
        } => match reproduce(
            Opts {
                quick,
                peers,
                venv: (!no_python).then_some(venv),
            },
            &out,
            &only,
        ) {
            Ok(o) if o.failed_studies == 0 && o.failed_checks == 0 => {}
            Ok(o) => {
                eprintln!(
                    "{} stud{} failed, {} check{} failed; see {}/report.md",
                    o.failed_studies,
                    if o.failed_studies == 1 { "y" } else { "ies" },
                    o.failed_checks,
                    if o.failed_checks == 1 { "" } else { "s" },
                    out.display()
                );
                std::process::exit(1);
            }
            Err(e) => {
                eprintln!("error: {e:#}");
                std::process::exit(2);
            }
        },
        Cmd::Peers(a) => {
            if let Err(e) = peers::run(a) {
                eprintln!("error: {e:#}");
                std::process::exit(2);
            }
        }
        Cmd::DiagnoseBench(a) => {
            if let Err(e) = dbench::run(a) {
                eprintln!("error: {e:#}");
                std::process::exit(2);
            }
        }
        Cmd::TrussLoop(a) => {
            if let Err(e) = truss_loop::run(a) {
                eprintln!("error: {e:#}");
                std::process::exit(2);
            }
        }
    }
}

/// Runs the studies; returns how many studies and checks failed (both are in the report).
fn reproduce(opts: Opts, out: &std::path::Path, only: &[String]) -> Result<Outcome> {
    for k in only {
        if !STUDIES.iter().any(|s| s.0 == k) {
            anyhow::bail!(
                "--only {k}: unknown study; use one of {}",
                STUDIES.map(|s| s.0).join(", ")
            );
        }
    }
    std::fs::create_dir_all(out)
        .with_context(|| format!("creating the output folder {}", out.display()))?;
    let start = Instant::now();
    let mut report = Report::new(out, opts.quick);
    for (key, title, f) in STUDIES {
        if !only.is_empty() && !only.iter().any(|k| k == key) {
            continue;
        }
        let mut st = Study::new(key, title, out);
        let t0 = Instant::now();
        let res = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(&mut st, &opts)));
        let err = match res {
            Ok(Ok(())) => None,
            Ok(Err(e)) => Some(format!("{e:#}")),
            Err(p) => Some(format!(
                "panic: {}",
                p.downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default()
            )),
        };
        let secs = t0.elapsed().as_secs_f64();
        if let Some(e) = &err {
            eprintln!("study {key} failed after {secs:.1} s: {e}");
        } else {
            eprintln!("study {key} done in {secs:.1} s");
        }
        report.push(st, err, secs);
    }
    let total = start.elapsed().as_secs_f64();
    report.write_summary_csv()?;
    report.write(total, PREAMBLE)?;
    print_summary(&report);
    println!(
        "\nreport: {}/report.md, {}/index.html, {}/results.json ({total:.1} s)",
        out.display(),
        out.display(),
        out.display()
    );
    Ok(Outcome {
        failed_studies: report.failures().len(),
        failed_checks: report.failed_checks().len(),
    })
}

/// What a reproduction run found wrong: studies that stopped with an error, and checks whose
/// number is outside its rule.
struct Outcome {
    failed_studies: usize,
    failed_checks: usize,
}

fn print_summary(report: &Report) {
    let rows = report.summary();
    let w = |f: &dyn Fn(&report::SummaryRow) -> usize, min: usize| {
        rows.iter().map(|r| f(r)).max().unwrap_or(0).max(min)
    };
    let (w0, w1, w2, w3) = (
        w(&|r| r.metric.chars().count(), 5),
        w(&|r| r.truth.chars().count(), 5),
        w(&|r| r.ours.chars().count(), 15),
        w(&|r| r.paper.chars().count(), 16),
    );
    println!("\nEach number judged against the truth it estimates; the paper's number beside it.");
    println!(
        "{:<w0$} | {:<w1$} | {:<w2$} | {:<w3$} | verdict",
        "check", "truth", "ours (vs truth)", "paper (vs truth)"
    );
    println!("{}", "-".repeat(w0 + w1 + w2 + w3 + 22));
    for r in &rows {
        println!(
            "{:<w0$} | {:<w1$} | {:<w2$} | {:<w3$} | {}",
            r.metric,
            r.truth,
            r.ours,
            r.paper,
            verdict(r.within_tolerance)
        );
    }
    println!();
    // The same verdict as report.md, without the Markdown emphasis.
    print!("{}", report.verdict_text().replace("**", ""));
}
