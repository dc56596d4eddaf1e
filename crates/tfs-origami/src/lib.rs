//! Kresling origami truss cells (paper Appendix A), serial chains of cells (§3.2) and synthetic
//! vibration datasets of them.
//!
//! * [`KreslingCell`]: crease geometry, the torque-free branch `θ(h)`, tabulated force `F(h)` and
//!   potential `V(h)` (`V(0) = 0`) with a folded stop for `h < 0`, equilibria, barriers, curves.
//! * [`Truth`]: simulate the truss force itself ([`Truth::Truss`]) or its run-time
//!   `{h^5, h^6, h^7}` least-squares surrogate ([`Truth::Surrogate`], the paper's setting).
//! * [`CellSystem`], [`Chain`]: base-excited [`tfs_dynamics::SecondOrderSystem`]s.
//! * [`generate`]: sweeps/sines of base acceleration, simulated and noised into
//!   [`tfs_data::Record`]s with metadata.
//! * [`oscillator`]: single-DOF truths with memory and hidden effects for testing a diagnosis:
//!   the Bouc–Wen hysteretic benchmark oscillator and Duffing oscillators (single or double
//!   well) with friction, damping, stiffness, offset, stop, Maxwell, Bouc–Wen, Dahl or exciter
//!   effects.
//! * [`hidden`]: any of those effects placed on an element or a mass of any system (a chain's
//!   coupling, a truss cell), [`WithHidden`], simulated from rest by [`simulate_motion`].
//!
//! Architecture invariant: no I/O; every result records which truth produced it.
//!
//! ```
//! use tfs_origami::{KreslingCell, KreslingParams};
//! let cell = KreslingCell::new(KreslingParams::default()).unwrap();
//! let s = cell.summary();
//! assert_eq!(s.classification, "bistable");
//! assert!((s.stable[1] - 1.582).abs() < 1e-3);
//! // F = dV/dh on the branch; the deployed state is a zero of F.
//! assert!(cell.force(s.stable[1]).abs() < 1e-9);
//! ```

#![deny(missing_docs)]

mod cell;
mod dataset;
mod geometry;
pub mod hidden;
pub mod oscillator;
mod system;
mod truth;

pub use cell::{Barrier, BranchPoint, CellOptions, CellSummary, Curve, KreslingCell};
pub use dataset::{
    CellSpec, Dataset, DatasetConfig, DatasetMeta, Excitation, NoiseKind, RecordMeta, SystemSpec,
    build_system, generate,
};
pub use geometry::KreslingParams;
pub use hidden::{Motion, On, Placed, WithHidden, simulate_motion};
pub use oscillator::{BoucWenOscillator, Hidden, Oscillator};
pub use system::{CellSystem, Chain, ChainEquilibrium};
pub use truth::{CellForce, Surrogate, SurrogateSpec, Truth};

/// Errors of this crate.
#[derive(Debug, thiserror::Error)]
pub enum OrigamiError {
    /// A parameter is out of range; the message names it and says what to do.
    #[error("invalid parameter: {0}")]
    Param(String),
    /// The torque-free branch could not be followed.
    #[error("torque-free branch: {0}")]
    Branch(String),
    /// A numerical sub-step (least squares) failed.
    #[error("numerical failure: {0}")]
    Numeric(String),
    /// A simulation failed (blow-up, step-size underflow).
    #[error("simulation of record {record} failed: {source}")]
    Simulation {
        /// Index of the record in the dataset.
        record: usize,
        /// The integrator's error.
        #[source]
        source: tfs_dynamics::DynError,
    },
    /// An excitation or noise parameter was rejected by `tfs-signal`.
    #[error("excitation: {0}")]
    Signal(#[from] tfs_signal::SignalError),
    /// A record could not be assembled.
    #[error(transparent)]
    Data(#[from] tfs_data::DataError),
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, OrigamiError>;
