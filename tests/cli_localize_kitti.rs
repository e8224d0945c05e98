//! `omcl localize` on a KITTI odometry sequence folder as it is (camera 2
//! from calib.txt, poses.txt as ground truth, labels_2/ with the sequence's
//! class table), end to end through the binary on a short synthetic street
//! made with the CLI itself (`omcl sim outdoor` -> `omcl map cloud`), and on
//! bad input: each must exit non-zero with a message naming the file, and
//! leave an existing `--out` untouched.
//!
//! The street follows the real KITTI 00 path, read from the shared data
//! (`../shared/data/trajectories/KITTI_00_gt.txt`): without it the
//! simulator fails and so do these tests.

mod common;

use common::{Run, omcl};

use std::path::{Path, PathBuf};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A street sequence of `frames` frames (about 0.75 m apart) and its map.
struct Street {
    dir: tempfile::TempDir,
    seq: PathBuf,
    map: PathBuf,
}

impl Street {
    fn new(frames: usize) -> Street {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("street");
        let n = frames.to_string();
        let r = omcl(&[
            "sim",
            "outdoor",
            "--out",
            s(&root),
            "--seed",
            "3",
            "--frames",
            &n,
            "--resolution",
            "0.2",
            "--azimuth-steps",
            "512",
        ]);
        assert!(r.ok(), "{}", r.text());
        let seq = root.join("sequences/00");
        let map = dir.path().join("street.omcl");
        let r = omcl(&[
            "map",
            "cloud",
            s(&seq),
            "--classes",
            s(&root.join("semantickitti_ids.txt")),
            "--embeddings",
            s(&root.join("embeddings.npy")),
            "-o",
            s(&map),
            "--resolution",
            "0.2",
        ]);
        assert!(r.ok(), "{}", r.text());
        Street { dir, seq, map }
    }

    fn localize(&self, map: &Path, seq: &Path, out: &Path, extra: &[&str]) -> Run {
        let args = [
            &[
                "localize",
                "--map",
                s(map),
                "--sequence",
                s(seq),
                "-o",
                s(out),
                "--particles",
                "256",
                "--rays",
                "1024",
                "--seed",
                "5",
            ][..],
            extra,
        ]
        .concat();
        omcl(&args)
    }

    fn copy_seq(&self, name: &str) -> PathBuf {
        let to = self.dir.path().join(name);
        copy_dir(&self.seq, &to);
        to
    }

    fn existing_out(&self, name: &str) -> PathBuf {
        let p = self.dir.path().join(name);
        std::fs::write(&p, OLD_OUT).unwrap();
        p
    }
}

/// An earlier estimate (one KITTI pose: a trajectory, which a run may
/// replace) that a failed run must not touch.
const OLD_OUT: &str = "1 0 0 0 0 1 0 0 0 0 1 0\n";

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let dst = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &dst);
        } else {
            std::fs::copy(e.path(), dst).unwrap();
        }
    }
}

fn assert_clean_failure(r: &Run, out: &Path, needles: &[&str]) {
    let text = r.text();
    assert!(!r.stderr.contains("panicked"), "panicked:\n{text}");
    assert_eq!(r.code, Some(1), "expected exit 1 (an error):\n{text}");
    for n in needles {
        assert!(r.stderr.contains(n), "message lacks {n:?}:\n{text}");
    }
    assert_eq!(
        std::fs::read_to_string(out).unwrap(),
        OLD_OUT,
        "{} was overwritten:\n{text}",
        out.display()
    );
}

fn kitti_rows(p: &Path) -> Vec<[f64; 12]> {
    std::fs::read_to_string(p)
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            v.try_into().unwrap()
        })
        .collect()
}

