//! Outdoor worlds: a street laid along a real driving path.
//!
//! The path is a stretch of KITTI odometry sequence 00 (its ground-truth
//! camera poses), turned into a z-up world. Around it: road, raised
//! sidewalks, terrain verges, building blocks with gaps, fences and hedges
//! where there are no buildings, trees, street-light poles, traffic signs
//! and parked cars. Ground, buildings and fences are built column by column
//! (they follow the curving road); trees, poles, signs and cars are
//! primitives. Ground height follows the path: 1.65 m below the camera
//! (KITTI's camera height).

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rustc_hash::FxHashMap;

use super::paths::world_from_kitti;
use super::world::{Aabb, Scene, Shape, VoxelWorld, voxelize_onto};
use crate::geometry::Pose;

/// Class names of outdoor worlds; id = index.
pub const OUTDOOR_CLASSES: &[&str] = &[
    "road",
    "sidewalk",
    "building",
    "vegetation",
    "terrain",
    "car",
    "pole",
    "traffic sign",
    "fence",
];

/// SemanticKITTI label ids of [`OUTDOOR_CLASSES`], in the same order.
pub const SEMANTIC_KITTI_IDS: [u32; 9] = [40, 48, 50, 70, 72, 10, 80, 81, 51];

const ROAD: u16 = 0;
const SIDEWALK: u16 = 1;
const BUILDING: u16 = 2;
const VEGETATION: u16 = 3;
const TERRAIN: u16 = 4;
const CAR: u16 = 5;
const POLE: u16 = 6;
const SIGN: u16 = 7;
const FENCE: u16 = 8;

/// Camera height above the road, metres (KITTI).
pub const CAMERA_HEIGHT: f64 = 1.65;

/// Parameters of an outdoor world.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OutdoorConfig {
    pub seed: u64,
    /// Voxel edge, metres.
    pub resolution: f64,
    /// First frame of the real path used.
    pub start: usize,
    /// Number of frames (poses) of the path used.
    pub frames: usize,
    /// Half width of the road, metres.
    pub road_half_width: f64,
    /// Sidewalk width, metres.
    pub sidewalk_width: f64,
    /// How far from the road centre the world extends, metres.
    pub extent: f64,
}

impl Default for OutdoorConfig {
    fn default() -> Self {
        OutdoorConfig {
            seed: 0,
            resolution: 0.2,
            start: 0,
            frames: 200,
            road_half_width: 4.5,
            sidewalk_width: 2.5,
            extent: 28.0,
        }
    }
}

/// A generated street world and the camera path through it.
#[derive(Debug, Clone)]
pub struct OutdoorWorld {
    pub config: OutdoorConfig,
    pub scene: Scene,
    pub voxels: VoxelWorld,
    /// Camera-0 poses in the world (z up): `world_from_camera`.
    pub poses: Vec<Pose>,
    /// The same poses as KITTI writes them: camera 0 relative to the first
    /// camera of the stretch (camera frame, z forward).
    pub kitti_poses: Vec<Pose>,
}

struct Sample {
    p: [f64; 2],
    t: [f64; 2],
    s: f64,
    ground: f64,
}

/// One side's building blocks along the arc length.
struct Block {
    s0: f64,
    s1: f64,
    setback: f64,
    depth: f64,
    height: f64,
}

/// Generates the street world along `kitti_gt[start..start + frames]`
/// (KITTI 3x4 camera poses, camera frame of the sequence's first camera):
/// the path's samples, building blocks on both sides, the ground, kerbs,
/// buildings, fences and hedges as voxel columns, then trees, poles, signs
/// and parked cars as primitives.
pub fn generate(config: &OutdoorConfig, kitti_gt: &[Pose]) -> OutdoorWorld {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed ^ 0x07d_0000_u64);
    let end = (config.start + config.frames).min(kitti_gt.len());
    let start = config.start.min(end);
    let raw = &kitti_gt[start..end];
    let first_inv = raw
        .first()
        .map(|p| p.inverse())
        .unwrap_or_else(Pose::identity);
    let kitti_poses: Vec<Pose> = raw.iter().map(|p| first_inv * p).collect();
    let w = world_from_kitti();
    let poses: Vec<Pose> = kitti_poses.iter().map(|p| w * p).collect();
    let (samples, total) = path_samples(&poses);
    let blocks = building_blocks(&mut rng, total);
    let r = config.resolution;
    let (origin, ni, nj) = grid_extent(&samples, config);
    let index = SampleIndex::new(&samples, config.extent);
    let cols = columns(&index, origin, r, ni, nj, config.extent);
    let cells = street_cells(&cols, &blocks, origin, config);
    let mut scene = Scene {
        classes: OUTDOOR_CLASSES.iter().map(|s| s.to_string()).collect(),
        primitives: Vec::new(),
    };
    street_furniture(&mut rng, &samples, total, config, &mut scene);
    let voxels = voxelize_onto(&scene, r, origin, cells);
    OutdoorWorld {
        config: config.clone(),
        scene,
        voxels,
        poses,
        kitti_poses,
    }
}

