//! `tfs.Model` and the functions that make one (`identify`, `Model.refit`) or use one on records
//! (`compare`, `simulate`, `predict`): thin wrappers over the library's workflows, the GIL
//! released while they run.

use std::path::PathBuf;

use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use serde_json::Value;
use tfs::data::Record;
use tfs::library::Model;
use tfs::records::{Clipped, Offsets, check_records, measured_columns};
use tfs::report::{OffsetsReport, RefineReport};

use crate::convert::{columns, json_to_py, records_arg, to_array2, warn_all};
use crate::errors::{OrRaise, PyResult, input_error};
use crate::options::{clipped_policy, identify_options, offsets_mode};

/// An identified second-order model `x'' = Σ ξ·θ(x, x', u)`, one equation per DOF.
#[pyclass(name = "Model", module = "tfs._tfs", frozen)]
#[derive(Clone)]
pub struct PyModel {
    /// The model.
    pub inner: Model,
    /// What the call that made it reported beyond the model (refinement, ladder), as JSON.
    pub report: Value,
    /// `refit` only: what the error ladder says about the effects added, in one sentence,
    /// and whether the geometric-mean R-MSE fell (`None`: a step failed to simulate some record).
    pub verdict: Option<tfs::report::LadderVerdict>,
}

impl PyModel {
    fn new(inner: Model) -> Self {
        Self {
            inner,
            report: Value::Null,
            verdict: None,
        }
    }
}

/// The inputs a model was identified with, in the order `simulate` and `predict` take them:
/// the model's own (those its terms use) in their order, then those the identification was
/// given whose terms sparsity dropped (the `offsets` channels its trace keeps), which are
/// accepted and ignored.
pub fn identified_inputs(m: &Model) -> Vec<String> {
    let mut out = m.inputs.clone();
    let channels = m.trace["offsets"]["channels"].as_array();
    for c in channels.into_iter().flatten().filter_map(Value::as_str) {
        if !m.dofs.iter().any(|d| d == c) && !out.iter().any(|i| i == c) {
            out.push(c.to_string());
        }
    }
    out
}

/// Validates records for `model` (its measured columns, the clipped policy) and applies the
/// offsets policy the model's trace asks for; returns the records, the offsets report and the
/// warnings.
pub fn prepare_for_model(
    model: &Model,
    records: Vec<Record>,
    offsets: Offsets,
    clipped: Clipped,
) -> tfs::Result<(Vec<Record>, OffsetsReport, Vec<String>)> {
    let required = measured_columns(model);
    let (mut recs, mut warnings) = check_records(records, &required, clipped)?;
    let (report, w) = tfs::records::offsets_for_model(&mut recs, model, &required, offsets)?;
    warnings.extend(w);
    Ok((recs, report, warnings))
}

/// Identifies a sparse second-order model from records (a `Record`, a CSV path or a list of
/// them, stacked), with the options and defaults of `tfs identify`.
///
/// `library`: the candidate terms, e.g. `"x^1..7, x', xb_acc"` (default: degree-7 restoring
/// terms, linear damping and every input column). `method`: `'tfs'` (T-F-S SINDy, default) or
/// `'sindy'` (classical). `threshold`: a fixed sparsity threshold (default: chosen on held-out
/// data). `refine=True` re-estimates the coefficients by simulation error, keeping with
/// `validate` records whichever fit predicts them better. Chains: `tie` (`None`: tie when the
/// libraries allow it), `masses` (`'equal'`, `'estimate'` or one number per DOF). `offsets`:
/// `'auto'`, `'keep'`, `'remove'` or `'constant-term'`. `clipped`: `'error'`, `'warn'` or
/// `'allow'`. Warnings (a DOF the data do not support, no intervals and why) are raised at the
/// calling line.
#[pyfunction]
#[pyo3(signature = (records, library=None, *, method="tfs", dofs=None, threshold=None,
    refine=false, validate=None, tie=None, masses="equal", offsets="auto", clipped="error"))]
