//! One numeric axis, linear or logarithmic, optionally with ticks at given
//! values: a single coordinate type for all plots, so a chart's type does
//! not change with the `log_x`/`log_y` flags.

use std::ops::Range;

use plotters::coord::ranged1d::{KeyPointHint, NoDefaultFormatting, Ranged, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::{IntoLogRange, LogCoord};

use super::style;

/// A value range `lo..hi` (`0 < lo < hi` on a log axis) mapped to pixels.
#[derive(Debug, Clone)]
pub(crate) struct Axis {
    lo: f64,
    hi: f64,
    log: bool,
    ticks: Option<Vec<f64>>,
}

impl Axis {
    /// `lo < hi`, both finite, and positive when `log`; the callers build
    /// ranges with [`style::padded_range`], which guarantees that.
    pub(crate) fn new(lo: f64, hi: f64, log: bool) -> Axis {
        Axis {
            lo,
            hi,
            log,
            ticks: None,
        }
    }

    /// Ticks exactly at `ticks` (those within the range) instead of the
    /// automatic ones.
    pub(crate) fn with_ticks(mut self, ticks: Vec<f64>) -> Axis {
        self.ticks = Some(ticks);
        self
    }

    /// Position of `v` along the axis, 0 at `lo` and 1 at `hi`.
    pub(crate) fn fraction(&self, v: f64) -> f64 {
        if self.log {
            (v.ln() - self.lo.ln()) / (self.hi.ln() - self.lo.ln())
        } else {
            (v - self.lo) / (self.hi - self.lo)
        }
    }

    pub(crate) fn lo(&self) -> f64 {
        self.lo
    }
}

impl Ranged for Axis {
    type FormatOption = NoDefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let t = self.fraction(*value);
        let p = limit.0 as f64 + t * (limit.1 - limit.0) as f64;
        // `as` saturates and maps NaN to 0: off-range values stay drawable
        // (and are clipped) instead of panicking.
        p.round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if let Some(ticks) = &self.ticks {
            if hint.weight().allow_light_points() {
                return Vec::new();
            }
            return ticks
                .iter()
                .copied()
                .filter(|t| *t >= self.lo && *t <= self.hi)
                .collect();
        }
        // Below one decade plotters' log ticks can be empty; evenly spaced
        // ticks are then more useful (and still correct on a log axis).
        if self.log && self.hi / self.lo >= 10.0 {
            LogCoord::from((self.lo..self.hi).log_scale()).key_points(hint)
        } else {
            RangedCoordf64::from(self.lo..self.hi).key_points(hint)
        }
    }

    fn range(&self) -> Range<f64> {
        self.lo..self.hi
    }
}

impl ValueFormatter<f64> for Axis {
    fn format(value: &f64) -> String {
        style::tick_label(*value)
    }
}