/// Path samples every 0.5 m with tangent, arc length and ground height,
/// and the path's length.
fn path_samples(poses: &[Pose]) -> (Vec<Sample>, f64) {
    let mut samples: Vec<Sample> = Vec::new();
    let mut s_acc = 0.0;
    for win in poses.windows(2) {
        let a = win[0].translation.vector;
        let b = win[1].translation.vector;
        let seg = (b - a).xy();
        let len = seg.norm();
        if len < 1e-6 {
            continue;
        }
        let t = [seg.x / len, seg.y / len];
        let n = (len / 0.5).ceil() as usize;
        for k in 0..n {
            let f = k as f64 / n as f64;
            let p = a + (b - a) * f;
            samples.push(Sample {
                p: [p.x, p.y],
                t,
                s: s_acc + f * len,
                ground: p.z - CAMERA_HEIGHT,
            });
        }
        s_acc += len;
    }
    if samples.is_empty()
        && let Some(p) = poses.first()
    {
        let v = p.translation.vector;
        let fwd = p.rotation * Vector3::z();
        let t = fwd
            .xy()
            .try_normalize(1e-9)
            .map_or([1.0, 0.0], |t| [t.x, t.y]);
        samples.push(Sample {
            p: [v.x, v.y],
            t,
            s: 0.0,
            ground: v.z - CAMERA_HEIGHT,
        });
    }
    (samples, s_acc)
}

/// Building blocks per side (index 0: left, 1: right) along `total` metres
/// of arc length.
fn building_blocks(rng: &mut ChaCha8Rng, total: f64) -> [Vec<Block>; 2] {
    let mut blocks: [Vec<Block>; 2] = [Vec::new(), Vec::new()];
    for side in blocks.iter_mut() {
        let mut s = -10.0;
        while s < total + 10.0 {
            let len = rng.random_range(12.0..30.0);
            if rng.random_bool(0.75) {
                side.push(Block {
                    s0: s,
                    s1: s + len,
                    setback: rng.random_range(1.0..5.0),
                    depth: rng.random_range(8.0..14.0),
                    height: rng.random_range(6.0..16.0),
                });
            }
            s += len + rng.random_range(3.0..10.0);
        }
    }

    blocks
}

/// The grid's origin and its cell counts in x and y: the samples' bounds
/// with the world's extent and a margin around them.
fn grid_extent(samples: &[Sample], config: &OutdoorConfig) -> (Vector3<f64>, i32, i32) {
    let r = config.resolution;
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for smp in samples {
        lo[0] = lo[0].min(smp.p[0]);
        lo[1] = lo[1].min(smp.p[1]);
        lo[2] = lo[2].min(smp.ground);
        hi[0] = hi[0].max(smp.p[0]);
        hi[1] = hi[1].max(smp.p[1]);
        hi[2] = hi[2].max(smp.ground);
    }
    let m = config.extent + 2.0;
    let snap = |v: f64| ((v / r).floor() - 2.0) * r;
    let origin = Vector3::new(snap(lo[0] - m), snap(lo[1] - m), snap(lo[2] - 2.0));
    let ni = ((hi[0] - lo[0] + 2.0 * m) / r).ceil() as i32 + 4;
    let nj = ((hi[1] - lo[1] + 2.0 * m) / r).ceil() as i32 + 4;
    (origin, ni, nj)
}

