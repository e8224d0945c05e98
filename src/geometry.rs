//! Rays, camera intrinsics and pose conventions shared by every module.
//!
//! Conventions: world is right-handed, z up, metres. Camera frame is OpenCV
//! (x right, y down, z forward). Transforms are named by frames:
//! `world_from_camera * p_camera` gives a point in the world frame. Pixel
//! centres are at `(u + 0.5, v + 0.5)`.

use nalgebra::{Isometry3, Point3, Vector3};

/// A rigid transform, named by the frames it maps between
/// (`world_from_camera` maps camera coordinates to world coordinates).
pub type Pose = Isometry3<f64>;

/// A ray in a map's grid frame (world minus the map origin), single precision
/// as the ray casters use it. `dir` need not be unit length; distances `t` are
/// in units of `|dir|`, so a unit `dir` gives metres.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct Ray {
    pub origin: [f32; 3],
    pub dir: [f32; 3],
    /// Smallest accepted distance (0 for a camera ray).
    pub t_min: f32,
    /// Largest accepted distance (`f32::INFINITY` for no range limit).
    pub t_max: f32,
}

impl Ray {
    /// A ray from `origin` along `dir` with no range limit.
    pub fn new(origin: [f32; 3], dir: [f32; 3]) -> Self {
        Ray {
            origin,
            dir,
            t_min: 0.0,
            t_max: f32::INFINITY,
        }
    }

    /// Whether the ray can hit anything: finite origin and direction within
    /// `1e18` (Embree's limit), a non-zero direction, and bounds that are not
    /// NaN. Casters return a miss for any other ray.
    pub fn is_valid(&self) -> bool {
        const LARGE: f32 = 1e18;
        let ok = |v: &f32| v.is_finite() && v.abs() <= LARGE;
        self.origin.iter().all(ok)
            && self.dir.iter().all(ok)
            && self.dir.iter().any(|&v| v != 0.0)
            && !self.t_min.is_nan()
            && !self.t_max.is_nan()
    }

    /// The point at distance `t`.
    pub fn at(&self, t: f32) -> [f32; 3] {
        [
            self.origin[0] + t * self.dir[0],
            self.origin[1] + t * self.dir[1],
            self.origin[2] + t * self.dir[2],
        ]
    }
}

/// Pinhole intrinsics: focal lengths and principal point in pixels, image
/// size in pixels (file form: `fx fy cx cy width height`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub width: u32,
    pub height: u32,
}

/// Farthest a map's origin, or a point mapped into it, may lie from 0 in
/// any coordinate, metres: any place on Earth in any projection is within
/// it; beyond it voxel centres lose every digit (an origin of 1e308 made
/// them inf).
pub const MAX_COORDINATE_M: f64 = 1e9;

/// Largest image side a camera may have, pixels.
pub const MAX_IMAGE_SIDE: u32 = 16_384;

impl Intrinsics {
    /// Whether the numbers make a camera rays can be cast through: focal
    /// lengths finite in `[0.01, 1e7]` pixels (`1e300` and `1e-300` were
    /// taken and localized to nonsense), the principal point within an
    /// image's size of the image (`cx = 1e9` was taken), sides in `1..=`
    /// [`MAX_IMAGE_SIDE`]; the reason otherwise, for the caller to name its
    /// source.
    pub fn check(&self) -> Result<(), String> {
        for (name, f) in [("fx", self.fx), ("fy", self.fy)] {
            if !(f.is_finite() && (0.01..=1e7).contains(&f)) {
                return Err(format!(
                    "focal length {name} = {f:?} is not a finite number of pixels in 0.01..=1e7"
                ));
            }
        }
        for (name, side) in [("width", self.width), ("height", self.height)] {
            if !(1..=MAX_IMAGE_SIDE).contains(&side) {
                return Err(format!(
                    "image {name} {side} is not in 1..={MAX_IMAGE_SIDE} pixels"
                ));
            }
        }
        for (name, c, side) in [("cx", self.cx, self.width), ("cy", self.cy, self.height)] {
            let side = side as f64;
            if !(c.is_finite() && (-side..=2.0 * side).contains(&c)) {
                return Err(format!(
                    "principal point {name} = {c:?} is not within an image's size of the \
                     {side}-pixel image (-{side}..={})",
                    2.0 * side
                ));
            }
        }
        Ok(())
    }

