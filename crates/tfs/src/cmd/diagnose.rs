//! `tfs diagnose`: compare a model with measurements, localise where it fails, and rank the
//! catalogue's physical effects that may be missing (or say clearly that none is).

use std::path::PathBuf;

use anyhow::{Context, Result};
use serde_json::json;
use tfs::diagnose::{DiagnoseOptions, diagnose};
use tfs::plot::{BarChart, Figure, LineChart, Series};

use tfs::records::{measured_columns, read_model};

use super::{DataArgs, ModelOffsets, offsets_for_model, print_json};

/// Arguments of `tfs diagnose`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model (tfs-model/1 JSON).
    #[arg(long)]
    pub model: PathBuf,
    /// CSV records with the model's displacement and input columns.
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Write residual map, spectra, phase portraits, the ranking and the force–displacement loop
    /// (before and after adding the top effect) as SVG and PNG into this directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Print the diagnosis as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Print more: the simulations' reasons, the offsets, the residual summary, every record's
    /// R-MSE and every effect with its reason (the default is the verdict without its reasons,
    /// the model's R-MSE and the top of the effect table).
    #[arg(short, long)]
    pub verbose: bool,
    /// Family-wise significance level of the effect tests.
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// Minimum effect size as a share of the force RMS; an effect below it still counts when the
    /// refitted model predicts the held-out data better by this share of the motion's RMS.
    #[arg(long, default_value_t = 0.02)]
    pub min_share: f64,
    /// DC offsets of the DOF and input channels: `auto` (default) does what `tfs identify` did
    /// for this model (its trace says so), `remove` subtracts each record's mean, `keep` uses
    /// the records as they are.
    #[arg(long, value_enum, default_value_t = ModelOffsets::Auto)]
    pub offsets: ModelOffsets,
    #[command(flatten)]
    pub data_args: DataArgs,
}

/// Says when the records' means were removed from a structure with memory: the model has an
/// internal state, or the effect named (`named`) adds one (see
/// [`tfs::records::memory_offsets_note`]).
fn memory_note(
    model: &tfs::library::Model,
    d: &tfs::diagnose::Diagnosis,
    named: Option<&str>,
    offsets: &tfs::report::OffsetsReport,
    records: &[tfs::data::Record],
) -> Option<String> {
    if !model.internal_states().is_empty() {
        return super::state_offsets_note(model, offsets, records);
    }
    let memory = {
        let top = d.ranked.iter().find(|r| Some(r.name.as_str()) == named)?;
        let adds_state = top.terms.iter().any(|t| {
            tfs::library::Library::parse(
                t,
                &model.dofs.iter().map(String::as_str).collect::<Vec<_>>(),
            )
            .is_ok_and(|l| l.terms().iter().any(|t| !t.states().is_empty()))
        });
        if !adds_state {
            return None;
        }
        format!("the missing effect {} has memory", top.name)
    };
    tfs::records::memory_offsets_note(offsets, records, &model.dofs, &memory)
}

/// Runs `tfs diagnose`.
pub fn run(args: Args) -> Result<()> {
    if let Some(dir) = &args.plots {
        super::paths::check_plots_for(dir, &args.model, &args.data, None)?;
    }
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
    let opts = DiagnoseOptions {
        alpha: args.alpha,
        min_share: args.min_share,
        ..DiagnoseOptions::default()
    };
    let d = super::with_spinner("diagnosing: testing the catalogue's effects", || {
        diagnose(&model, &records, &opts).map_err(anyhow::Error::from)
    })
    .context("diagnosing the model")?;
    // The one decision `refit --until-clean` takes too (tfs::decide): a model that fails to
    // simulate some records is given the candidate that makes them simulate; otherwise a
    // significant candidate whose addition makes the records simulate worse is passed over.
    let spinner = if tfs::gate::fails_somewhere(&d) {
        "the model fails to simulate some records: adding each candidate and simulating"
    } else {
        "checking the significant candidates: adding them in turn and simulating the records"
    };
    let decision = super::with_spinner(spinner, || {
        tfs::decide::decide(
            &model,
            &d.ranked,
            &records,
            &opts,
            &tfs::decide::DecideOptions::diagnose(),
        )
    })
    .context("simulating the candidates")?;
    let verdict = decision.verdict(&d.verdict);
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("--plots {}: cannot create the directory", dir.display()))?;
        write_plots(dir, &d)?;
        // The loop before and after adding the effect named, on the first record.
        let after = decision
            .added
            .as_ref()
            .map(|c| (format!("model + {}", c.effect), c.model.clone()));
        let mut models: Vec<(&str, &tfs::library::Model)> = vec![("model", &model)];
        if let Some((label, m)) = &after {
            models.push((label.as_str(), m));
        }
        super::plots::loop_figures(dir, &models, &records[0])?;
    }
    if args.json {
        print_json(&json!({
            "model": args.model.display().to_string(),
            "ranked": d.ranked,
            "verdict": verdict,
            "equation_error_verdict": d.verdict,
            "simulation": &decision,
            "residual_summary": d.residual_summary,
            "records": d.records,
            "localisation": d.localisation,
            "tests": d.tests,
            "cutoff_hz": d.cutoff_hz,
            "offsets": offsets_report.to_json(),
        }))?;
    } else {
        print_human(
            &args,
            &model,
            &d,
            &decision,
            &verdict,
            &offsets_report,
            &records,
        );
    }
    Ok(())
}

