//! Basins of attraction (BOA), BOA error and minimum-energy deployment (MED) of multi-stable
//! structures (paper §3, Eq. 17, Figs 4 and 7).
//!
//! * [`WellInfo`] finds the equilibria, wells and energy barriers of a 1-DOF restoring force.
//! * [`basin_sdof`] / [`basin_chain`] label a grid of initial conditions by the stable state
//!   each unforced trajectory settles in. A trajectory is fixed-step RK4 and stops as soon as it
//!   is provably trapped: inside a well with energy below the lowest barrier out of it (damping
//!   only removes energy). By default ([`Method::Refined`]) a coarse lattice of starts is
//!   integrated first and, level by level, only the starts whose surroundings disagree (in end
//!   state or in the number of well crossings on the way) are integrated; starts run sixteen at
//!   a time in SIMD lanes. Results do not depend on the thread count.
//! * [`step_limit_sdof`] / [`step_limit_chain`] bound the RK4 step by the system's fastest
//!   linearised rate on the reachable states (a longer step is refused, not run).
//! * [`boa_error`] / [`compare`] give the share of disagreeing cells and the disagreement mask.
//! * [`med_sdof`] / [`med_chain`] find the minimum input energy that deploys S1 → S2.
//!
//! ```
//! use tfs_basin::{BasinConfig, Label, Polynomial1Dof, WellInfo, basin_sdof, med_sdof};
//! // Paper Table 1 (60 dB): x'' + 1.99 x' + 12.12 x^5 − 18.03 x^6 + 6.56 x^7 = 0.
//! let model = Polynomial1Dof::table1_60db();
//! let wells = WellInfo::from_polynomial(&model, (-1.0, 2.5)).unwrap();
//! assert_eq!(wells.stable().len(), 2); // S1 = 0, S2 ≈ 1.577
//! let cfg = BasinConfig::new(40, 40, (-0.5, 2.0), (-2.0, 2.0));
//! let map = basin_sdof(&model, &wells, &cfg, None).unwrap();
//! assert_eq!(map.label(0, 20), Label::State(0)); // x0 = −0.5, v0 ≈ 0 stays undeployed
//! let med = med_sdof(&model, &wells, &map, &cfg, 0, 1).unwrap();
//! assert!(med.energy >= med.quasi_static_barrier * (1.0 - 1e-6));
//! ```

mod chain;
mod compare;
mod error;
mod grid;
mod lanes;
mod limits;
mod med;
mod refine;
mod scalar;
mod wells;

pub use chain::{ChainWells, Slice, SliceAxis, VectorFn, basin_chain, classify_chain};
pub use compare::{BoaComparison, boa_error, compare, relabel_to_nearest};
pub use error::{BasinError, Result};
pub use grid::{
    BasinConfig, BasinMap, Label, MAX_CELLS, MAX_STEPS, Method, Progress, basin_sdof,
    classify_sdof, dt_convergence,
};
pub use limits::{RK4_STABLE, StepLimit, step_limit_chain, step_limit_sdof};
pub use med::{ChainMed, Med, med_chain, med_sdof};
pub use wells::{Polynomial1Dof, ScalarFn, Well, WellInfo};
