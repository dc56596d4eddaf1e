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
//!   fewer failing than the model without it, and fewer than the model's own terms refitted on
//!   the records with nothing added: a candidate's model is that refit plus the candidate, so a
//!   failure the refit alone cures was the start fit's (a model identified on noisy records
//!   that runs away on one of them), and any candidate would seem to cure it.
//!   [`simulation_choice`] does this for `tfs diagnose`
//!   and for each round of `refit --until-clean`. When the chosen one still leaves records
//!   failing, `diagnose` goes on from the model with it the same way (forward selection, at most
//!   [`MAX_FURTHER`] more), so that it names what the records need together: one effect may not
//!   be enough (a chain whose cells each need their stop). The loop takes the first and
//!   re-diagnoses instead.
//! - The loop ([`loop_choice`]) otherwise takes the top significant candidate whose addition
//!   does not make the model simulate the records worse (more records failing, or as many and a
//!   higher mean R-MSE: what the error ladder warns the records do not support); one that does is
//!   passed over, and the next significant one is tried; one that cannot be added is passed over
//!   too. `diagnose` names its effect the same way ([`on_diagnosis`]) when the free run judged
//!   the candidates, so that it names what the loop adds; where the short horizon judged (the
//!   input's own noise decides a free run there) it names the ranking's top one.
//! - When no significant candidate remains, a stop whose held-out equation error falls is looked
//!   at by T-F-S: the stop's equation-error evidence is weak where the contact is stiff (the
//!   smoothing spreads its short acceleration burst), while T-F-S, re-identifying the model with
//!   the stop scanned over positions ([`crate::contact::rescan_stop`]), resolves it through the
//!   momentum it changes. The stop is added when the re-identified model replaced the
//!   equation-error fit, T-F-S's own term test of its coefficient passes at the diagnosis's
//!   level, corrected over the library's terms and the positions scanned
//!   ([`tfs_stop_p_value`]), and the model with it simulates the records better than without.

use serde::Serialize;
use tfs_data::Record;
use tfs_diagnose::{
    Catalogue, DiagnoseOptions, Diagnosis, Explanation, Judge, RankedEffect, error_ladder,
};
use tfs_library::Model;

