//! What is done with a model or the test structures beyond fitting: diagnosis, basins of
//! attraction, the minimum-energy deployment, the Kresling cell and its simulators.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde_json::{Value, json};
use tfs::basin::{BasinMap, Label, basin_sdof, med_sdof};
use tfs::origami::{KreslingCell, KreslingParams, Truth};
use tfs::sdof::{Sdof, cell_sdof, check_med_states, default_search, model_sdof};

use crate::convert::{json_to_py, records_arg, warn_all};
use crate::errors::{OrRaise, PyResult, input_error};
use crate::model::{PyModel, prepare_for_model};
use crate::options::{basin_config, clipped_policy, diagnose_options, offsets_mode};
use crate::record::PyRecord;

/// Diagnoses a model against records (as `tfs diagnose`): where it fails and which physical
/// effect is missing. Returns a dict: `verdict`, `named` (the effect the verdict names
/// first, for `model.refit(records, add=[d["named"]])`; `None` when none is missing), `r_mse`
/// (the model's mean R-MSE over the
/// records and DOFs, as `model.compare(records).r_mse` gives it; `None` when a record fails to
/// simulate), `ranked` (effects, best first: name, significance, held-out drop, p-value, share,
/// coefficient, and `r_mse_before`/`r_mse_after`: the prediction error of the model's structure
/// refitted on part of the records and judged on the rest, without and with the effect — a
/// ranking score, not the error of the model given), `residual_summary`,
/// `records`, `localisation`, `tests`, `cutoff_hz`, `offsets`; `simulation`: the decision
/// `tfs diagnose` and `refit(until_clean=…)` take (the candidates added and simulated: `before`,
/// `tried` with each one's `reason`, `chosen`, `then`, `reason`, `ranking_stands`, `why`), and
/// `equation_error_verdict` keeps the ranking's own verdict.
#[pyfunction]
#[pyo3(signature = (model, records, *, alpha=0.01, min_share=0.02, offsets="auto", clipped="error"))]
pub fn diagnose<'py>(
    py: Python<'py>,
    model: &PyModel,
    records: &Bound<'py, PyAny>,
    alpha: f64,
    min_share: f64,
    offsets: &str,
    clipped: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let (offsets, clipped) = (offsets_mode(offsets)?, clipped_policy(clipped)?);
    let opts = diagnose_options(alpha, min_share);
    let (recs, mut warnings) = records_arg(records, "records")?;
    let m = &model.inner;
    let (out, w) = py
        .detach(|| -> tfs::Result<_> {
            let (recs, report, w) = prepare_for_model(m, recs, offsets, clipped)?;
            let d = tfs::diagnose::diagnose(m, &recs, &opts)
                .map_err(|e| tfs::Error::from(e).context("diagnosing the model"))?;
            let decision = tfs::decide::decide(
                m,
                &d.ranked,
                &recs,
                &opts,
                &tfs::decide::DecideOptions::diagnose(),
            )
            .map_err(|e| e.context("simulating the candidates"))?;
            // The model's own error on the records, as `compare` scores it.
            let scores: Option<Vec<f64>> = d
                .records
                .iter()
                .map(|r| r.r_mse.clone())
                .collect::<Option<Vec<_>>>()
                .map(|v| v.concat());
            let r_mse = scores
                .filter(|v| !v.is_empty())
                .map(|v| v.iter().sum::<f64>() / v.len() as f64);
            Ok((
                json!({
                    "verdict": decision.verdict(&d.verdict),
                    "r_mse": r_mse,
                    "named": decision.chosen.clone(),
                    "equation_error_verdict": d.verdict,
                    "simulation": &decision,
                    "ranked": d.ranked,
                    "residual_summary": d.residual_summary, "records": d.records,
                    "localisation": d.localisation, "tests": d.tests,
                    "cutoff_hz": d.cutoff_hz, "offsets": report.to_json(),
                }),
                w,
            ))
        })
        .or_raise()?;
    warnings.extend(w);
    warn_all(py, &warnings)?;
    json_to_py(py, &out)
}

