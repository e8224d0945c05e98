//! Aligning an estimated trajectory to a reference before measuring absolute
//! error: Umeyama's least-squares rigid (SE(3)) or similarity (Sim(3))
//! transform, or evo's origin alignment.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::EvalError;
use crate::geometry::Pose;
use crate::trajectory::Trajectory;

/// How the estimate is brought into the reference frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Alignment {
    /// Compare as given.
    None,
    /// Umeyama rotation and translation (evo `--align`).
    Se3,
    /// Umeyama rotation, translation and scale (evo `--align --correct_scale`).
    Sim3,
    /// Left-multiply the estimate by `ref_0 * est_0^-1` so that the first
    /// poses coincide (evo `--align_origin`).
    Origin,
}

/// `y = scale * rotation * x + translation` (reference from estimate).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Similarity {
    pub rotation: Rotation3<f64>,
    /// Metres, reference frame.
    pub translation: Vector3<f64>,
    /// Dimensionless; 1 for rigid alignments.
    pub scale: f64,
}

impl Similarity {
    /// The rotation's angle in radians, 0 for a rotation that rounding put
    /// a hair past the identity (nalgebra's `Rotation3::angle` takes the
    /// arc cosine of a trace over 3 there: NaN).
    pub fn rotation_angle(&self) -> f64 {
        ((self.rotation.matrix().trace() - 1.0) / 2.0)
            .clamp(-1.0, 1.0)
            .acos()
    }

    /// The identity transform.
    pub fn identity() -> Self {
        Similarity {
            rotation: Rotation3::identity(),
            translation: Vector3::zeros(),
            scale: 1.0,
        }
    }

    /// Maps an estimated trajectory into the reference frame: positions
    /// become `s R p + t`, orientations `R R_p` (evo scales the translations,
    /// then applies the rigid part).
    pub fn apply(&self, trajectory: &Trajectory) -> Trajectory {
        let rigid = Pose::from_parts(self.translation.into(), self.rotation.into());
        trajectory.scaled(self.scale).transformed(&rigid)
    }
}

/// The transform applied by [`align_trajectory`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AlignmentResult {
    pub alignment: Alignment,
    /// Number of leading pose pairs the transform was fitted to (0 for none).
    pub poses_used: usize,
    pub reference_from_estimate: Similarity,
}

/// Umeyama (1991): the `s, R, t` minimizing `sum |y_i - (s R x_i + t)|^2`
/// over rotations `R` (and scales `s` when `with_scale`, else `s = 1`).
/// Follows evo's `geometry.umeyama_alignment` step by step, including its
/// degeneracy test (fewer than 2 singular values of the covariance above
/// machine epsilon).
pub fn umeyama(
    x: &[Vector3<f64>],
    y: &[Vector3<f64>],
    with_scale: bool,
) -> Result<Similarity, EvalError> {
    if x.len() != y.len() {
        return Err(EvalError::LengthMismatch {
            reference: y.len(),
            estimate: x.len(),
        });
    }
    if x.is_empty() {
        return Err(EvalError::Empty);
    }
    let n = x.len() as f64;
    let mean_x = x.iter().sum::<Vector3<f64>>() / n;
    let mean_y = y.iter().sum::<Vector3<f64>>() / n;
    let sigma_x = x.iter().map(|p| (p - mean_x).norm_squared()).sum::<f64>() / n;
    let mut cov = Matrix3::zeros();
    for (px, py) in x.iter().zip(y) {
        cov += (py - mean_y) * (px - mean_x).transpose();
    }
    cov /= n;
    // Sorted singular values, largest first, as numpy returns them.
    let svd = cov.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(EvalError::DegenerateAlignment);
    };
    let d = svd.singular_values;
    if d.iter().filter(|&&v| v > f64::EPSILON).count() < 2 {
        return Err(EvalError::DegenerateAlignment);
    }
    let mut s = Matrix3::identity();
    if u.determinant() * v_t.determinant() < 0.0 {
        // Keep a right-handed frame (Kabsch): flip the weakest direction.
        s[(2, 2)] = -1.0;
    }
    let r = u * s * v_t;
    let scale = if with_scale {
        (Matrix3::from_diagonal(&d) * s).trace() / sigma_x
    } else {
        1.0
    };
    let translation = mean_y - scale * (r * mean_x);
    Ok(Similarity {
        rotation: Rotation3::from_matrix_unchecked(r),
        translation,
        scale,
    })
}

