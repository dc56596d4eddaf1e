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

/// The CLI's flags and the Python keywords they are: a value flag by its keyword's name
/// (`--threshold` is `threshold`), a switch by the keyword's value (`--refine` is
/// `refine=True`).
const KEYWORDS: &[(&str, &str)] = &[
    ("--until-clean", "until_clean"),
    ("--min-share", "min_share"),
    ("--no-tie", "tie=False"),
    ("--threshold", "threshold"),
    ("--library", "library"),
    ("--offsets", "offsets"),
    ("--clipped", "clipped"),
    ("--validate", "validate"),
    ("--masses", "masses"),
    ("--method", "method"),
    ("--refine", "refine=True"),
    ("--alpha", "alpha"),
    ("--dofs", "dofs"),
    ("--tie", "tie=True"),
    ("--add", "add"),
];

/// A message of the library, which names the CLI's flags, as a Python user reads it: each
/// flag replaced by its keyword, and a flag followed by a number written as the keyword
/// argument (`--threshold -1` becomes `threshold=-1`).
pub fn pythonize(msg: &str) -> String {
    let mut out = String::with_capacity(msg.len());
    let mut rest = msg;
    while let Some(at) = rest.find("--") {
        out.push_str(&rest[..at]);
        let tail = &rest[at..];
        let flag_len = 2 + tail[2..]
            .find(|c: char| !(c.is_ascii_lowercase() || c == '-'))
            .unwrap_or(tail.len() - 2);
        let flag = &tail[..flag_len];
        rest = &tail[flag_len..];
        match KEYWORDS.iter().find(|(f, _)| *f == flag) {
            Some((_, kw)) => {
                out.push_str(kw);
                let number = rest.strip_prefix(' ').filter(|r| {
                    r.starts_with(|c: char| c.is_ascii_digit() || c == '-' || c == '.')
                });
                if let (Some(r), false) = (number, kw.contains('=')) {
                    out.push('=');
                    rest = r;
                }
            }
            None => out.push_str(flag),
        }
    }
    out.push_str(rest);
    out
}

/// Converts a tfs error into `SimulationError` (a blow-up, with its time and state),
/// `InputError` (bad input: a file, a column, an argument) or `TfsError`; the message names
/// Python keywords where the library's names the CLI's flags.
pub fn to_py(e: tfs::Error) -> PyErr {
    let msg = pythonize(&tfs::one_line(&e));
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
