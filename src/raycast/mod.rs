//! Ray casting against the voxels of a map.
//!
//! Semantics, shared by every backend and checked against each other in
//! tests: voxels are closed axis-aligned cubes `[i r, (i+1) r]` (per axis) in
//! the grid frame (world minus the map origin). A ray hits the voxel it
//! touches first at a distance `t` in `[t_min, t_max]`, `t` counted in units
//! of `|dir|`; a ray that starts inside a voxel hits it at `t_min`. Ties
//! (a ray through a shared edge or corner) may resolve to either voxel.
//!
//! Two backends: [`EmbreeCaster`] (Embree 3 user geometry of voxel bricks,
//! packet tracing; the fast one) and [`ReferenceCaster`] (a pure-Rust 3-D DDA; the
//! executable definition of the semantics).

mod bricks;
mod embree;
mod planar;
mod reference;

pub use bricks::BrickEdge;
pub use embree::{
    BuildOptions, BuildQuality, EmbreeCaster, EmbreeError, Geometry, Packet, misaligned_masks,
    thread_float_mode,
};
pub use planar::{PlanarCaster, column_bounds};
pub use reference::ReferenceCaster;

use rayon::prelude::*;

use crate::geometry::Ray;

/// The result of casting one ray.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct Hit {
    /// Index of the hit voxel in the caster's cell list (the map's leaf
    /// index), or [`Hit::MISS`].
    pub leaf: u32,
    /// Distance along the ray in units of `|dir|`; infinite for a miss.
    pub t: f32,
}

impl Hit {
    /// Leaf value of a ray that hit nothing.
    pub const MISS: u32 = u32::MAX;

    /// A miss.
    pub const fn miss() -> Self {
        Hit {
            leaf: Self::MISS,
            t: f32::INFINITY,
        }
    }

    /// Whether the ray hit a voxel.
    pub fn is_hit(&self) -> bool {
        self.leaf != Self::MISS
    }
}

/// Rays from one origin whose directions share the horizontal part `dir`
/// (see [`RayCaster::cast_fans`]): the rays `start..end` of a batch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fan {
    pub dir: [f32; 2],
    pub start: u32,
    pub end: u32,
}

/// Slab test: the part of the ray parameter interval `t` inside the box
/// `[lo, hi]` on the axes `lo` has (origin `o`, direction `d`), or `None`
/// when the ray misses it. On an axis the ray runs parallel to, it misses
/// when its origin lies outside the slab.
pub(crate) fn clip_to_box(
    o: &[f64],
    d: &[f64],
    lo: &[f64],
    hi: &[f64],
    (mut t0, mut t1): (f64, f64),
) -> Option<(f64, f64)> {
    for a in 0..lo.len() {
        let (l, h) = (lo[a], hi[a]);
        if d[a] == 0.0 {
            if o[a] < l || o[a] > h {
                return None;
            }
        } else {
            let (mut ta, mut tb) = ((l - o[a]) / d[a], (h - o[a]) / d[a]);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
    }
    if t0 > t1 { None } else { Some((t0, t1)) }
}

/// Rays per parallel work item: large enough to amortize scheduling,
/// small enough to balance two to sixteen cores.
pub const CHUNK: usize = 1024;

/// Casts batches of rays against a fixed set of voxels.
pub trait RayCaster: Send + Sync {
    /// Casts `rays` (grid frame) and writes one hit per ray into `hits`, on
    /// the calling thread: for callers that parallelize at a coarser grain
    /// (the filter casts each particle's rays inside its own parallel
    /// task). Panics if the slices differ in length.
    fn cast_serial(&self, rays: &[Ray], hits: &mut [Hit]);

    /// The first error the backend hit while casting since the last call
    /// (its rays then came back as misses), taken: callers that cast
    /// through this infallible interface check it once per batch (the
    /// filter does after every step). Backends that cannot fail keep the
    /// default, `None`.
    fn take_error(&self) -> Option<String> {
        None
    }

    /// Whether the caster is fastest when each particle's rays come
    /// together and in image-column order (pixels sorted by column, then
    /// row): the planar caster walks each run of rays sharing a planar ray
    /// once. The filter's sensor model then casts particle-major in that
    /// order. Default: `false`.
    fn wants_column_order(&self) -> bool {
        false
    }

    /// Casts fans of rays from `origin` (grid frame): ray `j` of fan `f`
    /// (`f.start <= j < f.end`) is `origin + t (f.dir[0], f.dir[1],
    /// slopes[j])` for `t` in `[0, t_max[j]]`, and its hit goes to
    /// `hits[j]` (`t` in those units). A level camera's pixels of one image
    /// column are one fan: their directions share the horizontal part. The
    /// default has no fan path: it returns `false` and writes nothing (the
    /// caller then casts [`Ray`]s); the planar caster walks each fan once.
    /// Panics if `slopes`, `t_max` and `hits` differ in length.
    fn cast_fans(
        &self,
        _origin: [f32; 3],
        _fans: &[Fan],
        _slopes: &[f32],
        _t_max: &[f32],
        _hits: &mut [Hit],
    ) -> bool {
        false
    }

    /// Casts `rays` (grid frame) and writes one hit per ray into `hits`,
    /// in parallel with rayon, [`CHUNK`] rays a task. Panics if the slices
    /// differ in length.
    fn cast(&self, rays: &[Ray], hits: &mut [Hit]) {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        rays.par_chunks(CHUNK)
            .zip(hits.par_chunks_mut(CHUNK))
            .for_each(|(r, h)| self.cast_serial(r, h));
    }

    /// Convenience form of [`RayCaster::cast`] that allocates the hits.
    fn cast_vec(&self, rays: &[Ray]) -> Vec<Hit> {
        let mut hits = vec![Hit::miss(); rays.len()];
        self.cast(rays, &mut hits);
        hits
    }

    /// Number of voxels.
    fn len(&self) -> usize;

    /// Whether there are no voxels.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests;