#[allow(clippy::too_many_arguments)]
pub fn identify(
    py: Python<'_>,
    records: &Bound<'_, PyAny>,
    library: Option<String>,
    method: &str,
    dofs: Option<Vec<String>>,
    threshold: Option<f64>,
    refine: bool,
    validate: Option<&Bound<'_, PyAny>>,
    tie: Option<bool>,
    masses: &str,
    offsets: &str,
    clipped: &str,
) -> PyResult<PyModel> {
    let opts = identify_options(
        library, method, dofs, threshold, refine, tie, masses, offsets,
    )?;
    let clipped = clipped_policy(clipped)?;
    let (recs, mut warnings) = records_arg(records, "records")?;
    let (held, w) = match validate {
        Some(v) => records_arg(v, "validate")?,
        None => (Vec::new(), Vec::new()),
    };
    warnings.extend(w);
    let started = std::time::Instant::now();
    let (id, w) = py
        .detach(|| -> tfs::Result<_> {
            let plan = tfs::identify::plan(&opts, recs[0].names(), recs[0].source())?;
            let (recs, mut w) = check_records(recs, &plan.required, clipped)?;
            let held = if held.is_empty() {
                held
            } else {
                let (h, w2) = check_records(held, &plan.required, clipped)?;
                w.extend(w2);
                h
            };
            Ok((tfs::identify::identify(recs, held, &opts, &plan)?, w))
        })
        .or_raise()?;
    // The library's own time (GIL released): what the Python layer adds is the rest of the call.
    let library_seconds = started.elapsed().as_secs_f64();
    warnings.extend(w);
    warnings.extend(id.warnings.iter().cloned());
    warnings.extend(tfs::report::interval_notes(&id.trace, &id.model));
    warn_all(py, &warnings)?;
    Ok(PyModel {
        inner: id.model,
        report: serde_json::json!({"refine": id.refine.as_ref().map(RefineReport::to_json),
            "offsets": id.offsets.to_json(),
            "library_seconds": library_seconds}),
        verdict: None,
    })
}

/// The terms of every equation in order of first appearance (the columns of
/// `coefficient_array`).
fn all_terms(m: &Model) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for e in &m.equations {
        for t in &e.terms {
            let s = t.term.to_string();
            if !out.contains(&s) {
                out.push(s);
            }
        }
    }
    out
}

#[pymethods]
impl PyModel {
    /// DOF names, in state order.
    #[getter]
    fn dofs(&self) -> Vec<String> {
        self.inner.dofs.clone()
    }

    /// The inputs the model was identified with, in the order `simulate` and `predict` take
    /// them positionally (or give them by name in a dict). Inputs whose terms sparsity dropped
    /// stay in this list: they are accepted and ignored (`used_inputs` lists those the
    /// equations use).
    #[getter]
    fn inputs(&self) -> Vec<String> {
        identified_inputs(&self.inner)
    }

    /// The inputs the equations use (the model file's `inputs`).
    #[getter]
    fn used_inputs(&self) -> Vec<String> {
        self.inner.inputs.clone()
    }

    /// `refit` only: what the error ladder says about the effects added, in one sentence (the
    /// geometric-mean R-MSE over the records before and after, or the records whose simulation failed);
    /// `None` for a model that `refit` did not make.
    #[getter]
    fn verdict(&self) -> Option<String> {
        self.verdict.as_ref().map(|v| v.sentence.clone())
    }

    /// `refit` only: `True` when the geometric-mean R-MSE over the records fell from the start model to
    /// the refitted one, `False` when it rose, `None` when a step failed to simulate a record
    /// (or the model was not made by `refit`).
    #[getter]
    fn improved(&self) -> Option<bool> {
        self.verdict.as_ref().and_then(|v| v.improved)
    }

    /// How the model was obtained (`tfs`, `sindy`, …).
    #[getter]
    fn method(&self) -> String {
        self.inner.method.clone()
    }

