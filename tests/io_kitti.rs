//! SemanticKITTI: the three real scans of sequence 00 with labels, calib and
//! poses must line up in one world frame; bad input must be named.
mod common;

use std::collections::HashSet;
use std::path::Path;

use common::{assert_err_names, shared, truncated_copy};
use omcl::io::cloud::PointCloud;
use omcl::io::kitti::{
    AggregateOptions, KITTI_IMAGE_SIZE, KittiSequence, read_calib, read_kitti_poses,
    read_label_file, read_velodyne_bin,
};
use omcl::io::labels::is_dropped_semantic_kitti;

const BUILDING: u32 = 50;

fn building_cells(c: &PointCloud, res: f64) -> HashSet<[i64; 3]> {
    c.points
        .iter()
        .zip(c.labels.as_ref().unwrap())
        .filter(|(_, l)| **l == BUILDING)
        .map(|(p, _)| p.map(|v| (v / res).floor() as i64))
        .collect()
}

fn iou_sets(a: &HashSet<[i64; 3]>, b: &HashSet<[i64; 3]>) -> f64 {
    let inter = a.intersection(b).count() as f64;
    inter / (a.len() as f64 + b.len() as f64 - inter)
}

#[test]
fn real_scans_line_up_with_lidar_poses() {
    let dir = shared("semantickitti/sequences/00");
    let seq = KittiSequence::open(&dir).unwrap();
    assert_eq!(seq.frames, vec![0, 1, 2]);
    assert_eq!(seq.camera_poses.len(), 4541);
    let world0 = seq.load_scan(0).unwrap();
    let world2 = seq.load_scan(2).unwrap();
    assert_eq!(world0.len(), 124_668);
    assert_eq!(world2.len(), 124_478);
    let sensor0 = read_velodyne_bin(&seq.scan_path(0)).unwrap();
    let mut sensor2 = read_velodyne_bin(&seq.scan_path(2)).unwrap();
    sensor2.labels = world2.labels.clone();
    let mut sensor0 = sensor0;
    sensor0.labels = world0.labels.clone();
    let with_poses = iou_sets(&building_cells(&world0, 0.3), &building_cells(&world2, 0.3));
    let without = iou_sets(
        &building_cells(&sensor0, 0.3),
        &building_cells(&sensor2, 0.3),
    );
    eprintln!("building IoU at 0.3 m: {with_poses:.3} with poses, {without:.3} without");
    assert!(with_poses > 0.5, "with poses {with_poses}");
    assert!(without < 0.3, "without poses {without}");
    // The car drives forward about 0.8 m a frame along the LiDAR's x axis.
    let t2 = seq.world_from_lidar(2).unwrap().translation.vector;
    assert!(
        t2.x > 1.0 && t2.x < 2.5 && t2.y.abs() < 0.3 && t2.z.abs() < 0.3,
        "{t2}"
    );
    // Frame 0 is the world frame.
    let t0 = seq.world_from_lidar(0).unwrap();
    assert!(t0.translation.vector.norm() < 0.05 && t0.rotation.angle() < 0.01);
}

#[test]
fn aggregation_filters_and_downsamples() {
    let dir = shared("semantickitti/sequences/00");
    let seq = KittiSequence::open(&dir).unwrap();
    let opts = AggregateOptions {
        voxel_size: Some(0.2),
        drop_unlabeled_outlier_moving: true,
        max_range: Some(40.0),
        features_dir: None,
    };
    let map = seq.aggregate(&[], &opts).unwrap();
    map.validate("map").unwrap();
    let labels = map.labels.as_ref().unwrap();
    assert!(labels.iter().all(|&l| !is_dropped_semantic_kitti(l)));
    let cells: HashSet<[i64; 3]> = map
        .points
        .iter()
        .map(|p| p.map(|v| (v / 0.2).floor() as i64))
        .collect();
    assert_eq!(cells.len(), map.len(), "one point per voxel");
    // Far fewer points than the three scans, yet more than one scan alone.
    let one = seq.aggregate(&[0], &opts).unwrap();
    assert!(
        map.len() > one.len() && map.len() < 3 * 124_668 / 2,
        "{} {}",
        map.len(),
        one.len()
    );
    // Range cut in the world frame of scan 0 (the sensor of frame 0 is the origin).
    assert!(
        one.points
            .iter()
            .all(|p| p.iter().map(|v| v * v).sum::<f64>().sqrt() <= 40.0 + 1e-6)
    );
}

