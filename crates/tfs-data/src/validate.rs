//! Validation rules for measured records: time axis, row count, constant and clipped channels.
//!
//! The rules, in the order they are checked (the first failure is returned):
//! 1. time strictly increases (first offending row);
//! 2. no gap: no step exceeds `gap_factor` (default 1.5) times the median step (plus the printed
//!    resolution `q` when the timestamps are rounded, see 3) (first offending row);
//! 3. uniform sampling: every step is within `time_tolerance` (default 1 %) of the median step,
//!    relative; the worst row is reported. Timestamps printed with fewer decimals than the
//!    sampling interval needs (resolution `q` with `dt/q` not a whole number, e.g. 3 kHz written
//!    with 4 decimals) are rounded, not jittered: steps may then differ by `q` more, and the file is
//!    accepted when every timestamp is within `q/2 + time_tolerance·dt` (5 % slack on `q/2`) of
//!    the uniform grid `t0 + k·dt` fitted by least squares; the time axis is then replaced by
//!    that grid and a [`DataError::TimeRounded`] warning is returned;
//! 4. at least `min_rows` (default 16) data rows;
//! 5. no required column is constant (range ≤ 1e-12 relative to its largest magnitude);
//! 6. no checked column is clipped: a column is *saturated* at its maximum (or minimum) when at
//!    least `saturation_fraction` (default 1 %) of its samples equal that extreme exactly **and**
//!    some run of at least `saturation_run` (default 3) consecutive samples sits at it. Checked
//!    columns are the required ones, or every non-constant data column when none is required.
//!    [`Saturation`] chooses whether this is an error, a warning or ignored.

use crate::{DataError, Result};

/// What to do with a clipped (saturated) channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Saturation {
    /// Reject the file (default).
    #[default]
    Error,
    /// Accept the file and report the problem as a warning.
    Warn,
    /// Do not check.
    Allow,
}

/// Options for reading and validating a CSV file. See the module docs for the rules.
#[derive(Debug, Clone, PartialEq)]
pub struct CsvOptions {
    /// Name of the time column (default `"t"`), in seconds.
    pub time_column: String,
    /// Columns that must be present (checked for existence, constancy and clipping).
    pub required: Vec<String>,
    /// Minimum number of data rows (default 16).
    pub min_rows: usize,
    /// Allowed relative deviation of any time step from the median step (default 0.01).
    pub time_tolerance: f64,
    /// A step larger than this multiple of the median step is a gap (default 1.5).
    pub gap_factor: f64,
    /// Policy for clipped channels (default [`Saturation::Error`]).
    pub saturation: Saturation,
    /// Fraction of samples at an extreme that counts as clipping (default 0.01).
    pub saturation_fraction: f64,
    /// Minimum run of consecutive samples at the extreme that counts as clipping (default 3).
    pub saturation_run: usize,
}

impl Default for CsvOptions {
    fn default() -> Self {
        Self {
            time_column: "t".into(),
            required: Vec::new(),
            min_rows: 16,
            time_tolerance: 0.01,
            gap_factor: 1.5,
            saturation: Saturation::Error,
            saturation_fraction: 0.01,
            saturation_run: 3,
        }
    }
}

impl CsvOptions {
    /// Adds required column names.
    pub fn require<I, S>(mut self, names: I) -> Self
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        self.required.extend(names.into_iter().map(Into::into));
        self
    }

    /// Sets the time column name.
    pub fn time_column(mut self, name: impl Into<String>) -> Self {
        self.time_column = name.into();
        self
    }

    /// Sets the minimum number of data rows.
    pub fn min_rows(mut self, n: usize) -> Self {
        self.min_rows = n;
        self
    }

    /// Sets the clipped-channel policy.
    pub fn saturation(mut self, s: Saturation) -> Self {
        self.saturation = s;
        self
    }
}

