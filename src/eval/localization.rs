//! Localization summaries built on per-frame errors: the paper's Table I
//! (APE statistics averaged over sequences, smallest and largest RMSE,
//! completed sequences) and Table IV (steps until the estimate reaches a
//! given accuracy).

use super::ErrorStats;

/// The accuracies of the paper's global-localization table, metres.
pub const CONVERGENCE_THRESHOLDS: [f64; 5] = [2.0, 1.0, 0.5, 0.2, 0.1];

/// Statistics over sequences: each APE statistic averaged over sequences
/// (each sequence weighs the same, as the paper's "averaged over all
/// sequences"), and the smallest and largest per-sequence RMSE (Table I's
/// "min RMSE" and "max RMSE").
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SequenceSummary {
    pub sequences: usize,
    /// Field-wise mean of the per-sequence statistics; `count` is the total
    /// number of errors.
    pub mean: ErrorStats,
    pub min_rmse: f64,
    pub max_rmse: f64,
}

/// Summarizes per-sequence statistics; `None` for no sequences.
pub fn summarize_sequences(stats: &[ErrorStats]) -> Option<SequenceSummary> {
    if stats.is_empty() {
        return None;
    }
    let n = stats.len() as f64;
    let avg = |f: fn(&ErrorStats) -> f64| stats.iter().map(f).sum::<f64>() / n;
    let rmses = stats.iter().map(|s| s.rmse);
    Some(SequenceSummary {
        sequences: stats.len(),
        mean: ErrorStats {
            rmse: avg(|s| s.rmse),
            mean: avg(|s| s.mean),
            median: avg(|s| s.median),
            std: avg(|s| s.std),
            min: avg(|s| s.min),
            max: avg(|s| s.max),
            sse: avg(|s| s.sse),
            count: stats.iter().map(|s| s.count).sum(),
        },
        min_rmse: rmses.clone().fold(f64::INFINITY, f64::min),
        max_rmse: rmses.fold(f64::NEG_INFINITY, f64::max),
    })
}

/// When a tracked sequence counts as completed (the paper leaves it open;
/// DESIGN.md fixes it): after the first `skip_frames` frames, the
/// translation error never exceeds `max_error_m` for more than
/// `max_consecutive` consecutive frames.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CompletionRule {
    pub skip_frames: usize,
    pub max_error_m: f64,
    pub max_consecutive: usize,
}

impl Default for CompletionRule {
    /// 10 frames, 1 m, 5 frames.
    fn default() -> Self {
        CompletionRule {
            skip_frames: 10,
            max_error_m: 1.0,
            max_consecutive: 5,
        }
    }
}

impl CompletionRule {
    /// The fewest frames a sequence needs for the rule to be able to fail
    /// it: more than `skip_frames + max_consecutive` (16 by default).
    pub fn frames_to_judge(&self) -> usize {
        self.skip_frames + self.max_consecutive + 1
    }

    /// [`CompletionRule::is_completed`], or `None` for a sequence too short
    /// for the rule to fail ([`CompletionRule::frames_to_judge`]): such a
    /// run is not judged rather than called completed.
    pub fn judge(&self, errors_m: &[f64]) -> Option<bool> {
        (errors_m.len() >= self.frames_to_judge()).then(|| self.is_completed(errors_m))
    }

    /// A judgement of [`CompletionRule::judge`] in words: yes, no, or not
    /// judged (with the frames the rule needs).
    pub fn verdict(&self, judged: Option<bool>) -> String {
        match judged {
            Some(true) => "yes".into(),
            Some(false) => "no".into(),
            None => format!(
                "not judged (the rule needs {} frames or more)",
                self.frames_to_judge()
            ),
        }
    }

    /// Judgements of several sequences as a table cell: `k/n` completed,
    /// and how many were too short to judge when any was (each such run
    /// had been counted completed by the benches, while `omcl localize`
    /// and `omcl eval` said "not judged").
    pub fn tally(&self, judged: impl IntoIterator<Item = Option<bool>>) -> String {
        let (mut yes, mut unjudged, mut n) = (0, 0, 0);
        for j in judged {
            n += 1;
            match j {
                Some(true) => yes += 1,
                Some(false) => {}
                None => unjudged += 1,
            }
        }
        match unjudged {
            0 => format!("{yes}/{n}"),
            m => format!(
                "{yes}/{n} ({m} not judged: under {} frames)",
                self.frames_to_judge()
            ),
        }
    }

    /// Whether the per-frame translation errors (metres, in frame order)
    /// complete the sequence. A non-finite error counts as above the bound.
    pub fn is_completed(&self, errors_m: &[f64]) -> bool {
        let mut run = 0usize;
        for &e in errors_m.iter().skip(self.skip_frames) {
            // A lost estimate (NaN) counts as a failed frame.
            if e.is_nan() || e > self.max_error_m {
                run += 1;
                if run > self.max_consecutive {
                    return false;
                }
            } else {
                run = 0;
            }
        }
        true
    }
}

/// For each threshold (metres), the number of filter steps until the
/// estimate's error first falls to or below it: `errors_m[k]` is the error
/// after step `k + 1`, so the answer is `k + 1`, or `None` if it never does.
pub fn steps_to_reach(errors_m: &[f64], thresholds_m: &[f64]) -> Vec<Option<usize>> {
    thresholds_m
        .iter()
        .map(|&t| errors_m.iter().position(|&e| e <= t).map(|k| k + 1))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_of_two_sequences() {
        let a = ErrorStats::from_errors(&[1.0, 1.0]).unwrap();
        let b = ErrorStats::from_errors(&[3.0, 4.0, 5.0]).unwrap();
        let s = summarize_sequences(&[a, b]).unwrap();
        // rmse: 1 and sqrt(50/3).
        assert_eq!(s.min_rmse, 1.0);
        assert!((s.max_rmse - (50.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert!((s.mean.mean - 2.5).abs() < 1e-12);
        assert_eq!(s.mean.median, 2.5);
        assert_eq!(s.mean.count, 5);
        assert!(summarize_sequences(&[]).is_none());
    }

    #[test]
    fn completion_rule() {
        let rule = CompletionRule::default();
        // Large errors in the first 10 frames do not count.
        let mut e = vec![5.0; 10];
        e.extend([0.1; 5]);
        // Five consecutive frames above 1 m are tolerated...
        e.extend([1.5; 5]);
        e.push(0.2);
        assert!(rule.is_completed(&e));
        // ...six are not.
        e.extend([1.5; 6]);
        assert!(!rule.is_completed(&e));
        // Exactly 1 m is not above the bound; NaN is.
        assert!(rule.is_completed(&[1.0; 30]));
        // Too short to fail: not judged; one frame more and it can be.
        assert_eq!(rule.frames_to_judge(), 16);
        assert_eq!(rule.judge(&[5.0; 15]), None);
        assert_eq!(rule.judge(&[5.0; 16]), Some(false));
        assert_eq!(rule.judge(&[0.1; 16]), Some(true));
        let mut nan = vec![0.0; 10];
        nan.extend([f64::NAN; 6]);
        assert!(!rule.is_completed(&nan));
    }

    #[test]
    fn steps_until_accuracy() {
        let e = [3.0, 1.5, 0.9, 0.4, 0.45, 0.15, 0.3];
        assert_eq!(
            steps_to_reach(&e, &CONVERGENCE_THRESHOLDS),
            vec![Some(2), Some(3), Some(4), Some(6), None]
        );
    }
}
