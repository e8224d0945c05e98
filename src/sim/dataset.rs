//! Whole datasets: generate a world, render a sequence along a path and
//! write it in a real dataset's layout (see [`super::files`] for the
//! layouts). The glue between the algorithms and the writers; the demo and
//! the CLI call these.

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

use super::embeddings::ClassEmbeddings;
use super::features::{FeatureModel, Preset};
use super::files::{self, SimIoError};
use super::indoor::{self, INDOOR_CLASSES, IndoorConfig, IndoorWorld};
use super::paths::{self, IndoorPathConfig, OdometryConfig};
use super::render::{self, Frame, NO_LABEL};
use crate::geometry::{Intrinsics, Pose};
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
    /// The defaults (paper's VLMaps camera: 540 x 540, 90 degrees) for `seed`.
    pub fn new(seed: u64) -> Self {
        IndoorDatasetConfig {
            seed,
            world: IndoorConfig {
                seed,
                ..Default::default()
            },
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
            feature_stride: 4,
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
    for sub in ["rgb", "depth", "labels", "world"] {
        files::create_dir(&dir.join(sub))?;
    }
    if cfg.features {
        files::create_dir(&dir.join("features"))?;
    }
    files::write_atomic(
        &dir.join("intrinsics.txt"),
        files::intrinsics_line(&k).as_bytes(),
    )?;
    files::write_atomic(
        &dir.join("poses.txt"),
        files::tum_lines(&scene.poses, 30.0).as_bytes(),
    )?;
    files::write_atomic(
        &dir.join("odometry.txt"),
        files::tum_lines(&odo, 30.0).as_bytes(),
    )?;
    files::save_table(dir, &table)?;
    files::write_world(&dir.join("world"), &scene.world.voxels)?;
    let model = cfg
        .features
        .then(|| FeatureModel::preset(table.clone(), cfg.preset, cfg.seed.wrapping_add(3)));
    // Render a batch (each frame's rays in parallel), then encode and write
    // the batch's images in parallel.
    let batch = 8;
    let done = std::sync::atomic::AtomicUsize::new(0);
    for chunk_start in (0..scene.poses.len()).step_by(batch) {
        let end = (chunk_start + batch).min(scene.poses.len());
        let frames: Vec<Frame> = (chunk_start..end)
            .map(|i| render::render_frame(&scene.caster, &scene.world.voxels, &k, &scene.poses[i]))
            .collect();
        frames
            .par_iter()
            .enumerate()
            .try_for_each(|(j, f)| -> Result<(), SimError> {
                let i = chunk_start + j;
                write_indoor_frame(dir, i, f, model.as_ref(), cfg.feature_stride)?;
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(n);
                Ok(())
            })?;
    }
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
        "generator": "omcl sim indoor",
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

fn write_indoor_frame(
    dir: &Path,
    i: usize,
    f: &Frame,
    model: Option<&FeatureModel>,
    stride: u32,
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
    if let Some(m) = model {
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
