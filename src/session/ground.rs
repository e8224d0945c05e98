//! A camera carried by a ground robot over a flat floor: its height, roll
//! and pitch stay as they were mounted, and only the robot's x, y and
//! heading change.
//!
//! The robot's *base* is a level frame at the camera (the camera's x, y and
//! heading, its image's y axis along the world's -z: [`level`]); the
//! [`Mount`] is the camera's rotation in it (identity for a level camera,
//! as on a floor plan; the start pose's pitch and roll for `omcl localize
//! --ground` and a session's [`super::SessionConfig::ground`]). Holding a
//! pose or an odometry increment to the ground ([`Mount::hold`],
//! [`Mount::hold_increment`]) levels the base and mounts the camera back
//! on it, so the odometry's horizontal motion and turn move the camera and
//! its drift in height, roll and pitch does not: every pose the session
//! composes stays at the start's height and tilt.

use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion};

use crate::geometry::Pose;

/// `world_from_camera` held level at height `z`: the camera's x, y and
/// heading (its optical axis projected on the floor; the image's up
/// direction for a camera looking straight up or down), its image's y axis
/// along the world's -z. A 2-D pose (x, y, yaw) is a camera carried level
/// at a known height, as a robot carries it; this is the 3-D pose it
/// stands for.
pub fn level(pose: &Pose, z: f64) -> Pose {
    let r = pose.rotation.to_rotation_matrix();
    let forward = r * nalgebra::Vector3::z();
    let up = r * -nalgebra::Vector3::y();
    let h = if forward.x.hypot(forward.y) > 1e-6 {
        forward
    } else {
        up
    };
    let heading = h.y.atan2(h.x);
    let (s, c) = heading.sin_cos();
    // Columns: camera x (right), y (down), z (forward) in the world.
    let m = Matrix3::new(s, 0.0, c, -c, 0.0, s, 0.0, -1.0, 0.0);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    let t = pose.translation.vector;
    Pose::from_parts(Translation3::new(t.x, t.y, z), rotation)
}

/// `prev_camera_from_camera` of a level camera, levelled: the increment's
/// motion along the camera's x and z axes (the floor, for a level camera)
/// and its turn about the camera's y axis, as [`level`] keeps them for a
/// camera levelled at the previous pose.
pub fn level_increment(increment: &Pose) -> Pose {
    // A level camera at the origin, heading along the world's x axis.
    let m = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    let prev = Pose::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m)),
    );
    prev.inverse() * level(&(prev * increment), 0.0)
}

/// The angle, degrees, between `pose`'s image y axis and the world's -z:
/// how far the camera is from level.
pub fn tilt_deg(pose: &Pose) -> f64 {
    let y = pose.rotation * nalgebra::Vector3::y();
    (-y.z).clamp(-1.0, 1.0).acos().to_degrees()
}

/// The camera's rotation in its robot's level base ([`level`]):
/// `base_from_camera`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mount {
    base_from_camera: Pose,
}

impl Mount {
    /// A level camera: its optical axis horizontal, its image upright.
    pub fn level() -> Self {
        Mount {
            base_from_camera: Pose::identity(),
        }
    }

    /// The mount of a camera at `world_from_camera`: its pitch and roll
    /// about its own heading.
    pub fn of(world_from_camera: &Pose) -> Self {
        let base = level(world_from_camera, world_from_camera.translation.vector.z);
        Mount {
            base_from_camera: Pose::from_parts(
                Translation3::identity(),
                base.rotation.inverse() * world_from_camera.rotation,
            ),
        }
    }

    /// The angle, degrees, between the camera and its level base.
    pub fn tilt_deg(&self) -> f64 {
        self.base_from_camera.rotation.angle().to_degrees()
    }

    /// `odom_from_camera` held to the ground: the base levelled at height
    /// 0 (its x, y and heading kept), the camera mounted back on it.
    pub fn hold(&self, odom_from_camera: &Pose) -> Pose {
        let m = &self.base_from_camera;
        level(&(odom_from_camera * m.inverse()), 0.0) * m
    }

