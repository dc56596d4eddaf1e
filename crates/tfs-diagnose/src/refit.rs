//! Add and refit: refit a model's structure by equation error, add a named effect (its scanned
//! parameter chosen by held-out error), keep the history, and print the error ladder.

use faer::Mat;
use serde::Serialize;
use serde_json::json;
use tfs_data::Record;
use tfs_library::{HistoryEntry, Model, RecordScore, Term};
use tfs_regress::Compressed;

use crate::anchor::{Planned, choose_anchor};
use crate::design::{compress_blocks, design, full_fit, partner_columns, with_equation};
use crate::effects::{Catalogue, EffectColumn};
use crate::prepare::{DiagnoseOptions, Layout, RecordStates, check_records};
use crate::{DiagnoseError, Result};

fn prepare(model: &Model, records: &[Record], opts: &DiagnoseOptions) -> Result<Vec<RecordStates>> {
    opts.validate()?;
    check_records(model, records)?;
    records
        .iter()
        .map(|r| RecordStates::new(model, r, opts))
        .collect()
}

/// Refits the coefficients of every equation of `model` (same terms) by equation-error least
/// squares on all usable rows of `records`.
pub fn refit(model: &Model, records: &[Record], opts: &DiagnoseOptions) -> Result<Model> {
    let states = prepare(model, records, opts)?;
    let layout = Layout::new(&states, opts)?;
    let mut out = model.clone();
    for idx in 0..model.dofs.len() {
        let cols: Vec<EffectColumn> = out.equations[idx]
            .terms
            .iter()
            .map(|t| EffectColumn::term(t.term.clone()))
            .collect();
        if cols.is_empty() {
            continue;
        }
        let d = design(&states, idx, &cols)?;
        let coef = full_fit(&compress_blocks(&d, &layout)?)?;
        out = with_equation(&out, idx, &cols, &coef)?;
    }
    Ok(out)
}

/// A term of a chain element's force law that two equations share (Newton's third law, as a
/// tied fit writes it): its coefficient in the partner DOF's equation is `factor` times the one
/// in the owner DOF's equation.
#[derive(Debug, Clone, PartialEq)]
pub struct SharedTerm {
    /// The term, a function of the relative coordinate between the two DOFs.
    pub term: Term,
    /// Index of the DOF whose equation holds the free coefficient.
    pub owner: usize,
    /// Index of the DOF whose coefficient is `factor` times the owner's.
    pub partner: usize,
    /// The tie factor (`−m_owner/m_partner` per unit mass).
    pub factor: f64,
}

