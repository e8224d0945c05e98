//! A 2-D caster for floor plans: rays are cast in the horizontal plane
//! against the occupied columns of a plan (a 2-D DDA, Amanatides and Woo,
//! with empty-space skipping).
//!
//! # Camera pixels as planar rays
//!
//! A ray of the 3-D filter (origin at the camera centre, direction through
//! the pixel, both in the grid frame) becomes its vertical projection: the
//! origin's and direction's x and y, the z components dropped. The ray
//! parameter `t` keeps its meaning: the planar hit at `t` is the xy of the
//! 3-D point `origin + t dir`, so `t` is still in units of the 3-D `|dir|`
//! (and `t_max` still limits the 3-D length). A pixel looking straight up
//! or down (horizontal part below 1e-6 of `|dir|`) misses. The z of
//! `cells` is ignored: every column is an infinitely tall prism
//! `[i r, (i+1) r] x [j r, (j+1) r]`, which is what the averaged floor plan
//! ([`crate::map::floorplan`]) stands for.
//!
//! # Speed
//!
//! The occupied columns are a dense grid over their bounding box (a leaf
//! index per cell) with each free cell's Chebyshev distance to the nearest
//! occupied one. While that distance `D` is 3 or more, the ray jumps
//! `D - 2` cells along its longer axis (no occupied cell can lie within);
//! near occupied cells it steps cell by cell. The result equals the plain
//! DDA's (checked against [`super::ReferenceCaster`] in the tests).
//!
//! A batch ([`RayCaster::cast_serial`]) casts each distinct planar ray
//! once: all pixels of one image column of a level camera project to the
//! same planar ray, so a particle's ~1,800 sampled pixels are ~135 casts
//! (stride-4 sampling on a 540-px image).

use super::{Hit, RayCaster};
use crate::geometry::Ray;
use crate::map::Cell;

/// The planar (floor-plan) ray caster.
#[derive(Debug, Clone)]
pub struct PlanarCaster {
    resolution: f64,
    lo: [i32; 2],
    size: [i32; 2],
    /// Leaf index per grid cell (row-major, x fastest) or `Hit::MISS`.
    leaf: Vec<u32>,
    /// Chebyshev distance in cells to the nearest occupied cell (0 on an
    /// occupied cell), capped at 255.
    clearance: Vec<u8>,
    n: usize,
}

impl PlanarCaster {
    /// A caster over columns of edge `resolution` at `cells` (`[i, j, _]`,
    /// the z index ignored); hit `leaf` values index `cells`. For a
    /// repeated column the first index wins.
    pub fn new(resolution: f32, cells: &[Cell]) -> Self {
        let (lo, hi) = column_bounds(cells);
        let size = [hi[0] - lo[0] + 1, hi[1] - lo[1] + 1];
        let total = (size[0].max(0) as usize) * (size[1].max(0) as usize);
        let mut leaf = vec![Hit::MISS; total];
        for (k, c) in cells.iter().enumerate() {
            let idx = ((c[1] - lo[1]) * size[0] + (c[0] - lo[0])) as usize;
            if leaf[idx] == Hit::MISS {
                leaf[idx] = k as u32;
            }
        }
        let clearance = chebyshev_clearance(&leaf, size[0] as usize, size[1] as usize);
        PlanarCaster {
            resolution: resolution as f64,
            lo,
            size,
            leaf,
            clearance,
            n: cells.len(),
        }
    }

    /// Casts one ray (see the module documentation).
    pub fn cast_one(&self, ray: &Ray) -> Hit {
        if self.n == 0 || !ray.is_valid() {
            return Hit::miss();
        }
        let r = self.resolution;
        let o = [ray.origin[0] as f64, ray.origin[1] as f64];
        let d = [ray.dir[0] as f64, ray.dir[1] as f64];
        let d3 = (ray.dir[0] as f64)
            .hypot(ray.dir[1] as f64)
            .hypot(ray.dir[2] as f64);
        let dxy = d[0].hypot(d[1]);
        if dxy <= 1e-6 * d3 {
            return Hit::miss();
        }
        let lo = [0, 1].map(|a| self.lo[a] as f64 * r);
        let hi = [0, 1].map(|a| (self.lo[a] + self.size[a]) as f64 * r);
        let t = (ray.t_min as f64, ray.t_max as f64);
        let Some((t0, t1)) = super::clip_to_box(&o, &d, &lo, &hi, t) else {
            return Hit::miss();
        };
        let step = [d[0].signum() as i32, d[1].signum() as i32];
        let delta = [r / d[0].abs(), r / d[1].abs()];
        let jump_per_cell = r / d[0].abs().max(d[1].abs());
        let mut t = t0;
        'outer: loop {
            // Cell at parameter t, kept inside the box against rounding.
            let mut cell = [0i32; 2];
            for a in 0..2 {
                let c = ((o[a] + t * d[a]) / r).floor() as i64;
                cell[a] = (c.clamp(self.lo[a] as i64, (self.lo[a] + self.size[a] - 1) as i64)
                    as i32)
                    - self.lo[a];
            }
            let mut next = [f64::INFINITY; 2];
            for a in 0..2 {
                if step[a] != 0 {
                    let edge = (cell[a] + self.lo[a] + i32::from(step[a] > 0)) as f64 * r;
                    next[a] = (edge - o[a]) / d[a];
                }
            }
            loop {
                let idx = (cell[1] * self.size[0] + cell[0]) as usize;
                let leaf = self.leaf[idx];
                if leaf != Hit::MISS {
                    return Hit { leaf, t: t as f32 };
                }
                let clear = self.clearance[idx];
                if clear >= 3 {
                    // No occupied cell within clear - 1 cells; one cell of
                    // margin for a position rounded into the next cell.
                    t += (clear - 2) as f64 * jump_per_cell;
                    if t > t1 {
                        return Hit::miss();
                    }
                    continue 'outer;
                }
                // One DDA step.
                let a = if next[0] < next[1] { 0 } else { 1 };
                t = next[a];
                if t > t1 {
                    return Hit::miss();
                }
                cell[a] += step[a];
                if cell[a] < 0 || cell[a] >= self.size[a] {
                    return Hit::miss();
                }
                next[a] += delta[a];
            }
        }
    }
}

