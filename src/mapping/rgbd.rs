//! Input option 1: posed depth frames with per-pixel features into voxels.

use nalgebra::Vector3;

use super::{FrameFeatures, IntegrationStats, MappingError, pixel_feature};
use crate::geometry::{Intrinsics, Pose};
use crate::map::Integrator;

/// Which pixels of a frame are used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameOptions {
    /// Depths outside `[min_depth, max_depth]` metres are skipped.
    pub min_depth: f32,
    pub max_depth: f32,
    /// Points above this world height (z, metres) are skipped: the authors
    /// crop the ceiling so that prompts and floor plans see the room.
    pub max_height: Option<f64>,
    /// Use every `stride`-th pixel in u and v (1 = all).
    pub stride: u32,
}

impl Default for FrameOptions {
    fn default() -> Self {
        FrameOptions {
            min_depth: 0.1,
            max_depth: 10.0,
            max_height: None,
            stride: 1,
        }
    }
}

/// Back-projects a z-depth image (`k.width x k.height`, metres, 0 invalid)
/// seen from `world_from_camera` and adds each used pixel's feature. A depth
/// image of another size than the intrinsics' is an error.
pub fn integrate_frame(
    integ: &mut Integrator,
    k: &Intrinsics,
    depth: &[f32],
    world_from_camera: &Pose,
    features: &dyn FrameFeatures,
    opt: &FrameOptions,
) -> Result<IntegrationStats, MappingError> {
    let want = k.width as usize * k.height as usize;
    if depth.len() != want {
        return Err(MappingError::DepthSize {
            got: depth.len(),
            want,
            width: k.width,
            height: k.height,
        });
    }
    let mut s = IntegrationStats::default();
    let stride = opt.stride.max(1);
    let mut buf = vec![0.0f32; features.dim()];
    for v in (0..k.height).step_by(stride as usize) {
        for u in (0..k.width).step_by(stride as usize) {
            s.offered += 1;
            let z = depth[v as usize * k.width as usize + u as usize];
            if !(z >= opt.min_depth && z <= opt.max_depth) {
                s.skipped += 1;
                continue;
            }
            let z = z as f64;
            let p: Vector3<f64> = (world_from_camera * k.back_project(u, v, z)).coords;
            if opt.max_height.is_some_and(|h| p.z > h) {
                s.skipped += 1;
                continue;
            }
            s.add(integ, &p, pixel_feature(features, u, v, &mut buf))?;
        }
    }
    Ok(s)
}

