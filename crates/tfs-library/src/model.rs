//! Identified models `x_i'' = Σ coef · term` and their JSON format `tfs-model/1`.

use std::path::Path;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::library::Library;
use crate::state::StateLaw;
use crate::term::{Factor, Term, Var};
use crate::{LibraryError, Result};

/// The format tag written to and required in model JSON files.
pub const MODEL_FORMAT: &str = "tfs-model/1";

/// The largest model file [`Model::from_path`] reads (64 MiB).
pub const MAX_MODEL_BYTES: u64 = 64 << 20;

/// One term of an equation with its coefficient and optional uncertainty information.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelTerm {
    /// The term.
    pub term: Term,
    /// Its coefficient in `x'' = Σ coef · term`.
    pub coef: f64,
    /// Optional confidence interval `[lo, hi]` of the coefficient (e.g. from bagging).
    pub interval: Option<[f64; 2]>,
    /// Optional inclusion probability of the term (share of bags selecting it).
    pub inclusion: Option<f64>,
}

impl ModelTerm {
    /// A term with a coefficient and no uncertainty information.
    pub fn new(term: Term, coef: f64) -> Self {
        Self {
            term,
            coef,
            interval: None,
            inclusion: None,
        }
    }
}

/// The explicit equation of one DOF: `dof'' = Σ coef · term`.
#[derive(Debug, Clone, PartialEq)]
pub struct Equation {
    /// The DOF whose acceleration this equation gives.
    pub dof: String,
    /// The terms with their coefficients.
    pub terms: Vec<ModelTerm>,
}

/// R-MSE of one record at one refit step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordScore {
    /// Record name or path.
    pub record: String,
    /// Relative mean-squared simulation error on the record's variance (mean removed).
    pub r_mse: f64,
}

/// One step of a model's refit history (identify, then each added effect).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HistoryEntry {
    /// Step label, e.g. `"identify"` or `"add dry-friction"`.
    pub step: String,
    /// Effects or terms added at this step.
    #[serde(default)]
    pub added: Vec<String>,
    /// R-MSE per record after this step (may be empty).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub r_mse: Vec<RecordScore>,
    /// Anything else the step wants to keep.
    #[serde(default, skip_serializing_if = "Value::is_null")]
    pub details: Value,
}

