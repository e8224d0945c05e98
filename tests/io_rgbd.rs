//! The two real TUM fr1_xyz RGB-D pairs: depth back-projected from the
//! previous view, moved by the ground-truth poses into the current view,
//! must agree with the current depth within sensor noise.
mod common;

use std::path::Path;

use common::{assert_err_names, shared, truncated_copy};
use nalgebra::Point3;
use omcl::geometry::{Intrinsics, Pose};
use omcl::io::rgbd::{
    DepthImage, TUM_DEPTH_UNITS_PER_METRE, backproject, read_depth_png, read_intrinsics,
    read_rgbd_frame, read_single_tum_pose,
};

/// TUM's calibrated freiburg1 intrinsics (integer-centre convention, so
/// +0.5 for the crate's pixel-centre convention).
fn fr1() -> Intrinsics {
    Intrinsics {
        fx: 517.3,
        fy: 516.5,
        cx: 318.6 + 0.5,
        cy: 255.3 + 0.5,
        width: 640,
        height: 480,
    }
}

/// Median |z_projected - z_current| over previous-view points that land on
/// a valid current pixel, and the fraction of points that do.
fn reprojection_error(
    k: &Intrinsics,
    prev: &DepthImage,
    world_from_prev: &Pose,
    curr: &DepthImage,
    world_from_curr: &Pose,
) -> (f64, f64) {
    let (pts, _) = backproject(k, prev).unwrap();
    let curr_from_prev = world_from_curr.inverse() * world_from_prev;
    let mut diffs = Vec::new();
    for p in &pts {
        let q = curr_from_prev * Point3::from(*p);
        let Some((u, v)) = k.project(&q) else {
            continue;
        };
        if u < 0.0 || v < 0.0 || u >= k.width as f64 || v >= k.height as f64 {
            continue;
        }
        let z = curr.depth[v as usize * k.width as usize + u as usize] as f64;
        if z > 0.0 {
            diffs.push((q.z - z).abs());
        }
    }
    let frac = diffs.len() as f64 / pts.len() as f64;
    diffs.sort_by(f64::total_cmp);
    (diffs[diffs.len() / 2], frac)
}

fn check_case(dir: &Path) {
    let k = fr1();
    let prev = read_depth_png(&dir.join("dep_prev.png"), TUM_DEPTH_UNITS_PER_METRE).unwrap();
    let curr = read_depth_png(&dir.join("dep_curr.png"), TUM_DEPTH_UNITS_PER_METRE).unwrap();
    assert_eq!((prev.width, prev.height), (640, 480));
    let valid = prev.depth.iter().filter(|&&z| z > 0.0).count();
    assert!(valid > 200_000, "{valid} valid pixels");
    // A desk scene seen from about a metre: depths between 0.3 m and 5 m.
    assert!(
        prev.depth
            .iter()
            .all(|&z| z == 0.0 || (0.3..5.0).contains(&z))
    );
    let wp = read_single_tum_pose(&dir.join("pose_prev.txt")).unwrap();
    let wc = read_single_tum_pose(&dir.join("pose_curr.txt")).unwrap();
    let (med, frac) = reprojection_error(&k, &prev, &wp, &curr, &wc);
    // Swapping the poses applies the motion backwards: twice the error.
    let (med_swapped, _) = reprojection_error(&k, &prev, &wc, &curr, &wp);
    eprintln!(
        "{}: median |dz| {med:.4} m over {:.0}% of points; poses swapped {med_swapped:.4} m",
        dir.display(),
        frac * 100.0
    );
    // Kinect noise at 1 m is about 1 cm.
    assert!(med < 0.03, "median {med}");
    assert!(frac > 0.8, "overlap {frac}");
    assert!(med_swapped > 3.0 * med, "{med_swapped} vs {med}");
    let rgb = omcl::io::rgb::read_rgb(&dir.join("img_prev.png")).unwrap();
    assert_eq!(rgb.dimensions(), (640, 480));
    let cloud = read_rgbd_frame(
        &dir.join("dep_prev.png"),
        &dir.join("img_prev.png"),
        &k,
        TUM_DEPTH_UNITS_PER_METRE,
        &wp,
    )
    .unwrap();
    assert_eq!(cloud.len(), valid);
    cloud.validate("tum").unwrap();
}

#[test]
fn real_pairs_agree_between_views() {
    let root = shared("rgbd_tum_fr1_xyz");
    check_case(&root.join("case_1"));
    check_case(&root.join("case_2"));
}

