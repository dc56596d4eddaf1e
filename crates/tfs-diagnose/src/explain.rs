//! Explain: refit the model's structure plus each catalogue effect by equation error, score it on
//! held-out blocks, test it, size it, and rank the effects.
//!
//! Per DOF equation, rows are the usable samples of every record: target the smoothed `x''`,
//! columns the equation's terms (plus the effect's) evaluated on smoothed states. Rows are cut
//! into contiguous blocks, each compressed once (`tfs_regress::Compressed`); folds are records
//! (several records) or time segments (one record). For a candidate, every fold is fitted on the
//! other folds' blocks, and each held-out block's residual sum of squares is read off its small
//! factor. The significance test combines three looks (Bonferroni over the three): the per-block
//! held-out drop `RSS_base,b − RSS_cand,b` and the log-ratio `ln(RSS_base,b / RSS_cand,b)`, each
//! tested one-sided against zero with a t statistic over blocks (the drop weighs blocks by their
//! error, the log-ratio treats quiet and loud blocks alike), and — for an effect that adds a
//! column — the block-robust (cluster sandwich) Wald test of the added coefficient on all data.
//! The Wald test is the direct test of a small effect whose held-out RSS drop is buried in
//! noise-dominated blocks (a constant offset confounded with a high-power restoring polynomial).
//! Blocks are long enough — four cut-off periods or more — to be nearly independent. The
//! combined p-value is Bonferroni-corrected over every variant of every effect tested. An effect is significant when the corrected p-value is below
//! `alpha`, the held-out error falls, and its size (RMS change of the fitted force over the RMS of
//! `x''`) is at least `min_share`. Significant effects are ranked by the held-out simulation
//! R-MSE of the refitted model (an equation-error gain that does not survive simulation ranks
//! lower), the rest by held-out equation-error improvement.

use faer::Mat;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use tfs_data::Record;
use tfs_library::{ColumnSet, Equation, Model, ModelTerm, Term, evaluate_term};
use tfs_regress::{Compressed, LeastSquares, Regressor};

use crate::effects::{Catalogue, EffectColumn, EffectContext, Variant};
use crate::prepare::{DiagnoseOptions, Layout, RecordStates, rms};
use crate::{DiagnoseError, Result};

/// The evidence for one effect on one DOF (its best variant).
#[derive(Debug, Clone, Serialize)]
pub struct RankedEffect {
    /// What `--add` accepts: the effect name, with `@dof` for multi-DOF models.
    pub name: String,
    /// The catalogue effect.
    pub effect: String,
    /// The DOF whose equation was extended.
    pub dof: String,
    /// The scanned parameter's name and best value, if any.
    pub parameter: Option<(String, f64)>,
    /// The terms added (or substituted) by the best variant.
    pub terms: Vec<String>,
    /// Passed the test, the size threshold and lowered the held-out error.
    pub significant: bool,
    /// One-sided p-value of the paired block test (uncorrected).
    pub p_value_raw: f64,
    /// p-value after the Bonferroni correction over every variant tested.
    pub p_value: f64,
    /// Relative drop of held-out equation error, `(RSS_base − RSS_cand)/RSS_base`.
    pub delta_heldout: f64,
    /// Coefficient of the main effect column (full-data fit).
    pub coef: f64,
    /// 95 % block-bootstrap interval of that coefficient.
    pub interval: [f64; 2],
    /// RMS change of the fitted force over the RMS of `x''`.
    pub share: f64,
    /// Held-out simulation R-MSE of the refitted structure without the effect.
    pub r_mse_before: Option<f64>,
    /// Held-out simulation R-MSE after adding the effect (None if a simulation failed).
    pub r_mse_after: Option<f64>,
    /// Why it is (not) significant, in words.
    pub reason: String,
}

/// Result of [`explain`]: ranked effects and the verdict.
#[derive(Debug, Clone, Serialize)]
pub struct Explanation {
    /// Effects ranked: significant first, then by held-out simulation R-MSE after adding the
    /// effect (the error the user will see), then by held-out equation-error improvement.
    pub ranked: Vec<RankedEffect>,
    /// One sentence: the top significant effect, or "no significant missing effect".
    pub verdict: String,
    /// Number of variants tested (the Bonferroni factor).
    pub tests: usize,
    /// Cut-off (Hz) used for the smoothed states, per record.
    pub cutoff_hz: Vec<f64>,
    /// Folds are records (true) or time segments (false).
    pub folds_by_record: bool,
    /// Number of held-out blocks.
    pub blocks: usize,
}

