//! The sensor model of the paper (eq. 2): a particle's likelihood is the
//! mean cosine similarity between the sampled pixels' features and the map
//! features hit by the particle's rays through those pixels.
//!
//! Per frame, the cosines of the N sampled pixel features against the K
//! database rows are computed once ([`SimilarityTable`], N x K; from the
//! sampler's clustering products when it kept them); per ray the work is a
//! cast and a table look-up.
//!
//! Rays are cast in groups of [`RAY_GROUP`] particles, each group one
//! parallel task that makes its rays, casts them on its thread and scores
//! them while they are in cache (an np x nj ray array written, cast and
//! read back was 10 % slower). Within a group the caster's 8-wide packets
//! are runs of consecutive rays, so the order decides how coherent a
//! packet is ([`RayOrder`]): particle-major, a packet is one particle's
//! rays through neighbouring sampled pixels (the sampler orders them along
//! a Morton curve), about 2 degrees apart; pixel-major, it is one pixel
//! seen from eight neighbouring particles (grouped by [`packet_order`], a
//! k-d split of their poses). Once the particles have gathered the second
//! is narrower; while they are spread out, the first. [`RayOrder::Auto`]
//! compares the two footprints every step ([`pixel_major_pays`]).
//!
//! A caster that walks the pixels of one image column together (the
//! planar one of floor plans, [`RayCaster::wants_column_order`]) gets each
//! particle's rays in column order, and, when every camera of the group is
//! level, as fans ([`RayCaster::cast_fans`]): per image column its
//! horizontal direction and per pixel a slope, no [`Ray`] made. On the
//! held-out sequence 1000 that made the 2-D cast 25 instead of 36 ms a
//! step (docs/table1.md, "Speed, 2-D against 3-D").
//!
//! Measured with `cargo bench --bench mcl` on the 1 M-voxel rooms map,
//! 1024 particles x 2048 pixels (2026-11-23, AMD EPYC Zen 3, two runs,
//! median cast time of nine interleaved steps from the same cloud):
//!
//! | cloud | particle-major | pixel-major | Auto |
//! | --- | --- | --- | --- |
//! | steady state (motion noise 0.10 m, 6 deg) | 122 / 144 ms | 92 / 113 ms | 90 / 115 ms (pixel-major) |
//! | local init 0.3 m / 17 deg | 138 / 140 ms | 160 / 166 ms | 138 / 140 ms (particle-major) |
//!
//! (Pixel-major packets then took the particles in the filter's Morton
//! order; grouping them with [`packet_order`] instead narrowed the
//! steady-state footprint from 0.24 to 0.18 m and made the whole step 5 to
//! 12 % faster in nine interleaved runs.)

use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::MclError;
use super::particles::Particle;
use super::sampling::Sample;
use crate::frame::FrameFeatures;
use crate::geometry::{Intrinsics, Ray};
use crate::map::Cell;
use crate::map::FeatureDb;
use crate::map::features::Features;
use crate::raycast::{
    BrickEdge, BuildOptions, BuildQuality, EmbreeCaster, EmbreeError, Fan, Geometry, Hit, Packet,
    RayCaster,
};

/// A pixel's dot products with the rows (`out`) made its cosines, given its
/// feature's norm `n`: zeros for a feature without direction; with
/// `contrast`, rescaled over the rows to `[0, 1]`.
fn cosines(out: &mut [f32], n: f32, contrast: bool) {
    if !(n.is_finite() && n > 0.0) {
        out.fill(0.0);
        return;
    }
    out.iter_mut().for_each(|o| *o /= n);
    if contrast {
        let lo = out.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = out.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        if hi > lo {
            out.iter_mut().for_each(|o| *o = (*o - lo) / (hi - lo));
        }
    }
}

/// Cosines between a frame's sampled pixel features and the database rows.
#[derive(Debug, Clone, PartialEq)]
pub struct SimilarityTable {
    rows: usize,
    /// `cos[j * rows + k]`, pixel j against database row k.
    cos: Vec<f32>,
}

impl SimilarityTable {
    /// Builds the table for `pixels` of `frame`. A pixel feature without
    /// direction (zero) scores 0 against every row.
    ///
    /// With `contrast`, each pixel's cosines are rescaled over the rows to
    /// `[0, 1]` (its most similar row 1, its least similar 0); see
    /// [`SensorParams::contrast`].
    pub fn new(
        frame: &dyn FrameFeatures,
        pixels: &[(u32, u32)],
        db: &FeatureDb,
        contrast: bool,
    ) -> Result<Self, MclError> {
        if frame.dim() != db.dim() {
            return Err(MclError::DimMismatch {
                expected: db.dim(),
                got: frame.dim(),
            });
        }
        let fill = |j: usize, buf: &mut [f32]| frame.feature(pixels[j].0, pixels[j].1, buf);
        let (dots, norms) = db.dots_and_norms(pixels.len(), Features::Fill(&fill));
        Ok(Self::from_products(db.len(), dots, &norms, contrast))
    }

