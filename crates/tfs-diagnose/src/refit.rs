//! Add and refit: refit a model's structure by equation error, add a named effect (its scanned
//! parameter chosen by held-out error), keep the history, and print the error ladder.

use serde::Serialize;
use serde_json::json;
use tfs_data::Record;
use tfs_library::{HistoryEntry, Model, RecordScore};

use crate::effects::{Catalogue, EffectColumn};
use crate::explain::{
    compress_blocks, cross_validate, design, full_fit, variant_columns, with_equation,
};
use crate::prepare::{DiagnoseOptions, Layout, RecordStates, check_records, dominant_period, rms};
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
/// kept; the extended equation is then refitted on all records. The model's history gets a
/// `"start"` entry (if empty) and an `"add <name>"` entry with the R-MSE of every record.
pub fn add_effect_with(
    model: &Model,
    effect_name: &str,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
) -> Result<Model> {
    let (effect, dofs) = targets(model, effect_name)?;
    let eff = catalogue.get(&effect)?;
    let states = prepare(model, records, opts)?;
    let layout = Layout::new(&states, opts)?;
    let dt = records[0].dt();
    let mut out = model.clone();
    let mut added = Vec::new();
    let mut details = Vec::new();
    for idx in dofs {
        let base: Vec<tfs_library::Term> = model.equations[idx]
            .terms
            .iter()
            .map(|t| t.term.clone())
            .collect();
        let dof = &model.dofs[idx];
        let vname = format!("{dof}'");
        let mut vel = Vec::new();
        let mut periods = Vec::new();
        let (mut xsum, mut xn) = (0.0, 0usize);
        for s in &states {
            let v = tfs_data::Columns::column(s, &vname).unwrap_or(&[]);
            vel.extend_from_slice(&v[s.margin..s.margin + s.usable()]);
            let x = tfs_data::Columns::column(s, dof).unwrap_or(&[]);
            periods.push(dominant_period(x, s.record.dt())?);
            let used = &x[s.margin.min(x.len())..(s.margin + s.usable()).min(x.len())];
            xsum += used.iter().sum::<f64>();
            xn += used.len();
        }
        periods.sort_by(f64::total_cmp);
        let ctx = crate::effects::EffectContext {
            model,
            dof,
            terms: base.clone(),
            velocity_scale: rms(&vel),
            period: periods[periods.len() / 2],
            dt,
            max_power: opts.max_power,
            displacement_mean: if xn > 0 { xsum / xn as f64 } else { 0.0 },
        };
        let variants = eff.variants(&ctx);
        if variants.is_empty() {
            return Err(DiagnoseError::NotApplicable {
                name: effect_name.to_string(),
                reason: format!(
                    "does not apply to the equation of '{dof}' (its terms are already there, or it needs an input/velocity scale the data lacks)"
                ),
            });
        }
        let mut best: Option<(f64, Vec<EffectColumn>, crate::effects::Variant)> = None;
        for v in &variants {
            let (cols, _) = variant_columns(&base, v);
            let d = design(&states, idx, &cols)?;
            let cv = cross_validate(&compress_blocks(&d, &layout)?, &layout)?;
            let rss: f64 = cv.heldout.iter().sum();
            if best.as_ref().is_none_or(|b| rss < b.0) {
                best = Some((rss, cols, v.clone()));
            }
        }
        let Some((_, cols, v)) = best else { continue };
        let d = design(&states, idx, &cols)?;
        let coef = full_fit(&compress_blocks(&d, &layout)?)?;
        out = with_equation(&out, idx, &cols, &coef)?;
        for c in v.add.iter().chain(v.replace.iter().map(|(_, c)| c)) {
            added.push(c.label());
        }
        details.push(json!({"dof": dof, "parameter": v.parameter}));
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
    let (scores, failed) = try_scores(&out, records);
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
    let mut ok = Vec::new();
    let mut failed = Vec::new();
    for r in records {
        match crate::simulate::r_mse(model, r) {
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
    /// Mean R-MSE over the step's records (NaN when none were scored).
    pub mean_r_mse: f64,
    /// R-MSE per record.
    pub r_mse: Vec<RecordScore>,
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
            r_mse: h.r_mse.clone(),
        })
        .collect()
}

/// The ladder as a plain-text table (step, added terms, mean R-MSE, factor versus the previous
/// step).
pub fn ladder_table(ladder: &[LadderStep]) -> String {
    let mut s = format!(
        "{:<28} {:>12} {:>9}  added\n",
        "step", "mean R-MSE", "factor"
    );
    let mut prev: Option<f64> = None;
    for st in ladder {
        let factor = match prev {
            Some(p) if st.mean_r_mse > 0.0 => format!("{:.2}x", p / st.mean_r_mse),
            _ => "-".into(),
        };
        s.push_str(&format!(
            "{:<28} {:>12.4e} {:>9}  {}\n",
            st.step,
            st.mean_r_mse,
            factor,
            st.added.join(", ")
        ));
        prev = Some(st.mean_r_mse);
    }
    s
}
