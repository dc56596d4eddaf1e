//! Explain: refit the model's structure plus each catalogue effect by equation error, score it on
//! held-out blocks, test it, size it, and rank the effects.
//!
//! Per DOF equation, rows are the usable samples of every record: target the smoothed `x''`,
//! columns the equation's terms (plus the effect's) evaluated on smoothed states, the nonlinear
//! ones band-limited like the acceleration ([`crate::design`]). Rows are cut
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
//! `x''`) is at least `min_share` — or, below it, the judge finds that the refitted model predicts
//! the held-out data better by at least `min_share` of the motion's RMS (its size on the motion),
//! or with at most half the RMS prediction error of the model without it (most of what a model
//! already that close misses: `judge::predicts_better_by`) — and the judge of held-out
//! predictions does not find that it predicts worse by more than the judge resolves, and its
//! held-out drop lies beyond what the same scan finds on the start model's own simulated
//! records (`null.rs`: the equation error's bias with nothing missing) — unless the judge
//! resolves that its refitted model removes most of the held-out prediction error, which that
//! bias cannot give. Significant effects are
//! ordered by the free-run R-MSE where the free run judges and shows skill (below 1), otherwise
//! by the held-out equation error; the rest by held-out simulation R-MSE, then equation error.
//! A significant effect that the ordering's own evidence does not tell from the top one (paired
//! block test of their held-out equation errors, and no free run with skill between them) is
//! reported as tied with it: the records cannot say which of the two is missing.

use faer::Mat;
use rayon::prelude::*;
use serde::Serialize;
use tfs_data::Record;
use tfs_library::{Model, Term};
use tfs_regress::Compressed;

use crate::design::{
    Cv, Design, FoldEquation, compress_blocks, cross_validate, design, full_fit, variant_columns,
};
use crate::effects::{Catalogue, EffectColumn, EffectContext, Variant};
use crate::judge::{Candidate, Heldout, Judge, JudgeUse, mark_ties, order};
use crate::judged::main_coefficient;
use crate::prepare::{DiagnoseOptions, Layout, RecordStates, rms};
use crate::simulate::BaseRun;
use crate::stats::{block_wald_p_value, paired_p_value};
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
    /// What ranked the held-out predictions (`None` when candidates were not simulated).
    pub judge: Option<Judge>,
    /// Held-out prediction R-MSE of the refitted structure without the effect, by `judge`.
    pub r_mse_before: Option<f64>,
    /// Held-out prediction R-MSE after adding the effect, by `judge` (None if a simulation
    /// failed).
    pub r_mse_after: Option<f64>,
    /// Significant, and neither the held-out equation error nor the judge tells it apart from
    /// the top-ranked effect of its DOF (paired tests over the held-out blocks, and over the
    /// judge's units or pieces, at `alpha`): the records cannot say which of the two is missing.
    pub tied_with_top: bool,
    /// Why it is (not) significant, in words.
    pub reason: String,
}

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

/// One DOF's equation as the start model has it: its terms, design, blocks and cross-validation.
pub(crate) struct DofSetup {
    pub idx: usize,
    pub base_terms: Vec<Term>,
    /// Those terms as columns.
    base_cols: Vec<EffectColumn>,
    base_design: Design,
    base_blocks: Vec<Compressed>,
    pub base_cv: Cv,
    acc_rms: f64,
    scales: crate::prepare::DataScales,
    /// Start-library terms the equation lacks ([`crate::readmit`]).
    left_out: Vec<Term>,
}

impl DofSetup {
    /// The same without the start equation's design, for a setup that is only rescanned (a
    /// null draw, [`crate::null`]): the design is read only when an effect is analysed against
    /// it, and a draw's would otherwise be kept for every draw at once.
    pub(crate) fn lean(self) -> Self {
        Self {
            base_design: Design::empty(),
            ..self
        }
    }

    /// What an anchored per-fold model of this equation takes away again (its columns and their
    /// per-fold fit, [`FoldEquation::anchor`]); `None` when `anchored` is false.
    pub(crate) fn anchor(&self, anchored: bool) -> Option<(&[EffectColumn], &Cv)> {
        anchored.then_some((self.base_cols.as_slice(), &self.base_cv))
    }
}

