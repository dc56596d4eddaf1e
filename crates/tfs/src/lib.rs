//! tfs: sparse, interpretable equations of motion for nonlinear, multi-stable structures, identified
//! from noisy vibration measurements with T-F-S SINDy (and classical SINDy as the baseline).
//!
//! This facade re-exports every layer so that a downstream crate needs one dependency, and
//! [`prelude`] the few types and functions most programs start from; the `tfs` binary (the CLI)
//! is built on it. See `docs/ARCHITECTURE.md` for what each layer owns.
//!
//! It also holds the workflows that the CLI and the Python package (`crates/tfs-py`) share, so
//! that both give the same results on the same data: [`records`] (validation, the DOF and input
//! columns, the offsets policy), [`identify`] (options with the CLI's defaults, default libraries,
//! fit and refinement), [`compare`], [`refit`], [`decide`] (which effect a model is missing: one decision
//! for `diagnose` and the loop), [`sdof`] (1-DOF systems for basins and MED) and [`simulate`]
//! (the Kresling records, a model run from a given state).
//!
//! ```
//! use tfs::library::{Library, Model};
//! // The paper's Table 1 model as a tfs-model/1 file, read back and simulated free of input.
//! let json = r#"{"format":"tfs-model/1","dofs":["x"],"inputs":[],
//!   "equations":[{"dof":"x","terms":[{"term":"x'","coef":-1.99},{"term":"x^5","coef":-12.12},
//!   {"term":"x^6","coef":18.03},{"term":"x^7","coef":-6.56}]}],"method":"paper"}"#;
//! let model = Model::from_json_str(json).unwrap();
//! let lib = Library::parse("x^5..7, x'", &["x"]).unwrap();
//! assert_eq!(lib.len(), 4);
//! // The restoring force vanishes at the folded state h = 0.
//! assert_eq!(model.restoring_force("x", 0.0).unwrap(), 0.0);
//! ```

pub mod chain;
pub mod compare;
pub mod contact;
pub mod decide;
mod error;
pub mod gate;
pub mod identify;
pub mod offsets_choice;
pub mod records;
pub mod refit;
pub mod report;
mod restore;
pub mod sdof;
pub mod simulate;

pub use error::{Context, Error, Result, one_line};

pub use tfs_basin as basin;
pub use tfs_criteria as criteria;
pub use tfs_data as data;
pub use tfs_diagnose as diagnose;
pub use tfs_dynamics as dynamics;
pub use tfs_library as library;
pub use tfs_origami as origami;
pub use tfs_plot as plot;
pub use tfs_refine as refine;
pub use tfs_regress as regress;
pub use tfs_signal as signal;

/// What most programs start from, in one import: records, libraries and models, the
/// identification pipelines with their options and trace, and simulation of a model.
///
/// ```
/// use tfs::prelude::*;
/// // A spec with the default T-F-S options: the library of every DOF, checked when it runs.
/// let mut spec = IdentifySpec::new(&["x"], "x^1..7, x', xb_acc");
/// spec.tfs.criterion3.window_counts = vec![3];
/// assert_eq!(Library::parse(&spec.library, &spec.dofs).unwrap().len(), 9);
/// ```
pub mod prelude {
    pub use tfs_criteria::{
        Identified, IdentifySpec, MassChoice, TfsOptions, TieOptions, Trace, identify_sindy,
        identify_tfs, identify_tfs_tied,
    };
    pub use tfs_data::{Record, read_csv};
    pub use tfs_dynamics::{SimulateOptions, simulate_model_on_record};
    pub use tfs_library::{Library, Model, Term};
}