/// 80 frames (about 60 m of the start of KITTI 00) with the authors'
/// odometry noise (0.1 m on camera x and z, 0.1 rad yaw a frame): the
/// estimate stays near the truth. Measured with this setup (256 particles,
/// 1024 rays, 0.2 m map, road motion): 0.41 m and 1.2 degrees mean error
/// (planar motion: 0.35 m, 0.77 degrees).
#[test]
fn a_short_street_localizes_in_kitti_layout() {
    let f = Street::new(80);
    let out = f.dir.path().join("est.txt");
    let metrics = f.dir.path().join("metrics.json");
    let r = f.localize(&f.map, &f.seq, &out, &["--metrics", s(&metrics)]);
    assert!(r.ok(), "{}", r.text());
    assert!(r.stdout.contains("rotation error mean"), "{}", r.text());
    // The map is this drive's: no warning about the first LiDAR scan.
    assert!(!r.stderr.contains("LiDAR scan"), "{}", r.text());
    // The estimate is written as KITTI camera-0 poses in poses.txt's frame.
    let est = kitti_rows(&out);
    let gt = kitti_rows(&f.seq.join("poses.txt"));
    assert_eq!(est.len(), 80);
    let mut direct = 0.0;
    for (e, g) in est.iter().zip(&gt) {
        direct += ((e[3] - g[3]).powi(2) + (e[7] - g[7]).powi(2) + (e[11] - g[11]).powi(2)).sqrt();
    }
    direct /= est.len() as f64;
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&metrics).unwrap()).unwrap();
    assert_eq!(m["method"], "OMCL (3-D map)");
    assert_eq!(m["horizontal"], false);
    let t_mean = m["translation_m"]["mean"].as_f64().unwrap();
    let r_mean = m["rotation_deg"]["mean"].as_f64().unwrap();
    eprintln!("translation mean {t_mean} m, rotation mean {r_mean} deg, direct {direct} m");
    assert!(
        t_mean < 0.6,
        "translation error mean {t_mean} m\n{}",
        r.text()
    );
    assert!(
        r_mean < 2.5,
        "rotation error mean {r_mean} deg\n{}",
        r.text()
    );
    assert_eq!(m["completed"], serde_json::Value::Bool(true));
    // Camera 0 and camera 2 move rigidly together: the error of the written
    // camera-0 poses equals the metric's up to the 6 cm lever arm.
    assert!((direct - t_mean).abs() < 0.07, "{direct} vs {t_mean}");
}

