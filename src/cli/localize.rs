//! `omcl localize`: the particle filter over a recorded sequence.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, bail, ensure};
use clap::{Args, ValueEnum};

use omcl::eval::ape::{PoseRelation, ape};
use omcl::eval::localization::CompletionRule;
use omcl::geometry::Pose;
use omcl::io::kitti_camera::{CameraInput, KittiCameraSequence};
use omcl::io::labels::EmbeddingTable;
use omcl::io::poses::{self, PoseFormat};
use omcl::io::rgbd;
use omcl::io::sevenscenes::FramePick;
use omcl::map;
use omcl::mcl::baselines::BaselineParams;
use omcl::mcl::{
    self, EarlyReject, FilterConfig, FilterPreset, FloorParams, MotionMode, PromptParams,
    SamplingStrategy,
};
use omcl::session::baseline::{BaselineMap, BaselineSession};
use omcl::session::floorplan::{EXIT_WORDS, PlanScene};
use omcl::session::ground;
use omcl::session::sequence::{
    self, CameraSequence, FrameSource, Layout, LocalizedFrame, Odometry,
};
use omcl::session::{LabelTable, Session, SessionConfig, SessionError, SharedMap, Start};
use omcl::trajectory::Trajectory;

#[derive(Debug, Clone, Copy, PartialEq, ValueEnum)]
pub enum InitArg {
    /// Around a known pose (--init-pose, or the first ground-truth pose).
    Local,
    /// Uniformly over all floor voxels.
    Global,
    /// Over the floor voxels that match --prompt.
    Prompt,
}

/// The frame `--init-pose` is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PoseFrameArg {
    /// The camera in the map's frame (KITTI: camera 2 in the frame of the
    /// first scan's LiDAR, which a map of the scans is in).
    Map,
    /// KITTI only: camera 0 in poses.txt's frame, as poses.txt, --odometry
    /// and the -o estimates are written.
    Poses,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MotionArg {
    Planar,
    Full,
    Road,
}

/// `--filter`: one of the tuned filters ([`FilterPreset`]), or `auto`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FilterArg {
    Auto,
    Indoor,
    FloorPlan,
    FloorPlanPointCloud,
    SixDof,
    SixDofPointCloud,
    Street,
}

