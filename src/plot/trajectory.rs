//! Trajectories over a floor plan, estimate coloured by its error (the
//! paper's Fig. 4), alone or in a grid of panels.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::PlotError;
use super::floor::{FloorPlan, PlanCell};
use super::output::{DrawError, Figure, write_figure};
use super::style::{self, FONT};

/// One trajectory figure: a sequence's paths over its floor plan.
///
/// All coordinates are world x, y in metres (top-down, z dropped).
#[derive(Debug, Clone, Copy)]
pub struct TrajectoryPanel<'a> {
    /// Drawn above the panel (e.g. the sequence name); empty for none.
    pub title: &'a str,
    /// Backdrop; `None` (or a plan with no cells) draws the paths alone.
    pub plan: Option<&'a FloorPlan>,
    /// Ground-truth positions in order, drawn as a thin black line; a
    /// non-finite position breaks the line.
    pub gt_xy: &'a [[f64; 2]],
    /// Estimated positions, drawn as dots coloured by `errors_m`.
    pub est_xy: &'a [[f64; 2]],
    /// APE of each estimated position, metres (same length as `est_xy`).
    pub errors_m: &'a [f64],
}

/// Writes one trajectory panel to `path` (`.png` or `.svg`); the canvas
/// follows the aspect ratio of the drawn extent (plan and paths).
///
/// Estimated positions with a non-finite coordinate or error are left out.
/// Errors if `errors_m` and `est_xy` differ in length, if no estimated
/// position remains, or if the plan is inconsistent (cell count, cell size).
pub fn trajectory_plot(path: &Path, panel: &TrajectoryPanel) -> Result<(), PlotError> {
    let figure = TrajectoryFigure::new(path, std::slice::from_ref(panel))?;
    write_figure(path, &figure).map(|_| ())
}

/// Writes several panels (one per sequence) in a grid into one file at
/// `path`: about as many columns as rows, filled row by row, each panel
/// with its own colour bar. Errors as [`trajectory_plot`] (naming the
/// panel) and if `panels` is empty.
pub fn trajectory_grid(path: &Path, panels: &[TrajectoryPanel]) -> Result<(), PlotError> {
    let figure = TrajectoryFigure::new(path, panels)?;
    write_figure(path, &figure).map(|_| ())
}

const FLOOR: RGBColor = RGBColor(222, 222, 222);
const OBSTACLE: RGBColor = RGBColor(70, 70, 70);
const START: RGBColor = RGBColor(215, 25, 28);
/// Width of the colour-bar strip right of each map, pixels.
const COLOUR_BAR_STRIP: u32 = 136;
const MARGIN: u32 = 12;
const X_LABEL_AREA: u32 = 46;
const Y_LABEL_AREA: u32 = 64;
/// Longer side of a single panel's map area, pixels.
const MAP_LONG_SIDE: f64 = 720.0;
/// Shorter side never below this (a corridor stays readable).
const MAP_SHORT_SIDE_MIN: f64 = 280.0;
/// Size of one panel in a grid, pixels.
const GRID_PANEL: (u32, u32) = (640, 560);
/// Radius of an estimate dot, pixels.
pub(crate) const DOT_RADIUS: i32 = 3;

/// A panel reduced to what is drawn.
struct Panel<'a> {
    title: &'a str,
    plan: Option<&'a FloorPlan>,
    /// Ground truth split at non-finite positions.
    gt_lines: Vec<Vec<(f64, f64)>>,
    /// (input index, x, y, error) of drawable estimates, by increasing error.
    est: Vec<(usize, f64, f64, f64)>,
    /// Top of the colour scale (largest error, or 1 m if all are zero), m.
    top: f64,
    /// World extent of everything drawn: (x_min, x_max, y_min, y_max).
    extent: (f64, f64, f64, f64),
}