    /// The table of a [`Sample`]'s pixels: from the products its clustering
    /// computed when it kept them (the same cosines, no second product),
    /// otherwise as [`SimilarityTable::new`].
    pub fn of_sample(
        frame: &dyn FrameFeatures,
        sample: &Sample,
        db: &FeatureDb,
        contrast: bool,
    ) -> Result<Self, MclError> {
        let k = db.len();
        match &sample.scores {
            Some((dots, norms)) if frame.dim() == db.dim() && dots.len() == norms.len() * k => {
                Ok(Self::from_products(k, dots.clone(), norms, contrast))
            }
            _ => Self::new(frame, &sample.pixels, db, contrast),
        }
    }

    /// The table of every `step`-th pixel of this one (pixels `0, step,
    /// 2 step, ...`), for those pixels in that order.
    pub fn every(&self, step: usize) -> Self {
        let (k, step) = (self.rows, step.max(1));
        let cos = if k == 0 {
            Vec::new()
        } else {
            self.cos
                .chunks_exact(k)
                .step_by(step)
                .flatten()
                .copied()
                .collect()
        };
        SimilarityTable { rows: k, cos }
    }

    /// The table of pixels whose products with the `k` rows are `dots`
    /// (pixel-major) and whose features' norms are `norms`.
    fn from_products(k: usize, mut cos: Vec<f32>, norms: &[f32], contrast: bool) -> Self {
        if k > 0 {
            for (c, &n) in cos.chunks_exact_mut(k).zip(norms) {
                cosines(c, n, contrast);
            }
        }
        SimilarityTable { rows: k, cos }
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.cos.len().checked_div(self.rows).unwrap_or(0)
    }

    /// Cosine of pixel `j` against database row `k`.
    pub fn get(&self, j: usize, k: usize) -> f32 {
        self.cos[j * self.rows + k]
    }

    /// The table of the pixels `cols` only.
    #[cfg(test)]
    pub(crate) fn columns(&self, cols: &[usize]) -> SimilarityTable {
        let k = self.rows;
        SimilarityTable {
            rows: k,
            cos: cols
                .iter()
                .flat_map(|&j| self.cos[j * k..(j + 1) * k].iter().copied())
                .collect(),
        }
    }
}

/// Choices the paper leaves open.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SensorParams {
    /// Score of a ray that hits nothing (paper: undefined; the authors'
    /// code skips misses). With `contrast` a hit scores in `[0, 1]`, so 0
    /// counts a miss as a hit on the pixel's least similar class: fine in
    /// closed rooms, where rays rarely miss, but outdoors it favours poses
    /// that turn the sky's rays onto facades (see [`STREET_MISS_SCORE`]).
    pub miss_score: f32,
    /// Largest ray length, metres (`inf`: unlimited; `null` in JSON). Hits
    /// beyond it miss.
    #[serde(with = "infinite_as_null")]
    pub max_range: f32,
    /// Rescale each pixel's cosines over the database rows to `[0, 1]`
    /// before averaging (the paper's eq. 2 uses the plain cosine: `false`).
    /// Real CLIP class embeddings are far from orthogonal (cosines of 0.7 to
    /// 0.9 between classes), so a wrong hit costs little and the plain mean
    /// barely separates poses: on the synthetic apartment (seed 7, 60
    /// frames, 256 particles x 512 rays, the sequence's noisy odometry) APE
    /// RMSE was 0.8 to 2.1 m with plain cosines for sharpening 80 to 2000,
    /// and 0.17 to 0.27 m with contrast for sharpening 10 to 80.
    pub contrast: bool,
    /// Stop casting for particles that cannot matter (`null`: every
    /// particle casts every ray, the paper's filter).
    #[serde(default)]
    pub early_reject: Option<EarlyReject>,
}

impl Default for SensorParams {
    fn default() -> Self {
        SensorParams {
            miss_score: 0.0,
            max_range: f32::INFINITY,
            contrast: true,
            early_reject: None,
        }
    }
}

