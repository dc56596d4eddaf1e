//! Measurement records: named, uniformly sampled columns, read from and written to CSV with
//! validation that names the file, row and column of every problem; and the atomic file writes
//! every tfs output goes through ([`write_atomic`], [`AtomicFile`]).
//!
//! A file is read once ([`read_table`], `-` for standard input) into a [`CsvTable`]; its column
//! names can be looked at before it is validated against [`CsvOptions`] into a [`Record`].
//!
//! Architecture invariant: this crate knows nothing about models or numerics beyond checking data.
//!
//! ```
//! use tfs_data::{CsvOptions, Record, read_csv_with, write_csv};
//! let r = Record::new("demo", vec![0.0, 0.1, 0.2], vec![("x".into(), vec![1.0, 2.0, 3.0])]).unwrap();
//! assert_eq!(r.column("x").unwrap()[2], 3.0);
//! assert!((r.dt() - 0.1).abs() < 1e-12);
//!
//! // Write a record to CSV and read it back with validation.
//! let dir = std::env::temp_dir().join(format!("tfs-data-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! let path = dir.join("demo.csv");
//! let t: Vec<f64> = (0..32).map(|i| i as f64 * 0.01).collect();
//! let x: Vec<f64> = t.iter().map(|t| (7.0 * t).sin()).collect();
//! write_csv(&path, &Record::new("demo", t, vec![("x".into(), x)]).unwrap()).unwrap();
//! let opts = CsvOptions::default().require(["x"]);
//! let back = read_csv_with(&path, &opts).unwrap();
//! assert_eq!(back.len(), 32);
//! // A misspelt required column gives a one-line message with a suggestion.
//! let err = read_csv_with(&path, &CsvOptions::default().require(["X"])).unwrap_err();
//! assert!(err.to_string().contains("did you mean 'x'?"));
//! std::fs::remove_dir_all(&dir).ok();
//! ```

#![warn(missing_docs)]

mod atomic;
mod csv_io;
mod read;
mod record;
mod validate;

pub use atomic::{AtomicFile, AtomicSet, check_target, write_atomic, write_atomic_with};
pub use csv_io::{
    check_consistent, check_record, from_reader, read_csv, read_csv_checked, read_csv_with,
    write_csv, write_csv_into,
};
pub use read::{CsvTable, STDIN_NAME, read_table};
pub use record::{Columns, Record};
pub use validate::{CsvOptions, Saturation};

