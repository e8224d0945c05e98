//! Table I's 3-D block: the full camera pose (x, y, z, roll, pitch, yaw)
//! estimated in the 3-D map.
//!
//! The benchmark's own paths keep the camera level at 1.5 m, so a 6-DoF
//! filter would have nothing to estimate in height, roll and pitch. Here
//! each sequence's path is the benchmark's with a smooth height, pitch and
//! roll motion added ([`SixDofMotion`]: +-0.15 m, +-10 and +-4 degrees by
//! default, periods of 60, 45 and 70 frames), and its odometry is
//! ground truth perturbed on all six degrees of freedom, each increment
//! `prev_from_cur` composed with Gaussian noise of 0.10 m per axis and 6
//! degrees per axis (the paper's sigmas) and accumulated, as real odometry
//! is. The filter runs with [`MotionMode::Full`] (noise on all six degrees
//! of freedom in the camera frame, the same sigmas); the start is the
//! paper's local one (0.3 m / 17 degrees in x, y and yaw around the first
//! true pose). The map is built from the benchmark's mapping path as for
//! the 3-D rows of the existing Table I; the error is the full 3-D
//! translation error, the completion rule the same.
//!
//! The paper's reference row is RTAB-Map RGB-D SLAM, which cannot be
//! installed here. In its place the block can show a geometry-only
//! frame-to-frame RGB-D odometry (Open3D, run by `tools/rgbd_odometry.py`
//! outside this crate; no map, no loop closure): [`export_block`] writes
//! the block's sequences, frames rendered by the same
//! [`SimSequence::render`] the filter is fed from, and [`odometry_row`]
//! scores the script's estimates as the filter's are scored.

use std::path::{Path, PathBuf};

use crate::sim::indoor::WorldKind;
use nalgebra::{Translation3, UnitQuaternion, Vector3};

use super::ExperimentError;
use super::features::builtin_table;
use super::mapping::BenchMap;
use super::run::RunResult;
use super::run::TrackingRow;
use super::sequence::SimSequence;
use super::table1::{
    BlockResult, FIGURE4_PANELS, Figure4Panel, PaperRow, ape_cells, block_markdown, track,
};
use super::table1_floorplan::BlockSpec;
use super::variant::Variant;
use crate::eval::ape::{PoseRelation, ape};
use crate::eval::localization::CompletionRule;
use crate::geometry::Pose;
use crate::io::poses::{PoseFormat, read_poses_in};
use crate::mcl::{FilterConfig, MotionMode};
use crate::sim::dataset::{RgbdSequenceOut, write_rgbd_sequence};
use crate::trajectory::Trajectory;

/// The motion added to the benchmark path.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SixDofMotion {
    pub height_m: f64,
    pub pitch_deg: f64,
    pub roll_deg: f64,
    /// Periods in frames of the height, pitch and roll sines.
    pub periods: [f64; 3],
    /// Odometry noise per step and axis.
    pub sigma_translation: f64,
    pub sigma_rotation_deg: f64,
}

impl Default for SixDofMotion {
    fn default() -> Self {
        SixDofMotion {
            height_m: 0.15,
            pitch_deg: 10.0,
            roll_deg: 4.0,
            periods: [60.0, 45.0, 70.0],
            sigma_translation: 0.10,
            sigma_rotation_deg: 6.0,
        }
    }
}

/// Sequence `seed` (corridor apartment) with the 6-DoF motion added to
/// its path and 6-DoF odometry noise.
pub fn sixdof_sequence(
    seed: u64,
    frames: usize,
    table: &crate::sim::embeddings::ClassEmbeddings,
    motion: &SixDofMotion,
) -> Result<SimSequence, ExperimentError> {
    sixdof_sequence_in(WorldKind::Corridor, seed, frames, table, motion)
}

