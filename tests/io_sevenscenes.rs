//! The 7-Scenes reader on the real redkitchen frames in ../shared/data
//! (a missing folder fails the test), and hostile copies of them through
//! `omcl encode colour-model`: exit code 1, the file named, nothing written.

use std::path::{Path, PathBuf};
use std::process::Command;

use omcl::io::sevenscenes::SevenScenes;

fn scenes() -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/rgbd_7scenes");
    assert!(
        p.join("camera-intrinsics.txt").exists(),
        "{} is missing: the tests need ../shared/data",
        p.display()
    );
    p
}

#[test]
fn real_frames_read_with_their_poses_depth_and_colour() {
    let seq = SevenScenes::open(&scenes()).unwrap();
    assert_eq!(seq.len(), 300);
    assert_eq!(seq.frames[299].number, 299);
    let k = seq.intrinsics;
    assert_eq!((k.fx, k.fy, k.cx, k.cy), (585.0, 585.0, 320.5, 240.5));
    assert_eq!((k.width, k.height), (640, 480));
    // Frame 0's pose file, first row: 0.9093129 0.27262229 -0.31422433 -0.34045634.
    let p0 = seq.poses[0];
    let m = p0.to_homogeneous();
    assert!((m[(0, 0)] - 0.9093129).abs() < 2e-4);
    assert!((m[(0, 3)] + 0.34045634).abs() < 1e-12);
    assert!((m[(2, 3)] - 0.29656917).abs() < 1e-12);
    // About 7 mm a frame, 2.1 m in all.
    let path: f64 = seq
        .poses
        .windows(2)
        .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
        .sum();
    assert!((1.9..2.3).contains(&path), "path {path} m");
    // Frame 0's depth: 89 % valid, 0.80 to 3.49 m (the data's README).
    let d = seq.read_depth(0).unwrap();
    let valid: Vec<f32> = d.depth.iter().copied().filter(|z| *z > 0.0).collect();
    let share = valid.len() as f64 / d.depth.len() as f64;
    assert!((share - 0.89).abs() < 0.01, "valid share {share}");
    let lo = valid.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = valid.iter().copied().fold(0.0, f32::max);
    assert!(
        (lo - 0.80).abs() < 0.01 && (hi - 3.49).abs() < 0.01,
        "{lo} {hi}"
    );
    // Millimetres to metres: every depth is a whole number of mm.
    assert!(
        valid
            .iter()
            .all(|z| ((z * 1000.0) - (z * 1000.0).round()).abs() < 1e-3)
    );
    // 7-Scenes' invalid depth, 65535 mm, reads as none: frame 33 stores
    // it at 46 pixels (besides its zeros), its largest reading 3.390 m.
    let png = omcl::io::rgbd::read_depth_png(&seq.frames[33].depth, 1000.0).unwrap();
    let raw_invalid = png.depth.iter().filter(|&&z| z > 65.0).count();
    let d = seq.read_depth(33).unwrap();
    let hi = d.depth.iter().copied().fold(0.0, f32::max);
    assert_eq!(raw_invalid, 46);
    assert!((hi - 3.390).abs() < 1e-4, "{hi}");
    let zeros = |d: &[f32]| d.iter().filter(|&&z| z == 0.0).count();
    assert_eq!(zeros(&d.depth), zeros(&png.depth) + 46);
    let c = seq.read_color(0).unwrap();
    assert_eq!(c.dimensions(), (640, 480));
    // Gravity: mostly along the first camera's +y (down in the image).
    let g = seq.gravity_in_first_camera.unwrap();
    assert!(g.y > 0.85 && (g.norm() - 1.0).abs() < 1e-12);
}