/// A spatial hash of the path samples in 4 m buckets for nearest-sample
/// queries within the world's extent.
struct SampleIndex<'a> {
    samples: &'a [Sample],
    grid: FxHashMap<(i32, i32), Vec<usize>>,
    bucket: f64,
    reach: i32,
}

impl<'a> SampleIndex<'a> {
    fn new(samples: &'a [Sample], extent: f64) -> Self {
        let bucket = 4.0;
        let mut grid: FxHashMap<(i32, i32), Vec<usize>> = FxHashMap::default();
        for (i, smp) in samples.iter().enumerate() {
            grid.entry((
                (smp.p[0] / bucket).floor() as i32,
                (smp.p[1] / bucket).floor() as i32,
            ))
            .or_default()
            .push(i);
        }
        SampleIndex {
            samples,
            grid,
            bucket,
            reach: (extent / bucket).ceil() as i32 + 1,
        }
    }

    /// The nearest sample to `(x, y)` and its distance.
    fn nearest(&self, x: f64, y: f64) -> Option<(usize, f64)> {
        let (bucket, reach, grid, samples) = (self.bucket, self.reach, &self.grid, self.samples);
        let (bx, by) = ((x / bucket).floor() as i32, (y / bucket).floor() as i32);
        let mut best: Option<(usize, f64)> = None;
        for ring in 0..=reach {
            for dx in -ring..=ring {
                for dy in -ring..=ring {
                    if dx.abs() != ring && dy.abs() != ring {
                        continue;
                    }
                    if let Some(v) = grid.get(&(bx + dx, by + dy)) {
                        for &i in v {
                            let d = (samples[i].p[0] - x).hypot(samples[i].p[1] - y);
                            if best.is_none_or(|b| d < b.1) {
                                best = Some((i, d));
                            }
                        }
                    }
                }
            }
            // A hit in ring k can be beaten only by rings up to k + 1.
            if let Some(b) = best
                && b.1 < (ring as f64) * bucket
            {
                break;
            }
        }
        best
    }
}

/// A ground column: signed lateral offset from the path (positive to the
/// left of the driving direction), arc length and ground height.
struct Column {
    d: f64,
    s: f64,
    g: f64,
}

/// The ground columns of the `ni x nj` grid within `extent` of the path.
fn columns(
    index: &SampleIndex,
    origin: Vector3<f64>,
    r: f64,
    ni: i32,
    nj: i32,
    extent: f64,
) -> FxHashMap<(i32, i32), Column> {
    let mut cols: FxHashMap<(i32, i32), Column> = FxHashMap::default();
    for i in 0..ni {
        for j in 0..nj {
            let x = origin.x + (i as f64 + 0.5) * r;
            let y = origin.y + (j as f64 + 0.5) * r;
            let Some((k, dist)) = index.nearest(x, y) else {
                continue;
            };
            if dist > extent {
                continue;
            }
            let smp = &index.samples[k];
            let (dx, dy) = (x - smp.p[0], y - smp.p[1]);
            // Positive to the left of the driving direction.
            let d = smp.t[0] * dy - smp.t[1] * dx;
            let along = smp.t[0] * dx + smp.t[1] * dy;
            cols.insert(
                (i, j),
                Column {
                    d,
                    s: smp.s + along,
                    g: smp.ground,
                },
            );
        }
    }
    cols
}

