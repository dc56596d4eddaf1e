//! The diagnosis's one decision: which effect a model is missing, given the equation-error
//! ranking of the catalogue's candidates and what the model does when simulated with each.
//!
//! `tfs diagnose`, the Python `diagnose`, `cargo xtask diagnose-bench` and every round of
//! `tfs refit --until-clean` call [`decide`], so they name the same effect. In order:
//!
//! 1. **Failures.** When the model fails to simulate some records (blows up, leaves the range, a
//!    non-finite R-MSE), every candidate whose held-out equation error falls is added (as
//!    `refit --add` adds it before refining it by simulation error, a stop re-scanned by T-F-S)
//!    and simulated; the one that leaves the
//!    fewest records failing (then the lowest geometric-mean R-MSE of the others, then the ranking's order)
//!    is chosen ([`Reason::CuresFailures`]) if it leaves fewer failing than the model and than the
//!    model's own terms refitted with nothing added (a failure the refit alone cures was the start
//!    fit's, and any candidate would seem to cure it). A failed simulation of a measured record is
//!    not a matter of degree or of noise, so it outranks the equation error. With
//!    [`DecideOptions::further`], when the chosen one still leaves records failing, the effects
//!    needed with it are looked for by forward selection ([`Decision::then`]).
//! 2. **Significant candidates.** Otherwise every contender is added and simulated: the
//!    significant candidates, and those whose test passes, whose held-out equation error falls
//!    and that reach the size but whose per-fold models could not be simulated on the held-out
//!    parts (a fit on part of the records is a weaker witness than the refit on all of them,
//!    which is what would be added). The ranking's first with which the records simulate no
//!    worse than without it is chosen ([`Reason::Supported`]), unless others make every record
//!    simulate better than it does, or fewer fail (`beats`): then the one of those with the
//!    lowest geometric-mean R-MSE. The others are passed over as simulating less well (the
//!    ranking's first, displaced: [`Reason::SimulatesLessWell`]), as not chosen (the others that
//!    hold: [`Reason::NotChosen`]), worse than the model ([`Reason::WorsensSimulation`]: more
//!    records fail, or as many and the geometric-mean R-MSE of the others rises) or as not made
//!    ([`Reason::CouldNotAdd`], [`Reason::AddsNothing`]). The held-out equation error tells that
//!    something of a kind is missing but is a poor judge between look-alikes (`x^4` and `x^7`
//!    on one well): their columns are nearly collinear on the smoothed states, and the refit of
//!    the wrong one reproduces every record far less well. Every contender is held to this,
//!    whichever judge ranked it: a candidate the ranking put first on a short-horizon score is
//!    still one the loop would add.
//! 3. **A contact the equation error cannot resolve.** When no significant candidate was chosen,
//!    a candidate that adds a one-sided contact term (`below`, `above`: recognised by its terms,
//!    not its name) whose held-out equation error falls is added with its position re-scanned by
//!    T-F-S ([`crate::contact::rescan_stop`]); it is chosen ([`Reason::StopByTfs`]) when the
//!    re-identified model replaced the equation-error fit, T-F-S's own term test of its
//!    coefficient passes at the diagnosis's level corrected over the library's terms and the
//!    positions scanned ([`crate::gate::tfs_stop_p_value`]), and the records simulate better with
//!    it. The stop's equation-error evidence is weak where the contact is stiff (the smoothing
//!    spreads its short acceleration burst), while T-F-S resolves it through the momentum it
//!    changes. The simulations must single the contact out: when another candidate whose test
//!    passes and whose error falls, short only of the size, makes the records simulate better
//!    still, the contact is not named ([`Reason::StopOutdone`]) — the simulations then say
//!    something is missing, not that it is a contact.
//! 4. Else nothing is named: [`Reason::NothingSignificant`] or [`Reason::NoneSupported`].
//!
//! Each candidate's model is made once per decision (the same candidate tried in two steps
//! reuses it), and the candidates of step 1 are made in parallel, collected in order.

use std::collections::HashMap;
use std::fmt;

use serde::Serialize;
use tfs_data::Record;
use tfs_diagnose::{Catalogue, DiagnoseOptions, RankedEffect, Significance};
use tfs_library::{Factor, Model, Term};

use crate::error::Result;
use crate::gate::{
    Chosen, MAX_FURTHER, NotMade, SimScore, Step, add_each, fewest_failing, further_steps, p_text,
    refitted_as_is, tfs_stop_p_value, worsens,
};