/// Errors raised while building, reading or writing records.
///
/// Every message is one line: it names the file, the row (the 1-based line number in the file,
/// the header being line 1) and the column where that applies, and says what to do.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A record was built from inconsistent parts.
    #[error("{source_name}: {message}")]
    Invalid {
        /// The file or record name.
        source_name: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// The file could not be opened, read or written.
    #[error("{file}: cannot {action}: {source}; check the path and permissions")]
    Io {
        /// The file.
        file: String,
        /// "read" or "write".
        action: &'static str,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file is empty or has no header line.
    #[error("{file}: {message}")]
    NoHeader {
        /// The file.
        file: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A column that is needed is not in the header.
    #[error(
        "{file}: row {row}, column '{column}': missing {what}; the header has [{available}]{hint}"
    )]
    MissingColumn {
        /// The file.
        file: String,
        /// 1-based line number of the header.
        row: u64,
        /// The missing column.
        column: String,
        /// "time column" or "required column".
        what: &'static str,
        /// Comma-separated list of the columns that exist.
        available: String,
        /// Empty, or "; did you mean 'x'?" / a hint on how to choose the column.
        hint: String,
    },
    /// Two header cells have the same name.
    #[error(
        "{file}: row {row}, column '{column}': name appears twice (header positions {first} and {second}); rename one of them"
    )]
    DuplicateColumn {
        /// The file.
        file: String,
        /// 1-based line number of the header.
        row: u64,
        /// The repeated name.
        column: String,
        /// 1-based position of the first occurrence.
        first: usize,
        /// 1-based position of the second occurrence.
        second: usize,
    },
    /// A data row has a different number of cells from the header.
    #[error(
        "{file}: row {row}: has {found} cells but the header has {expected} (cells separated by {separator}, as in the header); every row needs one value per column"
    )]
    Ragged {
        /// The file.
        file: String,
        /// 1-based line number.
        row: u64,
        /// Cells in the header.
        expected: usize,
        /// Cells in this row.
        found: usize,
        /// The separator the header chose ("commas", "semicolons", "tabs" or "spaces").
        separator: &'static str,
    },
    /// A cell is not a number.
    #[error(
        "{file}: row {row}, column '{column}': cell \"{cell}\" is not a number{hint}; write a decimal number"
    )]
    NonNumeric {
        /// The file.
        file: String,
        /// 1-based line number.
        row: u64,
        /// Column name.
        column: String,
        /// The cell text.
        cell: String,
        /// Empty, or what looks wrong (an empty cell, a decimal comma), starting with "; ".
        hint: String,
    },
    /// A cell is NaN or infinite.
    #[error(
        "{file}: row {row}, column '{column}': value \"{cell}\" is not finite; remove the row or fill the value"
    )]
    NonFinite {
        /// The file.
        file: String,
        /// 1-based line number.
        row: u64,
        /// Column name.
        column: String,
        /// The cell text.
        cell: String,
    },
    /// Time does not increase strictly.
    #[error(
        "{file}: row {row}, column '{column}': time {t} does not increase (previous row has {t_prev}); sort the rows and remove duplicates"
    )]
    NonIncreasingTime {
        /// The file.
        file: String,
        /// 1-based line number.
        row: u64,
        /// The time column name.
        column: String,
        /// Time on the previous data row.
        t_prev: f64,
        /// Time on this row.
        t: f64,
    },
    /// A time step is more than 1.5 sampling intervals (missing samples).
    #[error(
        "{file}: row {row}, column '{column}': gap in time before t = {t} (step {step:.6e} s is {ratio:.2} x the sampling interval {dt:.6e} s); split the file at the gap or fill the missing samples"
    )]
    TimeGap {
        /// The file.
        file: String,
        /// 1-based line number of the row after the gap.
        row: u64,
        /// The time column name.
        column: String,
        /// Time at this row.
        t: f64,
        /// The step into this row.
        step: f64,
        /// Median sampling interval.
        dt: f64,
        /// step / dt.
        ratio: f64,
    },
    /// Time steps vary by more than the tolerance.
    #[error(
        "{file}: row {row}, column '{column}': time is not uniformly sampled (worst step {step:.6e} s deviates {rel:.2e} from the sampling interval {dt:.6e} s, tolerance {tol:.1e}); resample to a uniform grid"
    )]
    NonUniformTime {
        /// The file.
        file: String,
        /// 1-based line number of the worst row.
        row: u64,
        /// The time column name.
        column: String,
        /// The worst step.
        step: f64,
        /// Median sampling interval.
        dt: f64,
        /// Relative deviation |step - dt| / dt.
        rel: f64,
        /// The tolerance used.
        tol: f64,
    },
    /// Warning: the timestamps are printed with fewer decimals than the sampling interval needs
    /// (e.g. 3 kHz written with 4 decimals); they lie on a uniform grid to within that rounding,
    /// so the time axis was replaced by the grid `t0 + k·dt`.
    #[error(
        "{file}: column '{column}': timestamps are rounded to {resolution:e} s, coarser than the sampling interval {dt:.6e} s needs; they agree with a uniform grid to within the rounding, so the time axis was replaced by that grid t0 + k·dt (write more decimals to avoid this)"
    )]
    TimeRounded {
        /// The file.
        file: String,
        /// The time column name.
        column: String,
        /// The printed resolution of the time column.
        resolution: f64,
        /// Start of the grid (least-squares fit to the timestamps).
        t0: f64,
        /// The sampling interval of the grid (least-squares fit to the timestamps).
        dt: f64,
    },
    /// Too few data rows.
    #[error(
        "{file}: row {last_row}: only {rows} data rows, at least {min} are needed; record a longer stretch"
    )]
    TooFewRows {
        /// The file.
        file: String,
        /// 1-based line number of the last data row (1 if none).
        last_row: u64,
        /// Number of data rows.
        rows: usize,
        /// Minimum required.
        min: usize,
    },
    /// A required column does not vary.
    #[error(
        "{file}: row {row}, column '{column}': constant signal (every row is {value}), so nothing about its coefficient can be identified; check that the sensor or exciter channel was connected, or leave the column out"
    )]
    Constant {
        /// The file.
        file: String,
        /// 1-based line number of the first data row.
        row: u64,
        /// Column name.
        column: String,
        /// The constant value.
        value: f64,
    },
    /// A column sits at its extreme value too often (clipped sensor).
    #[error(
        "{file}: row {row}, column '{column}': channel looks clipped: {count} samples ({percent:.1}%) sit exactly at the {which} {value}, with a run of {run} from this row; re-record with a lower gain or a wider input range, or accept the clipped samples knowingly (CLI: --clipped warn)"
    )]
    Saturated {
        /// The file.
        file: String,
        /// 1-based line number where the longest run at the extreme starts.
        row: u64,
        /// Column name.
        column: String,
        /// "maximum" or "minimum".
        which: &'static str,
        /// The extreme value.
        value: f64,
        /// Samples at the extreme.
        count: usize,
        /// Percentage of samples at the extreme.
        percent: f64,
        /// Longest run of consecutive samples at the extreme.
        run: usize,
    },
    /// Two records that should be used together do not match.
    #[error("{file_a} and {file_b}: {message}")]
    Inconsistent {
        /// First file.
        file_a: String,
        /// Second file.
        file_b: String,
        /// What differs and what to do.
        message: String,
    },
    /// A malformed CSV line (e.g. bad quoting or invalid UTF-8).
    #[error(
        "{file}: row {row}: cannot parse CSV ({message}); fix the quoting or encoding of this line"
    )]
    Csv {
        /// The file.
        file: String,
        /// 1-based line number (0 if unknown).
        row: u64,
        /// Parser message.
        message: String,
    },
}

