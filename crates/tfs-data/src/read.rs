//! Reading CSV text once into numbers: the header, every column as `f64`, each data row's line
//! number and each column's printed resolution. Validation against options (time column,
//! required columns, sampling, clipping) is [`CsvTable::into_record`], so a caller that needs
//! the column names first (to choose DOFs and inputs) does not read the file twice — which also
//! makes pipes, `<(…)` and `-` for standard input work.
//!
//! Cells are separated by commas; a header with no comma but semicolons, tabs, or runs of spaces
//! chooses that separator for the whole file. Cells are trimmed; a cell may be quoted (`"t"`,
//! with `""` for a quote inside). Lines starting with `#` and blank lines are skipped but
//! counted, so rows in messages are the file's own line numbers. A UTF-8 byte-order mark is
//! ignored.

use std::io::{BufRead, Read};
use std::path::Path;

use crate::validate::{Table, check_table, missing_column};
use crate::{CsvOptions, DataError, Record, Result};

/// The name a path of `-` (standard input) gets in messages.
pub const STDIN_NAME: &str = "standard input";

/// How the cells of a line are separated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sep {
    Byte(u8),
    /// Runs of spaces and tabs.
    Blank,
}

impl Sep {
    fn describe(self) -> &'static str {
        match self {
            Sep::Byte(b',') => "commas",
            Sep::Byte(b';') => "semicolons",
            Sep::Byte(b'\t') => "tabs",
            Sep::Byte(_) => "a separator",
            Sep::Blank => "spaces",
        }
    }
}

/// A CSV file parsed once: header names and every column as numbers, not yet validated.
#[derive(Debug)]
pub struct CsvTable {
    source: String,
    names: Vec<String>,
    header_line: u64,
    sep: Sep,
    cols: Vec<Vec<f64>>,
    lines: Vec<u64>,
    /// Per column, the finest printed resolution as `decimals − exponent` (the resolution is
    /// `10^-value`); `None` when some cell is not a plain decimal number.
    resolution: Vec<Option<i32>>,
    /// The first problem in the data rows; parsing stopped there. Reported after the
    /// header-level checks of [`CsvTable::into_record`] (a missing column is the clearer news).
    deferred: Option<DataError>,
    /// Per column, whether its values have strictly increased so far (only such a column can
    /// be the time axis).
    increasing: Vec<bool>,
}

/// Reads a CSV file (or standard input for `-`) once, without validating it against options.
pub fn read_table(path: impl AsRef<Path>) -> Result<CsvTable> {
    let path = path.as_ref();
    if path.as_os_str() == "-" {
        let stdin = std::io::stdin();
        return CsvTable::from_reader(STDIN_NAME, stdin.lock());
    }
    let name = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|source| DataError::Io {
        file: name.clone(),
        action: "read",
        source,
    })?;
    CsvTable::from_reader(&name, file)
}

/// The longest line read (bytes): a measurement row is far shorter; a longer one is not CSV
/// text (a binary file, a device like /dev/zero) and must not fill the memory.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// The most values (rows × columns) read from one file: 2 GB of numbers.
pub const MAX_VALUES: usize = 1 << 28;

/// Reads one line (up to and without `\n`) into `buf`; false at the end of the input.
fn next_line<R: BufRead>(r: &mut R, buf: &mut Vec<u8>, file: &str, line_no: u64) -> Result<bool> {
    buf.clear();
    let n = Read::take(&mut *r, MAX_LINE_BYTES as u64 + 1)
        .read_until(b'\n', buf)
        .map_err(|source| DataError::Io {
            file: file.to_string(),
            action: "read",
            source,
        })?;
    if n == 0 {
        return Ok(false);
    }
    if buf.last() == Some(&b'\n') {
        buf.pop();
    } else if buf.len() > MAX_LINE_BYTES {
        return Err(DataError::Csv {
            file: file.to_string(),
            row: line_no + 1,
            message: format!(
                "the line is longer than {} MiB, which no CSV row of measurements is; check that this is the CSV file",
                MAX_LINE_BYTES >> 20
            ),
        });
    }
    if buf.last() == Some(&b'\r') {
        buf.pop();
    }
    Ok(true)
}

fn is_blank(b: u8) -> bool {
    b == b' ' || b == b'\t' || b == b'\r' || b == 0x0b || b == 0x0c
}

fn trim(mut s: &[u8]) -> &[u8] {
    while let [first, rest @ ..] = s {
        if is_blank(*first) {
            s = rest;
        } else {
            break;
        }
    }
    while let [rest @ .., last] = s {
        if is_blank(*last) {
            s = rest;
        } else {
            break;
        }
    }
    s
}

/// A line that holds no cells: empty, blank, or a `#` comment.
fn skipped(line: &[u8]) -> bool {
    let t = trim(line);
    t.is_empty() || t[0] == b'#'
}