    /// The criteria trace (κ and its verdict, kept bands, chosen settings and why, assembly,
    /// offsets) as a dict: what the model file keeps.
    #[getter]
    fn trace<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.inner.trace)
    }

    /// What the call that made this model reported beyond it: `refine` (simulation-error
    /// refinement), `offsets`, for `identify` `library_seconds` (the time spent in the library,
    /// the GIL released) and for `refit` the error `ladder` and its `warnings`.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.report)
    }

    /// Coefficients as `{dof: {term: coefficient}}`.
    #[getter]
    fn coefficients<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for e in &self.inner.equations {
            let d = PyDict::new(py);
            for t in &e.terms {
                d.set_item(t.term.to_string(), t.coef)?;
            }
            out.set_item(&e.dof, d)?;
        }
        Ok(out)
    }

    /// Coefficient intervals as `{dof: {term: (lo, hi)}}` (terms without one are left out).
    #[getter]
    fn intervals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for e in &self.inner.equations {
            let d = PyDict::new(py);
            for t in &e.terms {
                if let Some([lo, hi]) = t.interval {
                    d.set_item(t.term.to_string(), (lo, hi))?;
                }
            }
            out.set_item(&e.dof, d)?;
        }
        Ok(out)
    }

    /// The terms of every equation (the columns of `coefficient_array`).
    #[getter]
    fn terms(&self) -> Vec<String> {
        all_terms(&self.inner)
    }

    /// Coefficients as an array: one row per DOF, one column per name of `terms` (0 where an
    /// equation lacks the term).
    #[getter]
    fn coefficient_array<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let terms = all_terms(&self.inner);
        let cols: Vec<Vec<f64>> = terms
            .iter()
            .map(|name| {
                self.inner
                    .equations
                    .iter()
                    .map(|e| {
                        e.terms
                            .iter()
                            .find(|t| t.term.to_string() == *name)
                            .map_or(0.0, |t| t.coef)
                    })
                    .collect()
            })
            .collect();
        to_array2(py, &cols, self.inner.equations.len())
    }

    /// The equations as text, one per DOF, 4 significant digits, coefficients with an interval
    /// as `(value ± half-width)`.
    fn equations(&self) -> Vec<String> {
        self.inner
            .equation_string()
            .lines()
            .map(str::to_string)
            .collect()
    }

    /// Prints the equations.
    fn print(&self) {
        println!("{}", self.inner.equation_string());
    }

    fn __str__(&self) -> String {
        self.inner.equation_string()
    }

    fn __repr__(&self) -> String {
        format!(
            "Model(method='{}', dofs={:?}, inputs={:?}):\n{}",
            self.inner.method,
            self.inner.dofs,
            self.inner.inputs,
            self.inner.equation_string()
        )
    }

    /// Simulates the model from `x0`, `v0` (default 0) at the uniformly spaced times `t` under
    /// the inputs `u`: a dict by name, or samples × inputs in the order of `inputs` (a 1-D
    /// array for one input). `inputs` are those the model was identified with; one whose terms
    /// sparsity dropped is accepted and ignored. Returns `(x, v)`, each samples × DOFs. A run
    /// that blows up raises `SimulationError` with the time and the state.
    #[pyo3(signature = (t, u=None, x0=None, v0=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
        x0: Option<Vec<f64>>,
        v0: Option<Vec<f64>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let t = crate::convert::vec1(t, "t")?;
        let u = self.inputs_arg(u)?;
        let n = self.inner.dofs.len();
        let x0 = x0.unwrap_or_else(|| vec![0.0; n]);
        let v0 = v0.unwrap_or_else(|| vec![0.0; n]);
        let traj = py
            .detach(|| tfs::simulate::simulate_model(&self.inner, &t, u, &x0, &v0))
            .or_raise()?;
        let rows = traj.t.len();
        let x = to_array2(py, &traj.x, rows);
        let v = to_array2(py, &traj.v, rows);
        PyTuple::new(py, [x, v])
    }

    /// The accelerations `x''` at given states: `x` and `v` samples × DOFs (1-D for one DOF),
    /// `u` samples × inputs (or a dict by name). Returns samples × DOFs.
    #[pyo3(signature = (x, v, u=None))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let xs = columns(x, "x")?;
        let vs = columns(v, "v")?;
        let us = self.inputs_arg(u)?;
        let rows = xs[0].len();
        let row_major = |cols: &[Vec<f64>]| -> Vec<f64> {
            (0..rows)
                .flat_map(|k| {
                    cols.iter()
                        .map(move |c| c.get(k).copied().unwrap_or(f64::NAN))
                })
                .collect()
        };
        if [&xs, &vs, &us]
            .iter()
            .any(|c| c.iter().any(|c| c.len() != rows))
        {
            return Err(input_error(format!(
                "predict: x, v and u need the same number of samples ({rows})"
            )));
        }
        let (xr, vr, ur) = (row_major(&xs), row_major(&vs), row_major(&us));
        let out = py
            .detach(|| tfs::simulate::predict(&self.inner, &xr, &vr, &ur, rows))
            .or_raise()?;
        let n = self.inner.dofs.len();
        let cols: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..rows).map(|k| out[k * n + i]).collect())
            .collect();
        Ok(to_array2(py, &cols, rows))
    }

    /// Simulates the model under each record's measured input and scores it (as `tfs compare`).
    /// Returns a `tfs.Comparison`: `r_mse` (the mean R-MSE over records and DOFs, the number
    /// `tfs compare` prints and `diagnose(...)["r_mse"]` gives), `per_dof`, `per_record`,
    /// `records` (one dict per record as `tfs compare --json` gives them); it prints as a
    /// short table. `offsets`: `"auto"`, `"keep"` or `"remove"`; `clipped`: `"error"`,
    /// `"warn"` or `"allow"`; `horizon`: also score every record by predictions over pieces of
    /// this many samples from the measured state (`short_horizon` of each record; as `tfs
    /// compare --horizon`).
    #[pyo3(signature = (records, *, offsets="auto", clipped="error", horizon=None))]
    fn compare<'py>(
        &self,
        py: Python<'py>,
        records: &Bound<'py, PyAny>,
        offsets: &str,
        clipped: &str,
        horizon: Option<usize>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (offsets, clipped) = (offsets_mode(offsets)?, clipped_policy(clipped)?);
        let (recs, mut warnings) = records_arg(records, "records")?;
        let (scores, w) = py
            .detach(|| -> tfs::Result<_> {
                let (recs, _, w) = prepare_for_model(&self.inner, recs, offsets, clipped)?;
                let scores: Vec<Value> = recs
                    .iter()
                    .map(|r| tfs::compare::score_with(&self.inner, r, horizon).map(|s| s.to_json()))
                    .collect::<tfs::Result<_>>()?;
                Ok((Value::Array(scores), w))
            })
            .or_raise()?;
        warnings.extend(w);
        warn_all(py, &warnings)?;
        let files = json_to_py(py, &scores)?;
        py.import("tfs._results")?
            .getattr("Comparison")?
            .call1((files,))
    }

    /// Adds named physical effects (`dry-friction`, `quadratic-damping`, `stop`, `name@dof`, …;
    /// `tfs.diagnose` ranks them) one by one and refits on the records, as `tfs refit`; with
    /// `until_clean=N`, then runs the diagnosis loop (`refit --until-clean N`): each round adds
    /// what `tfs.diagnose` finds missing, until nothing significant remains. The new model's
    /// `report` holds the error `ladder`, its `warnings`, the loop's `rounds` and the `stops`
    /// re-scanned; its `verdict` says in one sentence whether the geometric-mean R-MSE over the records
    /// fell (`improved`), and a rise is also warned at the calling line.
    #[pyo3(signature = (records, add=Vec::new(), *, until_clean=None, refine=false, validate=None, offsets="auto", clipped="error"))]
    #[allow(clippy::too_many_arguments)]
    fn refit(
        &self,
        py: Python<'_>,
        records: &Bound<'_, PyAny>,
        add: Vec<String>,
        until_clean: Option<usize>,
        refine: bool,
        validate: Option<&Bound<'_, PyAny>>,
        offsets: &str,
        clipped: &str,
    ) -> PyResult<PyModel> {
        let (offsets, clipped) = (offsets_mode(offsets)?, clipped_policy(clipped)?);
        let (recs, mut warnings) = records_arg(records, "records")?;
        let (held, w) = match validate {
            Some(v) => records_arg(v, "validate")?,
            None => (Vec::new(), Vec::new()),
        };
        warnings.extend(w);
        let (out, w) = py
            .detach(|| -> tfs::Result<_> {
                let (recs, report, mut w) = prepare_for_model(&self.inner, recs, offsets, clipped)?;
                let held = if held.is_empty() {
                    held
                } else {
                    let (h, _, w2) = prepare_for_model(&self.inner, held, offsets, clipped)?;
                    w.extend(w2);
                    h
                };
                let req = tfs::refit::RefitRequest {
                    add,
                    until_clean,
                    refine,
                    held_out: held,
                };
                let r = tfs::refit::refit_with(&self.inner, &recs, &req, &report)?;
                Ok(((r, report), w))
            })
            .or_raise()?;
        let (r, offsets_report) = out;
        warnings.extend(w);
        warnings.extend(r.warnings.iter().cloned());
        warn_all(py, &warnings)?;
        let verdict = tfs::report::ladder_verdict(&r.ladder);
        Ok(PyModel {
            inner: r.model,
            report: serde_json::json!({
                "ladder": r.ladder, "warnings": r.warnings, "stops": r.stops, "rounds": r.rounds,
                "refine": r.refine.as_ref().map(RefineReport::to_json),
                "offsets": offsets_report.to_json(), "verdict": verdict.sentence,
            }),
            verdict: Some(verdict),
        })
    }

    /// A model from its coefficients, `{dof: {term: coefficient}}` (what `model.coefficients`
    /// gives, so `Model.from_terms(m.coefficients)` has `m`'s equations), e.g. a model fitted
    /// elsewhere: `tfs.Model.from_terms({"x": {"x": -1.0, "x^3": -0.5, "x'": -0.1, "u": 1.0}})`.
    /// Terms are written in the library grammar (`x^3`, `x'`, `x^2*x'`, `(x2-x1)^3`, …); a name
    /// that is not a DOF is an input (its order of first use is the order of `inputs`). DOFs
    /// are the dict's keys in order, or `dofs` when given (every DOF needs an entry).
    #[staticmethod]
    #[pyo3(signature = (coefficients, *, dofs=None, method="from_terms"))]
    fn from_terms(
        coefficients: &Bound<'_, PyDict>,
        dofs: Option<Vec<String>>,
        method: &str,
    ) -> PyResult<Self> {
        let mut given: Vec<(String, Vec<(String, f64)>)> = Vec::new();
        for (k, v) in coefficients.iter() {
            let dof: String = k
                .extract()
                .map_err(|_| input_error("coefficients: keys must be DOF names (str)"))?;
            let terms = v.cast::<PyDict>().map_err(|_| {
                input_error(format!(
                    "coefficients['{dof}']: expected a dict {{term: coefficient}}"
                ))
            })?;
            let mut list = Vec::new();
            for (t, c) in terms.iter() {
                let t: String = t.extract().map_err(|_| {
                    input_error(format!("coefficients['{dof}']: term names must be str"))
                })?;
                let c: f64 = c.extract().map_err(|_| {
                    input_error(format!("coefficients['{dof}']['{t}']: expected a number"))
                })?;
                list.push((t, c));
            }
            given.push((dof, list));
        }
        let dofs = dofs.unwrap_or_else(|| given.iter().map(|(d, _)| d.clone()).collect());
        let model = model_from_terms(&dofs, &given, method).or_raise()?;
        Ok(Self::new(model))
    }

    /// The model as `tfs-model/1` JSON, the same text the CLI writes.
    fn to_json(&self) -> PyResult<String> {
        self.inner.to_json_string().or_raise()
    }

    /// A model from `tfs-model/1` JSON text.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        Ok(Self::new(Model::from_json_str(text).or_raise()?))
    }

    /// Writes the model file (`tfs-model/1` JSON, atomically), as `tfs identify --out`.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        self.inner.write_path(&path).or_raise()
    }

    /// Reads a model file written by the CLI or by `save`.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        Ok(Self::new(tfs::records::read_model(&path).or_raise()?))
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other
            .cast::<PyModel>()
            .map(|o| o.get().inner == self.inner)
            .unwrap_or(false)
    }

    /// Pickling: by the model file's JSON.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let text = slf.get().to_json()?;
        let from_json = py.get_type::<PyModel>().getattr("from_json")?;
        PyTuple::new(py, [from_json, PyTuple::new(py, [text])?.into_any()])
    }
}

