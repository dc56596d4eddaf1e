//! The public entry points: [`refine`] and [`choose_by_validation`].

use serde_json::json;
use tfs_data::Record;
use tfs_dynamics::{SampledInput, SimulateOptions, rms_error, simulate_model_on_record};
use tfs_library::{HistoryEntry, Model, RecordScore};
use tfs_signal::Differentiator;

use crate::lm::{LmSettings, Prepared};
use crate::sens::Structure;
use crate::sensitivity::{displacement_noise_var, input_noise_spread, noise_dominated};
use crate::shooting::{
    Progress, Shooting, default_segment_len, parameter_scales, shortened_segment_len,
};
use crate::{RefineError, Result};
use rayon::prelude::*;

/// Options of [`refine`].
#[derive(Debug, Clone, PartialEq)]
pub struct RefineOptions {
    /// Segment length in resonance periods (the period is the peak of the measured
    /// displacement's amplitude spectrum); default 5.
    pub segment_periods: f64,
    /// Fixed segment length in samples; overrides `segment_periods` when set.
    pub segment_len: Option<usize>,
    /// RK4 sub-steps per sample interval (the input is spline-interpolated inside); default 4.
    pub substeps: usize,
    /// LM iterations per stage (each defect weight, and the polish); default 40.
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction; default 1e-8.
    pub ftol: f64,
    /// Stop when the scaled gradient `max |g_j| / D_j` is below `gtol · ‖r‖`; default 1e-10.
    pub gtol: f64,
    /// Continuity-defect weights of successive multiple-shooting stages (each stage starts from
    /// the previous stage's coefficients, segment states re-initialised from the data); default
    /// `[1, 10, 100]`.
    pub defect_weights: Vec<f64>,
    /// Finish with single shooting (one segment per record) when it does not blow up; default true.
    pub polish: bool,
    /// Weight each record's residuals by `1/RMS` of its displacement (about its mean) so records
    /// of different amplitude weigh equally; default true. When false all records share one
    /// weight per DOF (the pooled RMS).
    pub scale_records: bool,
    /// Differentiator for the initial guesses of segment velocities; default Savitzky–Golay
    /// (half window 3, degree 4).
    pub velocity: Differentiator,
    /// How before/after training scores are simulated (tfs-dynamics Dopri5); default
    /// [`SimulateOptions::default`].
    pub simulate: SimulateOptions,
    /// Leave out records whose free-run error the input's own noise dominates
    /// ([`crate::noise_dominated`] for the start model); with none left, the start model is
    /// returned. Default true.
    pub screen_input_noise: bool,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            segment_periods: 5.0,
            segment_len: None,
            substeps: 4,
            max_iterations: 40,
            ftol: 1e-8,
            gtol: 1e-10,
            defect_weights: vec![1.0, 10.0, 100.0],
            polish: true,
            scale_records: true,
            velocity: Differentiator::SavitzkyGolay {
                half_window: 3,
                poly_order: 4,
            },
            simulate: SimulateOptions::default(),
            screen_input_noise: true,
        }
    }
}

/// Result of [`refine`].
#[derive(Debug, Clone)]
pub struct Refined {
    /// The refined model (same terms; the start model if refinement did not help).
    pub model: Model,
    /// Training simulation cost of the start model: `Σ_records Σ_dofs (rms_error · w)²`
    /// with `w` the residual weights (`+∞` if it blows up).
    pub initial_cost: f64,
    /// The same cost for [`Refined::model`]; never above `initial_cost`.
    pub final_cost: f64,
    /// Total LM iterations over all stages.
    pub iterations: usize,
    /// Per training record: (source name, RMS simulation error before, after), RMS over DOFs,
    /// in the record's units (`+∞` for a blow-up).
    pub per_record: Vec<(String, f64, f64)>,
    /// True if the last LM stage met a stopping tolerance and the result improved or matched.
    pub converged: bool,
    /// What happened, in words.
    pub message: String,
    /// Training records left out because their free-run error is dominated by the input's
    /// noise: (source name, RMS spread that a fresh draw of that noise causes, RMS error of the
    /// start model), RMS over DOFs. [`Refined::per_record`] lists the others.
    pub noise_dominated: Vec<(String, f64, f64)>,
}