/// Splits `line` into trimmed cells (ranges into `line`, quotes removed; a quoted cell with
/// `""` inside is marked so the header can unescape it). Returns an error message for an
/// unterminated quote.
fn split(
    line: &[u8],
    sep: Sep,
    out: &mut Vec<(usize, usize, bool)>,
) -> std::result::Result<(), &'static str> {
    out.clear();
    let n = line.len();
    let mut i = 0;
    if sep == Sep::Blank {
        loop {
            while i < n && is_blank(line[i]) {
                i += 1;
            }
            if i >= n {
                return Ok(());
            }
            let s = i;
            while i < n && !is_blank(line[i]) {
                i += 1;
            }
            out.push((s, i, false));
        }
    }
    let Sep::Byte(d) = sep else { return Ok(()) };
    loop {
        while i < n && is_blank(line[i]) && line[i] != d {
            i += 1;
        }
        if i < n && line[i] == b'"' {
            // Quoted cell: up to the closing quote; "" is a quote inside.
            let s = i + 1;
            let mut j = s;
            let mut escaped = false;
            loop {
                if j >= n {
                    return Err("a quote is not closed");
                }
                if line[j] == b'"' {
                    if j + 1 < n && line[j + 1] == b'"' {
                        escaped = true;
                        j += 2;
                        continue;
                    }
                    break;
                }
                j += 1;
            }
            out.push((s, j, escaped));
            i = j + 1;
            while i < n && line[i] != d {
                if !is_blank(line[i]) {
                    return Err("text follows a closing quote in the same cell");
                }
                i += 1;
            }
        } else {
            let s = i;
            while i < n && line[i] != d {
                i += 1;
            }
            let cell = trim(&line[s..i]);
            let off = cell.as_ptr() as usize - line.as_ptr() as usize;
            out.push((off, off + cell.len(), false));
        }
        if i >= n {
            return Ok(());
        }
        i += 1; // the separator
        if i == n {
            out.push((n, n, false));
            return Ok(());
        }
    }
}

/// The separator a header line uses: a comma when it has one (outside quotes), else a
/// semicolon, else a tab, else runs of spaces when the header has several words.
fn detect_sep(header: &[u8]) -> Sep {
    let mut count = [0usize; 3];
    let mut quoted = false;
    for &b in header {
        match b {
            b'"' => quoted = !quoted,
            b',' if !quoted => count[0] += 1,
            b';' if !quoted => count[1] += 1,
            b'\t' if !quoted => count[2] += 1,
            _ => {}
        }
    }
    if count[0] > 0 {
        Sep::Byte(b',')
    } else if count[1] > 0 {
        Sep::Byte(b';')
    } else if count[2] > 0 {
        Sep::Byte(b'\t')
    } else if trim(header).contains(&b' ') {
        Sep::Blank
    } else {
        Sep::Byte(b',')
    }
}

/// `decimals − exponent` of a plain decimal number (`"0.0003"` → 4, `"1.5e-3"` → 4, `"12"` →
/// 0), `None` if the exponent is not an integer. One pass over the cell.
fn printed_digits(cell: &[u8]) -> Option<i32> {
    let mut dot = None;
    for (i, &b) in cell.iter().enumerate() {
        match b {
            b'.' => dot = Some(i),
            b'e' | b'E' => {
                let e = std::str::from_utf8(&cell[i + 1..])
                    .ok()?
                    .parse::<i32>()
                    .ok()?;
                let decimals = dot.map_or(0, |p| i - p - 1) as i32;
                return Some(decimals.saturating_sub(e));
            }
            _ => {}
        }
    }
    Some(dot.map_or(0, |p| cell.len() - p - 1) as i32)
}

