//! The in-memory record: a time axis and named columns of equal length.

use crate::{DataError, Result};

/// Read access to named columns of equal length (a record, or derived state such as `x'`).
pub trait Columns {
    /// The column called `name`, if present.
    fn column(&self, name: &str) -> Option<&[f64]>;
    /// Number of rows of every column.
    fn rows(&self) -> usize;
}

/// One measurement record: a uniformly sampled time axis `t` and named data columns.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    source: String,
    t: Vec<f64>,
    names: Vec<String>,
    data: Vec<Vec<f64>>,
}

impl Record {
    /// Builds a record; every column must have as many rows as `t`, and names must be unique.
    pub fn new(
        source: impl Into<String>,
        t: Vec<f64>,
        columns: Vec<(String, Vec<f64>)>,
    ) -> Result<Self> {
        let source = source.into();
        let mut names = Vec::with_capacity(columns.len());
        let mut data = Vec::with_capacity(columns.len());
        for (name, col) in columns {
            if col.len() != t.len() {
                return Err(DataError::Invalid {
                    source_name: source,
                    message: format!(
                        "column '{name}' has {} rows but the time axis has {}; give every column the same length",
                        col.len(),
                        t.len()
                    ),
                });
            }
            if names.contains(&name) {
                return Err(DataError::Invalid {
                    source_name: source,
                    message: format!("column '{name}' appears twice; rename one of them"),
                });
            }
            names.push(name);
            data.push(col);
        }
        Ok(Self { source, t, names, data })
    }

    /// Where the record came from (file path or a generated name).
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The time axis in seconds.
    pub fn t(&self) -> &[f64] {
        &self.t
    }

    /// Sampling interval, taken from the first and last samples (the axis is uniform).
    pub fn dt(&self) -> f64 {
        let n = self.t.len();
        if n < 2 {
            return f64::NAN;
        }
        (self.t[n - 1] - self.t[0]) / (n - 1) as f64
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True if the record has no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Column names in order (the time column excluded).
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Adds or replaces a column.
    pub fn set_column(&mut self, name: impl Into<String>, values: Vec<f64>) -> Result<()> {
        let name = name.into();
        if values.len() != self.t.len() {
            return Err(DataError::Invalid {
                source_name: self.source.clone(),
                message: format!(
                    "column '{name}' has {} rows but the time axis has {}",
                    values.len(),
                    self.t.len()
                ),
            });
        }
        match self.names.iter().position(|n| *n == name) {
            Some(i) => self.data[i] = values,
            None => {
                self.names.push(name);
                self.data.push(values);
            }
        }
        Ok(())
    }
}

impl Columns for Record {
    fn column(&self, name: &str) -> Option<&[f64]> {
        if name == "t" {
            return Some(&self.t);
        }
        self.names
            .iter()
            .position(|n| n == name)
            .map(|i| self.data[i].as_slice())
    }

    fn rows(&self) -> usize {
        self.t.len()
    }
}

impl Record {
    /// The column called `name`, if present (`"t"` gives the time axis).
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        Columns::column(self, name)
    }
}
