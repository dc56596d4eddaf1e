//! Python bindings of tfs: the native module `tfs._tfs` of the wheel `tfs` (built by maturin,
//! abi3, numpy arrays in and out). Every function calls the same library workflows as the CLI
//! (`tfs::identify`, `tfs::compare`, `tfs::refit`, …) with the GIL released while they run, so
//! the Python package has no logic of its own and gives the CLI's results to the bit.
//!
//! The module is built and tested from Python (`crates/tfs-py/tests`, pytest); a Rust doctest
//! cannot load it. In Python:
//!
//! ```python
//! import tfs
//! recs = tfs.simulate_kresling(gamma0=30, snr_db=30, seed=1, duration=40)
//! model = tfs.identify(recs, library="x^1..7, x', xb_acc")
//! model.print()
//! ```
//!
//! Errors are raised as `tfs.TfsError` (base), `tfs.InputError` (also a `ValueError`: bad input,
//! with the CLI's message) and `tfs.SimulationError` (a blow-up, with its time and state).

mod analysis;
mod convert;
mod errors;
mod model;
mod options;
mod record;

use pyo3::prelude::*;

/// The native module `tfs._tfs`.
#[pymodule]
fn _tfs(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<record::PyRecord>()?;
    m.add_class::<model::PyModel>()?;
    m.add_function(wrap_pyfunction!(model::identify, m)?)?;
    m.add_function(wrap_pyfunction!(model::load, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::basin, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::med, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::kresling, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::simulate_kresling, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::simulate_chain, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
