//! Shared styling: the colour palette, dash patterns, fonts and axis-range helpers.

use plotters::prelude::*;

/// Ten distinguishable colours (the Tableau 10 set), as RGB triples.
pub const PALETTE: [(u8, u8, u8); 10] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
];

/// Palette colour `i` (wrapping around).
pub fn color(i: usize) -> RGBColor {
    let (r, g, b) = PALETTE[i % PALETTE.len()];
    RGBColor(r, g, b)
}

/// Dash length and gap (pixels) for the `k`-th dashed series: patterns cycle so that two dashed
/// series in the same colour remain distinguishable.
pub(crate) fn dash(k: usize) -> (u32, u32) {
    [(10, 6), (4, 4), (16, 5), (7, 3)][k % 4]
}

pub(crate) const FONT: &str = "sans-serif";

/// Axis range covering `vals` with 5 % padding; a degenerate or empty set gets a unit-wide range.
pub(crate) fn pad_range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = vals
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo <= 1e-12 * lo.abs().max(hi.abs()) {
        let w = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        return (lo - w, hi + w);
    }
    let p = 0.05 * (hi - lo);
    (lo - p, hi + p)
}

/// Log-axis range covering the positive finite `vals` with a 10 % multiplicative pad; `None`
/// when there is no positive value.
pub(crate) fn pad_log_range(vals: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = vals
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return None;
    }
    if hi / lo < 1.0 + 1e-9 {
        return Some((lo / 2.0, hi * 2.0));
    }
    Some((lo / 1.3, hi * 1.3))
}

/// The legend corner holding the fewest data points (ties prefer upper right, then upper
/// left, lower right, lower left). `ymap` maps y to its on-axis position (log10 for log axes).
pub(crate) fn quiet_corner(
    pts: impl Iterator<Item = (f64, f64)>,
    x: (f64, f64),
    y: (f64, f64),
    ymap: impl Fn(f64) -> f64,
) -> SeriesLabelPosition {
    let (y0, y1) = (ymap(y.0), ymap(y.1));
    // count points in the outer 45 % of each corner (the legend box region)
    let mut counts = [0usize; 4];
    for (px, py) in pts {
        let u = (px - x.0) / (x.1 - x.0);
        let v = (ymap(py) - y0) / (y1 - y0);
        if !(u.is_finite() && v.is_finite()) {
            continue;
        }
        let right = u > 0.55;
        let left = u < 0.45;
        let up = v > 0.55;
        let down = v < 0.45;
        if up && right {
            counts[0] += 1;
        }
        if up && left {
            counts[1] += 1;
        }
        if down && right {
            counts[2] += 1;
        }
        if down && left {
            counts[3] += 1;
        }
    }
    let best = (0..4).min_by_key(|&i| (counts[i], i)).unwrap_or(0);
    [
        SeriesLabelPosition::UpperRight,
        SeriesLabelPosition::UpperLeft,
        SeriesLabelPosition::LowerRight,
        SeriesLabelPosition::LowerLeft,
    ][best]
        .clone()
}

/// Tick label for a value: plain for moderate magnitudes, scientific otherwise.
pub(crate) fn tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (1e-3..1e4).contains(&a) {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.1e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legend_avoids_crowded_corner() {
        // points only in the upper right: any other corner is chosen, upper left first
        let pts = (0..50).map(|i| (0.8 + 0.004 * i as f64, 0.9));
        let pos = quiet_corner(pts, (0.0, 1.0), (0.0, 1.0), |v| v);
        assert!(matches!(pos, SeriesLabelPosition::UpperLeft));
        let pts = [(0.9, 0.9), (0.1, 0.9), (0.9, 0.1)].into_iter();
        let pos = quiet_corner(pts, (0.0, 1.0), (0.0, 1.0), |v| v);
        assert!(matches!(pos, SeriesLabelPosition::LowerLeft));
    }

    #[test]
    fn ranges_pad_and_handle_degenerate_input() {
        assert_eq!(pad_range([0.0, 10.0].into_iter()), (-0.5, 10.5));
        assert_eq!(pad_range([f64::NAN].into_iter()), (0.0, 1.0));
        assert_eq!(pad_range([2.0, 2.0].into_iter()), (1.8, 2.2));
        assert_eq!(pad_log_range([-1.0, 0.0].into_iter()), None);
        let (lo, hi) = pad_log_range([1e-3, -5.0, 10.0].into_iter()).unwrap();
        assert!(lo < 1e-3 && lo > 0.0 && hi > 10.0);
    }

    #[test]
    fn colours_are_distinct() {
        for i in 0..PALETTE.len() {
            for j in 0..i {
                assert_ne!(color(i), color(j));
            }
        }
        assert_eq!(color(3), color(13));
    }
}
