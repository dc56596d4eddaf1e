//! The `tfs` command-line tool: identify sparse equations of motion from CSV measurements, compare
//! them with held-out records, simulate the Kresling test structures, and map basins of attraction.

mod cmd;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// tfs — sparse equations of motion for multi-stable structures, from noisy vibration data.
#[derive(Debug, Parser)]
#[command(
    name = "tfs",
    version,
    about = "tfs — sparse equations of motion for multi-stable structures, from noisy vibration data (T-F-S SINDy)",
    long_about = None
)]
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
            // One line: the chain of causes joined, as the contract asks. Errors that already
            // print their cause (`… failed: {source}`) also return it as `source()`: a cause
            // whose text is already in the line is not repeated.
            let msg = one_line(&e);
            eprintln!("error: {}", msg.replace('\n', " "));
            ExitCode::from(2)
        }
    }
}

/// The error and its causes on one line, each cause once (the library's rule, so that the
/// Python package raises the same message).
fn one_line(e: &anyhow::Error) -> String {
    tfs::one_line(e.as_ref())
}

#[cfg(test)]
mod tests {
    use super::one_line;

    #[derive(Debug, thiserror::Error)]
    #[error("simulation of record 0 failed: {source}")]
    struct Outer {
        source: std::io::Error,
    }

    /// A cause that the error's own message already prints is not printed twice; a new one is.
    #[test]
    fn causes_are_joined_once() {
        let e = anyhow::Error::new(Outer {
            source: std::io::Error::other("blew up at t = 3 s"),
        })
        .context("simulating the dataset");
        assert_eq!(
            one_line(&e),
            "simulating the dataset: simulation of record 0 failed: blew up at t = 3 s"
        );
        let e = anyhow::anyhow!("inner").context("outer");
        assert_eq!(one_line(&e), "outer: inner");
    }
}