/// Invalidates (sets to 0) every depth pixel within `radius` pixels
/// (Chebyshev) of a depth edge: a pixel whose right or lower neighbour
/// differs by more than `max_jump` times the nearer depth, or borders a
/// pixel without depth. At such edges a depth sensor mixes foreground and
/// background, and a colour camera beside it (7-Scenes' Kinect: not
/// registered) sees the other side of the edge; dropping them keeps
/// colours off the wrong surface. `depth` is row-major `width x height`,
/// metres, 0 = none. Returns how many valid pixels were dropped.
pub fn drop_depth_edges(
    depth: &mut [f32],
    width: usize,
    height: usize,
    max_jump: f32,
    radius: usize,
) -> usize {
    if depth.len() != width * height || width == 0 {
        return 0;
    }
    let valid = |z: f32| z > 0.0 && z.is_finite();
    let mut edge = vec![false; depth.len()];
    for v in 0..height {
        for u in 0..width {
            let i = v * width + u;
            let z = depth[i];
            for (ok, j) in [(u + 1 < width, i + 1), (v + 1 < height, i + width)] {
                if !ok {
                    continue;
                }
                let n = depth[j];
                let cut = match (valid(z), valid(n)) {
                    (true, true) => (z - n).abs() > max_jump * z.min(n),
                    (false, false) => false,
                    _ => true,
                };
                if cut {
                    edge[i] = true;
                    edge[j] = true;
                }
            }
        }
    }
    // Dilate rows, then columns: a (2r+1)^2 square around each edge pixel.
    let r = radius;
    let mut rows = vec![false; edge.len()];
    for v in 0..height {
        let line = &edge[v * width..(v + 1) * width];
        for u in 0..width {
            let (a, b) = (u.saturating_sub(r), (u + r).min(width - 1));
            rows[v * width + u] = line[a..=b].iter().any(|&e| e);
        }
    }
    let mut dropped = 0;
    for v in 0..height {
        let (a, b) = (v.saturating_sub(r), (v + r).min(height - 1));
        for u in 0..width {
            if (a..=b).any(|w| rows[w * width + u]) && valid(depth[v * width + u]) {
                depth[v * width + u] = 0.0;
                dropped += 1;
            }
        }
    }
    dropped
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::level_camera;
    use crate::map::{FeatureDb, GridSpec};
    use crate::mapping::LabelImage;
    use crate::raycast::EmbreeCaster;
    use crate::scene::{RoomsConfig, rooms};

    #[test]
    fn depth_edges_are_dropped_with_their_neighbourhood() {
        // A 12 x 4 image: 1 m on the left, 2 m from column 6 on.
        let (w, h) = (12, 4);
        let mut d: Vec<f32> = (0..w * h)
            .map(|i| if i % w < 6 { 1.0 } else { 2.0 })
            .collect();
        let dropped = drop_depth_edges(&mut d, w, h, 0.05, 1);
        // Columns 5 and 6 are the edge; radius 1 adds 4 and 7.
        for (i, z) in d.iter().enumerate() {
            let gone = (4..=7).contains(&(i % w));
            assert_eq!(*z == 0.0, gone, "pixel {i}");
        }
        assert_eq!(dropped, 4 * h);
        // A smooth ramp (1 % a pixel) loses nothing.
        let mut ramp: Vec<f32> = (0..w * h).map(|i| 1.0 + 0.01 * (i % w) as f32).collect();
        assert_eq!(drop_depth_edges(&mut ramp, w, h, 0.05, 2), 0);
    }

    /// Renders depth and labels of `scene` with the ray caster, maps the
    /// frames back, and checks the voxels are where the surfaces are with
    /// the right rows.
    #[test]
    fn mapping_rendered_frames_recovers_the_scene() {
        let cfg = RoomsConfig {
            size_x: 8.0,
            size_y: 4.0,
            room_x: 4.0,
            room_y: 4.0,
            resolution: 0.1,
            ..RoomsConfig::default()
        };
        let scene = rooms(&cfg);
        let caster = EmbreeCaster::new(0.1, &scene.cells).unwrap();
        let k = Intrinsics::from_hfov(160, 120, 90.0);
        let nlabels = 3 + crate::scene::FURNITURE_KINDS as usize;
        let table: Vec<f32> = (0..nlabels)
            .flat_map(|i| (0..nlabels).map(move |j| if i == j { 1.0 } else { 0.0 }))
            .collect();
        let db = FeatureDb::from_rows(nlabels, 0.02, table).unwrap();
        let grid = GridSpec {
            resolution: 0.1,
            origin: Vector3::zeros(),
        };
        let mut integ = Integrator::new(grid, db).unwrap();
        let mut seen = rustc_hash::FxHashSet::default();
        let mut total = IntegrationStats::default();
        for (n, spot) in scene.free_spots.iter().enumerate() {
            for yaw in 0..8 {
                let pose = level_camera(
                    Vector3::new(spot[0], spot[1], 1.2),
                    yaw as f64 * std::f64::consts::FRAC_PI_4 + n as f64,
                );
                let view = crate::scene::render(&scene, &caster, &k, &pose);
                seen.extend(view.hits.iter().filter(|h| h.is_hit()).map(|h| h.leaf));
                let (depth, labels) = (view.depth, view.labels);
                let rows = |l: u32| (l != u32::MAX).then_some(l);
                let img = LabelImage::new(k.width, k.height, &labels, &rows).unwrap();
                total += integrate_frame(
                    &mut integ,
                    &k,
                    &depth,
                    &pose,
                    &img,
                    &FrameOptions::default(),
                )
                .unwrap();
            }
        }
        assert!(total.integrated > 100_000, "{total:?}");
        let m = integ.finish("t", 0.02).unwrap();
        // Points on a voxel face may fall into the empty voxel in front of
        // it, so "where the surfaces are" means within one cell of a surface
        // voxel, and "the right row" means the class of such a voxel.
        let truth: rustc_hash::FxHashMap<[i32; 3], u32> = scene
            .cells
            .iter()
            .copied()
            .zip(scene.labels.iter().copied())
            .collect();
        let around = |c: [i32; 3]| {
            (-1..=1).flat_map(move |dx| {
                (-1..=1)
                    .flat_map(move |dy| (-1..=1).map(move |dz| [c[0] + dx, c[1] + dy, c[2] + dz]))
            })
        };
        let mut right_row = 0;
        for (c, &r) in m.cells().iter().zip(m.rows()) {
            let f = m.db().row(r as usize);
            let labels: Vec<u32> = around(*c).filter_map(|n| truth.get(&n).copied()).collect();
            assert!(!labels.is_empty(), "voxel {c:?} is far from every surface");
            right_row += labels.iter().any(|&l| f[l as usize] > 0.7) as usize;
        }
        let n = m.len();
        assert!(
            right_row * 100 >= n * 99,
            "{right_row} of {n} voxels with a neighbouring class"
        );
        // Nearly every surface voxel the camera saw is mapped at or next to it.
        let covered = seen
            .iter()
            .filter(|&&leaf| around(scene.cells[leaf as usize]).any(|c| m.find(c).is_some()))
            .count();
        assert!(
            covered * 100 >= seen.len() * 95,
            "{covered} of {} seen voxels mapped",
            seen.len()
        );
        // And the map is not bloated: at most about twice the seen voxels.
        assert!(n <= 2 * seen.len(), "{n} voxels for {} seen", seen.len());
    }

    #[test]
    fn crop_and_range_skip_pixels() {
        let k = Intrinsics::from_hfov(4, 2, 90.0);
        let db = FeatureDb::from_rows(1, 0.02, vec![1.0]).unwrap();
        let grid = GridSpec {
            resolution: 0.1,
            origin: Vector3::zeros(),
        };
        let mut integ = Integrator::new(grid, db).unwrap();
        let pose = level_camera(Vector3::new(0.0, 0.0, 1.0), 0.0);
        // Row 0 looks up (above the camera), row 1 down; one pixel too far.
        let depth = [1.0, 1.0, 1.0, 50.0, 1.0, 1.0, 0.0, 1.0];
        let labels = [0u32; 8];
        let rows = |l: u32| Some(l);
        let img = LabelImage::new(4, 2, &labels, &rows).unwrap();
        let opt = FrameOptions {
            max_height: Some(1.0),
            ..FrameOptions::default()
        };
        let s = integrate_frame(&mut integ, &k, &depth, &pose, &img, &opt).unwrap();
        assert_eq!(s.offered, 8);
        // 3 valid pixels of row 0 are above 1 m, 1 is too far; row 1 has a hole.
        assert_eq!((s.integrated, s.skipped), (3, 5));
    }

    #[test]
    fn wrong_depth_length_and_empty_feature_maps_are_errors() {
        use crate::mapping::{FeatureMap, MappingError};
        let k = Intrinsics::from_hfov(4, 2, 90.0);
        let db = FeatureDb::new(2, 0.05).unwrap();
        let grid = GridSpec {
            resolution: 0.1,
            origin: Vector3::zeros(),
        };
        let mut integ = Integrator::new(grid, db).unwrap();
        let pose = level_camera(Vector3::new(0.0, 0.0, 1.0), 0.0);
        let data = [1.0f32, 0.0];
        let fm = FeatureMap::new(1, 1, 2, &data, 4, 2).unwrap();
        // Seven depth values for a 4 x 2 image: an error, nothing added.
        let err = integrate_frame(
            &mut integ,
            &k,
            &[1.0; 7],
            &pose,
            &fm,
            &FrameOptions::default(),
        )
        .unwrap_err();
        assert_eq!(
            err,
            MappingError::DepthSize {
                got: 7,
                want: 8,
                width: 4,
                height: 2
            }
        );
        let s = integrate_frame(
            &mut integ,
            &k,
            &[1.0; 8],
            &pose,
            &fm,
            &FrameOptions::default(),
        )
        .unwrap();
        assert_eq!(s.integrated, 8);
        for (h, w, dim) in [(0, 3, 2), (3, 0, 2), (3, 3, 0)] {
            assert_eq!(
                FeatureMap::new(h, w, dim, &[], 4, 2).err(),
                Some(MappingError::EmptyFeatureMap { h, w, dim })
            );
        }
        assert!(matches!(
            FeatureMap::new(2, 2, 2, &data, 4, 2),
            Err(MappingError::FeatureMapSize {
                want: 8,
                got: 2,
                ..
            })
        ));
        // Built by hand with zero extents, it reads nothing instead of
        // wrapping around.
        let raw = FeatureMap {
            h: 0,
            w: 3,
            dim: 2,
            data: &[],
            width: 4,
            height: 2,
        };
        assert_eq!(
            crate::mapping::pixel_feature(&raw, 1, 1, &mut [0.0; 2]),
            crate::mapping::Feature::Unknown
        );
    }
}
