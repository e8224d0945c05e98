//! Small procedural voxel scenes: a floor of rectangular rooms with walls,
//! doors, ceiling and box-shaped furniture, as labelled surface voxels.
//!
//! Used by the benchmarks, tests and `omcl demo` where a known, sizeable
//! scene is wanted without a dataset; the full synthetic benchmark with
//! realistic classes and sensors lives in `sim`.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::geometry::{Intrinsics, Pose, camera_ray};
use crate::map::Cell;
use crate::raycast::{Hit, RayCaster};

/// Labels of [`Scene`] voxels.
pub const FLOOR: u32 = 0;
/// Wall voxels.
pub const WALL: u32 = 1;
/// Ceiling voxels.
pub const CEILING: u32 = 2;
/// Furniture labels are `FURNITURE_BASE + kind`, `kind < FURNITURE_KINDS`.
pub const FURNITURE_BASE: u32 = 3;
/// Number of furniture kinds.
pub const FURNITURE_KINDS: u32 = 8;

/// Parameters of a rooms scene. Lengths in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct RoomsConfig {
    pub size_x: f64,
    pub size_y: f64,
    pub height: f64,
    pub room_x: f64,
    pub room_y: f64,
    pub resolution: f64,
    pub furniture_per_room: usize,
    pub seed: u64,
}

impl Default for RoomsConfig {
    fn default() -> Self {
        RoomsConfig {
            size_x: 12.0,
            size_y: 8.0,
            height: 2.6,
            room_x: 4.0,
            room_y: 4.0,
            resolution: 0.05,
            furniture_per_room: 4,
            seed: 7,
        }
    }
}

impl RoomsConfig {
    /// About a million voxels at 5 cm (30 m x 22 m, 30 rooms): the
    /// benchmark scene.
    pub fn million() -> Self {
        RoomsConfig {
            size_x: 30.0,
            size_y: 22.0,
            room_x: 5.0,
            room_y: 4.0,
            ..Self::default()
        }
    }
}

/// Labelled surface voxels; cell (i, j, k) spans `[i r, (i+1) r)` per axis
/// in the scene frame, whose origin is the corner of the floor.
#[derive(Debug, Clone)]
pub struct Scene {
    pub resolution: f64,
    pub cells: Vec<Cell>,
    pub labels: Vec<u32>,
    /// Free floor positions (x, y) in metres, at least 0.5 m from walls.
    pub free_spots: Vec<[f64; 2]>,
    pub config: RoomsConfig,
}

struct Builder {
    occupied: rustc_hash::FxHashMap<Cell, u32>,
}

impl Builder {
    fn put(&mut self, c: Cell, label: u32) {
        self.occupied.entry(c).or_insert(label);
    }

    /// Surface voxels of the closed box [lo, hi] (inclusive cell ranges).
    fn shell(&mut self, lo: Cell, hi: Cell, label: u32) {
        for i in lo[0]..=hi[0] {
            for j in lo[1]..=hi[1] {
                for k in lo[2]..=hi[2] {
                    let on = (0..3).any(|a| {
                        let v = [i, j, k][a];
                        v == lo[a] || v == hi[a]
                    });
                    if on {
                        self.put([i, j, k], label);
                    }
                }
            }
        }
    }
}