/// Why a candidate was chosen or passed over ([`Trial::reason`]), and why the decision named
/// what it named ([`Decision::reason`]). Printed in words; in JSON as its kebab-case name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Reason {
    /// The model fails to simulate some records and this candidate leaves the fewest failing,
    /// fewer than the model and than its own terms refitted with nothing added.
    CuresFailures,
    /// Tried because the model fails to simulate some records; another leaves fewer failing, or
    /// it leaves no fewer than the model (or its terms refitted with nothing added).
    CuresLess,
    /// A contender (significant by equation error, or its test passes and only its per-fold
    /// models could not be simulated): the ranking's first with which the records simulate no
    /// worse than without it, or one with which every record simulates better than with that.
    Supported,
    /// The ranking's first contender with which the records simulate no worse than without it,
    /// passed over for one with which every record simulates better.
    SimulatesLessWell,
    /// A contender ranked after the first supported one, with which the records simulate no
    /// worse than without it, but not named: it does not make every record simulate better
    /// than the first one does, or another that does simulates better still.
    NotChosen,
    /// Significant by equation error, but the records simulate worse with it (more fail, or as
    /// many and the geometric-mean R-MSE of the others rises): passed over.
    WorsensSimulation,
    /// Its refit could not be made: passed over.
    CouldNotAdd,
    /// No step toward its refit predicts the records better than the model without it (the
    /// refit returns the model unchanged): it adds nothing, so it is passed over.
    AddsNothing,
    /// A one-sided contact not significant by equation error that T-F-S's re-identification
    /// with its position scanned keeps, whose term test passes, and with which the records
    /// simulate better.
    StopByTfs,
    /// A one-sided contact not significant by equation error that T-F-S does not support (not
    /// kept, its term test fails or has no test, or the records simulate no better with it).
    StopNotByTfs,
    /// A one-sided contact T-F-S supports, but another candidate whose test passes (short only
    /// of the size) makes the records simulate better still: the simulations do not single out
    /// the contact, so it is not named on them.
    StopOutdone,
    /// No candidate is significant by equation error (nor a contact T-F-S supports).
    NothingSignificant,
    /// Every significant candidate was passed over (nor a contact T-F-S supports).
    NoneSupported,
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Reason::CuresFailures => "it leaves the fewest records failing to simulate",
            Reason::CuresLess => "another candidate leaves fewer records failing to simulate",
            Reason::Supported => {
                "the records simulate no worse with it, and best of the contenders"
            }
            Reason::SimulatesLessWell => {
                "every record simulates better with another candidate: passed over"
            }
            Reason::NotChosen => {
                "another candidate was named first and this one does not make every record simulate better: passed over"
            }
            Reason::WorsensSimulation => {
                "significant, but the records simulate worse with it: passed over"
            }
            Reason::CouldNotAdd => "it could not be added: passed over",
            Reason::AddsNothing => "its refit adds nothing to the model: passed over",
            Reason::StopByTfs => "a stop that T-F-S's own term test supports",
            Reason::StopNotByTfs => "a stop that T-F-S's own term test does not support",
            Reason::StopOutdone => {
                "a stop T-F-S supports, but another candidate makes the records simulate better"
            }
            Reason::NothingSignificant => "no candidate is significant",
            Reason::NoneSupported => {
                "every significant candidate was passed over by the simulations"
            }
        })
    }
}

/// One candidate added and simulated, and what the decision made of it.
#[derive(Debug, Clone, Serialize)]
pub struct Trial {
    /// The effect (`name@dof`).
    pub effect: String,
    /// How the model with it simulates the records (`None`: it could not be added).
    pub score: Option<SimScore>,
    /// Why it could not be added.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Why it was chosen or passed over.
    pub reason: Reason,
}

/// How far a decision looks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DecideOptions {
    /// When the candidate chosen for failing records still leaves some failing, how many more
    /// effects to look for after it ([`Decision::then`]). It does not change the first effect.
    pub further: usize,
}

impl DecideOptions {
    /// As `tfs diagnose` decides: the effects the records need together, up to
    /// [`MAX_FURTHER`] after the first.
    pub fn diagnose() -> Self {
        Self {
            further: MAX_FURTHER,
        }
    }

    /// As one round of `refit --until-clean` decides: the first effect only (the loop
    /// re-diagnoses after adding it).
    pub fn loop_round() -> Self {
        Self { further: 0 }
    }
}

