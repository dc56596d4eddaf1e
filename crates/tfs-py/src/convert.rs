//! Conversions between Python values and the library's: arrays, JSON values, records arguments.

use numpy::ndarray::Array2;
use numpy::{AllowTypeChange, IntoPyArray, PyArray2, PyArrayLike1, PyArrayLikeDyn};
use pyo3::prelude::*;

use crate::errors::{OrRaise, PyResult, input_error};
use crate::record::PyRecord;

/// A JSON value as the Python object `json.loads` gives (dicts, lists, floats, …).
pub fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v).map_err(|e| input_error(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A 1-D float array (or anything numpy turns into one) as a vector; `what` names it in errors.
pub fn vec1(a: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
    let arr: PyArrayLike1<'_, f64, AllowTypeChange> = a
        .extract()
        .map_err(|_| input_error(format!("{what}: expected a 1-D array of numbers")))?;
    Ok(arr.as_array().to_vec())
}

/// An array of one or two dimensions as columns (a 1-D array is one column); `what` names it.
pub fn columns(a: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vec<f64>>> {
    let arr: PyArrayLikeDyn<'_, f64, AllowTypeChange> = a
        .extract()
        .map_err(|_| input_error(format!("{what}: expected an array of numbers")))?;
    let view = arr.as_array();
    match view.ndim() {
        1 => Ok(vec![view.iter().copied().collect()]),
        2 => Ok(view
            .columns()
            .into_iter()
            .map(|c| c.iter().copied().collect())
            .collect()),
        d => Err(input_error(format!(
            "{what}: expected a 1-D array (one column) or a 2-D array (samples × columns), got {d} dimensions"
        ))),
    }
}

/// Columns of equal length as a 2-D array (samples × columns).
pub fn to_array2<'py>(
    py: Python<'py>,
    cols: &[Vec<f64>],
    rows: usize,
) -> Bound<'py, PyArray2<f64>> {
    let mut a = Array2::<f64>::zeros((rows, cols.len()));
    for (j, c) in cols.iter().enumerate() {
        for (i, v) in c.iter().enumerate().take(rows) {
            a[[i, j]] = *v;
        }
    }
    a.into_pyarray(py)
}

/// The records argument: a `Record`, a CSV path, or a sequence of them. Paths are read as the CLI
/// reads them (full validation follows in [`tfs::records::check_records`] once the required
/// columns are known); returns the records and the warnings raised while reading.
pub fn records_arg(
    obj: &Bound<'_, PyAny>,
    what: &str,
) -> PyResult<(Vec<tfs::data::Record>, Vec<String>)> {
    let items: Vec<Bound<'_, PyAny>> = if obj.is_instance_of::<PyRecord>() || is_path(obj) {
        vec![obj.clone()]
    } else if let Ok(list) = obj.extract::<Vec<Bound<'_, PyAny>>>() {
        list
    } else {
        return Err(input_error(format!(
            "{what}: expected a Record, a CSV path, or a list of them"
        )));
    };
    if items.is_empty() {
        return Err(input_error(format!(
            "{what}: no records given; pass one or more"
        )));
    }
    let mut out = Vec::with_capacity(items.len());
    let mut warnings = Vec::new();
    for it in items {
        if let Ok(r) = it.cast::<PyRecord>() {
            out.push(r.borrow().inner.clone());
        } else if is_path(&it) {
            let path: std::path::PathBuf = it.extract()?;
            let (rec, w) = it.py().detach(|| PyRecord::read(&path)).or_raise()?;
            warnings.extend(w);
            out.push(rec);
        } else {
            return Err(input_error(format!(
                "{what}: expected a Record or a CSV path, got {}",
                it.get_type().name()?
            )));
        }
    }
    Ok((out, warnings))
}

fn is_path(obj: &Bound<'_, PyAny>) -> bool {
    obj.is_instance_of::<pyo3::types::PyString>()
        || obj
            .py()
            .import("os")
            .and_then(|os| os.getattr("PathLike"))
            .and_then(|pl| obj.is_instance(&pl))
            .unwrap_or(false)
}

/// Issues each warning as a Python `UserWarning` attributed to the caller's line (the first
/// frame outside the `tfs` package, see `tfs/_warn.py`), so that a script's warning names the
/// script's file and the call that warned.
pub fn warn_all(py: Python<'_>, warnings: &[String]) -> PyResult<()> {
    if warnings.is_empty() {
        return Ok(());
    }
    let messages: Vec<String> = warnings
        .iter()
        .map(|w| crate::errors::pythonize(w))
        .collect();
    py.import("tfs._warn")?
        .call_method1("warn_all", (messages,))?;
    Ok(())
}
