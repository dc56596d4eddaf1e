//! Refitting an equation with an added effect toward the start model.
//!
//! The equation-error least squares of all columns at once (the "free" fit) re-estimates the
//! model's own terms on the smoothed states as well: where they are nearly collinear with each
//! other or with the added column (neighbouring powers of a displacement that stays on one side
//! of zero; a damper beside a friction law), noise and the smoothing move them along the
//! collinear direction, which costs little equation error inside the records' range and
//! changes the force a lot outside it. The start model's coefficients came from a fit that
//! already weighed that (the identification's own criteria), and its free runs were checked. So
//! the refit also considers the *held* fit — the model's own terms at their start values, only
//! the new columns estimated on what they leave — and fits in between, ridge-regularised
//! toward the start values (each deviation weighted by its column's norm, so the penalty does
//! not depend on units), and keeps the one that simulates the fit records best
//! ([`choose_anchor`]).
//!
//! None of those fits is the start model itself, and each can predict the fit records worse
//! than it: an equation-error estimate overshoots where the start already absorbed part of the
//! missing force or the smoothed states bias the new column. The kept fit is therefore
//! compared with the start model under the same rulers, and when it is not better the step
//! toward it is searched ([`line_search`]): `start + a·(fit − start)` for a few `a` in (0, 1),
//! `a = 0` being the start model. The refit so never ends worse than where it started on its own
//! records; a step of 0 means the effect adds nothing there, and the model returned is the
//! start's equations.

use faer::Mat;
use rayon::prelude::*;
use tfs_data::Record;
use tfs_library::{Equation, Model, ModelTerm, Term};
use tfs_regress::{Compressed, LeastSquares, Regressor};

use crate::Result;
use crate::design::with_equation;
use crate::effects::EffectColumn;
use crate::predict::PredictionScore;
use crate::prepare::DiagnoseOptions;

/// The relative ridge weights between the held and the free fits: a deviation `δ_j` from the
/// start value of column `j` costs `λ·‖a_j‖²·δ_j²`, equation error's own cost of moving the
/// column's force by that much when the columns are orthogonal. A decade apart, from a penalty
/// that barely restrains a well-determined column to one that holds even weakly collinear
/// ones.
pub const RIDGE: [f64; 4] = [1e-3, 1e-2, 1e-1, 1.0];

/// One way of refitting: how far the model's own terms may leave their start values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Anchor {
    /// The model's own terms at their start values; only the new columns are estimated.
    Held,
    /// Ridge toward the start values with relative weight λ ([`RIDGE`]).
    Ridge(f64),
    /// Every column estimated freely (plain least squares).
    Free,
}

impl Anchor {
    /// Every anchor, from the most held to the free fit.
    pub fn all() -> Vec<Anchor> {
        let mut v = vec![Anchor::Held];
        v.extend(RIDGE.iter().rev().map(|&l| Anchor::Ridge(l)));
        v.push(Anchor::Free);
        v
    }

    /// A short label for the history's details.
    pub fn label(&self) -> String {
        match self {
            Anchor::Held => "held".into(),
            Anchor::Ridge(l) => format!("ridge {l:e}"),
            Anchor::Free => "free".into(),
        }
    }
}

/// Per column of `cols`, the start value when it is one of the model's own terms of DOF `idx`
/// as it stands (a plain term, not computed, not centred), else `None` (a new column).
pub(crate) fn start_values(model: &Model, idx: usize, cols: &[EffectColumn]) -> Vec<Option<f64>> {
    cols.iter()
        .map(|c| {
            if c.computed.is_some() || c.centre.is_some() {
                return None;
            }
            model.equations[idx]
                .terms
                .iter()
                .find(|t| t.term == c.term)
                .map(|t| t.coef)
        })
        .collect()
}

