//! Line charts: curves, dashed curves and point sets on linear or logarithmic y axes.

use plotters::coord::Shift;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::style::{
    FONT, color, corner_hits, dash, log_ticks, pad_log_range, pad_range, sequential, tick_on,
};
use crate::{PlotError, Result};

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SeriesStyle {
    /// Solid line.
    #[default]
    Line,
    /// Dashed line (dash pattern varies with the series index).
    Dashed,
    /// Filled circles, no line.
    Points,
}

/// One named data series.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend entry (an empty name is left out of the legend).
    pub name: String,
    /// `(x, y)` points. Non-finite points are skipped (a line is broken there); on a log y axis
    /// points with `y <= 0` are skipped too.
    pub points: Vec<(f64, f64)>,
    /// Line, dashed or points.
    pub style: SeriesStyle,
    /// Palette index; `None` uses the series' position.
    pub color: Option<usize>,
    /// Position on the sequential colour scale (0..1; overrides `color`): for series that stand
    /// for ordered values, such as bins of a coordinate.
    pub shade: Option<f64>,
}

impl Series {
    /// A solid line.
    pub fn line(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            name: name.into(),
            points,
            style: SeriesStyle::Line,
            color: None,
            shade: None,
        }
    }
    /// A dashed line.
    pub fn dashed(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            name: name.into(),
            points,
            style: SeriesStyle::Dashed,
            color: None,
            shade: None,
        }
    }
    /// A point set.
    pub fn points(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            name: name.into(),
            points,
            style: SeriesStyle::Points,
            color: None,
            shade: None,
        }
    }
    /// Sets the palette index.
    pub fn color(mut self, idx: usize) -> Self {
        self.color = Some(idx);
        self
    }
    /// Colours the series by its position `t` (0..1) on the sequential scale.
    pub fn shade(mut self, t: f64) -> Self {
        self.shade = Some(t);
        self
    }
    fn rgb(&self, i: usize) -> RGBColor {
        match self.shade {
            Some(t) => sequential(t),
            None => color(self.color.unwrap_or(i)),
        }
    }
}

/// How a legend entry's sample is drawn.
#[derive(Debug, Clone, Copy)]
enum Sample {
    Line,
    Dashed(u32, u32),
    Points,
}

/// One legend entry.
#[derive(Debug, Clone)]
struct Entry {
    name: String,
    color: RGBColor,
    sample: Sample,
}

/// Legend geometry in pixels.
const ROW: i32 = 22;
const PAD: i32 = 9;
const SAMPLE_W: i32 = 26;
/// More entries than this go into a panel beside the plot instead of a box over it.
const MAX_INSIDE: usize = 6;

/// Where the legend goes.
#[derive(Debug, Clone)]
enum LegendPlace {
    None,
    Corner(usize),
    Panel,
}

/// A line chart (force–displacement curves, spectra, trajectories, time histories, …).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LineChart {
    /// Title above the plot.
    pub title: String,
    /// x-axis label (with units).
    pub x_label: String,
    /// y-axis label (with units).
    pub y_label: String,
    /// The data series, drawn in order.
    pub series: Vec<Series>,
    /// Fixed x range; `None` fits the data.
    pub x_range: Option<(f64, f64)>,
    /// Fixed y range; `None` fits the data.
    pub y_range: Option<(f64, f64)>,
    /// Logarithmic y axis (non-positive values are skipped; see [`Series::points`]).
    pub log_y: bool,
    /// Annotated points `(x, y, label)`, drawn as black rings with the label beside them.
    pub markers: Vec<(f64, f64, String)>,
    /// Vertical reference lines `(x, label)`, drawn dashed grey with the label at the top.
    pub vlines: Vec<(f64, String)>,
    /// At most this many x tick labels (e.g. few steps of a count, so that the ticks fall on
    /// whole numbers); `None` lets the axis choose.
    pub x_labels: Option<usize>,
}