/// How far `points` are from lying on one line: the second largest over
/// the largest singular value of their centred scatter, in `[0, 1]` (0 for
/// points on a line or fewer than two distinct points). A rigid alignment
/// fitted to nearly collinear positions leaves the rotation about that
/// line to noise.
pub fn off_line(points: &[Vector3<f64>]) -> f64 {
    if points.len() < 2 {
        return 0.0;
    }
    let mean = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let mut scatter = Matrix3::zeros();
    for p in points {
        scatter += (p - mean) * (p - mean).transpose();
    }
    let mut d: Vec<f64> = scatter
        .symmetric_eigenvalues()
        .iter()
        .map(|v| v.max(0.0).sqrt())
        .collect();
    d.sort_by(|a, b| b.total_cmp(a));
    if d[0] <= 0.0 { 0.0 } else { d[1] / d[0] }
}

/// Aligns `estimate` to `reference` (equal length, paired by index).
/// `n_to_align` limits the Umeyama fit to the first `n` pairs (evo's
/// `--n_to_align`); the transform is then applied to the whole estimate.
pub fn align_trajectory(
    estimate: &Trajectory,
    reference: &Trajectory,
    alignment: Alignment,
    n_to_align: Option<usize>,
) -> Result<(Trajectory, AlignmentResult), EvalError> {
    if estimate.len() != reference.len() {
        return Err(EvalError::LengthMismatch {
            reference: reference.len(),
            estimate: estimate.len(),
        });
    }
    if estimate.is_empty() {
        return Err(EvalError::Empty);
    }
    let n = n_to_align.unwrap_or(estimate.len()).min(estimate.len());
    let (similarity, poses_used) = match alignment {
        Alignment::None => (Similarity::identity(), 0),
        Alignment::Se3 | Alignment::Sim3 => {
            let x = &estimate.positions()[..n];
            let y = &reference.positions()[..n];
            (umeyama(x, y, alignment == Alignment::Sim3)?, n)
        }
        Alignment::Origin => {
            let to_ref = reference.poses()[0] * estimate.poses()[0].inverse();
            let sim = Similarity {
                rotation: to_ref.rotation.to_rotation_matrix(),
                translation: to_ref.translation.vector,
                scale: 1.0,
            };
            (sim, 1)
        }
    };
    let aligned = similarity.apply(estimate);
    Ok((
        aligned,
        AlignmentResult {
            alignment,
            poses_used,
            reference_from_estimate: similarity,
        },
    ))
}

