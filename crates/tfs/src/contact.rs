//! A stop's position and stiffness found by the model's own method.
//!
//! The diagnosis loop scores a stop `k·below(x, c)` (or `above`) by time-domain equation error on
//! smoothed states. A stiff contact lasts a few samples: the smoothing spreads its acceleration
//! spike over the smoothing window, and a soft stop placed inside the data's range fits the spread
//! spike better than the true one (on the Kresling truss cell, c = 0.0104 and k = 386 where the
//! contact is at 0 with k = 11,072, and the cell's polynomial force moves further from the truth
//! than before the stop). The weak form of T-F-S integrates the equation against smooth test
//! functions, so the contact enters through the momentum it changes, not through a smoothed
//! spike. After a stop is added to a T-F-S model, [`rescan_stop`] re-identifies the model by
//! T-F-S with its libraries plus the stop at each position on a grid from the data's extreme
//! inwards, shortlists the positions whose held-out residual (Criterion 4's σ on the held-out
//! record) is lowest, takes the one among them that simulates the records best, and keeps that
//! model only if it simulates them better than the equation-error fit.
//!
//! In a chain (DOFs `x1..xN`, cell `i` between `x(i-1)` and `xi`) a cell's stop acts on the
//! cell's own height: `x1` for cell 1, `(xi-x(i-1))` for cell `i`. The loop may put the stop of
//! `stop@xi` on the absolute `xi` (on smoothed states a contact of the cell is as visible there
//! as anywhere, that is, hardly); the re-scan moves it to the cell's height, puts it in the
//! equations of both DOFs the cell connects (the force on `x(i-1)` is the reaction) and, for a
//! tied chain, fits it tied like every other term of the cell.

use serde_json::json;
use tfs_criteria::{
    IdentifySpec, MassChoice, PreparedRecords, RecordBlocks, TieOptions, identify_tfs,
    identify_tfs_tied,
};
use tfs_data::Record;
use tfs_library::{Coord, Factor, HistoryEntry, Model, RecordScore, Term, Var};

use crate::error::Result;
use crate::gate::SimScore;
use tfs_diagnose::effects::stop_pushes_out;

/// Positions of the first, coarse pass; a second pass of the same size refines around the best.
const GRID: usize = 25;
/// Positions of lowest held-out residual that are simulated to choose among them.
const SHORTLIST: usize = 5;
/// How far in from the data's extreme a stop is scanned at least, as a share of the coordinate's
/// span: the deepest position the loop's stop effect offers.
const REACH_SHARE: f64 = 0.2;

/// The history step (ladder rung) of a model re-identified with its stop re-scanned.
pub const RESCAN_STEP: &str = "stop by T-F-S";

/// What [`rescan_stop`] did, in words for the ladder and the report (`--json`: `stops`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StopRescan {
    /// The stop term the loop added (equation-error fit).
    pub from: String,
    /// The stop term of the re-identified model.
    pub to: String,
    /// Its coefficient (the contact stiffness per unit mass, with its sign).
    pub coef: f64,
    /// Whether the re-identified model replaced the equation-error fit.
    pub kept: bool,
    /// How many positions T-F-S was fitted at (the scan's multiplicity).
    pub positions: usize,
    /// Why, in a sentence.
    pub why: String,
}

/// Half the depth of the scan of a stop's position in from the data's `extreme` (the scan runs
/// from the extreme to twice this in), for the loop's choice `c0` on a coordinate of span
/// `span` (`same_coordinate`: the re-scan keeps the loop's coordinate). At least as deep in as
/// the loop's stop effect looks ([`REACH_SHARE`] of the span), and as far past the loop's choice
/// on its coordinate: the equation error's choice of position is what the re-scan is there to
/// correct (module docs), so it does not bound the scan (a choice near the extreme would
/// otherwise confine the scan to a sliver by the extreme).
fn scan_reach(c0: f64, extreme: f64, span: f64, same_coordinate: bool) -> f64 {
    let depth = 0.5 * REACH_SHARE * span;
    if same_coordinate {
        (c0 - extreme).abs().max(depth)
    } else {
        depth
    }
}

