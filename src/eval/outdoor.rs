//! The outdoor metric of the paper's Table IV (after CMRNext): for every
//! frame the translation error `|t_est - t_gt|` (metres) and the rotation
//! error, the angle of `R_gt^T R_est` (degrees), of camera 2; mean and
//! standard deviation over all frames, with the completion rule of
//! [`CompletionRule`] reported beside them.

use super::{CompletionRule, ErrorStats, EvalError};
use crate::geometry::Pose;

/// Table IV's numbers for one run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OutdoorMetric {
    /// Translation error per frame, metres.
    pub translation_m: Vec<f64>,
    /// Rotation error per frame, degrees.
    pub rotation_deg: Vec<f64>,
    /// Statistics of `translation_m` (mean, std as population std, ...).
    pub translation: ErrorStats,
    /// Statistics of `rotation_deg`.
    pub rotation: ErrorStats,
    /// Whether the run completes under [`CompletionRule::default`] (after
    /// the first 10 frames the translation error never exceeds 1 m for
    /// more than 5 consecutive frames); `None` for a run too short for the
    /// rule to fail ([`CompletionRule::judge`]).
    pub completed: Option<bool>,
}

/// Per-frame errors of `estimate` against `reference` (both
/// `world_from_camera`, the same frames in the same order).
pub fn outdoor_metric(reference: &[Pose], estimate: &[Pose]) -> Result<OutdoorMetric, EvalError> {
    if reference.len() != estimate.len() {
        return Err(EvalError::LengthMismatch {
            reference: reference.len(),
            estimate: estimate.len(),
        });
    }
    let translation_m: Vec<f64> = reference
        .iter()
        .zip(estimate)
        .map(|(g, e)| (e.translation.vector - g.translation.vector).norm())
        .collect();
    let rotation_deg: Vec<f64> = reference
        .iter()
        .zip(estimate)
        .map(|(g, e)| g.rotation.angle_to(&e.rotation).to_degrees())
        .collect();
    let stats = |v: &[f64]| ErrorStats::from_errors(v).ok_or(EvalError::Empty);
    Ok(OutdoorMetric {
        translation: stats(&translation_m)?,
        rotation: stats(&rotation_deg)?,
        completed: CompletionRule::default().judge(&translation_m),
        translation_m,
        rotation_deg,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    #[test]
    fn errors_of_known_offsets() {
        let gt: Vec<Pose> = (0..3)
            .map(|i| {
                Pose::from_parts(
                    Translation3::new(i as f64, 0.0, 0.0),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3 * i as f64),
                )
            })
            .collect();
        // Offsets 0, 3-4-5 (5 m) and 1 m; rotations 0, 10 and 20 degrees
        // about different axes.
        let est = vec![
            gt[0],
            gt[1]
                * Pose::from_parts(
                    Translation3::new(0.0, 0.0, 0.0),
                    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 10f64.to_radians()),
                ),
            gt[2],
        ];
        let mut est = est;
        est[1].translation.vector += Vector3::new(3.0, 4.0, 0.0);
        est[2].translation.vector += Vector3::new(0.0, 0.0, 1.0);
        est[2].rotation =
            gt[2].rotation * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.349_065_850_4);
        let m = outdoor_metric(&gt, &est).unwrap();
        assert!((m.translation_m[1] - 5.0).abs() < 1e-12);
        assert!((m.translation.mean - 2.0).abs() < 1e-12);
        // Population std of (0, 5, 1): sqrt((4 + 9 + 1) / 3).
        assert!((m.translation.std - (14.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert!((m.rotation_deg[1] - 10.0).abs() < 1e-9);
        assert!((m.rotation_deg[2] - 20.0).abs() < 1e-6);
        assert!((m.rotation.mean - 10.0).abs() < 1e-6);
        // Three frames: too few for the rule to fail, not judged.
        assert_eq!(m.completed, None);
        assert!(outdoor_metric(&gt, &est[..2]).is_err());
        assert!(outdoor_metric(&[], &[]).is_err());
    }
}
