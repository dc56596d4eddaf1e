//! The diagnosis's one-sentence verdict: the top significant effect, what it cannot be told
//! apart from, and the judge that ranked it — or that no candidate is significant.

use crate::explain::RankedEffect;
use crate::judge::Judge;
use crate::prepare::DiagnoseOptions;

/// One sentence: the top significant effect and the judge that ranked it, or that none is.
pub(crate) fn verdict(
    ranked: &[RankedEffect],
    judges: &[(String, Judge, String)],
    opts: &DiagnoseOptions,
) -> String {
    match ranked.iter().find(|r| r.significant) {
        Some(top) => {
            let judged = judges
                .iter()
                .find(|(d, j, why)| {
                    *d == top.dof && (*j != Judge::FreeRun || why != crate::judge::FREE_RUN_WHY)
                })
                .map(|(_, j, why)| {
                    if *j == Judge::FreeRun {
                        return format!("; judged by {why}");
                    }
                    let ties = if *j == Judge::ShortHorizon {
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
