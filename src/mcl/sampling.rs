//! Which pixels to cast: stratified sampling over feature clusters (paper,
//! "Stratified Ray Sampling"), plus uniform and "equal, with duplicates"
//! sampling for the ablation.
//!
//! Clusters are formed by assigning pixels to their most similar database
//! row. Only the pixels of a strided grid are clustered (stride `s`: one
//! pixel in `s * s`), and samples are drawn among those grid pixels, so the
//! per-frame cost is `(W H / s^2) K F` multiply-adds and features are needed
//! only at the grid and the sampled pixels. The products are kept
//! ([`Sample`]): the sampled pixels are grid pixels, so their similarity
//! table ([`super::SimilarityTable::of_sample`]) needs no second product.
//! A source that holds the grid's features contiguously
//! ([`FrameFeatures::grid_features`]: the simulator's encoder output, a
//! dense image at stride 1) is multiplied where it lies, not copied out
//! pixel by pixel. Together these took the features stage of a step from
//! 10.2 / 10.9 to 7.4 / 7.8 ms (3-D map, 29 rows) and from 13.4 / 14.0 to
//! 10.8 / 11.3 ms (floor plan, 62 rows) on the held-out sequence 1000, two
//! interleaved runs each (docs/table1.md, "Speed, 2-D against 3-D").

use rand::Rng;
use rand::seq::SliceRandom;

use super::MclError;
use crate::frame::{FrameFeatures, grid_centre};
use crate::map::FeatureDb;
use crate::map::features::Features;

/// How pixels are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum SamplingStrategy {
    /// Equal number per cluster, with replacement, duplicates dropped
    /// (the paper's method).
    #[default]
    Stratified,
    /// Distinct pixels uniformly over the image.
    Uniform,
    /// Equal number per cluster, duplicates kept (small clusters then count
    /// several times in the mean).
    EqualWithDuplicates,
}

/// The boundary margin (cells) for a car's forward camera on streets
/// (KITTI camera 2, 1241 x 376): none. The width rule would give 2 cells
/// there (8 px), which skips the thin structures and edges (poles, hedge
/// tops, kerbs, facade corners) that fix a car's position at corners. On
/// the tuning streets 1 and 2 (Table IV, first 200 frames of KITTI 00,
/// `gt` features, the authors' odometry noise) translation / rotation
/// mean: 2 cells 0.454 m / 1.48 deg (0 of 2 completed), 1 cell 0.360 m /
/// 1.52 deg on street 1 (not completed), 0 cells 0.392 m / 1.26 deg (1 of
/// 2).
pub const STREET_BOUNDARY_MARGIN: u32 = 0;

