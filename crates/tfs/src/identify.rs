//! Identification as `tfs identify` and the Python package run it: the options with the CLI's
//! defaults, the default libraries, the offsets policy, the fit, and the optional
//! simulation-error refinement. The CLI and the Python package both call [`plan`] then
//! [`identify`], so the same records give the same model to the bit.
//!
//! Every option of the criteria layer that a caller can set is set here (in [`plan`]), so a change
//! of that layer's options touches this module only.

use serde_json::json;
use tfs_criteria::{
    IdentifySpec, MassChoice, TieOptions, Trace, identify_sindy, identify_tfs, identify_tfs_tied,
};
use tfs_data::Record;
use tfs_library::{Library, Model};

use crate::error::Result;
use crate::invalid;
use crate::records::{Offsets, apply_offsets, guess_dofs, guess_inputs};
use crate::report::{OffsetsReport, RefineReport, ValidationReport};

/// Identification method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Method {
    /// T-F-S SINDy: criteria 1–4 with frequency-domain (weak-form) regression (default).
    #[default]
    Tfs,
    /// Classical SINDy: numerical derivatives and time-domain STLSQ (the baseline).
    Sindy,
}

impl Method {
    /// The method by its name (`tfs`, `sindy`); the error names `what`.
    pub fn parse(text: &str, what: &str) -> Result<Self> {
        match text {
            "tfs" => Ok(Method::Tfs),
            "sindy" => Ok(Method::Sindy),
            _ => invalid!("{what} '{text}': expected tfs or sindy"),
        }
    }
}

/// Whether the T-F-S fit ties a chain element's force law between the two DOFs it connects
/// (Newton's third law; `tfs_criteria::identify_tfs_tied`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Tie {
    /// Tie when the method is T-F-S and a term of a relative coordinate is in both DOFs'
    /// libraries (a chain with the default libraries); fit each DOF on its own otherwise.
    #[default]
    Auto,
    /// Always tie (an error when nothing can be tied or the method is classical SINDy).
    On,
    /// Fit each DOF's equation on its own.
    Off,
}

/// What `tfs identify` can be asked, with its defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifyOptions {
    /// Library spec for every DOF (default: [`default_libraries`]).
    pub library: Option<String>,
    /// Identification method.
    pub method: Method,
    /// DOF columns (default: `x` or `x1`, `x2`, … found in the records).
    pub dofs: Vec<String>,
    /// Fixed sparsity threshold (default: chosen on held-out data).
    pub threshold: Option<f64>,
    /// Re-estimate the chosen structure's coefficients by simulation error.
    pub refine: bool,
    /// Chains: whether each element's force law is tied between the two DOFs it connects.
    pub tie: Tie,
    /// With `tie`: `equal`, `estimate` or one positive mass per DOF (`1,0.5`).
    pub masses: String,
    /// DC offsets of the DOF and input channels.
    pub offsets: Offsets,
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        Self {
            library: None,
            method: Method::Tfs,
            dofs: Vec::new(),
            threshold: None,
            refine: false,
            tie: Tie::Auto,
            masses: "equal".into(),
            offsets: Offsets::Auto,
        }
    }
}

/// What [`plan`] decided from the options and the records' column names: the spec handed to
/// the criteria layer, the columns every record must hold, and the offsets policy.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The identification spec.
    pub spec: IdentifySpec,
    /// The DOF columns.
    pub dofs: Vec<String>,
    /// Every column the libraries name (DOFs first): each record must hold them.
    pub required: Vec<String>,
    /// The DOF and input columns the offsets policy applies to.
    pub channels: Vec<String>,
    /// The offsets mode after resolving `auto`.
    pub mode: Offsets,
    /// Why that mode.
    pub why: String,
    /// Whether `constant-term` added `1` to a library.
    pub added_constant: bool,
}

impl Plan {
    /// What is done to the data: `Remove` or `Keep` (`constant-term` keeps the data).
    pub fn data_mode(&self) -> Offsets {
        if self.mode == Offsets::Remove {
            Offsets::Remove
        } else {
            Offsets::Keep
        }
    }
}