/// A copy of the first `n` frames with the intrinsics and gravity.
fn small_copy(n: usize) -> tempfile::TempDir {
    let src = scenes();
    let dir = tempfile::tempdir().unwrap();
    for f in ["camera-intrinsics.txt", "gravity-direction.txt"] {
        std::fs::copy(src.join(f), dir.path().join(f)).unwrap();
    }
    for i in 0..n {
        for ext in ["color.jpg", "depth.png", "pose.txt"] {
            let name = format!("frame-{i:06}.{ext}");
            std::fs::copy(src.join(&name), dir.path().join(&name)).unwrap();
        }
    }
    dir
}

/// Runs `omcl encode colour-model` on `dir`; asserts exit code 1, the
/// message naming `file` and containing `what`, and no model or card left.
fn refused(dir: &Path, file: &str, what: &str) {
    let out_dir = tempfile::tempdir().unwrap();
    let model = out_dir.path().join("m.onnx");
    let out = Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(["encode", "colour-model", "-k", "2", "--frames"])
        .arg(dir)
        .arg("-o")
        .arg(&model)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    eprintln!("{err}");
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(file), "error does not name {file}: {err}");
    assert!(err.contains(what), "error lacks {what:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    let left: Vec<_> = std::fs::read_dir(out_dir.path()).unwrap().collect();
    assert!(left.is_empty(), "output left behind: {left:?}");
}

