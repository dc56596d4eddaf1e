//! The ranking: each candidate's report entry ([`RankedEffect`], made once from its evidence),
//! the order of the candidates, and the ties the records cannot break.

use serde::Serialize;
use tfs_library::Model;

use crate::evidence::{Evidence, Judge, Significance};
use crate::judge::{Heldout, lowest_geometric_mean, predicts_worse, skill_key};
use crate::prepare::DiagnoseOptions;
use crate::scan::{Raw, variant_terms};
use crate::stats::paired_drop_p_value;

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
    /// Significant by the decision over its evidence ([`Evidence::significance`]).
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
    /// Why it is (not) significant, typed: the decision over its evidence
    /// ([`Evidence::significance`]); `significant` is true exactly for its significant kinds.
    pub significance: Significance,
    /// What each stage of the scan found ([`Evidence`]); in memory only, not in the JSON.
    #[serde(skip)]
    pub evidence: Evidence,
}

impl RankedEffect {
    /// The entry of the candidate `raw` with its `evidence`: the variant the judge judged
    /// (`alternative`, an index into [`Raw::alternatives`]) or else the best by equation error,
    /// and the decision and its words read from the evidence.
    pub(crate) fn new(
        model: &Model,
        raw: &Raw,
        alternative: Option<usize>,
        evidence: Evidence,
        opts: &DiagnoseOptions,
    ) -> Self {
        let (v, coef, interval) = match alternative.and_then(|k| raw.alternatives.get(k)) {
            Some(a) => (&a.scored.variant, a.coef, a.interval),
            None => (&raw.scored.variant, raw.coef, raw.interval),
        };
        let significance = evidence.significance(opts);
        let eq = evidence.equation();
        let prediction = evidence.prediction();
        RankedEffect {
            name: raw.name(model),
            effect: raw.effect.clone(),
            dof: model.dofs[raw.dof_idx].clone(),
            parameter: v.parameter.clone(),
            terms: variant_terms(v, &raw.readmitted),
            significant: significance.is_significant(),
            p_value_raw: eq.p_raw,
            p_value: eq.p,
            delta_heldout: eq.delta,
            coef,
            interval,
            share: eq.share,
            judge: prediction.map(|p| p.judge),
            r_mse_before: prediction.and_then(|p| p.before),
            r_mse_after: prediction.and_then(|p| p.after),
            tied_with_top: false,
            reason: evidence.reason(opts),
            significance,
            evidence,
        }
    }
}

/// A ranked effect with its analysis and its held-out prediction score.
pub(crate) struct Candidate {
    /// What is reported.
    pub entry: RankedEffect,
    /// The equation-error analysis.
    pub raw: Raw,
    /// The held-out prediction score by the judge.
    pub heldout: Option<Heldout>,
}

/// Orders the candidates: significant first. Among the significant, with the free run as judge,
/// by its held-out R-MSE where it shows skill and by the held-out equation error where it does
/// not: an R-MSE of 1 or more (on the measured displacement's variance) predicts no better than
/// the mean position, so every such candidate scores the same, "no skill" ([`skill_key`]).
/// With the short horizon or the equation error alone, by the equation error (over chaotic
/// divergence the short-horizon error is too coarse to order on its own); under the short
/// horizon, a candidate that the equation error does not tell apart from its DOF's top one
/// takes the top place when the paired tests over the pieces say the top predicts worse than it
/// ([`short_horizon_breaks_tie`]); under the free run, a candidate whose held-out equation
/// error is decisively lower than the top one's takes its place
/// ([`decisive_equation_error_first`]). The rest by the free-run R-MSE (failed simulations
/// last), then the equation error.
pub(crate) fn order(ranked: &mut [Candidate], judge: Judge, alpha: f64) {
    let sim_key = |c: &Candidate| c.entry.r_mse_after.unwrap_or(f64::INFINITY);
    let key = |c: &Candidate| {
        if !c.entry.significant {
            sim_key(c)
        } else if judge == Judge::FreeRun {
            skill_key(c.entry.r_mse_after)
        } else {
            0.0
        }
    };
    ranked.sort_by(|a, b| {
        b.entry
            .significant
            .cmp(&a.entry.significant)
            .then(key(a).total_cmp(&key(b)))
            .then(b.entry.delta_heldout.total_cmp(&a.entry.delta_heldout))
    });
    if judge == Judge::ShortHorizon {
        short_horizon_breaks_tie(ranked, alpha);
    }
    if judge == Judge::FreeRun {
        decisive_equation_error_first(ranked, alpha);
    }
}

