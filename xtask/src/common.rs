//! Shared helpers: progress bars, JSON numbers, coefficient look-ups, basin figures.

use anyhow::{Context, Result};
use serde_json::{Value, json};
use tfs::basin::{BasinMap, Label, WellInfo};
use tfs::data::Record;
use tfs::dynamics::{SimulateOptions, rmse_ratio, simulate_model_on_record};
use tfs::library::Model;
use tfs::plot::BasinMap as BasinFigure;

/// Run-size options shared by every study.
#[derive(Debug, Clone)]
pub struct Opts {
    /// Smaller grids and shorter records.
    pub quick: bool,
    /// Folder of a `cargo xtask peers` run whose table and figures the report includes.
    pub peers: std::path::PathBuf,
    /// Python virtual environment with pysindy for Table B1's PySINDy row; `None` with
    /// `--no-python` (the row then says it was not run).
    pub venv: Option<std::path::PathBuf>,
}

impl Opts {
    /// `quick` value or `full` value.
    pub fn pick<T>(&self, quick: T, full: T) -> T {
        if self.quick { quick } else { full }
    }
}

/// A progress bar of `len` steps, hidden when stderr is not a terminal.
pub fn progress(len: u64, what: &str) -> indicatif::ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new(len);
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{prefix:>10} [{bar:30}] {pos}/{len} {msg}")
    {
        pb.set_style(style.progress_chars("=> "));
    }
    pb.set_prefix(what.to_string());
    pb
}

/// Root mean square.
pub fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// A JSON number, or null when not finite.
pub fn num(v: f64) -> Value {
    if v.is_finite() { json!(v) } else { Value::Null }
}

/// `v` with 4 significant digits (or "—" when not finite).
pub fn f4(v: f64) -> String {
    if !v.is_finite() {
        return "—".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let mag = v.abs().log10().floor() as i32;
    if !(-3..5).contains(&mag) {
        return format!("{v:.3e}");
    }
    let dec = (3 - mag).max(0) as usize;
    format!("{v:.dec$}")
}

/// `v` with `dec` decimals, without the sign of a value that rounds to zero (`0.000`, never
/// `-0.000`).
pub fn fixed(v: f64, dec: usize) -> String {
    let s = format!("{v:.dec$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// `100·v` with two decimals and a percent sign.
pub fn pct(v: f64) -> String {
    if v.is_finite() {
        format!("{:.2}%", 100.0 * v)
    } else {
        "—".into()
    }
}

/// Coefficient of the term named `term` in `dof`'s equation (0 when absent).
pub fn coef(model: &Model, dof: &str, term: &str) -> f64 {
    model
        .equations
        .iter()
        .find(|e| e.dof == dof)
        .and_then(|e| e.terms.iter().find(|t| t.term.to_string() == term))
        .map_or(0.0, |t| t.coef)
}

/// Terms of `dof`'s equation as (name, coefficient).
pub fn terms(model: &Model, dof: &str) -> Vec<(String, f64)> {
    model
        .equations
        .iter()
        .find(|e| e.dof == dof)
        .map(|e| {
            e.terms
                .iter()
                .map(|t| (t.term.to_string(), t.coef))
                .collect()
        })
        .unwrap_or_default()
}

/// The model as JSON (null if it cannot be serialised).
pub fn model_json(model: &Model) -> Value {
    model
        .to_json_value()
        .map(|mut v| {
            if let Some(o) = v.as_object_mut() {
                o.remove("trace");
            }
            v
        })
        .unwrap_or(Value::Null)
}

/// Wells of a 1-DOF model's restoring force on `search`.
pub fn model_wells(model: &Model, dof: &str, search: (f64, f64)) -> Result<WellInfo> {
    let r = model
        .restoring(dof)
        .context("restoring force of the model")?;
    let r2 = r.clone();
    WellInfo::from_force(move |x| r.force(x), move |x| r2.potential(x), search, 1.0)
        .context("equilibria of the identified model")
}

/// Simulation R-MSE of `model` on `record` against the column `column` (the paper's Eq. B.2);
/// `Err` text when the simulation fails (e.g. blow-up).
pub fn sim_rmse(
    model: &Model,
    record: &Record,
    column: &str,
) -> std::result::Result<(f64, Vec<f64>), String> {
    let tr = simulate_model_on_record(model, record, &SimulateOptions::default())
        .map_err(|e| e.to_string())?;
    let meas = record
        .column(column)
        .ok_or_else(|| format!("record has no column '{column}'"))?;
    let pred = tr.x[0].clone();
    let r = rmse_ratio(meas, &pred).map_err(|e| e.to_string())?;
    Ok((r, pred))
}

/// Plot label index: stable state k → k, unsettled → n, diverged → n + 1.
fn label_index(l: Label, n: usize) -> u8 {
    match l {
        Label::State(k) => k as u8,
        Label::Unsettled => n as u8,
        Label::Diverged => n as u8 + 1,
    }
}

/// A basin-map figure with state names, disagreement marks and annotated points.
pub fn basin_figure(
    map: &BasinMap,
    title: &str,
    axes: (&str, &str),
    state_names: &[String],
    disagree: Option<&[bool]>,
    points: Vec<(f64, f64, String)>,
) -> BasinFigure {
    let n = map.states.len();
    let mut class_names: Vec<String> = state_names.to_vec();
    class_names.truncate(n);
    while class_names.len() < n {
        class_names.push(format!("S{}", class_names.len() + 1));
    }
    if map.unsettled_count > 0 || map.diverged_count > 0 {
        class_names.push("unsettled".into());
    }
    if map.diverged_count > 0 {
        class_names.push("diverged".into());
    }
    BasinFigure {
        title: title.to_string(),
        x_label: axes.0.to_string(),
        y_label: axes.1.to_string(),
        x_range: map.x_range,
        y_range: map.y_range,
        nx: map.nx,
        ny: map.ny,
        labels: map.labels.iter().map(|&l| label_index(l, n)).collect(),
        class_names,
        highlight: disagree.map(<[bool]>::to_vec),
        highlight_name: "differs from truth".into(),
        points: points
            .into_iter()
            .filter(|p| {
                p.0 >= map.x_range.0
                    && p.0 <= map.x_range.1
                    && p.1 >= map.y_range.0
                    && p.1 <= map.y_range.1
            })
            .collect(),
    }
}

/// `n` points of `f` on `[lo, hi]`.
pub fn curve(lo: f64, hi: f64, n: usize, f: impl Fn(f64) -> f64) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let x = lo + (hi - lo) * i as f64 / (n - 1) as f64;
            (x, f(x))
        })
        .collect()
}

/// Signed relative difference of `v` from `reference` in percent, e.g. `+1.23%` (`—` when
/// either is not finite or the reference is zero).
pub fn dev(v: f64, reference: f64) -> String {
    let d = 100.0 * (v - reference) / reference.abs();
    if d.is_finite() && d.abs() < 0.005 {
        "0.00%".into()
    } else if d.is_finite() {
        format!("{d:+.2}%")
    } else {
        "—".into()
    }
}

/// Relative deviation |ours − paper| / |paper|.
pub fn rel(ours: f64, paper: f64) -> f64 {
    (ours - paper).abs() / paper.abs()
}
