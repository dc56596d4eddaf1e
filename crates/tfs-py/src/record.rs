//! `tfs.Record`: one measurement record (a uniform time axis and named columns) from numpy
//! arrays or a CSV file, validated by the rules the CLI applies to files.

use std::path::{Path, PathBuf};

use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use tfs::data::{CsvOptions, Record, Saturation};

use crate::convert::{columns, vec1, warn_all};
use crate::errors::{OrRaise, PyResult, input_error};

/// One measurement record: a uniformly sampled time axis `t` (s) and named columns
/// (displacements `x` or `x1`, `x2`, …, and inputs such as `xb_acc`, `u`, `force`).
#[pyclass(name = "Record", module = "tfs._tfs", frozen)]
#[derive(Clone)]
pub struct PyRecord {
    /// The record.
    pub inner: Record,
}

impl PyRecord {
    /// Reads a CSV file as the CLI does (its checks with every column optional and clipping
    /// left to the command that uses the record); returns the record and the warnings.
    pub fn read(path: &Path) -> tfs::Result<(Record, Vec<String>)> {
        let opts = CsvOptions::default().saturation(Saturation::Allow);
        let (rec, w) = tfs::data::read_csv_checked(path, &opts)?;
        Ok((rec, w.iter().map(ToString::to_string).collect()))
    }
}

#[pymethods]
impl PyRecord {
    /// A record from arrays: `x` (one DOF as a 1-D array, several as samples × DOFs), the time
    /// axis `t` or the sampling interval `dt` (with start `t0`), `inputs` by name, `dofs` to
    /// name the displacement columns (default `x`, or `x1`, `x2`, …).
    #[new]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (x, *, t=None, dt=None, t0=0.0, inputs=None, dofs=None, name="record"))]
    fn new(
        py: Python<'_>,
        x: &Bound<'_, PyAny>,
        t: Option<&Bound<'_, PyAny>>,
        dt: Option<f64>,
        t0: f64,
        inputs: Option<&Bound<'_, PyDict>>,
        dofs: Option<Vec<String>>,
        name: &str,
    ) -> PyResult<Self> {
        let xs = columns(x, "x")?;
        let n = xs[0].len();
        let names = match dofs {
            Some(d) if d.len() == xs.len() => d,
            Some(d) => {
                return Err(input_error(format!(
                    "dofs: {} name(s) for {} displacement column(s); give one name per column",
                    d.len(),
                    xs.len()
                )));
            }
            None if xs.len() == 1 => vec!["x".to_string()],
            None => (1..=xs.len()).map(|k| format!("x{k}")).collect(),
        };
        let time = match (t, dt) {
            (Some(t), None) => vec1(t, "t")?,
            (None, Some(dt)) => {
                if !(dt.is_finite() && dt > 0.0) {
                    return Err(input_error(format!(
                        "dt {dt}: must be a positive number of seconds"
                    )));
                }
                (0..n).map(|k| t0 + k as f64 * dt).collect()
            }
            _ => {
                return Err(input_error(
                    "give the time axis t or the sampling interval dt (one of them)",
                ));
            }
        };
        let mut cols: Vec<(String, Vec<f64>)> = names.into_iter().zip(xs).collect();
        if let Some(inputs) = inputs {
            for (k, v) in inputs.iter() {
                let k: String = k
                    .extract()
                    .map_err(|_| input_error("inputs: keys must be column names"))?;
                let v = vec1(&v, &format!("inputs['{k}']"))?;
                cols.push((k, v));
            }
        }
        let rec = Record::new(name, time, cols).or_raise()?;
        let opts = CsvOptions::default().saturation(Saturation::Allow);
        let (rec, warnings) = py
            .detach(|| tfs::data::check_record(rec, &opts))
            .or_raise()?;
        let w: Vec<String> = warnings.iter().map(ToString::to_string).collect();
        warn_all(py, &w)?;
        Ok(Self { inner: rec })
    }

    /// Reads a CSV file (header `t`, displacement columns, inputs) with the CLI's checks.
    #[staticmethod]
    fn from_csv(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let (rec, w) = py.detach(|| Self::read(&path)).or_raise()?;
        warn_all(py, &w)?;
        Ok(Self { inner: rec })
    }

    /// Writes the record as CSV (values read back to the same bits), atomically.
    fn to_csv(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| tfs::data::write_csv(&path, &self.inner))
            .or_raise()
    }

    /// The time axis (s).
    #[getter]
    fn t<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.t().to_vec().into_pyarray(py)
    }

    /// The sampling interval (s).
    #[getter]
    fn dt(&self) -> f64 {
        self.inner.dt()
    }

    /// The column names (without `t`).
    #[getter]
    fn names(&self) -> Vec<String> {
        self.inner.names().to_vec()
    }

    /// Where the record came from (its file, or the name given).
    #[getter]
    fn source(&self) -> String {
        self.inner.source().to_string()
    }

    /// The column `name` as an array.
    fn __getitem__<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArray1<f64>>> {
        match self.inner.column(name) {
            Some(c) => Ok(c.to_vec().into_pyarray(py)),
            None => Err(pyo3::exceptions::PyKeyError::new_err(format!(
                "{}: no column '{name}'; the record has [{}]",
                self.inner.source(),
                self.inner.names().join(", ")
            ))),
        }
    }

    /// Whether the record has the column `name`.
    fn __contains__(&self, name: &str) -> bool {
        self.inner.column(name).is_some()
    }

    /// Number of samples.
    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Record('{}', {} samples, dt = {:.4e} s, columns [{}])",
            self.inner.source(),
            self.inner.len(),
            self.inner.dt(),
            self.inner.names().join(", ")
        )
    }

    /// Pickling: the source, the time axis and the columns.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let r = &slf.get().inner;
        let cols: Vec<(String, Vec<f64>)> = r
            .names()
            .iter()
            .map(|n| (n.clone(), r.column(n).unwrap_or_default().to_vec()))
            .collect();
        let restore = py.get_type::<PyRecord>().getattr("_restore")?;
        PyTuple::new(
            py,
            [
                restore,
                (r.source().to_string(), r.t().to_vec(), cols)
                    .into_pyobject(py)?
                    .into_any(),
            ],
        )
    }

    /// Rebuilds a pickled record.
    #[staticmethod]
    fn _restore(source: String, t: Vec<f64>, cols: Vec<(String, Vec<f64>)>) -> PyResult<Self> {
        Ok(Self {
            inner: Record::new(source, t, cols).or_raise()?,
        })
    }
}
