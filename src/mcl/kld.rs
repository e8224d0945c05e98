//! KLD-sampling (Fox 2003): the number of particles that keeps the
//! Kullback-Leibler divergence between the sample-based and the true
//! posterior below `epsilon` with probability `1 - delta`, given the number
//! of histogram bins (over x, y, yaw) the particles occupy.

use rand::Rng;
use rustc_hash::FxHashSet;

use super::particles::{Particle, yaw};

/// Parameters of the adaptive particle count.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KldParams {
    /// Bound on the KL divergence (AMCL default 0.01).
    pub epsilon: f64,
    /// Upper standard normal quantile of `1 - delta` (AMCL: 0.99 -> 2.326).
    pub z: f64,
    /// Bin size for x and y, metres.
    pub bin_xy: f64,
    /// Bin size for yaw, radians.
    pub bin_yaw: f64,
    pub min_particles: usize,
    pub max_particles: usize,
}

impl KldParams {
    /// Checks the parameters: bounds and bins finite and above 0,
    /// `1 <= min_particles <= max_particles <=` [`super::MAX_COUNT`].
    pub fn validate(&self) -> Result<(), super::MclError> {
        for (name, v) in [
            ("kld.epsilon", self.epsilon),
            ("kld.z", self.z),
            ("kld.bin_xy", self.bin_xy),
            ("kld.bin_yaw", self.bin_yaw),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(super::MclError::BadParam {
                    name,
                    why: format!("must be finite and above 0, got {v}"),
                });
            }
        }
        let (lo, hi) = (self.min_particles, self.max_particles);
        if !(1 <= lo && lo <= hi && hi <= super::MAX_COUNT) {
            return Err(super::MclError::BadParam {
                name: "kld.min_particles",
                why: format!(
                    "must have 1 <= min_particles <= max_particles <= {}, got {lo} and {hi}",
                    super::MAX_COUNT
                ),
            });
        }
        Ok(())
    }
}

impl Default for KldParams {
    fn default() -> Self {
        KldParams {
            epsilon: 0.01,
            z: 2.326,
            bin_xy: 0.5,
            bin_yaw: 10f64.to_radians(),
            min_particles: 256,
            max_particles: 4096,
        }
    }
}

/// Particles needed for `bins` occupied bins (Wilson-Hilferty form),
/// clamped to `[min, max]`.
pub fn required(bins: usize, p: &KldParams) -> usize {
    if bins <= 1 {
        return p.min_particles;
    }
    let k = (bins - 1) as f64;
    let a = 2.0 / (9.0 * k);
    let n = k / (2.0 * p.epsilon) * (1.0 - a + a.sqrt() * p.z).powi(3);
    (n.ceil() as usize).clamp(p.min_particles, p.max_particles.max(p.min_particles))
}

fn bin(q: &Particle, p: &KldParams) -> (i64, i64, i64) {
    let t = q.pose.translation.vector;
    (
        (t.x / p.bin_xy).floor() as i64,
        (t.y / p.bin_xy).floor() as i64,
        (yaw(&q.pose) / p.bin_yaw).floor() as i64,
    )
}

/// The particle count for the next resampling of the normalized set `ps`,
/// by the KLD-sampling procedure: draw from the weighted set one particle
/// at a time, count the bins the draws occupy, stop once the count reaches
/// the bound for those bins. Bins thus reflect the posterior (after
/// weighing), not the spread of the prediction.
pub fn particle_count<R: Rng>(ps: &[Particle], p: &KldParams, rng: &mut R) -> usize {
    let max = p.max_particles.max(p.min_particles);
    if ps.is_empty() {
        return p.min_particles;
    }
    let mut cum = Vec::with_capacity(ps.len());
    let mut acc = 0.0;
    for q in ps {
        acc += q.weight.max(0.0);
        cum.push(acc);
    }
    if !(acc.is_finite() && acc > 0.0) {
        return max;
    }
    let mut bins = FxHashSet::default();
    let mut n = 0;
    while n < max {
        let u = rng.random::<f64>() * acc;
        let i = cum.partition_point(|&c| c < u).min(ps.len() - 1);
        bins.insert(bin(&ps[i], p));
        n += 1;
        if n >= required(bins.len(), p) {
            break;
        }
    }
    n.max(p.min_particles)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_published_formula() {
        // Fox 2003, eq. 13 with k = 100 bins, epsilon 0.05, z = 2.326
        // (delta 0.01): hand-computed 99/(0.1) * (1 - 2/891 + sqrt(2/891) 2.326)^3.
        let p = KldParams {
            epsilon: 0.05,
            min_particles: 1,
            max_particles: 1_000_000,
            ..Default::default()
        };
        let a: f64 = 2.0 / 891.0;
        let want = (990.0 * (1.0 - a + a.sqrt() * 2.326).powi(3)).ceil() as usize;
        assert_eq!(required(100, &p), want);
        assert!((1340..1350).contains(&want), "{want}");
        assert_eq!(required(1, &p), 1);
        // More bins need more particles.
        assert!(required(1000, &p) > required(100, &p));
    }

    #[test]
    fn concentrated_sets_need_fewer_particles() {
        use crate::geometry::level_camera;
        use nalgebra::Vector3;
        use rand::SeedableRng;
        let p = KldParams {
            min_particles: 10,
            max_particles: 100_000,
            ..Default::default()
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        // 1000 particles on a 10 m x 10 m x 360 degree grid: about 7200
        // bins would be occupied; the count reaches the maximum bound.
        let spread: Vec<Particle> = (0..1000)
            .map(|i| {
                let (x, y) = ((i % 40) as f64 * 0.25, (i / 40) as f64 * 0.4);
                Particle::new(level_camera(Vector3::new(x, y, 1.0), i as f64), 1e-3)
            })
            .collect();
        let wide = particle_count(&spread, &p, &mut rng);
        // The same set with all weight on one particle: one bin.
        let mut peaked = spread.clone();
        peaked.iter_mut().for_each(|q| q.weight = 0.0);
        peaked[7].weight = 1.0;
        assert_eq!(particle_count(&peaked, &p, &mut rng), 10);
        assert!(wide > 5000, "{wide}");
    }
}
