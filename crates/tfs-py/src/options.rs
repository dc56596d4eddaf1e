//! Every option a Python call can set, turned into the library's option types in one place
//! (keyword names and defaults are the CLI's flags), so that a change of the library's options
//! is adapted here only.

use tfs::identify::{IdentifyOptions, Method, Tie};
use tfs::records::{Clipped, Offsets};

use crate::errors::{OrRaise, PyResult};

/// The keywords of `tfs.identify` (the flags of `tfs identify`).
#[allow(clippy::too_many_arguments)]
pub fn identify_options(
    library: Option<String>,
    method: &str,
    dofs: Option<Vec<String>>,
    threshold: Option<f64>,
    refine: bool,
    tie: Option<bool>,
    masses: &str,
    offsets: &str,
) -> PyResult<IdentifyOptions> {
    Ok(IdentifyOptions {
        library,
        method: Method::parse(method, "method").or_raise()?,
        dofs: dofs.unwrap_or_default(),
        threshold,
        refine,
        tie: match tie {
            None => Tie::Auto,
            Some(true) => Tie::On,
            Some(false) => Tie::Off,
        },
        masses: masses.to_string(),
        offsets: offsets_mode(offsets)?,
    })
}

/// `offsets=`: `auto`, `keep`, `remove` or `constant-term`.
pub fn offsets_mode(text: &str) -> PyResult<Offsets> {
    Offsets::parse(text, "offsets").or_raise()
}

/// `clipped=`: `error`, `warn` or `allow`.
pub fn clipped_policy(text: &str) -> PyResult<Clipped> {
    Clipped::parse(text, "clipped").or_raise()
}

/// The options of `tfs.diagnose` (the flags of `tfs diagnose`).
pub fn diagnose_options(alpha: f64, min_share: f64) -> tfs::diagnose::DiagnoseOptions {
    tfs::diagnose::DiagnoseOptions {
        alpha,
        min_share,
        ..tfs::diagnose::DiagnoseOptions::default()
    }
}

/// The basin grid (the flags of `tfs basin`).
pub fn basin_config(
    grid: (usize, usize),
    x: (f64, f64),
    v: (f64, f64),
    dt: f64,
    t_max: f64,
) -> PyResult<tfs::basin::BasinConfig> {
    let mut cfg = tfs::basin::BasinConfig::new(grid.0, grid.1, x, v);
    cfg.dt = dt;
    cfg.t_max = t_max;
    cfg.validate().or_raise()?;
    Ok(cfg)
}