/// Two-pass likelihoods: a stratified share of the pixels first (every
/// `every`-th sampled pixel), then the rest only for the particles whose
/// first-pass score is at least `ratio` times the best particle's. With
/// the filter's sharpening (weights as the likelihood to the power 80), a
/// particle 15 % below the best weighs 0.85^80 = 2e-6 of it: stopping it
/// changes nothing the filter keeps, and saves most of its rays.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct EarlyReject {
    pub every: usize,
    pub ratio: f32,
}

impl EarlyReject {
    /// `every` at least 2 (1 would cast every pixel in the first pass) and
    /// `ratio` in `[0, 1]`.
    pub fn validate(&self) -> Result<(), MclError> {
        if self.every < 2 {
            return Err(MclError::BadParam {
                name: "sensor.early_reject.every",
                why: format!("must be at least 2, got {}", self.every),
            });
        }
        if !(0.0..=1.0).contains(&self.ratio) {
            return Err(MclError::BadParam {
                name: "sensor.early_reject.ratio",
                why: format!("must be in [0, 1], got {}", self.ratio),
            });
        }
        Ok(())
    }
}

impl Default for EarlyReject {
    fn default() -> Self {
        EarlyReject {
            every: 4,
            ratio: 0.85,
        }
    }
}

impl EarlyReject {
    /// The split for streets (KITTI camera 2, 512 particles x 4096 pixels):
    /// every 2nd pixel first, the rest within 15 % of the best. Half of
    /// 4096 pixels is as many as the indoor filter casts in all, enough to
    /// tell a wrong road position; a quarter (the default split) was not:
    /// held-out street 1000, 300 frames, 0.420 m against the full filter's
    /// 0.371 m (README, "The real workload"). On the tuning streets 1 to 4
    /// (300 frames of KITTI 00, `gt` features, the authors' odometry
    /// noise; translation mean, m) this split gave 0.339 / 0.308 / 0.293 /
    /// 0.331 (mean 0.318; 3 of 4 completed) against the full filter's
    /// 0.413 / 0.351 / 0.301 / 0.313 (mean 0.345; 3 of 4); every 4th pixel
    /// first gave 0.358 on street 1, ratio 0.75 0.341 / 0.373 on 1 and 2.
    pub const STREET: EarlyReject = EarlyReject {
        every: 2,
        ratio: 0.85,
    };
}

/// The score of a ray that hits nothing on streets: 0.5, halfway along a
/// pixel's contrast scale, the score of a hit on a class it neither
/// matches nor rules out. A car's camera sees sky in a third of its image
/// and more at crossings; the map has nothing there, so at the true pose
/// those rays miss. With misses at 0, a sky pixel's ray scores more on any
/// facade than at the truth (an encoder gives sky a feature near some map
/// class: contrast puts that class at 1), so the filter prefers poses
/// turned towards buildings: at KITTI 00's left turn at frame 1545 it took
/// a pose 20 degrees off over the truth and lost the car with `lseg-like`
/// features, whose noise spreads the sky's pixels over every cluster (with
/// `gt` features they form one cluster, a ninth of the rays). Tuning
/// streets 1 to 4 (`omcl bench table4`, the authors' odometry noise;
/// translation mean over the four in m, runs completed), misses at 0 /
/// 0.25 / 0.5 / 0.75: `lseg-like`, frames 1450 to 1699: 5.20 (1 of 4) /
/// 0.312 (3) / 0.271 (4) / 0.273 (4); `gt`, frames 0 to 299: 0.318 (3) /
/// 0.304 (4) / 0.319 (4) / 0.318 (3). Halfway is the neutral score, and as good
/// as any.
pub const STREET_MISS_SCORE: f32 = 0.5;

/// JSON has no infinity: `inf` is written as `null` and read back.
mod infinite_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(x: &f32, s: S) -> Result<S::Ok, S::Error> {
        if x.is_finite() {
            s.serialize_f32(*x)
        } else {
            s.serialize_none()
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
        Ok(Option::<f32>::deserialize(d)?.unwrap_or(f32::INFINITY))
    }
}

