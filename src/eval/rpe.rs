//! Relative pose error (RPE) over a fixed frame delta, as evo's
//! `metrics.RPE` with `delta_unit = frames`.

use super::ape::{PoseErrors, PoseRelation};
use super::{ErrorStats, EvalError};
use crate::trajectory::Trajectory;

/// Which pose pairs are compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RpeOptions {
    pub relation: PoseRelation,
    /// Frame distance between the poses of a pair (evo `--delta`,
    /// `--delta_unit f`); at least 1.
    pub delta: usize,
    /// All pairs `(i, i + delta)` for every `i` instead of consecutive
    /// non-overlapping ones `(0, delta), (delta, 2 delta), ...`
    /// (evo `--all_pairs`).
    pub all_pairs: bool,
}

impl Default for RpeOptions {
    fn default() -> Self {
        RpeOptions {
            relation: PoseRelation::Translation,
            delta: 1,
            all_pairs: false,
        }
    }
}

/// The index pairs evo's `filter_pairs_by_index` produces for `n` poses.
pub fn pairs_by_index(n: usize, delta: usize, all_pairs: bool) -> Vec<(usize, usize)> {
    if delta == 0 {
        return Vec::new();
    }
    if all_pairs {
        (0..n.saturating_sub(delta))
            .map(|i| (i, i + delta))
            .collect()
    } else {
        (0..n)
            .step_by(delta)
            .zip((0..n).step_by(delta).skip(1))
            .collect()
    }
}

/// RPE of `estimate` against `reference`, paired by index. For a pair
/// `(i, j)` the error pose is `(Q_i^-1 Q_j)^-1 (P_i^-1 P_j)` (reference `Q`,
/// estimate `P`, as in the TUM RGB-D benchmark and evo); its translation norm
/// (metres) or rotation angle (degrees) is the error.
pub fn rpe(
    reference: &Trajectory,
    estimate: &Trajectory,
    options: &RpeOptions,
) -> Result<PoseErrors, EvalError> {
    if reference.len() != estimate.len() {
        return Err(EvalError::LengthMismatch {
            reference: reference.len(),
            estimate: estimate.len(),
        });
    }
    let pairs = pairs_by_index(reference.len(), options.delta, options.all_pairs);
    if pairs.is_empty() {
        return Err(EvalError::NoPairs {
            delta: options.delta,
            poses: reference.len(),
        });
    }
    let (q, p) = (reference.poses(), estimate.poses());
    let errors: Vec<f64> = pairs
        .iter()
        .map(|&(i, j)| {
            let q_rel = q[i].inverse() * q[j];
            let p_rel = p[i].inverse() * p[j];
            let e = q_rel.inverse() * p_rel;
            match options.relation {
                PoseRelation::Translation => e.translation.vector.norm(),
                PoseRelation::RotationAngleDeg => e.rotation.angle().to_degrees(),
            }
        })
        .collect();
    let stats = ErrorStats::from_errors(&errors).ok_or(EvalError::Empty)?;
    Ok(PoseErrors {
        relation: options.relation,
        errors,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    #[test]
    fn pairs_like_evo() {
        assert_eq!(pairs_by_index(5, 2, false), vec![(0, 2), (2, 4)]);
        assert_eq!(pairs_by_index(6, 2, false), vec![(0, 2), (2, 4)]);
        assert_eq!(pairs_by_index(5, 2, true), vec![(0, 2), (1, 3), (2, 4)]);
        assert_eq!(pairs_by_index(2, 3, true), vec![]);
    }

    #[test]
    fn hand_computed_three_poses() {
        let p = |x: f64, y: f64, yaw_deg: f64| {
            Pose::from_parts(
                Translation3::new(x, y, 0.0),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians()),
            )
        };
        // Reference drives 1 m along x per frame, heading x.
        let reference =
            Trajectory::from_poses(vec![p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(2.0, 0.0, 0.0)])
                .unwrap();
        // Estimate: frame 0 at the origin heading +y (90 deg); it moves 2 m
        // along its own heading, then turns to heading +x without moving.
        let estimate =
            Trajectory::from_poses(vec![p(0.0, 0.0, 90.0), p(0.0, 2.0, 90.0), p(0.0, 2.0, 0.0)])
                .unwrap();
        // Pair (0,1): reference moves (1,0,0) in its own frame, estimate
        // (2,0,0) in its own: error translation 1 m, no rotation.
        // Pair (1,2): reference (1,0,0), estimate none but a -90 deg turn:
        // E = Q_rel^-1 P_rel has translation -(1,0,0): 1 m; angle 90 deg.
        let t = rpe(&reference, &estimate, &RpeOptions::default()).unwrap();
        assert!((t.errors[0] - 1.0).abs() < 1e-12 && (t.errors[1] - 1.0).abs() < 1e-12);
        let r = rpe(
            &reference,
            &estimate,
            &RpeOptions {
                relation: PoseRelation::RotationAngleDeg,
                ..RpeOptions::default()
            },
        )
        .unwrap();
        assert!(r.errors[0].abs() < 1e-9 && (r.errors[1] - 90.0).abs() < 1e-9);
        // delta 2: reference moves (2,0,0); the estimate (2,0,0) in frame 0's
        // heading (+y) then ends heading x: relative translation (2,0,0) in
        // frame 0: error 0 m.
        let d2 = rpe(
            &reference,
            &estimate,
            &RpeOptions {
                delta: 2,
                ..RpeOptions::default()
            },
        )
        .unwrap();
        assert_eq!(d2.errors.len(), 1);
        assert!(d2.errors[0].abs() < 1e-12);
        assert!(matches!(
            rpe(
                &reference,
                &estimate,
                &RpeOptions {
                    delta: 3,
                    ..RpeOptions::default()
                }
            ),
            Err(EvalError::NoPairs { .. })
        ));
    }
}
