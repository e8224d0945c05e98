//! The Chebyshev distance transform of a 2-D grid: every cell's distance,
//! in cells, to the nearest seed cell (`max(|dx|, |dy|)`), by a two-pass
//! chamfer transform with unit 8-neighbour weights, which is exact for
//! this metric. Used by the floor-plan caster (free space it may jump
//! through) and the simulator's feature model (pixels far from any label
//! edge).

/// Distances of the `w x h` grid's cells (row-major) to the nearest cell
/// `i` with `seed(i)`, capped at 255; cells outside the grid are no seeds.
/// With no seed at all, every cell is 255.
pub fn distance(w: usize, h: usize, seed: impl Fn(usize) -> bool) -> Vec<u8> {
    const FAR: u32 = 255;
    let mut dist: Vec<u32> = (0..w * h).map(|i| if seed(i) { 0 } else { FAR }).collect();
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

/// One of the eight octants of directions in the plane: the sign of
/// each axis (`true`: negative) and which axis is the longer (`true`: y).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Octant {
    pub neg_x: bool,
    pub neg_y: bool,
    pub y_major: bool,
}

impl Octant {
    /// All eight, in the order of [`Octant::index`].
    pub fn all() -> [Octant; 8] {
        std::array::from_fn(|i| Octant {
            neg_x: i & 1 != 0,
            neg_y: i & 2 != 0,
            y_major: i & 4 != 0,
        })
    }

    /// 0 to 7.
    pub fn index(self) -> usize {
        usize::from(self.neg_x) | usize::from(self.neg_y) << 1 | usize::from(self.y_major) << 2
    }
}

/// Per cell of the `w x h` grid (row-major), how far a ray whose
/// direction lies in `octant` can go from anywhere in that cell before it
/// may reach a seed: the smallest `k` such that a seed lies `k` cells on
/// along the octant's longer axis and at most `k + 2` cells to its side
/// (its shorter axis' sense), capped at 255; cells outside the grid are no
/// seeds. A ray of slope at most 1 against its longer axis that enters a
/// cell `k` cells on is at most `k + 1` cells aside (it starts anywhere in
/// its first cell; the one cell more is a margin for a walk's rounding at
/// slope 1), so no cell a grid walk (DDA) of such a ray visits before it
/// is `k` cells on is a seed. One pass, from the far side: `c(p) = 0` if
/// `p` or one of its two side neighbours is a seed, else `1 + min(c(p +
/// ahead), c(p + ahead + side))`.
pub fn cone_distance(w: usize, h: usize, octant: Octant, seed: impl Fn(usize) -> bool) -> Vec<u8> {
    const FAR: u16 = 255;
    // Walk the grid in (major, minor) coordinates: `major` runs along the
    // longer axis in the octant's sense, `minor` along the other.
    let (nm, nn) = if octant.y_major { (h, w) } else { (w, h) };
    let cell = |major: usize, minor: usize| -> usize {
        let (x, y) = if octant.y_major {
            (minor, major)
        } else {
            (major, minor)
        };
        let x = if octant.neg_x { w - 1 - x } else { x };
        let y = if octant.neg_y { h - 1 - y } else { y };
        y * w + x
    };
    let mut out = vec![0u8; w * h];
    // Distances of the layer one step ahead (`major + 1`), by minor index.
    let mut ahead = vec![FAR; nn + 1];
    let mut here = vec![FAR; nn + 1];
    for major in (0..nm).rev() {
        for minor in 0..nn {
            let own = seed(cell(major, minor));
            let side = (1..=2).any(|m| minor + m < nn && seed(cell(major, minor + m)));
            let v = if own || side {
                0
            } else {
                (1 + ahead[minor].min(ahead[minor + 1])).min(FAR)
            };
            here[minor] = v;
            out[cell(major, minor)] = v as u8;
        }
        std::mem::swap(&mut ahead, &mut here);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_seed_gives_the_chebyshev_distance() {
        // 5 x 3 grid, one seed at (1, 1).
        let d = distance(5, 3, |i| i == 5 + 1);
        assert_eq!(d, vec![1, 1, 1, 2, 3, 1, 0, 1, 2, 3, 1, 1, 1, 2, 3]);
    }

    /// Against brute force on a random grid, and capped at 255.
    #[test]
    fn equals_brute_force_and_caps() {
        let (w, h) = (23, 17);
        let seeds: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 97 < 3).collect();
        let d = distance(w, h, |i| seeds[i]);
        for (i, &got) in d.iter().enumerate() {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            let brute = (0..w * h)
                .filter(|&j| seeds[j])
                .map(|j| ((j % w) as i64 - x).abs().max(((j / w) as i64 - y).abs()))
                .min()
                .unwrap_or(255)
                .min(255);
            assert_eq!(got as i64, brute, "cell {i}");
        }
        assert!(seeds.iter().any(|&s| s));
        assert_eq!(distance(300, 1, |i| i == 0)[299], 255);
        assert!(distance(4, 4, |_| false).iter().all(|&v| v == 255));
    }

    /// Against brute force on a random grid, in every octant.
    #[test]
    fn cone_distance_equals_brute_force_in_every_octant() {
        let (w, h) = (19, 13);
        let seeds: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 61 < 2).collect();
        assert!(seeds.iter().any(|&s| s));
        for o in Octant::all() {
            let d = cone_distance(w, h, o, |i| seeds[i]);
            let (sx, sy) = (if o.neg_x { -1 } else { 1 }, if o.neg_y { -1 } else { 1 });
            for (i, &got) in d.iter().enumerate() {
                let (x, y) = ((i % w) as i64, (i / w) as i64);
                let brute = (0..w * h)
                    .filter(|&j| seeds[j])
                    .filter_map(|j| {
                        let (dx, dy) = (((j % w) as i64 - x) * sx, ((j / w) as i64 - y) * sy);
                        let (k, m) = if o.y_major { (dy, dx) } else { (dx, dy) };
                        (k >= 0 && (0..=k + 2).contains(&m)).then_some(k)
                    })
                    .min()
                    .unwrap_or(255);
                assert_eq!(got as i64, brute, "octant {o:?}, cell {i}");
            }
        }
        // A hand-made case: a seed at (4, 2) of a 6 x 4 grid, octant +x +y.
        let o = Octant {
            neg_x: false,
            neg_y: false,
            y_major: false,
        };
        let d = cone_distance(6, 4, o, |i| i == 2 * 6 + 4);
        // From (0, 0) the seed is 4 on and 2 aside; from (0, 2) 4 on, 0
        // aside; from (0, 3) it is behind the cone's side; from (3, 0) it
        // is 1 on and 2 aside, from (4, 0) a side neighbour (2 aside).
        assert_eq!(&d[0..6], &[4, 3, 2, 1, 0, 255]);
        assert_eq!(&d[12..18], &[4, 3, 2, 1, 0, 255]);
        assert_eq!(&d[18..24], &[255; 6]);
        // Octant -x +y: from (5, 0) the seed is 1 on, 2 aside.
        let o = Octant {
            neg_x: true,
            neg_y: false,
            y_major: false,
        };
        assert_eq!(cone_distance(6, 4, o, |i| i == 2 * 6 + 4)[5], 1);
    }
}