/// [`sixdof_sequence`] in a world of `kind`.
pub fn sixdof_sequence_in(
    kind: WorldKind,
    seed: u64,
    frames: usize,
    table: &crate::sim::embeddings::ClassEmbeddings,
    motion: &SixDofMotion,
) -> Result<SimSequence, ExperimentError> {
    let mut seq = SimSequence::generate_in(kind, seed, frames, table)?;
    let tau = std::f64::consts::TAU;
    for (i, p) in seq.scene.poses.iter_mut().enumerate() {
        let s = |k: usize| (tau * i as f64 / motion.periods[k]).sin();
        let pitch = motion.pitch_deg.to_radians() * s(1);
        let roll = motion.roll_deg.to_radians() * s(2);
        // Camera frame: x right, y down, z forward; pitch about x, roll
        // about z.
        let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), pitch)
            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll);
        *p = Pose::from_parts(
            Translation3::from(p.translation.vector + Vector3::z() * motion.height_m * s(0)),
            p.rotation * tilt,
        );
    }
    seq.config.odometry = sixdof_odometry(seed, motion);
    seq.odometry = crate::sim::paths::odometry(seq.poses(), &[], &seq.config.odometry);
    Ok(seq)
}

/// The block's odometry noise: Gaussian on all six degrees of freedom of
/// every increment, accumulated (the first pose exact), no replayed drift.
fn sixdof_odometry(seed: u64, motion: &SixDofMotion) -> crate::sim::paths::OdometryConfig {
    crate::sim::paths::OdometryConfig {
        seed,
        sigma_t: motion.sigma_translation,
        sigma_r_deg: motion.sigma_rotation_deg,
        drift_scale: 0.0,
        all_axes: true,
    }
}

/// Tracks a 6-DoF sequence in `map` with the full motion model.
pub fn track_6dof(
    seq: &SimSequence,
    map: &BenchMap,
    variant: &Variant,
    filter: FilterConfig,
    particles: usize,
) -> Result<RunResult, ExperimentError> {
    let mut filter = filter;
    filter.motion.mode = MotionMode::Full;
    track(seq, map, variant.localize, filter, particles)
}

/// The 3-D block: per sequence, each variant's map is built (from the
/// level mapping path) and the 6-DoF sequence tracked in it.
pub fn rows_3d(
    spec: &super::table1_floorplan::BlockSpec,
    motion: &SixDofMotion,
    variants: &[Variant],
    progress: &dyn Fn(&str),
) -> Result<super::table1::BlockRuns, ExperimentError> {
    let table = builtin_table()?;
    let mut truths = Vec::new();
    let mut runs: Vec<Vec<RunResult>> = vec![Vec::new(); variants.len()];
    let mut panels: Vec<Vec<Figure4Panel>> = vec![Vec::new(); variants.len()];
    for (n, seed) in spec.seeds.clone().enumerate() {
        let seq = sixdof_sequence_in(spec.world, seed, spec.frames, &table, motion)?;
        truths.push((seed, seq.poses().to_vec()));
        for (k, v) in variants.iter().enumerate() {
            let map = BenchMap::build(&seq, v.map, &spec.map_params, &|_| {})?;
            let filter = spec.filter_for(v, seed);
            let r = track_6dof(&seq, &map, v, filter, spec.particles)?;
            let split = ErrorSplit::of(seq.poses(), &r.estimates);
            progress(&format!(
                "seed {seed} {}: 6-DoF RMSE {:.3} m (horizontal {:.3}, vertical {:.3}, bias {:+.3}; rotation {:.2} deg: tilt {:.2}, heading {:.2}), {:.1} steps/s",
                v.name,
                r.stats.rmse,
                split.horizontal_rmse_m,
                split.vertical_rmse_m,
                split.vertical_bias_m,
                split.rotation_rmse_deg,
                split.tilt_rmse_deg,
                split.heading_rmse_deg,
                r.fps()
            ));
            if n < FIGURE4_PANELS {
                let title = format!("{} (6-DoF) sequence {seed}", v.name);
                panels[k].push(Figure4Panel::of_run(title, Some(&map.map), &seq, &r));
            }
            runs[k].push(r);
        }
    }
    let rows = variants
        .iter()
        .zip(runs)
        .map(|(v, r)| TrackingRow::new(v.name, r))
        .collect();
    Ok((rows, panels, truths))
}