/// The default library for the given DOFs and inputs: per DOF, the cell's own relative coordinate
/// (and the next cell's, in a chain) to powers 1..7, their relative velocities, and the inputs.
pub fn default_libraries(dofs: &[String], inputs: &[String]) -> Vec<String> {
    let rel = |i: usize| -> String {
        if i == 0 {
            dofs[0].clone()
        } else {
            format!("({}-{})", dofs[i], dofs[i - 1])
        }
    };
    (0..dofs.len())
        .map(|i| {
            let mut parts = vec![format!("{}^1..7", rel(i)), format!("{}'", rel(i))];
            if i + 1 < dofs.len() {
                parts.push(format!("{}^1..7", rel(i + 1)));
                parts.push(format!("{}'", rel(i + 1)));
            }
            parts.extend(inputs.iter().cloned());
            parts.join(", ")
        })
        .collect()
}

/// `--masses`: `equal`, `estimate` (candidate ratios 0.25..4) or one positive mass per DOF.
pub fn parse_masses(text: &str, n: usize) -> Result<MassChoice> {
    match text.trim() {
        "equal" => Ok(MassChoice::Equal),
        "estimate" => Ok(MassChoice::Estimate {
            candidates: vec![0.25, 0.33, 0.5, 0.67, 0.8, 1.0, 1.25, 1.5, 2.0, 3.0, 4.0],
        }),
        list => {
            let m: Option<Vec<f64>> = list.split(',').map(|v| v.trim().parse().ok()).collect();
            let Some(m) = m else {
                invalid!(
                    "--masses '{text}': expected 'equal', 'estimate' or {n} comma-separated numbers"
                )
            };
            if m.len() != n || m.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                invalid!("--masses '{text}': give one positive mass per DOF ({n})");
            }
            Ok(MassChoice::Given(m))
        }
    }
}

/// Resolves `--offsets auto` by the kind of the input columns; returns the mode and why.
pub fn resolve_offsets(requested: Offsets, inputs: &[String]) -> (Offsets, String) {
    if requested != Offsets::Auto {
        return (requested, "given with --offsets".to_string());
    }
    if inputs.is_empty() {
        (
            Offsets::Keep,
            "auto: no input column, records used as they are".to_string(),
        )
    } else if inputs.iter().any(|c| c.starts_with("xb")) {
        (
            Offsets::Keep,
            "auto: base-motion input, displacements are geometric coordinates whose origin matters; records used as they are".to_string(),
        )
    } else {
        (
            Offsets::ConstantTerm,
            format!(
                "auto: force-like input(s) [{}]: records used as they are, with a constant term in the library that takes up a constant force or sensor offset (selected only when the records need it; the mean of a short or transient record is motion, not offset)",
                inputs.join(", ")
            ),
        )
    }
}

fn spec_libraries(spec: &IdentifySpec) -> Result<Vec<Library>> {
    let specs: Vec<&String> = if spec.dof_libraries.is_empty() {
        vec![&spec.library]
    } else {
        spec.dof_libraries.iter().collect()
    };
    specs
        .into_iter()
        .map(|s| Ok(Library::parse(s, &spec.dofs)?))
        .collect()
}

/// The most terms a library may have in `identify` (per DOF).
pub const MAX_LIBRARY_COLUMNS: usize = 512;

/// The time column among `columns` when the caller passed the header with it (`t` otherwise).
fn time_column(columns: &[String]) -> &str {
    columns
        .iter()
        .find(|c| *c == "t")
        .map_or("t", String::as_str)
}

/// Refuses DOFs that cannot be displacements: the time column, an input column of the data
/// contract (base motion `xb*`, force-like `u`, `force`, `voltage`), a measured velocity
/// (`*_vel`), or a name given twice.
pub fn check_dofs(dofs: &[String], time_column: &str) -> Result<()> {
    for (i, d) in dofs.iter().enumerate() {
        if dofs[..i].contains(d) {
            invalid!("--dofs: '{d}' is given twice; name each displacement column once");
        }
        if d == time_column || d == "t" {
            invalid!(
                "--dofs {d}: '{d}' is the time column, not a displacement; name the displacement columns (e.g. --dofs x)"
            );
        }
        let input = d.starts_with("xb") || ["u", "force", "voltage"].contains(&d.as_str());
        if input || d.ends_with("_vel") {
            let what = if input {
                "an input (excitation) column"
            } else {
                "a measured velocity"
            };
            invalid!(
                "--dofs {d}: '{d}' is {what}, not a displacement; a DOF is a measured displacement column such as x or x1, x2"
            );
        }
    }
    Ok(())
}

