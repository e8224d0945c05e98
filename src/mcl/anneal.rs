//! Progressive correction: one frame's likelihood brought in over several
//! layers, the particles resampled and jittered between layers.
//!
//! With six degrees of freedom the motion noise spreads 1024 particles over
//! a six-dimensional volume each step (0.10 m and 6 degrees per axis, the
//! paper's sigmas), and the sharpened likelihood is much narrower than that
//! volume: few particles land where it is high, and the estimate is only as
//! good as the nearest of them. Progressive correction (Oudjane and Musso,
//! "Progressive correction for regularized particle filters", FUSION 2000;
//! the annealed particle filter of Deutscher et al., CVPR 2000, is the same
//! idea) weighs with the likelihood raised to a fraction of the exponent,
//! resamples, moves each copy by a small jitter (a fraction of the motion
//! noise) and weighs again with the rest of the exponent, so the second
//! layer's particles sit where the first layer found the likelihood high.
//! The exponents of the layers add up to the filter's own, so a frame
//! counts once; each extra layer casts every ray again.
//!
//! With [`Anneal::expand`] `m > 1` the first layer weighs `m` copies of
//! each particle, each moved by its own draw of the motion noise, on every
//! `m`-th sampled pixel: the same rays as a plain first layer, `m` times
//! the proposals, each scored more coarsely; the resampling before the
//! second layer returns to the filter's count, and the second layer casts
//! every pixel. On the 6-DoF block's tuning sequences 0-2 (OMCL_GT, 4096
//! particles x 512 rays, two layers; docs/table1.md, "6-DoF (3-D block)") APE RMSE 0.171 m
//! without, 0.166 / 0.162 / 0.162 / 0.160 m with m = 2 / 4 / 8 / 16, at 5.3
//! against 5.4 steps/s (m = 4); a third layer or a first share of 0.3 on
//! top of m = 4 gave 0.162 and 0.163. With the copies, the second layer
//! can have fewer particles and more rays each: 1024 particles x 2048 rays
//! (the paper's counts) with m = 16 gave 0.158 m (0.152 over sequences
//! 0-5, against 0.158 with 4096 x 512 and m = 4) at about 6.4 against 5.1
//! steps/s, and is the block's filter since 2026-11-26.

use rand::Rng;

use super::motion::MotionModel;
use super::particles::Particle;
use crate::geometry::Pose;

/// Layers of progressive correction (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Anneal {
    /// Layers a frame (2 or more; 1 is the plain filter).
    pub layers: u32,
    /// Fraction of the sharpening exponent the first layer uses; the rest
    /// is split evenly over the other layers.
    pub first: f64,
    /// Jitter before the second layer as a fraction of the motion model's
    /// sigmas (same degrees of freedom as the motion mode); before each
    /// later layer it shrinks by the same factor again (`jitter^k` before
    /// layer `k + 1`), as the set narrows.
    pub jitter: f64,
    /// Copies of each particle the first layer weighs (1: none): each
    /// copy gets its own motion noise, and the layer casts every
    /// `expand`-th sampled pixel only, so it costs what a plain first layer
    /// does; the resampling after it goes back to the filter's count. More
    /// proposals for the sharp 6-D likelihood, each scored more coarsely.
    #[serde(default = "one")]
    pub expand: u32,
}

fn one() -> u32 {
    1
}

/// Most copies [`Anneal::expand`] takes (the first layer's set is this
/// many times the filter's).
pub const MAX_EXPAND: u32 = 64;

/// Most layers a frame: each casts the pixels again (`--layers`).
pub const MAX_LAYERS: u32 = 8;

impl Default for Anneal {
    /// Two layers, half the exponent each, jitter a third of the motion
    /// noise (chosen on the 6-DoF block's tuning sequences 0-2; README).
    fn default() -> Self {
        Anneal {
            layers: 2,
            first: 0.5,
            jitter: 1.0 / 3.0,
            expand: 1,
        }
    }
}

