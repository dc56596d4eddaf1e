//! The subcommands of the `tfs` binary and the helpers they share.

pub mod basin;
pub mod compare;
pub mod diagnose;
pub mod identify;
pub mod kresling;
pub mod med;
pub mod plots;
pub mod refit;
pub mod simulate;
pub mod systems;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use tfs::data::{CsvOptions, Record};
use tfs::library::Model;

/// Reads every file with validation; `required` columns must exist in each; records must agree.
pub fn read_records(paths: &[PathBuf], required: &[String]) -> Result<Vec<Record>> {
    if paths.is_empty() {
        bail!("no data files given; pass one or more CSV files");
    }
    let opts = CsvOptions::default().require(required.iter().cloned());
    let mut records = Vec::with_capacity(paths.len());
    for p in paths {
        records.push(tfs::data::read_csv_with(p, &opts)?);
    }
    tfs::data::check_consistent(&records)?;
    Ok(records)
}

/// Reads only the header-level facts of a file: its column names (for guessing DOFs and inputs).
pub fn peek_columns(path: &Path) -> Result<Vec<String>> {
    let r = tfs::data::read_csv_with(path, &CsvOptions::default().min_rows(2))?;
    Ok(r.names().to_vec())
}

/// DOF columns by the data contract: `x` or `x1`, `x2`, … (base columns `xb*` excluded).
pub fn guess_dofs(columns: &[String]) -> Vec<String> {
    let mut dofs: Vec<String> = columns
        .iter()
        .filter(|c| {
            c.as_str() == "x"
                || (c.len() > 1
                    && c.starts_with('x')
                    && c[1..].chars().all(|ch| ch.is_ascii_digit()))
        })
        .cloned()
        .collect();
    dofs.sort_by_key(|d| d[1..].parse::<u32>().unwrap_or(0));
    dofs
}

/// Input columns by the data contract: `xb_acc`, else `u`, `force` or `voltage`, whichever exist.
pub fn guess_inputs(columns: &[String]) -> Vec<String> {
    ["xb_acc", "u", "force", "voltage"]
        .iter()
        .filter(|n| columns.iter().any(|c| c == *n))
        .map(|s| s.to_string())
        .collect()
}

/// Reads a model file with its path in the error.
pub fn read_model(path: &Path) -> Result<Model> {
    Model::from_path(path).with_context(|| format!("reading model {}", path.display()))
}

/// Prints a value as pretty JSON on stdout.
pub fn print_json(value: &serde_json::Value) -> Result<()> {
    use std::io::Write;
    let text = serde_json::to_string_pretty(value)?;
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{text}").and_then(|()| out.flush()) {
        // A closed pipe (`tfs … --json | head`) is the reader's choice, not an error.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => Ok(r?),
    }
}

/// Parses `A:B` into a range with A < B; `what` names the flag in the error.
pub fn parse_range(text: &str, what: &str) -> Result<(f64, f64)> {
    let (a, b) = text
        .split_once(':')
        .with_context(|| format!("{what} '{text}': expected A:B, e.g. 0:2"))?;
    let a: f64 = a
        .trim()
        .parse()
        .with_context(|| format!("{what} '{text}': '{a}' is not a number"))?;
    let b: f64 = b
        .trim()
        .parse()
        .with_context(|| format!("{what} '{text}': '{b}' is not a number"))?;
    if !(a.is_finite() && b.is_finite() && a < b) {
        bail!("{what} '{text}': need finite A < B");
    }
    Ok((a, b))
}

/// Parses `NxM` into grid sizes ≥ 2.
pub fn parse_grid(text: &str) -> Result<(usize, usize)> {
    let (a, b) = text
        .split_once(['x', 'X'])
        .with_context(|| format!("--grid '{text}': expected NxM, e.g. 400x400"))?;
    let n: usize = a
        .trim()
        .parse()
        .with_context(|| format!("--grid '{text}': '{a}' is not a whole number"))?;
    let m: usize = b
        .trim()
        .parse()
        .with_context(|| format!("--grid '{text}': '{b}' is not a whole number"))?;
    if n < 2 || m < 2 || n * m > 25_000_000 {
        bail!("--grid '{text}': each side must be at least 2 and N·M at most 25,000,000");
    }
    Ok((n, m))
}

/// A progress bar drawn only when stderr is a terminal.
pub fn progress(len: u64, what: &str) -> indicatif::ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new(len);
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} ({eta})")
    {
        pb.set_style(style.progress_chars("=> "));
    }
    pb.set_message(what.to_string());
    pb
}
