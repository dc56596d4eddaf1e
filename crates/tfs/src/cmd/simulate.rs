//! `tfs simulate kresling|chain`: generate base-excitation records of the test structures with
//! measurement noise, as CSV (clean truth columns kept apart) plus a metadata JSON.

use std::path::PathBuf;

use anyhow::Result;
use clap::{Subcommand, ValueEnum};
use serde_json::json;
use tfs::origami::Truth;
use tfs::simulate::{
    CELL_DURATION, CELL_EXCITATIONS, CHAIN_DURATION, CHAIN_EXCITATIONS, DatasetRequest, dataset,
    stop_contacts,
};

use super::print_json;

/// Arguments of `tfs simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The structure.
    #[command(subcommand)]
    pub structure: Structure,
}

/// Which structure to simulate.
#[derive(Debug, Subcommand)]
pub enum Structure {
    /// One Kresling cell (DOF `x`).
    Kresling {
        /// Crease-pattern angle γ0 (degrees).
        #[arg(long, default_value_t = 30.0)]
        gamma0: f64,
        /// Common options.
        #[command(flatten)]
        common: Common,
    },
    /// A serial chain of Kresling cells, base cell first (DOFs `x1..xN`).
    Chain {
        /// γ0 of each cell (degrees), comma-separated, base cell first [default: 20,28.5].
        #[arg(
            long,
            value_delimiter = ',',
            default_values_t = [20.0, 28.5],
            hide_default_value = true
        )]
        gamma0: Vec<f64>,
        /// Common options.
        #[command(flatten)]
        common: Common,
    },
}

/// Force law simulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TruthArg {
    /// The paper's {h^5, h^6, h^7} least-squares surrogate of the truss force.
    Surrogate,
    /// The truss force itself, with the folded stop.
    Truss,
}

/// Options shared by both structures.
#[derive(Debug, clap::Args)]
pub struct Common {
    /// Truth (force law). Default: `surrogate` for one cell (the paper's S-DOF case), `truss`
    /// for a chain (the paper's chain truth; a cell's surrogate polynomial is fitted on
    /// 0 ≤ h ≤ 1.7 and has no folded stop, so a chain driven below h = 0 runs away).
    #[arg(long, value_enum)]
    pub truth: Option<TruthArg>,
    /// Excitation: sweep:F0:F1:AMP (linear sweep, Hz, acceleration) or sine:F:AMP; repeat for
    /// several records [default: one cell sweep:0.05:1.5:4; a chain four sweeps
    /// sweep:0.05:1.5:1.5, :2, :2.5 and :3, which stay off its folded stop but for brief touches].
    #[arg(long = "excitation")]
    pub excitations: Vec<String>,
    /// Record length (s) [default: 100 for one cell, 50 for a chain].
    #[arg(long)]
    pub duration: Option<f64>,
    /// Sampling interval (s).
    #[arg(long, default_value_t = 0.005)]
    pub dt: f64,
    /// Ramp-in/out time of the excitation (s).
    #[arg(long, default_value_t = 2.0)]
    pub ramp: f64,
    /// SNR (dB) of the noise on every measured channel; omit for clean data. Below 0 dB the
    /// noise is stronger than the signal (`--snr-db -10`: ten times its power).
    #[arg(long, allow_negative_numbers = true)]
    pub snr_db: Option<f64>,
    /// Pink (1/f) instead of white noise.
    #[arg(long)]
    pub pink: bool,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output CSV; with several records, `-1`, `-2`, … are added before the extension.
    #[arg(long)]
    pub out: PathBuf,
    /// Print the metadata as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Runs `tfs simulate`.
pub fn run(args: Args) -> Result<()> {
    let (cells, common) = match &args.structure {
        Structure::Kresling { gamma0, common } => (vec![*gamma0], common),
        Structure::Chain { gamma0, common } => (gamma0.clone(), common),
    };
    let (default_excitations, default_duration): (&[&str], f64) = match args.structure {
        Structure::Kresling { .. } => (&CELL_EXCITATIONS, CELL_DURATION),
        Structure::Chain { .. } => (&CHAIN_EXCITATIONS, CHAIN_DURATION),
    };
    let req = DatasetRequest {
        gamma0: cells,
        chain: matches!(args.structure, Structure::Chain { .. }),
        truth: common.truth.map(|t| match t {
            TruthArg::Surrogate => Truth::Surrogate,
            TruthArg::Truss => Truth::Truss,
        }),
        excitations: if common.excitations.is_empty() {
            default_excitations.iter().map(|e| e.to_string()).collect()
        } else {
            common.excitations.clone()
        },
        duration: common.duration.unwrap_or(default_duration),
        dt: common.dt,
        ramp: common.ramp,
        snr_db: common.snr_db,
        pink: common.pink,
        seed: common.seed,
    };
    let (csvs, meta_path) = super::paths::simulate_outputs(&common.out, req.excitations.len());
    let mut all = csvs.clone();
    all.push(meta_path.clone());
    super::paths::check_outputs(&common.out, &all, &[], "--out")?;
    let data = dataset(&req)?;
    let files = super::paths::write_record_set(&common.out, &data.records, &data.meta)?;
    let contacts = stop_contacts(&data);
    if common.json {
        let stops: Vec<_> = contacts
            .iter()
            .map(|c| json!({"record": files.get(data.records.iter().position(|r| r.source() == c.record).unwrap_or(0)), "cell": c.cell, "share": c.share, "min_h": c.min_h}))
            .collect();
        print_json(
            &json!({"files": files, "meta": data.meta, "meta_file": meta_path.display().to_string(), "stop_contacts": stops}),
        )?;
    } else {
        if let Some(snr) = common.snr_db.filter(|v| *v < 0.0) {
            println!(
                "note: SNR {snr} dB: the noise has {:.3} times the power of each signal",
                10f64.powf(-snr / 10.0)
            );
        }
        println!("truth: {}", data.meta.truth);
        for f in &files {
            println!("written: {f}");
        }
        println!("metadata: {}", meta_path.display());
        print_contacts(&contacts, &data, &files);
    }
    Ok(())
}

/// The folded-stop contacts per record and cell, as a table, when any cell went below h = 0.
fn print_contacts(
    contacts: &[tfs::simulate::StopContact],
    data: &tfs::origami::Dataset,
    files: &[String],
) {
    if !contacts.iter().any(|c| c.share > 0.0) {
        return;
    }
    println!(
        "folded stop (cell height h < 0: the cell pressed flat, a contact no polynomial force law represents):"
    );
    println!(
        "  {:<30} {:>5} {:>12} {:>10}",
        "file", "cell", "time at h<0", "lowest h"
    );
    for c in contacts {
        let k = data
            .records
            .iter()
            .position(|r| r.source() == c.record)
            .unwrap_or(0);
        println!(
            "  {:<30} {:>5} {:>11.3}% {:>10.4}",
            files.get(k).map(String::as_str).unwrap_or(&c.record),
            c.cell,
            100.0 * c.share,
            c.min_h.min(0.0)
        );
    }
}