fn lossy(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

impl CsvTable {
    /// Parses CSV text from any reader; `source` names it in messages.
    pub fn from_reader<R: Read>(source: &str, reader: R) -> Result<Self> {
        let mut r = std::io::BufReader::with_capacity(1 << 16, reader);
        let file = source.to_string();
        let mut buf = Vec::new();
        let mut line_no = 0u64;
        // Header: the first line that is not blank or a comment.
        loop {
            if !next_line(&mut r, &mut buf, &file, line_no)? {
                return Err(DataError::NoHeader {
                    file,
                    message: "row 1: the file is empty; write a header line (e.g. 't,x,xb_acc') followed by data rows".into(),
                });
            }
            line_no += 1;
            if line_no == 1 && buf.starts_with(&[0xEF, 0xBB, 0xBF]) {
                buf.drain(..3);
            }
            if !skipped(&buf) {
                break;
            }
        }
        let header_line = line_no;
        let sep = detect_sep(&buf);
        let mut cells = Vec::new();
        split(&buf, sep, &mut cells).map_err(|m| DataError::Csv {
            file: file.clone(),
            row: header_line,
            message: m.into(),
        })?;
        let mut names = Vec::with_capacity(cells.len());
        for &(a, b, esc) in &cells {
            let mut name = std::str::from_utf8(&buf[a..b])
                .map_err(|_| DataError::Csv {
                    file: file.clone(),
                    row: header_line,
                    message: "the header is not valid UTF-8 text".into(),
                })?
                .to_string();
            if esc {
                name = name.replace("\"\"", "\"");
            }
            names.push(name);
        }
        check_header(&file, header_line, &names, sep)?;
        let ncol = names.len();
        let mut table = CsvTable {
            source: file,
            names,
            header_line,
            sep,
            cols: vec![Vec::new(); ncol],
            lines: Vec::new(),
            resolution: vec![Some(i32::MIN); ncol],
            deferred: None,
            increasing: vec![true; ncol],
        };
        let max_rows = MAX_VALUES / ncol.max(1);
        loop {
            match next_line(&mut r, &mut buf, &table.source, line_no) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => {
                    table.deferred = Some(e);
                    break;
                }
            }
            line_no += 1;
            if skipped(&buf) {
                continue;
            }
            if table.lines.len() >= max_rows {
                table.deferred = Some(DataError::Csv {
                    file: table.source.clone(),
                    row: line_no,
                    message: format!(
                        "more than {max_rows} data rows ({MAX_VALUES} values); split the record into shorter files"
                    ),
                });
                break;
            }
            if let Err(e) = table.push_row(&buf, line_no, &mut cells) {
                table.deferred = Some(e);
                break;
            }
            if !table.increasing.contains(&true) {
                // No column can be the time axis any more: whichever is, the file fails the
                // time check at a row already read (the first check after the header's), so
                // the rest — an endless pipe, a huge file — need not be read.
                break;
            }
        }
        Ok(table)
    }

    /// Parses one data row into the columns.
    fn push_row(
        &mut self,
        line: &[u8],
        line_no: u64,
        cells: &mut Vec<(usize, usize, bool)>,
    ) -> Result<()> {
        split(line, self.sep, cells).map_err(|m| DataError::Csv {
            file: self.source.clone(),
            row: line_no,
            message: m.into(),
        })?;
        if cells.len() != self.names.len() {
            return Err(DataError::Ragged {
                file: self.source.clone(),
                row: line_no,
                expected: self.names.len(),
                found: cells.len(),
                separator: self.sep.describe(),
            });
        }
        for (j, &(a, b, _)) in cells.iter().enumerate() {
            let cell = &line[a..b];
            // Correctly rounded (the same bits as `str::parse`), straight from the bytes.
            let v =
                fast_float2::parse::<f64, _>(cell)
                    .ok()
                    .ok_or_else(|| DataError::NonNumeric {
                        file: self.source.clone(),
                        row: line_no,
                        column: self.names[j].clone(),
                        cell: lossy(cell),
                        hint: non_numeric_hint(cell, self.sep),
                    })?;
            if !v.is_finite() {
                return Err(DataError::NonFinite {
                    file: self.source.clone(),
                    row: line_no,
                    column: self.names[j].clone(),
                    cell: lossy(cell),
                });
            }
            if let Some(&prev) = self.cols[j].last()
                && v <= prev
            {
                self.increasing[j] = false;
            }
            self.cols[j].push(v);
            let res = &mut self.resolution[j];
            if let Some(cur) = *res {
                *res = printed_digits(cell).map(|d| cur.max(d));
            }
        }
        self.lines.push(line_no);
        Ok(())
    }

    /// Where the text came from (file path, or [`STDIN_NAME`]).
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The header's column names, in file order (the time column included).
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Number of data rows read (up to the first bad row, if any).
    pub fn rows(&self) -> usize {
        self.lines.len()
    }

    /// Validates the table against `opts` (time and required columns present, then the first
    /// bad cell or row if any, then the rules of `crate::validate`) and returns the record and
    /// the warnings raised.
    pub fn into_record(self, opts: &CsvOptions) -> Result<(Record, Vec<DataError>)> {
        let file = self.source.as_str();
        let tcol = &opts.time_column;
        let ti = self.names.iter().position(|n| n == tcol).ok_or_else(|| {
            missing_column(
                file,
                self.header_line,
                tcol,
                "time column",
                &self.names,
                &crate::validate::time_hint(tcol, &self.names),
            )
        })?;
        crate::validate::time_not_required(file, opts)?;
        for req in &opts.required {
            if !self.names.contains(req) {
                return Err(missing_column(
                    file,
                    self.header_line,
                    req,
                    "required column",
                    &self.names,
                    "; add the column or choose another with the matching option",
                ));
            }
        }
        if let Some(e) = self.deferred {
            return Err(e);
        }
        let CsvTable {
            source,
            mut names,
            mut cols,
            lines,
            resolution,
            ..
        } = self;
        let file = source.as_str();
        let time_resolution = match resolution[ti] {
            Some(d) if d != i32::MIN => 10f64.powi(-d),
            _ => 0.0,
        };
        let mut t = cols.remove(ti);
        names.remove(ti);
        let warnings = check_table(
            &Table {
                file,
                t: &t,
                names: &names,
                data: &cols,
                lines: &lines,
                time_resolution,
            },
            opts,
        )?;
        if let Some((t0, dt)) = warnings.iter().find_map(|w| match w {
            DataError::TimeRounded { t0, dt, .. } => Some((*t0, *dt)),
            _ => None,
        }) {
            // Rounded timestamps: use the uniform grid they round from.
            t = (0..t.len()).map(|k| t0 + k as f64 * dt).collect();
        }
        let record = Record::new(file, t, names.into_iter().zip(cols).collect())?;
        Ok((record, warnings))
    }
}

