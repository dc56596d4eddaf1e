//! Refitting as `tfs refit` and the Python package do: named effects added one by one, then
//! optionally the diagnosis loop run until nothing significant remains (each round adds the top
//! significant effect), then optionally simulation-error refinement, with the error ladder and
//! what it warns about.

use serde::Serialize;
use tfs_data::Record;
use tfs_diagnose::{
    Catalogue, DiagnoseOptions, LadderStep, SharedTerm, add_effect_fit, error_ladder, explain,
    hold_start, refit_shared,
};
use tfs_library::{Factor, Library, Model, Term};

use crate::contact::{StopRescan, rescan_stop};
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
    /// Each added stop's position re-scanned by the model's own method
    /// ([`crate::contact::rescan_stop`]), in the order the stops were added.
    pub stops: Vec<StopRescan>,
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
    /// Why the decision ([`crate::decide::decide`]) added what it added, or nothing.
    pub reason: crate::decide::Reason,
    /// What decided the round beyond the verdict, when anything did ([`crate::decide`]): the
    /// model fails to simulate some records and a candidate makes fewer fail; a significant
    /// candidate was passed over because the model simulates the records worse with it; a stop
    /// was added on T-F-S's evidence.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
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
/// and add the one the diagnosis names ([`crate::decide::decide`], as `tfs diagnose` names it;
/// refitting, with its history step); stop when it names none. Returns the model and one [`LoopRound`] per round (the last says why it
/// stopped, unless the rounds ran out).
pub fn until_clean(
    model: &Model,
    records: &[Record],
    max_rounds: usize,
    opts: &DiagnoseOptions,
) -> Result<(Model, Vec<LoopRound>)> {
    let mut notes = AddNotes::default();
    until_clean_with(model, records, max_rounds, opts, &mut notes)
}

/// What adding effects said beside the model: each stop's re-scan, and warnings.
#[derive(Debug, Default)]
pub(crate) struct AddNotes {
    pub(crate) stops: Vec<StopRescan>,
    pub(crate) warnings: Vec<String>,
}

/// Adds effect `name` to `model` (refitting on `records`), keeps a tied chain's ties, and for a
/// stop on a T-F-S model re-scans its position by T-F-S (pushing what was done to
/// `notes.stops`). A stop the refit's history lists as added but no equation holds (the refit
/// drops a column whose coefficient came out zero or non-finite, as for a stop that never
/// engages on the smoothed states) is warned about in `notes.warnings`. Last, the step toward
/// that model is searched ([`hold_start`]): when it does not predict the records better than
/// `model`, a fraction of the way, or `model`'s equations unchanged (warned about; a stop's
/// re-scan is then not reported).
pub(crate) fn add_one(
    model: &Model,
    name: &str,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
    notes: &mut AddNotes,
) -> Result<Model> {
    // Refinement by simulation error only on a one-DOF model: a tied chain is refitted jointly
    // with its ties after the effect is added (`keep_ties`), which would undo a refinement of
    // each equation on its own, and multiple shooting on every DOF of a chain costs minutes per
    // effect (the chain keeps the equation-error anchors' choice).
    let untied;
    let opts = if opts.refine_added && model.dofs.len() > 1 {
        untied = DiagnoseOptions {
            refine_added: false,
            ..opts.clone()
        };
        &untied
    } else {
        opts
    };
    // The effect's best fit, refitted with a chain's ties and a stop re-placed by T-F-S; the
    // step toward that model is searched last (`hold_start`), so what is returned never
    // predicts the records worse than `model`.
    let added = add_effect_fit(model, name, records, catalogue, opts)?;
    let added = keep_ties(added, records, opts)?;
    notes.warnings.extend(dropped_terms(&added).into_iter().map(|t| {
        format!(
            "'{name}': the refit gave '{t}' a zero or non-finite coefficient on these records and left it out, so the model does not have it (a stop that never engages in the data does that)"
        )
    }));
    let (added, report) =
        match rescan_stop(model, &added, name.split_once('@').map(|(_, d)| d), records)? {
            Some((m, report)) => (m, Some(report)),
            None => (added, None),
        };
    let mut held = hold_start(model, &added, records, opts)?;
    prune_ties(&mut held);
    if held.equations == model.equations {
        notes.warnings.push(format!(
            "'{name}': no step toward its refit predicts these records better than the model without it, so nothing was added (the equations are unchanged)"
        ));
    } else {
        notes.stops.extend(report);
    }
    Ok(held)
}

