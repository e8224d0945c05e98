//! Relative pose error (RPE) over a fixed delta in frames or metres of
//! travelled path, as evo's `metrics.RPE` (`delta_unit` `f` or `m`).

use super::ape::{PoseErrors, PoseRelation};
use super::{ErrorStats, EvalError};
use crate::trajectory::Trajectory;

/// The spacing of the two poses of a pair.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Delta {
    /// Frames (evo `--delta_unit f`); at least 1.
    Frames(usize),
    /// Metres of travelled path (evo `--delta_unit m`); accepted pairs are
    /// within 10 % of it in all-pairs mode (evo's `rel_delta_tol`).
    Meters(f64),
}

impl std::fmt::Display for Delta {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Delta::Frames(n) => write!(f, "{n} frames"),
            Delta::Meters(m) => write!(f, "{m} m"),
        }
    }
}

/// evo's relative tolerance on a metric delta in all-pairs mode.
pub const REL_DELTA_TOL: f64 = 0.1;

/// Which pose pairs are compared.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RpeOptions {
    pub relation: PoseRelation,
    pub delta: Delta,
    /// All pairs `(i, j)` for every start `i` instead of consecutive
    /// non-overlapping ones `(0, j1), (j1, j2), ...` (evo `--all_pairs`).
    pub all_pairs: bool,
    /// Measure path deltas on the reference instead of the estimate (evo's
    /// default is the estimate, `--pairs_from_reference` switches).
    pub pairs_from_reference: bool,
}

impl Default for RpeOptions {
    fn default() -> Self {
        RpeOptions {
            relation: PoseRelation::Translation,
            delta: Delta::Frames(1),
            all_pairs: false,
            pairs_from_reference: false,
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

/// The index pairs evo's `filter_pairs_by_path` produces: consecutive pairs
/// end at the first pose whose path from the pair's start reaches `delta`
/// metres; all-pairs mode pairs every pose with the later pose whose path
/// distance is closest to `delta` (the first on ties) if within `tol`.
pub fn pairs_by_path(
    trajectory: &Trajectory,
    delta: f64,
    tol: f64,
    all_pairs: bool,
) -> Vec<(usize, usize)> {
    let poses = trajectory.poses();
    let mut pairs = Vec::new();
    if poses.is_empty() || delta.is_nan() || delta <= 0.0 {
        return pairs;
    }
    if all_pairs {
        let dist = trajectory.path_lengths();
        for i in 0..dist.len() - 1 {
            let mut best: Option<(usize, f64)> = None;
            for (j, d) in dist.iter().enumerate().skip(i + 1) {
                let off = ((d - dist[i]) - delta).abs();
                if best.is_none_or(|(_, b)| off < b) {
                    best = Some((j, off));
                }
            }
            if let Some((j, off)) = best
                && off <= tol
            {
                pairs.push((i, j));
            }
        }
    } else {
        let mut start = 0;
        let mut path = 0.0;
        for j in 1..poses.len() {
            path += (poses[j].translation.vector - poses[j - 1].translation.vector).norm();
            if path >= delta {
                pairs.push((start, j));
                start = j;
                path = 0.0;
            }
        }
    }
    pairs
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
    let pairs = match options.delta {
        Delta::Frames(n) => pairs_by_index(reference.len(), n, options.all_pairs),
        Delta::Meters(m) => {
            let on = if options.pairs_from_reference {
                reference
            } else {
                estimate
            };
            pairs_by_path(on, m, m * REL_DELTA_TOL, options.all_pairs)
        }
    };
    if pairs.is_empty() {
        return Err(EvalError::NoPairs {
            delta: options.delta.to_string(),
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
        // Path 0, 1, 3, 3.5, 6 m (steps 1, 2, 0.5, 2.5).
        let xs = [0.0, 1.0, 3.0, 3.5, 6.0];
        let t = Trajectory::from_poses(
            xs.iter()
                .map(|&x| {
                    Pose::from_parts(Translation3::new(x, 0.0, 0.0), UnitQuaternion::identity())
                })
                .collect(),
        )
        .unwrap();
        // Consecutive, 2 m: 0->2 (3 m), then 2->4 (3 m).
        assert_eq!(pairs_by_path(&t, 2.0, 0.2, false), vec![(0, 2), (2, 4)]);
        // All pairs, 2.5 m within 0.25: 0->2 (3, off 0.5: no); 1->2 (2 m,
        // off 0.5) vs 1->3 (2.5): 1->3; 2->4 (3 m) vs 2->3 (0.5): 4, off
        // 0.5: no; 3->4 (2.5): yes.
        assert_eq!(pairs_by_path(&t, 2.5, 0.25, true), vec![(1, 3), (3, 4)]);
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
                delta: Delta::Frames(2),
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
                    delta: Delta::Frames(3),
                    ..RpeOptions::default()
                }
            ),
            Err(EvalError::NoPairs { .. })
        ));
    }
}