impl FilterArg {
    /// The preset named, `None` for `auto`.
    fn preset(self) -> Option<FilterPreset> {
        match self {
            FilterArg::Auto => None,
            FilterArg::Indoor => Some(FilterPreset::Indoor),
            FilterArg::FloorPlan => Some(FilterPreset::FloorPlan),
            FilterArg::FloorPlanPointCloud => Some(FilterPreset::FloorPlanPointCloud),
            FilterArg::SixDof => Some(FilterPreset::SixDof),
            FilterArg::SixDofPointCloud => Some(FilterPreset::SixDofPointCloud),
            FilterArg::Street => Some(FilterPreset::Street),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, ValueEnum)]
pub enum SamplingArg {
    Stratified,
    Uniform,
    Equal,
}

#[derive(Debug, Args)]
pub struct LocalizeArgs {
    /// The map (`.omcl`).
    #[arg(long)]
    pub map: PathBuf,
    /// The sequence folder, in one of three layouts. RGB-D: intrinsics.txt,
    /// labels/NNNNNN.png with classes.txt + embeddings.npy (ground-truth
    /// features) or features/NNNNNN.npy (`h x w x F`), poses.txt (ground
    /// truth, TUM; optional), odometry.txt (TUM; optional). KITTI odometry
    /// (a folder with calib.txt): camera 2 from calib.txt's P2, poses.txt
    /// (KITTI, camera 0) as ground truth, times.txt, and labels_2/NNNNNN.png
    /// with classes.txt + embeddings.npy, or features_2/NNNNNN.npy, or
    /// image_2/NNNNNN.png with --image-model. Microsoft 7-Scenes (a folder
    /// with camera-intrinsics.txt): frame-NNNNNN.color.jpg through
    /// --image-model, frame-NNNNNN.pose.txt as ground truth, turned z-up
    /// with gravity-direction.txt as `omcl map rgbd` builds its map.
    #[arg(long)]
    pub sequence: PathBuf,
    /// 7-Scenes folders: localize every n-th frame (a handheld camera moves
    /// millimetres a frame; with a map from the even frames, `--frame-step
    /// 8 --frame-offset 1` takes every 4th odd frame).
    #[arg(long, default_value_t = 1, value_name = "N", value_parser = super::count_in::<1, { usize::MAX }>)]
    pub frame_step: usize,
    /// 7-Scenes folders: the first frame localized (position among the
    /// sorted frames).
    #[arg(long, default_value_t = 0, value_name = "K")]
    pub frame_offset: usize,
    /// Odometry pose file (TUM or KITTI; for a KITTI sequence, camera 0 in
    /// the frame of poses.txt, e.g. a visual odometry's estimate: its
    /// frame-to-frame motion is replayed from the start pose); default: the
    /// sequence's odometry.txt, else ground truth plus noise (--odom-noise-*).
    #[arg(long)]
    pub odometry: Option<PathBuf>,
    /// Row of --odometry that belongs to the sequence's frame 0 (for a
    /// sequence cut from a longer drive).
    #[arg(long, default_value_t = 0)]
    pub odom_first: usize,
    /// Use ground truth plus Gaussian noise as odometry even if a file exists
    /// (the sequence's odometry.txt; not with --odometry).
    #[arg(long, conflicts_with = "odometry")]
    pub odom_from_gt: bool,
    /// Odometry noise per frame when made from ground truth: metres on
    /// camera x and z (the ground plane of a level camera; the authors'
    /// form, as `omcl sim` writes odometry.txt). Default 0.10; on 7-Scenes
    /// the paper's noise in proportion to the picked frames' motion (0.10 m
    /// per 0.13 m), on all six axes.
    #[arg(long, allow_negative_numbers = true, value_parser = super::metres)]
    pub odom_noise_m: Option<f64>,
    /// Odometry noise per frame when made from ground truth: degrees about
    /// camera y (default 6; KITTI 5.73, the authors' 0.1 rad; 7-Scenes 6
    /// per 8 degrees of motion, on all three axes).
    #[arg(long, allow_negative_numbers = true, value_parser = super::degrees)]
    pub odom_noise_deg: Option<f64>,
    /// Motion model of the particles: planar (x, y, yaw; height, roll and
    /// pitch follow the odometry), full (6-DoF noise in the camera frame)
    /// or road (planar plus a little height, pitch and roll noise). Default:
    /// the --filter's (full for six-dof and six-dof-point-cloud, road for
    /// street, planar for the others); with --filter auto planar, road for a
    /// KITTI sequence, full for 7-Scenes (a handheld camera).
    #[arg(long, value_enum)]
    pub motion: Option<MotionArg>,
    /// Particle motion noise per step: metres (paper 0.10; 7-Scenes: the
    /// odometry noise).
    #[arg(long, allow_negative_numbers = true, value_parser = super::metres)]
    pub motion_sigma_m: Option<f64>,
    /// Particle motion noise per step: degrees (paper 6; 7-Scenes: the
    /// odometry noise).
    #[arg(long, allow_negative_numbers = true, value_parser = super::degrees)]
    pub motion_sigma_deg: Option<f64>,
    /// How particles start.
    #[arg(long, value_enum, default_value = "local")]
    pub init: InitArg,
    /// `tx ty tz qx qy qz qw` for --init local (default: first ground
    /// truth), in the frame --init-pose-frame names.
    #[arg(long)]
    pub init_pose: Option<String>,
    /// The frame of --init-pose: `map` (the camera in the map's frame;
    /// KITTI: camera 2 in the first scan's LiDAR frame) or, on a KITTI
    /// sequence, `poses` (camera 0 as poses.txt and --odometry give it).
    #[arg(long, value_enum, default_value = "map", requires = "init_pose")]
    pub init_pose_frame: PoseFrameArg,
    /// Position spread of --init local, metres [default: 0.3] (paper: 0.3,
    /// with 17 degrees of --init-sigma-deg; on a KITTI sequence the
    /// authors' 0.3 m and 0.1 rad).
    #[arg(long, allow_negative_numbers = true, value_parser = super::metres)]
    pub init_sigma_m: Option<f64>,
    /// Rotation spread of --init local, degrees [default: 17; 5.73 on a
    /// KITTI sequence].
    #[arg(long, allow_negative_numbers = true, value_parser = super::degrees)]
    pub init_sigma_deg: Option<f64>,
    /// Prompt words for --init prompt, comma-separated ("toilet, sink").
    #[arg(long)]
    pub prompt: Option<String>,
    /// --init prompt: horizontal radius around a floor voxel in which the
    /// words' voxels are counted, metres [default: 2, the paper's]; one
    /// wider than the map counts the whole map.
    #[arg(long, requires = "prompt", value_parser = super::positive)]
    pub prompt_radius: Option<f64>,
    /// --init prompt: a voxel matches a word at this cosine similarity or
    /// more [default: 0.9, the paper's].
    #[arg(long, requires = "prompt", value_parser = super::cosine)]
    pub prompt_rho: Option<f32>,
    /// --init prompt: voxels each word needs within the radius, stated at
    /// 2 cm voxels and scaled to the map's resolution [default: 500, the
    /// paper's; 80 at 5 cm].
    #[arg(long, requires = "prompt", value_parser = super::non_negative)]
    pub prompt_k: Option<f64>,
    /// Number of particles [default: 1024, the paper's indoor setting; 512
    /// on a KITTI sequence, its street setting].
    #[arg(long, value_parser = super::count_in::<1, { super::MAX_COUNT }>)]
    pub particles: Option<usize>,
    /// The tuned filter to start from; --rays, --sharpen, --motion,
    /// --layers, --expand and the other filter options then change it.
    /// auto: floor-plan with --floorplan, street on a KITTI sequence,
    /// indoor elsewhere (on 7-Scenes with full motion and the odometry's
    /// noise). indoor: 2048 pixels, exponent 80, planar motion (the paper's
    /// indoor setting). floor-plan: 8192 pixels, exponent 240, estimate
    /// radius 0.5 m, planar (Table I's 2-D block). floor-plan-point-cloud:
    /// floor-plan with the pixels stratified over every row of the plan,
    /// not only its own, for a plan of a map made from a labelled point
    /// cloud with frames from an image encoder (Table I's 2-D
    /// OMCL_Open_LSeg row; where every row of the database is one of the
    /// plan's own, as on a plan of a map built from label images, the two
    /// sample alike and give the same estimates). six-dof: full 6-DoF motion, two layers of
    /// progressive correction, the first on 16 copies of each particle,
    /// 4096 pixels, exponent 240 (Table I's 6-DoF block). six-dof-point-cloud:
    /// six-dof with 512 pixels and exponent 20, for a map made from a
    /// labelled point cloud (`omcl map cloud`) with frames from an image
    /// encoder (Table I's 6-DoF OMCL_Open_LSeg row). street: road motion,
    /// 4096 pixels, two-pass likelihoods (Table IV, KITTI).
    #[arg(long, value_enum, default_value = "auto")]
    pub filter: FilterArg,
    /// Sampled pixels per frame before duplicates are dropped [default:
    /// the --filter's: 2048 indoor (the paper's indoor setting), 8192
    /// floor-plan and floor-plan-point-cloud, 4096 six-dof and street (the paper's street setting),
    /// 512 six-dof-point-cloud].
    #[arg(long, value_parser = super::count_in::<1, { super::MAX_COUNT }>)]
    pub rays: Option<usize>,
    /// Ray sampling strategy: stratified over the map's feature rows (the
    /// paper's), or uniform over the image, the better choice for a floor
    /// plan of raw image features (a map of an image model's features, not
    /// grounded on classes: its hundreds of near-duplicate rows make
    /// stratification draw as many pixels from each small cluster of odd
    /// pixels as from the walls).
    #[arg(long, value_enum, default_value = "stratified")]
    pub sampling: SamplingArg,
    /// Stratified and equal sampling skip pixels whose clustering-grid
    /// cell (4 px) has a cell of another cluster within this many cells,
    /// where labels and encoder features are least reliable (0: every
    /// pixel, as the paper). Default: 0.75 % of the image width in cells
    /// (1 on 540-px images, where it helped on the synthetic benchmark;
    /// 0 below about 270 px, where boundaries are what locates the camera);
    /// 0 on KITTI sequences (measured on the street world: edges and thin
    /// structures are what fixes a car at corners).
    #[arg(long, value_name = "CELLS")]
    pub boundary_margin: Option<u32>,
    /// Exponent on the likelihood (1 = the paper's eq. 2) [default: the
    /// --filter's: 80 indoor and street, 240 floor-plan, 240 six-dof, 20
    /// six-dof-point-cloud].
    #[arg(long)]
    pub sharpen: Option<f64>,
    /// Layers of progressive correction a frame (1: the paper's filter).
    /// With 2 or more, each frame is weighed with part of the exponent,
    /// resampled, jittered (a third of the motion noise, shrinking each
    /// layer) and weighed with the rest: it helps the full 6-DoF motion
    /// model (Table I's 6-DoF block: 0.246 -> 0.197 m on tuning
    /// sequences with 2), at the cost of casting every ray once a layer.
    /// [default: 1; 2 with --filter six-dof and six-dof-point-cloud]
    #[arg(long,
          value_parser = clap::value_parser!(u32).range(1..=omcl::mcl::anneal::MAX_LAYERS as i64))]
    pub layers: Option<u32>,
    /// With --layers 2 or more: the first layer weighs this many copies of
    /// each particle (each with its own motion noise) on every N-th
    /// sampled pixel, the same rays; the second goes back to --particles.
    /// Table I's 6-DoF block uses 16 with 1024 particles x 4096 rays
    /// (docs/table1.md, "6-DoF (3-D block)"). [default: 1; 16 with --filter six-dof and
    /// six-dof-point-cloud]
    #[arg(long, value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=omcl::mcl::anneal::MAX_EXPAND as i64))]
    pub expand: Option<u32>,
    /// Score rays with the plain cosine of eq. 2 instead of the per-pixel
    /// contrast-rescaled cosine (see `SensorParams::contrast`).
    #[arg(long)]
    pub no_contrast: bool,
    /// Two-pass likelihoods: a quarter of the pixels first (half on a KITTI
    /// sequence), the rest only for particles within 15 % of the best
    /// (`sensor::EarlyReject`). About 1.4 times the steps/s on the
    /// synthetic benchmark at the same APE. Off by default, as the paper's
    /// filter casts every ray, except on KITTI sequences (see --every-ray)
    #[arg(long, conflicts_with = "every_ray")]
    pub early_reject: bool,
    /// Cast every sampled pixel for every particle, as the paper's filter
    /// does, on a KITTI sequence too (whose default is two-pass
    /// likelihoods with every 2nd pixel first: faster and as accurate on
    /// the tuning streets, see docs/outdoor.md, "Outdoor speed")
    #[arg(long)]
    pub every_ray: bool,
    /// Score of a sampled pixel's ray that hits nothing in the map, on the
    /// contrast scale where a hit scores 0 (the pixel's least similar
    /// class) to 1 (its most similar). Default: 0.5 on a KITTI sequence,
    /// where a third of the image is sky and misses at 0 pull the filter
    /// towards poses that turn the sky onto facades (docs/outdoor.md, "Misses on
    /// streets"); 0 elsewhere
    #[arg(long, value_name = "SCORE", value_parser = super::unit_score)]
    pub miss_score: Option<f32>,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Use at most this many frames.
    #[arg(long, value_parser = super::count_in::<1, { usize::MAX }>)]
    pub frames: Option<usize>,
    /// Take pixel features from features/NNNNNN.npy (KITTI: features_2/)
    /// even if labels exist (e.g. the simulator's noisy "lseg-like"
    /// features).
    #[arg(long)]
    pub use_features: bool,
    /// Estimated trajectory, written atomically: TUM in the map frame for
    /// an RGB-D sequence (7-Scenes: the z-up map frame, stamped with the
    /// frame numbers); for a KITTI sequence KITTI lines of camera 0 in the
    /// frame of its poses.txt (what evo compares with poses.txt).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Per-frame errors and their statistics (JSON; needs ground truth):
    /// translation (m) and rotation (degrees) of the paper's Table IV.
    #[arg(long)]
    pub metrics: Option<PathBuf>,
    /// Figure (PNG or SVG by extension): the estimated path coloured by its
    /// error over the map's floor plan, with the ground truth (the paper's
    /// Figure 4). Needs poses.txt.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Per-frame diagnostics (CSV: ESS, spread, likelihood, confidence,
    /// time).
    #[arg(long)]
    pub diagnostics: Option<PathBuf>,
    /// Replace -o, --metrics, --diagnostics and --plot even when they hold
    /// files that are not earlier outputs of their kind (a trajectory,
    /// omcl's metrics JSON or diagnostics CSV, a figure omcl drew), or
    /// files of a dataset folder (another sequence's poses.txt)
    #[arg(long)]
    pub force: bool,
    /// Recover from track loss (a lost or kidnapped camera): when the frames
    /// suddenly agree less with the map, inject the best-scoring of fresh
    /// floor poses (augmented MCL with sensor resetting). Needs "floor" in
    /// the class table, like --init global.
    #[arg(long)]
    pub recovery: bool,
    #[command(flatten)]
    pub encoder: super::encoders::EncoderArgs,
    /// Text encoder for --prompt, "floor" and, with --floorplan,
    /// "ceiling" (default: the sequence's classes.txt + embeddings.npy).
    #[arg(long, value_name = "ONNX")]
    pub text_model: Option<PathBuf>,
    /// Localize in 2-D on the map's floor plan, the paper's Table I 2-D
    /// mode: the pose is x, y and yaw of a camera held level at the start
    /// pose's height (a robot's; the odometry's horizontal motion and
    /// heading move it, planar motion noise), the map's features are
    /// averaged along the vertical over a height band, and each sampled
    /// pixel's ray is followed over the plan with the 3-D map's column
    /// heights, floors and ceilings (what it sees in plan view). With a
    /// value, the plan file `omcl map floorplan` made from --map (its
    /// band); without one, --map projected with the default band, 0.10 to
    /// 2.00 m above its floor.
    /// The filter of Table I's 2-D block (8192 pixels, exponent 240,
    /// estimate radius 0.5 m, pixels stratified over the plan's own rows
    /// and the words) unless --rays or --sharpen; errors are horizontal.
    /// --init global and prompt and --recovery place level cameras over
    /// the 3-D map's floor, as without --floorplan. The words "floor" and "ceiling" come from
    /// --text-model or the class table (without them, rays leaving the
    /// plan's height window score only the columns' own floors and
    /// ceilings).
    #[arg(long, value_name = "PLAN", num_args = 0..=1)]
    pub floorplan: Option<Option<PathBuf>>,
    /// Hold the camera to the ground, as a robot on a flat floor carries
    /// it: its height, roll and pitch stay the start pose's (level for
    /// --init global and prompt), and only the odometry's horizontal
    /// motion and turn move it; its drift in height and tilt does not.
    /// Planar motion (the default with it); indoor sequences only (KITTI
    /// streets climb). --floorplan always does, with the camera level.
    #[arg(long)]
    pub ground: bool,
    /// With --floorplan: track the camera with one of Table I's two
    /// semantic MCL baselines instead of OMCL's sensor, on the same floor
    /// plan, with the same motion noise, estimate and start and the same
    /// stratified pixel sampler (over every row of the plan's database, as
    /// in `omcl bench table1-floorplan`; docs/table1.md says what was
    /// adapted). sedar (SeDAR*): each pixel's
    /// planar ray, the class of the column it reaches against the pixel's
    /// class. simp (SIMP*): each pixel placed at its depth, scored by its
    /// distance to the plan's nearest column of its class; needs the
    /// sequence's depth images (depth/NNNNNN.png, --depth-scale; 7-Scenes'
    /// own). Both label the plan's columns and the pixels with the nearest
    /// class of the sequence's class table (classes.txt + embeddings.npy,
    /// in the map's feature space). 2048 pixels a frame unless --rays;
    /// from a pose only (--init local); OMCL's sensor options (--sharpen,
    /// --layers, --expand, --no-contrast, --early-reject, --every-ray,
    /// --miss-score) and --recovery are refused.
    #[arg(long, value_enum, requires = "floorplan")]
    pub baseline: Option<BaselineArg>,
    /// --baseline: the class table to label with, a folder holding
    /// classes.txt and embeddings.npy (`omcl encode colour-model
    /// --class-table` writes one for its classes) [default: the
    /// sequence's own].
    #[arg(long, value_name = "DIR", requires = "baseline")]
    pub baseline_classes: Option<PathBuf>,
    /// --baseline simp: depth PNG units per metre [default: 5000, TUM's
    /// and `omcl map rgbd`'s; 7-Scenes folders are read in millimetres].
    #[arg(long, value_name = "UNITS", value_parser = super::positive)]
    pub depth_scale: Option<f64>,
    /// --baseline simp: place only pixels at most this deep (z-depth,
    /// metres), as SIMP's detector sees objects only so far [default:
    /// every pixel with a depth, as Table I's SIMP* rows].
    #[arg(long, value_name = "METRES", value_parser = super::positive)]
    pub max_depth: Option<f64>,
}