/// Drops from the trace's `"ties"` every tie whose term its owner's or its partner's equation
/// no longer holds: the ties are written when the tied refit is made, and a stop's re-scan by
/// T-F-S afterwards may re-identify the chain without a term (its interval covering zero), so a
/// listed tie would name a term the model does not have.
fn prune_ties(model: &mut Model) {
    let holds = |dof: Option<&str>, term: Option<&str>| {
        model
            .equations
            .iter()
            .find(|e| Some(e.dof.as_str()) == dof)
            .is_some_and(|e| {
                e.terms
                    .iter()
                    .any(|t| Some(t.term.to_string().as_str()) == term)
            })
    };
    let Some(ties) = model.trace.get("ties").and_then(|t| t.as_array()) else {
        return;
    };
    let kept: Vec<serde_json::Value> = ties
        .iter()
        .filter(|t| {
            let term = t["term"].as_str();
            holds(t["owner"].as_str(), term) && holds(t["partner"].as_str(), term)
        })
        .cloned()
        .collect();
    if kept.len() < ties.len()
        && let Some(trace) = model.trace.as_object_mut()
    {
        trace.insert("ties".into(), serde_json::Value::Array(kept));
    }
}

/// The stop terms (`below`, `above`) the model's last history step lists as added that no
/// equation holds.
fn dropped_terms(model: &Model) -> Vec<String> {
    let Some(last) = model.history.last() else {
        return Vec::new();
    };
    let held = |t: &Term| {
        model
            .equations
            .iter()
            .any(|e| e.terms.iter().any(|m| m.term == *t))
    };
    last.added
        .iter()
        .filter(|a| {
            Term::parse(a, &model.dofs).is_ok_and(|t| {
                matches!(t.factors(), [Factor::Below(..)] | [Factor::Above(..)]) && !held(&t)
            })
        })
        .cloned()
        .collect()
}

/// [`until_clean`], pushing each added stop's re-scan and the warnings to `notes`.
fn until_clean_with(
    model: &Model,
    records: &[Record],
    max_rounds: usize,
    opts: &DiagnoseOptions,
    notes: &mut AddNotes,
) -> Result<(Model, Vec<LoopRound>)> {
    let catalogue = Catalogue::standard(opts.max_power);
    // The diagnosis and the decision see every candidate as `tfs diagnose` does (equation-error
    // refits); the effect they name is then added with `opts` (refined when it asks for that).
    let scan = DiagnoseOptions {
        refine_added: false,
        ..opts.clone()
    };
    let mut model = model.clone();
    let mut rounds = Vec::new();
    for round in 1..=max_rounds {
        let ex = explain(&model, records, &catalogue, &scan)
            .with_context(|| format!("--until-clean: diagnosing in round {round}"))?;
        let decision = crate::decide::decide(
            &model,
            &ex.ranked,
            records,
            &scan,
            &crate::decide::DecideOptions::loop_round(),
        )
        .with_context(|| format!("--until-clean: round {round}"))?;
        // The decision's sentences when it did more than take the ranking's top significant
        // candidate of a model that simulates every record.
        let note = (!decision.ranking_stands || decision.before.failed > 0)
            .then(|| decision.why.clone())
            .filter(|w| !w.is_empty());
        let reason = decision.reason;
        let Some(chosen) = decision.added else {
            rounds.push(LoopRound {
                round,
                added: None,
                verdict: ex.verdict,
                reason,
                note,
            });
            break;
        };
        let mut again = AddNotes::default();
        let refined = if opts.refine_added {
            add_one(
                &model,
                &chosen.effect,
                records,
                &catalogue,
                opts,
                &mut again,
            )
            .ok()
        } else {
            None
        };
        if let Some(m) = refined {
            model = m;
            notes.stops.extend(again.stops);
            notes.warnings.extend(again.warnings);
        } else {
            model = chosen.model;
            notes.stops.extend(chosen.stops);
            notes.warnings.extend(chosen.warnings);
        }
        rounds.push(LoopRound {
            round,
            added: Some(chosen.effect),
            verdict: ex.verdict,
            reason,
            note,
        });
    }
    Ok((model, rounds))
}