/// Refuses a record on which a library term is not finite (a cell of 1e300 squares to
/// infinity), naming the file, the time, the term and the values of its columns there — before
/// the fit, which would only see a segment's row. Velocities are taken by central differences.
pub fn check_terms_finite(spec: &IdentifySpec, records: &[Record]) -> Result<()> {
    use tfs_data::Columns;
    use tfs_library::ColumnSet;
    let libs = spec_libraries(spec)?;
    for rec in records {
        let mut cols = ColumnSet::new(rec);
        for d in &spec.dofs {
            if let Some(x) = rec.column(d)
                && let Ok(v) = tfs_signal::diff::central_difference(x, rec.dt(), 1)
            {
                cols.insert(format!("{d}'"), v)?;
            }
        }
        // The library's bound of each term clears almost every term without evaluating it.
        for lib in &libs {
            if let Some((j, row)) = lib.first_non_finite(&cols) {
                let term = &lib.terms()[j];
                let values: Vec<String> = term
                    .required_columns()
                    .iter()
                    .filter_map(|c| cols.column(c).map(|v| format!("{c} = {:e}", v[row])))
                    .collect();
                invalid!(
                    "{}: data row {} (t = {} s): library term '{term}' is not finite there ({}); the value is out of range for this term: check that cell, or use a library without the high powers",
                    rec.source(),
                    row + 1,
                    rec.t()[row],
                    values.join(", ")
                );
            }
        }
    }
    Ok(())
}

/// A warning per DOF whose equation kept no term (`x'' = 0`: the model predicts nothing for it);
/// an error when no equation kept any, so no empty model is written or reported as a result.
pub fn empty_equation_warnings(model: &Model, method: Method) -> Result<Vec<String>> {
    let advice =
        "check that the records excite this DOF, lower --threshold, or use a smaller library";
    let method = match method {
        Method::Tfs => "T-F-S",
        Method::Sindy => "classical SINDy",
    };
    if model.equations.iter().all(|e| e.terms.is_empty()) {
        invalid!(
            "nothing identified: the {method} fit kept no library term in any equation (every equation is x'' = 0), so no model is written; {advice}"
        );
    }
    Ok(model
        .equations
        .iter()
        .filter(|e| e.terms.is_empty())
        .map(|e| {
            format!(
                "{}: the {method} fit kept no library term ({}'' = 0), so the model predicts nothing for it; {advice}",
                e.dof, e.dof
            )
        })
        .collect())
}

/// Decides the spec, the required columns and the offsets policy from the options and the
/// column names of the first record (`source` names it in messages).
pub fn plan(opts: &IdentifyOptions, columns: &[String], source: &str) -> Result<Plan> {
    let dofs = if opts.dofs.is_empty() {
        let d = guess_dofs(columns);
        if d.is_empty() {
            invalid!(
                "{source}: no displacement column found (expected 'x' or 'x1', 'x2', …; the header has [{}]); name them with --dofs",
                columns.join(", ")
            );
        }
        d
    } else {
        opts.dofs.clone()
    };
    check_dofs(&dofs, time_column(columns))?;
    let inputs = guess_inputs(columns);
    let mut spec = IdentifySpec::new(&dofs.iter().map(String::as_str).collect::<Vec<_>>(), "");
    match &opts.library {
        Some(lib) => spec.library = lib.clone(),
        None => {
            let libs = default_libraries(&dofs, &inputs);
            spec.library = libs[0].clone();
            if dofs.len() > 1 {
                spec.dof_libraries = libs;
            }
        }
    }
    if let Some(th) = opts.threshold {
        if !(th.is_finite() && th >= 0.0) {
            invalid!("--threshold {th}: must be a finite number ≥ 0");
        }
        spec.tfs.fit.threshold = Some(th);
        spec.sindy.threshold = Some(th);
    }
    // Every column the libraries name must be present in every record.
    let mut required: Vec<String> = dofs.clone();
    let libs = spec_libraries(&spec)?;
    for (lib, d) in libs.iter().zip(&dofs) {
        if lib.len() > MAX_LIBRARY_COLUMNS {
            let which = if libs.len() == 1 {
                "the library".to_string()
            } else {
                format!("the library of {d}''")
            };
            invalid!(
                "--library: {which} has {} terms; at most {MAX_LIBRARY_COLUMNS} are allowed (every candidate is a column over every sample, and a sparse fit needs far more independent samples than candidates): narrow the ranges",
                lib.len()
            );
        }
    }
    for lib in &libs {
        for c in lib.required_columns() {
            if !c.ends_with('\'') && !required.contains(&c) {
                required.push(c);
            }
        }
    }
    let input_cols: Vec<String> = required
        .iter()
        .filter(|c| !dofs.contains(c))
        .cloned()
        .collect();
    let (mode, why) = resolve_offsets(opts.offsets, &input_cols);
    let mut added_constant = false;
    if mode == Offsets::ConstantTerm {
        if spec.dof_libraries.is_empty() {
            if !libs[0].terms().iter().any(|t| t.is_constant()) {
                spec.library = format!("1, {}", spec.library);
                added_constant = true;
            }
        } else {
            for (s, lib) in spec.dof_libraries.iter_mut().zip(&libs) {
                if !lib.terms().iter().any(|t| t.is_constant()) {
                    *s = format!("1, {s}");
                    added_constant = true;
                }
            }
        }
    }
    let channels: Vec<String> = dofs.iter().chain(&input_cols).cloned().collect();
    Ok(Plan {
        spec,
        dofs,
        required,
        channels,
        mode,
        why,
        added_constant,
    })
}