/// An order of `particles` in which every run of `width` consecutive
/// particles is compact in pose: the runs are the cells of a k-d split
/// (each cell halved at the median of its widest coordinate, a multiple
/// of `width` on the near side) of the particles' positions and their
/// optical axes and up vectors scaled by [`FOOTPRINT_DEPTH`], so that a
/// run's rays through one pixel spread as little as the cloud allows. Used
/// for pixel-major packets; the filter's own Morton order leaves runs a
/// third wider (0.24 against 0.18 m at the benchmark's steady state, in
/// [`pixel_major_pays`]'s footprint).
pub fn packet_order(particles: &[Particle], width: usize) -> Vec<u32> {
    let width = width.max(1);
    let d = FOOTPRINT_DEPTH as f64;
    let keys: Vec<[f64; 9]> = particles
        .iter()
        .map(|p| {
            let t = p.pose.translation.vector;
            let f = p.pose.rotation * Vector3::z() * d;
            let u = p.pose.rotation * Vector3::y() * d;
            [t.x, t.y, t.z, f.x, f.y, f.z, u.x, u.y, u.z]
        })
        .collect();
    let mut order: Vec<u32> = (0..particles.len() as u32).collect();
    let mut stack = vec![(0, order.len())];
    while let Some((lo, hi)) = stack.pop() {
        if hi - lo <= width {
            continue;
        }
        let cell = &mut order[lo..hi];
        let axis = (0..9)
            .max_by(|&a, &b| {
                let extent = |a: usize| {
                    let (mut l, mut h) = (f64::INFINITY, f64::NEG_INFINITY);
                    for &i in cell.iter() {
                        l = l.min(keys[i as usize][a]);
                        h = h.max(keys[i as usize][a]);
                    }
                    h - l
                };
                extent(a).total_cmp(&extent(b))
            })
            .unwrap_or(0);
        let runs = cell.len().div_ceil(width);
        let mid = (runs / 2) * width;
        cell.select_nth_unstable_by(mid, |&a, &b| {
            keys[a as usize][axis].total_cmp(&keys[b as usize][axis])
        });
        stack.push((lo, lo + mid));
        stack.push((lo + mid, hi));
    }
    order
}

/// Casts particles' rays in a map and scores them.
pub struct SensorModel {
    caster: Arc<dyn RayCaster>,
    leaf_rows: Arc<[u32]>,
    origin: Vector3<f64>,
    intrinsics: Intrinsics,
    pub params: SensorParams,
    scores: Vec<f32>,
    last_cast: std::time::Duration,
    ray_order: RayOrder,
    last_pixel_major: bool,
}

/// In which order a group of particles' rays go to the caster, whose
/// packets are runs of consecutive rays. The order changes only the speed:
/// every ray is cast and every particle's scores are summed in pixel order
/// either way, so the likelihoods are identical to the bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RayOrder {
    /// Per step, the order whose packets are expected to be narrower (see
    /// [`pixel_major_pays`]): pixel-major once the particles have gathered,
    /// particle-major while they are spread out.
    #[default]
    Auto,
    /// Each particle's rays through all sampled pixels in turn: a packet is
    /// one origin and nearby pixels.
    ParticleMajor,
    /// Each pixel's rays from [`RAY_GROUP`] particles in turn, taken in
    /// [`packet_order`]: a packet is one pixel seen from neighbouring
    /// poses.
    PixelMajor,
}

/// Rays in one of the filter caster's packets ([`SensorModel::embree_caster`]
/// traces 8-wide packets): the run length that [`packet_order`] and
/// [`pixel_major_pays`] are asked for.
const PACKET: usize = 8;

/// Particles whose rays are made, cast and scored together in one parallel
/// task. 16 x 2048 rays are 1 MB, which the caster reads once.
pub const RAY_GROUP: usize = 16;

/// Depth (metres) at which [`pixel_major_pays`] compares the spread of a
/// packet's rays: a typical indoor range. Both spreads grow with the depth
/// at the same rate once rotation dominates, so the choice depends on it
/// only when particles differ mainly in position.
pub const FOOTPRINT_DEPTH: f32 = 2.0;

/// Whether pixel-major packets of `width` rays are expected to be narrower
/// than particle-major ones for `particles` (in the order they would be
/// cast: [`packet_order`]) and
/// the sampled pixels' camera-frame directions `dirs` (in sampling order).
///
/// A packet's footprint is estimated at [`FOOTPRINT_DEPTH`] `D`:
/// particle-major, the mean over runs of `width` consecutive pixels of the
/// largest `D * angle(d_0, d_i)`; pixel-major, the mean over runs of
/// `width` consecutive particles of the largest `|t_i - t_0| + D *
/// angle(R_0, R_i)`. Narrower packets hit fewer bricks and BVH nodes; the
/// module documentation has the times of both orders on both kinds of
/// cloud. Fewer than `width` particles or pixels: particle-major.
pub fn pixel_major_pays(particles: &[Particle], dirs: &[Vector3<f32>], width: usize) -> bool {
    let width = width.max(2);
    let mean = |spans: Vec<f32>| -> Option<f32> {
        (!spans.is_empty()).then(|| spans.iter().sum::<f32>() / spans.len() as f32)
    };
    let pixel = mean(
        dirs.chunks_exact(width)
            .map(|run| {
                run[1..]
                    .iter()
                    .map(|d| run[0].angle(d))
                    .fold(0.0f32, f32::max)
                    * FOOTPRINT_DEPTH
            })
            .collect(),
    );
    let particle = mean(
        particles
            .chunks_exact(width)
            .map(|run| {
                let p0 = &run[0].pose;
                run[1..]
                    .iter()
                    .map(|p| {
                        let dt = (p.pose.translation.vector - p0.translation.vector).norm();
                        dt as f32 + FOOTPRINT_DEPTH * p0.rotation.angle_to(&p.pose.rotation) as f32
                    })
                    .fold(0.0f32, f32::max)
            })
            .collect(),
    );
    matches!((particle, pixel), (Some(a), Some(b)) if a < b)
}