    /// Intrinsics of a square-pixel camera with horizontal field of view
    /// `hfov_deg` and the principal point at the image centre.
    pub fn from_hfov(width: u32, height: u32, hfov_deg: f64) -> Self {
        let f = 0.5 * width as f64 / (0.5 * hfov_deg.to_radians()).tan();
        Intrinsics {
            fx: f,
            fy: f,
            cx: 0.5 * width as f64,
            cy: 0.5 * height as f64,
            width,
            height,
        }
    }

    /// Unit direction, in the camera frame, of the ray through the centre of
    /// pixel `(u, v)`.
    pub fn pixel_dir(&self, u: u32, v: u32) -> Vector3<f64> {
        Vector3::new(
            (u as f64 + 0.5 - self.cx) / self.fx,
            (v as f64 + 0.5 - self.cy) / self.fy,
            1.0,
        )
        .normalize()
    }

    /// The camera-frame point at z-depth `z` (metres) seen through the
    /// centre of pixel `(u, v)`: the inverse of [`Intrinsics::project`].
    pub fn back_project(&self, u: u32, v: u32, z: f64) -> Point3<f64> {
        Point3::new(
            (u as f64 + 0.5 - self.cx) / self.fx * z,
            (v as f64 + 0.5 - self.cy) / self.fy * z,
            z,
        )
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Projects a camera-frame point to continuous pixel coordinates (pixel
    /// `(u, v)` spans `[u, u+1) x [v, v+1)`); `None` behind the camera.
    pub fn project(&self, p_camera: &Point3<f64>) -> Option<(f64, f64)> {
        if p_camera.z <= 0.0 {
            return None;
        }
        Some((
            self.fx * p_camera.x / p_camera.z + self.cx,
            self.fy * p_camera.y / p_camera.z + self.cy,
        ))
    }
}

/// `world_from_camera` of a level camera (no roll or pitch) at `position`
/// (world, metres) whose optical axis points along `yaw` radians from world
/// +x towards +y: camera z is forward, x right, y down (world -z).
pub fn level_camera(position: Vector3<f64>, yaw: f64) -> Pose {
    let (s, c) = yaw.sin_cos();
    let world_from_camera_rot = nalgebra::Matrix3::new(
        s, 0.0, c, //
        -c, 0.0, s, //
        0.0, -1.0, 0.0,
    );
    let rot = nalgebra::Rotation3::from_matrix_unchecked(world_from_camera_rot);
    Pose::from_parts(
        position.into(),
        nalgebra::UnitQuaternion::from_rotation_matrix(&rot),
    )
}

/// The camera ray through pixel `(u, v)` of a camera at `world_from_camera`,
/// expressed in the grid frame of a map whose origin is `map_origin`
/// (world coordinates of grid-frame zero).
pub fn camera_ray(
    intrinsics: &Intrinsics,
    world_from_camera: &Pose,
    map_origin: &Vector3<f64>,
    u: u32,
    v: u32,
) -> Ray {
    let d = world_from_camera.rotation * intrinsics.pixel_dir(u, v);
    let o = world_from_camera.translation.vector - map_origin;
    Ray::new(
        [o.x as f32, o.y as f32, o.z as f32],
        [d.x as f32, d.y as f32, d.z as f32],
    )
}

#[cfg(test)]
mod tests {

    #[test]
    fn cameras_rays_cannot_be_cast_through_are_refused() {
        let k = Intrinsics::from_hfov(640, 480, 60.0);
        k.check().unwrap();
        // An off-centre crop's principal point may lie outside the image.
        Intrinsics {
            cx: -300.0,
            cy: 900.0,
            ..k
        }
        .check()
        .unwrap();
        let bad = [
            (Intrinsics { fx: 1e300, ..k }, "fx"),
            (Intrinsics { fy: 1e-300, ..k }, "fy"),
            (Intrinsics { fx: f64::NAN, ..k }, "fx"),
            (Intrinsics { cx: 1e9, ..k }, "cx"),
            (Intrinsics { cy: -481.0, ..k }, "cy"),
            (
                Intrinsics {
                    cx: f64::INFINITY,
                    ..k
                },
                "cx",
            ),
            (Intrinsics { width: 0, ..k }, "width"),
            (
                Intrinsics {
                    height: 16_385,
                    ..k
                },
                "height",
            ),
        ];
        for (k, name) in bad {
            let e = k.check().unwrap_err();
            assert!(e.contains(name), "{e}");
        }
    }

    #[test]
    fn back_project_inverts_project_at_pixel_centres() {
        let k = Intrinsics::from_hfov(64, 48, 90.0);
        for (u, v, z) in [(0, 0, 1.0), (31, 20, 2.5), (63, 47, 0.3)] {
            let p = k.back_project(u, v, z);
            assert_eq!(p.z, z);
            let (x, y) = k.project(&p).unwrap();
            assert!((x - (u as f64 + 0.5)).abs() < 1e-9 && (y - (v as f64 + 0.5)).abs() < 1e-9);
        }
    }

    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn principal_pixel_looks_along_optical_axis() {
        let k = Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 50.0,
            cy: 40.0,
            width: 100,
            height: 80,
        };
        // Pixel (49, 39) has its centre at (49.5, 39.5): half a pixel off axis.
        let d = k.pixel_dir(49, 39);
        assert!((d.x + 0.005).abs() < 1e-4 && (d.y + 0.005).abs() < 1e-4);
        let (u, v) = k.project(&Point3::new(0.0, 0.0, 2.0)).unwrap();
        assert_eq!((u, v), (50.0, 40.0));
        assert!(k.project(&Point3::new(0.0, 0.0, -1.0)).is_none());
    }

    #[test]
    fn level_camera_axes() {
        let p = level_camera(Vector3::new(1.0, 2.0, 1.5), std::f64::consts::FRAC_PI_2);
        let fwd = p.rotation * Vector3::z();
        let right = p.rotation * Vector3::x();
        let down = p.rotation * Vector3::y();
        assert!((fwd - Vector3::y()).norm() < 1e-12, "{fwd}");
        assert!((right - Vector3::x()).norm() < 1e-12, "{right}");
        assert!((down + Vector3::z()).norm() < 1e-12, "{down}");
        assert_eq!(p.translation.vector, Vector3::new(1.0, 2.0, 1.5));
    }

    #[test]
    fn hfov_gives_the_expected_focal_length() {
        let k = Intrinsics::from_hfov(540, 540, 90.0);
        assert!((k.fx - 270.0).abs() < 1e-9);
    }

    #[test]
    fn camera_ray_is_in_grid_frame() {
        let k = Intrinsics::from_hfov(2, 2, 90.0);
        // Camera at (10, 0, 1) looking along world +x (z_cam -> x_world).
        let rot = UnitQuaternion::from_basis_unchecked(&[
            Vector3::new(0.0, -1.0, 0.0),
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(1.0, 0.0, 0.0),
        ]);
        let pose = Pose::from_parts(Translation3::new(10.0, 0.0, 1.0), rot);
        let r = camera_ray(&k, &pose, &Vector3::new(9.0, 0.0, 0.0), 1, 1);
        assert_eq!(r.origin, [1.0, 0.0, 1.0]);
        assert!(r.dir[0] > 0.5 && r.dir[1] < 0.0 && r.dir[2] < 0.0);
    }
}
