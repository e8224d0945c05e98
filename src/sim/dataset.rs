//! Whole datasets: generate a world, render a sequence along a path and
//! write it in a real dataset's layout (see [`super::files`] for the
//! layouts). The glue between the algorithms and the writers; the demo and
//! the CLI call these.

use crate::io::poses::PoseFormat;
use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

use super::embeddings::ClassEmbeddings;
use super::features::{FeatureModel, Preset};
use super::files::{self, SimIoError};
use super::indoor::{self, INDOOR_CLASSES, IndoorConfig, IndoorWorld, WorldKind};
use super::lidar::{self, LidarConfig};
use super::outdoor::{self, OUTDOOR_CLASSES, OutdoorConfig, SEMANTIC_KITTI_IDS};
use super::paths::{self, IndoorPathConfig, OdometryConfig};
use super::render::{self, Frame, NO_LABEL};
use super::world::VoxelWorld;
use crate::geometry::{Intrinsics, Pose};
use crate::io::kitti::{KITTI_IMAGE_SIZE, KittiCamera, parse_calib};
use crate::raycast::{EmbreeCaster, EmbreeError};

/// Errors of dataset generation.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error(transparent)]
    Io(#[from] SimIoError),
    #[error("ray caster: {0}")]
    Caster(#[from] EmbreeError),
    #[error("embedding table: {0}")]
    Embedding(#[from] super::embeddings::EmbeddingError),
    #[error("{0}")]
    Config(String),
}

/// Everything that decides an indoor dataset.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IndoorDatasetConfig {
    /// Master seed; world, path, odometry and features use seed-derived streams.
    pub seed: u64,
    pub world: IndoorConfig,
    pub path: IndoorPathConfig,
    pub odometry: OdometryConfig,
    /// Image size, pixels, and horizontal field of view, degrees.
    pub width: u32,
    pub height: u32,
    pub hfov_deg: f64,
    /// Feature model preset of the written features.
    pub preset: Preset,
    /// Write per-frame feature `.npy` files (large: H/s x W/s x 512 f32).
    pub features: bool,
    /// Pixel stride of the written features.
    pub feature_stride: u32,
}

impl IndoorDatasetConfig {
    /// The defaults (paper's VLMaps camera: 540 x 540, 90 degrees) for
    /// `seed` in the corridor apartment.
    pub fn new(seed: u64) -> Self {
        Self::of_kind(WorldKind::Corridor, seed)
    }

    /// The defaults for `seed` in a world of `kind`.
    pub fn of_kind(kind: WorldKind, seed: u64) -> Self {
        IndoorDatasetConfig {
            seed,
            world: IndoorConfig::of_kind(kind, seed),
            path: IndoorPathConfig {
                seed: seed.wrapping_add(1),
                ..Default::default()
            },
            odometry: OdometryConfig {
                seed: seed.wrapping_add(2),
                ..Default::default()
            },
            width: 540,
            height: 540,
            hfov_deg: 90.0,
            preset: Preset::LsegLike,
            features: false,
            feature_stride: 8,
        }
    }

    /// The camera intrinsics.
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics::from_hfov(self.width, self.height, self.hfov_deg)
    }
}

/// What a generation run produced.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Summary {
    /// The folder written (not in `sim.json`: a folder may be moved).
    #[serde(skip)]
    pub dir: PathBuf,
    pub frames: usize,
    pub cells: usize,
    pub classes: usize,
    pub seconds: f64,
    /// Mean motion per frame: metres and degrees.
    pub mean_step_m: f64,
    pub mean_turn_deg: f64,
    /// Where the odometry drift came from, if any.
    pub drift_source: Option<String>,
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {} frames, {} voxels, {} classes, {:.3} m / {:.1} deg per frame, drift {}, {:.1} s",
            self.dir.display(),
            self.frames,
            self.cells,
            self.classes,
            self.mean_step_m,
            self.mean_turn_deg,
            self.drift_source.as_deref().unwrap_or("none"),
            self.seconds
        )
    }
}

/// An indoor world with its path and the caster that renders it.
pub struct IndoorScene {
    pub world: IndoorWorld,
    pub poses: Vec<Pose>,
    pub caster: EmbreeCaster,
}