/// Horizontal extent (metres, along x or y) above which a map gets the
/// outdoor scene of [`SensorModel::filter_build_options`]: apartments and
/// office floors are tens of metres across, a street hundreds.
pub const LARGE_MAP_M: f64 = 100.0;

impl SensorModel {
    /// The Embree caster measured fastest for the filter's rays, over
    /// voxels of edge `resolution` (metres) at `cells` (grid frame), in
    /// 8-wide packets, with the brick edge and build quality of
    /// [`SensorModel::filter_build_options`].
    pub fn embree_caster(resolution: f32, cells: &[Cell]) -> Result<EmbreeCaster, EmbreeError> {
        let options = Self::filter_build_options(resolution, cells);
        Ok(EmbreeCaster::with_options(resolution, cells, options)?.with_packet(Packet::Eight))
    }

    /// The scene the filter casts in: bricks of edge 4 (medium build
    /// quality) for rooms, bricks of edge 8 with Embree's high build
    /// quality for maps more than [`LARGE_MAP_M`] across (streets, LiDAR
    /// surveys), whose rays run tens of metres over thin surfaces.
    ///
    /// Indoors, one step on the 1 M-voxel rooms map (1024 particles x 2048
    /// pixels, pixel-major packets, `cargo bench --bench mcl`, five
    /// interleaved runs each, Zen 3, 2026-11-23) took 107 to 124 ms
    /// (median 113) with edge 4, 121 to 151 ms (median 146) with edge 8
    /// and 133 to 158 ms with edge 2. On the street world (300 frames,
    /// 1.07 M voxels at 0.1 m, 512 particles x 4096 pixels, `omcl
    /// localize`, Zen 4, 2026-11-24, two interleaved runs each) edge 8
    /// gave 10.0 and 9.7 filter steps/s against edge 4's 8.9 and 8.7, and
    /// 10.3 and 10.2 with the high build quality (edge 4 with it: 8.8,
    /// 8.6); see docs/outdoor.md's "Outdoor speed".
    pub fn filter_build_options(resolution: f32, cells: &[Cell]) -> BuildOptions {
        let (lo, hi) = crate::raycast::column_bounds(cells);
        let across = (0..2)
            .map(|a| (hi[a] as f64 - lo[a] as f64 + 1.0) * resolution as f64)
            .fold(0.0f64, f64::max);
        let default = BuildOptions::default();
        let (edge, quality) = if across > LARGE_MAP_M {
            (BrickEdge::Eight, BuildQuality::High)
        } else {
            (BrickEdge::Four, default.quality)
        };
        BuildOptions {
            geometry: Geometry::Bricks(edge),
            quality,
            ..default
        }
    }

    /// A model for the map whose leaves `caster` indexes, with `leaf_rows`
    /// the database row of every leaf and `origin` the world coordinates of
    /// the grid frame's zero.
    pub fn new(
        caster: Arc<dyn RayCaster>,
        leaf_rows: Arc<[u32]>,
        origin: Vector3<f64>,
        intrinsics: Intrinsics,
        params: SensorParams,
    ) -> Self {
        SensorModel {
            caster,
            leaf_rows,
            origin,
            intrinsics,
            params,
            scores: Vec::new(),
            last_cast: std::time::Duration::ZERO,
            ray_order: RayOrder::Auto,
            last_pixel_major: false,
        }
    }

    /// The same model with another ray order (the default is
    /// [`RayOrder::Auto`]); for benchmarks and tests.
    pub fn with_ray_order(mut self, order: RayOrder) -> Self {
        self.ray_order = order;
        self
    }

    /// The first error the caster raised since the last call (its rays came
    /// back as misses, so the likelihoods since then are not to be used).
    pub fn take_cast_error(&self) -> Option<String> {
        self.caster.take_error()
    }

