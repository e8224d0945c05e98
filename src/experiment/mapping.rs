//! Maps of a benchmark sequence's world, built the ways the paper's Table I
//! compares: from posed RGB-D frames with ground-truth labels or with an
//! encoder's (simulated) features, the latter grounded on the class names.
//!
//! The mapping frames come from the sequence's own path (as maps built from
//! a recorded sequence are) and from a second camera path through the same
//! world (another seed) that fills in what the first did not see.

use std::sync::Arc;

use super::features::feature_model;
use crate::mcl::SensorModel;
use crate::raycast::RayCaster;
use nalgebra::Vector3;
use rayon::prelude::*;

use super::ExperimentError;
use super::sequence::SimSequence;
use crate::geometry::Pose;
use crate::map::{FeatureDb, GridSpec, Integrator, LanguageMap};
use crate::sim::features::{FeatureModel, LabelEdges, Preset};
use crate::sim::paths::{self, IndoorPathConfig};
use crate::sim::render::{self, Frame, NO_LABEL};

/// Where the voxels' features come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum MapSource {
    /// The true class of every back-projected pixel (a semantic mesh's
    /// labels, free of the bleed ground-truth images have): the map of
    /// OMCL_GT_exact. (The paper's OMCL_GT maps its ground-truth images:
    /// `Features(Preset::Gt)`.)
    Labels,
    /// Each pixel's feature from the preset's model, assigned to its most
    /// similar class row (grounding per observation), then counted per
    /// voxel: the "LSeg" map. (The paper averages raw features per voxel
    /// and grounds the means; with 512-d features and a million voxels
    /// that needs the whole feature stream in memory or a per-feature
    /// database search, so the experiment grounds first.)
    Features(Preset),
    /// The paper's ungrounded OMCL^auto: each pixel's raw feature from the
    /// preset's model (no class in between) goes into the map's
    /// observation database with tau, as `omcl map` integrates an image
    /// model's features ([`crate::map::Integrator::add_feature`], rows
    /// capped at [`MapParams::max_rows`]), and the voxel means form the
    /// database with tau (capped likewise), never grounded on the class
    /// names. Noisy raw features rarely come within tau of each other, so
    /// both databases reach their caps: the map's rows are a few thousand
    /// observed features and their blends, not classes.
    Auto(Preset),
    /// A point cloud (the mapping frames' points fused in the world frame)
    /// whose points a 3-D encoder labels ([`crate::sim::features::OPENSCENE_LIKE`],
    /// [`FeatureModel::point_class`]), integrated as point-cloud maps are
    /// ([`crate::mapping::cloud`]) and grounded: the paper's input option 2
    /// (OpenScene).
    PointCloud,
}

impl MapSource {
    /// A short name for tables.
    pub fn name(&self) -> String {
        match self {
            MapSource::Labels => "labels".into(),
            MapSource::Features(p) => format!("{}-features", p.name()),
            MapSource::Auto(p) => format!("{}-features-auto", p.name()),
            MapSource::PointCloud => "openscene-like-points".into(),
        }
    }

    /// Whether the finished map is grounded on the class names.
    pub fn grounded(&self) -> bool {
        !matches!(self, MapSource::Auto(_))
    }
}

/// How mapping frames are taken.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MapParams {
    /// Voxel edge, metres.
    pub resolution: f64,
    /// Frames of the mapping path (300, the simulator's default, visits
    /// every room) and the step between used frames.
    pub frames: usize,
    pub frame_step: usize,
    /// Use every `pixel_stride`-th pixel of a frame in u and v.
    pub pixel_stride: u32,
    /// Points above this height (m) are dropped: the ceiling is cropped so
    /// floor plans and prompts see the rooms (the authors do the same).
    pub max_height: f64,
    /// Admission threshold of the map's database (paper: 0.02).
    pub tau: f32,
    /// Ground the finished map on the class names (the paper's default:
    /// every voxel takes its most similar class row, the database becomes
    /// the class table); `false` keeps the admitted voxel means ("auto").
    pub ground: bool,
    /// Pixel stride of [`MapSource::Auto`]'s raw features: each one is a
    /// nearest-row search over up to `max_rows` rows of 512 values, so
    /// stride 8 (4,500 features a frame, a point every 3 cm at 2 m) keeps a
    /// map to minutes on 2 cores; stride 4 took over 12 minutes.
    pub raw_pixel_stride: u32,
    /// Cap on the rows of [`MapSource::Auto`]'s observation database and
    /// of its map's database (`omcl map --max-rows` defaults to 4096; the
    /// filter compares every sampled pixel with every row, so the bench
    /// keeps 1024).
    pub max_rows: usize,
}