/// Generates the world and path of `cfg` and builds the Embree caster.
pub fn indoor_scene(cfg: &IndoorDatasetConfig) -> Result<IndoorScene, SimError> {
    let world = indoor::generate(&cfg.world);
    let poses = paths::indoor_path(&world.layout, &cfg.path);
    let caster = EmbreeCaster::new(world.voxels.resolution as f32, &world.voxels.cells)?;
    Ok(IndoorScene {
        world,
        poses,
        caster,
    })
}

/// Relative-motion errors of a real estimate (KITTI 00 ORB-SLAM2 against its
/// ground truth) found in `trajectories`, with a description of the source.
pub fn load_drift(trajectories: &Path) -> Result<(Vec<Pose>, String), SimError> {
    let gt = files::read_kitti_poses(&trajectories.join("KITTI_00_gt.txt"))?;
    let est = files::read_kitti_poses(&trajectories.join("KITTI_00_ORB.txt"))?;
    Ok((
        paths::drift_errors(&gt, &est),
        "KITTI 00 ORB-SLAM2 vs ground truth".into(),
    ))
}

/// The `generator` of an indoor simulation's `sim.json`: with
/// [`OUTDOOR_GENERATOR`] and [`EXPORT_GENERATOR`], what marks a folder as
/// omcl's simulation (which `omcl sim --force` may replace).
pub const INDOOR_GENERATOR: &str = "omcl sim indoor";

/// The `generator` of an outdoor simulation's `sim.json`.
pub const OUTDOOR_GENERATOR: &str = "omcl sim outdoor";

/// The `generator` of a sequence `omcl bench table1-sixdof
/// --export-frames` writes (the indoor layout).
pub const EXPORT_GENERATOR: &str = "omcl bench table1-sixdof --export-frames";

/// What [`write_indoor`] writes into its folder: the sequence's frame
/// folders and files, the world and `sim.json` (which marks a folder as a
/// simulation's).
pub const INDOOR_ENTRIES: [&str; 11] = [
    "rgb",
    "depth",
    "labels",
    "features",
    "intrinsics.txt",
    "poses.txt",
    "odometry.txt",
    "classes.txt",
    "embeddings.npy",
    "world",
    "sim.json",
];

/// What [`write_outdoor`] writes into its folder: `sequences/` (the KITTI
/// layout), the class tables, the world and `sim.json`.
pub const OUTDOOR_ENTRIES: [&str; 6] = [
    "sequences",
    "classes.txt",
    "embeddings.npy",
    "semantickitti_ids.txt",
    "world",
    "sim.json",
];

