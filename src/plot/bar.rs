//! Grouped bar charts with error bars (the sampling-strategy ablation).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::Axis;
use super::output::{DrawError, Figure, write_figure};
use super::style::{self, FONT};
use super::{Axes, PlotError};

/// One group of bars, labelled on the x axis (e.g. a ray count).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BarGroup {
    /// Label under the group.
    pub label: String,
    /// `(series, value, std)`: the series name (legend entry, e.g. a
    /// sampling strategy), the bar's height in the y label's unit and an
    /// optional standard deviation drawn as a ± error bar.
    pub bars: Vec<(String, f64, Option<f64>)>,
}

/// Writes a grouped bar chart to `path` (`.png` or `.svg`): one group per
/// [`BarGroup`] along x, within each group one bar per series name (same
/// colour and slot in every group, in order of first appearance), ± std
/// error bars where given.
///
/// The x axis is categorical: `axes.log_x` must be false. With
/// `axes.log_y` the bars rise from the bottom of the axis. Bars with a
/// non-finite value (or non-positive on a log axis) are left out, and so
/// are error bars with a non-finite or negative std. Errors if no bar
/// remains.
pub fn bar_plot(path: &Path, axes: &Axes, groups: &[BarGroup]) -> Result<(), PlotError> {
    let figure = BarFigure::new(path, axes, groups)?;
    write_figure(path, &figure).map(|_| ())
}

/// Canvas size without the legend strip.
const CHART_SIZE: (u32, u32) = (800, 560);
/// Fraction of a group's width taken by its bars (the rest separates groups).
const GROUP_FILL: f64 = 0.8;

/// One drawable bar: group index, series index, value, error half-height.
#[derive(Debug, Clone, Copy)]
struct Bar {
    group: usize,
    series: usize,
    value: f64,
    std: Option<f64>,
}

/// A validated bar chart.
pub(crate) struct BarFigure<'a> {
    axes: &'a Axes,
    group_labels: Vec<&'a str>,
    series: Vec<&'a str>,
    bars: Vec<Bar>,
    y: Axis,
    legend_width: u32,
}

impl<'a> BarFigure<'a> {
    pub(crate) fn new(
        path: &Path,
        axes: &'a Axes,
        groups: &'a [BarGroup],
    ) -> Result<BarFigure<'a>, PlotError> {
        if axes.log_x {
            return Err(PlotError::Invalid {
                path: path.to_path_buf(),
                what: "a bar plot's x axis is categorical; log_x must be false".into(),
            });
        }
        let mut series: Vec<&str> = Vec::new();
        let mut bars = Vec::new();
        for (g, group) in groups.iter().enumerate() {
            for (name, value, std) in &group.bars {
                let s = match series.iter().position(|n| *n == name.as_str()) {
                    Some(s) => s,
                    None => {
                        series.push(name.as_str());
                        series.len() - 1
                    }
                };
                if style::drawable(*value, axes.log_y) {
                    bars.push(Bar {
                        group: g,
                        series: s,
                        value: *value,
                        std: std.filter(|d| d.is_finite() && *d >= 0.0),
                    });
                }
            }
        }
        // The range covers the error bars; a linear axis also includes 0,
        // where the bars start.
        let extremes = bars.iter().flat_map(|b| {
            let d = b.std.unwrap_or(0.0);
            let low = if axes.log_y && b.value - d <= 0.0 {
                b.value
            } else {
                b.value - d
            };
            [low, b.value + d]
        });
        let zero = (!axes.log_y).then_some(0.0);
        let range = if bars.is_empty() {
            None
        } else {
            style::padded_range(extremes.chain(zero), axes.log_y, 0.06)
        };
        let Some((mut y0, y1)) = range else {
            return Err(PlotError::Empty {
                path: path.to_path_buf(),
                what: format!(
                    "{} groups without a drawable bar (finite{}, spanning less than f64::MAX)",
                    groups.len(),
                    if axes.log_y { ", positive," } else { "" }
                ),
            });
        };
        if !axes.log_y && y0 < 0.0 && bars.iter().all(|b| b.value - b.std.unwrap_or(0.0) >= 0.0) {
            // Non-negative data: bars stand on the x axis, not above a margin.
            y0 = 0.0;
        }
        let longest = series.iter().map(|s| s.chars().count()).max().unwrap_or(0);
        Ok(BarFigure {
            axes,
            group_labels: groups.iter().map(|g| g.label.as_str()).collect(),
            legend_width: (60 + 9 * longest as u32).min(320),
            series,
            bars,
            y: Axis::new(y0, y1, axes.log_y),
        })
    }

    /// x extent of a bar (group `g`, series slot `s`) in group units.
    fn bar_span(&self, g: usize, s: usize) -> (f64, f64) {
        let width = GROUP_FILL / self.series.len() as f64;
        let x0 = g as f64 + (1.0 - GROUP_FILL) / 2.0 + s as f64 * width;
        (x0, x0 + width)
    }
}