/// Bad input: a calib.txt without P2, label images of the wrong size,
/// fewer images than poses, a map of another feature dimension.
#[test]
fn bad_kitti_input_is_named_and_leaves_no_output() {
    let f = Street::new(12);
    // No P2.
    let seq = f.copy_seq("no_p2");
    let calib = std::fs::read_to_string(seq.join("calib.txt")).unwrap();
    let no_p2: String = calib
        .lines()
        .filter(|l| !l.starts_with("P2"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(seq.join("calib.txt"), no_p2).unwrap();
    let out = f.existing_out("out_no_p2.txt");
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert_clean_failure(&r, &out, &["calib.txt", "no 'P2:' line"]);
    // One pose fewer than images.
    let seq = f.copy_seq("short");
    for name in ["poses.txt", "times.txt"] {
        let text = std::fs::read_to_string(seq.join(name)).unwrap();
        let kept: String = text.lines().take(11).map(|l| format!("{l}\n")).collect();
        std::fs::write(seq.join(name), kept).unwrap();
    }
    let out = f.existing_out("out_short.txt");
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert_clean_failure(
        &r,
        &out,
        &["labels_2", "12 frames", "only 11 poses", "poses.txt"],
    );
    // One image fewer than poses: the sequence's first 11 frames are
    // localized (a copy of a drive's first scans), and the run says so.
    let seq = f.copy_seq("first");
    std::fs::remove_file(seq.join("labels_2/000011.png")).unwrap();
    let out = f.dir.path().join("out_first.txt");
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert_eq!(r.code, Some(0), "{}", r.text());
    assert!(
        r.stderr.contains("first 11 frames, of 12 poses"),
        "{}",
        r.text()
    );
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 11);
    // poses.txt cut to those 11 frames, times.txt the whole drive's: the
    // first stamps are theirs. Fewer stamps than poses is refused.
    let text = std::fs::read_to_string(seq.join("poses.txt")).unwrap();
    let kept: String = text.lines().take(11).map(|l| format!("{l}\n")).collect();
    std::fs::write(seq.join("poses.txt"), kept).unwrap();
    let out = f.dir.path().join("out_cut.txt");
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert_eq!(r.code, Some(0), "{}", r.text());
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 11);
    let text = std::fs::read_to_string(seq.join("times.txt")).unwrap();
    let kept: String = text.lines().take(10).map(|l| format!("{l}\n")).collect();
    std::fs::write(seq.join("times.txt"), kept).unwrap();
    let out = f.existing_out("out_few_stamps.txt");
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert_clean_failure(&r, &out, &["times.txt", "10 time stamps for 11 poses"]);
    // A global start on a street: refused with the reason (its class
    // table has no floor), not only "floor is not a class".
    let out = f.existing_out("out_global.txt");
    let r = f.localize(&f.map, &f.seq, &out, &["--init", "global"]);
    assert_clean_failure(&r, &out, &["indoor idea", "--init local", "\"floor\""]);
    // A label image of another size than frame 0's (and the camera's).
    let seq = f.copy_seq("small");
    std::fs::copy(
        f.seq.join("labels_2/000000.png"),
        seq.join("labels_2/000000.png"),
    )
    .unwrap();
    let small = seq.join("labels_2/000003.png");
    omcl::sim::files::write_png_gray16(&small, 620, 188, &vec![40u16; 620 * 188]).unwrap();
    let out = f.existing_out("out_small.txt");
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert_clean_failure(&r, &out, &["000003.png", "620 x 188", "1241 x 376"]);
    // Every label image at half the calibration's size: P2's principal
    // point is then at their edge, and that is said (it tracked badly,
    // with a warning that blamed the pose).
    let seq = f.copy_seq("half");
    for i in 0..12 {
        let p = seq.join(format!("labels_2/{i:06}.png"));
        omcl::sim::files::write_png_gray16(&p, 620, 188, &vec![40u16; 620 * 188]).unwrap();
    }
    let out = f.existing_out("out_half.txt");
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert_clean_failure(
        &r,
        &out,
        &["000000.png", "620 x 188", "principal point", "calib.txt"],
    );
    // A frame cut short near the end is named before any frame is
    // localized (it failed after the work, with nothing written).
    let seq = f.copy_seq("cut");
    let last = seq.join("labels_2/000010.png");
    let bytes = std::fs::read(&last).unwrap();
    std::fs::write(&last, &bytes[..bytes.len() / 2]).unwrap();
    let out = f.existing_out("out_cut_png.txt");
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert_clean_failure(&r, &out, &["000010.png", "truncated"]);
    assert!(!r.stderr.contains("frames/s"), "{}", r.text());
    // Only the frames a run reads are checked; bytes after a PNG's IEND
    // (some writers append metadata) are no damage.
    let tail = seq.join("labels_2/000005.png");
    let mut bytes = std::fs::read(&tail).unwrap();
    bytes.extend_from_slice(b"appended by some writer");
    std::fs::write(&tail, bytes).unwrap();
    let ok = f.dir.path().join("out_first8.txt");
    let r = f.localize(&f.map, &seq, &ok, &["--frames", "8"]);
    assert_eq!(r.code, Some(0), "{}", r.text());
    // Feature grids: one frame of another shape, or every grid transposed.
    let seq = f.copy_seq("feat");
    std::fs::create_dir(seq.join("features_2")).unwrap();
    let grid = |p: &Path, h: usize, w: usize| {
        omcl::io::npy::write_npy(p, &[h, w, 2], &vec![0.5; h * w * 2]).unwrap()
    };
    for i in 0..12 {
        grid(&seq.join(format!("features_2/{i:06}.npy")), 47, 155);
    }
    let odd = seq.join("features_2/000007.npy");
    grid(&odd, 40, 155);
    let out = f.existing_out("out_feat.txt");
    let r = f.localize(&f.map, &seq, &out, &["--use-features"]);
    assert_clean_failure(&r, &out, &["000007.npy", "[40, 155, 2]", "[47, 155, 2]"]);
    for i in 0..12 {
        grid(&seq.join(format!("features_2/{i:06}.npy")), 155, 47);
    }
    let r = f.localize(&f.map, &seq, &out, &["--use-features"]);
    assert_clean_failure(&r, &out, &["000000.npy", "155 x 47", "transposed"]);
    // A square grid (a ViT's) is any h x w: taken, each axis stretched; the
    // run then stops at the features' dimension (2, the map's 512).
    for i in 0..12 {
        grid(&seq.join(format!("features_2/{i:06}.npy")), 24, 24);
    }
    let r = f.localize(&f.map, &seq, &out, &["--use-features"]);
    assert_clean_failure(&r, &out, &["000000.npy"]);
    assert!(!r.stderr.contains("transposed"), "{}", r.text());
    // A map of another feature dimension.
    let other = f.dir.path().join("other.omcl");
    let pts = f.dir.path().join("pts.ply");
    std::fs::write(
        &pts,
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
         property float z\nproperty uint label\nend_header\n0 0 0 1\n1 0 0 2\n",
    )
    .unwrap();
    let classes = f.dir.path().join("c.txt");
    std::fs::write(&classes, "1 a\n2 b\n").unwrap();
    let emb = f.dir.path().join("e.npy");
    omcl::io::npy::write_npy(&emb, &[2, 4], &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]).unwrap();
    let r = omcl(&[
        "map",
        "cloud",
        s(&pts),
        "--classes",
        s(&classes),
        "--embeddings",
        s(&emb),
        "-o",
        s(&other),
    ]);
    assert!(r.ok(), "{}", r.text());
    let out = f.existing_out("out_dim.txt");
    let r = f.localize(&other, &f.seq, &out, &[]);
    assert_clean_failure(
        &r,
        &out,
        &["embeddings.npy", "dimension 512", "other.omcl", "has 4"],
    );
}

