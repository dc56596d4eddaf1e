//! The evidence for one candidate effect, one part per stage of the scan, and the one decision
//! read from it.
//!
//! Each stage writes its own part once and never another's: the scan its equation-error test
//! ([`EquationEvidence`]: the held-out drop, its corrected p and the effect's size), the judge
//! its held-out prediction ([`PredictionEvidence`]: the prediction score with and without the
//! effect, against what the judge resolves, and the variant it judged), the calibrated null
//! what the start model's own simulated records say ([`NullEvidence`]). Whether a candidate is
//! significant is not a flag the stages pass around; it is one pure function of the evidence and
//! the thresholds of [`DiagnoseOptions`] ([`Evidence::significance`]), and every answer carries
//! its typed reason ([`Significance`], printed in words by [`Evidence::reason`]).
//!
//! The decision, in order:
//! 1. **Equation error.** Significant when the corrected p is below `alpha`, the held-out error
//!    falls and the size is at least `min_share` of the RMS of `x''`.
//! 2. **Prediction** (when the candidates were simulated). An effect significant by equation
//!    error whose refitted model predicts the held-out data worse than the model without it, by
//!    more than the judge resolves, or cannot be simulated there, is not significant. An effect
//!    whose test passes and whose error falls is significant — whatever its size — when its
//!    refitted model predicts the held-out data better by `min_share` of the motion's RMS, or
//!    removes most of the model's own prediction error.
//! 3. **Null** (for a candidate significant after 2 whose model does not remove most of the
//!    error). Its drop must lie beyond what the same scan finds on the start model's own
//!    simulated records, at `alpha` corrected like the block tests.

use serde::Serialize;

use crate::prepare::DiagnoseOptions;

/// What ranked the held-out predictions of the candidates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Judge {
    /// R-MSE of the free-run simulation under the measured input.
    FreeRun,
    /// R-MSE of simulations over pieces of two dominant periods, each from the measured state.
    ShortHorizon,
    /// Held-out equation error only (nothing could be simulated).
    EquationError,
}

impl Judge {
    /// In words, for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Judge::FreeRun => "free-run simulation",
            Judge::ShortHorizon => "short-horizon prediction",
            Judge::EquationError => "equation error",
        }
    }
}

/// The scan's part: the equation-error test of the effect's best variant on held-out blocks.
#[derive(Debug, Clone, PartialEq)]
pub struct EquationEvidence {
    /// One-sided p-value of the combined block tests (uncorrected).
    pub p_raw: f64,
    /// `p_raw` Bonferroni-corrected over every variant tested (at most 1).
    pub p: f64,
    /// Number of variants tested (the correction's factor).
    pub tests: usize,
    /// Relative drop of the held-out equation error, `(RSS_base − RSS_cand)/RSS_base`.
    pub delta: f64,
    /// RMS change of the fitted force over the RMS of `x''`.
    pub share: f64,
}

/// The variant the judge judged when it was not the best by equation error: among the
/// shortlist with the lowest held-out residual, the one whose model predicts best.
#[derive(Debug, Clone, PartialEq)]
pub struct JudgedAt {
    /// The scanned parameter's name and value.
    pub parameter: (String, f64),
    /// How many variants the shortlist held.
    pub shortlist: usize,
}