impl Figure for BarFigure<'_> {
    type Layout = ();

    fn size(&self) -> (u32, u32) {
        (CHART_SIZE.0 + self.legend_width, CHART_SIZE.1)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), DrawError> {
        let (chart_area, legend_area) = root.split_horizontally(CHART_SIZE.0);
        let n = self.group_labels.len();
        let x =
            Axis::new(0.0, n as f64, false).with_ticks((0..n).map(|g| g as f64 + 0.5).collect());
        let mut builder = ChartBuilder::on(&chart_area);
        builder
            .margin(16)
            .x_label_area_size(56)
            .y_label_area_size(76);
        if !self.axes.title.is_empty() {
            builder.caption(&self.axes.title, (FONT, style::TITLE_SIZE));
        }
        let mut chart = builder.build_cartesian_2d(x, self.y.clone())?;
        let group_label = |v: &f64| {
            let g = v.floor();
            if g >= 0.0 && (g as usize) < n {
                self.group_labels[g as usize].to_string()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_desc(self.axes.x_label.as_str())
            .y_desc(self.axes.y_label.as_str())
            .axis_desc_style((FONT, style::LABEL_SIZE))
            .label_style((FONT, style::TICK_SIZE))
            .x_label_formatter(&group_label)
            .y_label_formatter(&|v| style::tick_label(*v))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()?;

        let base = if self.axes.log_y { self.y.lo() } else { 0.0 };
        chart.draw_series(self.bars.iter().map(|b| {
            let (x0, x1) = self.bar_span(b.group, b.series);
            Rectangle::new(
                [(x0, base), (x1, b.value)],
                style::series_colour(b.series).filled(),
            )
        }))?;
        let black = BLACK.stroke_width(1);
        for b in &self.bars {
            let Some(d) = b.std.filter(|d| *d > 0.0) else {
                continue;
            };
            let (x0, x1) = self.bar_span(b.group, b.series);
            let (mid, cap) = ((x0 + x1) / 2.0, (x1 - x0) * 0.2);
            let low = if self.axes.log_y && b.value - d <= 0.0 {
                self.y.lo()
            } else {
                b.value - d
            };
            let high = b.value + d;
            chart.draw_series([
                PathElement::new(vec![(mid, low), (mid, high)], black),
                PathElement::new(vec![(mid - cap, low), (mid + cap, low)], black),
                PathElement::new(vec![(mid - cap, high), (mid + cap, high)], black),
            ])?;
        }

        // The legend sits in its own strip so it never hides a bar.
        let text = TextStyle::from((FONT, style::TICK_SIZE).into_font())
            .pos(Pos::new(HPos::Left, VPos::Center));
        for (s, name) in self.series.iter().enumerate() {
            let y = 60 + 26 * s as i32;
            legend_area.draw(&Rectangle::new(
                [(8, y - 7), (22, y + 7)],
                style::series_colour(s).filled(),
            ))?;
            legend_area.draw(&Text::new(name.to_string(), (30, y), text.clone()))?;
        }
        Ok(())
    }
}
