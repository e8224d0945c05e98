//! Time-stamp association of two trajectories, as evo's
//! `sync.associate_trajectories` with nearest-time matching.

use super::EvalError;
use crate::trajectory::Trajectory;

/// evo's default largest accepted stamp difference, seconds.
pub const DEFAULT_MAX_DIFF: f64 = 0.01;

/// For each stamp of `stamps_1` (in order) the index of the closest stamp of
/// `stamps_2 + offset_2`, kept when the two differ by at most `max_diff`
/// (seconds). Returns the matched indices into each list. On equal distance
/// the earlier stamp of `stamps_2` wins, as in evo. `stamps_2` must be sorted
/// (a [`Trajectory`]'s stamps are).
pub fn matching_time_indices(
    stamps_1: &[f64],
    stamps_2: &[f64],
    max_diff: f64,
    offset_2: f64,
) -> (Vec<usize>, Vec<usize>) {
    let shifted: Vec<f64> = stamps_2.iter().map(|s| s + offset_2).collect();
    let (mut ids_1, mut ids_2) = (Vec::new(), Vec::new());
    let (Some(&first), Some(&last)) = (shifted.first(), shifted.last()) else {
        return (ids_1, ids_2);
    };
    for (i1, &s1) in stamps_1.iter().enumerate() {
        if s1 < first - max_diff || s1 > last + max_diff {
            continue;
        }
        // numpy's searchsorted(side="right"): first index with a larger stamp.
        let i2 = shifted.partition_point(|&s| s <= s1).min(shifted.len() - 1);
        let diff_ub = shifted[i2] - s1;
        let diff_lb = if i2 > 0 {
            s1 - shifted[i2 - 1]
        } else {
            f64::INFINITY
        };
        let best = if diff_ub <= max_diff && diff_ub < diff_lb {
            i2
        } else if diff_lb <= max_diff && diff_lb <= diff_ub {
            i2 - 1
        } else {
            continue;
        };
        ids_1.push(i1);
        ids_2.push(best);
    }
    (ids_1, ids_2)
}

/// How many poses of `t` repeat the stamp of the pose before, and the
/// first such pose (0-based) with its stamp; `None` when every stamp is
/// distinct. Real files have them (TUM fr2/desk's ground truth, written
/// to 0.1 ms, has some); a file written with too few digits has many,
/// and time pairing then takes the last of each group, as evo 1.38.1
/// does (numpy's `searchsorted(side="right")`, the nearer neighbour below
/// winning ties).
pub fn repeated_stamps(t: &Trajectory) -> Option<(usize, usize, f64)> {
    let s = t.stamps();
    let first = s.windows(2).position(|w| w[0] == w[1])?;
    let n = s.windows(2).filter(|w| w[0] == w[1]).count();
    Some((n, first + 1, s[first]))
}

/// Keeps the poses of `first` and `second` whose stamps match within
/// `max_diff` seconds after adding `offset_2` seconds to `second`'s stamps,
/// returning two trajectories of equal length with paired poses at equal
/// indices (each keeps its own stamps).
///
/// As in evo, the shorter trajectory is the one walked through, so that none
/// of its poses is lost to a neighbour's better match. Poses sharing a
/// stamp pair as evo 1.38.1 pairs them: with the last of them
/// ([`repeated_stamps`] finds them, for a caller to say so).
pub fn associate(
    first: &Trajectory,
    second: &Trajectory,
    max_diff: f64,
    offset_2: f64,
) -> Result<(Trajectory, Trajectory), EvalError> {
    let second_longer = second.len() > first.len();
    let (short, long) = if second_longer {
        (first, second)
    } else {
        (second, first)
    };
    let offset = if second_longer { offset_2 } else { -offset_2 };
    let (ids_short, ids_long) =
        matching_time_indices(short.stamps(), long.stamps(), max_diff, offset);
    if ids_short.is_empty() {
        return Err(EvalError::NoMatches {
            max_diff,
            offset: offset_2,
        });
    }
    // Indices into sorted stamps found in order never decrease, so the
    // selections are valid trajectories; a failure here is a logic error
    // reported as no matches rather than a panic.
    let no_matches = |_| EvalError::NoMatches {
        max_diff,
        offset: offset_2,
    };
    let short = short.select(&ids_short).map_err(no_matches)?;
    let long = long.select(&ids_long).map_err(no_matches)?;
    Ok(if second_longer {
        (short, long)
    } else {
        (long, short)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use nalgebra::{Translation3, UnitQuaternion};

    fn traj(stamps: &[f64]) -> Trajectory {
        let poses = stamps
            .iter()
            .map(|&s| Pose::from_parts(Translation3::new(s, 0.0, 0.0), UnitQuaternion::identity()))
            .collect();
        Trajectory::new(stamps.to_vec(), poses).unwrap()
    }

    #[test]
    fn repeated_stamps_are_counted_and_pair_with_the_last() {
        let a = traj(&[0.0, 0.1, 0.2]);
        // Poses of one stamp told apart by y.
        let stamps = [0.0, 0.1, 0.1, 0.1, 0.2];
        let poses = (0..5)
            .map(|i| {
                let t = Translation3::new(stamps[i], i as f64, 0.0);
                Pose::from_parts(t, UnitQuaternion::identity())
            })
            .collect();
        let b = Trajectory::new(stamps.to_vec(), poses).unwrap();
        assert_eq!(repeated_stamps(&a), None);
        assert_eq!(repeated_stamps(&b), Some((2, 2, 0.1)));
        // As evo 1.38.1: the pose at 0.1 of `a` pairs with the last 0.1
        // of `b`, its fourth pose.
        let (ra, rb) = associate(&a, &b, 0.01, 0.0).unwrap();
        assert_eq!(ra.len(), 3);
        assert_eq!(rb.poses()[1], b.poses()[3]);
    }

    #[test]
    fn nearest_within_max_diff() {
        let a = [0.0, 1.0, 2.0, 3.0];
        let b = [0.004, 0.996, 1.02, 2.5, 3.01];
        let (i, j) = matching_time_indices(&a, &b, 0.01, 0.0);
        assert_eq!(i, vec![0, 1, 3]);
        assert_eq!(j, vec![0, 1, 4]);
        // An offset of +0.5 s moves b's 2.5 onto a's 3.0.
        let (i, j) = matching_time_indices(&a, &b, 0.01, 0.5);
        assert_eq!((i, j), (vec![3], vec![3]));
        // A tie goes to the earlier stamp.
        let (_, j) = matching_time_indices(&[1.0], &[0.5, 1.5], 0.6, 0.0);
        assert_eq!(j, vec![0]);
    }

    #[test]
    fn associate_walks_the_shorter() {
        let a = traj(&[0.0, 1.0, 2.0]);
        let b = traj(&[0.0, 0.5, 1.001, 1.5, 2.5]);
        let (x, y) = associate(&a, &b, 0.01, 0.0).unwrap();
        assert_eq!(x.stamps(), &[0.0, 1.0]);
        assert_eq!(y.stamps(), &[0.0, 1.001]);
        let (y2, x2) = associate(&b, &a, 0.01, 0.0).unwrap();
        assert_eq!((x2, y2), (x, y));
        assert!(matches!(
            associate(&a, &traj(&[10.0]), 0.01, 0.0),
            Err(EvalError::NoMatches { .. })
        ));
    }
}
