//! The sensor model of the paper (eq. 2): a particle's likelihood is the
//! mean cosine similarity between the sampled pixels' features and the map
//! features hit by the particle's rays through those pixels.
//!
//! Per frame, the cosines of the N sampled pixel features against the K
//! database rows are computed once ([`SimilarityTable`], N x K); per ray the
//! work is a cast and a table look-up. Rays are generated particle-major
//! (each particle's rays through the sampled pixels, which the sampler
//! orders so that neighbours are near in the image): consecutive rays share
//! an origin and nearly a direction, so the caster's 8-wide packets are
//! coherent. Measured on the 1 M-voxel rooms map with the default brick
//! geometry, 1024 particles x 2048 pixels, rays per CPU-second in four
//! interleaved runs on a shared machine (`OMCL_BENCH_GEOMETRIES=3 cargo
//! bench --bench raycast`): particle-major in 8-wide packets 6.9 to 7.8 M,
//! pixel-major (same pixel over nearby particles) in 8-wide packets 5.7 to
//! 6.5 M, single rays 5.2 to 6.3 M in either order. With the old
//! one-box-per-voxel geometry single rays pixel-major were best (5.3 to
//! 6.2 M, against 2.8 to 3.2 M for particle-major packets), which is why the
//! order was pixel-major before.
//!
//! Each particle is one parallel task that makes its rays, casts them on
//! its thread and scores them while they are in cache (see
//! [`SensorModel::likelihoods`]). Measured with `cargo bench --bench mcl`
//! (1024 x 2048, interleaved runs on 2026-11-22): one ray array for all
//! particles, cast in parallel chunks and scored afterwards, 114.9 to
//! 115.5 ms a step; one task a particle 105.1 ms; with the sampler's
//! Morton pixel order instead of 16 x 16 tiles 102.4 to 103.5 ms.

use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::MclError;
use super::particles::Particle;
use super::sampling::FrameFeatures;
use crate::geometry::{Intrinsics, Ray};
use crate::map::Cell;
use crate::map::FeatureDb;
use crate::map::features::dot;
use crate::raycast::{
    BrickEdge, BuildOptions, EmbreeCaster, EmbreeError, Geometry, Hit, Packet, RayCaster,
};

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
        let k = db.len();
        let cos: Vec<f32> = db
            .map_dots(
                pixels.len(),
                |j, buf| frame.feature(pixels[j].0, pixels[j].1, buf),
                |f, out| {
                    let n = dot(f, f).sqrt();
                    if !(n.is_finite() && n > 0.0) {
                        out.fill(0.0);
                        return out.to_vec();
                    }
                    out.iter_mut().for_each(|o| *o /= n);
                    if contrast {
                        let lo = out.iter().copied().fold(f32::INFINITY, f32::min);
                        let hi = out.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                        if hi > lo {
                            out.iter_mut().for_each(|o| *o = (*o - lo) / (hi - lo));
                        }
                    }
                    out.to_vec()
                },
            )
            .concat();
        Ok(SimilarityTable { rows: k, cos })
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.cos.len().checked_div(self.rows).unwrap_or(0)
    }

    /// Cosine of pixel `j` against database row `k`.
    pub fn get(&self, j: usize, k: usize) -> f32 {
        self.cos[j * self.rows + k]
    }
}

/// Choices the paper leaves open.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SensorParams {
    /// Score of a ray that hits nothing (paper: undefined; the authors'
    /// code skips misses). 0 means "no evidence either way".
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
}

impl Default for SensorParams {
    fn default() -> Self {
        SensorParams {
            miss_score: 0.0,
            max_range: f32::INFINITY,
            contrast: true,
        }
    }
}

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

/// Casts particles' rays in a map and scores them.
pub struct SensorModel {
    caster: Arc<dyn RayCaster>,
    leaf_rows: Arc<[u32]>,
    origin: Vector3<f64>,
    intrinsics: Intrinsics,
    pub params: SensorParams,
    scores: Vec<f32>,
    last_cast: std::time::Duration,
}

impl SensorModel {
    /// The Embree caster measured fastest for the filter's rays, over
    /// voxels of edge `resolution` (metres) at `cells` (grid frame): bricks
    /// of edge 8 in 8-wide packets. Against the default edge 4 on the 1 M
    /// voxel rooms map (1024 particles x 2048 pixels, particle-major), edge
    /// 8 gave 3 to 20 % more rays per CPU-second in six interleaved runs
    /// (its BVH is 1.4 MB instead of 7.5 MB; camera images prefer edge 4).
    pub fn embree_caster(resolution: f32, cells: &[Cell]) -> Result<EmbreeCaster, EmbreeError> {
        let options = BuildOptions {
            geometry: Geometry::Bricks(BrickEdge::Eight),
            ..BuildOptions::default()
        };
        Ok(EmbreeCaster::with_options(resolution, cells, options)?.with_packet(Packet::Eight))
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
        }
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
        let (caster, origin) = (&*self.caster, self.origin);
        let (rows, miss, t_max) = (
            &*self.leaf_rows,
            self.params.miss_score,
            self.params.max_range,
        );
        let (k, cos) = (table.rows, &table.cos);
        let t0 = std::time::Instant::now();
        // One task a particle: its rays are made, cast and scored while they
        // are in cache, instead of an np x nj ray array (58 MB at 1024 x
        // 1800) written, cast and read back.
        self.scores
            .par_iter_mut()
            .zip(particles.par_iter())
            .for_each_init(
                || (Vec::with_capacity(nj), vec![Hit::miss(); nj]),
                |(rays, hits), (out, p)| {
                    let r: Matrix3<f32> = p
                        .pose
                        .rotation
                        .to_rotation_matrix()
                        .into_inner()
                        .cast::<f32>();
                    let o = p.pose.translation.vector - origin;
                    let o = [o.x as f32, o.y as f32, o.z as f32];
                    rays.clear();
                    rays.extend(dirs.iter().map(|d| {
                        let w = r * d;
                        Ray {
                            origin: o,
                            dir: [w.x, w.y, w.z],
                            t_min: 0.0,
                            t_max,
                        }
                    }));
                    caster.cast_serial(rays, hits);
                    let mut sum = 0.0f32;
                    for (j, h) in hits.iter().enumerate() {
                        sum += match rows.get(h.leaf as usize) {
                            Some(&r) if (r as usize) < k => {
                                cos.get(j * k + r as usize).copied().unwrap_or(miss)
                            }
                            _ => miss,
                        };
                    }
                    *out = sum / nj as f32;
                },
            );
        self.last_cast = t0.elapsed();
        &self.scores
    }
}
