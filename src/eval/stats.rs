//! Summary statistics of an error sequence, as evo reports them.

/// evo's statistics of per-pose errors (units of the errors).
///
/// `std` is the population standard deviation (divides by `n`, as numpy's
/// `np.std` does); `median` of an even count is the mean of the two middle
/// values (as `np.median`); `sse` is the sum of squared errors.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ErrorStats {
    pub rmse: f64,
    pub mean: f64,
    pub median: f64,
    pub std: f64,
    pub min: f64,
    pub max: f64,
    pub sse: f64,
    /// Number of errors summarized.
    pub count: usize,
}

impl ErrorStats {
    /// Statistics of `errors`; `None` when it is empty.
    pub fn from_errors(errors: &[f64]) -> Option<ErrorStats> {
        if errors.is_empty() {
            return None;
        }
        let n = errors.len() as f64;
        let sse: f64 = errors.iter().map(|e| e * e).sum();
        let mean = errors.iter().sum::<f64>() / n;
        let var = errors.iter().map(|e| (e - mean) * (e - mean)).sum::<f64>() / n;
        let mut sorted = errors.to_vec();
        sorted.sort_by(f64::total_cmp);
        let mid = sorted.len() / 2;
        let median = if sorted.len() % 2 == 1 {
            sorted[mid]
        } else {
            0.5 * (sorted[mid - 1] + sorted[mid])
        };
        Some(ErrorStats {
            rmse: (sse / n).sqrt(),
            mean,
            median,
            std: var.sqrt(),
            min: sorted[0],
            max: sorted[sorted.len() - 1],
            sse,
            count: errors.len(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed() {
        // errors 1, 2, 3, 6: mean 3, sse 50, rmse sqrt(12.5), population
        // variance (4 + 1 + 0 + 9) / 4 = 3.5, median (2 + 3) / 2.
        let s = ErrorStats::from_errors(&[3.0, 1.0, 6.0, 2.0]).unwrap();
        assert_eq!(s.mean, 3.0);
        assert_eq!(s.sse, 50.0);
        assert_eq!(s.rmse, 12.5f64.sqrt());
        assert_eq!(s.std, 3.5f64.sqrt());
        assert_eq!(s.median, 2.5);
        assert_eq!((s.min, s.max, s.count), (1.0, 6.0, 4));
        assert_eq!(
            ErrorStats::from_errors(&[4.0, 1.0, 2.0]).unwrap().median,
            2.0
        );
        assert!(ErrorStats::from_errors(&[]).is_none());
    }
}
