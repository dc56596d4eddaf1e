//! Refitting as `tfs refit` and the Python package do: named effects added one by one, then
//! optionally the diagnosis loop run until nothing significant remains (each round adds the top
//! significant effect), then optionally simulation-error refinement, with the error ladder and
//! what it warns about.

use serde::Serialize;
use tfs_data::Record;
use tfs_diagnose::{
    Catalogue, DiagnoseOptions, LadderStep, add_effect_with, error_ladder, explain,
};
use tfs_library::Model;

use crate::error::{Context, Result};
use crate::identify::set_offsets;
use crate::invalid;
use crate::report::{OffsetsReport, RefineReport, ValidationReport};

/// A refitted model with its history.
#[derive(Debug, Clone)]
pub struct Refitted {
    /// The model; its trace holds the offsets report and the ladder's history.
    pub model: Model,
    /// R-MSE after each step.
    pub ladder: Vec<LadderStep>,
    /// What the ladder says against the steps taken (see [`ladder_warnings`]).
    pub warnings: Vec<String>,
    /// The simulation-error refinement (`None` without `refine`).
    pub refine: Option<RefineReport>,
    /// The rounds of the diagnosis loop (empty without `until_clean`).
    pub rounds: Vec<LoopRound>,
}

/// One round of the diagnosis loop: what the diagnosis said and what was added.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopRound {
    /// Round number, from 1.
    pub round: usize,
    /// The effect added (`name` or `name@dof`), or `None` when nothing was significant.
    pub added: Option<String>,
    /// The diagnosis's verdict in that round.
    pub verdict: String,
}

/// What [`refit_with`] is asked: effects to add by name, then the diagnosis loop, then
/// refinement.
#[derive(Debug, Clone, Default)]
pub struct RefitRequest {
    /// Effects to add first, in order (catalogue names, `name@dof`).
    pub add: Vec<String>,
    /// Run the diagnosis loop after them for at most this many rounds: each round adds the
    /// top significant effect; it stops when none is significant.
    pub until_clean: Option<usize>,
    /// Re-estimate the resulting structure by simulation error.
    pub refine: bool,
    /// Held-out records for `refine` (whichever fit predicts them better is kept).
    pub held_out: Vec<Record>,
}

/// The diagnosis loop: at most `max_rounds` times, rank the catalogue's effects on `records`
/// and add the top significant one (refitting, with its history step); stop when none is
/// significant. Returns the model and one [`LoopRound`] per round (the last says why it
/// stopped, unless the rounds ran out).
pub fn until_clean(
    model: &Model,
    records: &[Record],
    max_rounds: usize,
    opts: &DiagnoseOptions,
) -> Result<(Model, Vec<LoopRound>)> {
    let catalogue = Catalogue::standard(opts.max_power);
    let mut model = model.clone();
    let mut rounds = Vec::new();
    for round in 1..=max_rounds {
        let ex = explain(&model, records, &catalogue, opts)
            .with_context(|| format!("--until-clean: diagnosing in round {round}"))?;
        let Some(top) = ex.ranked.iter().find(|r| r.significant) else {
            rounds.push(LoopRound {
                round,
                added: None,
                verdict: ex.verdict,
            });
            break;
        };
        model = add_effect_with(&model, &top.name, records, &catalogue, opts)
            .with_context(|| format!("--until-clean: adding {} in round {round}", top.name))?;
        rounds.push(LoopRound {
            round,
            added: Some(top.name.clone()),
            verdict: ex.verdict,
        });
    }
    Ok((model, rounds))
}

/// Appends the model's input-derived computed columns (delayed or filtered inputs) to each
/// record so the model can be simulated under them (internal states are simulated by the model
/// itself).
pub fn with_computed_inputs(model: &Model, records: &mut [Record]) -> Result<()> {
    for c in tfs_diagnose::effects::computed_columns(model) {
        for r in records.iter_mut() {
            let v = c
                .compute(r, r.dt())
                .with_context(|| format!("{}: computing '{}'", r.source(), c.name()))?;
            r.set_column(c.name(), v)
                .with_context(|| format!("{}: adding column '{}'", r.source(), c.name()))?;
        }
    }
    Ok(())
}

/// What the error ladder says against the steps just taken: an added effect under which some
/// record's simulation fails, or one that makes the mean R-MSE worse than the step before it
/// (the records do not support it; `tfs diagnose` tests that before anything is added).
pub fn ladder_warnings(ladder: &[LadderStep]) -> Vec<String> {
    let mut out = Vec::new();
    for pair in ladder.windows(2) {
        let (before, after) = (&pair[0], &pair[1]);
        if after.incomplete() {
            out.push(format!(
                "after '{}', the simulation fails on {} of {} record(s) ({}); the model is not \
                 usable on them. `tfs diagnose` says which effects the records support",
                after.step,
                after.failed.len(),
                after.failed.len() + after.r_mse.len(),
                after.failed[0]
            ));
        } else if !before.incomplete()
            && before.mean_r_mse.is_finite()
            && after.mean_r_mse > before.mean_r_mse
        {
            out.push(format!(
                "'{}' made the mean R-MSE worse ({:.4e} -> {:.4e}): the records do not support \
                 it. `tfs diagnose` says which effects they do",
                after.step, before.mean_r_mse, after.mean_r_mse
            ));
        }
    }
    out
}