/// Builds a rooms scene.
pub fn rooms(cfg: &RoomsConfig) -> Scene {
    let r = cfg.resolution;
    let n = |m: f64| (m / r).round() as i32;
    let (nx, ny, nz) = (n(cfg.size_x), n(cfg.size_y), n(cfg.height));
    let mut b = Builder {
        occupied: rustc_hash::FxHashMap::default(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    for i in 0..nx {
        for j in 0..ny {
            b.put([i, j, 0], FLOOR);
            b.put([i, j, nz - 1], CEILING);
        }
    }
    let door_w = n(0.9).max(1);
    let door_h = n(2.0).min(nz - 2);
    let rooms_x = ((cfg.size_x / cfg.room_x).round() as i32).max(1);
    let rooms_y = ((cfg.size_y / cfg.room_y).round() as i32).max(1);
    let wall_x: Vec<i32> = (0..=rooms_x).map(|w| (w * (nx - 1)) / rooms_x).collect();
    let wall_y: Vec<i32> = (0..=rooms_y).map(|w| (w * (ny - 1)) / rooms_y).collect();
    // Walls at x = const, with a door in every room segment of inner walls.
    for (wi, &x) in wall_x.iter().enumerate() {
        let inner = wi > 0 && wi < wall_x.len() - 1;
        for s in wall_y.windows(2) {
            let mid = (s[0] + s[1]) / 2;
            for j in s[0]..=s[1] {
                for k in 1..nz - 1 {
                    let door = inner && (j - mid).abs() * 2 < door_w && k <= door_h;
                    if !door {
                        b.put([x, j, k], WALL);
                    }
                }
            }
        }
    }
    for (wi, &y) in wall_y.iter().enumerate() {
        let inner = wi > 0 && wi < wall_y.len() - 1;
        for s in wall_x.windows(2) {
            let mid = (s[0] + s[1]) / 2;
            for i in s[0]..=s[1] {
                for k in 1..nz - 1 {
                    let door = inner && (i - mid).abs() * 2 < door_w && k <= door_h;
                    if !door {
                        b.put([i, y, k], WALL);
                    }
                }
            }
        }
    }
    let mut free_spots = Vec::new();
    for sx in wall_x.windows(2) {
        for sy in wall_y.windows(2) {
            let (x0, x1, y0, y1) = (sx[0] + 2, sx[1] - 2, sy[0] + 2, sy[1] - 2);
            if x1 - x0 < n(1.2) || y1 - y0 < n(1.2) {
                continue;
            }
            for _ in 0..cfg.furniture_per_room {
                let w = rng.random_range(n(0.4)..=n(1.2)).min(x1 - x0);
                let d = rng.random_range(n(0.4)..=n(1.0)).min(y1 - y0);
                let h = rng.random_range(n(0.4)..=n(1.8)).min(nz - 3);
                let i0 = rng.random_range(x0..=x1 - w);
                let j0 = rng.random_range(y0..=y1 - d);
                let kind = rng.random_range(0..FURNITURE_KINDS);
                b.shell([i0, j0, 1], [i0 + w, j0 + d, h], FURNITURE_BASE + kind);
            }
            let cx = 0.5 * (sx[0] + sx[1]) as f64 * r;
            let cy = 0.5 * (sy[0] + sy[1]) as f64 * r;
            free_spots.push([cx, cy]);
        }
    }
    let mut v: Vec<(Cell, u32)> = b.occupied.into_iter().collect();
    v.sort_unstable_by_key(|&(c, _)| crate::map::key::encode(c));
    let (cells, labels) = v.into_iter().unzip();
    Scene {
        resolution: r,
        cells,
        labels,
        free_spots,
        config: cfg.clone(),
    }
}

/// What a camera sees of a [`Scene`]: z-depth (metres, 0 where the ray
/// missed), the label of the hit voxel (`u32::MAX` for a miss), and the hits,
/// row-major.
#[derive(Debug, Clone)]
pub struct View {
    pub depth: Vec<f32>,
    pub labels: Vec<u32>,
    pub hits: Vec<Hit>,
}

/// Renders `scene` (cast with `caster`, built over `scene.cells`) from a
/// camera at `world_from_camera`; the scene frame is the world frame.
pub fn render(
    scene: &Scene,
    caster: &dyn RayCaster,
    k: &Intrinsics,
    world_from_camera: &Pose,
) -> View {
    let origin = nalgebra::Vector3::zeros();
    let rays: Vec<_> = (0..k.height)
        .flat_map(|v| (0..k.width).map(move |u| (u, v)))
        .map(|(u, v)| camera_ray(k, world_from_camera, &origin, u, v))
        .collect();
    let hits = caster.cast_vec(&rays);
    // z-depth = t * (camera-frame z of the unit ray direction).
    let depth = hits
        .iter()
        .enumerate()
        .map(|(i, h)| {
            let (u, v) = (i as u32 % k.width, i as u32 / k.width);
            if h.is_hit() {
                h.t * k.pixel_dir(u, v).z as f32
            } else {
                0.0
            }
        })
        .collect();
    let labels = hits
        .iter()
        .map(|h| {
            if h.is_hit() {
                scene.labels[h.leaf as usize]
            } else {
                u32::MAX
            }
        })
        .collect();
    View {
        depth,
        labels,
        hits,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_scene_has_closed_rooms_and_is_deterministic() {
        let a = rooms(&RoomsConfig::default());
        let b = rooms(&RoomsConfig::default());
        assert_eq!(a.cells, b.cells);
        assert_eq!(a.labels, b.labels);
        let set: std::collections::HashSet<Cell> = a.cells.iter().copied().collect();
        // Floor under the room centres, ceiling above.
        assert!(set.contains(&[40, 40, 0]) && set.contains(&[40, 40, 51]));
        // The outer wall x = 0 is closed at mid height.
        assert!((1..159).all(|j| set.contains(&[0, j, 26])));
        let other = rooms(&RoomsConfig {
            seed: 8,
            ..RoomsConfig::default()
        });
        assert_ne!(a.cells, other.cells);
    }
}
