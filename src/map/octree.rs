//! The Octree Language Map: occupied voxels (leaves) of a regular grid kept
//! sorted by Morton code, a linear octree, each pointing at a row of the
//! feature database.

use nalgebra::Vector3;

use super::features::{FeatureDb, FeatureDbError, dot};
use super::georef::Georef;
use super::key::{self, Cell, GridSpec};

/// Smallest voxel edge a map may have, metres (0.1 mm). A header with
/// 1e-300 loaded and then failed in the ray caster, which works in f32.
pub const MIN_RESOLUTION: f64 = 1e-4;

/// Largest voxel edge a map may have, metres (1 km; 1e300 became an
/// infinite f32 edge in the ray caster).
pub const MAX_RESOLUTION: f64 = 1e3;

/// Errors assembling a map.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MapError {
    #[error(
        "resolution must be a number of metres from {MIN_RESOLUTION} to {MAX_RESOLUTION}, got {0}"
    )]
    BadResolution(f64),
    #[error("origin must be finite, got {0:?}")]
    BadOrigin([f64; 3]),
    #[error("leaf {leaf} points at feature row {row}, but the database has {rows} rows")]
    RowOutOfRange { leaf: usize, row: u32, rows: usize },
    #[error("leaf codes must be strictly increasing (duplicate or unsorted at leaf {0})")]
    Unsorted(usize),
    #[error("{codes} codes but {rows} row indices")]
    LengthMismatch { codes: usize, rows: usize },
    #[error("leaf {leaf}'s code {code:#x} is beyond the {bits}-bit cell keys (no cell has it)")]
    CodeOutOfRange { leaf: usize, code: u64, bits: u32 },
    #[error("the encoder's name {0:?} holds control characters")]
    BadEncoderName(String),
    #[error(transparent)]
    Features(#[from] FeatureDbError),
}

/// A language map: grid, sorted leaves and their feature rows.
#[derive(Debug, Clone, PartialEq)]
pub struct LanguageMap {
    grid: GridSpec,
    codes: Vec<u64>,
    rows: Vec<u32>,
    db: FeatureDb,
    encoder: String,
    georef: Option<Georef>,
}

impl LanguageMap {
    /// Checks a grid specification.
    pub fn check_grid(grid: &GridSpec) -> Result<(), MapError> {
        if !(MIN_RESOLUTION..=MAX_RESOLUTION).contains(&grid.resolution) {
            return Err(MapError::BadResolution(grid.resolution));
        }
        if !grid.origin.iter().all(|v| v.is_finite()) {
            return Err(MapError::BadOrigin([
                grid.origin.x,
                grid.origin.y,
                grid.origin.z,
            ]));
        }
        Ok(())
    }

    /// A map from leaves that are already strictly sorted by code.
    pub fn from_sorted(
        grid: GridSpec,
        db: FeatureDb,
        encoder: impl Into<String>,
        codes: Vec<u64>,
        rows: Vec<u32>,
    ) -> Result<Self, MapError> {
        Self::check_grid(&grid)?;
        if codes.len() != rows.len() {
            return Err(MapError::LengthMismatch {
                codes: codes.len(),
                rows: rows.len(),
            });
        }
        if let Some(i) = codes.windows(2).position(|w| w[0] >= w[1]) {
            return Err(MapError::Unsorted(i + 1));
        }
        // Sorted: the last code is the largest.
        let bits = 3 * super::key::AXIS_BITS;
        if let Some(&code) = codes.last()
            && code >> bits != 0
        {
            let leaf = codes.len() - 1;
            return Err(MapError::CodeOutOfRange { leaf, code, bits });
        }
        let encoder = encoder.into();
        if encoder.chars().any(char::is_control) {
            return Err(MapError::BadEncoderName(encoder));
        }
        let k = db.len();
        if let Some((leaf, &row)) = rows.iter().enumerate().find(|(_, r)| **r as usize >= k) {
            return Err(MapError::RowOutOfRange { leaf, row, rows: k });
        }
        Ok(LanguageMap {
            grid,
            codes,
            rows,
            db,
            encoder,
            georef: None,
        })
    }

    /// A map from `(cell, row)` leaves in any order; for repeated cells the
    /// last one wins.
    pub fn from_cells(
        grid: GridSpec,
        db: FeatureDb,
        encoder: impl Into<String>,
        leaves: impl IntoIterator<Item = (Cell, u32)>,
    ) -> Result<Self, MapError> {
        let mut v: Vec<(u64, u32)> = leaves
            .into_iter()
            .filter(|(c, _)| key::in_range(*c))
            .map(|(c, r)| (key::encode(c), r))
            .collect();
        // Stable sort keeps insertion order among equal codes; keep the last.
        v.sort_by_key(|&(c, _)| c);
        let mut codes = Vec::with_capacity(v.len());
        let mut rows = Vec::with_capacity(v.len());
        for (c, r) in v {
            if codes.last() == Some(&c) {
                *rows.last_mut().expect("rows and codes grow together") = r;
            } else {
                codes.push(c);
                rows.push(r);
            }
        }
        Self::from_sorted(grid, db, encoder, codes, rows)
    }

