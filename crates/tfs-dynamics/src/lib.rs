//! Second-order dynamics: the system trait, integrators, simulation under a sampled input,
//! blow-up detection, equilibria of 1-DOF restoring forces, and simulation error metrics.
//!
//! Architecture invariant: this crate does no I/O; the integrators never allocate per step.
//!
//! * [`SecondOrderSystem`]: `x'' = a(t, x, x', u)`; one required method, `accel`.
//! * [`Integrator`]: [`Rk4`] (fixed step) and [`Dopri5`] (adaptive Dormand–Prince 5(4)), both
//!   stopping at every input sample time and every output time; blow-up gives
//!   [`DynError::BlowUp`] with the time and state.
//! * [`SampledInput`]: a measured excitation, interpolated by a not-a-knot cubic spline.
//! * [`equilibria`], [`barriers`], [`potential_from_force`]: 1-DOF statics.
//! * [`rmse_ratio`] (the paper's R-MSE) and [`rms_error`].
//! * [`simulate_model_on_record`]: a `tfs_library::Model` simulated under a record's inputs
//!   (`tfs_library::CompiledModel` implements [`SecondOrderSystem`]), from an initial state
//!   fitted to the start of the record ([`InitialState`], [`choose_initial_state`]).
//!
//! ```
//! use tfs_dynamics::{Dopri5, FnSystem, Integrator, SampledInput, rmse_ratio};
//! // Damped oscillator x'' + 0.1 x' + x = u(t), forced at 10 samples per period.
//! let sys = FnSystem::new(1, 1, |_t, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]| {
//!     a[0] = u[0] - 0.1 * v[0] - x[0]
//! });
//! let (w, dt) = (1.0_f64, 2.0 * std::f64::consts::PI / 10.0);
//! let t: Vec<f64> = (0..200).map(|k| k as f64 * dt).collect();
//! let u = SampledInput::new(0.0, dt, vec![t.iter().map(|t| (w * t).sin()).collect()]).unwrap();
//! let tr = Dopri5::default().integrate(&sys, &u, &[0.0], &[0.0], &t).unwrap();
//! assert_eq!(tr.x[0].len(), 200);
//! // An unstable model reports where and when it blew up.
//! let bad = FnSystem::new(1, 0, |_t, x: &[f64], _v: &[f64], _u: &[f64], a: &mut [f64]| a[0] = x[0] * x[0] * x[0]);
//! let err = Dopri5::default().integrate(&bad, &SampledInput::zero(0), &[1.0], &[0.0], &[0.0, 10.0]).unwrap_err();
//! assert!(err.to_string().contains("blew up at t ="));
//! assert!(rmse_ratio(&tr.x[0], &tr.x[0]).unwrap() == 0.0);
//! ```

#![warn(missing_docs)]

mod dopri5;
mod equilibria;
mod error;
mod initial;
mod input;
mod integrate;
mod memo;
mod metrics;
mod model;
mod range;
mod rk4;
mod system;

pub use dopri5::{BUDGET_BASE, Dopri5, Dopri5Solver, STEPS_PER_STOP};
pub use equilibria::{Barrier, Equilibrium, barriers, equilibria, potential_from_force};
pub use error::{DynError, Result};
pub use initial::{
    InitialFit, InitialState, choose_initial_state, fit_horizon, fit_initial_state,
    warm_initial_state,
};
pub use input::{Interpolation, SampledInput};
pub use integrate::{Integrator, Stats, Trajectory};
pub use metrics::{rms_error, rmse_ratio, rmse_variance};
pub use model::{
    RANGE_SPANS, RESOLVED_SPAN_ATOL, SimulateOptions, initial_velocity, r_mse_on_record,
    r_mse_on_record_warm, simulate_model_on_record, simulate_model_on_record_warm,
};
pub use range::range_band;
pub use rk4::{Rk4, Rk4Scratch, rk4_step};
pub use system::{FnSystem, SecondOrderSystem};
