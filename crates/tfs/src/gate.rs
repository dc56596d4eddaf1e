//! What the model does when simulated, as evidence for the diagnosis loop's choice.
//!
//! The diagnosis ranks candidate effects by equation error on smoothed states. A model that
//! blows up or leaves its range on some records fails there for a reason the equation error may
//! not see: a chain cell's folded stop at 30 dB is the case in point (the smoothed heights never
//! reach the fold, so the stop's equation-error evidence is weak, while without it a cell falls
//! through its fold and the simulation diverges). A failed simulation of a measured record is not
//! a matter of degree or of noise: the records are finite, the model's motion is not. So:
//!
//! - When the current model fails to simulate some records, every candidate whose held-out
//!   equation error falls is added in turn (as `refit --add` would, a stop re-scanned by T-F-S)
//!   and simulated on the records; the candidate that leaves the fewest records failing (then the
//!   lowest mean R-MSE of the others, then the diagnosis's order) is chosen, provided it leaves
//!   fewer failing than the model without it. [`simulation_choice`] does this for `tfs diagnose`
//!   and for each round of `refit --until-clean`.
//! - A significant candidate whose addition makes more records fail than before is passed over
//!   by the loop ([`loop_choice`]): it cannot be what the records are missing.

use serde::Serialize;
use tfs_data::Record;
use tfs_diagnose::{Catalogue, DiagnoseOptions, Explanation, RankedEffect, error_ladder};
use tfs_library::Model;

use crate::contact::StopRescan;
use crate::error::{Context, Result};

/// How a model simulates the records: how many fail (blow up, leave the range, give a
/// non-finite R-MSE), and the mean R-MSE of the others.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SimScore {
    /// Records whose simulation failed.
    pub failed: usize,
    /// Records simulated in all.
    pub records: usize,
    /// Mean R-MSE over the records that simulate (infinite when none does).
    pub mean_r_mse: f64,
}

impl SimScore {
    /// Fewer failures first, then the lower mean R-MSE.
    fn key(&self) -> (usize, f64) {
        (
            self.failed,
            if self.mean_r_mse.is_finite() {
                self.mean_r_mse
            } else {
                f64::INFINITY
            },
        )
    }

    /// In words: `2 of 4 records fail` or `all 4 simulate (mean R-MSE …)`.
    pub fn describe(&self) -> String {
        match self.failed {
            0 => format!(
                "all {} records simulate (mean R-MSE {:.4e})",
                self.records, self.mean_r_mse
            ),
            f if f == self.records => format!("all {f} records fail to simulate"),
            f => format!(
                "{f} of {} records fail to simulate (mean R-MSE {:.4e} on the others)",
                self.records, self.mean_r_mse
            ),
        }
    }

    /// The model's free run on `records`: from the last rung of its history when that rung
    /// scored every record (what the refit just did), else simulated here.
    pub fn of(model: &Model, records: &[Record]) -> SimScore {
        if let Some(last) = error_ladder(model).last()
            && last.r_mse.len() + last.failed.len() == records.len()
        {
            let ok: Vec<f64> = last
                .r_mse
                .iter()
                .map(|s| s.r_mse)
                .filter(|v| v.is_finite())
                .collect();
            return SimScore::from_parts(records.len(), &ok);
        }
        let ok: Vec<f64> = records
            .iter()
            .filter_map(|r| tfs_diagnose::r_mse(model, r).ok())
            .filter(|v| v.is_finite())
            .collect();
        SimScore::from_parts(records.len(), &ok)
    }

    fn from_parts(records: usize, ok: &[f64]) -> SimScore {
        SimScore {
            failed: records - ok.len(),
            records,
            mean_r_mse: if ok.is_empty() {
                f64::INFINITY
            } else {
                ok.iter().sum::<f64>() / ok.len() as f64
            },
        }
    }
}