/// Design matrices of one equation: per record, usable rows × columns, and the target.
pub(crate) struct Design {
    pub a: Vec<Mat<f64>>,
    pub b: Vec<Vec<f64>>,
}

/// Evaluates `columns` for DOF `dof_idx` on every record's usable rows.
pub(crate) fn design(
    states: &[RecordStates],
    dof_idx: usize,
    columns: &[EffectColumn],
) -> Result<Design> {
    let mut a = Vec::with_capacity(states.len());
    let mut b = Vec::with_capacity(states.len());
    for s in states {
        let dt = s.record.dt();
        let mut set = ColumnSet::new(s);
        for c in columns {
            if let Some(cc) = &c.computed
                && tfs_data::Columns::column(s, &cc.name()).is_none()
            {
                let v = cc.compute(s, dt)?;
                set.insert(cc.name(), v)?;
            }
        }
        let (lo, n) = (s.margin, s.usable());
        let cols: Vec<Vec<f64>> = columns
            .iter()
            .map(|c| -> Result<Vec<f64>> {
                let mut out = vec![0.0; n];
                for (t, w) in c.expansion() {
                    let v = evaluate_term(&t, &set)?;
                    for (o, x) in out.iter_mut().zip(&v[lo..lo + n]) {
                        *o += w * x;
                    }
                }
                Ok(out)
            })
            .collect::<Result<_>>()?;
        a.push(Mat::from_fn(n, columns.len(), |i, j| cols[j][i]));
        b.push(s.acc[dof_idx][lo..lo + n].to_vec());
    }
    Ok(Design { a, b })
}

/// Compresses every block of the layout.
pub(crate) fn compress_blocks(d: &Design, layout: &Layout) -> Result<Vec<Compressed>> {
    layout
        .blocks
        .iter()
        .map(|bl| {
            let a = d.a[bl.record].as_ref().subrows(bl.start, bl.len);
            Ok(Compressed::from_rows(
                a,
                &d.b[bl.record][bl.start..bl.start + bl.len],
            )?)
        })
        .collect()
}

/// Cross-validated fit: per-fold coefficients and per-block held-out RSS.
pub(crate) struct Cv {
    pub coefs: Vec<Vec<f64>>,
    pub heldout: Vec<f64>,
}

pub(crate) fn cross_validate(blocks: &[Compressed], layout: &Layout) -> Result<Cv> {
    let mut coefs = Vec::with_capacity(layout.folds);
    let mut heldout = vec![0.0; blocks.len()];
    for f in 0..layout.folds {
        let train: Vec<(&Compressed, usize)> = blocks
            .iter()
            .zip(&layout.blocks)
            .filter(|(_, bl)| bl.fold != f)
            .map(|(c, _)| (c, 1))
            .collect();
        let merged = Compressed::merge_counted(&train)?;
        let fit = LeastSquares.fit_compressed(&merged)?;
        for (i, bl) in layout.blocks.iter().enumerate() {
            if bl.fold == f {
                heldout[i] = blocks[i].rss(&fit.coef)?;
            }
        }
        coefs.push(fit.coef);
    }
    Ok(Cv { coefs, heldout })
}

/// Full-data least squares on all blocks.
pub(crate) fn full_fit(blocks: &[Compressed]) -> Result<Vec<f64>> {
    let all: Vec<(&Compressed, usize)> = blocks.iter().map(|c| (c, 1)).collect();
    Ok(LeastSquares
        .fit_compressed(&Compressed::merge_counted(&all)?)?
        .coef)
}

/// One-sided p-value of `mean(d) > 0` with a t statistic over `d.len()` blocks
/// (t → z by the Cornish–Fisher-type approximation `z = t(1 − 1/4ν)/√(1 + t²/2ν)`).
pub fn paired_p_value(d: &[f64]) -> f64 {
    let b = d.len();
    if b < 2 {
        return 1.0;
    }
    let mean = d.iter().sum::<f64>() / b as f64;
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (b - 1) as f64;
    if var <= 0.0 {
        return if mean > 0.0 { 0.0 } else { 1.0 };
    }
    let t = mean / (var / b as f64).sqrt();
    t_upper_tail(t, (b - 1) as f64)
}

