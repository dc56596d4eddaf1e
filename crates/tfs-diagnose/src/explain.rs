//! Explain: refit the model's structure plus each catalogue effect by equation error, score it on
//! held-out blocks, test it, size it, judge its held-out predictions, check it against the
//! calibrated null, and rank the effects. This module is the orchestration only: the stages are
//! `scan.rs` (the equation-error analysis of one effect on one DOF), `judge.rs` and `judged.rs`
//! (held-out predictions), `null.rs` (the calibrated null) and `rank.rs` (order and ties); each
//! writes its own part of every candidate's [`Evidence`] once, and whether a candidate is
//! significant is read from that evidence by one function ([`Evidence::significance`]).
//!
//! An effect is significant when the corrected p-value is below `alpha`, the held-out error
//! falls, and its size (RMS change of the fitted force over the RMS of `x''`) is at least
//! `min_share` — or, below it, the judge finds that the refitted model predicts the held-out
//! data better by at least `min_share` of the motion's RMS (its size on the motion), or with at
//! most half the RMS prediction error of the model without it (most of what a model already that
//! close misses: `judge::predicts_better_by`) — and the judge of held-out predictions does not
//! find that it predicts worse by more than the judge resolves, and its held-out drop lies
//! beyond what the same scan finds on the start model's own simulated records (`null.rs`: the
//! equation error's bias with nothing missing) — unless the judge resolves that its refitted
//! model removes most of the held-out prediction error, which that bias cannot give.
//! Significant effects are ordered by the free-run R-MSE where the free run judges and shows
//! skill (below 1), otherwise by the held-out equation error; the rest by held-out simulation
//! R-MSE, then equation error. A significant effect that the ordering's own evidence does not
//! tell from the top one (paired block test of their held-out equation errors, and no free run
//! with skill between them) is reported as tied with it: the records cannot say which of the two
//! is missing.

use rayon::prelude::*;
use serde::Serialize;
use tfs_data::Record;
use tfs_library::Model;

use crate::Result;
use crate::design::FoldEquation;
use crate::effects::Catalogue;
use crate::evidence::{Evidence, JudgedAt, NullEvidence, PredictionEvidence, judged};
use crate::judge::{Choice, Heldout, Judge, JudgeUse};
use crate::null::NullJob;
use crate::prepare::{DiagnoseOptions, Layout, RecordStates};
use crate::rank::{Candidate, mark_ties, order};
use crate::scan::{DofSetup, Raw, analyse, context, setup_dof};
use crate::simulate::BaseRun;

pub use crate::rank::RankedEffect;

/// Result of [`explain`]: ranked effects and the verdict.
#[derive(Debug, Clone, Serialize)]
pub struct Explanation {
    /// Effects ranked: significant first; among them by the free-run R-MSE where the free run
    /// judges and shows skill, else by held-out equation-error improvement; the rest by
    /// held-out simulation R-MSE, then equation-error improvement (see the module docs).
    pub ranked: Vec<RankedEffect>,
    /// One sentence: the top significant effect, or "no significant missing effect".
    pub verdict: String,
    /// Number of variants tested (the Bonferroni factor).
    pub tests: usize,
    /// Per DOF: the judge of the held-out predictions and why it was chosen.
    pub judges: Vec<JudgeUse>,
    /// Cut-off (Hz) used for the smoothed states, per record.
    pub cutoff_hz: Vec<f64>,
    /// Folds are records (true) or time segments (false).
    pub folds_by_record: bool,
    /// Number of held-out blocks.
    pub blocks: usize,
}

/// One candidate during the scan: its analysis, its evidence as the stages write it, and what the
/// judge simulated.
struct Scan {
    raw: Raw,
    evidence: Evidence,
    /// The held-out prediction score by the judge.
    heldout: Option<Heldout>,
    /// The shortlisted variant the judge judged ([`Raw::alternatives`]), if not the best.
    alternative: Option<usize>,
}

/// What the judge found for one candidate under one choice of judge.
struct Judged {
    heldout: Option<Heldout>,
    alternative: Option<usize>,
    evidence: PredictionEvidence,
}