/// Chebyshev distance (cells) of every cell to the nearest occupied one,
/// by a two-pass chamfer transform with unit 8-neighbour weights (exact
/// for the Chebyshev metric), capped at 255; cells outside count as free.
fn chebyshev_clearance(leaf: &[u32], w: usize, h: usize) -> Vec<u8> {
    const FAR: u32 = 255;
    let mut dist: Vec<u32> = leaf
        .iter()
        .map(|&l| if l == Hit::MISS { FAR } else { 0 })
        .collect();
    for y in 0..h {
        for x in 0..w {
            let mut v = dist[y * w + x];
            if x > 0 {
                v = v.min(dist[y * w + x - 1] + 1);
            }
            if y > 0 {
                for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    v = v.min(dist[(y - 1) * w + xx] + 1);
                }
            }
            dist[y * w + x] = v;
        }
    }
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            let mut v = dist[y * w + x];
            if x + 1 < w {
                v = v.min(dist[y * w + x + 1] + 1);
            }
            if y + 1 < h {
                for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    v = v.min(dist[(y + 1) * w + xx] + 1);
                }
            }
            dist[y * w + x] = v;
        }
    }
    dist.into_iter().map(|v| v.min(FAR) as u8).collect()
}

/// Key of a planar ray for [`RayCaster::cast_serial`]'s reuse: origin x,
/// y bits and the direction's angle in the plane in micro-radians.
fn planar_key(ray: &Ray) -> Option<(u32, u32, i64)> {
    let (dx, dy) = (ray.dir[0] as f64, ray.dir[1] as f64);
    let d3 = dx.hypot(dy).hypot(ray.dir[2] as f64);
    if !(ray.t_min == 0.0 && ray.t_max == f32::INFINITY && dx.hypot(dy) > 1e-6 * d3) {
        return None;
    }
    let angle = (dy.atan2(dx) * 1e6).round() as i64;
    Some((ray.origin[0].to_bits(), ray.origin[1].to_bits(), angle))
}

impl RayCaster for PlanarCaster {
    /// Casts each distinct planar ray of the batch once: rays from the same
    /// origin whose horizontal directions agree to a micro-radian (a level
    /// camera's pixels of one image column, which all project to the same
    /// planar ray) share the cast, their `t` rescaled to their own
    /// direction's horizontal length. Rays with a finite `t_max` or a
    /// nonzero `t_min` are cast on their own.
    fn cast_serial(&self, rays: &[Ray], hits: &mut [Hit]) {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        let mut seen: rustc_hash::FxHashMap<(u32, u32, i64), (Hit, f64)> =
            rustc_hash::FxHashMap::default();
        for (r, h) in rays.iter().zip(hits.iter_mut()) {
            let Some(key) = planar_key(r) else {
                *h = self.cast_one(r);
                continue;
            };
            let n = (r.dir[0] as f64).hypot(r.dir[1] as f64);
            *h = match seen.get(&key) {
                Some(&(hit, n0)) => Hit {
                    leaf: hit.leaf,
                    t: (hit.t as f64 * n0 / n) as f32,
                },
                None => {
                    let hit = self.cast_one(r);
                    seen.insert(key, (hit, n));
                    hit
                }
            };
        }
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

    #[test]
    fn clearance_is_the_chebyshev_distance() {
        // 5 x 3 grid, one occupied cell at (1, 1).
        let mut leaf = vec![Hit::MISS; 15];
        leaf[5 + 1] = 0;
        let d = chebyshev_clearance(&leaf, 5, 3);
        assert_eq!(d, vec![1, 1, 1, 2, 3, 1, 0, 1, 2, 3, 1, 1, 1, 2, 3]);
    }
}