/// The decision: the effect named (if any), with its model, every candidate tried and why.
#[derive(Debug, Clone, Serialize)]
pub struct Decision {
    /// How the model without any candidate simulates the records.
    pub before: SimScore,
    /// How the model's own terms, refitted on the records as every candidate's model is
    /// (nothing added), simulate them; looked at only when the model fails some records (and
    /// not for an untied multi-DOF model, whose candidates refit only their own equations).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refitted: Option<SimScore>,
    /// Every candidate tried, in the order tried.
    pub tried: Vec<Trial>,
    /// The effect named (`name@dof`; `None`: none is).
    pub chosen: Option<String>,
    /// When the chosen one still leaves records failing: the effects that, added after it in
    /// this order, each leave fewer failing (empty when none is needed, none helps or
    /// [`DecideOptions::further`] is 0).
    pub then: Vec<Step>,
    /// Why the decision named what it named.
    pub reason: Reason,
    /// Whether the decision names what the equation-error ranking names on its own: its top
    /// significant candidate, or nothing when none is significant.
    pub ranking_stands: bool,
    /// What was tried and why, in sentences.
    pub why: String,
    /// The chosen effect with the model that has it.
    #[serde(skip)]
    pub added: Option<Chosen>,
}

impl Decision {
    /// The effects named, in the order they are added: the chosen one, then [`Decision::then`].
    pub fn effects(&self) -> Vec<&str> {
        self.chosen
            .iter()
            .map(String::as_str)
            .chain(self.then.iter().map(|s| s.effect.as_str()))
            .collect()
    }

    /// The verdict in a sentence: the ranking's own (`ranking_verdict`) where the decision
    /// names what it names; else the effect (or effects, in order) chosen, with why and the
    /// `--add` flags; else that the simulations support no significant candidate.
    pub fn verdict(&self, ranking_verdict: &str) -> String {
        if self.ranking_stands {
            return ranking_verdict.to_string();
        }
        match &self.chosen {
            Some(c) if self.then.is_empty() => {
                format!("missing effect: {c} ({}); add it with --add {c}", self.why)
            }
            Some(_) => {
                let effects = self.effects();
                format!(
                    "missing effects: {} ({}); add them with --add {}",
                    effects.join(", then "),
                    self.why,
                    effects.join(" --add ")
                )
            }
            None => format!(
                "no missing effect that the simulations support ({})",
                self.why
            ),
        }
    }
}

/// Each candidate's model, made once per decision.
struct Made<'a> {
    model: &'a Model,
    records: &'a [Record],
    catalogue: &'a Catalogue,
    opts: &'a DiagnoseOptions,
    made: HashMap<String, std::result::Result<Chosen, NotMade>>,
}

impl Made<'_> {
    /// Makes the models of `names` not made yet, in parallel.
    fn make(&mut self, names: &[&str]) {
        let todo: Vec<&str> = names
            .iter()
            .copied()
            .filter(|n| !self.made.contains_key(*n))
            .collect();
        let out = add_each(self.model, &todo, self.records, self.catalogue, self.opts);
        for (n, m) in todo.into_iter().zip(out) {
            self.made.insert(n.to_string(), m);
        }
    }

    /// The model with `name` added, or why it could not be made.
    fn get(&mut self, name: &str) -> &std::result::Result<Chosen, NotMade> {
        self.make(&[name]);
        &self.made[name]
    }

    /// What [`Trial`] records of `name`'s model.
    fn trial(&mut self, name: &str, reason: Reason) -> Trial {
        let (score, error) = match self.get(name) {
            Ok(c) => (Some(c.score), None),
            Err(e) => (None, Some(e.to_string())),
        };
        Trial {
            effect: name.to_string(),
            score,
            error,
            reason,
        }
    }

    /// `name`'s model, taken out of the store (made again if asked for later).
    fn take(&mut self, name: &str) -> Option<Chosen> {
        self.make(&[name]);
        self.made.remove(name).and_then(|m| m.ok())
    }
}

/// The reason of a candidate whose model was not made: it adds nothing, or could not be added.
fn not_made_reason(m: &std::result::Result<Chosen, NotMade>) -> Reason {
    match m {
        Err(NotMade::AddsNothing) => Reason::AddsNothing,
        _ => Reason::CouldNotAdd,
    }
}

