//! A 2-D caster for floor plans: rays are cast in the horizontal plane
//! against the occupied columns of a plan (a 2-D DDA, Amanatides and Woo,
//! with empty-space skipping).
//!
//! # Camera pixels as planar rays
//!
//! A ray of the 3-D filter (origin at the camera centre, direction through
//! the pixel, both in the grid frame) becomes its vertical projection: the
//! origin's and direction's x and y. The ray parameter `t` keeps its
//! meaning: the planar hit at `t` is the xy of the 3-D point
//! `origin + t dir`, so `t` is still in units of the 3-D `|dir|` (and
//! `t_max` still limits the 3-D length). A pixel looking straight up or
//! down (horizontal part below 1e-6 of `|dir|`) misses.
//!
//! Built with [`PlanarCaster::new`] alone, every column is an infinitely
//! tall prism `[i r, (i+1) r] x [j r, (j+1) r]` and the z of rays and cells
//! is ignored: a pixel's ray stops at the first occupied column in its
//! direction, whatever its elevation (the SeDAR\* baseline's view).
//!
//! # What a pixel sees in plan view ([`PlanarCaster::with_heights`])
//!
//! A floor plan keeps, besides each column's averaged feature, the vertical
//! extent of the leaves it averaged, up to the ceiling only where its 3-D
//! leaves go on up to it ([`crate::map::FloorPlan::column_extents`]);
//! and the room has a floor and a ceiling the plan leaves out. With those,
//! a pixel's ray is followed in 3-D over the plan: it ends where it leaves
//! the vertical window `[z_lo, z_hi]` (below it, the pixel sees the floor;
//! above it, the ceiling; either way no plan column: a miss), and it hits
//! the first column whose extent it passes through inside that column's
//! square (so it looks over a table at the wall behind, or down onto the
//! table top). Nothing but the pixel's direction and the camera's height is
//! used (no depth).
//!
//! Where the ray leaves the window, [`PlanarCaster::with_surfaces`] gives
//! it the floor or ceiling of the cell it is over at that point, if that
//! cell has one of its own (a floor plan's free columns keep the 3-D
//! map's floor under them), else the plan-wide exit.
//!
//! [`PlanarCaster::with_skirts`] gives a column its own base and top: a
//! pixel hitting it low (high) reports the base (top) leaf of its cell
//! instead of the column's own, so a wall can carry, near the floor and
//! the ceiling, what its 3-D voxels there carry.
//!
//! # Speed
//!
//! The occupied columns are a dense grid over their bounding box (a leaf
//! index per cell) with each free cell's Chebyshev distance `D` to the
//! nearest occupied one, and, per octant of directions, its distance to
//! the nearest occupied cell in the cone a ray of that octant can reach
//! ([`crate::chebyshev::cone_distance`]); `D` below is the larger of the
//! two for the walk's octant (a ray leaving a wall behind it looks only
//! ahead). From a cell with `D` of 6 or more the ray jumps
//! `D - 2` cells along its longer axis (no occupied cell can lie within);
//! from one with a smaller `D` it takes `D` DDA steps before it looks at a
//! cell again (each step reaches a neighbour, and every cell within `D - 1`
//! is free); from an occupied one, one step. The result equals the plain
//! DDA's (checked against [`super::ReferenceCaster`] in the tests).
//!
//! A batch ([`RayCaster::cast_serial`]) walks each run of consecutive rays
//! that share a planar ray (same origin, horizontal directions parallel to
//! 1e-6: a level camera's pixels of one image column) once: the walk lists
//! the occupied columns along the planar ray with the parameters at which
//! it enters and leaves them, up to the first column no ray can pass (one
//! that spans the whole window), and each ray of the run then checks its
//! own heights against that short list. The filter hands the caster its
//! rays in that order ([`RayCaster::wants_column_order`]); no hashing.
//!
//! Faster still, [`RayCaster::cast_fans`] takes a level camera's pixels
//! as fans, no [`Ray`] made: per image column the horizontal direction
//! once and each pixel's slope and range, so the run is known without
//! comparing directions, every ray's `t` is the walk's, and the walk is
//! the same. The filter's sensor model uses it whenever every particle's
//! camera is level (the 2-D block's are).
//!
//! Measured on the held-out sequence 1000 (150 frames, 1024 particles x
//! 2048 rays, `omcl bench table1-floorplan --sequences 1 --variants
//! OMCL_GT`, two interleaved runs each, AMD EPYC Zen 4, 2 cores,
//! 2026-11-25): see docs/table1.md's "Speed, 2-D against 3-D".

use super::{Fan, Hit, RayCaster};
use crate::geometry::Ray;
use crate::map::Cell;

/// [`PlanarCaster::vertical_range`]'s surface for a ray the window does not
/// end (it ends at its own `t_max`): no floor or ceiling hit.
const NO_EXIT: usize = usize::MAX;

/// The clearance (cells) from which a walk jumps through free space; below
/// it, it takes that many DDA steps without looking at the cells. A jump
/// restarts the walk (the cell and the edges from `t`: a chain of
/// conversions), where steps that look at no cell are a few additions
/// each. From 3 (every clearance a jump, 2026-11-25) to 6, with the steps:
/// the same hits, and the 2-D cast of the bench's speed line 11 to 13 %
/// cheaper at 1024 particles x 2048 pixels (21.2 / 21.8 ms a step against
/// 24.5 / 24.6, held-out sequence 1000), 9 % at the block's 8192 (35.2
/// against 38.7); docs/table1.md, "The walk's jumps, and what the walk
/// costs".
const JUMP_CLEARANCE: u32 = 6;

/// Most columns a shared walk lists before the rays still unresolved are
/// cast on their own.
const MAX_LISTED: usize = 64;

/// The planar (floor-plan) ray caster.
#[derive(Debug, Clone)]
pub struct PlanarCaster {
    resolution: f64,
    lo: [i32; 2],
    size: [i32; 2],
    /// Leaf index per grid cell (row-major, x fastest) or `Hit::MISS`.
    leaf: Vec<u32>,
    /// Per octant of walk directions ([`crate::chebyshev::Octant::index`]),
    /// then per grid cell (as `leaf`): how many cells a walk in that octant
    /// may go from the cell without looking (0 on an occupied cell, at
    /// least 1 on a free one), capped at 255: the larger of the cell's
    /// Chebyshev distance to the nearest occupied cell and its distance
    /// to one in the octant's cone ([`crate::chebyshev::cone_distance`]).
    /// What a walk reads a cell (the leaf only for the occupied ones).
    clearance: Vec<u8>,
    /// Vertical extent `[bottom, top]` (grid-frame z, metres) of each leaf's
    /// column; `None`: infinitely tall prisms.
    extents: Option<Vec<[f32; 2]>>,
    /// Grid-frame heights where a ray leaves the plan: below `window[0]`
    /// (the floor) or above `window[1]` (the ceiling).
    window: [f32; 2],
    /// Leaves reported where a ray leaves the window through the floor and
    /// through the ceiling (`Hit::MISS`: a miss).
    exits: [u32; 2],
    /// Per grid cell (as `leaf`), the floor's and the ceiling's own leaf
    /// there, or `Hit::MISS` for `exits`' ([`PlanarCaster::with_surfaces`]).
    surfaces: Option<Vec<[u32; 2]>>,
    /// Per grid cell (as `leaf`), the column's own base and top leaf, or
    /// `Hit::MISS` for the column's own ([`PlanarCaster::with_skirts`]).
    skirts: Option<Vec<[u32; 2]>>,
    /// A column hit below `skirt_z[0]` reports its base leaf, one hit at or
    /// above `skirt_z[1]` its top leaf (grid-frame z).
    skirt_z: [f64; 2],
    n: usize,
}

