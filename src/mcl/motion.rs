//! Motion model: every particle composes the odometry increment with its own
//! noise, drawn in its local frame.
//!
//! The increment is `prev_camera_from_camera` (the relative motion between
//! consecutive frames in the previous camera frame), so the prediction is
//! `world_from_camera = world_from_prev * increment * noise`.

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;

use super::MclError;
use super::particles::Particle;
use crate::geometry::Pose;

/// Which degrees of freedom the noise perturbs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum MotionMode {
    /// Ground robots: noise in x, y (horizontal, in the particle's heading
    /// frame) and yaw (about world z); height, roll and pitch follow the
    /// odometry exactly.
    #[default]
    Planar,
    /// Noise on all six degrees of freedom, in the camera frame.
    Full,
    /// Cars on sloped roads: the planar noise (x, y in the heading frame,
    /// yaw about world z) plus small noise on height
    /// ([`ROAD_VERTICAL_FRACTION`] of the translation sigma) and on pitch
    /// and roll about the camera's x and z axes ([`ROAD_TILT_FRACTION`] of
    /// the rotation sigma), so the filter can follow a road that climbs and
    /// pitches (KITTI 00) without spending particles on free 6-DoF noise.
    Road,
}

/// Height noise of [`MotionMode::Road`] as a fraction of
/// `sigma_translation` (0.02 m at the paper's 0.10 m).
pub const ROAD_VERTICAL_FRACTION: f64 = 0.2;

/// Pitch and roll noise of [`MotionMode::Road`] as a fraction of
/// `sigma_rotation` (0.6 degrees at the paper's 6).
pub const ROAD_TILT_FRACTION: f64 = 0.1;

/// Odometry composition with Gaussian noise per step.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MotionModel {
    pub mode: MotionMode,
    /// Standard deviation of the translation noise per axis and step, metres
    /// (paper: 0.10).
    pub sigma_translation: f64,
    /// Standard deviation of the rotation noise per axis and step, radians
    /// (paper: 6 degrees).
    pub sigma_rotation: f64,
}

impl Default for MotionModel {
    fn default() -> Self {
        MotionModel {
            mode: MotionMode::Planar,
            sigma_translation: 0.10,
            sigma_rotation: 6f64.to_radians(),
        }
    }
}

/// Checks that every entry of a pose is finite and the rotation is unit.
pub fn check_pose(p: &Pose) -> Result<(), MclError> {
    let q = p.rotation.coords;
    let ok = p.translation.vector.iter().all(|v| v.is_finite())
        && q.iter().all(|v| v.is_finite())
        && (q.norm() - 1.0).abs() < 1e-6;
    if ok {
        Ok(())
    } else {
        Err(MclError::BadOdometry(format!(
            "translation {:?}, quaternion (x y z w) {:?}",
            p.translation.vector.as_slice(),
            q.as_slice()
        )))
    }
}

impl MotionModel {
    /// Checks the sigmas: finite, at least 0, at most 10 km and a full
    /// turn (`1e300` ran and wrote poses of null).
    pub fn validate(&self) -> Result<(), MclError> {
        for (name, v, most) in [
            ("motion.sigma_translation", self.sigma_translation, 1e4),
            (
                "motion.sigma_rotation",
                self.sigma_rotation,
                std::f64::consts::TAU,
            ),
        ] {
            if !(v.is_finite() && (0.0..=most).contains(&v)) {
                return Err(MclError::BadParam {
                    name,
                    why: format!("must be finite, in [0, {most}], got {v}"),
                });
            }
        }
        Ok(())
    }

    /// Moves every particle by `increment` plus its own noise. Fails (and
    /// leaves the particles untouched) when the increment is not finite.
    pub fn predict<R: Rng>(
        &self,
        particles: &mut [Particle],
        increment: &Pose,
        rng: &mut R,
    ) -> Result<(), MclError> {
        check_pose(increment)?;
        self.validate()?;
        for p in particles.iter_mut() {
            p.pose = self.sample(&p.pose, increment, rng);
        }
        Ok(())
    }