/// Whether candidate `r` adds a one-sided contact term (`below`, `above`) to a model with DOFs
/// `dofs`.
fn adds_contact(r: &RankedEffect, dofs: &[String]) -> bool {
    r.terms.iter().any(|t| {
        Term::parse(t, dofs).is_ok_and(|t| {
            t.factors()
                .iter()
                .any(|f| matches!(f, Factor::Below(..) | Factor::Above(..)))
        })
    })
}

/// The decision on `model`, whose candidates on `records` the diagnosis ranked as `ranked`
/// (module docs). `opts` are the diagnosis's options (the catalogue's powers, the level of the
/// T-F-S stop test); `how` says how far to look after the first effect.
pub fn decide(
    model: &Model,
    ranked: &[RankedEffect],
    records: &[Record],
    opts: &DiagnoseOptions,
    how: &DecideOptions,
) -> Result<Decision> {
    let catalogue = Catalogue::standard(opts.max_power);
    let mut made = Made {
        model,
        records,
        catalogue: &catalogue,
        opts,
        made: HashMap::new(),
    };
    let before = SimScore::of(model, records);
    let mut out = Decision {
        before,
        refitted: None,
        tried: Vec::new(),
        chosen: None,
        then: Vec::new(),
        reason: Reason::NothingSignificant,
        ranking_stands: false,
        why: String::new(),
        added: None,
    };
    let mut notes: Vec<String> = Vec::new();
    if before.failed > 0 {
        if let Some(chosen) = for_failures(&mut made, ranked, &mut out, &mut notes, how)? {
            out.chosen = Some(chosen.effect.clone());
            out.reason = Reason::CuresFailures;
            out.why = notes.join("; ");
            out.added = Some(chosen);
            return Ok(out);
        }
    }
    let top = ranked.iter().find(|r| r.significant).map(|r| &r.name);
    if let Some(chosen) = best_supported(&mut made, ranked, &before, &mut out, &mut notes) {
        out.ranking_stands = Some(&chosen.effect) == top;
        let contenders = ranked.iter().filter(|r| contends(r, &before)).count();
        notes.push(format!(
            "{} is named {}: with it {}, without it {}",
            chosen.effect,
            if contenders == 1 {
                "as the one contender".to_string()
            } else {
                format!("of the {contenders} contenders")
            },
            chosen.score.describe(),
            before.describe()
        ));
        out.chosen = Some(chosen.effect.clone());
        out.reason = Reason::Supported;
        out.why = notes.join("; ");
        out.added = Some(chosen);
        return Ok(out);
    }
    if let Some(chosen) = contact_by_tfs(&mut made, ranked, &before, &mut out, &mut notes) {
        out.chosen = Some(chosen.effect.clone());
        out.reason = Reason::StopByTfs;
        out.why = notes.join("; ");
        out.added = Some(chosen);
        return Ok(out);
    }
    out.reason = if top.is_some() {
        Reason::NoneSupported
    } else {
        Reason::NothingSignificant
    };
    out.ranking_stands = top.is_none();
    if top.is_some() {
        notes.push("no significant candidate that the simulations support".into());
    }
    out.why = notes.join("; ");
    Ok(out)
}