/// The judge's part: the refitted per-fold models' held-out predictions against the start
/// model's, as the judge chosen for the record set scores them.
#[derive(Debug, Clone, PartialEq)]
pub struct PredictionEvidence {
    /// The judge.
    pub judge: Judge,
    /// Held-out prediction R-MSE of the model without the effect (`None`: not simulated).
    pub before: Option<f64>,
    /// Held-out prediction R-MSE with the effect (`None`: its simulation failed).
    pub after: Option<f64>,
    /// Predicts worse than the model without it by more than the judge resolves, or cannot be
    /// simulated (`None` when the model without it has no score to compare with).
    pub worse: Option<bool>,
    /// Predicts better, resolved by the judge, by at least `min_share` of the motion's RMS or
    /// with at most half the model's own RMS prediction error (both read above `floor`): the
    /// drop of that RMS error as a share of the motion's RMS (`None` otherwise).
    pub better_by: Option<f64>,
    /// The R-MSE the judge leaves to noise, not to any model (`crate::judge::Choice`'s
    /// `floor`: the measured record's and its input's noise under the free run, 0 otherwise);
    /// `better_by` is the drop of the error above it.
    pub floor: f64,
    /// Predicts with at most half the model's whole RMS prediction error (noise included),
    /// resolved by the judge.
    pub removes_most: bool,
    /// The variant judged, when the judge chose it from a shortlist over the best by equation
    /// error.
    pub judged_at: Option<JudgedAt>,
}

/// The calibrated null's part (`null.rs`): the candidate's held-out drop against the same scan
/// on the start model's own simulated records.
#[derive(Debug, Clone, PartialEq)]
pub enum NullEvidence {
    /// Not re-judged: its model removes most of the held-out prediction error, which the
    /// equation error's bias alone cannot do.
    RemovesMost,
    /// Not re-scanned: its drop exceeds the start model's whole held-out residual on every draw.
    Clears {
        /// Draws scored.
        draws: usize,
        /// The largest held-out residual of the start model over the draws.
        largest: f64,
        /// The start model's held-out residual on the measured records.
        measured: f64,
    },
    /// Re-scanned on the draws: the prediction t test of its drop against theirs.
    Tested {
        /// Draws the test rests on.
        draws: usize,
        /// Mean held-out drop over the draws.
        mean: f64,
        /// Its sample standard deviation.
        sd: f64,
        /// One-sided p, corrected like the block tests.
        p: f64,
    },
}

/// Why a candidate is or is not significant: the one decision over its [`Evidence`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Significance {
    /// The test passes, the held-out error falls, the size reaches `min_share`, and neither the
    /// judge nor the null found otherwise.
    Significant,
    /// The test passes and the error falls; below the size (or worse by the judge's first
    /// look), but its refitted model predicts the held-out data better by `min_share` of the
    /// motion's RMS or removes most of the model's prediction error.
    SignificantOnTheMotion,
    /// The held-out equation error does not fall.
    NoFall,
    /// The corrected p is not below `alpha`.
    NotSignificant,
    /// Its size is under `min_share`, and its predictions do not make up for it.
    TooSmall,
    /// Significant by equation error, but its refitted model predicts the held-out data worse.
    PredictsWorse,
    /// Significant by equation error, but its refitted model cannot be simulated on the held-out
    /// data.
    CannotBeSimulated,
    /// Its drop lies within what the equation error's own bias gives with nothing missing.
    WithinTheNull,
}

impl Significance {
    /// True for the two ways of being significant.
    pub fn is_significant(self) -> bool {
        matches!(
            self,
            Significance::Significant | Significance::SignificantOnTheMotion
        )
    }

    /// In words, for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Significance::Significant => "significant by equation error",
            Significance::SignificantOnTheMotion => {
                "significant: small on the force, large on the motion"
            }
            Significance::NoFall => "the held-out equation error does not fall",
            Significance::NotSignificant => "the test does not pass",
            Significance::TooSmall => "too small",
            Significance::PredictsWorse => "its model predicts the held-out data worse",
            Significance::CannotBeSimulated => "its model cannot be simulated on the held-out data",
            Significance::WithinTheNull => "within what the equation error's bias gives",
        }
    }
}

impl std::fmt::Display for Significance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.describe())
    }
}

/// Everything the stages found for one candidate effect, each part written once by its stage
/// (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Evidence {
    equation: EquationEvidence,
    prediction: Option<PredictionEvidence>,
    null: Option<NullEvidence>,
}

impl Evidence {
    /// The evidence of a scanned candidate: its equation-error test, nothing else yet.
    pub fn new(equation: EquationEvidence) -> Self {
        Self {
            equation,
            prediction: None,
            null: None,
        }
    }