/// Upper-tail probability of a t statistic with `nu` degrees of freedom
/// (t → z by `z = t(1 − 1/4ν)/√(1 + t²/2ν)`).
fn t_upper_tail(t: f64, nu: f64) -> f64 {
    let z = t * (1.0 - 1.0 / (4.0 * nu)) / (1.0 + t * t / (2.0 * nu)).sqrt();
    0.5 * libm::erfc(z / std::f64::consts::SQRT_2)
}

/// Two-sided p-value that coefficient `j` of the least-squares fit `coef` of `d` is zero, with a
/// block-robust (cluster sandwich) variance: blocks are treated as independent, rows inside a
/// block may be correlated (smoothed states are). `Var β = B (Σ_b g_b g_bᵀ) B · n_b/(n_b − 1)`
/// with `B = (AᵀA)⁻¹` and `g_b = A_bᵀ r_b` the block's score; the statistic is referred to a t
/// distribution with `n_b − 1` degrees of freedom. Columns are scaled to unit RMS first (the
/// statistic is scale-invariant; raw-unit columns can span many decades). Returns 1 when the
/// normal matrix is singular.
pub(crate) fn block_wald_p_value(d: &Design, layout: &Layout, coef: &[f64], j: usize) -> f64 {
    let p = coef.len();
    let nb = layout.blocks.len();
    if nb < 3 || j >= p {
        return 1.0;
    }
    let mut scale = vec![0.0f64; p];
    let mut rows = 0usize;
    for bl in &layout.blocks {
        let a = &d.a[bl.record];
        for i in bl.start..bl.start + bl.len {
            for (k, s) in scale.iter_mut().enumerate() {
                *s += a[(i, k)] * a[(i, k)];
            }
        }
        rows += bl.len;
    }
    for s in &mut scale {
        *s = (*s / rows.max(1) as f64).sqrt();
        if !(*s > 0.0 && s.is_finite()) {
            *s = 1.0;
        }
    }
    let mut ata = Mat::<f64>::zeros(p, p);
    let mut scores = Vec::with_capacity(nb);
    for bl in &layout.blocks {
        let a = &d.a[bl.record];
        let b = &d.b[bl.record];
        let mut g = vec![0.0; p];
        for i in bl.start..bl.start + bl.len {
            let fitted: f64 = (0..p).map(|k| a[(i, k)] * coef[k]).sum();
            let r = b[i] - fitted;
            for k in 0..p {
                let ak = a[(i, k)] / scale[k];
                g[k] += ak * r;
                for l in 0..=k {
                    ata[(k, l)] += ak * a[(i, l)] / scale[l];
                }
            }
        }
        scores.push(g);
    }
    for k in 0..p {
        for l in 0..k {
            ata[(l, k)] = ata[(k, l)];
        }
    }
    let Ok(llt) = ata.llt(faer::Side::Lower) else {
        return 1.0;
    };
    let mut e = Mat::<f64>::zeros(p, 1);
    e[(j, 0)] = 1.0;
    let w = faer::linalg::solvers::Solve::solve(&llt, &e);
    let var: f64 = scores
        .iter()
        .map(|g| (0..p).map(|k| w[(k, 0)] * g[k]).sum::<f64>().powi(2))
        .sum::<f64>()
        * nb as f64
        / (nb - 1) as f64;
    let beta = coef[j] * scale[j];
    if !(var > 0.0 && var.is_finite()) {
        return if beta != 0.0 { 0.0 } else { 1.0 };
    }
    (2.0 * t_upper_tail(beta.abs() / var.sqrt(), (nb - 1) as f64)).min(1.0)
}

/// The columns of the equation of `dof` after applying a variant (replacements in place, additions
/// appended); the main column's index is returned too.
pub(crate) fn variant_columns(base: &[Term], v: &Variant) -> (Vec<EffectColumn>, Option<usize>) {
    let mut cols: Vec<EffectColumn> = base
        .iter()
        .map(|t| {
            v.replace
                .iter()
                .find(|(old, _)| old == t)
                .map(|(_, new)| new.clone())
                .unwrap_or_else(|| EffectColumn::term(t.clone()))
        })
        .collect();
    cols.extend(v.add.iter().cloned());
    let main = v
        .main_term()
        .and_then(|m| cols.iter().position(|c| c.term == *m));
    (cols, main)
}

