//! Line charts: curves, dashed curves and point sets on linear or logarithmic y axes.

use plotters::coord::Shift;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::style::{FONT, color, dash, pad_log_range, pad_range, quiet_corner, tick};
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
}

impl Series {
    /// A solid line.
    pub fn line(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            name: name.into(),
            points,
            style: SeriesStyle::Line,
            color: None,
        }
    }
    /// A dashed line.
    pub fn dashed(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            name: name.into(),
            points,
            style: SeriesStyle::Dashed,
            color: None,
        }
    }
    /// A point set.
    pub fn points(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            name: name.into(),
            points,
            style: SeriesStyle::Points,
            color: None,
        }
    }
    /// Sets the palette index.
    pub fn color(mut self, idx: usize) -> Self {
        self.color = Some(idx);
        self
    }
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

    pub(crate) fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String> {
        let (x, y) = self.ranges();
        let y = y.ok_or("no positive values for the log axis")?;
        let xr: RangedCoordf64 = (x.0..x.1).into();
        if self.log_y {
            let yr: LogCoord<f64> = (y.0..y.1).log_scale().into();
            self.draw_with(root, xr, yr, x, y)
        } else {
            let yr: RangedCoordf64 = (y.0..y.1).into();
            self.draw_with(root, xr, yr, x, y)
        }
    }

    fn draw_with<DB, Y>(
        &self,
        root: &DrawingArea<DB, Shift>,
        xr: RangedCoordf64,
        yr: Y,
        x: (f64, f64),
        y: (f64, f64),
    ) -> std::result::Result<(), String>
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
        let fx = |v: &f64| tick(*v);
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 18))
            .x_label_formatter(&fx)
            .y_label_formatter(&fx)
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
        let mut any_legend = false;
        for (i, s) in self.series.iter().enumerate() {
            let c = color(s.color.unwrap_or(i));
            let keep = |&&(px, py): &&(f64, f64)| px.is_finite() && self.usable(py);
            match s.style {
                SeriesStyle::Points => {
                    let st = c.filled();
                    let ann = chart
                        .draw_series(s.points.iter().filter(keep).map(|&p| Circle::new(p, 3, st)))
                        .map_err(e)?;
                    if !s.name.is_empty() {
                        ann.label(&s.name)
                            .legend(move |(lx, ly)| Circle::new((lx + 10, ly), 4, st));
                        any_legend = true;
                    }
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
                    let mut labelled = false;
                    for seg in segs.into_iter().filter(|v| !v.is_empty()) {
                        let ann = if dashed {
                            chart
                                .draw_series(DashedLineSeries::new(seg, dl, dg, st))
                                .map_err(e)?
                        } else {
                            chart.draw_series(LineSeries::new(seg, st)).map_err(e)?
                        };
                        if !labelled && !s.name.is_empty() {
                            labelled = true;
                            any_legend = true;
                            let (dl, dg) = (dl as i32, dg as i32);
                            ann.label(&s.name).legend(move |(lx, ly)| {
                                let pts = if dashed {
                                    // a short dash–gap–dash sample
                                    vec![(lx, ly), (lx + dl.min(8), ly)]
                                } else {
                                    vec![(lx, ly), (lx + 22, ly)]
                                };
                                let tail = if dashed {
                                    vec![(lx + dl.min(8) + dg.min(5), ly), (lx + 22, ly)]
                                } else {
                                    vec![(lx + 22, ly), (lx + 22, ly)]
                                };
                                EmptyElement::at((0, 0))
                                    + PathElement::new(pts, st)
                                    + PathElement::new(tail, st)
                            });
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

        if any_legend {
            let pos = quiet_corner(
                self.all_points(),
                x,
                y,
                |v| if self.log_y { v.ln() } else { v },
            );
            chart
                .configure_series_labels()
                .position(pos)
                .margin(12)
                .label_font((FONT, 15))
                .background_style(WHITE.mix(0.92))
                .border_style(RGBColor(120, 120, 120))
                .draw()
                .map_err(e)?;
        }
        Ok(())
    }
}