/// The one-factor stop term (`below(q, c)` or `above(q, c)`) that `after` has and `before`
/// lacks, with the index of the equation it was added to: DOF `dof`'s when it names one (the
/// effect was asked for there, `stop@x2`; the loop also puts a stop on a coupling into the
/// partner's equation), else the first that has one.
fn added_stop(before: &Model, after: &Model, dof: Option<&str>) -> Option<(usize, Term)> {
    let new_stop = |i: usize| {
        let eq = after.equations.iter().find(|e| e.dof == after.dofs[i])?;
        let old: Vec<&Term> = before
            .equations
            .iter()
            .find(|e| e.dof == eq.dof)
            .map(|e| e.terms.iter().map(|t| &t.term).collect())
            .unwrap_or_default();
        eq.terms
            .iter()
            .map(|t| &t.term)
            .filter(|t| !old.contains(t))
            .find(|t| matches!(t.factors(), [Factor::Below(..)] | [Factor::Above(..)]))
            .map(|t| (i, t.clone()))
    };
    let named = dof.and_then(|d| after.dofs.iter().position(|x| x == d));
    match named {
        Some(i) => new_stop(i),
        None => (0..after.dofs.len()).find_map(new_stop),
    }
}

/// Where the re-scanned stop goes: the coordinate it acts on, the DOF whose equation owns it and
/// the DOF that feels its reaction (the lower DOF of a chain cell's relative height).
#[derive(Debug, Clone, PartialEq)]
struct Placement {
    var: Var,
    owner: usize,
    partner: Option<usize>,
    below: bool,
}

/// A chain cell's own height: `x1` for the first DOF, `(xk-x(k-1))` for DOF `k`.
fn cell_height(dofs: &[String], k: usize) -> Var {
    if k == 0 {
        Var::Disp(dofs[0].clone())
    } else {
        Var::RelDisp(dofs[k].clone(), Coord::Dof(dofs[k - 1].clone()))
    }
}

/// The placement of a stop the loop put on `var` in DOF `eq`'s equation. A model of several
/// DOFs is read as a chain when its libraries name the relative heights `(xk-x(k-1))` of
/// neighbouring DOFs: a stop added to DOF `k`'s equation (`stop@xk`) is then cell `k`'s stop, on
/// the cell's height, owned by DOF `k` with DOF `k-1` feeling the reaction, whichever coordinate
/// of the equation the loop put it on. Otherwise the stop stays on the loop's coordinate in the
/// loop's equation.
fn placement(
    dofs: &[String],
    libraries: &[Vec<String>],
    var: &Var,
    eq: usize,
    below: bool,
) -> Placement {
    let is_chain = dofs.len() > 1
        && (1..dofs.len()).all(|k| {
            let h = cell_height(dofs, k);
            libraries
                .iter()
                .flatten()
                .any(|t| Term::parse(t, dofs).is_ok_and(|t| t.vars().contains(&&h)))
        });
    if is_chain {
        Placement {
            var: cell_height(dofs, eq),
            owner: eq,
            partner: eq.checked_sub(1),
            below,
        }
    } else {
        Placement {
            var: var.clone(),
            owner: eq,
            partner: None,
            below,
        }
    }
}

impl Placement {
    /// The stop at position `c`.
    fn term(&self, c: f64) -> Term {
        let f = if self.below {
            Factor::Below(self.var.clone(), c)
        } else {
            Factor::Above(self.var.clone(), c)
        };
        Term::new(vec![f])
    }
}

/// A model's free-run R-MSE on the records: how many records fail to simulate, the mean and the
/// geometric-mean R-MSE over the others, and the score of each.
#[derive(Debug, Clone)]
pub(crate) struct Scores {
    /// Each failed record with why (`record: error`).
    failed: Vec<String>,
    mean: f64,
    geo: f64,
    pub(crate) each: Vec<RecordScore>,
}

impl Scores {
    /// Fewer failed records first, then the lower geometric mean ([`SimScore`]'s order).
    fn better_than(&self, other: &Scores) -> bool {
        self.summary().key() < other.summary().key()
    }

