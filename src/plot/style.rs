//! The shared look of the figures: the embedded font, text sizes, series
//! colours and markers, the error colour map, tick labels and axis ranges.

use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

/// DejaVu Sans 2.37 from Debian's fonts-dejavu-core (see
/// `assets/fonts/README.md`): plotters' bitmap backend draws text only
/// through a registered font, and a machine may have none installed.
const DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// The family every text style names; the embedded font is registered
/// under it, and SVG viewers map it to their own sans-serif font.
pub(crate) const FONT: &str = "sans-serif";
pub(crate) const TITLE_SIZE: u32 = 24;
pub(crate) const LABEL_SIZE: u32 = 18;
pub(crate) const TICK_SIZE: u32 = 15;

/// Registers the embedded font with plotters once per process; the error
/// says why it could not.
pub(crate) fn ensure_font() -> Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok =
        *REGISTERED.get_or_init(|| register_font(FONT, FontStyle::Normal, DEJAVU_SANS).is_ok());
    if ok {
        Ok(())
    } else {
        Err("the embedded DejaVu Sans font did not parse".into())
    }
}

/// Series colours: matplotlib's "tab10", distinct and familiar from papers.
const TAB10: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Colour of the `i`-th series.
pub(crate) fn series_colour(i: usize) -> RGBColor {
    TAB10[i % TAB10.len()]
}

/// Marker shapes cycled over series so lines stay apart in grey print.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Marker {
    Circle,
    Square,
    Triangle,
    Cross,
}

pub(crate) fn series_marker(i: usize) -> Marker {
    [
        Marker::Circle,
        Marker::Square,
        Marker::Triangle,
        Marker::Cross,
    ][i % 4]
}

/// A marker of `size` pixels (radius) centred on backend pixel `c`.
pub(crate) fn marker_element<DB: DrawingBackend>(
    marker: Marker,
    c: (i32, i32),
    size: i32,
    colour: RGBColor,
) -> DynElement<'static, DB, (i32, i32)> {
    let filled = colour.filled();
    match marker {
        Marker::Circle => Circle::new(c, size, filled).into_dyn(),
        Marker::Square => {
            Rectangle::new([(c.0 - size, c.1 - size), (c.0 + size, c.1 + size)], filled).into_dyn()
        }
        Marker::Triangle => Polygon::new(
            vec![
                (c.0, c.1 - size - 1),
                (c.0 - size - 1, c.1 + size),
                (c.0 + size + 1, c.1 + size),
            ],
            filled,
        )
        .into_dyn(),
        Marker::Cross => Cross::new(c, size + 1, colour.stroke_width(2)).into_dyn(),
    }
}

/// Colour of an error of `value` on a scale from 0 to `top` (viridis; at
/// or above `top` the map's last colour). `top` must be positive.
pub(crate) fn error_colour(value: f64, top: f64) -> RGBColor {
    let t = if top > 0.0 && value.is_finite() {
        (value / top).clamp(0.0, 1.0)
    } else {
        0.0
    };
    // t is finite and within [0, 1]: plotters' map unwraps conversions of
    // NaN, so it must never see one.
    ViridisRGB.get_color(t)
}

/// Tick label of `v`: short, no float noise ("0.1", "1024", "2.5e-5").
pub(crate) fn tick_label(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        return format!("{v:.1e}");
    }
    if (v - v.round()).abs() < 1e-9 * a.max(1.0) {
        return format!("{}", v.round() as i64);
    }
    let s = format!("{v:.4}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// An axis range covering the finite `values` with a margin of `pad` of
/// its span on each side; on a log axis the margin is in decades and the
/// values must be positive. Never empty: a single value gets a unit span
/// (or a factor of 2 either way on a log axis). `None` if no value is
/// drawable or the range does not fit in an `f64` (values near its limits).
pub(crate) fn padded_range(
    values: impl Iterator<Item = f64>,
    log: bool,
    pad: f64,
) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| drawable(*v, log)) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if lo > hi {
        return None;
    }
    let (a, b) = if log {
        let (l, h) = (lo.log10(), hi.log10());
        let span = h - l;
        let (l, h) = if span > 0.0 {
            (l - pad * span, h + pad * span)
        } else {
            (l - std::f64::consts::LOG10_2, h + std::f64::consts::LOG10_2)
        };
        (10f64.powf(l), 10f64.powf(h))
    } else {
        let span = hi - lo;
        if span > 0.0 {
            (lo - pad * span, hi + pad * span)
        } else {
            let half = if lo.abs() > 0.0 { lo.abs() * 0.5 } else { 0.5 };
            (lo - half, hi + half)
        }
    };
    let fits = a.is_finite() && b.is_finite() && (b - a).is_finite() && a < b;
    (fits && (!log || a > 0.0)).then_some((a, b))
}

/// Whether `v` can be drawn on an axis (finite, and positive on a log one).
pub(crate) fn drawable(v: f64, log: bool) -> bool {
    v.is_finite() && (!log || v > 0.0)
}

/// The legend corner with the fewest of `points` (as fractions of the plot
/// area, x right and y up) in its quadrant; ties prefer upper right, then
/// upper left, lower right, lower left.
pub(crate) fn emptiest_corner(points: impl Iterator<Item = (f64, f64)>) -> SeriesLabelPosition {
    let mut counts = [0usize; 4];
    for (fx, fy) in points {
        let (right, upper) = (fx >= 0.5, fy >= 0.5);
        counts[usize::from(!upper) * 2 + usize::from(!right)] += 1;
    }
    match (0..4).min_by_key(|&i| counts[i]) {
        Some(1) => SeriesLabelPosition::UpperLeft,
        Some(2) => SeriesLabelPosition::LowerRight,
        Some(3) => SeriesLabelPosition::LowerLeft,
        _ => SeriesLabelPosition::UpperRight,
    }
}