/// A copy of `model` whose equation `dof_idx` is `Σ coef·column`.
pub(crate) fn with_equation(
    model: &Model,
    dof_idx: usize,
    cols: &[EffectColumn],
    coef: &[f64],
) -> Result<Model> {
    let mut equations = model.equations.clone();
    // Centred columns expand into plain powers that merge with the equation's own terms.
    let mut merged: Vec<(Term, f64)> = Vec::new();
    for (c, v) in cols.iter().zip(coef) {
        for (t, w) in c.expansion() {
            match merged.iter_mut().find(|(m, _)| *m == t) {
                Some(slot) => slot.1 += v * w,
                None => merged.push((t, v * w)),
            }
        }
    }
    equations[dof_idx] = Equation {
        dof: model.dofs[dof_idx].clone(),
        terms: merged
            .into_iter()
            .filter(|(_, c)| *c != 0.0 && c.is_finite())
            .map(|(t, v)| ModelTerm::new(t, v))
            .collect(),
    };
    let mut m = Model::new(model.dofs.clone(), equations, model.method.clone())?;
    m.trace = model.trace.clone();
    m.history = model.history.clone();
    Ok(m)
}

/// Held-out simulation R-MSE of the per-fold models (mean over held-out units; None on failure).
pub(crate) fn heldout_r_mse(
    model: &Model,
    dof_idx: usize,
    cols: &[EffectColumn],
    cv: &Cv,
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
) -> Option<f64> {
    let mut sum = 0.0;
    let mut count = 0usize;
    for f in 0..layout.folds {
        let m = with_equation(model, dof_idx, cols, &cv.coefs[f]).ok()?;
        let units: Vec<Record> = if layout.by_record {
            states
                .iter()
                .enumerate()
                .filter(|(r, _)| layout.blocks.iter().any(|b| b.record == *r && b.fold == f))
                .map(|(_, s)| crate::simulate::augment_record(&m, &s.record, opts))
                .collect::<Result<_>>()
                .ok()?
        } else {
            let bl: Vec<_> = layout.blocks.iter().filter(|b| b.fold == f).collect();
            let s = &states[bl.first()?.record];
            let start = s.margin + bl.first()?.start;
            let end = s.margin + bl.last()?.start + bl.last()?.len;
            let full = crate::simulate::augment_record(&m, &s.record, opts).ok()?;
            vec![full.slice(start..end).ok()?]
        };
        for u in units {
            sum += crate::simulate::r_mse(&m, &u).ok()?;
            count += 1;
        }
    }
    (count > 0).then(|| sum / count as f64)
}

struct DofSetup {
    idx: usize,
    base_terms: Vec<Term>,
    base_design: Design,
    base_blocks: Vec<Compressed>,
    base_cv: Cv,
    acc_rms: f64,
    scales: crate::prepare::DataScales,
}

fn setup_dof(
    model: &Model,
    idx: usize,
    states: &[RecordStates],
    layout: &Layout,
) -> Result<DofSetup> {
    let base_terms: Vec<Term> = model.equations[idx]
        .terms
        .iter()
        .map(|t| t.term.clone())
        .collect();
    if base_terms.is_empty() {
        return Err(DiagnoseError::NotApplicable {
            name: "model".into(),
            reason: format!(
                "the equation of '{}' has no terms; identify a model first",
                model.dofs[idx]
            ),
        });
    }
    let cols: Vec<EffectColumn> = base_terms.iter().cloned().map(EffectColumn::term).collect();
    let base_design = design(states, idx, &cols)?;
    let base_blocks = compress_blocks(&base_design, layout)?;
    let base_cv = cross_validate(&base_blocks, layout)?;
    let all_acc: Vec<f64> = base_design.b.iter().flatten().copied().collect();
    let scales = crate::prepare::DataScales::measure(model, idx, &base_terms, states)?;
    Ok(DofSetup {
        idx,
        base_terms,
        base_design,
        base_blocks,
        base_cv,
        acc_rms: rms(&all_acc),
        scales,
    })
}

fn context<'a>(
    model: &'a Model,
    d: &'a DofSetup,
    dt: f64,
    opts: &DiagnoseOptions,
) -> EffectContext<'a> {
    EffectContext::new(
        model,
        &model.dofs[d.idx],
        d.base_terms.clone(),
        &d.scales,
        dt,
        opts.max_power,
    )
}

