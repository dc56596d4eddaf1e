//! The criteria of T-F-S SINDy (Qian et al.) and the identification pipelines built on them.
//!
//! * Criterion 1 ([`noise_level_index`], [`noise_level_index_factor`], [`knee_index`]): the noise
//!   level index κ of `B = [Θ | x'']` on the measured data (`x''` by Savitzky–Golay, as in the
//!   paper), raw and standardised, and the threshold κ0 calibrated by adding known noise to the
//!   user's own data.
//! * Criterion 2 ([`prune_library`], [`prune_factor`]): backward elimination on κ, run on the small
//!   factor of one thin QR.
//! * Criterion 3 ([`TransformForm`], on `tfs_signal`'s windows and band-limited reconstruction):
//!   windowed transforms (plain or derivative-transfer "weak" form),
//!   bins kept where `|ẍ̂| ≥ δ·max` and where `|ẍ̂|²` exceeds the variance the estimated
//!   displacement noise gives at that bin ([`TfsOptions::min_bin_snr`]; noise of `x` enters both
//!   sides of the regression there and would bias it), nonlinear terms evaluated on a
//!   band-limited reconstruction whose band comes from the data (noise floor fitted on the upper
//!   half of the spectrum, cut-off extended to harmonics that rise above the floor).
//! * Criterion 4 ([`residual_stats`]) inside the record-by-record data assembly of
//!   [`identify_tfs`]; once it is met, the structure it accepted is refit on every record
//!   ([`TfsOptions::refit_all_records`]). [`identify_sindy`] is the classical baseline.
//! * The final coefficients are corrected for errors in variables
//!   ([`TfsOptions::noise_correction_draws`]): draws of each record's estimated noise, pushed
//!   through the same reconstruction, windows, bins and weights (`tfs_signal::band::noise_draw`),
//!   estimate the noise's share of the normal equations, which is removed before solving.
//! * Every kept coefficient gets a 95 % interval (a jackknife over clusters of neighbouring bins)
//!   and an inclusion probability (bootstrap over the same clusters); a kept term must pass the
//!   [`TermTest`] (significance shared among every candidate term of the library), else the
//!   least significant is removed and the selection re-run;
//!   [`Criterion1::supported`] and [`Trace::warnings`] say when the data are too noisy for the
//!   library instead of presenting a wrong model with confidence.
//! * Chains ([`identify_tfs_tied`]): the same rows for every DOF stacked, with each element's
//!   force law shared by the two DOFs it connects (Newton's third law, [`chain_ties`]).
//!
//! Architecture invariant: every m-row matrix is decomposed once; all selection runs on small
//! factors ([`tfs_regress::Compressed`]).
//!
//! ```
//! use faer::Mat;
//! use tfs_criteria::{KappaVariant, prune_library};
//! // x'' = 2·t1 exactly; t0 and t2 are unrelated: pruning keeps only t1.
//! let m = 300;
//! let f = |i: usize, k: f64| ((i as f64) * k).sin();
//! let b = Mat::<f64>::from_fn(m, 4, |i, j| match j {
//!     0 => f(i, 0.37),
//!     1 => f(i, 0.11),
//!     2 => f(i, 0.73),
//!     _ => 2.0 * f(i, 0.11) + 1e-6 * f(i, 1.9),
//! });
//! let names: Vec<String> = ["t0", "t1", "t2"].iter().map(|s| s.to_string()).collect();
//! let c2 = prune_library(b.as_ref(), &names, KappaVariant::Raw, None, 1.0).unwrap();
//! assert_eq!(c2.kept, vec![1]);
//! ```

mod eiv;
mod error;
mod kappa;
mod pipeline;
mod prepare;
mod prune;
pub mod synthetic;
mod tied;

pub use error::{CriteriaError, Result};
pub use kappa::{
    CalibrationPoint, Criterion1, KAPPA_CAP, Kappa, KappaVariant, kappa0_from_curve, knee_index,
    noise_level_index, noise_level_index_factor,
};
pub use pipeline::{
    AssemblyStep, ChosenSettings, DofTrace, Identified, IdentifySpec, Kappa0Choice, RecordBins,
    SettingScore, SindyOptions, TermTest, TfsOptions, Trace, identify_sindy, identify_tfs,
    residual_stats,
};
pub use prepare::TransformForm;
pub use prune::{Criterion2, PruneStep, prune_factor, prune_library};
pub use tied::{MassChoice, Tie, TieOptions, chain_ties, identify_tfs_tied};