    /// Whether the last call of [`SensorModel::likelihoods`] cast its rays
    /// pixel-major.
    pub fn last_pixel_major(&self) -> bool {
        self.last_pixel_major
    }

    /// Wall-clock time of the per-particle pass (making the rays, casting
    /// and scoring them; casting is nearly all of it) in the last call of
    /// [`SensorModel::likelihoods`].
    pub fn last_cast(&self) -> std::time::Duration {
        self.last_cast
    }

    /// The camera intrinsics.
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    /// Likelihood `L_i` (mean score over the pixels, before clamping) of
    /// every particle. Buffers are reused between calls.
    pub fn likelihoods(
        &mut self,
        particles: &[Particle],
        pixels: &[(u32, u32)],
        table: &SimilarityTable,
    ) -> &[f32] {
        let (np, nj) = (particles.len(), pixels.len());
        self.scores.clear();
        self.scores.resize(np, 0.0);
        if np == 0 || nj == 0 || table.pixels() != nj {
            return &self.scores;
        }
        let dirs: Vec<Vector3<f32>> = pixels
            .iter()
            .map(|&(u, v)| self.intrinsics.pixel_dir(u, v).cast::<f32>())
            .collect();
        let t0 = std::time::Instant::now();
        // A caster that shares work between the rays of one image column
        // (the planar one) gets each particle's rays together, in column
        // order; the table columns follow the pixels there.
        let column_order = self.caster.wants_column_order();
        let mut cols: Vec<u32> = (0..nj as u32).collect();
        if column_order {
            cols.sort_by_key(|&j| pixels[j as usize]);
        }
        let cast_dirs: Vec<Vector3<f32>> = cols.iter().map(|&j| dirs[j as usize]).collect();
        // Pixel-major packets take the particles in packet order (compact
        // runs of PACKET); the scores go back to the caller's order at the
        // end.
        let (order, grouped) = if column_order {
            (Vec::new(), Vec::new())
        } else {
            let order = packet_order(particles, PACKET);
            let grouped: Vec<Particle> = order.iter().map(|&i| particles[i as usize]).collect();
            (order, grouped)
        };
        let pixel_major = match self.ray_order {
            _ if column_order => false,
            RayOrder::Auto => pixel_major_pays(&grouped, &dirs, PACKET),
            RayOrder::ParticleMajor => false,
            RayOrder::PixelMajor => true,
        };
        self.last_pixel_major = pixel_major;
        let cast = GroupCast {
            caster: &*self.caster,
            origin: self.origin,
            dirs: &cast_dirs,
            cols: &[],
            rows: &self.leaf_rows,
            cos: &table.cos,
            k: table.rows,
            miss: self.params.miss_score,
            t_max: self.params.max_range,
            pixel_major,
            fans: None,
            try_fans: column_order,
        };
        let cast_particles = if pixel_major { &grouped[..] } else { particles };
        // Mean scores in cast order.
        let means: Vec<f32> = match self.params.early_reject {
            None => {
                let sums = cast.sums(cast_particles, &cast_dirs, &cols);
                sums.into_iter().map(|s| s / nj as f32).collect()
            }
            Some(e) => cast.two_pass(cast_particles, &cast_dirs, &cols, &e),
        };
        if pixel_major {
            for (&i, &v) in order.iter().zip(&means) {
                self.scores[i as usize] = v;
            }
        } else {
            self.scores.copy_from_slice(&means);
        }
        self.last_cast = t0.elapsed();
        &self.scores
    }
}

/// What the groups of particles share in one call of
/// [`SensorModel::likelihoods`]: the caster, the pixels' directions in the
/// camera frame, the leaf-to-row map and the similarity table.
#[derive(Clone, Copy)]
struct GroupCast<'a> {
    caster: &'a dyn RayCaster,
    origin: Vector3<f64>,
    dirs: &'a [Vector3<f32>],
    /// The table column (pixel index) of each of `dirs`.
    cols: &'a [u32],
    rows: &'a [u32],
    /// `cos[j * k + r]`: pixel `j`'s score against feature row `r`.
    cos: &'a [f32],
    k: usize,
    miss: f32,
    t_max: f32,
    pixel_major: bool,
    /// The fans of `dirs` (see [`FanLayout`]), set per pass when
    /// `try_fans`.
    fans: Option<&'a FanLayout>,
    /// Offer the caster each particle's rays as fans
    /// ([`RayCaster::cast_fans`]); set with column order.
    try_fans: bool,
}