/// How much lower a significant candidate's held-out equation error must be than that of the
/// free run's top one (of its DOF) for the equation error to overrule the free run's order
/// ([`decisive_equation_error_first`]): it must leave less than this share of what the top one
/// leaves.
pub(crate) const DECISIVE_RATIO: f64 = 0.5;

/// Under the free-run judge, per DOF: the significant candidate with the lowest held-out
/// equation error takes the top place when it leaves less than [`DECISIVE_RATIO`] of the top
/// one's held-out equation error and the paired block tests say so at `alpha`; the others keep
/// their order. The free run scores each candidate's per-fold equation-error refits, which are
/// not the refit the loop makes (its anchors are chosen by simulation): an equation-error refit
/// can simulate far worse than the refit of the same terms chosen by simulation (a rig's
/// stiffness and offset terms whose small errors move its equilibrium), so between candidates
/// of comparable equation error the free run orders, and where one removes most of what the
/// other leaves, the equation error does.
fn decisive_equation_error_first(ranked: &mut [Candidate], alpha: f64) {
    for dof in significant_dofs(ranked) {
        let mine = significant_of(ranked, &dof);
        let top = mine[0];
        let left: Vec<f64> = mine
            .iter()
            .map(|&i| 1.0 - ranked[i].entry.delta_heldout)
            .collect();
        let told = |k: usize| !equation_ties(&ranked[mine[k]], &ranked[top], alpha);
        if let Some(k) = decisive(&left, told) {
            ranked[top..=mine[k]].rotate_right(1);
        }
    }
}

/// The DOFs with a significant candidate, in the order their first one is ranked.
fn significant_dofs(ranked: &[Candidate]) -> Vec<String> {
    let mut dofs: Vec<String> = Vec::new();
    for c in ranked.iter().filter(|c| c.entry.significant) {
        if !dofs.contains(&c.entry.dof) {
            dofs.push(c.entry.dof.clone());
        }
    }
    dofs
}

/// The positions of `dof`'s significant candidates in `ranked`, in ranked order.
fn significant_of(ranked: &[Candidate], dof: &str) -> Vec<usize> {
    (0..ranked.len())
        .filter(|&i| ranked[i].entry.significant && ranked[i].entry.dof == dof)
        .collect()
}

/// Of candidates leaving the held-out equation errors `left` (relative to the model without
/// them; the first is the top one), the index of the one with the lowest when it leaves less
/// than [`DECISIVE_RATIO`] of the first's and `told(index)` says the paired tests tell it apart.
fn decisive(left: &[f64], told: impl Fn(usize) -> bool) -> Option<usize> {
    let (k, &best) = left.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    (k != 0 && best < DECISIVE_RATIO * left[0] && told(k)).then_some(k)
}

