//! Class maps on a regular grid (basins of attraction) with a legend naming the classes.

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::style::{FONT, color, tick_on};
use crate::{PlotError, Result};

/// A class map: each cell of an `nx × ny` grid over `x_range × y_range` gets a class label.
///
/// `labels` is row-major with row 0 at the **bottom** (smallest y): cell `(i, j)` (column `i`
/// along x, row `j` along y) is `labels[j * nx + i]`. Label `k < class_names.len()` is drawn in
/// a light tint of palette colour `k`; any other label (e.g. 255 for "did not settle") in grey.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BasinMap {
    /// Title above the plot.
    pub title: String,
    /// x-axis label (with units).
    pub x_label: String,
    /// y-axis label (with units).
    pub y_label: String,
    /// x extent of the grid (cell edges).
    pub x_range: (f64, f64),
    /// y extent of the grid (cell edges).
    pub y_range: (f64, f64),
    /// Cells along x.
    pub nx: usize,
    /// Cells along y.
    pub ny: usize,
    /// Class label per cell, `nx * ny` values (see the type docs for the order).
    pub labels: Vec<u8>,
    /// Legend name of each class.
    pub class_names: Vec<String>,
    /// Cells to mark (darkened), same order as `labels`, e.g. where two maps disagree.
    pub highlight: Option<Vec<bool>>,
    /// Legend name of the marked cells (default "marked" when empty).
    pub highlight_name: String,
    /// Annotated points `(x, y, label)` such as stable states or the MED point.
    pub points: Vec<(f64, f64, String)>,
}

/// Mixes a colour with white (`w` = share of white).
/// Maximal horizontal runs of equal values in a row-major grid with `nx` columns:
/// `(row, first column, one past the last column, value)`.
fn runs<T: Copy + PartialEq>(values: &[T], nx: usize) -> Vec<(usize, usize, usize, T)> {
    let mut out = Vec::new();
    for (j, row) in values.chunks(nx.max(1)).enumerate() {
        let mut i0 = 0;
        for i in 1..=row.len() {
            if i == row.len() || row[i] != row[i0] {
                out.push((j, i0, i, row[i0]));
                i0 = i;
            }
        }
    }
    out
}

fn tint(c: RGBColor, w: f64) -> RGBColor {
    let m = |v: u8| (f64::from(v) * (1.0 - w) + 255.0 * w).round() as u8;
    RGBColor(m(c.0), m(c.1), m(c.2))
}

const OTHER: RGBColor = RGBColor(215, 215, 215);

impl BasinMap {
    fn invalid(&self, message: String) -> PlotError {
        PlotError::Invalid {
            title: self.title.clone(),
            message,
        }
    }

    fn class_color(&self, k: u8) -> RGBColor {
        if usize::from(k) < self.class_names.len() {
            tint(color(k.into()), 0.45)
        } else {
            OTHER
        }
    }

    /// Checks grid size, label counts and ranges.
    pub(crate) fn validate(&self) -> Result<()> {
        if self.nx == 0 || self.ny == 0 {
            return Err(self.invalid(format!(
                "grid is {}x{}; nx and ny must be positive",
                self.nx, self.ny
            )));
        }
        let n = self.nx * self.ny;
        if self.labels.len() != n {
            return Err(self.invalid(format!(
                "labels has {} entries but the {}x{} grid has {n} cells; pass one label per cell",
                self.labels.len(),
                self.nx,
                self.ny
            )));
        }
        if let Some(h) = &self.highlight {
            if h.len() != n {
                return Err(self.invalid(format!(
                    "highlight has {} entries but the grid has {n} cells; pass one flag per cell",
                    h.len()
                )));
            }
        }
        for (name, (a, b)) in [("x_range", self.x_range), ("y_range", self.y_range)] {
            if !(a.is_finite() && b.is_finite() && a < b) {
                return Err(
                    self.invalid(format!("{name} ({a}, {b}) must be finite with min < max"))
                );
            }
        }
        Ok(())
    }

