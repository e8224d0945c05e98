//! Frame stamps and their order within a session.
//!
//! A session's stamped frames must move forward in time: a frame stamped
//! earlier than a frame the session has stepped, or has on the pool or
//! waiting, is refused, and so is one stamped the same as the frame it
//! last stepped. The filter itself never reads a stamp (its motion comes
//! from the odometry poses), so an old frame would be stepped as the
//! newest: its pose answered after later ones (a trajectory whose stamps
//! go back), and under latest-frame-wins it would replace a newer waiting
//! frame. A repeated stamp steps the same instant twice, and a frame
//! weighed twice makes the filter surer of it than one view allows.
//!
//! A frame that was not stepped (refused, replaced by a newer one,
//! overloaded, past the deadline) sets nothing, so it may be sent again
//! with its stamp. A frame without a stamp is not ordered.

use std::fmt;

use tonic::Status;

use super::proto;

/// A frame's stamp (`Header.stamp`): seconds and nanoseconds since the
/// clock's epoch, ordered as time. Compared whole, not as `f64`: at Unix
/// times (1.7e9 s) an `f64` resolves about a quarter of a microsecond, so
/// frames a tenth of a microsecond apart could compare equal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct Stamp {
    // Field order is the order: seconds first, then nanoseconds in
    // [0, 1e9).
    sec: i64,
    nanosec: u32,
}

/// Nanoseconds in a second; a stamp's `nanosec` is below it.
const NANOS: u32 = 1_000_000_000;

impl Stamp {
    /// A stamp from the wire, its `nanosec` below 1e9 (ROS's
    /// `builtin_interfaces/Time`).
    pub fn from_msg(t: &proto::Time) -> Result<Stamp, Status> {
        if t.nanosec >= NANOS {
            return Err(Status::invalid_argument(format!(
                "header.stamp.nanosec {} is not below 1000000000 (stamp sec {})",
                t.nanosec, t.sec
            )));
        }
        Ok(Stamp {
            sec: t.sec,
            nanosec: t.nanosec,
        })
    }

    /// Seconds, as the session takes them (the nearest `f64`).
    pub fn seconds(self) -> f64 {
        self.sec as f64 + 1e-9 * f64::from(self.nanosec)
    }
}

/// Seconds with every significant decimal (up to nine): `12.5 s`,
/// `-0.000000001 s`, `3 s`.
impl fmt::Display for Stamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let total = i128::from(self.sec) * i128::from(NANOS) + i128::from(self.nanosec);
        let sign = if total < 0 { "-" } else { "" };
        let (whole, frac) = (
            total.unsigned_abs() / u128::from(NANOS),
            total.unsigned_abs() % u128::from(NANOS),
        );
        if frac == 0 {
            return write!(f, "{sign}{whole} s");
        }
        let digits = format!("{frac:09}");
        write!(f, "{sign}{whole}.{} s", digits.trim_end_matches('0'))
    }
}

/// The stamps a session's next frame must follow.
#[derive(Debug, Clone, Copy, Default)]
pub struct Seen {
    /// The last frame the session stepped (since it started or was last
    /// reinitialized).
    pub stepped: Option<Stamp>,
    /// The frame on the pool (queued or being stepped).
    pub on_pool: Option<Stamp>,
    /// The frame waiting behind it.
    pub waiting: Option<Stamp>,
}

