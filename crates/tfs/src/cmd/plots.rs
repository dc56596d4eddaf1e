//! Figures the CLI writes (SVG and PNG through tfs-plot).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use tfs::basin::BasinMap;
use tfs::data::Record;
use tfs::library::Model;
use tfs::plot::{BasinMap as BasinFigure, Figure};
use tfs::plot::{LineChart, Series};

use super::basin::label_index;

/// Draws a basin map (stable states marked, disagreeing cells darkened when given) to
/// `<out without extension>.svg` and `.png`; returns the files written.
pub fn basin_figure(
    map: &BasinMap,
    title: &str,
    disagree: Option<&[bool]>,
    out: &Path,
) -> Result<Vec<String>> {
    let names: Vec<String> = map
        .states
        .iter()
        .enumerate()
        .map(|(k, s)| format!("S{} (x = {:.3})", k + 1, s[0]))
        .collect();
    // A model carries the units of the record it was fitted on: displacement as recorded,
    // velocity in that unit per second.
    let axes = (
        "initial displacement x0 (record's length unit)",
        "initial velocity v0 (record's length unit / s)",
    );
    basin_figure_on(map, title, axes, &names, disagree, out)
}

/// [`basin_figure`] with the axes' labels and the states' names given (a chain's slice, where
/// the axes are a shift Δx and a velocity v0 and a state is a vector); a 1-DOF state is marked
/// on the axis at its displacement.
pub fn basin_figure_on(
    map: &BasinMap,
    title: &str,
    axes: (&str, &str),
    state_names: &[String],
    disagree: Option<&[bool]>,
    out: &Path,
) -> Result<Vec<String>> {
    let n = map.states.len();
    let mut class_names: Vec<String> = state_names.to_vec();
    if map.unsettled_count > 0 {
        class_names.push("unsettled".into());
    }
    if map.diverged_count > 0 {
        while class_names.len() < n + 1 {
            class_names.push("unsettled".into());
        }
        class_names.push("diverged".into());
    }
    let labels = map.labels.iter().map(|&l| label_index(l, n)).collect();
    let points = if map.states.iter().all(|s| s.len() == 1) {
        map.states
            .iter()
            .enumerate()
            .filter(|(_, s)| s[0] >= map.x_range.0 && s[0] <= map.x_range.1)
            .map(|(k, s)| (s[0], 0.0, format!("S{}", k + 1)))
            .collect()
    } else {
        Vec::new()
    };
    let fig = BasinFigure {
        title: title.to_string(),
        x_label: axes.0.into(),
        y_label: axes.1.into(),
        x_range: map.x_range,
        y_range: map.y_range,
        nx: map.nx,
        ny: map.ny,
        labels,
        class_names,
        highlight: disagree.map(<[bool]>::to_vec),
        highlight_name: "differs from truth".into(),
        points,
    };
    let stem: PathBuf = out.with_extension("");
    let files = Figure::from(fig).save(&stem)?;
    Ok(files.iter().map(|p| p.display().to_string()).collect())
}

/// Draws the force–displacement loop of every DOF of the last of `models` on `record` (the
/// restoring force measured from the record, and each model's; see
/// `tfs::diagnose::restoring_loop`) to `<dir>/loop-<dof>.svg` and `.png`; returns the files.
pub fn loop_figures(dir: &Path, models: &[(&str, &Model)], record: &Record) -> Result<Vec<String>> {
    let Some((_, last)) = models.last() else {
        return Ok(Vec::new());
    };
    let mut files = Vec::new();
    for dof in &last.dofs {
        let l = tfs::diagnose::restoring_loop(models, record, dof, &Default::default())
            .with_context(|| format!("{}: restoring-force loop of '{dof}'", record.source()))?;
        let pts =
            |f: &[f64]| -> Vec<(f64, f64)> { l.x.iter().copied().zip(f.iter().copied()).collect() };
        let mut chart = LineChart::new(
            format!(
                "{}: restoring force against {dof}, t = {:.2}..{:.2} s",
                l.record, l.window.0, l.window.1
            ),
            format!("{dof} (units of the record's {dof})"),
            l.force_label.clone(),
        )
        .with_series(Series::line("measured (from the record)", pts(&l.measured)));
        for (label, f) in &l.models {
            chart = chart.with_series(Series::dashed(label.clone(), pts(f)));
        }
        let saved = Figure::from(chart).save(&dir.join(format!("loop-{dof}")))?;
        files.extend(saved.iter().map(|p| p.display().to_string()));
    }
    Ok(files)
}