/// A KITTI sequence without poses.txt (KITTI's test sequences 11-21 have
/// none) localizes from a given odometry and start pose; without either
/// the run says which to pass, and metrics need the ground truth.
#[test]
fn a_kitti_sequence_without_poses_localizes_from_odometry_and_a_start() {
    let f = Street::new(12);
    let truth = omcl::io::kitti_camera::KittiCameraSequence::open(
        &f.seq,
        omcl::io::kitti_camera::CameraInput::Labels,
    )
    .unwrap()
    .ground_truth()
    .unwrap();
    let seq = f.copy_seq("no_poses");
    let odometry = f.dir.path().join("vo.txt");
    std::fs::rename(seq.join("poses.txt"), &odometry).unwrap();
    let out = f.existing_out("out_no_odometry.txt");
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert_clean_failure(&r, &out, &["no odometry", "--odometry FILE"]);
    let r = f.localize(&f.map, &seq, &out, &["--odometry", s(&odometry)]);
    assert_clean_failure(&r, &out, &["--init-pose", "camera 2", "poses.txt"]);
    // A poses.txt link that leads nowhere is an error naming it, not a
    // folder without ground truth.
    std::os::unix::fs::symlink(f.dir.path().join("gone.txt"), seq.join("poses.txt")).unwrap();
    let r = f.localize(&f.map, &seq, &out, &["--odometry", s(&odometry)]);
    assert_clean_failure(&r, &out, &["poses.txt"]);
    assert!(!r.stderr.contains("--init-pose"), "{}", r.text());
    std::fs::remove_file(seq.join("poses.txt")).unwrap();
    let metrics = f.dir.path().join("m.json");
    let (p, q) = (truth[0].translation.vector, truth[0].rotation.coords);
    let start = format!("{} {} {} {} {} {} {}", p.x, p.y, p.z, q.x, q.y, q.z, q.w);
    let with = ["--odometry", s(&odometry), "--init-pose", &start];
    let r = f.localize(
        &f.map,
        &seq,
        &out,
        &[&with[..], &["--metrics", s(&metrics)]].concat(),
    );
    assert_clean_failure(&r, &out, &["--metrics needs ground truth", "poses.txt"]);
    let out = f.dir.path().join("est.txt");
    let r = f.localize(&f.map, &seq, &out, &with);
    assert!(r.ok(), "{}", r.text());
    // The estimate (KITTI camera-0 rows, as poses.txt) follows the drive.
    let (est, gt) = (kitti_rows(&out), kitti_rows(&odometry));
    assert_eq!(est.len(), 12);
    let err: f64 = est
        .iter()
        .zip(&gt)
        .map(|(e, g)| {
            ((e[3] - g[3]).powi(2) + (e[7] - g[7]).powi(2) + (e[11] - g[11]).powi(2)).sqrt()
        })
        .sum::<f64>()
        / 12.0;
    assert!(err < 0.5, "mean error {err} m\n{}", r.text());
    assert!(gt.last().unwrap()[11] > 5.0, "the drive moves forward");
    assert!(!r.stderr.contains("warning"), "{}", r.text());
    // The same start given as poses.txt gives it (camera 0 in its frame,
    // the odometry's first row) with --init-pose-frame poses.
    let row = gt[0];
    let rot = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
        row[0], row[1], row[2], row[4], row[5], row[6], row[8], row[9], row[10],
    ));
    let q0 = nalgebra::UnitQuaternion::from_rotation_matrix(&rot);
    let cam0 = format!(
        "{} {} {} {} {} {} {}",
        row[3], row[7], row[11], q0.i, q0.j, q0.k, q0.w
    );
    let out0 = f.dir.path().join("est_cam0.txt");
    let as_poses = [
        "--odometry",
        s(&odometry),
        "--init-pose",
        &cam0,
        "--init-pose-frame",
        "poses",
    ];
    let r = f.localize(&f.map, &seq, &out0, &as_poses);
    assert!(r.ok() && !r.stderr.contains("warning"), "{}", r.text());
    let est0 = kitti_rows(&out0);
    let gap: f64 = est0
        .iter()
        .zip(&gt)
        .map(|(e, g)| ((e[3] - g[3]).powi(2) + (e[11] - g[11]).powi(2)).sqrt())
        .sum::<f64>()
        / 12.0;
    assert!(gap < 0.5, "mean error {gap} m\n{}", r.text());
    // That pose taken as the map's frame (the easy mistake) puts camera 2
    // where it sees none of the map: said, with the option to use.
    let r = f.localize(
        &f.map,
        &seq,
        &f.dir.path().join("est_wrong.txt"),
        &["--odometry", s(&odometry), "--init-pose", &cam0],
    );
    assert!(r.ok(), "{}", r.text());
    for needle in [
        "warning: --init-pose: from the start pose (at",
        "of the camera's view meets the map",
        "--init-pose-frame poses",
    ] {
        assert!(r.stderr.contains(needle), "{needle}: {}", r.text());
    }
    // With ground truth beside it, a start metres from its first pose is
    // said too (a start inside the map, seeing it).
    let moved = format!(
        "{} {} {} {} {} {} {}",
        p.x + 3.0,
        p.y,
        p.z,
        q.x,
        q.y,
        q.z,
        q.w
    );
    let r = f.localize(
        &f.map,
        &f.seq,
        &f.dir.path().join("est_moved.txt"),
        &["--init-pose", &moved],
    );
    assert!(
        r.ok()
            && r.stderr.contains(
                "--init-pose is 3.00 m and 0.0 degrees from the sequence's first ground-truth pose"
            ),
        "{}",
        r.text()
    );
}

