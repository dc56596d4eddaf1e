//! The trace of an identification run: what each stage measured and decided, per DOF, and the
//! identified model with it. Typed, with verdicts that print as sentences (`Display`); it
//! serialises to JSON only at the edges (the model file, the CLI's `--json`).

use std::fmt;

use serde::{Serialize, Serializer};
use tfs_library::Model;

use crate::criterion1::kappa::Criterion1;
use crate::criterion2::Criterion2;
use crate::criterion3::TransformForm;
use crate::uncertainty::TermTest;

/// Bins kept by Criterion 3 for one record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordBins {
    /// Record name.
    pub record: String,
    /// Reconstruction cut-off (Hz) of this DOF in this record.
    pub cutoff_hz: f64,
    /// The cut-off that best reconstructs the displacement itself (Hz); `cutoff_hz` adds the
    /// guard band of [`crate::Criterion3Options::guard_octaves`] to it.
    pub mse_cutoff_hz: f64,
    /// Estimated in-band noise share of the displacement power.
    pub in_band_noise_share: f64,
    /// Bins kept (over all windows).
    pub kept_bins: usize,
    /// Lowest and highest kept frequency (Hz).
    pub band_hz: [f64; 2],
    /// Decimation factor of the windowed transforms (exact for the kept bins; see the docs).
    pub decimation: usize,
}

/// Held-out score of one (δ, windows) setting.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SettingScore {
    /// δ.
    pub delta: f64,
    /// Windows per record.
    pub windows: usize,
    /// Mean over folds of the held-out relative residual energy.
    pub held_out_error: f64,
}

/// Settings chosen from the training data, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChosenSettings {
    /// Criterion 3 variant.
    pub form: TransformForm,
    /// δ.
    pub delta: f64,
    /// Windows per record.
    pub windows: usize,
    /// Scaled STLSQ threshold of the final model.
    pub threshold: f64,
    /// Every candidate setting with its score for selecting terms (held-out error of the
    /// λ-path fits).
    pub candidates: Vec<SettingScore>,
    /// Every candidate setting with its score for the selected terms' coefficients (held-out
    /// error of least squares on them; see [`crate::FitOptions::reselect_for_support`]). `delta` and
    /// `windows` above are this list's best; empty when the settings were not chosen again.
    pub coefficient_candidates: Vec<SettingScore>,
    /// Plain-language reasons.
    pub why: Vec<String>,
}

/// One data-assembly step (Criterion 4).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AssemblyStep {
    /// Records used in the fit.
    pub records: Vec<String>,
    /// Frequency-domain rows in the fit.
    pub rows: usize,
    /// Terms in the model.
    pub n_terms: usize,
    /// Mean of the held-out residual over the spread of x''.
    pub mu: f64,
    /// Spread of the held-out residual over the spread of x''.
    pub sigma: f64,
}

/// Everything one DOF's identification did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DofTrace {
    /// The DOF.
    pub dof: String,
    /// The library this DOF's final pass ran on, before Criterion 2's pruning (the elimination's
    /// re-runs remove failing terms from it; see `offered_library`).
    pub library: Vec<String>,
    /// The library offered, when backward elimination re-ran the selection on a smaller one
    /// (absent: `library` is the one offered). What a diagnosis may offer back.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub offered_library: Option<Vec<String>>,
    /// Criterion 1.
    pub criterion1: Option<Criterion1>,
    /// Criterion 2 (when run).
    pub criterion2: Option<Criterion2>,
    /// Library used for the regression.
    pub regression_library: Vec<String>,
    /// Criterion 3 per record.
    pub bins: Vec<RecordBins>,
    /// Settings.
    pub settings: ChosenSettings,
    /// Criterion 4 trajectory.
    pub assembly: Vec<AssemblyStep>,
    /// Criterion 4's outcome, after the support verdicts that qualify it.
    pub assembly_verdict: AssemblyVerdict,
    /// Held-out record of Criterion 4.
    pub held_out_record: String,
    /// The significance test applied to the kept terms (absent without intervals); a kept term
    /// that fails it makes the support verdict [`Support::NotSupported`].
    pub term_test: Option<TermTest>,
}