/// Where a 6-DoF run's error lies: RMSE over frames of the horizontal
/// (x, y) and vertical (z) parts of the translation error, of the rotation
/// error angle, and of its two parts: tilt (the angle between the true and
/// estimated world up seen from the camera: roll and pitch) and heading
/// (the angle between the horizontal projections of the optical axes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorSplit {
    pub horizontal_rmse_m: f64,
    pub vertical_rmse_m: f64,
    /// Mean of the estimate's height minus the truth's (m).
    pub vertical_bias_m: f64,
    pub rotation_rmse_deg: f64,
    pub tilt_rmse_deg: f64,
    pub heading_rmse_deg: f64,
}

impl ErrorSplit {
    /// Over the frames both slices have (`truth` and `estimates`, both
    /// `world_from_camera`).
    pub fn of(truth: &[Pose], estimates: &[Pose]) -> ErrorSplit {
        let n = truth.len().min(estimates.len()).max(1) as f64;
        let (mut h, mut v, mut r, mut tilt, mut head) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let mut bias = 0.0;
        let up = Vector3::z();
        let heading = |p: &Pose| {
            let f = p.rotation * Vector3::z();
            f.y.atan2(f.x)
        };
        for (t, e) in truth.iter().zip(estimates) {
            let d = e.translation.vector - t.translation.vector;
            h += d.x * d.x + d.y * d.y;
            v += d.z * d.z;
            bias += d.z;
            r += t.rotation.angle_to(&e.rotation).to_degrees().powi(2);
            let (ut, ue) = (t.rotation.inverse() * up, e.rotation.inverse() * up);
            tilt += ut.angle(&ue).to_degrees().powi(2);
            let dh = (heading(e) - heading(t)).sin_cos();
            head += dh.0.atan2(dh.1).to_degrees().powi(2);
        }
        let rms = |x: f64| (x / n).sqrt();
        ErrorSplit {
            horizontal_rmse_m: rms(h),
            vertical_rmse_m: rms(v),
            vertical_bias_m: bias / n,
            rotation_rmse_deg: rms(r),
            tilt_rmse_deg: rms(tilt),
            heading_rmse_deg: rms(head),
        }
    }
}

/// The folder of sequence `seed` under an export or results folder:
/// `seq_<seed>`.
pub fn sequence_dir(root: &Path, seed: u64) -> PathBuf {
    root.join(format!("seq_{seed}"))
}