/// The voxel cells of the columns: road, sidewalk and terrain surfaces,
/// buildings' walls and roofs, fences and hedges along verges without one.
fn street_cells(
    cols: &FxHashMap<(i32, i32), Column>,
    blocks: &[Vec<Block>; 2],
    origin: Vector3<f64>,
    config: &OutdoorConfig,
) -> FxHashMap<[i32; 3], u16> {
    let r = config.resolution;
    let hw = config.road_half_width;
    let curb = hw + config.sidewalk_width;
    let kz = |z: f64| ((z - origin.z) / r).floor() as i32;
    let block_of = |c: &Column| -> Option<&Block> {
        let side = if c.d >= 0.0 { 0 } else { 1 };
        let a = c.d.abs();
        blocks[side].iter().find(|b| {
            c.s >= b.s0 && c.s < b.s1 && a >= curb + b.setback && a < curb + b.setback + b.depth
        })
    };
    let mut cells: FxHashMap<[i32; 3], u16> = FxHashMap::default();
    for (&(i, j), c) in cols {
        let a = c.d.abs();
        let (label, z) = if a < hw {
            (ROAD, c.g)
        } else if a < curb {
            (SIDEWALK, c.g + 0.15)
        } else {
            (TERRAIN, c.g + 0.1)
        };
        cells.insert([i, j, kz(z - 0.5 * r)], label);
        if a >= curb {
            if let Some(b) = block_of(c) {
                // Shell: walls on the block's edge columns, a roof everywhere.
                let edge = [(1, 0), (-1, 0), (0, 1), (0, -1)].iter().any(|(di, dj)| {
                    cols.get(&(i + di, j + dj))
                        .is_none_or(|n| !block_of(n).is_some_and(|nb| std::ptr::eq(nb, b)))
                });
                let (k0, k1) = (kz(z), kz(c.g + b.height));
                if edge {
                    for k in k0..=k1 {
                        cells.insert([i, j, k], BUILDING);
                    }
                } else {
                    cells.insert([i, j, k1], BUILDING);
                }
            } else {
                // No building here: a fence or a hedge along the verge.
                let line = curb + 0.8;
                if (a - line).abs() < 0.5 * r + 1e-9 {
                    let side = if c.d >= 0.0 { 0 } else { 1 };
                    let hedge = ((c.s / 20.0).floor() as i64 + side) % 2 == 0;
                    let (label, h) = if hedge {
                        (VEGETATION, 1.0)
                    } else {
                        (FENCE, 1.2)
                    };
                    for k in kz(z)..=kz(z + h) {
                        cells.insert([i, j, k], label);
                    }
                }
            }
        }
    }
    cells
}

/// Trees, poles and signs on the sidewalk edge and parked cars along the
/// kerb, on both sides of the path.
fn street_furniture(
    rng: &mut ChaCha8Rng,
    samples: &[Sample],
    total: f64,
    config: &OutdoorConfig,
    scene: &mut Scene,
) {
    let (hw, sw) = (config.road_half_width, config.sidewalk_width);
    for side in [1.0, -1.0] {
        kerbside_objects(rng, samples, total, side * (hw + sw - 0.5), scene);
        parked_cars(rng, samples, total, side * (hw - 1.1), scene);
    }
}

/// The point `d` metres left of the path at arc length `s`, its ground
/// height and the path's tangent there.
fn at(samples: &[Sample], s: f64, d: f64) -> Option<([f64; 2], f64, [f64; 2])> {
    let k = samples
        .partition_point(|x| x.s < s)
        .min(samples.len().checked_sub(1)?);
    let smp = &samples[k];
    let along = s - smp.s;
    let p = [
        smp.p[0] + smp.t[0] * along - smp.t[1] * d,
        smp.p[1] + smp.t[1] * along + smp.t[0] * d,
    ];
    Some((p, smp.ground, smp.t))
}

/// Trees, poles and signs every 8 to 18 m at lateral offset `d`.
fn kerbside_objects(
    rng: &mut ChaCha8Rng,
    samples: &[Sample],
    total: f64,
    d: f64,
    scene: &mut Scene,
) {
    let mut s = rng.random_range(0.0..8.0);
    while s < total {
        let kind = rng.random_range(0..10);
        if let Some((p, g, t)) = at(samples, s, d) {
            let z0 = g + 0.15;
            match kind {
                0..=4 => {
                    let h = rng.random_range(2.5..4.0);
                    scene.add(
                        VEGETATION,
                        Shape::Cylinder {
                            x: p[0],
                            y: p[1],
                            radius: 0.2,
                            z0,
                            z1: z0 + h,
                        },
                    );
                    let cr = rng.random_range(1.5..2.8);
                    scene.add(
                        VEGETATION,
                        Shape::Ellipsoid {
                            centre: [p[0], p[1], z0 + h + cr * 0.8],
                            radii: [cr, cr, cr * 1.1],
                        },
                    );
                }
                5..=7 => {
                    scene.add(
                        POLE,
                        Shape::Cylinder {
                            x: p[0],
                            y: p[1],
                            radius: 0.12,
                            z0,
                            z1: z0 + 7.0,
                        },
                    );
                }
                _ => {
                    scene.add(
                        POLE,
                        Shape::Cylinder {
                            x: p[0],
                            y: p[1],
                            radius: 0.06,
                            z0,
                            z1: z0 + 2.6,
                        },
                    );
                    // Sign plate facing the traffic: thin along the road direction.
                    let (hx, hy) = if t[0].abs() > t[1].abs() {
                        (0.05, 0.35)
                    } else {
                        (0.35, 0.05)
                    };
                    scene.add(
                        SIGN,
                        Shape::Box(Aabb::new(
                            [p[0] - hx, p[1] - hy, z0 + 2.0],
                            [p[0] + hx, p[1] + hy, z0 + 2.7],
                        )),
                    );
                }
            }
        }
        s += rng.random_range(8.0..18.0);
    }
}

