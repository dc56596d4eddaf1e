//! Saving every chart type writes a non-empty SVG and a decodable PNG.

use std::path::{Path, PathBuf};
use tfs_plot::{BarChart, BasinMap, Figure, LineChart, PlotError, Series};

/// Where to write: `TFS_PLOT_OUT` (to look at the files) or a fresh temporary folder.
fn out_dir() -> (Option<tempfile::TempDir>, PathBuf) {
    match std::env::var_os("TFS_PLOT_OUT") {
        Some(d) => (None, PathBuf::from(d)),
        None => {
            let t = tempfile::tempdir().unwrap();
            let p = t.path().to_path_buf();
            (Some(t), p)
        }
    }
}

/// Checks SVG text and the PNG signature, IHDR size and IEND trailer.
fn check_files(files: &[PathBuf], stem: &Path) {
    assert_eq!(
        files,
        &[stem.with_extension("svg"), stem.with_extension("png")]
    );
    let svg = std::fs::read_to_string(&files[0]).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("<text"), "svg has no text");
    assert!(
        !svg.contains("NaN") && !svg.contains("inf"),
        "non-finite coordinates reached the SVG"
    );
    let png = std::fs::read(&files[1]).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert_eq!(&png[12..16], b"IHDR");
    let w = u32::from_be_bytes(png[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(png[20..24].try_into().unwrap());
    assert_eq!((w, h), tfs_plot::SIZE);
    assert_eq!(&png[png.len() - 8..png.len() - 4], b"IEND");
}

fn sine(n: usize, f: f64, a: f64) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let t = i as f64 * 0.01;
            (t, a * (f * t).sin())
        })
        .collect()
}

#[test]
fn line_chart_with_everything() {
    let (_g, dir) = out_dir();
    let mut noisy = sine(300, 6.0, 1.0);
    noisy[100].1 = f64::NAN; // skipped, line broken there
    noisy[101].0 = f64::INFINITY;
    let chart = LineChart::new("Time history", "t [s]", "x [mm]")
        .with_series(Series::line("measured", noisy))
        .with_series(Series::dashed("model", sine(300, 6.0, 0.9)))
        .with_series(Series::dashed("linear model", sine(300, 6.0, 0.7)))
        .with_series(Series::points("samples", sine(30, 6.0, 1.1)))
        .with_marker(0.26, 1.0, "peak")
        .with_vline(1.5, "t_split");
    let stem = dir.join("line");
    let files = Figure::from(chart).save(&stem).unwrap();
    check_files(&files, &stem);
}

#[test]
fn log_spectrum_filters_non_positive() {
    let (_g, dir) = out_dir();
    let spec: Vec<(f64, f64)> = (0..200)
        .map(|k| {
            (
                k as f64 * 0.5,
                if k % 17 == 0 {
                    0.0
                } else {
                    1.0 / (1.0 + (k as f64 - 40.0).powi(2))
                },
            )
        })
        .collect();
    let chart = LineChart::new("Spectrum", "f [Hz]", "|X(f)|")
        .log_y(true)
        .with_series(Series::line("|X|", spec))
        .with_series(Series::points(
            "kept bins",
            vec![(19.5, 0.5), (20.0, 1.0), (20.5, 0.5), (21.0, -1.0)],
        ));
    let stem = dir.join("spectrum");
    check_files(&Figure::from(chart).save(&stem).unwrap(), &stem);
}

#[test]
fn log_axis_without_positive_values_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let chart = LineChart::new("bad", "x", "y")
        .log_y(true)
        .with_series(Series::line(
            "neg",
            vec![(0.0, -1.0), (1.0, 0.0), (2.0, f64::NAN)],
        ));
    let err = Figure::from(chart)
        .save(&dir.path().join("bad"))
        .unwrap_err();
    assert!(matches!(err, PlotError::Invalid { .. }));
    let m = err.to_string();
    assert!(m.contains("'bad'") && m.contains("log"), "{m}");
    assert!(!dir.path().join("bad.png").exists());
}

#[test]
fn all_nan_series_does_not_panic() {
    let (_g, dir) = out_dir();
    let chart = LineChart::new("empty", "x", "y")
        .with_series(Series::line("nan", vec![(f64::NAN, 1.0), (2.0, f64::NAN)]));
    let stem = dir.join("nan");
    check_files(&Figure::from(chart).save(&stem).unwrap(), &stem);
}

#[test]
fn bad_range_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let mut chart =
        LineChart::new("r", "x", "y").with_series(Series::line("a", sine(10, 1.0, 1.0)));
    chart.x_range = Some((1.0, 1.0));
    let m = Figure::from(chart)
        .save(&dir.path().join("r"))
        .unwrap_err()
        .to_string();
    assert!(m.contains("x_range"), "{m}");
}

#[test]
fn basin_map() {
    let (_g, dir) = out_dir();
    let (nx, ny) = (120, 80);
    let (x0, x1, v0, v1) = (-2.0, 2.0, -3.0, 3.0);
    let mut labels = Vec::with_capacity(nx * ny);
    let mut highlight = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let x = x0 + (i as f64 + 0.5) * (x1 - x0) / nx as f64;
            let v = v0 + (j as f64 + 0.5) * (v1 - v0) / ny as f64;
            let s = x + 0.4 * v + 0.3 * (2.0 * v).sin();
            labels.push(if s > 0.0 { 1 } else { 0 });
            highlight.push(s.abs() < 0.08);
        }
    }
    let map = BasinMap {
        title: "Basins of attraction".into(),
        x_label: "x0 [mm]".into(),
        y_label: "v0 [mm/s]".into(),
        x_range: (x0, x1),
        y_range: (v0, v1),
        nx,
        ny,
        labels,
        class_names: vec!["state A".into(), "state B".into()],
        highlight: Some(highlight),
        highlight_name: "disagreement".into(),
        points: vec![
            (-1.0, 0.0, "A".into()),
            (1.0, 0.0, "B".into()),
            (0.0, 0.0, "MED".into()),
        ],
    };
    let stem = dir.join("basin");
    check_files(&Figure::from(map.clone()).save(&stem).unwrap(), &stem);

    let mut bad = map;
    bad.labels.pop();
    let m = Figure::from(bad)
        .save(&dir.join("bad_basin"))
        .unwrap_err()
        .to_string();
    assert!(
        m.contains("labels") && m.contains("9599") && m.contains("9600"),
        "{m}"
    );
}

#[test]
fn bar_chart_linear_and_log() {
    let (_g, dir) = out_dir();
    let bars = BarChart {
        title: "Error ladder".into(),
        x_label: "method".into(),
        y_label: "R-MSE".into(),
        labels: vec![
            "SINDy".into(),
            "T-F-S".into(),
            "+ friction".into(),
            "bad".into(),
        ],
        values: vec![0.31, 0.052, 0.004, -1.0],
        log_y: true,
        color: None,
    };
    let stem = dir.join("bars_log");
    check_files(&Figure::from(bars.clone()).save(&stem).unwrap(), &stem);
    let lin = BarChart {
        log_y: false,
        values: vec![0.31, 0.052, 0.004, 0.1],
        ..bars.clone()
    };
    let stem = dir.join("bars");
    check_files(&Figure::from(lin).save(&stem).unwrap(), &stem);
    let mut bad = bars;
    bad.values.pop();
    assert!(Figure::from(bad).save(&dir.join("bad_bars")).is_err());
}
