//! Does a map fit a sequence: a real SemanticKITTI scan of sequence 00
//! against a map of two other scans of the same drive, at its true pose, a
//! little off, and turned or mirrored as another street would look from
//! the car (`omcl::session::scan_fit`; `omcl localize` warns with it).
mod common;

use common::shared;
use nalgebra::Vector3;
use omcl::geometry::Pose;
use omcl::io::kitti::{KittiSequence, read_velodyne_bin};
use omcl::map::key::GridSpec;
use omcl::map::{FeatureDb, LanguageMap};
use omcl::session::scan_fit::{FIT_MIN_SHARE, scan_fit};

/// KITTI's Velodyne is 1.73 m above the road.
const MOUNT_M: f64 = 1.73;

fn map_of(points: &[[f64; 3]], resolution: f64) -> LanguageMap {
    let grid = GridSpec {
        resolution,
        origin: Vector3::zeros(),
    };
    let db = FeatureDb::from_rows(2, 0.1, vec![1.0, 0.0]).unwrap();
    let cells = points
        .iter()
        .filter_map(|p| grid.cell_of(&Vector3::from(*p)))
        .map(|c| (c, 0u32));
    LanguageMap::from_cells(grid, db, "test", cells).unwrap()
}

#[test]
fn a_real_scan_fits_its_drive_near_its_pose_and_not_turned_or_mirrored() {
    let seq = KittiSequence::open(&shared("semantickitti/sequences/00")).unwrap();
    // The map: scans 0 and 1 in the world (the first LiDAR frame), 5 cm.
    let mut pts = seq.load_scan(0).unwrap().points;
    pts.extend(seq.load_scan(1).unwrap().points);
    let map = map_of(&pts, 0.05);
    // Scan 2, not in the map, in its own (sensor) frame.
    let scan = read_velodyne_bin(&seq.scan_path(2)).unwrap().points;
    let truth = seq.world_from_lidar(2).unwrap();
    let moved = |dx: f64, dy: f64, yaw_deg: f64| {
        truth
            * Pose::new(
                Vector3::new(dx, dy, 0.0),
                Vector3::z() * yaw_deg.to_radians(),
            )
    };
    let share = |pose: &Pose, pts: &[[f64; 3]]| {
        let fit = scan_fit(&map, pose, pts, MOUNT_M).expect("enough points");
        assert!(fit.points > 3_000, "{fit:?}");
        assert_eq!(fit.cell_m, 0.4);
        fit.share
    };
    let fits = [
        ("at its pose", share(&truth, &scan)),
        ("1 m off", share(&moved(0.6, 0.8, 0.0), &scan)),
        ("5 degrees off", share(&moved(0.0, 0.0, 5.0), &scan)),
    ];
    let mirrored: Vec<[f64; 3]> = scan.iter().map(|p| [p[0], -p[1], p[2]]).collect();
    let misfits = [
        ("turned round", share(&moved(0.0, 0.0, 180.0), &scan)),
        ("turned 90 degrees", share(&moved(0.0, 0.0, 90.0), &scan)),
        ("mirrored", share(&truth, &mirrored)),
    ];
    eprintln!("fit: {fits:?}\nmisfit: {misfits:?}");
    assert!(fits[0].1 > 0.95, "{fits:?}");
    for (what, s) in fits {
        assert!(s >= FIT_MIN_SHARE, "{what}: {s}");
    }
    for (what, s) in misfits {
        assert!(s < 0.2, "{what}: {s}");
    }
}

#[test]
fn too_few_points_above_the_road_give_no_verdict() {
    let map = map_of(&[[5.0, 0.0, 0.0]], 0.05);
    // 1000 points low (the road, 1.73 m below the sensor, and a car's
    // height, 1.2 m above the road) and 100 on a wall at the sensor's height.
    let mut pts: Vec<[f64; 3]> = (0..1000)
        .map(|i| {
            [
                5.0 + i as f64 * 0.01,
                0.0,
                if i % 2 == 0 { -1.73 } else { -0.53 },
            ]
        })
        .collect();
    pts.extend((0..100).map(|i| [5.0, 0.0, i as f64 * 0.001]));
    assert_eq!(scan_fit(&map, &Pose::identity(), &pts, MOUNT_M), None);
    // 600 on the wall: a verdict; the 100 at the one voxel's node and
    // next to it fit, the 500 farther up (0.9 m and more) do not.
    pts.extend((0..500).map(|i| [5.0, 0.0, 0.9 + i as f64 * 0.001]));
    let fit = scan_fit(&map, &Pose::identity(), &pts, MOUNT_M).unwrap();
    assert_eq!(fit.points, 600);
    assert!((fit.share - 100.0 / 600.0).abs() < 1e-12, "{fit:?}");
}
