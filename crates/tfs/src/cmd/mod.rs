//! The subcommands of the `tfs` binary and the helpers they share.

pub mod basin;
pub mod chain_basin;
pub mod columns;
pub mod compare;
pub mod diagnose;
pub mod identify;
pub mod kresling;
pub mod med;
pub mod paths;
pub mod plots;
pub mod refit;
pub mod simulate;
pub mod trace_view;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use tfs::data::Record;
use tfs::library::Model;
pub use tfs::records::{Clipped, Offsets};

/// `--offsets` of the commands that use a model (`compare`, `diagnose`, `refit`): the modes
/// of [`Offsets`] less `constant-term`, which changes the library and so belongs to `identify`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModelOffsets {
    /// Do what `tfs identify` did for this model (its trace says so), else keep.
    Auto,
    /// Use the records as they are.
    Keep,
    /// Subtract each record's mean from every DOF and input column.
    Remove,
}

impl From<ModelOffsets> for Offsets {
    fn from(m: ModelOffsets) -> Self {
        match m {
            ModelOffsets::Auto => Offsets::Auto,
            ModelOffsets::Keep => Offsets::Keep,
            ModelOffsets::Remove => Offsets::Remove,
        }
    }
}

/// Prints warnings once where a person sees them: on stderr, and as `WARNING …` lines on stdout
/// too when stdout goes to a file or a pipe (so a saved report keeps them); on a terminal the
/// two streams are the same screen and each warning is shown once.
pub fn print_warnings(warnings: &[String]) {
    use std::io::IsTerminal;
    let both_on_screen = std::io::stdout().is_terminal() && std::io::stderr().is_terminal();
    for w in warnings {
        eprintln!("warning: {w}");
        if !both_on_screen {
            println!("WARNING {w}");
        }
    }
}

/// Options shared by every command that reads measurement records.
#[derive(Debug, Clone, clap::Args)]
pub struct DataArgs {
    /// A channel whose samples sit at its maximum or minimum in a run (≥ 3 in a row, ≥ 1 % of the
    /// record) is clipped by the sensor or the acquisition card. Default: refuse the file.
    #[arg(long, value_enum, default_value_t = Clipped::Error)]
    pub clipped: Clipped,
    /// The name of the time column (seconds) in the CSV files.
    #[arg(long, default_value = "t")]
    pub time_column: String,
}

/// Prints warnings on stderr, one line each.
fn warn_all(warnings: Vec<String>) {
    for w in warnings {
        eprintln!("warning: {w}");
    }
}

/// Reads every file once with validation (`-` is standard input); `required` columns must exist
/// in each; records must agree and be different recordings. Warnings (clipped channels accepted
/// with `--clipped warn`) go to stderr, one line each.
pub fn read_records(
    paths: &[PathBuf],
    required: &[String],
    data: &DataArgs,
) -> Result<Vec<Record>> {
    records_from(tfs::records::read_tables(paths)?, required, data)
}

/// Validates tables already read (see [`read_records`]).
pub fn records_from(
    tables: Vec<tfs::data::CsvTable>,
    required: &[String],
    data: &DataArgs,
) -> Result<Vec<Record>> {
    let (records, warnings) =
        tfs::records::records_from(tables, required, data.clipped, &data.time_column)?;
    warn_all(warnings);
    Ok(records)
}

/// Checks an output path before anything is computed: it must not be one of the `inputs`
/// (writing there would replace a measurement or a model with the result) nor a file tfs may
/// not replace (see [`paths::check_outputs`]), and its folder is created when missing. `flag`
/// names the option in messages.
pub fn prepare_output(out: &Path, inputs: &[&Path], flag: &str) -> Result<()> {
    paths::check_outputs(out, &[out.to_path_buf()], inputs, flag)
}

/// Writes a model file atomically (the previous file survives any failure).
pub fn write_model(model: &Model, path: &Path, flag: &str) -> Result<()> {
    model
        .write_path(path)
        .with_context(|| format!("{flag} {}", path.display()))
}

/// A spinner with the step's name and the time elapsed, for a step whose length is not known in
/// advance (diagnosis, refinement); drawn only when stderr is a terminal.
pub fn spinner(what: &str) -> indicatif::ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new_spinner();
    if let Ok(style) = indicatif::ProgressStyle::with_template("{spinner} {msg} ({elapsed})") {
        pb.set_style(style);
    }
    pb.set_message(what.to_string());
    pb.enable_steady_tick(std::time::Duration::from_millis(120));
    pb
}

/// Runs `step` under a [`spinner`] named `what`.
pub fn with_spinner<T>(what: &str, step: impl FnOnce() -> T) -> T {
    let pb = spinner(what);
    let out = step();
    pb.finish_and_clear();
    out
}

/// For commands that use a model (`compare`, `diagnose`, `refit`): resolves `--offsets` against
/// what the model's trace says `identify` did, applies it to the records' DOF and input columns,
/// and returns the report (a contradicting request is warned about on stderr).
pub fn offsets_for_model(
    records: &mut [Record],
    model: &Model,
    channels: &[String],
    requested: Offsets,
) -> Result<tfs::report::OffsetsReport> {
    let (report, warning) = tfs::records::offsets_for_model(records, model, channels, requested)?;
    if let Some(w) = warning {
        eprintln!("warning: {w}");
    }
    Ok(report)
}

/// The note [`tfs::records::memory_offsets_note`] gives for a `model` with an internal state on
/// `records` treated as `offsets` says; `None` for a model without memory.
pub fn state_offsets_note(
    model: &Model,
    offsets: &tfs::report::OffsetsReport,
    records: &[Record],
) -> Option<String> {
    let (v, law) = model.internal_states().into_iter().next()?;
    let memory = format!("the model has a {} state of {v}", law.name());
    tfs::records::memory_offsets_note(offsets, records, &model.dofs, &memory)
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
