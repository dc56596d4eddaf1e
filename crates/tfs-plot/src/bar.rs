//! Bar charts with labelled categories (e.g. error ladders), linear or log y.

use plotters::coord::Shift;
use plotters::coord::ranged1d::{SegmentValue, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::style::{FONT, color, log_ticks, pad_log_range, tick, tick_on};
use crate::{PlotError, Result};

/// One bar per label. On a log axis, bars with non-positive or non-finite values are left out
/// (their label stays); on a linear axis non-finite values are left out.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BarChart {
    /// Title above the plot.
    pub title: String,
    /// Category-axis label.
    pub x_label: String,
    /// Value-axis label (with units).
    pub y_label: String,
    /// Category names, one per bar.
    pub labels: Vec<String>,
    /// Bar heights, one per label.
    pub values: Vec<f64>,
    /// Logarithmic value axis.
    pub log_y: bool,
    /// Palette index of the bars (default 0).
    pub color: Option<usize>,
}

impl BarChart {
    fn invalid(&self, message: String) -> PlotError {
        PlotError::Invalid {
            title: self.title.clone(),
            message,
        }
    }

    fn usable(&self, v: f64) -> bool {
        v.is_finite() && (!self.log_y || v > 0.0)
    }

    /// Checks label/value counts and that a log axis has a positive value.
    pub(crate) fn validate(&self) -> Result<()> {
        if self.labels.len() != self.values.len() {
            return Err(self.invalid(format!(
                "{} labels but {} values; pass one value per label",
                self.labels.len(),
                self.values.len()
            )));
        }
        if self.labels.is_empty() {
            return Err(self.invalid("no bars; pass at least one label and value".into()));
        }
        if !self.values.iter().any(|&v| self.usable(v)) {
            return Err(self.invalid(if self.log_y {
                "log axis but no value is positive and finite; use a linear axis".into()
            } else {
                "no value is finite".into()
            }));
        }
        Ok(())
    }

    pub(crate) fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String> {
        let vals = self.values.iter().copied().filter(|&v| self.usable(v));
        if self.log_y {
            let (lo, hi) = pad_log_range(vals).ok_or("no positive value")?;
            let yr = (lo..hi).log_scale().with_key_points(log_ticks(lo, hi));
            self.draw_with(root, yr, lo, hi - lo)
        } else {
            let (lo, hi) = vals.fold((0.0_f64, 0.0_f64), |(a, b), v| (a.min(v), b.max(v)));
            let pad = 0.08 * (hi - lo).max(f64::MIN_POSITIVE);
            let lo = if lo < 0.0 { lo - pad } else { 0.0 };
            let hi = if hi > 0.0 { hi + pad } else { 0.0 };
            let (lo, hi) = if hi > lo { (lo, hi) } else { (-1.0, 1.0) };
            let yr: RangedCoordf64 = (lo..hi).into();
            self.draw_with(root, yr, 0.0, hi - lo)
        }
    }

    fn draw_with<DB, Y>(
        &self,
        root: &DrawingArea<DB, Shift>,
        yr: Y,
        base: f64,
        span: f64,
    ) -> std::result::Result<(), String>
    where
        DB: DrawingBackend,
        Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
    {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let n = self.labels.len();
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, (FONT, 24))
            .margin(15)
            .x_label_area_size(55)
            .y_label_area_size(80)
            .build_cartesian_2d((0..n - 1).into_segmented(), yr)
            .map_err(e)?;
        let fx = |v: &SegmentValue<usize>| match v {
            SegmentValue::CenterOf(i) | SegmentValue::Exact(i) => {
                self.labels.get(*i).cloned().unwrap_or_default()
            }
            SegmentValue::Last => String::new(),
        };
        let fy = |v: &f64| tick_on(*v, span);
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 18))
            .x_labels(n)
            .x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(205, 205, 205))
            .draw()
            .map_err(e)?;
        let c = color(self.color.unwrap_or(0));
        chart
            .draw_series(
                self.values
                    .iter()
                    .enumerate()
                    .filter(|(_, v)| self.usable(**v))
                    .map(|(i, &v)| {
                        let mut r = Rectangle::new(
                            [
                                (SegmentValue::Exact(i), base),
                                (SegmentValue::Exact(i + 1), v),
                            ],
                            c.filled(),
                        );
                        r.set_margin(0, 0, 12, 12);
                        r
                    }),
            )
            .map_err(e)?;
        // value printed above each bar
        chart
            .draw_series(
                self.values
                    .iter()
                    .enumerate()
                    .filter(|(_, v)| self.usable(**v))
                    .map(|(i, &v)| {
                        EmptyElement::at((SegmentValue::CenterOf(i), v))
                            + Text::new(
                                tick(v),
                                (0, -18),
                                TextStyle::from((FONT, 14).into_font()).pos(
                                    plotters::style::text_anchor::Pos::new(
                                        plotters::style::text_anchor::HPos::Center,
                                        plotters::style::text_anchor::VPos::Top,
                                    ),
                                ),
                            )
                    }),
            )
            .map_err(e)?;
        Ok(())
    }
}