    /// The judge's part, written once.
    pub(crate) fn record_prediction(&mut self, p: PredictionEvidence) {
        debug_assert!(self.prediction.is_none(), "the judge writes its part once");
        self.prediction = Some(p);
    }

    /// The null's part, written once.
    pub(crate) fn record_null(&mut self, n: NullEvidence) {
        debug_assert!(self.null.is_none(), "the null writes its part once");
        self.null = Some(n);
    }

    /// The scan's part.
    pub fn equation(&self) -> &EquationEvidence {
        &self.equation
    }

    /// The judge's part (`None` when the candidates were not simulated).
    pub fn prediction(&self) -> Option<&PredictionEvidence> {
        self.prediction.as_ref()
    }

    /// The null's part (`None` when it did not re-judge the candidate or could not be made).
    pub fn null(&self) -> Option<&NullEvidence> {
        self.null.as_ref()
    }

    /// The decision before the null: steps 1 and 2 of the module docs.
    pub fn judged(&self, opts: &DiagnoseOptions) -> Significance {
        judged(&self.equation, self.prediction.as_ref(), opts)
    }

    /// The decision: steps 1 to 3 of the module docs.
    pub fn significance(&self, opts: &DiagnoseOptions) -> Significance {
        let judged = self.judged(opts);
        match &self.null {
            Some(NullEvidence::Tested { p, .. }) if judged.is_significant() && *p >= opts.alpha => {
                Significance::WithinTheNull
            }
            _ => judged,
        }
    }

    /// Why the candidate is (not) significant, in words, with the numbers each stage found.
    pub fn reason(&self, opts: &DiagnoseOptions) -> String {
        let eq = &self.equation;
        let drop_words = |null: String, p: f64| {
            format!(
                "held-out equation error falls {:.1} %, but {null}: not beyond what the equation error's own bias gives with nothing missing (corrected p = {p:.2e} >= alpha = {})",
                100.0 * eq.delta,
                opts.alpha
            )
        };
        if let (Significance::WithinTheNull, Some(NullEvidence::Tested { draws, mean, sd, p })) =
            (self.significance(opts), &self.null)
        {
            return drop_words(null_words(*draws, *mean, *sd), *p);
        }
        let mut words = judged_words(eq, self.prediction.as_ref(), self.judged(opts), opts);
        if let Some(at) = self.prediction.as_ref().and_then(|p| p.judged_at.as_ref()) {
            let (name, value) = &at.parameter;
            words.push_str(&format!(
                "; judged at {name} = {value}, of the {} values with the lowest held-out residual the one whose model predicts the held-out data best (`refit` chooses it so)",
                at.shortlist
            ));
        }
        match &self.null {
            Some(NullEvidence::RemovesMost) => words.push_str(
                "; its model removes most of the held-out prediction error, which the equation error's bias alone cannot do, so the calibrated null does not re-judge it",
            ),
            Some(NullEvidence::Clears {
                draws,
                largest,
                measured,
            }) => words.push_str(&format!(
                "; it removes more than the start model's whole held-out residual on any of {draws} simulations of itself with the estimated measurement noise (at most {:.1} % of the measured one): more than the equation error's own bias can give",
                100.0 * largest / measured
            )),
            Some(NullEvidence::Tested { draws, mean, sd, p }) => words.push_str(&format!(
                "; {} (corrected p = {p:.2e})",
                null_words(*draws, *mean, *sd)
            )),
            None => {}
        }
        words
    }
}

