//! The paper's Table IV on the street world: a synthetic street laid along
//! a stretch of the real KITTI 00 path ([`crate::sim::outdoor`]), seen by
//! KITTI's camera 2 (intrinsics and its 6 cm offset from camera 0 from
//! KITTI 00's `calib.txt`), mapped from its simulated HDL-64E LiDAR scans
//! (as the paper maps SemanticKITTI: every labelled scan in the world
//! frame), with odometry in the authors' form or replayed from a real
//! visual odometry.

use nalgebra::Vector3;

use super::ExperimentError;
use super::sequence::BenchSequence;
use crate::geometry::{Intrinsics, Pose};
use crate::map::{FeatureDb, GridSpec, Integrator, LanguageMap};
use crate::raycast::EmbreeCaster;
use crate::sim::dataset::{kitti00_camera_from_velodyne, kitti00_camera2};
use crate::sim::embeddings::ClassEmbeddings;
use crate::sim::lidar::{self, LidarConfig};
use crate::sim::outdoor::{self, OUTDOOR_CLASSES, OutdoorConfig, OutdoorWorld};
use crate::sim::paths::{self, OdometryConfig};
use crate::sim::render::{self, Frame};

/// Where the odometry of a street run comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum StreetOdometry {
    /// Ground truth with Gaussian noise every frame, in the camera frame:
    /// `sigma_m` on camera x and z, `sigma_deg` on yaw about camera y (the
    /// authors' code: 0.1 m and 0.1 rad), accumulated.
    Noise { sigma_m: f64, sigma_deg: f64 },
    /// The frame-to-frame motion of a real visual odometry replayed from
    /// the first true pose: KITTI camera-0 poses of the whole drive (the
    /// rows of the path's frames are used).
    Replay(Vec<Pose>),
}

/// A street sequence: the world, its caster, camera 2's ground truth and
/// odometry.
pub struct StreetSequence {
    pub world: OutdoorWorld,
    pub caster: EmbreeCaster,
    /// The outdoor classes' embeddings (rows in class-id order).
    pub table: ClassEmbeddings,
    /// KITTI camera 2.
    pub intrinsics: Intrinsics,
    /// `world_from_camera2` of every frame.
    pub ground_truth: Vec<Pose>,
    /// Odometry poses of camera 2 (see [`Self::set_odometry`]).
    pub odometry: Vec<Pose>,
}

impl StreetSequence {
    /// The street world of `config` along `kitti_gt` (KITTI camera-0 poses
    /// of the whole drive), with ground truth plus noise as odometry until
    /// [`Self::set_odometry`] says otherwise.
    pub fn generate(
        config: &OutdoorConfig,
        kitti_gt: &[Pose],
        table: &ClassEmbeddings,
    ) -> Result<Self, ExperimentError> {
        let world = outdoor::generate(config, kitti_gt);
        if world.poses.len() < 2 {
            return Err(ExperimentError::Config(format!(
                "the street has {} frames: need at least 2 (start {} of a {}-pose path)",
                world.poses.len(),
                config.start,
                kitti_gt.len()
            )));
        }
        let caster = EmbreeCaster::new(world.voxels.resolution as f32, &world.voxels.cells)?;
        let cam2 = kitti00_camera2()?;
        let ground_truth: Vec<Pose> = world
            .poses
            .iter()
            .map(|p| p * cam2.camera0_from_camera)
            .collect();
        let mut s = StreetSequence {
            world,
            caster,
            table: table.subset(OUTDOOR_CLASSES).map_err(|e| {
                ExperimentError::Config(format!("the class table lacks a street class: {e}"))
            })?,
            intrinsics: cam2.intrinsics,
            odometry: ground_truth.clone(),
            ground_truth,
        };
        s.set_odometry(
            &StreetOdometry::Noise {
                sigma_m: 0.1,
                sigma_deg: 0.1f64.to_degrees(),
            },
            0,
        )?;
        Ok(s)
    }

    /// Replaces the odometry; `seed` draws the noise.
    pub fn set_odometry(
        &mut self,
        source: &StreetOdometry,
        seed: u64,
    ) -> Result<(), ExperimentError> {
        self.odometry = match source {
            StreetOdometry::Noise { sigma_m, sigma_deg } => paths::odometry(
                &self.ground_truth,
                &[],
                &OdometryConfig {
                    seed,
                    sigma_t: *sigma_m,
                    sigma_r_deg: *sigma_deg,
                    drift_scale: 1.0,
                },
            ),
            StreetOdometry::Replay(camera0) => {
                let start = self.world.config.start;
                let n = self.ground_truth.len();
                let rows = camera0.get(start..start + n).ok_or_else(|| {
                    ExperimentError::Config(format!(
                        "the odometry has {} poses, the street needs rows {start} to {}",
                        camera0.len(),
                        start + n - 1
                    ))
                })?;
                // Camera 2 moves as camera 0 does, seen from 6 cm aside.
                let c = kitti00_camera2()?.camera0_from_camera;
                let mut out = Vec::with_capacity(n);
                out.push(self.ground_truth[0]);
                for w in rows.windows(2) {
                    let inc = c.inverse() * (w[0].inverse() * w[1]) * c;
                    let prev = out[out.len() - 1];
                    out.push(prev * inc);
                }
                out
            }
        };
        Ok(())
    }

