//! A top-down floor plan: a raster over the world x-y plane, the backdrop
//! of the trajectory figures. Pure data; no drawing and no I/O here.

/// What a floor-plan cell shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlanCell {
    /// Nothing mapped in this column.
    #[default]
    Unknown,
    /// Floor and nothing in the obstacle height band above it.
    Floor,
    /// Something (wall, furniture) in the obstacle height band.
    Obstacle,
}

impl PlanCell {
    /// Which cell wins when cells are merged: obstacles stay visible.
    fn priority(self) -> u8 {
        match self {
            PlanCell::Unknown => 0,
            PlanCell::Floor => 1,
            PlanCell::Obstacle => 2,
        }
    }
}

/// A raster over the world x-y plane (metres, world frame, z up).
///
/// Cell `(col, row)` covers `x` in `min_xy[0] + [col, col + 1) * cell` and
/// `y` in `min_xy[1] + [row, row + 1) * cell`; `cells` is row-major with
/// row 0 at the smallest y (south), so `cells[row * width + col]`.
#[derive(Debug, Clone, PartialEq)]
pub struct FloorPlan {
    /// World (x, y) of the corner of cell (0, 0), metres.
    pub min_xy: [f64; 2],
    /// Edge length of a cell, metres.
    pub cell: f64,
    /// Number of columns (along x).
    pub width: usize,
    /// Number of rows (along y).
    pub height: usize,
    /// `width * height` cells, row-major, row 0 at the smallest y.
    pub cells: Vec<PlanCell>,
}

/// Plans larger than this are refused (a tiny `cell` over a large map
/// would otherwise try to allocate without bound).
const MAX_CELLS: usize = 1 << 26;

