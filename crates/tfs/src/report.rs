//! What `identify` and `refit` did besides fitting, as types: the treatment of the records'
//! offsets and the simulation-error refinement. They serialise to the JSON the CLI prints under
//! `--json` and the model file's trace holds (`offsets`, `refine`), and the human output is
//! printed from them.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use tfs_criteria::{Problem, Support, Trace};
use tfs_diagnose::LadderStep;
use tfs_library::Model;

use crate::records::Offsets;

/// What was done with one record's channel offsets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum RecordOffsets {
    /// The offsets were removed: each listed channel's mean, subtracted from it.
    Removed {
        /// The record's source name.
        record: String,
        /// The value subtracted from each channel.
        removed: BTreeMap<String, f64>,
    },
    /// The records were used as they are: each listed channel's mean, left in place.
    Kept {
        /// The record's source name.
        record: String,
        /// The mean of each channel.
        mean: BTreeMap<String, f64>,
    },
}

impl RecordOffsets {
    /// The record's source name.
    pub fn record(&self) -> &str {
        match self {
            RecordOffsets::Removed { record, .. } | RecordOffsets::Kept { record, .. } => record,
        }
    }
}

/// How the DC offsets of a set of records were treated (the `offsets` key of the CLI's JSON
/// and of a model file's trace).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OffsetsReport {
    /// The mode applied: `keep`, `remove`, or `constant-term` (records kept, constant term in
    /// the library).
    pub mode: Offsets,
    /// Why that mode was chosen, in words.
    pub why: String,
    /// The DOF and input columns the mode applies to.
    pub channels: Vec<String>,
    /// Per record, the offsets removed or the means kept.
    pub per_record: Vec<RecordOffsets>,
    /// `identify` only: the mode the user asked for (`auto` included).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub requested: Option<Offsets>,
    /// `identify --offsets constant-term` only: whether the constant term had to be added to
    /// the library (false when the library already had it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub constant_term_added: Option<bool>,
}

impl OffsetsReport {
    /// The report as JSON (sorted keys, as the model file's trace stores it).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("an offsets report is plain data and always serialises")
    }
}

/// Per record, the RMS simulation errors of two models: (source name, first, second), RMS over
/// DOFs in the record's units, `+∞` for a blow-up.
pub type RecordErrors = Vec<(String, f64, f64)>;

/// What the choice between the equation-error fit and the simulation-error fit on held-out
/// records found (the `validation` key of [`RefineReport`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationReport {
    /// Held-out score of the equation-error fit (sum over records of squared RMS errors
    /// normalised by the record's displacement RMS).
    pub equation_error_fit: f64,
    /// The same for the simulation-error fit.
    pub simulation_error_fit: f64,
    /// True if the simulation-error fit was kept.
    pub chose_refined: bool,
    /// Per held-out record: the two fits' RMS errors.
    pub per_record: RecordErrors,
    /// Held-out records left out of the choice because their error is about their input's own
    /// noise: (source name, spread a fresh draw of that noise causes, error).
    pub noise_dominated: RecordErrors,
}

impl From<&tfs_refine::ValidationScores> for ValidationReport {
    fn from(s: &tfs_refine::ValidationScores) -> Self {
        ValidationReport {
            equation_error_fit: s.eq_score,
            simulation_error_fit: s.refined_score,
            chose_refined: s.chose_refined,
            per_record: s.per_record.clone(),
            noise_dominated: s.noise_dominated.clone(),
        }
    }
}

/// What the simulation-error refinement did (the `refine` key of the CLI's JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RefineReport {
    /// Training simulation cost of the start model (`+∞` if it blows up).
    pub initial_cost: f64,
    /// The same cost after refinement; never above `initial_cost`.
    pub final_cost: f64,
    /// Levenberg-Marquardt iterations over all stages.
    pub iterations: usize,
    /// True if the last stage met a stopping tolerance.
    pub converged: bool,
    /// What happened, in words.
    pub message: String,
    /// Per training record: RMS simulation error before and after.
    pub per_record: RecordErrors,
    /// Training records left out because their free-run error is about the input's own noise:
    /// (source name, spread a fresh draw of that noise causes, error of the start model).
    pub noise_dominated: RecordErrors,
    /// With held-out records: which fit predicted them better.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validation: Option<ValidationReport>,
}