/// The coefficients of the merged compressed problem `p` under `anchor`, with `start` from
/// [`start_values`]. A column without a start value is always free; without any start value
/// every anchor is the free fit.
pub(crate) fn fit(p: &Compressed, start: &[Option<f64>], anchor: Anchor) -> Result<Vec<f64>> {
    let n = p.ncols();
    let free_fit = || -> Result<Vec<f64>> { Ok(LeastSquares.fit_compressed(p)?.coef) };
    if start.iter().all(Option::is_none) || anchor == Anchor::Free {
        return free_fit();
    }
    let r = p.r();
    let c = p.c();
    match anchor {
        Anchor::Held => {
            let free: Vec<usize> = (0..n).filter(|&j| start[j].is_none()).collect();
            let mut coef: Vec<f64> = start.iter().map(|s| s.unwrap_or(0.0)).collect();
            if free.is_empty() {
                return Ok(coef);
            }
            // ‖R x − c‖ with the held columns moved to the target.
            let target: Vec<f64> = (0..n)
                .map(|i| {
                    c[i] - (0..n)
                        .filter_map(|j| start[j].map(|s| r[(i, j)] * s))
                        .sum::<f64>()
                })
                .collect();
            let a = Mat::from_fn(n, free.len(), |i, k| r[(i, free[k])]);
            let sub = LeastSquares.fit_compressed(&Compressed::from_rows(a.as_ref(), &target)?)?;
            for (k, &j) in free.iter().enumerate() {
                coef[j] = sub.coef[k];
            }
            Ok(coef)
        }
        Anchor::Ridge(lambda) => {
            let norms = p.column_norms();
            let held: Vec<usize> = (0..n).filter(|&j| start[j].is_some()).collect();
            let rows = n + held.len();
            let mut a = Mat::<f64>::zeros(rows, n);
            let mut b = vec![0.0; rows];
            for i in 0..n {
                for j in i..n {
                    a[(i, j)] = r[(i, j)];
                }
                b[i] = c[i];
            }
            for (k, &j) in held.iter().enumerate() {
                let w = lambda.sqrt() * norms[j];
                a[(n + k, j)] = w;
                b[n + k] = w * start[j].unwrap_or(0.0);
            }
            Ok(LeastSquares
                .fit_compressed(&Compressed::from_rows(a.as_ref(), &b)?)?
                .coef)
        }
        Anchor::Free => free_fit(),
    }
}

/// The refit [`choose_anchor`] kept.
pub(crate) struct Anchored {
    pub(crate) model: Model,
    /// The anchor's label ([`Anchor::label`]), or `refined` for the simulation-error fit.
    pub(crate) anchor: String,
    /// Whether the kept fit is of the whole start library ([`Planned::whole`]).
    pub(crate) whole: bool,
    /// The step toward the best fit kept ([`line_search`]): 1 when that fit predicts the fit
    /// records better than the start model, 0 when the start model is kept (nothing added).
    pub(crate) step: f64,
    /// Each anchor's R-MSE on each fit record (`null`: the simulation failed).
    pub(crate) scores: Vec<(String, Vec<f64>)>,
    /// The kept model's R-MSE on each fit record by its own free run (infinite where the
    /// simulation failed or was not finite, where the record was scored by pieces, and on every
    /// record when the kept model is a refit: its runs here started warm from the start
    /// model's fitted start, and the history reports the run a user of the model gets, whose
    /// start is fitted cold).
    pub(crate) each: Vec<f64>,
}

/// One target DOF's refit to be made: its equation's columns with the effect, their merged
/// compressed rows, the start value of each column ([`start_values`]), and the
/// partner equations a coupling force also enters (index, columns, coefficients).
pub(crate) struct Planned {
    pub(crate) idx: usize,
    pub(crate) cols: Vec<EffectColumn>,
    pub(crate) merged: Compressed,
    pub(crate) partners: Vec<(usize, Vec<EffectColumn>, Vec<f64>)>,
    /// The same equation with every start-library term it still lacks (their names, merged
    /// rows, columns), when there are any.
    pub(crate) whole: Option<(Vec<String>, Compressed, Vec<EffectColumn>)>,
}

