//! Counters of the server, in Prometheus' text format.

use std::fmt::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Upper bounds of the step latency histogram, seconds.
pub const BUCKETS: [f64; 14] = [
    0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 30.0,
];

/// Rejection reasons counted (label `reason`).
pub const REASONS: [&str; 9] = [
    "overload",
    "session_cap",
    "invalid_frame",
    "unauthenticated",
    "shutting_down",
    // A frame whose turn came after the server's deadline, not stepped, or
    // a call the server's deadline ended (DEADLINE_EXCEEDED; a step already
    // running goes on to its end).
    "expired",
    // A frame whose caller had gone (call cancelled or timed out, stream
    // closed) when its turn came, not stepped.
    "abandoned",
    // A gRPC connection past --max-connections (refused or dropped).
    "connection_cap",
    // A frame that arrived before its session was reinitialized, answered
    // ABORTED at its turn, not stepped.
    "reinitialized",
];

#[derive(Default)]
pub struct Metrics {
    pub frames: AtomicU64,
    pub frames_dropped: AtomicU64,
    pub sessions_created: AtomicU64,
    pub sessions_expired: AtomicU64,
    rejected: [AtomicU64; REASONS.len()],
    /// Counts per bucket (not cumulative), sum of seconds.
    latency: Mutex<([u64; BUCKETS.len() + 1], f64)>,
}

impl Metrics {
    pub fn reject(&self, reason: &str) {
        if let Some(i) = REASONS.iter().position(|r| *r == reason) {
            self.rejected[i].fetch_add(1, Ordering::Relaxed);
        }
    }

    pub fn rejected(&self, reason: &str) -> u64 {
        REASONS
            .iter()
            .position(|r| *r == reason)
            .map_or(0, |i| self.rejected[i].load(Ordering::Relaxed))
    }

    /// A step answered `latency` after its frame arrived.
    pub fn observe_step(&self, latency: Duration) {
        self.frames.fetch_add(1, Ordering::Relaxed);
        let s = latency.as_secs_f64();
        let i = BUCKETS
            .iter()
            .position(|&b| s <= b)
            .unwrap_or(BUCKETS.len());
        let mut h = self.latency.lock().unwrap_or_else(|e| e.into_inner());
        h.0[i] += 1;
        h.1 += s;
    }

    /// The text exposition; `gauges` are (name, help, value) read by the
    /// caller (sessions, queue depth).
    pub fn render(&self, gauges: &[(&str, &str, f64)]) -> String {
        let mut out = String::new();
        for (name, help, v) in gauges {
            let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} gauge\n{name} {v}");
        }
        let counters = [
            (
                "omcl_frames_total",
                "Frames stepped by the filter.",
                &self.frames,
            ),
            (
                "omcl_frames_dropped_total",
                "Frames replaced by a newer frame of their session before they ran.",
                &self.frames_dropped,
            ),
            (
                "omcl_sessions_created_total",
                "Sessions started.",
                &self.sessions_created,
            ),
            (
                "omcl_sessions_expired_total",
                "Sessions closed for being idle.",
                &self.sessions_expired,
            ),
        ];
        for (name, help, c) in counters {
            let _ = writeln!(
                out,
                "# HELP {name} {help}\n# TYPE {name} counter\n{name} {}",
                c.load(Ordering::Relaxed)
            );
        }
        let _ = writeln!(
            out,
            "# HELP omcl_rejected_total Calls or frames refused, by reason.\n\
             # TYPE omcl_rejected_total counter"
        );
        for (i, r) in REASONS.iter().enumerate() {
            let _ = writeln!(
                out,
                "omcl_rejected_total{{reason=\"{r}\"}} {}",
                self.rejected[i].load(Ordering::Relaxed)
            );
        }
        let (counts, sum) = *self.latency.lock().unwrap_or_else(|e| e.into_inner());
        let name = "omcl_step_latency_seconds";
        let _ = writeln!(
            out,
            "# HELP {name} From a frame's arrival to its pose (waiting and the filter step).\n\
             # TYPE {name} histogram"
        );
        let mut acc = 0u64;
        for (i, b) in BUCKETS.iter().enumerate() {
            acc += counts[i];
            let _ = writeln!(out, "{name}_bucket{{le=\"{b}\"}} {acc}");
        }
        acc += counts[BUCKETS.len()];
        let _ = writeln!(out, "{name}_bucket{{le=\"+Inf\"}} {acc}");
        let _ = writeln!(out, "{name}_sum {sum}\n{name}_count {acc}");
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_buckets_are_cumulative() {
        let m = Metrics::default();
        m.observe_step(Duration::from_micros(1500)); // <= 0.002
        m.observe_step(Duration::from_millis(30)); // <= 0.05
        m.observe_step(Duration::from_secs(60)); // +Inf only
        m.reject("overload");
        let t = m.render(&[("omcl_sessions", "Open sessions.", 3.0)]);
        for line in [
            "omcl_sessions 3",
            "omcl_frames_total 3",
            "omcl_step_latency_seconds_bucket{le=\"0.001\"} 0",
            "omcl_step_latency_seconds_bucket{le=\"0.002\"} 1",
            "omcl_step_latency_seconds_bucket{le=\"0.05\"} 2",
            "omcl_step_latency_seconds_bucket{le=\"30\"} 2",
            "omcl_step_latency_seconds_bucket{le=\"+Inf\"} 3",
            "omcl_step_latency_seconds_count 3",
            "omcl_rejected_total{reason=\"overload\"} 1",
        ] {
            assert!(t.lines().any(|l| l == line), "no line {line:?} in\n{t}");
        }
    }
}