/// One occupied column along a shared planar walk: its leaf and the
/// parameters (in the walked ray's units) at which the ray enters and
/// leaves its square.
#[derive(Debug, Clone, Copy)]
struct Crossing {
    leaf: u32,
    t_in: f64,
    t_out: f64,
    /// The column's vertical extent (grid-frame z).
    bottom: f64,
    top: f64,
    /// The column's base and top leaves (`Hit::MISS`: none of its own).
    skirt: [u32; 2],
}

impl PlanarCaster {
    /// A caster over columns of edge `resolution` at the cells `[i, j, 0]`
    /// of `cells` (cells of other layers are no columns: a one-layer map
    /// keeps the leaves of [`PlanarCaster::with_heights`]' exits there);
    /// hit `leaf` values index `cells`. For a repeated column the first
    /// index wins. Columns are infinitely tall.
    pub fn new(resolution: f32, cells: &[Cell]) -> Self {
        let columns: Vec<Cell> = cells.iter().copied().filter(|c| c[2] == 0).collect();
        let (lo, hi) = column_bounds(&columns);
        let size = [hi[0] - lo[0] + 1, hi[1] - lo[1] + 1];
        let total = (size[0].max(0) as usize) * (size[1].max(0) as usize);
        let mut leaf = vec![Hit::MISS; total];
        for (k, c) in cells.iter().enumerate().filter(|(_, c)| c[2] == 0) {
            let idx = ((c[1] - lo[1]) * size[0] + (c[0] - lo[0])) as usize;
            if leaf[idx] == Hit::MISS {
                leaf[idx] = k as u32;
            }
        }
        let (w, h) = (size[0].max(0) as usize, size[1].max(0) as usize);
        let occupied = |i: usize| leaf[i] != Hit::MISS;
        let around = crate::chebyshev::distance(w, h, occupied);
        let mut clearance = Vec::with_capacity(8 * total);
        for octant in crate::chebyshev::Octant::all() {
            let cone = crate::chebyshev::cone_distance(w, h, octant, occupied);
            clearance.extend(
                around
                    .iter()
                    .zip(&cone)
                    .map(|(&a, &c)| if a == 0 { 0 } else { a.max(c) }),
            );
        }
        PlanarCaster {
            resolution: resolution as f64,
            lo,
            size,
            leaf,
            clearance,
            extents: None,
            window: [f32::NEG_INFINITY, f32::INFINITY],
            exits: [Hit::MISS; 2],
            surfaces: None,
            skirts: None,
            skirt_z: [f64::NEG_INFINITY, f64::INFINITY],
            n: cells.len(),
        }
    }

    /// The same caster with each leaf's column spanning `extents[leaf]`
    /// (`[bottom, top]`, grid-frame z in metres; `-inf` / `inf` for a
    /// column reaching the floor / ceiling) and rays ending where they
    /// leave `window` (`[floor, ceiling]`, grid-frame z): there they hit
    /// leaf `exits[0]` (the floor) or `exits[1]` (the ceiling), or miss
    /// for `Hit::MISS`. A leaf without an extent (a short slice) spans the
    /// whole window.
    pub fn with_heights(mut self, extents: &[[f32; 2]], window: [f32; 2], exits: [u32; 2]) -> Self {
        let mut e = vec![[f32::NEG_INFINITY, f32::INFINITY]; self.n];
        for (a, b) in e.iter_mut().zip(extents) {
            *a = *b;
        }
        self.extents = Some(e);
        self.window = window;
        self.exits = exits;
        self
    }

    /// The same caster with a floor and a ceiling of their own per column:
    /// a ray leaving the window through the floor (ceiling) at a point
    /// over cell `[i, j]` hits `floor` (`ceiling`) leaf of that cell, and
    /// `exits`' one where the cell has none or lies outside the columns'
    /// bounding box. Each entry is a cell and its leaf.
    pub fn with_surfaces(mut self, floor: &[([i32; 2], u32)], ceiling: &[([i32; 2], u32)]) -> Self {
        self.surfaces = Some(self.per_cell([floor, ceiling]));
        self
    }

    /// A pair of leaves per grid cell (as `leaf`): `lists[k]`'s leaf of
    /// the cell in slot `k`, `Hit::MISS` where it names none; cells outside
    /// the columns' bounding box are dropped.
    fn per_cell(&self, lists: [&[([i32; 2], u32)]; 2]) -> Vec<[u32; 2]> {
        let mut s = vec![[Hit::MISS; 2]; self.leaf.len()];
        for (side, list) in lists.into_iter().enumerate() {
            for &(c, leaf) in list {
                let (i, j) = (c[0] - self.lo[0], c[1] - self.lo[1]);
                if (0..self.size[0]).contains(&i) && (0..self.size[1]).contains(&j) {
                    s[(j * self.size[0] + i) as usize][side] = leaf;
                }
            }
        }
        s
    }

    /// The same caster with each column's own base and top: a column hit
    /// below `heights[0]` (grid-frame z) reports the `base` leaf of its
    /// cell, one hit at or above `heights[1]` its `top` leaf, if the cell
    /// has one; elsewhere, and where it has none, the column's own leaf.
    /// Each entry is a cell and its leaf.
    pub fn with_skirts(
        mut self,
        base: &[([i32; 2], u32)],
        top: &[([i32; 2], u32)],
        heights: [f32; 2],
    ) -> Self {
        self.skirts = Some(self.per_cell([base, top]));
        self.skirt_z = heights.map(f64::from);
        self
    }

    /// The base and top leaves of grid cell `idx` (`Hit::MISS` for none).
    fn skirt(&self, idx: usize) -> [u32; 2] {
        self.skirts.as_ref().map_or([Hit::MISS; 2], |s| s[idx])
    }

    /// The leaf a column of leaf `leaf` with skirt leaves `skirt` reports
    /// for a hit at height `z`.
    fn zone_leaf(&self, leaf: u32, skirt: [u32; 2], z: f64) -> u32 {
        let own = if z < self.skirt_z[0] {
            skirt[0]
        } else if z >= self.skirt_z[1] {
            skirt[1]
        } else {
            Hit::MISS
        };
        if own == Hit::MISS { leaf } else { own }
    }

