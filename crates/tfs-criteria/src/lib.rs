//! The criteria of T-F-S SINDy (Qian et al.) and the identification pipelines built on them, one
//! module per stage, each computing its part, deciding, and reporting it in the [`Trace`]:
//!
//! 1. `blocks`: records cut to blocks of fast transform lengths, checked, every DOF
//!    reconstructed in its data-chosen band (`tfs_signal::band`).
//! 2. `criterion1`: the noise level index κ of `B = [Θ | x'']` on the measured data
//!    ([`noise_level_index`]) and its threshold κ0, calibrated by adding known noise to the user's
//!    own data ([`knee_index`]): high SNR, or below κ0 the cause the records' own noise
//!    estimate names ([`SnrVerdict`]: noise, model error, or the block's derivatives).
//! 3. `criterion2`: library pruning by backward elimination on κ ([`prune_library`]).
//! 4. `criterion3`: the frequency-domain (weak-form) rows — windowed transforms of every library
//!    column, bins kept where `|ẍ̂| ≥ δ·max` and above the estimated noise, weighted by feasible
//!    GLS — and δ and the window count chosen by held-out error ([`Criterion3Options`]).
//! 5. `criterion4`: data assembly record by record until the held-out residual is small and has
//!    converged ([`residual_stats`]).
//! 6. `fit` (and `eiv`): the chosen structure's coefficients, with the settings chosen again for
//!    them and the errors-in-variables correction ([`FitOptions`]).
//! 7. `uncertainty`: 95 % intervals by a cluster jackknife, inclusion probabilities by a
//!    bootstrap, and the [`TermTest`] every kept term must pass.
//! 8. `verdict`: does the data support the library ([`Support`], [`Trace::warnings`])?
//! 9. `elimination`: while a kept term fails the term test, the least significant is removed
//!    and the selection re-run.
//!
//! `pipeline` ([`identify_tfs`]) runs them in this order; `tied` ([`identify_tfs_tied`]) runs
//! the same stages on the stacked rows of a chain's DOFs with each element's force law shared
//! by the two DOFs it connects ([`chain_ties`]); `classical` ([`identify_sindy`]) is the
//! classical SINDy baseline. Options come grouped by stage ([`TfsOptions`]) and are checked
//! once per identification.
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

#![warn(missing_docs)]

mod blocks;
mod classical;
mod criterion1;
mod criterion2;
mod criterion3;
mod criterion4;
mod eiv;
mod elimination;
mod error;
mod fit;
mod options;
mod pipeline;
mod prepared;
mod swap;
mod tied;
mod trace;
mod uncertainty;
mod verdict;

pub use classical::identify_sindy;
pub use criterion1::cause::SnrVerdict;
pub use criterion1::kappa::{
    CalibrationPoint, Criterion1, KAPPA_CAP, Kappa, Kappa0Source, KappaVariant, kappa0_from_curve,
    knee_index, noise_level_index, noise_level_index_factor,
};
pub use criterion2::{Criterion2, Kappa1Reason, PruneStep, prune_factor, prune_library};
pub use criterion3::TransformForm;
pub use criterion4::residual_stats;
pub use error::{CriteriaError, Result};
pub use options::{
    Criterion1Options, Criterion2Options, Criterion3Options, Criterion4Options, FitOptions,
    IdentifySpec, Kappa0Choice, SindyOptions, TfsOptions, UncertaintyOptions,
};
pub use pipeline::identify_tfs;
pub use prepared::{PreparedRecords, RecordBlocks};
pub use tied::{MassChoice, Tie, TieOptions, chain_ties, identify_tfs_tied, library_ties};
pub use trace::{
    AssemblyStep, AssemblyVerdict, ChosenSettings, Criterion4Outcome, DofTrace, Identified, Method,
    NoiseCause, Problem, RecordBins, SettingScore, SnrEstimate, Support, TieTrace, TiedTrace,
    Trace,
};
pub use uncertainty::TermTest;

/// Helpers shared by the unit tests of several stages.
#[cfg(test)]
pub(crate) mod test_util {
    /// A deterministic uniform draw in [-0.5, 0.5) (a 64-bit linear congruential generator), for
    /// test matrices that must be the same on every machine.
    pub(crate) fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    }
}
