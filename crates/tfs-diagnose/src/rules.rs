//! The rules the diagnosis applies, as data: each with the stage it belongs to, the threshold it
//! uses (read from the code's own constants and option defaults, so the list cannot drift from
//! them) and what it decides. `docs/diagnosis.md` carries [`rules_table`] verbatim, checked by a
//! test, the way a linter lists its lints.

use crate::DiagnoseOptions;

/// One rule in force.
#[derive(Debug, Clone, PartialEq)]
pub struct Rule {
    /// Short name.
    pub name: &'static str,
    /// The stage that applies it (scan, judge, null, rank, residual, refit).
    pub stage: &'static str,
    /// The threshold or setting, in words with its value.
    pub threshold: String,
    /// What it decides.
    pub decides: &'static str,
}

/// The diagnosis's rules with the default options' thresholds, in the order they apply.
pub fn rules() -> Vec<Rule> {
    let o = DiagnoseOptions::default();
    let r = |name, stage, threshold: String, decides| Rule {
        name,
        stage,
        threshold,
        decides,
    };
    vec![
        r(
            "cut-off",
            "scan",
            format!(
                "highest bin at least `floor_factor` = {} times the noise floor, plus 10 %",
                o.floor_factor
            ),
            "the low-pass of the smoothed states x, x', x'' every candidate is scored on",
        ),
        r(
            "blocks",
            "scan",
            format!(
                "about `blocks` = {} held-out blocks, at least four cut-off periods each; folds are records, or `time_folds` = {} time segments of one record",
                o.blocks, o.time_folds
            ),
            "the units of the paired tests; each fold is fitted on the others",
        ),
        r(
            "test",
            "scan",
            format!(
                "corrected p < `alpha` = {}: the least of three one-sided looks (held-out drop, its log-ratio, the added coefficient's block-robust Wald test) times 3, times the number of variants tested",
                o.alpha
            ),
            "whether the held-out equation error falls by more than chance",
        ),
        r(
            "falls",
            "scan",
            "held-out equation error lower with the effect than without".to_string(),
            "an effect that does not lower it is never significant",
        ),
        r(
            "size",
            "scan",
            format!(
                "RMS change of the fitted force ≥ `min_share` = {} of the RMS of x''",
                o.min_share
            ),
            "significant by equation error: test, falls and size all hold",
        ),
        r(
            "judge",
            "judge",
            format!(
                "free run under the measured input; short-horizon pieces when on any record a fresh draw of the input's noise, or the run's own divergence from a start one displacement-noise std away (where the runs end farther apart than they started), moves the free run about as far as the model's error (pieces as long as the start model's predictions keep their skill, over {} starts per record)",
                crate::judge::HORIZON_STARTS
            ),
            "how held-out predictions are scored, once per record set",
        ),
        r(
            "range",
            "judge",
            format!(
                "every run on a record stops once a measured displacement leaves the record's span widened by {} spans on each side; a tied chain's fold model also stops as blown up past {} times the record's largest state",
                tfs_dynamics::RANGE_SPANS,
                crate::judge::RANGE_FACTOR
            ),
            "a prediction that leaves the records' range fails instead of crawling",
        ),
        r(
            "worse",
            "judge",
            format!(
                "free run: mean R-MSE higher by more than the input-noise spread (unless neither shows skill); short horizon: paired one-sided tests over the pieces at `alpha` = {}",
                o.alpha
            ),
            "a significant effect whose refitted model predicts the held-out data worse is not significant",
        ),
        r(
            "small on the force, large on the motion",
            "judge",
            format!(
                "test passed and error falls, and the refitted model predicts better by ≥ `min_share` = {} of the motion's RMS, or with at most {} of the start model's RMS prediction error (both read above the error the records' own noise leaves under the free run)",
                o.min_share,
                crate::judge::MOST_OF_THE_ERROR
            ),
            "an effect under the size threshold is significant",
        ),
        r(
            "alternatives",
            "judge",
            format!(
                "of the {} scanned parameter values with the lowest held-out residual, the one whose model predicts best",
                crate::score::SHORTLIST
            ),
            "the parameter (stop position, time constant, …) that is reported and refitted",
        ),
        r(
            "null",
            "null",
            format!(
                "`null_draws` = {} simulations of the start model with the estimated noise, scanned the same way; the held-out drop must lie beyond theirs",
                o.null_draws
            ),
            "a significant effect within the equation error's own bias is not significant, unless its model removes most of the held-out prediction error",
        ),
        r(
            "order",
            "rank",
            format!(
                "significant first; by free-run R-MSE where the free run judges and shows skill (below 1), else by held-out equation error; under the free run, a candidate leaving less than {} of the top one's held-out equation error (the paired block test at `alpha` = {} agreeing) goes first",
                crate::rank::DECISIVE_RATIO,
                o.alpha
            ),
            "the ranking and the effect named first",
        ),
        r(
            "ties",
            "rank",
            format!(
                "neither the paired block test of held-out equation errors nor the judge tells it from the top at `alpha` = {}",
                o.alpha
            ),
            "reported as tied: the records cannot say which of the two is missing",
        ),
        r(
            "noise",
            "residual",
            format!(
                "residual at most {} times what the estimated measurement noise leaves; records clean at an estimated SNR of {} dB or more",
                crate::residual::NOISE_FACTOR,
                crate::noise::CLEAN_SNR_DB
            ),
            "whether the residual line calls the residual noise",
        ),
        r(
            "refit toward the start",
            "refit",
            format!(
                "the added effect fitted with the start terms held, with ridge weights {:?} toward the start, and free; the fit whose free runs predict the fit records best is kept; when it does not predict them better than the start model (and that simulates every fit record), the best of the steps {:?} toward it, or the start model itself (nothing added)",
                crate::anchor::RIDGE,
                crate::anchor::STEPS
            ),
            "the model `refit --add` returns",
        ),
        r(
            "polish",
            "refit",
            format!(
                "a pattern search of at most {} evaluations within the scanned range",
                crate::polish::MAX_EVALS
            ),
            "a memory effect's parameters after the scan",
        ),
    ]
}

/// [`rules`] as a Markdown table (the one `docs/diagnosis.md` carries).
pub fn rules_table() -> String {
    let mut s = String::from("| rule | stage | threshold | decides |\n|---|---|---|---|\n");
    for r in rules() {
        s.push_str(&format!(
            "| {} | {} | {} | {} |\n",
            r.name, r.stage, r.threshold, r.decides
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    /// `docs/diagnosis.md` carries the table of the rules in force as the code states them: a
    /// threshold changed in the code and not in the docs fails here (the expected table is
    /// printed, to paste).
    #[test]
    fn the_docs_table_is_the_code_s() {
        let docs = include_str!("../../../docs/diagnosis.md");
        let table = super::rules_table();
        assert!(
            docs.contains(&table),
            "docs/diagnosis.md does not carry the rules table; paste this:\n\n{table}"
        );
    }
}