    /// The parameter interval of `ray` inside the vertical window, within
    /// its own `[t_min, t_max]`, and the surface it meets at the end of it
    /// (0 the floor, 1 the ceiling, [`NO_EXIT`] when the window does not
    /// end it); `None` if empty.
    fn vertical_range(&self, ray: &Ray) -> Option<(f64, f64, usize)> {
        self.window_range(ray.origin[2], ray.dir[2], ray.t_min, ray.t_max)
    }

    /// [`PlanarCaster::vertical_range`] of a ray from height `oz` with
    /// vertical direction `dz` over `[t_min, t_max]`.
    fn window_range(&self, oz: f32, dz: f32, t_min: f32, t_max: f32) -> Option<(f64, f64, usize)> {
        let (oz, dz) = (oz as f64, dz as f64);
        let (zl, zh) = (self.window[0] as f64, self.window[1] as f64);
        let (mut a, mut b) = (t_min as f64, t_max as f64);
        let mut exit = NO_EXIT;
        if dz == 0.0 {
            if oz < zl || oz > zh {
                return None;
            }
        } else {
            let (t1, t2) = ((zl - oz) / dz, (zh - oz) / dz);
            // Plain comparisons (no NaN here; see `first_met`).
            let (near, end) = if t1 < t2 { (t1, t2) } else { (t2, t1) };
            if near > a {
                a = near;
            }
            if end <= b {
                b = end;
                exit = usize::from(dz > 0.0);
            }
        }
        (a <= b).then_some((a, b, exit))
    }

    /// Where `ray` (its own units, already limited to `[a, b]`) first meets
    /// leaf `leaf`'s column inside the square it crosses over `[t_in,
    /// t_out]`; `None` if it passes over or under.
    fn meets(&self, ray: &Ray, leaf: u32, t_in: f64, t_out: f64, a: f64, b: f64) -> Option<f64> {
        let (lo, hi) = (t_in.max(a), t_out.min(b));
        if lo > hi {
            return None;
        }
        let Some(ext) = &self.extents else {
            return Some(lo);
        };
        let [bottom, top] = ext.get(leaf as usize).copied()?;
        let (oz, dz) = (ray.origin[2] as f64, ray.dir[2] as f64);
        let (bottom, top) = (bottom as f64, top as f64);
        if dz == 0.0 {
            return (bottom <= oz && oz <= top).then_some(lo);
        }
        let (t1, t2) = ((bottom - oz) / dz, (top - oz) / dz);
        let (s, e) = (lo.max(t1.min(t2)), hi.min(t1.max(t2)));
        (s <= e).then_some(s)
    }

    /// Whether no ray inside the window passes leaf `leaf`'s column.
    fn full_height(&self, leaf: u32) -> bool {
        match &self.extents {
            None => true,
            Some(e) => e
                .get(leaf as usize)
                .is_some_and(|&[b, t]| b <= self.window[0] && t >= self.window[1]),
        }
    }