/// How many effects the default table lists (`-v` lists them all).
const TABLE_ROWS: usize = 8;

/// The diagnosis for people: the verdict, the model's own R-MSE on the records (as `compare`
/// scores it) and the effect table; with `-v` also the simulations' reasons, the offsets, the
/// residual summary, every record's R-MSE and each effect's reason.
fn print_human(
    args: &Args,
    model: &tfs::library::Model,
    d: &tfs::diagnose::Diagnosis,
    decision: &tfs::decide::Decision,
    verdict: &str,
    offsets_report: &tfs::report::OffsetsReport,
    records: &[tfs::data::Record],
) {
    if args.verbose {
        println!("{verdict}");
    } else {
        println!("{}", short_verdict(verdict));
    }
    if args.verbose {
        // The verdict gives the decision's reasons when it does not follow the ranking.
        if decision.ranking_stands {
            if !decision.why.is_empty() {
                println!("simulation: {}", decision.why);
            }
        } else {
            println!("equation-error ranking: {}", d.verdict);
        }
        println!("decision: {}", decision.reason);
        for t in &decision.tried {
            let score = match (&t.score, &t.error) {
                (Some(s), _) => s.describe(),
                (None, Some(e)) => format!("could not be added ({e})"),
                (None, None) => "not simulated".to_string(),
            };
            println!("  tried {}: {score}: {}", t.effect, t.reason);
        }
        println!(
            "offsets: {} ({})",
            offsets_report.mode.name(),
            offsets_report.why
        );
    }
    if let Some(note) = memory_note(
        model,
        d,
        decision.chosen.as_deref(),
        offsets_report,
        records,
    ) {
        println!("note: {note}");
    }
    if args.verbose {
        for s in &d.residual_summary {
            println!("residual: {s}");
        }
    }
    let mut scored = Vec::new();
    for r in &d.records {
        match (&r.r_mse, &r.error) {
            (Some(v), _) => {
                scored.extend(v.iter().copied());
                if args.verbose {
                    println!(
                        "{}: R-MSE {} (on the variance; Appendix B, over the mean square: {})",
                        r.record,
                        sci4(v, &model.dofs),
                        sci4(r.r_mse_mean_square.as_deref().unwrap_or(&[]), &model.dofs)
                    );
                }
            }
            (_, Some(e)) => println!("{}: simulation failed: {e}", r.record),
            _ => {}
        }
        if args.verbose {
            for m in &r.missing_harmonics {
                println!("  missing drive harmonics (order) {m}");
            }
        }
    }
    if !scored.is_empty() && !args.verbose {
        println!(
            "the model's R-MSE on these records: {:.4e} (mean over {} record(s) and DOFs, as `tfs compare` scores it)",
            scored.iter().sum::<f64>() / scored.len() as f64,
            d.records.iter().filter(|r| r.r_mse.is_some()).count()
        );
    }
    // An effect whose terms the model already has cannot be added again: not offered.
    let has = |r: &tfs::diagnose::RankedEffect| {
        let own: Vec<String> = model
            .equations
            .iter()
            .filter(|e| e.dof == r.dof)
            .flat_map(|e| e.terms.iter().map(|t| t.term.to_string()))
            .collect();
        !r.terms.is_empty() && r.terms.iter().all(|t| own.contains(t))
    };
    let (already, offered): (Vec<_>, Vec<_>) = d.ranked.iter().partition(|r| has(r));
    println!(
        "\n{:<22} {:>5} {:>10} {:>10} {:>8} {:>12} {:>12}{}",
        "effect",
        "sig",
        "delta",
        "p",
        "share",
        "coef",
        "R-MSE after",
        if args.verbose { "  why" } else { "" }
    );
    let shown = if args.verbose {
        offered.len()
    } else {
        offered.len().min(TABLE_ROWS)
    };
    for r in &offered[..shown] {
        let why = if args.verbose {
            format!("  {}", r.reason)
        } else {
            String::new()
        };
        println!(
            "{:<22} {:>5} {:>10.4} {:>10.2e} {:>8.4} {:>12.4e} {:>12}{why}",
            r.name,
            if r.significant { "yes" } else { "no" },
            r.delta_heldout,
            r.p_value,
            r.share,
            r.coef,
            r.r_mse_after
                .map(|v| format!("{v:.4e}"))
                .unwrap_or_else(|| "sim. failed".into()),
        );
    }
    if shown < offered.len() {
        let rest = &offered[shown..];
        let significant = rest.iter().filter(|r| r.significant).count();
        println!(
            "… {} more effect(s), {} (-v lists them all, with each one's reason)",
            rest.len(),
            match significant {
                0 => "none significant".to_string(),
                n => format!("{n} significant"),
            }
        );
    }
    if args.verbose && !already.is_empty() {
        println!(
            "not offered (the model already has their terms): {}",
            already
                .iter()
                .map(|r| r.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    println!(
        "(delta: drop of the held-out equation error; R-MSE after: prediction error of the model's terms refitted with the effect, on parts of the records held out of that fit)"
    );
}

/// The verdict without its reasons (the parenthesis after the effect, which `-v` prints): what
/// is missing and the `--add` flags that add it.
fn short_verdict(verdict: &str) -> String {
    let Some(open) = verdict.find(" (") else {
        return verdict.to_string();
    };
    match verdict.rfind("; add ").filter(|&k| k > open) {
        Some(k) => format!("{}{}", &verdict[..open], &verdict[k..]),
        None => format!("{} (-v says why)", &verdict[..open]),
    }
}

/// One number per DOF with 5 significant digits, each followed by its DOF's name.
fn sci4(v: &[f64], dofs: &[String]) -> String {
    v.iter()
        .zip(dofs)
        .map(|(e, dof)| format!("{e:.4e} ({dof})"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn write_plots(dir: &std::path::Path, d: &tfs::diagnose::Diagnosis) -> Result<()> {
    // Ranking: held-out improvement per effect.
    // The six best-ranked candidates: more labels would overlap on the axis.
    let top: Vec<_> = d.ranked.iter().take(6).collect();
    let bars = BarChart {
        title: "Held-out equation-error drop of the six best-ranked effects (* = significant)"
            .into(),
        x_label: "effect".into(),
        y_label: "relative drop of held-out error (1 = 100 %)".into(),
        labels: top
            .iter()
            .map(|r| format!("{}{}", r.name, if r.significant { " *" } else { "" }))
            .collect(),
        // a negative drop (the effect made the held-out error worse) is drawn below zero
        values: top.iter().map(|r| r.delta_heldout).collect(),
        log_y: false,
        color: None,
    };
    Figure::from(bars).save(&dir.join("effects"))?;
    for (k, r) in d.records.iter().enumerate() {
        for s in &r.spectra {
            // From the first bin above DC: the DC bin of a record with its offset removed is
            // near zero and would stretch the log axis by ten decades.
            let spectrum = |a: &[f64]| -> Vec<(f64, f64)> {
                s.freqs
                    .iter()
                    .copied()
                    .zip(a.iter().copied())
                    .filter(|(f, _)| *f > 0.0)
                    .collect()
            };
            let mut chart = LineChart::new(
                format!("{}: spectrum of {}", r.record, s.dof),
                "f (Hz)",
                format!("amplitude of {} (record units)", s.dof),
            )
            .log_y(true)
            .with_series(Series::line("measured", spectrum(&s.measured)))
            .with_series(Series::dashed("model", spectrum(&s.model)));
            for h in s.harmonics.iter().filter(|h| h.missing) {
                chart = chart.with_vline(h.band.0, format!("{}x drive (missing)", h.order));
            }
            Figure::from(chart).save(&dir.join(format!("spectrum-{k}-{}", s.dof)))?;
        }
        for p in &r.phase {
            let chart = LineChart::new(
                format!("{}: phase portrait of {}", r.record, p.dof),
                format!("{} (record units)", p.dof),
                format!("{}' (record units/s)", p.dof),
            )
            .with_series(Series::line("measured", p.measured.clone()))
            .with_series(Series::dashed("model", p.model.clone()));
            Figure::from(chart).save(&dir.join(format!("phase-{k}-{}", p.dof)))?;
        }
    }
    for l in &d.localisation {
        // Residual map as one line per x bin over x' (mean residual); the bins are ordered, so
        // their lines are coloured along a sequential scale instead of a repeating palette.
        let mut chart = LineChart::new(
            format!("Residual of {}'' over {}' per {} bin", l.dof, l.dof, l.dof),
            format!("{}' (record units/s)", l.dof),
            format!("mean residual of {}'' (record units/s²)", l.dof),
        );
        let m = &l.map;
        let bins = m.mean.len().max(2);
        for (i, row) in m.mean.iter().enumerate() {
            let pts: Vec<(f64, f64)> = row
                .iter()
                .enumerate()
                .filter(|(_, v)| v.is_finite())
                .map(|(j, v)| (0.5 * (m.v_edges[j] + m.v_edges[j + 1]), *v))
                .collect();
            if pts.len() >= 2 {
                let xc = 0.5 * (m.x_edges[i] + m.x_edges[i + 1]);
                chart = chart.with_series(
                    Series::line(format!("{} = {xc:.3}", l.dof), pts)
                        .shade(i as f64 / (bins - 1) as f64),
                );
            }
        }
        Figure::from(chart).save(&dir.join(format!("residual-map-{}", l.dof)))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::short_verdict;

    #[test]
    fn the_short_verdict_keeps_the_effect_and_the_flags() {
        assert_eq!(
            short_verdict("missing effect: stop (falls 90 % (p = 1e-3)); add it with --add stop"),
            "missing effect: stop; add it with --add stop"
        );
        assert_eq!(
            short_verdict("no missing effect (nothing is significant)"),
            "no missing effect (-v says why)"
        );
        assert_eq!(short_verdict("no missing effect"), "no missing effect");
    }
}