    /// The map: the labelled LiDAR returns of every `frame_step`-th frame,
    /// in the world frame, integrated at `resolution` (m) into a database of
    /// the class rows (`tau` as `omcl map cloud`). The grid is offset from
    /// the world's voxels by half a map voxel, as a real map's grid is not
    /// aligned with the surfaces.
    pub fn lidar_map(
        &self,
        resolution: f64,
        tau: f32,
        frame_step: usize,
        lidar: &LidarConfig,
    ) -> Result<LanguageMap, ExperimentError> {
        let db = FeatureDb::from_rows(self.table.dim, tau, self.table.rows.clone())?;
        let grid = GridSpec {
            resolution,
            origin: self.world.voxels.origin - Vector3::repeat(0.5 * resolution),
        };
        let mut integ = Integrator::new(grid, db)?;
        let velo = kitti00_camera_from_velodyne();
        for (i, pose) in self
            .world
            .poses
            .iter()
            .enumerate()
            .step_by(frame_step.max(1))
        {
            let world_from_lidar = pose * velo;
            let pts = lidar::scan(
                &self.caster,
                &self.world.voxels,
                &world_from_lidar,
                lidar,
                self.world.config.seed.wrapping_add(i as u64),
            );
            let (points, rows): (Vec<[f64; 3]>, Vec<Option<u32>>) = pts
                .iter()
                .map(|p| {
                    let q = world_from_lidar
                        * nalgebra::Point3::new(p.xyz[0] as f64, p.xyz[1] as f64, p.xyz[2] as f64);
                    ([q.x, q.y, q.z], Some(p.label as u32))
                })
                .unzip();
            integ.add_rows_batch(&points, &rows);
        }
        Ok(integ.finish("street-lidar-labels", tau)?)
    }

    /// Driven distance along the ground truth, metres.
    pub fn length_m(&self) -> f64 {
        self.ground_truth
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum()
    }
}

impl BenchSequence for StreetSequence {
    fn poses(&self) -> &[Pose] {
        &self.ground_truth
    }
    fn render(&self, i: usize) -> Frame {
        render::render_frame(
            &self.caster,
            &self.world.voxels,
            &self.intrinsics,
            &self.ground_truth[i],
        )
    }
    fn increment(&self, i: usize) -> Pose {
        if i == 0 {
            Pose::identity()
        } else {
            self.odometry[i - 1].inverse() * self.odometry[i]
        }
    }
    fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }
    fn table(&self) -> &ClassEmbeddings {
        &self.table
    }
}

/// One street run scored with the Table IV metric.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StreetRun {
    /// Per-frame translation (m) and rotation (deg) errors and their
    /// statistics.
    pub metric: crate::eval::OutdoorMetric,
    /// The run itself (estimates, step times, rays).
    pub run: super::RunResult,
}

/// Runs the filter over `seq` in `map` (whose leaves `caster` indexes)
/// and scores it with [`crate::eval::outdoor_metric`].
pub fn run_street(
    seq: &StreetSequence,
    map: &LanguageMap,
    caster: std::sync::Arc<dyn crate::raycast::RayCaster>,
    model: &crate::sim::features::FeatureModel,
    spec: &super::RunSpec,
) -> Result<StreetRun, ExperimentError> {
    let run = super::run(seq, map, caster, model, spec)?;
    let first = spec.first.min(seq.frames().saturating_sub(1));
    let truth = &seq.ground_truth[first..first + run.estimates.len()];
    let metric = crate::eval::outdoor_metric(truth, &run.estimates)
        .map_err(|e| ExperimentError::Config(format!("scoring the run: {e}")))?;
    Ok(StreetRun { metric, run })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::paths::{level_camera, world_from_kitti};

    /// A straight 40 m KITTI path along camera z.
    fn straight() -> Vec<Pose> {
        let k_from_w = world_from_kitti().inverse();
        (0..50)
            .map(|i| k_from_w * level_camera(Vector3::new(0.8 * i as f64, 0.0, 0.0), 0.0))
            .collect()
    }

    #[test]
    fn replayed_odometry_moves_as_the_estimate_does() {
        let table = crate::sim::files::builtin_table().unwrap();
        let cfg = OutdoorConfig {
            frames: 10,
            start: 5,
            ..Default::default()
        };
        let path = straight();
        let mut seq = StreetSequence::generate(&cfg, &path, &table).unwrap();
        assert_eq!(seq.frames(), 10);
        // Camera 2 sits 6 cm left of camera 0 (world +y: left of a drive
        // along world +x).
        let d = seq.ground_truth[0].translation.vector - seq.world.poses[0].translation.vector;
        assert!(
            (d - Vector3::new(0.0, 0.063_131_2, 0.0)).norm() < 1e-6,
            "{d:?}"
        );
        // A VO that sees every step 10 % too long.
        let vo: Vec<Pose> = path
            .iter()
            .map(|p| {
                let mut q = *p;
                q.translation.vector *= 1.1;
                q
            })
            .collect();
        seq.set_odometry(&StreetOdometry::Replay(vo.clone()), 0)
            .unwrap();
        for i in 1..10 {
            let step = seq.increment(i).translation.vector.norm();
            assert!((step - 0.88).abs() < 1e-9, "frame {i}: {step}");
        }
        assert!(
            seq.set_odometry(&StreetOdometry::Replay(vo[..12].to_vec()), 0)
                .is_err()
        );
        seq.set_odometry(
            &StreetOdometry::Noise {
                sigma_m: 0.0,
                sigma_deg: 0.0,
            },
            0,
        )
        .unwrap();
        assert!((seq.increment(3).translation.vector.norm() - 0.8).abs() < 1e-9);
        assert!((seq.length_m() - 7.2).abs() < 1e-9);
    }
}