    /// `prev_camera_from_camera` held to the ground: the base's increment
    /// levelled ([`level_increment`]), seen from the mounted camera.
    pub fn hold_increment(&self, increment: &Pose) -> Pose {
        let m = &self.base_from_camera;
        m.inverse() * level_increment(&(m * increment * m.inverse())) * m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{UnitQuaternion, Vector3};

    /// A level camera at heading `h` (radians from the world's x axis).
    fn camera(h: f64, z: f64) -> Pose {
        let (s, c) = h.sin_cos();
        let m = Matrix3::new(s, 0.0, c, -c, 0.0, s, 0.0, -1.0, 0.0);
        Pose::from_parts(
            Translation3::new(1.0, 2.0, z),
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m)),
        )
    }

    #[test]
    fn level_keeps_position_and_heading_and_drops_tilt() {
        for h in [0.0, 0.7, 2.0, -2.5] {
            let p = camera(h, 1.5);
            assert!(tilt_deg(&p) < 1e-6);
            // Forward along (cos h, sin h, 0), image y down.
            let f = p.rotation * Vector3::z();
            assert!((f - Vector3::new(h.cos(), h.sin(), 0.0)).norm() < 1e-12);
            // Level already: only the height changes.
            let l = level(&p, 1.2);
            assert!((l.translation.vector - Vector3::new(1.0, 2.0, 1.2)).norm() < 1e-12);
            assert!(l.rotation.angle_to(&p.rotation) < 1e-9);
            // Pitched down 20 degrees and rolled 5 (about the camera's x
            // and z axes): levelled back to the same heading.
            let tilted = Pose::from_parts(
                p.translation,
                p.rotation
                    * UnitQuaternion::from_euler_angles(-20f64.to_radians(), 0.0, 0.0)
                    * UnitQuaternion::from_euler_angles(0.0, 0.0, 5f64.to_radians()),
            );
            let t = tilt_deg(&tilted);
            assert!((t - 20.6).abs() < 0.1, "tilt {t}");
            let l = level(&tilted, 1.5);
            assert!(tilt_deg(&l) < 1e-6);
            assert!(l.rotation.angle_to(&p.rotation) < 1e-9, "heading {h}");
        }
        // Looking straight down with the image's top towards +y: heading +y.
        let down = Pose::from_parts(
            Translation3::new(0.0, 0.0, 1.0),
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(Matrix3::new(
                1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0,
            ))),
        );
        let l = level(&down, 1.0);
        let f = l.rotation * Vector3::z();
        assert!((f - Vector3::y()).norm() < 1e-9, "{f:?}");
    }

    #[test]
    fn levelled_increments_compose_like_levelled_poses() {
        // Two tilted poses of a camera that moves 0.3 m, turns 20 degrees,
        // and whose height, pitch and roll change on the way.
        let tilt = |p: Pose, pitch: f64, roll: f64, dz: f64| {
            Pose::from_parts(
                Translation3::from(p.translation.vector + Vector3::new(0.0, 0.0, dz)),
                p.rotation
                    * UnitQuaternion::from_euler_angles(pitch.to_radians(), 0.0, 0.0)
                    * UnitQuaternion::from_euler_angles(0.0, 0.0, roll.to_radians()),
            )
        };
        let a = tilt(camera(0.4, 1.5), 8.0, -3.0, 0.0);
        let mut b = tilt(camera(0.4 + 20f64.to_radians(), 1.5), -5.0, 4.0, 0.07);
        b.translation.vector += Vector3::new(0.2, -0.22, 0.0);
        // The levelled increment moves the levelled first pose onto the
        // levelled second (at the first's height).
        let inc = level_increment(&(a.inverse() * b));
        let moved = level(&a, 1.5) * inc;
        let want = level(&b, 1.5);
        // Not exact: the increment is levelled in the first camera's
        // tilted frame; the tilts here are a few degrees.
        assert!(
            (moved.translation.vector - want.translation.vector).norm() < 0.02,
            "{moved:?} vs {want:?}"
        );
        assert!(moved.rotation.angle_to(&want.rotation) < 1.5f64.to_radians());
        assert!(tilt_deg(&moved) < 1e-6);
        // A level increment is kept.
        let flat = level(&a, 1.5).inverse() * level(&b, 1.5);
        let kept = level_increment(&flat);
        assert!((kept.translation.vector - flat.translation.vector).norm() < 1e-12);
        assert!(kept.rotation.angle_to(&flat.rotation) < 1e-9);
    }

    /// A camera pitched `pitch` and rolled `roll` degrees (about its own x
    /// and z axes) on a level base at heading `h`, height `z`.
    fn mounted(h: f64, z: f64, pitch: f64, roll: f64) -> Pose {
        let base = camera(h, z);
        Pose::from_parts(
            base.translation,
            base.rotation
                * UnitQuaternion::from_euler_angles(pitch.to_radians(), 0.0, 0.0)
                * UnitQuaternion::from_euler_angles(0.0, 0.0, roll.to_radians()),
        )
    }

    /// The world z of the camera's forward and image-y axes: its tilt
    /// against gravity, whatever its heading.
    fn gravity(p: &Pose) -> [f64; 2] {
        [(p.rotation * Vector3::z()).z, (p.rotation * Vector3::y()).z]
    }

    #[test]
    fn a_mount_is_the_tilt_on_a_level_base() {
        assert!(Mount::of(&camera(0.3, 1.2)).tilt_deg() < 1e-6);
        assert_eq!(Mount::level().tilt_deg(), 0.0);
        let p = mounted(0.7, 1.4, -12.0, 3.0);
        let m = Mount::of(&p);
        // Pitch and roll compose to 12.4 degrees.
        assert!((m.tilt_deg() - 12.36).abs() < 0.01, "{}", m.tilt_deg());
        // The base is the level camera at the pose's heading; base * mount
        // is the pose again.
        let again = level(&p, 1.4) * m.base_from_camera;
        assert!((again.translation.vector - p.translation.vector).norm() < 1e-12);
        assert!(again.rotation.angle_to(&p.rotation) < 1e-12);
    }

    #[test]
    fn holding_keeps_ground_motion_and_drops_drift() {
        let m = Mount::of(&mounted(0.0, 1.4, -12.0, 3.0));
        // A robot driving and turning on the floor: its mounted camera's
        // poses are held as they are (at height 0), and so are their
        // increments.
        let path: Vec<Pose> = (0..5)
            .map(|k| {
                let k = k as f64;
                let mut p = mounted(0.2 * k, 1.4, -12.0, 3.0);
                p.translation.vector += Vector3::new(0.3 * k, -0.1 * k * k, 0.0);
                p
            })
            .collect();
        for w in path.windows(2) {
            let held = m.hold(&w[1]);
            let mut want = w[1];
            want.translation.vector.z = 0.0;
            assert!((held.translation.vector - want.translation.vector).norm() < 1e-12);
            assert!(held.rotation.angle_to(&want.rotation) < 1e-9);
            let inc = w[0].inverse() * w[1];
            let kept = m.hold_increment(&inc);
            assert!((kept.translation.vector - inc.translation.vector).norm() < 1e-12);
            assert!(kept.rotation.angle_to(&inc.rotation) < 1e-9);
        }
        // The same path with odometry drift in height, pitch and roll: the
        // held poses and the poses composed from held increments keep the
        // start's height and tilt, and move as the robot does within the
        // drift's effect on heading.
        let drift = |p: &Pose, k: f64| {
            Pose::from_parts(
                Translation3::from(p.translation.vector + Vector3::new(0.0, 0.0, 0.04 * k)),
                p.rotation
                    * UnitQuaternion::from_euler_angles((2.0 * k).to_radians(), 0.0, 0.0)
                    * UnitQuaternion::from_euler_angles(0.0, 0.0, (-1.5 * k).to_radians()),
            )
        };
        let odom: Vec<Pose> = path
            .iter()
            .enumerate()
            .map(|(k, p)| drift(p, k as f64))
            .collect();
        let start = path[0];
        let mut composed = start;
        for (k, w) in odom.windows(2).enumerate() {
            let held = m.hold(&w[1]);
            assert!(held.translation.vector.z.abs() < 1e-12);
            let g = gravity(&held);
            let want = gravity(&start);
            assert!((g[0] - want[0]).abs() < 1e-9 && (g[1] - want[1]).abs() < 1e-9);
            composed *= m.hold_increment(&(w[0].inverse() * w[1]));
            assert!(
                (composed.translation.vector.z - 1.4).abs() < 1e-9,
                "step {k}"
            );
            let g = gravity(&composed);
            assert!((g[0] - want[0]).abs() < 1e-9 && (g[1] - want[1]).abs() < 1e-9);
            let truth = path[k + 1];
            let off = (composed.translation.vector - truth.translation.vector)
                .xy()
                .norm();
            assert!(off < 0.05, "step {k}: {off:.3} m off the robot's path");
        }
    }
}
