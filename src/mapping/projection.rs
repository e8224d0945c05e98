//! Labelled points projected into a camera: the ground-truth label images
//! of a real sequence (the paper's GT setting on SemanticKITTI), made from
//! its labelled, aggregated LiDAR map seen from camera 2 at each pose.
//!
//! Each point within `max_range` of the camera and in front of it is
//! projected with the pinhole intrinsics and drawn as a square splat whose
//! side follows the point spacing at its depth (`fx * spacing / z` pixels,
//! at least one pixel, at most `max_splat`), so a surface sampled every
//! `spacing` metres covers the image without holes; a z-buffer keeps the
//! nearest point at every pixel (occlusion). Pixels no point reaches get
//! label 0 (SemanticKITTI "unlabeled"; the sky, beyond-range and
//! never-scanned parts of the image). No I/O here; `omcl map project`
//! reads the sequence and writes the images.

use nalgebra::{Point3, Vector3};

use crate::geometry::{Intrinsics, Pose};

/// How points become pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectionParams {
    /// Points farther than this from the camera are left out, metres.
    pub max_range: f64,
    /// Points nearer than this (in front of the camera) are left out.
    pub near: f64,
    /// Spacing of the points on a surface, metres (the map's voxel size or
    /// the down-sampling of the aggregated cloud): sizes the splats.
    pub spacing: f64,
    /// Largest splat side, pixels (bounds the cost of very near points).
    pub max_splat: u32,
}

impl Default for ProjectionParams {
    fn default() -> Self {
        ProjectionParams {
            max_range: 80.0,
            near: 0.5,
            spacing: 0.1,
            max_splat: 32,
        }
    }
}

/// Points bucketed on a horizontal grid, so that a frame looks only at the
/// buckets within its range, not at the whole (kilometres long) cloud.
#[derive(Debug, Clone)]
pub struct PointIndex {
    cell: f64,
    buckets: rustc_hash::FxHashMap<(i64, i64), Vec<u32>>,
}

impl PointIndex {
    /// Buckets of `cell` metres over the x-y plane of `points`.
    pub fn new(points: &[[f64; 3]], cell: f64) -> Self {
        let mut buckets: rustc_hash::FxHashMap<(i64, i64), Vec<u32>> = Default::default();
        for (i, p) in points.iter().enumerate() {
            let key = ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64);
            buckets.entry(key).or_default().push(i as u32);
        }
        PointIndex { cell, buckets }
    }

    /// Indices of the points whose bucket touches the disk of `radius`
    /// about `centre` (x, y): a superset of the points within `radius`.
    pub fn near(&self, centre: &Vector3<f64>, radius: f64) -> Vec<u32> {
        let lo = |c: f64| ((c - radius) / self.cell).floor() as i64;
        let hi = |c: f64| ((c + radius) / self.cell).floor() as i64;
        let mut out = Vec::new();
        for bx in lo(centre.x)..=hi(centre.x) {
            for by in lo(centre.y)..=hi(centre.y) {
                if let Some(b) = self.buckets.get(&(bx, by)) {
                    out.extend_from_slice(b);
                }
            }
        }
        out.sort_unstable();
        out
    }
}