/// An identified model with what was done on the way.
#[derive(Debug, Clone)]
pub struct Identification {
    /// The model; its trace holds the criteria trace and the offsets report.
    pub model: Model,
    /// The criteria trace.
    pub trace: Trace,
    /// What was done with the channel offsets (mode, why, per record).
    pub offsets: OffsetsReport,
    /// The simulation-error refinement (`None` without `refine`).
    pub refine: Option<RefineReport>,
    /// What the user must know about the result: the criteria trace's warnings and a DOF whose
    /// equation kept no term.
    pub warnings: Vec<String>,
}

/// Identifies a model from validated records (holding `plan.required`): applies the offsets
/// policy, fits by the chosen method, refines when asked (keeping, with `held_out` records,
/// whichever fit predicts them better), and records the offsets in the model's trace.
pub fn identify(
    records: Vec<Record>,
    mut held_out: Vec<Record>,
    opts: &IdentifyOptions,
    plan: &Plan,
) -> Result<Identification> {
    let auto_force = opts.offsets == Offsets::Auto && plan.mode == Offsets::ConstantTerm;
    let (plan, fitted) = if auto_force && opts.method == Method::Tfs {
        choose_by_sparse_fits(&records, opts, plan)?
    } else if auto_force {
        let decided = choose_force_offsets(&records, opts, plan)?;
        let fitted = fit_treatment(records, opts, &decided)?;
        (decided, fitted)
    } else {
        (plan.clone(), fit_treatment(records, opts, plan)?)
    };
    let Treated {
        records,
        mut offsets,
        mut identified,
        restored,
    } = fitted;
    offsets.why = plan.why.clone();
    let data_mode = plan.data_mode();
    let mut refine = None;
    if opts.refine {
        let refined = tfs_refine::refine(
            &identified.model,
            &records,
            &tfs_refine::RefineOptions::default(),
        )?;
        let mut report = RefineReport::from(&refined);
        if held_out.is_empty() {
            identified.model = refined.model;
        } else {
            apply_offsets(&mut held_out, &plan.channels, data_mode, &plan.why)?;
            let (chosen, scores) =
                tfs_refine::choose_by_validation(&identified.model, &refined.model, &held_out)?;
            report.validation = Some(ValidationReport::from(&scores));
            identified.model = chosen;
        }
        refine = Some(report);
    } else if !held_out.is_empty() {
        invalid!("--validate needs --refine (the held-out records choose the refined fit or not)");
    }
    set_offsets(&mut identified.model, &offsets);
    let mut warnings = crate::report::support_warnings(&identified.trace, &identified.model);
    warnings.extend(restored);
    warnings.extend(empty_equation_warnings(&identified.model, opts.method)?);
    Ok(Identification {
        model: identified.model,
        trace: identified.trace,
        offsets,
        refine,
        warnings,
    })
}

/// The records as one treatment of their offsets left them, the fit on them, what was done to
/// the offsets, and the warnings of a restored restoring force.
struct Treated {
    records: Vec<Record>,
    offsets: OffsetsReport,
    identified: tfs_criteria::Identified,
    restored: Vec<String>,
}