impl Anneal {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=MAX_LAYERS).contains(&self.layers) {
            return Err(format!(
                "anneal.layers must be 1 to {MAX_LAYERS}, got {}",
                self.layers
            ));
        }
        if !(self.first.is_finite() && self.first > 0.0 && self.first <= 1.0) {
            return Err(format!(
                "anneal.first must be in (0, 1], got {}",
                self.first
            ));
        }
        if !(1..=MAX_EXPAND).contains(&self.expand) || (self.expand > 1 && self.layers < 2) {
            return Err(format!(
                "anneal.expand must be 1 to {MAX_EXPAND}, and 1 with one layer, got {} with {} layer(s)",
                self.expand, self.layers
            ));
        }
        if !(self.jitter.is_finite() && self.jitter >= 0.0) {
            return Err(format!(
                "anneal.jitter must be finite and >= 0, got {}",
                self.jitter
            ));
        }
        Ok(())
    }

    /// The exponent of each layer, as fractions of the filter's exponent:
    /// `first`, then `(1 - first) / (layers - 1)` each; they sum to 1.
    pub fn fractions(&self) -> Vec<f64> {
        let n = self.layers.max(1) as usize;
        if n == 1 {
            return vec![1.0];
        }
        let rest = (1.0 - self.first) / (n - 1) as f64;
        std::iter::once(self.first)
            .chain(std::iter::repeat_n(rest, n - 1))
            .collect()
    }

    /// Moves every particle by noise of `motion`'s kind with its sigmas
    /// scaled by `jitter^layer` (no odometry: the identity increment);
    /// `layer` 1 is the jitter before the second layer.
    pub fn jitter<R: Rng>(
        &self,
        layer: u32,
        motion: &MotionModel,
        particles: &mut [Particle],
        rng: &mut R,
    ) {
        let scale = self.jitter.powi(layer as i32);
        let m = MotionModel {
            sigma_translation: motion.sigma_translation * scale,
            sigma_rotation: motion.sigma_rotation * scale,
            ..*motion
        };
        let identity = Pose::identity();
        for p in particles {
            p.pose = m.sample(&p.pose, &identity, rng);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::level_camera;
    use crate::mcl::MotionMode;
    use nalgebra::Vector3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn fractions_sum_to_one() {
        let a = Anneal {
            layers: 3,
            first: 0.4,
            jitter: 0.2,
            expand: 1,
        };
        let f = a.fractions();
        assert_eq!(f.len(), 3);
        assert!((f[0] - 0.4).abs() < 1e-12 && (f[1] - 0.3).abs() < 1e-12);
        assert!((f.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert_eq!(Anneal { layers: 1, ..a }.fractions(), vec![1.0]);
    }

    #[test]
    fn jitter_is_the_scaled_motion_noise() {
        let motion = MotionModel {
            mode: MotionMode::Full,
            ..Default::default()
        };
        let a = Anneal {
            jitter: 0.25,
            ..Default::default()
        };
        let start = level_camera(Vector3::new(1.0, 2.0, 1.5), 0.4);
        let mut ps = vec![Particle::new(start, 1.0); 20000];
        a.jitter(1, &motion, &mut ps, &mut ChaCha8Rng::seed_from_u64(5));
        fn sd(ps: &[Particle], f: impl Fn(&Particle) -> f64) -> f64 {
            (ps.iter().map(|p| f(p).powi(2)).sum::<f64>() / ps.len() as f64).sqrt()
        }
        // 0.25 x 0.10 m on each axis, 0.25 x 6 degrees on each rotation axis.
        for k in 0..3 {
            let s = sd(&ps, |p| {
                p.pose.translation.vector[k] - start.translation.vector[k]
            });
            assert!((s - 0.025).abs() < 0.001, "axis {k}: {s}");
        }
        let s = sd(&ps, |p| p.pose.rotation.angle_to(&start.rotation));
        // The angle of a 3-D Gaussian rotation: RMS is sqrt(3) sigma.
        let want = 3f64.sqrt() * 0.25 * 6f64.to_radians();
        assert!((s - want).abs() < 0.02 * want, "{s} vs {want}");
        // Before the third layer the jitter has shrunk by the factor again.
        let mut ps = vec![Particle::new(start, 1.0); 20000];
        a.jitter(2, &motion, &mut ps, &mut ChaCha8Rng::seed_from_u64(6));
        let s = sd(&ps, |p| {
            p.pose.translation.vector[0] - start.translation.vector[0]
        });
        assert!((s - 0.00625).abs() < 0.0003, "layer 2: {s}");
        let bad = Anneal {
            first: 0.0,
            ..Default::default()
        };
        assert!(bad.validate().is_err());
        assert!(Anneal::default().validate().is_ok());
    }
}
