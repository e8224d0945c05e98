//! Camera rendering through the project's ray caster: z-depth, per-pixel
//! class, incidence, and an RGB image for people to look at.
//!
//! Every ray goes through a [`RayCaster`] built from the world's cells
//! (grid frame = world minus `VoxelWorld::origin`), so the synthetic images
//! see exactly the voxels a map built from the world would hold.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::world::VoxelWorld;
use crate::geometry::{Intrinsics, Pose, Ray, camera_ray};
use crate::raycast::{Hit, RayCaster};

/// Label of a pixel whose ray hit nothing.
pub const NO_LABEL: u16 = u16::MAX;

/// One rendered camera frame; images are row-major, `width * height`.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// z-depth along the optical axis, metres; 0 where the ray missed.
    pub depth: Vec<f32>,
    /// Class id of the hit voxel; [`NO_LABEL`] where the ray missed.
    pub labels: Vec<u16>,
    /// Index of the hit voxel in `VoxelWorld::cells`; `u32::MAX` for a miss.
    pub leaves: Vec<u32>,
    /// |cos| of the angle between the ray and the normal of the voxel face
    /// it entered (1 = head-on, 0 = grazing); 0 for a miss.
    pub incidence: Vec<f32>,
}

impl Frame {
    /// Pixel index of `(u, v)`.
    pub fn index(&self, u: u32, v: u32) -> usize {
        v as usize * self.width as usize + u as usize
    }
}

/// The camera rays of every pixel, row-major, in the world's grid frame.
pub fn camera_rays(world: &VoxelWorld, k: &Intrinsics, world_from_camera: &Pose) -> Vec<Ray> {
    let w = k.width as usize;
    (0..k.pixel_count())
        .into_par_iter()
        .map(|i| {
            let (u, v) = ((i % w) as u32, (i / w) as u32);
            camera_ray(k, world_from_camera, &world.origin, u, v)
        })
        .collect()
}

/// Renders one frame of camera `k` at `world_from_camera`.
pub fn render_frame(
    caster: &dyn RayCaster,
    world: &VoxelWorld,
    k: &Intrinsics,
    world_from_camera: &Pose,
) -> Frame {
    let rays = camera_rays(world, k, world_from_camera);
    let hits = caster.cast_vec(&rays);
    let axis_cam = world_from_camera.rotation * Vector3::z();
    let axis = [axis_cam.x as f32, axis_cam.y as f32, axis_cam.z as f32];
    let px: Vec<(f32, u16, u32, f32)> = rays
        .par_iter()
        .zip(hits.par_iter())
        .map(|(ray, hit)| match shade(world, ray, hit) {
            Some((label, inc)) => {
                let along = ray.dir[0] * axis[0] + ray.dir[1] * axis[1] + ray.dir[2] * axis[2];
                (hit.t * along, label, hit.leaf, inc)
            }
            None => (0.0, NO_LABEL, u32::MAX, 0.0),
        })
        .collect();
    Frame {
        width: k.width,
        height: k.height,
        depth: px.iter().map(|p| p.0).collect(),
        labels: px.iter().map(|p| p.1).collect(),
        leaves: px.iter().map(|p| p.2).collect(),
        incidence: px.iter().map(|p| p.3).collect(),
    }
}

/// Class and incidence of a hit (`None` for a miss). The entered face is
/// the one the hit point lies closest to.
pub fn shade(world: &VoxelWorld, ray: &Ray, hit: &Hit) -> Option<(u16, f32)> {
    if !hit.is_hit() {
        return None;
    }
    let leaf = hit.leaf as usize;
    let cell = *world.cells.get(leaf)?;
    let label = *world.labels.get(leaf)?;
    let p = ray.at(hit.t);
    let r = world.resolution as f32;
    let mut best = (0usize, f32::INFINITY);
    for a in 0..3 {
        let f = p[a] / r - cell[a] as f32;
        let dist = f.abs().min((1.0 - f).abs());
        if dist < best.1 {
            best = (a, dist);
        }
    }
    let norm = (ray.dir[0].powi(2) + ray.dir[1].powi(2) + ray.dir[2].powi(2)).sqrt();
    Some((label, (ray.dir[best.0] / norm).abs()))
}