/// Under the short-horizon judge, per DOF: among the significant candidates whose held-out
/// equation error is tied with the DOF's top one ([`equation_ties`]), the top one included, the
/// one whose pieces' geometric-mean error is lowest ([`lowest_geometric_mean`]) takes the top place; the
/// others keep their order. Only a tie is broken. The geometric mean, not the mean: the error of
/// a chaotic prediction is heavy-tailed over the pieces, and the mean follows the one piece in
/// which a model loses the motion (as the sole key it put true effects last). Whether the pieces
/// resolve the difference is for [`mark_ties`] to say.
fn short_horizon_breaks_tie(ranked: &mut [Candidate], alpha: f64) {
    for dof in significant_dofs(ranked) {
        let mine = significant_of(ranked, &dof);
        let top = mine[0];
        let tied: Vec<usize> = mine
            .iter()
            .copied()
            .filter(|&i| i == top || equation_ties(&ranked[top], &ranked[i], alpha))
            .collect();
        let pieces: Option<Vec<&[f64]>> = tied
            .iter()
            .map(|&i| ranked[i].heldout.as_ref().map(|h| h.parts.as_slice()))
            .collect();
        let best = pieces
            .and_then(|p| lowest_geometric_mean(&p))
            .map(|k| tied[k]);
        if let Some(i) = best {
            ranked[top..=i].rotate_right(1);
        }
    }
}

/// True when the paired one-sided tests over the held-out blocks (the RSS difference and its
/// log-ratio, Bonferroni over the two) do not put `top`'s advantage in held-out equation error
/// over `other` below `alpha`.
fn equation_ties(top: &Candidate, other: &Candidate, alpha: f64) -> bool {
    let (t, o) = (&top.raw.scored.cv.heldout, &other.raw.scored.cv.heldout);
    paired_drop_p_value(o, t) >= alpha
}

/// Marks the significant candidates that the ordering's own evidence does not tell apart from
/// the top-ranked one of their DOF ([`RankedEffect::tied_with_top`]): the held-out equation error
/// does not ([`equation_ties`]), and neither does the judge — when the free run judges, neither of
/// the two free runs shows skill ([`skill_key`]); when the short horizon judges, its paired tests
/// over the pieces do not say the candidate predicts worse than the top ([`predicts_worse`]).
pub(crate) fn mark_ties(ranked: &mut [Candidate], judge: Judge, alpha: f64) {
    let mut tops: Vec<usize> = Vec::new();
    for i in 0..ranked.len() {
        if !ranked[i].entry.significant {
            continue;
        }
        let Some(&t) = tops
            .iter()
            .find(|&&t| ranked[t].entry.dof == ranked[i].entry.dof)
        else {
            tops.push(i);
            continue;
        };
        let (top, c) = (&ranked[t], &ranked[i]);
        let judge_ties = match judge {
            Judge::FreeRun => {
                skill_key(top.entry.r_mse_after) == 1.0 && skill_key(c.entry.r_mse_after) == 1.0
            }
            Judge::ShortHorizon => match (&top.heldout, &c.heldout) {
                (Some(th), Some(ch)) => !predicts_worse(judge, th, ch, 0.0, alpha),
                _ => true,
            },
            Judge::EquationError => true,
        };
        let tied = equation_ties(top, c, alpha) && judge_ties;
        ranked[i].entry.tied_with_top = tied;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The equation error overrules the free run's top place only when decisive: the lowest
    /// held-out equation error, less than half the top one's, and told apart by the paired
    /// tests; otherwise the free run's order stands.
    #[test]
    fn only_a_decisively_lower_equation_error_takes_the_top_place() {
        let all = |_: usize| true;
        // A candidate leaving 6 % of the start model's error against the top one's 75 %.
        assert_eq!(decisive(&[0.75, 0.9, 0.06], all), Some(2));
        // The lowest is taken, not the first below the ratio.
        assert_eq!(decisive(&[0.8, 0.3, 0.1], all), Some(2));
        // Comparable equation errors: the free run's order stands.
        assert_eq!(decisive(&[0.75, 0.4], all), None);
        assert_eq!(decisive(&[0.4, 0.2], all), None);
        // The top one already has the lowest.
        assert_eq!(decisive(&[0.1, 0.9], all), None);
        // The paired tests do not tell the two apart.
        assert_eq!(decisive(&[0.75, 0.06], |_| false), None);
        assert_eq!(decisive(&[], all), None);
    }
}