/// A second-order model: per DOF `x'' = Σ coef · term(x, x', inputs)`.
///
/// `inputs` lists, in order, the input columns the model needs (the order of `u` in
/// [`crate::CompiledModel::accel`]); [`Model::new`] derives it from the terms.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// DOF names, in state order.
    pub dofs: Vec<String>,
    /// Input names, in the order of the `u` vector.
    pub inputs: Vec<String>,
    /// One equation per DOF, in DOF order.
    pub equations: Vec<Equation>,
    /// How the model was obtained (`"tfs"`, `"sindy"`, `"truth"`, …).
    pub method: String,
    /// Criteria trace or any other provenance (free JSON).
    pub trace: Value,
    /// Refit history.
    pub history: Vec<HistoryEntry>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTerm {
    term: String,
    coef: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    interval: Option<[f64; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    inclusion: Option<f64>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEquation {
    dof: String,
    terms: Vec<RawTerm>,
}

#[derive(Serialize, Deserialize)]
struct RawModel {
    format: String,
    dofs: Vec<String>,
    #[serde(default)]
    inputs: Option<Vec<String>>,
    equations: Vec<RawEquation>,
    #[serde(default)]
    method: String,
    #[serde(default)]
    trace: Value,
    #[serde(default)]
    history: Vec<HistoryEntry>,
}

fn invalid(field: impl Into<String>, message: impl Into<String>) -> LibraryError {
    LibraryError::Invalid {
        field: field.into(),
        message: message.into(),
    }
}

impl Model {
    /// Builds a model from DOF names and one equation per DOF (any order; stored in DOF order).
    /// Inputs are derived from the terms in first-use order. Validates everything
    /// [`Model::validate`] checks.
    pub fn new(
        dofs: Vec<String>,
        equations: Vec<Equation>,
        method: impl Into<String>,
    ) -> Result<Self> {
        let mut inputs: Vec<String> = Vec::new();
        for eq in &equations {
            for t in &eq.terms {
                for i in t.term.required_inputs() {
                    if !inputs.contains(&i) {
                        inputs.push(i);
                    }
                }
            }
        }
        let mut m = Self {
            dofs,
            inputs,
            equations,
            method: method.into(),
            trace: Value::Null,
            history: Vec::new(),
        };
        m.sort_equations()?;
        m.validate()?;
        Ok(m)
    }

    /// Builds a model from a library and one coefficient vector per DOF (library order); exact
    /// zeros are dropped.
    pub fn from_coefficients(
        library: &Library,
        coefs: &[Vec<f64>],
        method: impl Into<String>,
    ) -> Result<Self> {
        if coefs.len() != library.dofs().len() {
            return Err(invalid(
                "coefs",
                format!(
                    "{} coefficient vectors given for {} DOFs; give one per DOF",
                    coefs.len(),
                    library.dofs().len()
                ),
            ));
        }
        let mut equations = Vec::new();
        for (d, c) in library.dofs().iter().zip(coefs) {
            if c.len() != library.len() {
                return Err(invalid(
                    format!("coefs[{d}]"),
                    format!(
                        "{} coefficients for a library of {} terms",
                        c.len(),
                        library.len()
                    ),
                ));
            }
            equations.push(Equation {
                dof: d.clone(),
                terms: library
                    .terms()
                    .iter()
                    .zip(c)
                    .filter(|(_, c)| **c != 0.0)
                    .map(|(t, c)| ModelTerm::new(t.clone(), *c))
                    .collect(),
            });
        }
        Self::new(library.dofs().to_vec(), equations, method)
    }

    fn sort_equations(&mut self) -> Result<()> {
        let mut sorted = Vec::with_capacity(self.dofs.len());
        for d in &self.dofs {
            let n = self.equations.iter().filter(|e| e.dof == *d).count();
            if n != 1 {
                return Err(invalid(
                    "equations",
                    format!("DOF '{d}' has {n} equations; give exactly one per DOF"),
                ));
            }
        }
        for (i, e) in self.equations.iter().enumerate() {
            if !self.dofs.contains(&e.dof) {
                return Err(invalid(
                    format!("equations[{i}].dof"),
                    format!("'{}' is not one of the model's DOFs {:?}", e.dof, self.dofs),
                ));
            }
        }
        for d in &self.dofs {
            let e = self.equations.iter().find(|e| e.dof == *d).cloned();
            sorted.extend(e);
        }
        self.equations = sorted;
        Ok(())
    }

    /// Checks the model: valid distinct DOF names, one equation per DOF, terms mention only
    /// declared DOFs, finite coefficients, every needed input listed in `inputs`.
    pub fn validate(&self) -> Result<()> {
        Library::new(&self.dofs, vec![])?;
        for (i, name) in self.inputs.iter().enumerate() {
            if self.dofs.contains(name) {
                return Err(invalid(
                    format!("inputs[{i}]"),
                    format!("'{name}' is a DOF; an input must not share a DOF's name"),
                ));
            }
            if self.inputs[..i].contains(name) {
                return Err(invalid(
                    format!("inputs[{i}]"),
                    format!("input '{name}' is listed twice"),
                ));
            }
        }
        for d in &self.dofs {
            let n = self.equations.iter().filter(|e| e.dof == *d).count();
            if n != 1 {
                return Err(invalid(
                    "equations",
                    format!("DOF '{d}' has {n} equations; give exactly one per DOF"),
                ));
            }
        }
        for (i, e) in self.equations.iter().enumerate() {
            if !self.dofs.contains(&e.dof) {
                return Err(invalid(
                    format!("equations[{i}].dof"),
                    format!("'{}' is not one of the model's DOFs {:?}", e.dof, self.dofs),
                ));
            }
            for (j, t) in e.terms.iter().enumerate() {
                let field = format!("equations[{i}].terms[{j}]");
                if !t.coef.is_finite() {
                    return Err(invalid(
                        format!("{field}.coef"),
                        format!(
                            "coefficient of '{}' is {}; coefficients must be finite",
                            t.term, t.coef
                        ),
                    ));
                }
                for (_, law) in t.term.states() {
                    law.validate()
                        .map_err(|e| invalid(format!("{field}.term"), e.to_string()))?;
                }
                for d in t.term.dofs() {
                    if !self.dofs.contains(&d) {
                        return Err(invalid(
                            format!("{field}.term"),
                            format!("'{}' uses DOF '{d}', not one of {:?}", t.term, self.dofs),
                        ));
                    }
                }
                for inp in t.term.required_inputs() {
                    if !self.inputs.contains(&inp) {
                        return Err(invalid(
                            "inputs",
                            format!(
                                "term '{}' in {field} needs input '{inp}'; add it to \"inputs\"",
                                t.term
                            ),
                        ));
                    }
                }
                if let Some([lo, hi]) = t.interval
                    && !(lo.is_finite() && hi.is_finite() && lo <= hi)
                {
                    return Err(invalid(
                        format!("{field}.interval"),
                        format!("[{lo}, {hi}] is not a finite interval with lo <= hi"),
                    ));
                }
                if let Some(p) = t.inclusion
                    && !(0.0..=1.0).contains(&p)
                {
                    return Err(invalid(
                        format!("{field}.inclusion"),
                        format!("{p} is not a probability in [0, 1]"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The internal states the model's terms use (see [`crate::state`]): each distinct
    /// (drive, law) pair once, in order of first use over the equations (DOF order) and their
    /// terms. A state used in several terms or equations (a coupling's hysteresis acting on both
    /// masses) is one state. This is the order of the auxiliary coordinates of
    /// [`crate::CompiledModel`].
    pub fn internal_states(&self) -> Vec<(Var, StateLaw)> {
        let mut out: Vec<(Var, StateLaw)> = Vec::new();
        for e in &self.equations {
            for t in &e.terms {
                for (v, law) in t.term.states() {
                    if !out.iter().any(|(w, l)| w == v && l == law) {
                        out.push((v.clone(), *law));
                    }
                }
            }
        }
        out
    }

    /// A copy whose internal states ([`Model::internal_states`] order) follow the laws `laws`
    /// instead (same drives; every term using state `j` gets law `j`). Errors on a wrong count
    /// or invalid parameters.
    pub fn with_state_laws(&self, laws: &[StateLaw]) -> Result<Model> {
        let states = self.internal_states();
        if laws.len() != states.len() {
            return Err(invalid(
                "states",
                format!(
                    "{} laws given for {} internal states",
                    laws.len(),
                    states.len()
                ),
            ));
        }
        for l in laws {
            l.validate()?;
        }
        let mut m = self.clone();
        for e in &mut m.equations {
            for t in &mut e.terms {
                if t.term.states().is_empty() {
                    continue;
                }
                let factors = t
                    .term
                    .factors()
                    .iter()
                    .map(|f| match f {
                        Factor::State(v, law) => {
                            let j = states
                                .iter()
                                .position(|(w, l)| w == v && l == law)
                                .unwrap_or(0);
                            Factor::State(v.clone(), laws[j])
                        }
                        other => other.clone(),
                    })
                    .collect();
                t.term = Term::new(factors);
            }
        }
        m.validate()?;
        Ok(m)
    }

    /// The equation of `dof`.
    pub fn equation(&self, dof: &str) -> Result<&Equation> {
        self.equations.iter().find(|e| e.dof == dof).ok_or_else(|| {
            invalid(
                "dof",
                format!("'{dof}' is not one of the model's DOFs {:?}", self.dofs),
            )
        })
    }

    /// Coefficient of `term` in the equation of `dof` (0 if absent).
    pub fn coef(&self, dof: &str, term: &Term) -> Result<f64> {
        Ok(self
            .equation(dof)?
            .terms
            .iter()
            .filter(|t| t.term == *term)
            .map(|t| t.coef)
            .sum())
    }

    /// Serialises to pretty JSON in the `tfs-model/1` format.
    pub fn to_json_string(&self) -> Result<String> {
        self.validate()?;
        let raw = RawModel {
            format: MODEL_FORMAT.to_string(),
            dofs: self.dofs.clone(),
            inputs: Some(self.inputs.clone()),
            equations: self
                .equations
                .iter()
                .map(|e| RawEquation {
                    dof: e.dof.clone(),
                    terms: e
                        .terms
                        .iter()
                        .map(|t| RawTerm {
                            term: t.term.to_string(),
                            coef: t.coef,
                            interval: t.interval,
                            inclusion: t.inclusion,
                        })
                        .collect(),
                })
                .collect(),
            method: self.method.clone(),
            trace: self.trace.clone(),
            history: self.history.clone(),
        };
        serde_json::to_string_pretty(&raw).map_err(|e| LibraryError::Json {
            source_name: "model".into(),
            message: e.to_string(),
        })
    }

    /// Serialises to a `serde_json::Value` (same content as [`Model::to_json_string`]).
    pub fn to_json_value(&self) -> Result<Value> {
        let s = self.to_json_string()?;
        serde_json::from_str(&s).map_err(|e| LibraryError::Json {
            source_name: "model".into(),
            message: e.to_string(),
        })
    }

    /// Parses and validates `tfs-model/1` JSON. If `"inputs"` is absent it is derived from the
    /// terms; if present it must list every input the terms need.
    pub fn from_json_str(text: &str) -> Result<Self> {
        Self::from_json_named(text, "model JSON")
    }

    /// Reads and validates a model file (at most [`MAX_MODEL_BYTES`]; a model file is a few
    /// kilobytes to a few megabytes with its trace).
    pub fn from_path(path: impl AsRef<Path>) -> Result<Self> {
        use std::io::Read;
        let path = path.as_ref();
        let name = path.display().to_string();
        let io = |e: std::io::Error| LibraryError::Io {
            path: name.clone(),
            message: format!("cannot read the model file: {e}"),
        };
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .map_err(io)?
            .take(MAX_MODEL_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(io)?;
        if bytes.len() as u64 > MAX_MODEL_BYTES {
            return Err(LibraryError::Io {
                path: name,
                message: format!(
                    "larger than {} MiB, which no model file is; check that this is the model (tfs-model/1 JSON)",
                    MAX_MODEL_BYTES >> 20
                ),
            });
        }
        let text = String::from_utf8(bytes).map_err(|e| LibraryError::Io {
            path: name.clone(),
            message: format!(
                "not a model file: byte {} is not UTF-8 text (a model is tfs-model/1 JSON written by tfs identify or tfs refit)",
                e.utf8_error().valid_up_to()
            ),
        })?;
        Self::from_json_named(&text, &name)
    }

    /// Writes the model as pretty JSON, atomically: on any failure (a full disk, a killed
    /// process) the previous file at `path` is left as it was.
    pub fn write_path(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let s = self.to_json_string()?;
        tfs_data::write_atomic(path, (s + "\n").as_bytes()).map_err(|e| LibraryError::Io {
            path: path.display().to_string(),
            message: format!("cannot write the model file: {e}"),
        })
    }

    fn from_json_named(text: &str, source: &str) -> Result<Self> {
        let value: Value = serde_json::from_str(text).map_err(|e| LibraryError::Json {
            source_name: source.into(),
            message: e.to_string(),
        })?;
        match value.get("format") {
            Some(Value::String(f)) if f == MODEL_FORMAT => {}
            Some(other) => {
                return Err(invalid(
                    "format",
                    format!("{source}: expected \"{MODEL_FORMAT}\", found {other}"),
                ));
            }
            None => {
                return Err(invalid(
                    "format",
                    format!(
                        "{source}: missing; a model file must contain \"format\": \"{MODEL_FORMAT}\""
                    ),
                ));
            }
        }
        let raw: RawModel = serde_json::from_value(value).map_err(|e| LibraryError::Json {
            source_name: source.into(),
            message: e.to_string(),
        })?;
        Library::new(&raw.dofs, vec![]).map_err(|e| invalid("dofs", format!("{source}: {e}")))?;
        let mut equations = Vec::with_capacity(raw.equations.len());
        for (i, e) in raw.equations.into_iter().enumerate() {
            if !raw.dofs.contains(&e.dof) {
                return Err(invalid(
                    format!("equations[{i}].dof"),
                    format!(
                        "{source}: '{}' is not one of the model's DOFs {:?}",
                        e.dof, raw.dofs
                    ),
                ));
            }
            let mut terms: Vec<ModelTerm> = Vec::with_capacity(e.terms.len());
            for (j, t) in e.terms.into_iter().enumerate() {
                let term = Term::parse(&t.term, &raw.dofs).map_err(|err| {
                    invalid(
                        format!("equations[{i}].terms[{j}].term"),
                        format!("{source}: {err}"),
                    )
                })?;
                // A term listed twice would be summed silently: the file is not what it says.
                if let Some(k) = terms.iter().position(|m| m.term == term) {
                    return Err(invalid(
                        format!("equations[{i}].terms[{j}].term"),
                        format!(
                            "{source}: term '{term}' of {}'' appears twice (also terms[{k}]); list each term once with its whole coefficient",
                            e.dof
                        ),
                    ));
                }
                terms.push(ModelTerm {
                    term,
                    coef: t.coef,
                    interval: t.interval,
                    inclusion: t.inclusion,
                });
            }
            equations.push(Equation { dof: e.dof, terms });
        }
        if equations.iter().all(|e| e.terms.is_empty()) {
            return Err(invalid(
                "equations",
                format!(
                    "{source}: the model has no terms (every equation reads x'' = 0), so it predicts nothing; identify a model with data first"
                ),
            ));
        }
        let mut m = Model::new(raw.dofs, equations, raw.method)?;
        if let Some(inputs) = raw.inputs {
            m.inputs = inputs;
        }
        m.trace = raw.trace;
        m.history = raw.history;
        m.validate()?;
        Ok(m)
    }

    /// The library the model's identify trace says was offered for `dof` (term names, in
    /// library order): `offered_library` when backward elimination re-ran the selection on a
    /// smaller library, else `library`. What the diagnosis may offer back and a stop's
    /// re-identification starts from. `None` when the trace lists no library of strings for
    /// that DOF (a model written by hand or by another tool).
    pub fn offered_library(&self, dof: &str) -> Option<Vec<String>> {
        let entry = self
            .trace
            .get("dofs")?
            .as_array()?
            .iter()
            .find(|e| e.get("dof").and_then(Value::as_str) == Some(dof))?;
        let listed = entry
            .get("offered_library")
            .filter(|l| !l.is_null())
            .or_else(|| entry.get("library"))?;
        listed
            .as_array()?
            .iter()
            .map(|t| t.as_str().map(str::to_string))
            .collect()
    }

    /// Whether the model was fitted with laws tied between its equations (a chain's coupling
    /// terms, one force law per cell): its trace lists the ties (`"ties"`, non-empty).
    pub fn is_tied(&self) -> bool {
        self.trace["ties"].as_array().is_some_and(|t| !t.is_empty())
    }

    /// Readable equations, one line per DOF, 4 significant digits, e.g.
    /// `x'' = -1.990·x' - 12.12·x^5 + 18.03·x^6 - 1.000·xb_acc`; coefficients with an interval
    /// print as `(1.990 ± 0.01200)` with the interval's half-width.
    pub fn equation_string(&self) -> String {
        self.equations
            .iter()
            .map(|e| {
                let mut s = format!("{}'' =", e.dof);
                if e.terms.is_empty() {
                    s.push_str(" 0");
                }
                for (i, t) in e.terms.iter().enumerate() {
                    let neg = t.coef < 0.0;
                    let sign = match (i, neg) {
                        (0, true) => " -".to_string(),
                        (0, false) => " ".to_string(),
                        (_, true) => " - ".to_string(),
                        (_, false) => " + ".to_string(),
                    };
                    s.push_str(&sign);
                    let mag = sig4(t.coef.abs());
                    match t.interval {
                        Some([lo, hi]) => {
                            s.push_str(&format!("({mag} ± {})", sig4((hi - lo).abs() / 2.0)))
                        }
                        None => s.push_str(&mag),
                    }
                    if !t.term.is_constant() {
                        s.push('·');
                        s.push_str(&t.term.to_string());
                    }
                }
                s
            })
            .collect::<Vec<_>>()
            .join("\n")
    }
}

/// Formats a non-negative number with 4 significant digits (scientific outside 1e-3..1e5).
pub fn sig4(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let a = x.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{x:.3e}");
    }
    let mut e = a.log10().floor() as i32;
    // Rounding can carry into the next decade (9.9996 → 10.00).
    let rounded = (a / 10f64.powi(e - 3)).round();
    if rounded >= 1e4 {
        e += 1;
    }
    let decimals = (3 - e).max(0) as usize;
    format!("{x:.decimals$}")
}
