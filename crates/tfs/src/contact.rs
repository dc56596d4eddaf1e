//! A stop's position and stiffness found by the model's own method.
//!
//! The diagnosis loop scores a stop `k·below(x, c)` (or `above`) by time-domain equation error on
//! smoothed states. A stiff contact lasts a few samples: the smoothing spreads its acceleration
//! spike over the smoothing window, and a soft stop placed inside the data's range fits the spread
//! spike better than the true one (on the Kresling truss cell, c = 0.0104 and k = 386 where the
//! contact is at 0 with k = 11,072, and the cell's polynomial force moves further from the truth
//! than before the stop). The weak form of T-F-S integrates the equation against smooth test
//! functions, so the contact enters through the momentum it changes, not through a smoothed
//! spike. After a stop is added to a one-DOF T-F-S model, [`rescan_stop`] re-identifies the
//! equation by T-F-S with the model's library plus the stop at each position on a grid from the
//! data's extreme past the loop's choice, shortlists the positions whose held-out residual
//! (Criterion 4's σ on the held-out record) is lowest, takes the one among them that simulates
//! the records best, and keeps that model only if it simulates them better than the
//! equation-error fit.

use serde_json::json;
use tfs_criteria::{IdentifySpec, identify_tfs};
use tfs_data::Record;
use tfs_library::{Factor, HistoryEntry, Model, RecordScore, Term};

use crate::error::Result;

/// Positions of the first, coarse pass; a second pass of the same size refines around the best.
const GRID: usize = 25;
/// Positions of lowest held-out residual that are simulated to choose among them.
const SHORTLIST: usize = 5;

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
    /// Why, in a sentence.
    pub why: String,
}

/// The one-factor stop term (`below(q, c)` or `above(q, c)`) that `after` has and `before` lacks.
fn added_stop(before: &Model, after: &Model) -> Option<Term> {
    let old: Vec<&Term> = before.equations[0].terms.iter().map(|t| &t.term).collect();
    after.equations[0]
        .terms
        .iter()
        .map(|t| &t.term)
        .filter(|t| !old.contains(t))
        .find(|t| matches!(t.factors(), [Factor::Below(..)] | [Factor::Above(..)]))
        .cloned()
}

/// The stop `term` moved to position `c`.
fn at(term: &Term, c: f64) -> Term {
    let f = match &term.factors()[0] {
        Factor::Below(v, _) => Factor::Below(v.clone(), c),
        Factor::Above(v, _) => Factor::Above(v.clone(), c),
        other => other.clone(),
    };
    Term::new(vec![f])
}

/// A model's mean free-run R-MSE over the records, with the score of each.
type Scores = (f64, Vec<RecordScore>);

/// Mean free-run R-MSE over `records`, `None` when any record cannot be simulated.
fn mean_r_mse(model: &Model, records: &[Record]) -> Option<Scores> {
    let mut scores = Vec::with_capacity(records.len());
    for r in records {
        let v = tfs_diagnose::r_mse(model, r).ok()?;
        scores.push(RecordScore {
            record: r.source().to_string(),
            r_mse: v,
        });
    }
    let mean = scores.iter().map(|s| s.r_mse).sum::<f64>() / scores.len().max(1) as f64;
    Some((mean, scores))
}

/// One T-F-S fit with the stop at `c`: the model and its held-out σ, `None` when the fit fails
/// or drops the stop.
fn fit_at(
    library: &[String],
    dof: &str,
    stop: &Term,
    c: f64,
    records: &[Record],
) -> Option<(f64, tfs_criteria::Identified)> {
    let term = at(stop, c);
    let mut lib = library.to_vec();
    lib.push(term.to_string());
    let spec = IdentifySpec::new(&[dof], &lib.join(", "));
    let id = identify_tfs(records, &spec).ok()?;
    let keeps = id.model.equations[0].terms.iter().any(|t| t.term == term);
    let sigma = id.trace.dofs.first()?.assembly.last()?.sigma;
    (keeps && sigma.is_finite()).then_some((sigma, id))
}

