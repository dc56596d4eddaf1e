//! tfs errors as Python exceptions: the classes live in `tfs/errors.py` (so that
//! `InputError` can be both a `TfsError` and a `ValueError`, and every exception pickles across
//! processes); the message is the CLI's one-line message.

use pyo3::prelude::*;

/// Builds the Python exception class `name` of `tfs.errors` with `args`.
fn raise<'py, A: pyo3::call::PyCallArgs<'py>>(py: Python<'py>, name: &str, args: A) -> PyErr {
    let made = py
        .import("tfs.errors")
        .and_then(|m| m.getattr(name))
        .and_then(|cls| cls.call1(args));
    match made {
        Ok(obj) => PyErr::from_value(obj),
        Err(e) => e,
    }
}

/// Converts a tfs error into `SimulationError` (a blow-up, with its time and state),
/// `InputError` (bad input: a file, a column, an argument) or `TfsError`.
pub fn to_py(e: tfs::Error) -> PyErr {
    let msg = tfs::one_line(&e);
    Python::attach(|py| {
        if let Some(tfs::dynamics::DynError::BlowUp { t, x, v }) = e.blow_up() {
            return raise(py, "SimulationError", (msg, *t, x.clone(), v.clone()));
        }
        if e.is_bad_input() {
            raise(py, "InputError", (msg,))
        } else {
            raise(py, "TfsError", (msg,))
        }
    })
}

/// A bad argument found by the bindings themselves (an array of the wrong shape).
pub fn input_error(msg: impl Into<String>) -> PyErr {
    to_py(tfs::Error::Invalid(msg.into()))
}

/// Result alias of the bindings.
pub type PyResult<T> = Result<T, PyErr>;

/// Maps a tfs result to a Python one.
pub trait OrRaise<T> {
    /// The value, or the error as a Python exception.
    fn or_raise(self) -> PyResult<T>;
}

impl<T, E: Into<tfs::Error>> OrRaise<T> for Result<T, E> {
    fn or_raise(self) -> PyResult<T> {
        self.map_err(|e| to_py(e.into()))
    }
}
