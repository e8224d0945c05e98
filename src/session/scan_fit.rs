//! Does a map fit a sequence? A LiDAR scan of the sequence, placed in the
//! map at its pose, against the map's occupied space.
//!
//! Localizing a camera in the wrong map (another drive's, or this drive's
//! with the start pose in another frame) goes wrong without a sign: the
//! filter scores the rays it casts into the wrong street and reports a
//! confident track. A KITTI sequence folder holds the LiDAR scans the map
//! of its drive was made from, so the first scan tells: placed at the start
//! pose, most of what it saw above the road lies where the right map has
//! voxels, and little of it where a wrong one has.
//!
//! The test is coarse on purpose: a point fits when the map has a voxel in
//! its octree node of about [`FIT_CELL_M`] edge or in one of the 26 nodes
//! around it. A start pose a metre or five degrees off, a map made from
//! other scans of the same drive, still fit; a scan turned round or
//! mirrored, as another street would look, does not, and neither does
//! another synthetic street of the same layout. Only points at least
//! [`FIT_ABOVE_GROUND_M`] above the ground the sensor's mount height puts
//! under it count: facades, trees and poles, not the road, kerbs, parked
//! cars and hedges, which every street has in about the same places.

use crate::geometry::Pose;
use crate::map::LanguageMap;
use crate::map::key;

/// Edge of the map nodes a scan's points are looked up in, metres (the
/// largest octree level at or below it is used).
pub const FIT_CELL_M: f64 = 0.4;
/// Points this far or more above the ground under the sensor count.
/// With 0.5 m (above the road, cars included) two synthetic streets of
/// the same layout met at 0.63, with 1.5 m at 0.39 (the right map 1.00).
pub const FIT_ABOVE_GROUND_M: f64 = 1.5;
/// Points nearer than this to the sensor (the car itself) or farther
/// (sparse, and beyond most maps' reach) do not count, metres.
pub const FIT_RANGE_M: [f64; 2] = [3.0, 25.0];
/// Fewer counted points than this: no verdict.
pub const FIT_MIN_POINTS: usize = 500;
/// A share of counted points in occupied nodes below this says the map
/// does not fit. Measured on the real SemanticKITTI scans of
/// `../shared/data` (`tests/session_scan_fit.rs`; scan 2 against a map of
/// scans 0 and 1, 5 cm voxels): at its pose 1.00, 1 m off 0.70 to 0.87, 5 degrees
/// off 0.72, 10 degrees off 0.52; turned by 90 or 180 degrees or mirrored
/// 0.08 to 0.12. On the synthetic street (`omcl sim outdoor`, seeds 3 and
/// 4, 0.2 m maps; `tests/cli_localize_kitti.rs`): the right map 1.00, the
/// other seed's 0.39.
pub const FIT_MIN_SHARE: f64 = 0.5;

/// How a scan placed at a pose meets a map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanFit {
    /// Share of the counted points in or next to occupied map nodes.
    pub share: f64,
    /// Points counted (in range, above the ground).
    pub points: usize,
    /// Edge of the nodes looked up in, metres.
    pub cell_m: f64,
}

impl ScanFit {
    /// Whether the share says the map does not fit ([`FIT_MIN_SHARE`]).
    pub fn misfit(&self) -> bool {
        self.share < FIT_MIN_SHARE
    }
}

/// How `points` (the sensor's frame, z up, the sensor `mount_height_m`
/// above the ground) placed by `map_from_sensor` meet `map`'s occupied
/// space; `None` when fewer than [`FIT_MIN_POINTS`] count (in
/// [`FIT_RANGE_M`], [`FIT_ABOVE_GROUND_M`] above the ground).
pub fn scan_fit(
    map: &LanguageMap,
    map_from_sensor: &Pose,
    points: &[[f64; 3]],
    mount_height_m: f64,
) -> Option<ScanFit> {
    let grid = map.grid();
    let levels = (FIT_CELL_M / grid.resolution).log2().floor().max(0.0) as u32;
    let levels = levels.min(key::AXIS_BITS);
    let shift = 3 * levels;
    // The leaves under a node are a contiguous run of the sorted codes: no
    // copy of them (a full drive's map holds 10^8 leaves).
    let codes = map.codes();
    let occupied = |node: u64| {
        let first = codes.partition_point(|&c| c >> shift < node);
        codes.get(first).is_some_and(|&c| c >> shift == node)
    };
    let z_min = FIT_ABOVE_GROUND_M - mount_height_m;
    let (r_lo, r_hi) = (FIT_RANGE_M[0].powi(2), FIT_RANGE_M[1].powi(2));
    let (mut counted, mut inside) = (0usize, 0usize);
    for p in points {
        let r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
        if p[2] < z_min || !(r_lo..=r_hi).contains(&r2) {
            continue;
        }
        counted += 1;
        let w = map_from_sensor * nalgebra::Point3::new(p[0], p[1], p[2]);
        let Some(cell) = grid.cell_of(&w.coords) else {
            continue;
        };
        // The node's own index, and the 27 around it (itself included).
        let node = key::decode(key::encode(cell) >> shift);
        let near = (0..27).any(|k| {
            let n = [
                node[0] + k % 3 - 1,
                node[1] + k / 3 % 3 - 1,
                node[2] + k / 9 - 1,
            ];
            key::in_range(n) && occupied(key::encode(n))
        });
        inside += usize::from(near);
    }
    (counted >= FIT_MIN_POINTS).then(|| ScanFit {
        share: inside as f64 / counted as f64,
        points: counted,
        cell_m: grid.resolution * f64::from(1u32 << levels),
    })
}