impl<'a> Panel<'a> {
    fn new(path: &Path, i: usize, p: &TrajectoryPanel<'a>) -> Result<Panel<'a>, PlotError> {
        let name = if p.title.is_empty() {
            format!("panel {i}")
        } else {
            format!("panel {i} ({:?})", p.title)
        };
        if p.errors_m.len() != p.est_xy.len() {
            return Err(PlotError::LengthMismatch {
                path: path.to_path_buf(),
                what: format!("errors_m of {name}"),
                got: p.errors_m.len(),
                expected: p.est_xy.len(),
                why: "one APE per estimated position",
            });
        }
        let plan = match p.plan {
            Some(plan)
                if plan.width.checked_mul(plan.height) != Some(0) || !plan.cells.is_empty() =>
            {
                check_plan(path, &name, plan)?;
                Some(plan)
            }
            _ => None,
        };
        let mut est: Vec<(usize, f64, f64, f64)> = p
            .est_xy
            .iter()
            .zip(p.errors_m)
            .enumerate()
            .filter(|(_, (xy, e))| xy[0].is_finite() && xy[1].is_finite() && e.is_finite())
            .map(|(k, (xy, e))| (k, xy[0], xy[1], *e))
            .collect();
        if est.is_empty() {
            return Err(PlotError::Empty {
                path: path.to_path_buf(),
                what: format!(
                    "{name} has no estimated position with a finite position and error (of {})",
                    p.est_xy.len()
                ),
            });
        }
        // Large errors last, so they are drawn on top and stay visible.
        est.sort_by(|a, b| a.3.total_cmp(&b.3));
        let largest = est.iter().map(|e| e.3).fold(0.0, f64::max);
        let top = if largest > 0.0 { largest } else { 1.0 };

        let mut gt_lines = vec![Vec::new()];
        for xy in p.gt_xy {
            if xy[0].is_finite() && xy[1].is_finite() {
                if let Some(line) = gt_lines.last_mut() {
                    line.push((xy[0], xy[1]));
                }
            } else if gt_lines.last().is_some_and(|l| !l.is_empty()) {
                gt_lines.push(Vec::new());
            }
        }
        gt_lines.retain(|l| !l.is_empty());

        let mut ext = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        let mut grow = |x: f64, y: f64| {
            ext = (ext.0.min(x), ext.1.max(x), ext.2.min(y), ext.3.max(y));
        };
        est.iter().for_each(|e| grow(e.1, e.2));
        gt_lines.iter().flatten().for_each(|&(x, y)| grow(x, y));
        if let Some(plan) = plan {
            let (lo, hi) = plan.bounds();
            grow(lo[0], lo[1]);
            grow(hi[0], hi[1]);
        }
        let (x0, x1, y0, y1) = ext;
        if !((x1 - x0).is_finite() && (y1 - y0).is_finite()) {
            return Err(PlotError::Invalid {
                path: path.to_path_buf(),
                what: format!("{name} spans x {x0}..{x1} m, y {y0}..{y1} m: too large to draw"),
            });
        }
        Ok(Panel {
            title: p.title,
            plan,
            gt_lines,
            est,
            top,
            extent: ext,
        })
    }

    /// The extent with a margin, never degenerate: (x0, x1, y0, y1).
    fn padded_extent(&self) -> (f64, f64, f64, f64) {
        let (x0, x1, y0, y1) = self.extent;
        let pad = 0.04 * (x1 - x0).max(y1 - y0) + 0.25;
        (x0 - pad, x1 + pad, y0 - pad, y1 + pad)
    }
}

fn check_plan(path: &Path, name: &str, plan: &FloorPlan) -> Result<(), PlotError> {
    let expected = plan.width.checked_mul(plan.height);
    if expected != Some(plan.cells.len()) {
        return Err(PlotError::LengthMismatch {
            path: path.to_path_buf(),
            what: format!("the floor plan's cells of {name}"),
            got: plan.cells.len(),
            expected: expected.unwrap_or(usize::MAX),
            why: "width * height",
        });
    }
    if !(plan.cell.is_finite() && plan.cell > 0.0 && plan.min_xy.iter().all(|v| v.is_finite())) {
        return Err(PlotError::Invalid {
            path: path.to_path_buf(),
            what: format!(
                "the floor plan of {name} has cell {} m at corner {:?}; expected a positive cell and a finite corner",
                plan.cell, plan.min_xy
            ),
        });
    }
    Ok(())
}

/// Where a panel's map landed on the canvas: the world window and the
/// pixel rectangle it fills (pixels, canvas frame, y down).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PanelLayout {
    pub(crate) x_range: (f64, f64),
    pub(crate) y_range: (f64, f64),
    pub(crate) pixels_x: (i32, i32),
    pub(crate) pixels_y: (i32, i32),
    /// Pixel of each input estimate that was drawn (`None` if skipped).
    pub(crate) est_pixels: Vec<Option<(i32, i32)>>,
    /// Pixel rectangle of the colour bar: (x0, x1, y_top, y_bottom).
    pub(crate) colour_bar: (i32, i32, i32, i32),
}

/// Validated panels, one or a grid.
pub(crate) struct TrajectoryFigure<'a> {
    panels: Vec<Panel<'a>>,
    /// Input length of each panel's estimates (for the layout).
    est_lens: Vec<usize>,
}

impl<'a> TrajectoryFigure<'a> {
    pub(crate) fn new(
        path: &Path,
        panels: &[TrajectoryPanel<'a>],
    ) -> Result<TrajectoryFigure<'a>, PlotError> {
        if panels.is_empty() {
            return Err(PlotError::Empty {
                path: path.to_path_buf(),
                what: "no trajectory panels".into(),
            });
        }
        Ok(TrajectoryFigure {
            panels: panels
                .iter()
                .enumerate()
                .map(|(i, p)| Panel::new(path, i, p))
                .collect::<Result<_, _>>()?,
            est_lens: panels.iter().map(|p| p.est_xy.len()).collect(),
        })
    }