    /// The grid.
    pub fn grid(&self) -> &GridSpec {
        &self.grid
    }

    /// The feature database.
    pub fn db(&self) -> &FeatureDb {
        &self.db
    }

    /// The same map, georeferenced: built from a survey in `georef`'s CRS
    /// (`None`: a local frame).
    pub fn with_georef(mut self, georef: Option<Georef>) -> Self {
        self.georef = georef;
        self
    }

    /// The CRS of the survey the map was built from, when it stated one.
    pub fn georef(&self) -> Option<&Georef> {
        self.georef.as_ref()
    }

    /// Name of the encoder whose feature space the rows live in.
    pub fn encoder(&self) -> &str {
        &self.encoder
    }

    /// Number of leaves (occupied voxels).
    pub fn len(&self) -> usize {
        self.codes.len()
    }

    /// Whether the map has no leaves.
    pub fn is_empty(&self) -> bool {
        self.codes.is_empty()
    }

    /// Morton codes of the leaves, strictly increasing.
    pub fn codes(&self) -> &[u64] {
        &self.codes
    }

    /// Feature row of every leaf.
    pub fn rows(&self) -> &[u32] {
        &self.rows
    }

    /// Cells of all leaves, in leaf order (the order ray casters index).
    pub fn cells(&self) -> Vec<Cell> {
        self.codes.iter().map(|&c| key::decode(c)).collect()
    }

    /// Leaf index of `cell`, if occupied.
    pub fn find(&self, cell: Cell) -> Option<usize> {
        if !key::in_range(cell) {
            return None;
        }
        self.codes.binary_search(&key::encode(cell)).ok()
    }

    /// Leaf index of the voxel holding world point `p`, if occupied.
    pub fn find_point(&self, p: &Vector3<f64>) -> Option<usize> {
        self.grid.cell_of(p).and_then(|c| self.find(c))
    }

    /// Cosine similarity of `feature` to every leaf's feature, computed once
    /// per database row and looked up per leaf.
    pub fn similarity(&self, feature: &[f32]) -> Result<Vec<f32>, MapError> {
        let per_row = self.db.similarities(feature)?;
        Ok(self.rows.iter().map(|&r| per_row[r as usize]).collect())
    }

    /// Number of leaves per database row.
    pub fn row_counts(&self) -> Vec<usize> {
        let mut n = vec![0usize; self.db.len()];
        for &r in &self.rows {
            n[r as usize] += 1;
        }
        n
    }

