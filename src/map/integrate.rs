//! Integration: features that fall into one voxel are averaged.
//!
//! Averaging raw F-dimensional vectors per voxel costs `4 F` bytes a voxel
//! (2 KiB for CLIP), gigabytes for million-voxel maps. Instead each incoming
//! feature is first quantized to a row of an *observation database* (the
//! paper's admission rule with `tau`, optionally capped), and each voxel
//! keeps a running count of the rows it saw in [`SLOTS`] slots. When a fifth
//! distinct row arrives, the least-seen slot is replaced and its count
//! carried over (the space-saving sketch), so heavy rows are never lost.
//!
//! Memory bound: 8 bytes of key + `SLOTS * 8` bytes of slots per voxel in a
//! hash map (about 56 bytes a voxel with table overhead), plus `4 F` bytes
//! per observation row. The voxel feature is the normalized count-weighted
//! mean of its rows: the exact running mean of the quantized features while
//! a voxel has seen at most `SLOTS` distinct rows.
//!
//! [`Integrator::finish`] forms the map's database from the voxel means with
//! the same admission rule (paper: "once all data have been processed, the
//! mapped features form Features_DB").

use nalgebra::Vector3;
use rustc_hash::FxHashMap;

use super::features::{FeatureDb, FeatureDbError, normalize};
use super::key::{self, Cell, GridSpec};
use super::octree::{LanguageMap, MapError};

/// Distinct rows remembered per voxel.
pub const SLOTS: usize = 4;
const EMPTY: u32 = u32::MAX;

#[derive(Debug, Clone, Copy)]
struct Slots {
    row: [u32; SLOTS],
    count: [f32; SLOTS],
}

impl Slots {
    const NEW: Slots = Slots {
        row: [EMPTY; SLOTS],
        count: [0.0; SLOTS],
    };

    fn add(&mut self, row: u32, weight: f32) {
        if let Some(i) = self.row.iter().position(|&r| r == row) {
            self.count[i] += weight;
        } else if let Some(i) = self.row.iter().position(|&r| r == EMPTY) {
            self.row[i] = row;
            self.count[i] = weight;
        } else {
            let (i, _) = self
                .count
                .iter()
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(b.1))
                .expect("SLOTS > 0");
            self.row[i] = row;
            self.count[i] += weight;
        }
    }
}

/// An axis-aligned box of world points, metres: where a cloud's points are
/// expected (`crate::mapping::pipeline::OriginEstimate`); an integrator
/// given one ([`Integrator::keeping`]) rejects points outside it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeepBox {
    /// Lowest corner.
    pub lo: [f64; 3],
    /// Highest corner.
    pub hi: [f64; 3],
}

impl KeepBox {
    /// Whether `p` lies inside (a NaN does not).
    pub fn contains(&self, p: &[f64; 3]) -> bool {
        (0..3).all(|a| p[a] >= self.lo[a] && p[a] <= self.hi[a])
    }

    /// The box grown on every side by `times` its largest extent, or by
    /// `at_least` metres when that is more.
    pub fn grown(&self, times: f64, at_least: f64) -> KeepBox {
        let extent = (0..3).map(|a| self.hi[a] - self.lo[a]).fold(0.0, f64::max);
        let m = (times * extent).max(at_least);
        KeepBox {
            lo: self.lo.map(|v| v - m),
            hi: self.hi.map(|v| v + m),
        }
    }
}

/// Accumulates features into voxels.
#[derive(Debug, Clone)]
pub struct Integrator {
    grid: GridSpec,
    obs: FeatureDb,
    voxels: FxHashMap<u64, Slots>,
    rejected: usize,
    keep: Option<KeepBox>,
}

impl Integrator {
    /// An integrator on `grid` quantizing features with `obs` (an empty
    /// database with the wanted tau and cap, or a fixed table such as class
    /// embeddings used through [`Integrator::add_row`]).
    pub fn new(grid: GridSpec, obs: FeatureDb) -> Result<Self, MapError> {
        LanguageMap::check_grid(&grid)?;
        Ok(Integrator {
            grid,
            obs,
            voxels: FxHashMap::default(),
            rejected: 0,
            keep: None,
        })
    }

    /// Rejects the points outside `keep` from now on (strays), as points
    /// out of the grid's reach are.
    pub fn keeping(mut self, keep: Option<KeepBox>) -> Self {
        self.keep = keep;
        self
    }

    /// The cell of `p`: `None` when out of the grid's reach or outside the
    /// kept box.
    fn cell_of(grid: &GridSpec, keep: Option<&KeepBox>, p: &Vector3<f64>) -> Option<Cell> {
        if keep.is_some_and(|k| !k.contains(&[p.x, p.y, p.z])) {
            return None;
        }
        grid.cell_of(p)
    }

    /// Adds a feature observed at world point `p`. Returns `false` (and
    /// counts the point as rejected) when `p` is not finite or out of range.
    pub fn add_feature(
        &mut self,
        p: &Vector3<f64>,
        feature: &[f32],
    ) -> Result<bool, FeatureDbError> {
        let Some(cell) = Self::cell_of(&self.grid, self.keep.as_ref(), p) else {
            self.rejected += 1;
            return Ok(false);
        };
        let row = self.obs.admit(feature)? as u32;
        self.voxels
            .entry(key::encode(cell))
            .or_insert(Slots::NEW)
            .add(row, 1.0);
        Ok(true)
    }