/// A fixed, well-separated display colour per class id (sRGB).
pub fn class_colour(label: u16) -> [u8; 3] {
    const PALETTE: [[u8; 3]; 40] = [
        [200, 196, 186],
        [150, 111, 80],
        [235, 235, 230],
        [120, 72, 40],
        [140, 190, 230],
        [170, 110, 60],
        [210, 60, 50],
        [60, 90, 170],
        [230, 200, 150],
        [130, 140, 90],
        [190, 150, 100],
        [250, 250, 250],
        [180, 220, 230],
        [200, 230, 240],
        [230, 120, 160],
        [30, 30, 35],
        [240, 170, 40],
        [50, 150, 60],
        [160, 40, 80],
        [250, 230, 120],
        [110, 110, 120],
        [70, 70, 70],
        [225, 230, 235],
        [245, 245, 240],
        [220, 140, 90],
        [120, 90, 60],
        [90, 60, 50],
        [160, 120, 80],
        [180, 80, 120],
        [128, 64, 128],
        [244, 35, 232],
        [70, 70, 70],
        [107, 142, 35],
        [152, 251, 152],
        [0, 0, 142],
        [153, 153, 153],
        [220, 220, 0],
        [190, 153, 153],
        [0, 80, 100],
        [0, 0, 230],
    ];
    PALETTE[label as usize % PALETTE.len()]
}

/// An RGB picture of a frame: class colours shaded by incidence and faded
/// with distance, sky-blue where nothing was hit. For people, not for
/// algorithms (the feature model never looks at it).
pub fn rgb_image(frame: &Frame, colours: &dyn Fn(u16) -> [u8; 3]) -> Vec<u8> {
    let mut out = Vec::with_capacity(frame.labels.len() * 3);
    for i in 0..frame.labels.len() {
        if frame.labels[i] == NO_LABEL {
            out.extend_from_slice(&[170, 200, 235]);
            continue;
        }
        let c = colours(frame.labels[i]);
        let light = 0.55 + 0.45 * frame.incidence[i];
        let fade = 1.0 / (1.0 + 0.01 * frame.depth[i]);
        for ch in c {
            out.push((ch as f32 * light * fade).clamp(0.0, 255.0) as u8);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raycast::ReferenceCaster;
    use crate::sim::world::{Scene, voxelize};
    use nalgebra::{Translation3, UnitQuaternion};

    /// A camera at (0, 0, 1) looking along world +x (OpenCV: z forward).
    fn looking_along_x(x: f64) -> Pose {
        let rot = UnitQuaternion::from_basis_unchecked(&[
            Vector3::new(0.0, -1.0, 0.0),
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(1.0, 0.0, 0.0),
        ]);
        Pose::from_parts(Translation3::new(x, 0.0, 1.0), rot)
    }

    #[test]
    fn plain_wall_depth_matches_analytic_depth() {
        // Wall: the face x = 3 m of a slab; at z-depth every pixel sees 3 m.
        let mut s = Scene::new(&["wall"]);
        s.add_box(0, [3.0, -20.0, -20.0], [3.1, 20.0, 20.0]);
        let w = voxelize(&s, 0.05, Vector3::new(-1.0, -21.0, -21.0));
        let caster = ReferenceCaster::new(0.05, &w.cells);
        let k = Intrinsics::from_hfov(64, 48, 90.0);
        let f = render_frame(&caster, &w, &k, &looking_along_x(0.0));
        for i in 0..f.depth.len() {
            assert!((f.depth[i] - 3.0).abs() < 1e-4, "pixel {i}: {}", f.depth[i]);
            assert_eq!(f.labels[i], 0);
        }
        // Head-on at the centre, oblique at the corner: cos = z / |pixel dir|.
        let c = f.incidence[f.index(32, 24)];
        assert!((c - k.pixel_dir(32, 24).z as f32).abs() < 1e-4);
        let corner = f.incidence[f.index(0, 0)];
        assert!((corner - k.pixel_dir(0, 0).z as f32).abs() < 1e-4);
        // From 1.2 m further on, the depth drops by 1.2 m.
        let g = render_frame(&caster, &w, &k, &looking_along_x(1.2));
        assert!(g.depth.iter().all(|d| (d - 1.8).abs() < 1e-4));
    }

    #[test]
    fn labels_follow_the_geometry() {
        // Left half of the view a red box at x = 2, right half a wall at x = 4.
        let mut s = Scene::new(&["wall", "box"]);
        s.add_box(0, [4.0, -10.0, -10.0], [4.1, 10.0, 10.0]);
        s.add_box(1, [2.0, 0.0, -10.0], [2.5, 10.0, 10.0]);
        let w = voxelize(&s, 0.05, Vector3::new(-1.0, -11.0, -11.0));
        let caster = ReferenceCaster::new(0.05, &w.cells);
        let k = Intrinsics::from_hfov(40, 20, 90.0);
        let f = render_frame(&caster, &w, &k, &looking_along_x(0.0));
        for v in 0..20 {
            for u in 0..40 {
                let i = f.index(u, v);
                // World +y is image left (camera x = -world y).
                if u < 20 {
                    assert_eq!(f.labels[i], 1);
                    assert!((f.depth[i] - 2.0).abs() < 1e-4);
                } else {
                    assert_eq!(f.labels[i], 0);
                    assert!((f.depth[i] - 4.0).abs() < 1e-4);
                }
            }
        }
        let rgb = rgb_image(&f, &class_colour);
        assert_eq!(rgb.len(), 40 * 20 * 3);
    }
}
