//! Per-frame feature sources a session consumes: a label image looked up in
//! a class table bound to the map ([`LabelTable`] as the crate's one
//! [`LabelImage`]'s lookup), and a dense `h x w x F` feature grid at any
//! resolution. Both check their sizes when made, so a malformed frame is an
//! error before it reaches the filter.

use crate::frame::{LabelImage, LabelLookup};
use crate::io::labels::EmbeddingTable;
use crate::map::LanguageMap;
use crate::mapping::FeatureMap;

use super::SessionError;

/// A class table (label id -> feature) bound to a map: every row's nearest
/// map row is found once, for the sampler's clustering.
#[derive(Debug, Clone)]
pub struct LabelTable {
    table: EmbeddingTable,
    /// Per table row, the map row nearest its feature (`None`: a zero or
    /// non-finite feature, a class with no direction, read as unknown).
    map_row: Vec<Option<u32>>,
}

impl LabelTable {
    /// Binds `table` to `map`; fails if the dimensions differ or no class
    /// has a feature with a direction (an all-zero `embeddings.npy` was
    /// read as map row 0 for every class).
    pub fn new(table: EmbeddingTable, map: &LanguageMap) -> Result<Self, SessionError> {
        if table.dim != map.db().dim() {
            return Err(SessionError::ClassTable(format!(
                "features have dimension {}, the map has {}",
                table.dim,
                map.db().dim()
            )));
        }
        let map_row = (0..table.ids.len())
            .map(|r| {
                map.db()
                    .nearest(&table.data[r * table.dim..(r + 1) * table.dim])
                    .ok()
                    .flatten()
                    .map(|(i, _)| i as u32)
            })
            .collect::<Vec<_>>();
        if !table.ids.is_empty() && map_row.iter().all(Option::is_none) {
            return Err(SessionError::ClassTable(format!(
                "its {} features are all zero or not finite: no class has a direction",
                table.ids.len()
            )));
        }
        Ok(LabelTable { table, map_row })
    }

    /// The class table.
    pub fn table(&self) -> &EmbeddingTable {
        &self.table
    }

    /// The feature of the class named `word` (case-insensitive).
    pub fn word(&self, word: &str) -> Option<&[f32]> {
        self.table.word(word)
    }
}

/// The table's rows are looked up in the map: a label's row is the map row
/// nearest its feature, its feature the table's (zeros for labels the
/// table lacks).
impl LabelLookup for LabelTable {
    fn row(&self, label: u32) -> Option<u32> {
        self.table.row_index(label).and_then(|r| self.map_row[r])
    }
    fn feature(&self, label: u32) -> Option<&[f32]> {
        self.table.row(label)
    }
    fn dim(&self) -> usize {
        self.table.dim
    }
}

/// A label image looked up in `table`, checked: `labels` holds `width x
/// height` ids (the crate's one label frame, [`LabelImage`]), and at least
/// one of them is a class of the table. A frame none of whose ids is (a
/// class table of another dataset) gave likelihoods of 0 and the
/// odometry as the estimate, without a word.
pub fn label_frame<'a>(
    width: u32,
    height: u32,
    labels: &'a [u32],
    table: &'a LabelTable,
) -> Result<LabelImage<'a>, SessionError> {
    let f = LabelImage::new(width, height, labels, table)
        .map_err(|e| SessionError::BadFrame(e.to_string()))?;
    if !labels.iter().any(|&l| table.row(l).is_some()) {
        let mut ids: Vec<u32> = labels.to_vec();
        ids.sort_unstable();
        ids.dedup();
        let shown: Vec<String> = ids.iter().take(5).map(u32::to_string).collect();
        let more = if ids.len() > 5 { ", ..." } else { "" };
        return Err(SessionError::BadFrame(format!(
            "none of its label ids ({}{more}) is a class of the class table: is the table \
             the sequence's?",
            shown.join(", ")
        )));
    }
    Ok(f)
}

