//! Where particles start: around a known pose (local), over all floor
//! voxels (global), or over the floor voxels near objects a text prompt
//! names (paper, "Prompt-augmented Initialization").
//!
//! Prompt matching counts, for every floor voxel, the voxels matching each
//! word within a horizontal radius R. Instead of all pairs it projects the
//! matching voxels of each word on a 2-D floor plan (cell `max(res, R/32)`),
//! takes prefix sums along x, and sums a disc of rows per floor voxel:
//! `O(voxels + floor voxels * R / cell)` per word.

use nalgebra::Vector3;
use rand::Rng;
use rayon::prelude::*;

use super::MclError;
use super::motion::{MotionMode, MotionModel};
use super::particles::Particle;
use crate::geometry::{Pose, level_camera};
use crate::map::LanguageMap;

/// Particles around `world_from_camera`: Gaussian position noise `sigma_xy`
/// (m) in the horizontal plane and yaw noise `sigma_yaw` (rad) about world z
/// (paper: 0.3 m, 17 degrees).
pub fn local_init<R: Rng>(
    world_from_camera: &Pose,
    n: usize,
    sigma_xy: f64,
    sigma_yaw: f64,
    rng: &mut R,
) -> Vec<Particle> {
    let m = MotionModel {
        mode: MotionMode::Planar,
        sigma_translation: sigma_xy,
        sigma_rotation: sigma_yaw,
    };
    let w = 1.0 / n.max(1) as f64;
    (0..n)
        .map(|_| Particle::new(m.sample(world_from_camera, &Pose::identity(), rng), w))
        .collect()
}

/// How floor voxels are found and cameras placed on them.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FloorParams {
    /// A voxel is floor when its cosine similarity to the text feature of
    /// "floor" is at least this.
    pub rho: f32,
    /// Height of the camera above the top of the floor voxel, metres.
    pub camera_height: f64,
    /// Yaw is drawn uniformly in `[-yaw_spread/2, yaw_spread/2)` radians
    /// around `yaw_centre` (full circle by default).
    pub yaw_spread: f64,
    pub yaw_centre: f64,
}

impl Default for FloorParams {
    fn default() -> Self {
        FloorParams {
            rho: 0.9,
            camera_height: 1.5,
            yaw_spread: std::f64::consts::TAU,
            yaw_centre: 0.0,
        }
    }
}

/// Prompt matching (paper: R = 2 m, rho = 0.9, k = 500 voxels at 2 cm).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PromptParams {
    /// Horizontal search radius around a floor voxel, metres.
    pub radius: f64,
    /// A voxel matches a word at cosine similarity at least `rho`.
    pub rho: f32,
    /// Voxels each word needs within the radius, counted at `k_resolution`.
    /// Surface voxel counts scale with `1/res^2`, so on a map of resolution
    /// `res` the threshold is `k (k_resolution / res)^2`.
    pub k: f64,
    /// Resolution (metres) at which `k` is stated.
    pub k_resolution: f64,
}

impl Default for PromptParams {
    fn default() -> Self {
        PromptParams {
            radius: 2.0,
            rho: 0.9,
            k: 500.0,
            k_resolution: 0.02,
        }
    }
}

impl PromptParams {
    /// The voxel count threshold on a map of resolution `res` metres.
    pub fn k_at(&self, res: f64) -> f64 {
        self.k * (self.k_resolution / res).powi(2)
    }
}

fn check_dim(map: &LanguageMap, index: usize, f: &[f32]) -> Result<(), MclError> {
    if f.len() != map.db().dim() {
        return Err(MclError::PromptDim {
            index,
            expected: map.db().dim(),
            got: f.len(),
        });
    }
    Ok(())
}

/// Leaf indices of the voxels at least `rho` similar to `feature`.
fn matching(map: &LanguageMap, feature: &[f32], rho: f32) -> Vec<usize> {
    let per_row = map.db().similarities(feature).unwrap_or_default();
    map.rows()
        .iter()
        .enumerate()
        .filter(|(_, r)| per_row.get(**r as usize).is_some_and(|s| *s >= rho))
        .map(|(i, _)| i)
        .collect()
}