impl From<&tfs_refine::Refined> for RefineReport {
    fn from(r: &tfs_refine::Refined) -> Self {
        RefineReport {
            initial_cost: r.initial_cost,
            final_cost: r.final_cost,
            iterations: r.iterations,
            converged: r.converged,
            message: r.message.clone(),
            per_record: r.per_record.clone(),
            noise_dominated: r.noise_dominated.clone(),
            validation: None,
        }
    }
}

impl RefineReport {
    /// The report as JSON (the CLI's `refine` key).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("a refinement report is plain data and always serialises")
    }

    /// The report as lines for a terminal: the cost before and after, records left out, and
    /// the held-out choice.
    pub fn lines(&self) -> Vec<String> {
        let num = |x: f64| {
            if x.is_finite() {
                format!("{x:.4e}")
            } else {
                "—".to_string()
            }
        };
        let mut out = vec![format!(
            "refinement by simulation error: cost {} -> {} in {} iteration(s), {}{}",
            num(self.initial_cost),
            num(self.final_cost),
            self.iterations,
            if self.converged {
                "converged"
            } else {
                "not converged"
            },
            if self.message.is_empty() {
                String::new()
            } else {
                format!(" ({})", self.message)
            }
        )];
        if !self.noise_dominated.is_empty() {
            out.push(format!(
                "  {} record(s) left out: their error is about the measured input's own noise",
                self.noise_dominated.len()
            ));
        }
        if let Some(v) = &self.validation
            && v.per_record.is_empty()
        {
            out.push(format!(
                "  held-out records: all {} left out (their free runs cannot rank the fits: the input's own noise or the run's own divergence moves them about as far as their error); kept the equation-error fit",
                v.noise_dominated.len()
            ));
        } else if let Some(v) = &self.validation {
            out.push(format!(
                "  held-out records: equation-error fit {}, simulation-error fit {}; kept the {}",
                num(v.equation_error_fit),
                num(v.simulation_error_fit),
                if v.chose_refined {
                    "simulation-error fit"
                } else {
                    "equation-error fit"
                }
            ));
            if !v.noise_dominated.is_empty() {
                out.push(format!(
                    "  ({} held-out record(s) left out of that choice: the input's own noise or the run's own divergence moves their free run about as far as its error)",
                    v.noise_dominated.len()
                ));
            }
        }
        out
    }
}

/// The support verdict of every DOF whose data do not support its library, one warning each,
/// worded so that it agrees with the model printed under it: when the full library failed and
/// the model was reduced one significance test at a time, the terms of the first fit that
/// failed are split into those removed and those the reduced model keeps (they pass in it).
pub fn support_warnings(trace: &Trace, model: &Model) -> Vec<String> {
    trace
        .dofs
        .iter()
        .filter_map(|d| {
            let c1 = d.criterion1.as_ref()?;
            if c1.support.is_supported() {
                return None;
            }
            if let Support::NotSupported {
                problem: problem @ Problem::Reduced { snr_db, first },
                ..
            } = &c1.support
                && let Problem::FailsTermTest { terms, .. } = first.as_ref()
            {
                let kept: Vec<String> = model
                    .equations
                    .iter()
                    .filter(|e| e.dof == d.dof)
                    .flat_map(|e| e.terms.iter().map(|t| t.term.to_string()))
                    .collect();
                // The verdict's own sentence (its cause and advice), with the reduction said
                // so that it agrees with the model.
                let said = c1.support.to_string().replacen(
                    &problem.to_string(),
                    &reduced_problem(*snr_db, terms, &kept),
                    1,
                );
                return Some(format!("{}: {said}", d.dof));
            }
            Some(format!("{}: {}", d.dof, c1.support))
        })
        .collect()
}

