//! Voxels grouped into bricks of `edge^3` cells for the Embree backend: one
//! Embree primitive per non-empty brick instead of one per voxel.
//!
//! A brick is a record of 64-bit words whose layout `ffi/omcl_embree.h`
//! documents (`OmclBricks`): its base cell, the index of its first voxel in
//! [`Bricks::leaves`], the tight bounds of its occupied cells, and an
//! occupancy mask. The C intersect callback walks the brick's cells with a
//! small DDA and reports the first occupied cell as a leaf slot (the brick's
//! first slot plus the cell's rank in the mask), which [`Bricks::leaves`]
//! maps to the voxel index. Grouping cuts the primitives (and the BVH over
//! them) by the bricks' fill factor: a BVH over a million voxel boxes is
//! ~100 MB, far beyond the caches, and ~70 % of the time went into
//! traversing it.
//!
//! Pure data; no `unsafe` and no Embree here.

use rustc_hash::FxHashMap;

use crate::map::Cell;

/// Edge of a brick in voxels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BrickEdge {
    /// 2 x 2 x 2 voxels (an 8-bit mask).
    Two,
    /// 4 x 4 x 4 voxels (a 64-bit mask; the default).
    #[default]
    Four,
    /// 8 x 8 x 8 voxels (a 512-bit mask and per-layer rank counts).
    Eight,
}

impl BrickEdge {
    /// Cells along one edge.
    pub fn cells(self) -> u32 {
        1 << self.shift()
    }

    fn shift(self) -> u32 {
        match self {
            BrickEdge::Two => 1,
            BrickEdge::Four => 2,
            BrickEdge::Eight => 3,
        }
    }

    /// 64-bit words of one record (`OMCL_BRICK_WORDS_*` in the C header).
    pub(crate) fn record_words(self) -> usize {
        match self {
            BrickEdge::Two | BrickEdge::Four => 4,
            BrickEdge::Eight => 13,
        }
    }

    /// Mask words of one brick.
    fn mask_words(self) -> usize {
        match self {
            BrickEdge::Two | BrickEdge::Four => 1,
            BrickEdge::Eight => 8,
        }
    }
}

/// The bricks of a set of voxels, in the layout the C callbacks read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Bricks {
    /// `count` records of [`BrickEdge::record_words`] words each, in Morton
    /// order of the bricks (neighbouring bricks are near in memory).
    pub data: Vec<u64>,
    /// Voxel index (into the caster's cell list) of every leaf slot:
    /// brick by brick, cells in mask-bit order.
    pub leaves: Vec<u32>,
    pub count: usize,
    pub edge: BrickEdge,
}

impl Bricks {
    /// Groups `cells` (voxel `i` is `cells[i]`) into bricks. A repeated
    /// cell keeps its first index, as in the reference caster.
    pub fn new(cells: &[Cell], edge: BrickEdge) -> Self {
        let shift = edge.shift();
        let n = edge.cells() as i32;
        let low = n - 1;
        let mw = edge.mask_words();
        // Pass 1: find each cell's brick, set its mask bit, grow its bounds.
        let mut index: FxHashMap<Cell, u32> = FxHashMap::default();
        let mut keys: Vec<Cell> = Vec::new();
        let mut masks: Vec<u64> = Vec::new();
        let mut bounds: Vec<[u8; 6]> = Vec::new();
        let mut brick_of: Vec<u32> = Vec::with_capacity(cells.len());
        for c in cells {
            // Arithmetic shifts floor negative cells into the right brick.
            let key = [c[0] >> shift, c[1] >> shift, c[2] >> shift];
            let local = [c[0] & low, c[1] & low, c[2] & low];
            let b = *index.entry(key).or_insert_with(|| {
                keys.push(key);
                masks.extend(std::iter::repeat_n(0, mw));
                bounds.push([u8::MAX, u8::MAX, u8::MAX, 0, 0, 0]);
                (keys.len() - 1) as u32
            });
            brick_of.push(b);
            let (word, bit) = mask_position(edge, local);
            masks[b as usize * mw + word] |= 1 << bit;
            let bb = &mut bounds[b as usize];
            for a in 0..3 {
                bb[a] = bb[a].min(local[a] as u8);
                bb[a + 3] = bb[a + 3].max(local[a] as u8);
            }
        }
        // Morton order of the bricks, for memory locality of neighbours.
        let mut order: Vec<u32> = (0..keys.len() as u32).collect();
        let morton = |k: &Cell| {
            let u = |v: i32| (v as u32) ^ 0x8000_0000;
            crate::morton::encode3(u(k[0]).into(), u(k[1]).into(), u(k[2]).into())
        };
        order.sort_unstable_by_key(|&b| (morton(&keys[b as usize]), b));
        // Records, with each brick's first leaf slot.
        let rw = edge.record_words();
        let mut data = vec![0u64; rw * keys.len()];
        let mut first = vec![0u32; keys.len()]; // by old index
        let mut total = 0u32;
        for (new, &old) in order.iter().enumerate() {
            let old = old as usize;
            let key = keys[old];
            let base = key.map(|k| (k << shift) as u32);
            let m = &masks[old * mw..(old + 1) * mw];
            let bb = bounds[old];
            let rec = &mut data[new * rw..(new + 1) * rw];
            rec[0] = base[0] as u64 | (base[1] as u64) << 32;
            rec[1] = base[2] as u64 | (total as u64) << 32;
            rec[2] = bb
                .iter()
                .enumerate()
                .fold(0u64, |w, (i, &v)| w | (v as u64) << (8 * i));
            rec[3..3 + mw].copy_from_slice(m);
            if edge == BrickEdge::Eight {
                // Occupied cells before each mask word, 16 bits each.
                let mut before = 0u64;
                for (z, w) in m.iter().enumerate() {
                    rec[11 + z / 4] |= before << (16 * (z % 4));
                    before += w.count_ones() as u64;
                }
            }
            first[old] = total;
            total += m.iter().map(|w| w.count_ones()).sum::<u32>();
        }
        // Pass 2: every cell's leaf slot, first index winning.
        let mut leaves = vec![u32::MAX; total as usize];
        for (i, (c, &b)) in cells.iter().zip(&brick_of).enumerate() {
            let local = [c[0] & low, c[1] & low, c[2] & low];
            let (word, bit) = mask_position(edge, local);
            let m = &masks[b as usize * mw..(b as usize + 1) * mw];
            let rank = m[..word].iter().map(|w| w.count_ones()).sum::<u32>()
                + (m[word] & ((1u64 << bit) - 1)).count_ones();
            let s = &mut leaves[(first[b as usize] + rank) as usize];
            if *s == u32::MAX {
                *s = i as u32;
            }
        }
        Bricks {
            data,
            leaves,
            count: keys.len(),
            edge,
        }
    }

