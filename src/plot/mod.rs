//! Figures of the evaluation, drawn with `plotters` from plain data into PNG
//! or SVG files.
//!
//! Every function takes numbers and a path and writes one file; the format
//! follows the path's extension (`.png` or `.svg`, any case; anything else
//! is an error). Files are written to a temporary file beside the target
//! and renamed into place, so a failed plot never leaves a half-written
//! figure. Non-finite values (and, on logarithmic axes, non-positive ones)
//! are skipped, never drawn and never a panic; data with nothing left to
//! draw is an error.
//!
//! The figures:
//! - [`line_plot`]: lines with markers and a legend, one line per
//!   [`Series`]; the paper's Fig. 5 ablation (APE or FPS against the number
//!   of particles, one line per ray count). Axes may be logarithmic. When
//!   the lines share at most 12 distinct x values (a sweep), the x ticks sit
//!   exactly at those values. The legend goes into the corner with the
//!   fewest points.
//! - [`bar_plot`]: grouped bars with optional ± one standard deviation
//!   error bars; the sampling-strategy ablation (APE per strategy, one group
//!   per ray count). The x axis is categorical (the group labels).
//! - [`trajectory_plot`]: the paper's Fig. 4. Top-down view (world x right,
//!   world y up, metres, equal scale on both axes) of a [`FloorPlan`]
//!   (light grey floor, dark grey obstacles, white unknown), the
//!   ground-truth path as a thin black line, the estimated positions as
//!   dots coloured by their APE with the viridis colour map (0 m dark
//!   purple, the largest error yellow; dots drawn in increasing error so
//!   the large ones stay visible), a colour bar in metres on the right and
//!   a hollow circle at the start of the ground truth.
//! - [`trajectory_grid`]: several such panels (one per sequence) in a grid
//!   in one file, each with its own colour bar.
//!
//! Text in PNGs is rasterised from DejaVu Sans embedded in the crate
//! (`assets/fonts/`), so no installed font or fontconfig is needed; SVGs
//! name the `sans-serif` family and leave the font to the viewer.

mod axis;
mod bar;
mod floor;
mod line;
mod output;
mod style;
mod trajectory;

#[cfg(test)]
mod tests;

use std::path::PathBuf;

pub use bar::{BarGroup, bar_plot};
pub use floor::{FloorPlan, PlanCell};
pub use line::{Series, line_plot};
pub use output::{FIGURE_MARK, is_omcl_figure, write_picture_png};
pub use trajectory::{TrajectoryPanel, trajectory_grid, trajectory_plot};

/// Titles and axis labels of a line or bar plot.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Axes {
    /// Drawn above the plot; empty for none.
    pub title: String,
    /// Label under the x axis, with its unit, e.g. `"particles"`.
    pub x_label: String,
    /// Label beside the y axis, with its unit, e.g. `"APE RMSE [m]"`.
    pub y_label: String,
    /// Logarithmic x axis (line plots only; bar plots have a categorical x).
    pub log_x: bool,
    /// Logarithmic y axis; bars then rise from the bottom of the axis.
    pub log_y: bool,
}

/// Why a figure was not written; each names the output file.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("{path}: unknown figure format {extension:?}: expected a path ending in .png or .svg")]
    UnknownFormat { path: PathBuf, extension: String },
    #[error("{path}: nothing to plot: {what}")]
    Empty { path: PathBuf, what: String },
    #[error("{path}: {what} has {got} entries but {expected} were expected ({why})")]
    LengthMismatch {
        path: PathBuf,
        what: String,
        got: usize,
        expected: usize,
        why: &'static str,
    },
    #[error("{path}: invalid input: {what}")]
    Invalid { path: PathBuf, what: String },
    #[error("{path}: drawing failed: {message}")]
    Draw { path: PathBuf, message: String },
    #[error("{path}: encoding the PNG failed: {source}")]
    Png {
        path: PathBuf,
        source: png::EncodingError,
    },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}