    /// One noisy successor of `world_from_prev`.
    pub fn sample<R: Rng>(&self, world_from_prev: &Pose, increment: &Pose, rng: &mut R) -> Pose {
        let moved = world_from_prev * increment;
        let mut g = || -> f64 { rng.sample(StandardNormal) };
        match self.mode {
            MotionMode::Full => {
                let t = Vector3::new(g(), g(), g()) * self.sigma_translation;
                let r = Vector3::new(g(), g(), g()) * self.sigma_rotation;
                moved * Pose::from_parts(Translation3::from(t), UnitQuaternion::from_scaled_axis(r))
            }
            MotionMode::Planar | MotionMode::Road => {
                let (dx, dy, dyaw) = (
                    g() * self.sigma_translation,
                    g() * self.sigma_translation,
                    g() * self.sigma_rotation,
                );
                let (dz, tilt) = if self.mode == MotionMode::Road {
                    let t = ROAD_TILT_FRACTION * self.sigma_rotation;
                    (
                        g() * ROAD_VERTICAL_FRACTION * self.sigma_translation,
                        Vector3::new(g() * t, 0.0, g() * t),
                    )
                } else {
                    (0.0, Vector3::zeros())
                };
                let yaw = super::particles::yaw(&moved);
                let (s, c) = yaw.sin_cos();
                // Forward/left noise in the heading frame, expressed in world.
                let offset = Vector3::new(c * dx - s * dy, s * dx + c * dy, dz);
                let spin = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), dyaw);
                // Pitch and roll in the camera frame (camera x and z).
                let tilt = UnitQuaternion::from_scaled_axis(tilt);
                Pose::from_parts(
                    Translation3::from(moved.translation.vector + offset),
                    spin * moved.rotation * tilt,
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::level_camera;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn noiseless_motion_is_composition() {
        let m = MotionModel {
            sigma_translation: 0.0,
            sigma_rotation: 0.0,
            ..Default::default()
        };
        let start = level_camera(Vector3::new(1.0, 2.0, 1.5), 0.3);
        // One metre forward (camera z) and a turn.
        let inc = Pose::from_parts(
            Translation3::new(0.0, 0.0, 1.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.2),
        );
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for mode in [MotionMode::Planar, MotionMode::Full, MotionMode::Road] {
            let m = MotionModel { mode, ..m };
            let p = m.sample(&start, &inc, &mut rng);
            let want = start * inc;
            assert!((p.translation.vector - want.translation.vector).norm() < 1e-12);
            assert!(p.rotation.angle_to(&want.rotation) < 1e-12);
            let expect_xy = Vector3::new(1.0 + 0.3f64.cos(), 2.0 + 0.3f64.sin(), 1.5);
            assert!((p.translation.vector - expect_xy).norm() < 1e-12);
        }
    }

    #[test]
    fn planar_noise_keeps_height_roll_pitch_and_has_the_right_spread() {
        let m = MotionModel::default();
        let start = level_camera(Vector3::new(0.0, 0.0, 1.5), 1.0);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let n = 20000;
        let (mut sx, mut sy, mut syaw) = (0.0, 0.0, 0.0);
        for _ in 0..n {
            let p = m.sample(&start, &Pose::identity(), &mut rng);
            assert!((p.translation.z - 1.5).abs() < 1e-12);
            // Optical axis stays horizontal: no roll or pitch.
            assert!((p.rotation * Vector3::z()).z.abs() < 1e-12);
            assert!((p.rotation * Vector3::y() + Vector3::z()).norm() < 1e-12);
            sx += p.translation.x.powi(2);
            sy += p.translation.y.powi(2);
            let dyaw = super::super::particles::yaw(&p) - 1.0;
            syaw += dyaw.powi(2);
        }
        let sd = |s: f64| (s / n as f64).sqrt();
        assert!((sd(sx) - 0.10).abs() < 0.004, "{}", sd(sx));
        assert!((sd(sy) - 0.10).abs() < 0.004, "{}", sd(sy));
        assert!((sd(syaw) - 6f64.to_radians()).abs() < 0.004);
    }

    #[test]
    fn road_noise_adds_small_height_and_tilt_noise_to_planar() {
        let m = MotionModel {
            mode: MotionMode::Road,
            ..Default::default()
        };
        let start = level_camera(Vector3::new(0.0, 0.0, 1.5), 1.0);
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let n = 20000;
        let (mut sx, mut sz, mut spitch, mut syaw) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..n {
            let p = m.sample(&start, &Pose::identity(), &mut rng);
            sx += p.translation.x.powi(2);
            sz += (p.translation.z - 1.5).powi(2);
            // Pitch: elevation of the optical axis.
            spitch += (p.rotation * Vector3::z()).z.asin().powi(2);
            let dyaw = super::super::particles::yaw(&p) - 1.0;
            syaw += dyaw.powi(2);
        }
        let sd = |s: f64| (s / n as f64).sqrt();
        assert!((sd(sx) - 0.10).abs() < 0.004, "{}", sd(sx));
        assert!((sd(sz) - 0.02).abs() < 0.001, "{}", sd(sz));
        let tilt = 0.6f64.to_radians();
        assert!((sd(spitch) - tilt).abs() < 0.05 * tilt, "{}", sd(spitch));
        assert!((sd(syaw) - 6f64.to_radians()).abs() < 0.004);
    }

    #[test]
    fn nan_odometry_is_an_error_and_changes_nothing() {
        let m = MotionModel::default();
        let start = level_camera(Vector3::zeros(), 0.0);
        let mut ps = vec![Particle::new(start, 1.0)];
        let bad = Pose::from_parts(
            Translation3::new(f64::NAN, 0.0, 0.0),
            UnitQuaternion::identity(),
        );
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        assert!(matches!(
            m.predict(&mut ps, &bad, &mut rng),
            Err(MclError::BadOdometry(_))
        ));
        assert_eq!(ps[0].pose, start);
    }
}