/// Re-identifies a one-DOF T-F-S model to which the loop has just added a stop (`after`, refitted
/// from `before` by equation error) with the stop's position scanned by the model's own method
/// (module docs). Returns `None` when it does not apply (several DOFs, another method, no stop
/// added, no library in the trace); otherwise the model to use and what was done.
pub fn rescan_stop(
    before: &Model,
    after: &Model,
    records: &[Record],
) -> Result<Option<(Model, StopRescan)>> {
    if before.dofs.len() != 1 || after.method != "tfs-sindy" || records.is_empty() {
        return Ok(None);
    }
    let Some(stop) = added_stop(before, after) else {
        return Ok(None);
    };
    let dof = before.dofs[0].clone();
    // The library T-F-S chose from, with the model's own terms (a term added by the loop).
    let mut library: Vec<String> = before.trace["dofs"][0]["library"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|v| v.as_str().map(str::to_string))
        .collect();
    if library.is_empty() {
        return Ok(None);
    }
    for t in &before.equations[0].terms {
        let s = t.term.to_string();
        if !library.contains(&s) {
            library.push(s);
        }
    }
    let (Factor::Below(v, c0) | Factor::Above(v, c0)) = &stop.factors()[0] else {
        return Ok(None);
    };
    let below = matches!(stop.factors()[0], Factor::Below(..));
    // The data's range over every record; the stop's side of it is where a contact holds.
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for r in records {
        let Ok(col) = tfs_library::evaluate_term(&Term::new(vec![Factor::Pow(v.clone(), 1)]), r)
        else {
            return Ok(None);
        };
        for &x in &col {
            lo = lo.min(x);
            hi = hi.max(x);
        }
    }
    let extreme = if below { lo } else { hi };
    let span = hi - lo;
    let reach = (c0 - extreme).abs();
    if !(span > 0.0 && reach > 0.0 && reach.is_finite()) {
        return Ok(None);
    }
    // From the extreme (a stop beyond it never engages) to as far past the loop's choice.
    // Positions to a decimal place about 1e-4 of the span, so the term's name is exact.
    let places = (-(span * 1e-4).log10().floor()).clamp(0.0, 12.0) as usize;
    let round = |c: f64| {
        let r: f64 = format!("{c:.places$}").parse().unwrap_or(c);
        r + 0.0
    };
    let dir = if below { 1.0 } else { -1.0 };
    let step = 2.0 * reach / (GRID - 1) as f64;
    let coarse: Vec<f64> = (0..GRID)
        .map(|i| round(extreme + dir * step * i as f64))
        .collect();
    // Each kept position with its σ and the model T-F-S fitted there.
    let scan = |cs: &[f64]| -> Vec<(f64, f64, Model)> {
        use rayon::prelude::*;
        cs.par_iter()
            .filter_map(|&c| {
                fit_at(&library, &dof, &stop, c, records)
                    .map(|(s, id)| (c, s, id.model_with_trace()))
            })
            .collect()
    };
    let mut scored = scan(&coarse);
    let best_coarse = scored
        .iter()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|p| p.0);
    let Some(bc) = best_coarse else {
        return Ok(Some((
            after.clone(),
            StopRescan {
                from: stop.to_string(),
                to: stop.to_string(),
                coef: f64::NAN,
                kept: false,
                why: "T-F-S kept no stop at any position between the data's extreme and the loop's choice; the equation-error fit stays".into(),
            },
        )));
    };
    let mut fine: Vec<f64> = (0..GRID)
        .map(|i| round(bc - step + 2.0 * step * i as f64 / (GRID - 1) as f64))
        .filter(|c| dir * (c - extreme) >= 0.0 && !coarse.contains(c))
        .collect();
    fine.dedup();
    scored.extend(scan(&fine));
    // σ on one held-out record barely separates neighbouring positions, while T-F-S's term
    // selection can jump between them; so the few positions with the lowest σ are each
    // simulated on the records and the one that simulates them best is taken.
    let positions = scored.len();
    scored.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.total_cmp(&b.0)));
    scored.truncate(SHORTLIST);
    let shortlist: Vec<(f64, f64, Model, Option<Scores>)> = {
        use rayon::prelude::*;
        scored
            .into_par_iter()
            .map(|(c, sigma, m)| {
                let score = mean_r_mse(&m, records);
                (c, sigma, m, score)
            })
            .collect()
    };
    let Some((c, sigma, mut model, ours)) = shortlist.into_iter().min_by(|a, b| {
        let key = |s: &Option<Scores>| s.as_ref().map_or(f64::INFINITY, |v| v.0);
        key(&a.3).total_cmp(&key(&b.3)).then(a.1.total_cmp(&b.1))
    }) else {
        return Ok(None);
    };
    let term = at(&stop, c);
    let coef = model.equations[0]
        .terms
        .iter()
        .find(|t| t.term == term)
        .map_or(f64::NAN, |t| t.coef);
    let theirs = mean_r_mse(after, records);
    let kept = match (&ours, &theirs) {
        (Some((a, _)), Some((b, _))) => a < b,
        (Some(_), None) => true,
        _ => false,
    };
    let fmt = |m: &Option<Scores>| match m {
        Some((v, _)) => format!("{v:.4e}"),
        None => "a failed simulation".to_string(),
    };
    let why = format!(
        "T-F-S with the stop at {} positions from the data's extreme ({extreme:.4}) past the loop's choice ({c0}): of the {SHORTLIST} with the lowest held-out residual, c = {c} simulates the records best (σ = {sigma:.4}), stiffness {coef:.4e}; mean R-MSE {} against {} for the equation-error fit, so {}",
        positions,
        fmt(&ours),
        fmt(&theirs),
        if kept {
            "the re-identified model is used"
        } else {
            "the equation-error fit stays"
        }
    );
    let report = StopRescan {
        from: stop.to_string(),
        to: term.to_string(),
        coef,
        kept,
        why,
    };
    if !kept {
        return Ok(Some((after.clone(), report)));
    }
    // The re-identified model keeps the loop's history, with one more rung.
    model.history = after.history.clone();
    let scores = ours.map(|(_, s)| s).unwrap_or_default();
    model.history.push(HistoryEntry {
        step: "stop by T-F-S".into(),
        added: vec![term.to_string()],
        r_mse: scores,
        details: json!({"equations": model.equation_string(), "from": stop.to_string(), "why": report.why, "failed": []}),
    });
    Ok(Some((model, report)))
}