/// Levenshtein distance between two strings (by chars).
fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for i in 1..=a.len() {
        cur[0] = i;
        for j in 1..=b.len() {
            let sub = prev[j - 1] + usize::from(a[i - 1] != b[j - 1]);
            cur[j] = sub.min(prev[j] + 1).min(cur[j - 1] + 1);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}

/// The closest existing name to `wanted`: a case-insensitive match, else one within an edit
/// distance of a third of the name's length, at most 2 (smallest distance, first in header
/// order on ties): `xb_ac` → `xb_acc`, but a one-letter name is never "corrected" to another
/// one-letter name (`t` is not a misspelt `x`).
pub(crate) fn suggest<'a>(wanted: &str, available: &'a [String]) -> Option<&'a str> {
    if let Some(n) = available.iter().find(|n| n.eq_ignore_ascii_case(wanted)) {
        return Some(n);
    }
    let limit = (wanted.chars().count() / 3).min(2);
    available
        .iter()
        .map(|n| (edit_distance(&n.to_lowercase(), &wanted.to_lowercase()), n))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, _)| *d)
        .map(|(_, n)| n.as_str())
}

/// The columns named `wanted` followed by a number (`x1`, `x2` for `x`), quoted and listed, if
/// there are any: a chain's record where one DOF was expected.
fn numbered(wanted: &str, available: &[String]) -> Option<String> {
    let list: Vec<String> = available
        .iter()
        .filter(|n| {
            n.strip_prefix(wanted)
                .is_some_and(|rest| !rest.is_empty() && rest.chars().all(|c| c.is_ascii_digit()))
        })
        .map(|n| format!("'{n}'"))
        .collect();
    (!list.is_empty()).then(|| list.join(", "))
}

/// The hint for a missing time column: a header cell that looks like a time axis (`time`,
/// `Time [s]`, `t_s`, `seconds`, …) is named with how to choose it; else how to name it.
pub(crate) fn time_hint(wanted: &str, available: &[String]) -> String {
    let looks_like_time = |n: &str| {
        let l = n.to_lowercase();
        let word: String = l.chars().take_while(|c| c.is_alphabetic()).collect();
        matches!(
            word.as_str(),
            "t" | "time" | "times" | "sec" | "secs" | "second" | "seconds"
        ) && l != wanted.to_lowercase()
    };
    match available.iter().find(|n| looks_like_time(n)) {
        Some(n) => format!(
            "; '{n}' looks like the time axis: rename it '{wanted}' or choose it with the time-column option (CLI: --time-column '{n}')"
        ),
        None => format!(
            "; add a time column in seconds named '{wanted}', or choose another with the time-column option (CLI: --time-column NAME)"
        ),
    }
}

/// Builds the error for a missing column.
pub(crate) fn missing_column(
    file: &str,
    row: u64,
    wanted: &str,
    what: &'static str,
    available: &[String],
    extra_hint: &str,
) -> DataError {
    let hint = match (suggest(wanted, available), numbered(wanted, available)) {
        (Some(s), _) => format!("; did you mean '{s}'?"),
        (None, Some(list)) => format!(
            "; the file has {list} instead: columns of a chain's DOFs, one per mass, while '{wanted}' is one DOF (a model of one DOF cannot be run on a chain's record; identify a chain model from it)"
        ),
        (None, None) => extra_hint.to_string(),
    };
    DataError::MissingColumn {
        file: file.to_string(),
        row,
        column: wanted.to_string(),
        what,
        available: available.join(", "),
        hint,
    }
}

/// Median of the positive steps of `t` (`t.len() >= 2`).
pub(crate) fn median_step(t: &[f64]) -> f64 {
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let m = steps.len();
    if m % 2 == 1 {
        steps[m / 2]
    } else {
        0.5 * (steps[m / 2 - 1] + steps[m / 2])
    }
}

/// The parsed table handed to [`check_table`].
pub(crate) struct Table<'a> {
    pub file: &'a str,
    pub t: &'a [f64],
    pub names: &'a [String],
    pub data: &'a [Vec<f64>],
    /// 1-based line number of every data row.
    pub lines: &'a [u64],
    /// Printed resolution of the time column (finest over its cells; 0 if unknown).
    pub time_resolution: f64,
}

/// The step allowance for timestamps rounded to `q`: `q` when the sampling interval `dt` is not a
/// whole multiple of `q` (the printed times are then rounded), else 0. Resolutions below
/// 1e-6·dt (full-precision printing) never matter and give 0.
fn rounding_allowance(q: f64, dt: f64) -> f64 {
    if !(q > 0.0 && q.is_finite() && dt > 0.0) || q < 1e-6 * dt {
        return 0.0;
    }
    let r = dt / q;
    if (r - r.round()).abs() > 1e-3 { q } else { 0.0 }
}