    /// Smallest and largest occupied cell index on each axis.
    pub fn cell_bounds(&self) -> Option<(Cell, Cell)> {
        let mut it = self.codes.iter().map(|&c| key::decode(c));
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), c| {
            (
                [lo[0].min(c[0]), lo[1].min(c[1]), lo[2].min(c[2])],
                [hi[0].max(c[0]), hi[1].max(c[1]), hi[2].max(c[2])],
            )
        }))
    }

    /// The world-frame box the occupied voxels fill: the lower corner of
    /// the lowest cell and the upper corner of the highest on each axis,
    /// metres.
    pub fn world_bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        let (lo, hi) = self.cell_bounds()?;
        let g = &self.grid;
        let at = |c: Cell, up: i32| {
            std::array::from_fn(|k| g.origin[k] + (c[k] + up) as f64 * g.resolution)
        };
        Some((at(lo, 0), at(hi, 1)))
    }

    /// Codes of the occupied nodes `levels` above the leaves (each level
    /// doubles the edge length), strictly increasing.
    pub fn coarse_codes(&self, levels: u32) -> Vec<u64> {
        let shift = 3 * levels.min(key::AXIS_BITS);
        let mut v: Vec<u64> = self.codes.iter().map(|c| c >> shift).collect();
        v.dedup();
        v
    }

    /// Bytes held by the leaves and the database.
    pub fn memory_bytes(&self) -> usize {
        self.codes.len() * 8 + self.rows.len() * 4 + self.db.memory_bytes()
    }

    /// Mean cosine similarity between database rows `a` and `b`.
    pub fn row_similarity(&self, a: usize, b: usize) -> f32 {
        dot(self.db.row(a), self.db.row(b))
    }

    /// Replaces the database and the leaves (used by grounding).
    pub(crate) fn replace(&mut self, db: FeatureDb, codes: Vec<u64>, rows: Vec<u32>) {
        self.db = db;
        self.codes = codes;
        self.rows = rows;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> GridSpec {
        GridSpec {
            resolution: 0.1,
            origin: Vector3::zeros(),
        }
    }

    fn db2() -> FeatureDb {
        FeatureDb::from_rows(2, 0.02, vec![1.0, 0.0, 0.0, 1.0]).unwrap()
    }

    #[test]
    fn leaves_are_sorted_deduplicated_and_findable() {
        let m = LanguageMap::from_cells(
            grid(),
            db2(),
            "test",
            vec![
                ([3, 0, 0], 0),
                ([0, 0, 0], 1),
                ([3, 0, 0], 1),
                ([-5, 2, 1], 0),
            ],
        )
        .unwrap();
        assert_eq!(m.len(), 3);
        assert!(m.codes().windows(2).all(|w| w[0] < w[1]));
        let i = m.find([3, 0, 0]).unwrap();
        assert_eq!(m.rows()[i], 1, "the last duplicate wins");
        assert_eq!(m.find([1, 1, 1]), None);
        assert_eq!(m.find_point(&Vector3::new(0.35, 0.05, 0.01)), Some(i));
        assert_eq!(m.cell_bounds(), Some(([-5, 0, 0], [3, 2, 1])));
        assert_eq!(m.row_counts(), vec![1, 2]);
    }

    #[test]
    fn similarity_is_a_row_lookup() {
        let m = LanguageMap::from_cells(grid(), db2(), "t", vec![([0, 0, 0], 0), ([1, 0, 0], 1)])
            .unwrap();
        let s = m.similarity(&[3.0, 4.0]).unwrap();
        assert!((s[0] - 0.6).abs() < 1e-6 && (s[1] - 0.8).abs() < 1e-6);
    }

    #[test]
    fn coarse_levels_merge_siblings() {
        let m = LanguageMap::from_cells(
            grid(),
            db2(),
            "t",
            vec![([0, 0, 0], 0), ([1, 1, 1], 0), ([2, 0, 0], 1)],
        )
        .unwrap();
        assert_eq!(m.coarse_codes(1).len(), 2);
        assert_eq!(m.coarse_codes(2).len(), 1);
    }

    #[test]
    fn invalid_maps_are_rejected() {
        assert!(matches!(
            LanguageMap::from_sorted(grid(), db2(), "t", vec![1, 1], vec![0, 0]),
            Err(MapError::Unsorted(1))
        ));
        assert!(matches!(
            LanguageMap::from_sorted(grid(), db2(), "t", vec![1], vec![2]),
            Err(MapError::RowOutOfRange { .. })
        ));
        // Codes past the 63 bits of the cell keys (sorted, so the last).
        let top = (1u64 << 63) - 1;
        assert!(LanguageMap::from_sorted(grid(), db2(), "t", vec![1, top], vec![0, 0]).is_ok());
        let e = LanguageMap::from_sorted(grid(), db2(), "t", vec![1, u64::MAX], vec![0, 0]);
        assert!(
            matches!(
                e,
                Err(MapError::CodeOutOfRange {
                    leaf: 1,
                    code: u64::MAX,
                    bits: 63
                })
            ),
            "{e:?}"
        );
        // Control characters in the encoder's name (printed by `map info`).
        let e = LanguageMap::from_sorted(grid(), db2(), "clip\x1b[31m\nx", vec![1], vec![0]);
        assert!(matches!(e, Err(MapError::BadEncoderName(_))), "{e:?}");
        let bad = GridSpec {
            resolution: 0.0,
            origin: Vector3::zeros(),
        };
        assert!(LanguageMap::from_sorted(bad, db2(), "t", vec![], vec![]).is_err());
        // Finite but beyond what the f32 ray caster can hold.
        for r in [1e300, 1e-300, 2e3, 5e-5, f64::NAN] {
            let g = GridSpec {
                resolution: r,
                origin: Vector3::zeros(),
            };
            let e = LanguageMap::from_sorted(g, db2(), "t", vec![], vec![]).unwrap_err();
            assert!(e.to_string().contains("from 0.0001 to 1000"), "{e}");
        }
        for r in [MIN_RESOLUTION, 0.05, MAX_RESOLUTION] {
            let g = GridSpec {
                resolution: r,
                origin: Vector3::zeros(),
            };
            assert!(LanguageMap::from_sorted(g, db2(), "t", vec![], vec![]).is_ok());
        }
    }
}