/// Step 1 (module docs): the candidate that leaves the fewest records failing, if it leaves
/// fewer than the model and its own terms refitted; the effects needed after it with
/// `how.further`. Records the tries in `out` and a sentence in `notes` either way.
fn for_failures(
    made: &mut Made<'_>,
    ranked: &[RankedEffect],
    out: &mut Decision,
    notes: &mut Vec<String>,
    how: &DecideOptions,
) -> Result<Option<Chosen>> {
    let before = out.before;
    let names: Vec<&str> = ranked
        .iter()
        .filter(|r| r.delta_heldout > 0.0)
        .map(|r| r.name.as_str())
        .collect();
    out.refitted = refitted_as_is(made.model, made.records, made.opts)
        .ok()
        .flatten()
        // Simulated here: the refit keeps the start's history, whose last rung scored the
        // start's coefficients (what `SimScore::of` would read).
        .map(|m| crate::contact::score(&m, made.records).summary());
    // Where the refit alone makes as many simulate, the failures say nothing about the
    // candidates: a candidate must leave fewer failing than that refit too.
    let bar = match out.refitted {
        Some(r) if r.failed < before.failed => r,
        _ => before,
    };
    made.make(&names);
    let scores: Vec<Option<SimScore>> = names
        .iter()
        .map(|n| made.get(n).as_ref().ok().map(|c| c.score))
        .collect();
    let best = fewest_failing(&bar, &scores);
    for (i, n) in names.iter().enumerate() {
        let reason = match (Some(i) == best, &scores[i]) {
            (true, _) => Reason::CuresFailures,
            (false, None) => not_made_reason(made.get(n)),
            (false, Some(_)) => Reason::CuresLess,
        };
        let trial = made.trial(n, reason);
        out.tried.push(trial);
    }
    let Some(i) = best else {
        notes.push(if bar.failed < before.failed {
            format!(
                "the model fails to simulate {}, but its own terms refitted on these records (nothing added) leave {} failing, and none of the {} candidates whose held-out equation error falls leaves fewer: the failure is the start fit's, not a missing effect's (identify the model again on these records)",
                before.failing(),
                bar.failed,
                names.len()
            )
        } else {
            format!(
                "the model fails to simulate {} and none of the {} candidates whose held-out equation error falls makes fewer fail",
                before.failing(),
                names.len()
            )
        });
        return Ok(None);
    };
    let Some(chosen) = made.take(names[i]) else {
        return Ok(None);
    };
    let mut why = format!(
        "the model fails to simulate {}; of the {} candidates whose held-out equation error falls, adding {} leaves the fewest failing: {}",
        before.failing(),
        names.len(),
        chosen.effect,
        chosen.score.describe()
    );
    if how.further > 0 {
        out.then = further_steps(
            &chosen,
            &names,
            made.records,
            made.catalogue,
            made.opts,
            how.further,
        );
    }
    for s in &out.then {
        why.push_str(&format!(
            "; then adding {} leaves the fewest: {}",
            s.effect,
            s.score.describe()
        ));
    }
    notes.push(why);
    Ok(Some(chosen))
}

/// Step 2 (module docs): the first contender in the ranking's order with which the records
/// simulate no worse than `before`, unless others make every record simulate better than it
/// does (`beats`): then the best of those. Each passed over is recorded with a sentence.
fn best_supported(
    made: &mut Made<'_>,
    ranked: &[RankedEffect],
    before: &SimScore,
    out: &mut Decision,
    notes: &mut Vec<String>,
) -> Option<Chosen> {
    let names: Vec<&str> = ranked
        .iter()
        .filter(|r| contends(r, before))
        .map(|r| r.name.as_str())
        .collect();
    made.make(&names);
    let made_ok: Vec<Option<(SimScore, Vec<Option<f64>>)>> = names
        .iter()
        .map(|n| made.get(n).as_ref().ok().map(|c| (c.score, c.each.clone())))
        .collect();
    let holds = |i: usize| {
        made_ok[i]
            .as_ref()
            .is_some_and(|(s, _)| !worsens(before, s))
    };
    let first = (0..names.len()).find(|&i| holds(i));
    let best = first.map(|a| {
        let mut best = a;
        for i in (0..names.len()).filter(|&i| i != a && holds(i)) {
            let (Some(c), Some(f), Some(b)) = (&made_ok[i], &made_ok[a], &made_ok[best]) else {
                continue;
            };
            if beats(c, f) && c.0.key() < b.0.key() {
                best = i;
            }
        }
        best
    });
    for (i, n) in names.iter().enumerate() {
        // `best` is `Some` whenever any contender holds, so every contender that holds is
        // named, displaced (the ranking's first, when another beats it) or not chosen.
        let reason = match &made_ok[i] {
            None => {
                match made.get(n) {
                    Err(e @ NotMade::AddsNothing) => notes.push(format!("{n} passed over: {e}")),
                    Err(e) => notes.push(format!("{n} passed over: it could not be added ({e})")),
                    Ok(_) => {}
                }
                not_made_reason(made.get(n))
            }
            Some((s, _)) if worsens(before, s) => {
                notes.push(format!(
                    "{n} passed over: with it {}, without it {}",
                    s.describe(),
                    before.describe()
                ));
                Reason::WorsensSimulation
            }
            Some(_) if Some(i) == best => Reason::Supported,
            Some((s, _)) if Some(i) == first => {
                // The ranking's own choice, displaced by `best`, which beats it.
                if let Some(b) = best {
                    notes.push(format!(
                        "{n} passed over: with it {}, and every record simulates better with {}",
                        s.describe(),
                        names[b]
                    ));
                }
                Reason::SimulatesLessWell
            }
            Some(_) => Reason::NotChosen,
        };
        let trial = made.trial(n, reason);
        out.tried.push(trial);
    }
    made.take(names[best?])
}