/// Writes sequence `seed` of the block into `dir` in the RGB-D layout of
/// `omcl sim indoor` (`crate::sim::files`): `poses.txt` is the 6-DoF
/// ground truth, `odometry.txt` the block's noisy odometry, the frames are
/// [`SimSequence::render`]'s (the images the filter's features come
/// from), with `sim.json` naming the seed, frames and motion. No `world/`
/// and no feature files. `progress` is told the frames written so far.
pub fn export_sequence(
    seed: u64,
    frames: usize,
    motion: &SixDofMotion,
    dir: &Path,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<(), ExperimentError> {
    let table = builtin_table()?;
    let seq = sixdof_sequence(seed, frames, &table, motion)?;
    let out = RgbdSequenceOut {
        intrinsics: seq.intrinsics,
        poses: seq.poses(),
        odometry: &seq.odometry,
        table: &seq.table,
        features: None,
    };
    write_rgbd_sequence(dir, &out, &|i| seq.render(i), progress)?;
    let meta = serde_json::json!({
        "generator": crate::sim::dataset::EXPORT_GENERATOR,
        "version": env!("CARGO_PKG_VERSION"),
        "seed": seed,
        "frames": seq.len(),
        "motion": motion,
        "config": seq.config,
        "intrinsics": seq.intrinsics,
        "depth_scale": 5000.0,
        "no_label": crate::sim::render::NO_LABEL,
    });
    crate::sim::files::write_json(&dir.join("sim.json"), &meta)
        .map_err(crate::sim::dataset::SimError::from)?;
    Ok(())
}

/// Writes every sequence of the block (`spec.seeds`, `spec.frames`) into
/// [`sequence_dir`]`(root, seed)`; returns the folders. `progress` is told
/// each finished sequence.
pub fn export_block(
    spec: &BlockSpec,
    motion: &SixDofMotion,
    root: &Path,
    progress: &dyn Fn(&str),
) -> Result<Vec<PathBuf>, ExperimentError> {
    let mut dirs = Vec::new();
    for seed in spec.seeds.clone() {
        let dir = sequence_dir(root, seed);
        export_sequence(seed, spec.frames, motion, &dir, &|_| {})?;
        progress(&format!(
            "seed {seed}: {} frames written to {}",
            spec.frames,
            dir.display()
        ));
        dirs.push(dir);
    }
    Ok(dirs)
}

/// Refuses an estimate made on another sequence than the block's `seed`
/// as this call makes it (other `--set sixdof.*`, `--world`, frames): the
/// `odometry.json` that `tools/rgbd_odometry.py` writes beside
/// `estimate.txt` records the CRC-32 of the `poses.txt` it read
/// (`poses_crc32`), which must be that of the `poses.txt` the block's
/// export writes for `poses`. Without the record (an estimate made
/// otherwise) nothing is checked but the pose count.
fn check_odometry_record(
    seed: u64,
    estimate: &Path,
    poses: &[Pose],
) -> Result<(), ExperimentError> {
    let record = estimate.with_file_name("odometry.json");
    let Ok(text) = crate::io::bounded_read::read_text(&record) else {
        return Ok(());
    };
    let json: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| ExperimentError::Config(format!("{}: not JSON: {e}", record.display())))?;
    let Some(theirs) = json.get("poses_crc32").and_then(|v| v.as_str()) else {
        return Ok(());
    };
    let lines = crate::sim::files::pose_lines(poses, crate::io::poses::PoseFormat::Tum, 30.0);
    let ours = format!("{:08x}", crc32fast::hash(lines.as_bytes()));
    if theirs != ours {
        return Err(ExperimentError::Config(format!(
            "{}: the estimate beside it was made on a sequence whose poses.txt (CRC-32 {theirs}) \
             is not the block's sequence {seed} as this call makes it ({ours}): export the \
             frames with this call's --set sixdof.*, --world, --frames and seeds \
             (--export-frames) and run the odometry on those",
            record.display()
        )));
    }
    Ok(())
}

/// The name of the geometric odometry row.
pub const ODOMETRY_ROW: &str =
    "geometric RGB-D odometry (Open3D, frame to frame, no map; stand-in for RTAB-Map)";

/// Scores an odometry estimate of the block's sequence `seed` (`estimate`,
/// TUM, one pose a frame in frame order) as the filter's runs are scored:
/// per-frame translation error against the ground truth with no alignment
/// (`omcl eval ape --align none`), its statistics and the completion rule.
pub fn score_estimate(
    seed: u64,
    frames: usize,
    motion: &SixDofMotion,
    estimate: &Path,
) -> Result<RunResult, ExperimentError> {
    let table = builtin_table()?;
    let seq = sixdof_sequence(seed, frames, &table, motion)?;
    let est = read_poses_in(estimate, PoseFormat::Tum)?.trajectory;
    if est.len() != seq.len() {
        return Err(ExperimentError::Config(format!(
            "{}: {} poses, but sequence {seed} of the block has {} frames (one pose a frame)",
            estimate.display(),
            est.len(),
            seq.len()
        )));
    }
    check_odometry_record(seed, estimate, seq.poses())?;
    // Paired by index: pose i is frame i's.
    let truth = Trajectory::from_poses(seq.poses().to_vec())
        .map_err(|e| ExperimentError::Config(e.to_string()))?;
    let errors = ape(&truth, &est, PoseRelation::Translation)
        .map_err(|e| ExperimentError::Config(format!("{}: {e}", estimate.display())))?;
    Ok(RunResult {
        completed: CompletionRule::default().judge(&errors.errors),
        estimates: est.poses().to_vec(),
        errors_m: errors.errors,
        stats: errors.stats,
        step_seconds: Vec::new(),
        encoder_seconds: Vec::new(),
        mean_rays: 0.0,
        map_rows: 0,
    })
}

