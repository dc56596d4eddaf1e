//! Records as every command and the Python package read them: validation with the clipped-channel
//! policy, the DOF and input columns by the data contract, and the per-channel offsets policy.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use tfs_data::{CsvOptions, CsvTable, Record, Saturation};
use tfs_library::Model;

use crate::error::{Context, Result};
use crate::invalid;
use crate::report::{OffsetsReport, RecordOffsets};

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

impl Clipped {
    /// The policy by its name (`error`, `warn`, `allow`); the error names `what`.
    pub fn parse(text: &str, what: &str) -> Result<Self> {
        match text {
            "error" => Ok(Clipped::Error),
            "warn" => Ok(Clipped::Warn),
            "allow" => Ok(Clipped::Allow),
            _ => invalid!("{what} '{text}': expected error, warn or allow"),
        }
    }

    /// The CSV options for this policy with `required` columns.
    pub fn csv_options(self, required: &[String]) -> CsvOptions {
        let sat = match self {
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
/// Returns the records and the warnings (clipped channels accepted with [`Clipped::Warn`],
/// timestamps put back on their grid), one line each. Each file is read once (`-` is standard
/// input); a file given twice, or two files with the same samples, are refused.
pub fn read_records(
    paths: &[PathBuf],
    required: &[String],
    clipped: Clipped,
) -> Result<(Vec<Record>, Vec<String>)> {
    records_from(read_tables(paths)?, required, clipped, "t")
}

/// How a path names its file for "the same file twice": device and inode where the file
/// exists (a link or another spelling of the path is the same file), else the path as given.
pub fn file_identity(p: &Path) -> String {
    if p.as_os_str() == "-" {
        return "-".into();
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let Ok(m) = std::fs::metadata(p) {
            return format!("{}:{}", m.dev(), m.ino());
        }
    }
    std::fs::canonicalize(p)
        .unwrap_or_else(|_| p.to_path_buf())
        .display()
        .to_string()
}

/// Refuses a file given twice among `paths` (by identity, so `./a.csv` and `a.csv` are one):
/// a record counted twice looks like twice the evidence and narrows every interval.
pub fn refuse_repeated(paths: &[&Path]) -> Result<()> {
    let ids: Vec<String> = paths.iter().map(|p| file_identity(p)).collect();
    for j in 0..ids.len() {
        if let Some(i) = ids[..j].iter().position(|id| *id == ids[j]) {
            invalid!(
                "{} is given twice (as {} and {}); pass each record once: a record counted twice looks like twice the evidence and narrows the intervals",
                paths[j].display(),
                paths[i].display(),
                paths[j].display()
            );
        }
    }
    Ok(())
}

/// Reads every file once (`-` is standard input), without validating it against options yet:
/// the column names can be looked at first. A file given twice is refused. The files are read
/// in parallel and kept in order; an error is the first file's in that order (the same as
/// reading one after the other).
pub fn read_tables(paths: &[PathBuf]) -> Result<Vec<CsvTable>> {
    use rayon::prelude::*;
    if paths.is_empty() {
        invalid!("no data files given; pass one or more CSV files");
    }
    refuse_repeated(&paths.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    let tables: Vec<_> = paths.par_iter().map(tfs_data::read_table).collect();
    Ok(tables
        .into_iter()
        .collect::<std::result::Result<Vec<_>, _>>()?)
}

/// Validates tables read by [`read_tables`] (time column `time_column`): `required` columns
/// must exist in each; records must agree and be different recordings. Returns the records and
/// the warnings, one line each.
pub fn records_from(
    tables: Vec<CsvTable>,
    required: &[String],
    clipped: Clipped,
    time_column: &str,
) -> Result<(Vec<Record>, Vec<String>)> {
    use rayon::prelude::*;
    let opts = clipped.csv_options(required).time_column(time_column);
    let mut records = Vec::with_capacity(tables.len());
    let mut warnings = Vec::new();
    // Each table is validated on its own, in parallel; results, warnings and the first error
    // are taken in file order.
    let checked: Vec<_> = tables
        .into_par_iter()
        .map(|t| t.into_record(&opts))
        .collect();
    for c in checked {
        let (rec, w) = c?;
        warnings.extend(w.iter().map(ToString::to_string));
        records.push(rec);
    }
    tfs_data::check_consistent(&records)?;
    for j in 0..records.len() {
        if let Some(i) = (0..j).find(|&i| same_samples(&records[i], &records[j])) {
            invalid!(
                "{} and {} hold the same samples; pass each record once: a record counted twice looks like twice the evidence and narrows the intervals",
                records[i].source(),
                records[j].source()
            );
        }
    }
    Ok((records, warnings))
}

/// Two records with the same time axis and the same values in every column (to the bit).
fn same_samples(a: &Record, b: &Record) -> bool {
    a.len() == b.len()
        && a.t() == b.t()
        && a.names() == b.names()
        && a.names().iter().all(|n| a.column(n) == b.column(n))
}

/// Validates records built in memory by the rules [`read_records`] applies to files (the same
/// `required` columns and clipped policy) and checks that they agree; returns the records
/// (timestamps put back on their grid where they were rounded) and the warnings.
pub fn check_records(
    records: Vec<Record>,
    required: &[String],
    clipped: Clipped,
) -> Result<(Vec<Record>, Vec<String>)> {
    if records.is_empty() {
        invalid!("no records given; pass one or more records");
    }
    let opts = clipped.csv_options(required);
    let mut out = Vec::with_capacity(records.len());
    let mut warnings = Vec::new();
    for r in records {
        let (rec, w) = tfs_data::check_record(r, &opts)?;
        warnings.extend(w.iter().map(ToString::to_string));
        out.push(rec);
    }
    tfs_data::check_consistent(&out)?;
    Ok((out, warnings))
}

/// How per-channel DC offsets are treated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Offsets {
    /// `identify`: with force-like input channels (`u`, `force`, `voltage`) the records are
    /// identified both as `constant-term` (a constant force or sensor offset estimated with the
    /// model, dropped when the records do not need it) and as `remove`, and the means are
    /// removed only when that law predicts the held-out rows as well and is worth its terms
    /// (`crate::offsets_choice`); a constant the kept law holds is likewise checked against
    /// the law found without it (`keep`); `keep` when
    /// there is no input or a base-motion input (`xb_*`: the displacements are then geometric
    /// coordinates whose origin matters). Other commands: follow what the model's trace says
    /// `identify` did, else `keep`.
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

    /// The mode by its name (`auto`, `keep`, `remove`, `constant-term`); the error names `what`.
    pub fn parse(text: &str, what: &str) -> Result<Self> {
        match text {
            "auto" => Ok(Offsets::Auto),
            "keep" => Ok(Offsets::Keep),
            "remove" => Ok(Offsets::Remove),
            "constant-term" => Ok(Offsets::ConstantTerm),
            _ => invalid!("{what} '{text}': expected auto, keep, remove or constant-term"),
        }
    }
}

/// Mean of every listed column of every record (for the report when offsets are kept).
fn channel_means(records: &[Record], channels: &[String]) -> Vec<RecordOffsets> {
    records
        .iter()
        .map(|r| {
            let mean = channels
                .iter()
                .filter_map(|c| {
                    let x = r.column(c)?;
                    let m = x.iter().sum::<f64>() / x.len().max(1) as f64;
                    Some((c.clone(), m))
                })
                .collect();
            RecordOffsets::Kept {
                record: r.source().to_string(),
                mean,
            }
        })
        .collect()
}

/// Applies an offsets mode already resolved to `Keep` or `Remove` to the records' `channels`
/// and returns what was done: the mode, why, and per record either the offsets removed or the
/// channel means left in place.
pub fn apply_offsets(
    records: &mut [Record],
    channels: &[String],
    mode: Offsets,
    why: &str,
) -> Result<OffsetsReport> {
    let per_record = match mode {
        Offsets::Remove => {
            let mut out = Vec::with_capacity(records.len());
            for r in records.iter_mut() {
                let present: Vec<&String> =
                    channels.iter().filter(|c| r.column(c).is_some()).collect();
                let removed = r.remove_offsets(&present)?.into_iter().collect();
                out.push(RecordOffsets::Removed {
                    record: r.source().to_string(),
                    removed,
                });
            }
            out
        }
        _ => channel_means(records, channels),
    };
    Ok(OffsetsReport {
        mode,
        why: why.to_string(),
        channels: channels.to_vec(),
        per_record,
        requested: None,
        constant_term_added: None,
    })
}

/// The offsets mode a model's trace says `identify` used (`None` for a model file that does
/// not say, or says it in a form this version does not know).
fn identified_mode(model: &Model) -> Option<Offsets> {
    let mode = model.trace.get("offsets")?.get("mode")?;
    serde_json::from_value(mode.clone()).ok()
}

/// For commands that use a model (`compare`, `diagnose`, `refit`): resolves `requested` against
/// what the model's trace says `identify` did, applies it to the records' DOF and input columns,
/// and returns the report and, when the request contradicts how the model was identified, a
/// warning.
pub fn offsets_for_model(
    records: &mut [Record],
    model: &Model,
    channels: &[String],
    requested: Offsets,
) -> Result<(OffsetsReport, Option<String>)> {
    let identified = identified_mode(model);
    let (mode, why) = match requested {
        Offsets::ConstantTerm => invalid!(
            "--offsets constant-term applies to `tfs identify` only (it changes the library); use auto, keep or remove here"
        ),
        Offsets::Keep | Offsets::Remove => (requested, "given with --offsets".to_string()),
        Offsets::Auto => match identified {
            Some(Offsets::Remove) => (
                Offsets::Remove,
                "the model was identified on records with their offsets removed".to_string(),
            ),
            Some(m) => (
                Offsets::Keep,
                format!("the model was identified with offsets '{}'", m.name()),
            ),
            None => (
                Offsets::Keep,
                "the model does not say how offsets were treated: records used as they are"
                    .to_string(),
            ),
        },
    };
    let mut warning = None;
    if let (Some(m), true) = (identified, requested != Offsets::Auto) {
        let same = (m == Offsets::Remove) == (mode == Offsets::Remove);
        if !same {
            warning = Some(format!(
                "--offsets {} differs from how the model was identified (offsets '{}'); its simulation will be shifted",
                mode.name(),
                m.name()
            ));
        }
    }
    Ok((apply_offsets(records, channels, mode, &why)?, warning))
}

/// A note for when removing each record's mean may have removed motion: `report` is what
/// [`offsets_for_model`] or [`apply_offsets`] did to `records` (after the removal), `dofs` the
/// displacement columns, and `memory` names what has memory (the model's internal state, or an
/// effect found to be missing). A structure with memory (hysteresis, a Maxwell element, Dahl
/// friction) comes to rest at a mean position that depends on its history, so a record's mean
/// displacement is motion the model must reproduce, not necessarily a sensor offset. `None`
/// unless the means were removed and a displacement's mean was at least 0.01 % of its RMS.
pub fn memory_offsets_note(
    report: &OffsetsReport,
    records: &[Record],
    dofs: &[String],
    memory: &str,
) -> Option<String> {
    if report.mode != Offsets::Remove {
        return None;
    }
    let mut worst: Vec<String> = Vec::new();
    for d in dofs {
        let share = records
            .iter()
            .zip(&report.per_record)
            .filter_map(|(r, p)| {
                let RecordOffsets::Removed { removed, .. } = p else {
                    return None;
                };
                let (x, m) = (r.column(d)?, removed.get(d)?);
                let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt();
                (rms > 0.0).then(|| m.abs() / rms)
            })
            .fold(0.0, f64::max);
        // Below 0.01 % of the RMS a mean is rounding, not motion.
        if share >= 1e-4 {
            worst.push(format!("{d} up to {:.3} % of its RMS", 100.0 * share));
        }
    }
    (!worst.is_empty()).then(|| {
        format!(
            "{memory}: a structure with memory comes to rest at a mean position that depends on its history, so the means removed from the records ({}) may be motion rather than sensor offsets; if the sensors have no offset, use --offsets keep",
            worst.join(", ")
        )
    })
}

/// Reads only the header-level facts of a file: its column names (for guessing DOFs and inputs).
/// A caller that reads the records too should use [`read_tables`] instead (one read per file).
pub fn peek_columns(path: &Path) -> Result<Vec<String>> {
    let names = tfs_data::read_table(path)?.names().to_vec();
    Ok(names.into_iter().filter(|n| n != "t").collect())
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
    tfs_diagnose::effects::CONTRACT_INPUTS
        .iter()
        .filter(|n| columns.iter().any(|c| c == *n))
        .map(|s| s.to_string())
        .collect()
}

/// The columns a record must hold to simulate `model`: its DOFs and its inputs, less the effect
/// columns `tfs diagnose`/`refit` add (delayed or filtered inputs), which are computed from the
/// record (internal states are simulated with the motion).
pub fn measured_columns(model: &Model) -> Vec<String> {
    let computed = tfs_diagnose::effects::computed_columns(model);
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

/// Reads a model file with its path in the error (a hidden Maxwell element written as a
/// computed column by an older version becomes the internal state it stands for).
pub fn read_model(path: &Path) -> Result<Model> {
    let m = Model::from_path(path).with_context(|| format!("reading model {}", path.display()))?;
    tfs_diagnose::effects::upgrade_legacy(&m)
        .with_context(|| format!("reading model {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The note names the removed displacement mean as a share of its RMS when the means were
    /// removed, and says nothing when they were kept or when no displacement mean was removed.
    #[test]
    fn memory_note_only_when_a_displacement_mean_was_removed() {
        let t: Vec<f64> = (0..400).map(|k| k as f64 * 0.01).collect();
        let x: Vec<f64> = t.iter().map(|t| (3.0 * t).sin() + 0.05).collect();
        let u: Vec<f64> = t.iter().map(|t| (3.0 * t).cos()).collect();
        let rec = Record::new("r", t, vec![("x".into(), x), ("u".into(), u)]).unwrap();
        let channels = vec!["x".to_string(), "u".to_string()];
        let dofs = vec!["x".to_string()];
        let mut kept = vec![rec.clone()];
        let report = apply_offsets(&mut kept, &channels, Offsets::Keep, "test").unwrap();
        assert!(memory_offsets_note(&report, &kept, &dofs, "m").is_none());
        let mut removed = vec![rec];
        let report = apply_offsets(&mut removed, &channels, Offsets::Remove, "test").unwrap();
        let note = memory_offsets_note(&report, &removed, &dofs, "the model has memory").unwrap();
        let x = removed[0].column("x").unwrap();
        let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        let mean = kept[0].column("x").unwrap().iter().sum::<f64>() / x.len() as f64;
        let want = format!("x up to {:.3} % of its RMS", 100.0 * mean / rms);
        assert!(note.contains(&want), "{note} / {want}");
        assert!(note.contains("--offsets keep"), "{note}");
        let mut centred = removed.clone();
        let report = apply_offsets(&mut centred, &channels, Offsets::Remove, "test").unwrap();
        assert!(memory_offsets_note(&report, &centred, &dofs, "m").is_none());
    }
}
