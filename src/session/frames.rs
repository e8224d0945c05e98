//! Per-frame feature sources a session consumes: a label image looked up in
//! a class table, and a dense `h x w x F` feature grid at any resolution.
//! Both implement [`crate::mcl::FrameFeatures`] and check their sizes when
//! made, so a malformed frame is an error before it reaches the filter.

use crate::frame::FrameFeatures;
use crate::io::labels::EmbeddingTable;
use crate::map::LanguageMap;
use crate::mapping::FeatureMap;

use super::SessionError;

/// A class table (label id -> feature) bound to a map: every row's nearest
/// map row is found once, for the sampler's clustering.
#[derive(Debug, Clone)]
pub struct LabelTable {
    table: EmbeddingTable,
    map_row: Vec<u32>,
}

impl LabelTable {
    /// Binds `table` to `map`; fails if the dimensions differ.
    pub fn new(table: EmbeddingTable, map: &LanguageMap) -> Result<Self, SessionError> {
        if table.dim != map.db().dim() {
            return Err(SessionError::BadFrame(format!(
                "class table features have dimension {}, the map has {}",
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
                    .map_or(0, |(i, _)| i as u32)
            })
            .collect();
        Ok(LabelTable { table, map_row })
    }

    /// The class table.
    pub fn table(&self) -> &EmbeddingTable {
        &self.table
    }

    /// The feature of the class named `word` (case-insensitive).
    pub fn word(&self, word: &str) -> Option<&[f32]> {
        let t = &self.table;
        let i = t.names.iter().position(|n| n.eq_ignore_ascii_case(word))?;
        Some(&t.data[i * t.dim..(i + 1) * t.dim])
    }
}

/// Features of one frame: a label image looked up in a [`LabelTable`].
/// Labels missing from the table have a zero feature.
pub struct LabelFrame<'a> {
    width: u32,
    height: u32,
    labels: &'a [u32],
    table: &'a LabelTable,
}

impl<'a> LabelFrame<'a> {
    /// A `width x height` label image (row-major); fails if `labels` has
    /// another length.
    pub fn new(
        width: u32,
        height: u32,
        labels: &'a [u32],
        table: &'a LabelTable,
    ) -> Result<Self, SessionError> {
        if width == 0 || height == 0 || labels.len() != width as usize * height as usize {
            return Err(SessionError::BadFrame(format!(
                "label image of {width}x{height} pixels needs {} labels, got {}",
                width as usize * height as usize,
                labels.len()
            )));
        }
        Ok(LabelFrame {
            width,
            height,
            labels,
            table,
        })
    }
}

impl FrameFeatures for LabelFrame<'_> {
    fn width(&self) -> u32 {
        self.width
    }
    fn height(&self) -> u32 {
        self.height
    }
    fn dim(&self) -> usize {
        self.table.table.dim
    }
    fn feature(&self, u: u32, v: u32, out: &mut [f32]) {
        let l = self.labels[(v * self.width + u) as usize];
        match self.table.table.row(l) {
            Some(f) => out.copy_from_slice(f),
            None => out.fill(0.0),
        }
    }
    fn nearest_row(&self, u: u32, v: u32) -> Option<u32> {
        let l = self.labels[(v * self.width + u) as usize];
        self.table.table.row_index(l).map(|r| self.table.map_row[r])
    }
}

/// A dense feature map of `h x w x dim` (row-major, features last) for an
/// image of `width x height` pixels ([`crate::mapping::FeatureMap`], the
/// crate's one such grid: pixel `(u, v)` reads the cell covering its
/// centre), checked: every extent above 0 and `data` holding `h * w * dim`
/// values.
pub fn feature_grid(
    width: u32,
    height: u32,
    shape: [usize; 3],
    data: &[f32],
) -> Result<FeatureMap<'_>, SessionError> {
    let [h, w, dim] = shape;
    let extent = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    FeatureMap::new(extent(h), extent(w), dim, data, width, height).map_err(|e| {
        SessionError::BadFrame(format!(
            "{e} (features of shape {shape:?} for a {width}x{height} image)"
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
    }
}