/// A KITTI sequence localizes with two-pass likelihoods by default (half
/// the pixels first), as accurately as with every pixel cast for every
/// particle (`--every-ray`); the two switches exclude each other. Misses
/// score 0.5 there, and a miss score that is not a number is refused.
#[test]
fn streets_default_to_two_pass_likelihoods_and_every_ray_turns_them_off() {
    let f = Street::new(80);
    let run = |name: &str, extra: &[&str]| {
        let out = f.dir.path().join(format!("{name}.txt"));
        let metrics = f.dir.path().join(format!("{name}.json"));
        let r = f.localize(
            &f.map,
            &f.seq,
            &out,
            &[&["--metrics", s(&metrics)][..], extra].concat(),
        );
        assert!(r.ok(), "{}", r.text());
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&metrics).unwrap()).unwrap();
        (r, m["translation_m"]["mean"].as_f64().unwrap())
    };
    let (two, two_mean) = run("two_pass", &[]);
    assert!(
        two.stdout
            .contains("two-pass likelihoods: one pixel in 2 first"),
        "{}",
        two.text()
    );
    // Misses score halfway on streets (README, "Misses on streets").
    assert!(
        two.stdout
            .contains("rays that hit nothing score 0.5 (the street default"),
        "{}",
        two.text()
    );
    assert!(
        two.stdout.contains("256 particles x 1024 rays a frame\n"),
        "{}",
        two.text()
    );
    // Without --particles and --rays: the paper's street setting.
    let out = f.dir.path().join("defaults.txt");
    let args = [
        "localize",
        "--map",
        s(&f.map),
        "--sequence",
        s(&f.seq),
        "-o",
        s(&out),
    ];
    let r = omcl(&[&args[..], &["--frames", "3", "--seed", "5"]].concat());
    assert!(r.ok(), "{}", r.text());
    assert!(
        r.stdout
            .contains("512 particles x 4096 rays a frame (the paper's street setting"),
        "{}",
        r.text()
    );
    let (every, every_mean) = run("every", &["--every-ray"]);
    assert!(!every.stdout.contains("two-pass"), "{}", every.text());
    eprintln!("translation mean: two-pass {two_mean} m, every ray {every_mean} m");
    assert!(
        two_mean < 0.6 && two_mean < 1.25 * every_mean + 0.02,
        "two-pass {two_mean:.3} m, every ray {every_mean:.3} m"
    );
    let out = f.existing_out("both.txt");
    let r = f.localize(&f.map, &f.seq, &out, &["--every-ray", "--early-reject"]);
    assert!(!r.ok());
    assert!(r.stderr.contains("--every-ray"), "{}", r.text());
    assert_eq!(std::fs::read_to_string(&out).unwrap(), OLD_OUT);
    // A score off its 0-to-1 scale is refused by the option's parser.
    for bad in ["NaN", "5"] {
        let r = f.localize(&f.map, &f.seq, &out, &["--miss-score", bad]);
        assert!(!r.ok());
        assert!(r.stderr.contains("--miss-score"), "{}", r.text());
    }
    assert_eq!(std::fs::read_to_string(&out).unwrap(), OLD_OUT);
}

