//! The benchmark's two seed ranges, stated once.
//!
//! Everything that is tuned or calibrated (the feature models' parameters,
//! filter defaults, thresholds) is tuned on [`TUNING`] only; every table
//! omcl reports comes from seeds at or above [`FIRST_REPORTING`], which no
//! tuning ever looked at. `omcl bench` and `omcl sweep plan` start at
//! [`FIRST_REPORTING`] unless told otherwise, and `omcl demo` runs on a
//! reporting seed.

use std::ops::Range;

/// Seeds for tuning and calibration.
pub const TUNING: Range<u64> = 0..100;

/// The first seed of the reported (held-out) range; it runs upward.
pub const FIRST_REPORTING: u64 = 1000;

const _: () = assert!(TUNING.end <= FIRST_REPORTING, "the ranges must not meet");

/// Whether `seed` is a held-out (reporting) seed.
pub fn is_reporting(seed: u64) -> bool {
    seed >= FIRST_REPORTING
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ranges_do_not_meet() {
        assert!(!TUNING.clone().any(is_reporting));
        assert!(is_reporting(FIRST_REPORTING));
    }
}