/// Generates an indoor dataset into `dir` (created if missing). `table`
/// must know every indoor class; `drift` are relative-motion errors to
/// replay in the odometry (may be empty). `progress` is called with the
/// number of frames written so far.
pub fn write_indoor(
    dir: &Path,
    cfg: &IndoorDatasetConfig,
    table: &ClassEmbeddings,
    drift: (&[Pose], Option<String>),
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Summary, SimError> {
    let start = Instant::now();
    if cfg.width == 0 || cfg.height == 0 || !(cfg.hfov_deg > 0.0 && cfg.hfov_deg < 180.0) {
        return Err(SimError::Config(format!(
            "image {}x{} with {} degrees field of view: need a positive size and 0 < fov < 180",
            cfg.width, cfg.height, cfg.hfov_deg
        )));
    }
    let table = table.subset(INDOOR_CLASSES)?;
    let scene = indoor_scene(cfg)?;
    let k = cfg.intrinsics();
    let odo = paths::odometry(&scene.poses, drift.0, &cfg.odometry);
    files::write_world(&dir.join("world"), &scene.world.voxels)?;
    let model = cfg
        .features
        .then(|| FeatureModel::preset(table.clone(), cfg.preset, cfg.seed.wrapping_add(3)));
    let out = RgbdSequenceOut {
        intrinsics: k,
        poses: &scene.poses,
        odometry: &odo,
        table: &table,
        features: model.as_ref().map(|m| (m, cfg.feature_stride)),
    };
    let render =
        |i: usize| render::render_frame(&scene.caster, &scene.world.voxels, &k, &scene.poses[i]);
    write_rgbd_sequence(dir, &out, &render, progress)?;
    let (mean_step_m, mean_turn_deg) = paths::mean_motion(&scene.poses);
    let summary = Summary {
        dir: dir.to_path_buf(),
        frames: scene.poses.len(),
        cells: scene.world.voxels.cells.len(),
        classes: table.len(),
        seconds: start.elapsed().as_secs_f64(),
        mean_step_m,
        mean_turn_deg,
        drift_source: if drift.0.is_empty() { None } else { drift.1 },
    };
    let meta = serde_json::json!({
        "generator": INDOOR_GENERATOR,
        "version": env!("CARGO_PKG_VERSION"),
        "config": cfg,
        "layout": scene.world.layout,
        "intrinsics": k,
        "depth_scale": 5000.0,
        "no_label": NO_LABEL,
        "summary": summary,
    });
    files::write_json(&dir.join("sim.json"), &meta)?;
    Ok(summary)
}

/// A rendered indoor sequence to write in the RGB-D layout of
/// [`super::files`] (`omcl sim indoor`).
pub struct RgbdSequenceOut<'a> {
    pub intrinsics: Intrinsics,
    /// Ground-truth `world_from_camera` of every frame (`poses.txt`).
    pub poses: &'a [Pose],
    /// Odometry poses, one a frame (`odometry.txt`).
    pub odometry: &'a [Pose],
    /// Class names and embeddings (`classes.txt`, `embeddings.npy`); the
    /// label images hold row indices of this table.
    pub table: &'a ClassEmbeddings,
    /// Also write each frame's feature `.npy` from this model at this pixel
    /// stride.
    pub features: Option<(&'a FeatureModel, u32)>,
}

/// Writes `seq` into `dir` (created if missing): `intrinsics.txt`,
/// `poses.txt`, `odometry.txt`, `classes.txt`, `embeddings.npy` and each
/// frame's `rgb/`, `depth/` and `labels/` images (and `features/`), frame
/// `i` being `render(i)`. Not `world/` nor `sim.json`, which say where the
/// sequence came from. Frames are rendered a batch at a time (each frame's
/// rays in parallel) and each batch is encoded and written in parallel;
/// `progress` is called with the number of frames written so far.
pub fn write_rgbd_sequence(
    dir: &Path,
    seq: &RgbdSequenceOut,
    render: &dyn Fn(usize) -> Frame,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<(), SimError> {
    if seq.odometry.len() != seq.poses.len() {
        return Err(SimError::Config(format!(
            "{} odometry poses for {} frames",
            seq.odometry.len(),
            seq.poses.len()
        )));
    }
    for sub in ["rgb", "depth", "labels"] {
        files::create_dir(&dir.join(sub))?;
    }
    if seq.features.is_some() {
        files::create_dir(&dir.join("features"))?;
    }
    files::write_atomic(
        &dir.join("intrinsics.txt"),
        files::intrinsics_line(&seq.intrinsics).as_bytes(),
    )?;
    files::write_atomic(
        &dir.join("poses.txt"),
        files::pose_lines(seq.poses, PoseFormat::Tum, 30.0).as_bytes(),
    )?;
    files::write_atomic(
        &dir.join("odometry.txt"),
        files::pose_lines(seq.odometry, PoseFormat::Tum, 30.0).as_bytes(),
    )?;
    files::save_table(dir, seq.table)?;
    let batch = 8;
    let done = std::sync::atomic::AtomicUsize::new(0);
    for chunk_start in (0..seq.poses.len()).step_by(batch) {
        let end = (chunk_start + batch).min(seq.poses.len());
        let frames: Vec<Frame> = (chunk_start..end).map(render).collect();
        frames
            .par_iter()
            .enumerate()
            .try_for_each(|(j, f)| -> Result<(), SimError> {
                let i = chunk_start + j;
                write_indoor_frame(dir, i, f, seq.features)?;
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(n);
                Ok(())
            })?;
    }
    Ok(())
}

fn write_indoor_frame(
    dir: &Path,
    i: usize,
    f: &Frame,
    features: Option<(&FeatureModel, u32)>,
) -> Result<(), SimError> {
    let name = format!("{i:06}");
    let rgb = render::rgb_image(f, &render::class_colour);
    files::write_png_rgb(
        &dir.join("rgb").join(format!("{name}.png")),
        f.width,
        f.height,
        &rgb,
    )?;
    let depth: Vec<u16> = f
        .depth
        .iter()
        .map(|&d| {
            let v = (d as f64 * 5000.0).round();
            if d > 0.0 && v < 65535.0 { v as u16 } else { 0 }
        })
        .collect();
    files::write_png_gray16(
        &dir.join("depth").join(format!("{name}.png")),
        f.width,
        f.height,
        &depth,
    )?;
    files::write_png_gray16(
        &dir.join("labels").join(format!("{name}.png")),
        f.width,
        f.height,
        &f.labels,
    )?;
    if let Some((m, stride)) = features {
        let (feat, w, h) = m.image_features(i as u64, f, stride);
        crate::io::npy::write_npy(
            &dir.join("features").join(format!("{name}.npy")),
            &[h as usize, w as usize, m.dim()],
            &feat,
        )
        .map_err(SimIoError::from)?;
    }
    Ok(())
}

/// KITTI odometry sequence 00's calibration (`calib.txt`): P0..P3 are the
/// rectified projection matrices of cameras 0..3, Tr maps velodyne to
/// camera-0 coordinates. Public numbers of the KITTI benchmark.
pub const KITTI00_CALIB: &str = "P0: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 0.000000000000e+00 0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 0.000000000000e+00 0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00
P1: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 -3.861448000000e+02 0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 0.000000000000e+00 0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00
P2: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 4.538225000000e+01 0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 -1.130887000000e-01 0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 3.779761000000e-03
P3: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 -3.372877000000e+02 0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 2.369057000000e+00 0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 4.915215000000e-03
Tr: 4.276802385584e-04 -9.999672484946e-01 -8.084491683471e-03 -1.198459927713e-02 -7.210626507497e-03 8.081198471645e-03 -9.999413164504e-01 -5.403984729748e-02 9.999738645903e-01 4.859485810390e-04 -7.206933692422e-03 -2.921968648686e-01
";

/// `camera0_from_velodyne` of [`KITTI00_CALIB`] (its `Tr`).
pub fn kitti00_camera_from_velodyne() -> Pose {
    use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion};
    let m = Matrix3::new(
        4.276802385584e-04,
        -9.999672484946e-01,
        -8.084491683471e-03, //
        -7.210626507497e-03,
        8.081198471645e-03,
        -9.999413164504e-01, //
        9.999738645903e-01,
        4.859485810390e-04,
        -7.206933692422e-03,
    );
    Pose::from_parts(
        Translation3::new(
            -1.198459927713e-02,
            -5.403984729748e-02,
            -2.921968648686e-01,
        ),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&m)),
    )
}

