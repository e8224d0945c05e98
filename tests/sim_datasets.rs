//! Written synthetic datasets: deterministic by seed, read back by the
//! project's loaders, and their depth, labels and LiDAR points agree with
//! the ground-truth world written beside them.

mod common;

use common::shared;

use std::path::Path;

use nalgebra::{Point3, Vector3};

use omcl::io::kitti::KittiSequence;
use omcl::io::npy::read_npy;
use omcl::io::poses::read_poses;
use omcl::io::rgb::read_rgb;
use omcl::io::rgbd::{TUM_DEPTH_UNITS_PER_METRE, read_depth_png, read_intrinsics};
use omcl::sim::dataset::{IndoorDatasetConfig, OutdoorDatasetConfig, write_indoor, write_outdoor};
use omcl::sim::files::builtin_table;
use omcl::sim::outdoor::{OUTDOOR_CLASSES, SEMANTIC_KITTI_IDS};
use omcl::sim::paths::{level_camera, world_from_kitti};
use omcl::sim::world::VoxelWorld;

fn small_indoor(seed: u64) -> IndoorDatasetConfig {
    let mut cfg = IndoorDatasetConfig::new(seed);
    cfg.world.rooms = 3;
    cfg.path.frames = 12;
    cfg.width = 64;
    cfg.height = 48;
    cfg.features = true;
    cfg.feature_stride = 4;
    cfg
}

/// The ground-truth world as written: cells, labels, resolution, origin.
fn read_world(dir: &Path) -> VoxelWorld {
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("world.json")).unwrap()).unwrap();
    let cells = read_npy(&dir.join("cells.npy")).unwrap();
    let labels = read_npy(&dir.join("labels.npy")).unwrap();
    let o = meta["origin"].as_array().unwrap();
    VoxelWorld {
        resolution: meta["resolution"].as_f64().unwrap(),
        origin: Vector3::new(
            o[0].as_f64().unwrap(),
            o[1].as_f64().unwrap(),
            o[2].as_f64().unwrap(),
        ),
        cells: cells
            .data
            .chunks(3)
            .map(|c| [c[0] as i32, c[1] as i32, c[2] as i32])
            .collect(),
        labels: labels.data.iter().map(|&l| l as u16).collect(),
        classes: vec![],
    }
}