/// Parameters of pixel sampling.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SamplingParams {
    pub strategy: SamplingStrategy,
    /// Draws in total: for the per-cluster strategies `rays / clusters`
    /// draws per cluster (so after dropping duplicates there may be fewer).
    pub rays: usize,
    /// Grid stride in pixels for clustering and candidate pixels.
    pub stride: u32,
    /// Per-cluster strategies: draw a cluster's pixels only from grid cells
    /// whose clusters agree with every grid neighbour within this many
    /// cells (Chebyshev distance, `stride` pixels a cell), so pixels near a
    /// label boundary, where encoders and annotations are least reliable,
    /// are avoided; a cluster with no such cell keeps all of its cells.
    /// `Some(0)` samples every cell, as the paper does. `None` (the
    /// default) takes [`SamplingParams::boundary_margin_width`] of the image
    /// width instead, so the margin follows the resolution as boundary
    /// errors do (encoders run at a fixed input size and are upsampled).
    #[serde(default)]
    pub boundary_margin: Option<u32>,
    /// The margin, when `boundary_margin` is `None`, as a fraction of the
    /// image width, rounded to whole cells: 0.0075 gives 1 cell on the
    /// benchmark's 540 x 540 images (stride 4) and 0 below about 270
    /// pixels. Over the 10 benchmark sequences (APE RMSE, 0 -> 1 cell)
    /// OMCL_GT 0.098 -> 0.091 m, OMCL_LSeg 0.103 -> 0.094, OMCL_auto_LSeg
    /// 0.096 -> 0.096, OMCL_Open_LSeg 0.165 -> 0.169, OMCL_GT_exact 0.091
    /// -> 0.088; 2 cells and more were worse than 1 on 3 sequences. Small
    /// images must not lose their boundaries: there they are most of the
    /// pose information, and on the 96 x 72 frames of this module's tests
    /// a margin of 1 cell leaves only the insides of large regions, so
    /// poses 0.14 m apart score the same.
    #[serde(default = "default_boundary_margin_width")]
    pub boundary_margin_width: f32,
    /// Stratify over the rows the map marks when it marks some (a floor
    /// plan's own rows and the floor and ceiling words, see
    /// [`crate::mcl::Filter::with_strata`]); `false`: over every row of the
    /// map's database whatever it marks. The default, `true`, is every
    /// filter's but [`crate::mcl::FilterConfig::floor_plan_point_cloud`]'s.
    #[serde(default = "default_map_strata")]
    pub map_strata: bool,
}

fn default_boundary_margin_width() -> f32 {
    SamplingParams::default().boundary_margin_width
}

fn default_map_strata() -> bool {
    SamplingParams::default().map_strata
}

impl SamplingParams {
    /// The boundary margin in grid cells for an image `width` pixels wide.
    pub fn margin_cells(&self, width: u32) -> u32 {
        self.boundary_margin.unwrap_or_else(|| {
            let cells = width.div_ceil(self.stride.max(1)) as f32;
            // Non-finite or negative widths give 0 (the cast saturates).
            (self.boundary_margin_width * cells).round() as u32
        })
    }
}

impl Default for SamplingParams {
    fn default() -> Self {
        SamplingParams {
            strategy: SamplingStrategy::Stratified,
            rays: 2048,
            stride: 4,
            boundary_margin: None,
            boundary_margin_width: 0.0075,
            map_strata: true,
        }
    }
}

/// Whether grid cell `i` (of a `gw` x `gh` grid of cluster rows) has a cell
/// of another cluster within `margin` cells.
fn near_boundary(rows: &[u32], gw: usize, gh: usize, i: usize, margin: usize) -> bool {
    let (x, y) = (i % gw, i / gw);
    let (x0, x1) = (x.saturating_sub(margin), (x + margin).min(gw - 1));
    let (y0, y1) = (y.saturating_sub(margin), (y + margin).min(gh - 1));
    (y0..=y1).any(|yy| {
        rows[yy * gw + x0..=yy * gw + x1]
            .iter()
            .any(|&r| r != rows[i])
    })
}

/// The clustering grid of a frame: its candidate pixels (centres of the
/// stride cells), each one's nearest row and, where they were computed, its
/// dot products with the rows.
struct Grid {
    px: Vec<(u32, u32)>,
    rows: Vec<u32>,
    /// Products of the pixels whose rows the frame did not name.
    scores: Option<GridScores>,
}

/// Dot products of some grid pixels with the database rows.
struct GridScores {
    k: usize,
    /// Per grid pixel, its place in `dots` / `norms`, or `u32::MAX`.
    slot: Vec<u32>,
    dots: Vec<f32>,
    norms: Vec<f32>,
}

