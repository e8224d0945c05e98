//! A real sensor track: 7-Scenes frames (Kinect v1 depth and colour,
//! KinectFusion ground truth), mapped and localized with the colour-class
//! encoder ([`crate::encode::colour`]) run through ONNX Runtime.
//!
//! Frames are split by position in the folder: the even ones build the
//! map, every `localize_every`-th odd one is localized (so a filter step
//! spans `2 * localize_every` recorded frames). The colour classes are
//! fitted on the mapping frames only. The world is turned so that z is up
//! (from `gravity-direction.txt`, one rotation of the whole dataset), so
//! the paper's local start (0.3 m on the ground plane, 17 degrees of yaw)
//! means what it means indoors. Odometry is ground truth with Gaussian
//! noise on all six degrees of freedom of each increment, accumulated,
//! scaled to the paper's proportion (0.10 m and 6 degrees of noise for
//! 0.13 m and 8 degrees of motion a step) of the localized path's mean
//! motion; the filter's motion noise is the same ([`MotionMode::Full`]).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::ExperimentError;
use crate::encode::Encoder as _;
use crate::encode::colour::{ColourClasses, srgb8_to_lab};
use crate::encode::colour_model::{colour_card, colour_model};
use crate::encode::image::EncodedFrame;
use crate::encode::{FeatureMap, ImageEncoder, Runtime};
use crate::eval::ErrorStats;
use crate::eval::ape::{PoseRelation, ape};
use crate::eval::consistency::{ConsistencyMetrics, NO_HIT, count_frame};
use crate::eval::localization::CompletionRule;
use crate::geometry::{Pose, camera_ray};
use crate::io::sevenscenes::SevenScenes;
use crate::map::{FeatureDb, GridSpec, Integrator};
use crate::mapping::rgbd::{FrameOptions, drop_depth_edges, integrate_frame};
use crate::mapping::{FrameFeatures, IntegrationStats};
use crate::mcl::{FilterConfig, MotionMode};
use crate::session::{Session, SessionConfig, SharedMap, Start};
use crate::trajectory::Trajectory;

/// Everything the track is run with.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TrackSpec {
    /// Use only the first `frames` frames of the folder (all: `None`).
    pub frames: Option<usize>,
    /// Localize every n-th odd frame.
    pub localize_every: usize,
    /// Colour classes and the length of their embeddings.
    pub classes: usize,
    pub dim: usize,
    /// Seed of k-means and the embeddings.
    pub colour_seed: u64,
    /// The encoder's input size (the card resizes to it, box filter).
    pub model_size: (u32, u32),
    /// Voxel edge, metres.
    pub resolution: f64,
    /// Feature database threshold (cosine distance).
    pub tau: f32,
    /// Every n-th depth pixel in u and v is mapped.
    pub map_stride: u32,
    pub max_depth: f32,
    /// Drop depth within this many pixels of a depth edge (relative jump
    /// `edge_jump`) before mapping; `None`: keep all depth.
    pub edge_radius: Option<usize>,
    pub edge_jump: f32,
    /// Shift (pixels, x and y) from a depth pixel to the colour pixel whose
    /// feature it takes while mapping (0, 0: the nominal, unregistered
    /// pairing the dataset's tools use).
    pub colour_shift: (i32, i32),
    pub particles: usize,
    pub rays: usize,
    /// Local start: metres on the ground plane and degrees of yaw.
    pub init_sigma_m: f64,
    pub init_sigma_deg: f64,
    /// Seed of the odometry noise, the start and the filter.
    pub seed: u64,
    /// Table II's consistency: every n-th pixel of each localized frame.
    pub consistency_stride: u32,
}

impl Default for TrackSpec {
    fn default() -> Self {
        TrackSpec {
            frames: None,
            localize_every: 4,
            classes: 10,
            dim: 32,
            colour_seed: 7,
            model_size: (320, 240),
            resolution: 0.02,
            tau: 0.02,
            map_stride: 2,
            max_depth: 4.0,
            edge_radius: None,
            edge_jump: 0.03,
            colour_shift: (0, 0),
            particles: 1024,
            rays: 2048,
            init_sigma_m: 0.3,
            init_sigma_deg: 17.0,
            seed: 1,
            consistency_stride: 8,
        }
    }
}