/// KITTI 00's camera 2 (1241 x 376) as [`KITTI00_CALIB`]'s `P2` gives it:
/// intrinsics and `camera0_from_camera2` (about 6 cm to the left).
pub fn kitti00_camera2() -> Result<KittiCamera, SimError> {
    let name = Path::new("<built-in KITTI 00 calib.txt>");
    let (w, h) = KITTI_IMAGE_SIZE;
    parse_calib(KITTI00_CALIB, name)
        .and_then(|c| c.camera("P2", w, h, name))
        .map_err(|e| SimError::Config(e.to_string()))
}

/// Everything that decides an outdoor dataset.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OutdoorDatasetConfig {
    pub seed: u64,
    pub world: OutdoorConfig,
    pub lidar: LidarConfig,
    /// Render camera 2: `image_2/` RGB PNGs and `labels_2/` label PNGs.
    pub images: bool,
    /// Also write per-pixel features of camera 2 (`features_2/NNNNNN.npy`,
    /// `H/s x W/s x F` f32 at stride `feature_stride`) from `preset`.
    pub features: bool,
    /// Feature model preset of the written features.
    pub preset: Preset,
    /// Pixel stride of the written features.
    pub feature_stride: u32,
}

impl OutdoorDatasetConfig {
    /// Defaults for `seed`.
    pub fn new(seed: u64) -> Self {
        OutdoorDatasetConfig {
            seed,
            world: OutdoorConfig {
                seed,
                ..Default::default()
            },
            lidar: LidarConfig::default(),
            images: true,
            features: false,
            preset: Preset::Gt,
            feature_stride: 8,
        }
    }
}

/// Label of a camera-2 pixel that sees nothing (sky): SemanticKITTI's
/// "unlabeled".
pub const CAMERA_NO_LABEL: u16 = 0;

