//! End to end on real sensor data: the first 120 frames of 7-Scenes
//! redkitchen, the even ones mapped with real depth and the colour-class
//! encoder through ONNX Runtime, every 4th odd frame (15 frames, 5 cm a
//! step) localized in 6-DoF from the paper's local start (0.3 m / 17
//! degrees) with odometry noise in the paper's proportion to the motion.

mod common;

use std::path::{Path, PathBuf};

use omcl::experiment::sevenscenes::{TrackSpec, fit_colour_model, run_track, split};
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
fn a_real_stretch_is_tracked_within_ten_centimetres() {
    let seq = SevenScenes::open(&scenes()).unwrap();
    let spec = TrackSpec {
        frames: Some(120),
        seed: 1,
        ..TrackSpec::default()
    };
    let (mapping, localized) = split(120, spec.localize_every);
    assert_eq!((mapping.len(), localized.len()), (60, 15));
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("colour.onnx");
    let classes = fit_colour_model(&seq, &mapping, &spec, &model).unwrap();
    let r = run_track(&seq, &spec, &classes, &model, None, &|_| {}).unwrap();
    let c = r.consistency.unwrap();
    eprintln!(
        "APE rmse {:.3} m, max {:.3}, rotation rmse {:.2} deg; step {:.3} m / {:.2} deg, \
         odometry noise {:.3} m / {:.2} deg; consistency accuracy {:.3} precision {:.3} \
         recall {:.3} IoU {:.3}; {} voxels",
        r.ape.rmse,
        r.ape.max,
        r.ape_rotation_deg.rmse,
        r.step_motion.0,
        r.step_motion.1,
        r.odometry_sigma.0,
        r.odometry_sigma.1,
        c.accuracy,
        c.precision,
        c.recall,
        c.iou,
        r.voxels
    );
    assert_eq!(r.localized.first(), Some(&1));
    assert_eq!(r.localized.last(), Some(&113));
    // Measured (release and test builds, seed 1): 0.061 m RMSE, 0.12 max.
    assert!(r.ape.rmse < 0.10, "APE rmse {:.3} m", r.ape.rmse);
    assert!(r.ape.max < 0.20, "APE max {:.3} m", r.ape.max);
    // 15 localized frames (1, 9, ..., 113) are too few for the completion
    // rule (16): not judged (the bound on the maximum above is this
    // stretch's tracking check; it had been called completed).
    assert_eq!(r.completed, None);
    // A step moves about 5 cm and 2 degrees; noise in the paper's ratio.
    assert!(
        (0.04..0.06).contains(&r.step_motion.0),
        "{:?}",
        r.step_motion
    );
    assert!((r.odometry_sigma.0 / r.step_motion.0 - 0.10 / 0.13).abs() < 1e-9);
    // The map agrees with the frames' colours from the true poses more
    // often than chance over 10 classes.
    assert!(c.accuracy > 0.2, "accuracy {:.3}", c.accuracy);
}

/// Runs the binary; prints and returns its exit code, stdout and stderr.
fn omcl(args: &[&str]) -> (Option<i32>, String, String) {
    let r = common::omcl(args);
    eprintln!("{}", r.output());
    (r.code, r.stdout, r.stderr)
}