/// `strata`: which rows a pixel may be clustered to (all when `None`).
fn cluster_grid(
    frame: &dyn FrameFeatures,
    db: &FeatureDb,
    stride: u32,
    strata: Option<&[bool]>,
) -> Grid {
    use rayon::prelude::*;
    let s = stride.max(1);
    let (w, h) = (frame.width(), frame.height());
    let px: Vec<(u32, u32)> = (0..h.div_ceil(s))
        .flat_map(|gy| (0..w.div_ceil(s)).map(move |gx| (gx, gy)))
        .map(|(gx, gy)| grid_centre(s, w, h, gx, gy))
        .collect();
    // Rows the frame names itself (label images); the others by the
    // nearest row of their feature, all features in one matrix product
    // (where the frame holds the grid's features, multiplied in place).
    let mut rows: Vec<Option<u32>> = px
        .par_iter()
        .map(|&(u, v)| frame.nearest_row(u, v))
        .collect();
    let todo: Vec<usize> = (0..px.len()).filter(|&i| rows[i].is_none()).collect();
    let mut scores = None;
    if !todo.is_empty() {
        let k = db.len();
        let fill = |j: usize, buf: &mut [f32]| frame.feature(px[todo[j]].0, px[todo[j]].1, buf);
        let source = match frame.grid_features(s) {
            Some(all) if todo.len() == px.len() && all.len() == px.len() * db.dim() => {
                Features::Slice(all)
            }
            _ => Features::Fill(&fill),
        };
        let (dots, norms) = db.dots_and_norms(todo.len(), source);
        // Each feature's most similar row (the first of equals; among the
        // strata rows), in parallel: 18,225 x K comparisons are a
        // millisecond on one core.
        let allowed: Option<Vec<usize>> = strata.map(|s| {
            (0..k)
                .filter(|&r| s.get(r).copied().unwrap_or(true))
                .collect()
        });
        let nearest: Vec<u32> = dots
            .par_chunks(k.max(1))
            .map(|d| {
                let mut best = (0u32, f32::NEG_INFINITY);
                match &allowed {
                    None => {
                        for (r, &x) in d.iter().enumerate() {
                            if x > best.1 {
                                best = (r as u32, x);
                            }
                        }
                    }
                    Some(rows) => {
                        for &r in rows {
                            if d[r] > best.1 {
                                best = (r as u32, d[r]);
                            }
                        }
                    }
                }
                best.0
            })
            .collect();
        let mut slot = vec![u32::MAX; px.len()];
        for (j, (&i, &r)) in todo.iter().zip(&nearest).enumerate() {
            slot[i] = j as u32;
            rows[i] = Some(r);
        }
        scores = Some(GridScores {
            k,
            slot,
            dots,
            norms,
        });
    }
    let rows = rows.into_iter().map(|r| r.unwrap_or(0)).collect();
    Grid { px, rows, scores }
}

/// A frame's sampled pixels, in the order the filter casts them, and,
/// when the sampler's clustering computed them, their features' dot
/// products with the database rows and norms, from which
/// [`super::SimilarityTable::of_sample`] builds the frame's table without
/// a second product.
#[derive(Debug, Clone)]
pub struct Sample {
    pub pixels: Vec<(u32, u32)>,
    /// `(dots, norms)`: `dots[j * K + k]`, pixel `j` against row `k`.
    pub(crate) scores: Option<(Vec<f32>, Vec<f32>)>,
}

/// Chooses the frame's pixels (the same for every particle). Fails when the
/// frame's dimension differs from the database's or the image is empty.
pub fn sample_pixels<R: Rng>(
    frame: &dyn FrameFeatures,
    db: &FeatureDb,
    params: &SamplingParams,
    rng: &mut R,
) -> Result<Vec<(u32, u32)>, MclError> {
    sample(frame, db, params, rng).map(|s| s.pixels)
}

/// [`sample_pixels`], keeping the sampled pixels' products with the rows
/// where the clustering computed them.
pub fn sample<R: Rng>(
    frame: &dyn FrameFeatures,
    db: &FeatureDb,
    params: &SamplingParams,
    rng: &mut R,
) -> Result<Sample, MclError> {
    sample_in_strata(frame, db, params, rng, None)
}