/// Which pipeline made a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// T-F-S SINDy ([`crate::identify_tfs`]).
    TfsSindy,
    /// The tied chain fit ([`crate::identify_tfs_tied`]).
    TfsSindyTied,
    /// Classical SINDy ([`crate::identify_sindy`]).
    Sindy,
}

impl Method {
    /// The method's name in model files (`tfs-sindy`, `tfs-sindy-tied`, `sindy`).
    pub fn name(self) -> &'static str {
        match self {
            Method::TfsSindy => "tfs-sindy",
            Method::TfsSindyTied => "tfs-sindy-tied",
            Method::Sindy => "sindy",
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for Method {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

/// One tie of the tied chain fit as the trace reports it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TieTrace {
    /// The tied term.
    pub term: String,
    /// The DOF whose relative coordinate it is.
    pub owner: String,
    /// The other DOF.
    pub partner: String,
    /// The factor of the owner's coefficient in the partner's equation (`−m_owner/m_partner`).
    pub factor_in_partner: f64,
}

/// What only the tied chain fit reports: its ties and the masses in their factors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TiedTrace {
    /// Every tie.
    pub ties: Vec<TieTrace>,
    /// The masses (relative; the first DOF's is 1 when estimated).
    pub masses: Vec<f64>,
}

/// The trace of an identification run (the CLI prints it, and `--json` gives it as JSON).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Trace {
    /// The pipeline.
    pub method: Method,
    /// Per DOF.
    pub dofs: Vec<DofTrace>,
    /// Milliseconds per stage.
    pub timing_ms: Vec<(String, f64)>,
    /// The tied fit's ties and masses.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub tied: Option<TiedTrace>,
}

impl Trace {
    /// Warnings a user must see (one per DOF whose data cannot support its library, from the
    /// Criterion 1 verdict of the identified model), each prefixed by the DOF name.
    pub fn warnings(&self) -> Vec<String> {
        self.dofs
            .iter()
            .filter_map(|d| {
                d.criterion1
                    .as_ref()
                    .filter(|c| !c.support.is_supported())
                    .map(|c| format!("{}: {}", d.dof, c.support))
            })
            .collect()
    }
}

/// An identified model with its trace.
#[derive(Debug, Clone)]
pub struct Identified {
    /// The model (its `trace` field is left empty: see [`Identified::model_with_trace`]).
    pub model: Model,
    /// What was done.
    pub trace: Trace,
}

impl Identified {
    /// The model with the trace written into it as JSON, as a model file carries it.
    pub fn model_with_trace(&self) -> Model {
        let mut m = self.model.clone();
        m.trace = self.trace.to_json();
        m
    }
}

impl Trace {
    /// The trace as JSON (the model file's `trace` entry): everything but the stage timings,
    /// which differ from run to run, so that the same records and options give the same model
    /// file to the byte (the timings stay in [`Trace::timing_ms`], printed by the CLI under
    /// `--verbose` and given by its `--json`).
    pub fn to_json(&self) -> serde_json::Value {
        let mut v =
            serde_json::to_value(self).expect("a trace is plain data and always serialises");
        if let Some(obj) = v.as_object_mut() {
            obj.remove("timing_ms");
        }
        v
    }
}

/// What the trace tells the user when the data do not support the library.
pub(crate) const NOT_SUPPORTED_ADVICE: &str = "the model below is not a reliable identification. What to do: measure longer or repeat the test (more records), raise the excitation level or lower the sensor noise, or use a smaller library (fewer high powers)";