/// What a track gives.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TrackResult {
    /// How many frames built the map.
    pub map_frames: usize,
    pub voxels: usize,
    pub feature_rows: usize,
    pub mapping: IntegrationStats,
    /// Depth pixels the edge filter dropped.
    pub edge_dropped: usize,
    /// The localized frames' numbers.
    pub localized: Vec<u32>,
    /// Mean motion of a step (metres, degrees) and the odometry noise
    /// drawn for it (per axis).
    pub step_motion: (f64, f64),
    pub odometry_sigma: (f64, f64),
    /// Ground truth and estimate, z-up world, metres.
    pub ground_truth: Vec<Pose>,
    pub estimate: Vec<Pose>,
    /// Per-frame translation error and evo's statistics (no alignment).
    pub errors_m: Vec<f64>,
    pub ape: ErrorStats,
    /// Rotation error statistics, degrees.
    pub ape_rotation_deg: ErrorStats,
    /// [`CompletionRule::judge`]: `None` for a run too short to judge.
    pub completed: Option<bool>,
    /// Table II's scores of the map against the localized frames' features
    /// from their true poses (averaged over the frames).
    pub consistency: Option<ConsistencyMetrics>,
    pub filter_steps_per_s: f64,
}

/// Positions (in the sequence) of the mapping and the localized frames.
pub fn split(n: usize, localize_every: usize) -> (Vec<usize>, Vec<usize>) {
    let map = (0..n).step_by(2).collect();
    let loc = (1..n).step_by(2).step_by(localize_every.max(1)).collect();
    (map, loc)
}

/// Lab colours of every `stride`-th pixel of `images` (the k-means input).
pub fn lab_samples(images: &[image::RgbImage], stride: u32) -> Vec<[f32; 3]> {
    let s = stride.max(1);
    images
        .iter()
        .flat_map(|img| {
            (0..img.height()).step_by(s as usize).flat_map(move |v| {
                (0..img.width())
                    .step_by(s as usize)
                    .map(move |u| srgb8_to_lab(img.get_pixel(u, v).0))
            })
        })
        .collect()
}

/// A frame's encoded features, read at a shifted colour pixel.
struct Shifted<'a> {
    inner: EncodedFrame<'a>,
    shift: (i32, i32),
}

impl Shifted<'_> {
    fn at(&self, u: u32, v: u32) -> Option<(u32, u32)> {
        let (x, y) = (
            u as i64 + self.shift.0 as i64,
            v as i64 + self.shift.1 as i64,
        );
        (x >= 0 && y >= 0 && x < self.inner.width as i64 && y < self.inner.height as i64)
            .then_some((x as u32, y as u32))
    }
}

impl FrameFeatures for Shifted<'_> {
    fn width(&self) -> u32 {
        self.inner.width
    }
    fn height(&self) -> u32 {
        self.inner.height
    }
    fn dim(&self) -> usize {
        self.inner.map.dim
    }
    fn feature(&self, u: u32, v: u32, out: &mut [f32]) {
        match self.at(u, v) {
            Some((x, y)) => self.inner.feature(x, y, out),
            None => out.fill(0.0),
        }
    }
    fn known(&self, u: u32, v: u32) -> bool {
        self.at(u, v).is_some_and(|(x, y)| self.inner.known(x, y))
    }
}

fn err(e: impl std::fmt::Display) -> ExperimentError {
    ExperimentError::Config(e.to_string())
}

/// Fits the colour classes on the mapping frames of `seq` (every 8th pixel
/// of each) and writes the ONNX model and its card to `model` (and
/// `model` with `.card.json`).
pub fn fit_colour_model(
    seq: &SevenScenes,
    mapping: &[usize],
    spec: &TrackSpec,
    model: &Path,
) -> Result<ColourClasses, ExperimentError> {
    let images = mapping
        .iter()
        .map(|&i| seq.read_color(i).map_err(err))
        .collect::<Result<Vec<_>, _>>()?;
    let lab = lab_samples(&images, 8);
    let classes =
        ColourClasses::fit(&lab, spec.classes, spec.dim, 50, spec.colour_seed).map_err(err)?;
    write_colour_model(&classes, spec.model_size, model)?;
    Ok(classes)
}

/// How the name of every colour-class encoder omcl writes begins.
pub const COLOUR_MODEL_PREFIX: &str = "omcl-colour-lab-";

/// Writes `classes` as ONNX to `model` and its card beside it.
pub fn write_colour_model(
    classes: &ColourClasses,
    size: (u32, u32),
    model: &Path,
) -> Result<(), ExperimentError> {
    // The classes, their dimension and a CRC-32 of the model's bytes: two
    // fits (another seed, other frames) are two feature spaces, and a map
    // of one is not localized with the other (`omcl localize` refuses).
    let bytes = colour_model(classes);
    let name = format!(
        "{COLOUR_MODEL_PREFIX}k{}-d{}-{:08x}",
        classes.len(),
        classes.dim,
        crc32fast::hash(&bytes)
    );
    let card = colour_card(classes, &name, size.0, size.1);
    let card_text = serde_json::to_string_pretty(&card).map_err(err)?;
    crate::io::atomic::write(model, &bytes)
        .map_err(|e| err(format!("{}: {e}", model.display())))?;
    let card_path = crate::encode::card::card_path_for(model);
    crate::io::atomic::write(&card_path, card_text.as_bytes())
        .map_err(|e| err(format!("{}: {e}", card_path.display())))
}

