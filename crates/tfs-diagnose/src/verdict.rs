//! The diagnosis's one-sentence verdict: the top significant effect, what it cannot be told
//! apart from, and the judge that ranked it — or that no candidate is significant.

use crate::judge::{Judge, JudgeUse};
use crate::prepare::DiagnoseOptions;
use crate::rank::RankedEffect;

/// One sentence: the top significant effect and the judge that ranked it, or that none is.
pub(crate) fn verdict(
    ranked: &[RankedEffect],
    judges: &[JudgeUse],
    opts: &DiagnoseOptions,
) -> String {
    match ranked.iter().find(|r| r.significant) {
        Some(top) => {
            let judged = judges
                .iter()
                .find(|u| u.dof == top.dof && !u.plain)
                .map(|u| {
                    let (j, why) = (u.judge, &u.why);
                    if j == Judge::FreeRun {
                        return format!("; judged by {why}");
                    }
                    let ties = if j == Judge::ShortHorizon {
                        " (its ties broken by the geometric-mean error over the pieces)"
                    } else {
                        ""
                    };
                    format!(
                        "; ranked by held-out equation error{ties}, judged by {} ({why}; a candidate that predicts worse is not reported)",
                        j.describe()
                    )
                })
                .unwrap_or_default();
            let tied: Vec<&str> = ranked
                .iter()
                .filter(|r| r.tied_with_top && r.dof == top.dof)
                .map(|r| r.name.as_str())
                .collect();
            let ties = if tied.is_empty() {
                String::new()
            } else {
                format!(
                    "; indistinguishable on these records from {} (the held-out equation error does not tell them apart at alpha {}, nor does the judge): the data cannot say which is missing",
                    tied.join(", "),
                    opts.alpha
                )
            };
            format!(
                "missing effect: {} ({}){ties}{judged}; add it with --add {}",
                top.name, top.reason, top.name
            )
        }
        None => format!(
            "no significant missing effect among {} candidates (corrected alpha {}, minimum size {:.1} % of the force RMS)",
            ranked.len(),
            opts.alpha,
            100.0 * opts.min_share
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evidence::{EquationEvidence, Evidence, Significance};

    fn effect(name: &str) -> RankedEffect {
        RankedEffect {
            name: name.into(),
            effect: name.into(),
            dof: "x".into(),
            parameter: None,
            terms: vec![],
            significant: true,
            p_value_raw: 1e-6,
            p_value: 1e-5,
            delta_heldout: 0.5,
            coef: 1.0,
            interval: [0.9, 1.1],
            share: 0.2,
            judge: Some(Judge::FreeRun),
            r_mse_before: Some(0.2),
            r_mse_after: Some(0.02),
            tied_with_top: false,
            reason: "passes".into(),
            significance: Significance::Significant,
            evidence: Evidence::new(EquationEvidence {
                p_raw: 1e-6,
                p: 1e-5,
                tests: 10,
                delta: 0.5,
                share: 0.2,
            }),
        }
    }

    fn use_of(judge: Judge, why: &str, plain: bool) -> JudgeUse {
        JudgeUse {
            dof: "x".into(),
            judge,
            why: why.into(),
            plain,
        }
    }

    /// The plain free run goes unnamed; a free run with a reason of its own, and any other
    /// judge, is named with that reason — whatever the wording of the reasons.
    #[test]
    fn verdict_names_the_judge_unless_it_is_the_plain_free_run() {
        let ranked = [effect("stop")];
        let opts = DiagnoseOptions::default();
        let plain = verdict(&ranked, &[use_of(Judge::FreeRun, "any words", true)], &opts);
        assert!(plain.starts_with("missing effect: stop"), "{plain}");
        assert!(!plain.contains("judged by"), "{plain}");
        let rows = verdict(
            &ranked,
            &[use_of(Judge::FreeRun, "over the fitted rows", false)],
            &opts,
        );
        assert!(rows.contains("; judged by over the fitted rows"), "{rows}");
        let short = verdict(
            &ranked,
            &[use_of(Judge::ShortHorizon, "input noise dominates", false)],
            &opts,
        );
        assert!(
            short.contains("judged by short-horizon prediction (input noise dominates"),
            "{short}"
        );
        assert!(short.contains("its ties broken"), "{short}");
        // Another DOF's judge says nothing about this one.
        let other = JudgeUse {
            dof: "y".into(),
            ..use_of(Judge::ShortHorizon, "elsewhere", false)
        };
        assert!(!verdict(&ranked, &[other], &opts).contains("judged by"));
    }
}