/// The start model's equation of DOF `idx` on `states`.
pub(crate) fn setup_dof(
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
    let base_cols: Vec<EffectColumn> = base_terms.iter().cloned().map(EffectColumn::term).collect();
    let base_design = design(states, idx, &base_cols)?;
    let base_blocks = compress_blocks(&base_design, layout)?;
    let base_cv = cross_validate(&base_blocks, layout)?;
    let all_acc: Vec<f64> = base_design.b.iter().flatten().copied().collect();
    let scales = crate::prepare::DataScales::measure(model, idx, &base_terms, states)?;
    Ok(DofSetup {
        idx,
        base_terms,
        base_cols,
        base_design,
        base_blocks,
        base_cv,
        acc_rms: rms(&all_acc),
        scales,
        left_out: crate::readmit::left_out(model, idx),
    })
}

/// What the catalogue's effects are told about the equation of `d`.
pub(crate) fn context<'a>(
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

/// One variant scored: its columns, design, compressed blocks and cross-validation.
pub(crate) struct Scored {
    pub variant: Variant,
    pub cols: Vec<EffectColumn>,
    pub main: Option<usize>,
    pub blocks: Vec<Compressed>,
    pub design: Design,
    pub cv: Cv,
    /// Held-out residual sum of squares over all blocks.
    pub cv_rss: f64,
}

/// Scores variant `v` on the equation of DOF `idx` with the terms `base`.
pub(crate) fn score_variant(
    states: &[RecordStates],
    layout: &Layout,
    idx: usize,
    base: &[Term],
    v: &Variant,
) -> Result<Scored> {
    let (cols, main) = variant_columns(base, v);
    let design = design(states, idx, &cols)?;
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

/// Scores every variant of one effect on the equation of DOF `idx` (terms `base`) and returns
/// the best (lowest held-out RSS), an internal state's parameters then refined locally by the
/// same criterion ([`crate::polish`]). The variants are scored side by side (an effect with
/// many variants was otherwise the scan's serial tail), the choice the same as in order
/// ([`crate::stats::first_lowest`]).
pub(crate) fn best_variant(
    states: &[RecordStates],
    layout: &Layout,
    idx: usize,
    base: &[Term],
    variants: &[Variant],
) -> Result<Option<Scored>> {
    let score = |v: &Variant| score_variant(states, layout, idx, base, v);
    let Some(best) = crate::stats::first_lowest(variants, &score, |s: &Scored| s.cv_rss)? else {
        return Ok(None);
    };
    let dt = states.first().map_or(0.0, |s| s.record.dt());
    Ok(Some(crate::polish::polish(best, variants, &score, dt)?))
}

/// The held-out analysis of one (effect, DOF) pair before the multiple-comparison correction.
pub(crate) struct Raw {
    pub effect: String,
    /// Start-library terms put back beside the effect ([`crate::readmit`]).
    pub readmitted: Vec<Term>,
    pub dof_idx: usize,
    pub scored: Scored,
    /// For an effect whose parameter `refit` chooses by simulation, the next variants by
    /// held-out residual ([`crate::judged`]); empty otherwise.
    pub alternatives: Vec<crate::judged::Alternative>,
    p_raw: f64,
    delta: f64,
    coef: f64,
    interval: [f64; 2],
    share: f64,
}

/// Scores the variants of effect `name` on the equation of `d` and analyses the best one: the
/// held-out drop, the combined one-sided test, the size and the coefficient's interval.
fn analyse(
    states: &[RecordStates],
    layout: &Layout,
    d: &DofSetup,
    name: &str,
    (vars, by_simulation): (&[Variant], bool),
    opts: &DiagnoseOptions,
) -> Result<Option<Raw>> {
    let eq = (d.idx, d.base_terms.as_slice());
    let readmit = crate::readmit::best_with_library;
    let Some(re) = readmit(states, layout, eq, vars, &d.left_out, opts.alpha)? else {
        return Ok(None);
    };
    let s = re.scored;
    // The effect against the start equation, or against it with the re-admitted terms.
    let (base_design, base_blocks, base_cv) = match &re.reference {
        Some(reference) => (&reference.design, &reference.blocks, &reference.cv),
        None => (&d.base_design, &d.base_blocks, &d.base_cv),
    };
    let pairs = base_cv.heldout.iter().zip(&s.cv.heldout);
    let logs: Vec<f64> = pairs
        .clone()
        .map(|(a, b)| (a.max(f64::MIN_POSITIVE) / b.max(f64::MIN_POSITIVE)).ln())
        .collect();
    let diffs: Vec<f64> = pairs.map(|(a, b)| a - b).collect();
    let base_rss: f64 = base_cv.heldout.iter().sum();
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
        Some(m) if !s.variant.add.is_empty() => block_wald_p_value(&s.design, layout, &coef_c, m),
        _ => 1.0,
    };
    let p_raw = (3.0 * paired_p_value(&diffs).min(paired_p_value(&logs)).min(wald)).min(1.0);
    let coef_0 = full_fit(base_blocks)?;
    let mut diff2 = 0.0;
    let mut rows = 0usize;
    // Row by row in a fixed order (a library matrix-vector product splits its sums by the
    // thread count, which moved `share` in its last digits between 1, 2 and 7 threads).
    let dot = |a: &Mat<f64>, i: usize, c: &[f64]| -> f64 {
        c.iter().enumerate().map(|(k, ck)| a[(i, k)] * ck).sum()
    };
    for r in 0..states.len() {
        let (ac, a0) = (&s.design.a[r], &base_design.a[r]);
        for i in 0..ac.nrows() {
            diff2 += (dot(ac, i, &coef_c) - dot(a0, i, &coef_0)).powi(2);
        }
        rows += ac.nrows();
    }
    let share = (diff2 / rows.max(1) as f64).sqrt() / d.acc_rms.max(f64::MIN_POSITIVE);
    let (coef, interval) = main_coefficient(&s, &coef_c, opts)?;
    let alternatives = if by_simulation {
        let mut terms = d.base_terms.clone();
        terms.extend(re.terms.iter().cloned());
        crate::judged::alternatives(states, layout, d.idx, &terms, (vars, &s.variant), opts)?
    } else {
        Vec::new()
    };
    Ok(Some(Raw {
        alternatives,
        readmitted: re.terms,
        effect: name.to_string(),
        dof_idx: d.idx,
        p_raw,
        delta,
        coef,
        interval,
        share,
        scored: s.lean(),
    }))
}

