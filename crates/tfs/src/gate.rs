//! What the model does when simulated, the evidence [`crate::decide`] weighs: how a model
//! simulates the records ([`SimScore`]), each candidate added as `refit --add` adds it
//! (`add_each`), the control a candidate is measured against when the model fails some records
//! (its own terms refitted with nothing added), the forward steps that say which effects failing
//! records need together (`further_steps`), and T-F-S's own test of a stop
//! ([`tfs_stop_p_value`]).
//!
//! The diagnosis ranks candidate effects by equation error on smoothed states. A model that
//! blows up or leaves its range on some records fails there for a reason the equation error may
//! not see: a chain cell's folded stop at 30 dB is the case in point (the smoothed heights never
//! reach the fold, so the stop's equation-error evidence is weak, while without it a cell falls
//! through its fold and the simulation diverges). A failed simulation of a measured record is not
//! a matter of degree or of noise: the records are finite, the model's motion is not.

use serde::Serialize;
use tfs_data::Record;
use tfs_diagnose::{Catalogue, DiagnoseOptions, Diagnosis, error_ladder};
use tfs_library::Model;

use crate::contact::StopRescan;
use crate::error::Result;

/// How a model simulates the records: how many fail (blow up, leave the range, give a
/// non-finite R-MSE), and the geometric-mean R-MSE of the others (what is compared:
/// [`tfs_diagnose::geometric_mean_r_mse`]) beside their arithmetic mean.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SimScore {
    /// Records whose simulation failed.
    pub failed: usize,
    /// Records simulated in all.
    pub records: usize,
    /// Mean R-MSE over the records that simulate (infinite when none does).
    pub mean_r_mse: f64,
    /// Geometric-mean R-MSE over the records that simulate (infinite when none does): the
    /// score `SimScore::key` orders by and the sentences print.
    pub geo_mean_r_mse: f64,
}

impl SimScore {
    /// Fewer failures first, then the lower geometric-mean R-MSE.
    pub(crate) fn key(&self) -> (usize, f64) {
        (
            self.failed,
            if self.geo_mean_r_mse.is_finite() {
                self.geo_mean_r_mse
            } else {
                f64::INFINITY
            },
        )
    }

    /// In words: `2 of 4 records fail` or `all 4 simulate (geometric-mean R-MSE …)` (`the
    /// record …` when there is one).
    pub fn describe(&self) -> String {
        match self.failed {
            0 if self.records == 1 => {
                format!("the record simulates (R-MSE {:.4e})", self.geo_mean_r_mse)
            }
            1 if self.records == 1 => "the record fails to simulate".to_string(),
            0 => format!(
                "all {} records simulate (geometric-mean R-MSE {:.4e})",
                self.records, self.geo_mean_r_mse
            ),
            f if f == self.records => format!("all {f} records fail to simulate"),
            f => format!(
                "{f} of {} records fail to simulate (geometric-mean R-MSE {:.4e} on the others)",
                self.records, self.geo_mean_r_mse
            ),
        }
    }

    /// The records that fail, in words: `2 of 4 records`, or `the record` when there is one.
    pub fn failing(&self) -> String {
        if self.records == 1 {
            "the record".to_string()
        } else {
            format!("{} of {} records", self.failed, self.records)
        }
    }

    /// The model's free run on `records`: from the last rung of its history when that rung
    /// scored every record (what the refit just did), else simulated here ([`each_record`]).
    pub fn of(model: &Model, records: &[Record]) -> SimScore {
        SimScore::from_each(&each_record(model, records))
    }

    /// The score of each record's R-MSE in `each` (`None`: that record failed), in the
    /// records' order: the failed ones counted, the means taken over the others.
    pub(crate) fn from_each(each: &[Option<f64>]) -> SimScore {
        let ok: Vec<f64> = each.iter().flatten().copied().collect();
        SimScore::from_parts(each.len(), &ok)
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
            geo_mean_r_mse: tfs_diagnose::geometric_mean_r_mse(ok),
        }
    }
}

/// Why a candidate's model was not made (`add_each`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum NotMade {
    /// The refit failed, in one line.
    Failed(String),
    /// No step toward its refit predicts the records better than the model without it: the
    /// refit returned the model unchanged.
    AddsNothing,
}