    /// The counts and the mean, without the per-record detail.
    pub(crate) fn summary(&self) -> SimScore {
        SimScore {
            failed: self.failed.len(),
            records: self.failed.len() + self.each.len(),
            mean_r_mse: self.mean,
            geo_mean_r_mse: self.geo,
        }
    }

    fn describe(&self, n: usize) -> String {
        match self.failed.len() {
            0 => format!("{:.4e}", self.geo),
            f if f == n => format!("a failed simulation on all {n} records"),
            f => format!("{:.4e} with {f} of {n} records failing", self.geo),
        }
    }
}

/// Free-run R-MSE of `model` on each record (records that cannot be simulated counted apart),
/// the records side by side.
pub(crate) fn score(model: &Model, records: &[Record]) -> Scores {
    use rayon::prelude::*;
    let runs: Vec<_> = records
        .par_iter()
        .with_max_len(1)
        .map(|r| tfs_diagnose::r_mse(model, r).map_err(|e| e.to_string()))
        .collect();
    let mut each = Vec::with_capacity(records.len());
    let mut failed = Vec::new();
    for (r, run) in records.iter().zip(runs) {
        match run {
            Ok(v) if v.is_finite() => each.push(RecordScore {
                record: r.source().to_string(),
                r_mse: v,
            }),
            Ok(v) => failed.push(format!("{}: R-MSE {v}", r.source())),
            Err(e) => failed.push(format!("{}: {e}", r.source())),
        }
    }
    let mean = if each.is_empty() {
        f64::INFINITY
    } else {
        each.iter().map(|s| s.r_mse).sum::<f64>() / each.len() as f64
    };
    let geo = tfs_diagnose::geometric_mean_r_mse(&each.iter().map(|s| s.r_mse).collect::<Vec<_>>());
    Scores {
        failed,
        mean,
        geo,
        each,
    }
}

/// How the model is re-identified: the DOFs, each DOF's library (without the stop), the tie
/// options of a tied chain, and the records prepared once for every position (untied: the
/// blocks, reconstructions and noise draws do not depend on the library).
struct Refit<'a> {
    dofs: Vec<&'a str>,
    libraries: Vec<Vec<String>>,
    tie: Option<TieOptions>,
    prepared: Option<PreparedRecords<'a>>,
}

impl Refit<'_> {
    /// One T-F-S fit with the stop at `c`: the model and the owner's held-out σ, `None` when the
    /// fit fails, drops the stop from the owner's equation, or gives it a coefficient that pulls
    /// the coordinate into the contact instead of pushing it out.
    fn at(&self, place: &Placement, c: f64, records: &[Record]) -> Option<(f64, Model)> {
        let term = place.term(c);
        let libs: Vec<String> = self
            .libraries
            .iter()
            .enumerate()
            .map(|(d, lib)| {
                let mut lib = lib.clone();
                if d == place.owner || Some(d) == place.partner {
                    lib.push(term.to_string());
                }
                lib.join(", ")
            })
            .collect();
        let mut spec = IdentifySpec::new(&self.dofs, &libs[0]);
        spec.dof_libraries = libs;
        let id = match (&self.tie, &self.prepared) {
            (Some(tie), _) => identify_tfs_tied(records, &spec, tie).ok()?,
            (None, Some(prepared)) => prepared.identify_tfs(&spec).ok()?,
            (None, None) => identify_tfs(records, &spec).ok()?,
        };
        // A stop pushes its coordinate back out of the contact (the one rule every fit of a
        // stop keeps).
        let owner = &self.dofs[place.owner];
        let keeps = id.model.equations[place.owner]
            .terms
            .iter()
            .any(|t| t.term == term && stop_pushes_out(&term, owner, t.coef).unwrap_or(true));
        let sigma = id.trace.dofs.get(place.owner)?.assembly.last()?.sigma;
        (keeps && sigma.is_finite()).then(|| (sigma, id.model_with_trace()))
    }
}

