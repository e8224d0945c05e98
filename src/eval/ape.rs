//! Absolute pose error (APE), as evo's `metrics.APE`.

use super::{ErrorStats, EvalError};
use crate::trajectory::Trajectory;

/// Which part of the pose error becomes the scalar error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PoseRelation {
    /// Distance between the camera centres, metres (evo `-r trans_part`).
    Translation,
    /// Angle of the rotation error, degrees (evo `-r angle_deg`).
    RotationAngleDeg,
}

impl PoseRelation {
    /// Unit of the errors.
    pub fn unit(self) -> &'static str {
        match self {
            PoseRelation::Translation => "m",
            PoseRelation::RotationAngleDeg => "deg",
        }
    }
}

/// Per-pose errors and their statistics.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PoseErrors {
    pub relation: PoseRelation,
    /// One error per pose (APE) or per pose pair (RPE), in `relation`'s unit.
    pub errors: Vec<f64>,
    pub stats: ErrorStats,
}

/// APE of `estimate` against `reference`, paired by index (associate and
/// align first). Translation: `|t_est - t_ref|`; rotation: the angle of
/// `est^-1 * ref`.
pub fn ape(
    reference: &Trajectory,
    estimate: &Trajectory,
    relation: PoseRelation,
) -> Result<PoseErrors, EvalError> {
    if reference.len() != estimate.len() {
        return Err(EvalError::LengthMismatch {
            reference: reference.len(),
            estimate: estimate.len(),
        });
    }
    let errors: Vec<f64> = reference
        .poses()
        .iter()
        .zip(estimate.poses())
        .map(|(r, e)| match relation {
            PoseRelation::Translation => (e.translation.vector - r.translation.vector).norm(),
            PoseRelation::RotationAngleDeg => e.rotation.angle_to(&r.rotation).to_degrees(),
        })
        .collect();
    let stats = ErrorStats::from_errors(&errors).ok_or(EvalError::Empty)?;
    Ok(PoseErrors {
        relation,
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
    fn hand_computed_three_poses() {
        let p = |x: f64, y: f64, yaw_deg: f64| {
            Pose::from_parts(
                Translation3::new(x, y, 0.0),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians()),
            )
        };
        let reference =
            Trajectory::from_poses(vec![p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(2.0, 0.0, 0.0)])
                .unwrap();
        let estimate = Trajectory::from_poses(vec![
            p(0.0, 0.0, 10.0),
            p(1.0, 3.0, 0.0),
            p(6.0, 3.0, -30.0),
        ])
        .unwrap();
        // Errors 0, 3, 5 m: mean 8/3, sse 34, rmse sqrt(34/3).
        let t = ape(&reference, &estimate, PoseRelation::Translation).unwrap();
        assert_eq!(t.errors, vec![0.0, 3.0, 5.0]);
        assert!((t.stats.rmse - (34.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(t.stats.median, 3.0);
        let var = ((8.0f64 / 3.0).powi(2) + (1.0f64 / 3.0).powi(2) + (7.0f64 / 3.0).powi(2)) / 3.0;
        assert!((t.stats.std - var.sqrt()).abs() < 1e-12);
        let r = ape(&reference, &estimate, PoseRelation::RotationAngleDeg).unwrap();
        for (a, b) in r.errors.iter().zip([10.0, 0.0, 30.0]) {
            assert!((a - b).abs() < 1e-9, "{a} vs {b}");
        }
        let short = Trajectory::from_poses(vec![p(0.0, 0.0, 0.0)]).unwrap();
        assert!(matches!(
            ape(&reference, &short, PoseRelation::Translation),
            Err(EvalError::LengthMismatch { .. })
        ));
    }
}