/// Generates an outdoor dataset along `kitti_gt` (KITTI 00 ground-truth
/// camera poses) into `dir`: `dir/sequences/00/...` in the SemanticKITTI
/// layout plus classes, embeddings, world and sim.json beside it. Camera 2
/// (when `cfg.images`) gets `image_2/` (RGB), `labels_2/` (16-bit
/// SemanticKITTI ids of the voxel each pixel sees, the ids its LiDAR labels
/// use; [`CAMERA_NO_LABEL`] for sky) and, with `cfg.features`,
/// `features_2/`; the sequence folder gets the class table the labels index
/// (`classes.txt` with `<id> <name>` lines, `embeddings.npy`).
/// The outdoor dataset's files other than the frames: folders, calibration,
/// poses, times, class tables and the world.
fn write_outdoor_layout(
    dir: &Path,
    seq: &Path,
    cfg: &OutdoorDatasetConfig,
    world: &outdoor::OutdoorWorld,
    table: &ClassEmbeddings,
) -> Result<(), SimError> {
    files::create_dir(&seq.join("velodyne"))?;
    files::create_dir(&seq.join("labels"))?;
    if cfg.images {
        files::create_dir(&seq.join("image_2"))?;
        files::create_dir(&seq.join("labels_2"))?;
    }
    if cfg.images && cfg.features {
        files::create_dir(&seq.join("features_2"))?;
    }
    files::create_dir(&dir.join("world"))?;
    files::write_atomic(&seq.join("calib.txt"), KITTI00_CALIB.as_bytes())?;
    files::write_atomic(
        &seq.join("poses.txt"),
        files::pose_lines(&world.kitti_poses, PoseFormat::Kitti, 10.0).as_bytes(),
    )?;
    let times: String = (0..world.poses.len())
        .map(|i| format!("{:.6e}\n", i as f64 * 0.1))
        .collect();
    files::write_atomic(&seq.join("times.txt"), times.as_bytes())?;
    files::save_table(dir, table)?;
    let ids: String = OUTDOOR_CLASSES
        .iter()
        .zip(SEMANTIC_KITTI_IDS)
        .map(|(n, id)| format!("{id} {n}\n"))
        .collect();
    files::write_atomic(&dir.join("semantickitti_ids.txt"), ids.as_bytes())?;
    // The camera labels' table, in the sequence folder as `omcl localize`
    // reads it: SemanticKITTI ids, rows in OUTDOOR_CLASSES order.
    files::write_atomic(&seq.join("classes.txt"), ids.as_bytes())?;
    crate::io::npy::write_npy(
        &seq.join("embeddings.npy"),
        &[table.len(), table.dim],
        &table.rows,
    )
    .map_err(SimIoError::from)?;
    files::write_world(&dir.join("world"), &world.voxels)?;
    Ok(())
}

/// Frame `i`'s LiDAR scan and its point labels (SemanticKITTI ids).
fn write_scan(
    seq: &Path,
    name: &str,
    caster: &EmbreeCaster,
    voxels: &VoxelWorld,
    world_from_lidar: &Pose,
    cfg: &OutdoorDatasetConfig,
    i: usize,
) -> Result<(), SimError> {
    let pts = lidar::scan(
        caster,
        voxels,
        world_from_lidar,
        &cfg.lidar,
        cfg.seed.wrapping_add(i as u64),
    );
    let xyzr: Vec<[f32; 4]> = pts
        .iter()
        .map(|p| [p.xyz[0], p.xyz[1], p.xyz[2], p.reflectance])
        .collect();
    let labels: Vec<u32> = pts
        .iter()
        .map(|p| {
            SEMANTIC_KITTI_IDS
                .get(p.label as usize)
                .copied()
                .unwrap_or(0)
        })
        .collect();
    files::write_velodyne(&seq.join("velodyne").join(format!("{name}.bin")), &xyzr)?;
    files::write_labels(&seq.join("labels").join(format!("{name}.label")), &labels)?;
    Ok(())
}

/// What camera 2's frames are rendered with.
struct Camera2<'a> {
    caster: &'a EmbreeCaster,
    voxels: &'a VoxelWorld,
    intrinsics: &'a Intrinsics,
    model: Option<&'a FeatureModel>,
    stride: u32,
}