/// Runs the track on `seq` with the encoder at `model` (written by
/// [`fit_colour_model`]); `progress` hears what is going on.
pub fn run_track(
    seq: &SevenScenes,
    spec: &TrackSpec,
    classes: &ColourClasses,
    model: &Path,
    ort_lib: Option<&Path>,
    progress: &dyn Fn(&str),
) -> Result<TrackResult, ExperimentError> {
    let n = seq.len().min(spec.frames.unwrap_or(usize::MAX));
    let (mapping, localized) = split(n, spec.localize_every);
    if localized.len() < 2 {
        return Err(err(format!(
            "{}: {n} frames leave {} to localize; need 2 or more",
            seq.dir.display(),
            localized.len()
        )));
    }
    let poses = seq.poses_z_up();
    let k = seq.intrinsics;
    let rt = Runtime::init(ort_lib).map_err(err)?;
    let mut encoder = ImageEncoder::load(rt, model, 0).map_err(err)?;

    // The map.
    let grid = GridSpec {
        resolution: spec.resolution,
        origin: poses[0]
            .translation
            .vector
            .map(|v| (v / spec.resolution).floor() * spec.resolution - 5.0),
    };
    let db = FeatureDb::new(encoder.feature_dim(), spec.tau)?;
    let mut integ = Integrator::new(grid, db)?;
    let opt = FrameOptions {
        min_depth: 0.05,
        max_depth: spec.max_depth,
        max_height: None,
        stride: spec.map_stride,
    };
    let mut stats = IntegrationStats::default();
    let mut edge_dropped = 0;
    for (j, &i) in mapping.iter().enumerate() {
        let mut depth = seq.read_depth(i).map_err(err)?;
        if let Some(r) = spec.edge_radius {
            edge_dropped += drop_depth_edges(
                &mut depth.depth,
                depth.width as usize,
                depth.height as usize,
                spec.edge_jump,
                r,
            );
        }
        let fm = encode(&mut encoder, seq, i)?;
        let frame = Shifted {
            inner: EncodedFrame {
                map: &fm,
                width: k.width,
                height: k.height,
            },
            shift: spec.colour_shift,
        };
        stats +=
            integrate_frame(&mut integ, &k, &depth.depth, &poses[i], &frame, &opt).map_err(err)?;
        if j % 25 == 0 {
            progress(&format!("mapped frame {j} of {}", mapping.len()));
        }
    }
    let map = crate::mapping::pipeline::finish(integ, &encoder.card().name, spec.tau, &stats)
        .map_err(err)?;
    let (voxels, feature_rows) = (map.len(), map.db().len());
    progress(&format!(
        "map: {voxels} voxels, {feature_rows} feature rows"
    ));
    let shared = Arc::new(SharedMap::new("7scenes", map).map_err(err)?);
    let row_class: Vec<u32> = shared
        .map()
        .db()
        .rows()
        .chunks_exact(classes.dim)
        .map(|r| nearest_class(classes, r))
        .collect();

    // Odometry in the paper's proportion to this path's motion.
    let gt: Vec<Pose> = localized.iter().map(|&i| poses[i]).collect();
    let (step_t, step_r) = crate::sim::paths::mean_motion(&gt);
    let sigma = crate::sim::paths::paper_noise_for(&gt);
    let odom = crate::sim::paths::odometry(
        &gt,
        &[],
        &crate::sim::paths::OdometryConfig {
            seed: spec.seed,
            sigma_t: sigma.0,
            sigma_r_deg: sigma.1,
            drift_scale: 0.0,
            all_axes: true,
        },
    );
    let mut filter = FilterConfig {
        seed: spec.seed,
        ..FilterConfig::default()
    };
    filter.motion.mode = MotionMode::Full;
    filter.motion.sigma_translation = sigma.0;
    filter.motion.sigma_rotation = sigma.1.to_radians();
    filter.sampling.rays = spec.rays;
    let config = SessionConfig {
        intrinsics: k,
        particles: spec.particles,
        filter,
        floor: Default::default(),
        floor_feature: None,
        ground: false,
    };
    let start = Start::Pose {
        pose: gt[0],
        sigma_m: spec.init_sigma_m,
        sigma_rad: spec.init_sigma_deg.to_radians(),
    };
    let mut session = Session::new(shared.clone(), config, &start).map_err(err)?;
    let mut estimate = Vec::with_capacity(gt.len());
    let mut per_pose = Vec::new();
    let mut filter_s = 0.0;
    for (j, &i) in localized.iter().enumerate() {
        let fm = encode(&mut encoder, seq, i)?;
        let frame = EncodedFrame {
            map: &fm,
            width: k.width,
            height: k.height,
        };
        let r = session
            .step(&odom[j], j as f64, &frame)
            .map_err(|e| err(format!("frame {}: {e}", seq.frames[i].number)))?;
        let t = &r.step.timings;
        filter_s += (t.features + t.predict + t.weigh + t.update).as_secs_f64();
        estimate.push(r.pose);
        if let Some(m) = consistency(
            &shared,
            &k,
            &gt[j],
            &frame,
            (classes, &row_class),
            spec.consistency_stride,
        )? {
            per_pose.push(m);
        }
        progress(&format!(
            "frame {:06}: error {:.3} m",
            seq.frames[i].number,
            (r.pose.translation.vector - gt[j].translation.vector).norm()
        ));
    }
    let stamps: Vec<f64> = (0..gt.len()).map(|j| j as f64).collect();
    let reference = Trajectory::new(stamps.clone(), gt.clone()).map_err(err)?;
    let est = Trajectory::new(stamps, estimate.clone()).map_err(err)?;
    let e = ape(&reference, &est, PoseRelation::Translation).map_err(err)?;
    let er = ape(&reference, &est, PoseRelation::RotationAngleDeg).map_err(err)?;
    let completed = CompletionRule::default().judge(&e.errors);
    Ok(TrackResult {
        map_frames: mapping.len(),
        voxels,
        feature_rows,
        mapping: stats,
        edge_dropped,
        localized: localized.iter().map(|&i| seq.frames[i].number).collect(),
        step_motion: (step_t, step_r),
        odometry_sigma: sigma,
        ground_truth: gt,
        estimate,
        errors_m: e.errors,
        ape: e.stats,
        ape_rotation_deg: er.stats,
        completed,
        consistency: ConsistencyMetrics::mean(&per_pose),
        filter_steps_per_s: localized.len() as f64 / filter_s.max(1e-12),
    })
}

