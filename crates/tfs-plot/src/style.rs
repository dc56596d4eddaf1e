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

/// A colour on a sequential scale (dark blue → teal → yellow, perceptually ordered like
/// viridis) for `t` in [0, 1]: series that stand for ordered values (bins of a coordinate) get
/// neighbouring colours in order instead of a repeating palette.
pub fn sequential(t: f64) -> RGBColor {
    const STOPS: [(u8, u8, u8); 5] = [
        (68, 1, 84),
        (59, 82, 139),
        (33, 145, 140),
        (94, 201, 98),
        (253, 231, 37),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (STOPS.len() - 1) as f64;
    let k = (x.floor() as usize).min(STOPS.len() - 2);
    let w = x - k as f64;
    let mix = |a: u8, b: u8| (f64::from(a) * (1.0 - w) + f64::from(b) * w).round() as u8;
    let (a, b) = (STOPS[k], STOPS[k + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// A rectangle `[u0, u1] × [v0, v1]` in axis-normalised coordinates (0..1 across the plot).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Rect {
    pub u0: f64,
    pub u1: f64,
    pub v0: f64,
    pub v1: f64,
}

impl Rect {
    fn contains(&self, u: f64, v: f64) -> bool {
        (self.u0..=self.u1).contains(&u) && (self.v0..=self.v1).contains(&v)
    }

    /// Whether the segment (a, b) passes through the rectangle (Liang–Barsky clipping).
    pub(crate) fn hit_by(&self, a: (f64, f64), b: (f64, f64)) -> bool {
        if self.contains(a.0, a.1) || self.contains(b.0, b.1) {
            return true;
        }
        let (du, dv) = (b.0 - a.0, b.1 - a.1);
        let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
        for (p, q) in [
            (-du, a.0 - self.u0),
            (du, self.u1 - a.0),
            (-dv, a.1 - self.v0),
            (dv, self.v1 - a.1),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    return false;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
                if t0 > t1 {
                    return false;
                }
            }
        }
        true
    }
}

/// The rectangle a legend of relative size `(fu, fv)` covers in corner `k` (upper right, upper
/// left, lower right, lower left).
pub(crate) fn corner_rect(k: usize, fu: f64, fv: f64) -> Rect {
    let (right, up) = (k % 2 == 0, k < 2);
    Rect {
        u0: if right { 1.0 - fu } else { 0.0 },
        u1: if right { 1.0 } else { fu },
        v0: if up { 1.0 - fv } else { 0.0 },
        v1: if up { 1.0 } else { fv },
    }
}

/// How many of the polylines' points and segments (axis-normalised) fall in each corner's
/// legend rectangle.
pub(crate) fn corner_hits(lines: &[Vec<(f64, f64)>], fu: f64, fv: f64) -> [usize; 4] {
    let mut hits = [0; 4];
    for (k, h) in hits.iter_mut().enumerate() {
        let r = corner_rect(k, fu, fv);
        for line in lines {
            match line.as_slice() {
                [p] => *h += usize::from(r.contains(p.0, p.1)),
                l => *h += l.windows(2).filter(|w| r.hit_by(w[0], w[1])).count(),
            }
        }
    }
    hits
}

/// Tick label for a value on an axis spanning `span`: a value within 1e-9 of the span from zero
/// is a zero tick that rounding moved (e.g. -2.2e-16) and is printed as `0`.
pub(crate) fn tick_on(v: f64, span: f64) -> String {
    if v.abs() <= 1e-9 * span.abs() {
        "0".into()
    } else {
        tick(v)
    }
}

/// Tick positions for a log axis on `[lo, hi]`: 1-2-5 steps per decade, every step 1…9 on a
/// range under a decade or so (at least three ticks), powers of ten (or every n-th) on a wide
/// range (at most about a dozen).
pub(crate) fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return Vec::new();
    }
    let (k0, k1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let within = |mults: &[f64], every: i32| -> Vec<f64> {
        (k0..=k1)
            .filter(|k| (k - k0) % every == 0)
            .flat_map(|k| mults.iter().map(move |m| m * 10f64.powi(k)))
            .filter(|v| *v >= lo * (1.0 - 1e-9) && *v <= hi * (1.0 + 1e-9))
            .collect()
    };
    let all: Vec<f64> = (1..10).map(f64::from).collect();
    for mults in [&[1.0, 2.0, 5.0][..], &all] {
        let t = within(mults, 1);
        if (3..=12).contains(&t.len()) {
            return t;
        }
        if t.len() > 12 {
            let ones = within(&[1.0], 1);
            if ones.len() <= 12 {
                return ones;
            }
            let every = (ones.len() as i32 + 9) / 10;
            return within(&[1.0], every);
        }
    }
    within(&all, 1)
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
    fn legend_corner_hits_count_points_and_crossing_segments() {
        // a line across the top passes through both upper corners without a point in them
        let top = vec![(0.0, 0.95), (1.0, 0.95)];
        let hits = corner_hits(&[top], 0.3, 0.2);
        assert_eq!(hits, [1, 1, 0, 0]);
        let pts: Vec<Vec<(f64, f64)>> = vec![vec![(0.9, 0.1)], vec![(0.1, 0.1)]];
        assert_eq!(corner_hits(&pts, 0.3, 0.2), [0, 0, 1, 1]);
        // a segment that misses the rectangle
        let r = corner_rect(0, 0.3, 0.2);
        assert!(!r.hit_by((0.0, 0.0), (0.5, 0.9)));
        assert!(r.hit_by((0.5, 0.85), (1.0, 0.95)));
    }

    #[test]
    fn ticks_print_zero_and_log_axes_get_enough_ticks() {
        assert_eq!(tick_on(-2.2e-16, 2.0), "0");
        assert_eq!(tick_on(1e-13, 1e-12), "1.0e-13");
        assert_eq!(tick_on(0.25, 2.0), "0.25");
        // the tutorial's ladder: 1.4e-2 .. 1.7e-1 had two ticks
        let t = log_ticks(1.0e-2, 2.3e-1);
        assert!(t.len() >= 3, "{t:?}");
        assert!(t.iter().all(|v| (1.0e-2..=2.3e-1).contains(v)));
        // under a decade: still three or more
        assert!(log_ticks(0.3, 0.8).len() >= 3);
        // twenty decades: at most about a dozen
        let w = log_ticks(1e-12, 1e8);
        assert!((3..=12).contains(&w.len()), "{w:?}");
    }

    #[test]
    fn sequential_colours_run_in_order() {
        assert_eq!(sequential(0.0), RGBColor(68, 1, 84));
        assert_eq!(sequential(1.0), RGBColor(253, 231, 37));
        let lum =
            |c: RGBColor| 0.3 * f64::from(c.0) + 0.59 * f64::from(c.1) + 0.11 * f64::from(c.2);
        let l: Vec<f64> = (0..=10)
            .map(|i| lum(sequential(f64::from(i) / 10.0)))
            .collect();
        assert!(l.windows(2).all(|w| w[1] > w[0]), "{l:?}");
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