    /// Walks the planar ray `o + t d` over `[t0, t1]` and calls `visit`
    /// with every occupied column it crosses (grid cell index, leaf, entry
    /// and exit parameters) in order, until `visit` returns `true`.
    fn walk(
        &self,
        o: [f64; 2],
        d: [f64; 2],
        t_range: (f64, f64),
        mut visit: impl FnMut(usize, u32, f64, f64) -> bool,
    ) {
        let r = self.resolution;
        let lo = [0, 1].map(|a| self.lo[a] as f64 * r);
        let hi = [0, 1].map(|a| (self.lo[a] + self.size[a]) as f64 * r);
        let Some((t0, t1)) = super::clip_to_box(&o, &d, &lo, &hi, t_range) else {
            return;
        };
        let (sx, sy) = (d[0].signum() as i32, d[1].signum() as i32);
        let (dx, dy) = (r / d[0].abs(), r / d[1].abs());
        let jump_per_cell = r / d[0].abs().max(d[1].abs());
        // The walk restarts after every jump through free space: no
        // division and no libm `floor` call there.
        let inv_r = 1.0 / r;
        let inv_d = [1.0 / d[0], 1.0 / d[1]];
        let (w, h) = (self.size[0], self.size[1]);
        let octant = crate::chebyshev::Octant {
            neg_x: sx < 0,
            neg_y: sy < 0,
            y_major: d[1].abs() > d[0].abs(),
        };
        let cells = (w as usize) * (h as usize);
        let clearance = &self.clearance[octant.index() * cells..(octant.index() + 1) * cells];
        // The cell at a parameter, kept inside the box against rounding,
        // and the parameter of its next edge along an axis.
        let cell_at = |t: f64, a: usize| -> i32 {
            let c = floor_i64((o[a] + t * d[a]) * inv_r);
            (c.clamp(self.lo[a] as i64, (self.lo[a] + self.size[a] - 1) as i64) as i32) - self.lo[a]
        };
        let edge = |c: i32, a: usize, s: i32| -> f64 {
            if s == 0 {
                return f64::INFINITY;
            }
            let e = (c + self.lo[a] + i32::from(s > 0)) as f64 * r;
            (e - o[a]) * inv_d[a]
        };
        let mut t = t0;
        'outer: loop {
            let (mut cx, mut cy) = (cell_at(t, 0), cell_at(t, 1));
            let (mut nx, mut ny) = (edge(cx, 0, sx), edge(cy, 1, sy));
            loop {
                let idx = (cy * w + cx) as usize;
                let clear = clearance[idx] as u32;
                // DDA steps to take before looking at a cell again: one
                // from an occupied cell, and from a free one its clearance
                // (every cell the walk can reach in clearance - 1 steps is
                // free: see the field's documentation).
                let steps = if clear == 0 {
                    let next = if nx < ny { nx } else { ny };
                    let out = if next < t1 { next } else { t1 };
                    if visit(idx, self.leaf[idx], t, out) {
                        return;
                    }
                    1
                } else {
                    if clear >= JUMP_CLEARANCE {
                        // Farther than the steps would go cheaply: jump,
                        // keeping one cell of margin for a position
                        // rounded into the next.
                        t += (clear - 2) as f64 * jump_per_cell;
                        if t > t1 {
                            return;
                        }
                        continue 'outer;
                    }
                    clear.max(1)
                };
                for _ in 0..steps {
                    let step_x = nx < ny;
                    t = if step_x { nx } else { ny };
                    if t > t1 {
                        return;
                    }
                    cx += if step_x { sx } else { 0 };
                    cy += if step_x { 0 } else { sy };
                    if (cx as u32) >= w as u32 || (cy as u32) >= h as u32 {
                        return;
                    }
                    nx = if step_x { nx + dx } else { nx };
                    ny = if step_x { ny } else { ny + dy };
                }
            }
        }
    }

    /// The ray's planar origin and direction, or `None` for an invalid or
    /// vertical ray.
    fn planar(ray: &Ray) -> Option<([f64; 2], [f64; 2])> {
        if !ray.is_valid() {
            return None;
        }
        let d = [ray.dir[0] as f64, ray.dir[1] as f64];
        let dz = ray.dir[2] as f64;
        let xy2 = d[0] * d[0] + d[1] * d[1];
        // |d_xy| <= 1e-6 |d|, squared (hypot is slow, and this runs per ray).
        if xy2 <= 1e-12 * (xy2 + dz * dz) {
            return None;
        }
        Some(([ray.origin[0] as f64, ray.origin[1] as f64], d))
    }

    /// Casts one ray (see the module documentation).
    pub fn cast_one(&self, ray: &Ray) -> Hit {
        if self.n == 0 {
            return Hit::miss();
        }
        let Some((o, d)) = Self::planar(ray) else {
            return Hit::miss();
        };
        let Some((a, b, exit)) = self.vertical_range(ray) else {
            return Hit::miss();
        };
        let mut hit = None;
        self.walk(o, d, (a, b), |idx, leaf, t_in, t_out| {
            match self.meets(ray, leaf, t_in, t_out, a, b) {
                Some(t) => {
                    let z = ray.origin[2] as f64 + ray.dir[2] as f64 * t;
                    let leaf = self.zone_leaf(leaf, self.skirt(idx), z);
                    hit = Some(Hit { leaf, t: t as f32 });
                    true
                }
                None => false,
            }
        });
        // The floor or ceiling only for a ray no column stopped.
        hit.unwrap_or_else(|| self.exit_hit(exit, o, d, b))
    }

    /// The hit of a ray `o + t d` (planar part) that meets no column
    /// before its window ends at `b` through `side` (see
    /// [`PlanarCaster::vertical_range`]): the floor's or ceiling's leaf
    /// over the cell it leaves through, else the plan-wide exit.
    fn exit_hit(&self, side: usize, o: [f64; 2], d: [f64; 2], b: f64) -> Hit {
        if side == NO_EXIT {
            return Hit::miss();
        }
        let mut leaf = self.exits[side];
        if let Some(s) = &self.surfaces {
            let inv_r = 1.0 / self.resolution;
            let i = floor_i64((o[0] + b * d[0]) * inv_r) - self.lo[0] as i64;
            let j = floor_i64((o[1] + b * d[1]) * inv_r) - self.lo[1] as i64;
            if (0..self.size[0] as i64).contains(&i) && (0..self.size[1] as i64).contains(&j) {
                let own = s[(j * self.size[0] as i64 + i) as usize][side];
                if own != Hit::MISS {
                    leaf = own;
                }
            }
        }
        if leaf == Hit::MISS {
            Hit::miss()
        } else {
            Hit { leaf, t: b as f32 }
        }
    }

    /// Lists the occupied columns along the planar ray `o + t d`, `t` in
    /// `[0, reach]`, with their extents, up to the first one no ray can
    /// pass or [`MAX_LISTED`] of them. Returns whether the list ends at
    /// such a column.
    fn list_crossings(
        &self,
        o: [f64; 2],
        d: [f64; 2],
        reach: f64,
        list: &mut Vec<Crossing>,
    ) -> bool {
        list.clear();
        let mut complete = false;
        self.walk(o, d, (0.0, reach), |idx, leaf, t_in, t_out| {
            let [bottom, top] = match &self.extents {
                Some(e) => e
                    .get(leaf as usize)
                    .copied()
                    .unwrap_or([f32::NEG_INFINITY; 2]),
                None => [f32::NEG_INFINITY, f32::INFINITY],
            };
            list.push(Crossing {
                leaf,
                t_in,
                t_out,
                bottom: bottom as f64,
                top: top as f64,
                skirt: self.skirt(idx),
            });
            complete = self.full_height(leaf);
            complete || list.len() >= MAX_LISTED
        });
        complete
    }

    /// The first listed column met by a ray of height `oz + m t` over
    /// `t` in `[a, b]` (the walk's units): its leaf and `t`. Compared in z,
    /// a multiply-add a column; the division only for the hit.
    fn first_met(&self, list: &[Crossing], oz: f64, m: f64, a: f64, b: f64) -> Option<(u32, f64)> {
        // Plain comparisons, not `f64::max` / `min` (whose NaN handling
        // was most of this loop by `perf`): no operand here is NaN, and
        // the slope's sign says which end of a crossing is the lower.
        let rising = m >= 0.0;
        for c in list {
            let lo = if c.t_in > a { c.t_in } else { a };
            if lo > b {
                return None;
            }
            let hi = if c.t_out < b { c.t_out } else { b };
            if lo > hi {
                continue;
            }
            let (z0, z1) = (oz + m * lo, oz + m * hi);
            let (z_min, z_max) = if rising { (z0, z1) } else { (z1, z0) };
            if z_max < c.bottom || z_min > c.top {
                continue;
            }
            let t = if (c.bottom..=c.top).contains(&z0) {
                lo
            } else if m < 0.0 {
                (c.top - oz) / m
            } else {
                (c.bottom - oz) / m
            };
            return Some((self.zone_leaf(c.leaf, c.skirt, oz + m * t), t));
        }
        None
    }

    /// Casts a run of rays sharing one planar ray (`rays[0]`'s): one walk,
    /// then each ray checks the listed columns against its own heights.
    fn cast_run(
        &self,
        rays: &[Ray],
        hits: &mut [Hit],
        list: &mut Vec<Crossing>,
        scratch: &mut Vec<Option<(f64, f64, f64, usize)>>,
    ) {
        let Some((o, d0)) = Self::planar(&rays[0]) else {
            for (r, h) in rays.iter().zip(hits.iter_mut()) {
                *h = self.cast_one(r);
            }
            return;
        };
        let n0 = (d0[0] * d0[0] + d0[1] * d0[1]).sqrt();
        // Each ray's scale (its t per walked t) and window, in its units;
        // `None` for a ray that cannot hit.
        let mut reach = 0.0f64;
        scratch.clear();
        scratch.extend(rays.iter().map(|r| {
            let (dx, dy) = (r.dir[0] as f64, r.dir[1] as f64);
            let k = n0 / (dx * dx + dy * dy).sqrt();
            let range = Self::planar(r).and(self.vertical_range(r));
            if let Some((_, b, _)) = range {
                reach = reach.max(b / k);
            }
            range.map(|(a, b, exit)| (k, a, b, exit))
        }));
        let complete = self.list_crossings(o, d0, reach, list);
        let last = list.last().map_or(f64::INFINITY, |c| c.t_out);
        for ((r, h), s) in rays.iter().zip(hits.iter_mut()).zip(scratch.iter()) {
            let Some((k, a, b, exit)) = *s else {
                *h = Hit::miss();
                continue;
            };
            // In the walk's units: t / k, heights oz + (dz k) t.
            let (oz, m) = (r.origin[2] as f64, r.dir[2] as f64 * k);
            *h = match self.first_met(list, oz, m, a / k, b / k) {
                Some((leaf, t)) => Hit {
                    leaf,
                    t: (t * k) as f32,
                },
                None if !complete && list.len() >= MAX_LISTED && b > last * k => self.cast_one(r),
                None => {
                    let dr = [r.dir[0] as f64, r.dir[1] as f64];
                    self.exit_hit(exit, o, dr, b)
                }
            };
        }
    }
}