    /// Adds an observation of observation-database row `row` at `p` (for
    /// sources that already know the row, such as labels with an embedding
    /// table). Returns `false` when `p` is rejected or `row` does not exist.
    pub fn add_row(&mut self, p: &Vector3<f64>, row: u32) -> bool {
        match Self::cell_of(&self.grid, self.keep.as_ref(), p) {
            Some(cell) if (row as usize) < self.obs.len() => {
                self.voxels
                    .entry(key::encode(cell))
                    .or_insert(Slots::NEW)
                    .add(row, 1.0);
                true
            }
            _ => {
                self.rejected += 1;
                false
            }
        }
    }

    /// Adds many observations of known rows at once: `rows[i]` observed at
    /// `points[i]` (world frame), `None` to skip a point. Equivalent to
    /// calling [`Integrator::add_row`] for each point, but parallel: voxel
    /// codes are computed and sorted with rayon and the voxel table is
    /// touched once per voxel. Returns how many points were integrated.
    pub fn add_rows_batch(&mut self, points: &[[f64; 3]], rows: &[Option<u32>]) -> usize {
        use rayon::prelude::*;
        let k = self.obs.len();
        let (grid, keep) = (self.grid, self.keep);
        let mut keyed: Vec<(u64, u32)> = points
            .par_iter()
            .zip(rows.par_iter())
            .filter_map(|(p, r)| {
                let r = (*r).filter(|&r| (r as usize) < k)?;
                let cell = Self::cell_of(&grid, keep.as_ref(), &Vector3::from(*p))?;
                Some((key::encode(cell), r))
            })
            .collect();
        let offered = points.len().min(rows.len());
        let skipped = rows.iter().take(offered).filter(|r| r.is_none()).count();
        self.rejected += offered - skipped - keyed.len();
        keyed.par_sort_unstable();
        self.voxels.reserve(keyed.len() / 4);
        let n = keyed.len();
        let mut i = 0;
        while i < n {
            let code = keyed[i].0;
            let slots = self.voxels.entry(code).or_insert(Slots::NEW);
            while i < n && keyed[i].0 == code {
                let row = keyed[i].1;
                let start = i;
                while i < n && keyed[i] == (code, row) {
                    i += 1;
                }
                slots.add(row, (i - start) as f32);
            }
        }
        n
    }

    /// Occupied voxels so far.
    pub fn voxel_count(&self) -> usize {
        self.voxels.len()
    }

    /// Points rejected as non-finite, out of range or of an unknown row.
    pub fn rejected(&self) -> usize {
        self.rejected
    }

    /// The observation database.
    pub fn observation_db(&self) -> &FeatureDb {
        &self.obs
    }

    /// Approximate bytes held (voxel table with its overhead, and rows).
    pub fn memory_bytes(&self) -> usize {
        let per = std::mem::size_of::<(u64, Slots)>() + 1;
        self.voxels.capacity() * per + self.obs.memory_bytes()
    }

    /// Builds the map: voxel means form the database with admission
    /// threshold `tau` (cosine distance).
    pub fn finish(self, encoder: impl Into<String>, tau: f32) -> Result<LanguageMap, MapError> {
        let db = FeatureDb::new(self.obs.dim(), tau)?;
        self.finish_into(encoder, db)
    }