/// The label image (`width x height`, row-major, 0 where no point lands)
/// of the points `candidates` of `points` (with `labels`) seen by a camera
/// at `world_from_camera` with intrinsics `k`.
pub fn project_labels(
    points: &[[f64; 3]],
    labels: &[u32],
    candidates: &[u32],
    world_from_camera: &Pose,
    k: &Intrinsics,
    params: &ProjectionParams,
) -> Vec<u32> {
    let (w, h) = (k.width as usize, k.height as usize);
    let mut depth = vec![f64::INFINITY; w * h];
    let mut out = vec![0u32; w * h];
    let camera_from_world = world_from_camera.inverse();
    let origin = world_from_camera.translation.vector;
    let r2 = params.max_range * params.max_range;
    for &i in candidates {
        let p = Vector3::from(points[i as usize]);
        if (p - origin).norm_squared() > r2 {
            continue;
        }
        let q = camera_from_world * Point3::from(p);
        if q.z < params.near {
            continue;
        }
        let Some((u, v)) = k.project(&q) else {
            continue;
        };
        let side = (k.fx * params.spacing / q.z)
            .ceil()
            .clamp(1.0, params.max_splat.max(1) as f64);
        let half = side / 2.0;
        // Pixels p whose centres p + 0.5 fall in (u - half, u + half]: for a
        // one-pixel splat, the pixel the point lies in.
        let first = |c: f64| ((c - half - 0.5).floor() + 1.0).max(0.0);
        let end = |c: f64, n: usize| ((c + half - 0.5).floor() + 1.0).min(n as f64);
        let (u0, u1) = (first(u), end(u, w));
        let (v0, v1) = (first(v), end(v, h));
        if u0 >= u1 || v0 >= v1 {
            continue;
        }
        let label = labels[i as usize];
        for py in v0 as usize..v1 as usize {
            for px in u0 as usize..u1 as usize {
                let j = py * w + px;
                if q.z < depth[j] {
                    depth[j] = q.z;
                    out[j] = label;
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    /// A camera at the origin looking along world +z (camera = world axes).
    fn camera() -> (Pose, Intrinsics) {
        let k = Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 50.0,
            cy: 40.0,
            width: 100,
            height: 80,
        };
        (Pose::identity(), k)
    }

    fn all(n: usize) -> Vec<u32> {
        (0..n as u32).collect()
    }

    #[test]
    fn a_point_lands_on_its_hand_computed_pixel_with_a_one_pixel_splat() {
        let (pose, k) = camera();
        // (1, -0.5, 10): u = 100 * 1 / 10 + 50 = 60, v = 100 * -0.5 / 10 +
        // 40 = 35; spacing 0.05 m at 10 m is 0.5 px: one pixel, the one
        // whose centre (60.5, 35.5) is nearest: (60, 35) holds u in [60, 61).
        let params = ProjectionParams {
            spacing: 0.05,
            ..Default::default()
        };
        let pts = [[1.0, -0.5, 10.0]];
        let img = project_labels(&pts, &[40], &all(1), &pose, &k, &params);
        let hit: Vec<usize> = (0..img.len()).filter(|&j| img[j] != 0).collect();
        assert_eq!(hit, vec![35 * 100 + 60]);
        assert_eq!(img[35 * 100 + 60], 40);
    }

    #[test]
    fn splats_follow_depth_and_the_nearest_point_wins() {
        let (pose, k) = camera();
        let params = ProjectionParams {
            spacing: 0.2,
            ..Default::default()
        };
        // Both on the optical axis: u = 50, v = 40. At 5 m a 0.2 m spacing
        // is 4 px: pixels 48..52 x 38..42 (16). At 2 m it is 10 px:
        // pixels 45..55 x 35..45 (100), and the nearer point (label 50)
        // covers the farther one (label 40) wherever both land.
        let pts = [[0.0, 0.0, 5.0], [0.0, 0.0, 2.0]];
        let far = project_labels(&pts[..1], &[40], &all(1), &pose, &k, &params);
        assert_eq!(far.iter().filter(|&&l| l == 40).count(), 16);
        assert_eq!(far[38 * 100 + 48], 40);
        assert_eq!(far[41 * 100 + 51], 40);
        assert_eq!(far[42 * 100 + 52], 0);
        let both = project_labels(&pts, &[40, 50], &all(2), &pose, &k, &params);
        assert_eq!(both.iter().filter(|&&l| l == 50).count(), 100);
        assert_eq!(both.iter().filter(|&&l| l == 40).count(), 0);
        // Order does not matter: the far point drawn last stays hidden.
        let rev = [[0.0, 0.0, 2.0], [0.0, 0.0, 5.0]];
        let both2 = project_labels(&rev, &[50, 40], &all(2), &pose, &k, &params);
        assert_eq!(both, both2);
    }

    #[test]
    fn points_behind_too_near_or_too_far_are_left_out() {
        let (pose, k) = camera();
        let params = ProjectionParams::default();
        let pts = [[0.0, 0.0, -5.0], [0.0, 0.0, 0.2], [0.0, 0.0, 90.0]];
        let img = project_labels(&pts, &[1, 2, 3], &all(3), &pose, &k, &params);
        assert!(img.iter().all(|&l| l == 0));
        // Only candidates are drawn.
        let img = project_labels(&[[0.0, 0.0, 5.0]], &[7], &[], &pose, &k, &params);
        assert!(img.iter().all(|&l| l == 0));
    }

    #[test]
    fn a_moved_camera_sees_the_point_where_its_pose_says() {
        let (_, k) = camera();
        // Camera 3 m along world x, turned 90 degrees about y (its +z along
        // world +x): the world point (8, 0, 0) is 5 m straight ahead.
        let pose = Pose::from_parts(
            Translation3::new(3.0, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2),
        );
        let params = ProjectionParams {
            spacing: 0.01,
            ..Default::default()
        };
        let img = project_labels(&[[8.0, 0.0, 0.0]], &[9], &all(1), &pose, &k, &params);
        assert_eq!(img[40 * 100 + 50], 9);
        assert_eq!(img.iter().filter(|&&l| l != 0).count(), 1);
    }

    #[test]
    fn the_index_returns_every_point_within_the_radius() {
        let pts: Vec<[f64; 3]> = (0..400)
            .map(|i| {
                [
                    (i % 20) as f64 * 7.0 - 60.0,
                    (i / 20) as f64 * 7.0 - 60.0,
                    1.0,
                ]
            })
            .collect();
        let idx = PointIndex::new(&pts, 25.0);
        let c = Vector3::new(3.0, -4.0, 0.0);
        let near = idx.near(&c, 30.0);
        for (i, p) in pts.iter().enumerate() {
            let d = ((p[0] - c.x).powi(2) + (p[1] - c.y).powi(2)).sqrt();
            if d <= 30.0 {
                assert!(
                    near.binary_search(&(i as u32)).is_ok(),
                    "point {i} at {d} m"
                );
            }
        }
        assert!(near.len() < pts.len());
    }
}