/// Judges every candidate's refitted per-fold models on held-out data ([`crate::judge`]): per
/// candidate the judge's part of its evidence (whether it predicts worse than the model without
/// it by more than the judge can resolve, or better), and the judge of each DOF with its reason.
///
/// The free run's verdict on a candidate is only as good as the candidate's own free run: a
/// model closer to the truth can be the one whose motion the input's noise decides (a slower
/// escape from an initial well, a snap-through the start model smoothed away), and then its
/// worse free-run score says which way the noise tipped it, not that it is wrong. So when the
/// free run vetoes a candidate the equation error finds significant, and that candidate's own
/// per-fold free run is dominated by the input's noise on a held-out record, the free run
/// cannot rank these candidates and all of them are judged again by short-horizon prediction.
/// Otherwise, when such a candidate's per-fold model cannot be simulated from the record's
/// start at all, all of them are judged again by the free run over the fitted rows alone, each
/// held-out unit from the measured state at its first row (`Choice::from_fitted_rows`).
fn judge_candidates(
    model: &Model,
    setups: &[DofSetup],
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
    scans: &[Scan],
    runs: &[BaseRun],
) -> (Vec<Judged>, Vec<JudgeUse>) {
    let choice = crate::judge::choose(model, states, opts, runs);
    let first = judge_with(model, setups, states, layout, opts, scans, &choice);
    if choice.judge != Judge::FreeRun {
        return first;
    }
    // Significant by equation error, not once the free run has judged it.
    let dropped = |s: &Scan, j: &Judged| {
        let eq = s.evidence.equation();
        judged(eq, None, opts).is_significant()
            && !judged(eq, Some(&j.evidence), opts).is_significant()
    };
    let dominated = scans.iter().zip(&first.0).find(|(s, j)| {
        dropped(s, j) && j.heldout.is_some() && {
            let at = (s.raw.dof_idx, &s.raw.scored);
            let partners = crate::judged::partner_equations(model, at, states, layout);
            let eqs = crate::judged::fold_equations(model, setups, at, &partners);
            folds_noise_dominated(model, &eqs, states, layout, opts)
        }
    });
    let choice = if let Some((s, _)) = dominated {
        Choice {
            judge: Judge::ShortHorizon,
            why: format!(
                "free-run simulation cannot rank these candidates: a fresh draw of the measured input's noise, or the run's own divergence from a start one displacement-noise standard deviation away, moves the free run of the model with {} about as far as its error",
                s.raw.name(model)
            ),
            plain: false,
            resolution: choice.resolution,
            floor: 0.0,
            from_fitted_rows: false,
        }
    } else if let Some((s, _)) = scans
        .iter()
        .zip(&first.0)
        .find(|(s, j)| dropped(s, j) && j.heldout.is_none())
    {
        // A significant candidate's per-fold model could not be simulated from the record's
        // start: the smoothing margin before the fitted rows holds states none of the fold's
        // rows taught it (a cell leaving its deployed well there). Every candidate is judged
        // again over the fitted rows alone.
        Choice {
            judge: Judge::FreeRun,
            why: format!(
                "free-run simulation under the measured input over the rows the equations were fitted on, each from the measured state at its first (the model with {} could not be simulated from the start of the records)",
                s.raw.name(model)
            ),
            plain: false,
            resolution: choice.resolution,
            floor: choice.floor,
            from_fitted_rows: true,
        }
    } else {
        return first;
    };
    judge_with(model, setups, states, layout, opts, scans, &choice)
}