/// A sequence dir in `tmp` with scan 0 of the real data and the given
/// calib/poses text.
fn fake_sequence(tmp: &Path, real: &Path, calib: &str, poses: &str) {
    std::fs::create_dir_all(tmp.join("velodyne")).unwrap();
    std::fs::create_dir_all(tmp.join("labels")).unwrap();
    std::fs::copy(
        real.join("velodyne/000000.bin"),
        tmp.join("velodyne/000000.bin"),
    )
    .unwrap();
    std::fs::copy(
        real.join("labels/000000.label"),
        tmp.join("labels/000000.label"),
    )
    .unwrap();
    std::fs::write(tmp.join("calib.txt"), calib).unwrap();
    std::fs::write(tmp.join("poses.txt"), poses).unwrap();
}

const IDENTITY: &str = "1 0 0 0 0 1 0 0 0 0 1 0\n";

#[test]
fn bad_scans_and_labels_are_named() {
    let dir = shared("semantickitti/sequences/00");
    let d = tempfile::tempdir().unwrap();
    let p = truncated_copy(
        &dir.join("velodyne/000000.bin"),
        d.path(),
        "000000.bin",
        1000 * 16 + 6,
    );
    assert_err_names(read_velodyne_bin(&p).unwrap_err(), &p, "multiple of 16");
    let l = dir.join("labels/000001.label");
    let e = read_label_file(&l, 124_668).unwrap_err();
    assert_err_names(e, &l, "124605 labels for a scan of 124668 points");
    let p = truncated_copy(
        &dir.join("labels/000000.label"),
        d.path(),
        "odd.label",
        4001,
    );
    assert_err_names(read_label_file(&p, 1000).unwrap_err(), &p, "multiple of 4");
    // NaN in a scan.
    let mut bytes = std::fs::read(dir.join("velodyne/000000.bin")).unwrap();
    bytes.truncate(16 * 100);
    bytes[16 * 42 + 4..16 * 42 + 8].copy_from_slice(&f32::NAN.to_le_bytes());
    let p = d.path().join("nan.bin");
    std::fs::write(&p, bytes).unwrap();
    assert_err_names(read_velodyne_bin(&p).unwrap_err(), &p, "point 42");
    let p = d.path().join("empty.bin");
    std::fs::write(&p, b"").unwrap();
    assert_err_names(read_velodyne_bin(&p).unwrap_err(), &p, "empty");
    // A label file of the wrong length inside a sequence is caught on load.
    let seq_dir = d.path().join("seq_badlabel");
    let calib = std::fs::read_to_string(dir.join("calib.txt")).unwrap();
    fake_sequence(&seq_dir, &dir, &calib, IDENTITY);
    std::fs::copy(
        dir.join("labels/000002.label"),
        seq_dir.join("labels/000000.label"),
    )
    .unwrap();
    let seq = KittiSequence::open(&seq_dir).unwrap();
    let e = seq.load_scan(0).unwrap_err();
    assert_err_names(
        e,
        &seq_dir.join("labels/000000.label"),
        "labels for a scan of",
    );
}

