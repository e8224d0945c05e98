//! The server's log: one line on stderr per event of its life (a session
//! opened, closed or expired, the shutdown and the end of its drain), each
//! with a UTC timestamp; nothing per frame (`/metrics` counts those).

use std::time::{SystemTime, UNIX_EPOCH};

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
    let t = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap_or_default();
    utc(t.as_secs(), t.subsec_millis())
}

/// `secs` after the Unix epoch (and `millis`) as an ISO 8601 UTC time.
fn utc(secs: u64, millis: u32) -> String {
    let (days, rest) = (secs / 86_400, secs % 86_400);
    let (y, m, d) = civil_from_days(days as i64);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{millis:03}Z",
        rest / 3600,
        rest % 3600 / 60,
        rest % 60
    )
}

/// The Gregorian date `days` after 1970-01-01 (Howard Hinnant's
/// `civil_from_days`, eras of 400 years).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

#[cfg(test)]
mod tests {
    use super::utc;

    /// Against Python's `datetime.fromtimestamp(t, timezone.utc)`.
    #[test]
    fn utc_times_match_a_trusted_calendar() {
        assert_eq!(utc(0, 0), "1970-01-01T00:00:00.000Z");
        assert_eq!(utc(951_782_400, 7), "2000-02-29T00:00:00.007Z");
        assert_eq!(utc(1_795_856_523, 250), "2026-11-28T09:02:03.250Z");
        // 2100 is not a leap year.
        assert_eq!(utc(4_107_542_400, 0), "2100-03-01T00:00:00.000Z");
    }
}
