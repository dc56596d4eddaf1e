//! The diagnosis loop of tfs: *compare the model with measurements, see where it
//! fails, learn which physical effect is missing, add it and watch the error fall.*
//!
//! * [`compare()`](compare::compare) — simulate under each record's measured input: R-MSE per
//!   record and per time window, measured vs model spectra with the drive harmonics the model
//!   misses, phase portraits.
//! * [`localise()`](residual::localise) — the equation residual `x''_meas − model(x, x', u)`
//!   mapped over (x, x') bins, frequency and time, with a plain-words summary.
//! * [`explain()`](explain::explain) — the open [`Catalogue`] of [`Effect`]s (dry friction,
//!   quadratic/cubic/amplitude damping, missing stiffness powers, offset, memory effects as
//!   internal states — Maxwell relaxation, Bouc–Wen hysteresis, Dahl friction —, input delay,
//!   input filter, one-sided stops), each on the DOF's own and relative (chain) coordinates, in raw
//!   units about the mean position when the model has a constant; refitted with the model's
//!   terms, scored on held-out data, tested, sized and ranked; "no significant missing effect"
//!   when none passes.
//! * [`add_effect`] — add an effect by name, refit, and append to the model's history;
//!   [`error_ladder`] and [`ladder_table`] show each step.
//! * [`restoring_loop()`](restoring::restoring_loop) — the force–displacement loop measured
//!   from a record against models' (a hysteresis loop where the structure has memory).
//! * [`diagnose`] — all of the above in one report.
//! * [`rules()`](rules::rules) — the rules the diagnosis applies, with their thresholds read from
//!   the code (`docs/diagnosis.md` carries them as a table).
//!
//! Architecture invariant: no I/O and no plotting; everything returned is data.
//!
//! ```
//! use tfs_diagnose::{Catalogue, ComputedColumn};
//! let cat = Catalogue::standard(7);
//! assert!(cat.names().contains(&"dry-friction".to_string()));
//! let err = cat.get("friction").err().unwrap().to_string();
//! assert!(err.contains("known effects") && err.contains("hysteresis"));
//! // Computed input columns round-trip through their documented names.
//! let c = ComputedColumn::Delayed { input: "u".into(), delay: 0.35 };
//! assert_eq!(c.name(), "u_delay_0p35");
//! assert_eq!(ComputedColumn::parse(&c.name()), Some(c));
//! // In raw units a power is offered about the mean position: (x − 0.5)² = x² − x + 0.25.
//! let x2 = tfs_library::Term::parse("x^2", &["x"]).unwrap();
//! let weights: Vec<f64> = tfs_diagnose::EffectColumn::centred(x2, "x", 0.5)
//!     .expansion()
//!     .iter()
//!     .map(|(_, w)| *w)
//!     .collect();
//! assert_eq!(weights, vec![1.0, -1.0, 0.25]);
//! // The low-pass of a constant is that constant.
//! let y = tfs_diagnose::effects::lowpass(&[2.0; 50], 0.01, 0.1);
//! assert!(y.iter().all(|v| (v - 2.0).abs() < 1e-12));
//! ```

#![warn(missing_docs)]

mod anchor;
pub mod compare;
mod design;
pub mod effects;
mod error;
pub mod evidence;
pub mod explain;
pub mod judge;
mod judged;
pub mod noise;
mod null;
mod polish;
pub mod predict;
pub mod prepare;
mod rank;
mod readmit;
pub mod refit;
pub mod residual;
pub mod restoring;
pub mod rules;
mod scan;
mod score;
pub mod simulate;
mod stats;
mod verdict;

pub use compare::{RecordComparison, compare};
pub use effects::{Catalogue, ComputedColumn, Effect, EffectColumn, EffectContext, Variant};
pub use error::{DiagnoseError, Result};
pub use evidence::{
    EquationEvidence, Evidence, JudgedAt, NullEvidence, PredictionEvidence, Significance,
};
pub use explain::{Explanation, RankedEffect, explain};
pub use judge::{Judge, JudgeUse};
pub use predict::PredictionScore;
pub use prepare::DiagnoseOptions;
pub use refit::{
    LadderStep, SharedTerm, add_effect, add_effect_fit, add_effect_with, error_ladder, hold_start,
    ladder_table, refit, refit_shared, score_records,
};
pub use residual::{Localisation, localise};
pub use restoring::{RestoringLoop, restoring_loop};
pub use rules::{Rule, rules, rules_table};
pub use simulate::{augment_record, r_mse, simulate};
pub use stats::{geometric_mean_r_mse, paired_p_value};

use serde::Serialize;
use tfs_data::Record;
use tfs_library::Model;

/// The full diagnosis of a model against records.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Ranked effects.
    pub ranked: Vec<RankedEffect>,
    /// One sentence.
    pub verdict: String,
    /// Plain-words residual summary, one per DOF.
    pub residual_summary: Vec<String>,
    /// Per-record comparison.
    pub records: Vec<RecordComparison>,
    /// Residual localisation per DOF.
    pub localisation: Vec<Localisation>,
    /// The explanation's bookkeeping (tests, cut-offs, folds).
    pub tests: usize,
    /// Cut-off per record (Hz).
    pub cutoff_hz: Vec<f64>,
}

/// Compare, localise and explain in one call with the standard catalogue.
pub fn diagnose(model: &Model, records: &[Record], opts: &DiagnoseOptions) -> Result<Diagnosis> {
    diagnose_with(model, records, &Catalogue::standard(opts.max_power), opts)
}

/// [`diagnose`] with a custom catalogue.
pub fn diagnose_with(
    model: &Model,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Result<Diagnosis> {
    // The model's own simulation of each record serves the judge's choice, the input-noise
    // spread and the comparison: made once.
    opts.validate()?;
    crate::prepare::check_records(model, records)?;
    let runs = simulate::base_runs(model, records, opts);
    let ex = explain::explain_with_runs(model, records, catalogue, opts, Some(&runs))?;
    let localisation = localise(model, records, opts)?;
    let records = compare::compare_with_runs(model, records, opts, &runs)?;
    let mut verdict = ex.verdict;
    // Nothing missing on clean data: say both.
    if !ex.ranked.iter().any(|r| r.significant) && localisation.iter().all(|l| l.noise.clean()) {
        let least = localisation
            .iter()
            .map(|l| &l.noise)
            .min_by(|a, b| a.snr_db.total_cmp(&b.snr_db))
            .map_or_else(|| "above 80 dB".to_string(), |n| n.snr_words());
        verdict.push_str(&format!(
            "; nothing is missing and the records are clean (estimated displacement SNR {least})"
        ));
    }
    Ok(Diagnosis {
        ranked: ex.ranked,
        verdict,
        residual_summary: localisation.iter().map(|l| l.summary.clone()).collect(),
        records,
        localisation,
        tests: ex.tests,
        cutoff_hz: ex.cutoff_hz,
    })
}