/// Whether the records simulate better with `c` than with `f` beyond doubt: fewer fail, or the
/// same ones fail and every other has a lower R-MSE. The geometric mean alone is not enough: on
/// a multi-stable structure one record whose run settles in another well moves it by orders of
/// magnitude either way, while the records that agree are what the missing effect explains.
fn beats(c: &(SimScore, Vec<Option<f64>>), f: &(SimScore, Vec<Option<f64>>)) -> bool {
    if c.0.failed != f.0.failed {
        return c.0.failed < f.0.failed;
    }
    c.1.len() == f.1.len()
        && c.1.iter().zip(&f.1).all(|(a, b)| match (a, b) {
            (Some(a), Some(b)) => a < b,
            (None, None) => true,
            _ => false,
        })
}

/// Whether candidate `r` contends in step 2: significant, or its test passes, its held-out
/// equation error falls and it reaches the size, but its per-fold models (refitted on part of
/// the records) could not be simulated on the rest, while the model itself simulates every
/// record (`before`): whether the refit on all of them simulates is the decision's own
/// question. When the model itself fails some records, every candidate's per-fold models are
/// expected to fail too, and that says nothing for the candidate.
fn contends(r: &RankedEffect, before: &SimScore) -> bool {
    r.significant || (r.significance == Significance::CannotBeSimulated && before.failed == 0)
}

/// Step 3 (module docs): a one-sided contact the equation error does not make significant,
/// chosen on T-F-S's evidence; each looked at is recorded with a sentence.
fn contact_by_tfs(
    made: &mut Made<'_>,
    ranked: &[RankedEffect],
    before: &SimScore,
    out: &mut Decision,
    notes: &mut Vec<String>,
) -> Option<Chosen> {
    let dofs = made.model.dofs.clone();
    let alpha = made.opts.alpha;
    let contacts: Vec<&RankedEffect> = ranked
        .iter()
        .filter(|r| !r.significant && r.delta_heldout > 0.0 && adds_contact(r, &dofs))
        .collect();
    // The other candidates whose test passes and whose error falls, short only of the size:
    // the same simulations must not support one of them better than the contact.
    let rivals: Vec<&str> = ranked
        .iter()
        .filter(|r| r.significance == Significance::TooSmall && !adds_contact(r, &dofs))
        .map(|r| r.name.as_str())
        .collect();
    for cand in contacts {
        let looked = made.get(&cand.name).as_ref().ok().and_then(|m| {
            let stop = m.stops.last()?;
            let p = stop
                .kept
                .then(|| tfs_stop_p_value(&m.model, stop))
                .flatten();
            Some((m.score, stop.clone(), p))
        });
        let Some((score, stop, p)) = looked else {
            continue;
        };
        let supported = p.is_some_and(|p| p < alpha) && score.key() < before.key();
        let outdone = if supported {
            outdone_by(made, &rivals, &score)
        } else {
            None
        };
        let accepted = supported && outdone.is_none();
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
        let reason = match (accepted, &outdone) {
            (true, _) => Reason::StopByTfs,
            (false, Some(_)) => Reason::StopOutdone,
            (false, None) => Reason::StopNotByTfs,
        };
        let trial = made.trial(&cand.name, reason);
        out.tried.push(trial);
        if accepted {
            notes.push(format!("{words}: added"));
            return made.take(&cand.name);
        }
        match outdone {
            Some((rival, s)) => notes.push(format!(
                "{words}, but with {rival} (its test passes too, short only of the size) {}: the simulations do not single out the contact, not added",
                s.describe()
            )),
            None => notes.push(format!("{words}: not added")),
        }
    }
    None
}

/// The rival (test passed, error falls, short only of the size) with which the records
/// simulate best, if better than `score`, the contact's (ties go to the contact).
fn outdone_by(
    made: &mut Made<'_>,
    rivals: &[&str],
    score: &SimScore,
) -> Option<(String, SimScore)> {
    made.make(rivals);
    let mut best: Option<(String, SimScore)> = None;
    for r in rivals {
        let Ok(m) = made.get(r) else { continue };
        let s = m.score;
        if s.key() < score.key() && best.as_ref().is_none_or(|(_, b)| s.key() < b.key()) {
            best = Some((r.to_string(), s));
        }
    }
    best
}

#[cfg(test)]
mod tests;