pub(crate) fn check_records(model: &Model, records: &[Record], what: &str) -> Result<()> {
    if records.is_empty() {
        return Err(RefineError::Invalid {
            name: what.into(),
            message: "no records given; pass at least one record".into(),
        });
    }
    for r in records {
        if r.len() < 8 {
            return Err(RefineError::Invalid {
                name: format!("{what} record '{}'", r.source()),
                message: format!("has {} samples; at least 8 are needed", r.len()),
            });
        }
        let dt = r.dt();
        if !(dt.is_finite() && dt > 0.0) {
            return Err(RefineError::Invalid {
                name: format!("{what} record '{}'", r.source()),
                message: format!("time axis gives dt = {dt}; it must increase uniformly"),
            });
        }
        for name in model.dofs.iter().chain(&model.inputs) {
            let col = r.column(name).ok_or_else(|| RefineError::MissingColumn {
                record: r.source().into(),
                column: name.clone(),
                available: r.names().join(", "),
            })?;
            if let Some(k) = col.iter().position(|v| !v.is_finite()) {
                return Err(RefineError::NonFinite {
                    record: r.source().into(),
                    column: name.clone(),
                    row: k,
                    value: col[k],
                });
            }
        }
        if let Some(k) = r.t().iter().position(|v| !v.is_finite()) {
            return Err(RefineError::NonFinite {
                record: r.source().into(),
                column: "t".into(),
                row: k,
                value: r.t()[k],
            });
        }
    }
    Ok(())
}

pub(crate) fn rms(x: &[f64]) -> f64 {
    let m = x.iter().sum::<f64>() / x.len() as f64;
    (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / x.len() as f64).sqrt()
}

/// Per-DOF RMS simulation errors of `model` on `record` (`+∞` on blow-up).
pub(crate) fn sim_errors(model: &Model, record: &Record, opts: &SimulateOptions) -> Vec<f64> {
    match simulate_model_on_record(model, record, opts) {
        Ok(tr) => model
            .dofs
            .iter()
            .enumerate()
            .map(|(i, d)| {
                record
                    .column(d)
                    .and_then(|m| rms_error(m, &tr.x[i]).ok())
                    .filter(|e| e.is_finite())
                    .unwrap_or(f64::INFINITY)
            })
            .collect(),
        Err(_) => vec![f64::INFINITY; model.dofs.len()],
    }
}