#[test]
fn bad_poses_and_calibration_are_named() {
    let dir = shared("semantickitti/sequences/00");
    let d = tempfile::tempdir().unwrap();
    let calib = std::fs::read_to_string(dir.join("calib.txt")).unwrap();
    let p = d.path().join("poses_nan.txt");
    std::fs::write(&p, format!("{IDENTITY}1 0 0 nan 0 1 0 0 0 0 1 0\n")).unwrap();
    assert_err_names(read_kitti_poses(&p).unwrap_err(), &p, ":2: column 4");
    let p = d.path().join("poses_scaled.txt");
    std::fs::write(&p, "2 0 0 0 0 2 0 0 0 0 2 0\n").unwrap();
    assert_err_names(read_kitti_poses(&p).unwrap_err(), &p, "not a rotation");
    let p = d.path().join("poses_short.txt");
    std::fs::write(&p, "1 0 0 0 0 1 0 0 0 0 1\n").unwrap();
    assert_err_names(read_kitti_poses(&p).unwrap_err(), &p, "expected 12");
    let p = d.path().join("poses_empty.txt");
    std::fs::write(&p, "\n").unwrap();
    assert_err_names(read_kitti_poses(&p).unwrap_err(), &p, "no poses");
    let p = d.path().join("calib_no_tr.txt");
    let no_tr: String = calib
        .lines()
        .filter(|l| !l.starts_with("Tr"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&p, no_tr).unwrap();
    assert_err_names(read_calib(&p).unwrap_err(), &p, "Tr");
    let p = d.path().join("calib_shear.txt");
    std::fs::write(&p, "Tr: 1 0.5 0 0 0 1 0 0 0 0 1 0\n").unwrap();
    assert_err_names(read_calib(&p).unwrap_err(), &p, "not a rigid pose");
    // P2 twice (the second one won): which is right cannot be told.
    let p = d.path().join("calib_two_p2.txt");
    let p2 = calib.lines().find(|l| l.starts_with("P2")).unwrap();
    std::fs::write(&p, format!("{calib}{p2}\n")).unwrap();
    assert_err_names(read_calib(&p).unwrap_err(), &p, "'P2:' again");
    // Time stamps that go back (named with the file, not as 'pose 1').
    let p = d.path().join("times_back.txt");
    std::fs::write(&p, "0.0\n0.9\n0.8\n").unwrap();
    assert_err_names(
        omcl::io::poses::read_times(&p).unwrap_err(),
        &p,
        ":3: time stamp 0.8 s is before the previous one",
    );
    // Poses shorter than the scans.
    let seq_dir = d.path().join("seq_short");
    fake_sequence(&seq_dir, &dir, &calib, IDENTITY);
    std::fs::copy(
        dir.join("velodyne/000002.bin"),
        seq_dir.join("velodyne/000002.bin"),
    )
    .unwrap();
    let e = KittiSequence::open(&seq_dir).unwrap_err();
    assert_err_names(e, &seq_dir.join("poses.txt"), "needs pose 2");
}

#[test]
fn everything_filtered_is_an_empty_error() {
    let dir = shared("semantickitti/sequences/00");
    let d = tempfile::tempdir().unwrap();
    let seq_dir = d.path().join("seq_unlabeled");
    let calib = std::fs::read_to_string(dir.join("calib.txt")).unwrap();
    fake_sequence(&seq_dir, &dir, &calib, IDENTITY);
    // Every point labelled "moving-car" (252), instance 3.
    let n = std::fs::metadata(seq_dir.join("velodyne/000000.bin"))
        .unwrap()
        .len() as usize
        / 16;
    let raw: Vec<u8> = (0..n)
        .flat_map(|_| ((3u32 << 16) | 252).to_le_bytes())
        .collect();
    std::fs::write(seq_dir.join("labels/000000.label"), raw).unwrap();
    let seq = KittiSequence::open(&seq_dir).unwrap();
    let e = seq
        .aggregate(&[], &AggregateOptions::default())
        .unwrap_err();
    assert_err_names(e, &seq_dir, "empty result");
}

#[test]
fn real_labels_use_known_classes_and_instances() {
    use omcl::io::labels::{instance_id, semantic_id, semantic_kitti_name};
    let dir = shared("semantickitti/sequences/00");
    let n = read_velodyne_bin(&dir.join("velodyne/000000.bin"))
        .unwrap()
        .len();
    let raw = read_label_file(&dir.join("labels/000000.label"), n).unwrap();
    let unknown: HashSet<u32> = raw
        .iter()
        .map(|&r| semantic_id(r))
        .filter(|&s| semantic_kitti_name(s).is_none())
        .collect();
    assert!(unknown.is_empty(), "unknown classes {unknown:?}");
    let count = |id: u32| raw.iter().filter(|&&r| semantic_id(r) == id).count();
    // An urban street: road, building, vegetation and cars all present.
    for id in [40, 50, 70, 10] {
        assert!(count(id) > 500, "class {id}: {}", count(id));
    }
    // Cars carry instance ids; road does not.
    assert!(
        raw.iter()
            .any(|&r| semantic_id(r) == 10 && instance_id(r) > 0)
    );
    assert!(
        raw.iter()
            .filter(|&&r| semantic_id(r) == 40)
            .all(|&r| instance_id(r) == 0)
    );
}

#[test]
fn per_scan_features_stay_with_their_points() {
    let dir = shared("semantickitti/sequences/00");
    let seq = KittiSequence::open(&dir).unwrap();
    let d = tempfile::tempdir().unwrap();
    // Feature row = (semantic label, frame): after filtering and down-sampling
    // every point's feature must still name its own label.
    for &frame in &seq.frames {
        let scan = seq.load_scan(frame).unwrap();
        let data: Vec<f32> = scan
            .labels
            .as_ref()
            .unwrap()
            .iter()
            .flat_map(|&l| [l as f32, frame as f32])
            .collect();
        omcl::io::npy::write_npy(
            &d.path().join(format!("{frame:06}.npy")),
            &[scan.len(), 2],
            &data,
        )
        .unwrap();
    }
    let opts = AggregateOptions {
        voxel_size: Some(0.5),
        features_dir: Some(d.path().to_path_buf()),
        ..AggregateOptions::default()
    };
    let map = seq.aggregate(&[], &opts).unwrap();
    let (dim, f) = map.features.as_ref().unwrap();
    assert_eq!(*dim, 2);
    for (i, &l) in map.labels.as_ref().unwrap().iter().enumerate() {
        assert_eq!(f[2 * i], l as f32, "point {i}");
    }
    let frames: HashSet<u32> = f.chunks(2).map(|r| r[1] as u32).collect();
    assert_eq!(frames, HashSet::from([0, 1, 2]));
    // A feature file for another scan (wrong row count) is named.
    std::fs::copy(d.path().join("000002.npy"), d.path().join("000000.npy")).unwrap();
    let e = seq.aggregate(&[], &opts).unwrap_err();
    assert_err_names(
        e,
        &d.path().join("000000.npy"),
        "feature rows for a cloud of 124668",
    );
}

/// Camera 2 of the real KITTI 00 calibration, against values computed by
/// hand from its `P2` line (fx = P2[0][0] = 718.856, cx = 607.1928 + 0.5,
/// cy = 185.2157 + 0.5, offset -45.38225 / 718.856 = -0.0631312 m along
/// camera-0 x). Reads the shared data directly: a missing file fails.
#[test]
fn real_calibration_gives_camera_2_and_its_offset_from_camera_0() {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/semantickitti/sequences/00/calib.txt"
    ));
    let calib = read_calib(path).unwrap();
    let (w, h) = KITTI_IMAGE_SIZE;
    assert_eq!((w, h), (1241, 376));
    let cam = calib.camera("P2", w, h, path).unwrap();
    let k = cam.intrinsics;
    assert_eq!((k.fx, k.fy), (718.856, 718.856));
    assert!((k.cx - 607.6928).abs() < 1e-9, "{}", k.cx);
    assert!((k.cy - 185.7157).abs() < 1e-9, "{}", k.cy);
    assert_eq!((k.width, k.height), (1241, 376));
    let t = cam.camera0_from_camera.translation.vector;
    assert!((t.x + 0.063_131_2).abs() < 1e-6, "{t:?}");
    assert_eq!((t.y, t.z), (0.0, 0.0));
    assert_eq!(cam.camera0_from_camera.rotation.angle(), 0.0);
    // Camera 0 is itself; camera 3 sits 0.469 m right of camera 2.
    let c0 = calib.camera("P0", w, h, path).unwrap();
    assert_eq!(c0.camera0_from_camera.translation.vector.norm(), 0.0);
    let c3 = calib.camera("P3", w, h, path).unwrap();
    let x3 = c3.camera0_from_camera.translation.vector.x;
    assert!((x3 - 337.2877 / 718.856).abs() < 1e-9, "{x3}");
    // A point 10 m ahead of camera 2 on its axis projects to its
    // principal point, in camera 0 it lies 6.3 cm to the left.
    let p0 = cam.camera0_from_camera * nalgebra::Point3::new(0.0, 0.0, 10.0);
    assert!((p0.x + 0.0631312).abs() < 1e-6);
}

