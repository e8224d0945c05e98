//! The server's log: one line on stderr per event of its life (a session
//! opened, closed or expired, the shutdown and the end of its drain), each
//! with a UTC timestamp; nothing per frame (`/metrics` counts those).

use std::time::SystemTime;

/// Writes `omcl serve: <what>` after the time, as one line.
pub fn event(what: impl std::fmt::Display) {
    eprintln!("{} omcl serve: {what}", utc_now());
}

/// `n` and `what`, plural when `n` is not 1: "1 step", "2 steps".
pub fn count(n: u64, what: &str) -> String {
    match n {
        1 => format!("1 {what}"),
        n => format!("{n} {what}s"),
    }
}

/// The time now as `YYYY-MM-DDTHH:MM:SS.mmmZ`.
pub fn utc_now() -> String {
    utc(SystemTime::now())
}

/// `t` as an ISO 8601 UTC time to the millisecond.
fn utc(t: SystemTime) -> String {
    chrono::DateTime::<chrono::Utc>::from(t)
        .format("%Y-%m-%dT%H:%M:%S%.3fZ")
        .to_string()
}

#[cfg(test)]
mod tests {
    use super::utc;
    use std::time::{Duration, UNIX_EPOCH};

    /// Against Python's `datetime.fromtimestamp(t, timezone.utc)`.
    #[test]
    fn utc_times_match_a_trusted_calendar() {
        let at = |secs: u64, millis: u64| {
            utc(UNIX_EPOCH + Duration::from_secs(secs) + Duration::from_millis(millis))
        };
        assert_eq!(at(0, 0), "1970-01-01T00:00:00.000Z");
        assert_eq!(at(951_782_400, 7), "2000-02-29T00:00:00.007Z");
        assert_eq!(at(1_795_856_523, 250), "2026-11-28T09:02:03.250Z");
        // 2100 is not a leap year.
        assert_eq!(at(4_107_542_400, 0), "2100-03-01T00:00:00.000Z");
    }
}
