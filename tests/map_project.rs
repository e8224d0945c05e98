//! `omcl map project`: ground-truth camera-2 label images from the real
//! labelled SemanticKITTI scans in ../shared/data (the paper's GT setting on
//! real sequences), checked against what a street seen from a car's camera
//! must look like, and read back by `omcl localize`'s KITTI reader.

mod common;

use common::shared;

use std::collections::BTreeMap;
use std::path::Path;

use omcl::io::kitti_camera::{CameraInput, KittiCameraSequence};
use omcl::io::rgbd::read_label_png;

fn omcl(args: &[&str]) -> (bool, String) {
    let r = common::omcl(args);
    (r.ok(), r.output())
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let t = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &t);
        } else {
            std::fs::copy(e.path(), &t).unwrap();
        }
    }
}

/// Share of each label among `pixels` (0 = none counted as its own key).
fn shares(pixels: &[u32]) -> BTreeMap<u32, f64> {
    let mut m = BTreeMap::new();
    for &l in pixels {
        *m.entry(l).or_insert(0.0) += 1.0 / pixels.len() as f64;
    }
    m
}

#[test]
fn real_scans_project_into_camera_2_as_a_street() {
    let real = shared("semantickitti/sequences/00");
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("00");
    // The shared folder as it is: the poses of the whole drive (4541) and
    // its first three scans, whose poses are the first three.
    copy_dir(&real, &seq);
    let (ok, text) = omcl(&["map", "project", seq.to_str().unwrap()]);
    assert!(ok, "{text}");
    assert!(text.contains("wrote 3 label images"), "{text}");
    // Every label written is a class the scans carry (static ones: the
    // authors' filter drops unlabeled, outlier and moving points).
    let scan_classes: std::collections::BTreeSet<u32> = (0..3)
        .flat_map(|i| {
            let bytes = std::fs::read(seq.join(format!("labels/{i:06}.label"))).unwrap();
            bytes
                .chunks(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]) & 0xffff)
                .collect::<Vec<_>>()
        })
        .collect();
    let road_like = [40u32, 44, 48, 49, 60, 72];
    for i in 0..3 {
        let (w, h, px) = read_label_png(&seq.join(format!("labels_2/{i:06}.png"))).unwrap();
        assert_eq!((w, h), (1241, 376));
        for &l in &px {
            assert!(
                l == 0 || (scan_classes.contains(&l) && l > 1 && l < 252),
                "label {l}"
            );
        }
        let rows = |a: f64, b: f64| -> Vec<u32> {
            let (r0, r1) = ((a * h as f64) as usize, (b * h as f64) as usize);
            px[r0 * w as usize..r1 * w as usize].to_vec()
        };
        // The bottom quarter is the road ahead of the car: mostly labelled,
        // and mostly ground classes.
        let bottom = shares(&rows(0.75, 1.0));
        let labelled = 1.0 - bottom.get(&0).copied().unwrap_or(0.0);
        let ground: f64 = road_like.iter().filter_map(|l| bottom.get(l)).sum();
        eprintln!("frame {i}: bottom {bottom:?}");
        assert!(labelled > 0.8, "frame {i}: bottom labelled {labelled}");
        assert!(ground > 0.6, "frame {i}: bottom ground share {ground}");
        // The top third is above the HDL-64E's field of view (+2 degrees
        // at most; the image's top third looks 5 to 14 degrees up): almost
        // no point lands there.
        let top = shares(&rows(0.0, 0.33));
        eprintln!("frame {i}: top {top:?}");
        assert!(
            top.get(&0).copied().unwrap_or(0.0) > 0.9,
            "frame {i}: top {top:?}"
        );
        // At the horizon's band, the sides are what stands along a street
        // (buildings, fences, vegetation, trunks, poles, signs, parked
        // cars), not ground.
        for (side, u0, u1) in [("left", 0, w / 4), ("right", 3 * w / 4, w)] {
            let band: Vec<u32> = (h as usize * 2 / 5..h as usize / 2)
                .flat_map(|v| (u0..u1).map(move |u| (v, u)))
                .map(|(v, u)| px[v * w as usize + u as usize])
                .collect();
            let s = shares(&band);
            eprintln!("frame {i}: {side} {s:?}");
            let upright: f64 = [10u32, 50, 51, 52, 70, 71, 80, 81, 99]
                .iter()
                .filter_map(|l| s.get(l))
                .sum();
            let ground: f64 = road_like.iter().filter_map(|l| s.get(l)).sum();
            assert!(
                upright > 0.5 && upright > 2.0 * ground,
                "frame {i} {side}: {s:?}"
            );
        }
    }
    // The folder now opens for `omcl localize` with label images, and the
    // built-in class table was written beside them.
    let k = KittiCameraSequence::open(&seq, CameraInput::Labels).unwrap();
    assert_eq!(k.len(), 3);
    assert!(seq.join("classes.txt").exists() && seq.join("embeddings.npy").exists());
    // The real GT setting end to end: the scans' map, camera 2 localized
    // in it from its label images (three frames from the paper's start).
    let map = dir.path().join("00.omcl");
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        seq.to_str().unwrap(),
        "--classes",
        "semantickitti",
        "--resolution",
        "0.2",
        "-o",
        map.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let est = dir.path().join("est.txt");
    let (ok, text) = omcl(&[
        "localize",
        "--map",
        map.to_str().unwrap(),
        "--sequence",
        seq.to_str().unwrap(),
        "-o",
        est.to_str().unwrap(),
        "--particles",
        "256",
        "--rays",
        "1024",
    ]);
    assert!(ok, "{text}");
    let mean: f64 = text
        .split("translation error mean ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{text}"));
    assert!(mean < 0.3, "{text}");
    // A second run refuses to overwrite; --force replaces.
    let (ok, text) = omcl(&["map", "project", seq.to_str().unwrap()]);
    assert!(!ok && text.contains("--force"), "{text}");
    // Never into a folder the sequence is read from, --force or not (the
    // scans' labels here; camera images alike).
    let labels = seq.join("labels");
    let before = std::fs::read(labels.join("000000.label")).unwrap();
    for out in [labels.clone(), seq.clone()] {
        let (ok, text) = omcl(&[
            "map",
            "project",
            seq.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--force",
        ]);
        assert!(!ok && text.contains("is read from"), "{text}");
    }
    assert_eq!(std::fs::read(labels.join("000000.label")).unwrap(), before);
    assert!(!labels.join("000000.png").exists());
    let (ok, text) = omcl(&["map", "project", seq.to_str().unwrap(), "--force"]);
    assert!(ok, "{text}");
}

