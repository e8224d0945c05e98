//! Low-variance (systematic) resampling, triggered by the effective sample
//! size.

use rand::Rng;

use super::particles::{Particle, ess, set_uniform};

/// When to resample and what happens to the weights.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ResamplePolicy {
    /// Resample when `ESS < ess_fraction * n` (1.0 or more: every step, as
    /// the authors do; 0: never).
    pub ess_fraction: f64,
    /// After resampling, set weights to `1/n` (standard, unbiased). `false`
    /// keeps each copy's old weight (the authors' code), which sharpens the
    /// distribution further on every step.
    pub reset_weights: bool,
}

impl Default for ResamplePolicy {
    fn default() -> Self {
        ResamplePolicy {
            ess_fraction: 0.5,
            reset_weights: true,
        }
    }
}

impl ResamplePolicy {
    /// Whether the normalized set `ps` should be resampled now.
    pub fn due(&self, ps: &[Particle]) -> bool {
        !ps.is_empty() && ess(ps) < self.ess_fraction * ps.len() as f64
    }
}

/// Indices of `n` draws by systematic resampling from normalized weights:
/// one uniform offset, then evenly spaced pointers, O(n + m). A particle of
/// weight `w` is drawn `floor(n w)` or `ceil(n w)` times.
pub fn systematic_indices<R: Rng>(weights: &[f64], n: usize, rng: &mut R) -> Vec<usize> {
    let mut out = Vec::with_capacity(n);
    if weights.is_empty() || n == 0 {
        return out;
    }
    let total: f64 = weights.iter().sum();
    let step = total / n as f64;
    let mut u = rng.random::<f64>() * step;
    let mut c = weights[0];
    let mut i = 0;
    for _ in 0..n {
        while u > c && i + 1 < weights.len() {
            i += 1;
            c += weights[i];
        }
        out.push(i);
        u += step;
    }
    out
}

/// Replaces `ps` by `n` systematic draws from it. Weights become `1/n`
/// when `reset_weights`, else copies keep their weight and the set is
/// renormalized.
pub fn resample<R: Rng>(ps: &mut Vec<Particle>, n: usize, reset_weights: bool, rng: &mut R) {
    let w: Vec<f64> = ps.iter().map(|p| p.weight).collect();
    let idx = systematic_indices(&w, n, rng);
    let new: Vec<Particle> = idx.iter().map(|&i| ps[i]).collect();
    *ps = new;
    if reset_weights {
        set_uniform(ps);
    } else {
        super::particles::normalize(ps);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn systematic_counts_are_floor_or_ceil() {
        let w = [0.1, 0.45, 0.05, 0.4];
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for n in [7, 20, 101] {
            let idx = systematic_indices(&w, n, &mut rng);
            assert_eq!(idx.len(), n);
            for (k, wk) in w.iter().enumerate() {
                let c = idx.iter().filter(|&&i| i == k).count() as f64;
                let e = wk * n as f64;
                assert!(
                    c >= e.floor() - 1e-9 && c <= e.ceil() + 1e-9,
                    "{k}: {c} vs {e}"
                );
            }
        }
    }

    /// Resampling keeps the distribution: over many repetitions with
    /// random weights, the counts per particle follow n w (chi-square with
    /// 49 degrees of freedom well below its 0.999 quantile, 85.4).
    #[test]
    fn resampling_keeps_the_distribution() {
        let mut rng = ChaCha8Rng::seed_from_u64(10);
        let m = 50;
        let w: Vec<f64> = (0..m).map(|_| rng.random::<f64>().powi(3)).collect();
        let s: f64 = w.iter().sum();
        let w: Vec<f64> = w.iter().map(|x| x / s).collect();
        let mut counts = vec![0usize; m];
        let (n, reps) = (37, 400);
        for _ in 0..reps {
            for i in systematic_indices(&w, n, &mut rng) {
                counts[i] += 1;
            }
        }
        let total = (n * reps) as f64;
        let chi2: f64 = counts
            .iter()
            .zip(&w)
            .filter(|(_, wk)| **wk * total > 5.0)
            .map(|(&c, wk)| (c as f64 - wk * total).powi(2) / (wk * total))
            .sum();
        // Systematic resampling has lower variance than multinomial, so the
        // statistic is typically far below the multinomial quantile.
        assert!(chi2 < 85.4, "chi2 = {chi2}");
        // And a wrong sampler (uniform indices) would fail it.
        let uni: f64 = w
            .iter()
            .filter(|wk| **wk * total > 5.0)
            .map(|wk| (total / m as f64 - wk * total).powi(2) / (wk * total))
            .sum();
        assert!(uni > 85.4);
    }

    #[test]
    fn policy_and_reset() {
        let p = crate::geometry::level_camera(nalgebra::Vector3::zeros(), 0.0);
        let mut ps = vec![
            Particle::new(p, 0.97),
            Particle::new(p, 0.01),
            Particle::new(p, 0.02),
        ];
        let pol = ResamplePolicy::default();
        assert!(pol.due(&ps));
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        resample(&mut ps, 5, true, &mut rng);
        assert_eq!(ps.len(), 5);
        assert!(ps.iter().all(|p| (p.weight - 0.2).abs() < 1e-12));
        assert!(!pol.due(&ps));
    }
}