/// Applies `plan`'s treatment of the offsets to `records` and fits them by the chosen method.
fn fit_treatment(mut records: Vec<Record>, opts: &IdentifyOptions, plan: &Plan) -> Result<Treated> {
    let data_mode = plan.data_mode();
    let mut offsets = apply_offsets(&mut records, &plan.channels, data_mode, &plan.why)?;
    offsets.requested = Some(opts.offsets);
    if plan.mode == Offsets::ConstantTerm {
        offsets.mode = plan.mode;
        offsets.constant_term_added = Some(plan.added_constant);
    }
    let spec = &plan.spec;
    check_terms_finite(spec, &records)?;
    let mut restored = Vec::new();
    let mut identified = match (opts.method, tied(opts, plan)?) {
        (Method::Tfs, false) => {
            let mut id = identify_tfs(&records, spec)?;
            // A DOF left without a restoring force gets the library's displacement terms back
            // when the records simulate better with them (not with a threshold the user fixed).
            if opts.threshold.is_none() {
                restored = crate::restore::restore_displacement(&mut id, &records, spec)?;
            }
            id
        }
        (Method::Tfs, true) => {
            let tie = TieOptions::new(parse_masses(&opts.masses, plan.dofs.len())?);
            identify_tfs_tied(&records, spec, &tie)?
        }
        (Method::Sindy, _) => identify_sindy(&records, spec)?,
    };
    // The model file carries the criteria trace (the offsets are added below).
    identified.model.trace = identified.trace.to_json();
    Ok(Treated {
        records,
        offsets,
        identified,
        restored,
    })
}

/// The plan of `opts` with each record's means removed (`--offsets remove`), for `records`.
fn remove_plan(records: &[Record], opts: &IdentifyOptions) -> Result<Option<Plan>> {
    let Some(first) = records.first() else {
        return Ok(None);
    };
    let remove_opts = IdentifyOptions {
        offsets: Offsets::Remove,
        ..opts.clone()
    };
    Ok(Some(self::plan(
        &remove_opts,
        first.names(),
        first.source(),
    )?))
}

/// How much lower [`crate::offsets_choice::compare_sparse`]'s criterion (a BIC over the kept
/// bins) must be with each record's means removed before `--offsets auto` removes them: 2, where
/// Kass & Raftery's scale (1995) starts "positive evidence" (a difference below it is "not worth
/// more than a bare mention"). Removing the means changes the user's data, and where the mean is
/// motion it puts a constant force into the law that the library has no column for (a short
/// record's `x^2` then takes it up: its interval excludes the true zero however narrow the
/// noise). On records without offsets the two laws often score within a fraction of this; a
/// sensor offset inside the nonlinear terms separates them by far more (see
/// `docs/DECISIONS.md`).
const REMOVAL_EVIDENCE: f64 = 2.0;