/// Each DOF's library as the model's trace gives it (the library offered,
/// [`Model::offered_library`], not the elimination's reduced one: the re-identification with
/// the stop decides afresh which terms the data support), with the equation's own terms of
/// `before` (a term added by the loop); `None` when the trace has no library for some DOF.
fn libraries(before: &Model) -> Option<Vec<Vec<String>>> {
    before
        .dofs
        .iter()
        .map(|dof| {
            let mut lib = before.offered_library(dof)?;
            if lib.is_empty() {
                return None;
            }
            let eq = before.equations.iter().find(|e| &e.dof == dof)?;
            for t in &eq.terms {
                let s = t.term.to_string();
                if !lib.contains(&s) {
                    lib.push(s);
                }
            }
            Some(lib)
        })
        .collect()
}

/// Re-identifies a T-F-S model to which the loop has just added a stop (`after`, refitted from
/// `before` by equation error) with the stop's position scanned by the model's own method (module
/// docs; a chain cell's stop on the cell's height, tied in a tied chain). `dof` is the DOF the
/// stop was asked for (`stop@x2`), `None` when the effect named none. Returns `None` when it
/// does not apply (another method, no stop added, no library in the trace); otherwise the model
/// to use and what was done.
pub fn rescan_stop(
    before: &Model,
    after: &Model,
    dof: Option<&str>,
    records: &[Record],
) -> Result<Option<(Model, StopRescan)>> {
    let tied = crate::chain::is_tied(before);
    let tfs = matches!(after.method.as_str(), "tfs-sindy" | "tfs-sindy-tied");
    if !tfs || records.is_empty() || before.dofs.len() != before.equations.len() {
        return Ok(None);
    }
    let Some((eq, stop)) = added_stop(before, after, dof) else {
        return Ok(None);
    };
    let Some(libraries) = libraries(before) else {
        return Ok(None);
    };
    let (Factor::Below(v0, c0) | Factor::Above(v0, c0)) = &stop.factors()[0] else {
        return Ok(None);
    };
    let below = matches!(stop.factors()[0], Factor::Below(..));
    let place = placement(&before.dofs, &libraries, v0, eq, below);
    let Some(grid) = Grid::over(&place, records, below, *c0, v0) else {
        return Ok(None);
    };
    let dofs: Vec<&str> = before.dofs.iter().map(String::as_str).collect();
    // Prepared once for the whole scan (untied); where that fails, each position's fit is left
    // to fail on its own, as it would.
    let blocks = (!tied).then(|| RecordBlocks::new(records).ok()).flatten();
    let prepared = blocks.as_ref().and_then(|b| {
        let mut spec = IdentifySpec::new(&dofs, &libraries[0].join(", "));
        spec.dof_libraries = libraries.iter().map(|l| l.join(", ")).collect();
        b.prepare(&spec).ok()
    });
    let refit = Refit {
        dofs,
        libraries,
        tie: tied.then(|| TieOptions::new(MassChoice::Given(crate::chain::fit_masses(before)))),
        prepared,
    };
    let (scored, tried) = grid.scan(&refit, &place, records);
    if scored.is_empty() {
        let why = format!(
            "T-F-S kept no stop {}({}, c) pushing out of the contact at any position c from the data's extreme ({:.4}) to {:.4} in from it; the equation-error fit stays",
            if below { "below" } else { "above" },
            place.var,
            grid.extreme,
            2.0 * grid.reach
        );
        let report = StopRescan {
            from: stop.to_string(),
            to: stop.to_string(),
            coef: f64::NAN,
            kept: false,
            positions: grid.coarse().len(),
            why,
        };
        return Ok(Some((after.clone(), report)));
    }
    let Some(chosen) = simulate_shortlist(scored, after, records) else {
        return Ok(None);
    };
    let report = chosen.report(&place, &stop, &grid, (tried, tied), records.len());
    if !report.kept {
        return Ok(Some((after.clone(), report)));
    }
    // The re-identified model keeps the loop's history, with one more rung.
    let Chosen {
        mut model, ours, ..
    } = chosen;
    let term = place.term(chosen.c);
    model.history = after.history.clone();
    let failed = ours.failed.clone();
    model.history.push(HistoryEntry {
        step: RESCAN_STEP.into(),
        added: vec![term.to_string()],
        r_mse: ours.each,
        details: json!({"equations": model.equation_string(), "from": stop.to_string(), "why": report.why, "failed": failed}),
    });
    Ok(Some((model, report)))
}

