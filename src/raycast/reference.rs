//! A pure-Rust reference traversal: 3-D DDA (Amanatides and Woo) over a
//! hash set of occupied cells, clipped to the cells' bounding box.
//!
//! About 1 M rays/s a core: the executable definition of the casting
//! semantics that tests hold Embree to, not the fast path.

use rustc_hash::FxHashMap;

use super::{Hit, RayCaster};
use crate::geometry::Ray;
use crate::map::Cell;

/// The reference ray caster.
#[derive(Debug, Clone)]
pub struct ReferenceCaster {
    resolution: f64,
    cells: FxHashMap<Cell, u32>,
    lo: [i32; 3],
    hi: [i32; 3],
}

impl ReferenceCaster {
    /// A caster over voxels of edge `resolution` (metres) at integer
    /// `cells` (grid frame); hit `leaf` values index `cells`. For a repeated
    /// cell the first index wins.
    pub fn new(resolution: f32, cells: &[Cell]) -> Self {
        let mut map = FxHashMap::default();
        map.reserve(cells.len());
        let mut lo = [i32::MAX; 3];
        let mut hi = [i32::MIN; 3];
        for (i, c) in cells.iter().enumerate() {
            map.entry(*c).or_insert(i as u32);
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        ReferenceCaster {
            resolution: resolution as f64,
            cells: map,
            lo,
            hi,
        }
    }

    /// Casts one ray.
    pub fn cast_one(&self, ray: &Ray) -> Hit {
        if self.cells.is_empty() || !ray.is_valid() {
            return Hit::miss();
        }
        let r = self.resolution;
        let o = ray.origin.map(|v| v as f64);
        let d = ray.dir.map(|v| v as f64);
        // Clip [t_min, t_max] to the bounding box of all cells.
        let lo = self.lo.map(|l| l as f64 * r);
        let hi = self.hi.map(|h| (h + 1) as f64 * r);
        let t = (ray.t_min as f64, ray.t_max as f64);
        let Some((t0, t1)) = super::clip_to_box(&o, &d, &lo, &hi, t) else {
            return Hit::miss();
        };
        // The cell at the entry point, kept inside the box against rounding.
        // A ray running inside a cell plane (zero direction component, origin
        // exactly on the plane) touches the closed cubes on both sides:
        // `graze` marks those axes, whose lower neighbour is looked up too.
        let mut graze = [false; 3];
        let mut cell = [0i32; 3];
        let mut step = [0i32; 3];
        let mut t_next = [f64::INFINITY; 3];
        let mut t_delta = [f64::INFINITY; 3];
        for a in 0..3 {
            let p = o[a] + t0 * d[a];
            let mut c = (p / r).floor() as i32;
            // Moving backwards from exactly a boundary: start in the lower cell.
            if d[a] < 0.0 && p == c as f64 * r {
                c -= 1;
            }
            graze[a] = d[a] == 0.0 && p == c as f64 * r && c > self.lo[a] && c <= self.hi[a];
            cell[a] = c.clamp(self.lo[a], self.hi[a]);
            if d[a] > 0.0 {
                step[a] = 1;
                t_next[a] = ((cell[a] + 1) as f64 * r - o[a]) / d[a];
                t_delta[a] = r / d[a];
            } else if d[a] < 0.0 {
                step[a] = -1;
                t_next[a] = (cell[a] as f64 * r - o[a]) / d[a];
                t_delta[a] = -r / d[a];
            }
        }
        let mut t = t0;
        loop {
            if let Some(leaf) = self.touched(cell, graze) {
                return Hit { leaf, t: t as f32 };
            }
            let a = if t_next[0] <= t_next[1] && t_next[0] <= t_next[2] {
                0
            } else if t_next[1] <= t_next[2] {
                1
            } else {
                2
            };
            t = t_next[a];
            // A zero direction never leaves its cell; beyond t1 is out of range.
            if !t.is_finite() || t > t1 {
                return Hit::miss();
            }
            cell[a] += step[a];
            if cell[a] < self.lo[a] || cell[a] > self.hi[a] {
                return Hit::miss();
            }
            t_next[a] += t_delta[a];
        }
    }
}

impl ReferenceCaster {
    /// The leaf at `cell`, or else at a cell across the grazed planes.
    fn touched(&self, cell: Cell, graze: [bool; 3]) -> Option<u32> {
        if let Some(&leaf) = self.cells.get(&cell) {
            return Some(leaf);
        }
        if !graze.contains(&true) {
            return None;
        }
        // The neighbours below along every non-empty subset of grazed axes.
        (1..8u32)
            .filter(|m| (0..3).all(|a| m & (1 << a) == 0 || graze[a]))
            .find_map(|m| {
                let c: Cell = std::array::from_fn(|a| cell[a] - ((m >> a) & 1) as i32);
                self.cells.get(&c).copied()
            })
    }
}

impl RayCaster for ReferenceCaster {
    fn cast_serial(&self, rays: &[Ray], hits: &mut [Hit]) {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        for (ray, hit) in rays.iter().zip(hits) {
            *hit = self.cast_one(ray);
        }
    }

    fn len(&self) -> usize {
        self.cells.len()
    }
}
