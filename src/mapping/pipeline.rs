//! The map-building pipelines users run, the paper's two input options:
//! - from a cloud (`omcl map cloud`): read a point-cloud file or a
//!   SemanticKITTI sequence, drop the points the authors drop, attach or
//!   compute per-point features, integrate them on a grid centred on the
//!   cloud ([`load_cloud`], [`map_from_cloud`]);
//! - from posed RGB-D frames (`omcl map rgbd`): depth back-projected with
//!   each frame's labels, feature files or encoder output
//!   ([`map_from_rgbd`]).
//!
//! The command line only parses options, shows progress and saves.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use super::{Feature, IntegrationStats};
use crate::encode::{EncodeError, PointEncoder};
use crate::io::cloud::{CloudError, PointCloud};
use crate::io::formats::{CloudFormat, read_point_cloud};
use crate::io::kitti::{AggregateOptions, KittiSequence};
use crate::io::labels::EmbeddingTable;
use crate::map::integrate::KeepBox;
use crate::map::{FeatureDb, FeatureDbError, GridSpec, Integrator, LanguageMap, MapError};

/// Errors of the pipeline; each names its input.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error(transparent)]
    Cloud(#[from] CloudError),
    #[error(transparent)]
    Db(#[from] FeatureDbError),
    #[error(transparent)]
    Map(#[from] MapError),
    #[error("{source_name}: {source}")]
    Encode {
        source_name: String,
        source: EncodeError,
    },
    #[error(transparent)]
    Mapping(#[from] super::MappingError),
    #[error(transparent)]
    Npy(#[from] crate::io::npy::NpyError),
    #[error(transparent)]
    Poses(#[from] crate::io::poses::PosesError),
    /// The inputs do not make a map (why, and what to pass).
    #[error("{0}")]
    Input(String),
}

/// Where the points come from and which of them to keep.
#[derive(Debug, Clone, Default)]
pub struct CloudInput {
    /// A point-cloud file or a SemanticKITTI sequence folder.
    pub path: PathBuf,
    /// The file's format when its extension does not tell.
    pub format: Option<CloudFormat>,
    /// A single KITTI scan's `.label` file (default: beside it or in
    /// `../labels/`).
    pub labels: Option<PathBuf>,
    /// Per-point features (`N x F` .npy).
    pub features: Option<PathBuf>,
    /// Sequence folders: at most this many scans from the start.
    pub frames: Option<usize>,
    /// Sequence folders: per-scan feature files `NNNNNN.npy` here.
    pub features_dir: Option<PathBuf>,
    /// Keep the points the authors drop (SemanticKITTI unlabeled, outlier
    /// and moving classes; LAS noise classes 7 and 18).
    pub keep_all: bool,
    /// Sequence folders: ignore points farther than this from the sensor.
    pub max_range: Option<f64>,
    /// PLY files: the vertex property holding the labels
    /// ([`crate::io::ply::PlyOptions::label_property`]).
    pub label_property: Option<String>,
}

/// Reads the cloud of `input`, features attached and dropped points gone,
/// validated.
pub fn load_cloud(input: &CloudInput) -> Result<PointCloud, PipelineError> {
    let path = &input.path;
    if path.is_dir() {
        let (seq, frames, opts) = open_sequence(input)?;
        return Ok(seq.aggregate(&frames, &opts)?);
    }
    let kitti_scan = input.format == Some(CloudFormat::KittiBin);
    if input.labels.is_some() && !kitti_scan {
        return Err(PipelineError::Input(
            "--labels is for a single KITTI scan (--format kitti); other formats carry their labels"
                .into(),
        ));
    }
    let format = input.format.or_else(|| CloudFormat::from_path(path));
    if input.label_property.is_some() && format != Some(CloudFormat::Ply) {
        return Err(PipelineError::Input(format!(
            "{}: --label-property is for PLY files (the others' labels have their place)",
            path.display()
        )));
    }
    let mut c = if kitti_scan {
        crate::io::kitti::read_labelled_scan(path, input.labels.as_deref())?
    } else if let Some(label) = &input.label_property {
        let opts = crate::io::ply::PlyOptions {
            label_property: Some(label.clone()),
        };
        crate::io::ply::read_ply_with(path, &opts)?
    } else {
        read_point_cloud(path, input.format)?
    };
    if let Some(f) = &input.features {
        if let Some((dim, _)) = &c.features {
            c.notes.push(format!(
                "{}: its own features ({dim} values a point) are replaced by --features {}",
                path.display(),
                f.display()
            ));
        }
        c.attach_features_npy(f)?;
    }
    // After the features are attached, so their rows stay with their
    // points.
    if kitti_scan && !input.keep_all {
        // As for sequences: unlabeled, outlier and moving points are dropped.
        if let Some(labels) = c.labels.clone() {
            let before = c.len();
            c.retain_indices(|i| !crate::io::labels::is_dropped_semantic_kitti(labels[i]));
            note_dropped(&mut c, path, before, "unlabeled, outlier and moving");
        }
    }
    let is_las = matches!(
        input.format.or_else(|| CloudFormat::from_path(path)),
        Some(CloudFormat::Las)
    );
    if is_las && !input.keep_all {
        // ASPRS classes 7 (low point, noise) and 18 (high noise) are outliers.
        if let Some(labels) = c.labels.clone() {
            let before = c.len();
            c.retain_indices(|i| !crate::io::las::is_asprs_noise(labels[i]));
            note_dropped(&mut c, path, before, "noise (ASPRS classes 7 and 18)");
        }
    }
    if let (Some(f), Some((dim, values))) = (&input.features, &c.features) {
        refuse_zero_features(f, *dim, values)?;
    }
    c.validate(&path.display().to_string())?;
    Ok(c)
}

/// Notes how many of `before` points a class filter left out of `c`.
fn note_dropped(c: &mut PointCloud, path: &Path, before: usize, what: &str) {
    let dropped = before - c.len();
    if dropped > 0 {
        c.notes.push(format!(
            "{}: {dropped} {what} points left out (--keep-all keeps them)",
            path.display()
        ));
    }
}

/// A feature is a direction: a point kept for the map whose feature row (from
/// `file`) is all zeros has none (nor one whose length f32 cannot hold), and
/// the map would refuse it without naming the file. Points dropped before
/// (unlabeled, noise) may have such rows.
fn refuse_zero_features(file: &Path, dim: usize, values: &[f32]) -> Result<(), CloudError> {
    let none = |r: &[f32]| !crate::io::labels::has_direction(r);
    let Some(i) = values.chunks_exact(dim).position(none) else {
        return Ok(());
    };
    let n = values.chunks_exact(dim).filter(|r| none(r)).count();
    let zeros = values
        .chunks_exact(dim)
        .filter(|r| r.iter().all(|&v| v == 0.0))
        .count();
    let what = if zeros == n {
        "all-zero feature rows".to_string()
    } else {
        format!(
            "feature rows without a direction in f32 (all zeros: {zeros}; the rest with a \
             length f32 cannot hold)"
        )
    };
    Err(CloudError::format(
        file,
        format!(
            "{what} for {n} of the {} points kept for the map (the first: point {i} of those \
             kept): a feature needs a direction; leave such points out of the cloud and the file",
            values.len() / dim
        ),
    ))
}

/// The sequence folder of `input`, the scans to use and how to filter them.
fn open_sequence(
    input: &CloudInput,
) -> Result<(KittiSequence, Vec<usize>, AggregateOptions), PipelineError> {
    let seq = KittiSequence::open(&input.path)?;
    let frames: Vec<usize> = seq
        .frames
        .iter()
        .copied()
        .take(input.frames.unwrap_or(usize::MAX))
        .collect();
    let opts = AggregateOptions {
        voxel_size: None,
        drop_unlabeled_outlier_moving: !input.keep_all,
        max_range: input.max_range,
        features_dir: input.features_dir.clone(),
    };
    Ok((seq, frames, opts))
}

/// The two passes of [`map_from_sequence`] (and of
/// [`super::tiles::map_from_tiles`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SequencePass {
    /// Reading every scan for the bounds of the kept points.
    Bounds,
    /// Integrating every scan.
    Mapping,
}

/// Builds the map of a SemanticKITTI sequence folder (`input.path`) one
/// scan at a time, so memory holds one scan and the map being integrated,
/// never the merged cloud (4541 scans of KITTI 00 are about 9 GB of
/// points): a first pass reads every scan for the centre of the kept
/// points (the grid's origin, as [`grid_for`] of the merged cloud), a
/// second integrates each scan and drops it. Points, their order and the
/// grid are those of `map_from_cloud(load_cloud(input))`, so the map is the
/// same. `progress(pass, scans done, scans)` after every scan.
pub fn map_from_sequence(
    input: &CloudInput,
    params: &BuildParams,
    table: Option<&EmbeddingTable>,
    progress: &mut dyn FnMut(SequencePass, usize, usize),
) -> Result<(LanguageMap, IntegrationStats), PipelineError> {
    let name = input.path.display().to_string();
    let (seq, frames, opts) = open_sequence(input)?;
    let mut origin = OriginEstimate::default();
    for (done, &f) in frames.iter().enumerate() {
        let scan = seq.filtered_scan(f, &opts)?;
        origin.add(&scan.points);
        progress(SequencePass::Bounds, done + 1, frames.len());
    }
    let centre = origin.finish(params.resolution).ok_or_else(|| {
        PipelineError::Input(format!(
            "{name}: empty result: no points left to map; no map written"
        ))
    })?;
    let (grid, keep) = (centre.grid, params.keep(&centre));
    let mut integ: Option<Integrator> = None;
    let mut stats = IntegrationStats::default();
    let mut label_rows: Option<LabelRows> = None;
    for (done, &f) in frames.iter().enumerate() {
        let scan = seq.filtered_scan(f, &opts)?;
        let s = match (&scan.features, &scan.labels, table) {
            (Some((dim, feats)), _, _) => {
                let integ = match &mut integ {
                    Some(i) => i,
                    None => integ.insert(
                        Integrator::new(
                            grid,
                            FeatureDb::new(*dim, params.tau)?.with_max_rows(params.max_rows),
                        )?
                        .keeping(keep),
                    ),
                };
                if integ.observation_db().dim() != *dim {
                    return Err(PipelineError::Input(format!(
                        "{name}: scan {f:06} has {dim}-d features, the scans before it {}-d",
                        integ.observation_db().dim()
                    )));
                }
                super::cloud::integrate_points(integ, &scan.points, |i| {
                    Feature::Vector(&feats[i * dim..(i + 1) * dim])
                })?
            }
            (None, Some(labels), Some(t)) => {
                let integ = match &mut integ {
                    Some(i) => i,
                    None => integ.insert(
                        Integrator::new(
                            grid,
                            FeatureDb::from_rows(t.dim, params.tau, t.data.clone())?,
                        )?
                        .keeping(keep),
                    ),
                };
                let rows = label_rows.get_or_insert_with(|| LabelRows::new(t));
                super::cloud::integrate_point_rows(integ, &scan.points, rows.rows(labels))
            }
            (None, Some(_), None) => return Err(no_table(&name)),
            (None, None, _) => return Err(no_features(&name)),
        };
        stats += s;
        progress(SequencePass::Mapping, done + 1, frames.len());
    }
    let integ = integ.ok_or_else(|| {
        PipelineError::Input(format!("{name}: empty result: no points left to map"))
    })?;
    if let Some(rows) = &label_rows {
        rows.check(&name, &stats)?;
    }
    Ok((finish(integ, &params.encoder, params.tau, &stats)?, stats))
}

/// Labels made rows through a class table, remembering the labels the
/// table lacks: when no point's label is in the table (the table of
/// another dataset, or a list numbered from 0 for a cloud with its
/// dataset's ids), the error names both sides instead of an empty map.
pub struct LabelRows<'a> {
    table: &'a EmbeddingTable,
    missing: std::collections::BTreeSet<u32>,
    rows: Vec<Option<u32>>,
}

/// Points integrated a batch from a cloud held whole.
const ROW_BATCH: usize = 1 << 20;

/// Labels the table lacks that [`LabelRows`] keeps, at most.
const MISSING_KEPT: usize = 1 << 12;

impl<'a> LabelRows<'a> {
    /// Rows through `table`.
    pub fn new(table: &'a EmbeddingTable) -> Self {
        Self {
            table,
            missing: Default::default(),
            rows: Vec::new(),
        }
    }

    /// The rows of `labels` (`None` for a label the table lacks).
    pub fn rows(&mut self, labels: &[u32]) -> &[Option<u32>] {
        self.rows.clear();
        for &l in labels {
            let r = self.table.row_index(l).map(|r| r as u32);
            if r.is_none() && self.missing.len() < MISSING_KEPT {
                self.missing.insert(l);
            }
            self.rows.push(r);
        }
        &self.rows
    }

    /// An error naming the labels seen and the table's ids when every
    /// point offered was skipped for its label.
    pub fn check(&self, input: &str, stats: &IntegrationStats) -> Result<(), PipelineError> {
        if stats.offered == 0 || stats.skipped < stats.offered || self.missing.is_empty() {
            return Ok(());
        }
        let list = |v: Vec<String>, total: usize| {
            let shown = v.len();
            let mut s = v.join(", ");
            if total > shown {
                let at_least = if total >= MISSING_KEPT {
                    "at least "
                } else {
                    ""
                };
                s.push_str(&format!(", ... ({at_least}{total} in all)"));
            }
            s
        };
        let seen: Vec<String> = self.missing.iter().take(12).map(u32::to_string).collect();
        let ids: Vec<String> = (self.table.ids.iter().zip(&self.table.names))
            .take(12)
            .map(|(i, n)| format!("{i} {n}"))
            .collect();
        Err(PipelineError::Input(format!(
            "{input}: none of the {} points' labels is a class of the table: the points carry \
             {}; the table's ids are {}. Give the class table of the cloud's dataset (`<id> \
             <name>` lines with the labels' ids; a list of bare names numbers them from 0) or a \
             built-in list (--classes semantickitti, asprs); no map written",
            stats.offered,
            list(seen, self.missing.len()),
            list(ids, self.table.ids.len()),
        )))
    }
}

fn no_table(input: &str) -> PipelineError {
    PipelineError::Input(format!(
        "{input}: points carry labels but no class table was given: pass --classes \
         semantickitti (SemanticKITTI ids) or asprs (LAS codes), or a class list file with \
         --embeddings NPY or --text-model ONNX"
    ))
}

fn no_features(input: &str) -> PipelineError {
    PipelineError::Input(format!(
        "{input}: points carry neither features nor labels (a class table maps labels, \
         which these points lack): pass --features (N x F .npy; --features-dir for a \
         sequence) or --point-model, or use a labelled cloud with --classes (a PLY's labels \
         are read from a vertex property named label, class, classification, semantic or \
         semantic_label, or from the one --label-property names, such as DALES's sem_class)"
    ))
}

/// Where a cloud's grid is centred: the per-axis median of the medians of
/// consecutive blocks of [`ORIGIN_BLOCK`] points, fed in the cloud's order
/// (so a sequence fed scan by scan gets the origin of its merged cloud).
/// A median, not the lower corner: one stray point far from the data (a
/// point at 0, 0, 0 in UTM coordinates, common in real LAS files) cannot
/// move the grid away from the data.
///
/// And where the data is ([`Centre::keep`]): the box from the 1st to the
/// 99th percentile of all the points on each axis (counted in 1 m bins, so
/// it does not depend on the points' order), grown on every side by
/// [`STRAY_GROWTH`] times its largest extent or [`STRAY_MARGIN_M`],
/// whichever is more. A point outside is a stray (a georeferenced file's
/// points at 0, 0, 0 lie hundreds of kilometres out) and is left out as
/// rejected; without this, at the coarse voxels aerial LiDAR wants, such a
/// point was within the grid's reach and made the map span the distance.
/// Separate clusters of real data within that reach are kept, however few
/// their points.
#[derive(Debug, Default)]
pub struct OriginEstimate {
    block: Vec<[f64; 3]>,
    medians: Vec<[f64; 3]>,
    /// Points a 1 m bin, per axis.
    bins: [rustc_hash::FxHashMap<i64, u64>; 3],
    count: u64,
}

/// Points a block of [`OriginEstimate`].
pub const ORIGIN_BLOCK: usize = 1 << 16;

/// Clouds of fewer points get no data box (their 1st percentile would be
/// their lowest point).
pub const STRAY_MIN_POINTS: u64 = 100;

/// The data's box grows by this many times its largest extent...
pub const STRAY_GROWTH: f64 = 10.0;

/// ... or by this many metres, whichever is more.
pub const STRAY_MARGIN_M: f64 = 10_000.0;

/// A cloud's grid and where its points are expected ([`OriginEstimate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Centre {
    /// The grid, centred on the cloud.
    pub grid: GridSpec,
    /// Points outside are strays; `None` when the cloud is too small to
    /// tell (under [`STRAY_MIN_POINTS`] points).
    pub keep: Option<KeepBox>,
}

impl OriginEstimate {
    /// Feeds the next points of the cloud.
    pub fn add(&mut self, points: &[[f64; 3]]) {
        for p in points {
            // A non-finite coordinate (which the readers leave out) counts
            // in no bin.
            if p.iter().all(|v| v.is_finite()) {
                for (bins, v) in self.bins.iter_mut().zip(p) {
                    *bins.entry(v.floor() as i64).or_insert(0) += 1;
                }
                self.count += 1;
            }
            self.block.push(*p);
            if self.block.len() == ORIGIN_BLOCK {
                let m = median3(&mut self.block);
                self.medians.push(m);
                self.block.clear();
            }
        }
    }

    /// The grid of resolution `resolution` centred on the points fed
    /// (the origin snapped to the resolution, so the voxels are those of
    /// any other snapped origin); `None` before any point.
    pub fn grid(self, resolution: f64) -> Option<GridSpec> {
        self.finish(resolution).map(|c| c.grid)
    }

    /// The grid ([`OriginEstimate::grid`]) and the box outside which a
    /// point is a stray; `None` before any point.
    pub fn finish(mut self, resolution: f64) -> Option<Centre> {
        if !self.block.is_empty() {
            let m = median3(&mut self.block);
            self.medians.push(m);
        }
        if self.medians.is_empty() {
            return None;
        }
        let keep = (self.count >= STRAY_MIN_POINTS).then(|| {
            let (lo_rank, hi_rank) = (self.count / 100, self.count - 1 - self.count / 100);
            let mut b = KeepBox {
                lo: [0.0; 3],
                hi: [0.0; 3],
            };
            for a in 0..3 {
                let mut bins: Vec<(i64, u64)> =
                    self.bins[a].iter().map(|(&k, &n)| (k, n)).collect();
                bins.sort_unstable();
                // The bins holding the points of those ranks (0-based).
                let (mut seen, mut lo, mut hi) = (0u64, None, None);
                for (k, n) in bins {
                    seen += n;
                    if lo.is_none() && seen > lo_rank {
                        lo = Some(k);
                    }
                    if hi.is_none() && seen > hi_rank {
                        hi = Some(k);
                    }
                }
                b.lo[a] = lo.unwrap_or(0) as f64;
                b.hi[a] = hi.unwrap_or(0) as f64 + 1.0;
            }
            b.grown(STRAY_GROWTH, STRAY_MARGIN_M)
        });
        Some(Centre {
            grid: grid_at(median3(&mut self.medians), resolution),
            keep,
        })
    }
}

/// The per-axis medians (the upper one of an even count) of `v`, which
/// must not be empty (NaN, which the readers leave out, would sort by its
/// sign bit).
fn median3(v: &mut [[f64; 3]]) -> [f64; 3] {
    let mid = v.len() / 2;
    std::array::from_fn(|a| {
        let (_, m, _) = v.select_nth_unstable_by(mid, |x, y| x[a].total_cmp(&y[a]));
        m[a]
    })
}

/// A grid centred on the cloud ([`OriginEstimate`]) with its origin
/// snapped to the resolution, so that georeferenced coordinates (UTM)
/// keep float precision and a stray point cannot push the data out of
/// the grid's reach (2^20 cells each way of the origin).
pub fn grid_for(points: &[[f64; 3]], resolution: f64) -> GridSpec {
    let mut o = OriginEstimate::default();
    o.add(points);
    o.grid(resolution)
        .unwrap_or_else(|| grid_at([0.0; 3], resolution))
}

/// The grid of resolution `resolution` whose origin is `at` snapped down.
fn grid_at(at: [f64; 3], resolution: f64) -> GridSpec {
    let snap = |v: f64| {
        if v.is_finite() {
            (v / resolution).floor() * resolution
        } else {
            0.0
        }
    };
    GridSpec {
        resolution,
        origin: Vector3::new(snap(at[0]), snap(at[1]), snap(at[2])),
    }
}

/// How the map is built.
#[derive(Debug, Clone)]
pub struct BuildParams {
    /// Voxel edge, metres.
    pub resolution: f64,
    /// The feature database's cosine-distance threshold.
    pub tau: f32,
    /// Cap on observation rows for raw features.
    pub max_rows: usize,
    /// Name of the feature space stored in the map (a point encoder's own
    /// name replaces it).
    pub encoder: String,
    /// Keep the points far outside the rest of the data ([`Centre::keep`])
    /// instead of leaving them out as strays.
    pub keep_strays: bool,
}

impl BuildParams {
    /// The box outside which points are left out, if any.
    pub fn keep(&self, centre: &Centre) -> Option<KeepBox> {
        if self.keep_strays { None } else { centre.keep }
    }
}

/// Builds the map of `cloud` (named `input` in errors): per-point
/// features from the cloud or from `encoder`, else labels through
/// `table` (the ground-truth mode). Fails, naming what to pass, when the
/// points carry neither or when nothing could be integrated.
pub fn map_from_cloud(
    cloud: PointCloud,
    input: &str,
    params: &BuildParams,
    table: Option<&EmbeddingTable>,
    encoder: Option<&mut PointEncoder>,
) -> Result<(LanguageMap, IntegrationStats), PipelineError> {
    map_from_cloud_with(cloud, input, params, table, encoder, &mut |_, _| {})
}

/// Points integrated between two calls of [`map_from_cloud_with`]'s
/// `progress` (512-dimensional features take a quarter of a millisecond a
/// point: 65,536 points are a few seconds).
const PROGRESS_BATCH: usize = 1 << 16;

/// [`map_from_cloud`], telling `progress(done, total)` the points
/// integrated so far (the same map: points are integrated one by one).
pub fn map_from_cloud_with(
    mut cloud: PointCloud,
    input: &str,
    params: &BuildParams,
    table: Option<&EmbeddingTable>,
    encoder: Option<&mut PointEncoder>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(LanguageMap, IntegrationStats), PipelineError> {
    if cloud.is_empty() {
        return Err(PipelineError::Input(format!(
            "{input}: empty result: no points left to map; no map written"
        )));
    }
    let mut origin = OriginEstimate::default();
    origin.add(&cloud.points);
    let centre = origin
        .finish(params.resolution)
        .expect("a cloud with points has a centre");
    let (grid, keep) = (centre.grid, params.keep(&centre));
    let mut name = params.encoder.clone();
    // Strays left out before a point encoder ran.
    let mut strays = 0;
    if let Some(enc) = encoder {
        // Points relative to the cloud's lower corner (snapped to the
        // resolution; strays, which are left out, not counted) keep f32
        // precision (UTM) and stay non-negative, as the encoder contract
        // (`crate::encode::point`) states.
        // Strays are left out before the encoder sees them (it is promised
        // non-negative coordinates from the corner of the rest).
        if let Some(k) = keep {
            let inside: Vec<bool> = cloud.points.iter().map(|p| k.contains(p)).collect();
            cloud.retain_indices(|i| inside[i]);
            strays = inside.len() - cloud.len();
        }
        let mut lo = [f64::INFINITY; 3];
        for p in &cloud.points {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
            }
        }
        let corner = grid_at(lo, params.resolution).origin;
        let pts: Vec<[f32; 3]> = cloud
            .points
            .iter()
            .map(|p| {
                let q = Vector3::from(*p) - corner;
                [q.x as f32, q.y as f32, q.z as f32]
            })
            .collect();
        let cols: Vec<[f32; 3]> = match &cloud.colors {
            Some(cs) => cs.iter().map(|k| k.map(|v| v as f32 / 255.0)).collect(),
            None => vec![[0.5; 3]; pts.len()],
        };
        let f = enc.encode(&pts, &cols).map_err(|e| PipelineError::Encode {
            source_name: format!("{input}: point encoder"),
            source: e,
        })?;
        cloud.features = Some((enc.feature_dim(), f));
        name = enc.card().name.clone();
    }
    let (integ, mut stats) = if let Some((dim, feats)) = &cloud.features {
        let db = FeatureDb::new(*dim, params.tau)?.with_max_rows(params.max_rows);
        let mut integ = Integrator::new(grid, db)?.keeping(keep);
        let total = cloud.points.len();
        let mut s = IntegrationStats::default();
        for (b, chunk) in cloud.points.chunks(PROGRESS_BATCH).enumerate() {
            let first = b * PROGRESS_BATCH;
            s += super::cloud::integrate_points(&mut integ, chunk, |i| {
                let i = first + i;
                Feature::Vector(&feats[i * dim..(i + 1) * dim])
            })?;
            progress(first + chunk.len(), total);
        }
        (integ, s)
    } else if let (Some(labels), Some(t)) = (&cloud.labels, table) {
        let db = FeatureDb::from_rows(t.dim, params.tau, t.data.clone())?;
        let mut integ = Integrator::new(grid, db)?.keeping(keep);
        // In batches: the rows and the integrator's sort keys take 24
        // bytes a point, which for the whole cloud at once came on top of
        // the cloud.
        let mut rows = LabelRows::new(t);
        let mut s = IntegrationStats::default();
        let (total, mut done) = (cloud.points.len(), 0);
        for (p, l) in cloud.points.chunks(ROW_BATCH).zip(labels.chunks(ROW_BATCH)) {
            s += super::cloud::integrate_point_rows(&mut integ, p, rows.rows(l));
            done += p.len();
            progress(done, total);
        }
        rows.check(input, &s)?;
        (integ, s)
    } else if cloud.labels.is_some() {
        return Err(no_table(input));
    } else {
        return Err(no_features(input));
    };
    stats.offered += strays;
    stats.rejected += strays;
    let map = finish(integ, &name, params.tau, &stats)?.with_georef(cloud.georef);
    Ok((map, stats))
}

/// The map of an integrator, or an error saying why nothing was
/// integrated.
pub fn finish(
    integ: Integrator,
    encoder: &str,
    tau: f32,
    stats: &IntegrationStats,
) -> Result<LanguageMap, PipelineError> {
    if integ.voxel_count() == 0 {
        return Err(PipelineError::Input(format!(
            "empty result: none of {} points/pixels could be integrated ({} skipped without \
             feature or outside the crop, {} rejected as non-finite or out of range); no map written",
            stats.offered, stats.skipped, stats.rejected
        )));
    }
    Ok(integ.finish(encoder.to_string(), tau)?)
}

/// An RGB-D sequence folder and which of its pixels to use.
#[derive(Debug, Clone)]
pub struct RgbdInput {
    /// `intrinsics.txt`, `poses.txt` (TUM), `depth/NNNNNN.png`, and
    /// `labels/NNNNNN.png`, `features/NNNNNN.npy` or `rgb/NNNNNN.png`.
    pub dir: PathBuf,
    /// Depth PNG units per metre.
    pub depth_scale: f64,
    pub max_depth: f32,
    /// Points above this world height are skipped (the ceiling crop).
    pub max_height: Option<f64>,
    /// Every `stride`-th pixel in each direction.
    pub stride: u32,
    /// At most this many frames.
    pub frames: Option<usize>,
}

/// Where the frames' features come from.
pub enum RgbdFeatures<'a> {
    /// `labels/NNNNNN.png` through a class table (the ground-truth mode).
    Labels(&'a EmbeddingTable),
    /// An image encoder on `rgb/NNNNNN.png`.
    Encoder(&'a mut crate::encode::cache::ImageSource),
    /// `features/NNNNNN.npy` (`h x w x F`, any `h x w`).
    Files,
}

/// Builds the map of an RGB-D sequence: every frame's depth back-projected
/// with its pose, each used pixel's feature added to its voxel. `progress`
/// hears each frame done (its index). A frame whose sizes disagree with
/// the intrinsics is an error naming its file.
pub fn map_from_rgbd(
    input: &RgbdInput,
    params: &BuildParams,
    mut features: RgbdFeatures<'_>,
    progress: &mut dyn FnMut(usize),
) -> Result<(LanguageMap, IntegrationStats), PipelineError> {
    use crate::io::{poses, rgbd as rgbd_io};
    let d = &input.dir;
    let k = rgbd_io::read_intrinsics(&d.join("intrinsics.txt"))?;
    let traj = poses::read_poses(&d.join("poses.txt"))?.trajectory;
    let n = traj.poses().len().min(input.frames.unwrap_or(usize::MAX));
    // A pose a frame: a poses.txt shorter or longer than the frames is a
    // truncated or foreign file, not a request to map part of them.
    if input.frames.is_none() {
        let depth = d.join("depth");
        // NNNNNN.png names only (`0.png` is named as the error it is).
        let files = crate::io::kitti::numbered_files(&depth, "png")?;
        let images = files.len();
        let have: std::collections::HashSet<usize> = files.iter().map(|f| f.0).collect();
        if let Some(gap) = (0..traj.poses().len().min(images + 1)).find(|i| !have.contains(i)) {
            return Err(PipelineError::Input(format!(
                "{}: missing: {} poses and {images} depth images, depth/NNNNNN.png numbered \
                 from 000000 a pose each",
                depth.join(format!("{gap:06}.png")).display(),
                traj.poses().len()
            )));
        }
        if images != traj.poses().len() {
            return Err(PipelineError::Input(format!(
                "{}: {} poses but {images} depth images in {}; pass --frames N to map the first N",
                d.join("poses.txt").display(),
                traj.poses().len(),
                depth.display()
            )));
        }
    }
    // Any origin works; the first camera, snapped, keeps coordinates small.
    let grid = grid_at(traj.poses()[0].translation.vector.into(), params.resolution);
    let db = observation_db(&features, d, params)?;
    let mut name = params.encoder.clone();
    let mut integ = Integrator::new(grid, db)?;
    let opt = frame_options(input.max_depth, input.max_height, input.stride);
    let mut stats = IntegrationStats::default();
    for (i, pose) in traj.poses().iter().take(n).enumerate() {
        let depth_path = d.join("depth").join(format!("{i:06}.png"));
        let depth = rgbd_io::read_depth_png(&depth_path, input.depth_scale)?;
        if (depth.width, depth.height) != (k.width, k.height) {
            return Err(PipelineError::Input(format!(
                "{}: {}x{} pixels, intrinsics say {}x{}",
                depth_path.display(),
                depth.width,
                depth.height,
                k.width,
                k.height
            )));
        }
        let frame = RgbdFrame {
            dir: d,
            index: i,
            intrinsics: &k,
            depth: &depth.depth,
            pose,
            options: &opt,
        };
        stats += frame.integrate(&mut integ, &mut features, &mut name)?;
        progress(i);
    }
    // The map lives in the encoder's feature space: it records its name.
    Ok((finish(integ, &name, params.tau, &stats)?, stats))
}

/// The depth pixels an RGB-D map uses: 5 cm to `max_depth`, below
/// `max_height`, every `stride`-th in each direction.
fn frame_options(
    max_depth: f32,
    max_height: Option<f64>,
    stride: u32,
) -> super::rgbd::FrameOptions {
    super::rgbd::FrameOptions {
        min_depth: 0.05,
        max_depth,
        max_height,
        stride,
    }
}

/// The image encoder's features of the RGB image `path` (frame `frame`
/// of its cache).
fn encode_image(
    src: &mut crate::encode::cache::ImageSource,
    path: &std::path::Path,
    frame: usize,
) -> Result<crate::encode::FeatureMap, PipelineError> {
    src.encode(path, frame).map_err(|e| PipelineError::Encode {
        source_name: format!("encoding {}", path.display()),
        source: e,
    })
}

/// What of a 7-Scenes folder builds a map, and how.
#[derive(Debug, Clone)]
pub struct SevenScenesInput {
    /// The frames mapped (e.g. every second: the even frames).
    pub pick: crate::io::sevenscenes::FramePick,
    pub max_depth: f32,
    /// Points above this height of the z-up world are skipped.
    pub max_height: Option<f64>,
    /// Every `stride`-th pixel in each direction.
    pub stride: u32,
    /// Drop depth within `radius` pixels of a depth edge of relative jump
    /// `jump` first ([`super::rgbd::drop_depth_edges`]): `(radius, jump)`.
    pub depth_edges: Option<(usize, f32)>,
}

/// Builds the map of a 7-Scenes folder in its z-up world
/// ([`crate::io::sevenscenes::SevenScenes::poses_z_up`], the frame
/// `omcl localize` reads such a folder's ground truth in): the picked
/// frames' depth, each used pixel taking the image encoder's feature of
/// the colour image at the same pixel (colour and depth are not
/// registered; this is the dataset's own nominal pairing). Returns the
/// map, the integration counts and the depth pixels the edge filter
/// dropped. `progress` hears each picked frame done (its position).
pub fn map_from_sevenscenes(
    seq: &crate::io::sevenscenes::SevenScenes,
    input: &SevenScenesInput,
    params: &BuildParams,
    src: &mut crate::encode::cache::ImageSource,
    progress: &mut dyn FnMut(usize),
) -> Result<(LanguageMap, IntegrationStats, usize), PipelineError> {
    let picked = seq.pick(&input.pick)?;
    let first = picked[0];
    let poses = seq.poses_z_up();
    let k = seq.intrinsics;
    let grid = grid_at(poses[first].translation.vector.into(), params.resolution);
    let db = FeatureDb::new(src.dim(), params.tau)?.with_max_rows(params.max_rows);
    let mut integ = Integrator::new(grid, db)?;
    let opt = frame_options(input.max_depth, input.max_height, input.stride);
    let mut stats = IntegrationStats::default();
    let mut dropped = 0;
    for &i in &picked {
        let mut depth = seq.read_depth(i)?;
        if let Some((radius, jump)) = input.depth_edges {
            let (w, h) = (depth.width as usize, depth.height as usize);
            dropped += super::rgbd::drop_depth_edges(&mut depth.depth, w, h, jump, radius);
        }
        seq.check_color(i)?;
        let color = &seq.frames[i].color;
        let number = seq.frames[i].number as usize;
        let fm = encode_image(src, color, number)?;
        let f = crate::encode::image::EncodedFrame {
            map: &fm,
            width: k.width,
            height: k.height,
        };
        stats += super::rgbd::integrate_frame(&mut integ, &k, &depth.depth, &poses[i], &f, &opt)?;
        progress(i);
    }
    Ok((
        finish(integ, &src.name, params.tau, &stats)?,
        stats,
        dropped,
    ))
}

/// The observation database of an RGB-D map: the class table's rows, or
/// an empty database of the encoder's or the feature files' dimension.
fn observation_db(
    features: &RgbdFeatures<'_>,
    d: &std::path::Path,
    params: &BuildParams,
) -> Result<FeatureDb, PipelineError> {
    Ok(match features {
        RgbdFeatures::Labels(t) => FeatureDb::from_rows(t.dim, params.tau, t.data.clone())?,
        RgbdFeatures::Encoder(src) => {
            FeatureDb::new(src.dim(), params.tau)?.with_max_rows(params.max_rows)
        }
        RgbdFeatures::Files => {
            let f0 = d.join("features").join(format!("{:06}.npy", 0));
            if !d.join("features").is_dir() {
                return Err(PipelineError::Input(format!(
                    "{}: {}",
                    d.display(),
                    crate::session::sequence::NO_FRAMES
                )));
            }
            let arr = crate::io::npy::read_npy(&f0).map_err(|e| {
                PipelineError::Input(format!("no labels/ folder, so features/ is needed: {e}"))
            })?;
            FeatureDb::new(arr.as_matrix_dims().1, params.tau)?.with_max_rows(params.max_rows)
        }
    })
}

/// One posed depth frame of an RGB-D folder.
struct RgbdFrame<'a> {
    dir: &'a std::path::Path,
    index: usize,
    intrinsics: &'a crate::geometry::Intrinsics,
    depth: &'a [f32],
    pose: &'a crate::geometry::Pose,
    options: &'a super::rgbd::FrameOptions,
}

impl RgbdFrame<'_> {
    /// Integrates the frame's pixels with their features from `features`
    /// (its label image, its RGB image through the encoder, whose name goes
    /// to `name`, or its feature file).
    fn integrate(
        &self,
        integ: &mut Integrator,
        features: &mut RgbdFeatures<'_>,
        name: &mut String,
    ) -> Result<IntegrationStats, PipelineError> {
        use crate::io::{npy, rgbd as rgbd_io};
        let bad = |m: String| PipelineError::Input(m);
        let (d, i, k) = (self.dir, self.index, self.intrinsics);
        let integrate = |integ: &mut Integrator, f: &dyn crate::frame::FrameFeatures| {
            super::rgbd::integrate_frame(integ, k, self.depth, self.pose, f, self.options)
        };
        Ok(match features {
            RgbdFeatures::Labels(t) => {
                let p = d.join("labels").join(format!("{i:06}.png"));
                let (w, h, labels) = rgbd_io::read_label_png(&p)?;
                if (w, h) != (k.width, k.height) {
                    return Err(bad(format!(
                        "{}: {w}x{h} pixels, expected {}x{}",
                        p.display(),
                        k.width,
                        k.height
                    )));
                }
                // The database is the table: a label's row is its table row.
                let img = super::LabelImage::new(k.width, k.height, &labels, *t)
                    .map_err(|e| bad(format!("{}: {e}", p.display())))?;
                integrate(integ, &img)?
            }
            RgbdFeatures::Encoder(src) => {
                let rgb = d.join("rgb").join(format!("{i:06}.png"));
                // The encoder's features cover its image: one of another
                // size than the intrinsics' had mapped a part of the frame.
                let (w, h, _, _) = crate::io::bounded_png::png_header(&rgb)?;
                if (w, h) != (k.width, k.height) {
                    return Err(bad(format!(
                        "{}: {w}x{h} pixels, intrinsics say {}x{}",
                        rgb.display(),
                        k.width,
                        k.height
                    )));
                }
                let fm = encode_image(src, &rgb, i)?;
                *name = src.name.clone();
                let f = crate::encode::image::EncodedFrame {
                    map: &fm,
                    width: k.width,
                    height: k.height,
                };
                integrate(integ, &f)?
            }
            RgbdFeatures::Files => {
                let p = d.join("features").join(format!("{i:06}.npy"));
                let arr = npy::read_npy(&p)?;
                if arr.shape.len() != 3 {
                    return Err(bad(format!(
                        "{}: expected h x w x F, got shape {:?}",
                        p.display(),
                        arr.shape
                    )));
                }
                let dim = arr.shape[2];
                if dim != integ.observation_db().dim() {
                    return Err(bad(format!(
                        "{}: features have dimension {dim}, earlier frames {}",
                        p.display(),
                        integ.observation_db().dim()
                    )));
                }
                let fm = super::FeatureMap::new(
                    u32::try_from(arr.shape[0]).unwrap_or(u32::MAX),
                    u32::try_from(arr.shape[1]).unwrap_or(u32::MAX),
                    dim,
                    &arr.data,
                    k.width,
                    k.height,
                )
                .map_err(|e| bad(format!("{}: {e}", p.display())))?;
                integrate(integ, &fm).map_err(|e| bad(format!("{}: {e}", p.display())))?
            }
        })
    }
}

/// What [`project_sequence_labels`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectionSummary {
    /// Label images written.
    pub frames: usize,
    /// Points of the aggregated, down-sampled labelled map.
    pub points: usize,
    /// Fraction of all pixels that got a label.
    pub coverage: f64,
}

