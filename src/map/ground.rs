//! Semantic grounding: the database is replaced by the features of user
//! prompts, every voxel is remapped to its most similar prompt, and voxels
//! whose best similarity is below a threshold are dropped (the paper's
//! discard step).

use super::features::{FeatureDb, dot};
use super::octree::{LanguageMap, MapError};

/// What grounding did.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundingReport {
    /// Rows before and after.
    pub old_rows: usize,
    pub new_rows: usize,
    /// Leaves kept and dropped.
    pub kept: usize,
    pub dropped: usize,
    /// For every old row: the prompt it maps to and the similarity, or
    /// `None` when it was dropped.
    pub row_map: Vec<Option<(u32, f32)>>,
}

/// Grounds `map` on `prompts` (one row per prompt, in the map's feature
/// space): every old row maps to the prompt with the highest cosine
/// similarity; rows whose best similarity is below `min_similarity` are
/// discarded with their voxels.
pub fn ground(
    map: &mut LanguageMap,
    prompts: &FeatureDb,
    min_similarity: f32,
) -> Result<GroundingReport, MapError> {
    let old = map.db();
    if prompts.dim() != old.dim() {
        return Err(MapError::Features(
            super::features::FeatureDbError::DimMismatch {
                expected: old.dim(),
                got: prompts.dim(),
            },
        ));
    }
    let row_map: Vec<Option<(u32, f32)>> = (0..old.len())
        .map(|r| {
            let f = old.row(r);
            (0..prompts.len())
                .map(|p| (p as u32, dot(f, prompts.row(p))))
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .filter(|&(_, s)| s >= min_similarity)
        })
        .collect();
    let mut codes = Vec::with_capacity(map.len());
    let mut rows = Vec::with_capacity(map.len());
    for (&c, &r) in map.codes().iter().zip(map.rows()) {
        if let Some((p, _)) = row_map[r as usize] {
            codes.push(c);
            rows.push(p);
        }
    }
    let report = GroundingReport {
        old_rows: old.len(),
        new_rows: prompts.len(),
        kept: codes.len(),
        dropped: map.len() - codes.len(),
        row_map,
    };
    let new_db = FeatureDb::from_rows(prompts.dim(), old.tau(), prompts.rows().to_vec())?;
    map.replace(new_db, codes, rows);
    Ok(report)
}

/// Which of `classes` (one row a class, in the map's feature space) each
/// row of `db` stands for: a class's feature goes to its nearest row when
/// within the database's tau of it, as building the map admitted it, so a
/// row can stand for several classes (SemanticKITTI's moving car shares
/// the car's feature) or none (a row of another origin). Indices into
/// `classes`, ascending, for every row of `db`.
pub fn classes_of_rows(db: &FeatureDb, classes: &FeatureDb) -> Result<Vec<Vec<usize>>, MapError> {
    if classes.dim() != db.dim() {
        return Err(MapError::Features(
            super::features::FeatureDbError::DimMismatch {
                expected: db.dim(),
                got: classes.dim(),
            },
        ));
    }
    let mut out = vec![Vec::new(); db.len()];
    for c in 0..classes.len() {
        let nearest = db.nearest(classes.row(c)).map_err(MapError::Features)?;
        if let Some((row, sim)) = nearest
            && 1.0 - sim <= db.tau() + 1e-6
        {
            out[row].push(c);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::key::GridSpec;
    use nalgebra::Vector3;

    #[test]
    fn rows_are_named_by_the_classes_within_tau() {
        let deg = |a: f32| [a.to_radians().cos(), a.to_radians().sin(), 0.0];
        let rows = |angles: &[f32]| angles.iter().flat_map(|&a| deg(a)).collect::<Vec<f32>>();
        // tau 0.02 is about 11.5 degrees of cosine distance.
        let db = FeatureDb::from_rows(3, 0.02, rows(&[0.0, 40.0, 90.0])).unwrap();
        // Class 0 is row 1's; classes 1 (0 deg) and 3 (5 deg) share row
        // 0; class 2 (65 deg) is 25 degrees from any row: none.
        let classes = FeatureDb::from_rows(3, 0.0, rows(&[40.0, 0.0, 65.0, 5.0])).unwrap();
        assert_eq!(
            classes_of_rows(&db, &classes).unwrap(),
            vec![vec![1, 3], vec![0], vec![]]
        );
        let other = FeatureDb::from_rows(2, 0.0, vec![1.0, 0.0]).unwrap();
        assert!(classes_of_rows(&db, &other).is_err());
    }

    #[test]
    fn remaps_to_most_similar_prompt_and_drops_the_rest() {
        // Old rows at 0, 40 and 90 degrees in the plane; prompts at 10 and 60.
        let deg = |a: f32| [a.to_radians().cos(), a.to_radians().sin(), 0.0];
        let old: Vec<f32> = [0.0, 40.0, 90.0].iter().flat_map(|&a| deg(a)).collect();
        let db = FeatureDb::from_rows(3, 0.02, old).unwrap();
        let grid = GridSpec {
            resolution: 1.0,
            origin: Vector3::zeros(),
        };
        let mut map = LanguageMap::from_cells(
            grid,
            db,
            "t",
            vec![
                ([0, 0, 0], 0),
                ([1, 0, 0], 1),
                ([2, 0, 0], 2),
                ([3, 0, 0], 2),
            ],
        )
        .unwrap();
        let prompts =
            FeatureDb::from_rows(3, 0.0, [10.0, 60.0].iter().flat_map(|&a| deg(a)).collect())
                .unwrap();
        // cos(30) = 0.866 for row 2 -> prompt 1: below 0.9, dropped.
        let rep = ground(&mut map, &prompts, 0.9).unwrap();
        assert_eq!(rep.row_map[0].unwrap().0, 0);
        assert_eq!(
            rep.row_map[1].unwrap().0,
            1,
            "40 deg is 20 from 60, 30 from 10"
        );
        assert!(rep.row_map[2].is_none());
        assert_eq!((rep.kept, rep.dropped), (2, 2));
        assert_eq!(map.len(), 2);
        assert_eq!(map.db().len(), 2);
        assert_eq!(map.rows()[map.find([1, 0, 0]).unwrap()], 1);
        assert_eq!(map.find([2, 0, 0]), None);
    }

    #[test]
    fn dimension_mismatch_is_an_error() {
        let db = FeatureDb::from_rows(3, 0.02, vec![1.0, 0.0, 0.0]).unwrap();
        let grid = GridSpec {
            resolution: 1.0,
            origin: Vector3::zeros(),
        };
        let mut map = LanguageMap::from_cells(grid, db, "t", vec![([0, 0, 0], 0)]).unwrap();
        let prompts = FeatureDb::from_rows(2, 0.0, vec![1.0, 0.0]).unwrap();
        assert!(ground(&mut map, &prompts, 0.0).is_err());
        assert_eq!(map.len(), 1, "a failed grounding leaves the map unchanged");
    }
}