impl DataError {
    /// The file (or record name) the error is about; for [`DataError::Inconsistent`] the first file.
    pub fn file(&self) -> &str {
        match self {
            DataError::Invalid { source_name, .. } => source_name,
            DataError::Inconsistent { file_a, .. } => file_a,
            DataError::Io { file, .. }
            | DataError::NoHeader { file, .. }
            | DataError::MissingColumn { file, .. }
            | DataError::DuplicateColumn { file, .. }
            | DataError::Ragged { file, .. }
            | DataError::NonNumeric { file, .. }
            | DataError::NonFinite { file, .. }
            | DataError::NonIncreasingTime { file, .. }
            | DataError::TimeGap { file, .. }
            | DataError::NonUniformTime { file, .. }
            | DataError::TimeRounded { file, .. }
            | DataError::TooFewRows { file, .. }
            | DataError::Constant { file, .. }
            | DataError::Saturated { file, .. }
            | DataError::Csv { file, .. } => file,
        }
    }

    /// The 1-based line number in the file, when the error is about one row.
    pub fn row(&self) -> Option<u64> {
        match self {
            DataError::MissingColumn { row, .. }
            | DataError::DuplicateColumn { row, .. }
            | DataError::Ragged { row, .. }
            | DataError::NonNumeric { row, .. }
            | DataError::NonFinite { row, .. }
            | DataError::NonIncreasingTime { row, .. }
            | DataError::TimeGap { row, .. }
            | DataError::NonUniformTime { row, .. }
            | DataError::Constant { row, .. }
            | DataError::Saturated { row, .. }
            | DataError::Csv { row, .. } => Some(*row),
            DataError::TooFewRows { last_row, .. } => Some(*last_row),
            _ => None,
        }
    }

    /// The column the error is about, when there is one.
    pub fn column(&self) -> Option<&str> {
        match self {
            DataError::MissingColumn { column, .. }
            | DataError::DuplicateColumn { column, .. }
            | DataError::NonNumeric { column, .. }
            | DataError::NonFinite { column, .. }
            | DataError::NonIncreasingTime { column, .. }
            | DataError::TimeGap { column, .. }
            | DataError::NonUniformTime { column, .. }
            | DataError::TimeRounded { column, .. }
            | DataError::Constant { column, .. }
            | DataError::Saturated { column, .. } => Some(column),
            _ => None,
        }
    }
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, DataError>;