/// An odometry file with more poses than the folder's frames (a sequence
/// cut from a longer drive wants --odom-first), one in TUM whose stamps
/// are not times.txt's (rows pair with frames by order), and a folder
/// without times.txt are each said in a note; a TUM file with the frames'
/// own stamps is not.
#[test]
fn odometry_that_does_not_fit_the_frames_is_noted() {
    let f = Street::new(6);
    let rows = kitti_rows(&f.seq.join("poses.txt"));
    let times: Vec<f64> = std::fs::read_to_string(f.seq.join("times.txt"))
        .unwrap()
        .lines()
        .map(|l| l.trim().parse().unwrap())
        .collect();
    let tum = |shift: f64| -> String {
        rows.iter()
            .zip(&times)
            .map(|(r, t)| {
                let rot = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
                    r[0], r[1], r[2], r[4], r[5], r[6], r[8], r[9], r[10],
                ));
                let q = nalgebra::UnitQuaternion::from_rotation_matrix(&rot);
                format!(
                    "{} {} {} {} {} {} {} {}\n",
                    t + shift,
                    r[3],
                    r[7],
                    r[11],
                    q.i,
                    q.j,
                    q.k,
                    q.w
                )
            })
            .collect()
    };
    let run = |name: &str, text: String| {
        let odo = f.dir.path().join(name);
        std::fs::write(&odo, text).unwrap();
        let out = f.dir.path().join(format!("{name}.est"));
        let r = f.localize(&f.map, &f.seq, &out, &["--odometry", s(&odo)]);
        assert!(r.ok(), "{}", r.text());
        r.stderr
    };
    let longer = std::fs::read_to_string(f.seq.join("poses.txt"))
        .unwrap()
        .repeat(3);
    let e = run("longer.txt", longer);
    assert!(
        e.contains("has 18 poses for the sequence's 6 frames") && e.contains("--odom-first"),
        "{e}"
    );
    let e = run("same_stamps.tum", tum(0.0));
    assert!(!e.contains("note"), "{e}");
    let e = run("later_stamps.tum", tum(1.3e9));
    assert!(
        e.contains("time stamps are not the frames'") && e.contains("paired with frames in order"),
        "{e}"
    );
    std::fs::remove_file(f.seq.join("times.txt")).unwrap();
    let out = f.dir.path().join("no_times.est");
    let r = f.localize(&f.map, &f.seq, &out, &[]);
    assert!(r.ok() && r.stderr.contains("no times.txt"), "{}", r.text());
}

