//! Voxel keys: integer cells of a regular grid, encoded as Morton codes.
//!
//! Cell `(i, j, k) = floor((p_world - origin) / resolution)`. Each index is
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
    pub fn cell_of(&self, p: &Vector3<f64>) -> Option<Cell> {
        let q = (p - self.origin) / self.resolution;
        let f = |v: f64| -> Option<i32> {
            let c = v.floor();
            (c.is_finite() && c >= CELL_MIN as f64 && c <= CELL_MAX as f64).then_some(c as i32)
        };
        Some([f(q.x)?, f(q.y)?, f(q.z)?])
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