/// Why a DOF's full library was not supported and its model reduced, said so that it agrees
/// with the reduced model: the first fit's failing `terms` split into those removed and those
/// the reduced model keeps (`kept`, its terms), so that no term of the printed model is called
/// failing.
fn reduced_problem(
    snr_db: Option<tfs_criteria::SnrEstimate>,
    terms: &[String],
    kept: &[String],
) -> String {
    let (stayed, removed): (Vec<&str>, Vec<&str>) = terms
        .iter()
        .map(String::as_str)
        .partition(|t| kept.iter().any(|k| k == t));
    let snr = snr_db.map_or(String::new(), |v| {
        format!(" (estimated displacement SNR {v})")
    });
    let mut w = format!(
        "the full library was not supported{snr}: in the first fit {} failed the term test; ",
        terms.join(", ")
    );
    if !removed.is_empty() {
        w.push_str(&format!(
            "{} removed one significance test at a time",
            removed.join(", ")
        ));
    }
    if !stayed.is_empty() {
        w.push_str(&format!(
            "{}{} kept (significant once the others were removed)",
            if removed.is_empty() { "" } else { ", " },
            stayed.join(", ")
        ));
    }
    w.push_str(", so check the reduced model against held-out records (`tfs compare`) before relying on it");
    w
}

/// Why a DOF's kept terms have no coefficient intervals, one line per such DOF (the trace's
/// reason, e.g. too few independent windows to resample, and what to do), so that missing
/// intervals are never dropped silently.
pub fn interval_notes(trace: &Trace, model: &Model) -> Vec<String> {
    let mut out = Vec::new();
    for e in &model.equations {
        if e.terms.is_empty() || e.terms.iter().any(|t| t.interval.is_some()) {
            continue;
        }
        let why = trace
            .dofs
            .iter()
            .find(|d| d.dof == e.dof)
            .and_then(|d| {
                d.settings
                    .why
                    .iter()
                    .find(|w| w.starts_with("no coefficient intervals"))
            })
            .map(|w| w.split(';').next().unwrap_or(w).to_string());
        let Some(why) = why else { continue };
        out.push(format!(
            "{}: {why}; give two or more records, or longer ones, for intervals",
            e.dof
        ));
    }
    out
}

/// What the error ladder of a refit says about the effects added, in one sentence.
#[derive(Debug, Clone, PartialEq)]
pub struct LadderVerdict {
    /// The sentence: the geometric-mean R-MSE over the records before and after, or which step
    /// failed.
    pub sentence: String,
    /// True when the geometric-mean R-MSE fell from the first step to the last, false when it rose;
    /// `None` when a step could not simulate every record (the means are not comparable).
    pub improved: Option<bool>,
}