/// The terms a variant adds or substitutes, then the start-library terms re-admitted beside it,
/// as the report prints them.
fn variant_terms(v: &Variant, readmitted: &[Term]) -> Vec<String> {
    v.add
        .iter()
        .map(|c| c.label())
        .chain(
            v.replace
                .iter()
                .map(|(o, n)| format!("{o} -> {}", n.label())),
        )
        .chain(
            readmitted
                .iter()
                .map(|t| format!("{t} (start library, re-admitted)")),
        )
        .collect()
}

/// The ranked entry of one analysed effect: the Bonferroni correction over `tests`, the
/// significance decision by equation error, and the words.
fn entry(model: &Model, raw: &Raw, tests: usize, opts: &DiagnoseOptions) -> RankedEffect {
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
        format!(
            "not significant: corrected p = {p:.2e} >= alpha = {}",
            opts.alpha
        )
    } else {
        format!(
            "significant but too small: {:.2} % of the force RMS < {:.1} %",
            100.0 * raw.share,
            100.0 * opts.min_share
        )
    };
    let dof = model.dofs[raw.dof_idx].clone();
    let name = if model.dofs.len() > 1 {
        format!("{}@{dof}", raw.effect)
    } else {
        raw.effect.clone()
    };
    let v = &raw.scored.variant;
    let terms = variant_terms(v, &raw.readmitted);
    RankedEffect {
        name,
        effect: raw.effect.clone(),
        dof,
        parameter: v.parameter.clone(),
        terms,
        significant,
        p_value_raw: raw.p_raw,
        p_value: p,
        delta_heldout: raw.delta,
        coef: raw.coef,
        interval: raw.interval,
        share: raw.share,
        judge: None,
        r_mse_before: None,
        r_mse_after: None,
        tied_with_top: false,
        reason,
    }
}