/// The positions a stop is scanned at: from the data's extreme of its coordinate (`extreme`)
/// inwards to twice `reach`, rounded to a decimal place about 1e-4 of the data's span so the
/// term's name is exact.
struct Grid {
    extreme: f64,
    reach: f64,
    /// Toward the data: +1 for a stop below, −1 above.
    dir: f64,
    /// Decimal places of a position.
    places: usize,
}

impl Grid {
    /// The grid over the data's range of the stop's coordinate (`place.var`) over every record
    /// (the stop's side of it is where a contact holds); `None` when a record lacks the
    /// coordinate or the range gives no reach.
    fn over(place: &Placement, records: &[Record], below: bool, c0: f64, v0: &Var) -> Option<Self> {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for r in records {
            let height = Term::new(vec![Factor::Pow(place.var.clone(), 1)]);
            let col = tfs_library::evaluate_term(&height, r).ok()?;
            for &x in &col {
                lo = lo.min(x);
                hi = hi.max(x);
            }
        }
        let extreme = if below { lo } else { hi };
        let span = hi - lo;
        let reach = scan_reach(c0, extreme, span, place.var == *v0);
        if !(span > 0.0 && reach > 0.0 && reach.is_finite()) {
            return None;
        }
        Some(Self {
            extreme,
            reach,
            dir: if below { 1.0 } else { -1.0 },
            places: (-(span * 1e-4).log10().floor()).clamp(0.0, 12.0) as usize,
        })
    }

    /// `c` rounded to the grid's decimal places.
    fn round(&self, c: f64) -> f64 {
        let places = self.places;
        let r: f64 = format!("{c:.places$}").parse().unwrap_or(c);
        r + 0.0
    }

    /// The coarse pass's step.
    fn step(&self) -> f64 {
        2.0 * self.reach / (GRID - 1) as f64
    }

    /// The coarse pass: `GRID` positions from the extreme inwards.
    fn coarse(&self) -> Vec<f64> {
        let step = self.step();
        (0..GRID)
            .map(|i| self.round(self.extreme + self.dir * step * i as f64))
            .collect()
    }

    /// T-F-S fitted with the stop at every position of the coarse pass, then of two finer
    /// passes, each over one step either side of the best so far: the second brings the step to
    /// about 1/300 of the coarse one, near the positions' rounding, so a stiff contact is placed
    /// as closely as a scan from the loop's own choice placed it. Returns each kept position
    /// with its σ and model, and how many positions were fitted.
    fn scan(
        &self,
        refit: &Refit<'_>,
        place: &Placement,
        records: &[Record],
    ) -> (Vec<(f64, f64, Model)>, usize) {
        let fit = |cs: &[f64]| -> Vec<(f64, f64, Model)> {
            use rayon::prelude::*;
            cs.par_iter()
                .filter_map(|&c| refit.at(place, c, records).map(|(s, m)| (c, s, m)))
                .collect()
        };
        let coarse = self.coarse();
        let mut scored = fit(&coarse);
        if scored.is_empty() {
            return (scored, coarse.len());
        }
        let mut seen = coarse;
        let mut step = self.step();
        for _ in 0..2 {
            let Some(best) = scored
                .iter()
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|p| p.0)
            else {
                break;
            };
            let mut fine: Vec<f64> = (0..GRID)
                .map(|i| self.round(best - step + 2.0 * step * i as f64 / (GRID - 1) as f64))
                .filter(|c| self.dir * (c - self.extreme) >= 0.0 && !seen.contains(c))
                .collect();
            fine.dedup();
            seen.extend(&fine);
            scored.extend(fit(&fine));
            step *= 2.0 / (GRID - 1) as f64;
        }
        (scored, seen.len())
    }
}

/// The shortlisted position that simulates the records best, beside the equation-error fit.
struct Chosen {
    c: f64,
    sigma: f64,
    model: Model,
    ours: Scores,
    theirs: Scores,
    /// Positions with a kept fit.
    positions: usize,
}