/// The terms a tied chain model shares between two equations (one cell's force law, Newton's
/// third law), from its equations' current terms and the tied fit's masses: each term of a
/// relative coordinate `(xi-xj)` in both DOFs' equations, the partner's coefficient
/// `−m_i/m_j` times the owner's. Empty for a model that was not fitted with ties
/// ([`crate::chain::is_tied`]).
pub fn shared_terms(model: &Model) -> Result<Vec<SharedTerm>> {
    if !crate::chain::is_tied(model) {
        return Ok(Vec::new());
    }
    let masses = crate::chain::fit_masses(model);
    let libs = model
        .equations
        .iter()
        .map(|e| {
            Library::new(
                &model.dofs,
                e.terms.iter().map(|t| t.term.clone()).collect(),
            )
        })
        .collect::<std::result::Result<Vec<Library>, _>>()
        .context("the tied model's equations as libraries")?;
    Ok(tfs_criteria::library_ties(&libs, &model.dofs)
        .into_iter()
        .map(|t| SharedTerm {
            term: libs[t.owner].terms()[t.owner_col].clone(),
            owner: t.owner,
            partner: t.partner,
            factor: -masses[t.owner] / masses[t.partner],
        })
        .collect())
}

/// A tied chain model after an effect was added (each equation refitted on its own): its
/// coefficients re-estimated jointly with the shared terms tied ([`shared_terms`], which
/// includes an added term of a cell's coordinate in both equations), and the trace's `"ties"`
/// updated to them, so that the written model says it is tied and a later refit keeps them.
/// An untied model is returned as it is.
fn keep_ties(model: Model, records: &[Record], opts: &DiagnoseOptions) -> Result<Model> {
    let shared = shared_terms(&model)?;
    if shared.is_empty() {
        return Ok(model);
    }
    let mut out =
        refit_shared(&model, records, &shared, opts).context("refitting with the chain's ties")?;
    let ties: Vec<serde_json::Value> = shared
        .iter()
        .map(|s| {
            serde_json::json!({
                "term": s.term.to_string(),
                "owner": out.dofs[s.owner],
                "partner": out.dofs[s.partner],
                "factor_in_partner": s.factor,
            })
        })
        .collect();
    if let Some(trace) = out.trace.as_object_mut() {
        trace.insert("ties".into(), serde_json::Value::Array(ties));
    }
    Ok(out)
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
/// record's simulation fails, or one that makes the geometric-mean R-MSE over the records
/// ([`tfs_diagnose::geometric_mean_r_mse`]) worse than the step before it
/// (the records do not support it; `tfs diagnose` tests that before anything is added).
pub fn ladder_warnings(ladder: &[LadderStep]) -> Vec<String> {
    let mut out = Vec::new();
    // A stop's equation-error rung that the T-F-S re-scan replaced (the next rung) is not the
    // model any more: the re-scan's rung is judged against the rung before it.
    let kept: Vec<&LadderStep> = ladder
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            ladder
                .get(i + 1)
                .is_none_or(|next| next.step != crate::contact::RESCAN_STEP)
        })
        .map(|(_, s)| s)
        .collect();
    for pair in kept.windows(2) {
        let (before, after) = (pair[0], pair[1]);
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
            && before.geo_mean_r_mse.is_finite()
            && after.geo_mean_r_mse > before.geo_mean_r_mse
        {
            out.push(format!(
                "'{}' made the geometric-mean R-MSE over the records worse ({:.4e} -> {:.4e}): \
                 the records do not support it. `tfs diagnose` says which effects they do",
                after.step, before.geo_mean_r_mse, after.geo_mean_r_mse
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
    // Each effect added is also refined by simulation error where that predicts the records
    // better (`DiagnoseOptions::refine_added`).
    let opts = DiagnoseOptions {
        refine_added: true,
        ..DiagnoseOptions::default()
    };
    let catalogue = Catalogue::standard(opts.max_power);
    let mut model = model.clone();
    let mut notes = AddNotes::default();
    for name in &req.add {
        model = add_one(&model, name, records, &catalogue, &opts, &mut notes)
            .with_context(|| format!("--add {name}"))?;
    }
    let mut rounds = Vec::new();
    if let Some(max) = req.until_clean {
        (model, rounds) = until_clean_with(&model, records, max, &opts, &mut notes)?;
    }
    let (refine, mut held_out) = (req.refine, req.held_out.clone());
    let mut report = None;
    let mut tie_warning = None;
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
        if crate::chain::is_tied(&model) {
            // Refinement re-estimates each equation on its own: the file must not claim ties.
            if let Some(trace) = model.trace.as_object_mut() {
                trace.remove("ties");
            }
            tie_warning = Some(
                "--refine re-estimated each equation on its own: the chain's tied terms (one force law per cell) no longer hold in the refined model; refit without --refine to keep them".to_string(),
            );
        }
    } else if !held_out.is_empty() {
        invalid!("--validate needs --refine (the held-out records choose the refined fit or not)");
    }
    // The refitted model was fitted on records treated this way: say so in its trace, so that
    // `compare` and `diagnose` treat them the same.
    set_offsets(&mut model, offsets);
    let ladder = error_ladder(&model);
    let mut warnings = notes.warnings;
    warnings.extend(ladder_warnings(&ladder));
    warnings.extend(tie_warning);
    Ok(Refitted {
        model,
        ladder,
        warnings,
        refine: report,
        rounds,
        stops: notes.stops,
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
            geo_mean_r_mse: if r_mse.is_empty() {
                f64::NAN
            } else {
                tfs_diagnose::geometric_mean_r_mse(scores)
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
        assert!(
            w[0].contains("'add a' made the geometric-mean R-MSE over the records worse"),
            "{w:?}"
        );
        // A multi-stable record whose free run settles in the other well under either model
        // (R-MSE ≫ 1) does not outvote the records the effect predicts far better: the
        // arithmetic mean rises (1.5e1 against 4.0), the geometric mean falls 60x.
        let lost_record = [
            step("start", &[5.06, 5.22, 1.71], &[]),
            step("add a", &[1.05e-2, 4.1e-4, 47.4], &[]),
        ];
        assert!(lost_record[1].mean_r_mse > lost_record[0].mean_r_mse);
        assert!(ladder_warnings(&lost_record).is_empty());
        // Worse on every record by the same factor is worse whatever the mean.
        let all_worse = [
            step("start", &[5.06, 5.22, 1.71], &[]),
            step("add a", &[10.12, 10.44, 3.42], &[]),
        ];
        assert_eq!(ladder_warnings(&all_worse).len(), 1);
        // A stop's equation-error rung replaced by its T-F-S re-scan is not warned about; the
        // re-scan's rung is judged against the rung before the stop.
        let rescanned = [
            step("start", &[0.5, 0.5], &[]),
            step("add stop", &[0.2], &["r1: blew up"]),
            step(crate::contact::RESCAN_STEP, &[0.1, 0.1], &[]),
        ];
        assert!(ladder_warnings(&rescanned).is_empty());
        let rescanned_worse = [
            step("start", &[0.05, 0.05], &[]),
            step("add stop", &[0.02, 0.02], &[]),
            step(crate::contact::RESCAN_STEP, &[0.1, 0.1], &[]),
        ];
        let w = ladder_warnings(&rescanned_worse);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("made the geometric-mean R-MSE over the records worse (5.0000e-2"),
            "{w:?}"
        );
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

    /// A tied model's shared terms are the terms of a cell's coordinate in both equations (the
    /// stop too), with the factor −m2/m1 from its masses; a model without ties shares none.
    #[test]
    fn shared_terms_follow_the_tied_masses() {
        let json = |ties: bool| {
            let trace = if ties {
                serde_json::json!({"masses": [1.0, 0.5], "ties": [{"term": "(x2-x1)^3", "owner": "x2", "partner": "x1", "factor_in_partner": -0.5}]})
            } else {
                serde_json::json!({})
            };
            serde_json::json!({"format": "tfs-model/1", "dofs": ["x1", "x2"], "inputs": [], "method": "test", "trace": trace,
                "equations": [
                    {"dof": "x1", "terms": [{"term": "x1", "coef": -1.0}, {"term": "(x2-x1)^3", "coef": 2.0}, {"term": "below((x2-x1), 0.1)", "coef": -4.0}]},
                    {"dof": "x2", "terms": [{"term": "(x2-x1)^3", "coef": -1.0}, {"term": "below((x2-x1), 0.1)", "coef": 2.0}, {"term": "x2'", "coef": -0.1}]}]})
            .to_string()
        };
        let tied = Model::from_json_str(&json(true)).unwrap();
        let shared = shared_terms(&tied).unwrap();
        let names: Vec<String> = shared.iter().map(|s| s.term.to_string()).collect();
        assert_eq!(names, ["(x2-x1)^3", "below((x2-x1), 0.1)"]);
        assert!(
            shared
                .iter()
                .all(|s| s.owner == 1 && s.partner == 0 && s.factor == -0.5)
        );
        let untied = Model::from_json_str(&json(false)).unwrap();
        assert!(shared_terms(&untied).unwrap().is_empty());
    }
}