/// True when on some held-out record the free run of a per-fold model whose equations `eqs`
/// replace the model's cannot rank models: dominated by the input's own noise or by its own
/// divergence ([`crate::simulate::free_run_noise_dominated`]).
fn folds_noise_dominated(
    model: &Model,
    eqs: &[FoldEquation<'_>],
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
) -> bool {
    (0..layout.folds).into_par_iter().any(|f| {
        let Some(m) = crate::design::fold_model(model, eqs, f) else {
            return false;
        };
        (0..states.len()).any(|r| {
            layout.blocks.iter().any(|b| b.fold == f && b.record == r)
                && crate::simulate::free_run_noise_dominated(&m, &states[r].record, opts)
        })
    })
}

/// [`judge_candidates`] under the judge `choice`: per candidate, its held-out prediction score,
/// the shortlisted variant judged, and the judge's part of its evidence.
fn judge_with(
    model: &Model,
    setups: &[DofSetup],
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
    scans: &[Scan],
    choice: &Choice,
) -> (Vec<Judged>, Vec<JudgeUse>) {
    let judge = choice.judge;
    let dt = states[0].record.dt();
    // Pieces of two dominant periods at most; under the short horizon, as long as the start
    // model's predictions keep their skill ([`crate::judge::divergence_horizon`]), and at least
    // one cut-off period of the smoothing.
    let cap = |d: &DofSetup| ((2.0 * d.scales.period / dt).round() as usize).max(16);
    let skill = (judge == Judge::ShortHorizon).then(|| {
        let mut fc: Vec<f64> = states.iter().map(|s| s.cutoff_hz).collect();
        fc.sort_by(f64::total_cmp);
        let floor = (1.0 / (fc[fc.len() / 2] * dt)).ceil().max(1.0) as usize;
        let longest = setups.iter().map(cap).max().unwrap_or(16);
        crate::judge::divergence_horizon(model, states, opts, longest, floor)
    });
    let horizon = |d: &DofSetup| skill.map_or(cap(d), |h| h.min(cap(d)));
    let before: Vec<Option<Heldout>> = setups
        .par_iter()
        .map(|d| {
            let h = horizon(d);
            let eq = FoldEquation {
                idx: d.idx,
                cols: &d.base_cols,
                cv: &d.base_cv,
                anchor: d.anchor(crate::design::anchored(model)),
            };
            crate::judge::heldout_error(choice, model, &[eq], states, layout, opts, h)
        })
        .collect();
    let judged: Vec<Judged> = scans
        .par_iter()
        .map(|s| {
            let raw = &s.raw;
            let at = (choice, horizon(&setups[raw.dof_idx]));
            let (heldout, alternative) =
                crate::judged::heldout(model, setups, states, layout, opts, at, raw);
            let before = before[raw.dof_idx].as_ref();
            let resolution = choice.resolution;
            // Worse means worse by more than the judge resolves: a difference a fresh draw of
            // the input's noise makes, or one the pieces do not bear out, decides nothing. A
            // model that cannot be simulated on the held-out data predicts it worse.
            let worse = before.map(|b| match &heldout {
                Some(a) => crate::judge::predicts_worse(judge, b, a, resolution, opts.alpha),
                None => true,
            });
            let better = |floor: f64, min_share: f64| {
                before.zip(heldout.as_ref()).and_then(|(b, a)| {
                    crate::judge::predicts_better_by(
                        judge,
                        (b, a),
                        (resolution, floor),
                        opts.alpha,
                        min_share,
                    )
                })
            };
            let judged_at = alternative
                .and_then(|k| raw.alternatives.get(k))
                .and_then(|a| a.scored.variant.parameter.clone())
                .map(|parameter| JudgedAt {
                    parameter,
                    shortlist: raw.alternatives.len() + 1,
                });
            let evidence = PredictionEvidence {
                judge,
                before: before.map(|h| h.mean),
                after: heldout.as_ref().map(|h| h.mean),
                worse,
                // The size on the motion: the drop of the model's own error, above what the
                // noise leaves to any model.
                better_by: better(choice.floor, opts.min_share),
                floor: choice.floor,
                // Most of the whole error, whatever the drop's share of the motion (`min_share`
                // never met): what exempts a candidate from the null, so read on the whole
                // R-MSE, the noise's share included — the stricter reading, since the null is
                // the guard against the equation error's bias it would skip.
                removes_most: better(0.0, f64::INFINITY).is_some(),
                judged_at,
            };
            Judged {
                heldout,
                alternative,
                evidence,
            }
        })
        .collect();
    let uses = setups
        .iter()
        .map(|d| {
            let why = match skill {
                Some(_) => format!(
                    "{}; pieces of {:.4} s, as long as the model's predictions keep their skill",
                    choice.why,
                    horizon(d) as f64 * dt
                ),
                None => choice.why.clone(),
            };
            JudgeUse {
                dof: model.dofs[d.idx].clone(),
                judge,
                why,
                plain: choice.plain,
            }
        })
        .collect();
    (judged, uses)
}

/// The calibrated null's stage ([`crate::null`]): every candidate significant once judged is
/// re-judged against the start model's own simulated records, unless its model removes most of
/// the held-out prediction error; each such candidate's null part is written once.
fn null_stage(
    model: &Model,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
    scans: &mut [Scan],
    runs: &[BaseRun],
    tests: usize,
) {
    let mut jobs = Vec::new();
    let mut at = Vec::new();
    for (k, s) in scans.iter_mut().enumerate() {
        if !s.evidence.judged(opts).is_significant() {
            continue;
        }
        if s.evidence.prediction().is_some_and(|p| p.removes_most) {
            s.evidence.record_null(NullEvidence::RemovesMost);
            continue;
        }
        jobs.push(NullJob {
            dof_idx: s.raw.dof_idx,
            effect: s.raw.effect.clone(),
            delta: s.evidence.equation().delta,
            after: s.raw.scored.cv_rss,
        });
        at.push(k);
    }
    let found = crate::null::calibrate(model, records, catalogue, opts, &jobs, runs, tests);
    for (k, n) in at.into_iter().zip(found) {
        if let Some(n) = n {
            scans[k].evidence.record_null(n);
        }
    }
}

/// Ranks every catalogue effect for `model` on `records`.
pub fn explain(
    model: &Model,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Result<Explanation> {
    explain_with_runs(model, records, catalogue, opts, None)
}

/// [`explain`] with the model's own simulations of the records when the caller has them
/// ([`crate::simulate::base_runs`]); made here when needed otherwise.
pub(crate) fn explain_with_runs(
    model: &Model,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
    runs: Option<&[BaseRun]>,
) -> Result<Explanation> {
    opts.validate()?;
    crate::prepare::check_records(model, records)?;
    let states: Vec<RecordStates> = records
        .par_iter()
        .map(|r| RecordStates::new(model, r, opts))
        .collect::<Result<_>>()?;
    let layout = Layout::new(&states, opts)?;
    let dt = records[0].dt();
    let setups: Vec<DofSetup> = (0..model.dofs.len())
        .map(|i| setup_dof(model, i, &states, &layout))
        .collect::<Result<_>>()?;
    // Every (effect, DOF) pair with its variants.
    let mut jobs = Vec::new();
    for d in &setups {
        let ctx = context(model, d, dt, opts);
        for e in catalogue.effects() {
            let vars = e.variants(&ctx);
            if !vars.is_empty() {
                jobs.push((e.name(), d.idx, vars, e.parameter_by_simulation()));
            }
        }
    }
    let tests: usize = jobs.iter().map(|j| j.2.len()).sum::<usize>().max(1);
    // The scan: each candidate's equation-error part of its evidence.
    let mut scans: Vec<Scan> = jobs
        .par_iter()
        .map(|(name, idx, vars, by_sim)| {
            analyse(&states, &layout, &setups[*idx], name, (vars, *by_sim), opts)
        })
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .flatten()
        .map(|raw| Scan {
            evidence: Evidence::new(raw.equation_evidence(tests)),
            raw,
            heldout: None,
            alternative: None,
        })
        .collect();
    // The scan is over and no design of it is read again (a coupled candidate's partner design
    // is made afresh): the start equations' designs and the columns the states cache for them
    // are dropped before the judge and the null stage simulate (60 MB at 640,000 samples).
    let setups: Vec<DofSetup> = setups.into_iter().map(DofSetup::lean).collect();
    states.iter().for_each(RecordStates::forget_designs);
    let judges = if opts.simulate {
        let made;
        let runs = match runs {
            Some(r) => r,
            None => {
                made = crate::simulate::base_runs(model, records, opts);
                &made
            }
        };
        let (judged, judges) =
            judge_candidates(model, &setups, &states, &layout, opts, &scans, runs);
        for (s, j) in scans.iter_mut().zip(judged) {
            s.evidence.record_prediction(j.evidence);
            (s.heldout, s.alternative) = (j.heldout, j.alternative);
        }
        null_stage(model, records, catalogue, opts, &mut scans, runs, tests);
        judges
    } else {
        setups
            .iter()
            .map(|d| JudgeUse {
                dof: model.dofs[d.idx].clone(),
                judge: Judge::EquationError,
                why: "simulation of the candidates is switched off".to_string(),
                plain: false,
            })
            .collect()
    };
    // The decision and the report, once, from each candidate's evidence.
    let mut ranked: Vec<Candidate> = scans
        .into_iter()
        .map(|s| Candidate {
            entry: crate::rank::RankedEffect::new(model, &s.raw, s.alternative, s.evidence, opts),
            raw: s.raw,
            heldout: s.heldout,
        })
        .collect();
    let judge = judges.first().map_or(Judge::EquationError, |j| j.judge);
    order(&mut ranked, judge, opts.alpha);
    mark_ties(&mut ranked, judge, opts.alpha);
    let ranked: Vec<RankedEffect> = ranked.into_iter().map(|c| c.entry).collect();
    let verdict = crate::verdict::verdict(&ranked, &judges, opts);
    Ok(Explanation {
        ranked,
        verdict,
        tests,
        judges,
        cutoff_hz: states.iter().map(|s| s.cutoff_hz).collect(),
        folds_by_record: layout.by_record,
        blocks: layout.blocks.len(),
    })
}
