//! Input option 2: points with features into voxels.

use nalgebra::Vector3;

use super::{Feature, IntegrationStats};
use crate::map::{FeatureDbError, Integrator};

/// Adds `points` (world frame, metres) with known rows (`None`: no
/// feature), in parallel.
pub fn integrate_point_rows(
    integ: &mut Integrator,
    points: &[[f64; 3]],
    rows: &[Option<u32>],
) -> IntegrationStats {
    let before = integ.rejected();
    let integrated = integ.add_rows_batch(points, rows);
    let skipped = rows.iter().filter(|r| r.is_none()).count();
    IntegrationStats {
        offered: points.len(),
        integrated,
        skipped,
        rejected: integ.rejected() - before,
    }
}

/// Adds `points` (world frame, metres) with `feature(i)` for point `i`.
pub fn integrate_points<'a>(
    integ: &mut Integrator,
    points: &[[f64; 3]],
    feature: impl Fn(usize) -> Feature<'a>,
) -> Result<IntegrationStats, FeatureDbError> {
    let mut s = IntegrationStats {
        offered: points.len(),
        ..Default::default()
    };
    for (i, p) in points.iter().enumerate() {
        s.add(integ, &Vector3::from(*p), feature(i))?;
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::{FeatureDb, GridSpec};

    #[test]
    fn row_batches_count_like_single_points() {
        let table = FeatureDb::from_rows(2, 0.02, vec![1.0, 0.0, 0.0, 1.0]).unwrap();
        let grid = GridSpec {
            resolution: 0.5,
            origin: Vector3::zeros(),
        };
        let mut it = Integrator::new(grid, table).unwrap();
        let pts = [
            [0.1, 0.1, 0.1],
            [0.2, 0.4, 0.3],
            [f64::NAN, 0.0, 0.0],
            [0.0; 3],
            [1.0; 3],
        ];
        let rows = [Some(0), Some(1), Some(1), None, Some(5)];
        let s = integrate_point_rows(&mut it, &pts, &rows);
        assert_eq!(
            (s.offered, s.integrated, s.skipped, s.rejected),
            (5, 2, 1, 2)
        );
        assert_eq!(it.voxel_count(), 1);
    }

    #[test]
    fn points_land_in_their_voxels_with_their_rows() {
        let table = FeatureDb::from_rows(2, 0.02, vec![1.0, 0.0, 0.0, 1.0]).unwrap();
        let grid = GridSpec {
            resolution: 0.5,
            origin: Vector3::new(-1.0, -1.0, 0.0),
        };
        let mut it = Integrator::new(grid, table).unwrap();
        let pts = [
            [0.1, 0.1, 0.1],
            [0.2, 0.4, 0.3],
            [2.0, 0.0, 0.0],
            [f64::NAN, 0.0, 0.0],
            [0.0; 3],
        ];
        let labels = [0u32, 0, 1, 1, 9];
        let s = integrate_points(&mut it, &pts, |i| match labels[i] {
            9 => Feature::Unknown,
            l => Feature::Row(l),
        })
        .unwrap();
        assert_eq!(
            (s.offered, s.integrated, s.skipped, s.rejected),
            (5, 3, 1, 1)
        );
        let m = it.finish("t", 0.02).unwrap();
        assert_eq!(m.len(), 2);
        // (0.1, 0.1, 0.1) - origin = (1.1, 1.1, 0.1) -> cell (2, 2, 0).
        let a = m.find([2, 2, 0]).unwrap();
        let b = m.find([6, 2, 0]).unwrap();
        assert_eq!(m.db().row(m.rows()[a] as usize), &[1.0, 0.0]);
        assert_eq!(m.db().row(m.rows()[b] as usize), &[0.0, 1.0]);
    }
}