impl Default for MapParams {
    fn default() -> Self {
        MapParams {
            resolution: 0.05,
            frames: 300,
            frame_step: 2,
            pixel_stride: 2,
            max_height: 10.0,
            tau: 0.02,
            ground: true,
            raw_pixel_stride: 8,
            max_rows: 1024,
        }
    }
}

/// The mapping path of `seq`: a different walk through the same world.
pub fn mapping_poses(seq: &SimSequence, frames: usize) -> Vec<Pose> {
    let cfg = IndoorPathConfig {
        frames,
        seed: seq.config.path.seed.wrapping_add(0x9a9),
        ..seq.config.path.clone()
    };
    paths::indoor_path(&seq.scene.world.layout, &cfg)
}

/// Builds the map of `seq`'s world from `source`. `model` gives the
/// features of every source but [`MapSource::Labels`] (the preset's model,
/// or for [`MapSource::PointCloud`] the point encoder's).
pub fn build_map(
    seq: &SimSequence,
    source: MapSource,
    params: &MapParams,
    model: Option<&FeatureModel>,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<LanguageMap, ExperimentError> {
    if source != MapSource::Labels && model.is_none() {
        return Err(ExperimentError::Config(
            "a feature map needs a feature model".into(),
        ));
    }
    if let (MapSource::Auto(_), Some(m)) = (source, model) {
        return build_raw_map(seq, source, params, m, progress);
    }
    let table = &seq.table;
    let db = FeatureDb::from_rows(table.dim, params.tau, table.rows.clone())?;
    let mut integ = Integrator::new(map_grid(seq, params), db)?;
    let k = &seq.intrinsics;
    let s = params.pixel_stride.max(1);
    for (i, pose) in mapping_frame_poses(seq, params).iter().enumerate() {
        let frame = render::render_frame(&seq.scene.caster, &seq.scene.world.voxels, k, pose);
        let edges = matches!(source, MapSource::Features(_)).then(|| LabelEdges::new(&frame));
        let (points, rows) = frame_points(&frame, k, pose, s, params.max_height, |u, v, p| {
            let l = frame.labels[frame.index(u, v)];
            match (source, model, &edges) {
                (MapSource::Features(_), Some(m), Some(e)) => {
                    let ctx = m.context_near(&frame, e, u, v);
                    m.predicted_class(0x9a9_0000 + i as u64, u, v, &ctx)
                        .map(|c| c as u32)
                }
                (MapSource::PointCloud, Some(m), _) => m.point_class(p, l).map(|c| c as u32),
                _ => (l != NO_LABEL).then_some(l as u32),
            }
        });
        if source == MapSource::PointCloud {
            crate::mapping::cloud::integrate_point_rows(&mut integ, &points, &rows);
        } else {
            integ.add_rows_batch(&points, &rows);
        }
        progress(i + 1);
    }
    let mut map = integ.finish(source.name(), params.tau)?;
    if params.ground && source.grounded() {
        let prompts = FeatureDb::from_rows(table.dim, params.tau, table.rows.clone())?;
        crate::map::ground::ground(&mut map, &prompts, -1.0)?;
    }
    Ok(map)
}

/// The map's grid: offset from the world's voxels by half a map voxel (a
/// real map's grid does not line up with the walls, and surfaces on voxel
/// faces would split their points between two voxels).
fn map_grid(seq: &SimSequence, params: &MapParams) -> GridSpec {
    GridSpec {
        resolution: params.resolution,
        origin: seq.scene.world.voxels.origin - Vector3::repeat(0.5 * params.resolution),
    }
}

/// The mapping frames' poses: every `frame_step`-th of the mapping path,
/// then of the sequence's own path.
fn mapping_frame_poses(seq: &SimSequence, params: &MapParams) -> Vec<Pose> {
    let step = params.frame_step.max(1);
    mapping_poses(seq, params.frames)
        .into_iter()
        .step_by(step)
        .chain(seq.poses().iter().copied().step_by(step))
        .collect()
}

/// [`MapSource::Auto`]: raw features through a capped observation database
/// into voxels, voxel means into a capped database, no grounding. Each
/// frame's features are computed where needed; while the observation
/// database has room they are admitted one by one (the admission rule is
/// sequential), once it is full each takes its nearest row, found for the
/// frame's remaining features in parallel blocks ([`FeatureDb::map_dots`]),
/// which is what [`FeatureDb::admit`] returns past the cap.
fn build_raw_map(
    seq: &SimSequence,
    source: MapSource,
    params: &MapParams,
    model: &FeatureModel,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<LanguageMap, ExperimentError> {
    let dim = model.dim();
    let cap = params.max_rows.max(1);
    let obs = FeatureDb::new(dim, params.tau)?.with_max_rows(cap);
    let mut integ = Integrator::new(map_grid(seq, params), obs)?;
    let k = &seq.intrinsics;
    for (i, pose) in mapping_frame_poses(seq, params).iter().enumerate() {
        let frame = render::render_frame(&seq.scene.caster, &seq.scene.world.voxels, k, pose);
        let (points, pixels) = frame_points(
            &frame,
            k,
            pose,
            params.raw_pixel_stride.max(1),
            params.max_height,
            |u, v, _| Some((u, v)),
        );
        let frame_id = 0x9a9_0000 + i as u64;
        let edges = LabelEdges::new(&frame);
        let feature = |j: usize, out: &mut [f32]| {
            let (u, v) = pixels[j].expect("every kept pixel has its coordinates");
            let ctx = model.context_near(&frame, &edges, u, v);
            model.feature_at(frame_id, u, v, &ctx, out);
        };
        let mut j = 0;
        let mut buf = vec![0f32; dim];
        while j < points.len() && integ.observation_db().len() < cap {
            feature(j, &mut buf);
            integ.add_feature(&Vector3::from(points[j]), &buf)?;
            j += 1;
        }
        if j < points.len() {
            // Features are unit vectors (`feature_at`), so the largest dot
            // product is the nearest row.
            let rows = integ.observation_db().map_dots(
                points.len() - j,
                |r, out| feature(j + r, out),
                |_, dots| {
                    dots.iter()
                        .enumerate()
                        .max_by(|a, b| a.1.total_cmp(b.1))
                        .map(|(r, _)| r as u32)
                },
            );
            integ.add_rows_batch(&points[j..], &rows);
        }
        progress(i + 1);
    }
    let db = FeatureDb::new(dim, params.tau)?.with_max_rows(cap);
    Ok(integ.finish_into(source.name(), db)?)
}

/// World points and rows of the used pixels of one frame (rows computed in
/// parallel by `row_of(u, v, point)`).
fn frame_points<T: Send>(
    frame: &Frame,
    k: &crate::geometry::Intrinsics,
    pose: &Pose,
    stride: u32,
    max_height: f64,
    row_of: impl Fn(u32, u32, [f64; 3]) -> Option<T> + Sync,
) -> (Vec<[f64; 3]>, Vec<Option<T>>) {
    let px: Vec<(u32, u32)> = (0..frame.height)
        .step_by(stride as usize)
        .flat_map(|v| {
            (0..frame.width)
                .step_by(stride as usize)
                .map(move |u| (u, v))
        })
        .filter(|&(u, v)| frame.depth[frame.index(u, v)] > 0.0)
        .collect();
    px.par_iter()
        .filter_map(|&(u, v)| {
            let z = frame.depth[frame.index(u, v)] as f64;
            let p: Vector3<f64> = (pose * k.back_project(u, v, z)).coords;
            let p = [p.x, p.y, p.z];
            (p[2] <= max_height).then(|| (p, row_of(u, v, p)))
        })
        .unzip()
}

/// A map of a sequence's world with its ray caster.
pub struct BenchMap {
    pub source: MapSource,
    pub map: LanguageMap,
    pub caster: Arc<dyn RayCaster>,
}

impl BenchMap {
    /// Builds the map of `seq` from `source`.
    pub fn build(
        seq: &SimSequence,
        source: MapSource,
        params: &MapParams,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<Self, ExperimentError> {
        let model = match source {
            MapSource::Features(p) | MapSource::Auto(p) => Some(feature_model(seq, p, 0x3a9)),
            MapSource::PointCloud => Some(FeatureModel::new(
                seq.table.clone(),
                crate::sim::features::OPENSCENE_LIKE,
                seq.config.seed.wrapping_mul(0x9e37).wrapping_add(0x3d9),
            )),
            MapSource::Labels => None,
        };
        let map = build_map(seq, source, params, model.as_ref(), progress)?;
        Self::from_map(source, map)
    }

    /// A built (or loaded) map of `source` with its ray caster.
    pub fn from_map(source: MapSource, map: LanguageMap) -> Result<Self, ExperimentError> {
        let caster = Arc::new(SensorModel::embree_caster(
            map.grid().resolution as f32,
            &map.cells(),
        )?);
        Ok(BenchMap {
            source,
            map,
            caster,
        })
    }
}