/// The verdict of an error ladder: the first step (the model refit started from) against the
/// last (the model returned).
pub fn ladder_verdict(ladder: &[LadderStep]) -> LadderVerdict {
    let (Some(first), Some(last)) = (ladder.first(), ladder.last()) else {
        return LadderVerdict {
            sentence: "nothing was added".into(),
            improved: None,
        };
    };
    // The steps' own labels (`add linear-damping`), not the terms each step added.
    let added: Vec<&str> = ladder[1..]
        .iter()
        .map(|s| s.step.strip_prefix("add ").unwrap_or(&s.step))
        .collect();
    let added = if added.is_empty() {
        "nothing".to_string()
    } else {
        added.join(", ")
    };
    if last.incomplete() {
        return LadderVerdict {
            sentence: format!(
                "after adding {added}, the simulation fails on {} of {} record(s) ({}): the model is not usable on them",
                last.failed.len(),
                last.failed.len() + last.r_mse.len(),
                last.failed[0]
            ),
            improved: None,
        };
    }
    if first.incomplete() || !first.geo_mean_r_mse.is_finite() {
        return LadderVerdict {
            sentence: format!(
                "after adding {added}, every record simulates (geometric-mean R-MSE {:.4e}; the start model failed on {} record(s))",
                last.geo_mean_r_mse,
                first.failed.len()
            ),
            improved: Some(true),
        };
    }
    let (a, b) = (first.geo_mean_r_mse, last.geo_mean_r_mse);
    if b < a {
        LadderVerdict {
            sentence: format!(
                "adding {added} lowered the geometric-mean R-MSE over the records from {a:.4e} to {b:.4e} ({}x)",
                tfs_library::sig4(a / b)
            ),
            improved: Some(true),
        }
    } else {
        LadderVerdict {
            sentence: format!(
                "adding {added} raised the geometric-mean R-MSE over the records from {a:.4e} to {b:.4e}: the records do not support it (`diagnose` names the effects they do)"
            ),
            improved: Some(false),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(noise: usize, validation: Option<ValidationReport>) -> RefineReport {
        RefineReport {
            initial_cost: 2.0,
            final_cost: 1.0,
            iterations: 3,
            converged: true,
            message: String::new(),
            per_record: vec![("a.csv".into(), 0.2, 0.1)],
            noise_dominated: (0..noise)
                .map(|i| (format!("n{i}.csv"), 0.1, 0.1))
                .collect(),
            validation,
        }
    }

    /// A term the first fit failed and the reduced model keeps is not called failing.
    #[test]
    fn a_reduced_model_s_warning_agrees_with_its_terms() {
        let terms: Vec<String> = ["x^3", "x'", "force"].map(String::from).to_vec();
        let kept: Vec<String> = ["x", "x^3", "force"].map(String::from).to_vec();
        let w = reduced_problem(None, &terms, &kept);
        assert!(w.contains("x' removed"), "{w}");
        assert!(w.contains("x^3, force kept"), "{w}");
        assert!(
            !w.contains("x^3, x' removed") && !w.contains("force removed"),
            "{w}"
        );
    }

    #[test]
    fn ladder_verdicts_say_whether_the_error_fell() {
        let step = |name: &str, mean: f64| LadderStep {
            step: name.into(),
            added: vec!["x'".into()],
            mean_r_mse: mean,
            geo_mean_r_mse: mean,
            r_mse: Vec::new(),
            failed: Vec::new(),
        };
        let v = ladder_verdict(&[step("start", 1.0), step("add linear-damping", 0.25)]);
        assert_eq!(v.improved, Some(true));
        assert!(
            v.sentence.contains("adding linear-damping lowered"),
            "{}",
            v.sentence
        );
        assert!(v.sentence.contains("(4.000x)"), "{}", v.sentence);
        let v = ladder_verdict(&[step("start", 1.0), step("add offset", 2.0)]);
        assert_eq!(v.improved, Some(false));
        assert!(v.sentence.contains("raised"), "{}", v.sentence);
        let mut failed = step("add stop", f64::NAN);
        failed.failed = vec!["a.csv: blew up at t = 3 s".into()];
        let v = ladder_verdict(&[step("start", 1.0), failed]);
        assert_eq!(v.improved, None);
        assert!(v.sentence.contains("fails on 1 of 1"), "{}", v.sentence);
    }

    #[test]
    fn records_left_out_are_counted() {
        // Left-out records are (name, spread, error) triples; the old JSON-reading code looked
        // for `true` among them and never printed this line.
        let lines = report(2, None).lines();
        assert!(lines[1].contains("2 record(s) left out"), "{lines:?}");
        assert_eq!(report(0, None).lines().len(), 1);
    }

    #[test]
    fn held_out_records_all_left_out_are_not_scored_as_zero() {
        let v = ValidationReport {
            equation_error_fit: 0.0,
            simulation_error_fit: 0.0,
            chose_refined: false,
            per_record: Vec::new(),
            noise_dominated: vec![("h.csv".into(), 0.3, 0.4)],
        };
        let lines = report(0, Some(v)).lines();
        let last = lines.last().unwrap();
        assert!(last.contains("all 1 left out"), "{lines:?}");
        assert!(!last.contains("0.0000e0"), "{lines:?}");
    }

    #[test]
    fn reports_round_trip_through_json() {
        let r = report(1, None);
        let back: RefineReport = serde_json::from_value(r.to_json()).unwrap();
        assert_eq!(back, r);
        assert!(r.to_json().get("validation").is_none());
        let o = OffsetsReport {
            mode: Offsets::ConstantTerm,
            why: "given".into(),
            channels: vec!["x".into()],
            per_record: vec![RecordOffsets::Kept {
                record: "a.csv".into(),
                mean: [("x".to_string(), 0.5)].into(),
            }],
            requested: Some(Offsets::Auto),
            constant_term_added: Some(true),
        };
        let j = o.to_json();
        assert_eq!(j["mode"], "constant-term");
        assert_eq!(j["requested"], "auto");
        assert_eq!(j["per_record"][0]["mean"]["x"], 0.5);
        assert_eq!(serde_json::from_value::<OffsetsReport>(j).unwrap(), o);
    }
}