/// A system for basins and MED: a model (1 DOF) or a truth spec (`kresling`,
/// `kresling:surrogate`, `kresling:truss`) of the cell `params`.
fn system(
    model: Option<&PyModel>,
    truth: Option<&str>,
    params: KreslingParams,
    search: (f64, f64),
) -> tfs::Result<Sdof> {
    match (model, truth) {
        (Some(_), Some(_)) => Err(tfs::Error::Invalid(
            "give a model or truth=SPEC, not both".into(),
        )),
        (Some(m), None) => model_sdof("model", &m.inner, search),
        (None, Some(spec)) => cell_sdof(spec, params, search),
        (None, None) => Err(tfs::Error::Invalid("give a model or truth=SPEC".into())),
    }
}

/// The Kresling cell's parameters from the keywords of `tfs.kresling` (`a0`, `c0`, `gamma0`,
/// `ka`, `kb`, `mass`, `damping`), the defaults for those not given.
fn cell_params(cell: Option<&Bound<'_, PyDict>>) -> PyResult<KreslingParams> {
    let mut p = KreslingParams::default();
    let Some(cell) = cell else { return Ok(p) };
    for (k, v) in cell.iter() {
        let key: String = k.extract()?;
        let val: f64 = v
            .extract()
            .map_err(|_| input_error(format!("cell['{key}']: expected a number")))?;
        match key.as_str() {
            "a0" => p.a0 = val,
            "c0" => p.c0 = val,
            "gamma0" => p.gamma0_deg = val,
            "ka" => p.k_a = val,
            "kb" => p.k_b = val,
            "mass" => p.m = val,
            "damping" => p.c = val,
            _ => {
                return Err(input_error(format!(
                    "cell: unknown parameter '{key}'; use a0, c0, gamma0, ka, kb, mass, damping"
                )));
            }
        }
    }
    Ok(p)
}

/// Labels as an array (rows: velocity nodes, columns: displacement nodes): the stable state's
/// index (0-based, in the order of `stable`), -1 unsettled, -2 diverged.
fn label_array<'py>(py: Python<'py>, map: &BasinMap) -> Bound<'py, PyArray2<i64>> {
    let a = Array2::from_shape_fn((map.ny, map.nx), |(j, i)| match map.label(i, j) {
        Label::State(k) => k as i64,
        Label::Unsettled => -1,
        Label::Diverged => -2,
    });
    a.into_pyarray(py)
}

/// The basin-of-attraction map of a 1-DOF model (as `tfs basin`), optionally against a truth
/// (`truth=` with a model), or of the truth itself (`truth=` alone; `cell=` its geometry, the
/// keywords of `kresling`).
/// Returns a dict: `labels` (an array, rows over `v`, columns over `x`: the stable state's index,
/// -1 unsettled, -2 diverged), `x`, `v` (the grid's nodes), `stable`, `unstable`, `shares`,
/// `unsettled`, `diverged`, `seconds`, and with `truth` its `truth_labels`, `truth` summary and
/// `boa_error`.
#[pyfunction]
#[pyo3(signature = (model=None, *, grid=(200, 200), x=(0.0, 2.0), v=(-3.0, 3.0), truth=None,
    cell=None, dt=0.01, t_max=100.0, search=None))]