/// The second half of a verdict on records whose spectra show no noise floor (see
/// [`NoiseCause::NoNoiseFloor`]).
pub(crate) const NO_FLOOR_ADVICE: &str = "the records show no noise floor and κ reaches κ0 (criterion 1): if they are as clean as that bound says, noise is not why, but terms that the range the records visit cannot tell apart one by one (nearly collinear powers) or a force not exactly of the library's form, and longer or cleaner records of the same kind would not change that. The sum the terms form (the force law, its stable states) can still be accurate (`tfs compare` on held-out records tells); records that visit a wider range, or a smaller library (fewer high powers), pin the terms down one by one";

/// Why the data do not support the library.
#[derive(Debug, Clone, PartialEq)]
pub enum Problem {
    /// The model is empty.
    NoTermSurvives,
    /// The library offers a displacement term of the DOF and the model keeps none.
    NoRestoringTerm {
        /// The DOF.
        dof: String,
    },
    /// No kept term in the DOF's own motion is significant.
    NoOwnTerm {
        /// The DOF.
        dof: String,
    },
    /// Kept terms fail the term test.
    FailsTermTest {
        /// The terms.
        terms: Vec<String>,
        /// The test's critical `|coefficient| / SE`.
        t_critical: f64,
        /// Candidate terms of the test.
        candidates: usize,
    },
    /// Driven records, and no equation keeps an input term.
    NoInputTerm,
    /// Removing insignificant terms brought in terms the first pass did not select.
    StructureChanged {
        /// The new terms.
        new_terms: Vec<String>,
    },
    /// The full library was not supported (`first`, with the first pass's estimated SNR); the
    /// model was reduced one significance test at a time.
    Reduced {
        /// The first pass's estimated displacement SNR.
        snr_db: Option<SnrEstimate>,
        /// Why the first pass was not supported.
        first: Box<Problem>,
    },
}

/// The displacement SNR estimated from the records' noise floors (the one estimate of
/// `tfs_signal::estimate`).
pub use tfs_signal::estimate::SnrEstimate;

/// The estimated-SNR clause of a support verdict.
fn snr_clause(snr: Option<SnrEstimate>) -> String {
    snr.map_or(String::new(), |v| {
        format!(" (estimated displacement SNR {v})")
    })
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Problem::NoTermSurvives => f.write_str("no term survives selection"),
            Problem::NoRestoringTerm { dof } => write!(
                f,
                "no displacement (restoring-force) term of '{dof}' survives selection, so the model has no stiffness and no equilibria"
            ),
            Problem::NoOwnTerm { dof } => write!(
                f,
                "no term in the motion of '{dof}' itself is distinguishable from zero"
            ),
            Problem::FailsTermTest {
                terms,
                t_critical,
                candidates,
            } => {
                let one = terms.len() == 1;
                write!(
                    f,
                    "{} {} the term test (|coefficient| ≥ {t_critical:.2}·SE, {candidates} candidate terms), so the data cannot pin {} down",
                    terms.join(", "),
                    if one { "fails" } else { "fail" },
                    if one { "it" } else { "these terms" }
                )
            }
            Problem::NoInputTerm => f.write_str(
                "no input term survives selection in any equation, so the model cannot be driven by the measured excitation",
            ),
            Problem::StructureChanged { new_terms } => write!(
                f,
                "removing the insignificant terms changed the selected structure (new terms {} appeared), so the data do not pin the structure down",
                new_terms.join(", ")
            ),
            Problem::Reduced { snr_db, first } => write!(
                f,
                "the full library was not supported{}: {first}; the reduced model was found by removing terms one significance test at a time, so check it against held-out records (`tfs compare`) before relying on it",
                snr_clause(*snr_db)
            ),
        }
    }
}