/// Adds the effects `add` (catalogue names, `name@dof`) to `model` one by one, refitting on
/// `records` (offsets already treated as `offsets` says); with `refine`, re-estimates the
/// resulting structure by simulation error, keeping with `held_out` records (offsets treated
/// the same) whichever fit predicts them better. See [`refit_with`] for the diagnosis loop.
pub fn refit(
    model: &Model,
    add: &[String],
    records: &[Record],
    refine: bool,
    held_out: Vec<Record>,
    offsets: &OffsetsReport,
) -> Result<Refitted> {
    let req = RefitRequest {
        add: add.to_vec(),
        until_clean: None,
        refine,
        held_out,
    };
    refit_with(model, records, &req, offsets)
}

/// [`refit`] with the diagnosis loop: the effects `req.add` first, then with `req.until_clean`
/// the loop of [`until_clean`] (default diagnosis options), then refinement.
pub fn refit_with(
    model: &Model,
    records: &[Record],
    req: &RefitRequest,
    offsets: &OffsetsReport,
) -> Result<Refitted> {
    if req.add.is_empty() && req.until_clean.is_none() {
        invalid!("--add: give at least one effect name (or --until-clean)");
    }
    if req.until_clean == Some(0) {
        invalid!("--until-clean 0: give the most rounds the loop may run (at least 1)");
    }
    let opts = DiagnoseOptions::default();
    let catalogue = Catalogue::standard(opts.max_power);
    let mut model = model.clone();
    for name in &req.add {
        model = add_effect_with(&model, name, records, &catalogue, &opts)
            .with_context(|| format!("--add {name}"))?;
    }
    let mut rounds = Vec::new();
    if let Some(max) = req.until_clean {
        (model, rounds) = until_clean(&model, records, max, &opts)?;
    }
    let (refine, mut held_out) = (req.refine, req.held_out.clone());
    let mut report = None;
    if refine {
        let mut train = records.to_vec();
        with_computed_inputs(&model, &mut train)?;
        let refined = tfs_refine::refine(&model, &train, &tfs_refine::RefineOptions::default())
            .context("--refine")?;
        let mut r = RefineReport::from(&refined);
        if held_out.is_empty() {
            model = refined.model;
        } else {
            with_computed_inputs(&model, &mut held_out)?;
            let (chosen, scores) =
                tfs_refine::choose_by_validation(&model, &refined.model, &held_out)
                    .context("--validate")?;
            r.validation = Some(ValidationReport::from(&scores));
            model = chosen;
        }
        report = Some(r);
    } else if !held_out.is_empty() {
        invalid!("--validate needs --refine (the held-out records choose the refined fit or not)");
    }
    // The refitted model was fitted on records treated this way: say so in its trace, so that
    // `compare` and `diagnose` treat them the same.
    set_offsets(&mut model, offsets);
    let ladder = error_ladder(&model);
    let warnings = ladder_warnings(&ladder);
    Ok(Refitted {
        model,
        ladder,
        warnings,
        refine: report,
        rounds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use tfs_library::RecordScore;

    fn step(name: &str, scores: &[f64], failed: &[&str]) -> LadderStep {
        let r_mse: Vec<RecordScore> = scores
            .iter()
            .map(|&v| RecordScore {
                record: "r".into(),
                r_mse: v,
            })
            .collect();
        LadderStep {
            step: name.into(),
            added: Vec::new(),
            mean_r_mse: if r_mse.is_empty() {
                f64::NAN
            } else {
                scores.iter().sum::<f64>() / scores.len() as f64
            },
            r_mse,
            failed: failed.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// An added effect that makes the error worse, or under which a record's simulation fails,
    /// is warned about; one that lowers it is not.
    #[test]
    fn warns_when_an_added_effect_does_not_help() {
        let good = [step("start", &[0.02], &[]), step("add a", &[0.01], &[])];
        assert!(ladder_warnings(&good).is_empty());
        let worse = [step("start", &[0.01], &[]), step("add a", &[0.02], &[])];
        let w = ladder_warnings(&worse);
        assert_eq!(w.len(), 1);
        assert!(w[0].contains("'add a' made the mean R-MSE worse"), "{w:?}");
        let broke = [
            step("start", &[0.01, 0.01], &[]),
            step("add a", &[0.01], &["r1: blew up"]),
        ];
        let w = ladder_warnings(&broke);
        assert_eq!(w.len(), 1);
        assert!(
            w[0].contains("fails on 1 of 2") && w[0].contains("blew up"),
            "{w:?}"
        );
    }
}