    fn grid(&self) -> (usize, usize) {
        let n = self.panels.len();
        let cols = (n as f64).sqrt().ceil() as usize;
        (n.div_ceil(cols), cols)
    }
}

impl Figure for TrajectoryFigure<'_> {
    type Layout = Vec<PanelLayout>;

    fn size(&self) -> (u32, u32) {
        if let [panel] = self.panels.as_slice() {
            // Fit the canvas to the extent so little of it is empty.
            let (x0, x1, y0, y1) = panel.padded_extent();
            let aspect = (x1 - x0) / (y1 - y0);
            let (w, h) = if aspect >= 1.0 {
                (
                    MAP_LONG_SIDE,
                    (MAP_LONG_SIDE / aspect).max(MAP_SHORT_SIDE_MIN),
                )
            } else {
                (
                    (MAP_LONG_SIDE * aspect).max(MAP_SHORT_SIDE_MIN),
                    MAP_LONG_SIDE,
                )
            };
            let title = if panel.title.is_empty() { 0 } else { 40 };
            (
                w as u32 + 2 * MARGIN + Y_LABEL_AREA + COLOUR_BAR_STRIP,
                h as u32 + 2 * MARGIN + X_LABEL_AREA + title,
            )
        } else {
            let (rows, cols) = self.grid();
            (GRID_PANEL.0 * cols as u32, GRID_PANEL.1 * rows as u32)
        }
    }

    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> Result<Vec<PanelLayout>, DrawError> {
        let areas = if self.panels.len() == 1 {
            vec![root.clone()]
        } else {
            root.split_evenly(self.grid())
        };
        self.panels
            .iter()
            .zip(&self.est_lens)
            .zip(areas)
            .map(|((panel, &n), area)| draw_panel(&area, panel, n))
            .collect()
    }
}

/// Draws one panel into `area`: title, map with equal scale on x and y,
/// colour bar on the right.
fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    est_len: usize,
) -> Result<PanelLayout, DrawError> {
    let area = if panel.title.is_empty() {
        area.clone()
    } else {
        area.titled(panel.title, (FONT, style::TITLE_SIZE))?
    };
    let (w, _) = area.dim_in_pixel();
    let (map_area, bar_area) = area.split_horizontally(w.saturating_sub(COLOUR_BAR_STRIP));

    // Plot pixels per metre must be equal on both axes, so measure the
    // plotting rectangle first and widen the shorter world range to fit.
    let chart_builder = || {
        let mut b = ChartBuilder::on(&map_area);
        b.margin(MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA);
        b
    };
    let (pw, ph) = chart_builder()
        .build_cartesian_2d(0f64..1f64, 0f64..1f64)?
        .plotting_area()
        .dim_in_pixel();
    let (x_range, y_range, metres_per_pixel) = equal_aspect(panel.padded_extent(), (pw, ph));

    let mut chart =
        chart_builder().build_cartesian_2d(x_range.0..x_range.1, y_range.0..y_range.1)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x [m]")
        .y_desc("y [m]")
        .axis_desc_style((FONT, style::LABEL_SIZE))
        .label_style((FONT, style::TICK_SIZE))
        .x_label_formatter(&|v| style::tick_label(*v))
        .y_label_formatter(&|v| style::tick_label(*v))
        .draw()?;

    if let Some(plan) = panel.plan {
        draw_plan(&mut chart, plan, metres_per_pixel)?;
    }

    draw_paths(&mut chart, panel)?;
    let fraction = |x: f64, y: f64| {
        (
            (x - x_range.0) / (x_range.1 - x_range.0),
            (y - y_range.0) / (y_range.1 - y_range.0),
        )
    };
    chart
        .configure_series_labels()
        .position(style::emptiest_corner(
            panel.est.iter().map(|e| fraction(e.1, e.2)),
        ))
        .label_font((FONT, style::TICK_SIZE))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(160, 160, 160))
        .legend_area_size(26)
        .draw()?;

    let (px, py) = chart.plotting_area().get_pixel_range();
    let mut est_pixels = vec![None; est_len];
    for &(k, x, y, _) in &panel.est {
        est_pixels[k] = Some(chart.backend_coord(&(x, y)));
    }
    let colour_bar = draw_colour_bar(&bar_area, panel.top)?;
    Ok(PanelLayout {
        x_range,
        y_range,
        pixels_x: (px.start, px.end),
        pixels_y: (py.start, py.end),
        est_pixels,
        colour_bar,
    })
}

