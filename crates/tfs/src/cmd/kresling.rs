//! `tfs kresling`: the Kresling truss cell of the paper's Appendix A — b0, stable and unstable
//! states, the barrier, and (with `--plot`) its potential and force curves.

use std::path::PathBuf;

use anyhow::{Context, Result};
use serde_json::json;
use tfs::origami::{KreslingCell, KreslingParams};
use tfs::plot::{Figure, LineChart, Series};

use super::print_json;

/// Arguments of `tfs kresling`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Crease length a0.
    #[arg(long, default_value_t = 1.6)]
    pub a0: f64,
    /// Base polygon side c0.
    #[arg(long, default_value_t = 1.0)]
    pub c0: f64,
    /// Crease-pattern angle γ0 (degrees).
    #[arg(long, default_value_t = 30.0)]
    pub gamma0: f64,
    /// Stiffness of the a creases.
    #[arg(long, default_value_t = 9.30)]
    pub ka: f64,
    /// Stiffness of the b creases.
    #[arg(long, default_value_t = 9.30)]
    pub kb: f64,
    /// Moving mass.
    #[arg(long, default_value_t = 1.0)]
    pub mass: f64,
    /// Viscous damping coefficient.
    #[arg(long, default_value_t = 2.0)]
    pub damping: f64,
    /// Write the potential and force curves into this directory: `potential.svg`/`.png` and
    /// `force.svg`/`.png`.
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
    /// Older form of --plots: write `PREFIX-potential.svg`/`.png` and `PREFIX-force.svg`/`.png`.
    #[arg(long, value_name = "PREFIX", conflicts_with = "plots")]
    pub plot: Option<PathBuf>,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Runs `tfs kresling`.
pub fn run(args: Args) -> Result<()> {
    let params = KreslingParams {
        a0: args.a0,
        c0: args.c0,
        gamma0_deg: args.gamma0,
        k_a: args.ka,
        k_b: args.kb,
        m: args.mass,
        c: args.damping,
        ..KreslingParams::default()
    };
    let cell = KreslingCell::new(params).context("Kresling cell")?;
    let s = cell.summary();
    let mut files = Vec::new();
    let stems = match (&args.plots, &args.plot) {
        (Some(dir), _) => Some((dir.join("potential"), dir.join("force"))),
        (None, Some(prefix)) => {
            let stem = prefix.with_extension("");
            let name = stem
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or("kresling")
                .to_string();
            Some((
                stem.with_file_name(format!("{name}-potential")),
                stem.with_file_name(format!("{name}-force")),
            ))
        }
        (None, None) => None,
    };
    if let Some((pot_stem, force_stem)) = stems {
        files = plot_cell(&cell, &s, &args, &pot_stem, &force_stem)?;
    }
    let files: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
    if args.json {
        let mut v = serde_json::to_value(&s)?;
        v["files"] = json!(files);
        print_json(&v)?;
    } else {
        let list = |v: &[f64]| {
            if v.is_empty() {
                "none".to_string()
            } else {
                v.iter()
                    .map(|h| format!("{h:.4}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        };
        println!("b0 = {:.5}", s.b0);
        println!("classification: {}", s.classification);
        println!("stable states h: {}", list(&s.stable));
        println!("unstable states h: {}", list(&s.unstable));
        match s.barrier {
            Some(b) => println!("barrier (from the folded state): {b:.5}"),
            None => println!("barrier: none (monostable)"),
        }
        for f in &files {
            println!("written: {f}");
        }
    }
    Ok(())
}

/// The potential and force curves of `cell` over its wells. The folded stop (h < 0, a stiff
/// contact) would flatten the force curve to a spike: the force axis is fitted to the wells and
/// the stop is marked by a line at h = 0 instead.
fn plot_cell(
    cell: &KreslingCell,
    s: &tfs::origami::CellSummary,
    args: &Args,
    pot_stem: &std::path::Path,
    force_stem: &std::path::Path,
) -> Result<Vec<PathBuf>> {
    // Frame the wells: a little past the outermost equilibrium, a sliver of the folded stop.
    let outer = s
        .stable
        .iter()
        .chain(&s.unstable)
        .cloned()
        .fold(1.0, f64::max);
    let h_hi = cell.h_max().min(1.12 * outer);
    let h_lo = -0.03 * outer;
    let curve = cell.curve(h_lo, h_hi, 600)?;
    let pts =
        |y: &[f64]| -> Vec<(f64, f64)> { curve.h.iter().copied().zip(y.iter().copied()).collect() };
    // the force range of the wells (h ≥ 0), padded
    let (lo, hi) = curve
        .h
        .iter()
        .zip(&curve.f)
        .filter(|(h, _)| **h >= 0.0)
        .fold((0.0_f64, 0.0_f64), |(a, b), (_, f)| (a.min(*f), b.max(*f)));
    let pad = 0.15 * (hi - lo).max(f64::MIN_POSITIVE);
    let f_range = (lo - pad, hi + pad);
    // past the stop the contact force leaves the range: the line is broken there
    let f: Vec<(f64, f64)> = pts(&curve.f)
        .into_iter()
        .map(|(h, v)| {
            (
                h,
                if v >= f_range.0 && v <= f_range.1 {
                    v
                } else {
                    f64::NAN
                },
            )
        })
        .collect();
    let title = format!(
        "Kresling cell a0 = {}, c0 = {}, γ0 = {}° ({})",
        args.a0, args.c0, args.gamma0, s.classification
    );
    let mut pot = LineChart::new(
        format!("{title}: potential"),
        "height h (c0)",
        "potential V(h) (k·c0²)",
    )
    .with_series(Series::line("V(h) truss", pts(&curve.v)))
    .with_vline(0.0, "folded stop");
    for (k, h) in s.stable.iter().enumerate() {
        pot = pot.with_marker(*h, cell.potential(*h), format!("S{}", k + 1));
    }
    for h in &s.unstable {
        pot = pot.with_marker(*h, cell.potential(*h), "unstable");
    }
    let mut files = Figure::from(pot).save(pot_stem)?;
    let mut force = LineChart::new(
        format!("{title}: axial force"),
        "height h (c0)",
        "force F(h) = dV/dh (k·c0)",
    )
    .with_series(Series::line("F(h) truss", f))
    .with_series(Series::dashed("", vec![(h_lo, 0.0), (h_hi, 0.0)]).color(7))
    .with_vline(0.0, "folded stop: contact force below, off the scale");
    force.y_range = Some(f_range);
    for (k, h) in s.stable.iter().enumerate() {
        force = force.with_marker(*h, 0.0, format!("S{}", k + 1));
    }
    files.extend(Figure::from(force).save(force_stem)?);
    Ok(files)
}