/// The pixels of a pass grouped by image column, read off their unit
/// camera-frame directions `(x, y, 1) / |(x, y, 1)|`: consecutive pixels
/// with the same `x` (one image column, since the caster wants column
/// order) form a fan. Through a level camera (its image's y axis along the
/// world's -z) a fan's rays, scaled to `(x, y, 1)`, share their horizontal
/// part, so a planar caster walks it once.
struct FanLayout {
    /// `(x, first pixel, end)` of each fan.
    fans: Vec<(f32, u32, u32)>,
    /// Each pixel's `y`.
    y: Vec<f32>,
    /// Each pixel's largest `t` in fan units (`(x, y, 1)` directions): the
    /// ray length limit over `|(x, y, 1)|`.
    t_max: Vec<f32>,
}

impl FanLayout {
    /// The layout of `dirs`, rays limited to `t_max` metres.
    fn of(dirs: &[Vector3<f32>], t_max: f32) -> Self {
        let mut fans: Vec<(f32, u32, u32)> = Vec::new();
        let (mut y, mut t_lim) = (
            Vec::with_capacity(dirs.len()),
            Vec::with_capacity(dirs.len()),
        );
        for (j, d) in dirs.iter().enumerate() {
            let x = d.x / d.z;
            y.push(d.y / d.z);
            t_lim.push(t_max * d.z);
            match fans.last_mut() {
                Some(f) if (f.0 - x).abs() <= 1e-6 * (1.0 + x.abs()) => f.2 = j as u32 + 1,
                _ => fans.push((x, j as u32, j as u32 + 1)),
            }
        }
        FanLayout {
            fans,
            y,
            t_max: t_lim,
        }
    }
}

