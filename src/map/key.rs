//! Voxel keys: integer cells of a regular grid, encoded as Morton codes.
//!
//! Cell `(i, j, k) = floor((p_world - origin) / resolution)` (computed as
//! `floor(p_world / resolution) - origin / resolution` when the origin is
//! on the world's lattice, so ties do not depend on it). Each index is
//! biased by 2^20 and interleaved into 63 bits (x in the lowest bit of each
//! triple), so sorting by code gives a linear octree: the parent of a code
//! at the next coarser level is `code >> 3`, and the leaves under one parent
//! are contiguous.

use nalgebra::Vector3;

/// Integer voxel index in a map's grid.
pub type Cell = [i32; 3];

/// Bits per axis in a Morton code.
pub const AXIS_BITS: u32 = 21;
const BIAS: i64 = 1 << (AXIS_BITS - 1);
/// Smallest cell index an axis can hold.
pub const CELL_MIN: i32 = -(1 << (AXIS_BITS - 1));
/// Largest cell index an axis can hold.
pub const CELL_MAX: i32 = (1 << (AXIS_BITS - 1)) - 1;

/// Whether every index of `c` fits a Morton code.
pub fn in_range(c: Cell) -> bool {
    c.iter().all(|&v| (CELL_MIN..=CELL_MAX).contains(&v))
}

/// Morton code of a cell; the cell must be [`in_range`].
pub fn encode(c: Cell) -> u64 {
    debug_assert!(in_range(c));
    let b = |v: i32| (v as i64 + BIAS) as u64;
    crate::morton::encode3(b(c[0]), b(c[1]), b(c[2]))
}

/// The cell of a Morton code.
pub fn decode(code: u64) -> Cell {
    let u = |s: u32| (crate::morton::compact3(code >> s) as i64 - BIAS) as i32;
    [u(0), u(1), u(2)]
}

/// Where a grid sits in the world and how fine it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridSpec {
    /// Edge length of a voxel, metres.
    pub resolution: f64,
    /// World coordinates of the corner of cell (0, 0, 0); the grid frame is
    /// the world frame translated by `-origin`.
    pub origin: Vector3<f64>,
}

impl GridSpec {
    /// The cell holding world point `p`, or `None` when `p` is not finite or
    /// lies beyond the range a Morton code can index.
    ///
    /// On a grid whose origin is a whole number of voxels from the world's
    /// origin (every grid omcl makes), the cell is the world's lattice
    /// cell `floor(p / resolution)` shifted by the origin's: a point on a
    /// lattice plane (coordinates stored to the centimetre sit on 5 cm
    /// planes, a fifth of them) falls on the same side whatever the
    /// origin, which the rest of the data chooses. `floor((p - origin) /
    /// resolution)` had rounded such points either way: two orders of the
    /// same tiles gave 21,831 voxels of 139,000 apart.
    pub fn cell_of(&self, p: &Vector3<f64>) -> Option<Cell> {
        let f = |v: f64| -> Option<i32> {
            let c = v.floor();
            (c.is_finite() && c >= CELL_MIN as f64 && c <= CELL_MAX as f64).then_some(c as i32)
        };
        let axis = |v: f64, o: f64| -> f64 {
            let k = o / self.resolution;
            let whole = k.round();
            if (k - whole).abs() <= 1e-6 {
                (v / self.resolution).floor() - whole
            } else {
                (v - o) / self.resolution
            }
        };
        Some([
            f(axis(p.x, self.origin.x))?,
            f(axis(p.y, self.origin.y))?,
            f(axis(p.z, self.origin.z))?,
        ])
    }