/// Judges every candidate's refitted per-fold models on held-out data ([`crate::judge`]) and
/// takes significance away from one that predicts worse than the model without it by more than
/// the judge can resolve. Returns the judge of each DOF with its reason.
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
    ranked: &mut [Candidate],
    runs: &[BaseRun],
) -> Vec<JudgeUse> {
    let choice = crate::judge::choose(model, states, opts, runs);
    if choice.judge != Judge::FreeRun {
        return judge_with(model, setups, states, layout, opts, ranked, &choice);
    }
    let found: Vec<(bool, String)> = ranked
        .iter()
        .map(|c| (c.entry.significant, c.entry.reason.clone()))
        .collect();
    let judged = judge_with(model, setups, states, layout, opts, ranked, &choice);
    let dominated = ranked.iter().zip(&found).find(|(c, (was, _))| {
        *was && !c.entry.significant && c.heldout.is_some() && {
            let at = (c.raw.dof_idx, &c.raw.scored);
            let partners = crate::judged::partner_equations(model, at, states, layout);
            let eqs = crate::judged::fold_equations(model, setups, at, &partners);
            folds_noise_dominated(model, &eqs, states, layout, opts)
        }
    });
    let choice = if let Some((c, _)) = dominated {
        crate::judge::Choice {
            judge: Judge::ShortHorizon,
            why: format!(
                "free-run simulation cannot rank these candidates: a fresh draw of the measured input's noise moves the free run of the model with {} about as far as its error",
                c.entry.name
            ),
            plain: false,
            resolution: choice.resolution,
            from_fitted_rows: false,
        }
    } else if let Some((c, _)) = ranked
        .iter()
        .zip(&found)
        .find(|(c, (was, _))| *was && !c.entry.significant && c.heldout.is_none())
    {
        // A significant candidate's per-fold model could not be simulated from the record's
        // start: the smoothing margin before the fitted rows holds states none of the fold's
        // rows taught it (a cell leaving its deployed well there). Every candidate is judged
        // again over the fitted rows alone.
        crate::judge::Choice {
            judge: Judge::FreeRun,
            why: format!(
                "free-run simulation under the measured input over the rows the equations were fitted on, each from the measured state at its first (the model with {} could not be simulated from the start of the records)",
                c.entry.name
            ),
            plain: false,
            resolution: choice.resolution,
            from_fitted_rows: true,
        }
    } else {
        return judged;
    };
    for (c, (was, reason)) in ranked.iter_mut().zip(found) {
        c.entry.significant = was;
        c.entry.reason = reason;
    }
    judge_with(model, setups, states, layout, opts, ranked, &choice)
}

/// True when on some held-out record the free run of a per-fold model whose equations `eqs`
/// replace the model's is dominated by the input's own noise
/// ([`crate::simulate::free_run_noise_dominated`]).
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