fn files_of(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.file_name().unwrap() != "sim.json" {
                // sim.json records the wall-clock time of the run.
                out.push((
                    p.strip_prefix(dir).unwrap().display().to_string(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn indoor_dataset_is_deterministic_and_reads_back_consistently() {
    let table = builtin_table().unwrap();
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    let c = tempfile::tempdir().unwrap();
    let none = |_: usize| {};
    let s = write_indoor(a.path(), &small_indoor(4), &table, (&[], None), &none).unwrap();
    write_indoor(b.path(), &small_indoor(4), &table, (&[], None), &none).unwrap();
    write_indoor(c.path(), &small_indoor(5), &table, (&[], None), &none).unwrap();
    assert_eq!(s.frames, 12);
    let fa = files_of(a.path());
    assert_eq!(fa, files_of(b.path()), "same seed, different files");
    assert_ne!(fa, files_of(c.path()), "different seeds, same files");

    let dir = a.path();
    let k = read_intrinsics(&dir.join("intrinsics.txt")).unwrap();
    assert_eq!((k.width, k.height), (64, 48));
    let poses = read_poses(&dir.join("poses.txt")).unwrap().trajectory;
    let odo = read_poses(&dir.join("odometry.txt")).unwrap().trajectory;
    assert_eq!(poses.len(), 12);
    assert_eq!(odo.len(), 12);
    let classes: Vec<String> = std::fs::read_to_string(dir.join("classes.txt"))
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    let emb = read_npy(&dir.join("embeddings.npy")).unwrap();
    assert_eq!(emb.shape, vec![classes.len(), 512]);
    let feat = read_npy(&dir.join("features/000003.npy")).unwrap();
    assert_eq!(feat.shape, vec![12, 16, 512]);
    let world = read_world(&dir.join("world"));

    // Every valid depth pixel, back-projected from the written pose, lands
    // in (or on the face of) a ground-truth voxel with the pixel's label.
    let (mut checked, mut agree) = (0, 0);
    for i in [0usize, 5, 11] {
        let depth = read_depth_png(
            &dir.join(format!("depth/{i:06}.png")),
            TUM_DEPTH_UNITS_PER_METRE,
        )
        .unwrap();
        let (w, h, labels) =
            omcl::io::rgbd::read_label_png(&dir.join(format!("labels/{i:06}.png"))).unwrap();
        assert_eq!((w, h), (64, 48));
        let rgb = read_rgb(&dir.join(format!("rgb/{i:06}.png"))).unwrap();
        assert_eq!(rgb.dimensions(), (64, 48));
        let pose = poses.poses()[i];
        for v in 0..h {
            for u in 0..w {
                let j = (v * w + u) as usize;
                let d = depth.depth[j] as f64;
                if d <= 0.0 {
                    continue;
                }
                let ray = k.pixel_dir(u, v);
                // Step 2 mm beyond the surface along the ray: inside the hit voxel.
                let p_cam = ray * (d / ray.z + 0.002);
                let p = pose * Point3::from(p_cam);
                let cell = world.cell_of(&p.coords);
                if world.label_at(cell) == Some(labels[j] as u16) {
                    agree += 1;
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 3 * 64 * 48 * 9 / 10, "{checked}");
    // Rays that graze a voxel edge can leave it within the 2 mm step.
    assert!(agree as f64 > 0.99 * checked as f64, "{agree} of {checked}");
}

#[test]
fn outdoor_sequence_reads_back_and_lidar_points_lie_on_labelled_surfaces() {
    // A straight 30 m drive along camera z (KITTI camera 0 frame).
    let k_from_w = world_from_kitti().inverse();
    let path: Vec<_> = (0..30)
        .map(|i| k_from_w * level_camera(Vector3::new(i as f64, 0.0, 0.0), 0.0))
        .collect();
    let mut cfg = OutdoorDatasetConfig::new(2);
    cfg.world.frames = 4;
    cfg.lidar.azimuth_steps = 180;
    cfg.lidar.range_noise = 0.0;
    cfg.images = false;
    let dir = tempfile::tempdir().unwrap();
    let table = builtin_table().unwrap();
    write_outdoor(dir.path(), &cfg, &path, &table, &|_| {}).unwrap();
    let seq = KittiSequence::open(&dir.path().join("sequences/00")).unwrap();
    assert_eq!(seq.frames, vec![0, 1, 2, 3]);
    let world = read_world(&dir.path().join("world"));
    // Sequence world = first LiDAR frame; ours = world_from_kitti * camera 0.
    let ours_from_seq = world_from_kitti() * seq.calib.camera_from_lidar;
    let (mut points, mut agree) = (0, 0);
    for f in [0usize, 3] {
        let cloud = seq.load_scan(f).unwrap();
        let labels = cloud.labels.as_ref().unwrap();
        let origin = seq.world_from_lidar(f).unwrap().translation.vector;
        assert!(cloud.points.len() > 64 * 180 / 2);
        for (p, &l) in cloud.points.iter().zip(labels) {
            let p = Vector3::from(*p);
            // 2 mm beyond the return along the beam: inside the hit voxel.
            let q = p + (p - origin).normalize() * 0.002;
            let q = ours_from_seq * Point3::from(q);
            let class = world.label_at(world.cell_of(&q.coords));
            if class.map(|c| SEMANTIC_KITTI_IDS[c as usize]) == Some(l) {
                agree += 1;
            } else if points - agree < 3 {
                eprintln!(
                    "frame {f}: {q:?} label {l} found {class:?}, range {}",
                    (p - origin).norm()
                );
            }
            points += 1;
        }
    }
    assert!(agree as f64 > 0.99 * points as f64, "{agree} of {points}");
    assert_eq!(OUTDOOR_CLASSES.len(), SEMANTIC_KITTI_IDS.len());
}

#[test]
fn real_drift_comes_from_kitti_orb_against_ground_truth() {
    let dir = &shared("trajectories");
    let (errs, source) = omcl::sim::dataset::load_drift(dir).unwrap();
    assert_eq!(errs.len(), 4540);
    assert!(source.contains("ORB"));
    // ORB-SLAM2's per-frame relative errors on KITTI 00 are centimetres and
    // hundredths of a degree: real, small, and not all zero.
    let n = errs.len() as f64;
    let mean_t = errs
        .iter()
        .map(|e| e.translation.vector.norm())
        .sum::<f64>()
        / n;
    let mean_r = errs
        .iter()
        .map(|e| e.rotation.angle().to_degrees())
        .sum::<f64>()
        / n;
    assert!(mean_t > 1e-3 && mean_t < 0.5, "{mean_t}");
    assert!(mean_r > 1e-4 && mean_r < 2.0, "{mean_r}");
    eprintln!("KITTI 00 ORB drift: {mean_t:.4} m, {mean_r:.4} deg per frame");
}

/// Camera 2 of the street world: label images of KITTI's size with the
/// SemanticKITTI ids of the class table written beside them, features on
/// request, and the LiDAR's labelled points, projected into camera 2
/// through calib.txt (Tr, P2), land on pixels of their own label.
#[test]
fn outdoor_camera_2_labels_agree_with_the_lidar_labels() {
    use omcl::io::kitti::{KITTI_IMAGE_SIZE, read_calib};
    use omcl::io::labels::EmbeddingTable;
    let k_from_w = world_from_kitti().inverse();
    let path: Vec<_> = (0..40)
        .map(|i| k_from_w * level_camera(Vector3::new(i as f64, 0.0, 0.0), 0.0))
        .collect();
    let mut cfg = OutdoorDatasetConfig::new(5);
    cfg.world.frames = 2;
    cfg.lidar.azimuth_steps = 360;
    cfg.lidar.range_noise = 0.0;
    cfg.features = true;
    cfg.feature_stride = 16;
    let dir = tempfile::tempdir().unwrap();
    let table = builtin_table().unwrap();
    write_outdoor(dir.path(), &cfg, &path, &table, &|_| {}).unwrap();
    let seq_dir = dir.path().join("sequences/00");
    let classes = EmbeddingTable::read(
        &seq_dir.join("classes.txt"),
        &seq_dir.join("embeddings.npy"),
    )
    .unwrap();
    assert_eq!(classes.ids, SEMANTIC_KITTI_IDS.to_vec());
    assert_eq!(classes.dim, 512);
    let (w, h, labels) =
        omcl::io::rgbd::read_label_png(&seq_dir.join("labels_2/000000.png")).unwrap();
    assert_eq!((w, h), KITTI_IMAGE_SIZE);
    // Road straight below the camera, sky (0) somewhere above the street.
    assert_eq!(labels[(h as usize - 4) * w as usize + w as usize / 2], 40);
    assert!(labels.contains(&0));
    assert!(
        labels
            .iter()
            .all(|l| *l == 0 || SEMANTIC_KITTI_IDS.contains(l))
    );
    let f = read_npy(&seq_dir.join("features_2/000001.npy")).unwrap();
    assert_eq!(f.shape, vec![376 / 16, 1241 / 16, 512]);
    // Project frame 0's labelled LiDAR points into camera 2.
    let calib = read_calib(&seq_dir.join("calib.txt")).unwrap();
    let cam = calib
        .camera("P2", w, h, &seq_dir.join("calib.txt"))
        .unwrap();
    let cam2_from_lidar = cam.camera0_from_camera.inverse() * calib.camera_from_lidar;
    let seq = KittiSequence::open(&seq_dir).unwrap();
    let scan = omcl::io::kitti::read_velodyne_bin(&seq.scan_path(0)).unwrap();
    let point_labels =
        omcl::io::kitti::read_label_file(&seq.label_path(0), scan.points.len()).unwrap();
    let k = cam.intrinsics;
    let (mut seen, mut agree) = (0usize, 0usize);
    for (p, &l) in scan.points.iter().zip(&point_labels) {
        let q = cam2_from_lidar * Point3::from(*p);
        if q.z < 2.0 {
            continue;
        }
        let (u, v) = (k.fx * q.x / q.z + k.cx, k.fy * q.y / q.z + k.cy);
        if u < 0.0 || v < 0.0 || u >= w as f64 || v >= h as f64 {
            continue;
        }
        seen += 1;
        agree += usize::from(labels[v as usize * w as usize + u as usize] == l);
    }
    assert!(seen > 2000, "{seen}");
    // The two sensors see from 0.33 m apart: occlusion edges differ.
    assert!(agree as f64 > 0.95 * seen as f64, "{agree} of {seen}");
}