/// [`sample`] with the per-cluster strategies' clusters formed over the
/// rows `strata` marks only (`strata[r]`; rows past its end count as
/// marked): each grid pixel joins its most similar marked row. The
/// products with every row are kept for the similarity table. A floor
/// plan's 2-D map marks its own rows and the floor and ceiling words, not
/// the blends its sensor derives from them
/// ([`crate::session::floorplan::PlanScene::strata`]). Rows a frame
/// names itself ([`FrameFeatures::nearest_row`]) are taken as named.
pub fn sample_in_strata<R: Rng>(
    frame: &dyn FrameFeatures,
    db: &FeatureDb,
    params: &SamplingParams,
    rng: &mut R,
    strata: Option<&[bool]>,
) -> Result<Sample, MclError> {
    if frame.dim() != db.dim() {
        return Err(MclError::DimMismatch {
            expected: db.dim(),
            got: frame.dim(),
        });
    }
    if frame.width() == 0 || frame.height() == 0 || params.rays == 0 {
        return Err(MclError::NoPixels);
    }
    if db.is_empty() {
        return Err(MclError::EmptyDb);
    }
    let out = match params.strategy {
        SamplingStrategy::Uniform => {
            let s = params.stride.max(1);
            let (w, h) = (frame.width(), frame.height());
            let mut px: Vec<(u32, u32)> = (0..h.div_ceil(s))
                .flat_map(|gy| (0..w.div_ceil(s)).map(move |gx| (gx, gy)))
                .map(|(gx, gy)| grid_centre(s, w, h, gx, gy))
                .collect();
            let n = params.rays.min(px.len());
            px.partial_shuffle(rng, n);
            px.truncate(n);
            px.sort_unstable_by_key(|&(u, v)| crate::morton::encode2(u, v));
            Sample {
                pixels: px,
                scores: None,
            }
        }
        SamplingStrategy::Stratified | SamplingStrategy::EqualWithDuplicates => {
            let Grid { px, rows, scores } = cluster_grid(frame, db, params.stride, strata);
            let mut clusters: Vec<Vec<usize>> = vec![Vec::new(); db.len()];
            for (i, &r) in rows.iter().enumerate() {
                if let Some(c) = clusters.get_mut(r as usize) {
                    c.push(i);
                }
            }
            clusters.retain(|c| !c.is_empty());
            let m = params.margin_cells(frame.width()) as usize;
            if m > 0 {
                let s = params.stride.max(1);
                let (gw, gh) = (
                    frame.width().div_ceil(s) as usize,
                    frame.height().div_ceil(s) as usize,
                );
                for c in clusters.iter_mut() {
                    let inner: Vec<usize> = c
                        .iter()
                        .copied()
                        .filter(|&i| !near_boundary(&rows, gw, gh, i, m))
                        .collect();
                    if !inner.is_empty() {
                        *c = inner;
                    }
                }
            }
            let per = params.rays.div_ceil(clusters.len().max(1));
            let mut picks: Vec<usize> = Vec::with_capacity(per * clusters.len());
            for c in &clusters {
                for _ in 0..per {
                    picks.push(c[rng.random_range(0..c.len())]);
                }
            }
            if params.strategy == SamplingStrategy::Stratified {
                picks.sort_unstable();
                picks.dedup();
            }
            // Nearby pixels consecutive (Morton order: each run of 8 fills
            // a compact patch of the image): one particle's rays through
            // them stay coherent in the caster's packets.
            picks.sort_by_key(|&i| crate::morton::encode2(px[i].0, px[i].1));
            let scores = scores.and_then(|g| {
                let slots: Option<Vec<usize>> = picks
                    .iter()
                    .map(|&i| (g.slot[i] != u32::MAX).then_some(g.slot[i] as usize))
                    .collect();
                let slots = slots?;
                let dots = slots
                    .iter()
                    .flat_map(|&j| &g.dots[j * g.k..(j + 1) * g.k])
                    .copied()
                    .collect();
                Some((dots, slots.iter().map(|&j| g.norms[j]).collect()))
            });
            Sample {
                pixels: picks.into_iter().map(|i| px[i]).collect(),
                scores,
            }
        }
    };
    if out.pixels.is_empty() {
        return Err(MclError::NoPixels);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::DenseFeatures;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// A 64 x 64 image whose left 60 columns are row 0 and right 4 row 1.
    fn frame() -> (DenseFeatures, FeatureDb) {
        let db = FeatureDb::from_rows(2, 0.02, vec![1.0, 0.0, 0.0, 1.0]).unwrap();
        let mut data = Vec::new();
        for _v in 0..64 {
            for u in 0..64 {
                data.extend(if u < 60 { [1.0, 0.1] } else { [0.1, 1.0] });
            }
        }
        (
            DenseFeatures {
                width: 64,
                height: 64,
                dim: 2,
                data,
            },
            db,
        )
    }

    #[test]
    fn stratified_gives_small_clusters_an_equal_share() {
        let (f, db) = frame();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let p = SamplingParams {
            strategy: SamplingStrategy::Stratified,
            rays: 40,
            stride: 1,
            boundary_margin: Some(0),
            ..Default::default()
        };
        let px = sample_pixels(&f, &db, &p, &mut rng).unwrap();
        let small = px.iter().filter(|(u, _)| *u >= 60).count();
        // 20 draws among 256 small-cluster pixels: about 20 distinct.
        assert!((15..=20).contains(&small), "{small}");
        let mut d = px.clone();
        d.sort();
        d.dedup();
        assert_eq!(d.len(), px.len(), "duplicates dropped");

        let p = SamplingParams {
            strategy: SamplingStrategy::Uniform,
            ..p
        };
        let px = sample_pixels(&f, &db, &p, &mut rng).unwrap();
        assert_eq!(px.len(), 40);
        let small = px.iter().filter(|(u, _)| *u >= 60).count();
        assert!(small <= 8, "uniform rarely hits a 6 % cluster: {small}");
    }

    /// Strata leave a blend row out of the clustering: three regions
    /// (columns 0..30 along row 0, 30..60 along a blend row 2 of rows 0
    /// and 1, 60..64 along row 1) are three clusters over every row but
    /// two over rows 0 and 1, so the small region draws half the rays
    /// instead of a third. Every row is still in the kept products.
    #[test]
    fn strata_leave_unmarked_rows_out_of_the_clusters() {
        let n = (1.0f32 + 0.09).sqrt();
        let db = FeatureDb::from_rows(2, 0.02, vec![1.0, 0.0, 0.0, 1.0, 1.0 / n, 0.3 / n]).unwrap();
        let mut data = Vec::new();
        for _v in 0..64 {
            for u in 0..64 {
                data.extend(match u {
                    0..30 => [1.0, 0.0],
                    30..60 => [1.0, 0.3],
                    _ => [0.0, 1.0],
                });
            }
        }
        let f = DenseFeatures {
            width: 64,
            height: 64,
            dim: 2,
            data,
        };
        let p = SamplingParams {
            strategy: SamplingStrategy::EqualWithDuplicates,
            rays: 60,
            stride: 1,
            boundary_margin: Some(0),
            ..Default::default()
        };
        let small = |strata: Option<&[bool]>| {
            let mut rng = ChaCha8Rng::seed_from_u64(8);
            let s = sample_in_strata(&f, &db, &p, &mut rng, strata).unwrap();
            let (dots, norms) = s.scores.as_ref().unwrap();
            assert_eq!(dots.len(), 3 * norms.len());
            assert_eq!(norms.len(), s.pixels.len());
            s.pixels.iter().filter(|(u, _)| *u >= 60).count()
        };
        assert_eq!(small(None), 20);
        assert_eq!(small(Some(&[true, true, false])), 30);
        // Marking every row is no mask at all.
        assert_eq!(small(Some(&[true; 3])), 20);
    }

    #[test]
    fn equal_with_duplicates_keeps_every_draw() {
        let (f, db) = frame();
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let p = SamplingParams {
            strategy: SamplingStrategy::EqualWithDuplicates,
            rays: 600,
            stride: 2,
            boundary_margin: Some(0),
            ..Default::default()
        };
        let px = sample_pixels(&f, &db, &p, &mut rng).unwrap();
        assert_eq!(px.len(), 600);
        // Cluster 1 has 2 x 32 grid pixels: 300 draws must repeat some.
        let mut d: Vec<_> = px.iter().filter(|(u, _)| *u >= 60).collect();
        assert_eq!(d.len(), 300);
        d.sort();
        d.dedup();
        assert!(d.len() <= 64);
    }

    #[test]
    fn boundary_margin_avoids_cells_next_to_another_cluster() {
        let (f, db) = frame();
        // Stride 4: a 16 x 16 grid, cluster 1 is grid column 15 (u = 62),
        // cluster 0 columns 0 to 14 (u = 2, 6, ..., 58).
        let p = SamplingParams {
            strategy: SamplingStrategy::Stratified,
            rays: 2048,
            stride: 4,
            boundary_margin: Some(0),
            ..Default::default()
        };
        let columns = |margin: u32| {
            let mut rng = ChaCha8Rng::seed_from_u64(8);
            let p = SamplingParams {
                boundary_margin: Some(margin),
                ..p
            };
            let mut us: Vec<u32> = sample_pixels(&f, &db, &p, &mut rng)
                .unwrap()
                .iter()
                .map(|&(u, _)| u)
                .collect();
            us.sort();
            us.dedup();
            us
        };
        // 1024 draws over 240 cells reach every column of cluster 0.
        assert_eq!(columns(0), (0..16).map(|x| 4 * x + 2).collect::<Vec<_>>());
        // Margin 2: cluster 0 loses columns 13 and 14; cluster 1 has no cell
        // away from cluster 0 and keeps its own.
        let mut want: Vec<u32> = (0..13).map(|x| 4 * x + 2).collect();
        want.push(62);
        assert_eq!(columns(2), want);
    }

    #[test]
    fn the_default_margin_follows_the_image_width() {
        let p = SamplingParams::default();
        // 1 cell on the benchmark's 540 px images, none on small ones.
        assert_eq!(p.margin_cells(540), 1);
        assert_eq!(p.margin_cells(640), 1);
        assert_eq!(p.margin_cells(96), 0);
        assert_eq!(p.margin_cells(300), 1);
        assert_eq!(p.margin_cells(260), 0);
        assert_eq!(p.margin_cells(1241), 2);
        // An explicit margin wins; a broken width fraction gives none.
        let fixed = SamplingParams {
            boundary_margin: Some(3),
            ..p
        };
        assert_eq!(fixed.margin_cells(96), 3);
        for w in [f32::NAN, -1.0] {
            let bad = SamplingParams {
                boundary_margin_width: w,
                ..p
            };
            assert_eq!(bad.margin_cells(540), 0);
        }
        // Serialized configurations without the new fields read as the
        // defaults; `null` is the automatic margin.
        let old: SamplingParams =
            serde_json::from_str(r#"{"strategy":"Stratified","rays":2048,"stride":4}"#).unwrap();
        assert_eq!(old, p);
        let json = serde_json::to_string(&p).unwrap();
        assert!(json.contains("\"boundary_margin\":null"), "{json}");
    }

    #[test]
    fn wrong_dimension_is_an_error() {
        let (mut f, db) = frame();
        f.dim = 3;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        assert_eq!(
            sample_pixels(&f, &db, &SamplingParams::default(), &mut rng),
            Err(MclError::DimMismatch {
                expected: 2,
                got: 3
            })
        );
    }
}
