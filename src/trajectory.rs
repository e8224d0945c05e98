//! A timed sequence of camera poses: the common currency of pose files,
//! evaluation and the filter's output.
//!
//! Poses are `world_from_camera` rigid transforms (metres); stamps are seconds
//! (or frame indices for files that carry no time, see [`crate::io::poses`]).

use nalgebra::{Point3, Vector3};

use crate::geometry::Pose;

/// Why a set of stamps and poses is not a trajectory.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrajectoryError {
    #[error("{stamps} stamps but {poses} poses")]
    LengthMismatch { stamps: usize, poses: usize },
    #[error("pose {index}: stamp {stamp} is not finite")]
    NonFiniteStamp { index: usize, stamp: f64 },
    #[error(
        "pose {index}: stamp {stamp} s is before the previous stamp {previous} s (stamps must not decrease)"
    )]
    UnsortedStamps {
        index: usize,
        stamp: f64,
        previous: f64,
    },
    #[error("pose {index}: translation or rotation is not finite")]
    NonFinitePose { index: usize },
    #[error("pose {index}: rotation quaternion has norm {norm} (expected 1 within 1e-6)")]
    NonRigidRotation { index: usize, norm: f64 },
    #[error("index {index} out of range for a trajectory of {len} poses")]
    IndexOutOfRange { index: usize, len: usize },
}

/// Poses with their time stamps; stamps never decrease, every number is
/// finite and every rotation is a unit quaternion.
///
/// The fields are private so that these invariants hold; build one with
/// [`Trajectory::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    stamps: Vec<f64>,
    poses: Vec<Pose>,
}

impl Trajectory {
    /// Checks and wraps stamps (seconds) and `world_from_camera` poses.
    pub fn new(stamps: Vec<f64>, poses: Vec<Pose>) -> Result<Self, TrajectoryError> {
        if stamps.len() != poses.len() {
            return Err(TrajectoryError::LengthMismatch {
                stamps: stamps.len(),
                poses: poses.len(),
            });
        }
        for (index, (&stamp, pose)) in stamps.iter().zip(&poses).enumerate() {
            if !stamp.is_finite() {
                return Err(TrajectoryError::NonFiniteStamp { index, stamp });
            }
            if index > 0 && stamp < stamps[index - 1] {
                return Err(TrajectoryError::UnsortedStamps {
                    index,
                    stamp,
                    previous: stamps[index - 1],
                });
            }
            let q = pose.rotation.quaternion();
            let finite = pose.translation.vector.iter().all(|v| v.is_finite())
                && q.coords.iter().all(|v| v.is_finite());
            if !finite {
                return Err(TrajectoryError::NonFinitePose { index });
            }
            let norm = q.norm();
            if (norm - 1.0).abs() > 1e-6 {
                return Err(TrajectoryError::NonRigidRotation { index, norm });
            }
        }
        Ok(Trajectory { stamps, poses })
    }

    /// A trajectory whose stamps are the frame indices 0, 1, 2, ...
    /// (for pose files that carry no time, such as KITTI's).
    pub fn from_poses(poses: Vec<Pose>) -> Result<Self, TrajectoryError> {
        let stamps = (0..poses.len()).map(|i| i as f64).collect();
        Trajectory::new(stamps, poses)
    }

    /// Time stamps, seconds (or frame indices), never decreasing.
    pub fn stamps(&self) -> &[f64] {
        &self.stamps
    }

    /// `world_from_camera` poses.
    pub fn poses(&self) -> &[Pose] {
        &self.poses
    }

    /// Number of poses.
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    /// True when there are no poses.
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// Camera centres in the world frame, metres.
    pub fn positions(&self) -> Vec<Vector3<f64>> {
        self.poses.iter().map(|p| p.translation.vector).collect()
    }