#[test]
fn bad_sequences_are_refused_by_name_with_nothing_written() {
    let real = shared("semantickitti/sequences/00");
    let dir = tempfile::tempdir().unwrap();
    // calib.txt without P2.
    let seq = dir.path().join("nop2");
    copy_dir(&real, &seq);
    let calib = std::fs::read_to_string(seq.join("calib.txt")).unwrap();
    let kept: String = calib
        .lines()
        .filter(|l| !l.starts_with("P2"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(seq.join("calib.txt"), kept).unwrap();
    let (ok, text) = omcl(&["map", "project", seq.to_str().unwrap()]);
    assert!(
        !ok && text.contains("calib.txt") && text.contains("P2"),
        "{text}"
    );
    // Not a sequence at all.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let (ok, text) = omcl(&["map", "project", empty.to_str().unwrap()]);
    assert!(!ok && text.contains("empty"), "{text}");
    assert!(!empty.join("labels_2").exists());
    // A scan cut short, found while reading: the folders this run made
    // for -o (two new levels) go with the failure.
    let cut = dir.path().join("cut");
    copy_dir(&real, &cut);
    let scan = cut.join("velodyne/000001.bin");
    let bytes = std::fs::read(&scan).unwrap();
    std::fs::write(&scan, &bytes[..bytes.len() / 2 + 3]).unwrap();
    let new = dir.path().join("new");
    let out = new.join("sub/labels_2");
    let (ok, text) = omcl(&[
        "map",
        "project",
        cut.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!ok && text.contains("000001.bin"), "{text}");
    assert!(!new.exists(), "{text}");
}

#[test]
fn project_writes_only_where_asked_and_never_into_read_only_folders() {
    use std::os::unix::fs::PermissionsExt;
    let real = shared("semantickitti/sequences/00");
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("00");
    copy_dir(&real, &seq);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let untouched = |what: &str| {
        for f in ["labels_2", "classes.txt", "embeddings.npy"] {
            assert!(!seq.join(f).exists(), "{what}: {f} written");
        }
    };
    // A folder marked read-only (the shared data's mode) is left alone,
    // even by root, whom the permissions do not stop.
    std::fs::set_permissions(&seq, std::fs::Permissions::from_mode(0o555)).unwrap();
    let (ok, text) = omcl(&["map", "project", &s(&seq)]);
    std::fs::set_permissions(&seq, std::fs::Permissions::from_mode(0o755)).unwrap();
    assert!(
        !ok && text.contains("read-only") && text.contains("555"),
        "{text}"
    );
    untouched("read-only");
    // -o elsewhere: the images and the class table there, nothing in the
    // sequence.
    let other = dir.path().join("work");
    let (ok, text) = omcl(&[
        "map",
        "project",
        &s(&seq),
        "-o",
        &s(&other.join("labels_2")),
    ]);
    assert!(ok, "{text}");
    untouched("-o elsewhere");
    assert!(other.join("labels_2/000002.png").exists());
    assert!(other.join("classes.txt").exists() && other.join("embeddings.npy").exists());
    // The copy opens as the sequence: its calibration, poses and times are
    // links to the sequence's.
    assert!(
        text.contains("linked calib.txt, poses.txt, times.txt, velodyne"),
        "{text}"
    );
    assert!(other.join("velodyne/000000.bin").is_file());
    for f in ["calib.txt", "poses.txt", "times.txt"] {
        assert_eq!(
            std::fs::read(other.join(f)).unwrap(),
            std::fs::read(seq.join(f)).unwrap(),
            "{f}"
        );
    }
    let k = KittiCameraSequence::open(&other, CameraInput::Labels).unwrap();
    assert_eq!(k.len(), 3);
    // A failure leaves no empty label folder behind (localize would then
    // say "no frames" instead of the cause).
    std::fs::remove_file(seq.join("labels/000001.label")).unwrap();
    let (ok, text) = omcl(&["map", "project", &s(&seq)]);
    assert!(!ok && text.contains("000001.label"), "{text}");
    untouched("a missing label file");
    copy_dir(&real.join("labels"), &seq.join("labels"));
    // Camera images of another size than KITTI 00's (sequences 04-10):
    // label images of that size.
    std::fs::create_dir(seq.join("image_2")).unwrap();
    image::RgbImage::new(1226, 370)
        .save(seq.join("image_2/000000.png"))
        .unwrap();
    let (ok, text) = omcl(&["map", "project", &s(&seq), "--frames", "1"]);
    assert!(ok, "{text}");
    let (w, h, _) = read_label_png(&seq.join("labels_2/000000.png")).unwrap();
    assert_eq!((w, h), (1226, 370));
    // `map cloud` does not write its map over a file the sequence is read
    // from.
    let poses = std::fs::read(seq.join("poses.txt")).unwrap();
    for out in ["poses.txt", "calib.txt", "velodyne/000003.bin"] {
        let (ok, text) = omcl(&[
            "map",
            "cloud",
            &s(&seq),
            "--classes",
            "semantickitti",
            "-o",
            &s(&seq.join(out)),
        ]);
        assert!(!ok && text.contains(out), "{out}: {text}");
    }
    assert_eq!(std::fs::read(seq.join("poses.txt")).unwrap(), poses);
    assert!(!seq.join("velodyne/000003.bin").exists());
}

/// Ctrl-C (SIGINT) while `map project` writes its label images: the
/// folder it made goes, images and all, and omcl ends as SIGINT ends a
/// program (a shell loop around it stops), so that the rerun starts clean
/// instead of finding a half-filled folder.
#[test]
fn an_interrupted_projection_leaves_no_half_filled_folder() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("street");
    let r = common::omcl(&[
        "sim",
        "outdoor",
        "--out",
        root.to_str().unwrap(),
        "--frames",
        "120",
        "--resolution",
        "0.4",
        "--azimuth-steps",
        "256",
    ]);
    assert!(r.ok(), "{}", r.text());
    let seq = root.join("sequences/00");
    let out = dir.path().join("work/labels_2");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(["map", "project", seq.to_str().unwrap(), "-o"])
        .arg(&out)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Interrupted once the first images are there.
    let t0 = std::time::Instant::now();
    while !out.join("000001.png").exists() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "ended before it wrote a second image"
        );
        assert!(t0.elapsed().as_secs() < 120, "no image in 120 s");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let kill = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(o.status.signal(), Some(2), "{:?}: {stderr}", o.status);
    assert!(!stderr.contains("error"), "{stderr}");
    assert!(!out.exists(), "{} left behind", out.display());
    // The folder above it, made by the run too (-o work/labels_2), stays
    // on an interrupt (another run may be writing into it), empty.
    let left: Vec<_> = std::fs::read_dir(dir.path().join("work"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(left.is_empty(), "{left:?}");
    // Started with SIGINT ignored (`omcl ... &` in a script, here a
    // shell's trap), omcl keeps it ignored and runs to the end.
    let script = format!(
        "trap '' INT; exec '{}' map project '{}' -o '{}'",
        env!("CARGO_BIN_EXE_omcl"),
        seq.display(),
        out.display()
    );
    let mut child = std::process::Command::new("sh")
        .args(["-c", &script])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    while !out.join("000001.png").exists() && child.try_wait().unwrap().is_none() {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let _ = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    let o = child.wait_with_output().unwrap();
    assert!(
        o.status.success(),
        "{:?}: {}",
        o.status,
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(out.join("000119.png").exists());
}