impl Camera2<'_> {
    /// Frame `i`'s image, label image and, with a feature model, its
    /// feature file.
    fn write_frame(
        &self,
        seq: &Path,
        name: &str,
        world_from_camera: &Pose,
        i: usize,
    ) -> Result<(), SimError> {
        let f = render::render_frame(self.caster, self.voxels, self.intrinsics, world_from_camera);
        let colour = |l: u16| render::class_colour(l + 29);
        let rgb = render::rgb_image(&f, &colour);
        files::write_png_rgb(
            &seq.join("image_2").join(format!("{name}.png")),
            f.width,
            f.height,
            &rgb,
        )?;
        files::write_png_gray16(
            &seq.join("labels_2").join(format!("{name}.png")),
            f.width,
            f.height,
            &camera_labels(&f.labels),
        )?;
        if let Some(m) = self.model {
            let (feat, w, h) = m.image_features(i as u64, &f, self.stride);
            crate::io::npy::write_npy(
                &seq.join("features_2").join(format!("{name}.npy")),
                &[h as usize, w as usize, m.dim()],
                &feat,
            )
            .map_err(SimIoError::from)?;
        }
        Ok(())
    }
}

pub fn write_outdoor(
    dir: &Path,
    cfg: &OutdoorDatasetConfig,
    kitti_gt: &[Pose],
    table: &ClassEmbeddings,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Summary, SimError> {
    let start = Instant::now();
    if kitti_gt.is_empty() {
        return Err(SimError::Config("the driving path has no poses".into()));
    }
    let table = table.subset(OUTDOOR_CLASSES)?;
    let world = outdoor::generate(&cfg.world, kitti_gt);
    let caster = EmbreeCaster::new(world.voxels.resolution as f32, &world.voxels.cells)?;
    let seq = dir.join("sequences").join("00");
    write_outdoor_layout(dir, &seq, cfg, &world, &table)?;
    let model = (cfg.images && cfg.features)
        .then(|| FeatureModel::preset(table.clone(), cfg.preset, cfg.seed.wrapping_add(3)));
    let cam_from_velo = kitti00_camera_from_velodyne();
    let cam2 = kitti00_camera2()?;
    let (k2, cam0_from_cam2) = (cam2.intrinsics, cam2.camera0_from_camera);
    let camera = Camera2 {
        caster: &caster,
        voxels: &world.voxels,
        intrinsics: &k2,
        model: model.as_ref(),
        stride: cfg.feature_stride,
    };
    let done = std::sync::atomic::AtomicUsize::new(0);
    for (i, pose) in world.poses.iter().enumerate() {
        let name = format!("{i:06}");
        write_scan(
            &seq,
            &name,
            &caster,
            &world.voxels,
            &(pose * cam_from_velo),
            cfg,
            i,
        )?;
        if cfg.images {
            camera.write_frame(&seq, &name, &(pose * cam0_from_cam2), i)?;
        }
        progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
    }
    let (mean_step_m, mean_turn_deg) = paths::mean_motion(&world.poses);
    let summary = Summary {
        dir: dir.to_path_buf(),
        frames: world.poses.len(),
        cells: world.voxels.cells.len(),
        classes: table.len(),
        seconds: start.elapsed().as_secs_f64(),
        mean_step_m,
        mean_turn_deg,
        drift_source: None,
    };
    let meta = serde_json::json!({
        "generator": OUTDOOR_GENERATOR,
        "version": env!("CARGO_PKG_VERSION"),
        "config": cfg,
        "path": "KITTI odometry 00 ground truth (CC BY-NC-SA 3.0, Geiger et al.)",
        "world_from_kitti_camera0": "x = z_cam, y = -x_cam, z = -y_cam",
        "camera_2": {
            "intrinsics": k2,
            "labels_2": "16-bit SemanticKITTI ids (sequences/00/classes.txt), 0 = sky",
            "features_2": cfg.features.then_some(cfg.preset.name()),
            "feature_stride": cfg.feature_stride,
        },
        "summary": summary,
    });
    files::write_json(&dir.join("sim.json"), &meta)?;
    Ok(summary)
}

/// World class ids of a rendered frame as SemanticKITTI ids
/// ([`SEMANTIC_KITTI_IDS`]); misses become [`CAMERA_NO_LABEL`].
pub fn camera_labels(labels: &[u16]) -> Vec<u16> {
    labels
        .iter()
        .map(|&l| {
            SEMANTIC_KITTI_IDS
                .get(l as usize)
                .map_or(CAMERA_NO_LABEL, |&id| id as u16)
        })
        .collect()
}