impl std::fmt::Display for NotMade {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NotMade::Failed(e) => f.write_str(e),
            NotMade::AddsNothing => f.write_str(
                "no step toward its refit predicts the records better than the model without it: it adds nothing",
            ),
        }
    }
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
    /// Each record's R-MSE with it, in the records' order (`None`: that record failed).
    pub each: Vec<Option<f64>>,
}

/// Each record's free-run R-MSE with `model`, in the order of `records` (`None` where the run
/// failed, or its R-MSE is not finite): from the last rung of its history when that rung scored
/// every record, else simulated here. [`SimScore::of`] is made from it.
pub(crate) fn each_record(model: &Model, records: &[Record]) -> Vec<Option<f64>> {
    let from = |ok: &[tfs_library::RecordScore]| -> Vec<Option<f64>> {
        records
            .iter()
            .map(|r| {
                ok.iter()
                    .find(|s| s.record == r.source())
                    .map(|s| s.r_mse)
                    .filter(|v| v.is_finite())
            })
            .collect()
    };
    if let Some(last) = error_ladder(model).last()
        && last.r_mse.len() + last.failed.len() == records.len()
    {
        return from(&last.r_mse);
    }
    from(&crate::contact::score(model, records).each)
}

/// How many effects `diagnose` adds after the chosen one when records still fail: the search
/// costs one refit and simulation per candidate and step, and the loop (`refit --until-clean`)
/// re-diagnoses after each effect anyway, so a few steps are enough to say what the records need
/// together.
pub const MAX_FURTHER: usize = 2;

/// One effect added after the chosen one (and those before it), with how the records then
/// simulate.
#[derive(Debug, Clone, Serialize)]
pub struct Step {
    /// The effect (`name@dof`).
    pub effect: String,
    /// How the model with it (and every effect before it) simulates the records.
    pub score: SimScore,
}