#[test]
fn calibration_without_p2_or_with_a_skewed_p2_is_named() {
    let d = tempfile::tempdir().unwrap();
    let tr = "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n";
    let p = d.path().join("calib_no_p2.txt");
    std::fs::write(&p, format!("P0: 700 0 600 0 0 700 180 0 0 0 1 0\n{tr}")).unwrap();
    let calib = read_calib(&p).unwrap();
    let e = calib.camera("P2", 1241, 376, &p).unwrap_err();
    assert_err_names(&e, &p, "no 'P2:' line");
    assert!(e.to_string().contains("has P0"), "{e}");
    let p = d.path().join("calib_skew.txt");
    std::fs::write(&p, format!("P2: 700 3 600 0 0 700 180 0 0 0 1 0\n{tr}")).unwrap();
    let e = read_calib(&p)
        .unwrap()
        .camera("P2", 1241, 376, &p)
        .unwrap_err();
    assert_err_names(&e, &p, "not a rectified projection");
    let p = d.path().join("calib_zero_f.txt");
    std::fs::write(&p, format!("P2: 0 0 600 0 0 700 180 0 0 0 1 0\n{tr}")).unwrap();
    let e = read_calib(&p)
        .unwrap()
        .camera("P2", 1241, 376, &p)
        .unwrap_err();
    assert_err_names(&e, &p, "must be positive");
}

#[test]
fn hidden_files_are_passed_over_and_unpadded_names_refused() {
    let real = shared("semantickitti/sequences/00");
    let tmp = tempfile::tempdir().unwrap();
    let calib = std::fs::read_to_string(real.join("calib.txt")).unwrap();
    fake_sequence(tmp.path(), &real, &calib, IDENTITY);
    // macOS's AppleDouble file beside a copied scan: not a frame.
    std::fs::write(tmp.path().join("velodyne/._000000.bin"), b"xxxx").unwrap();
    let seq = KittiSequence::open(tmp.path()).unwrap();
    assert_eq!(seq.frames, vec![0]);
    // "19.bin" is not read as frame 19 (it would be looked for as
    // 000019.bin); neither is a seven-digit name.
    for name in ["1.bin", "0000001.bin"] {
        let p = tmp.path().join("velodyne").join(name);
        std::fs::copy(real.join("velodyne/000001.bin"), &p).unwrap();
        assert_err_names(
            KittiSequence::open(tmp.path()).unwrap_err(),
            &p,
            "NNNNNN.bin",
        );
        std::fs::remove_file(&p).unwrap();
    }
}