#[cfg(test)]
mod tests {
    #[test]
    fn off_line_tells_a_line_from_a_square() {
        let v = |x: f64, y: f64| Vector3::new(x, y, 0.0);
        assert!(off_line(&[v(0.0, 0.0), v(1.0, 0.0), v(2.0, 0.0)]) < 1e-9);
        assert!(
            (off_line(&[v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0), v(1.0, 1.0)]) - 1.0).abs() < 1e-9
        );
        // 1 cm off a 2 m line: about 0.01 / 1.4 of the spread along it.
        let r = off_line(&[v(0.0, 0.0), v(1.0, 0.01), v(2.0, 0.0)]);
        assert!(r > 1e-3 && r < 1e-2, "{r}");
        assert_eq!(off_line(&[v(1.0, 1.0)]), 0.0);
        assert_eq!(off_line(&[v(1.0, 1.0), v(1.0, 1.0)]), 0.0);
    }

    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn recovers_a_known_similarity() {
        let x = vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 2.0, 0.0),
            Vector3::new(0.0, 0.0, 3.0),
        ];
        let r = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.3)
            * Rotation3::from_axis_angle(&Vector3::x_axis(), -1.1);
        let t = Vector3::new(5.0, -2.0, 0.5);
        let y: Vec<_> = x.iter().map(|p| 2.5 * (r * p) + t).collect();
        let sim = umeyama(&x, &y, true).unwrap();
        assert!((sim.scale - 2.5).abs() < 1e-12);
        assert!((sim.rotation.matrix() - r.matrix()).abs().max() < 1e-12);
        assert!((sim.translation - t).norm() < 1e-12);
        // Without scale the rotation is still exact for a pure similarity.
        let rigid = umeyama(&x, &y, false).unwrap();
        assert!((rigid.rotation.matrix() - r.matrix()).abs().max() < 1e-12);
        assert_eq!(rigid.scale, 1.0);
    }

    #[test]
    fn hand_computed_two_points_and_a_third() {
        // x: (0,0,0), (2,0,0), (0,1,0) ; y = x rotated 90 deg about z and
        // shifted by (1,1,0): (1,1,0), (1,3,0), (0,1,0).
        let x = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(2.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
        ];
        let y = [
            Vector3::new(1.0, 1.0, 0.0),
            Vector3::new(1.0, 3.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
        ];
        let sim = umeyama(&x, &y, false).unwrap();
        let expected = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        assert!((sim.rotation.matrix() - expected).abs().max() < 1e-12);
        assert!((sim.translation - Vector3::new(1.0, 1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn the_rotation_angle_is_a_number_a_hair_past_the_identity() {
        let mut sim = Similarity::identity();
        // As an SE(3) fit of a pure shift left it (trace 3 + 1e-15).
        sim.rotation =
            Rotation3::from_matrix_unchecked(Matrix3::from_diagonal_element(1.0000000000000007));
        assert!(sim.rotation.angle().is_nan());
        assert_eq!(sim.rotation_angle(), 0.0);
        sim.rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.5);
        assert!((sim.rotation_angle() - 0.5).abs() < 1e-12);
        sim.rotation = Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        assert!((sim.rotation_angle() - std::f64::consts::PI).abs() < 1e-7);
    }

    #[test]
    fn collinear_points_are_degenerate() {
        let x: Vec<_> = (0..5).map(|i| Vector3::new(i as f64, 0.0, 0.0)).collect();
        assert_eq!(umeyama(&x, &x, false), Err(EvalError::DegenerateAlignment));
    }

    #[test]
    fn origin_alignment_makes_first_poses_equal() {
        let pose = |x: f64, yaw: f64| {
            Pose::from_parts(
                Translation3::new(x, 1.0, 0.0),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
            )
        };
        let reference = Trajectory::from_poses(vec![pose(0.0, 0.0), pose(1.0, 0.0)]).unwrap();
        let estimate = Trajectory::from_poses(vec![pose(5.0, 1.0), pose(6.0, 1.0)]).unwrap();
        let (aligned, res) =
            align_trajectory(&estimate, &reference, Alignment::Origin, None).unwrap();
        let d = aligned.poses()[0].inverse() * reference.poses()[0];
        assert!(d.translation.vector.norm() < 1e-12 && d.rotation.angle() < 1e-12);
        assert_eq!(res.poses_used, 1);
        // The estimate moved 1 m along world x while heading 1 rad, i.e.
        // (cos 1, -sin 1) in its own frame; origin alignment replays that
        // motion from the reference's first pose (heading 0).
        let expected = Vector3::new(1f64.cos(), 1.0 - 1f64.sin(), 0.0);
        assert!((aligned.positions()[1] - expected).norm() < 1e-12);
    }
}