#[allow(clippy::too_many_arguments)]
pub fn basin<'py>(
    py: Python<'py>,
    model: Option<&PyModel>,
    grid: (usize, usize),
    x: (f64, f64),
    v: (f64, f64),
    truth: Option<String>,
    cell: Option<&Bound<'py, PyDict>>,
    dt: f64,
    t_max: f64,
    search: Option<(f64, f64)>,
) -> PyResult<Bound<'py, PyAny>> {
    let cfg = basin_config(grid, x, v, dt, t_max)?;
    let search = search.unwrap_or_else(|| default_search(x));
    let params = cell_params(cell)?;
    // Without a model the truth itself is mapped; with both, the model against the truth.
    let (map, sdof, truth_run) = py
        .detach(|| -> tfs::Result<_> {
            let sdof = match model {
                Some(_) => system(model, None, params, search)?,
                None => system(None, truth.as_deref(), params, search)?,
            };
            let map = basin_sdof(&*sdof.system, &sdof.wells, &cfg, None)
                .map_err(|e| tfs::Error::from(e).context("basin map of the model"))?;
            let truth_run = match (model, &truth) {
                (Some(_), Some(spec)) => {
                    let t = cell_sdof(spec, params, search)?;
                    let tmap = basin_sdof(&*t.system, &t.wells, &cfg, None)
                        .map_err(|e| tfs::Error::from(e).context("basin map of the truth"))?;
                    let cmp = tfs::basin::compare(&map, &tmap)?;
                    Some((t, tmap, cmp.error))
                }
                _ => None,
            };
            Ok((map, sdof, truth_run))
        })
        .or_raise()?;
    let mut out = json!({
        "x": (0..map.nx).map(|i| map.x_at(i)).collect::<Vec<_>>(),
        "v": (0..map.ny).map(|j| map.y_at(j)).collect::<Vec<_>>(),
        "stable": sdof.wells.stable(), "unstable": sdof.wells.unstable(),
        "shares": map.shares, "unsettled": map.unsettled_count,
        "diverged": map.diverged_count, "seconds": map.seconds,
    });
    if let Some((t, tmap, err)) = &truth_run {
        out["boa_error"] = json!(err);
        out["truth"] = json!({"spec": truth, "label": t.label, "stable": t.wells.stable(),
            "shares": tmap.shares, "seconds": tmap.seconds});
    }
    let d = json_to_py(py, &out)?;
    d.set_item("labels", label_array(py, &map))?;
    if let Some((_, tmap, _)) = &truth_run {
        d.set_item("truth_labels", label_array(py, tmap))?;
    }
    Ok(d)
}

/// The minimum-energy deployment of a bistable 1-DOF model or truth (as `tfs med`) from stable
/// state `from_state` to `to_state` (1-based). Returns a dict: `from`, `to` (the states), `x0`,
/// `v0`, `energy`, `kinetic`, `potential`, `quasi_static_barrier`.
#[pyfunction]
#[pyo3(signature = (model=None, *, truth=None, cell=None, grid=(200, 200), x=(0.0, 2.0),
    v=(-3.0, 3.0), from_state=1, to_state=2))]
#[allow(clippy::too_many_arguments)]
pub fn med<'py>(
    py: Python<'py>,
    model: Option<&PyModel>,
    truth: Option<String>,
    cell: Option<&Bound<'py, PyDict>>,
    grid: (usize, usize),
    x: (f64, f64),
    v: (f64, f64),
    from_state: usize,
    to_state: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let params = cell_params(cell)?;
    let cfg = basin_config(grid, x, v, 0.01, 100.0)?;
    let search = default_search(x);
    let out = py
        .detach(|| -> tfs::Result<Value> {
            let sdof = system(model, truth.as_deref(), params, search)?;
            let what = truth.clone().unwrap_or_else(|| "model".into());
            check_med_states(&sdof, &what, search, from_state, to_state)?;
            let map = basin_sdof(&*sdof.system, &sdof.wells, &cfg, None)?;
            let m = med_sdof(&*sdof.system, &sdof.wells, &map, &cfg, from_state - 1, to_state - 1)?;
            Ok(json!({
                "from": sdof.wells.stable()[from_state - 1], "to": sdof.wells.stable()[to_state - 1],
                "x0": m.x0, "v0": m.v0, "energy": m.energy, "kinetic": m.kinetic,
                "potential": m.potential, "quasi_static_barrier": m.quasi_static_barrier,
            }))
        })
        .or_raise()?;
    json_to_py(py, &out)
}

/// The Kresling truss cell of the paper's Appendix A (as `tfs kresling`): `b0`, its
/// classification, stable and unstable heights and the barrier, as a dict.
#[pyfunction]
#[pyo3(signature = (*, a0=1.6, c0=1.0, gamma0=30.0, ka=9.30, kb=9.30, mass=1.0, damping=2.0))]
#[allow(clippy::too_many_arguments)]
pub fn kresling<'py>(
    py: Python<'py>,
    a0: f64,
    c0: f64,
    gamma0: f64,
    ka: f64,
    kb: f64,
    mass: f64,
    damping: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let params = KreslingParams {
        a0,
        c0,
        gamma0_deg: gamma0,
        k_a: ka,
        k_b: kb,
        m: mass,
        c: damping,
        ..KreslingParams::default()
    };
    let summary = py
        .detach(|| -> tfs::Result<Value> {
            let cell = KreslingCell::new(params)
                .map_err(|e| tfs::Error::from(e).context("Kresling cell"))?;
            serde_json::to_value(cell.summary()).map_err(|e| tfs::Error::Invalid(e.to_string()))
        })
        .or_raise()?;
    json_to_py(py, &summary)
}

