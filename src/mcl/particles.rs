//! Particles: hypotheses of `world_from_camera` with importance weights.

use crate::geometry::Pose;

/// One hypothesis of the camera pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Particle {
    /// `world_from_camera` (OpenCV camera, world z up, metres).
    pub pose: Pose,
    /// Importance weight; the filter keeps the set normalized (sum 1).
    pub weight: f64,
}

impl Particle {
    /// A particle of weight `weight` at `pose`.
    pub fn new(pose: Pose, weight: f64) -> Self {
        Particle { pose, weight }
    }
}

/// Normalizes weights to sum 1 and returns the sum before normalizing. A
/// set whose weights sum to zero or are not finite gets uniform weights
/// (returns 0): there is no information to keep.
pub fn normalize(ps: &mut [Particle]) -> f64 {
    let sum: f64 = ps.iter().map(|p| p.weight).sum();
    if !(sum.is_finite() && sum > 0.0) {
        set_uniform(ps);
        return 0.0;
    }
    ps.iter_mut().for_each(|p| p.weight /= sum);
    sum
}

/// Sets every weight to `1 / n`.
pub fn set_uniform(ps: &mut [Particle]) {
    let w = 1.0 / ps.len().max(1) as f64;
    ps.iter_mut().for_each(|p| p.weight = w);
}

/// Effective sample size `1 / sum w^2` of normalized weights: `n` for
/// uniform weights, 1 when one particle holds all the weight.
pub fn ess(ps: &[Particle]) -> f64 {
    let s2: f64 = ps.iter().map(|p| p.weight * p.weight).sum();
    if s2 > 0.0 { 1.0 / s2 } else { 0.0 }
}

/// Index of the particle with the largest weight.
pub fn best(ps: &[Particle]) -> Option<usize> {
    ps.iter()
        .enumerate()
        .max_by(|a, b| a.1.weight.total_cmp(&b.1.weight))
        .map(|(i, _)| i)
}

/// Heading of the camera's optical axis projected on the world xy plane,
/// radians from +x towards +y (the yaw of [`crate::geometry::level_camera`]).
pub fn yaw(pose: &Pose) -> f64 {
    let f = pose.rotation * nalgebra::Vector3::z();
    f.y.atan2(f.x)
}

/// Sorts particles so that neighbours in the slice are near in (x, y, yaw):
/// rays of consecutive particles through one pixel then travel together,
/// which makes ray casting cache friendly. `cell` is the position bin (m).
pub fn sort_spatially(ps: &mut [Particle], cell: f64) {
    let q = |v: f64, s: f64| ((v / s).floor() as i64 + (1 << 20)).clamp(0, (1 << 21) - 1) as u64;
    ps.sort_by_cached_key(|p| {
        let t = p.pose.translation.vector;
        // One yaw bin spans about as much image motion as one position bin
        // at 2 m range.
        let y = yaw(&p.pose) + std::f64::consts::PI;
        crate::morton::encode3(q(t.x, cell), q(t.y, cell), q(y, cell / 2.0))
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::level_camera;
    use nalgebra::Vector3;

    #[test]
    fn normalize_and_ess() {
        let p = level_camera(Vector3::zeros(), 0.0);
        let mut ps = vec![Particle::new(p, 1.0), Particle::new(p, 3.0)];
        assert_eq!(normalize(&mut ps), 4.0);
        assert_eq!(ps[1].weight, 0.75);
        // 1 / (1/16 + 9/16)
        assert!((ess(&ps) - 1.6).abs() < 1e-12);
        assert_eq!(best(&ps), Some(1));
        ps.iter_mut().for_each(|p| p.weight = 0.0);
        assert_eq!(normalize(&mut ps), 0.0);
        assert_eq!(ps[0].weight, 0.5);
        assert!((ess(&ps) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn yaw_of_level_camera() {
        for y in [-3.0, -1.0, 0.0, 0.5, 2.5] {
            let p = level_camera(Vector3::new(1.0, 2.0, 3.0), y);
            assert!((yaw(&p) - y).abs() < 1e-12);
        }
    }
}