pub(crate) fn combine(errs: &[f64]) -> f64 {
    (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt()
}

/// `model` with the unknowns `coefs` of a refinement: its coefficients (DOF by DOF, term by
/// term) and then the parameters of its internal states (`None` when those are invalid).
fn with_coefs(st: &Structure, model: &Model, coefs: &[f64]) -> Option<Model> {
    let pc = st.n_coefs();
    let mut m = if st.m > 0 {
        model.with_state_laws(&st.laws(&coefs[pc..])?).ok()?
    } else {
        model.clone()
    };
    let mut j = 0;
    for d in model.dofs.clone() {
        if let Some(eq) = m.equations.iter_mut().find(|e| e.dof == d) {
            for t in &mut eq.terms {
                t.coef = coefs[j];
                t.interval = None;
                j += 1;
            }
        }
    }
    Some(m)
}

/// Each internal state of `model` along a record's measured displacements `xm` and smoothed
/// velocities `vm` (DOF order), from rest: the initial guesses of the states at segment starts.
fn state_tracks(model: &Model, r: &Record, vm: &[Vec<f64>]) -> Result<Vec<Vec<f64>>> {
    let mut cols = tfs_library::ColumnSet::new(r);
    for (d, v) in model.dofs.iter().zip(vm) {
        cols.insert(format!("{d}'"), v.clone())?;
    }
    model
        .internal_states()
        .into_iter()
        .map(|(v, law)| {
            let term = tfs_library::Term::new(vec![tfs_library::Factor::State(v, law)]);
            Ok(tfs_library::evaluate_term(&term, &cols)?)
        })
        .collect()
}

/// Dominant (non-DC) frequency of `x` in Hz, if any.
pub(crate) fn dominant_frequency(x: &[f64], dt: f64) -> Option<f64> {
    let (f, a) = tfs_signal::amplitude_spectrum(x, dt).ok()?;
    let (k, _) = a
        .iter()
        .enumerate()
        .skip(1)
        .max_by(|p, q| p.1.total_cmp(q.1))?;
    Some(f[k]).filter(|f| *f > 0.0)
}

/// Re-estimates the coefficients of `model` (same terms, zeros stay zero) to minimise the
/// free-run simulation error of the displacements on `train`.
///
/// Multiple shooting: each record is split into segments whose initial states are extra
/// unknowns, with continuity defects as weighted residuals (weights increased stage by stage,
/// [`RefineOptions::defect_weights`]); then an optional single-shooting polish. Each stage is a
/// Levenberg–Marquardt run with forward sensitivities (analytic state Jacobians of the model)
/// integrated by fixed-step RK4. The result is scored by simulating with tfs-dynamics; if it is
/// not better than the start on the training records, the start model is returned (with a
/// message saying so). A [`HistoryEntry`] `"refine (simulation error)"` is appended.
///
/// Errors: empty `train`, a record missing a DOF or input column (named), non-finite data,
/// invalid options.
pub fn refine(model: &Model, train: &[Record], opts: &RefineOptions) -> Result<Refined> {
    check_records(model, train, "train")?;
    check_options(opts)?;
    let screened: Vec<Option<(f64, f64)>> = if opts.screen_input_noise {
        train
            .par_iter()
            .map(|r| noise_screen(model, r, &opts.simulate))
            .collect()
    } else {
        vec![None; train.len()]
    };
    let noise_dominated: Vec<(String, f64, f64)> = train
        .iter()
        .zip(&screened)
        .filter_map(|(r, s)| s.map(|(sp, e)| (r.source().to_string(), sp, e)))
        .collect();
    let kept: Vec<Record> = train
        .iter()
        .zip(&screened)
        .filter(|(_, s)| s.is_none())
        .map(|(r, _)| r.clone())
        .collect();
    if kept.is_empty() {
        return Ok(start_model_kept(model, train, opts, noise_dominated));
    }
    let mut out = refine_records(model, &kept, opts)?;
    if !noise_dominated.is_empty() {
        out.message = format!(
            "left out {} of {} records whose free-run error is dominated by the noise on the measured input ({}: a fresh draw of that noise moves the start model's simulation so far that it explains at least half of the error measurement noise does not, so that error cannot rank coefficients); {}",
            noise_dominated.len(),
            train.len(),
            left_out(&noise_dominated),
            out.message
        );
        if let Some(h) = out.model.history.last_mut() {
            h.details["message"] = json!(out.message);
            h.details["noise_dominated"] = json!(
                noise_dominated
                    .iter()
                    .map(|(n, sp, e)| json!({"record": n, "spread": sp, "error": e}))
                    .collect::<Vec<_>>()
            );
        }
    }
    out.noise_dominated = noise_dominated;
    Ok(out)
}

/// The records of a screen's list in words: name, spread and error.
fn left_out(list: &[(String, f64, f64)]) -> String {
    list.iter()
        .map(|(n, sp, e)| format!("'{n}' (spread {sp:.3e} vs error {e:.3e})"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// `Some((spread, error))` (RMS over DOFs) when `record`'s free run under `model` cannot rank
/// models ([`crate::probe_free_run`]: the input's noise or the run's own divergence accounts
/// for its error), with the spread that decided; `None` otherwise, and when it cannot be judged
/// (the simulation fails, or neither spread can be measured). Held-out records are screened
/// this way: a free run there is a ruler between fits. Training records are screened by the
/// input's noise alone ([`noise_screen`]): the refinement fits short shooting segments, which a
/// run's divergence over the whole record does not reach, while the input's noise biases every
/// segment's fit.
pub(crate) fn ranking_screen(
    model: &Model,
    record: &Record,
    opts: &SimulateOptions,
) -> Option<(f64, f64)> {
    let run = simulate_model_on_record(model, record, opts).ok()?;
    let probe = crate::probe_free_run(model, record, opts, &run)?;
    if probe.error.iter().any(|e| !e.is_finite()) || !probe.dominated() {
        return None;
    }
    Some((combine(probe.spread()?), combine(&probe.error)))
}

/// `Some((spread, error))` (RMS over DOFs) when `record`'s free-run error under `model` is
/// dominated by the noise on its measured inputs ([`noise_dominated`]); `None` otherwise, and
/// when it cannot be judged (the simulation blows up, or no input has a noise-only floor).
pub(crate) fn noise_screen(
    model: &Model,
    record: &Record,
    opts: &SimulateOptions,
) -> Option<(f64, f64)> {
    let err = sim_errors(model, record, opts);
    if err.iter().any(|e| !e.is_finite()) {
        return None;
    }
    let spread = input_noise_spread(model, record, opts).ok()??;
    let noise_var = displacement_noise_var(model, record);
    noise_dominated(&spread, &err, &noise_var).then(|| (combine(&spread), combine(&err)))
}

/// The [`Refined`] of a refinement that had no usable record: the start model, with a history
/// entry saying why.
fn start_model_kept(
    model: &Model,
    train: &[Record],
    opts: &RefineOptions,
    noise_dominated: Vec<(String, f64, f64)>,
) -> Refined {
    let errs: Vec<Vec<f64>> = train
        .iter()
        .map(|r| sim_errors(model, r, &opts.simulate))
        .collect();
    let cost: f64 = train
        .iter()
        .zip(&errs)
        .map(|(r, e)| {
            model
                .dofs
                .iter()
                .zip(e)
                .map(|(d, e)| {
                    let s = r.column(d).map_or(1.0, rms);
                    let s = if s > 0.0 { s } else { 1.0 };
                    (e / s) * (e / s)
                })
                .sum::<f64>()
        })
        .sum();
    let message = format!(
        "no record left to refine on: on every training record the spread that a fresh draw of the measured input's own noise causes in the start model's simulation explains at least half of its free-run error beyond measurement noise ({}). That error cannot rank coefficients (it is at the floor the input noise sets, or the motion is sensitive to that noise, as in snap-through), and fitting it would fit the noise: the start model is kept. To refine, use records with a cleaner input or motion away from snap-through",
        left_out(&noise_dominated)
    );
    let per_record: Vec<(String, f64, f64)> = train
        .iter()
        .zip(&errs)
        .map(|(r, e)| (r.source().to_string(), combine(e), combine(e)))
        .collect();
    let mut out_model = model.clone();
    out_model.history.push(HistoryEntry {
        step: "refine (simulation error)".into(),
        added: Vec::new(),
        r_mse: Vec::new(),
        details: json!({
            "initial_cost": finite_or_null(cost),
            "final_cost": finite_or_null(cost),
            "improved": false,
            "iterations": 0,
            "noise_dominated": noise_dominated
                .iter()
                .map(|(n, sp, e)| json!({"record": n, "spread": sp, "error": e}))
                .collect::<Vec<_>>(),
            "message": message,
        }),
    });
    Refined {
        model: out_model,
        initial_cost: cost,
        final_cost: cost,
        iterations: 0,
        per_record,
        converged: false,
        message,
        noise_dominated,
    }
}

/// The training records prepared for the least-squares problem (inputs, measured
/// displacements, smoothed velocities, state tracks, residual weights) and the scales of the
/// segment unknowns: displacements, velocities, internal states.
#[allow(clippy::type_complexity)]
fn prepare(
    model: &Model,
    st: &Structure,
    train: &[Record],
    opts: &RefineOptions,
) -> Result<(Vec<Prepared>, Vec<f64>, Vec<f64>, Vec<f64>)> {
    let n = st.n;
    let mut recs = Vec::with_capacity(train.len());
    for r in train {
        let dt = r.dt();
        let channels: Vec<Vec<f64>> = model
            .inputs
            .iter()
            .map(|c| r.column(c).map(<[f64]>::to_vec).unwrap_or_default())
            .collect();
        let input = SampledInput::new(r.t()[0], dt, channels)?;
        let xm: Vec<Vec<f64>> = model
            .dofs
            .iter()
            .map(|d| r.column(d).map(<[f64]>::to_vec).unwrap_or_default())
            .collect();
        let mut vm = Vec::with_capacity(n);
        for x in &xm {
            vm.push(opts.velocity.apply(x, dt, 1)?);
        }
        let zm = state_tracks(model, r, &vm)?;
        recs.push(Prepared {
            input,
            t0: r.t()[0],
            dt,
            xm,
            vm,
            zm,
            w: vec![1.0; n],
        });
    }
    // Scales of the internal states: their RMS along the records (1 if they never move).
    let zs: Vec<f64> = (0..st.m)
        .map(|j| {
            let all: Vec<f64> = recs.iter().flat_map(|r| r.zm[j].iter().copied()).collect();
            let s = (all.iter().map(|v| v * v).sum::<f64>() / all.len().max(1) as f64).sqrt();
            if s > 0.0 && s.is_finite() { s } else { 1.0 }
        })
        .collect();
    // Weights and scales.
    let mut xs = vec![0.0; n];
    let mut vs = vec![0.0; n];
    for i in 0..n {
        let all_x: Vec<f64> = recs.iter().flat_map(|r| r.xm[i].iter().copied()).collect();
        let all_v: Vec<f64> = recs.iter().flat_map(|r| r.vm[i].iter().copied()).collect();
        let sx = rms(&all_x);
        let sv = rms(&all_v);
        if sx.is_nan() || sx <= 0.0 {
            return Err(RefineError::Invalid {
                name: format!("train column '{}'", model.dofs[i]),
                message: "displacement is constant in every record; refinement needs motion".into(),
            });
        }
        xs[i] = sx.max(all_x.iter().map(|v| v.abs()).fold(0.0, f64::max) * 1e-3);
        vs[i] = if sv > 0.0 { sv } else { sx };
        for r in &mut recs {
            let s = if opts.scale_records {
                let s = rms(&r.xm[i]);
                if s > 0.0 { s } else { sx }
            } else {
                sx
            };
            r.w[i] = 1.0 / s;
        }
    }
    Ok((recs, xs, vs, zs))
}

/// The weighted training simulation cost of `m` (`Σ_records Σ_dofs (rms_error · w)²`) and its
/// per-record, per-DOF RMS errors.
fn training_cost(
    m: &Model,
    train: &[Record],
    recs: &[Prepared],
    opts: &SimulateOptions,
) -> (f64, Vec<Vec<f64>>) {
    let mut cost = 0.0;
    let mut errs = Vec::new();
    for (r, p) in train.iter().zip(recs) {
        let e = sim_errors(m, r, opts);
        for (ei, wi) in e.iter().zip(&p.w) {
            cost += (ei * wi) * (ei * wi);
        }
        errs.push(e);
    }
    (cost, errs)
}

/// Per training record the R-MSE of errors `errs`: the squared errors summed over DOFs over
/// the summed variances (mean removed, as the ladder's other steps score) of `model`'s DOFs.
fn record_r_mse(model: &Model, train: &[Record], errs: &[Vec<f64>]) -> Vec<RecordScore> {
    train
        .iter()
        .zip(errs)
        .map(|(r, e)| {
            let num: f64 = e.iter().map(|v| v * v).sum();
            let den: f64 = model
                .dofs
                .iter()
                .filter_map(|d| r.column(d))
                .map(|c| {
                    let m = c.iter().sum::<f64>() / c.len() as f64;
                    c.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / c.len() as f64
                })
                .sum();
            RecordScore {
                record: r.source().to_string(),
                r_mse: if den > 0.0 { num / den } else { f64::NAN },
            }
        })
        .collect()
}

/// [`refine`] on the records that passed the input-noise screen: multiple-shooting stages of
/// rising continuity weight from the start model's coefficients, a single-shooting polish, and
/// the start model returned unless the training simulation cost falls.
fn refine_records(model: &Model, train: &[Record], opts: &RefineOptions) -> Result<Refined> {
    let (st, coefs0) = Structure::new(model)?;
    let n = st.n;
    let (recs, xs, vs, zs) = prepare(model, &st, train, opts)?;
    let setup = Shooting {
        st: &st,
        recs: &recs,
        pscale: parameter_scales(&st, &coefs0),
        xs,
        vs,
        zs,
        substeps: opts.substeps,
    };
    let settings = LmSettings {
        max_iterations: opts.max_iterations,
        ftol: opts.ftol,
        gtol: opts.gtol,
    };
    let (initial_cost, errs_before) = training_cost(model, train, &recs, &opts.simulate);

    let mut seg_len = default_segment_len(&recs, opts);
    if opts.segment_len.is_none() {
        seg_len = shortened_segment_len(&setup, &coefs0, seg_len);
    }
    let mut fit = Progress {
        coefs: coefs0,
        iterations: 0,
        converged: false,
        last_message: String::from("no LM stage ran"),
        stages: Vec::new(),
    };
    for &wd in &opts.defect_weights {
        seg_len = fit.shooting_stage(&setup, seg_len, wd, &settings);
    }
    if opts.polish {
        fit.polish(&setup, seg_len, &settings);
    }
    let Progress {
        coefs,
        iterations,
        mut converged,
        last_message,
        stages,
    } = fit;

    let candidate = with_coefs(&st, model, &coefs).filter(|m| m.validate().is_ok());
    let (cand_cost, errs_after) = match &candidate {
        Some(c) if coefs.iter().all(|c| c.is_finite()) => {
            training_cost(c, train, &recs, &opts.simulate)
        }
        _ => (f64::INFINITY, vec![vec![f64::INFINITY; n]; train.len()]),
    };
    let improved =
        cand_cost < initial_cost || (initial_cost.is_infinite() && cand_cost.is_finite());
    let (mut out_model, final_cost, errs_final, message) = if let (true, Some(candidate)) =
        (improved, candidate)
    {
        (
            candidate,
            cand_cost,
            errs_after,
            format!(
                "simulation cost {initial_cost:.6e} -> {cand_cost:.6e} in {iterations} LM iterations ({last_message})"
            ),
        )
    } else {
        converged = false;
        (
            model.clone(),
            initial_cost,
            errs_before.clone(),
            format!(
                "refinement did not lower the training simulation cost ({initial_cost:.6e}, candidate {cand_cost:.6e}); returning the start model"
            ),
        )
    };
    let per_record: Vec<(String, f64, f64)> = train
        .iter()
        .zip(errs_before.iter().zip(&errs_final))
        .map(|(r, (b, a))| (r.source().to_string(), combine(b), combine(a)))
        .collect();
    out_model.history.push(HistoryEntry {
        step: "refine (simulation error)".into(),
        added: Vec::new(),
        r_mse: record_r_mse(model, train, &errs_final),
        details: json!({
            "initial_cost": finite_or_null(initial_cost),
            "final_cost": finite_or_null(final_cost),
            "improved": improved,
            "iterations": iterations,
            "stages": stages,
            "per_record": per_record.iter().map(|(n, b, a)| json!({
                "record": n, "rms_before": finite_or_null(*b), "rms_after": finite_or_null(*a)
            })).collect::<Vec<_>>(),
            "message": message,
        }),
    });
    Ok(Refined {
        model: out_model,
        initial_cost,
        final_cost,
        iterations,
        per_record,
        converged,
        message,
        noise_dominated: Vec::new(),
    })
}

fn finite_or_null(v: f64) -> serde_json::Value {
    if v.is_finite() {
        json!(v)
    } else {
        serde_json::Value::Null
    }
}

fn check_options(o: &RefineOptions) -> Result<()> {
    let bad = |name: &str, message: String| {
        Err(RefineError::Invalid {
            name: name.into(),
            message,
        })
    };
    if o.substeps == 0 {
        return bad("substeps", "must be at least 1".into());
    }
    if !(o.segment_periods.is_finite() && o.segment_periods > 0.0) {
        return bad(
            "segment_periods",
            format!("{} must be positive and finite", o.segment_periods),
        );
    }
    if o.segment_len.is_some_and(|l| l < 2) {
        return bad("segment_len", "must be at least 2 samples".into());
    }
    if o.defect_weights
        .iter()
        .any(|w| !(w.is_finite() && *w > 0.0))
    {
        return bad(
            "defect_weights",
            format!(
                "{:?}: every weight must be positive and finite",
                o.defect_weights
            ),
        );
    }
    if o.defect_weights.is_empty() && !o.polish {
        return bad(
            "defect_weights",
            "is empty and polish is off, so nothing would run; give a weight or enable polish"
                .into(),
        );
    }
    if !(o.ftol >= 0.0 && o.gtol >= 0.0) {
        return bad("ftol/gtol", "must be non-negative".into());
    }
    Ok(())
}