fn truth_arg(truth: Option<&str>) -> PyResult<Option<Truth>> {
    match truth {
        None => Ok(None),
        Some("surrogate") => Ok(Some(Truth::Surrogate)),
        Some("truss") => Ok(Some(Truth::Truss)),
        Some(other) => Err(input_error(format!(
            "truth '{other}': expected surrogate or truss"
        ))),
    }
}

#[allow(clippy::too_many_arguments)]
fn simulate_structure(
    py: Python<'_>,
    gamma0: Vec<f64>,
    chain: bool,
    truth: Option<&str>,
    excitations: Vec<String>,
    duration: f64,
    dt: f64,
    ramp: f64,
    snr_db: Option<f64>,
    pink: bool,
    seed: u64,
) -> PyResult<Vec<PyRecord>> {
    let req = tfs::simulate::DatasetRequest {
        gamma0,
        chain,
        truth: truth_arg(truth)?,
        excitations,
        duration,
        dt,
        ramp,
        snr_db,
        pink,
        seed,
    };
    let data = py.detach(|| tfs::simulate::dataset(&req)).or_raise()?;
    Ok(data
        .records
        .into_iter()
        .map(|inner| PyRecord { inner })
        .collect())
}

/// Simulates one Kresling cell under base excitation (as `tfs simulate kresling`): one record
/// per excitation (`sweep:F0:F1:AMP` or `sine:F:AMP`), with noise at `snr_db` on every measured
/// channel and the clean truth columns beside them.
#[pyfunction]
#[pyo3(signature = (*, gamma0=30.0, excitations=vec!["sweep:0.05:1.5:4".to_string()],
    duration=100.0, dt=0.005, ramp=2.0, snr_db=None, pink=false, seed=1, truth=None))]
#[allow(clippy::too_many_arguments)]
pub fn simulate_kresling(
    py: Python<'_>,
    gamma0: f64,
    excitations: Vec<String>,
    duration: f64,
    dt: f64,
    ramp: f64,
    snr_db: Option<f64>,
    pink: bool,
    seed: u64,
    truth: Option<&str>,
) -> PyResult<Vec<PyRecord>> {
    simulate_structure(
        py,
        vec![gamma0],
        false,
        truth,
        excitations,
        duration,
        dt,
        ramp,
        snr_db,
        pink,
        seed,
    )
}

/// Simulates a serial chain of Kresling cells (base cell first; DOFs `x1..xN`) under base
/// excitation (as `tfs simulate chain`); the truss force law by default, and by default the
/// four sweeps of `tfs simulate chain` (50 s each), which stay off the folded stop but for
/// brief touches.
#[pyfunction]
#[pyo3(signature = (*, gamma0=vec![20.0, 28.5], excitations=None,
    duration=None, dt=0.005, ramp=2.0, snr_db=None, pink=false, seed=1, truth=None))]
#[allow(clippy::too_many_arguments)]
pub fn simulate_chain(
    py: Python<'_>,
    gamma0: Vec<f64>,
    excitations: Option<Vec<String>>,
    duration: Option<f64>,
    dt: f64,
    ramp: f64,
    snr_db: Option<f64>,
    pink: bool,
    seed: u64,
    truth: Option<&str>,
) -> PyResult<Vec<PyRecord>> {
    simulate_structure(
        py,
        gamma0,
        true,
        truth,
        excitations.unwrap_or_else(|| {
            tfs::simulate::CHAIN_EXCITATIONS
                .iter()
                .map(|e| e.to_string())
                .collect()
        }),
        duration.unwrap_or(tfs::simulate::CHAIN_DURATION),
        dt,
        ramp,
        snr_db,
        pink,
        seed,
    )
}
