//! CSV reading (with validation) and writing of records, and cross-record consistency checks.

use std::io::Read;
use std::path::Path;

use crate::validate::{Table, check_table, missing_column};
use crate::{CsvOptions, CsvTable, DataError, Record, Result};

/// Reads and validates a CSV file with default options (time column `t`, no required columns).
pub fn read_csv(path: impl AsRef<Path>) -> Result<Record> {
    read_csv_with(path, &CsvOptions::default())
}

/// Reads and validates a CSV file; warnings (e.g. clipped channels under
/// [`crate::Saturation::Warn`]) are dropped — use [`read_csv_checked`] to see them.
pub fn read_csv_with(path: impl AsRef<Path>, opts: &CsvOptions) -> Result<Record> {
    read_csv_checked(path, opts).map(|(r, _)| r)
}

/// Reads and validates a CSV file (`-` reads standard input), returning the record and the
/// warnings raised. The file is read once.
pub fn read_csv_checked(
    path: impl AsRef<Path>,
    opts: &CsvOptions,
) -> Result<(Record, Vec<DataError>)> {
    crate::read_table(path)?.into_record(opts)
}

/// Reads and validates CSV text from any reader; `source` names it in messages.
pub fn from_reader<R: Read>(source: &str, reader: R, opts: &CsvOptions) -> Result<Record> {
    CsvTable::from_reader(source, reader)?
        .into_record(opts)
        .map(|(r, _)| r)
}

/// Validates a record built in memory (from arrays rather than a file) by the same rules as a CSV
/// file: the `required` columns of `opts` exist, every value is finite, and the time axis and
/// columns pass the checks of the module docs of `validate` (rows are numbered from 1, the first
/// sample). Returns the record (its time axis replaced by the uniform grid when the timestamps were
/// rounded) and the warnings.
pub fn check_record(record: Record, opts: &CsvOptions) -> Result<(Record, Vec<DataError>)> {
    let file = record.source().to_string();
    let names = record.names().to_vec();
    // The columns as a file's header lists them: time first.
    let header: Vec<String> = std::iter::once(opts.time_column.clone())
        .chain(names.iter().cloned())
        .collect();
    crate::validate::time_not_required(&file, opts)?;
    for req in &opts.required {
        if *req != opts.time_column && !names.contains(req) {
            return Err(missing_column(
                &file,
                1,
                req,
                "required column",
                &header,
                "; add the column or choose another with the matching option",
            ));
        }
    }
    let cols: Vec<Vec<f64>> = names
        .iter()
        .map(|n| record.column(n).unwrap_or_default().to_vec())
        .collect();
    let t = record.t().to_vec();
    for (name, col) in std::iter::once((&opts.time_column, &t)).chain(names.iter().zip(&cols)) {
        if let Some(k) = col.iter().position(|v| !v.is_finite()) {
            return Err(DataError::NonFinite {
                file,
                row: k as u64 + 1,
                column: name.clone(),
                cell: col[k].to_string(),
            });
        }
    }
    let lines: Vec<u64> = (1..=t.len() as u64).collect();
    let warnings = check_table(
        &Table {
            file: &file,
            t: &t,
            names: &names,
            data: &cols,
            lines: &lines,
            time_resolution: 0.0,
        },
        opts,
    )?;
    Ok((record, warnings))
}

/// Formats a finite float so that parsing it gives back the same bits.
fn fmt_f64(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || (1e-4..1e15).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Writes a record as CSV: header `t,<names…>`, one row per sample, values written so that
/// reading them back gives the same `f64` bits. Non-finite values are rejected (row and column
/// named). The file is written atomically: on any error the previous file is left as it was.
pub fn write_csv(path: impl AsRef<Path>, record: &Record) -> Result<()> {
    let path = path.as_ref();
    let cols = csv_columns(path, record)?;
    crate::write_atomic_with(path, |out| render_csv(out, &cols, record.len()))
        .map_err(write_err(path))
}

/// [`write_csv`] into a set of files written together ([`crate::AtomicSet`]): the CSV goes to
/// its temporary file now and replaces `path` only when the whole set is committed.
pub fn write_csv_into(
    set: &mut crate::AtomicSet,
    path: impl AsRef<Path>,
    record: &Record,
) -> Result<()> {
    let path = path.as_ref();
    let cols = csv_columns(path, record)?;
    set.add_with(path, |out| render_csv(out, &cols, record.len()))
        .map_err(write_err(path))
}

/// The error of a failed write of `path`.
fn write_err(path: &Path) -> impl FnOnce(std::io::Error) -> DataError {
    let file = path.display().to_string();
    move |source| DataError::Io {
        file,
        action: "write",
        source,
    }
}

/// The columns of a record as written (time first), after checking every value is finite.
fn csv_columns<'a>(path: &Path, record: &'a Record) -> Result<Vec<(&'a str, &'a [f64])>> {
    let mut cols: Vec<(&str, &[f64])> = vec![("t", record.t())];
    for n in record.names() {
        cols.push((n.as_str(), record.column(n).unwrap_or(&[])));
    }
    for (c, x) in &cols {
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(DataError::NonFinite {
                file: path.display().to_string(),
                row: i as u64 + 2,
                column: c.to_string(),
                cell: x[i].to_string(),
            });
        }
    }
    Ok(cols)
}

/// Writes the header and `rows` rows of `cols` as CSV text.
fn render_csv(
    out: &mut dyn std::io::Write,
    cols: &[(&str, &[f64])],
    rows: usize,
) -> std::io::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    let to_io = |e: csv::Error| match e.into_kind() {
        csv::ErrorKind::Io(source) => source,
        other => std::io::Error::other(format!("{other:?}")),
    };
    w.write_record(cols.iter().map(|(c, _)| *c))
        .map_err(to_io)?;
    let mut row: Vec<String> = Vec::with_capacity(cols.len());
    for i in 0..rows {
        row.clear();
        row.extend(cols.iter().map(|(_, x)| fmt_f64(x[i])));
        w.write_record(&row).map_err(to_io)?;
    }
    w.flush()
}

/// Checks that records can be used together: the same set of column names and sampling
/// intervals equal within 1e-6 relative. The error names both records' sources.
pub fn check_consistent(records: &[Record]) -> Result<()> {
    let Some(first) = records.first() else {
        return Ok(());
    };
    for r in &records[1..] {
        let only_a: Vec<&str> = first
            .names()
            .iter()
            .filter(|n| !r.names().contains(n))
            .map(String::as_str)
            .collect();
        let only_b: Vec<&str> = r
            .names()
            .iter()
            .filter(|n| !first.names().contains(n))
            .map(String::as_str)
            .collect();
        if !only_a.is_empty() || !only_b.is_empty() {
            return Err(DataError::Inconsistent {
                file_a: first.source().to_string(),
                file_b: r.source().to_string(),
                message: format!(
                    "columns differ (only in {}: [{}]; only in {}: [{}]); give every file the same columns",
                    first.source(),
                    only_a.join(", "),
                    r.source(),
                    only_b.join(", ")
                ),
            });
        }
        let (da, db) = (first.dt(), r.dt());
        let rel = (da - db).abs() / da.abs().max(db.abs());
        if rel.is_nan() || rel > 1e-6 {
            return Err(DataError::Inconsistent {
                file_a: first.source().to_string(),
                file_b: r.source().to_string(),
                message: format!(
                    "sampling intervals differ ({da:e} s vs {db:e} s, relative {rel:.2e} > 1e-6); resample to a common interval"
                ),
            });
        }
    }
    Ok(())
}