/// Table I's baselines, by `--baseline`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BaselineArg {
    /// SeDAR* (Mendez et al., ICRA 2018): semantic ray casting.
    Sedar,
    /// SIMP* (Zimmerman et al., 2023): a per-class likelihood field.
    Simp,
}

impl BaselineArg {
    /// The method's name, starred as in Table I.
    fn label(self) -> &'static str {
        self.baseline().label()
    }

    fn baseline(self) -> omcl::mcl::baselines::Baseline {
        match self {
            BaselineArg::Sedar => omcl::mcl::baselines::Baseline::Sedar,
            BaselineArg::Simp => omcl::mcl::baselines::Baseline::Simp,
        }
    }
}

/// What to do when global or prompt initialization cannot place particles,
/// in the command line's terms.
fn init_advice(e: mcl::MclError) -> anyhow::Error {
    let advice = match &e {
        mcl::MclError::NoFloor { .. } => {
            "particles start on floor voxels: use a map whose database has a \"floor\" row \
             (e.g. grounded with it), or start from a known pose with --init local --init-pose"
        }
        mcl::MclError::NoPromptMatch { .. } => {
            "try fewer or other words, a lower --prompt-k or --prompt-rho, a larger \
             --prompt-radius, --init global, or --init local --init-pose"
        }
        _ => return e.into(),
    };
    anyhow::Error::new(e).context(advice)
}

fn parse_pose(s: &str) -> anyhow::Result<Pose> {
    // Seven numbers, no stamp (a TUM line's eight would read its first as
    // a stamp and hide a wrong count).
    let n = s.split_whitespace().count();
    ensure!(
        n == 7,
        "--init-pose {s:?}: expected 7 numbers 'tx ty tz qx qy qz qw', found {n}"
    );
    rgbd::parse_tum_pose(s).map_err(|e| anyhow::anyhow!("--init-pose {s:?}: {e}"))
}

/// A lowercase word and its text feature.
type WordFeature = (String, Vec<f32>);

/// Where the features of words (prompt words, "floor", "ceiling") come
/// from: `--text-model`, which encodes every word the run needs once, else
/// the sequence's class table (classes.txt + embeddings.npy).
struct Words<'a> {
    /// The text encoder and its features of the run's words.
    encoded: Option<(PathBuf, Vec<WordFeature>)>,
    table: Option<&'a LabelTable>,
    classes: &'a Path,
}

impl<'a> Words<'a> {
    /// With `--text-model`, encodes `--prompt`'s words and the map words
    /// the run may use (features of dimension `dim`, the map's).
    fn new(
        a: &LocalizeArgs,
        table: Option<&'a LabelTable>,
        classes: &'a Path,
        dim: usize,
    ) -> anyhow::Result<Self> {
        let encoded = match &a.text_model {
            Some(model) => {
                let mut words: Vec<String> = split_words(a.prompt.as_deref().unwrap_or(""))
                    .chain(["floor"].into_iter().chain(EXIT_WORDS))
                    .map(str::to_lowercase)
                    .collect();
                words.sort();
                words.dedup();
                let (name, rows) =
                    super::encoders::text_features(model, a.encoder.ort_lib.as_deref(), &words)?;
                let got = rows.first().map_or(0, Vec::len);
                ensure!(
                    got == dim,
                    "--text-model {} ({name}) gives {got}-d features, the map {} has {dim}",
                    model.display(),
                    a.map.display()
                );
                Some((model.clone(), words.into_iter().zip(rows).collect()))
            }
            None => None,
        };
        Ok(Words {
            encoded,
            table,
            classes,
        })
    }

    /// Whether any source of word features was given.
    fn available(&self) -> bool {
        self.encoded.is_some() || self.table.is_some()
    }

    /// The features of the comma-separated `words`; `what` names them in
    /// errors ("prompt word", "map word").
    fn features(&self, words: &str, what: &str) -> anyhow::Result<Vec<Vec<f32>>> {
        split_words(words)
            .map(|w| match (&self.encoded, self.table) {
                (Some((model, rows)), _) => rows
                    .iter()
                    .find(|(n, _)| n.eq_ignore_ascii_case(w))
                    .map(|(_, f)| f.clone())
                    .with_context(|| {
                        format!("{what} {w:?} was not encoded by {}", model.display())
                    }),
                (None, Some(t)) => t.word(w).map(<[f32]>::to_vec).with_context(|| {
                    format!("{what} {w:?} is not a class of {}", self.classes.display())
                }),
                (None, None) => bail!(
                    "{what} {w:?} needs word features: --text-model ONNX, or classes.txt and \
                     embeddings.npy beside label images ({})",
                    self.classes.display()
                ),
            })
            .collect()
    }
}

/// The trimmed, non-empty words of a comma-separated list.
fn split_words(words: &str) -> impl Iterator<Item = &str> {
    words.split(',').map(str::trim).filter(|w| !w.is_empty())
}

/// The odometry noise made from ground truth: metres, degrees and whether
/// on all six axes (the options, else the layout's default).
fn odometry_noise(a: &LocalizeArgs, inputs: &CameraSequence) -> (f64, f64, bool) {
    let (m, deg, all_axes) = match (inputs.layout(), &inputs.ground_truth) {
        (Layout::SevenScenes, Some(g)) => {
            let n = g.len().min(a.frames.unwrap_or(usize::MAX));
            let (m, deg) = omcl::sim::paths::paper_noise_for(&g.poses()[..n]);
            (m, deg, true)
        }
        (Layout::Kitti, _) => (0.10, 0.1f64.to_degrees(), false),
        _ => (0.10, 6.0, false),
    };
    (
        a.odom_noise_m.unwrap_or(m),
        a.odom_noise_deg.unwrap_or(deg),
        all_axes,
    )
}

/// Where the odometry comes from: a pose file (`--odometry`, or
/// odometry.txt beside an RGB-D sequence), or ground truth with the
/// library's one definition of odometry noise (noise on camera x and z and
/// on yaw about camera y, every frame, accumulated: the authors' form; on
/// 7-Scenes on all six axes).
fn odometry_source(a: &LocalizeArgs, inputs: &CameraSequence) -> anyhow::Result<Odometry> {
    let odom_file = a.odometry.clone().or_else(|| {
        let p = inputs.dir.join("odometry.txt");
        (!a.odom_from_gt && inputs.layout() == Layout::Rgbd && p.exists()).then_some(p)
    });
    if let Some(path) = odom_file {
        // Noise shapes odometry made from ground truth only.
        let noise: Vec<&str> = [
            ("--odom-noise-m", a.odom_noise_m.is_some()),
            ("--odom-noise-deg", a.odom_noise_deg.is_some()),
        ]
        .into_iter()
        .filter_map(|(f, set)| set.then_some(f))
        .collect();
        ensure!(
            noise.is_empty(),
            "{} shape odometry made from ground truth, but the odometry comes from {} (its \
             motion is replayed as it is); drop {}, or pass --odom-from-gt for ground truth \
             plus noise",
            noise.join(" and "),
            path.display(),
            if noise.len() == 1 { "it" } else { "them" }
        );
        return Ok(Odometry::File {
            path,
            first: a.odom_first,
        });
    }
    ensure!(
        a.odom_first == 0,
        "--odom-first {} picks a row of an odometry file, but none is read (--odometry FILE, \
         or an RGB-D sequence's odometry.txt)",
        a.odom_first
    );
    let (sigma_t, sigma_r_deg, all_axes) = odometry_noise(a, inputs);
    let cfg = omcl::sim::paths::OdometryConfig {
        seed: a.seed ^ 0x0d0,
        sigma_t,
        sigma_r_deg,
        drift_scale: 1.0,
        all_axes,
    };
    ensure!(
        cfg.sigma_t >= 0.0 && cfg.sigma_r_deg >= 0.0,
        "--odom-noise-m and --odom-noise-deg must be >= 0"
    );
    if !a.odom_from_gt && inputs.layout() == Layout::Rgbd {
        // Not asked for: a folder without odometry.txt (one left behind
        // when copying a sequence) should not pass unseen.
        eprintln!(
            "note: {} has no odometry.txt: the odometry is the ground truth with noise \
             ({} m and {} degrees a frame; --odometry FILE replays a recorded one, \
             --odom-from-gt says this is meant)",
            inputs.dir.display(),
            cfg.sigma_t,
            cfg.sigma_r_deg
        );
    }
    Ok(Odometry::FromTruth(cfg))
}