/// Refuses options whose required columns include the time column: a model or a DOF list that
/// names the time axis as a displacement or input would be scored against time itself.
pub(crate) fn time_not_required(file: &str, opts: &CsvOptions) -> Result<()> {
    if opts.required.contains(&opts.time_column) {
        return Err(DataError::Invalid {
            source_name: file.to_string(),
            message: format!(
                "'{0}' is the time column, yet it is asked for as a displacement or input column (a model's DOF or input named '{0}'); a record's DOFs and inputs are its other columns: use a model fitted on them, or name another time column",
                opts.time_column
            ),
        });
    }
    Ok(())
}

/// Checks a parsed table; returns the warnings (errors downgraded by options) or the first error.
pub(crate) fn check_table(tab: &Table<'_>, opts: &CsvOptions) -> Result<Vec<DataError>> {
    let file = tab.file.to_string();
    let tcol = opts.time_column.clone();
    let t = tab.t;
    let n = t.len();
    let first_line = tab.lines.first().copied().unwrap_or(1);
    // 1. strictly increasing
    for i in 1..n {
        if t[i] <= t[i - 1] {
            return Err(DataError::NonIncreasingTime {
                file,
                row: tab.lines[i],
                column: tcol,
                t_prev: t[i - 1],
                t: t[i],
            });
        }
    }
    let mut warnings = Vec::new();
    if n >= 3 {
        let dt = median_step(t);
        // The sampling interval without gaps (mean of the steps that are not gaps): rounded
        // timestamps have steps of ⌊dt/q⌋·q and ⌈dt/q⌉·q whose mean is dt.
        let (sum, cnt) = t
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|&st| st <= opts.gap_factor * dt)
            .fold((0.0, 0usize), |(s, c), st| (s + st, c + 1));
        let allow = rounding_allowance(tab.time_resolution, sum / cnt.max(1) as f64);
        // 2. gaps
        for i in 1..n {
            let step = t[i] - t[i - 1];
            if step > opts.gap_factor * dt + allow {
                return Err(DataError::TimeGap {
                    file,
                    row: tab.lines[i],
                    column: tcol,
                    t: t[i],
                    step,
                    dt,
                    ratio: step / dt,
                });
            }
        }
        if allow > 0.0 {
            // 3'. rounded timestamps: every one within q/2 + tol·dt of the uniform grid fitted
            // by least squares (the endpoints themselves are rounded).
            let kbar = 0.5 * (n - 1) as f64;
            let tbar = t.iter().sum::<f64>() / n as f64;
            let (sxy, sxx) = t.iter().enumerate().fold((0.0, 0.0), |(a, b), (k, &tk)| {
                let dk = k as f64 - kbar;
                (a + dk * (tk - tbar), b + dk * dk)
            });
            let slope = sxy / sxx;
            let t0 = tbar - slope * kbar;
            let (worst, dev) = (0..n)
                .map(|k| (k, (t[k] - (t0 + k as f64 * slope)).abs()))
                .fold((0, 0.0_f64), |acc, x| if x.1 > acc.1 { x } else { acc });
            if dev > 0.55 * allow + opts.time_tolerance * slope {
                let k = worst.max(1);
                return Err(DataError::NonUniformTime {
                    file,
                    row: tab.lines[k],
                    column: tcol,
                    step: t[k] - t[k - 1],
                    dt: slope,
                    rel: dev / slope,
                    tol: opts.time_tolerance,
                });
            }
            warnings.push(DataError::TimeRounded {
                file: file.clone(),
                column: tcol.clone(),
                resolution: allow,
                t0,
                dt: slope,
            });
        } else {
            // 3. uniform sampling: worst relative deviation
            let (worst, rel) = (1..n)
                .map(|i| (i, ((t[i] - t[i - 1]) - dt).abs() / dt))
                .fold((0, 0.0_f64), |acc, x| if x.1 > acc.1 { x } else { acc });
            if rel > opts.time_tolerance {
                return Err(DataError::NonUniformTime {
                    file,
                    row: tab.lines[worst],
                    column: tcol,
                    step: t[worst] - t[worst - 1],
                    dt,
                    rel,
                    tol: opts.time_tolerance,
                });
            }
        }
    }
    // 4. row count
    if n < opts.min_rows.max(2) {
        return Err(DataError::TooFewRows {
            file,
            last_row: tab.lines.last().copied().unwrap_or(1),
            rows: n,
            min: opts.min_rows.max(2),
        });
    }
    let col = |name: &str| {
        tab.names
            .iter()
            .position(|c| c == name)
            .map(|i| tab.data[i].as_slice())
    };
    let is_constant = |x: &[f64]| {
        let (lo, hi) = min_max(x);
        let scale = lo.abs().max(hi.abs());
        hi - lo <= 1e-12 * scale
    };
    // 5. constant required columns
    for name in &opts.required {
        if *name == opts.time_column {
            continue;
        }
        if let Some(x) = col(name) {
            if is_constant(x) {
                return Err(DataError::Constant {
                    file,
                    row: first_line,
                    column: name.clone(),
                    value: x[0],
                });
            }
        }
    }
    // 6. clipped channels
    if opts.saturation != Saturation::Allow {
        let checked: Vec<&String> = if opts.required.is_empty() {
            tab.names.iter().collect()
        } else {
            opts.required
                .iter()
                .filter(|r| **r != opts.time_column)
                .collect()
        };
        for name in checked {
            let Some(x) = col(name) else { continue };
            if is_constant(x) {
                continue;
            }
            if let Some(e) = saturation(&file, name, x, tab.lines, opts) {
                match opts.saturation {
                    Saturation::Error => return Err(e),
                    _ => warnings.push(e),
                }
            }
        }
    }
    Ok(warnings)
}

