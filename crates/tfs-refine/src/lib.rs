//! tfs-refine: simulation-error refinement of identified models.
//!
//! An equation-error fit (what SINDy solves) can match accelerations well and still simulate
//! badly. [`refine`] keeps a [`tfs_library::Model`]'s sparse structure and re-estimates its
//! coefficients to minimise the free-run simulation error of the displacements on training
//! records:
//!
//! * **Levenberg–Marquardt** on faer, with Marquardt column scaling `D² = diag(JᵀJ)`
//!   (so coefficients spanning 1e-2…1e6 are handled; unknowns are also scaled internally by
//!   the start coefficients and the data RMS) and a trust-region-style damping update.
//!   The damped normal equations are solved by block elimination: with multiple shooting the
//!   Gauss–Newton matrix is block-tridiagonal in the segment states with a dense border for the
//!   coefficients, so records of 100k+ samples with thousands of segments stay cheap.
//! * **Forward sensitivities** from the variational equations, with *analytic* state Jacobians
//!   `∂a/∂x`, `∂a/∂v` of the model's terms. State and sensitivities form one second-order system
//!   (`S'' = A_x S + A_v S' + Θ`), stepped by tfs-dynamics' `rk4_step` with `substeps` fixed steps
//!   per sample interval and the input spline-interpolated (`SampledInput`). A fixed-step
//!   scheme is used (not Dopri5) so the sensitivities are the exact derivatives of the discrete
//!   map that produces the residuals, sampled exactly at the measurement times.
//! * **Multiple shooting**: each record is split into segments of a few resonance periods; each
//!   segment's initial `(x, v)` is an unknown initialised from the data (`v` from a
//!   Savitzky–Golay derivative), continuity defects are weighted residuals whose weight grows
//!   stage by stage, then an optional single-shooting polish. A blow-up inside a segment is a
//!   rejected step (more damping), never a panic.
//! * The result is scored by simulating with tfs-dynamics (Dopri5); a refined model is never
//!   returned if it simulates worse than the start on the training data.
//! * **Records whose free-run error is the input's noise** are left out: when a fresh draw of the
//!   measured input's own noise moves the start model's simulation so far that it explains at
//!   least half of the error measurement noise does not ([`input_noise_spread`],
//!   [`noise_dominated`]; typical of a multi-stable structure swept through snap-through),
//!   that error cannot tell good coefficients from bad, and fitting it fits the noise.
//!
//! [`choose_by_validation`] compares an equation-error model and a refined one on held-out
//! records.
//!
//! ```
//! use tfs_data::Record;
//! use tfs_library::{Equation, Model, ModelTerm, Term};
//! use tfs_refine::{RefineOptions, refine};
//!
//! // Truth: x'' = -4 x - 0.2 x' + u, simulated with tfs-dynamics (Dopri5).
//! let dofs = vec!["x".to_string()];
//! let term = |s: &str| Term::parse(s, &dofs).unwrap();
//! let make = |k: f64, c: f64| {
//!     Model::new(
//!         dofs.clone(),
//!         vec![Equation {
//!             dof: "x".into(),
//!             terms: vec![
//!                 ModelTerm::new(term("x"), -k),
//!                 ModelTerm::new(term("x'"), -c),
//!                 ModelTerm::new(term("u"), 1.0),
//!             ],
//!         }],
//!         "example",
//!     )
//!     .unwrap()
//! };
//! let truth = make(4.0, 0.2);
//! let n = 400;
//! let dt = 0.1;
//! let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
//! let u: Vec<f64> = t.iter().map(|t| (1.3 * t).sin() + 0.5 * (2.9 * t).cos()).collect();
//! let rec = Record::new("gen", t.clone(), vec![("x".into(), vec![0.0; n]), ("u".into(), u.clone())]).unwrap();
//! let tr = tfs_dynamics::simulate_model_on_record(&truth, &rec, &Default::default()).unwrap();
//! let rec = Record::new("train", t, vec![("x".into(), tr.x[0].clone()), ("u".into(), u)]).unwrap();
//!
//! let start = make(4.4, 0.3);
//! let out = refine(&start, &[rec], &RefineOptions::default()).unwrap();
//! assert!(out.final_cost <= out.initial_cost);
//! let k = -out.model.coef("x", &term("x")).unwrap();
//! assert!((k - 4.0).abs() < 0.01, "k = {k}");
//! ```

mod error;
mod lm;
mod refine;
mod sens;
mod sensitivity;
mod shooting;
mod validation;

pub use error::{RefineError, Result};
pub use refine::{RefineOptions, Refined, refine};
pub use sensitivity::{
    FreeRunProbe, NOISE_SHARE, displacement_noise_var, input_noise_spread, input_noise_spread_from,
    noise_dominated, probe_free_run, start_spread_from,
};
pub use validation::{ValidationScores, choose_by_validation};

#[cfg(test)]
mod tests;
