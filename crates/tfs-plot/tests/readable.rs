//! What can be checked of a figure's legibility from its SVG: the axis labels (with their units)
//! are drawn, no tick label shows a rounding residue such as `-2.2e-16` where the axis has a
//! zero, and a log axis over one decade or so still gets several labelled ticks.

use std::path::Path;
use tfs_plot::{BarChart, BasinMap, Figure, LineChart, Series};

/// The contents of every `<text>` element of an SVG file, without the line breaks the SVG
/// writer puts around them.
fn texts(svg: &Path) -> Vec<String> {
    let s = std::fs::read_to_string(svg).unwrap();
    let mut out = Vec::new();
    let mut rest = s.as_str();
    while let Some(i) = rest.find("<text") {
        rest = &rest[i..];
        let Some(open) = rest.find('>') else { break };
        let Some(close) = rest.find("</text>") else {
            break;
        };
        out.push(
            rest[open + 1..close]
                .replace("&lt;", "<")
                .replace("&gt;", ">")
                .replace("&amp;", "&")
                .trim()
                .to_string(),
        );
        rest = &rest[close..];
    }
    out
}

/// Tick labels: the texts that parse as numbers.
fn numbers(texts: &[String]) -> Vec<f64> {
    texts
        .iter()
        .filter_map(|t| t.trim().parse::<f64>().ok())
        .collect()
}

fn save(fig: impl Into<Figure>, dir: &Path, name: &str) -> Vec<String> {
    let stem = dir.join(name);
    fig.into().save(&stem).unwrap();
    texts(&stem.with_extension("svg"))
}

/// No tick label of magnitude below 1e-12 when the axis spans much more than that.
fn assert_no_residue(t: &[String], what: &str) {
    for v in numbers(t) {
        assert!(
            v == 0.0 || v.abs() >= 1e-12,
            "{what}: tick label {v} is a rounding residue of zero; labels {t:?}"
        );
    }
}

#[test]
fn every_figure_type_shows_its_axis_labels_and_clean_ticks() {
    let dir = tempfile::tempdir().unwrap();
    // Ranges whose tick arithmetic passes near zero (start + k·step), on both axes.
    for (k, (lo, hi)) in [
        (-0.7, 0.3),
        (-0.3, 0.5),
        (-1.1, 1.3),
        (-2.2, 0.6),
        (-0.15, 0.05),
    ]
    .into_iter()
    .enumerate()
    {
        let pts: Vec<(f64, f64)> = (0..=100)
            .map(|i| {
                let u = lo + (hi - lo) * f64::from(i) / 100.0;
                (u, 0.5 * u - 0.1 * u * u * u)
            })
            .collect();
        let chart = LineChart::new("force curve", "h (c0)", "F (k·c0)")
            .with_series(Series::line("F(h)", pts));
        let t = save(chart, dir.path(), &format!("line{k}"));
        assert!(t.iter().any(|s| s == "h (c0)") && t.iter().any(|s| s == "F (k·c0)"));
        assert!(
            numbers(&t).contains(&0.0),
            "no zero tick on ({lo}, {hi}): {t:?}"
        );
        assert_no_residue(&t, &format!("line chart on ({lo}, {hi})"));

        let (nx, ny) = (20, 10);
        let map = BasinMap {
            title: "basins".into(),
            x_label: "x0 (mm)".into(),
            y_label: "v0 (mm/s)".into(),
            x_range: (lo, hi),
            y_range: (lo, hi),
            nx,
            ny,
            labels: (0..nx * ny).map(|i| u8::from(i % nx > nx / 2)).collect(),
            class_names: vec!["S1 (x = 0)".into(), "S2 (x = 1)".into()],
            ..BasinMap::default()
        };
        let t = save(map, dir.path(), &format!("basin{k}"));
        assert!(t.iter().any(|s| s == "x0 (mm)") && t.iter().any(|s| s == "v0 (mm/s)"));
        assert_no_residue(&t, &format!("basin map on ({lo}, {hi})"));
    }
    // A tiny range is drawn with tiny ticks: they are the data, not residue.
    let tiny: Vec<(f64, f64)> = (0..10)
        .map(|i| (f64::from(i), 1e-14 * f64::from(i)))
        .collect();
    let t = save(
        LineChart::new("tiny", "t (s)", "x (m)").with_series(Series::line("x", tiny)),
        dir.path(),
        "tiny",
    );
    assert!(
        numbers(&t).iter().any(|v| *v != 0.0 && v.abs() < 1e-12),
        "{t:?}"
    );
}

#[test]
fn log_axes_over_about_a_decade_get_several_ticks() {
    let dir = tempfile::tempdir().unwrap();
    // the tutorial's error ladder: 1.73e-1 down to 1.42e-2
    let bars = BarChart {
        title: "Error ladder".into(),
        x_label: "step".into(),
        y_label: "R-MSE (dimensionless, log scale)".into(),
        labels: vec!["start".into(), "add dry-friction".into()],
        values: vec![0.17279, 0.014172],
        log_y: true,
        color: None,
    };
    let t = save(bars, dir.path(), "ladder");
    assert!(t.iter().any(|s| s == "R-MSE (dimensionless, log scale)"));
    // tick labels (the values printed above the bars are numbers too: count those apart)
    let ticks: Vec<f64> = numbers(&t)
        .into_iter()
        .filter(|v| (*v - 0.17279).abs() > 1e-9 && (*v - 0.014172).abs() > 1e-9)
        .collect();
    assert!(ticks.len() >= 3, "log axis ticks {ticks:?} of {t:?}");
    let spec: Vec<(f64, f64)> = (1..200)
        .map(|k| (f64::from(k) * 0.1, 0.3 + 0.2 * (f64::from(k) * 0.05).sin()))
        .collect();
    let chart = LineChart::new("spectrum", "f (Hz)", "amplitude (mm)")
        .log_y(true)
        .with_series(Series::line("measured", spec));
    let t = save(chart, dir.path(), "spectrum");
    let ticks = numbers(&t);
    assert!(
        ticks.iter().filter(|v| **v > 0.0 && **v < 1.0).count() >= 3,
        "{t:?}"
    );
}