impl LineChart {
    /// An empty chart with a title and axis labels.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            ..Self::default()
        }
    }
    /// Adds a series.
    pub fn with_series(mut self, s: Series) -> Self {
        self.series.push(s);
        self
    }
    /// Switches the y axis to log scale.
    pub fn log_y(mut self, on: bool) -> Self {
        self.log_y = on;
        self
    }
    /// Adds an annotated marker.
    pub fn with_marker(mut self, x: f64, y: f64, label: impl Into<String>) -> Self {
        self.markers.push((x, y, label.into()));
        self
    }
    /// Adds a vertical reference line.
    pub fn with_vline(mut self, x: f64, label: impl Into<String>) -> Self {
        self.vlines.push((x, label.into()));
        self
    }

    fn invalid(&self, message: String) -> PlotError {
        PlotError::Invalid {
            title: self.title.clone(),
            message,
        }
    }

    fn usable(&self, y: f64) -> bool {
        y.is_finite() && (!self.log_y || y > 0.0)
    }

    /// Checks ranges; on a log axis at least one positive value (or a positive y range) is needed.
    pub(crate) fn validate(&self) -> Result<()> {
        for (name, r) in [("x_range", self.x_range), ("y_range", self.y_range)] {
            if let Some((a, b)) = r {
                if !(a.is_finite() && b.is_finite() && a < b) {
                    return Err(
                        self.invalid(format!("{name} ({a}, {b}) must be finite with min < max"))
                    );
                }
            }
        }
        if self.log_y {
            if let Some((a, _)) = self.y_range {
                if a <= 0.0 {
                    return Err(self.invalid(format!(
                        "y_range starts at {a} but a log axis needs a positive minimum"
                    )));
                }
            } else if self.ranges().1.is_none() {
                return Err(self.invalid(
                    "log y axis but no series has a positive finite y value; use a linear axis"
                        .into(),
                ));
            }
        }
        Ok(())
    }

    fn all_points(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .chain(self.markers.iter().map(|m| (m.0, m.1)))
            .filter(|&(x, y)| x.is_finite() && self.usable(y))
    }

    fn ranges(&self) -> ((f64, f64), Option<(f64, f64)>) {
        let x = self.x_range.unwrap_or_else(|| {
            pad_range(
                self.all_points()
                    .map(|p| p.0)
                    .chain(self.vlines.iter().map(|v| v.0)),
            )
        });
        let y = match self.y_range {
            Some(r) => Some(r),
            None if self.log_y => pad_log_range(self.all_points().map(|p| p.1)),
            None => Some(pad_range(self.all_points().map(|p| p.1))),
        };
        (x, y)
    }

    /// The legend entries, in series order (unnamed series are left out).
    fn entries(&self) -> Vec<Entry> {
        let mut dashed_k = 0;
        let mut out = Vec::new();
        for (i, s) in self.series.iter().enumerate() {
            let sample = match s.style {
                SeriesStyle::Line => Sample::Line,
                SeriesStyle::Points => Sample::Points,
                SeriesStyle::Dashed => {
                    let (dl, dg) = dash(dashed_k);
                    dashed_k += 1;
                    Sample::Dashed(dl, dg)
                }
            };
            if !s.name.is_empty() {
                out.push(Entry {
                    name: s.name.clone(),
                    color: s.rgb(i),
                    sample,
                });
            }
        }
        out
    }

    /// The drawn polylines (and markers as single points) in axis-normalised coordinates.
    fn normalised(&self, x: (f64, f64), y: (f64, f64)) -> Vec<Vec<(f64, f64)>> {
        let ymap = |v: f64| if self.log_y { v.ln() } else { v };
        let (ly0, ly1) = (ymap(y.0), ymap(y.1));
        let norm =
            |(px, py): (f64, f64)| ((px - x.0) / (x.1 - x.0), (ymap(py) - ly0) / (ly1 - ly0));
        let mut lines = Vec::new();
        for s in &self.series {
            let mut cur: Vec<(f64, f64)> = Vec::new();
            for &(px, py) in &s.points {
                if px.is_finite() && self.usable(py) {
                    cur.push(norm((px, py)));
                    if s.style == SeriesStyle::Points {
                        lines.push(std::mem::take(&mut cur));
                    }
                } else if !cur.is_empty() {
                    lines.push(std::mem::take(&mut cur));
                }
            }
            if !cur.is_empty() {
                lines.push(cur);
            }
        }
        for m in &self.markers {
            if m.0.is_finite() && self.usable(m.1) {
                lines.push(vec![norm((m.0, m.1))]);
            }
        }
        // a reference line's label runs to the right of it near the top
        for (vx, label) in &self.vlines {
            if vx.is_finite() && !label.is_empty() {
                let u = (vx - x.0) / (x.1 - x.0);
                let w = 0.012 * label.chars().count() as f64;
                lines.push(vec![(u, 0.96), (u + w, 0.96)]);
            }
        }
        lines
    }

    /// Places the legend: in a corner no data pass through; else, when the y range is free,
    /// over headroom added on top of the data; else in the least crowded corner. Many entries
    /// go into a panel beside the plot. Returns the place and the (possibly raised) y range.
    fn place_legend(
        &self,
        entries: &[Entry],
        box_px: (i32, i32),
        plot_px: (i32, i32),
        x: (f64, f64),
        y: (f64, f64),
    ) -> (LegendPlace, (f64, f64)) {
        if entries.is_empty() {
            return (LegendPlace::None, y);
        }
        let fu = f64::from(box_px.0 + 2 * PAD) / f64::from(plot_px.0.max(1));
        let fv = f64::from(box_px.1 + 2 * PAD) / f64::from(plot_px.1.max(1));
        if entries.len() > MAX_INSIDE || fv > 0.45 || fu > 0.6 {
            return (LegendPlace::Panel, y);
        }
        let hits = corner_hits(&self.normalised(x, y), fu, fv);
        if let Some(k) = (0..4).find(|&k| hits[k] == 0) {
            return (LegendPlace::Corner(k), y);
        }
        if self.y_range.is_none() {
            // raise the top so that every datum sits below the legend's band
            let raised = if self.log_y {
                (y.0, y.0 * (y.1 / y.0).powf(1.0 / (1.0 - fv)))
            } else {
                (y.0, y.0 + (y.1 - y.0) / (1.0 - fv))
            };
            return (LegendPlace::Corner(0), raised);
        }
        let k = (0..4).min_by_key(|&k| (hits[k], k)).unwrap_or(0);
        (LegendPlace::Corner(k), y)
    }

    pub(crate) fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String> {
        let (x, y) = self.ranges();
        let y = y.ok_or("no positive values for the log axis")?;
        let entries = self.entries();
        let font = TextStyle::from((FONT, 15).into_font());
        let text_w = entries
            .iter()
            .map(|e| {
                root.estimate_text_size(&e.name, &font)
                    .map_or(0, |s| s.0 as i32)
            })
            .max()
            .unwrap_or(0);
        let box_px = (
            PAD + SAMPLE_W + 8 + text_w + PAD,
            2 * PAD + ROW * entries.len() as i32,
        );
        let (w, h) = root.dim_in_pixel();
        // the plot area left by the caption, margins and label areas (see draw_with)
        let plot_px = (w as i32 - 2 * 15 - 80, h as i32 - 2 * 15 - 34 - 55);
        let (place, y) = self.place_legend(&entries, box_px, plot_px, x, y);
        let (area, panel) = if matches!(place, LegendPlace::Panel) {
            let pw = (box_px.0 + 16).clamp(150, w as i32 / 3);
            let (a, b) = root.split_horizontally(w as i32 - pw);
            (a, Some(b))
        } else {
            (root.clone(), None)
        };
        let xr: RangedCoordf64 = (x.0..x.1).into();
        let plot_px = if self.log_y {
            let yr = (y.0..y.1).log_scale().with_key_points(log_ticks(y.0, y.1));
            self.draw_with(&area, xr, yr, x, y)?
        } else {
            let yr: RangedCoordf64 = (y.0..y.1).into();
            self.draw_with(&area, xr, yr, x, y)?
        };
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        match (place, panel) {
            (LegendPlace::Panel, Some(p)) => {
                draw_legend(&p, (4, plot_px.1.start), &entries, box_px).map_err(e)?
            }
            (LegendPlace::Corner(k), _) => {
                let (right, up) = (k % 2 == 0, k < 2);
                let lx = if right {
                    plot_px.0.end - PAD - box_px.0
                } else {
                    plot_px.0.start + PAD
                };
                let ly = if up {
                    plot_px.1.start + PAD
                } else {
                    plot_px.1.end - PAD - box_px.1
                };
                draw_legend(root, (lx, ly), &entries, box_px).map_err(e)?;
            }
            _ => {}
        }
        Ok(())
    }

    /// Draws axes, reference lines, series and markers; returns the plot area's pixel ranges
    /// (x, y) in the coordinates of `root`'s backend.
    fn draw_with<DB, Y>(
        &self,
        root: &DrawingArea<DB, Shift>,
        xr: RangedCoordf64,
        yr: Y,
        x: (f64, f64),
        y: (f64, f64),
    ) -> std::result::Result<(std::ops::Range<i32>, std::ops::Range<i32>), String>
    where
        DB: DrawingBackend,
        Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
    {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, (FONT, 24))
            .margin(15)
            .x_label_area_size(55)
            .y_label_area_size(80)
            .build_cartesian_2d(xr, yr)
            .map_err(e)?;
        let fx = |v: &f64| tick_on(*v, x.1 - x.0);
        let fy = |v: &f64| tick_on(*v, y.1 - y.0);
        chart
            .configure_mesh()
            .x_labels(self.x_labels.unwrap_or(10))
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 18))
            .x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(205, 205, 205))
            .draw()
            .map_err(e)?;

        // vertical reference lines first, under the data
        for (vx, label) in &self.vlines {
            if !vx.is_finite() {
                continue;
            }
            let st = ShapeStyle::from(&RGBColor(90, 90, 90)).stroke_width(1);
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(*vx, y.0), (*vx, y.1)],
                    6,
                    4,
                    st,
                ))
                .map_err(e)?;
            if !label.is_empty() {
                let top = if self.log_y {
                    y.1 / (y.1 / y.0).powf(0.04)
                } else {
                    y.1 - 0.04 * (y.1 - y.0)
                };
                chart
                    .draw_series(std::iter::once(Text::new(
                        format!(" {label}"),
                        (*vx, top),
                        (FONT, 14).into_font().color(&RGBColor(60, 60, 60)),
                    )))
                    .map_err(e)?;
            }
        }

        let mut dashed_k = 0;
        for (i, s) in self.series.iter().enumerate() {
            let c = s.rgb(i);
            let keep = |&&(px, py): &&(f64, f64)| px.is_finite() && self.usable(py);
            match s.style {
                SeriesStyle::Points => {
                    let st = c.filled();
                    chart
                        .draw_series(s.points.iter().filter(keep).map(|&p| Circle::new(p, 3, st)))
                        .map_err(e)?;
                }
                SeriesStyle::Line | SeriesStyle::Dashed => {
                    let st = c.stroke_width(2);
                    let (dl, dg) = dash(dashed_k);
                    let dashed = s.style == SeriesStyle::Dashed;
                    if dashed {
                        dashed_k += 1;
                    }
                    // split at skipped points so a line never bridges missing data
                    let mut segs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
                    for p in &s.points {
                        if keep(&p) {
                            if let Some(v) = segs.last_mut() {
                                v.push(*p);
                            }
                        } else if !segs.last().is_some_and(Vec::is_empty) {
                            segs.push(Vec::new());
                        }
                    }
                    for seg in segs.into_iter().filter(|v| !v.is_empty()) {
                        if dashed {
                            chart
                                .draw_series(DashedLineSeries::new(seg, dl, dg, st))
                                .map_err(e)?;
                        } else {
                            chart.draw_series(LineSeries::new(seg, st)).map_err(e)?;
                        }
                    }
                }
            }
        }

        for (mx, my, label) in &self.markers {
            if !(mx.is_finite() && self.usable(*my)) {
                continue;
            }
            let ring = ShapeStyle::from(&BLACK).stroke_width(2);
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((*mx, *my))
                        + Circle::new((0, 0), 6, ring)
                        + Text::new(label.clone(), (9, -18), (FONT, 14).into_font()),
                ))
                .map_err(e)?;
        }
        Ok(chart.plotting_area().get_pixel_range())
    }
}