    pub(crate) fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String> {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let (w, _) = root.dim_in_pixel();
        let (plot_area, legend_area) = root.split_horizontally(w as i32 - 190);
        let (x, y) = (self.x_range, self.y_range);
        let mut chart = ChartBuilder::on(&plot_area)
            .caption(&self.title, (FONT, 24))
            .margin(15)
            .x_label_area_size(55)
            .y_label_area_size(80)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)
            .map_err(e)?;
        let fx = |v: &f64| tick_on(*v, x.1 - x.0);
        let fy = |v: &f64| tick_on(*v, y.1 - y.0);
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 18))
            .x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .draw()
            .map_err(e)?;
        let (dx, dy) = ((x.1 - x.0) / self.nx as f64, (y.1 - y.0) / self.ny as f64);
        // One rectangle per horizontal run of equal cells (not per cell): the same picture with
        // far fewer SVG elements on large grids.
        let span = |j: usize, i0: usize, i1: usize| {
            let (cx0, cx1, cy) = (
                x.0 + i0 as f64 * dx,
                x.0 + i1 as f64 * dx,
                y.0 + j as f64 * dy,
            );
            [(cx0, cy), (cx1, cy + dy)]
        };
        let class_runs = runs(&self.labels, self.nx);
        chart
            .draw_series(class_runs.iter().map(|&(j, i0, i1, l)| {
                Rectangle::new(span(j, i0, i1), self.class_color(l).filled())
            }))
            .map_err(e)?;
        let mark = RGBColor(20, 20, 20).mix(0.6).filled();
        if let Some(h) = &self.highlight {
            chart
                .draw_series(
                    runs(h, self.nx)
                        .into_iter()
                        .filter(|r| r.3)
                        .map(|(j, i0, i1, _)| Rectangle::new(span(j, i0, i1), mark)),
                )
                .map_err(e)?;
        }
        for (px, py, label) in &self.points {
            if !(px.is_finite() && py.is_finite()) {
                continue;
            }
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((*px, *py))
                        + Circle::new((0, 0), 6, WHITE.filled())
                        + Circle::new((0, 0), 6, BLACK.stroke_width(2))
                        + Text::new(label.clone(), (9, -20), (FONT, 16).into_font()),
                ))
                .map_err(e)?;
        }

        // legend panel beside the map, so it never covers cells
        let mut entries: Vec<(String, ShapeStyle)> = self
            .class_names
            .iter()
            .enumerate()
            .map(|(k, n)| (n.clone(), self.class_color(k as u8).filled()))
            .collect();
        if self
            .labels
            .iter()
            .any(|&l| usize::from(l) >= self.class_names.len())
        {
            entries.push(("other".into(), OTHER.filled()));
        }
        if self
            .highlight
            .as_ref()
            .is_some_and(|h| h.iter().any(|&b| b))
        {
            let name = if self.highlight_name.is_empty() {
                "marked"
            } else {
                &self.highlight_name
            };
            entries.push((name.to_string(), mark));
        }
        let top = 70;
        for (r, (name, st)) in entries.iter().enumerate() {
            let yy = top + 28 * r as i32;
            legend_area
                .draw(&Rectangle::new([(8, yy), (30, yy + 18)], *st))
                .map_err(e)?;
            legend_area
                .draw(&Rectangle::new(
                    [(8, yy), (30, yy + 18)],
                    BLACK.stroke_width(1),
                ))
                .map_err(e)?;
            legend_area
                .draw(&Text::new(
                    name.clone(),
                    (38, yy + 1),
                    (FONT, 15).into_font(),
                ))
                .map_err(e)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::runs;

    #[test]
    fn runs_cover_every_cell_once_and_split_at_changes() {
        let v = [1u8, 1, 2, 2, 2, 1, 3, 3, 3];
        let r = runs(&v, 3);
        assert_eq!(
            r,
            vec![
                (0, 0, 2, 1),
                (0, 2, 3, 2),
                (1, 0, 2, 2),
                (1, 2, 3, 1),
                (2, 0, 3, 3)
            ]
        );
        let covered: usize = r.iter().map(|&(_, a, b, _)| b - a).sum();
        assert_eq!(covered, v.len());
    }
}