impl PyModel {
    /// The inputs argument of `simulate`/`predict` as one column per input the equations use
    /// (the model file's `inputs`): `u` gives the inputs the model was identified with, by name
    /// (a dict) or positionally in that order; those the equations do not use are ignored.
    fn inputs_arg(&self, u: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<Vec<f64>>> {
        let names = identified_inputs(&self.inner);
        let used = &self.inner.inputs;
        match u {
            None if used.is_empty() => Ok(Vec::new()),
            None => Err(input_error(format!(
                "u: the model takes the input(s) [{}]; give them (a dict by name, or samples × inputs in that order)",
                names.join(", ")
            ))),
            Some(u) => {
                if let Ok(d) = u.cast::<PyDict>() {
                    for k in d.keys() {
                        let k: String = k.extract()?;
                        if !names.contains(&k) {
                            return Err(input_error(format!(
                                "u: no input '{k}'; the model takes [{}]",
                                names.join(", ")
                            )));
                        }
                    }
                    used.iter()
                        .map(|n| match d.get_item(n)? {
                            Some(col) => crate::convert::vec1(&col, &format!("u['{n}']")),
                            None => Err(input_error(format!(
                                "u: input '{n}' is missing; the model takes [{}]",
                                names.join(", ")
                            ))),
                        })
                        .collect()
                } else {
                    let cols = columns(u, "u")?;
                    if cols.len() != names.len() && cols.len() != used.len() {
                        return Err(input_error(format!(
                            "u has {} column(s) but the model takes {} input(s) [{}]",
                            cols.len(),
                            names.len(),
                            names.join(", ")
                        )));
                    }
                    // All identified inputs in their order, or just the used ones.
                    let order: &[String] = if cols.len() == names.len() {
                        &names
                    } else {
                        used
                    };
                    Ok(used
                        .iter()
                        .map(|n| {
                            let k = order.iter().position(|o| o == n).unwrap_or(0);
                            cols[k].clone()
                        })
                        .collect())
                }
            }
        }
    }
}

/// A model from `(dof, [(term, coefficient)])` lists (see `Model.from_terms`).
fn model_from_terms(
    dofs: &[String],
    given: &[(String, Vec<(String, f64)>)],
    method: &str,
) -> tfs::Result<Model> {
    use tfs::library::{Equation, Library, ModelTerm};
    let mut equations = Vec::new();
    for (dof, terms) in given {
        let mut eq = Equation {
            dof: dof.clone(),
            terms: Vec::new(),
        };
        for (name, coef) in terms {
            let lib = Library::parse(name, dofs).map_err(|e| {
                tfs::Error::Invalid(format!(
                    "coefficients['{dof}']: term '{name}': {}",
                    tfs::one_line(&e)
                ))
            })?;
            let [term] = lib.terms() else {
                return Err(tfs::Error::Invalid(format!(
                    "coefficients['{dof}']: '{name}' names {} terms; give one term per key",
                    lib.terms().len()
                )));
            };
            eq.terms.push(ModelTerm::new(term.clone(), *coef));
        }
        equations.push(eq);
    }
    Ok(Model::new(dofs.to_vec(), equations, method)?)
}

/// Reads a model file (`tfs-model/1`), as `Model.load`.
#[pyfunction]
pub fn load(path: PathBuf) -> PyResult<PyModel> {
    PyModel::load(path)
}