struct Scored {
    variant: Variant,
    cols: Vec<EffectColumn>,
    main: Option<usize>,
    blocks: Vec<Compressed>,
    design: Design,
    cv: Cv,
    cv_rss: f64,
}

fn score_variant(
    states: &[RecordStates],
    layout: &Layout,
    d: &DofSetup,
    v: &Variant,
) -> Result<Scored> {
    let (cols, main) = variant_columns(&d.base_terms, v);
    let design = design(states, d.idx, &cols)?;
    let blocks = compress_blocks(&design, layout)?;
    let cv = cross_validate(&blocks, layout)?;
    let cv_rss = cv.heldout.iter().sum();
    Ok(Scored {
        variant: v.clone(),
        cols,
        main,
        blocks,
        design,
        cv,
        cv_rss,
    })
}

/// Scores every variant of one effect on one DOF and returns the best (lowest held-out RSS).
fn best_variant(
    states: &[RecordStates],
    layout: &Layout,
    d: &DofSetup,
    variants: &[Variant],
) -> Result<Option<Scored>> {
    let mut best: Option<Scored> = None;
    for v in variants {
        let s = score_variant(states, layout, d, v)?;
        if best.as_ref().is_none_or(|b| s.cv_rss < b.cv_rss) {
            best = Some(s);
        }
    }
    Ok(best)
}

