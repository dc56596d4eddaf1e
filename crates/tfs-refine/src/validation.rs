//! Choosing between an equation-error fit and a simulation-error refinement of it on held-out
//! records.

use rayon::prelude::*;
use tfs_data::Record;
use tfs_dynamics::SimulateOptions;
use tfs_library::Model;

use crate::Result;
use crate::refine::{check_records, combine, ranking_screen, rms, sim_errors};

/// Scores of [`choose_by_validation`].
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationScores {
    /// Per record: (source name, RMS error of the first model, RMS error of the second),
    /// RMS over DOFs, `+∞` for a blow-up.
    pub per_record: Vec<(String, f64, f64)>,
    /// Sum over records of squared RMS errors normalised by the record's displacement RMS
    /// (first model).
    pub eq_score: f64,
    /// The same for the second (refined) model.
    pub refined_score: f64,
    /// True if the refined model was chosen.
    pub chose_refined: bool,
    /// Validation records left out of the choice because the first model's free run there
    /// cannot rank models ([`crate::probe_free_run`]: their input's noise or the run's own
    /// divergence accounts for its error); (source name, spread that decided, error), RMS over
    /// DOFs. With every record left out, the first model is kept.
    pub noise_dominated: Vec<(String, f64, f64)>,
}

/// Simulates `eq_model` and `refined` on held-out `validation` records (tfs-dynamics
/// `simulate_model_on_record` with default options) and returns a clone of the one that
/// predicts better (lower sum over records of squared RMS error normalised by the record's
/// displacement RMS; ties keep `eq_model`), with the scores. Records where `eq_model`'s free run
/// cannot rank models ([`crate::probe_free_run`]: the noise on their measured input, or the
/// run's own divergence, accounts for its error) are left out of the sums (listed in
/// [`ValidationScores::noise_dominated`]); with none left, `eq_model` is kept.
pub fn choose_by_validation(
    eq_model: &Model,
    refined: &Model,
    validation: &[Record],
) -> Result<(Model, ValidationScores)> {
    check_records(eq_model, validation, "validation")?;
    check_records(refined, validation, "validation")?;
    let opts = SimulateOptions::default();
    let mut per_record = Vec::new();
    let mut noise_dominated = Vec::new();
    let (mut s_eq, mut s_ref) = (0.0, 0.0);
    let screened: Vec<Option<(f64, f64)>> = validation
        .par_iter()
        .map(|r| ranking_screen(eq_model, r, &opts))
        .collect();
    for (r, screen) in validation.iter().zip(screened) {
        if let Some((spread, error)) = screen {
            noise_dominated.push((r.source().to_string(), spread, error));
            continue;
        }
        let norm: Vec<f64> = eq_model
            .dofs
            .iter()
            .map(|d| r.column(d).map(rms).unwrap_or(1.0).max(f64::MIN_POSITIVE))
            .collect();
        let e1 = sim_errors(eq_model, r, &opts);
        let e2 = sim_errors(refined, r, &opts);
        s_eq += e1
            .iter()
            .zip(&norm)
            .map(|(e, s)| (e / s) * (e / s))
            .sum::<f64>();
        s_ref += e2
            .iter()
            .zip(&norm)
            .map(|(e, s)| (e / s) * (e / s))
            .sum::<f64>();
        per_record.push((r.source().to_string(), combine(&e1), combine(&e2)));
    }
    let chose_refined = s_ref < s_eq && noise_dominated.len() < validation.len();
    let chosen = if chose_refined {
        refined.clone()
    } else {
        eq_model.clone()
    };
    Ok((
        chosen,
        ValidationScores {
            per_record,
            eq_score: s_eq,
            refined_score: s_ref,
            chose_refined,
            noise_dominated,
        },
    ))
}