#[test]
fn a_small_copy_fits_a_model() {
    let dir = small_copy(4);
    let out_dir = tempfile::tempdir().unwrap();
    let model = out_dir.path().join("m.onnx");
    let out = Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(["encode", "colour-model", "-k", "3", "--frames"])
        .arg(dir.path())
        .arg("-o")
        .arg(&model)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("3 colour classes"));
    assert!(model.exists() && out_dir.path().join("m.card.json").exists());

    // Another fit (another seed) is another feature space of the same
    // dimension: a map of the first is not localized with the second.
    let run = |args: &[&std::ffi::OsStr]| {
        let out = Command::new(env!("CARGO_BIN_EXE_omcl"))
            .args(args)
            .output()
            .unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let os = |s: &str| std::ffi::OsString::from(s);
    let other = out_dir.path().join("other.onnx");
    let (code, err) = run(&[
        &os("encode"),
        &os("colour-model"),
        &os("-k"),
        &os("3"),
        &os("--seed"),
        &os("8"),
        &os("--frames"),
        dir.path().as_os_str(),
        &os("-o"),
        other.as_os_str(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let map = out_dir.path().join("m.omcl");
    let (code, err) = run(&[
        &os("map"),
        &os("rgbd"),
        dir.path().as_os_str(),
        &os("--image-model"),
        model.as_os_str(),
        &os("-o"),
        map.as_os_str(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let est = out_dir.path().join("est.txt");
    let (code, err) = run(&[
        &os("localize"),
        &os("--map"),
        map.as_os_str(),
        &os("--sequence"),
        dir.path().as_os_str(),
        &os("--image-model"),
        other.as_os_str(),
        &os("-o"),
        est.as_os_str(),
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("the colour model `omcl-colour-lab-k3-d32-") && err.contains("another fit"),
        "{err}"
    );
    assert!(!est.exists());
}

#[test]
fn missing_depth_is_refused_naming_it() {
    let dir = small_copy(4);
    std::fs::remove_file(dir.path().join("frame-000002.depth.png")).unwrap();
    refused(
        dir.path(),
        "frame-000002.depth.png",
        "depth image of frame 000002 is missing",
    );
}

/// A frame whose pose is missing, and a file named `frame-...` as the
/// dataset does not name them, are refused by name (both frames had been
/// left out without a word).
#[test]
fn a_missing_pose_and_an_odd_frame_name_are_refused_naming_them() {
    let dir = small_copy(4);
    std::fs::remove_file(dir.path().join("frame-000002.pose.txt")).unwrap();
    refused(
        dir.path(),
        "frame-000002.pose.txt",
        "the pose of frame 000002 is missing",
    );
    let dir = small_copy(4);
    std::fs::rename(
        dir.path().join("frame-000003.pose.txt"),
        dir.path().join("frame-3.pose.txt"),
    )
    .unwrap();
    refused(dir.path(), "frame-3.pose.txt", "not a 7-Scenes frame file");
}

#[test]
fn a_pose_that_is_not_a_rotation_is_refused_naming_it() {
    let dir = small_copy(4);
    // Row 0 scaled by 1.1: orthonormality broken.
    std::fs::write(
        dir.path().join("frame-000003.pose.txt"),
        "1.1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
    )
    .unwrap();
    refused(dir.path(), "frame-000003.pose.txt", "not a rotation");
    // A reflection (det -1).
    std::fs::write(
        dir.path().join("frame-000003.pose.txt"),
        "1 0 0 0\n0 1 0 0\n0 0 -1 0\n0 0 0 1\n",
    )
    .unwrap();
    refused(dir.path(), "frame-000003.pose.txt", "det = -1");
    // A bad last row, and a NaN.
    std::fs::write(
        dir.path().join("frame-000003.pose.txt"),
        "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 1 1\n",
    )
    .unwrap();
    refused(dir.path(), "frame-000003.pose.txt", "last row");
    std::fs::write(
        dir.path().join("frame-000003.pose.txt"),
        "1 0 0 NaN\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
    )
    .unwrap();
    refused(dir.path(), "frame-000003.pose.txt", "not a finite number");
}

#[test]
fn an_empty_folder_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let name = dir
        .path()
        .file_name()
        .unwrap()
        .to_string_lossy()
        .to_string();
    refused(dir.path(), &name, "no frame-NNNNNN.pose.txt");
}

#[test]
fn truncated_and_wrong_sized_images_are_refused_naming_them() {
    let dir = small_copy(4);
    // A truncated colour JPEG of a mapping (even) frame.
    let jpg = dir.path().join("frame-000002.color.jpg");
    let bytes = std::fs::read(&jpg).unwrap();
    std::fs::write(&jpg, &bytes[..bytes.len() / 3]).unwrap();
    refused(dir.path(), "frame-000002.color.jpg", "truncated JPEG");
    // Not an image at all.
    std::fs::write(&jpg, b"hello").unwrap();
    refused(dir.path(), "frame-000002.color.jpg", "not a readable");
    // A colour image of the wrong size.
    image::RgbImage::new(64, 48).save(&jpg).unwrap();
    refused(dir.path(), "frame-000002.color.jpg", "64x48 pixels");
    // Truncated and wrong-sized depth, through the reader.
    let dir = small_copy(2);
    let png = dir.path().join("frame-000001.depth.png");
    let bytes = std::fs::read(&png).unwrap();
    std::fs::write(&png, &bytes[..bytes.len() / 2]).unwrap();
    let seq = SevenScenes::open(dir.path()).unwrap();
    let e = seq.read_depth(1).unwrap_err().to_string();
    assert!(
        e.contains("frame-000001.depth.png") && e.contains("truncated"),
        "{e}"
    );
    image::ImageBuffer::<image::Luma<u16>, _>::new(32, 24)
        .save(&png)
        .unwrap();
    let e = seq.read_depth(1).unwrap_err().to_string();
    assert!(
        e.contains("frame-000001.depth.png") && e.contains("32x24"),
        "{e}"
    );
    // A missing intrinsics file is named.
    std::fs::remove_file(dir.path().join("camera-intrinsics.txt")).unwrap();
    let e = SevenScenes::open(dir.path()).unwrap_err().to_string();
    assert!(e.contains("camera-intrinsics.txt"), "{e}");
}

#[test]
fn bench_refuses_too_few_frames_before_writing_the_model() {
    let dir = small_copy(4);
    let out = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(["bench", "sevenscenes", "--scenes"])
        .arg(dir.path())
        .arg("-o")
        .arg(out.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("4 frames leave 1 to localize"), "{err}");
    assert!(!out.path().join("colour_model.onnx").exists());
}