fn bootstrap_interval(
    blocks: &[Compressed],
    main: usize,
    reps: usize,
    seed: u64,
) -> Result<[f64; 2]> {
    if reps < 10 {
        return Ok([f64::NAN, f64::NAN]);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nb = blocks.len();
    let mut vals = Vec::with_capacity(reps);
    for _ in 0..reps {
        let mut counts = vec![0usize; nb];
        for _ in 0..nb {
            counts[rng.random_range(0..nb)] += 1;
        }
        let pairs: Vec<(&Compressed, usize)> = blocks.iter().zip(counts).collect();
        let fit = LeastSquares.fit_compressed(&Compressed::merge_counted(&pairs)?)?;
        vals.push(fit.coef[main]);
    }
    vals.sort_by(f64::total_cmp);
    let q = |p: f64| vals[((p * (reps - 1) as f64).round() as usize).min(reps - 1)];
    Ok([q(0.025), q(0.975)])
}

/// The held-out analysis of one (effect, DOF) pair before the multiple-comparison correction.
struct Raw {
    effect: String,
    dof_idx: usize,
    scored: Scored,
    p_raw: f64,
    delta: f64,
    coef: f64,
    interval: [f64; 2],
    share: f64,
    r_mse_after: Option<f64>,
}

/// Ranks every catalogue effect for `model` on `records`.
pub fn explain(
    model: &Model,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
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
                jobs.push((e.name(), d.idx, vars));
            }
        }
    }
    let tests: usize = jobs.iter().map(|j| j.2.len()).sum::<usize>().max(1);
    let raws: Vec<Raw> = jobs
        .par_iter()
        .map(|(name, idx, vars)| -> Result<Option<Raw>> {
            let d = &setups[*idx];
            let Some(s) = best_variant(&states, &layout, d, vars)? else {
                return Ok(None);
            };
            let pairs = d.base_cv.heldout.iter().zip(&s.cv.heldout);
            let logs: Vec<f64> = pairs
                .clone()
                .map(|(a, b)| (a.max(f64::MIN_POSITIVE) / b.max(f64::MIN_POSITIVE)).ln())
                .collect();
            let diffs: Vec<f64> = pairs.map(|(a, b)| a - b).collect();
            let base_rss: f64 = d.base_cv.heldout.iter().sum();
            let delta = if base_rss > 0.0 {
                (base_rss - s.cv_rss) / base_rss
            } else {
                0.0
            };
            let coef_c = full_fit(&s.blocks)?;
            // Three one-sided looks at the same question, Bonferroni-combined: the held-out RSS
            // drop, its log-ratio, and (for an effect that adds a column) the block-robust Wald
            // test of the added coefficient. The Wald test is the direct test of a small effect
            // whose held-out RSS drop is buried in noise-dominated blocks (a constant offset
            // confounded with a high-power restoring polynomial); the held-out drop guards
            // against in-sample overfitting below.
            let wald = match s.main {
                Some(m) if !s.variant.add.is_empty() => {
                    block_wald_p_value(&s.design, &layout, &coef_c, m)
                }
                _ => 1.0,
            };
            let p_raw =
                (3.0 * paired_p_value(&diffs).min(paired_p_value(&logs)).min(wald)).min(1.0);
            let coef_0 = full_fit(&d.base_blocks)?;
            let mut diff2 = 0.0;
            let mut rows = 0usize;
            for r in 0..states.len() {
                let fc = &s.design.a[r] * faer::col::ColRef::from_slice(&coef_c);
                let f0 = &d.base_design.a[r] * faer::col::ColRef::from_slice(&coef_0);
                for i in 0..fc.nrows() {
                    diff2 += (fc[i] - f0[i]).powi(2);
                }
                rows += fc.nrows();
            }
            let share = (diff2 / rows.max(1) as f64).sqrt() / d.acc_rms.max(f64::MIN_POSITIVE);
            let (coef, interval) = match s.main {
                Some(m) => (
                    coef_c[m],
                    bootstrap_interval(&s.blocks, m, opts.bootstrap, opts.seed)?,
                ),
                None => (f64::NAN, [f64::NAN, f64::NAN]),
            };
            Ok(Some(Raw {
                effect: name.clone(),
                dof_idx: *idx,
                p_raw,
                delta,
                coef,
                interval,
                share,
                r_mse_after: None,
                scored: s,
            }))
        })
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .flatten()
        .collect();
    let multi = model.dofs.len() > 1;
    let mut ranked: Vec<(RankedEffect, Raw)> = raws
        .into_iter()
        .map(|raw| {
            let p = (raw.p_raw * tests as f64).min(1.0);
            let passes_p = p < opts.alpha;
            let passes_size = raw.share >= opts.min_share;
            let falls = raw.delta > 0.0;
            let significant = passes_p && passes_size && falls;
            let reason = if significant {
                format!(
                    "held-out equation error falls {:.1} %, p = {p:.2e} (corrected over {tests} tests), size {:.1} % of the force RMS",
                    100.0 * raw.delta,
                    100.0 * raw.share
                )
            } else if !falls {
                "held-out equation error does not fall".to_string()
            } else if !passes_p {
                format!("not significant: corrected p = {p:.2e} >= alpha = {}", opts.alpha)
            } else {
                format!(
                    "significant but too small: {:.2} % of the force RMS < {:.1} %",
                    100.0 * raw.share,
                    100.0 * opts.min_share
                )
            };
            let dof = model.dofs[raw.dof_idx].clone();
            let name = if multi {
                format!("{}@{dof}", raw.effect)
            } else {
                raw.effect.clone()
            };
            let terms = raw
                .scored
                .variant
                .add
                .iter()
                .map(|c| c.label())
                .chain(
                    raw.scored
                        .variant
                        .replace
                        .iter()
                        .map(|(o, n)| format!("{o} -> {}", n.label())),
                )
                .collect();
            (
                RankedEffect {
                    name,
                    effect: raw.effect.clone(),
                    dof,
                    parameter: raw.scored.variant.parameter.clone(),
                    terms,
                    significant,
                    p_value_raw: raw.p_raw,
                    p_value: p,
                    delta_heldout: raw.delta,
                    coef: raw.coef,
                    interval: raw.interval,
                    share: raw.share,
                    r_mse_before: None,
                    r_mse_after: None,
                    reason,
                },
                raw,
            )
        })
        .collect();
    if opts.simulate {
        let before: Vec<Option<f64>> = setups
            .iter()
            .map(|d| {
                let cols: Vec<EffectColumn> = d
                    .base_terms
                    .iter()
                    .cloned()
                    .map(EffectColumn::term)
                    .collect();
                heldout_r_mse(model, d.idx, &cols, &d.base_cv, &states, &layout, opts)
            })
            .collect();
        ranked.par_iter_mut().for_each(|(r, raw)| {
            r.r_mse_before = before[raw.dof_idx];
            r.r_mse_after = heldout_r_mse(
                model,
                raw.dof_idx,
                &raw.scored.cols,
                &raw.scored.cv,
                &states,
                &layout,
                opts,
            );
            raw.r_mse_after = r.r_mse_after;
            // An effect whose refitted model predicts the held-out data worse than the model
            // without it is not a discovered effect, however well it fits the equation error
            // (a flexible term can soak up the residual of a slightly mis-sized true effect).
            if r.significant
                && let Some(before) = r.r_mse_before
            {
                let worse = match r.r_mse_after {
                    Some(after) => after >= before,
                    None => true,
                };
                if worse {
                    r.significant = false;
                    r.reason = match r.r_mse_after {
                        Some(after) => format!(
                            "held-out equation error falls {:.1} %, but the refitted model predicts the held-out data worse (R-MSE {after:.3e} vs {before:.3e})",
                            100.0 * r.delta_heldout
                        ),
                        None => format!(
                            "held-out equation error falls {:.1} %, but the refitted model cannot be simulated on the held-out data",
                            100.0 * r.delta_heldout
                        ),
                    };
                }
            }
        });
    }
    // Significant first; among equals, the lower held-out simulation R-MSE (failed simulations
    // last), then the larger held-out equation-error drop.
    let sim_key = |r: &RankedEffect| r.r_mse_after.unwrap_or(f64::INFINITY);
    ranked.sort_by(|a, b| {
        b.0.significant
            .cmp(&a.0.significant)
            .then(sim_key(&a.0).total_cmp(&sim_key(&b.0)))
            .then(b.0.delta_heldout.total_cmp(&a.0.delta_heldout))
    });
    let mut ranked: Vec<RankedEffect> = ranked.into_iter().map(|(r, _)| r).collect();
    if !opts.simulate {
        ranked.sort_by(|a, b| {
            b.significant
                .cmp(&a.significant)
                .then(b.delta_heldout.total_cmp(&a.delta_heldout))
        });
    }
    let verdict = match ranked.iter().find(|r| r.significant) {
        Some(top) => format!(
            "missing effect: {} ({}); add it with --add {}",
            top.name, top.reason, top.name
        ),
        None => format!(
            "no significant missing effect among {} candidates (corrected alpha {}, minimum size {:.1} % of the force RMS)",
            ranked.len(),
            opts.alpha,
            100.0 * opts.min_share
        ),
    };
    Ok(Explanation {
        ranked,
        verdict,
        tests,
        cutoff_hz: states.iter().map(|s| s.cutoff_hz).collect(),
        folds_by_record: layout.by_record,
        blocks: layout.blocks.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prepare::Block;
    use rand_distr::{Distribution, StandardNormal};

    /// A design `b = β·z + c·w + e` over 32 blocks of 50 rows with block-correlated noise (each
    /// block's noise is a random walk, so rows inside a block are strongly correlated).
    fn problem(beta: f64, seed: u64) -> (Design, Layout, Vec<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (nb, len) = (32, 50);
        let n = nb * len;
        let z: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let w: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).cos()).collect();
        let mut e = vec![0.0; n];
        for b in 0..nb {
            let mut acc = 0.0;
            for i in 0..len {
                let g: f64 = StandardNormal.sample(&mut rng);
                acc = 0.9 * acc + g;
                e[b * len + i] = 0.3 * acc;
            }
        }
        let rhs: Vec<f64> = (0..n).map(|i| beta * z[i] + 2.0 * w[i] + e[i]).collect();
        let a = Mat::from_fn(n, 2, |i, j| if j == 0 { z[i] } else { 1e5 * w[i] });
        let layout = Layout {
            blocks: (0..nb)
                .map(|b| Block {
                    record: 0,
                    start: b * len,
                    len,
                    fold: b % 4,
                })
                .collect(),
            folds: 4,
            by_record: false,
        };
        let d = Design {
            a: vec![a],
            b: vec![rhs],
        };
        let blocks = compress_blocks(&d, &layout).unwrap();
        let coef = full_fit(&blocks).unwrap();
        (d, layout, coef)
    }

    #[test]
    fn block_wald_detects_a_real_coefficient_and_is_calibrated_under_the_null() {
        let (d, l, c) = problem(0.5, 1);
        assert!(block_wald_p_value(&d, &l, &c, 0) < 1e-6);
        // The other column (raw scale 1e5) is certainly non-zero too.
        assert!(block_wald_p_value(&d, &l, &c, 1) < 1e-6);
        // Under β = 0, p < 0.05 should happen about 5 % of the time (binomial: at most 7 of 40
        // is far beyond the 99.9 % range for a calibrated test with 2 expected).
        let small = (0..40)
            .filter(|s| {
                let (d, l, c) = problem(0.0, 100 + s);
                block_wald_p_value(&d, &l, &c, 0) < 0.05
            })
            .count();
        assert!(small <= 7, "{small} of 40 null p-values below 0.05");
    }
}