/// `x.floor()` as an integer, without the libm call `floor` is on a
/// baseline x86-64 target (saturating, as `as` casts are).
fn floor_i64(x: f64) -> i64 {
    let c = x as i64;
    c - i64::from((c as f64) > x)
}

/// Whether `b` shares `a`'s planar ray: the same origin (bit for bit) and
/// horizontal directions parallel to 1e-6 (same sense).
fn same_planar_ray(a: &Ray, b: &Ray) -> bool {
    if a.origin != b.origin {
        return false;
    }
    let (ax, ay, bx, by) = (
        a.dir[0] as f64,
        a.dir[1] as f64,
        b.dir[0] as f64,
        b.dir[1] as f64,
    );
    let cross = ax * by - ay * bx;
    let dot = ax * bx + ay * by;
    dot > 0.0 && cross * cross <= 1e-12 * (ax * ax + ay * ay) * (bx * bx + by * by)
}

impl RayCaster for PlanarCaster {
    /// Casts each run of consecutive rays that share a planar ray with one
    /// walk (see the module documentation); every ray gets the hit it
    /// would get alone.
    fn cast_serial(&self, rays: &[Ray], hits: &mut [Hit]) {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        let (mut list, mut scratch) = (Vec::new(), Vec::new());
        let mut start = 0;
        while start < rays.len() {
            let mut end = start + 1;
            while end < rays.len() && same_planar_ray(&rays[start], &rays[end]) {
                end += 1;
            }
            self.cast_run(
                &rays[start..end],
                &mut hits[start..end],
                &mut list,
                &mut scratch,
            );
            start = end;
        }
    }

    /// Yes: rays of one particle through pixels of one image column in a
    /// row share one walk.
    fn wants_column_order(&self) -> bool {
        true
    }

    /// One walk a fan, then each ray checks the listed columns against
    /// its own heights; no [`Ray`] is made unless a walk lists 64 columns
    /// without ending.
    fn cast_fans(
        &self,
        origin: [f32; 3],
        fans: &[Fan],
        slopes: &[f32],
        t_max: &[f32],
        hits: &mut [Hit],
    ) -> bool {
        assert!(
            slopes.len() == hits.len() && t_max.len() == hits.len(),
            "one slope, range and hit slot per ray"
        );
        let (mut list, mut window) = (Vec::new(), Vec::new());
        let oz = origin[2] as f64;
        let o = [origin[0] as f64, origin[1] as f64];
        for fan in fans {
            let (s, e) = (fan.start as usize, fan.end as usize);
            let d = [fan.dir[0] as f64, fan.dir[1] as f64];
            if self.n == 0 || d[0] * d[0] + d[1] * d[1] <= 1e-24 {
                hits[s..e].fill(Hit::miss());
                continue;
            }
            let mut reach = 0.0f64;
            window.clear();
            window.extend(slopes[s..e].iter().zip(&t_max[s..e]).map(|(&m, &tm)| {
                let range = self.window_range(origin[2], m, 0.0, tm);
                if let Some((_, b, _)) = range
                    && b > reach
                {
                    reach = b;
                }
                range
            }));
            let complete = self.list_crossings(o, d, reach, &mut list);
            let last = list.last().map_or(f64::INFINITY, |c| c.t_out);
            for (j, w) in (s..e).zip(&window) {
                let Some((a, b, exit)) = *w else {
                    hits[j] = Hit::miss();
                    continue;
                };
                hits[j] = match self.first_met(&list, oz, slopes[j] as f64, a, b) {
                    Some((leaf, t)) => Hit { leaf, t: t as f32 },
                    None if !complete && list.len() >= MAX_LISTED && b > last => {
                        self.cast_one(&Ray {
                            origin,
                            dir: [fan.dir[0], fan.dir[1], slopes[j]],
                            t_min: 0.0,
                            t_max: t_max[j],
                        })
                    }
                    None => self.exit_hit(exit, o, d, b),
                };
            }
        }
        true
    }

    fn len(&self) -> usize {
        self.n
    }
}