impl FloorPlan {
    /// Builds a plan from voxel centres (world x, y, z in metres) and
    /// whether each voxel is floor.
    ///
    /// A column is [`PlanCell::Obstacle`] if any non-floor voxel in it has
    /// `z_range.0 <= z <= z_range.1` (the obstacle height band: above floor
    /// clutter, below the ceiling), else [`PlanCell::Floor`] if it has a
    /// floor voxel (at any height), else [`PlanCell::Unknown`]. Non-floor
    /// voxels outside the band neither mark nor extend the plan. The plan's
    /// corner is half a cell below the smallest contributing centre, so
    /// with `cell` equal to the voxel size every centre lies mid-cell.
    ///
    /// `None` if no voxel contributes, if `cell` is not positive and
    /// finite, if `z_range` is not an ordered finite pair, or if the plan
    /// would exceed 2^26 cells. Voxels with non-finite coordinates are
    /// skipped.
    pub fn from_voxels(
        centres: impl Iterator<Item = ([f64; 3], bool)>,
        cell: f64,
        z_range: (f64, f64),
    ) -> Option<FloorPlan> {
        let (z_min, z_max) = z_range;
        if !(cell.is_finite() && cell > 0.0 && z_min.is_finite() && z_max.is_finite())
            || z_min > z_max
        {
            return None;
        }
        let marks: Vec<([f64; 2], PlanCell)> = centres
            .filter(|(p, _)| p.iter().all(|v| v.is_finite()))
            .filter_map(|(p, is_floor)| {
                if is_floor {
                    Some(([p[0], p[1]], PlanCell::Floor))
                } else if p[2] >= z_min && p[2] <= z_max {
                    Some(([p[0], p[1]], PlanCell::Obstacle))
                } else {
                    None
                }
            })
            .collect();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (p, _) in &marks {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        if marks.is_empty() {
            return None;
        }
        let min_xy = [lo[0] - cell / 2.0, lo[1] - cell / 2.0];
        let cols = ((hi[0] - min_xy[0]) / cell).floor() + 1.0;
        let rows = ((hi[1] - min_xy[1]) / cell).floor() + 1.0;
        if !(cols * rows).is_finite() || cols * rows > MAX_CELLS as f64 {
            return None;
        }
        let (width, height) = (cols as usize, rows as usize);
        let mut plan = FloorPlan {
            min_xy,
            cell,
            width,
            height,
            cells: vec![PlanCell::Unknown; width * height],
        };
        for (p, mark) in marks {
            if let Some((c, r)) = plan.cell_of(p[0], p[1]) {
                let i = r * width + c;
                if mark.priority() > plan.cells[i].priority() {
                    plan.cells[i] = mark;
                }
            }
        }
        Some(plan)
    }

    /// The floor plan of a language map at its resolution: voxels whose
    /// similarity to `floor_feature` (the text feature of "floor") is at
    /// least `rho` are floor; obstacles are the other voxels from 0.2 to
    /// 2.0 m above the median floor height. Without a floor feature or a
    /// floor voxel (a street's map), the band is above each column's own
    /// lowest voxel, the ground there, so a street that climbs metres
    /// keeps its buildings along the whole way.
    pub fn from_map(
        map: &crate::map::LanguageMap,
        floor_feature: Option<&[f32]>,
        rho: f32,
    ) -> Option<FloorPlan> {
        let g = map.grid();
        let centres: Vec<[f64; 3]> = map
            .cells()
            .into_iter()
            .map(|c| {
                let p = g.center(c);
                [p.x, p.y, p.z]
            })
            .collect();
        let is_floor: Vec<bool> = match floor_feature.and_then(|f| map.similarity(f).ok()) {
            Some(sim) => sim.iter().map(|&s| s >= rho).collect(),
            None => vec![false; centres.len()],
        };
        let mut floor_z: Vec<f64> = centres
            .iter()
            .zip(&is_floor)
            .filter(|(_, f)| **f)
            .map(|(p, _)| p[2])
            .collect();
        floor_z.sort_by(f64::total_cmp);
        let Some(&base) = floor_z.get(floor_z.len() / 2) else {
            // Heights above each column's lowest voxel.
            let key = |p: &[f64; 3]| {
                (
                    (p[0] / g.resolution).floor() as i64,
                    (p[1] / g.resolution).floor() as i64,
                )
            };
            let mut ground: std::collections::HashMap<(i64, i64), f64> = Default::default();
            for p in &centres {
                let z = ground.entry(key(p)).or_insert(p[2]);
                *z = z.min(p[2]);
            }
            let above = centres.iter().map(|p| [p[0], p[1], p[2] - ground[&key(p)]]);
            return Self::from_voxels(above.zip(is_floor), g.resolution, (0.2, 2.0));
        };
        Self::from_voxels(
            centres.into_iter().zip(is_floor),
            g.resolution,
            (base + 0.2, base + 2.0),
        )
    }

    /// The (column, row) of the cell containing world point (x, y), if any.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let c = ((x - self.min_xy[0]) / self.cell).floor();
        let r = ((y - self.min_xy[1]) / self.cell).floor();
        if c >= 0.0 && r >= 0.0 && c < self.width as f64 && r < self.height as f64 {
            Some((c as usize, r as usize))
        } else {
            None
        }
    }

    /// The cell at (column, row), if inside the plan.
    pub fn get(&self, col: usize, row: usize) -> Option<PlanCell> {
        if col >= self.width || row >= self.height {
            return None;
        }
        // Checked: the fields are public, so width and height may not
        // match `cells` (and their product may not even fit).
        let i = row.checked_mul(self.width)?.checked_add(col)?;
        self.cells.get(i).copied()
    }