    /// Distance travelled from the first pose to each pose along the
    /// straight segments between consecutive camera centres, metres.
    pub fn path_lengths(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.len());
        let mut acc = 0.0;
        for (i, p) in self.poses.iter().enumerate() {
            if i > 0 {
                acc += (p.translation.vector - self.poses[i - 1].translation.vector).norm();
            }
            out.push(acc);
        }
        out
    }

    /// The poses at `ids`, in that order. The ids must not decrease, so the
    /// stamps stay sorted.
    pub fn select(&self, ids: &[usize]) -> Result<Trajectory, TrajectoryError> {
        let mut stamps = Vec::with_capacity(ids.len());
        let mut poses = Vec::with_capacity(ids.len());
        for &index in ids {
            let (Some(&s), Some(p)) = (self.stamps.get(index), self.poses.get(index)) else {
                return Err(TrajectoryError::IndexOutOfRange {
                    index,
                    len: self.len(),
                });
            };
            stamps.push(s);
            poses.push(*p);
        }
        Trajectory::new(stamps, poses)
    }

    /// Replaces the stamps (for example with a KITTI `times.txt`).
    pub fn with_stamps(self, stamps: Vec<f64>) -> Result<Trajectory, TrajectoryError> {
        Trajectory::new(stamps, self.poses)
    }

    /// Applies `other_from_world` on the left of every pose, giving a
    /// trajectory expressed in frame `other`.
    pub fn transformed(&self, other_from_world: &Pose) -> Trajectory {
        Trajectory {
            stamps: self.stamps.clone(),
            poses: self.poses.iter().map(|p| other_from_world * p).collect(),
        }
    }

    /// Multiplies every translation by `scale` (rotations are kept), as a
    /// Sim(3) alignment does to a monocular estimate.
    pub fn scaled(&self, scale: f64) -> Trajectory {
        let poses = self
            .poses
            .iter()
            .map(|p| {
                let mut q = *p;
                q.translation.vector *= scale;
                q
            })
            .collect();
        Trajectory {
            stamps: self.stamps.clone(),
            poses,
        }
    }

    /// Every position's height set to 0 (rotations kept): translation
    /// errors between two such trajectories are horizontal (x and y), as
    /// Table I's 2-D block measures them.
    pub fn horizontal(&self) -> Trajectory {
        let poses = self
            .poses
            .iter()
            .map(|p| {
                let mut q = *p;
                q.translation.vector.z = 0.0;
                q
            })
            .collect();
        Trajectory {
            stamps: self.stamps.clone(),
            poses,
        }
    }

    /// The camera centre of pose `i` as a point (world frame, metres).
    pub fn position(&self, i: usize) -> Option<Point3<f64>> {
        self.poses
            .get(i)
            .map(|p| Point3::from(p.translation.vector))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Quaternion, Translation3, UnitQuaternion};

    fn at(x: f64) -> Pose {
        Pose::from_parts(Translation3::new(x, 0.0, 0.0), UnitQuaternion::identity())
    }

    #[test]
    fn rejects_bad_input() {
        assert!(matches!(
            Trajectory::new(vec![0.0], vec![]),
            Err(TrajectoryError::LengthMismatch { .. })
        ));
        assert!(matches!(
            Trajectory::new(vec![1.0, 0.5], vec![at(0.0), at(1.0)]),
            Err(TrajectoryError::UnsortedStamps { index: 1, .. })
        ));
        assert!(matches!(
            Trajectory::new(vec![f64::NAN], vec![at(0.0)]),
            Err(TrajectoryError::NonFiniteStamp { .. })
        ));
        assert!(matches!(
            Trajectory::new(vec![0.0], vec![at(f64::INFINITY)]),
            Err(TrajectoryError::NonFinitePose { index: 0 })
        ));
        let skewed = Pose::from_parts(
            Translation3::identity(),
            UnitQuaternion::new_unchecked(Quaternion::new(2.0, 0.0, 0.0, 0.0)),
        );
        assert!(matches!(
            Trajectory::new(vec![0.0], vec![skewed]),
            Err(TrajectoryError::NonRigidRotation { .. })
        ));
    }

    #[test]
    fn path_lengths_accumulate() {
        let t = Trajectory::from_poses(vec![at(0.0), at(3.0), at(1.0)]).unwrap();
        assert_eq!(t.path_lengths(), vec![0.0, 3.0, 5.0]);
        assert_eq!(t.stamps(), &[0.0, 1.0, 2.0]);
        let s = t.select(&[0, 2]).unwrap();
        assert_eq!(s.positions()[1].x, 1.0);
        assert!(t.select(&[3]).is_err());
        assert_eq!(t.scaled(2.0).positions()[1].x, 6.0);
    }
}