/// The same stretch as a user runs it, through the command line: `omcl
/// encode colour-model`, `omcl map rgbd` on the 7-Scenes folder (the even
/// frames), `omcl localize` on the folder (every 4th odd frame, 6-DoF
/// motion and odometry noise in the paper's proportion by default).
#[test]
fn the_command_line_maps_and_localizes_a_7scenes_folder() {
    let scenes = scenes();
    let scenes = scenes.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (colour, kitchen, refused, estimate) = (
        p("colour.onnx"),
        p("kitchen.omcl"),
        p("refused.txt"),
        p("estimate.txt"),
    );
    let table = p("colour-classes");
    let (code, out, _) = omcl(&[
        "encode",
        "colour-model",
        "--frames",
        scenes,
        "--first",
        "120",
        "-o",
        &colour,
        "--class-table",
        &table,
    ]);
    assert_eq!(code, Some(0));
    assert!(out.contains("wrote the class table"), "{out}");
    let (code, out, _) = omcl(&[
        "map",
        "rgbd",
        scenes,
        "--image-model",
        &colour,
        "--frame-step",
        "2",
        "--frames",
        "60",
        "--resolution",
        "0.02",
        "--max-depth",
        "4",
        "-o",
        &kitchen,
    ]);
    assert_eq!(code, Some(0));
    assert!(out.contains("wrote"), "{out}");
    // `omcl localize` of the kitchen map on the folder, with `rest`.
    let localize = |rest: &[&str]| {
        omcl(
            &[
                &["localize", "--map", &kitchen, "--sequence", scenes][..],
                rest,
            ]
            .concat(),
        )
    };
    // Without an image encoder the folder is refused, naming it, and
    // nothing is written.
    let (code, _, err) = localize(&["-o", &refused]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("rgbd_7scenes") && err.contains("--image-model"),
        "{err}"
    );
    assert!(!std::path::Path::new(&refused).exists());
    // An offset past the last frame picks nothing: refused the same way.
    let (code, _, err) = localize(&[
        "--image-model",
        &colour,
        "--frame-offset",
        "400",
        "-o",
        &refused,
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("no frames picked (offset 400, step 1) of its 300 frames"),
        "{err}"
    );
    assert!(!std::path::Path::new(&refused).exists());
    let (code, out, _) = localize(&[
        "--image-model",
        &colour,
        "--frame-step",
        "8",
        "--frame-offset",
        "1",
        "--frames",
        "15",
        "--seed",
        "1",
        "-o",
        &estimate,
    ]);
    assert_eq!(code, Some(0));
    // TUM lines stamped with the frame numbers 1, 9, ..., 113.
    let est = std::fs::read_to_string(&estimate).unwrap();
    let stamps: Vec<f64> = est
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(stamps.len(), 15);
    assert_eq!((stamps[0], stamps[14]), (1.0, 113.0));
    let rmse: f64 = out
        .split("APE rmse ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no APE in {out}"));
    // The library track above measured 0.061 m on this stretch.
    assert!(rmse < 0.10, "APE rmse {rmse:.3} m");

    // Table I's baselines on the same stretch, on the map's floor plan,
    // labelling with the colour model's class table: both run to the last
    // frame. Measured (seeds 1-5, 2026-12-02), horizontal APE RMSE: SIMP*
    // (7-Scenes' real depth) 0.092 to 0.129 m, max 0.131 to 0.189 (0.089
    // to 0.132 m, max 0.131 to 0.202, with its distance fields padded past
    // the outer walls, 2026-12-04);
    // SeDAR* 0.41 to 0.67 m; OMCL's own 2-D mode 0.23 to 0.37 m.
    for (baseline, bound) in [("simp", 0.18), ("sedar", 1.0)] {
        let est = p(&format!("{baseline}.txt"));
        let (code, out, err) = localize(&[
            "--image-model",
            &colour,
            "--frame-step",
            "8",
            "--frame-offset",
            "1",
            "--frames",
            "15",
            "--seed",
            "1",
            "--floorplan",
            "--baseline",
            baseline,
            "--baseline-classes",
            &table,
            "-o",
            &est,
        ]);
        assert_eq!(code, Some(0), "{err}");
        let lines = std::fs::read_to_string(&est).unwrap();
        assert_eq!(lines.lines().filter(|l| !l.starts_with('#')).count(), 15);
        let rmse: f64 = out
            .split("APE (horizontal) rmse ")
            .nth(1)
            .and_then(|t| t.split_whitespace().next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no APE in {out}"));
        assert!(rmse < bound, "{baseline}: APE rmse {rmse:.3} m");
    }
    // --depth-scale on a 7-Scenes folder (read in millimetres) is refused.
    let (code, _, err) = localize(&[
        "--image-model",
        &colour,
        "--floorplan",
        "--baseline",
        "simp",
        "--baseline-classes",
        &table,
        "--depth-scale",
        "1000",
        "-o",
        &refused,
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("read in millimetres"), "{err}");
    // A second fit into the same class table is refused, the table kept.
    let classes = std::path::Path::new(&table).join("classes.txt");
    let before = std::fs::read(&classes).unwrap();
    let (code, _, err) = omcl(&[
        "encode",
        "colour-model",
        "--frames",
        scenes,
        "--first",
        "20",
        "--seed",
        "9",
        "-o",
        &p("other.onnx"),
        "--class-table",
        &table,
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("exists") && err.contains("classes.txt"),
        "{err}"
    );
    assert_eq!(std::fs::read(&classes).unwrap(), before);
    assert!(!dir.path().join("other.onnx").exists());
    // Without a class table (a 7-Scenes folder has none) it is refused,
    // naming the table it looked for.
    let (code, _, err) = localize(&[
        "--image-model",
        &colour,
        "--floorplan",
        "--baseline",
        "sedar",
        "-o",
        &refused,
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("the sequence's class table") && err.contains("classes.txt"),
        "{err}"
    );
    assert!(!std::path::Path::new(&refused).exists());
}