/// [`judge_candidates`] under the judge `choice`.
fn judge_with(
    model: &Model,
    setups: &[DofSetup],
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
    ranked: &mut [Candidate],
    choice: &crate::judge::Choice,
) -> Vec<JudgeUse> {
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
    ranked.par_iter_mut().for_each(|c| {
        let (r, raw) = (&mut c.entry, &c.raw);
        let d = &setups[raw.dof_idx];
        r.judge = Some(judge);
        let at = (choice, horizon(d));
        let (heldout, judged) = crate::judged::heldout(model, setups, states, layout, opts, at, raw);
        c.heldout = heldout;
        let judged_alternative = judged.is_some();
        let (v, (coef, interval)) = match judged {
            Some(a) => (&a.scored.variant, (a.coef, a.interval)),
            None => (&raw.scored.variant, (raw.coef, raw.interval)),
        };
        (r.parameter, r.coef, r.interval) = (v.parameter.clone(), coef, interval);
        r.terms = variant_terms(v, &raw.readmitted);
        let before = &before[raw.dof_idx];
        r.r_mse_before = before.as_ref().map(|h| h.mean);
        r.r_mse_after = c.heldout.as_ref().map(|h| h.mean);
        // Most of the error, whatever the drop's share of the motion (`min_share` never met).
        c.removes_most = before.as_ref().zip(c.heldout.as_ref()).is_some_and(|(b, a)| {
            crate::judge::predicts_better_by(judge, b, a, choice.resolution, opts.alpha, f64::INFINITY)
                .is_some()
        });
        // An effect whose refitted model predicts the held-out data worse than the model
        // without it is not a discovered effect, however well it fits the equation error
        // (a flexible term can soak up the residual of a slightly mis-sized true effect).
        // Worse means worse by more than the judge resolves: a difference a fresh draw of the
        // input's noise makes, or one the pieces do not bear out, decides nothing.
        if r.significant
            && let Some(before) = before
        {
            let worse = match &c.heldout {
                Some(after) => crate::judge::predicts_worse(
                    judge,
                    before,
                    after,
                    choice.resolution,
                    opts.alpha,
                ),
                None => true,
            };
            if worse {
                r.significant = false;
                r.reason = match r.r_mse_after {
                    Some(after) => format!(
                        "held-out equation error falls {:.1} %, but the refitted model predicts the held-out data worse ({} R-MSE {after:.3e} vs {:.3e})",
                        100.0 * r.delta_heldout,
                        judge.describe(),
                        before.mean
                    ),
                    None => format!(
                        "held-out equation error falls {:.1} %, but the refitted model cannot be simulated on the held-out data",
                        100.0 * r.delta_heldout
                    ),
                };
            }
        }
        // Too small on the force, large on the motion: it passes the block tests, and the
        // refitted model predicts the held-out data better by at least `min_share` of the
        // motion's RMS, or with at most half the RMS prediction error of the model without it.
        if !r.significant
            && r.p_value < opts.alpha
            && r.delta_heldout > 0.0
            && let (Some(before), Some(after)) = (before, &c.heldout)
            && let Some(drop) = crate::judge::predicts_better_by(
                judge,
                before,
                after,
                choice.resolution,
                opts.alpha,
                opts.min_share,
            )
        {
            r.significant = true;
            let how = if drop >= opts.min_share {
                format!("by {:.1} % of the motion's RMS", 100.0 * drop)
            } else {
                format!(
                    "with {:.1} % of the RMS prediction error of the model without it, most of what that model misses",
                    100.0 * (after.mean / before.mean).sqrt()
                )
            };
            r.reason = format!(
                "held-out equation error falls {:.1} %, p = {:.2e}; size {:.2} % of the force RMS, under {:.1} %, but the refitted model predicts the held-out data better {how} ({} R-MSE {:.3e} vs {:.3e})",
                100.0 * r.delta_heldout,
                r.p_value,
                100.0 * r.share,
                100.0 * opts.min_share,
                judge.describe(),
                after.mean,
                before.mean
            );
        }
        if judged_alternative && let Some((name, value)) = &r.parameter {
            r.reason.push_str(&format!(
                "; judged at {name} = {value}, of the {} values with the lowest held-out residual the one whose model predicts the held-out data best (`refit` chooses it so)",
                raw.alternatives.len() + 1
            ));
        }
    });
    setups
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
        .collect()
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
    let raws: Vec<Raw> = jobs
        .par_iter()
        .map(|(name, idx, vars, by_sim)| {
            analyse(&states, &layout, &setups[*idx], name, (vars, *by_sim), opts)
        })
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .flatten()
        .collect();
    let mut ranked: Vec<Candidate> = raws
        .into_iter()
        .map(|raw| Candidate {
            entry: entry(model, &raw, tests, opts),
            raw,
            heldout: None,
            removes_most: false,
        })
        .collect();
    let judges = if opts.simulate {
        let made;
        let runs = match runs {
            Some(r) => r,
            None => {
                made = crate::simulate::base_runs(model, records, opts);
                &made
            }
        };
        let judges = judge_candidates(model, &setups, &states, &layout, opts, &mut ranked, runs);
        crate::null::calibrate(model, records, catalogue, opts, &mut ranked, runs, tests);
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