/// Steps 1 and 2 of the decision (module docs) on the scan's and the judge's parts.
pub(crate) fn judged(
    eq: &EquationEvidence,
    prediction: Option<&PredictionEvidence>,
    opts: &DiagnoseOptions,
) -> Significance {
    let falls = eq.delta > 0.0;
    let passes_p = eq.p < opts.alpha;
    let by_equation = passes_p && falls && eq.share >= opts.min_share;
    let by_equation_alone = if by_equation {
        Significance::Significant
    } else if !falls {
        Significance::NoFall
    } else if !passes_p {
        Significance::NotSignificant
    } else {
        Significance::TooSmall
    };
    let Some(pr) = prediction else {
        return by_equation_alone;
    };
    let vetoed = by_equation && pr.worse == Some(true);
    if by_equation && !vetoed {
        Significance::Significant
    } else if passes_p && falls && pr.better_by.is_some() {
        Significance::SignificantOnTheMotion
    } else if vetoed && pr.after.is_some() {
        Significance::PredictsWorse
    } else if vetoed {
        Significance::CannotBeSimulated
    } else {
        by_equation_alone
    }
}

/// The words of steps 1 and 2 for the decision `judged`.
fn judged_words(
    eq: &EquationEvidence,
    prediction: Option<&PredictionEvidence>,
    judged: Significance,
    opts: &DiagnoseOptions,
) -> String {
    let (p, tests) = (eq.p, eq.tests);
    let judge = prediction.map_or("", |pr| pr.judge.describe());
    let before = prediction.and_then(|pr| pr.before).unwrap_or(f64::NAN);
    let after = prediction.and_then(|pr| pr.after).unwrap_or(f64::NAN);
    let floor = prediction.map_or(0.0, |pr| pr.floor);
    match judged {
        Significance::Significant => format!(
            "held-out equation error falls {:.1} %, p = {p:.2e} (corrected over {tests} tests), size {:.1} % of the force RMS",
            100.0 * eq.delta,
            100.0 * eq.share
        ),
        Significance::NoFall => "held-out equation error does not fall".to_string(),
        Significance::NotSignificant => format!(
            "not significant: corrected p = {p:.2e} >= alpha = {}",
            opts.alpha
        ),
        Significance::TooSmall => format!(
            "significant but too small: {:.2} % of the force RMS < {:.1} %",
            100.0 * eq.share,
            100.0 * opts.min_share
        ),
        Significance::PredictsWorse => format!(
            "held-out equation error falls {:.1} %, but the refitted model predicts the held-out data worse ({judge} R-MSE {after:.3e} vs {before:.3e})",
            100.0 * eq.delta,
        ),
        Significance::CannotBeSimulated => format!(
            "held-out equation error falls {:.1} %, but the refitted model cannot be simulated on the held-out data",
            100.0 * eq.delta
        ),
        Significance::SignificantOnTheMotion | Significance::WithinTheNull => {
            let drop = prediction.and_then(|pr| pr.better_by).unwrap_or(f64::NAN);
            let how = if drop >= opts.min_share {
                format!("by {:.1} % of the motion's RMS", 100.0 * drop)
            } else if floor > 0.0 {
                format!(
                    "with {:.1} % of the RMS prediction error of the model without it above what the noise leaves (R-MSE {floor:.3e}), most of what that model misses",
                    100.0 * ((after - floor).max(0.0) / (before - floor)).sqrt()
                )
            } else {
                format!(
                    "with {:.1} % of the RMS prediction error of the model without it, most of what that model misses",
                    100.0 * (after / before).sqrt()
                )
            };
            format!(
                "held-out equation error falls {:.1} %, p = {p:.2e}; size {:.2} % of the force RMS, under {:.1} %, but the refitted model predicts the held-out data better {how} ({judge} R-MSE {after:.3e} vs {before:.3e})",
                100.0 * eq.delta,
                100.0 * eq.share,
                100.0 * opts.min_share,
            )
        }
    }
}

/// What the null's draws gave, in words.
fn null_words(draws: usize, mean: f64, sd: f64) -> String {
    format!(
        "on {draws} simulations of the start model with the estimated measurement noise it falls {:.1} ± {:.1} %",
        100.0 * mean,
        100.0 * sd
    )
}

#[cfg(test)]
mod tests;