/// Leaf indices of floor voxels.
pub fn floor_voxels(
    map: &LanguageMap,
    floor_feature: &[f32],
    rho: f32,
) -> Result<Vec<usize>, MclError> {
    check_dim(map, 0, floor_feature)?;
    let v = matching(map, floor_feature, rho);
    if v.is_empty() {
        return Err(MclError::NoFloor { rho });
    }
    Ok(v)
}

/// Draws level camera poses over a set of floor voxels: uniform over the
/// voxels, uniform within a voxel's footprint, at camera height, with yaw
/// spread. Keeps only the voxel tops, so it outlives the map borrow (the
/// filter uses one to inject particles during recovery).
#[derive(Debug, Clone, PartialEq)]
pub struct FloorSampler {
    /// World position of the centre of each voxel's top face.
    tops: Vec<Vector3<f64>>,
    resolution: f64,
    params: FloorParams,
    /// Every camera at this height instead of `camera_height` over its
    /// voxel's top ([`FloorSampler::at_height`]).
    height: Option<f64>,
}

impl FloorSampler {
    /// A sampler over map leaves `leaves`.
    pub fn new(map: &LanguageMap, leaves: &[usize], params: FloorParams) -> Self {
        let res = map.grid().resolution;
        let tops = leaves
            .iter()
            .filter_map(|&l| map.codes().get(l))
            .map(|&code| {
                map.grid().center(crate::map::key::decode(code)) + Vector3::z() * 0.5 * res
            })
            .collect();
        FloorSampler {
            tops,
            resolution: res,
            params,
            height: None,
        }
    }

    /// The same sampler with every camera at height `z` (world metres):
    /// for a session that holds its camera at a pose start's height (a
    /// floor plan, `ground`), so that recovery's cameras stand where the
    /// tracked ones do.
    pub fn at_height(mut self, z: f64) -> Self {
        self.height = Some(z);
        self
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.tops.len()
    }

    /// Whether there are no voxels.
    pub fn is_empty(&self) -> bool {
        self.tops.is_empty()
    }

    /// One pose (`world_from_camera`); `None` when empty.
    pub fn sample<R: Rng>(&self, rng: &mut R) -> Option<Pose> {
        if self.tops.is_empty() {
            return None;
        }
        let top = self.tops[rng.random_range(0..self.tops.len())];
        let res = self.resolution;
        let p = Vector3::new(
            top.x + (rng.random::<f64>() - 0.5) * res,
            top.y + (rng.random::<f64>() - 0.5) * res,
            self.height.unwrap_or(top.z + self.params.camera_height),
        );
        let yaw = self.params.yaw_centre + (rng.random::<f64>() - 0.5) * self.params.yaw_spread;
        Some(level_camera(p, yaw))
    }

    /// `n` particles of weight `1/n`.
    pub fn particles<R: Rng>(&self, n: usize, rng: &mut R) -> Vec<Particle> {
        let w = 1.0 / n.max(1) as f64;
        (0..n)
            .filter_map(|_| self.sample(rng).map(|p| Particle::new(p, w)))
            .collect()
    }
}

/// Global initialization: `n` particles uniformly over all floor voxels.
pub fn global_init<R: Rng>(
    map: &LanguageMap,
    floor_feature: &[f32],
    params: &FloorParams,
    n: usize,
    rng: &mut R,
) -> Result<Vec<Particle>, MclError> {
    let floor = floor_voxels(map, floor_feature, params.rho)?;
    Ok(FloorSampler::new(map, &floor, *params).particles(n, rng))
}