/// Does the data support the library? The verdict of one DOF.
#[derive(Debug, Clone, PartialEq)]
pub enum Support {
    /// Not decided yet (a pass before its verdict).
    Undecided,
    /// Every kept term is distinguishable from zero.
    Supported {
        /// The estimated displacement SNR.
        snr_db: Option<SnrEstimate>,
    },
    /// The tied fit keeps a restoring-force term in every DOF (it has no term test).
    SupportedTied,
    /// The model is not a reliable identification.
    NotSupported {
        /// The estimated displacement SNR (when the verdict states it).
        snr_db: Option<SnrEstimate>,
        /// Why.
        problem: Problem,
        /// Whether the records' own noise estimate blames noise (only then does the sentence
        /// say "too noisy").
        cause: NoiseCause,
    },
}

/// What the records' own noise estimate says about a verdict of [`Support::NotSupported`]
/// (from Criterion 1's [`crate::SnrVerdict`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseCause {
    /// The library's residual is about what the estimated noise alone would leave: the data
    /// are too noisy for this library.
    Noise,
    /// The residual is well above the noise, or the records are clean: not a noise problem
    /// (a missing effect, terms the data cannot tell apart, or derivatives that err).
    NotNoise,
    /// Criterion 1 did not compare the residual with the noise (κ reached κ0, or the noise could
    /// not be carried through): the sentence blames neither.
    Unknown,
    /// κ reached κ0 and the records' spectra show no noise floor (the SNR estimate is a lower
    /// bound): if the records are as clean as that bound says, noise is not why terms fail, and
    /// the sentence says what is left (terms the visited range cannot tell apart one by one, or
    /// a force not exactly of the library's form) instead of asking for cleaner or longer data.
    NoNoiseFloor,
}

impl Support {
    /// False when the data cannot support the library.
    pub fn is_supported(&self) -> bool {
        !matches!(self, Support::NotSupported { .. })
    }
}

impl fmt::Display for Support {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Support::Undecided => Ok(()),
            Support::Supported { snr_db } => write!(
                f,
                "supported{}: every kept term is distinguishable from zero",
                snr_clause(*snr_db)
            ),
            Support::SupportedTied => f.write_str(
                "supported: every DOF keeps a restoring-force term (the tied fit has intervals but no term test, which its shared unknowns would need; check the model against held-out records with `tfs compare`)",
            ),
            Support::NotSupported {
                snr_db,
                problem,
                cause: NoiseCause::Noise,
            } => write!(
                f,
                "too noisy for this library{}: {problem}; {NOT_SUPPORTED_ADVICE}",
                snr_clause(*snr_db)
            ),
            Support::NotSupported {
                snr_db,
                problem,
                cause: NoiseCause::NotNoise,
            } => write!(
                f,
                "not supported by these data{}: {problem}; the records' own noise estimate says this is not noise (see criterion 1): the library misses an effect or holds terms the data cannot tell apart. What to do: `tfs diagnose` names missing effects; or use a smaller library",
                snr_clause(*snr_db)
            ),
            Support::NotSupported {
                snr_db,
                problem,
                cause: NoiseCause::NoNoiseFloor,
            } => write!(
                f,
                "not supported term by term{}: {problem}; {NO_FLOOR_ADVICE}",
                snr_clause(*snr_db)
            ),
            Support::NotSupported {
                snr_db,
                problem,
                cause: NoiseCause::Unknown,
            } => write!(
                f,
                "not supported by these data for this library{}: {problem}; {NOT_SUPPORTED_ADVICE}",
                snr_clause(*snr_db)
            ),
        }
    }
}

/// In JSON the verdict is two entries, `supported` and `support_note` (its sentence).
impl Serialize for Support {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(Some(2))?;
        m.serialize_entry("supported", &self.is_supported())?;
        m.serialize_entry("support_note", &self.to_string())?;
        m.end()
    }
}

