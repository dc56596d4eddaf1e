//! The `tfs` command-line tool: identify sparse equations of motion from CSV measurements, compare
//! them with held-out records, simulate the Kresling test structures, and map basins of attraction.

mod cmd;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// tfs — sparse equations of motion for multi-stable structures, from noisy vibration data.
#[derive(Debug, Parser)]
#[command(name = "tfs", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Identify a sparse second-order model from one or more CSV records (stacked).
    Identify(cmd::identify::Args),
    /// Simulate a model under each file's measured input and report R-MSE per file.
    Compare(cmd::compare::Args),
    /// Diagnose a model against measurements: where it fails and which physical effect is missing.
    Diagnose(cmd::diagnose::Args),
    /// Add named physical effects to a model and refit it, keeping its history (error ladder).
    Refit(cmd::refit::Args),
    /// Kresling truss cell: b0, stable and unstable states, barrier, potential/force plot.
    Kresling(cmd::kresling::Args),
    /// Simulate a test structure (Kresling cell or chain) under base excitation, write CSV.
    Simulate(cmd::simulate::Args),
    /// Basin of attraction map of a 1-DOF model (optionally against a truth).
    Basin(cmd::basin::Args),
    /// Minimum-energy deployment of a 1-DOF bistable model.
    Med(cmd::med::Args),
}

fn main() -> ExitCode {
    // Like other Unix filters, end quietly when the reader closes the pipe (`tfs … | head`)
    // instead of failing on the next write.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Identify(a) => cmd::identify::run(a),
        Command::Compare(a) => cmd::compare::run(a),
        Command::Diagnose(a) => cmd::diagnose::run(a),
        Command::Refit(a) => cmd::refit::run(a),
        Command::Kresling(a) => cmd::kresling::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Basin(a) => cmd::basin::run(a),
        Command::Med(a) => cmd::med::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the chain of causes joined, as the contract asks.
            let msg = e
                .chain()
                .map(|c| c.to_string())
                .collect::<Vec<_>>()
                .join(": ");
            eprintln!("error: {}", msg.replace('\n', " "));
            ExitCode::from(2)
        }
    }
}