/// Whether a frame stamped `stamp` may follow what `session` has `seen`:
/// later than the frame it stepped last, and not earlier than those on
/// the pool or waiting (the same stamp as the waiting frame is a frame
/// sent again, which replaces it; the same as the frame on the pool is
/// decided against the stepped one when its turn comes). The refusal is
/// INVALID_ARGUMENT naming both stamps and the session (an id the server
/// made, quoted whole).
pub fn follows(stamp: Stamp, seen: &Seen, session: &str) -> Result<(), Status> {
    let refuse = |how: &str, other: Stamp, which: &str| {
        Err(Status::invalid_argument(format!(
            "session {session:?}: frame stamped {stamp} {how} {other}, the stamp of {which}: \
             stamps must increase within a session (SetInitialPose and GlobalLocalization start \
             them afresh)"
        )))
    };
    if let Some(prev) = seen.stepped {
        if stamp < prev {
            return refuse("is earlier than", prev, "the last frame stepped");
        }
        if stamp == prev {
            return refuse("repeats", prev, "the last frame stepped");
        }
    }
    if let Some(prev) = seen.on_pool
        && stamp < prev
    {
        return refuse("is earlier than", prev, "the frame being stepped");
    }
    if let Some(prev) = seen.waiting
        && stamp < prev
    {
        return refuse("is earlier than", prev, "the frame waiting");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(sec: i64, nanosec: u32) -> Stamp {
        Stamp::from_msg(&proto::Time { sec, nanosec }).unwrap()
    }

    #[test]
    fn stamps_order_as_time_across_zero_and_below_f64_resolution() {
        // -1 s + 0.5 s = -0.5 s is after -1 s and before 0.
        assert!(at(-1, 0) < at(-1, 500_000_000));
        assert!(at(-1, 500_000_000) < at(0, 0));
        assert!(at(0, 999_999_999) < at(1, 0));
        // 90 ns apart at a Unix time: equal as f64 (its step there is
        // 2^-22 s, 238 ns), ordered as stamps.
        let (a, b) = (at(1_700_000_000, 10), at(1_700_000_000, 100));
        assert_eq!(a.seconds(), b.seconds());
        assert!(a < b);
    }

    #[test]
    fn stamps_print_their_significant_decimals() {
        assert_eq!(at(12, 500_000_000).to_string(), "12.5 s");
        assert_eq!(at(3, 0).to_string(), "3 s");
        assert_eq!(at(-1, 999_999_999).to_string(), "-0.000000001 s");
        assert_eq!(at(-2, 250_000_000).to_string(), "-1.75 s");
        assert_eq!(
            at(1_305_031_102, 175_304_000).to_string(),
            "1305031102.175304 s"
        );
    }

    #[test]
    fn a_nanosecond_count_of_a_second_or_more_is_refused() {
        let e = Stamp::from_msg(&proto::Time {
            sec: 4,
            nanosec: NANOS,
        })
        .unwrap_err();
        assert_eq!(e.code(), tonic::Code::InvalidArgument);
        assert!(e.message().contains("nanosec 1000000000"), "{e:?}");
    }

    #[test]
    fn a_frame_must_be_later_than_the_last_stepped_and_not_earlier_than_the_queued() {
        let seen = Seen {
            stepped: Some(at(10, 0)),
            on_pool: Some(at(11, 0)),
            waiting: Some(at(12, 0)),
        };
        let msg = |s: Stamp| follows(s, &seen, "s1").unwrap_err().message().to_string();
        let m = msg(at(9, 500_000_000));
        assert!(
            m.starts_with(
                "session \"s1\": frame stamped 9.5 s is earlier than 10 s, the stamp of the \
                 last frame stepped"
            ),
            "{m}"
        );
        assert!(
            msg(at(10, 0)).contains("repeats 10 s"),
            "{}",
            msg(at(10, 0))
        );
        assert!(
            msg(at(10, 1)).contains("earlier than 11 s, the stamp of the frame being stepped"),
            "{}",
            msg(at(10, 1))
        );
        assert!(
            msg(at(11, 0)).contains("earlier than 12 s, the stamp of the frame waiting"),
            "{}",
            msg(at(11, 0))
        );
        // The waiting frame sent again, or a later one: taken.
        follows(at(12, 0), &seen, "s1").unwrap();
        follows(at(12, 1), &seen, "s1").unwrap();
        // Nothing seen yet: any stamp, negative ones too.
        follows(at(-5, 0), &Seen::default(), "s1").unwrap();
        // The frame on the pool sent again is left to its turn.
        let running = Seen {
            waiting: None,
            ..seen
        };
        follows(at(11, 0), &running, "s1").unwrap();
    }
}