/// Refits every planned equation under each [`Anchor`] toward `model`'s coefficients (one
/// anchor for all target DOFs, so a coupling force added to both masses stays one law), with
/// the partners' equations as they were fitted, and keeps the model whose free runs predict the
/// fit `records` best ([`sim_key`]: fewest failed records, then the lowest geometric-mean
/// R-MSE; ties go to the more held anchor). With `opts.refine_added`, the kept fit is then
/// re-estimated by simulation error ([`refined`]) and that fit replaces it when it predicts
/// the records better by the same key; and a record on which the input's own noise decides
/// `model`'s free run is scored, for every fit alike, by short-horizon predictions from its
/// measured state ([`PredictionScore::choose`]): there a free run's R-MSE says which well
/// the noise put the run in, not which fit is closer. The start model is scored under the same
/// rulers; with `search`, a kept fit that does not predict the records better than it is
/// replaced by the best step toward it ([`line_search`]; the start model itself when no step
/// helps). See the module docs.
pub(crate) fn choose_anchor(
    model: &Model,
    plans: &[Planned],
    records: &[Record],
    opts: &DiagnoseOptions,
    search: bool,
) -> Result<Anchored> {
    let mut fits = Vec::new();
    let whole = plans.iter().any(|p| p.whole.is_some());
    for with_rest in [false, true].into_iter().filter(|w| !w || whole) {
        for anchor in Anchor::all() {
            let mut m = model.clone();
            for p in plans {
                let (merged, cols) = match (&p.whole, with_rest) {
                    (Some((_, wm, wc)), true) => (wm, wc),
                    _ => (&p.merged, &p.cols),
                };
                let start = start_values(model, p.idx, cols);
                let coef = fit(merged, &start, anchor)?;
                m = with_equation(&m, p.idx, cols, &coef)?;
                for (pi, pcols, pcoef) in &p.partners {
                    m = with_equation(&m, *pi, pcols, pcoef)?;
                }
            }
            let label = if with_rest {
                format!("{}, whole library", anchor.label())
            } else {
                anchor.label()
            };
            fits.push((label, m, with_rest));
        }
    }
    // A fit whose added stop pulls its coordinate into the contact is no stop
    // ([`crate::effects::stop_pushes_out`]); when every fit does that, nothing is added.
    fits.retain(|(_, m, _)| !pulls_a_stop(model, m, plans));
    let rulers = rulers(model, records, opts);
    if fits.is_empty() {
        let start = r_mse_each(model, None, records, &rulers, opts);
        let each = start
            .iter()
            .zip(&rulers)
            .map(|(&v, r)| {
                if r.horizon.is_none() {
                    v
                } else {
                    f64::INFINITY
                }
            })
            .collect();
        return Ok(Anchored {
            model: model.clone(),
            anchor: "none: every fit's stop pulls into its contact".into(),
            whole: false,
            step: 0.0,
            scores: vec![("start".into(), start)],
            each,
        });
    }
    // The start model is scored under the same rulers (the kept fit is compared with it), and
    // first: its fitted starts warm the fits' runs ([`r_mse_each`]). Then the fits side by
    // side; the choice is made in anchor order, as a serial loop would.
    let start = r_mse_each(model, None, records, &rulers, opts);
    let mut each: Vec<Vec<f64>> = fits
        .par_iter()
        .map(|(_, m, _)| r_mse_each(m, Some(model), records, &rulers, opts))
        .collect();
    let mut pick = 0;
    for (k, e) in each.iter().enumerate() {
        if better(sim_key(e), sim_key(&each[pick])) {
            pick = k;
        }
    }
    if opts.refine_added
        && let Some((m, e)) = refined(&fits[pick].1, model, records, &rulers, opts)
        && !pulls_a_stop(model, &m, plans)
    {
        let w = fits[pick].2;
        let label = if w {
            "refined, whole library"
        } else {
            "refined"
        };
        fits.push((label.into(), m, w));
        each.push(e);
        if better(sim_key(&each[fits.len() - 1]), sim_key(&each[pick])) {
            pick = fits.len() - 1;
        }
    }
    let mut scores: Vec<(String, Vec<f64>)> = fits
        .iter()
        .zip(&each)
        .map(|((a, _, _), e)| (a.clone(), e.clone()))
        .collect();
    scores.push(("start".into(), start.clone()));
    let mut step = 1.0;
    if search && holds(&start) && !better(sim_key(&each[pick]), sim_key(&start)) {
        let Stepped {
            step: a,
            model: m,
            each: e,
            tried,
        } = line_search(model, &fits[pick].1, &each[pick], &start, |m| {
            r_mse_each(m, Some(model), records, &rulers, opts)
        })?;
        scores.extend(tried);
        step = a;
        let label = if a == 0.0 {
            "none: the start model".to_string()
        } else {
            format!("{}, step {a}", fits[pick].0)
        };
        fits.push((label, m, fits[pick].2 && a > 0.0));
        each.push(e);
        pick = fits.len() - 1;
    }
    let (anchor, kept, whole) = fits.swap_remove(pick);
    // The history holds free-run R-MSEs of cold-started runs: a record scored by pieces, or a
    // refit's warm-started run, is simulated again for it.
    let cold = kept.equations == model.equations;
    let each = each
        .swap_remove(pick)
        .into_iter()
        .zip(&rulers)
        .map(|(v, r)| {
            if r.horizon.is_none() && cold {
                v
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let model = kept;
    Ok(Anchored {
        model,
        anchor,
        whole,
        step,
        scores,
        each,
    })
}

/// Whether `m`, a refit of `model` by `plans`, holds a stop that `model`'s equation did not have
/// (in a planned equation or a partner's) whose coefficient pulls its coordinate into the
/// contact ([`crate::effects::stop_pushes_out`]).
fn pulls_a_stop(model: &Model, m: &Model, plans: &[Planned]) -> bool {
    let eqs = plans
        .iter()
        .flat_map(|p| std::iter::once(p.idx).chain(p.partners.iter().map(|(pi, _, _)| *pi)));
    eqs.into_iter().any(|i| {
        let (Some(before), Some(after), Some(dof)) =
            (model.equations.get(i), m.equations.get(i), m.dofs.get(i))
        else {
            return false;
        };
        after.terms.iter().any(|t| {
            !before.terms.iter().any(|o| o.term == t.term)
                && crate::effects::stop_pushes_out(&t.term, dof, t.coef) == Some(false)
        })
    })
}

/// Whether the start model's scores `start` (one per record) are a baseline the refit must not
/// fall below: it simulates every record. A start that fails on some record is no such
/// baseline; which candidate cures the failures is the decision's question (its control is the
/// start's own terms refitted), and a tie among failing fits would otherwise go to the start
/// and drop the candidate before it is asked.
pub(crate) fn holds(start: &[f64]) -> bool {
    sim_key(start).0 == 0
}

/// The steps [`line_search`] tries toward a fit that does not predict the fit records better
/// than the start model, halving from the half step: the smallest moves the added effect's
/// coefficients by a sixteenth of the fit's, where its sign and shape are kept but the
/// overshoot of an equation-error estimate (a collinear power, a biased smoothed state) is
/// mostly gone.
pub const STEPS: [f64; 4] = [0.0625, 0.125, 0.25, 0.5];

/// What [`line_search`] kept.
pub(crate) struct Stepped {
    /// The step kept: 0 is the start model (nothing added), 1 the fit.
    pub(crate) step: f64,
    /// The model at that step.
    pub(crate) model: Model,
    /// Its score on each record.
    pub(crate) each: Vec<f64>,
    /// Each step tried (`step a`) with its score on each record.
    pub(crate) tried: Vec<(String, Vec<f64>)>,
}

/// The line search on an added effect's step, when the kept fit `fit` (scores `fit_each`) does
/// not predict the fit records better than `start` itself (scores `start_each`, by [`sim_key`]):
/// `start + a·(fit − start)` coefficient-wise ([`toward`]) for every `a` of [`STEPS`], scored by
/// `score` side by side. Returns the step kept (0: the start model, nothing added; 1: `fit`),
/// its model and scores, and each step tried with its scores (for the history). The kept step
/// is the best by [`sim_key`]; ties go to the smaller step, so a step that changes nothing the
/// records can see leaves the start model. The result is never worse than the start model on
/// the records `score` simulates.
pub(crate) fn line_search(
    start: &Model,
    fit: &Model,
    fit_each: &[f64],
    start_each: &[f64],
    score: impl Fn(&Model) -> Vec<f64> + Sync,
) -> Result<Stepped> {
    let trials: Vec<(f64, Model)> = STEPS
        .iter()
        .map(|&a| Ok((a, toward(start, fit, a)?)))
        .collect::<Result<_>>()?;
    let scored: Vec<Vec<f64>> = trials.par_iter().map(|(_, m)| score(m)).collect();
    let tried = trials
        .iter()
        .zip(&scored)
        .map(|((a, _), e)| (format!("step {a}"), e.clone()))
        .collect();
    // From the start (a = 0) up to the fit (a = 1): the first of the best is kept.
    let mut best: (f64, Option<usize>, &[f64]) = (0.0, None, start_each);
    for (k, e) in scored.iter().enumerate() {
        if better(sim_key(e), sim_key(best.2)) {
            best = (trials[k].0, Some(k), e);
        }
    }
    if better(sim_key(fit_each), sim_key(best.2)) {
        return Ok(Stepped {
            step: 1.0,
            model: fit.clone(),
            each: fit_each.to_vec(),
            tried,
        });
    }
    let each = best.2.to_vec();
    let model = match best.1 {
        Some(k) => trials[k].1.clone(),
        None => {
            let mut m = start.clone();
            m.history = fit.history.clone();
            m
        }
    };
    Ok(Stepped {
        step: best.0,
        model,
        each,
        tried,
    })
}

/// The model `start + a·(fit − start)`, coefficient by coefficient over the union of both
/// models' terms in each equation (a term one model lacks counts as 0 there; zero coefficients
/// are left out): `a = 0` is `start`'s equations exactly, `a = 1` is `fit`'s. The added
/// effect's columns start at 0, so a small `a` adds a fraction of the effect and moves the
/// model's own terms a fraction of the way to their refitted values. History and trace are
/// `fit`'s. Both models must have the same DOFs.
pub(crate) fn toward(start: &Model, fit: &Model, a: f64) -> Result<Model> {
    let equations = start
        .equations
        .iter()
        .zip(&fit.equations)
        .map(|(s, f)| {
            let mut terms: Vec<(Term, f64)> = s
                .terms
                .iter()
                .map(|t| (t.term.clone(), (1.0 - a) * t.coef))
                .collect();
            for t in &f.terms {
                match terms.iter_mut().find(|(m, _)| *m == t.term) {
                    Some(slot) => slot.1 += a * t.coef,
                    None => terms.push((t.term.clone(), a * t.coef)),
                }
            }
            Equation {
                dof: s.dof.clone(),
                terms: terms
                    .into_iter()
                    .filter(|(_, c)| *c != 0.0 && c.is_finite())
                    .map(|(t, c)| ModelTerm::new(t, c))
                    .collect(),
            }
        })
        .collect();
    let mut m = Model::new(fit.dofs.clone(), equations, fit.method.clone())?;
    m.trace = fit.trace.clone();
    m.history = fit.history.clone();
    Ok(m)
}

/// One ruler per record, chosen from the start `model`: the free run unless `opts` refines
/// the added effect, then [`PredictionScore::choose`] per record.
pub(crate) fn rulers(
    model: &Model,
    records: &[Record],
    opts: &DiagnoseOptions,
) -> Vec<PredictionScore> {
    if opts.refine_added {
        records
            .par_iter()
            .map(|r| {
                PredictionScore::choose(model, &[], r, opts)
                    .unwrap_or_else(|_| PredictionScore::free_run())
            })
            .collect()
    } else {
        vec![PredictionScore::free_run(); records.len()]
    }
}

/// How well free runs with R-MSE `each` (one per record, infinite where the simulation failed)
/// predict the records: (records failed, geometric mean R-MSE of the others,
/// [`crate::stats::geometric_mean_r_mse`]).
pub(crate) fn sim_key(each: &[f64]) -> (usize, f64) {
    let failed = each.iter().filter(|v| !v.is_finite()).count();
    (failed, crate::stats::geometric_mean_r_mse(each))
}

/// Whether key `a` ([`sim_key`]) is strictly better than `b`.
pub(crate) fn better(a: (usize, f64), b: (usize, f64)) -> bool {
    a.0 < b.0 || (a.0 == b.0 && a.1 < b.1)
}

/// `model`'s coefficients re-estimated by simulation error on `records`
/// ([`tfs_refine::refine`]: multiple shooting from the records' own states, records whose
/// free-run error the input's noise dominates left out), with its R-MSE on each record; `None`
/// when refinement cannot run on this model or returns it unchanged. Each record is scored by
/// its ruler in `rulers`, the run warmed by the start model `start`'s ([`r_mse_each`]).
fn refined(
    model: &Model,
    start: &Model,
    records: &[Record],
    rulers: &[PredictionScore],
    opts: &DiagnoseOptions,
) -> Option<(Model, Vec<f64>)> {
    let train: Vec<Record> = records
        .iter()
        .map(|r| crate::simulate::augment_record(model, r, &DiagnoseOptions::default()))
        .collect::<Result<_>>()
        .ok()?;
    let out = tfs_refine::refine(model, &train, &tfs_refine::RefineOptions::default()).ok()?;
    if out.model.equations == model.equations {
        return None;
    }
    // The refinement's own history step is not the ladder's: the added effect's step is.
    let mut m = out.model;
    m.history = model.history.clone();
    let each = r_mse_each(&m, Some(start), records, rulers, opts);
    Some((m, each))
}

/// R-MSE of `model` on each of `records`, each under its ruler in `rulers` (infinite where a
/// simulation fails), the records side by side. With `near` (the start model `model` is a refit
/// of), a free run's start-state fit begins at `near`'s fitted start on the record
/// ([`PredictionScore::r_mse_near`]): one fit instead of two.
pub(crate) fn r_mse_each(
    model: &Model,
    near: Option<&Model>,
    records: &[Record],
    rulers: &[PredictionScore],
    opts: &DiagnoseOptions,
) -> Vec<f64> {
    records
        .par_iter()
        .zip(rulers)
        .map(|(r, ruler)| match ruler.r_mse_near(model, near, r, opts) {
            Ok(v) if v.is_finite() => v,
            _ => f64::INFINITY,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The anchor choice's key: a fit that fails a record loses to one that simulates every
    /// record; among those that simulate, one record whose free run departs under every fit
    /// (R-MSE ≫ 1, as a multi-stable record that settles in the other well) does not decide —
    /// the fit that predicts the other records better wins, which an arithmetic mean gets
    /// backwards here.
    #[test]
    fn the_kept_fit_is_not_chosen_by_the_one_record_every_fit_misses() {
        let a = [98.0, 0.0014, 0.066];
        let b = [87.0, 0.008, 0.021];
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        assert!(mean(&b) < mean(&a));
        assert!(better(sim_key(&a), sim_key(&b)));
        let failed = [f64::INFINITY, 1e-4, 1e-4];
        assert!(better(sim_key(&[5.0, 5.0, 5.0]), sim_key(&failed)));
        assert_eq!(sim_key(&failed).0, 1);
        assert!(!better(sim_key(&a), sim_key(&a)));
        assert_eq!(sim_key(&[f64::INFINITY]), (1, f64::INFINITY));
    }

    /// Two nearly collinear columns and a new one: the held fit keeps the start values and
    /// fits the new column on what they leave; the ridge fits move from the held fit toward
    /// the free fit as λ falls; the free fit is plain least squares.
    #[test]
    fn anchors_run_from_the_start_values_to_least_squares() {
        let n = 200;
        let x: Vec<f64> = (0..n).map(|i| 1.0 + i as f64 / n as f64).collect();
        let noise = |i: usize| ((i * 7919 % 101) as f64 / 101.0 - 0.5) * 1e-3;
        let a = Mat::from_fn(n, 3, |i, j| match j {
            0 => x[i].powi(5),
            1 => x[i].powi(6),
            _ => (i as f64 * 0.3).sin(),
        });
        let b: Vec<f64> = (0..n)
            .map(|i| -2.0 * a[(i, 0)] + 1.0 * a[(i, 1)] + 0.5 * a[(i, 2)] + noise(i))
            .collect();
        let p = Compressed::from_rows(a.as_ref(), &b).unwrap();
        let start = [Some(-2.1), Some(1.05), None];
        let held = fit(&p, &start, Anchor::Held).unwrap();
        assert_eq!(&held[..2], &[-2.1, 1.05]);
        let free = fit(&p, &start, Anchor::Free).unwrap();
        assert!(
            (free[0] + 2.0).abs() < 0.05 && (free[2] - 0.5).abs() < 1e-2,
            "{free:?}"
        );
        let mut last = 0.0;
        for l in RIDGE.iter().rev() {
            let r = fit(&p, &start, Anchor::Ridge(*l)).unwrap();
            let d = (r[0] + 2.1).abs();
            assert!(d >= last - 1e-12, "λ {l}: {r:?}");
            last = d;
        }
        let no_start = fit(&p, &[None, None, None], Anchor::Held).unwrap();
        assert_eq!(no_start, free);
    }

    fn model(json: &str) -> Model {
        Model::from_json_str(&format!(
            r#"{{"format":"tfs-model/1","dofs":["x"],"equations":[{{"dof":"x","terms":[{json}]}}]}}"#
        ))
        .unwrap()
    }

    fn coef(m: &Model, t: &str) -> f64 {
        m.equations[0]
            .terms
            .iter()
            .find(|x| x.term.to_string() == t)
            .map_or(0.0, |x| x.coef)
    }

    /// A step from the start model toward a fit that replaced one of its terms and added one:
    /// step 0 is the start's equations exactly, step 1 the fit's, and a step between moves every
    /// coefficient of either model that far, the replaced term fading and the new one growing.
    #[test]
    fn a_step_runs_from_the_start_model_to_the_fit() {
        let start = model(r#"{"term":"x","coef":-4.0},{"term":"xb_acc","coef":-1.0}"#);
        let fit = model(
            r#"{"term":"x","coef":-2.0},{"term":"xb_acc_lowpass_0p01","coef":-0.8},{"term":"x^3","coef":-0.5}"#,
        );
        assert_eq!(
            toward(&start, &fit, 0.0).unwrap().equations,
            start.equations
        );
        let one = toward(&start, &fit, 1.0).unwrap();
        for t in ["x", "xb_acc_lowpass_0p01", "x^3"] {
            assert_eq!(coef(&one, t), coef(&fit, t), "{t}");
        }
        assert_eq!(coef(&one, "xb_acc"), 0.0);
        let q = toward(&start, &fit, 0.25).unwrap();
        assert_eq!(coef(&q, "x"), -3.5);
        assert_eq!(coef(&q, "xb_acc"), -0.75);
        assert_eq!(coef(&q, "xb_acc_lowpass_0p01"), -0.2);
        assert_eq!(coef(&q, "x^3"), -0.125);
        assert_eq!(q.inputs.len(), 2, "{:?}", q.inputs);
    }

    /// The line search keeps the best step by the records' key, the smaller of equals: the
    /// start model (step 0, its equations exactly) when every step predicts worse or no better,
    /// a step between when the fit overshoots, and the fit only when it is better than every
    /// step and the start.
    #[test]
    fn the_line_search_never_ends_worse_than_the_start() {
        let start = model(r#"{"term":"x","coef":-4.0}"#);
        let fit = model(r#"{"term":"x","coef":-4.0},{"term":"x^3","coef":-1.0}"#);
        let run = |best: f64| {
            // A record's R-MSE as a function of the added coefficient, least at `-best`.
            let score = |m: &Model| vec![1e-3 * (1.0 + (coef(m, "x^3") + best).powi(2))];
            let (s0, s1) = (score(&start), score(&fit));
            line_search(&start, &fit, &s1, &s0, score).unwrap()
        };
        // The fit's direction is wrong: the start model is kept, nothing added.
        let s = run(-0.3);
        assert_eq!(s.step, 0.0);
        assert_eq!(s.model.equations, start.equations);
        assert_eq!(s.each, vec![1e-3 * (1.0 + 0.09)]);
        assert_eq!(s.tried.len(), STEPS.len());
        // The fit overshoots fourfold: the quarter step.
        let s = run(0.25);
        assert_eq!(s.step, 0.25);
        assert_eq!(coef(&s.model, "x^3"), -0.25);
        // The fit is right: kept.
        let s = run(1.0);
        assert_eq!(s.step, 1.0);
        assert_eq!(s.model.equations, fit.equations);
        // Nothing the records can see changes: the start.
        let flat = |_: &Model| vec![2e-3];
        let s = line_search(&start, &fit, &[2e-3], &[2e-3], flat).unwrap();
        assert_eq!((s.step, s.model.equations), (0.0, start.equations.clone()));
    }
}