/// Floor voxels (leaf indices) that have, for every word feature in
/// `words`, at least `k_at(res)` matching voxels within the radius.
pub fn prompt_floor_voxels(
    map: &LanguageMap,
    floor_feature: &[f32],
    words: &[Vec<f32>],
    floor_rho: f32,
    params: &PromptParams,
) -> Result<Vec<usize>, MclError> {
    if words.is_empty() {
        return Err(MclError::EmptyPrompt);
    }
    for (i, w) in words.iter().enumerate() {
        check_dim(map, i, w)?;
    }
    if !(params.radius.is_finite() && params.radius > 0.0) {
        return Err(MclError::BadParam {
            name: "radius",
            why: format!("must be a positive number of metres, got {}", params.radius),
        });
    }
    let floor = floor_voxels(map, floor_feature, floor_rho)?;
    let grid = map.grid();
    let res = grid.resolution;
    let (lo, hi) = map
        .cell_bounds()
        .ok_or(MclError::NoFloor { rho: floor_rho })?;
    // A radius wider than the map's horizontal diagonal counts every voxel
    // of the map, as that diagonal does: capped to it, a huge radius
    // (1e308) neither overflows its square nor makes the plan's cells
    // coarser than the map.
    let diag = res * f64::hypot((hi[0] - lo[0] + 1) as f64, (hi[1] - lo[1] + 1) as f64);
    let whole_map = params.radius > diag;
    let radius = params.radius.min(diag);
    let cell = res.max(radius / 32.0);
    // Plan cell of a leaf: its centre's horizontal offset from the map's
    // lower corner, in plan cells.
    let to_plan = |c: [i32; 3]| -> (usize, usize) {
        let x = ((c[0] - lo[0]) as f64 + 0.5) * res / cell;
        let y = ((c[1] - lo[1]) as f64 + 0.5) * res / cell;
        (x as usize, y as usize)
    };
    let nx = to_plan(hi).0 + 1;
    let ny = to_plan(hi).1 + 1;
    let floor_plan: Vec<(usize, (usize, usize))> = floor
        .iter()
        .map(|&l| (l, to_plan(crate::map::key::decode(map.codes()[l]))))
        .collect();
    let r = (radius / cell).ceil() as i64;
    let half: Vec<usize> = (-r..=r)
        .map(|dj| {
            let d = dj as f64 * cell;
            ((radius * radius - d * d).max(0.0).sqrt() / cell).floor() as usize
        })
        .collect();
    let k = params.k_at(res);
    let mut ok = vec![true; floor_plan.len()];
    for w in words {
        let mut pre = vec![0u32; (nx + 1) * ny];
        for l in matching(map, w, params.rho) {
            let (x, y) = to_plan(crate::map::key::decode(map.codes()[l]));
            pre[y * (nx + 1) + x + 1] += 1;
        }
        for row in pre.chunks_exact_mut(nx + 1) {
            for i in 1..=nx {
                row[i] += row[i - 1];
            }
        }
        ok.par_iter_mut()
            .zip(floor_plan.par_iter())
            .filter(|(o, _)| **o)
            .for_each(|(o, &(_, (fx, fy)))| {
                let mut count = 0u64;
                for (dj, &hw) in (-r..=r).zip(&half) {
                    let y = fy as i64 + dj;
                    if y < 0 || y >= ny as i64 {
                        continue;
                    }
                    let row = &pre[y as usize * (nx + 1)..(y as usize + 1) * (nx + 1)];
                    let a = fx.saturating_sub(hw);
                    let b = (fx + hw + 1).min(nx);
                    count += (row[b] - row[a]) as u64;
                }
                *o = count as f64 >= k;
            });
    }
    let out: Vec<usize> = floor_plan
        .iter()
        .zip(&ok)
        .filter(|(_, o)| **o)
        .map(|((l, _), _)| *l)
        .collect();
    if out.is_empty() {
        return Err(MclError::NoPromptMatch {
            k,
            radius,
            whole_map,
        });
    }
    Ok(out)
}

/// Prompt-augmented initialization: `n` particles uniformly over the floor
/// voxels that match every word of the prompt (text features `words`).
/// Errors when the map has no floor ([`MclError::NoFloor`]) or no floor
/// voxel matches ([`MclError::NoPromptMatch`]; a caller may then fall back
/// to [`global_init`]).
pub fn prompt_init<R: Rng>(
    map: &LanguageMap,
    floor_feature: &[f32],
    words: &[Vec<f32>],
    floor: &FloorParams,
    prompt: &PromptParams,
    n: usize,
    rng: &mut R,
) -> Result<Vec<Particle>, MclError> {
    let leaves = prompt_floor_voxels(map, floor_feature, words, floor.rho, prompt)?;
    Ok(FloorSampler::new(map, &leaves, *floor).particles(n, rng))
}
