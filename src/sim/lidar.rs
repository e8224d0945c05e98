//! A rotating multi-beam LiDAR (Velodyne HDL-64E-like) simulated through
//! the project's ray caster.
//!
//! Beams are spread evenly in elevation between `fov_down` and `fov_up`;
//! each revolution samples `azimuth_steps` directions. Points are returned
//! in the LiDAR frame (KITTI velodyne: x forward, y left, z up) with the
//! class of the hit voxel and a reflectance that depends on class and
//! incidence.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::render::shade;
use super::world::VoxelWorld;
use crate::geometry::{Pose, Ray};
use crate::raycast::RayCaster;

/// Scanner geometry and noise.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LidarConfig {
    /// Number of beams (64 for the HDL-64E).
    pub beams: u32,
    /// Directions per revolution.
    pub azimuth_steps: u32,
    /// Highest and lowest beam elevation, degrees.
    pub fov_up_deg: f64,
    pub fov_down_deg: f64,
    /// Maximum range, metres.
    pub max_range: f64,
    /// Standard deviation of range noise, metres (0 for exact surfaces).
    pub range_noise: f64,
}

impl Default for LidarConfig {
    fn default() -> Self {
        LidarConfig {
            beams: 64,
            azimuth_steps: 2048,
            fov_up_deg: 2.0,
            fov_down_deg: -24.8,
            max_range: 80.0,
            range_noise: 0.02,
        }
    }
}

/// One LiDAR return.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LidarPoint {
    /// Position in the LiDAR frame, metres.
    pub xyz: [f32; 3],
    /// Reflectance in [0, 1].
    pub reflectance: f32,
    /// Class id of the hit voxel.
    pub label: u16,
}

/// The unit beam directions of one revolution, in the LiDAR frame.
pub fn beam_directions(cfg: &LidarConfig) -> Vec<Vector3<f64>> {
    let mut dirs = Vec::with_capacity((cfg.beams * cfg.azimuth_steps) as usize);
    for b in 0..cfg.beams {
        let f = if cfg.beams > 1 {
            b as f64 / (cfg.beams - 1) as f64
        } else {
            0.5
        };
        let el = (cfg.fov_up_deg + f * (cfg.fov_down_deg - cfg.fov_up_deg)).to_radians();
        for a in 0..cfg.azimuth_steps {
            let az = std::f64::consts::TAU * a as f64 / cfg.azimuth_steps as f64;
            dirs.push(Vector3::new(
                el.cos() * az.cos(),
                el.cos() * az.sin(),
                el.sin(),
            ));
        }
    }
    dirs
}

/// Simulates one revolution from `world_from_lidar`; `seed` drives the
/// range noise.
pub fn scan(
    caster: &dyn RayCaster,
    world: &VoxelWorld,
    world_from_lidar: &Pose,
    cfg: &LidarConfig,
    seed: u64,
) -> Vec<LidarPoint> {
    let dirs = beam_directions(cfg);
    let o = world_from_lidar.translation.vector - world.origin;
    let rays: Vec<Ray> = dirs
        .iter()
        .map(|d| {
            let w = world_from_lidar.rotation * d;
            let mut r = Ray::new(
                [o.x as f32, o.y as f32, o.z as f32],
                [w.x as f32, w.y as f32, w.z as f32],
            );
            r.t_max = cfg.max_range as f32;
            r
        })
        .collect();
    let hits = caster.cast_vec(&rays);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x11da_7000);
    let noise = Normal::new(0.0, cfg.range_noise.max(0.0)).ok();
    let mut out = Vec::new();
    for ((ray, hit), d) in rays.iter().zip(&hits).zip(&dirs) {
        let Some((label, inc)) = shade(world, ray, hit) else {
            continue;
        };
        let range = hit.t as f64 + noise.as_ref().map_or(0.0, |n| n.sample(&mut rng));
        let p = d * range;
        // Class-dependent albedo, dimmer at grazing incidence.
        let albedo = 0.2 + 0.6 * ((label as f32 * 0.618_034) % 1.0);
        out.push(LidarPoint {
            xyz: [p.x as f32, p.y as f32, p.z as f32],
            reflectance: (albedo * (0.3 + 0.7 * inc)).clamp(0.0, 1.0),
            label,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raycast::ReferenceCaster;
    use crate::sim::world::{Scene, voxelize};

    #[test]
    fn beams_span_the_vertical_field_of_view() {
        let cfg = LidarConfig {
            azimuth_steps: 8,
            ..Default::default()
        };
        let d = beam_directions(&cfg);
        assert_eq!(d.len(), 64 * 8);
        let top = d[0].z.asin().to_degrees();
        let bottom = d[d.len() - 1].z.asin().to_degrees();
        assert!((top - 2.0).abs() < 1e-9 && (bottom + 24.8).abs() < 1e-9);
        assert!(d.iter().all(|v| (v.norm() - 1.0).abs() < 1e-12));
    }

    #[test]
    fn points_lie_on_the_ground_plane() {
        // Flat ground at z = 0; scanner 1.73 m above it, no noise.
        let mut s = Scene::new(&["road"]);
        s.add_box(0, [-60.0, -60.0, -0.2], [60.0, 60.0, 0.0]);
        let w = voxelize(&s, 0.2, Vector3::new(-61.0, -61.0, -1.0));
        let caster = ReferenceCaster::new(0.2, &w.cells);
        let cfg = LidarConfig {
            azimuth_steps: 90,
            range_noise: 0.0,
            max_range: 200.0,
            ..Default::default()
        };
        let pose = Pose::translation(0.0, 0.0, 1.73);
        let pts = scan(&caster, &w, &pose, &cfg, 0);
        // Beams above the horizon miss; the rest hit the ground top at z = 0.
        assert!(pts.len() > 50 * 90, "{}", pts.len());
        for p in &pts {
            let z_world = p.xyz[2] as f64 + 1.73;
            let r = (p.xyz[0] as f64).hypot(p.xyz[1] as f64);
            if r < 55.0 {
                assert!(z_world.abs() < 1e-3, "{p:?}");
            }
            assert_eq!(p.label, 0);
        }
    }
}