/// Parked cars at lateral offset `d` (on the road, along the kerb).
fn parked_cars(rng: &mut ChaCha8Rng, samples: &[Sample], total: f64, d: f64, scene: &mut Scene) {
    let mut s = rng.random_range(0.0..10.0);
    while s < total {
        if rng.random_bool(0.6)
            && let Some((p, g, t)) = at(samples, s, d)
        {
            let (lx, ly) = if t[0].abs() > t[1].abs() {
                (2.2, 0.9)
            } else {
                (0.9, 2.2)
            };
            scene.add(
                CAR,
                Shape::Box(Aabb::new(
                    [p[0] - lx, p[1] - ly, g + 0.2],
                    [p[0] + lx, p[1] + ly, g + 0.9],
                )),
            );
            let (cx, cy) = (lx * 0.55, ly * 0.55);
            let (cx, cy) = if lx > ly {
                (cx, ly * 0.95)
            } else {
                (lx * 0.95, cy)
            };
            scene.add(
                CAR,
                Shape::Box(Aabb::new(
                    [p[0] - cx, p[1] - cy, g + 0.9],
                    [p[0] + cx, p[1] + cy, g + 1.45],
                )),
            );
        }
        s += rng.random_range(5.5..12.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::paths::level_camera;

    /// A straight 60 m KITTI path along camera z (world +x after the axis change).
    fn straight() -> Vec<Pose> {
        let k_from_w = world_from_kitti().inverse();
        (0..60)
            .map(|i| k_from_w * level_camera(Vector3::new(i as f64, 0.0, 0.0), 0.0))
            .collect()
    }

    #[test]
    fn street_cross_section_is_road_sidewalk_then_verge() {
        let cfg = OutdoorConfig {
            frames: 60,
            ..Default::default()
        };
        let w = generate(&cfg, &straight());
        // The path runs along world x at y = 0, camera 1.65 m above the road.
        let v = &w.voxels;
        let label_below = |y: f64| {
            // Lowest occupied cell of the column at x = 30.
            let c = v.cell_of(&Vector3::new(30.0, y, 0.0));
            (-40..40).find_map(|dk| v.label_at([c[0], c[1], c[2] + dk]).map(|l| (l, c[2] + dk)))
        };
        let (road, k_road) = label_below(0.3).unwrap();
        assert_eq!(road, ROAD);
        // Road surface cell holds z = -1.65 (camera at z = 0).
        let z = v.origin.z + (k_road as f64 + 0.5) * v.resolution;
        assert!((z + CAMERA_HEIGHT).abs() <= v.resolution, "{z}");
        assert_eq!(label_below(5.5).unwrap().0, SIDEWALK);
        assert_eq!(label_below(-5.5).unwrap().0, SIDEWALK);
        assert!(
            w.voxels
                .class_histogram()
                .iter()
                .take(9)
                .filter(|&&n| n > 0)
                .count()
                >= 8,
            "{:?}",
            w.voxels.class_histogram()
        );
        assert_eq!(w.poses.len(), 60);
        assert!((w.kitti_poses[0].translation.vector.norm()) < 1e-12);
    }

    #[test]
    fn outdoor_world_is_deterministic_by_seed() {
        let cfg = OutdoorConfig {
            frames: 40,
            ..Default::default()
        };
        let a = generate(&cfg, &straight());
        let b = generate(&cfg, &straight());
        let c = generate(&OutdoorConfig { seed: 9, ..cfg }, &straight());
        assert_eq!(a.voxels, b.voxels);
        assert_ne!(a.voxels.cells, c.voxels.cells);
    }
}
