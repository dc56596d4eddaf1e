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
use tfs::data::{CsvOptions, Record, Saturation};
use tfs::library::Model;

/// What to do with a channel that looks clipped (a run of samples stuck at its maximum or minimum).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Clipped {
    /// Refuse the file (default): clipped samples are wrong values and bias every coefficient.
    #[default]
    Error,
    /// Use the file anyway and print one warning line per clipped channel on stderr.
    Warn,
    /// Do not check.
    Allow,
}

/// Options shared by every command that reads measurement records.
#[derive(Debug, Clone, clap::Args)]
pub struct DataArgs {
    /// A channel whose samples sit at its maximum or minimum in a run (≥ 3 in a row, ≥ 1 % of the
    /// record) is clipped by the sensor or the acquisition card. Default: refuse the file.
    #[arg(long, value_enum, default_value_t = Clipped::Error)]
    pub clipped: Clipped,
}

impl DataArgs {
    /// The CSV options for these flags with `required` columns.
    pub fn csv_options(&self, required: &[String]) -> CsvOptions {
        let sat = match self.clipped {
            Clipped::Error => Saturation::Error,
            Clipped::Warn => Saturation::Warn,
            Clipped::Allow => Saturation::Allow,
        };
        CsvOptions::default()
            .require(required.iter().cloned())
            .saturation(sat)
    }
}

/// Reads every file with validation; `required` columns must exist in each; records must agree.
/// Warnings (clipped channels accepted with `--clipped warn`) go to stderr, one line each.
pub fn read_records(
    paths: &[PathBuf],
    required: &[String],
    data: &DataArgs,
) -> Result<Vec<Record>> {
    if paths.is_empty() {
        bail!("no data files given; pass one or more CSV files");
    }
    let opts = data.csv_options(required);
    let mut records = Vec::with_capacity(paths.len());
    for p in paths {
        let (rec, warnings) = tfs::data::read_csv_checked(p, &opts)?;
        for w in warnings {
            eprintln!("warning: {w}");
        }
        records.push(rec);
    }
    tfs::data::check_consistent(&records)?;
    Ok(records)
}

/// How per-channel DC offsets are treated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Offsets {
    /// `identify`: `remove` when every input column is a force-like channel (`u`, `force`,
    /// `voltage`, … — a rig recorded in raw units, where DC is a sensor or amplifier offset),
    /// `keep` when there is no input or a base-motion input (`xb_*`: the displacements are then
    /// geometric coordinates whose origin matters). Other commands: follow what the model's
    /// trace says `identify` did, else `keep`.
    Auto,
    /// Use the records as they are.
    Keep,
    /// Subtract each record's mean from every DOF and input column (each record its own mean).
    Remove,
    /// `identify` only: keep the records and add the constant term `1` to every library.
    ConstantTerm,
}

impl Offsets {
    /// The name used on the command line and in traces.
    pub fn name(self) -> &'static str {
        match self {
            Offsets::Auto => "auto",
            Offsets::Keep => "keep",
            Offsets::Remove => "remove",
            Offsets::ConstantTerm => "constant-term",
        }
    }
}

/// Mean of every listed column of every record (for the trace when offsets are kept).
fn channel_means(records: &[Record], channels: &[String]) -> Vec<serde_json::Value> {
    records
        .iter()
        .map(|r| {
            let means: serde_json::Map<String, serde_json::Value> = channels
                .iter()
                .filter_map(|c| {
                    let x = r.column(c)?;
                    let m = x.iter().sum::<f64>() / x.len().max(1) as f64;
                    Some((c.clone(), serde_json::json!(m)))
                })
                .collect();
            serde_json::json!({"record": r.source(), "mean": means})
        })
        .collect()
}

/// Applies an offsets mode already resolved to `Keep` or `Remove` to the records' `channels`
/// and returns what was done, as JSON for the trace: the mode, why, and per record either the
/// offsets removed or the channel means left in place.
pub fn apply_offsets(
    records: &mut [Record],
    channels: &[String],
    mode: Offsets,
    why: &str,
) -> Result<serde_json::Value> {
    let per_record = match mode {
        Offsets::Remove => {
            let mut out = Vec::with_capacity(records.len());
            for r in records.iter_mut() {
                let present: Vec<&String> =
                    channels.iter().filter(|c| r.column(c).is_some()).collect();
                let removed = r.remove_offsets(&present)?;
                let map: serde_json::Map<String, serde_json::Value> = removed
                    .into_iter()
                    .map(|(c, v)| (c, serde_json::json!(v)))
                    .collect();
                out.push(serde_json::json!({"record": r.source(), "removed": map}));
            }
            out
        }
        _ => channel_means(records, channels),
    };
    Ok(serde_json::json!({
        "mode": mode.name(),
        "why": why,
        "channels": channels,
        "per_record": per_record,
    }))
}

/// For commands that use a model (`compare`, `diagnose`, `refit`): resolves `--offsets` against
/// what the model's trace says `identify` did, applies it to the records' DOF and input columns,
/// and returns the report.
pub fn offsets_for_model(
    records: &mut [Record],
    model: &Model,
    channels: &[String],
    requested: Offsets,
) -> Result<serde_json::Value> {
    let identified = model
        .trace
        .get("offsets")
        .and_then(|o| o.get("mode"))
        .and_then(|m| m.as_str());
    let (mode, why) = match requested {
        Offsets::ConstantTerm => bail!(
            "--offsets constant-term applies to `tfs identify` only (it changes the library); use auto, keep or remove here"
        ),
        Offsets::Keep | Offsets::Remove => (requested, "given with --offsets".to_string()),
        Offsets::Auto => match identified {
            Some("remove") => (
                Offsets::Remove,
                "the model was identified on records with their offsets removed".to_string(),
            ),
            Some(m) => (
                Offsets::Keep,
                format!("the model was identified with offsets '{m}'"),
            ),
            None => (
                Offsets::Keep,
                "the model does not say how offsets were treated: records used as they are"
                    .to_string(),
            ),
        },
    };
    if let (Some(m), true) = (identified, requested != Offsets::Auto) {
        let same = (m == "remove") == (mode == Offsets::Remove);
        if !same {
            eprintln!(
                "warning: --offsets {} differs from how the model was identified (offsets '{m}'); its simulation will be shifted",
                mode.name()
            );
        }
    }
    apply_offsets(records, channels, mode, &why)
}

/// Reads only the header-level facts of a file: its column names (for guessing DOFs and inputs).
pub fn peek_columns(path: &Path) -> Result<Vec<String>> {
    // Only the names are used here: the full checks (clipping included) run when the records
    // are read with the command's options.
    let opts = CsvOptions::default()
        .min_rows(2)
        .saturation(Saturation::Allow);
    let r = tfs::data::read_csv_with(path, &opts)?;
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

/// The columns a record must hold to simulate `model`: its DOFs and its inputs, less the effect
/// columns `tfs diagnose`/`refit` add (delayed or filtered inputs, Maxwell elements), which are
/// computed from the record.
pub fn measured_columns(model: &Model) -> Vec<String> {
    let computed = tfs::diagnose::effects::computed_columns(model);
    let mut required = model.dofs.clone();
    required.extend(
        model
            .inputs
            .iter()
            .filter(|i| !computed.iter().any(|c| c.name() == **i))
            .cloned(),
    );
    required
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
