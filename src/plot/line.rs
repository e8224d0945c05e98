//! Line plots with markers and a legend (the particle/ray ablation).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::axis::Axis;
use super::output::{DrawError, Figure, write_figure};
use super::style::{self, FONT};
use super::{Axes, PlotError};

/// One line of a line plot.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Series {
    /// Legend entry; empty for none.
    pub label: String,
    /// (x, y) points in drawing order, in the units of the axis labels.
    pub points: Vec<(f64, f64)>,
}

/// Writes a line plot of `series` (one colour and marker each, with a
/// legend) to `path` (`.png` or `.svg`).
///
/// Points with a non-finite coordinate, or a non-positive one on a log
/// axis, are left out. Errors if no point remains.
pub fn line_plot(path: &Path, axes: &Axes, series: &[Series]) -> Result<(), PlotError> {
    let figure = LineFigure::new(path, axes, series)?;
    write_figure(path, &figure).map(|_| ())
}

/// Ticks go exactly at the data's x values when there are at most this
/// many (a parameter sweep), else automatic.
const MAX_DATA_TICKS: usize = 12;

/// A validated line plot: only drawable points, non-empty.
pub(crate) struct LineFigure<'a> {
    axes: &'a Axes,
    lines: Vec<(&'a str, Vec<(f64, f64)>)>,
    x: Axis,
    y: Axis,
}

impl<'a> LineFigure<'a> {
    pub(crate) fn new(
        path: &Path,
        axes: &'a Axes,
        series: &'a [Series],
    ) -> Result<LineFigure<'a>, PlotError> {
        let lines: Vec<(&str, Vec<(f64, f64)>)> = series
            .iter()
            .map(|s| {
                let points = s
                    .points
                    .iter()
                    .copied()
                    .filter(|&(x, y)| {
                        style::drawable(x, axes.log_x) && style::drawable(y, axes.log_y)
                    })
                    .collect();
                (s.label.as_str(), points)
            })
            .collect();
        let all = || lines.iter().flat_map(|(_, p)| p.iter().copied());
        let (Some((x0, x1)), Some((y0, y1))) = (
            style::padded_range(all().map(|p| p.0), axes.log_x, 0.05),
            style::padded_range(all().map(|p| p.1), axes.log_y, 0.08),
        ) else {
            return Err(PlotError::Empty {
                path: path.to_path_buf(),
                what: format!(
                    "{} series without a drawable point (finite{}, spanning less than f64::MAX)",
                    series.len(),
                    if axes.log_x || axes.log_y {
                        ", positive on the log axes,"
                    } else {
                        ""
                    }
                ),
            });
        };
        let mut xs: Vec<f64> = all().map(|p| p.0).collect();
        xs.sort_by(f64::total_cmp);
        xs.dedup();
        let mut x = Axis::new(x0, x1, axes.log_x);
        if xs.len() <= MAX_DATA_TICKS {
            x = x.with_ticks(xs);
        }
        Ok(LineFigure {
            axes,
            lines,
            x,
            y: Axis::new(y0, y1, axes.log_y),
        })
    }
}

impl Figure for LineFigure<'_> {
    type Layout = ();

    fn size(&self) -> (u32, u32) {
        (800, 560)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), DrawError> {
        let mut builder = ChartBuilder::on(root);
        builder
            .margin(16)
            .x_label_area_size(56)
            .y_label_area_size(76);
        if !self.axes.title.is_empty() {
            builder.caption(&self.axes.title, (FONT, style::TITLE_SIZE));
        }
        let mut chart = builder.build_cartesian_2d(self.x.clone(), self.y.clone())?;
        chart
            .configure_mesh()
            .x_desc(self.axes.x_label.as_str())
            .y_desc(self.axes.y_label.as_str())
            .axis_desc_style((FONT, style::LABEL_SIZE))
            .label_style((FONT, style::TICK_SIZE))
            .x_label_formatter(&|v| style::tick_label(*v))
            .y_label_formatter(&|v| style::tick_label(*v))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()?;

        let mut any_label = false;
        for (i, (label, points)) in self.lines.iter().enumerate() {
            let colour = style::series_colour(i);
            let marker = style::series_marker(i);
            let line_style = colour.stroke_width(2);
            let annotation = chart.draw_series(std::iter::once(PathElement::new(
                points.clone(),
                line_style,
            )))?;
            if !label.is_empty() {
                annotation.label(*label).legend(move |(px, py)| {
                    EmptyElement::at((px, py))
                        + PathElement::new(vec![(0, 0), (24, 0)], line_style)
                        + style::marker_element(marker, (12, 0), 4, colour)
                });
            }
            chart.draw_series(points.iter().map(|&p| {
                EmptyElement::at(p) + style::marker_element(marker, (0, 0), 4, colour)
            }))?;
            any_label |= !label.is_empty();
        }
        if any_label {
            chart
                .configure_series_labels()
                .position(style::emptiest_corner(self.lines.iter().flat_map(
                    |(_, p)| {
                        p.iter()
                            .map(|&(x, y)| (self.x.fraction(x), self.y.fraction(y)))
                    },
                )))
                .label_font((FONT, style::TICK_SIZE))
                .background_style(WHITE.mix(0.85))
                .border_style(RGBColor(160, 160, 160))
                .legend_area_size(30)
                .draw()?;
        }
        Ok(())
    }
}
