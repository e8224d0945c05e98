//! Morton (Z-order) codes: the bits of two or three integers interleaved,
//! so that sorting by code keeps neighbours near each other. One module for
//! the voxel keys ([`crate::map::key`]), the ray caster's bricks, the
//! particles' spatial sort and the sampled pixels' order.

/// Spreads the low 21 bits of `v` to every third bit (bit `i` to `3 i`).
pub fn spread3(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x1f00000000ffff;
    x = (x | (x << 16)) & 0x1f0000ff0000ff;
    x = (x | (x << 8)) & 0x100f00f00f00f00f;
    x = (x | (x << 4)) & 0x10c30c30c30c30c3;
    (x | (x << 2)) & 0x1249249249249249
}

/// The inverse of [`spread3`]: every third bit gathered into the low 21.
pub fn compact3(v: u64) -> u64 {
    let mut x = v & 0x1249249249249249;
    x = (x | (x >> 2)) & 0x10c30c30c30c30c3;
    x = (x | (x >> 4)) & 0x100f00f00f00f00f;
    x = (x | (x >> 8)) & 0x1f0000ff0000ff;
    x = (x | (x >> 16)) & 0x1f00000000ffff;
    (x | (x >> 32)) & 0x1f_ffff
}

/// Interleaves the low 21 bits of `x`, `y` and `z` (x in the lowest bit of
/// each triple).
pub fn encode3(x: u64, y: u64, z: u64) -> u64 {
    spread3(x) | (spread3(y) << 1) | (spread3(z) << 2)
}

/// Spreads the 32 bits of `v` to the even bits.
pub fn spread2(v: u32) -> u64 {
    let mut x = u64::from(v);
    x = (x | (x << 16)) & 0x0000_ffff_0000_ffff;
    x = (x | (x << 8)) & 0x00ff_00ff_00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333_3333_3333;
    (x | (x << 1)) & 0x5555_5555_5555_5555
}

/// Interleaves `u` (even bits) and `v` (odd bits).
pub fn encode2(u: u32, v: u32) -> u64 {
    spread2(u) | (spread2(v) << 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit by bit against the definition.
    fn naive3(x: u64, y: u64, z: u64) -> u64 {
        (0..21).fold(0, |c, i| {
            c | ((x >> i) & 1) << (3 * i)
                | ((y >> i) & 1) << (3 * i + 1)
                | ((z >> i) & 1) << (3 * i + 2)
        })
    }

    #[test]
    fn codes_match_the_bitwise_definition() {
        let vals = [0u64, 1, 2, 5, 0x15555, 0x1f_ffff, 0x10_0000, 123_456];
        for &x in &vals {
            for &y in &vals {
                for &z in &vals {
                    assert_eq!(encode3(x, y, z), naive3(x, y, z));
                }
            }
            assert_eq!(compact3(spread3(x)), x);
        }
        for (u, v) in [
            (0u32, 0u32),
            (1, 0),
            (0, 1),
            (3, 5),
            (u32::MAX, 7),
            (0xdead, 0xbeef),
        ] {
            let want = (0..32).fold(0u64, |c, i| {
                c | (u64::from(u >> i) & 1) << (2 * i) | (u64::from(v >> i) & 1) << (2 * i + 1)
            });
            assert_eq!(encode2(u, v), want);
        }
    }
}