    /// World (x, y) extent: `([x_min, y_min], [x_max, y_max])`, metres.
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        (
            self.min_xy,
            [
                self.min_xy[0] + self.width as f64 * self.cell,
                self.min_xy[1] + self.height as f64 * self.cell,
            ],
        )
    }

    /// A plan with cells `factor` times larger (`factor >= 1`), each
    /// merged cell showing the most important of its cells (obstacle over
    /// floor over unknown), so thin walls survive when drawn small.
    pub(crate) fn coarsened(&self, factor: usize) -> FloorPlan {
        let factor = factor.max(1);
        let width = self.width.div_ceil(factor);
        let height = self.height.div_ceil(factor);
        let mut cells = vec![PlanCell::Unknown; width * height];
        for row in 0..self.height {
            for col in 0..self.width {
                let Some(c) = self.get(col, row) else {
                    continue;
                };
                let i = (row / factor) * width + col / factor;
                if c.priority() > cells[i].priority() {
                    cells[i] = c;
                }
            }
        }
        FloorPlan {
            min_xy: self.min_xy,
            cell: self.cell * factor as f64,
            width,
            height,
            cells,
        }
    }

    /// Horizontal runs of equal, known cells: `(row, first col, end col
    /// (exclusive), kind)`. Drawing runs instead of cells keeps SVGs small.
    pub(crate) fn runs(&self) -> Vec<(usize, usize, usize, PlanCell)> {
        let mut runs = Vec::new();
        for row in 0..self.height {
            let mut col = 0;
            while col < self.width {
                let kind = self.get(col, row).unwrap_or_default();
                let start = col;
                while col < self.width && self.get(col, row) == Some(kind) {
                    col += 1;
                }
                if kind != PlanCell::Unknown {
                    runs.push((row, start, col, kind));
                }
            }
        }
        runs
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use PlanCell::{Floor, Obstacle, Unknown};

    /// Voxels of 0.1 m at centres (i + 0.5) * 0.1 in x and y.
    fn centre(i: i32, j: i32, z: f64) -> [f64; 3] {
        [(i as f64 + 0.5) * 0.1, (j as f64 + 0.5) * 0.1, z]
    }

    /// A street climbing 4 m over 20 columns, with a wall 1 m above the
    /// ground at its foot and one at its top, and no floor feature: both
    /// walls are obstacles (above the lowest voxel of the whole map, the
    /// top one fell outside the band), the ground between them is not.
    #[test]
    fn a_climbing_street_keeps_its_walls_along_the_whole_way() {
        use crate::map::{FeatureDb, GridSpec, LanguageMap};
        let grid = GridSpec {
            resolution: 0.2,
            origin: nalgebra::Vector3::zeros(),
        };
        let db = FeatureDb::from_rows(2, 0.02, vec![1.0, 0.0]).unwrap();
        let mut leaves = Vec::new();
        for i in 0..20 {
            leaves.push(([i, 0, i], 0u32)); // the ground, 0.2 m up a column
        }
        leaves.push(([0, 0, 5], 0)); // 1 m above the foot's ground
        leaves.push(([19, 0, 24], 0)); // 1 m above the top's ground
        let map = LanguageMap::from_cells(grid, db, "t", leaves).unwrap();
        let plan = FloorPlan::from_map(&map, None, 0.9).unwrap();
        let at = |x: f64| plan.get(plan.cell_of(x, 0.1).unwrap().0, 0).unwrap();
        assert_eq!(at(0.1), Obstacle);
        assert_eq!(at(19.0 * 0.2 + 0.1), Obstacle);
        assert_eq!(at(10.0 * 0.2 + 0.1), Unknown);
    }

    #[test]
    fn from_voxels_marks_columns_by_the_obstacle_band() {
        let voxels = vec![
            // column (0,0): floor only
            (centre(0, 0, 0.05), true),
            // column (1,0): floor and a chair seat in the band
            (centre(1, 0, 0.05), true),
            (centre(1, 0, 0.45), false),
            // column (2,0): floor with ceiling above the band: still floor
            (centre(2, 0, 0.05), true),
            (centre(2, 0, 2.55), false),
            // column (0,2): a wall without floor
            (centre(0, 2, 1.05), false),
            // column (3,2): clutter below the band only: ignored entirely,
            // so it does not widen the plan either
            (centre(3, 2, 0.05), false),
            // non-finite voxels are skipped
            ([f64::NAN, 0.0, 0.5], false),
        ];
        let plan = FloorPlan::from_voxels(voxels.into_iter(), 0.1, (0.2, 2.0)).unwrap();
        assert_eq!((plan.width, plan.height), (3, 3));
        assert!((plan.min_xy[0] - 0.0).abs() < 1e-12 && (plan.min_xy[1] - 0.0).abs() < 1e-12);
        #[rustfmt::skip]
        let expected = vec![
            Floor,    Obstacle, Floor,    // row 0 (y in [0, 0.1))
            Unknown,  Unknown,  Unknown,  // row 1
            Obstacle, Unknown,  Unknown,  // row 2
        ];
        assert_eq!(plan.cells, expected);
        assert_eq!(plan.cell_of(0.15, 0.05), Some((1, 0)));
        assert_eq!(plan.cell_of(-0.01, 0.05), None);
        let (lo, hi) = plan.bounds();
        assert!((hi[0] - 0.3).abs() < 1e-12 && (hi[1] - 0.3).abs() < 1e-12 && lo == [0.0, 0.0]);
    }

    #[test]
    fn from_voxels_with_coarser_cells_merges_columns() {
        // 0.1 m voxels into 0.25 m cells: the corner is at 0.05 - 0.125 =
        // -0.075, so x centres 0.05 and 0.15 fall in column 0, 0.25 and 0.35
        // in column 1; y centres 0.05 and 0.15 in row 0. An obstacle
        // anywhere in a cell wins.
        let voxels = vec![
            (centre(0, 0, 0.0), true),
            (centre(1, 0, 0.0), true),
            (centre(0, 1, 0.0), true),
            (centre(1, 1, 1.0), false),
            (centre(2, 0, 0.0), true),
            (centre(3, 1, 0.0), true),
        ];
        let plan = FloorPlan::from_voxels(voxels.into_iter(), 0.25, (0.5, 1.5)).unwrap();
        assert_eq!((plan.width, plan.height), (2, 1));
        assert!((plan.min_xy[0] + 0.075).abs() < 1e-12);
        assert_eq!(plan.cells, vec![Obstacle, Floor]);
    }

    #[test]
    fn from_voxels_rejects_bad_input() {
        let one = || std::iter::once(([0.0, 0.0, 0.0], true));
        assert!(FloorPlan::from_voxels(one(), 0.0, (0.0, 1.0)).is_none());
        assert!(FloorPlan::from_voxels(one(), f64::NAN, (0.0, 1.0)).is_none());
        assert!(FloorPlan::from_voxels(one(), 0.1, (1.0, 0.0)).is_none());
        assert!(FloorPlan::from_voxels(std::iter::empty(), 0.1, (0.0, 1.0)).is_none());
        // Only out-of-band obstacles: nothing contributes.
        let high = std::iter::once(([0.0, 0.0, 5.0], false));
        assert!(FloorPlan::from_voxels(high, 0.1, (0.0, 1.0)).is_none());
        // A huge extent at a tiny cell is refused, not allocated.
        let far = vec![([0.0, 0.0, 0.0], true), ([1e4, 1e4, 0.0], true)];
        assert!(FloorPlan::from_voxels(far.into_iter(), 1e-3, (0.0, 1.0)).is_none());
        let single = FloorPlan::from_voxels(one(), 0.1, (0.0, 1.0)).unwrap();
        assert_eq!(
            (single.width, single.height, single.cells.as_slice()),
            (1, 1, &[Floor][..])
        );
    }

    #[test]
    fn coarsened_keeps_obstacles_and_runs_cover_known_cells() {
        #[rustfmt::skip]
        let plan = FloorPlan {
            min_xy: [0.0, 0.0],
            cell: 1.0,
            width: 5,
            height: 2,
            cells: vec![
                Floor, Floor, Obstacle, Unknown, Floor,
                Floor, Floor, Floor,    Unknown, Unknown,
            ],
        };
        let coarse = plan.coarsened(2);
        assert_eq!((coarse.width, coarse.height, coarse.cell), (3, 1, 2.0));
        assert_eq!(coarse.cells, vec![Floor, Obstacle, Floor]);
        assert_eq!(
            plan.runs(),
            vec![
                (0, 0, 2, Floor),
                (0, 2, 3, Obstacle),
                (0, 4, 5, Floor),
                (1, 0, 3, Floor)
            ]
        );
    }
}
