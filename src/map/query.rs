//! Open-vocabulary queries: how similar each voxel is to a set of words.
//!
//! A voxel's feature is its database row, so similarities are computed once
//! per row and prompt (`K x P` dot products) and then looked up per voxel;
//! a million-voxel map costs a table look-up a voxel.

use super::features::FeatureDb;
use super::octree::{LanguageMap, MapError};

/// Each voxel's best cosine similarity to any of `prompts` (one row a word,
/// in the map's feature space), in leaf order.
pub fn best_similarity(map: &LanguageMap, prompts: &FeatureDb) -> Result<Vec<f32>, MapError> {
    let mut per_row = vec![f32::NEG_INFINITY; map.db().len()];
    for p in 0..prompts.len() {
        let s = map.db().similarities(prompts.row(p))?;
        for (b, s) in per_row.iter_mut().zip(s) {
            *b = b.max(s);
        }
    }
    Ok(map.rows().iter().map(|&r| per_row[r as usize]).collect())
}

/// How many of `scores` exceed `fraction` of their maximum (the query's
/// "within 10 % of the best" with `fraction` 0.9). The maximum is taken
/// once: linear in the number of scores.
pub fn count_near_best(scores: &[f32], fraction: f32) -> usize {
    let best = scores.iter().copied().fold(f32::MIN, f32::max);
    let bar = fraction * best;
    scores.iter().filter(|&&s| s > bar).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::key::GridSpec;
    use nalgebra::Vector3;

    #[test]
    fn voxel_scores_match_a_direct_computation() {
        let deg = |a: f32| [a.to_radians().cos(), a.to_radians().sin(), 0.0];
        let rows: Vec<f32> = [0.0, 40.0, 90.0].iter().flat_map(|&a| deg(a)).collect();
        let db = FeatureDb::from_rows(3, 0.01, rows).unwrap();
        let grid = GridSpec {
            resolution: 0.1,
            origin: Vector3::zeros(),
        };
        let cells = [
            ([0, 0, 0], 2),
            ([1, 0, 0], 0),
            ([2, 0, 0], 1),
            ([3, 0, 0], 2),
        ];
        let map = LanguageMap::from_cells(grid, db, "t", cells).unwrap();
        let words: Vec<f32> = [10.0, 80.0].iter().flat_map(|&a| deg(a)).collect();
        let prompts = FeatureDb::from_rows(3, 0.01, words).unwrap();
        let got = best_similarity(&map, &prompts).unwrap();
        // Direct: every voxel's row against every word.
        let want: Vec<f32> = map
            .rows()
            .iter()
            .map(|&r| {
                (0..prompts.len())
                    .map(|p| crate::map::features::dot(map.db().row(r as usize), prompts.row(p)))
                    .fold(f32::NEG_INFINITY, f32::max)
            })
            .collect();
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).abs() < 1e-6, "{got:?} {want:?}");
        }
        // Row 0 (0 deg) and row 1 (40 deg) are 10 and 30 deg from a word,
        // row 2 (90 deg) 10 deg: cos 10 = 0.985, cos 30 = 0.866.
        assert_eq!(count_near_best(&got, 0.9), 3);
        assert_eq!(count_near_best(&got, 0.8), 4);
        // Against the old per-element definition.
        let slow = got
            .iter()
            .filter(|&&s| s > 0.9 * got.iter().copied().fold(f32::MIN, f32::max))
            .count();
        assert_eq!(count_near_best(&got, 0.9), slow);
        // A prompt of another dimension is an error.
        let bad = FeatureDb::from_rows(2, 0.01, vec![1.0, 0.0]).unwrap();
        assert!(best_similarity(&map, &bad).is_err());
    }
}