#[test]
fn bad_images_and_intrinsics_are_named() {
    let root = shared("rgbd_tum_fr1_xyz");
    let d = tempfile::tempdir().unwrap();
    let dep = root.join("case_1/dep_prev.png");
    let p = truncated_copy(&dep, d.path(), "cut_depth.png", 60_000);
    assert_err_names(read_depth_png(&p, 5000.0).unwrap_err(), &p, "PNG");
    let p = truncated_copy(&dep, d.path(), "header_only.png", 20);
    assert_err_names(read_depth_png(&p, 5000.0).unwrap_err(), &p, "PNG");
    // A colour image is not a depth image.
    let img = root.join("case_1/img_prev.png");
    assert_err_names(
        read_depth_png(&img, 5000.0).unwrap_err(),
        &img,
        "16-bit grayscale",
    );
    let k = d.path().join("k.txt");
    std::fs::write(&k, "525 525 319.5 239.5 640\n").unwrap();
    assert_err_names(read_intrinsics(&k).unwrap_err(), &k, "expected 6 values");
    // Numbers no camera has (each was taken, and localized to nonsense).
    for (text, why) in [
        ("1e300 1e300 48 36 96 72", "focal length fx = 1e300"),
        ("1e-300 48 48 36 96 72", "focal length fx = 1e-300"),
        ("48 48 1e9 36 96 72", "principal point cx = 1000000000"),
        ("48 48 -1e30 36 96 72", "principal point cx"),
        ("48 48 48 36 96 100000", "image height 100000"),
    ] {
        std::fs::write(&k, format!("{text}\n")).unwrap();
        assert_err_names(read_intrinsics(&k).unwrap_err(), &k, why);
    }
    std::fs::write(&k, "# fx fy cx cy w h\n525 525 319.5 239.5 640 480\n").unwrap();
    let small = Intrinsics {
        width: 320,
        height: 240,
        ..read_intrinsics(&k).unwrap()
    };
    let e = read_rgbd_frame(&dep, &img, &small, 5000.0, &Pose::identity()).unwrap_err();
    assert_err_names(e, &dep, "intrinsics are for 320x240");
    let pose = d.path().join("pose.txt");
    std::fs::write(&pose, "1 2 3 0 0 0 3\n").unwrap();
    assert_err_names(read_single_tum_pose(&pose).unwrap_err(), &pose, "norm");
}

/// A TUM sequence as published (the real pair in its names and lists) is
/// refused by `map rgbd` and `localize` with what an RGB-D folder needs,
/// not with "poses.txt: No such file".
#[test]
fn a_raw_tum_sequence_is_named_with_what_omcl_reads() {
    let root = shared("rgbd_tum_fr1_xyz/case_1");
    let d = tempfile::tempdir().unwrap();
    let tum = d.path().join("rgbd_dataset_freiburg1_xyz");
    for (sub, name, from) in [
        ("rgb", "1305031102.175304.png", "img_prev.png"),
        ("depth", "1305031102.160407.png", "dep_prev.png"),
    ] {
        std::fs::create_dir_all(tum.join(sub)).unwrap();
        std::fs::copy(root.join(from), tum.join(sub).join(name)).unwrap();
        let stamp = name.trim_end_matches(".png");
        std::fs::write(
            tum.join(format!("{sub}.txt")),
            format!("# {sub}\n# timestamp filename\n{stamp} {sub}/{name}\n"),
        )
        .unwrap();
    }
    std::fs::write(
        tum.join("groundtruth.txt"),
        "# ground truth\n1305031102.1758 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\n",
    )
    .unwrap();
    let map = d.path().join("m.omcl");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    // A map to localize in: a few labelled points.
    let ply = d.path().join("p.ply");
    std::fs::write(
        &ply,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
         property float z\nproperty int label\nend_header\n0 0 0 40\n1 0 0 40\n0 1 0 50\n",
    )
    .unwrap();
    let r = common::omcl(&[
        "map",
        "cloud",
        &s(&ply),
        "--classes",
        "semantickitti",
        "-o",
        &s(&map),
    ]);
    assert!(r.ok(), "{}", r.output());
    let before = std::fs::read(&map).unwrap();
    let map2 = d.path().join("m2.omcl");
    let est = d.path().join("est.txt");
    for args in [
        vec!["map", "rgbd", &s(&tum), "-o", &s(&map2)],
        vec![
            "localize",
            "--map",
            &s(&map),
            "--sequence",
            &s(&tum),
            "-o",
            &s(&est),
        ],
    ] {
        let r = common::omcl(&args);
        assert_ne!(r.code, Some(0), "{args:?}: {}", r.output());
        let e = r.stderr;
        assert!(
            e.contains(&format!(
                "{}: a TUM RGB-D sequence as published",
                tum.display()
            )) && e.contains("intrinsics.txt (`fx fy cx cy width height`")
                && e.contains("associate.py"),
            "{args:?}: {e}"
        );
    }
    assert!(!map2.exists() && !est.exists());
    assert_eq!(std::fs::read(&map).unwrap(), before);
}