    /// As [`Integrator::finish`], admitting the voxel means into `db` (an
    /// empty database with the wanted tau and, for noisy raw features
    /// whose means rarely come within tau of each other, a cap on its
    /// rows: past the cap a mean takes its nearest row).
    pub fn finish_into(
        self,
        encoder: impl Into<String>,
        mut db: FeatureDb,
    ) -> Result<LanguageMap, MapError> {
        let dim = self.obs.dim();
        let mut leaves: Vec<(u64, Slots)> = self.voxels.into_iter().collect();
        leaves.sort_unstable_by_key(|&(c, _)| c);
        // Single-row voxels share their row's final index.
        let mut single: Vec<u32> = vec![EMPTY; self.obs.len()];
        let mut mean = vec![0.0f32; dim];
        let mut codes = Vec::with_capacity(leaves.len());
        let mut rows = Vec::with_capacity(leaves.len());
        for (code, s) in leaves {
            let used: Vec<usize> = (0..SLOTS).filter(|&i| s.row[i] != EMPTY).collect();
            let row = if let [i] = used[..] {
                let r = s.row[i] as usize;
                if single[r] == EMPTY {
                    single[r] = db.admit(self.obs.row(r))? as u32;
                }
                single[r]
            } else {
                mean.iter_mut().for_each(|m| *m = 0.0);
                for &i in &used {
                    let f = self.obs.row(s.row[i] as usize);
                    mean.iter_mut()
                        .zip(f)
                        .for_each(|(m, x)| *m += s.count[i] * x);
                }
                if !normalize(&mut mean) {
                    // Opposite features cancelled: keep the most seen row.
                    let &i = used
                        .iter()
                        .max_by(|&&a, &&b| s.count[a].total_cmp(&s.count[b]))
                        .expect("a voxel has at least one row");
                    mean.copy_from_slice(self.obs.row(s.row[i] as usize));
                }
                db.admit(&mean)? as u32
            };
            codes.push(code);
            rows.push(row);
        }
        LanguageMap::from_sorted(self.grid, db, encoder, codes, rows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::features::dot;

    fn grid() -> GridSpec {
        GridSpec {
            resolution: 1.0,
            origin: Vector3::zeros(),
        }
    }

    #[test]
    fn features_in_one_voxel_are_averaged() {
        let mut it = Integrator::new(grid(), FeatureDb::new(2, 0.02).unwrap()).unwrap();
        let p = Vector3::new(0.5, 0.5, 0.5);
        // Three observations of x and one of y: mean direction (3, 1).
        for _ in 0..3 {
            it.add_feature(&p, &[1.0, 0.0]).unwrap();
        }
        it.add_feature(&p, &[0.0, 2.0]).unwrap();
        // Another voxel sees only y.
        it.add_feature(&Vector3::new(1.5, 0.5, 0.5), &[0.0, 1.0])
            .unwrap();
        assert_eq!(it.voxel_count(), 2);
        let m = it.finish("t", 0.02).unwrap();
        let f = m
            .db()
            .row(m.rows()[m.find([0, 0, 0]).unwrap()] as usize)
            .to_vec();
        let expected = [3.0 / 10f32.sqrt(), 1.0 / 10f32.sqrt()];
        assert!((f[0] - expected[0]).abs() < 1e-6 && (f[1] - expected[1]).abs() < 1e-6);
        let g = m.db().row(m.rows()[m.find([1, 0, 0]).unwrap()] as usize);
        assert!((dot(g, &[0.0, 1.0]) - 1.0).abs() < 1e-6);
        assert_eq!(m.db().len(), 2);
    }

    #[test]
    fn identical_labels_share_one_row() {
        let table = FeatureDb::from_rows(2, 0.02, vec![1.0, 0.0, 0.0, 1.0]).unwrap();
        let mut it = Integrator::new(grid(), table).unwrap();
        for x in 0..10 {
            assert!(it.add_row(&Vector3::new(x as f64 + 0.5, 0.0, 0.0), (x % 2) as u32));
        }
        assert!(!it.add_row(&Vector3::new(0.0, 0.0, 0.0), 7), "unknown row");
        assert!(!it.add_row(&Vector3::new(f64::INFINITY, 0.0, 0.0), 0));
        assert_eq!(it.rejected(), 2);
        let m = it.finish("t", 0.02).unwrap();
        assert_eq!(m.len(), 10);
        assert_eq!(m.db().len(), 2);
        assert_eq!(m.row_counts(), vec![5, 5]);
    }

    #[test]
    fn batch_equals_one_by_one() {
        let table =
            FeatureDb::from_rows(3, 0.02, vec![1.0, 0., 0., 0., 1., 0., 0., 0., 1.]).unwrap();
        let pts: Vec<[f64; 3]> = (0..5000)
            .map(|i| {
                let f = i as f64;
                [
                    (f * 0.37).sin() * 3.0,
                    (f * 0.11).cos() * 3.0,
                    (f * 0.05).sin(),
                ]
            })
            .collect();
        let rows: Vec<Option<u32>> = (0..5000)
            .map(|i| match i % 7 {
                0 => None,
                6 => Some(9),
                r => Some(r as u32 % 3),
            })
            .collect();
        let mut a = Integrator::new(grid(), table.clone()).unwrap();
        let mut b = Integrator::new(grid(), table).unwrap();
        let n = a.add_rows_batch(&pts, &rows);
        let mut m = 0;
        for (p, r) in pts.iter().zip(&rows) {
            if let Some(r) = r {
                m += b.add_row(&Vector3::from(*p), *r) as usize;
            }
        }
        assert_eq!(n, m);
        assert_eq!(a.rejected(), b.rejected());
        assert_eq!(a.finish("t", 0.02).unwrap(), b.finish("t", 0.02).unwrap());
    }

    #[test]
    fn heavy_rows_survive_slot_eviction() {
        let table: Vec<f32> = (0..6)
            .flat_map(|i| {
                let mut v = vec![0.0; 6];
                v[i] = 1.0;
                v
            })
            .collect();
        let mut it =
            Integrator::new(grid(), FeatureDb::from_rows(6, 0.02, table).unwrap()).unwrap();
        let p = Vector3::new(0.1, 0.1, 0.1);
        for _ in 0..50 {
            it.add_row(&p, 0);
        }
        for r in 1..6 {
            it.add_row(&p, r);
        }
        let m = it.finish("t", 0.02).unwrap();
        let f = m.db().row(m.rows()[0] as usize);
        assert!(f[0] > 0.99, "the dominant row dominates the mean: {f:?}");
    }
}
