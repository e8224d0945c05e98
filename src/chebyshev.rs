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
}
