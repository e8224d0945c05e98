//! Recovery from track loss, augmented MCL (Thrun, Burgard, Fox,
//! "Probabilistic Robotics", table 8.3): short- and long-term averages of
//! the mean measurement likelihood; when the short-term average drops below
//! the long-term one, a fraction `max(0, 1 - w_fast / w_slow)` of the
//! particles is replaced by fresh ones from an injection distribution
//! (global floor initialization in the filter).

/// Smoothing rates of the averages (`0 < alpha_slow << alpha_fast < 1`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RecoveryParams {
    pub alpha_slow: f64,
    pub alpha_fast: f64,
    /// Largest fraction of particles replaced in one step.
    pub max_fraction: f64,
    /// Candidates drawn for each injected particle; the best-scoring on the
    /// current frame are injected (sensor-resetting localization, Lenser
    /// and Veloso, ICRA 2000). 1 is plain augmented MCL; more costs that
    /// many extra particle evaluations while the filter is injecting, and
    /// nothing while it tracks.
    #[serde(default = "default_candidates")]
    pub candidates: usize,
}

impl RecoveryParams {
    /// Checks the parameters: `0 < alpha_slow < alpha_fast <= 1` (as AMCL
    /// needs), `max_fraction` in `[0, 1]`, 1 to 1024 candidates.
    pub fn validate(&self) -> Result<(), super::MclError> {
        let bad = |name, why| Err(super::MclError::BadParam { name, why });
        let (slow, fast) = (self.alpha_slow, self.alpha_fast);
        if !(0.0 < slow && slow < fast && fast <= 1.0) {
            return bad(
                "recovery.alpha_slow",
                format!("must have 0 < alpha_slow < alpha_fast <= 1, got {slow} and {fast}"),
            );
        }
        if !(0.0..=1.0).contains(&self.max_fraction) {
            return bad(
                "recovery.max_fraction",
                format!("must be in [0, 1], got {}", self.max_fraction),
            );
        }
        if !(1..=1024).contains(&self.candidates) {
            return bad(
                "recovery.candidates",
                format!("must be 1 to 1024, got {}", self.candidates),
            );
        }
        Ok(())
    }
}

fn default_candidates() -> usize {
    8
}

impl Default for RecoveryParams {
    fn default() -> Self {
        RecoveryParams {
            alpha_slow: 0.01,
            alpha_fast: 0.3,
            max_fraction: 0.3,
            candidates: default_candidates(),
        }
    }
}

/// The running averages.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Recovery {
    pub w_slow: f64,
    pub w_fast: f64,
}

impl Recovery {
    /// `w_fast / w_slow` capped to `[0, 1]` (1 before any update).
    pub fn confidence(&self) -> f64 {
        if self.w_slow > 0.0 {
            (self.w_fast / self.w_slow).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    /// Updates the averages with this step's mean likelihood and returns
    /// the fraction of particles to replace.
    pub fn update(&mut self, mean_likelihood: f64, p: &RecoveryParams) -> f64 {
        if !mean_likelihood.is_finite() {
            return 0.0;
        }
        if self.w_slow == 0.0 {
            self.w_slow = mean_likelihood;
            self.w_fast = mean_likelihood;
        } else {
            self.w_slow += p.alpha_slow * (mean_likelihood - self.w_slow);
            self.w_fast += p.alpha_fast * (mean_likelihood - self.w_fast);
        }
        if self.w_slow > 0.0 {
            (1.0 - self.w_fast / self.w_slow).clamp(0.0, p.max_fraction)
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn injects_only_after_a_drop() {
        let p = RecoveryParams::default();
        let mut r = Recovery::default();
        for _ in 0..50 {
            assert_eq!(r.update(0.6, &p), 0.0);
        }
        // A sudden drop in likelihood: w_fast falls faster than w_slow.
        let mut f = 0.0;
        for _ in 0..10 {
            f = r.update(0.1, &p);
        }
        assert!(f > 0.1, "{f}");
        assert!(f <= p.max_fraction);
    }
}