impl GroupCast<'_> {
    /// Each particle's sum of scores over the pixels of `dirs` (table
    /// columns `cols`), in the order of `ps`. One task a group of
    /// particles: their rays are made, cast and scored while they are in
    /// cache, instead of an np x nj ray array (58 MB at 1024 x 1800)
    /// written, cast and read back.
    fn sums(&self, ps: &[Particle], dirs: &[Vector3<f32>], cols: &[u32]) -> Vec<f32> {
        let layout = self.try_fans.then(|| FanLayout::of(dirs, self.t_max));
        let pass = GroupCast {
            dirs,
            cols,
            fans: layout.as_ref(),
            ..*self
        };
        let nj = dirs.len();
        let mut out = vec![0.0f32; ps.len()];
        out.par_chunks_mut(RAY_GROUP)
            .zip(ps.par_chunks(RAY_GROUP))
            .for_each_init(
                || {
                    (
                        Vec::with_capacity(nj * RAY_GROUP),
                        vec![Hit::miss(); nj * RAY_GROUP],
                    )
                },
                |(rays, hits), (o, group)| pass.group(group, o, rays, hits),
            );
        out
    }

    /// Mean scores in two passes ([`EarlyReject`]): every `every`-th pixel
    /// first for all particles; the rest only for the particles whose
    /// first-pass sum reaches `ratio` times the best one. A particle
    /// stopped after the first pass keeps its first-pass mean.
    fn two_pass(
        &self,
        ps: &[Particle],
        dirs: &[Vector3<f32>],
        cols: &[u32],
        e: &EarlyReject,
    ) -> Vec<f32> {
        let every = e.every.max(2); // validated by `Filter::new`; kept safe here
        let (mut first, mut rest) = ((vec![], vec![]), (vec![], vec![]));
        for (j, (d, &c)) in dirs.iter().zip(cols).enumerate() {
            let pass = if j % every == 0 {
                &mut first
            } else {
                &mut rest
            };
            pass.0.push(*d);
            pass.1.push(c);
        }
        let s1 = self.sums(ps, &first.0, &first.1);
        let best = s1.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let gate = if best > 0.0 {
            e.ratio * best
        } else {
            f32::NEG_INFINITY
        };
        let survivors: Vec<usize> = (0..ps.len()).filter(|&i| s1[i] >= gate).collect();
        let sub: Vec<Particle> = survivors.iter().map(|&i| ps[i]).collect();
        let s2 = self.sums(&sub, &rest.0, &rest.1);
        let n1 = first.0.len() as f32;
        let mut means: Vec<f32> = s1.iter().map(|&s| s / n1).collect();
        for (&i, &s) in survivors.iter().zip(&s2) {
            means[i] = (s1[i] + s) / dirs.len() as f32;
        }
        means
    }

    /// Makes, casts and scores the rays of one group of particles; `out`
    /// gets each particle's sum of scores. `rays` and `hits` are the task's
    /// reused buffers.
    fn group(&self, group: &[Particle], out: &mut [f32], rays: &mut Vec<Ray>, hits: &mut [Hit]) {
        let nj = self.dirs.len();
        let hits = &mut hits[..nj * group.len()];
        if !self.cast_fans(group, hits) {
            self.rays(group, rays);
            self.caster.cast_serial(rays, hits);
        }
        self.score(hits, out);
    }

    /// Casts the group's rays as fans (particle-major) when the caster
    /// takes fans and every particle's camera is level (its image y axis
    /// within 1e-6 of the world's -z); `false`, writing nothing, if not.
    /// A hit's `t` is then in units of the pixel's `(x, y, 1)` direction.
    fn cast_fans(&self, group: &[Particle], hits: &mut [Hit]) -> bool {
        let Some(layout) = self.fans else {
            return false;
        };
        let frames = self.frames(group);
        let level = |r: &Matrix3<f32>| r[(0, 1)].powi(2) + r[(1, 1)].powi(2) <= 1e-12;
        if !frames.iter().all(|(r, _)| level(r)) {
            return false;
        }
        let nj = self.dirs.len();
        let (mut fans, mut slopes) = (Vec::with_capacity(layout.fans.len()), vec![0.0f32; nj]);
        for ((r, o), hits) in frames.iter().zip(hits.chunks_exact_mut(nj)) {
            let (c0, c2, gz) = (r.column(0), r.column(2), r[(2, 1)]);
            fans.clear();
            for &(x, s, e) in &layout.fans {
                let h = c0 * x + c2;
                fans.push(Fan {
                    dir: [h.x, h.y],
                    start: s,
                    end: e,
                });
                for (m, &y) in slopes[s as usize..e as usize]
                    .iter_mut()
                    .zip(&layout.y[s as usize..e as usize])
                {
                    *m = h.z + y * gz;
                }
            }
            if !self
                .caster
                .cast_fans(*o, &fans, &slopes, &layout.t_max, hits)
            {
                return false;
            }
        }
        true
    }

    /// Each particle's rotation and origin in the grid frame.
    fn frames(&self, group: &[Particle]) -> Vec<(Matrix3<f32>, [f32; 3])> {
        group
            .iter()
            .map(|p| {
                let r = p.pose.rotation.to_rotation_matrix().into_inner();
                let o = p.pose.translation.vector - self.origin;
                (r.cast::<f32>(), [o.x as f32, o.y as f32, o.z as f32])
            })
            .collect()
    }

    /// Every ray of the group, pixel-major (a row a pixel) or
    /// particle-major (a row a particle).
    fn rays(&self, group: &[Particle], rays: &mut Vec<Ray>) {
        let (m, nj) = (group.len(), self.dirs.len());
        let frames = self.frames(group);
        let t_max = self.t_max;
        let ray = |(r, o): &(Matrix3<f32>, [f32; 3]), d: &Vector3<f32>| {
            let w = r * d;
            Ray {
                origin: *o,
                dir: [w.x, w.y, w.z],
                t_min: 0.0,
                t_max,
            }
        };
        // Written in place (nested loops over exact slices), which the
        // compiler turns into tight code, unlike a flat_map.
        rays.resize(nj * m, Ray::new([0.0; 3], [1.0, 0.0, 0.0]));
        if self.pixel_major {
            for (row, d) in rays.chunks_exact_mut(m).zip(self.dirs) {
                for (r, f) in row.iter_mut().zip(&frames) {
                    *r = ray(f, d);
                }
            }
        } else {
            for (row, f) in rays.chunks_exact_mut(nj).zip(&frames) {
                for (r, d) in row.iter_mut().zip(self.dirs) {
                    *r = ray(f, d);
                }
            }
        }
    }

    /// Each particle's sum of scores over its pixels. Each particle sums
    /// its pixels in order in either layout, so both give the same floats.
    fn score(&self, hits: &[Hit], out: &mut [f32]) {
        let (m, nj, k) = (out.len(), self.dirs.len(), self.k);
        let score = |h: &Hit, j: usize| match self.rows.get(h.leaf as usize) {
            Some(&r) if (r as usize) < k => self
                .cos
                .get(self.cols[j] as usize * k + r as usize)
                .copied()
                .unwrap_or(self.miss),
            _ => self.miss,
        };
        out.fill(0.0);
        if self.pixel_major {
            for (j, row) in hits.chunks_exact(m).enumerate() {
                for (o, h) in out.iter_mut().zip(row) {
                    *o += score(h, j);
                }
            }
        } else {
            for (o, row) in out.iter_mut().zip(hits.chunks_exact(nj)) {
                *o = row
                    .iter()
                    .enumerate()
                    .fold(0.0, |a, (j, h)| a + score(h, j));
            }
        }
    }
}