/// Draws a legend box with its top-left corner at `at` (pixels of `area`).
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    at: (i32, i32),
    entries: &[Entry],
    size: (i32, i32),
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (x0, y0) = at;
    area.draw(&Rectangle::new(
        [(x0, y0), (x0 + size.0, y0 + size.1)],
        WHITE.mix(0.92).filled(),
    ))?;
    area.draw(&Rectangle::new(
        [(x0, y0), (x0 + size.0, y0 + size.1)],
        RGBColor(120, 120, 120).stroke_width(1),
    ))?;
    for (r, en) in entries.iter().enumerate() {
        let cy = y0 + PAD + ROW * r as i32 + ROW / 2;
        let (sx0, sx1) = (x0 + PAD, x0 + PAD + SAMPLE_W);
        let st = en.color.stroke_width(2);
        match en.sample {
            Sample::Line => area.draw(&PathElement::new(vec![(sx0, cy), (sx1, cy)], st))?,
            Sample::Dashed(dl, dg) => {
                let (dl, dg) = (dl.min(9) as i32, dg.min(5) as i32);
                let mut a = sx0;
                while a < sx1 {
                    let b = (a + dl).min(sx1);
                    area.draw(&PathElement::new(vec![(a, cy), (b, cy)], st))?;
                    a = b + dg;
                }
            }
            Sample::Points => {
                area.draw(&Circle::new((sx0 + SAMPLE_W / 2, cy), 4, en.color.filled()))?
            }
        }
        area.draw(&Text::new(
            en.name.clone(),
            (sx1 + 8, cy - 8),
            (FONT, 15).into_font(),
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart(series: usize, top_heavy: bool) -> LineChart {
        let mut c = LineChart::new("t", "t (s)", "x (m)");
        for k in 0..series {
            // a line over the whole width near the top (or spread over the height)
            let pts = (0..200)
                .map(|i| {
                    let t = f64::from(i) / 10.0;
                    // top-heavy: near 1 everywhere but a narrow dip to 0 mid-way, so the
                    // auto-fitted range reaches 0 and the lower corners hold no data
                    let y = if top_heavy {
                        1.0 - 0.02 * (t * 3.0).sin().abs() - (-(t - 10.0).powi(2) / 0.5).exp()
                    } else {
                        (t + k as f64).sin()
                    };
                    (t, y)
                })
                .collect();
            c = c.with_series(Series::line(format!("series {k}"), pts));
        }
        c
    }

    fn place(c: &LineChart) -> (LegendPlace, (f64, f64), (f64, f64)) {
        let (x, y) = c.ranges();
        let y = y.unwrap();
        let e = c.entries();
        let (p, ny) = c.place_legend(&e, (150, 2 * PAD + ROW * e.len() as i32), (790, 480), x, y);
        (p, y, ny)
    }

    /// A legend never covers data: a free corner is used, else headroom is added above the
    /// data; with many entries the legend goes beside the plot.
    #[test]
    fn legend_goes_where_there_are_no_data() {
        // data only near the top: a lower corner is free
        let (p, y, ny) = place(&chart(2, true));
        assert!(
            matches!(p, LegendPlace::Corner(2) | LegendPlace::Corner(3)),
            "{p:?}"
        );
        assert_eq!(y, ny);
        // sines over the whole box: no corner is free, the top is raised
        let c = chart(3, false);
        let (p, y, ny) = place(&c);
        assert!(matches!(p, LegendPlace::Corner(0)), "{p:?}");
        assert!(ny.1 > y.1 && ny.0 == y.0);
        let (x, _) = c.ranges();
        let box_h = f64::from(2 * PAD + ROW * 3 + 2 * PAD) / 480.0;
        let hits = corner_hits(&c.normalised(x, ny), 150.0 / 790.0, box_h);
        assert_eq!(hits[0], 0, "data under the raised legend: {hits:?}");
        // twelve entries: a panel
        let (p, _, _) = place(&chart(12, false));
        assert!(matches!(p, LegendPlace::Panel), "{p:?}");
    }
}