/// [`refit`] with the `shared` terms tied: every equation's coefficients (same terms) are
/// estimated jointly by equation-error least squares on the usable rows of `records`, one
/// unknown per shared term for both equations it enters. The last history step, if any, is
/// rescored with these coefficients (it was scored with the untied ones).
pub fn refit_shared(
    model: &Model,
    records: &[Record],
    shared: &[SharedTerm],
    opts: &DiagnoseOptions,
) -> Result<Model> {
    let states = prepare(model, records, opts)?;
    let layout = Layout::new(&states, opts)?;
    // Each equation's column -> (unknown, factor): owners' and untied terms get their own
    // unknown, a partner's shared term the owner's unknown times the factor.
    let position = |d: usize, t: &Term| model.equations[d].terms.iter().position(|m| m.term == *t);
    let mut map: Vec<Vec<Option<(usize, f64)>>> = model
        .equations
        .iter()
        .map(|e| vec![None; e.terms.len()])
        .collect();
    let mut unknowns = 0;
    for (d, cols) in map.iter_mut().enumerate() {
        for (c, slot) in cols.iter_mut().enumerate() {
            let t = &model.equations[d].terms[c].term;
            let partner_of_owner = shared
                .iter()
                .any(|s| s.partner == d && s.term == *t && position(s.owner, t).is_some());
            if !partner_of_owner {
                *slot = Some((unknowns, 1.0));
                unknowns += 1;
            }
        }
    }
    for s in shared {
        if let (Some(oc), Some(pc)) = (position(s.owner, &s.term), position(s.partner, &s.term))
            && let Some((u, _)) = map[s.owner][oc]
        {
            map[s.partner][pc] = Some((u, s.factor));
        }
    }
    let map: Vec<Vec<(usize, f64)>> = map
        .into_iter()
        .map(|cols| cols.into_iter().map(|m| m.unwrap_or((0, 0.0))).collect())
        .collect();
    let columns: Vec<Vec<EffectColumn>> = model
        .equations
        .iter()
        .map(|e| {
            e.terms
                .iter()
                .map(|t| EffectColumn::term(t.term.clone()))
                .collect()
        })
        .collect();
    let mut blocks = Vec::new();
    for (d, cols) in columns.iter().enumerate() {
        if cols.is_empty() {
            continue;
        }
        let des = design(&states, d, cols)?;
        for bl in &layout.blocks {
            let a = des.block(bl.record, bl.start, bl.len);
            let mut joint = Mat::<f64>::zeros(bl.len, unknowns);
            for (c, &(u, f)) in map[d].iter().enumerate() {
                for i in 0..bl.len {
                    joint[(i, u)] += f * a[(i, c)];
                }
            }
            let b = &des.target(bl.record)[bl.start..bl.start + bl.len];
            blocks.push(Compressed::from_rows(joint.as_ref(), b)?);
        }
    }
    let theta = full_fit(&blocks)?;
    let mut out = model.clone();
    for (d, cols) in columns.iter().enumerate() {
        if cols.is_empty() {
            continue;
        }
        let coef: Vec<f64> = map[d].iter().map(|&(u, f)| f * theta[u]).collect();
        out = with_equation(&out, d, cols, &coef)?;
    }
    if !out.history.is_empty() {
        let (scores, failed) = try_scores(&out, records);
        let equations = out.equation_string();
        if let Some(last) = out.history.last_mut() {
            last.r_mse = scores;
            if let Some(details) = last.details.as_object_mut() {
                details.insert("failed".into(), json!(failed));
                details.insert("equations".into(), json!(equations));
                details.insert("shared_terms".into(), json!(shared.len()));
            }
        }
    }
    Ok(out)
}

/// R-MSE of `model` on every record (simulated under each record's input).
pub fn score_records(model: &Model, records: &[Record]) -> Result<Vec<RecordScore>> {
    records
        .iter()
        .map(|r| {
            Ok(RecordScore {
                record: r.source().to_string(),
                r_mse: crate::simulate::r_mse(model, r)?,
            })
        })
        .collect()
}

/// Splits `name@dof` into the effect and the DOF list it applies to (every DOF without `@`).
fn targets(model: &Model, name: &str) -> Result<(String, Vec<usize>)> {
    match name.split_once('@') {
        Some((e, d)) => {
            let idx = model.dofs.iter().position(|x| x == d).ok_or_else(|| {
                DiagnoseError::NotApplicable {
                    name: name.to_string(),
                    reason: format!(
                        "'{d}' is not one of the model's DOFs [{}]",
                        model.dofs.join(", ")
                    ),
                }
            })?;
            Ok((e.to_string(), vec![idx]))
        }
        None => Ok((name.to_string(), (0..model.dofs.len()).collect())),
    }
}

/// Adds the catalogue effect `effect_name` (optionally `name@dof`) with default options and the
/// standard catalogue; see [`add_effect_with`].
pub fn add_effect(model: &Model, effect_name: &str, records: &[Record]) -> Result<Model> {
    let opts = DiagnoseOptions::default();
    add_effect_with(
        model,
        effect_name,
        records,
        &Catalogue::standard(opts.max_power),
        &opts,
    )
}