/// Where the particles start: around a pose (`--init-pose` or the first
/// ground-truth pose), globally, or from prompt words.
fn start(
    a: &LocalizeArgs,
    gt: Option<&Trajectory>,
    words_of: &Words,
    kitti: Option<&KittiCameraSequence>,
) -> anyhow::Result<Start> {
    let is_kitti = kitti.is_some();
    let init_sigma_deg =
        a.init_sigma_deg
            .unwrap_or(if is_kitti { 0.1f64.to_degrees() } else { 17.0 });
    Ok(match a.init {
        InitArg::Local => {
            let pose = match (&a.init_pose, gt) {
                (Some(s), _) => match (a.init_pose_frame, kitti) {
                    (PoseFrameArg::Map, _) => parse_pose(s)?,
                    (PoseFrameArg::Poses, Some(k)) => k.camera2_in_map(&[parse_pose(s)?])[0],
                    (PoseFrameArg::Poses, None) => bail!(
                        "--init-pose-frame poses is for KITTI sequences (camera 0 in \
                         poses.txt's frame); this sequence's poses are in the map's frame"
                    ),
                },
                (None, Some(g)) => g.poses()[0],
                (None, None) => bail!(
                    "--init local needs --init-pose 'tx ty tz qx qy qz qw' (the camera in the \
                     map's frame; camera 2 on a KITTI sequence) without ground truth to start \
                     from (poses.txt)"
                ),
            };
            Start::Pose {
                pose,
                sigma_m: a.init_sigma_m.unwrap_or(DEFAULT_INIT_SIGMA_M),
                sigma_rad: init_sigma_deg.to_radians(),
            }
        }
        InitArg::Global => Start::Global,
        InitArg::Prompt => {
            let words = a
                .prompt
                .as_deref()
                .context("--init prompt needs --prompt \"word, word\"")?;
            Start::Prompt {
                words: words_of.features(words, "prompt word")?,
                params: {
                    let d = PromptParams::default();
                    PromptParams {
                        radius: a.prompt_radius.unwrap_or(d.radius),
                        rho: a.prompt_rho.unwrap_or(d.rho),
                        k: a.prompt_k.unwrap_or(d.k),
                        ..d
                    }
                },
            }
        }
    })
}

/// `--particles`, or the default: the paper's street setting on KITTI
/// sequences, its indoor one elsewhere.
fn particle_count(a: &LocalizeArgs, is_kitti: bool) -> usize {
    a.particles.unwrap_or(if is_kitti {
        omcl::mcl::STREET_PARTICLES
    } else {
        omcl::mcl::INDOOR_PARTICLES
    })
}

/// The tuned filter `--filter` names, or `auto`'s: the 2-D block's with
/// `--floorplan`, the street filter on KITTI sequences, the indoor one
/// elsewhere.
fn filter_preset(a: &LocalizeArgs, is_kitti: bool) -> FilterPreset {
    a.filter.preset().unwrap_or(if a.floorplan.is_some() {
        FilterPreset::FloorPlan
    } else if is_kitti {
        FilterPreset::Street
    } else {
        FilterPreset::Indoor
    })
}

/// The layers of progressive correction: the preset's (`base`), with
/// `--layers` and `--expand` over them (`--layers 1`: none).
fn anneal(a: &LocalizeArgs, base: Option<mcl::Anneal>) -> Option<mcl::Anneal> {
    let layers = a.layers.unwrap_or(base.map_or(1, |b| b.layers));
    (layers > 1).then(|| {
        let b = base.unwrap_or_default();
        mcl::Anneal {
            layers,
            expand: a.expand.unwrap_or(b.expand),
            ..b
        }
    })
}

/// `--motion`'s word for a motion mode.
fn motion_name(m: MotionMode) -> &'static str {
    match m {
        MotionMode::Planar => "planar",
        MotionMode::Full => "full",
        MotionMode::Road => "road",
    }
}

/// The filter's configuration from the options (KITTI sequences default to
/// road motion; 7-Scenes to full 6-DoF motion with the odometry's noise).
fn filter_config(a: &LocalizeArgs, inputs: &CameraSequence) -> FilterConfig {
    let layout = inputs.layout();
    let is_kitti = layout == Layout::Kitti;
    let base = filter_preset(a, is_kitti).config();
    let mut config = FilterConfig {
        seed: a.seed,
        ..base
    };
    if let Some(r) = a.rays {
        config.sampling.rays = r;
    }
    if a.boundary_margin.is_some() {
        config.sampling.boundary_margin = a.boundary_margin;
    }
    config.sampling.strategy = match a.sampling {
        SamplingArg::Stratified => SamplingStrategy::Stratified,
        SamplingArg::Uniform => SamplingStrategy::Uniform,
        SamplingArg::Equal => SamplingStrategy::EqualWithDuplicates,
    };
    // A named filter brings its own motion; `auto` the sequence's.
    let motion = a.motion.or(match (a.filter, layout) {
        (FilterArg::Auto, _) if a.floorplan.is_some() || a.ground => Some(MotionArg::Planar),
        (FilterArg::Auto, Layout::SevenScenes) => Some(MotionArg::Full),
        _ => None,
    });
    if layout == Layout::SevenScenes {
        let (m, deg, _) = odometry_noise(a, inputs);
        config.motion.sigma_translation = m;
        config.motion.sigma_rotation = deg.to_radians();
    }
    if let Some(m) = motion {
        config.motion.mode = match m {
            MotionArg::Planar => MotionMode::Planar,
            MotionArg::Full => MotionMode::Full,
            MotionArg::Road => MotionMode::Road,
        };
    }
    if let Some(v) = a.motion_sigma_m {
        config.motion.sigma_translation = v;
    }
    if let Some(v) = a.motion_sigma_deg {
        config.motion.sigma_rotation = v.to_radians();
    }
    if let Some(s) = a.sharpen {
        config.sharpen = s;
    }
    config.anneal = anneal(a, base.anneal);
    config.sensor.contrast = !a.no_contrast;
    config.sensor.early_reject = match (a.early_reject, a.every_ray) {
        (_, true) => None,
        (true, _) => base.sensor.early_reject.or(Some(EarlyReject::default())),
        (false, false) => base.sensor.early_reject,
    };
    if let Some(m) = a.miss_score {
        config.sensor.miss_score = m;
    }
    if a.recovery {
        config.recovery = Some(mcl::recovery::RecoveryParams::default());
    }
    config
}

/// The method a run localizes with, as `--metrics` names it: Table I's
/// names, a baseline starred.
fn method_name(a: &LocalizeArgs) -> &'static str {
    match (a.baseline, a.floorplan.is_some()) {
        (Some(b), _) => b.label(),
        (None, true) => "OMCL (2-D, floor plan)",
        (None, false) => "OMCL (3-D map)",
    }
}

/// Writes `--metrics`: the outdoor metric of the run as JSON.
fn write_metrics(
    p: &Path,
    d: &Path,
    n: usize,
    mt: &omcl::eval::OutdoorMetric,
    method: &str,
    horizontal: bool,
    steps_per_s: f64,
) -> anyhow::Result<()> {
    let translation = match horizontal {
        true => {
            "horizontal translation error |(t_est - t_gt)_xy| (m; a floor plan's \
                 2-D estimate, as `omcl eval ape --horizontal`)"
        }
        false => "translation error |t_est - t_gt| (m)",
    };
    let json = serde_json::json!({
        "sequence": d.display().to_string(),
        "method": method,
        "frames": n,
        "metric": format!(
            "per-frame {translation} and rotation error angle(R_gt^T R_est) (deg) of the \
             camera; completed: after frame 10 the error never exceeds 1 m for more than 5 \
             frames"
        ),
        "horizontal": horizontal,
        "translation_m": mt.translation,
        "rotation_deg": mt.rotation,
        // null: too few frames for the rule to fail (not judged).
        "completed": mt.completed,
        "filter_steps_per_s": steps_per_s,
        "per_frame": {
            "translation_m": mt.translation_m,
            "rotation_deg": mt.rotation_deg,
        },
    });
    let text = serde_json::to_string_pretty(&json)?;
    omcl::io::atomic::write(p, text.as_bytes())
        .with_context(|| format!("writing {}", p.display()))?;
    Ok(())
}