/// One candidate added and simulated.
#[derive(Debug, Clone, Serialize)]
pub struct Trial {
    /// The effect (`name@dof`).
    pub effect: String,
    /// How the model with it simulates the records (`None`: it could not be added).
    pub score: Option<SimScore>,
    /// Why it could not be added.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// A candidate chosen with the model that has it.
#[derive(Debug, Clone)]
pub struct Chosen {
    /// The effect (`name@dof`).
    pub effect: String,
    /// The model with the effect added.
    pub model: Model,
    /// The stops re-scanned while adding it.
    pub stops: Vec<StopRescan>,
    /// Warnings of the refit.
    pub warnings: Vec<String>,
    /// How the model with it simulates the records.
    pub score: SimScore,
}

/// What the simulations said in one diagnosis: how the model simulates, the candidates tried
/// and the one chosen, in a sentence.
#[derive(Debug, Clone, Serialize)]
pub struct GateReport {
    /// How the model without any candidate simulates the records.
    pub before: SimScore,
    /// Every candidate tried, in the diagnosis's order.
    pub tried: Vec<Trial>,
    /// The candidate chosen (`None`: the simulations chose none).
    pub chosen: Option<String>,
    /// Why, in a sentence.
    pub why: String,
}

/// Adds every name of `names` to `model` in turn as `refit --add` does (a stop re-scanned by
/// T-F-S) and scores each result on `records`; a candidate that cannot be added is kept as a
/// trial with its error.
fn try_each(
    model: &Model,
    names: &[&str],
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> (Vec<Trial>, Vec<Option<Chosen>>) {
    let mut trials = Vec::with_capacity(names.len());
    let mut made = Vec::with_capacity(names.len());
    for &name in names {
        let mut notes = crate::refit::AddNotes::default();
        match crate::refit::add_one(model, name, records, catalogue, opts, &mut notes) {
            Ok(m) => {
                let score = SimScore::of(&m, records);
                trials.push(Trial {
                    effect: name.to_string(),
                    score: Some(score),
                    error: None,
                });
                made.push(Some(Chosen {
                    effect: name.to_string(),
                    model: m,
                    stops: notes.stops,
                    warnings: notes.warnings,
                    score,
                }));
            }
            Err(e) => {
                trials.push(Trial {
                    effect: name.to_string(),
                    score: None,
                    error: Some(crate::one_line(&e)),
                });
                made.push(None);
            }
        }
    }
    (trials, made)
}

/// When `model` fails to simulate some of `records`: every candidate of the diagnosis's
/// ranking `ranked` whose held-out equation error falls is added and simulated (module docs), and the one that
/// leaves the fewest records failing is chosen if it leaves fewer than `model` does. `None`
/// when `model` simulates every record (the simulations then have nothing to say here).
pub fn simulation_choice(
    model: &Model,
    ranked: &[RankedEffect],
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Result<Option<(GateReport, Option<Chosen>)>> {
    let before = SimScore::of(model, records);
    if before.failed == 0 {
        return Ok(None);
    }
    let names: Vec<&str> = ranked
        .iter()
        .filter(|r| r.delta_heldout > 0.0)
        .map(|r| r.name.as_str())
        .collect();
    let (tried, mut made) = try_each(model, &names, records, catalogue, opts);
    let scores: Vec<Option<SimScore>> = tried.iter().map(|t| t.score).collect();
    let best = fewest_failing(&before, &scores).and_then(|i| made[i].take());
    let why = match &best {
        Some(b) => format!(
            "the model fails to simulate {} of {} records; of the {} candidates whose held-out equation error falls, adding {} leaves the fewest failing: {}",
            before.failed,
            before.records,
            names.len(),
            b.effect,
            b.score.describe()
        ),
        None => format!(
            "the model fails to simulate {} of {} records and none of the {} candidates whose held-out equation error falls makes fewer fail",
            before.failed,
            before.records,
            names.len()
        ),
    };
    let report = GateReport {
        before,
        tried,
        chosen: best.as_ref().map(|b| b.effect.clone()),
        why,
    };
    Ok(Some((report, best)))
}

/// One round of the diagnosis loop's choice on the diagnosis `ex` of `model`: when the model
/// fails to simulate some records, the candidate [`simulation_choice`] finds; otherwise (or
/// when it finds none) the top significant candidate whose addition does not make more records
/// fail, the ones passed over said in the sentence. Returns the chosen candidate (`None`: none
/// qualifies, the loop stops) and what the simulations said, if anything.
pub(crate) fn loop_choice(
    model: &Model,
    ex: &Explanation,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Result<(Option<Chosen>, Option<String>)> {
    let mut notes = Vec::new();
    if let Some((report, chosen)) = simulation_choice(model, &ex.ranked, records, catalogue, opts)?
    {
        if chosen.is_some() {
            return Ok((chosen, Some(report.why)));
        }
        notes.push(report.why);
    }
    let before = SimScore::of(model, records);
    for top in ex.ranked.iter().filter(|r| r.significant) {
        let mut added = crate::refit::AddNotes::default();
        let m = crate::refit::add_one(model, &top.name, records, catalogue, opts, &mut added)
            .with_context(|| format!("adding {}", top.name))?;
        let score = SimScore::of(&m, records);
        if breaks_more(&before, &score) {
            notes.push(format!(
                "{} passed over: with it {} (without it {})",
                top.name,
                score.describe(),
                before.describe()
            ));
            continue;
        }
        if !notes.is_empty() {
            notes.push(format!(
                "{} added, the next significant: with it {}",
                top.name,
                score.describe()
            ));
        }
        let chosen = Chosen {
            effect: top.name.clone(),
            model: m,
            stops: added.stops,
            warnings: added.warnings,
            score,
        };
        return Ok((Some(chosen), (!notes.is_empty()).then(|| notes.join("; "))));
    }
    Ok((None, (!notes.is_empty()).then(|| notes.join("; "))))
}

/// The candidate (index into `scores`; `None` entries could not be added) that leaves the
/// fewest records failing, then the lowest mean R-MSE, the first of equals (the diagnosis's
/// order); `None` unless it leaves fewer failing than `before`.
fn fewest_failing(before: &SimScore, scores: &[Option<SimScore>]) -> Option<usize> {
    let mut best: Option<(usize, SimScore)> = None;
    for (i, s) in scores.iter().enumerate() {
        if let Some(s) = s
            && best.is_none_or(|(_, b)| s.key() < b.key())
        {
            best = Some((i, *s));
        }
    }
    best.filter(|(_, b)| b.failed < before.failed)
        .map(|(i, _)| i)
}

/// Whether adding a candidate made more records fail to simulate than before.
fn breaks_more(before: &SimScore, after: &SimScore) -> bool {
    after.failed > before.failed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(failed: usize, mean: f64) -> SimScore {
        SimScore {
            failed,
            records: 4,
            mean_r_mse: mean,
        }
    }

    /// The candidate with the fewest failing records wins over one with a lower mean R-MSE on
    /// fewer records; among equals the first (the diagnosis's order) wins; one that leaves as
    /// many failing as the model without it is not chosen; candidates that could not be added
    /// are skipped.
    #[test]
    fn the_candidate_that_makes_the_most_records_simulate_is_chosen() {
        let before = s(3, 1.0);
        let scores = [
            Some(s(3, 0.1)),
            None,
            Some(s(0, 6.5)),
            Some(s(2, 0.5)),
            Some(s(0, 6.5)),
        ];
        assert_eq!(fewest_failing(&before, &scores), Some(2));
        let lower = [Some(s(1, 9.0)), Some(s(1, 2.0))];
        assert_eq!(fewest_failing(&before, &lower), Some(1));
        let none_better = [Some(s(3, 0.01)), None, Some(s(4, f64::INFINITY))];
        assert_eq!(fewest_failing(&before, &none_better), None);
        assert_eq!(fewest_failing(&before, &[None, None]), None);
        // A model that simulates every record cannot be improved on in this sense.
        assert_eq!(fewest_failing(&s(0, 0.2), &[Some(s(0, 0.01))]), None);
    }

    /// A candidate that makes a record fail which simulated before breaks the model; one that
    /// only worsens the R-MSE does not (the ladder warns about that).
    #[test]
    fn a_candidate_that_makes_a_record_fail_breaks_the_model() {
        assert!(breaks_more(&s(0, 0.1), &s(1, 0.05)));
        assert!(!breaks_more(&s(0, 0.1), &s(0, 0.5)));
        assert!(!breaks_more(&s(2, 0.1), &s(1, 0.5)));
    }

    /// The words say how many records fail of how many, and the mean where there is one.
    #[test]
    fn the_score_is_described_in_words() {
        assert!(s(0, 0.25).describe().starts_with("all 4 records simulate"));
        assert_eq!(
            s(4, f64::INFINITY).describe(),
            "all 4 records fail to simulate"
        );
        let two = s(2, 0.5).describe();
        assert!(
            two.starts_with("2 of 4 records fail") && two.contains("5.0000e-1"),
            "{two}"
        );
    }
}