use crate::contact::StopRescan;
use crate::error::Result;

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
    pub(crate) fn key(&self) -> (usize, f64) {
        (
            self.failed,
            if self.mean_r_mse.is_finite() {
                self.mean_r_mse
            } else {
                f64::INFINITY
            },
        )
    }

    /// In words: `2 of 4 records fail` or `all 4 simulate (mean R-MSE …)` (`the record …`
    /// when there is one).
    pub fn describe(&self) -> String {
        match self.failed {
            0 if self.records == 1 => {
                format!("the record simulates (R-MSE {:.4e})", self.mean_r_mse)
            }
            1 if self.records == 1 => "the record fails to simulate".to_string(),
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

    /// The records that fail, in words: `2 of 4 records`, or `the record` when there is one.
    pub fn failing(&self) -> String {
        if self.records == 1 {
            "the record".to_string()
        } else {
            format!("{} of {} records", self.failed, self.records)
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
        crate::contact::score(model, records).summary()
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

/// What the simulations said in one diagnosis: how the model simulates, the candidates tried
/// and the one chosen, in a sentence.
#[derive(Debug, Clone, Serialize)]
pub struct GateReport {
    /// How the model without any candidate simulates the records.
    pub before: SimScore,
    /// How the model's own terms, refitted on the records as every candidate's model is
    /// (nothing added), simulate them. A candidate must leave fewer records failing than this
    /// too: when the refit alone makes them simulate, the failure was the start fit's, not a
    /// missing effect's. `None` when not looked at (the model simulates every record, or is an
    /// untied multi-DOF model, whose candidates refit only their own equations) or when that
    /// refit could not be made.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refitted: Option<SimScore>,
    /// Every candidate tried, in the diagnosis's order.
    pub tried: Vec<Trial>,
    /// The candidate chosen (`None`: the simulations chose none).
    pub chosen: Option<String>,
    /// When the chosen one still leaves records failing: the effects that, added after it in
    /// this order, each leave fewer failing (empty when none is needed or none helps).
    pub then: Vec<Step>,
    /// Why, in a sentence.
    pub why: String,
}

impl GateReport {
    /// The effects the simulations chose, in the order they are added: the chosen one, then
    /// [`GateReport::then`].
    pub fn effects(&self) -> Vec<&str> {
        self.chosen
            .iter()
            .map(String::as_str)
            .chain(self.then.iter().map(|s| s.effect.as_str()))
            .collect()
    }

    /// Whether the verdict follows the simulations: they chose an effect, or the model
    /// simulates every record and they passed over every significant candidate (then nothing is
    /// named). Otherwise (the model fails some records and no candidate makes fewer fail) the
    /// equation-error ranking's verdict stands.
    pub fn decides(&self) -> bool {
        self.chosen.is_some() || self.before.failed == 0
    }
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
    use rayon::prelude::*;
    // Each candidate is refitted and simulated on its own; collected in order, so the result
    // does not depend on the threads.
    names
        .par_iter()
        .map(|&name| {
            let mut notes = crate::refit::AddNotes::default();
            match crate::refit::add_one(model, name, records, catalogue, opts, &mut notes) {
                Ok(m) => {
                    let score = SimScore::of(&m, records);
                    let trial = Trial {
                        effect: name.to_string(),
                        score: Some(score),
                        error: None,
                    };
                    let made = Chosen {
                        effect: name.to_string(),
                        model: m,
                        stops: notes.stops,
                        warnings: notes.warnings,
                        score,
                    };
                    (trial, Some(made))
                }
                Err(e) => {
                    let trial = Trial {
                        effect: name.to_string(),
                        score: None,
                        error: Some(crate::one_line(&e)),
                    };
                    (trial, None)
                }
            }
        })
        .unzip()
}

/// Forward from `first` (which still leaves records failing): each step adds, to the model with
/// every effect so far, the candidate of `names` not yet in it that leaves the fewest records
/// failing, while that is fewer than before the step, records still fail and fewer than
/// [`MAX_FURTHER`] steps were taken.
fn further_steps(
    first: &Chosen,
    names: &[&str],
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Vec<Step> {
    let mut steps: Vec<Step> = Vec::new();
    let mut current = first.model.clone();
    let mut score = first.score;
    while score.failed > 0 && steps.len() < MAX_FURTHER {
        let rest: Vec<&str> = names
            .iter()
            .copied()
            .filter(|n| *n != first.effect && steps.iter().all(|s| s.effect != *n))
            .collect();
        let (tried, mut made) = try_each(&current, &rest, records, catalogue, opts);
        let scores: Vec<Option<SimScore>> = tried.iter().map(|t| t.score).collect();
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

/// When `model` fails to simulate some of `records`: every candidate of the diagnosis's
/// ranking `ranked` whose held-out equation error falls is added and simulated (module docs), and the one that
/// leaves the fewest records failing is chosen if it leaves fewer than `model` does and than
/// `model`'s terms refitted with nothing added ([`GateReport::refitted`]). With
/// `further`, when it still leaves records failing, the effects needed with it are looked for
/// (module docs; [`GateReport::then`]). `None` when `model` simulates every record (the
/// simulations then have nothing to say here).
pub fn simulation_choice(
    model: &Model,
    ranked: &[RankedEffect],
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
    further: bool,
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
    let refitted = refitted_as_is(model, records, opts)
        .ok()
        .flatten()
        // Simulated here: the refit keeps the start's history, whose last rung scored the
        // start's coefficients (what `SimScore::of` would read).
        .map(|m| crate::contact::score(&m, records).summary());
    // A candidate's model is the start's terms refitted with it: it has to leave fewer records
    // failing than that refit alone as well as the start model. Where the refit alone makes as
    // many simulate, the failures say nothing about the candidates (the equation-error
    // ranking and the judge then decide, as for a model that simulates).
    let bar = match refitted {
        Some(r) if r.failed < before.failed => r,
        _ => before,
    };
    let (tried, mut made) = try_each(model, &names, records, catalogue, opts);
    let scores: Vec<Option<SimScore>> = tried.iter().map(|t| t.score).collect();
    let best = fewest_failing(&bar, &scores).and_then(|i| made[i].take());
    let then = match &best {
        Some(b) if further => further_steps(b, &names, records, catalogue, opts),
        _ => Vec::new(),
    };
    let why = match &best {
        Some(b) => {
            let mut why = format!(
                "the model fails to simulate {}; of the {} candidates whose held-out equation error falls, adding {} leaves the fewest failing: {}",
                before.failing(),
                names.len(),
                b.effect,
                b.score.describe()
            );
            for s in &then {
                why.push_str(&format!(
                    "; then adding {} leaves the fewest: {}",
                    s.effect,
                    s.score.describe()
                ));
            }
            why
        }
        None if bar.failed < before.failed => format!(
            "the model fails to simulate {}, but its own terms refitted on these records (nothing added) leave {} failing, and none of the {} candidates whose held-out equation error falls leaves fewer: the failure is the start fit's, not a missing effect's (identify the model again on these records)",
            before.failing(),
            bar.failed,
            names.len()
        ),
        None => format!(
            "the model fails to simulate {} and none of the {} candidates whose held-out equation error falls makes fewer fail",
            before.failing(),
            names.len()
        ),
    };
    let report = GateReport {
        before,
        refitted,
        tried,
        chosen: best.as_ref().map(|b| b.effect.clone()),
        then,
        why,
    };
    Ok(Some((report, best)))
}

/// What the simulations said on a diagnosis, and the candidate they chose with its model.
pub type Simulated = (GateReport, Option<Chosen>);

/// Whether the diagnosis `d` could not simulate some of its records (then [`on_diagnosis`]
/// adds and simulates the candidates to see which makes them simulate).
pub fn fails_somewhere(d: &Diagnosis) -> bool {
    d.records.iter().any(|r| r.error.is_some())
}

/// The simulations' say on the diagnosis `d` of `model` on `records`, as `tfs diagnose` (and
/// `tfs.diagnose` in Python) gives it: when the diagnosis could not simulate some records,
/// [`simulation_choice`] with the further steps; otherwise, when the free run judged, the first
/// significant candidate whose addition does not make the records simulate worse (the one the
/// diagnosis loop would add; `None` when that is the top one or nothing is significant).
pub fn on_diagnosis(
    model: &Model,
    d: &Diagnosis,
    records: &[Record],
    opts: &DiagnoseOptions,
) -> Result<Option<Simulated>> {
    let catalogue = Catalogue::standard(opts.max_power);
    if !fails_somewhere(d) {
        return Ok(supported_choice(
            model, &d.ranked, records, &catalogue, opts,
        ));
    }
    simulation_choice(model, &d.ranked, records, &catalogue, opts, true)
}

/// [`on_diagnosis`] on a ranking alone (an [`Explanation`]'s, without the comparison that says
/// whether every record simulates: the model is simulated here to find out).
pub fn on_ranking(
    model: &Model,
    ranked: &[RankedEffect],
    records: &[Record],
    opts: &DiagnoseOptions,
) -> Result<Option<Simulated>> {
    let catalogue = Catalogue::standard(opts.max_power);
    match simulation_choice(model, ranked, records, &catalogue, opts, true)? {
        Some(s) => Ok(Some(s)),
        None => Ok(supported_choice(model, ranked, records, &catalogue, opts)),
    }
}

/// The effect the verdict names first, given the ranking and what the simulations said
/// (`gate`, from [`on_diagnosis`] or [`on_ranking`]): the simulations' choice; none when they
/// passed over every significant candidate of a model that simulates every record; else the top
/// significant candidate of the ranking.
pub fn named<'a>(ranked: &'a [RankedEffect], gate: Option<&'a Simulated>) -> Option<&'a str> {
    match gate {
        Some((_, Some(chosen))) => Some(chosen.effect.as_str()),
        Some((report, None)) if report.decides() => None,
        _ => ranked
            .iter()
            .find(|r| r.significant)
            .map(|r| r.name.as_str()),
    }
}

/// The verdict of a diagnosis `d` with what the simulations said (`gate`, from
/// [`on_diagnosis`]): the effect (or effects, in order) the simulations chose, with why and the
/// `--add` flags; that no significant candidate is supported when the simulations passed over
/// every one; else the diagnosis's own verdict by equation error.
pub fn verdict(d: &Diagnosis, gate: Option<&Simulated>) -> String {
    match gate {
        Some((report, Some(chosen))) if report.then.is_empty() => format!(
            "missing effect: {} ({}); add it with --add {}",
            chosen.effect, report.why, chosen.effect
        ),
        Some((report, Some(_))) => {
            let effects = report.effects();
            format!(
                "missing effects: {} ({}); add them with --add {}",
                effects.join(", then "),
                report.why,
                effects.join(" --add ")
            )
        }
        Some((report, None)) if report.decides() => format!(
            "no missing effect that the simulations support ({})",
            report.why
        ),
        _ => d.verdict.clone(),
    }
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
    if let Some((report, chosen)) =
        simulation_choice(model, &ex.ranked, records, catalogue, opts, false)?
    {
        if chosen.is_some() {
            return Ok((chosen, Some(report.why)));
        }
        notes.push(report.why);
    }
    let before = SimScore::of(model, records);
    let significant = ex.ranked.iter().filter(|r| r.significant);
    let supported = first_supported(model, significant, &before, records, catalogue, opts);
    notes.extend(supported.notes);
    if let Some(chosen) = supported.chosen {
        if !notes.is_empty() {
            notes.push(format!(
                "{} added, the next significant: with it {}",
                chosen.effect,
                chosen.score.describe()
            ));
        }
        return Ok((Some(chosen), (!notes.is_empty()).then(|| notes.join("; "))));
    }
    // A stop the equation error cannot resolve: T-F-S's own test of it (module docs).
    let stops = ex
        .ranked
        .iter()
        .filter(|r| r.effect == "stop" && !r.significant && r.delta_heldout > 0.0);
    for cand in stops {
        let mut added = crate::refit::AddNotes::default();
        let Ok(m) = crate::refit::add_one(model, &cand.name, records, catalogue, opts, &mut added)
        else {
            continue;
        };
        let Some(stop) = added.stops.last() else {
            continue;
        };
        let p = stop.kept.then(|| tfs_stop_p_value(&m, stop)).flatten();
        let score = SimScore::of(&m, records);
        let accepted = p.is_some_and(|p| p < opts.alpha) && score.key() < before.key();
        let tfs = match p {
            Some(p) => format!(
                "T-F-S re-identified the model with {} (stiffness {:.4e}, {} corrected over the library's terms and the {} positions scanned)",
                stop.to,
                stop.coef,
                p_text(p),
                stop.positions
            ),
            None if stop.kept => format!(
                "T-F-S re-identified the model with {} but has no term test to judge it by",
                stop.to
            ),
            None => "T-F-S's re-identification did not replace the equation-error fit".to_string(),
        };
        let words = format!(
            "{} is not significant by equation error; {tfs}; with it {}, without it {}",
            cand.name,
            score.describe(),
            before.describe()
        );
        if accepted {
            notes.push(format!("{words}: added"));
            let chosen = Chosen {
                effect: cand.name.clone(),
                model: m,
                stops: added.stops,
                warnings: added.warnings,
                score,
            };
            return Ok((Some(chosen), Some(notes.join("; "))));
        }
        notes.push(format!("{words}: not added"));
    }
    Ok((None, (!notes.is_empty()).then(|| notes.join("; "))))
}

/// What [`first_supported`] found: the candidate chosen, every candidate tried (in order) and
/// a sentence for each passed over.
struct Supported {
    chosen: Option<Chosen>,
    tried: Vec<Trial>,
    notes: Vec<String>,
}

/// The first of `candidates` (in the diagnosis's order) whose addition, as `refit --add` makes
/// it, does not make the model simulate the records worse than `before` ([`worsens`]); one that
/// does, or that cannot be added, is passed over with a sentence saying so. The diagnosis loop
/// and the diagnosis's verdict both choose this way, so `tfs diagnose` names what
/// `refit --until-clean` adds.
fn first_supported<'a>(
    model: &Model,
    candidates: impl Iterator<Item = &'a RankedEffect>,
    before: &SimScore,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Supported {
    let mut out = Supported {
        chosen: None,
        tried: Vec::new(),
        notes: Vec::new(),
    };
    for cand in candidates {
        let mut added = crate::refit::AddNotes::default();
        let m = match crate::refit::add_one(model, &cand.name, records, catalogue, opts, &mut added)
        {
            Ok(m) => m,
            Err(e) => {
                let e = crate::one_line(&e);
                out.notes.push(format!(
                    "{} passed over: it could not be added ({e})",
                    cand.name
                ));
                out.tried.push(Trial {
                    effect: cand.name.clone(),
                    score: None,
                    error: Some(e),
                });
                continue;
            }
        };
        let score = SimScore::of(&m, records);
        out.tried.push(Trial {
            effect: cand.name.clone(),
            score: Some(score),
            error: None,
        });
        if worsens(before, &score) {
            out.notes.push(format!(
                "{} passed over: with it {}, without it {}",
                cand.name,
                score.describe(),
                before.describe()
            ));
            continue;
        }
        out.chosen = Some(Chosen {
            effect: cand.name.clone(),
            model: m,
            stops: added.stops,
            warnings: added.warnings,
            score,
        });
        break;
    }
    out
}

/// The simulations' say on a ranking whose model simulates every record: when the top
/// significant candidate was judged by the free run (the free run then ranks models on these
/// records), the significant candidates are added in the ranking's order as `refit --add` makes
/// them and the first that does not make the model simulate the records worse is the one named
/// ([`first_supported`]), as the diagnosis loop chooses. `None` when the top one is that one
/// (the ranking's own verdict stands), when nothing is significant, or when the free run did not
/// judge (the input's own noise decides a free run there, so it says nothing either way).
fn supported_choice(
    model: &Model,
    ranked: &[RankedEffect],
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Option<Simulated> {
    let free_run = |r: &&RankedEffect| r.significant && r.judge == Some(Judge::FreeRun);
    let top = ranked.iter().find(|r| r.significant)?;
    if !free_run(&top) {
        return None;
    }
    let before = SimScore::of(model, records);
    if before.failed > 0 {
        return None;
    }
    let supported = first_supported(
        model,
        ranked.iter().filter(free_run),
        &before,
        records,
        catalogue,
        opts,
    );
    if supported.tried.len() == 1 && supported.chosen.is_some() {
        return None;
    }
    let why = match &supported.chosen {
        Some(c) => format!(
            "{}; {} is the next significant: with it {}",
            supported.notes.join("; "),
            c.effect,
            c.score.describe()
        ),
        None => format!(
            "{}: no significant candidate that the simulations support",
            supported.notes.join("; ")
        ),
    };
    let report = GateReport {
        before,
        refitted: None,
        tried: supported.tried,
        chosen: supported.chosen.as_ref().map(|c| c.effect.clone()),
        then: Vec::new(),
        why,
    };
    Some((report, supported.chosen))
}

/// `model`'s own terms refitted by equation error on `records` as a candidate's model is
/// refitted, with nothing added: the control every candidate of [`simulation_choice`] is
/// measured against. A candidate refits every equation of a one-DOF model or of a tied chain
/// (jointly, with its ties); in an untied multi-DOF model it refits only the equations it
/// enters, so there is no one control for all candidates and `None` is returned.
fn refitted_as_is(
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

/// Whether adding a candidate made the model simulate the records worse: more records fail,
/// or as many and the mean R-MSE of the others rises (what the error ladder warns about: the
/// records do not support it).
fn worsens(before: &SimScore, after: &SimScore) -> bool {
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
fn p_text(p: f64) -> String {
    if p < 1e-300 {
        "p < 1e-300".to_string()
    } else {
        format!("p = {p:.2e}")
    }
}

#[cfg(test)]
mod tests;