/// Prints APE and completion against ground truth `g` (and, on KITTI,
/// the outdoor metric), and draws `--plot`.
fn report_against_truth(
    a: &LocalizeArgs,
    g: &Trajectory,
    est: &Trajectory,
    n: usize,
    metric: Option<&omcl::eval::OutdoorMetric>,
    floor: Option<&[f32]>,
    m: &omcl::map::LanguageMap,
) -> anyhow::Result<()> {
    let d = &a.sequence;
    let is_kitti = d.join("calib.txt").exists();
    let reference = Trajectory::new(g.stamps()[..n].to_vec(), g.poses()[..n].to_vec())?;
    // On a floor plan the error is horizontal (x and y), as Table I's 2-D
    // block measures it.
    let e = if a.floorplan.is_some() {
        ape(
            &reference.horizontal(),
            &est.horizontal(),
            PoseRelation::Translation,
        )?
    } else {
        ape(&reference, est, PoseRelation::Translation)?
    };
    let rule = CompletionRule::default();
    // A run too short for the rule to fail is not judged rather than
    // called completed.
    let done = match rule.judge(&e.errors) {
        None => format!(
            "not judged (the rule needs {} frames or more)",
            rule.frames_to_judge()
        ),
        Some(true) => "yes".into(),
        Some(false) => "no".into(),
    };
    if let Some(p) = &a.plot {
        let plan = omcl::plot::FloorPlan::from_map(m, floor, 0.9);
        let xy = |t: &Trajectory| -> Vec<[f64; 2]> {
            t.poses()
                .iter()
                .map(|p| [p.translation.vector.x, p.translation.vector.y])
                .collect()
        };
        let title = format!("{} (APE rmse {:.3} m)", d.display(), e.stats.rmse);
        omcl::plot::trajectory_plot(
            p,
            &omcl::plot::TrajectoryPanel {
                title: &title,
                plan: plan.as_ref(),
                gt_xy: &xy(&reference),
                est_xy: &xy(est),
                errors_m: &e.errors,
            },
        )?;
    }
    print!(
        "; APE{} rmse {:.3} m, mean {:.3}, median {:.3}, max {:.3}; completed: {}",
        if a.floorplan.is_some() {
            " (horizontal)"
        } else {
            ""
        },
        e.stats.rmse,
        e.stats.mean,
        e.stats.median,
        e.stats.max,
        done
    );
    if let (Some(mt), true) = (metric, is_kitti) {
        print!(
            "; translation error mean {:.3} m (std {:.3}), rotation error mean {:.2} deg \
             (std {:.2})",
            mt.translation.mean, mt.translation.std, mt.rotation.mean, mt.rotation.std
        );
    }
    println!();
    Ok(())
}

/// The class table of label images (bound to the map), when the frames
/// are label images or a prompt, global start or recovery needs words.
fn class_table(
    a: &LocalizeArgs,
    inputs: &CameraSequence,
    has_image_encoder: bool,
    m: &omcl::map::LanguageMap,
) -> anyhow::Result<Option<LabelTable>> {
    let classes = &inputs.classes;
    let is_kitti = inputs.kitti.is_some();
    // Frames from the image model or from features/: the table would only
    // give words, so one that cannot serve the map is left out with a note.
    let frames_from = match (has_image_encoder, a.use_features) {
        (true, _) => Some("the image model"),
        (false, true) => Some("features/ (--use-features)"),
        (false, false) => None,
    };
    let wants_table = inputs.labels_dir.is_dir() && (frames_from.is_none() || classes.exists());
    if !wants_table || (is_kitti && a.use_features) {
        return Ok(None);
    }
    let t = match (
        EmbeddingTable::read(classes, &inputs.embeddings),
        frames_from,
    ) {
        (Ok(t), _) => t,
        (Err(e), Some(from)) => {
            eprintln!(
                "note: the class table is not used (the frames come from {from}): {e}; words \
                 (--init prompt or global, recovery) need a class table or --text-model"
            );
            return Ok(None);
        }
        (Err(e), None) => return Err(e.into()),
    };
    if let Some(from) = frames_from
        && t.dim != m.db().dim()
    {
        // The table lives in another feature space than the map (one built
        // with the image model, or from the feature files). With
        // --text-model the words come from it: nothing to say.
        if a.text_model.is_some() {
            return Ok(None);
        }
        eprintln!(
            "note: {}: {}-d class features, not the map's {}-d (its encoder {}): the frames \
             come from {from} and this table is not used; words (--init prompt or global, \
             recovery) need --text-model in the map's feature space",
            inputs.embeddings.display(),
            t.dim,
            m.db().dim(),
            m.encoder()
        );
        return Ok(None);
    }
    ensure!(
        t.dim == m.db().dim(),
        "{}: features have dimension {}, the map {} has {}",
        inputs.embeddings.display(),
        t.dim,
        a.map.display(),
        m.db().dim()
    );
    let bound =
        LabelTable::new(t, m).with_context(|| format!("{}", inputs.embeddings.display()))?;
    Ok(Some(bound))
}

/// --init local's position spread when --init-sigma-m is not given.
const DEFAULT_INIT_SIGMA_M: f64 = 0.3;