/// The folders a KITTI sequence is read from (scans, their labels, camera
/// images, camera features).
const SEQUENCE_INPUTS: [&str; 5] = ["velodyne", "labels", "image_2", "image_3", "features_2"];

/// `out` may not be the sequence's folder or one it is read from: label
/// images written there would replace what they are made from (camera
/// images were replaced with `--force`).
pub fn refuse_sequence_input(
    out: &std::path::Path,
    seq: &std::path::Path,
) -> Result<(), PipelineError> {
    let (Ok(out_abs), Ok(seq_abs)) = (std::fs::canonicalize(out), std::fs::canonicalize(seq))
    else {
        // A folder still to be made holds nothing; a missing sequence is
        // its reader's to report.
        return Ok(());
    };
    let read_from = out_abs == seq_abs
        || SEQUENCE_INPUTS
            .iter()
            .any(|f| std::fs::canonicalize(seq_abs.join(f)).is_ok_and(|p| p == out_abs));
    if read_from {
        return Err(PipelineError::Input(format!(
            "{}: the output is a folder the sequence {} is read from; label images written \
             there would replace its own files (choose another folder; the default is {})",
            out.display(),
            seq.display(),
            seq.join("labels_2").display()
        )));
    }
    Ok(())
}

/// Ground-truth label images of camera 2 from a SemanticKITTI sequence
/// folder (`input.path`: `velodyne/`, `labels/`, `calib.txt` with `P2`,
/// `poses.txt`): the labelled scans aggregated in the map frame
/// (down-sampled to `params.spacing`, the authors' dropped classes gone
/// unless `input.keep_all`), projected at every camera-2 pose
/// ([`super::projection`]) and written to `out/NNNNNN.png` (16-bit ids,
/// 0 = no point; the size of `image_2/`'s images where the sequence has
/// them, else 1241 x 376), each written atomically. `input.frames` caps the scans
/// aggregated and the images made.
pub fn project_sequence_labels(
    input: &CloudInput,
    params: &super::projection::ProjectionParams,
    out: &std::path::Path,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ProjectionSummary, PipelineError> {
    use super::projection::{PointIndex, project_labels};
    use crate::io::kitti::{KITTI_IMAGE_SIZE, read_calib, read_kitti_poses};
    let dir = &input.path;
    refuse_sequence_input(out, dir)?;
    let (seq, frames, mut opts) = open_sequence(input)?;
    let calib_path = dir.join("calib.txt");
    let calib = read_calib(&calib_path)?;
    // Label images the size of the camera's own, where the sequence has
    // them; else KITTI 00's.
    let (w, h) = crate::io::kitti_camera::camera2_image_size(dir)?.unwrap_or(KITTI_IMAGE_SIZE);
    let camera = calib.camera("P2", w, h, &calib_path)?;
    let poses = read_kitti_poses(&dir.join("poses.txt"))?;
    let n = frames.len().min(poses.len());
    opts.voxel_size = Some(params.spacing);
    let cloud = seq.aggregate(&frames, &opts)?;
    let labels = cloud.labels.as_ref().ok_or_else(|| {
        PipelineError::Input(format!(
            "{}: the scans carry no labels (labels/NNNNNN.label)",
            dir.display()
        ))
    })?;
    let cameras = crate::io::kitti_camera::camera_in_map(&calib, &camera, &poses[..n]);
    let index = PointIndex::new(&cloud.points, params.max_range.max(1.0) / 2.0);
    let k = camera.intrinsics;
    let mut labelled = 0usize;
    for (i, pose) in cameras.iter().enumerate() {
        let near = index.near(&pose.translation.vector, params.max_range);
        let img = project_labels(&cloud.points, labels, &near, pose, &k, params);
        labelled += img.iter().filter(|&&l| l != 0).count();
        let data: Vec<u16> = img.iter().map(|&l| l.min(u16::MAX as u32) as u16).collect();
        crate::sim::files::write_png_gray16(&out.join(format!("{i:06}.png")), w, h, &data)
            .map_err(|e| PipelineError::Input(e.to_string()))?;
        progress(i + 1, n);
    }
    Ok(ProjectionSummary {
        frames: n,
        points: cloud.len(),
        coverage: labelled as f64 / (n.max(1) * (w * h) as usize) as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Georeferenced points (UTM, 0.1 m apart on a 100 x 200 patch) with
    /// one stray point at 0, 0, 0, 6,400 km away.
    fn utm_with_a_stray_point() -> PointCloud {
        let mut points: Vec<[f64; 3]> = (0..20_000)
            .map(|i| {
                let (x, y) = ((i % 100) as f64, (i / 100) as f64);
                [630_000.0 + 0.1 * x, 4_830_000.0 + 0.1 * y, 100.0]
            })
            .collect();
        points.insert(7, [0.0; 3]);
        let n = points.len();
        PointCloud {
            features: Some((2, [1.0, 0.0].repeat(n))),
            ..PointCloud::from_points(points)
        }
    }

    /// At the coarse voxels aerial LiDAR wants the stray is within the
    /// grid's reach: it is the data's box that leaves it out (it made a
    /// map 6,400 km wide); `keep_strays` keeps it.
    #[test]
    fn a_stray_point_is_left_out_at_every_resolution_unless_kept() {
        for resolution in [0.05, 1.0, 10.0] {
            for keep_strays in [false, true] {
                let params = BuildParams {
                    resolution,
                    tau: 0.02,
                    max_rows: 16,
                    encoder: "test".into(),
                    keep_strays,
                };
                let (m, stats) =
                    map_from_cloud(utm_with_a_stray_point(), "utm", &params, None, None).unwrap();
                // Within the grid's reach (2^20 cells) only at 10 m: 4,830
                // km from the data.
                let kept = keep_strays && resolution == 10.0;
                assert_eq!(
                    (stats.integrated, stats.rejected),
                    if kept { (20_001, 0) } else { (20_000, 1) },
                    "{resolution} m, keep {keep_strays}"
                );
                let g = m.grid();
                let lowest = m
                    .codes()
                    .iter()
                    .map(|&c| g.center(crate::map::key::decode(c)).x)
                    .fold(f64::INFINITY, f64::min);
                assert_eq!(lowest < 600_000.0, kept, "{resolution} m");
            }
        }
    }

    /// The data's box: the 1st-99th percentiles of all points in 1 m bins,
    /// grown by ten times its size or 10 km; the same box whatever the
    /// points' order (a run of strays in one block, or at the end, used to
    /// stretch a per-block box); a cloud of fewer than 100 points has none.
    #[test]
    fn the_data_box_is_the_bulk_grown_in_any_order() {
        // 1000 points on x in 0..999 m, strays at x = 50 km: one, then a
        // run of 9 at the end (1 % of the cloud, not more).
        let mut pts: Vec<[f64; 3]> = (0..1000).map(|i| [i as f64 + 0.5, 0.25, 0.0]).collect();
        pts.insert(500, [50_000.0, 0.0, 0.0]);
        pts.extend([[50_000.0, 0.0, 0.0]; 9]);
        let box_of = |pts: &[[f64; 3]]| {
            let mut o = OriginEstimate::default();
            o.add(pts);
            o.finish(1.0).unwrap().keep.unwrap()
        };
        let k = box_of(&pts);
        // 1010 points: ranks 10 and 999 (0-based) are x = 10.5 and 999.5
        // (bins 10 and 999), the strays ranks 1000 to 1009: the box
        // [10, 1000] grown by 10 km (10 x 990 m is less).
        assert_eq!((k.lo[0], k.hi[0]), (10.0 - 10_000.0, 1000.0 + 10_000.0));
        assert_eq!((k.lo[1], k.hi[1]), (-10_000.0, 10_001.0));
        assert!(!k.contains(&[50_000.0, 0.0, 0.0]) && k.contains(&[9_000.0, 0.0, 0.0]));
        let mut reversed = pts.clone();
        reversed.reverse();
        assert_eq!(box_of(&reversed), k);
        let mut small = OriginEstimate::default();
        small.add(&pts[..99]);
        assert_eq!(small.finish(1.0).unwrap().keep, None);
        // A separate cluster of real data, 0.5 % of the points 2 km from
        // a 200 m site, is inside, first or last in the file.
        let site: Vec<[f64; 3]> = (0..20_000)
            .map(|i| [(i % 200) as f64, (i / 200) as f64, 0.0])
            .collect();
        let cluster = [[2_000.0, 50.0, 0.0]; 100];
        for pts in [
            [&site[..], &cluster[..]].concat(),
            [&cluster[..], &site[..]].concat(),
        ] {
            let k = box_of(&pts);
            assert!(k.contains(&cluster[0]), "{k:?}");
        }
    }

    #[test]
    fn a_stray_point_far_from_the_data_is_rejected_not_the_data() {
        let params = BuildParams {
            resolution: 0.05,
            tau: 0.02,
            max_rows: 16,
            encoder: "test".into(),
            keep_strays: false,
        };
        let (m, stats) =
            map_from_cloud(utm_with_a_stray_point(), "utm", &params, None, None).unwrap();
        assert_eq!(
            (stats.offered, stats.integrated, stats.rejected),
            (20_001, 20_000, 1)
        );
        // 0.1 m apart at 0.05 m: a voxel a point.
        assert_eq!(m.len(), 20_000);
        // The origin is the data's middle, snapped to the resolution.
        let o = m.grid().origin;
        assert!((o.x - 630_005.0).abs() < 0.2, "{o:?}");
        assert!((o.y - 4_830_010.0).abs() < 0.2, "{o:?}");
        assert!((o.z - 100.0).abs() < 0.051, "{o:?}");
    }

    #[test]
    fn the_origin_does_not_depend_on_how_the_points_are_fed() {
        let pts: Vec<[f64; 3]> = (0..150_001)
            .map(|i| {
                let t = i as f64;
                [
                    (t * 0.37).sin() * 50.0 + t * 1e-3,
                    (t * 0.11).cos() * 20.0,
                    t * 1e-4,
                ]
            })
            .collect();
        let whole = grid_for(&pts, 0.1);
        let mut fed = OriginEstimate::default();
        for chunk in pts.chunks(7_001) {
            fed.add(chunk);
        }
        assert_eq!(fed.grid(0.1), Some(whole));
        assert_eq!(OriginEstimate::default().grid(0.1), None);
        // Three blocks' medians and the last block's: the median of four
        // is the upper middle one, per axis.
        let mut v = vec![
            [1.0, 9.0, 0.0],
            [4.0, 2.0, 0.0],
            [3.0, 3.0, 5.0],
            [2.0, 1.0, 5.0],
        ];
        assert_eq!(median3(&mut v), [3.0, 3.0, 5.0]);
    }
}