/// The smallest and largest column index (`[i, j]`) of `cells`, both
/// inclusive; `([0, 0], [-1, -1])` (no columns) for none.
pub fn column_bounds(cells: &[Cell]) -> ([i32; 2], [i32; 2]) {
    if cells.is_empty() {
        return ([0, 0], [-1, -1]);
    }
    let (mut lo, mut hi) = ([i32::MAX; 2], [i32::MIN; 2]);
    for c in cells {
        for a in 0..2 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raycast::ReferenceCaster;
    use rand::{Rng, SeedableRng};

    /// A hand-made plan at 0.5 m: a wall of columns x index 4, y 0..=3
    /// (leaves 0..=3), and a single column at (1, 3) (leaf 4).
    fn plan() -> Vec<Cell> {
        vec![[4, 0, 0], [4, 1, 0], [4, 2, 0], [4, 3, 0], [1, 3, 0]]
    }

    #[test]
    fn planar_rays_hit_the_hand_made_plan_where_computed() {
        let c = PlanarCaster::new(0.5, &plan());
        // From (0.25, 0.75) along +x: enters column x 4 at x = 2.0, t 1.75.
        let h = c.cast_one(&Ray::new([0.25, 0.75, 1.3], [1.0, 0.0, 0.0]));
        assert_eq!(h.leaf, 1);
        assert!((h.t - 1.75).abs() < 1e-6, "{h:?}");
        // The same pixel ray tilted down: z is ignored, t is in units of
        // the 3-D direction (horizontal part 1, so the same t).
        let h = c.cast_one(&Ray::new([0.25, 0.75, 1.3], [1.0, 0.0, -0.5]));
        assert_eq!((h.leaf, h.t), (1, 1.75));
        // Twice as long a direction: half the t.
        let h = c.cast_one(&Ray::new([0.25, 0.75, 0.0], [2.0, 0.0, 0.0]));
        assert!((h.t - 0.875).abs() < 1e-6);
        // Diagonal from (0.6, 0.05) along (1, 1): y = x - 0.55 reaches
        // x = 2.0 at y = 1.45, column (4, 2), t 1.4.
        let h = c.cast_one(&Ray::new([0.6, 0.05, 0.0], [1.0, 1.0, 0.0]));
        assert_eq!(h.leaf, 2);
        assert!((h.t - 1.4).abs() < 1e-5, "{h:?}");
        // Towards (1, 3) from (0.75, 0.25) along +y: enters at y 1.5, t 1.25.
        let h = c.cast_one(&Ray::new([0.75, 0.25, 0.0], [0.0, 1.0, 0.0]));
        assert_eq!(h.leaf, 4);
        assert!((h.t - 1.25).abs() < 1e-6);
        // Away from everything, vertical and beyond t_max: misses.
        assert!(
            !c.cast_one(&Ray::new([0.25, 0.75, 0.0], [-1.0, 0.0, 0.0]))
                .is_hit()
        );
        assert!(
            !c.cast_one(&Ray::new([0.25, 0.75, 0.0], [0.0, 0.0, 1.0]))
                .is_hit()
        );
        let mut short = Ray::new([0.25, 0.75, 0.0], [1.0, 0.0, 0.0]);
        short.t_max = 1.7;
        assert!(!c.cast_one(&short).is_hit());
        // Starting inside a column: hit at t_min.
        let h = c.cast_one(&Ray::new([2.2, 0.2, 0.0], [-1.0, 0.3, 0.0]));
        assert_eq!((h.leaf, h.t), (0, 0.0));
        assert_eq!(c.len(), 5);
    }

    /// The hand-made room below with a floor and a ceiling of their own
    /// over column (3, 0) (leaves 9 and 10): from (1.25, 0.25, 1.5) along
    /// +x, down 2 leaves the window (z 0.1) at t 0.7, x 1.95, over (3, 0):
    /// its floor; up 2 reaches the ceiling (z 2.5) at t 0.5, x 1.75, over
    /// (3, 0): its ceiling. Along -x the floor is reached at x 0.55, over
    /// (1, 0), outside the columns' box: the plan-wide floor (7). Batches
    /// and fans agree.
    #[test]
    fn rays_leaving_the_window_hit_the_floor_and_ceiling_of_their_cell() {
        let mut cells = plan();
        cells[4] = [2, 1, 0];
        let inf = f32::INFINITY;
        let mut extents = vec![[-inf, inf]; 4];
        extents.push([-inf, 0.75]);
        let c = PlanarCaster::new(0.5, &cells)
            .with_heights(&extents, [0.1, 2.5], [7, 8])
            .with_surfaces(&[([3, 0], 9), ([9, 9], 11)], &[([3, 0], 10)]);
        let o = [1.25, 0.25, 1.5];
        let rays = [
            Ray::new(o, [1.0, 0.0, -2.0]),
            Ray::new(o, [1.0, 0.0, 2.0]),
            Ray::new(o, [-1.0, 0.0, -2.0]),
            Ray::new(o, [-1.0, 0.0, 2.0]),
        ];
        let want = [(9, 0.7), (10, 0.5), (7, 0.7), (8, 0.5)];
        for (r, (leaf, t)) in rays.iter().zip(want) {
            let h = c.cast_one(r);
            assert_eq!(h.leaf, leaf, "{r:?}");
            assert!((h.t - t).abs() < 1e-6, "{h:?}");
        }
        // Level along +x: the wall (column (4, 0), leaf 0) at x 2, t 0.75.
        assert_eq!(c.cast_one(&Ray::new(o, [1.0, 0.0, 0.0])).leaf, 0);
        let mut hits = vec![Hit::miss(); 2];
        c.cast_serial(&rays[..2], &mut hits);
        assert_eq!([hits[0].leaf, hits[1].leaf], [9, 10]);
        let fans = [
            Fan {
                dir: [1.0, 0.0],
                start: 0,
                end: 2,
            },
            Fan {
                dir: [-1.0, 0.0],
                start: 2,
                end: 4,
            },
        ];
        let mut hits = vec![Hit::miss(); 4];
        assert!(c.cast_fans(o, &fans, &[-2.0, 2.0, -2.0, 2.0], &[inf; 4], &mut hits));
        let leaves: Vec<u32> = hits.iter().map(|h| h.leaf).collect();
        assert_eq!(leaves, [9, 10, 7, 8]);
    }

    /// The hand-made room's wall column (4, 0) (leaf 0) with a base of its
    /// own (leaf 20, hit below 0.4 m) and a top (leaf 21, hit from 2.2 m),
    /// and the table (2, 1) (leaf 4, top at 0.75 m) with a top of its own
    /// that no hit reaches (its top is below 2.2 m). From (0.25, 0.25, 1.5)
    /// along +x the wall is at x 2, t 1.75: level, z 1.5, the wall's own
    /// leaf; down 0.7, z 0.275, its base; up 0.5, z 2.375, its top; down
    /// 0.4 along row j 1, z 0.8 .. 0.6 over the table's square (x 1 to
    /// 1.5), so it meets the table top at z 0.75 (t 0.875, inside the
    /// 0.4 m .. 2.2 m middle): the table's own leaf. Column (4, 2) has none
    /// and reports its own leaf (2) at every height. Batches and fans
    /// agree.
    #[test]
    fn columns_report_their_own_base_and_top_by_the_height_hit() {
        let mut cells = plan();
        cells[4] = [2, 1, 0];
        let inf = f32::INFINITY;
        let mut extents = vec![[-inf, inf]; 4];
        extents.push([-inf, 0.75]);
        let c = PlanarCaster::new(0.5, &cells)
            .with_heights(&extents, [0.1, 2.5], [7, 8])
            .with_skirts(&[([4, 0], 20)], &[([4, 0], 21), ([2, 1], 22)], [0.4, 2.2]);
        let o = [0.25, 0.25, 1.5];
        let rays = [
            Ray::new(o, [1.0, 0.0, 0.0]),
            Ray::new(o, [1.0, 0.0, -0.7]),
            Ray::new(o, [1.0, 0.0, 0.5]),
        ];
        for (r, leaf) in rays.iter().zip([0, 20, 21]) {
            let h = c.cast_one(r);
            assert_eq!(h.leaf, leaf, "{r:?}");
            assert!((h.t - 1.75).abs() < 1e-6, "{h:?}");
        }
        let o1 = [0.25, 0.75, 1.5];
        let h = c.cast_one(&Ray::new(o1, [1.0, 0.0, -0.8]));
        assert_eq!(h.leaf, 4);
        assert!((h.t - 0.9375).abs() < 1e-6, "{h:?}");
        for dz in [-0.7, 0.0, 0.5] {
            assert_eq!(
                c.cast_one(&Ray::new([0.25, 1.25, 1.5], [1.0, 0.0, dz]))
                    .leaf,
                2
            );
        }
        let leaves = |hits: &[Hit]| hits.iter().map(|h| h.leaf).collect::<Vec<_>>();
        let mut hits = vec![Hit::miss(); 3];
        c.cast_serial(&rays, &mut hits);
        assert_eq!(leaves(&hits), [0, 20, 21]);
        let fans = [Fan {
            dir: [1.0, 0.0],
            start: 0,
            end: 3,
        }];
        let mut hits = vec![Hit::miss(); 3];
        assert!(c.cast_fans(o, &fans, &[0.0, -0.7, 0.5], &[inf; 3], &mut hits));
        assert_eq!(leaves(&hits), [0, 20, 21]);
    }

    /// A room by hand at 0.5 m: a full-height wall at x index 4 (j 0..=3,
    /// leaves 0..=3) and a table whose top is at 0.75 m in column (2, 1)
    /// (leaf 4), floor window at 0.1 m, ceiling at 2.5 m. The camera is at
    /// (0.25, 0.75, 1.5) looking along +x (row j 1): the table's square is
    /// x in [1.0, 1.5] (t 0.75 to 1.25), the wall starts at x 2.0 (t 1.75).
    #[test]
    fn pixels_look_over_low_columns_and_stop_at_floor_and_ceiling() {
        let mut cells = plan();
        cells[4] = [2, 1, 0];
        let inf = f32::INFINITY;
        let extents = [[-inf, inf]; 4]
            .into_iter()
            .chain([[-inf, 0.75]])
            .collect::<Vec<_>>();
        let c = PlanarCaster::new(0.5, &cells).with_heights(&extents, [0.1, 2.5], [Hit::MISS; 2]);
        let o = [0.25, 0.75, 1.5];
        let cast = |dz: f32| c.cast_one(&Ray::new(o, [1.0, 0.0, dz]));
        // Level: over the table (z 1.5 > 0.75), onto the wall at t 1.75.
        assert_eq!((cast(0.0).leaf, cast(0.0).t), (1, 1.75));
        // Down 0.5: z 1.125 .. 0.875 over the table's square, still above
        // it; the wall at z 0.625.
        assert_eq!((cast(-0.5).leaf, cast(-0.5).t), (1, 1.75));
        // Down 0.8: z reaches 0.75 at t 0.9375, inside the table's square.
        let h = cast(-0.8);
        assert_eq!(h.leaf, 4);
        assert!((h.t - 0.9375).abs() < 1e-6, "{h:?}");
        // Down 2: at the floor window (z 0.1) by t 0.7, before the table:
        // the pixel sees the floor, which the plan does not hold.
        assert!(!cast(-2.0).is_hit());
        // Up 0.5: z 2.375 at the wall, below the ceiling: the wall, which
        // goes on above the band.
        assert_eq!((cast(0.5).leaf, cast(0.5).t), (1, 1.75));
        // Up 1: at the ceiling by t 1.0: a miss.
        assert!(!cast(1.0).is_hit());
        // With exits, the floor and ceiling pixels hit their leaves (here 7
        // and 8) where they leave the window: z 0.1 at t 0.7, z 2.5 at t 1.
        let sky = PlanarCaster::new(0.5, &cells).with_heights(&extents, [0.1, 2.5], [7, 8]);
        let h = sky.cast_one(&Ray::new(o, [1.0, 0.0, -2.0]));
        assert_eq!(h.leaf, 7);
        assert!((h.t - 0.7).abs() < 1e-6, "{h:?}");
        let h = sky.cast_one(&Ray::new(o, [1.0, 0.0, 1.0]));
        assert_eq!((h.leaf, h.t), (8, 1.0));
        assert_eq!(sky.cast_one(&Ray::new(o, [1.0, 0.0, 0.0])).leaf, 1);
        // Without heights every column is a full prism: the table at 0.75.
        let flat = PlanarCaster::new(0.5, &cells);
        let h = flat.cast_one(&Ray::new(o, [1.0, 0.0, -2.0]));
        assert_eq!((h.leaf, h.t), (4, 0.75));
        // One run of these rays (the pixels of one image column) cast as a
        // batch gets the same hits, and so does a run with its directions
        // scaled (t in each ray's own units).
        let dzs = [0.0, -0.5, -0.8, -2.0, 0.5, 1.0];
        for scale in [1.0f32, 2.5] {
            let rays: Vec<Ray> = dzs
                .iter()
                .map(|&dz| Ray::new(o, [scale, 0.0, scale * dz]))
                .collect();
            for caster in [&c, &sky] {
                let mut hits = vec![Hit::miss(); rays.len()];
                caster.cast_serial(&rays, &mut hits);
                for (r, h) in rays.iter().zip(&hits) {
                    let one = caster.cast_one(r);
                    assert_eq!(h.leaf, one.leaf, "{r:?}");
                    assert!(!one.is_hit() || (h.t - one.t).abs() < 1e-6, "{h:?} {one:?}");
                }
                assert_eq!(hits[2].leaf, 4);
                assert!((hits[2].t - 0.9375 / scale).abs() < 1e-6);
            }
        }
    }

    /// The jumps through free space change nothing: on a random sparse plan
    /// the planar caster agrees with the 3-D reference DDA cast in a
    /// one-layer map with horizontal rays.
    #[test]
    fn agrees_with_the_reference_dda_on_a_random_plan() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut cells: Vec<Cell> = Vec::new();
        for _ in 0..60 {
            let c = [rng.random_range(-40..40), rng.random_range(-30..30), 0];
            if !cells.contains(&c) {
                cells.push(c);
            }
        }
        // A closed rectangle of walls so most rays hit.
        for i in -45..=45 {
            cells.push([i, -35, 0]);
            cells.push([i, 35, 0]);
        }
        for j in -34..=34 {
            cells.push([-45, j, 0]);
            cells.push([45, j, 0]);
        }
        let planar = PlanarCaster::new(0.1, &cells);
        let reference = ReferenceCaster::new(0.1, &cells);
        let mut hits = 0;
        for _ in 0..5000 {
            let o = [
                rng.random_range(-4.4f32..4.4),
                rng.random_range(-3.4f32..3.4),
                0.05,
            ];
            let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let ray = Ray::new(o, [a.cos(), a.sin(), 0.0]);
            let (p, q) = (planar.cast_one(&ray), reference.cast_one(&ray));
            assert_eq!(p.leaf, q.leaf, "{ray:?}: {p:?} vs {q:?}");
            if p.is_hit() {
                assert!((p.t - q.t).abs() < 1e-4, "{ray:?}: {p:?} vs {q:?}");
                hits += 1;
            }
        }
        assert!(hits > 4900, "{hits}");
    }

    /// A batch of one image column's pixel rays (same planar direction,
    /// different tilts) shares one cast: every ray gets the hit it would
    /// get alone.
    #[test]
    fn batched_rays_of_one_column_match_single_casts() {
        let c = PlanarCaster::new(0.5, &plan());
        let rays: Vec<Ray> = (0..8)
            .map(|k| {
                let tilt = -0.4 + 0.1 * k as f32;
                let d = [0.9, 0.3, tilt];
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                Ray::new([0.3, 0.2, 1.5], [d[0] / n, d[1] / n, d[2] / n])
            })
            .chain([Ray::new([0.3, 0.2, 1.5], [0.0, 1.0, 0.0])])
            .collect();
        let mut hits = vec![Hit::miss(); rays.len()];
        c.cast_serial(&rays, &mut hits);
        for (r, h) in rays.iter().zip(&hits) {
            let one = c.cast_one(r);
            assert_eq!(h.leaf, one.leaf);
            if one.is_hit() {
                assert!((h.t - one.t).abs() < 1e-5, "{h:?} {one:?}");
            }
        }
        // The column rays reach the wall (leaf 1 at y 0.77); the +y ray
        // starts left of every column and misses.
        assert!(hits[..8].iter().all(|h| h.leaf == 1));
        assert!(!hits[8].is_hit());
    }

    /// A random plan at 0.1 m of about 300 columns with random heights
    /// (some standing on the floor, some reaching the ceiling), window
    /// [0.1, 2.5] m with the exits `n` (floor) and `n + 1` (ceiling), `n`
    /// the number of columns; returns the caster, the cells and `n`.
    fn random_room(rng: &mut rand_chacha::ChaCha8Rng) -> (PlanarCaster, Vec<Cell>, u32) {
        let mut cells: Vec<Cell> = Vec::new();
        let mut extents = Vec::new();
        let inf = f32::INFINITY;
        for _ in 0..300 {
            let c = [rng.random_range(-40..40), rng.random_range(-30..30), 0];
            if !cells.contains(&c) {
                cells.push(c);
                let b: f32 = rng.random_range(0.0..1.5);
                let t: f32 = b + rng.random_range(0.05..1.5);
                extents.push([
                    if b < 0.3 { -inf } else { b },
                    if t > 2.0 { inf } else { t },
                ]);
            }
        }
        let n = cells.len() as u32;
        // Own floor (leaf n + 2) and ceiling (n + 3) over a third of the
        // cells each; the plan-wide exits (n, n + 1) elsewhere.
        let mut own: [Vec<([i32; 2], u32)>; 2] = [Vec::new(), Vec::new()];
        for i in -40..40 {
            for j in -30..30 {
                match rng.random_range(0..3) {
                    0 => own[0].push(([i, j], n + 2)),
                    1 => own[1].push(([i, j], n + 3)),
                    _ => {}
                }
            }
        }
        // Own base (leaf n + 4, below 0.4 m) and top (n + 5, from 2.2 m)
        // of a third of the columns each.
        let mut skirts: [Vec<([i32; 2], u32)>; 2] = [Vec::new(), Vec::new()];
        for c in &cells {
            match rng.random_range(0..3) {
                0 => skirts[0].push(([c[0], c[1]], n + 4)),
                1 => skirts[1].push(([c[0], c[1]], n + 5)),
                _ => {}
            }
        }
        let c = PlanarCaster::new(0.1, &cells)
            .with_heights(&extents, [0.1, 2.5], [n, n + 1])
            .with_surfaces(&own[0], &own[1])
            .with_skirts(&skirts[0], &skirts[1], [0.4, 2.2]);
        (c, cells, n)
    }

    /// Which of the random room's kinds of hit `leaf` is: 0 the floor
    /// (plan-wide or own), 1 the ceiling, 2 a column (its own leaf, base or
    /// top), 3 a miss, 4 a column's base or top.
    fn kind(leaf: u32, n: u32) -> usize {
        match leaf {
            l if l == n || l == n + 2 => 0,
            l if l == n + 1 || l == n + 3 => 1,
            l if l == n + 4 || l == n + 5 => 4,
            Hit::MISS => 3,
            _ => 2,
        }
    }

    /// On a random plan with random column heights, a batch of runs of
    /// rays sharing planar rays (pixels of image columns looking up and
    /// down) gets exactly the hits each ray gets alone, exits included.
    #[test]
    fn batched_runs_with_heights_match_single_casts_on_a_random_plan() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let (c, _, n) = random_room(&mut rng);
        let mut hits_seen = [0usize; 5];
        let mut own = 0;
        for _ in 0..200 {
            let o = [
                rng.random_range(-4.0f32..4.0),
                rng.random_range(-3.0f32..3.0),
                rng.random_range(0.5f32..2.0),
            ];
            let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let rays: Vec<Ray> = (0..12)
                .map(|k| {
                    let s = 0.5 + 0.25 * k as f32;
                    let dz = rng.random_range(-1.5f32..1.0);
                    Ray::new(o, [s * a.cos(), s * a.sin(), s * dz])
                })
                .collect();
            let mut hits = vec![Hit::miss(); rays.len()];
            c.cast_serial(&rays, &mut hits);
            for (r, h) in rays.iter().zip(&hits) {
                let one = c.cast_one(r);
                assert_eq!(h.leaf, one.leaf, "{r:?}");
                assert!(!one.is_hit() || (h.t - one.t).abs() <= 1e-5 * one.t.max(1.0));
                hits_seen[kind(h.leaf, n)] += 1;
                own += usize::from((n + 2..n + 4).contains(&h.leaf));
            }
        }
        // Floor, ceiling (plan-wide and own), columns and their bases and
        // tops all occur.
        assert!(
            hits_seen[..3].iter().all(|&k| k > 50) && own > 50 && hits_seen[4] > 10,
            "{hits_seen:?} {own}"
        );
    }

    /// Fans (rays from one origin sharing the horizontal part of their
    /// directions, each with its own slope and range) get exactly the hits
    /// the same rays get alone, on a random plan with random heights,
    /// exits and short ranges included.
    #[test]
    fn fans_match_single_casts_on_a_random_plan() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
        let (c, cells, n) = random_room(&mut rng);
        let inf = f32::INFINITY;
        let mut seen = [0usize; 5];
        for _ in 0..100 {
            let o = [
                rng.random_range(-4.0f32..4.0),
                rng.random_range(-3.0f32..3.0),
                rng.random_range(0.5f32..2.0),
            ];
            let (mut fans, mut slopes, mut t_max) = (Vec::new(), Vec::new(), Vec::new());
            for _ in 0..5 {
                let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
                let s: f32 = rng.random_range(0.5..2.0);
                let start = slopes.len() as u32;
                for _ in 0..rng.random_range(1..10) {
                    slopes.push(rng.random_range(-1.5f32..1.0));
                    t_max.push(if rng.random_bool(0.2) {
                        rng.random_range(0.2f32..3.0)
                    } else {
                        inf
                    });
                }
                fans.push(Fan {
                    dir: [s * a.cos(), s * a.sin()],
                    start,
                    end: slopes.len() as u32,
                });
            }
            let mut hits = vec![Hit { leaf: 7, t: 0.0 }; slopes.len()];
            assert!(c.cast_fans(o, &fans, &slopes, &t_max, &mut hits));
            for f in &fans {
                for j in f.start as usize..f.end as usize {
                    let mut ray = Ray::new(o, [f.dir[0], f.dir[1], slopes[j]]);
                    ray.t_max = t_max[j];
                    let (h, one) = (hits[j], c.cast_one(&ray));
                    assert_eq!(h.leaf, one.leaf, "{ray:?}");
                    assert!(!one.is_hit() || (h.t - one.t).abs() <= 1e-5 * one.t.max(1.0));
                    seen[kind(h.leaf, n)] += 1;
                }
            }
        }
        // Floor, ceiling, columns and their bases and tops all occur, and
        // short ranges miss.
        assert!(
            seen[..3].iter().all(|&k| k > 50) && seen[3] > 10 && seen[4] > 10,
            "{seen:?}"
        );
        // No columns: every ray misses, and other casters have no fans.
        let empty = PlanarCaster::new(0.1, &[]);
        let mut hits = vec![Hit { leaf: 7, t: 0.0 }; 2];
        let fan = [Fan {
            dir: [1.0, 0.0],
            start: 0,
            end: 2,
        }];
        assert!(empty.cast_fans([0.0; 3], &fan, &[0.0, 0.5], &[inf; 2], &mut hits));
        assert!(hits.iter().all(|h| !h.is_hit()));
        let reference = ReferenceCaster::new(0.1, &cells);
        assert!(!reference.cast_fans([0.0; 3], &fan, &[0.0, 0.5], &[inf; 2], &mut hits));
    }
}