/// The panel's world ranges with equal metres per pixel on both axes (the
/// shorter range widened to fit the plotting rectangle of `pw` x `ph`
/// pixels), and the metres per pixel.
fn equal_aspect(
    (x0, x1, y0, y1): (f64, f64, f64, f64),
    (pw, ph): (u32, u32),
) -> ((f64, f64), (f64, f64), f64) {
    let metres_per_pixel = ((x1 - x0) / pw.max(1) as f64).max((y1 - y0) / ph.max(1) as f64);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let half = (
        metres_per_pixel * pw as f64 / 2.0,
        metres_per_pixel * ph as f64 / 2.0,
    );
    (
        (cx - half.0, cx + half.0),
        (cy - half.1, cy + half.1),
        metres_per_pixel,
    )
}

type Chart<'a, DB> = ChartContext<
    'a,
    DB,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// The floor plan under the paths: floor and obstacle runs as rectangles.
fn draw_plan<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    plan: &FloorPlan,
    metres_per_pixel: f64,
) -> Result<(), DrawError> {
    // Cells smaller than a pixel are merged first: that bounds the
    // number of rectangles (and the SVG's size) by the pixel count.
    let factor = (metres_per_pixel / plan.cell).ceil().max(1.0) as usize;
    let plan = if factor > 1 {
        std::borrow::Cow::Owned(plan.coarsened(factor))
    } else {
        std::borrow::Cow::Borrowed(plan)
    };
    let (c, o) = (plan.cell, plan.min_xy);
    chart.draw_series(plan.runs().into_iter().map(|(row, start, end, kind)| {
        let colour = if kind == PlanCell::Obstacle {
            OBSTACLE
        } else {
            FLOOR
        };
        Rectangle::new(
            [
                (o[0] + start as f64 * c, o[1] + row as f64 * c),
                (o[0] + end as f64 * c, o[1] + (row + 1) as f64 * c),
            ],
            colour.filled(),
        )
    }))?;
    Ok(())
}

/// The ground truth as lines, the estimates as dots coloured by their
/// error, and the start, each with its legend entry.
fn draw_paths<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    panel: &Panel,
) -> Result<(), DrawError> {
    let gt_style = BLACK.stroke_width(1);
    for (k, line) in panel.gt_lines.iter().enumerate() {
        let annotation =
            chart.draw_series(std::iter::once(PathElement::new(line.clone(), gt_style)))?;
        if k == 0 {
            annotation
                .label("ground truth")
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], gt_style));
        }
    }
    let top = panel.top;
    chart
        .draw_series(panel.est.iter().map(|&(_, x, y, e)| {
            Circle::new((x, y), DOT_RADIUS, style::error_colour(e, top).filled())
        }))?
        .label("estimate (colour: APE)")
        .legend(move |(x, y)| {
            Circle::new(
                (x + 10, y),
                DOT_RADIUS + 1,
                style::error_colour(0.5, 1.0).filled(),
            )
        });
    let start = panel
        .gt_lines
        .first()
        .and_then(|l| l.first().copied())
        .or_else(|| panel.est.iter().min_by_key(|e| e.0).map(|e| (e.1, e.2)));
    if let Some(s) = start {
        chart
            .draw_series(std::iter::once(Circle::new(s, 7, START.stroke_width(2))))?
            .label("start")
            .legend(move |(x, y)| Circle::new((x + 10, y), 6, START.stroke_width(2)));
    }
    Ok(())
}

/// The error scale: viridis from 0 m (bottom) to `top` metres, ticks in
/// metres on its right. Returns its pixel rectangle (x0, x1, y_top, y_bottom).
fn draw_colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    top: f64,
) -> Result<(i32, i32, i32, i32), DrawError> {
    // Same top margin and bottom label area as the map, so the bar spans
    // the map's height.
    let mut chart = ChartBuilder::on(area)
        .margin(MARGIN)
        .margin_left(8)
        .margin_right(24)
        .x_label_area_size(X_LABEL_AREA)
        .right_y_label_area_size(76)
        .build_cartesian_2d(0f64..1f64, 0f64..top)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .set_tick_mark_size(LabelAreaPosition::Right, 5)
        .y_desc("APE [m]")
        .axis_desc_style((FONT, style::LABEL_SIZE))
        .label_style((FONT, style::TICK_SIZE))
        .y_label_formatter(&|v| style::tick_label(*v))
        .draw()?;
    const STEPS: usize = 64;
    chart.draw_series((0..STEPS).map(|k| {
        let (a, b) = (k as f64 / STEPS as f64, (k + 1) as f64 / STEPS as f64);
        Rectangle::new(
            [(0.0, a * top), (1.0, b * top)],
            style::error_colour((a + b) / 2.0 * top, top).filled(),
        )
    }))?;
    let (px, py) = chart.plotting_area().get_pixel_range();
    Ok((px.start, px.end, py.start, py.end))
}