/// Adds every name of `names` to `model` in turn as `refit --add` does (a stop re-scanned by
/// T-F-S) and scores each result on `records`; a candidate that cannot be added gives why, in
/// one line, and so does one whose refit leaves the equations unchanged (no step toward it
/// predicts the records better than the model: it adds nothing, and is never named as the
/// effect that helps). The candidates are made in parallel and collected in order, so the result does not
/// depend on the threads.
pub(crate) fn add_each(
    model: &Model,
    names: &[&str],
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Vec<std::result::Result<Chosen, NotMade>> {
    use rayon::prelude::*;
    names
        .par_iter()
        .map(|&name| {
            let mut notes = crate::refit::AddNotes::default();
            let m = crate::refit::add_one(model, name, records, catalogue, opts, &mut notes)
                .map_err(|e| NotMade::Failed(crate::one_line(&e)))?;
            if m.equations == model.equations {
                return Err(NotMade::AddsNothing);
            }
            let each = each_record(&m, records);
            let score = SimScore::from_each(&each);
            Ok(Chosen {
                effect: name.to_string(),
                model: m,
                stops: notes.stops,
                warnings: notes.warnings,
                score,
                each,
            })
        })
        .collect()
}

/// Forward from `first` (which still leaves records failing): each step adds, to the model with
/// every effect so far, the candidate of `names` not yet in it that leaves the fewest records
/// failing, while that is fewer than before the step, records still fail and fewer than `max`
/// steps were taken.
pub(crate) fn further_steps(
    first: &Chosen,
    names: &[&str],
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
    max: usize,
) -> Vec<Step> {
    let mut steps: Vec<Step> = Vec::new();
    let mut current = first.model.clone();
    let mut score = first.score;
    while score.failed > 0 && steps.len() < max {
        let rest: Vec<&str> = names
            .iter()
            .copied()
            .filter(|n| *n != first.effect && steps.iter().all(|s| s.effect != *n))
            .collect();
        let mut made: Vec<Option<Chosen>> = add_each(&current, &rest, records, catalogue, opts)
            .into_iter()
            .map(|m| m.ok())
            .collect();
        let scores: Vec<Option<SimScore>> =
            made.iter().map(|m| m.as_ref().map(|c| c.score)).collect();
        let Some(next) = fewest_failing(&score, &scores).and_then(|i| made[i].take()) else {
            break;
        };
        steps.push(Step {
            effect: next.effect,
            score: next.score,
        });
        current = next.model;
        score = next.score;
    }
    steps
}

/// Whether the diagnosis `d` could not simulate some of its records (the decision then adds
/// and simulates the candidates to see which makes them simulate).
pub fn fails_somewhere(d: &Diagnosis) -> bool {
    d.records.iter().any(|r| r.error.is_some())
}

/// `model`'s own terms refitted by equation error on `records` as a candidate's model is
/// refitted, with nothing added: the control every candidate is measured against when the
/// model fails some records ([`crate::decide`]). A candidate refits every equation of a one-DOF
/// model or of a tied chain (jointly, with its ties); in an untied multi-DOF model it refits
/// only the equations it enters, so there is no one control for all candidates and `None` is returned.
pub(crate) fn refitted_as_is(
    model: &Model,
    records: &[Record],
    opts: &DiagnoseOptions,
) -> Result<Option<Model>> {
    let shared = crate::refit::shared_terms(model)?;
    Ok(if !shared.is_empty() {
        Some(tfs_diagnose::refit_shared(model, records, &shared, opts)?)
    } else if model.dofs.len() == 1 {
        Some(tfs_diagnose::refit(model, records, opts)?)
    } else {
        None
    })
}

/// The candidate (index into `scores`; `None` entries could not be added) that leaves the
/// fewest records failing, then the lowest mean R-MSE, the first of equals (the diagnosis's
/// order); `None` unless it leaves fewer failing than `before`.
pub(crate) fn fewest_failing(before: &SimScore, scores: &[Option<SimScore>]) -> Option<usize> {
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

/// Whether adding a candidate made the model simulate the records worse: more records fail,
/// or as many and the mean R-MSE of the others rises (what the error ladder warns about: the
/// records do not support it).
pub(crate) fn worsens(before: &SimScore, after: &SimScore) -> bool {
    after.key() > before.key()
}

/// The stop's evidence by T-F-S, for a stop the equation error does not make significant: its
/// coefficient in the model T-F-S re-identified with it ([`crate::contact::rescan_stop`]), tested
/// as T-F-S tests every term it keeps (`|coef|/SE` on Student's t with the term test's degrees of
/// freedom, the SE from the term's 95 % interval on that interval's own degrees of freedom),
/// Bonferroni-corrected over the library's candidate terms (as T-F-S's own test is) and over the
/// positions the re-scan tried. `None` when the model has no such test for the stop (a tied
/// chain's fit has intervals but no term test).
pub fn tfs_stop_p_value(model: &Model, stop: &StopRescan) -> Option<f64> {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    let (d, t) = model.equations.iter().enumerate().find_map(|(d, e)| {
        e.terms
            .iter()
            .find(|t| t.term.to_string() == stop.to)
            .map(|t| (d, t))
    })?;
    let [lo, hi] = t.interval?;
    let test = &model.trace["dofs"][d]["term_test"];
    let dof = test["dof"].as_f64()?;
    let candidates = test["candidates"].as_f64()?;
    let nu = test["interval_dof"][stop.to.as_str()]
        .as_f64()
        .unwrap_or(dof);
    let q = StudentsT::new(0.0, 1.0, nu.max(1.0))
        .ok()?
        .inverse_cdf(0.975);
    let se = 0.5 * (hi - lo) / q;
    if !(se > 0.0 && se.is_finite() && t.coef.is_finite()) {
        return None;
    }
    let tt = StudentsT::new(0.0, 1.0, dof.max(1.0)).ok()?;
    let p = 2.0 * (1.0 - tt.cdf(t.coef.abs() / se));
    Some((p * candidates * stop.positions.max(1) as f64).min(1.0))
}

/// A p value for people: `p = 3.14e-5`, or `p < 1e-300` when it is below what an `f64`
/// carries to two significant digits (a coefficient very far from zero rounds it to 0).
pub(crate) fn p_text(p: f64) -> String {
    if p < 1e-300 {
        "p < 1e-300".to_string()
    } else {
        format!("p = {p:.2e}")
    }
}

#[cfg(test)]
mod tests;
