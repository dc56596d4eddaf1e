//! The scan's equation-error analysis of one (effect, DOF) pair: the start model's equation of
//! the DOF ([`DofSetup`]), the effect's best variant on it (with start-library terms re-admitted
//! beside it, `readmit.rs`), the held-out drop, the combined one-sided test, the size and the
//! coefficient's interval ([`Raw`]), and what the scan writes into the candidate's evidence
//! ([`Raw::equation_evidence`]).
//!
//! Per DOF equation, rows are the usable samples of every record: target the smoothed `x''`,
//! columns the equation's terms (plus the effect's) evaluated on smoothed states, the nonlinear
//! ones band-limited like the acceleration (`design.rs`). Rows are cut into contiguous blocks,
//! each compressed once (`tfs_regress::Compressed`); folds are records (several records) or time
//! segments (one record). For a candidate, every fold is fitted on the other folds' blocks, and
//! each held-out block's residual sum of squares is read off its small factor. The significance
//! test combines three looks (Bonferroni over the three): the per-block held-out drop
//! `RSS_base,b − RSS_cand,b` and the log-ratio `ln(RSS_base,b / RSS_cand,b)`, each tested
//! one-sided against zero with a t statistic over blocks (the drop weighs blocks by their error,
//! the log-ratio treats quiet and loud blocks alike), and — for an effect that adds a column —
//! the block-robust (cluster sandwich) Wald test of the added coefficient on all data. The Wald
//! test is the direct test of a small effect whose held-out RSS drop is buried in
//! noise-dominated blocks (a constant offset confounded with a high-power restoring polynomial).
//! Blocks are long enough — four cut-off periods or more — to be nearly independent. The
//! combined p-value is Bonferroni-corrected over every variant of every effect tested.

use tfs_library::{Model, Term};
use tfs_regress::Compressed;

use crate::design::{Cv, Design, compress_blocks, cross_validate, design, full_fit};
use crate::effects::{DataScales, EffectColumn, EffectContext, Variant};
use crate::evidence::EquationEvidence;
use crate::prepare::{DiagnoseOptions, Layout, RecordStates, rms};
use crate::score::{Alternative, Scored, main_coefficient};
use crate::stats::{block_wald_p_value, paired_p_value};
use crate::{DiagnoseError, Result};

/// One DOF's equation as the start model has it: its terms, design, blocks and cross-validation.
pub(crate) struct DofSetup {
    pub idx: usize,
    pub base_terms: Vec<Term>,
    /// Those terms as columns.
    pub base_cols: Vec<EffectColumn>,
    base_design: Design,
    base_blocks: Vec<Compressed>,
    pub base_cv: Cv,
    acc_rms: f64,
    /// What the catalogue's effects are told about the equation's data.
    pub scales: DataScales,
    /// Start-library terms the equation lacks ([`crate::readmit`]).
    left_out: Vec<Term>,
}

impl DofSetup {
    /// The same without the start equation's design, for a setup that is only rescanned (a
    /// null draw, `null.rs`): the design is read only when an effect is analysed against
    /// it, and a draw's would otherwise be kept for every draw at once.
    pub(crate) fn lean(self) -> Self {
        Self {
            base_design: Design::empty(),
            ..self
        }
    }

    /// What an anchored per-fold model of this equation takes away again (its columns and their
    /// per-fold fit, [`crate::design::FoldEquation::anchor`]); `None` when `anchored` is false.
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
    let all_acc: Vec<f64> = (0..base_design.records())
        .flat_map(|r| base_design.target(r).iter().copied())
        .collect();
    let scales = DataScales::measure(model, idx, &base_terms, states)?;
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

/// The held-out analysis of one (effect, DOF) pair before the multiple-comparison correction.
pub(crate) struct Raw {
    pub effect: String,
    /// Start-library terms put back beside the effect ([`crate::readmit`]).
    pub readmitted: Vec<Term>,
    pub dof_idx: usize,
    pub scored: Scored,
    /// For an effect whose parameter `refit` chooses by simulation, the next variants by
    /// held-out residual ([`crate::score::alternatives`]); empty otherwise.
    pub alternatives: Vec<Alternative>,
    /// One-sided p of the combined block tests (uncorrected).
    pub p_raw: f64,
    /// Relative drop of the held-out equation error.
    pub delta: f64,
    /// The main column's coefficient (full-data fit).
    pub coef: f64,
    /// Its 95 % block-bootstrap interval.
    pub interval: [f64; 2],
    /// RMS change of the fitted force over the RMS of `x''`.
    pub share: f64,
}

/// Scores the variants of effect `name` on the equation of `d` and analyses the best one: the
/// held-out drop, the combined one-sided test, the size and the coefficient's interval.
pub(crate) fn analyse(
    states: &[RecordStates],
    layout: &Layout,
    d: &DofSetup,
    name: &str,
    (vars, by_simulation): (&[Variant], bool),
    opts: &DiagnoseOptions,
) -> Result<Option<Raw>> {
    let eq = (d.idx, d.base_terms.as_slice());
    let readmit = crate::readmit::best_with_library;
    let keep = by_simulation;
    let Some(re) = readmit(states, layout, eq, vars, &d.left_out, (opts.alpha, keep))? else {
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
    let dot = |a: &Design, r: usize, i: usize, c: &[f64]| -> f64 {
        c.iter().enumerate().map(|(k, ck)| a.at(r, i, k) * ck).sum()
    };
    for r in 0..states.len() {
        let (ac, a0) = (&s.design, base_design);
        for i in 0..ac.rows(r) {
            diff2 += (dot(ac, r, i, &coef_c) - dot(a0, r, i, &coef_0)).powi(2);
        }
        rows += ac.rows(r);
    }
    let share = (diff2 / rows.max(1) as f64).sqrt() / d.acc_rms.max(f64::MIN_POSITIVE);
    let (coef, interval) = main_coefficient(&s, &coef_c, opts)?;
    let alternatives = if by_simulation {
        crate::score::alternatives(re.scanned, &s.variant, opts)?
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
pub(crate) fn variant_terms(v: &Variant, readmitted: &[Term]) -> Vec<String> {
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

impl Raw {
    /// What `--add` accepts: the effect's name, with `@dof` for a multi-DOF model.
    pub(crate) fn name(&self, model: &Model) -> String {
        if model.dofs.len() > 1 {
            format!("{}@{}", self.effect, model.dofs[self.dof_idx])
        } else {
            self.effect.clone()
        }
    }

    /// What the scan writes into the candidate's evidence: its test Bonferroni-corrected over
    /// `tests` variants, its drop and its size.
    pub(crate) fn equation_evidence(&self, tests: usize) -> EquationEvidence {
        EquationEvidence {
            p_raw: self.p_raw,
            p: (self.p_raw * tests as f64).min(1.0),
            tests,
            delta: self.delta,
            share: self.share,
        }
    }
}