/// Header-level checks that need no options: names, not numbers; no empty or repeated name.
fn check_header(file: &str, row: u64, names: &[String], sep: Sep) -> Result<()> {
    if names.iter().all(|c| c.parse::<f64>().is_ok()) {
        return Err(DataError::NoHeader {
            file: file.to_string(),
            message: format!(
                "row {row}: the first line is numbers, not column names; add a header line such as 't,x,xb_acc'"
            ),
        });
    }
    if let Some(i) = names.iter().position(String::is_empty) {
        return Err(DataError::NoHeader {
            file: file.to_string(),
            message: format!(
                "row {row}: header cell {} is empty (cells separated by {}); give every column a name",
                i + 1,
                sep.describe()
            ),
        });
    }
    for (j, name) in names.iter().enumerate() {
        if let Some(i) = names[..j].iter().position(|n| n == name) {
            return Err(DataError::DuplicateColumn {
                file: file.to_string(),
                row,
                column: name.clone(),
                first: i + 1,
                second: j + 1,
            });
        }
    }
    Ok(())
}

/// What to do about a cell that is not a number, when its text says more than "write a number".
fn non_numeric_hint(cell: &[u8], sep: Sep) -> String {
    if cell.is_empty() {
        return "; the cell is empty: fill it or remove the row".into();
    }
    if sep != Sep::Byte(b',') && cell.contains(&b',') {
        let fixed: Vec<u8> = cell
            .iter()
            .map(|&b| if b == b',' { b'.' } else { b })
            .collect();
        if std::str::from_utf8(&fixed)
            .ok()
            .and_then(|s| s.parse::<f64>().ok())
            .is_some()
        {
            return format!(
                "; it uses a decimal comma: write a decimal point ({})",
                lossy(&fixed)
            );
        }
    }
    String::new()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cells(line: &str, sep: Sep) -> Vec<String> {
        let mut out = Vec::new();
        split(line.as_bytes(), sep, &mut out).unwrap();
        out.iter()
            .map(|&(a, b, _)| line[a..b].to_string())
            .collect()
    }

    #[test]
    fn splits_trims_and_unquotes() {
        assert_eq!(cells(" a , b,c ", Sep::Byte(b',')), ["a", "b", "c"]);
        assert_eq!(cells("a,,c,", Sep::Byte(b',')), ["a", "", "c", ""]);
        assert_eq!(cells("\"a,b\" , c", Sep::Byte(b',')), ["a,b", "c"]);
        assert_eq!(cells("1\t2\t 3", Sep::Byte(b'\t')), ["1", "2", "3"]);
        assert_eq!(cells("  1   2 3  ", Sep::Blank), ["1", "2", "3"]);
        let mut out = Vec::new();
        assert!(split(b"\"abc", Sep::Byte(b','), &mut out).is_err());
        assert!(split(b"\"a\"b,c", Sep::Byte(b','), &mut out).is_err());
    }

    #[test]
    fn separator_from_the_header() {
        assert_eq!(detect_sep(b"t,x"), Sep::Byte(b','));
        assert_eq!(detect_sep(b"t;x;xb_acc"), Sep::Byte(b';'));
        assert_eq!(detect_sep(b"t\tx"), Sep::Byte(b'\t'));
        assert_eq!(detect_sep(b"t x  xb_acc"), Sep::Blank);
        assert_eq!(detect_sep(b"\"a;b\",c"), Sep::Byte(b','));
        assert_eq!(detect_sep(b"t"), Sep::Byte(b','));
    }

    #[test]
    fn printed_digits_of_decimal_text() {
        assert_eq!(printed_digits(b"0.0003"), Some(4));
        assert_eq!(printed_digits(b"12"), Some(0));
        assert_eq!(printed_digits(b"1.5e-3"), Some(4));
        assert_eq!(printed_digits(b"2E2"), Some(-2));
        assert_eq!(printed_digits(b"1e"), None);
    }
}