/// How Criterion 4 with data assembly ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Criterion4Outcome {
    /// Met after `after` records (μ, σ on the held-out record); `refit_on`: the structure's
    /// coefficients were then refit on that many records.
    Met {
        /// Records used when it was met.
        after: usize,
        /// μ then.
        mu: f64,
        /// σ then.
        sigma: f64,
        /// The held-out record.
        held_out: String,
        /// Records the coefficients were refit on, if refit.
        refit_on: Option<usize>,
    },
    /// The records ran out (the last step's μ and σ, NaN without steps); the last support was
    /// refit on all `records`.
    RanOut {
        /// μ of the last step.
        mu: f64,
        /// σ of the last step.
        sigma: f64,
        /// Records refit on.
        records: usize,
    },
    /// The tied fit met it for every DOF after `after` records.
    TiedMet {
        /// Records used.
        after: usize,
        /// The held-out record.
        held_out: String,
    },
    /// The tied fit ran out of records.
    TiedRanOut {
        /// Records refit on.
        records: usize,
    },
    /// Classical SINDy has no data assembly.
    NotUsed,
}

impl fmt::Display for Criterion4Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Criterion4Outcome::Met {
                after,
                mu,
                sigma,
                held_out,
                refit_on,
            } => {
                write!(
                    f,
                    "criterion 4 met after {after} record(s): μ = {mu:.4}, σ = {sigma:.4} on held-out '{held_out}'"
                )?;
                match refit_on {
                    Some(nb) => write!(
                        f,
                        "; that structure is kept and its coefficients refit on all {nb} records"
                    ),
                    None => Ok(()),
                }
            }
            Criterion4Outcome::RanOut { mu, sigma, records } => write!(
                f,
                "records ran out before criterion 4 was met (last step μ = {mu:.4}, σ = {sigma:.4}); support from the last step, coefficients refit on all {records} records"
            ),
            Criterion4Outcome::TiedMet { after, held_out } => write!(
                f,
                "criterion 4 met for every DOF after {after} record(s) of the tied fit (held-out '{held_out}')"
            ),
            Criterion4Outcome::TiedRanOut { records } => write!(
                f,
                "records ran out before criterion 4 was met for every DOF; support of the tied fit from the last step, coefficients refit on all {records} records"
            ),
            Criterion4Outcome::NotUsed => f.write_str("not used by classical SINDy"),
        }
    }
}

/// Criterion 4's outcome and the support verdicts that qualify it (the latest first); prints
/// as the verdicts' sentences followed by the outcome's.
#[derive(Debug, Clone, PartialEq)]
pub struct AssemblyVerdict {
    /// Support verdicts stated before the outcome, the latest first.
    pub caveats: Vec<Support>,
    /// The outcome.
    pub outcome: Criterion4Outcome,
}

impl AssemblyVerdict {
    /// The outcome with no caveat.
    pub(crate) fn new(outcome: Criterion4Outcome) -> Self {
        Self {
            caveats: Vec::new(),
            outcome,
        }
    }

    /// Puts `support` before everything said so far.
    pub(crate) fn qualify(&mut self, support: Support) {
        self.caveats.insert(0, support);
    }
}

impl fmt::Display for AssemblyVerdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for c in &self.caveats {
            write!(f, "{c}. ")?;
        }
        write!(f, "{}", self.outcome)
    }
}

