//! SVG + PNG charts for tfs: line charts (linear or log y), class maps (basins of attraction) and
//! bar charts, each described once as a [`Figure`] value and rendered to both formats.
//!
//! Architecture invariant: this crate only draws; it knows nothing about models or data files.
//! Fonts come from the `dejavu` crate (registered once as `sans-serif`), so no system libraries
//! are needed.
//!
//! ```
//! use tfs_plot::{Figure, LineChart, Series};
//! let dir = std::env::temp_dir().join(format!("tfs-plot-doc-{}", std::process::id()));
//! let pts: Vec<(f64, f64)> = (0..50).map(|i| (i as f64 * 0.1, (i as f64 * 0.1).sin())).collect();
//! let chart = LineChart::new("Displacement", "t [s]", "x [mm]")
//!     .with_series(Series::line("measured", pts.clone()))
//!     .with_series(Series::dashed("model", pts.iter().map(|&(t, x)| (t, 0.9 * x)).collect()));
//! let files = Figure::from(chart).save(&dir.join("x")).unwrap();
//! assert_eq!(files.len(), 2); // x.svg and x.png
//! assert!(files.iter().all(|f| std::fs::metadata(f).unwrap().len() > 0));
//! std::fs::remove_dir_all(&dir).ok();
//! ```

#![warn(missing_docs)]

mod bar;
mod heat;
mod line;
mod style;

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

pub use bar::BarChart;
pub use heat::BasinMap;
pub use line::{LineChart, Series, SeriesStyle};
pub use style::{PALETTE, color, sequential};

/// Errors raised while describing or saving a figure.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// A chart description is inconsistent (e.g. label count does not match the grid).
    #[error("plot '{title}': {message}")]
    Invalid {
        /// The chart title.
        title: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// The output file or its folder could not be created.
    #[error("{file}: cannot write plot: {source}; check that the folder is writable")]
    Io {
        /// The file.
        file: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The plotting backend failed while drawing or encoding.
    #[error("{file}: drawing failed: {message}")]
    Draw {
        /// The file.
        file: String,
        /// The backend message.
        message: String,
    },
    /// The embedded font could not be registered.
    #[error("font registration failed: {0}")]
    Font(String),
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, PlotError>;

/// Width and height in pixels of every saved figure (SVG and PNG).
pub const SIZE: (u32, u32) = (900, 600);

/// One chart, rendered identically to SVG and PNG by [`Figure::save`].
#[derive(Debug, Clone, PartialEq)]
pub enum Figure {
    /// Curves and point sets.
    Line(LineChart),
    /// A class map on a regular grid.
    Basin(BasinMap),
    /// Labelled bars.
    Bar(BarChart),
}

impl From<LineChart> for Figure {
    fn from(c: LineChart) -> Self {
        Figure::Line(c)
    }
}
impl From<BasinMap> for Figure {
    fn from(c: BasinMap) -> Self {
        Figure::Basin(c)
    }
}
impl From<BarChart> for Figure {
    fn from(c: BarChart) -> Self {
        Figure::Bar(c)
    }
}

/// Registers the DejaVu Sans fonts as `sans-serif` exactly once per process.
fn register_fonts() -> Result<()> {
    static DONE: std::sync::OnceLock<std::result::Result<(), String>> = std::sync::OnceLock::new();
    DONE.get_or_init(|| {
        for (style, bytes) in [
            (FontStyle::Normal, dejavu::sans::regular()),
            (FontStyle::Bold, dejavu::sans::bold()),
        ] {
            plotters::style::register_font("sans-serif", style, bytes)
                .map_err(|_| "DejaVu Sans bytes were rejected".to_string())?;
        }
        Ok(())
    })
    .clone()
    .map_err(PlotError::Font)
}

impl Figure {
    /// The chart title.
    pub fn title(&self) -> &str {
        match self {
            Figure::Line(c) => &c.title,
            Figure::Basin(c) => &c.title,
            Figure::Bar(c) => &c.title,
        }
    }

    /// Checks the description without drawing.
    pub fn validate(&self) -> Result<()> {
        match self {
            Figure::Line(c) => c.validate(),
            Figure::Basin(c) => c.validate(),
            Figure::Bar(c) => c.validate(),
        }
    }

    /// Writes `<stem>.svg` and `<stem>.png` (each [`SIZE`] pixels), creating the folder if
    /// needed, and returns both paths. The files are written atomically: a failure while
    /// drawing or writing leaves any previous figures at those paths as they were.
    pub fn save(&self, stem: &Path) -> Result<Vec<PathBuf>> {
        self.validate()?;
        register_fonts()?;
        if let Some(dir) = stem.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|source| PlotError::Io {
                file: dir.display().to_string(),
                source,
            })?;
        }
        let svg = stem.with_extension("svg");
        let png = stem.with_extension("png");
        let draw_err = |p: &Path, message: String| PlotError::Draw {
            file: p.display().to_string(),
            message,
        };
        let io_err = |p: &Path| {
            let file = p.display().to_string();
            move |source| PlotError::Io { file, source }
        };
        // Both figures are drawn into temporary files beside their targets and replace them
        // only when both are complete: a failure leaves the previous figures as they were.
        let svg_tmp = tfs_data::AtomicFile::create(&svg).map_err(io_err(&svg))?;
        let png_tmp = tfs_data::AtomicFile::create(&png).map_err(io_err(&png))?;
        {
            let root = SVGBackend::new(svg_tmp.temp_path(), SIZE).into_drawing_area();
            self.draw(&root).map_err(|m| draw_err(&svg, m))?;
            root.present().map_err(|e| draw_err(&svg, e.to_string()))?;
        }
        {
            let root = BitMapBackend::new(png_tmp.temp_path(), SIZE).into_drawing_area();
            self.draw(&root).map_err(|m| draw_err(&png, m))?;
            root.present().map_err(|e| draw_err(&png, e.to_string()))?;
        }
        for (tmp, p) in [(&svg_tmp, &svg), (&png_tmp, &png)] {
            let ok = std::fs::metadata(tmp.temp_path())
                .map(|m| m.len() > 0)
                .unwrap_or(false);
            if !ok {
                return Err(PlotError::Io {
                    file: p.display().to_string(),
                    source: std::io::Error::other("file is missing or empty after drawing"),
                });
            }
        }
        svg_tmp.commit().map_err(io_err(&svg))?;
        png_tmp.commit().map_err(io_err(&png))?;
        Ok(vec![svg, png])
    }

    /// Draws onto any plotters drawing area (the single drawing path behind both formats).
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        match self {
            Figure::Line(c) => c.draw(root),
            Figure::Basin(c) => c.draw(root),
            Figure::Bar(c) => c.draw(root),
        }
    }
}