/// The geometric odometry row over the block's sequences, from
/// `tools/rgbd_odometry.py`'s results folder: [`sequence_dir`]`(results,
/// seed)/estimate.txt` for each seed, scored by [`score_estimate`].
pub fn odometry_row(
    spec: &BlockSpec,
    motion: &SixDofMotion,
    results: &Path,
) -> Result<TrackingRow, ExperimentError> {
    let runs = spec
        .seeds
        .clone()
        .map(|seed| {
            let est = sequence_dir(results, seed).join("estimate.txt");
            score_estimate(seed, spec.frames, motion, &est)
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(TrackingRow::new(ODOMETRY_ROW, runs))
}

/// The paper's 3-D rows of Table I.
pub const PAPER_3D: [PaperRow; 4] = [
    PaperRow {
        variant: "OMCL_GT",
        ape: [0.15, 0.09, 0.12, 0.1, 0.1, 0.3, 30.45],
        completed: "10/10",
    },
    PaperRow {
        variant: "OMCL_LSeg",
        ape: [0.2, 0.1, 0.18, 0.17, 0.17, 0.41, 59.53],
        completed: "10/10",
    },
    PaperRow {
        variant: "OMCL_Open_LSeg",
        ape: [0.42, 0.25, 0.31, 0.25, 0.22, 0.75, 223.32],
        completed: "8/10",
    },
    PaperRow {
        variant: "RTAB-Map",
        ape: [5.23, 2.97, 4.30, 3.6, 0.31, 8.14, 25781.93],
        completed: "10/10",
    },
];

/// The variants of the 3-D block (the paper's 3-D rows but RTAB-Map's).
pub const ROWS: [&str; 3] = ["OMCL_GT", "OMCL_LSeg", "OMCL_Open_LSeg"];

/// Table I's 3-D block: OMCL_GT, OMCL_LSeg and OMCL_Open_LSeg, those of
/// them in `names` (comma-separated; `None`: all), and the block as
/// Markdown beside the paper's rows.
pub fn block(
    spec: &BlockSpec,
    motion: &SixDofMotion,
    names: Option<&str>,
    odometry: Option<&Path>,
    progress: &dyn Fn(&str),
) -> Result<BlockResult, ExperimentError> {
    let variants = spec.variants(&ROWS, names);
    let (mut rows, mut figures, truths) = rows_3d(spec, motion, &variants, progress)?;
    let mut markdown = block_markdown(
        "Table I, 3-D block: APE (m) of the full 6-DoF pose",
        &rows,
        &PAPER_3D,
    );
    // The odometry rows are rows of the table: right after the others,
    // before the notes (they had come after the notes, outside it).
    if let Some(dir) = odometry {
        let row = odometry_row(spec, motion, dir)?;
        markdown.push_str(&odometry_markdown(&row));
        rows.push(row);
        // The script's estimates stay in its files: no panels for it.
        figures.push(Vec::new());
    }
    markdown.push_str(&format!(
        "\nSequences: the benchmark path with height +-{} m, pitch +-{} deg and roll +-{} deg \
         (periods {:?} frames); odometry noise {} m and {} deg per axis a step.",
        motion.height_m,
        motion.pitch_deg,
        motion.roll_deg,
        motion.periods,
        motion.sigma_translation,
        motion.sigma_rotation_deg,
    ));
    // The filter only when an OMCL row ran.
    if !variants.is_empty() {
        markdown.push_str(&format!(
            " Filter: {} particles x {} rays, likelihood exponent {}, {} layer(s) of \
             progressive correction a frame{}.",
            spec.particles,
            spec.filter.sampling.rays,
            spec.filter.sharpen,
            spec.filter.anneal.map_or(1, |a| a.layers),
            match spec.filter.anneal.map_or(1, |a| a.expand) {
                1 => String::new(),
                m => format!(", the first on {m} copies of each particle and every {m}th pixel"),
            }
        ));
    }
    markdown.push('\n');
    markdown.push_str(super::table1_floorplan::SSE_NOTE);
    let cloud = &spec.point_cloud_filter;
    let differs =
        (cloud.sampling.rays, cloud.sharpen) != (spec.filter.sampling.rays, spec.filter.sharpen);
    if differs
        && variants
            .iter()
            .any(|v| v.map == super::mapping::MapSource::PointCloud)
    {
        markdown.push_str(&format!(
            "The point-cloud row (a map from a labelled point cloud) has its own filter: {} rays, \
             likelihood exponent {}.\n",
            cloud.sampling.rays, cloud.sharpen
        ));
    }
    if !variants.is_empty() {
        markdown.push_str(&spec.preset_note());
    }
    Ok(BlockResult {
        rows,
        markdown,
        figures,
        truths,
    })
}

/// The odometry row's lines of the block: ours (no steps/s: the script
/// reports its own time) and the paper's RTAB-Map row.
fn odometry_markdown(row: &TrackingRow) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    if let Some(cells) = ape_cells(row) {
        let _ = writeln!(s, "| {}, omcl | {cells} | |", row.variant);
    }
    for p in PAPER_3D.iter().filter(|p| p.variant == "RTAB-Map") {
        let v = p.ape;
        let _ = writeln!(
            s,
            "| RTAB-Map RGB-D SLAM, paper | {} | {} | {} | {} | {} | {} | {} | {} | |",
            v[0], v[1], v[2], v[3], v[4], v[5], v[6], p.completed
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_path_moves_in_height_pitch_and_roll_and_odometry_is_noisy() {
        let table = crate::experiment::features::builtin_table().unwrap();
        let m = SixDofMotion::default();
        let seq = sixdof_sequence(3, 40, &table, &m).unwrap();
        let level = SimSequence::generate(3, 40, &table).unwrap();
        // Frame 15: height sin(2 pi 15 / 60) = 1: +0.15 m; same x, y.
        let (a, b) = (seq.poses()[15], level.poses()[15]);
        assert!((a.translation.z - b.translation.z - 0.15).abs() < 1e-9);
        assert!((a.translation.x - b.translation.x).abs() < 1e-12);
        // The relative rotation is the tilt: pitch 10 sin(2 pi 15/45)
        // and roll 4 sin(2 pi 15/70) degrees, about 9.4 deg in all.
        let rel = b.rotation.inverse() * a.rotation;
        let p = 10f64 * (std::f64::consts::TAU * 15.0 / 45.0).sin();
        let r = 4f64 * (std::f64::consts::TAU * 15.0 / 70.0).sin();
        let want = (UnitQuaternion::from_axis_angle(&Vector3::x_axis(), p.to_radians())
            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), r.to_radians()))
        .angle();
        assert!((rel.angle() - want).abs() < 1e-9);
        // Odometry: first pose exact, noise in height too.
        assert_eq!(seq.odometry[0], seq.poses()[0]);
        let dz: Vec<f64> = (1..40)
            .map(|i| {
                let e = seq.increment(i);
                let t = seq.poses()[i - 1].inverse() * seq.poses()[i];
                (e.translation.vector - t.translation.vector).norm()
            })
            .collect();
        assert!(dz.iter().all(|d| *d > 0.0));
    }

    #[test]
    fn exported_frames_are_the_blocks_own() {
        let dir = tempfile::tempdir().unwrap();
        let m = SixDofMotion::default();
        export_sequence(4, 3, &m, dir.path(), &|_| {}).unwrap();
        let table = crate::experiment::features::builtin_table().unwrap();
        let seq = sixdof_sequence(4, 3, &table, &m).unwrap();
        let read = |name: &str| {
            read_poses_in(&dir.path().join(name), PoseFormat::Tum)
                .unwrap()
                .trajectory
        };
        let (truth, odo) = (read("poses.txt"), read("odometry.txt"));
        assert_eq!(truth.len(), 3);
        for i in 0..3 {
            let (a, b) = (truth.poses()[i], seq.poses()[i]);
            assert!((a.translation.vector - b.translation.vector).norm() < 1e-8);
            assert!(a.rotation.angle_to(&b.rotation) < 1e-8);
            let (a, b) = (odo.poses()[i], seq.odometry[i]);
            assert!((a.translation.vector - b.translation.vector).norm() < 1e-8);
        }
        // Frame 2's depth is the block's rendering, in TUM units.
        let depth = crate::io::rgbd::read_depth_png(
            &dir.path().join("depth/000002.png"),
            crate::io::rgbd::TUM_DEPTH_UNITS_PER_METRE,
        )
        .unwrap();
        let f = seq.render(2);
        assert_eq!(depth.depth.len(), f.depth.len());
        let mut hits = 0;
        for (a, b) in depth.depth.iter().zip(&f.depth) {
            assert!((a - b).abs() <= 0.5 / 5000.0 + 1e-6, "{a} against {b}");
            hits += usize::from(*b > 0.0);
        }
        assert!(hits > depth.depth.len() / 2);
        let k = crate::io::rgbd::read_intrinsics(&dir.path().join("intrinsics.txt")).unwrap();
        assert_eq!(k, seq.intrinsics);
        assert!(dir.path().join("rgb/000000.png").exists());
    }

    #[test]
    fn an_estimate_is_scored_as_the_filter_is() {
        let dir = tempfile::tempdir().unwrap();
        let m = SixDofMotion::default();
        let table = crate::experiment::features::builtin_table().unwrap();
        let seq = sixdof_sequence(5, 30, &table, &m).unwrap();
        let write = |poses: &[Pose]| {
            let p = dir.path().join("estimate.txt");
            std::fs::write(
                &p,
                crate::sim::files::pose_lines(poses, PoseFormat::Tum, 30.0),
            )
            .unwrap();
            p
        };
        // The truth scores zero and completes.
        let r = score_estimate(5, 30, &m, &write(seq.poses())).unwrap();
        assert!(r.stats.rmse < 1e-8 && r.completed == Some(true));
        // 0.5 m off in x from frame 10 on: RMSE sqrt(20 / 30) 0.5 m; 2 m
        // off from frame 20 on: more than 5 frames above 1 m, not completed.
        let shifted = |from: usize, by: f64| -> Vec<Pose> {
            seq.poses()
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let dx = if i >= from { by } else { 0.0 };
                    Translation3::new(dx, 0.0, 0.0) * p
                })
                .collect()
        };
        let r = score_estimate(5, 30, &m, &write(&shifted(10, 0.5))).unwrap();
        assert!((r.stats.rmse - 0.5 * (20.0f64 / 30.0).sqrt()).abs() < 1e-6);
        assert_eq!(r.completed, Some(true));
        let r = score_estimate(5, 30, &m, &write(&shifted(20, 2.0))).unwrap();
        assert_eq!(r.completed, Some(false));
        // One pose a frame, or the file is named.
        let e = score_estimate(5, 30, &m, &write(&seq.poses()[..29]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("estimate.txt") && e.contains("29 poses"), "{e}");
    }

    #[test]
    fn error_split_is_hand_computed() {
        let level =
            |t: Vector3<f64>, yaw_deg: f64| crate::geometry::level_camera(t, yaw_deg.to_radians());
        let truth = [level(Vector3::zeros(), 0.0), level(Vector3::zeros(), 0.0)];
        let est = [
            // 3 m east, 4 m north, 2 m up, 10 degrees of yaw.
            level(Vector3::new(3.0, 4.0, 2.0), 10.0),
            level(Vector3::zeros(), 0.0),
        ];
        let s = ErrorSplit::of(&truth, &est);
        assert!((s.horizontal_rmse_m - (25.0f64 / 2.0).sqrt()).abs() < 1e-12);
        assert!((s.vertical_rmse_m - (4.0f64 / 2.0).sqrt()).abs() < 1e-12);
        assert!((s.vertical_bias_m - 1.0).abs() < 1e-12);
        assert!((s.rotation_rmse_deg - (100.0f64 / 2.0).sqrt()).abs() < 1e-9);
        // A yaw about world z leaves the up vector alone: all heading.
        assert!(s.tilt_rmse_deg.abs() < 1e-9);
        assert!((s.heading_rmse_deg - (100.0f64 / 2.0).sqrt()).abs() < 1e-9);
        // A level camera (optical axis along world x) pitched down 4
        // degrees: all tilt, no heading.
        let level = level(Vector3::zeros(), 0.0);
        let pitch = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 4f64.to_radians());
        let tilted = Pose::from_parts(level.translation, level.rotation * pitch);
        let s = ErrorSplit::of(&[level], &[tilted]);
        assert!((s.tilt_rmse_deg - 4.0).abs() < 1e-9, "{s:?}");
        assert!(s.heading_rmse_deg.abs() < 1e-9, "{s:?}");
    }
}