/// A dense feature map of `h x w x dim` (row-major, features last) for an
/// image of `width x height` pixels ([`crate::mapping::FeatureMap`], the
/// crate's one such grid: pixel `(u, v)` reads the cell covering its
/// centre), checked: every extent above 0, `data` holding `h * w * dim`
/// values, every value finite and not all of them zero. A frame of NaN or
/// zero features has no direction to compare with the map: localized, it
/// scored every particle alike and the estimate was the odometry's, with
/// full confidence and no word (mapping refuses such features too).
pub fn feature_grid(
    width: u32,
    height: u32,
    shape: [usize; 3],
    data: &[f32],
) -> Result<FeatureMap<'_>, SessionError> {
    let [h, w, dim] = shape;
    let extent = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    let map = FeatureMap::new(extent(h), extent(w), dim, data, width, height).map_err(|e| {
        SessionError::BadFrame(format!(
            "{e} (features of shape {shape:?} for a {width}x{height} image)"
        ))
    })?;
    finite_and_not_all_zero(shape, data)?;
    Ok(map)
}

/// [`feature_grid`]'s check of the values.
fn finite_and_not_all_zero(shape: [usize; 3], data: &[f32]) -> Result<(), SessionError> {
    let [_, w, dim] = shape;
    // Whole blocks folded without a branch (vectorized); the first bad
    // value found only in a block that has one.
    const BLOCK: usize = 4096;
    let mut any_nonzero = false;
    for (b, block) in data.chunks(BLOCK).enumerate() {
        let (finite, nonzero) = block.iter().fold((true, false), |(f, n), &x| {
            (f & x.is_finite(), n | (x != 0.0))
        });
        any_nonzero |= nonzero;
        if !finite {
            let i = b * BLOCK + block.iter().position(|x| !x.is_finite()).unwrap_or(0);
            let cell = i / dim.max(1);
            return Err(SessionError::BadFrame(format!(
                "the feature of cell (row {}, column {}) holds {} (features of shape {shape:?}): \
                 features must be finite",
                cell / w.max(1),
                cell % w.max(1),
                data[i]
            )));
        }
    }
    if !any_nonzero && !data.is_empty() {
        return Err(SessionError::BadFrame(format!(
            "every feature is zero (features of shape {shape:?}): a zero feature has no \
             direction to compare with the map"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::FrameFeatures;
    use crate::map::{FeatureDb, GridSpec};

    #[test]
    fn feature_grid_reads_the_nearest_cell_centre() {
        // 2 x 2 grid of 1-d features over a 4 x 4 image: each quadrant
        // reads its own cell.
        let data = [1.0, 2.0, 3.0, 4.0];
        let g = feature_grid(4, 4, [2, 2, 1], &data).unwrap();
        let mut out = [0.0f32];
        for (u, v, want) in [
            (0, 0, 1.0),
            (3, 0, 2.0),
            (0, 3, 3.0),
            (3, 3, 4.0),
            (1, 2, 3.0),
        ] {
            g.feature(u, v, &mut out);
            assert_eq!(out[0], want, "pixel ({u}, {v})");
        }
    }

    #[test]
    fn malformed_grids_and_label_images_are_named_errors() {
        let data = [0.0f32; 6];
        let e = feature_grid(4, 4, [2, 2, 2], &data).err().unwrap();
        assert!(e.to_string().contains("needs 8 values, got 6"), "{e}");
        let e = feature_grid(4, 4, [0, 2, 3], &data).err().unwrap();
        assert!(e.to_string().contains("at least 1"), "{e}");
        // Non-finite values are named by their cell; all-zero frames refused;
        // one zero feature among others is fine.
        let mut data = [1.0f32; 8];
        data[7] = f32::NAN;
        let e = feature_grid(4, 4, [2, 2, 2], &data).err().unwrap();
        assert!(
            e.to_string().contains("cell (row 1, column 1) holds NaN"),
            "{e}"
        );
        data[7] = 1.0;
        data[2] = f32::NEG_INFINITY;
        let e = feature_grid(4, 4, [2, 2, 2], &data).err().unwrap();
        assert!(
            e.to_string().contains("cell (row 0, column 1) holds -inf"),
            "{e}"
        );
        let e = feature_grid(4, 4, [2, 2, 2], &[0.0; 8]).err().unwrap();
        assert!(e.to_string().contains("every feature is zero"), "{e}");
        let mut data = [0.0f32; 8];
        data[5] = 0.5;
        assert!(feature_grid(4, 4, [2, 2, 2], &data).is_ok());
        // Past a block of 4096 values too.
        let mut big = vec![1.0f32; 3 * 4096];
        big[2 * 4096 + 3] = f32::INFINITY;
        let e = feature_grid(64, 64, [64, 64, 3], &big).err().unwrap();
        assert!(
            e.to_string().contains("cell (row 42, column 43) holds inf"),
            "{e}"
        );
        let table = LabelTable::new(
            EmbeddingTable::new(vec![7], vec!["x".into()], 2, vec![1.0, 0.0]).unwrap(),
            &one_row_map(),
        )
        .unwrap();
        let e = label_frame(2, 2, &[7, 7, 7], &table).err().unwrap();
        assert!(e.to_string().contains("needs 4 labels, got 3"), "{e}");
        // Ids none of which the table has: named, not scored as nothing.
        let e = label_frame(2, 2, &[101, 102, 101, 103], &table)
            .err()
            .unwrap();
        assert!(
            e.to_string()
                .contains("none of its label ids (101, 102, 103)"),
            "{e}"
        );
        assert!(label_frame(2, 2, &[101, 7, 101, 103], &table).is_ok());
        // A table whose features are all zero has no class to score.
        let zero = EmbeddingTable::new(vec![7], vec!["x".into()], 2, vec![0.0, 0.0]).unwrap();
        let e = LabelTable::new(zero, &one_row_map()).err().unwrap();
        assert!(
            e.to_string()
                .contains("class table: its 1 features are all zero"),
            "{e}"
        );
    }

    fn one_row_map() -> LanguageMap {
        // Rows: (0, 1) and (1, 0); a table row (1, 0) is nearest map row 1.
        let db = FeatureDb::from_rows(2, 0.0, vec![0.0, 1.0, 1.0, 0.0]).unwrap();
        let grid = GridSpec {
            resolution: 1.0,
            origin: nalgebra::Vector3::zeros(),
        };
        LanguageMap::from_cells(grid, db, "t", [([0, 0, 0], 0u32), ([1, 0, 0], 1)]).unwrap()
    }

    #[test]
    fn a_label_frame_reads_the_table_through_the_map() {
        // Class 7 has feature (1, 0), nearest map row 1; class 9 (0.6, 0.8)
        // nearest row 0; class 3 is not in the table.
        let t = EmbeddingTable::new(
            vec![7, 9],
            vec!["a".into(), "b".into()],
            2,
            vec![1.0, 0.0, 0.6, 0.8],
        )
        .unwrap();
        let table = LabelTable::new(t, &one_row_map()).unwrap();
        let labels = [7, 9, 3, 7];
        let f = label_frame(2, 2, &labels, &table).unwrap();
        assert_eq!((f.width(), f.height(), f.dim()), (2, 2, 2));
        assert_eq!(f.nearest_row(0, 0), Some(1));
        assert_eq!(f.nearest_row(1, 0), Some(0));
        assert_eq!(f.nearest_row(0, 1), None);
        assert!(f.known(1, 1) && !f.known(0, 1));
        let mut out = [9.0f32; 2];
        f.feature(1, 0, &mut out);
        assert_eq!(out, [0.6, 0.8]);
        f.feature(0, 1, &mut out);
        assert_eq!(out, [0.0, 0.0]);
    }
}