/// The names of the options `flags` marks as given.
fn given(flags: &[(bool, &'static str)]) -> Vec<&'static str> {
    flags
        .iter()
        .filter(|(on, _)| *on)
        .map(|(_, o)| *o)
        .collect()
}

/// Refuses options the run would not use: a start pose or spread for a
/// start that is not --init local, pixel-margin for uniform sampling, a
/// runtime library with no model to run, OMCL's sensor options, another
/// start or recovery with --baseline, a depth scale or range without SIMP*.
fn check_options_apply(a: &LocalizeArgs) -> anyhow::Result<()> {
    if let Some(b) = a.baseline {
        let name = b.label();
        ensure!(
            a.init == InitArg::Local,
            "--baseline: {name} starts from a pose (--init local, the paper's start for both \
             baselines); its sensor scores class labels, and --init global and prompt place \
             cameras with the floor's feature"
        );
        ensure!(
            !a.recovery,
            "--baseline: {name} has no recovery (it injects floor poses scored by OMCL's \
             sensor); leave --recovery out"
        );
        let omcl_only = given(&[
            (a.sharpen.is_some(), "--sharpen"),
            (a.layers.is_some(), "--layers"),
            (a.expand.is_some(), "--expand"),
            (a.no_contrast, "--no-contrast"),
            (a.early_reject, "--early-reject"),
            (a.every_ray, "--every-ray"),
            (a.miss_score.is_some(), "--miss-score"),
        ]);
        ensure!(
            omcl_only.is_empty(),
            "--baseline: {} set{} OMCL's sensor, which {name} does not use (its likelihood is \
             its own, tempered with 30 beams); leave {} out",
            omcl_only.join(" and "),
            if omcl_only.len() == 1 { "s" } else { "" },
            if omcl_only.len() == 1 { "it" } else { "them" }
        );
    }
    ensure!(
        a.depth_scale.is_none() || a.baseline == Some(BaselineArg::Simp),
        "--depth-scale is for --baseline simp (the only sensor here that reads depth images)"
    );
    ensure!(
        a.max_depth.is_none() || a.baseline == Some(BaselineArg::Simp),
        "--max-depth is for --baseline simp (the only sensor here that places pixels at \
         their depth)"
    );
    if a.init != InitArg::Local {
        let given = given(&[
            (a.init_pose.is_some(), "--init-pose"),
            (a.init_sigma_m.is_some(), "--init-sigma-m"),
            (a.init_sigma_deg.is_some(), "--init-sigma-deg"),
        ]);
        ensure!(
            given.is_empty(),
            "{} {} for --init local (a start pose and its spread); --init {} places the \
             particles by itself: leave {} out",
            given.join(" and "),
            if given.len() == 1 { "is" } else { "are" },
            a.init
                .to_possible_value()
                .map_or(String::new(), |v| v.get_name().to_string()),
            if given.len() == 1 { "it" } else { "them" }
        );
    }
    ensure!(
        a.boundary_margin.is_none() || a.sampling != SamplingArg::Uniform,
        "--boundary-margin is for stratified and equal sampling (pixels near a cluster's \
         edge); --sampling uniform draws over the whole image: leave it out"
    );
    ensure!(
        a.encoder.ort_lib.is_none() || a.encoder.image_model.is_some() || a.text_model.is_some(),
        "--ort-lib is for --image-model or --text-model, and neither is given"
    );
    Ok(())
}

/// The session of the run: its start, filter and floor (with advice when
/// the start cannot place particles).
fn open_session(
    a: &LocalizeArgs,
    shared: Arc<SharedMap>,
    inputs: &CameraSequence,
    words: &Words,
) -> anyhow::Result<Session> {
    let (k, gt) = (inputs.intrinsics, inputs.ground_truth.as_ref());
    let is_kitti = inputs.layout() == Layout::Kitti;
    let start = start(a, gt, words, inputs.kitti.as_ref())?;
    if let Start::Pose { pose, .. } = &start {
        let tilt = ground::tilt_deg(pose);
        if tilt > 2.0 && shared.is_level() {
            eprintln!(
                "note: the start pose is {tilt:.1} degrees from level; on a floor plan the \
                 camera is held level at its height{}",
                if tilt > 80.0 {
                    ", its heading taken from an optical axis this close to the vertical \
                     (little more than a guess: give a start that looks sideways)"
                } else {
                    ""
                }
            );
        } else if tilt > 2.0 && a.ground {
            eprintln!(
                "note: --ground holds the camera {tilt:.1} degrees from level, the start \
                 pose's tilt, for the whole run"
            );
        }
    }
    let floor_feature = match (a.init, a.recovery) {
        (InitArg::Local, false) => None,
        _ => Some(
            words
                .features("floor", "map word")
                .map_err(|e| {
                    if is_kitti {
                        // A street's class table has no floor (its ground
                        // is road, sidewalk, parking, ...): the reason is
                        // the idea, not the missing word.
                        anyhow::anyhow!(
                            "--init global, --init prompt and --recovery place cameras on the \
                             map's floor, an indoor idea (a street's classes have no \"floor\"); \
                             on a KITTI sequence start from a pose (--init local, the default: \
                             the first ground-truth pose or --init-pose)"
                        )
                    } else {
                        e
                    }
                })?
                .remove(0),
        ),
    };
    let config = SessionConfig {
        intrinsics: k,
        particles: particle_count(a, is_kitti),
        filter: filter_config(a, inputs),
        floor: FloorParams::default(),
        floor_feature,
        ground: a.ground,
    };
    if let Start::Pose { pose, .. } = &start {
        start_advice(a, &shared, pose, &config, inputs);
    }
    Session::new(shared, config, &start).map_err(|e| match e {
        SessionError::Init(e) => match &a.prompt {
            Some(words) if matches!(a.init, InitArg::Prompt) => {
                init_advice(e).context(format!("prompt {words:?}"))
            }
            _ => init_advice(e),
        },
        SessionError::Recovery(e) => {
            init_advice(e).context("--recovery injects poses over the floor")
        }
        e => e.into(),
    })
}

/// Warnings about a start pose that cannot be right: `--init-pose` far
/// from the sequence's own first ground-truth pose, or a start from which
/// the camera sees almost none of the map (outside it, or in another
/// frame: every ray misses, all particles score alike, and the run goes
/// nowhere while looking confident), or on a KITTI sequence a map its
/// first LiDAR scan does not fit there (another drive's map). Advice only;
/// the run goes on.
fn start_advice(
    a: &LocalizeArgs,
    shared: &SharedMap,
    pose: &Pose,
    config: &SessionConfig,
    inputs: &CameraSequence,
) {
    let (gt, is_kitti) = (inputs.ground_truth.as_ref(), inputs.kitti.is_some());
    let frame = match (is_kitti, a.init_pose_frame) {
        (true, PoseFrameArg::Map) => {
            "camera 2 in the map's frame, the first scan's LiDAR's (--init-pose-frame poses \
             takes camera 0 as poses.txt gives it)"
        }
        (true, PoseFrameArg::Poses) => "camera 0 in poses.txt's frame",
        (false, _) => "the camera in the map's frame",
    };
    if let (Some(_), Some(g)) = (&a.init_pose, gt) {
        let first = &g.poses()[0];
        let d = (pose.translation.vector - first.translation.vector).norm();
        let angle = (pose.rotation.inverse() * first.rotation)
            .angle()
            .to_degrees();
        if d > 1.0 || angle > 10.0 {
            eprintln!(
                "warning: --init-pose is {d:.2} m and {angle:.1} degrees from the sequence's \
                 first ground-truth pose; is it {frame}? (without --init-pose the run starts \
                 around the ground truth)"
            );
        }
    }
    let blind = omcl::session::blind_start(shared, pose, config);
    // A floor plan has no view to measure: a start off the map's extent
    // is said by its place (it had been taken without a word).
    if blind.is_none()
        && shared.is_level()
        && let Some((lo, hi)) = shared.map().world_bounds()
    {
        let t = pose.translation.vector;
        let margin = 1.0;
        if t.x < lo[0] - margin
            || t.x > hi[0] + margin
            || t.y < lo[1] - margin
            || t.y > hi[1] + margin
        {
            eprintln!(
                "warning: {}: the start (x {:.2}, y {:.2} m) lies outside the map's extent \
                 (x {:.1} to {:.1}, y {:.1} to {:.1} m); is the pose {frame}?",
                if a.init_pose.is_some() {
                    "--init-pose"
                } else {
                    "the first ground-truth pose"
                },
                t.x,
                t.y,
                lo[0],
                hi[0],
                lo[1],
                hi[1]
            );
        }
    }
    if let Some(b) = blind {
        let source = if a.init_pose.is_some() {
            "--init-pose"
        } else {
            "the first ground-truth pose"
        };
        eprintln!(
            "warning: {source}: {b}; every ray that misses scores alike, so the filter cannot \
             find the camera. Is the pose {frame}?"
        );
    } else if let Some(fit) = match shared.is_level() {
        // A floor plan has no 3-D voxels to meet.
        true => None,
        // The camera never uses the scan: one that cannot be read skips
        // the check, not the run.
        false => inputs
            .first_scan_fit(shared.map(), pose)
            .unwrap_or_else(|e| {
                eprintln!("note: the map was not checked against the first LiDAR scan: {e}");
                None
            }),
    } && fit.misfit()
    {
        let (source, question) = match a.init_pose {
            Some(_) => ("--init-pose", format!(", and is the pose {frame}")),
            None => ("the first ground-truth pose", String::new()),
        };
        eprintln!(
            "warning: the first LiDAR scan (velodyne/000000.bin) placed at {source}: {:.0} % \
             of its {} points {} m and more above the road lie in or next to the map's voxels \
             ({:.1} m nodes); in a map of this drive it is 90 % and more at the scan's true \
             pose, over half within a metre or five degrees of it. Is {} this sequence's \
             map{question}?",
            100.0 * fit.share,
            fit.points,
            omcl::session::scan_fit::FIT_ABOVE_GROUND_M,
            fit.cell_m,
            a.map.display(),
        );
    }
}

/// The estimates, the `--diagnostics` CSV, and the filter's and the
/// input's total seconds (reading frames, running the image encoder).
fn diagnostics(frames: &[LocalizedFrame]) -> (Vec<Pose>, String, f64, f64) {
    let mut estimates = Vec::with_capacity(frames.len());
    let mut diag = String::from(
        "frame,ess,spread_m,mean_likelihood,confidence,particles,rays,step_ms,input_ms\n",
    );
    let (mut filter_s, mut input_s) = (0.0f64, 0.0f64);
    for (i, f) in frames.iter().enumerate() {
        let report = &f.report.step;
        let t = &report.timings;
        let step = (t.features + t.predict + t.weigh + t.update).as_secs_f64();
        filter_s += step;
        input_s += f.input_seconds;
        diag.push_str(&format!(
            "{i},{:.1},{:.4},{:.4},{:.3},{},{},{:.1},{:.1}\n",
            report.ess,
            report.spread,
            report.mean_likelihood,
            report.confidence,
            report.n_particles,
            report.n_rays,
            1e3 * step,
            1e3 * f.input_seconds
        ));
        estimates.push(report.estimate);
    }
    (estimates, diag, filter_s, input_s)
}

pub fn run(a: LocalizeArgs) -> anyhow::Result<()> {
    if let Some(e) = a.expand.filter(|&e| e > 1) {
        let base = a.filter.preset().and_then(|p| p.config().anneal);
        ensure!(
            anneal(&a, base).is_some(),
            "--expand {e} needs --layers 2 or more (the copies are the first of several layers)"
        );
    }
    check_plan_and_ground_args(&a)?;
    check_options_apply(&a)?;
    refuse_replacing_inputs(&a)?;
    let map3 = map::load(&a.map)?;
    ensure!(
        !map3.is_empty(),
        "{}: the map has no voxels: there is nothing to localize against",
        a.map.display()
    );
    let m = &map3;
    let d = &a.sequence;
    let mut image = super::encoders::open_image_source(&a.encoder)?;
    // Two colour-class encoders are two feature spaces of the same
    // dimension: a map of one localized with the other ran to a wrong
    // answer (0.48 m where the right model gave 0.05 m).
    if let Some(src) = &image {
        let prefix = omcl::experiment::sevenscenes::COLOUR_MODEL_PREFIX;
        ensure!(
            !(src.name.starts_with(prefix)
                && m.encoder().starts_with(prefix)
                && src.name != m.encoder()),
            "{}: the map is in the features of the colour model `{}`, --image-model gives \
             `{}` (another fit): localize with the model the map was built with",
            a.map.display(),
            m.encoder(),
            src.name
        );
    }
    let pick = FramePick {
        step: a.frame_step,
        offset: a.frame_offset,
        limit: None,
    };
    ensure!(
        image.is_some() || Layout::of(d) != Layout::SevenScenes,
        "{}: a 7-Scenes folder gives colour images only: pass --image-model (e.g. the \
         colour classes of `omcl encode colour-model`)",
        d.display()
    );
    let inputs = CameraSequence::open(d, camera_input(&a, image.is_some()), pick)?;
    if let Some((k, n)) = (inputs.kitti.as_ref())
        .and_then(|k| Some((k, k.poses_in_file?)))
        .filter(|(k, n)| k.len() < *n)
    {
        eprintln!(
            "note: {} holds the sequence's first {} frames, of {n} poses in poses.txt: those \
             frames are localized",
            d.join(k.input.folder()).display(),
            k.len(),
        );
    }
    let gt = inputs.ground_truth.clone();
    check_truth_given(&a, &inputs)?;
    let classes = &inputs.classes;
    if let Some(src) = &image {
        ensure!(
            src.dim() == m.db().dim(),
            "image encoder {} gives {}-d features, the map {} has {}",
            src.name,
            src.dim(),
            a.map.display(),
            m.db().dim()
        );
    }
    ensure!(
        a.floorplan.is_none() || inputs.layout() != Layout::Kitti,
        "{}: --floorplan localizes an indoor camera under a ceiling; a KITTI sequence \
         localizes in the 3-D map (leave --floorplan out)",
        d.display()
    );
    ensure!(
        !a.ground || inputs.layout() != Layout::Kitti,
        "{}: --ground holds the camera at its start's height, and KITTI streets climb (leave \
         --ground out; the road motion follows them)",
        d.display()
    );
    let table = class_table(&a, &inputs, image.is_some(), m)?;
    let words = Words::new(&a, table.as_ref(), classes, m.db().dim())?;
    let source = odometry_source(&a, &inputs)?;
    let read = inputs.odometry(&source)?;
    let n = inputs
        .frames(read.poses.len(), a.frames)
        .map_err(|e| match &source {
            // Which file gave too few poses, and from where it was read.
            Odometry::File { path, first } => anyhow::Error::new(e).context(format!(
                "{} (read from its pose {first}, --odom-first)",
                path.display()
            )),
            Odometry::FromTruth(_) => anyhow::Error::new(e),
        })?;
    let frames_input = match (image.is_some(), table.is_some() && !a.use_features) {
        (true, _) => CameraInput::Images,
        (false, true) => CameraInput::Labels,
        (false, false) => CameraInput::Features,
    };
    ensure!(
        frames_input != CameraInput::Features
            || inputs.layout() != Layout::Rgbd
            || inputs.features_dir.is_dir()
            || (a.use_features && inputs.labels_dir.is_dir()),
        "{}: {}",
        d.display(),
        omcl::session::sequence::NO_FRAMES
    );
    // An RGB-D folder of more frames than its poses: a short poses.txt
    // (the run had localized the first frames only, without a word).
    if a.frames.is_none()
        && let Some(stored) = inputs.stored_frames(frames_input)?
        && stored > n
    {
        bail!(
            "{}: {} frames in {}, but poses for {n} (poses.txt, or the odometry); pass \
             --frames {n} to localize the first {n}, or complete the poses",
            d.display(),
            stored,
            inputs.input_folder(frames_input).display()
        );
    }
    inputs.check_frames(n, frames_input)?;
    for r in inputs.odometry_remarks(&source, &read, n) {
        eprintln!("note: {r}");
    }
    if inputs.kitti.as_ref().is_some_and(|k| !k.times_in_file) {
        eprintln!(
            "note: {} has no times.txt: frames are stamped 0.1 s apart (KITTI's 10 Hz)",
            d.display()
        );
    }

    // The session's map: the 3-D map with its Embree scene, or (with
    // --floorplan) the floor plan's sighted map with its planar caster, the
    // label table bound to it, and the 3-D map kept for the plot.
    let mut baseline = None;
    let (shared, plan_table, map3) = match &a.floorplan {
        Some(plan) => {
            let map3 = Arc::new(map3);
            let scene = plan_scene(&a, plan.as_deref(), &map3, &words)?;
            let shared = SharedMap::floor_plan("floor plan", scene).with_floor_map(map3.clone());
            if let (Some(b), Some(on)) = (a.baseline, shared.baseline_map()) {
                baseline = Some(open_baseline(&a, b, on, &inputs, &words, n)?);
            }
            let t = table
                .as_ref()
                .map(|t| LabelTable::new(t.table().clone(), shared.map()))
                .transpose()?;
            (shared, t, Some(map3))
        }
        None => (SharedMap::new("map", map3)?, None, None),
    };
    let shared = Arc::new(shared);
    let m = map3.as_deref().unwrap_or(shared.map());
    let frames_table = plan_table.as_ref().or(table.as_ref());

    let mut session = match baseline {
        Some(b) => Err(b),
        None => Ok(open_session(&a, shared.clone(), &inputs, &words)?),
    };
    match &session {
        Ok(_) => print_setup(&a, &inputs),
        Err(b) => print_baseline_setup(&a, &inputs, b),
    }
    let stamps = inputs.stamps(n);
    let mut source = match (image.as_mut(), frames_table) {
        (Some(src), _) => FrameSource::Images(src),
        (None, Some(t)) if !a.use_features => FrameSource::Labels(t),
        _ => FrameSource::Features,
    };
    let pb = super::progress::bar(n as u64, "localizing");
    let frames = match &mut session {
        Ok(session) => sequence::localize(
            session,
            &inputs,
            &mut source,
            &read.poses[..n],
            &stamps,
            &mut |_| pb.inc(1),
        )?,
        Err(b) => sequence::localize_baseline(
            b,
            &inputs,
            &mut source,
            &read.poses[..n],
            &stamps,
            depth_scale(&a),
            &mut |_| pb.inc(1),
        )?,
    };
    super::progress::finish(&pb);
    let (estimates, diag, filter_s, input_s) = diagnostics(&frames);
    let est = Trajectory::new(stamps.clone(), estimates)?;
    // On a floor plan the translation errors are horizontal, as printed.
    let horizontal = a.floorplan.is_some();
    let metric = gt
        .as_ref()
        .map(|g| {
            let (g, e) = match horizontal {
                true => (g.horizontal(), est.horizontal()),
                false => (g.clone(), est.clone()),
            };
            omcl::eval::outdoor_metric(&g.poses()[..n], e.poses())
        })
        .transpose()?;
    // Every output is made in memory first, then written: a failure
    // leaves nothing half-written behind.
    match &inputs.kitti {
        Some(seq) => poses::write_poses(
            &a.out,
            &Trajectory::new(stamps, seq.camera0_in_kitti(est.poses()))?,
            PoseFormat::Kitti,
        )?,
        None => poses::write_poses(&a.out, &est, PoseFormat::Tum)?,
    }
    if let Some(p) = &a.diagnostics {
        omcl::io::atomic::write(p, diag.as_bytes())
            .with_context(|| format!("writing {}", p.display()))?;
    }
    if let (Some(p), Some(mt)) = (&a.metrics, &metric) {
        let steps_per_s = n as f64 / filter_s.max(1e-12);
        write_metrics(p, d, n, mt, method_name(&a), horizontal, steps_per_s)?;
    }
    println!(
        "{:.1} filter steps/s; {:.1} frames/s with reading the frames{}",
        n as f64 / filter_s.max(1e-12),
        n as f64 / (filter_s + input_s).max(1e-12),
        if image.is_some() {
            " and the image encoder"
        } else {
            ""
        }
    );
    let frames = if n == 1 { "frame" } else { "frames" };
    print!("wrote {} ({n} {frames})", a.out.display());
    match &gt {
        Some(g) => {
            // The floor's feature colours the plot's floor plan.
            let floor = words
                .available()
                .then(|| words.features("floor", "map word").ok())
                .flatten()
                .and_then(|mut w| w.pop());
            report_against_truth(&a, g, &est, n, metric.as_ref(), floor.as_deref(), m)?
        }
        None => println!(),
    }
    Ok(())
}

/// The run's setup on standard output, before its first frame (a log
/// of an interrupted run keeps it): particles and rays, the filter, and
/// the street's defaults.
fn print_setup(a: &LocalizeArgs, inputs: &CameraSequence) {
    let is_kitti = inputs.layout() == Layout::Kitti;
    let config = filter_config(a, inputs);
    let particles = particle_count(a, is_kitti);
    println!(
        "{particles} particle{} x {} ray{} a frame{}",
        if particles == 1 { "" } else { "s" },
        config.sampling.rays,
        if config.sampling.rays == 1 { "" } else { "s" },
        match (is_kitti, a.particles.is_none() && a.rays.is_none()) {
            _ if a.filter != FilterArg::Auto && a.rays.is_none() => {
                format!(
                    " (--filter {}'s rays; --particles, --rays)",
                    filter_preset(a, is_kitti)
                )
            }
            _ if a.floorplan.is_some() && a.rays.is_none() => {
                " (Table I's 2-D block; --particles, --rays)".into()
            }
            (true, true) => " (the paper's street setting; --particles, --rays)".into(),
            (false, true) => " (the paper's indoor setting; --particles, --rays)".into(),
            _ => String::new(),
        }
    );
    println!(
        "filter {}{}: {} motion noise, likelihood exponent {} (--filter, --motion, --sharpen)",
        filter_preset(a, is_kitti),
        if a.filter == FilterArg::Auto {
            " (auto)"
        } else {
            ""
        },
        motion_name(config.motion.mode),
        config.sharpen
    );
    if a.ground {
        println!(
            "--ground: the camera held at the start's height, roll and pitch; the odometry's \
             horizontal motion and turn move it"
        );
    }
    if let Some(e) = config.sensor.early_reject {
        println!(
            "two-pass likelihoods: one pixel in {} first, the rest for particles within {:.0} % \
             of the best{}",
            e.every,
            100.0 * (1.0 - e.ratio),
            if is_kitti {
                " (the street default; --every-ray casts every pixel)"
            } else {
                ""
            }
        );
    }
    if let Some(an) = config.anneal {
        println!(
            "{} layers of progressive correction a frame (--layers){}",
            an.layers,
            if an.expand > 1 {
                format!(
                    ", the first on {} copies of each particle (--expand)",
                    an.expand
                )
            } else {
                String::new()
            }
        );
    }
    if is_kitti {
        println!(
            "rays that hit nothing score {}{}",
            config.sensor.miss_score,
            if a.miss_score.is_some() {
                " (--miss-score)"
            } else {
                " (the street default; --miss-score sets it)"
            }
        );
    }
}

/// Refuses outputs over the files a run reads (the map, the plan, the
/// odometry, the sequence's ground truth, calibration and class table) or
/// over each other, before anything is read.
fn refuse_replacing_inputs(a: &LocalizeArgs) -> anyhow::Result<()> {
    let mut outputs = vec![("--out", a.out.as_path())];
    for (option, p) in [
        ("--metrics", &a.metrics),
        ("--plot", &a.plot),
        ("--diagnostics", &a.diagnostics),
    ] {
        outputs.extend(p.as_deref().map(|p| (option, p)));
    }
    let files = super::outputs::sequence_files(&a.sequence);
    let mut inputs = vec![("the map".to_string(), a.map.clone())];
    inputs.extend(
        a.floorplan
            .iter()
            .flatten()
            .map(|p| ("the floor plan".to_string(), p.clone())),
    );
    inputs.extend(a.odometry.clone().map(|p| ("the odometry".to_string(), p)));
    for d in a.baseline_classes.iter() {
        for f in ["classes.txt", "embeddings.npy"] {
            inputs.push((format!("--baseline-classes' {f}"), d.join(f)));
        }
    }
    inputs.extend(
        files
            .into_iter()
            .map(|p| (super::outputs::SEQUENCE_FILE.to_string(), p)),
    );
    inputs.extend(a.encoder.inputs());
    inputs.extend(super::outputs::model_files(
        "--text-model",
        a.text_model.as_deref(),
    ));
    super::outputs::refuse_overlaps(&outputs, &inputs)?;
    super::outputs::refuse_inside_sequence(&outputs, &a.sequence)?;
    if let Some(cache) = &a.encoder.feature_cache {
        super::outputs::refuse_folder_in_sequence("--feature-cache", cache, &a.sequence)?;
    }
    let text: Vec<(&str, &Path)> = outputs
        .iter()
        .copied()
        .filter(|(option, _)| *option != "--plot")
        .collect();
    super::outputs::refuse_replacing_data(&text)?;
    super::outputs::refuse_unwritable(&outputs, &["--plot"])?;
    use super::outputs::TextOutput;
    for (option, p) in outputs {
        let kind = match option {
            "--metrics" => TextOutput::Metrics,
            "--diagnostics" => TextOutput::Diagnostics,
            "--plot" => {
                super::outputs::refuse_replacing_figure(option, p, a.force)?;
                continue;
            }
            _ => TextOutput::Trajectory,
        };
        super::outputs::refuse_replacing_unlike(option, p, kind, a.force)?;
    }
    Ok(())
}

/// `--floorplan`'s and `--ground`'s limits, by name: planar motion.
fn check_plan_and_ground_args(a: &LocalizeArgs) -> anyhow::Result<()> {
    ensure!(
        a.prompt.is_none() || a.init == InitArg::Prompt,
        "--prompt gives the words of --init prompt (now --init {}); add --init prompt",
        format!("{:?}", a.init).to_lowercase()
    );
    // The option that asks for motion other than planar, if one does.
    let non_planar = match a.motion {
        Some(MotionArg::Planar) => None,
        Some(m) => Some(format!("--motion {}", format!("{m:?}").to_lowercase())),
        None => a
            .filter
            .preset()
            .filter(|p| p.config().motion.mode != MotionMode::Planar)
            .map(|p| format!("--filter {p}, whose motion is not planar")),
    };
    if let Some(what) = &non_planar {
        ensure!(
            !a.ground,
            "--ground holds the camera's height, roll and pitch: it takes --motion planar only \
             ({what})"
        );
        ensure!(
            a.floorplan.is_none(),
            "--floorplan estimates x, y and yaw: it takes --motion planar only ({what})"
        );
    }
    Ok(())
}

/// The floor-plan scene of `--floorplan`: the plan file `plan` checked
/// against `map3` (the map it must have been made from), or `map3`
/// projected with the default band; its sighted map and planar caster,
/// with the words "floor" and "ceiling" when `words` has them.
fn plan_scene(
    a: &LocalizeArgs,
    plan: Option<&Path>,
    map3: &omcl::map::LanguageMap,
    words: &Words,
) -> anyhow::Result<PlanScene> {
    let exits = words
        .available()
        .then(|| words.features(&EXIT_WORDS.join(","), "map word"))
        .transpose()
        .unwrap_or_else(|e| {
            eprintln!("note: {e:#}");
            None
        });
    if exits.is_none() {
        eprintln!(
            "note: no features of \"floor\" and \"ceiling\" (--text-model, or a class table \
             with both): rays leaving the plan's height window score only the columns' own \
             floors and ceilings"
        );
    }
    let rows = exits.as_ref().map(|f| [f[0].as_slice(), f[1].as_slice()]);
    let file = plan.map(map::floorplan::load).transpose()?;
    let scene = PlanScene::for_map(map3, file, rows).with_context(|| match plan {
        Some(p) => format!("{} with the map {}", p.display(), a.map.display()),
        None => format!("the floor plan of {}", a.map.display()),
    })?;
    let band = scene.plan.params;
    println!(
        "floor plan: {} columns of {} m, {} feature rows, band {:.2} to {:.2} m above the floor{}",
        scene.plan.len(),
        scene.plan.resolution,
        scene.plan.db().len(),
        band.band_min,
        band.band_max,
        match plan {
            Some(p) => format!(" ({})", p.display()),
            None => String::new(),
        }
    );
    Ok(scene)
}

/// `--baseline b`'s session on `scene` for `n` frames: the sequence's
/// class table labels the plan's columns and the pixels; the start,
/// particles and filter are the OMCL run's, the pixels 2048 unless --rays.
fn open_baseline(
    a: &LocalizeArgs,
    b: BaselineArg,
    scene: &BaselineMap,
    inputs: &CameraSequence,
    words: &Words,
    n: usize,
) -> anyhow::Result<BaselineSession> {
    let name = b.label();
    ensure!(
        a.depth_scale.is_none() || inputs.sevenscenes.is_none(),
        "--depth-scale: {} is a 7-Scenes folder, whose depth images are read in millimetres; \
         leave --depth-scale out",
        inputs.dir.display()
    );
    let (list, npy, whose) = match &a.baseline_classes {
        Some(d) => (
            d.join("classes.txt"),
            d.join("embeddings.npy"),
            "--baseline-classes",
        ),
        None => (
            inputs.classes.clone(),
            inputs.embeddings.clone(),
            "the sequence's class table",
        ),
    };
    let classes = EmbeddingTable::read(&list, &npy).with_context(|| {
        format!(
            "--baseline: {name} labels the floor plan's columns and the pixels by class, from \
             {whose} ({} and {}; --baseline-classes DIR names another)",
            list.display(),
            npy.display()
        )
    })?;
    if let Some(scale) = depth_scale(a)
        && inputs.sevenscenes.is_none()
    {
        // Every frame's depth image is there (not found at frame 17).
        let png = |i: usize| inputs.dir.join("depth").join(format!("{i:06}.png"));
        if let Some(i) = (0..n).find(|&i| !png(i).is_file()) {
            bail!(
                "--baseline simp places each pixel at its depth: {} is missing (the run \
                 localizes {n} frames; --frames N localizes fewer; --baseline sedar needs no \
                 depth)",
                png(i).display()
            );
        }
        // The first depth image read as the run will read them: a scale
        // that makes a room kilometres deep, or millimetres, is named.
        let d = inputs.read_depth(0, scale)?;
        if let Some(doubt) = rgbd::depth_scale_doubt(&d.depth, scale) {
            eprintln!("note: {}: {doubt}", png(0).display());
        }
    }
    let start = start(a, inputs.ground_truth.as_ref(), words, None)?;
    if let Start::Pose { pose, .. } = &start {
        let tilt = ground::tilt_deg(pose);
        if tilt > 2.0 {
            eprintln!(
                "note: the start pose is {tilt:.1} degrees from level; on a floor plan the \
                 camera is held level at its height, and {name} places its pixels from a level \
                 camera"
            );
        }
    }
    let config = SessionConfig {
        intrinsics: inputs.intrinsics,
        particles: particle_count(a, false),
        filter: filter_config(a, inputs),
        floor: FloorParams::default(),
        floor_feature: None,
        ground: false,
    };
    let params = baseline_params(a);
    BaselineSession::new(scene, &classes, b.baseline(), params, &config, &start).with_context(
        || {
            format!(
                "--baseline {name} with {} and {}",
                list.display(),
                npy.display()
            )
        },
    )
}

/// The baselines' parameters with the run's pixel count and depth range.
fn baseline_params(a: &LocalizeArgs) -> BaselineParams {
    let defaults = BaselineParams::default();
    BaselineParams {
        pixels: a.rays.unwrap_or(defaults.pixels),
        max_depth: a.max_depth,
        ..defaults
    }
}

/// The depth scale `--baseline simp` reads depth images with (`None`:
/// the run reads none).
fn depth_scale(a: &LocalizeArgs) -> Option<f64> {
    (a.baseline == Some(BaselineArg::Simp))
        .then(|| a.depth_scale.unwrap_or(rgbd::TUM_DEPTH_UNITS_PER_METRE))
}

/// A baseline run's setup on standard output, before its first frame.
fn print_baseline_setup(a: &LocalizeArgs, inputs: &CameraSequence, session: &BaselineSession) {
    let params = baseline_params(a);
    let pixels = params.pixels;
    println!(
        "{} particle{} x {pixels} pixel{} a frame{}",
        session.particles().len(),
        if session.particles().len() == 1 {
            ""
        } else {
            "s"
        },
        if pixels == 1 { "" } else { "s" },
        if a.rays.is_none() {
            " (Table I's baselines; --particles, --rays)"
        } else {
            ""
        }
    );
    println!(
        "baseline {}: {} on the floor plan, planar motion noise, beams {}, z_rand {}",
        a.baseline.map_or("", BaselineArg::label),
        match a.baseline {
            Some(BaselineArg::Simp) => format!(
                "each pixel at its depth ({}{}) against the nearest column of its class, sigma {} \
                 m",
                match inputs.layout() {
                    Layout::SevenScenes => "7-Scenes' depth images, millimetres".to_string(),
                    _ => format!(
                        "depth/, --depth-scale {}",
                        depth_scale(a).unwrap_or_default()
                    ),
                },
                params
                    .max_depth
                    .map_or(String::new(), |m| format!(", at most {m} m deep")),
                params.sigma
            ),
            _ => "each pixel's planar ray against the class of the column it reaches".into(),
        },
        params.beams,
        params.z_rand
    );
}

/// What the camera gives: images through --encoder, else label images
/// when the sequence has them (and --use-features is not given), else
/// feature files.
fn camera_input(a: &LocalizeArgs, has_encoder: bool) -> CameraInput {
    if has_encoder {
        CameraInput::Images
    } else if a.use_features || !a.sequence.join(CameraInput::Labels.folder()).is_dir() {
        CameraInput::Features
    } else {
        CameraInput::Labels
    }
}

/// --plot and --metrics need the sequence's ground truth.
fn check_truth_given(a: &LocalizeArgs, inputs: &CameraSequence) -> anyhow::Result<()> {
    let gt_path = &inputs.ground_truth_path;
    let has_gt = inputs.ground_truth.is_some();
    ensure!(
        a.plot.is_none() || has_gt,
        "--plot needs ground truth: {} is missing",
        gt_path.display()
    );
    ensure!(
        a.metrics.is_none() || has_gt,
        "--metrics needs ground truth: {} is missing",
        gt_path.display()
    );
    Ok(())
}
