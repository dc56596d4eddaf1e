//! The in-memory record: a time axis and named columns of equal length.

use std::sync::Arc;

use crate::{DataError, Result};

/// Read access to named columns of equal length (a record, or derived state such as `x'`).
pub trait Columns {
    /// The column called `name`, if present.
    fn column(&self, name: &str) -> Option<&[f64]>;
    /// Number of rows of every column.
    fn rows(&self) -> usize;
}

/// One measurement record: a uniformly sampled time axis `t` and named data columns.
///
/// Columns are shared between clones and copied only when written (`set_column` replaces a
/// column, `remove_offsets` copies one that another clone still holds): a record passed on with a
/// column added or perturbed (a simulation's input, a noise draw) costs the new column, not a
/// copy of every sample of the record.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    source: String,
    t: Arc<Vec<f64>>,
    names: Vec<String>,
    data: Vec<Arc<Vec<f64>>>,
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
        for (name, mut col) in columns {
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
            // A column read row by row has up to twice its length allocated; a record keeps its
            // columns for as long as it lives.
            col.shrink_to_fit();
            data.push(Arc::new(col));
        }
        let mut t = t;
        t.shrink_to_fit();
        Ok(Self {
            source,
            t: Arc::new(t),
            names,
            data,
        })
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
            Some(i) => self.data[i] = Arc::new(values),
            None => {
                self.names.push(name);
                self.data.push(Arc::new(values));
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

impl Record {
    fn missing(&self, name: &str) -> DataError {
        crate::validate::missing_column(
            &self.source,
            1,
            name,
            "column",
            &self.names,
            "; use one of the existing names",
        )
    }

    /// The listed columns as an `n × names.len()` array (one row per sample). `"t"` selects the
    /// time axis. A missing name is an error that lists the columns that exist.
    pub fn to_ndarray<S: AsRef<str>>(&self, names: &[S]) -> Result<ndarray::Array2<f64>> {
        let cols = names
            .iter()
            .map(|n| {
                self.column(n.as_ref())
                    .ok_or_else(|| self.missing(n.as_ref()))
            })
            .collect::<Result<Vec<&[f64]>>>()?;
        Ok(ndarray::Array2::from_shape_fn(
            (self.len(), cols.len()),
            |(i, j)| cols[j][i],
        ))
    }

    /// Builds a record from a time axis and an `n × names.len()` array whose columns are named by
    /// `names`; the shapes must agree.
    pub fn from_ndarray<S: AsRef<str>>(
        source: impl Into<String>,
        t: Vec<f64>,
        names: &[S],
        data: &ndarray::Array2<f64>,
    ) -> Result<Self> {
        let source = source.into();
        if data.ncols() != names.len() || data.nrows() != t.len() {
            return Err(DataError::Invalid {
                message: format!(
                    "array is {}x{} but {} time samples and {} names were given; pass one row per sample and one name per column",
                    data.nrows(),
                    data.ncols(),
                    t.len(),
                    names.len()
                ),
                source_name: source,
            });
        }
        let columns = names
            .iter()
            .zip(data.columns())
            .map(|(n, c)| (n.as_ref().to_string(), c.to_vec()))
            .collect();
        Self::new(source, t, columns)
    }

    /// The samples with indices in `range` (time values are kept, not shifted).
    pub fn slice(&self, range: std::ops::Range<usize>) -> Result<Self> {
        if range.start > range.end || range.end > self.len() {
            return Err(DataError::Invalid {
                source_name: self.source.clone(),
                message: format!(
                    "slice {}..{} is outside the record's {} samples; choose a range within 0..{}",
                    range.start,
                    range.end,
                    self.len(),
                    self.len()
                ),
            });
        }
        Ok(Self {
            source: self.source.clone(),
            t: Arc::new(self.t[range.clone()].to_vec()),
            names: self.names.clone(),
            data: self
                .data
                .iter()
                .map(|c| Arc::new(c[range.clone()].to_vec()))
                .collect(),
        })
    }

    /// Subtracts the mean of each listed column in place and returns the offsets removed, in the
    /// order given. The time axis cannot be offset this way.
    pub fn remove_offsets<S: AsRef<str>>(&mut self, names: &[S]) -> Result<Vec<(String, f64)>> {
        let mut idx = Vec::with_capacity(names.len());
        for n in names {
            let n = n.as_ref();
            match self.names.iter().position(|c| c == n) {
                Some(i) => idx.push(i),
                None => return Err(self.missing(n)),
            }
        }
        if self.is_empty() {
            return Err(DataError::Invalid {
                source_name: self.source.clone(),
                message: "cannot remove offsets from an empty record; load some samples first"
                    .into(),
            });
        }
        let mut out = Vec::with_capacity(idx.len());
        for i in idx {
            let col = Arc::make_mut(&mut self.data[i]);
            let mean = col.iter().sum::<f64>() / col.len() as f64;
            col.iter_mut().for_each(|v| *v -= mean);
            out.push((self.names[i].clone(), mean));
        }
        Ok(out)
    }
}
