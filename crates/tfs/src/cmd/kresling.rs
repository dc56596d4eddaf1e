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
    /// Write the potential and force curves to FILE.svg and FILE.png.
    #[arg(long)]
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
    if let Some(stem) = &args.plot {
        let stem = stem.with_extension("");
        // Frame the wells: a little past the outermost equilibrium, a sliver of the folded stop.
        let outer = s
            .stable
            .iter()
            .chain(&s.unstable)
            .cloned()
            .fold(1.0, f64::max);
        let h_hi = cell.h_max().min(1.12 * outer);
        let h_lo = -0.01 * outer;
        let curve = cell.curve(h_lo, h_hi, 600)?;
        let v: Vec<(f64, f64)> = curve
            .h
            .iter()
            .copied()
            .zip(curve.v.iter().copied())
            .collect();
        let f: Vec<(f64, f64)> = curve
            .h
            .iter()
            .copied()
            .zip(curve.f.iter().copied())
            .collect();
        let title = format!(
            "Kresling cell a0 = {}, c0 = {}, γ0 = {}° ({})",
            args.a0, args.c0, args.gamma0, s.classification
        );
        let mut pot = LineChart::new(format!("{title}: potential"), "height h", "potential V(h)")
            .with_series(Series::line("V(h) truss", v));
        for (k, h) in s.stable.iter().enumerate() {
            pot = pot.with_marker(*h, cell.potential(*h), format!("S{}", k + 1));
        }
        for h in &s.unstable {
            pot = pot.with_marker(*h, cell.potential(*h), "unstable");
        }
        files.extend(Figure::from(pot).save(&stem.with_file_name(format!(
            "{}-potential",
            stem.file_name().and_then(|n| n.to_str()).unwrap_or("kresling")
        )))?);
        let force = LineChart::new(
            format!("{title}: axial force"),
            "height h",
            "force F(h) = dV/dh",
        )
        .with_series(Series::line("F(h) truss", f))
        .with_series(Series::dashed("zero", vec![(h_lo, 0.0), (h_hi, 0.0)]).color(7));
        files.extend(Figure::from(force).save(&stem.with_file_name(format!(
            "{}-force",
            stem.file_name().and_then(|n| n.to_str()).unwrap_or("kresling")
        )))?);
    }
    let files: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
    if args.json {
        let mut v = serde_json::to_value(&s)?;
        v["files"] = json!(files);
        print_json(&v)?;
    } else {
        println!("b0 = {:.6}", s.b0);
        println!("classification: {}", s.classification);
        println!("stable states h: {:?}", s.stable);
        println!("unstable states h: {:?}", s.unstable);
        match s.barrier {
            Some(b) => println!("barrier (from the folded state): {b:.6}"),
            None => println!("barrier: none (monostable)"),
        }
        for f in &files {
            println!("written: {f}");
        }
    }
    Ok(())
}