/// σ on one held-out record barely separates neighbouring positions, while T-F-S's term
/// selection can jump between them; so the `SHORTLIST` positions of `scored` with the lowest σ
/// are each simulated on the records (beside the equation-error fit `after`) and the one that
/// simulates them best is taken (then the lower σ). `None` when `scored` is empty.
fn simulate_shortlist(
    mut scored: Vec<(f64, f64, Model)>,
    after: &Model,
    records: &[Record],
) -> Option<Chosen> {
    let positions = scored.len();
    scored.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.total_cmp(&b.0)));
    scored.truncate(SHORTLIST);
    let (shortlist, theirs): (Vec<(f64, f64, Model, Scores)>, Scores) = rayon::join(
        || {
            use rayon::prelude::*;
            scored
                .into_par_iter()
                .map(|(c, sigma, m)| {
                    let s = score(&m, records);
                    (c, sigma, m, s)
                })
                .collect()
        },
        || score(after, records),
    );
    let (c, sigma, model, ours) = shortlist.into_iter().min_by(|a, b| {
        a.3.summary()
            .key()
            .partial_cmp(&b.3.summary().key())
            .unwrap_or(std::cmp::Ordering::Equal)
            .then(a.1.total_cmp(&b.1))
    })?;
    Some(Chosen {
        c,
        sigma,
        model,
        ours,
        theirs,
        positions,
    })
}

impl Chosen {
    /// What the re-scan did, with whether the re-identified model replaces the equation-error
    /// fit: when it simulates the records better, or when neither simulates any record (a chain
    /// whose other cell still falls through its fold: the simulations cannot choose, and the
    /// model with the stop where the model's own criterion puts it on the cell's height is used).
    /// `tried` is how many positions were fitted, `tied` whether the chain is tied, `n` the
    /// records.
    fn report(
        &self,
        place: &Placement,
        stop: &Term,
        grid: &Grid,
        (tried, tied): (usize, bool),
        n: usize,
    ) -> StopRescan {
        let Self {
            c,
            sigma,
            ours,
            theirs,
            positions,
            ..
        } = self;
        let term = place.term(*c);
        let coef = self.model.equations[place.owner]
            .terms
            .iter()
            .find(|t| t.term == term)
            .map_or(f64::NAN, |t| t.coef);
        let none_simulate = ours.each.is_empty() && theirs.each.is_empty();
        let kept = none_simulate || (!ours.each.is_empty() && ours.better_than(theirs));
        let why = format!(
            "T-F-S{} with the stop {} at {} positions from the data's extreme ({:.4}) to {:.4} in from it: of the {SHORTLIST} with the lowest held-out residual, c = {c} simulates the records best (σ = {sigma:.4}), stiffness {coef:.4e}; geometric-mean R-MSE {} against {} for the equation-error fit ({stop}), so {}",
            if tied { " (tied)" } else { "" },
            place.term(*c),
            positions,
            grid.extreme,
            2.0 * grid.reach,
            ours.describe(n),
            theirs.describe(n),
            if none_simulate {
                "the simulations cannot choose and the re-identified model is used"
            } else if kept {
                "the re-identified model is used"
            } else {
                "the equation-error fit stays"
            }
        );
        StopRescan {
            from: stop.to_string(),
            to: term.to_string(),
            coef,
            kept,
            positions: tried,
            why,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scan reaches the depth the stop effect offers however near the extreme the loop's
    /// choice lies, and past a deeper choice by as much again.
    #[test]
    fn the_scan_reaches_the_stop_effects_depth() {
        let (lo, hi) = (-0.0157, 1.8487);
        let span = hi - lo;
        // The loop's choice 5 % of the span in from the top: the scan still runs 20 % in.
        let r = scan_reach(hi - 0.05 * span, hi, span, true);
        assert!((2.0 * r / span - REACH_SHARE).abs() < 1e-12, "{r}");
        // A choice 15 % in: the scan runs 30 % in, past it by as much again.
        let r = scan_reach(lo + 0.15 * span, lo, span, true);
        assert!((2.0 * r / span - 0.3).abs() < 1e-12, "{r}");
        // Moved to another coordinate: the effect's depth.
        let r = scan_reach(lo + 0.15 * span, lo, span, false);
        assert!((2.0 * r / span - REACH_SHARE).abs() < 1e-12, "{r}");
    }
}