fn min_max(x: &[f64]) -> (f64, f64) {
    x.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// The clipping rule of the module docs, applied to the maximum then the minimum.
fn saturation(
    file: &str,
    name: &str,
    x: &[f64],
    lines: &[u64],
    opts: &CsvOptions,
) -> Option<DataError> {
    let (lo, hi) = min_max(x);
    let need = ((opts.saturation_fraction * x.len() as f64).ceil() as usize).max(1);
    for (which, value) in [("maximum", hi), ("minimum", lo)] {
        let count = x.iter().filter(|&&v| v == value).count();
        // longest run at the extreme and where it starts
        let (mut best, mut best_start, mut run, mut start) = (0, 0, 0, 0);
        for (i, &v) in x.iter().enumerate() {
            if v == value {
                if run == 0 {
                    start = i;
                }
                run += 1;
                if run > best {
                    best = run;
                    best_start = start;
                }
            } else {
                run = 0;
            }
        }
        if count >= need && best >= opts.saturation_run.max(1) {
            return Some(DataError::Saturated {
                file: file.to_string(),
                row: lines[best_start],
                column: name.to_string(),
                which,
                value,
                count,
                percent: 100.0 * count as f64 / x.len() as f64,
                run: best,
            });
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_distance_closed_forms() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("xb_acc", "xb_acc"), 0);
        assert_eq!(edit_distance("xbacc", "xb_acc"), 1);
    }

    #[test]
    fn suggestions_prefer_case_then_distance() {
        let av: Vec<String> = ["t", "X", "xb_acc", "xb_vel"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        assert_eq!(suggest("x", &av), Some("X"));
        assert_eq!(suggest("xb_ac", &av), Some("xb_acc"));
        assert_eq!(suggest("force", &av), None);
    }

    #[test]
    fn rounding_allowance_when_dt_is_not_a_multiple() {
        assert_eq!(rounding_allowance(1e-4, 1.0 / 3000.0), 1e-4);
        assert_eq!(rounding_allowance(1e-3, 1e-3), 0.0);
        assert_eq!(rounding_allowance(1e-17, 1e-3), 0.0);
        assert_eq!(rounding_allowance(1e-13, 1.37e-5), 0.0);
    }

    #[test]
    fn median_step_even_and_odd() {
        assert_eq!(median_step(&[0.0, 1.0, 3.0, 4.0]), 1.0);
        assert_eq!(median_step(&[0.0, 1.0, 3.0]), 1.5);
    }
}