/// `--offsets auto` with force-like inputs and T-F-S: the records are identified both ways —
/// kept with the constant term of `plan`, and with each record's means removed — and the
/// treatment whose sparse law scores better is used (see [`crate::offsets_choice::compare_sparse`]:
/// held-out equation error against the number of terms, on the bins the fit kept). Returns the
/// plan used (saying why) and its fit.
fn choose_by_sparse_fits(
    records: &[Record],
    opts: &IdentifyOptions,
    plan: &Plan,
) -> Result<(Plan, Treated)> {
    let Some(mut removing) = remove_plan(records, opts)? else {
        return Ok((plan.clone(), fit_treatment(records.to_vec(), opts, plan)?));
    };
    // A treatment the fit refuses leaves the other (the kept data's error when both fail).
    let kept = fit_treatment(records.to_vec(), opts, plan);
    let removed = fit_treatment(records.to_vec(), opts, &removing);
    let (kept, removed) = match (kept, removed) {
        (Ok(k), Ok(r)) => (k, r),
        (Ok(k), Err(_)) => return Ok((plan.clone(), k)),
        (Err(_), Ok(r)) => {
            removing.why = "auto: force-like input(s): each record's means removed from every DOF and input channel (the records as they are, with a constant term, could not be fitted)".to_string();
            return Ok((removing, r));
        }
        (Err(e), Err(_)) => return Err(e),
    };
    use crate::offsets_choice::{compare_sparse, sparse_scores};
    let (kept_plan, kept, kept_how) = drop_unneeded_constant(records, opts, plan, kept)?;
    let s_keep = sparse_scores(&kept.identified.trace, &kept.identified.model);
    let s_remove = sparse_scores(&removed.identified.trace, &removed.identified.model);
    let compared = s_keep
        .as_ref()
        .zip(s_remove.as_ref())
        .and_then(|(k, r)| compare_sparse(k, r));
    let (Some(s_keep), Some(s_remove), Some((c_keep, c_remove))) = (s_keep, s_remove, compared)
    else {
        // No held-out score to compare (no equation kept a term): the full library decides.
        let decided = choose_force_offsets(records, opts, plan)?;
        return Ok(if decided.mode == Offsets::Remove {
            (decided, removed)
        } else if kept_plan.mode == Offsets::Keep {
            (kept_plan, kept)
        } else {
            (decided, kept)
        });
    };
    let terms = |s: &[crate::offsets_choice::SparseScore]| s.iter().map(|v| v.terms).sum::<usize>();
    let held = |s: &[crate::offsets_choice::SparseScore]| {
        s.iter().map(|v| v.held_out).sum::<f64>() / s.len() as f64
    };
    let pct = |v: f64| format!("{:.4} %", 100.0 * v);
    // Removing the means changes the user's data: it must not predict the held-out records
    // worse on any DOF, and must win the criterion by positive evidence, `REMOVAL_EVIDENCE`
    // (the rig's linear law, as good either way, is one constant shorter without its offsets:
    // ln of its bins, 4.6 at 100).
    let removal_predicts = s_remove
        .iter()
        .zip(&s_keep)
        .all(|(r, k)| r.held_out <= k.held_out);
    if !(removal_predicts && c_remove + REMOVAL_EVIDENCE <= c_keep) {
        let mut chosen = kept_plan;
        chosen.why = format!(
            "auto: force-like input(s): records used as they are {kept_how} — the sparse law found that way ({} terms) leaves {} of the held-out accelerations unexplained, against {} ({} terms) with each record's means removed (the means are motion, not offsets; they are removed only on positive evidence, a criterion lower by {REMOVAL_EVIDENCE})",
            terms(&s_keep),
            pct(held(&s_keep)),
            pct(held(&s_remove)),
            terms(&s_remove)
        );
        Ok((chosen, kept))
    } else {
        removing.why = format!(
            "auto: force-like input(s): each record's means removed from every DOF and input channel — the sparse law found that way ({} terms) leaves {} of the held-out accelerations unexplained, against {} ({} terms) with the records kept {kept_how} (sensor offsets inside the nonlinear terms)",
            terms(&s_remove),
            pct(held(&s_remove)),
            pct(held(&s_keep)),
            terms(&s_keep)
        );
        Ok((removing, removed))
    }
}

/// The constant-term treatment's fit `kept` of `plan`, or the records as they are without the
/// constant when it is not needed: when `plan` added the constant and the sparse law keeps it,
/// the records are identified once more without it (`--offsets keep`), and that law is used
/// when it predicts the held-out records as well on every DOF and wins
/// [`crate::offsets_choice::compare_sparse`] (held-out error against terms). The constant's own
/// test in the fit weighs its value against the noise of the residual's mean only, with the
/// other coefficients taken as exact; where the record's mean is motion (a response that stays
/// in one well of a double-well law) `1, x, x², x³` are nearly collinear over the record, the
/// constant and `x²` stand in for `x³`, and only the law found without the constant shows that
/// none was needed. Returns the plan used, its fit, and how the records were used (for the
/// trace's sentence).
fn drop_unneeded_constant(
    records: &[Record],
    opts: &IdentifyOptions,
    plan: &Plan,
    kept: Treated,
) -> Result<(Plan, Treated, &'static str)> {
    const WITH: &str = "with a constant term in the library (kept only if the records need it)";
    const WITHOUT: &str = "without a constant term (the law found with one keeps it, the law found without it predicts the held-out accelerations as well with fewer terms)";
    let keeps_constant = kept
        .identified
        .model
        .equations
        .iter()
        .any(|e| e.terms.iter().any(|t| t.term.is_constant()));
    let Some(first) = records.first() else {
        return Ok((plan.clone(), kept, WITH));
    };
    if !(plan.added_constant && keeps_constant) {
        return Ok((plan.clone(), kept, WITH));
    }
    let keep_opts = IdentifyOptions {
        offsets: Offsets::Keep,
        ..opts.clone()
    };
    let keep_plan = self::plan(&keep_opts, first.names(), first.source())?;
    let Ok(plain) = fit_treatment(records.to_vec(), opts, &keep_plan) else {
        return Ok((plan.clone(), kept, WITH));
    };
    use crate::offsets_choice::{compare_sparse, sparse_scores};
    let s_const = sparse_scores(&kept.identified.trace, &kept.identified.model);
    let s_plain = sparse_scores(&plain.identified.trace, &plain.identified.model);
    let better = match (&s_const, &s_plain) {
        (Some(c), Some(p)) => {
            p.iter().zip(c).all(|(p, c)| p.held_out <= c.held_out)
                && compare_sparse(p, c).is_some_and(|(cp, cc)| cp < cc)
        }
        _ => false,
    };
    Ok(if better {
        (keep_plan, plain, WITHOUT)
    } else {
        (plan.clone(), kept, WITH)
    })
}