fn encode(
    encoder: &mut ImageEncoder,
    seq: &SevenScenes,
    i: usize,
) -> Result<FeatureMap, ExperimentError> {
    let img = seq.read_color(i).map_err(err)?;
    encoder
        .encode(&img)
        .map_err(|e| err(format!("{}: {e}", seq.frames[i].color.display())))
}

/// The colour class whose embedding is most similar to `f`.
fn nearest_class(classes: &ColourClasses, f: &[f32]) -> u32 {
    let mut best = (0u32, f32::NEG_INFINITY);
    for c in 0..classes.len() {
        let s: f32 = classes.embedding(c).iter().zip(f).map(|(a, b)| a * b).sum();
        if s > best.1 {
            best = (c as u32, s);
        }
    }
    best.0
}

/// Table II's scores of one frame over the K colour classes: each pixel of
/// a `stride` grid is cast from the true pose into the map; the reference
/// class is the class nearest the hit voxel's feature row (`row_class`:
/// rows are averages of observations, so mixtures, each collapsed to its
/// nearest class), the prediction the pixel's own class.
fn consistency(
    map: &SharedMap,
    k: &crate::geometry::Intrinsics,
    pose: &Pose,
    frame: &dyn FrameFeatures,
    (classes, row_class): (&ColourClasses, &[u32]),
    stride: u32,
) -> Result<Option<ConsistencyMetrics>, ExperimentError> {
    let m = map.map();
    let origin = m.grid().origin;
    let s = stride.max(1) as usize;
    let px: Vec<(u32, u32)> = (0..k.height)
        .step_by(s)
        .flat_map(|v| (0..k.width).step_by(s).map(move |u| (u, v)))
        .filter(|&(u, v)| frame.known(u, v))
        .collect();
    let rays: Vec<_> = px
        .iter()
        .map(|&(u, v)| camera_ray(k, pose, &origin, u, v))
        .collect();
    let hits = map.caster().cast_vec(&rays);
    let map_rows: Vec<u32> = hits
        .iter()
        .map(|h| {
            m.rows()
                .get(h.leaf as usize)
                .and_then(|&r| row_class.get(r as usize))
                .copied()
                .unwrap_or(NO_HIT)
        })
        .collect();
    let mut buf = vec![0.0f32; frame.dim()];
    let measured: Vec<u32> = px
        .iter()
        .map(|&(u, v)| {
            frame.feature(u, v, &mut buf);
            nearest_class(classes, &buf)
        })
        .collect();
    let (counts, _) = count_frame(classes.len(), &map_rows, &measured).map_err(err)?;
    Ok(counts.metrics())
}

/// The colour model's file in a bench's output folder.
pub fn default_model_path(out_dir: &Path) -> PathBuf {
    out_dir.join("colour_model.onnx")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_takes_even_for_the_map_and_every_nth_odd_to_localize() {
        let (m, l) = split(20, 3);
        assert_eq!(m, vec![0, 2, 4, 6, 8, 10, 12, 14, 16, 18]);
        assert_eq!(l, vec![1, 7, 13, 19]);
    }
}