    /// Bytes of the records and the leaf table.
    pub fn bytes(&self) -> usize {
        self.data.len() * 8 + self.leaves.len() * 4
    }
}

/// Mask word and bit of a cell at `local` (each in `0..edge`) in its brick.
fn mask_position(edge: BrickEdge, local: [i32; 3]) -> (usize, u32) {
    let n = edge.cells() as i32;
    let bit = (local[0] + n * (local[1] + n * local[2])) as u32;
    (bit as usize / 64, bit % 64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(b: &Bricks, i: usize) -> ([i32; 3], u32, [u8; 6]) {
        let rec = &b.data[i * b.edge.record_words()..];
        (
            [
                rec[0] as u32 as i32,
                (rec[0] >> 32) as u32 as i32,
                rec[1] as u32 as i32,
            ],
            (rec[1] >> 32) as u32,
            std::array::from_fn(|k| (rec[2] >> (8 * k)) as u8),
        )
    }

    #[test]
    fn negative_cells_fall_in_the_brick_below_zero() {
        let b = Bricks::new(&[[-1, 0, 0], [0, 0, 0], [-4, 3, 0]], BrickEdge::Four);
        assert_eq!(b.count, 2);
        let mut seen: Vec<_> = (0..b.count).map(|i| decode(&b, i)).collect();
        seen.sort();
        // Brick (-1, 0, 0) spans cells x -4..=-1: cells -4 and -1 at local x 0 and 3.
        assert_eq!(seen[0].0, [-4, 0, 0]);
        assert_eq!(seen[0].2, [0, 0, 0, 3, 3, 0]);
        assert_eq!(seen[1].0, [0, 0, 0]);
        assert_eq!(seen[1].2, [0, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn leaves_follow_mask_order_and_first_index_wins() {
        for edge in [BrickEdge::Two, BrickEdge::Four, BrickEdge::Eight] {
            let cells = [[1, 1, 1], [0, 0, 0], [1, 1, 1], [1, 0, 0]];
            let b = Bricks::new(&cells, edge);
            assert_eq!(b.count, 1);
            // Mask order: (0,0,0), (1,0,0), (1,1,1); the repeat keeps index 0.
            assert_eq!(b.leaves, vec![1, 3, 0], "{edge:?}");
        }
    }

    #[test]
    fn eight_wide_rank_counts_cover_the_layers_below() {
        // One cell in each of the layers z = 0..8 of one brick.
        let cells: Vec<Cell> = (0..8).map(|z| [z, 7 - z, z]).collect();
        let b = Bricks::new(&cells, BrickEdge::Eight);
        let rec = &b.data[..13];
        for z in 0..8 {
            let before = (rec[11 + z / 4] >> (16 * (z % 4))) & 0xffff;
            assert_eq!(before, z as u64);
        }
        assert_eq!(b.leaves, (0..8).collect::<Vec<u32>>());
    }
}
