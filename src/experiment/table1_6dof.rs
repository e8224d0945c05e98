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

use crate::sim::indoor::WorldKind;
use nalgebra::{Translation3, UnitQuaternion, Vector3};

use super::ExperimentError;
use super::features::builtin_table;
use super::mapping::BenchMap;
use super::run::RunResult;
use super::run::TrackingRow;
use super::sequence::SimSequence;
use super::table1::{PaperRow, block_markdown, track};
use super::table1_floorplan::BlockSpec;
use super::variant::{TABLE1_VARIANTS, Variant, named_in};
use crate::geometry::Pose;
use crate::mcl::{FilterConfig, MotionMode};

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
    // Gaussian noise on all six degrees of freedom of every increment,
    // accumulated (the first pose exact).
    seq.odometry = crate::sim::paths::odometry(
        seq.poses(),
        &[],
        &crate::sim::paths::OdometryConfig {
            seed,
            sigma_t: motion.sigma_translation,
            sigma_r_deg: motion.sigma_rotation_deg,
            drift_scale: 0.0,
            all_axes: true,
        },
    );
    Ok(seq)
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
) -> Result<Vec<TrackingRow>, ExperimentError> {
    let table = builtin_table()?;
    let mut runs: Vec<Vec<RunResult>> = vec![Vec::new(); variants.len()];
    for seed in spec.seeds.clone() {
        let seq = sixdof_sequence_in(spec.world, seed, spec.frames, &table, motion)?;
        for (k, v) in variants.iter().enumerate() {
            let map = BenchMap::build(&seq, v.map, &spec.map_params, &|_| {})?;
            let filter = FilterConfig {
                seed,
                ..spec.filter
            };
            let r = track_6dof(&seq, &map, v, filter, spec.particles)?;
            progress(&format!(
                "seed {seed} {}: 6-DoF RMSE {:.3} m, {:.1} steps/s",
                v.name,
                r.stats.rmse,
                r.fps()
            ));
            runs[k].push(r);
        }
    }
    Ok(variants
        .iter()
        .zip(runs)
        .map(|(v, r)| TrackingRow::new(v.name, r))
        .collect())
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

/// Table I's 3-D block: OMCL_GT, OMCL_LSeg and OMCL_Open_LSeg, those of
/// them in `names` (comma-separated; `None`: all), and the block as
/// Markdown beside the paper's rows.
pub fn block(
    spec: &BlockSpec,
    motion: &SixDofMotion,
    names: Option<&str>,
    progress: &dyn Fn(&str),
) -> Result<(Vec<TrackingRow>, String), ExperimentError> {
    let variants: Vec<_> = TABLE1_VARIANTS
        .iter()
        .filter(|v| ["OMCL_GT", "OMCL_LSeg", "OMCL_Open_LSeg"].contains(&v.name))
        .filter(|v| named_in(names, v.name))
        .copied()
        .collect();
    let rows = rows_3d(spec, motion, &variants, progress)?;
    let md = block_markdown(
        "Table I, 3-D block: APE (m) of the full 6-DoF pose",
        &rows,
        &PAPER_3D,
    );
    Ok((rows, md))
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
}