/// `--offsets auto` with force-like inputs (classical SINDy, or when the sparse fits give no
/// score): the treatment of the channel offsets whose full-library least squares explains the
/// records' accelerations better (see [`crate::offsets_choice::score_treatment`]): `plan` (the
/// constant term) or the plan with each record's means removed. The plan returned says why.
fn choose_force_offsets(records: &[Record], opts: &IdentifyOptions, plan: &Plan) -> Result<Plan> {
    let Some(mut remove_plan) = remove_plan(records, opts)? else {
        return Ok(plan.clone());
    };
    let mut removed = records.to_vec();
    apply_offsets(&mut removed, &remove_plan.channels, Offsets::Remove, "")?;
    let score = crate::offsets_choice::score_treatment;
    let s_remove = score(&removed, &plan.dofs, &spec_libraries(&remove_plan.spec)?)?;
    let s_const = score(records, &plan.dofs, &spec_libraries(&plan.spec)?)?;
    let pct = |v: f64| format!("{:.4} %", 100.0 * v);
    if s_remove.bic < s_const.bic {
        remove_plan.why = format!(
            "auto: force-like input(s): each record's means removed from every DOF and input channel — the full library leaves {} of the accelerations unexplained that way, against {} with the records kept and a constant term (sensor offsets inside the nonlinear terms)",
            pct(s_remove.residual_share),
            pct(s_const.residual_share)
        );
        Ok(remove_plan)
    } else {
        let mut kept = plan.clone();
        kept.why = format!(
            "auto: force-like input(s): records used as they are with a constant term in the library (kept only if the records need it) — the full library leaves {} of the accelerations unexplained that way, against {} with each record's means removed (the means are motion, not offsets)",
            pct(s_const.residual_share),
            pct(s_remove.residual_share)
        );
        Ok(kept)
    }
}

/// Whether the fit ties the chain's element laws: [`Tie::Auto`] ties when the method is T-F-S
/// and some relative-coordinate term is in two DOFs' libraries; [`Tie::On`] is refused when
/// nothing can be tied or the method is classical SINDy.
pub fn tied(opts: &IdentifyOptions, plan: &Plan) -> Result<bool> {
    let can_tie = plan.dofs.len() > 1 && !tfs_criteria::chain_ties(&plan.spec)?.is_empty();
    let tie = match (opts.tie, opts.method) {
        (Tie::Off, _) | (Tie::Auto, Method::Sindy) => false,
        (Tie::Auto, Method::Tfs) => can_tie,
        (Tie::On, Method::Sindy) => {
            invalid!("--tie works with --method tfs only (the tied fit is a T-F-S regression)")
        }
        (Tie::On, Method::Tfs) if !can_tie => invalid!(
            "--tie: no term of a relative coordinate between two DOFs (e.g. '(x2-x1)^3') is in both DOFs' libraries, so nothing can be tied; put the coupling terms in both libraries or drop --tie"
        ),
        (Tie::On, Method::Tfs) => true,
    };
    if !tie && opts.masses.trim() != "equal" {
        invalid!(
            "--masses {}: the masses enter the tied chain fit only, and this fit is not tied ({}); drop --masses or fit a chain with ties",
            opts.masses,
            if can_tie {
                "untied by request or by the method"
            } else {
                "no relative-coordinate term is in two DOFs' libraries"
            }
        );
    }
    Ok(tie)
}

/// Records in the model's trace how the offsets of the records it was fitted on were treated,
/// so that `compare`, `diagnose` and `refit` treat theirs the same.
pub fn set_offsets(model: &mut Model, offsets: &OffsetsReport) {
    let value = offsets.to_json();
    if let Some(obj) = model.trace.as_object_mut() {
        obj.insert("offsets".into(), value);
    } else {
        model.trace = json!({ "offsets": value });
    }
}