/// Another street's map (another seed of the simulator, the same layout
/// along the same path): the run goes on, with a warning that the first
/// LiDAR scan does not fit the map, naming it (see
/// `omcl::session::scan_fit`; the right map is checked in
/// `a_short_street_localizes_in_kitti_layout`).
#[test]
fn another_streets_map_is_warned_about_from_the_first_lidar_scan() {
    let f = Street::new(3);
    let other = f.dir.path().join("other");
    let r = omcl(&[
        "sim",
        "outdoor",
        "--out",
        s(&other),
        "--seed",
        "4",
        "--frames",
        "3",
        "--resolution",
        "0.2",
        "--azimuth-steps",
        "512",
    ]);
    assert!(r.ok(), "{}", r.text());
    let out = f.dir.path().join("est.txt");
    let seq = other.join("sequences/00");
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert!(r.ok(), "{}", r.text());
    let warning = r
        .stderr
        .lines()
        .find(|l| l.contains("first LiDAR scan"))
        .unwrap_or_else(|| panic!("no warning:\n{}", r.text()));
    assert!(warning.starts_with("warning: "), "{warning}");
    assert!(warning.contains(s(&f.map)), "{warning}");
    assert!(warning.contains("this sequence's map"), "{warning}");
    // Its share is printed: below the 50 % a map must reach.
    let pct: f64 = warning
        .split(" % of its")
        .next()
        .and_then(|a| a.rsplit(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{warning}"));
    assert!(pct < 50.0, "{warning}");
    // The same street's own map: no warning.
    let r = f.localize(&f.map, &f.seq, &out, &[]);
    assert!(r.ok(), "{}", r.text());
    assert!(!r.stderr.contains("LiDAR scan"), "{}", r.text());
    // A damaged scan skips the check, not the run (the camera never
    // reads it): a note names the file and the problem.
    let scan = seq.join("velodyne/000000.bin");
    let bytes = std::fs::read(&scan).unwrap();
    std::fs::write(&scan, &bytes[..bytes.len() - 1]).unwrap();
    std::fs::remove_file(&out).unwrap();
    let r = f.localize(&f.map, &seq, &out, &[]);
    assert!(r.ok(), "{}", r.text());
    assert!(out.exists());
    assert!(
        r.stderr
            .contains("note: the map was not checked against the first LiDAR scan")
            && r.stderr.contains("000000.bin")
            && r.stderr.contains("not a multiple of 16"),
        "{}",
        r.text()
    );
}