impl Serialize for AssemblyVerdict {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A verdict prints its sentence; a reduced model's verdict states the first pass's reason
    /// once, with the SNR it stated, and the advice once.
    #[test]
    fn verdicts_print_as_sentences_stating_the_advice_once() {
        let first = Problem::FailsTermTest {
            terms: vec!["x1".into()],
            t_critical: 3.2,
            candidates: 36,
        };
        let noisy = Support::NotSupported {
            snr_db: Some(SnrEstimate {
                db: 20.42,
                lower_bound: false,
            }),
            problem: first.clone(),
            cause: NoiseCause::Noise,
        };
        assert_eq!(
            noisy.to_string(),
            format!(
                "too noisy for this library (estimated displacement SNR 20.4 dB): x1 fails the term test (|coefficient| ≥ 3.20·SE, 36 candidate terms), so the data cannot pin it down; {NOT_SUPPORTED_ADVICE}"
            )
        );
        let reduced = Support::NotSupported {
            snr_db: None,
            problem: Problem::Reduced {
                snr_db: Some(SnrEstimate {
                    db: 20.42,
                    lower_bound: false,
                }),
                first: Box::new(first.clone()),
            },
            cause: NoiseCause::Noise,
        }
        .to_string();
        assert!(
            reduced.starts_with(
                "too noisy for this library: the full library was not supported (estimated displacement SNR 20.4 dB): x1 fails the term test"
            ),
            "{reduced}"
        );
        assert_eq!(reduced.matches("too noisy").count(), 1, "{reduced}");
        assert_eq!(
            reduced.matches(NOT_SUPPORTED_ADVICE).count(),
            1,
            "{reduced}"
        );
        assert!(Support::SupportedTied.is_supported() && !noisy.is_supported());
        // Without the noise estimate's word, the sentence does not say "noise".
        for cause in [NoiseCause::NotNoise, NoiseCause::Unknown] {
            let clean = Support::NotSupported {
                snr_db: Some(SnrEstimate {
                    db: 60.0,
                    lower_bound: false,
                }),
                problem: first.clone(),
                cause,
            };
            let text = clean.to_string();
            assert!(!text.contains("noisy"), "{text}");
            assert!(text.starts_with("not supported by these data"), "{text}");
            assert!(!clean.is_supported());
        }
        // Records whose spectra show no noise floor: neither noise nor the data's length is
        // blamed, and the advice to lower the noise or measure longer is not given.
        let no_floor = Support::NotSupported {
            snr_db: Some(SnrEstimate {
                db: 84.11,
                lower_bound: true,
            }),
            problem: first.clone(),
            cause: NoiseCause::NoNoiseFloor,
        };
        let text = no_floor.to_string();
        assert!(text.starts_with("not supported term by term"), "{text}");
        for blame in ["noisy", "lower the sensor noise", "measure longer"] {
            assert!(!text.contains(blame), "{text}");
        }
        assert!(text.contains(NO_FLOOR_ADVICE) && !no_floor.is_supported());
        // Records without a visible noise floor state a bound, not a value.
        let bound = Support::Supported {
            snr_db: Some(SnrEstimate {
                db: 83.04,
                lower_bound: true,
            }),
        }
        .to_string();
        assert!(
            bound.starts_with(
                "supported (estimated displacement SNR at least 83.0 dB if the noise is white; the spectrum shows no noise floor"
            ),
            "{bound}"
        );
    }

    /// The assembly verdict puts the latest caveat first and serialises as one sentence; the
    /// support verdict serialises as `supported` and `support_note`.
    #[test]
    fn verdicts_serialise_as_the_model_file_has_them() {
        let mut v = AssemblyVerdict::new(Criterion4Outcome::Met {
            after: 2,
            mu: 1e-5,
            sigma: 0.03781,
            held_out: "r4".into(),
            refit_on: Some(4),
        });
        let first = Support::NotSupported {
            snr_db: None,
            problem: Problem::NoTermSurvives,
            cause: NoiseCause::Noise,
        };
        let second = Support::NotSupported {
            snr_db: None,
            problem: Problem::NoInputTerm,
            cause: NoiseCause::Unknown,
        };
        v.qualify(first.clone());
        v.qualify(second.clone());
        let text = v.to_string();
        assert!(
            text.starts_with(&format!("{second}. {first}. criterion 4 met after 2 record(s): μ = 0.0000, σ = 0.0378 on held-out 'r4'; that structure is kept and its coefficients refit on all 4 records")),
            "{text}"
        );
        assert_eq!(serde_json::to_value(&v).unwrap(), serde_json::json!(text));
        let s = serde_json::to_value(&first).unwrap();
        assert_eq!(s["supported"], false);
        assert_eq!(s["support_note"], first.to_string());
    }
}