/// Adds an effect to the equation of each target DOF: every variant of its family is fitted with
/// the equation's terms on training folds and the one with the lowest held-out equation error is
/// kept; the extended equation is then refitted on all records toward the model's own
/// coefficients (`crate::anchor`: held, ridge-regularised or free), keeping the fit whose free
/// runs predict the records best. When that fit does not predict them better than `model`
/// itself, the step toward it is searched (`crate::anchor::line_search`): the result never
/// predicts the fit records worse than `model`, and when no step helps it is `model`'s equations
/// unchanged, with nothing listed as added. The model's history gets a `"start"` entry (if
/// empty) and an `"add <name>"` entry with the R-MSE of every record (its details name the
/// anchor kept, the `step` kept toward it (1: the fit itself; 0: nothing added), and every
/// anchor's and step's R-MSE per record, and the start model's as `start`).
pub fn add_effect_with(
    model: &Model,
    effect_name: &str,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Result<Model> {
    add(model, effect_name, records, catalogue, opts, true)
}

/// [`add_effect_with`] without the step search: the best fit of the effect is kept even when it
/// predicts the records worse than `model`. For a caller that changes the refit further (a tied
/// chain refitted with its ties, a stop re-placed by another method) and then searches the step
/// on what it ends with ([`hold_start`]), so the step is chosen for the model returned.
pub fn add_effect_fit(
    model: &Model,
    effect_name: &str,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Result<Model> {
    add(model, effect_name, records, catalogue, opts, false)
}

/// `fitted` (a refit of `start` with an effect added, its last history step that effect's) kept
/// only as far as it predicts `records` better than `start`, by the rulers and key the refit's
/// anchors are chosen by: when it is not better (and `start` simulates every record), the best
/// step toward it
/// (`crate::anchor::line_search`), or `start`'s equations (nothing added, the step's `added`
/// list emptied). The last history step gets the step kept (`step` in its first variant's
/// details; 1: `fitted` as it is) and, when the model changed, its R-MSE per record again.
pub fn hold_start(
    start: &Model,
    fitted: &Model,
    records: &[Record],
    opts: &DiagnoseOptions,
) -> Result<Model> {
    use crate::anchor::{better, holds, line_search, r_mse_each, rulers, sim_key};
    let rulers = rulers(start, records, opts);
    // The start first: its fitted starts warm the refit's runs ([`r_mse_each`]).
    let s0 = r_mse_each(start, None, records, &rulers, opts);
    let s1 = r_mse_each(fitted, Some(start), records, &rulers, opts);
    let (step, mut out) = if !holds(&s0) || better(sim_key(&s1), sim_key(&s0)) {
        (1.0, fitted.clone())
    } else {
        let s = line_search(start, fitted, &s1, &s0, |m| {
            r_mse_each(m, Some(start), records, &rulers, opts)
        })?;
        (s.step, s.model)
    };
    let rescore = step < 1.0;
    let (scores, failed) = if rescore {
        try_scores(&out, records)
    } else {
        (Vec::new(), Vec::new())
    };
    let equations = out.equation_string();
    if let Some(last) = out.history.last_mut() {
        if let Some(v) = last.details["variants"]
            .get_mut(0)
            .and_then(|v| v.as_object_mut())
        {
            v.insert("step".into(), json!(step));
            if rescore {
                let fit = v.get("anchor").and_then(|a| a.as_str()).unwrap_or("fit");
                let anchor = if step == 0.0 {
                    "none: the start model".to_string()
                } else {
                    format!("{fit}, step {step}")
                };
                v.insert("anchor".into(), json!(anchor));
            }
        }
        if rescore {
            last.r_mse = scores;
            last.details["failed"] = json!(failed);
            last.details["equations"] = json!(equations);
        }
        if step == 0.0 {
            last.added.clear();
        }
    }
    Ok(out)
}

/// [`add_effect_with`], with the step search only when `search`.
fn add(
    model: &Model,
    effect_name: &str,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
    search: bool,
) -> Result<Model> {
    let (effect, dofs) = targets(model, effect_name)?;
    let eff = catalogue.get(&effect)?;
    let states = prepare(model, records, opts)?;
    let layout = Layout::new(&states, opts)?;
    let dt = records[0].dt();
    let mut out = model.clone();
    let mut added = Vec::new();
    let mut details = Vec::new();
    let mut plans = Vec::new();
    for &idx in &dofs {
        let base: Vec<tfs_library::Term> = model.equations[idx]
            .terms
            .iter()
            .map(|t| t.term.clone())
            .collect();
        let dof = &model.dofs[idx];
        let scales = crate::prepare::DataScales::measure(model, idx, &base, &states)?;
        let ctx = crate::effects::EffectContext::new(
            model,
            dof,
            base.clone(),
            &scales,
            dt,
            opts.max_power,
        );
        let variants = eff.variants(&ctx);
        if variants.is_empty() {
            return Err(DiagnoseError::NotApplicable {
                name: effect_name.to_string(),
                reason: format!(
                    "does not apply to the equation of '{dof}' (its terms are already there, or it needs an input/velocity scale the data lacks)"
                ),
            });
        }
        // Start-library terms the missing effect hid come back with it (as `explain` scored it).
        let left_out = crate::readmit::left_out(model, idx);
        let eq = (idx, base.as_slice());
        let readmit = crate::readmit::best_with_library;
        let Some(re) = readmit(
            &states,
            &layout,
            eq,
            &variants,
            &left_out,
            (opts.alpha, false),
        )?
        else {
            continue;
        };
        let best = re.scored;
        // Start-library terms still missing after the re-admission: the alternative structure
        // (`Planned::whole`).
        let rest: Vec<tfs_library::Term> = left_out
            .iter()
            .filter(|t| !re.terms.contains(t) && crate::readmit::offerable(t, &best))
            .cloned()
            .collect();
        let (cols, v) = (best.cols, best.variant);
        for c in v.add.iter().chain(v.replace.iter().map(|(_, c)| c)) {
            added.push(c.label());
        }
        added.extend(re.terms.iter().map(ToString::to_string));
        let readmitted: Vec<String> = re.terms.iter().map(ToString::to_string).collect();
        // A force on a coupling acts on both masses: the same variant goes into each partner's
        // equation (refitted there), unless that DOF is a target of its own.
        let mut partners = Vec::new();
        for (pi, pcols) in partner_columns(model, dof, &v) {
            if dofs.contains(&pi) {
                continue;
            }
            let pd = design(&states, pi, &pcols)?;
            let pcoef = full_fit(&compress_blocks(&pd, &layout)?)?;
            partners.push((pi, pcols, pcoef));
        }
        details.push(json!({"dof": dof, "parameter": v.parameter, "readmitted": readmitted}));
        for (pi, _, _) in &partners {
            let p = &model.dofs[*pi];
            details.push(json!({"dof": p, "parameter": v.parameter, "partner_of": dof}));
        }
        let all: Vec<(&Compressed, usize)> = best.blocks.iter().map(|c| (c, 1)).collect();
        let merged = Compressed::merge_counted(&all)?;
        // The alternative structure: every start-library term the equation still lacks comes
        // back too (the refit's simulations choose; see `choose_anchor`).
        let whole = if rest.is_empty() {
            None
        } else {
            let mut terms = base.clone();
            terms.extend(re.terms.iter().cloned());
            terms.extend(rest.iter().cloned());
            let (wcols, _) = crate::design::variant_columns(&terms, &v);
            let wd = design(&states, idx, &wcols)?;
            let wmerged = compress_blocks(&wd, &layout)?;
            let wall: Vec<(&Compressed, usize)> = wmerged.iter().map(|c| (c, 1)).collect();
            Some((
                rest.iter().map(ToString::to_string).collect(),
                Compressed::merge_counted(&wall)?,
                wcols,
            ))
        };
        plans.push(Planned {
            idx,
            cols,
            merged,
            partners,
            whole,
        });
    }
    // The chosen refit's R-MSE on each record where its choice simulated it (infinite where
    // that failed: simulated again below for the message).
    let mut known = None;
    if !plans.is_empty() {
        let chosen = choose_anchor(model, &plans, records, opts, search)?;
        if chosen.whole {
            for p in &plans {
                if let Some((names, _, _)) = &p.whole {
                    added.extend(names.iter().cloned());
                }
            }
        }
        if chosen.step == 0.0 {
            // Every step toward the effect predicts the records worse: nothing is added.
            added.clear();
        }
        out = chosen.model;
        known = Some(chosen.each);
        if let Some(first) = details.first_mut().and_then(|d| d.as_object_mut()) {
            first.insert("anchor".into(), json!(chosen.anchor));
            first.insert("step".into(), json!(chosen.step));
            first.insert("train_r_mse".into(), json!(chosen.scores));
        }
    }
    if out.history.is_empty() {
        let (scores, failed) = try_scores(model, records);
        out.history.push(HistoryEntry {
            step: "start".into(),
            added: Vec::new(),
            r_mse: scores,
            details: json!({"equations": model.equation_string(), "failed": failed}),
        });
    }
    let (scores, failed) = try_scores_known(&out, records, known.as_deref());
    out.history.push(HistoryEntry {
        step: format!("add {effect_name}"),
        added,
        r_mse: scores,
        details: json!({"variants": details, "equations": out.equation_string(), "failed": failed}),
    });
    Ok(out)
}

/// Scores every record, keeping failed simulations (e.g. blow-up) as messages instead of scores.
fn try_scores(model: &Model, records: &[Record]) -> (Vec<RecordScore>, Vec<String>) {
    try_scores_known(model, records, None)
}

/// [`try_scores`] where the finite entries of `known` (one per record, when given) are the
/// model's free-run R-MSE on those records already ([`r_mse_each`] under the free run: the same
/// simulation), so only the others are simulated.
fn try_scores_known(
    model: &Model,
    records: &[Record],
    known: Option<&[f64]>,
) -> (Vec<RecordScore>, Vec<String>) {
    let mut ok = Vec::new();
    let mut failed = Vec::new();
    for (k, r) in records.iter().enumerate() {
        let score = match known.and_then(|v| v.get(k)).filter(|v| v.is_finite()) {
            Some(&v) => Ok(v),
            None => crate::simulate::r_mse(model, r),
        };
        match score {
            Ok(v) => ok.push(RecordScore {
                record: r.source().to_string(),
                r_mse: v,
            }),
            Err(e) => failed.push(format!("{}: {e}", r.source())),
        }
    }
    (ok, failed)
}

/// One rung of the error ladder.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LadderStep {
    /// The history step label.
    pub step: String,
    /// What was added.
    pub added: Vec<String>,
    /// Mean R-MSE over the step's scored records (NaN when none were scored: see `failed`).
    pub mean_r_mse: f64,
    /// Geometric-mean R-MSE over the step's scored records ([`crate::geometric_mean_r_mse`];
    /// NaN when none were scored): what the ladder prints and what every "the records support
    /// it" comparison of the steps reads.
    pub geo_mean_r_mse: f64,
    /// R-MSE per record.
    pub r_mse: Vec<RecordScore>,
    /// Records whose simulation failed at this step (e.g. blow-up), with the reason.
    pub failed: Vec<String>,
}

impl LadderStep {
    /// True when some record could not be simulated: the mean then covers only the others
    /// (or none), so it cannot be compared with a step that scored every record.
    pub fn incomplete(&self) -> bool {
        !self.failed.is_empty()
    }
}

/// The error ladder of a model: one step per history entry.
pub fn error_ladder(model: &Model) -> Vec<LadderStep> {
    model
        .history
        .iter()
        .map(|h| LadderStep {
            step: h.step.clone(),
            added: h.added.clone(),
            mean_r_mse: if h.r_mse.is_empty() {
                f64::NAN
            } else {
                h.r_mse.iter().map(|s| s.r_mse).sum::<f64>() / h.r_mse.len() as f64
            },
            geo_mean_r_mse: if h.r_mse.is_empty() {
                f64::NAN
            } else {
                crate::stats::geometric_mean_r_mse(
                    &h.r_mse.iter().map(|s| s.r_mse).collect::<Vec<_>>(),
                )
            },
            r_mse: h.r_mse.clone(),
            failed: h.details["failed"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|v| v.as_str().map(str::to_string))
                .collect(),
        })
        .collect()
}

/// The ladder as a plain-text table (step, added terms, geometric-mean R-MSE over the records,
/// factor versus the previous step). A step whose simulation failed on some record says so: its
/// mean then covers the other records only, and no factor is given against or from it.
pub fn ladder_table(ladder: &[LadderStep]) -> String {
    let mut s = format!(
        "{:<28} {:>12} {:>9}  added\n",
        "step", "R-MSE (geo)", "factor"
    );
    let mut prev: Option<f64> = None;
    for st in ladder {
        let g = st.geo_mean_r_mse;
        let comparable = !st.incomplete() && g.is_finite();
        let factor = match prev {
            Some(p) if comparable && g > 0.0 => format!("{}x", tfs_library::sig4(p / g)),
            _ => "-".into(),
        };
        let mean = if g.is_finite() {
            format!("{g:.4e}")
        } else {
            "failed".into()
        };
        s.push_str(&format!(
            "{:<28} {:>12} {:>9}  {}\n",
            st.step,
            mean,
            factor,
            st.added.join(", ")
        ));
        if st.incomplete() {
            let total = st.failed.len() + st.r_mse.len();
            s.push_str(&format!(
                "  simulation failed on {} of {total} record(s){}: {}\n",
                st.failed.len(),
                if st.r_mse.is_empty() {
                    ""
                } else {
                    " (the mean is over the others)"
                },
                st.failed[0]
            ));
        }
        prev = comparable.then_some(g);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(name: &str, scores: &[f64], failed: &[&str]) -> HistoryEntry {
        HistoryEntry {
            step: name.into(),
            added: Vec::new(),
            r_mse: scores
                .iter()
                .enumerate()
                .map(|(i, &v)| RecordScore {
                    record: format!("r{i}"),
                    r_mse: v,
                })
                .collect(),
            details: json!({ "failed": failed }),
        }
    }

    /// A refit's R-MSE that its anchor choice already has is taken as it is; a record
    /// without one (infinite: the simulation failed) is simulated again for its message.
    #[test]
    fn known_scores_are_kept_and_failures_simulated_again() {
        // `xb_acc` is missing from the records: every simulation fails.
        let m = Model::from_json_str(
            r#"{"format":"tfs-model/1","dofs":["x"],"equations":[{"dof":"x","terms":[{"term":"x","coef":-1},{"term":"xb_acc","coef":1}]}]}"#,
        )
        .unwrap();
        let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.1).collect();
        let x: Vec<f64> = t.iter().map(|t| t.cos()).collect();
        let rec = |n: &str| Record::new(n, t.clone(), vec![("x".to_string(), x.clone())]).unwrap();
        let records = [rec("a"), rec("b")];
        let (ok, failed) = try_scores_known(&m, &records, Some(&[0.25, f64::INFINITY]));
        assert_eq!(ok.len(), 1);
        assert_eq!((ok[0].record.as_str(), ok[0].r_mse), ("a", 0.25));
        assert_eq!(failed.len(), 1);
        assert!(failed[0].starts_with("b: "), "{failed:?}");
        let (ok, failed) = try_scores(&m, &records);
        assert!(ok.is_empty() && failed.len() == 2, "{ok:?} {failed:?}");
    }

    /// A step whose simulations failed says so instead of printing NaN, and no factor is
    /// computed against a mean that covers only some of the records.
    #[test]
    fn failed_steps_are_named_not_nan() {
        let mut m = Model::from_json_str(
            r#"{"format":"tfs-model/1","dofs":["x"],"equations":[{"dof":"x","terms":[{"term":"x","coef":-1}]}]}"#,
        )
        .unwrap();
        m.history = vec![
            step("start", &[0.02, 0.04], &[]),
            step("add a", &[], &["r0: blew up", "r1: blew up"]),
            step("add b", &[0.01], &["r1: blew up"]),
            step("add c", &[0.01, 0.01], &[]),
        ];
        let ladder = error_ladder(&m);
        assert!(!ladder[0].incomplete());
        assert!(ladder[1].incomplete() && ladder[1].mean_r_mse.is_nan());
        assert_eq!(ladder[2].failed, vec!["r1: blew up".to_string()]);
        let t = ladder_table(&ladder);
        assert!(!t.contains("NaN"), "{t}");
        let lines: Vec<&str> = t.lines().collect();
        // header, start, add a + note, add b + note, add c
        assert_eq!(lines.len(), 7, "{t}");
        assert!(
            lines[2].contains("failed") && lines[2].contains(" - "),
            "{t}"
        );
        assert!(lines[3].contains("2 of 2"), "{t}");
        assert!(
            lines[4].contains("1.0000e-2") && !lines[4].contains('x'),
            "{t}"
        );
        assert!(
            lines[5].contains("1 of 2") && lines[5].contains("over the others"),
            "{t}"
        );
        // 'add c' follows an incomplete step: no factor either.
        assert!(
            lines[6].starts_with("add c") && !lines[6].contains("x "),
            "{t}"
        );
    }
}