    /// World coordinates of the centre of cell `c`.
    pub fn center(&self, c: Cell) -> Vector3<f64> {
        self.origin
            + Vector3::new(c[0] as f64 + 0.5, c[1] as f64 + 0.5, c[2] as f64 + 0.5)
                * self.resolution
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn known_codes() {
        // Bias 2^20 on every axis: cell (-2^20, -2^20, -2^20) is code 0.
        assert_eq!(encode([CELL_MIN; 3]), 0);
        let base = encode([0, 0, 0]);
        // Unit steps set x, y, z bits in that order.
        assert_eq!(encode([CELL_MIN + 1, CELL_MIN, CELL_MIN]), 1);
        assert_eq!(encode([CELL_MIN, CELL_MIN + 1, CELL_MIN]), 2);
        assert_eq!(encode([CELL_MIN, CELL_MIN, CELL_MIN + 1]), 4);
        assert_eq!(decode(base), [0, 0, 0]);
    }

    #[test]
    fn siblings_share_a_parent() {
        let p = encode([4, 6, 8]) >> 3;
        for dx in 0..2 {
            for dy in 0..2 {
                for dz in 0..2 {
                    assert_eq!(encode([4 + dx, 6 + dy, 8 + dz]) >> 3, p);
                }
            }
        }
        assert_ne!(encode([5, 6, 10]) >> 3, p);
    }

    #[test]
    fn cell_of_floors_and_rejects_far_points() {
        let g = GridSpec {
            resolution: 0.5,
            origin: Vector3::new(1.0, 0.0, -1.0),
        };
        assert_eq!(g.cell_of(&Vector3::new(1.0, 0.49, -1.01)), Some([0, 0, -1]));
        assert_eq!(g.cell_of(&Vector3::new(f64::NAN, 0.0, 0.0)), None);
        assert_eq!(g.cell_of(&Vector3::new(1e9, 0.0, 0.0)), None);
        let c = g.center([0, 0, -1]);
        assert_eq!(c, Vector3::new(1.25, 0.25, -1.25));
    }

    #[test]
    fn points_on_lattice_planes_fall_alike_whatever_the_origin() {
        // Centimetre coordinates on 5 cm planes, under grids of origins
        // chosen by other data (14.6 and 5.35, as two tile orders gave).
        let grid = |o: f64| GridSpec {
            resolution: 0.05,
            origin: Vector3::new((o / 0.05).round() * 0.05, 0.0, 0.0),
        };
        let (a, b) = (grid(14.6), grid(5.35));
        let world = |g: &GridSpec, c: Cell| c[0] as i64 + (g.origin.x / 0.05).round() as i64;
        let mut ties = 0;
        for i in 0..20_000 {
            let x = f64::from(i) * 0.01;
            let p = Vector3::new(x, 0.0, 0.0);
            let (ca, cb) = (a.cell_of(&p).unwrap(), b.cell_of(&p).unwrap());
            assert_eq!(world(&a, ca), world(&b, cb), "x = {x}");
            assert_eq!(world(&a, ca), (x / 0.05).floor() as i64, "x = {x}");
            // The old rule disagreed on some of these.
            let old = |g: &GridSpec| ((x - g.origin.x) / 0.05).floor() as i64 + world(g, [0; 3]);
            ties += usize::from(old(&a) != old(&b));
        }
        assert!(ties > 0, "the case shows nothing");
        // A grid off the lattice keeps the plain rule.
        let off = GridSpec {
            resolution: 0.5,
            origin: Vector3::new(0.25, 0.0, 0.0),
        };
        assert_eq!(off.cell_of(&Vector3::new(0.74, 0.0, 0.0)), Some([0, 0, 0]));
        assert_eq!(off.cell_of(&Vector3::new(0.75, 0.0, 0.0)), Some([1, 0, 0]));
    }

    proptest! {
        #[test]
        fn round_trip(x in CELL_MIN..=CELL_MAX, y in CELL_MIN..=CELL_MAX, z in CELL_MIN..=CELL_MAX) {
            prop_assert_eq!(decode(encode([x, y, z])), [x, y, z]);
        }

        #[test]
        fn order_is_z_order_within_a_block(x in 0i32..1024, y in 0i32..1024, z in 0i32..1024) {
            // The code is monotone in each axis with the others fixed.
            let c = encode([x, y, z]);
            prop_assert!(encode([x + 1, y, z]) > c);
            prop_assert!(encode([x, y + 1, z]) > c);
            prop_assert!(encode([x, y, z + 1]) > c);
        }
    }
}
