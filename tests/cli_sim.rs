//! `omcl sim` writes a whole sequence into its `--out` folder: it must
//! never mix its frames with, or write them over, a folder that holds
//! something else (a real sequence), and replacing an earlier simulation
//! (`--force`) must leave no frame of the earlier run behind.

mod common;

use common::{Run, omcl};

use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// `omcl sim indoor` of `frames` small frames into `out`, with `extra`.
fn sim_indoor(out: &Path, frames: usize, extra: &[&str]) -> Run {
    let n = frames.to_string();
    let mut args = vec![
        "sim",
        "indoor",
        "--out",
        s(out),
        "--seed",
        "2",
        "--rooms",
        "2",
        "--frames",
        &n,
        "--width",
        "64",
        "--height",
        "48",
        "--trajectories",
        "none",
    ];
    args.extend_from_slice(extra);
    omcl(&args)
}

fn refused(r: &Run, needles: &[&str]) {
    assert_eq!(r.code, Some(1), "{}", r.text());
    for n in needles {
        assert!(r.stderr.contains(n), "{n:?} missing:\n{}", r.text());
    }
    assert!(!r.stderr.contains("panicked"), "{}", r.text());
}

fn count(dir: &Path) -> usize {
    std::fs::read_dir(dir).unwrap().count()
}

#[test]
fn a_folder_of_other_files_is_refused_with_or_without_force_and_left_intact() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("recorded");
    std::fs::create_dir_all(seq.join("labels")).unwrap();
    std::fs::write(seq.join("poses.txt"), b"0 0 0 0 0 0 0 1\n").unwrap();
    std::fs::write(seq.join("labels/000000.png"), b"not really a png").unwrap();
    for extra in [&[][..], &["--force"][..]] {
        let r = sim_indoor(&seq, 4, extra);
        refused(&r, &[s(&seq), "no earlier simulation", "poses.txt"]);
    }
    assert_eq!(
        std::fs::read(seq.join("poses.txt")).unwrap(),
        b"0 0 0 0 0 0 0 1\n"
    );
    assert_eq!(
        std::fs::read(seq.join("labels/000000.png")).unwrap(),
        b"not really a png"
    );
    assert_eq!(count(&seq), 2, "nothing was added");
    assert_eq!(count(&seq.join("labels")), 1);

    // A sim.json omcl's simulator did not write (empty, the user's own
    // JSON, another program's) does not make the folder a simulation's:
    // --force must not remove the folder's files.
    let mine = dir.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("poses.txt"), b"my ground truth\n").unwrap();
    for mark in [
        &b""[..],
        b"{}",
        br#"{"generator": "my recorder", "config": {}}"#,
    ] {
        std::fs::write(mine.join("sim.json"), mark).unwrap();
        let r = sim_indoor(&mine, 2, &["--force"]);
        refused(
            &r,
            &[s(&mine), "not one omcl's simulator wrote", "poses.txt"],
        );
        assert_eq!(
            std::fs::read(mine.join("poses.txt")).unwrap(),
            b"my ground truth\n"
        );
        assert_eq!(std::fs::read(mine.join("sim.json")).unwrap(), mark);
        assert_eq!(count(&mine), 2, "nothing was added");
    }

    // A file where the folder should be.
    let file = dir.path().join("file");
    std::fs::write(&file, b"x").unwrap();
    refused(&sim_indoor(&file, 4, &[]), &[s(&file), "is a file"]);
    assert_eq!(std::fs::read(&file).unwrap(), b"x");
}

#[test]
fn an_earlier_simulation_is_replaced_only_with_force_and_whole() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("sim");
    // An empty folder that exists is fine.
    std::fs::create_dir(&seq).unwrap();
    let r = sim_indoor(&seq, 8, &[]);
    assert_eq!(r.code, Some(0), "{}", r.text());
    assert_eq!(count(&seq.join("labels")), 8);
    let poses = std::fs::read(seq.join("poses.txt")).unwrap();

    let r = sim_indoor(&seq, 4, &[]);
    refused(&r, &[s(&seq), "earlier simulation", "--force"]);
    assert_eq!(std::fs::read(seq.join("poses.txt")).unwrap(), poses);
    assert_eq!(count(&seq.join("labels")), 8);

    // A run that fails midway (the field of view is checked as the world
    // is made) leaves the earlier simulation whole and no staging folder.
    let r = sim_indoor(&seq, 4, &["--force", "--hfov", "200"]);
    refused(&r, &["fov"]);
    assert_eq!(std::fs::read(seq.join("poses.txt")).unwrap(), poses);
    assert_eq!(count(&seq.join("labels")), 8);
    assert!(seq.join("sim.json").is_file());
    assert_eq!(count(dir.path()), 1, "only the simulation's folder");

    // The simulation's mark is a dataset file: no estimate or metrics
    // replace it without --force.
    let r = omcl(&[
        "eval",
        "ape",
        s(&seq.join("poses.txt")),
        s(&seq.join("poses.txt")),
        "--json",
        s(&seq.join("sim.json")),
    ]);
    refused(&r, &["sim.json", "dataset's file"]);
    assert!(
        std::fs::read_to_string(seq.join("sim.json"))
            .unwrap()
            .contains("omcl sim indoor")
    );

    // Replaced: four frames, and none of the earlier eight left over.
    let r = sim_indoor(&seq, 4, &["--force"]);
    assert_eq!(r.code, Some(0), "{}", r.text());
    for sub in ["labels", "depth", "rgb"] {
        assert_eq!(count(&seq.join(sub)), 4, "{sub}");
    }
    let lines = std::fs::read_to_string(seq.join("poses.txt")).unwrap();
    assert_eq!(lines.lines().filter(|l| !l.starts_with('#')).count(), 4);
    assert_eq!(count(dir.path()), 1, "the staging folder is gone");
    assert!(
        r.stdout.contains(s(&seq)),
        "the summary names --out:\n{}",
        r.text()
    );
    // A new folder under folders that do not exist yet.
    let deep = dir.path().join("a/b/sim");
    let r = sim_indoor(&deep, 2, &[]);
    assert_eq!(r.code, Some(0), "{}", r.text());
    assert_eq!(count(&deep.join("labels")), 2);
    assert_eq!(count(&dir.path().join("a/b")), 1);

    // A poses.txt shorter than the frames is refused by `map rgbd`, not
    // mapped in part without a word; --frames asks for part.
    let poses = std::fs::read_to_string(deep.join("poses.txt")).unwrap();
    let first: Vec<&str> = poses.lines().filter(|l| !l.starts_with('#')).collect();
    std::fs::write(deep.join("poses.txt"), format!("{}\n", first[0])).unwrap();
    let m = dir.path().join("short.omcl");
    let r = omcl(&["map", "rgbd", s(&deep), "-o", s(&m)]);
    refused(&r, &["poses.txt", "1 poses but 2 depth images", "--frames"]);
    assert!(!m.exists());
    let r = omcl(&["map", "rgbd", s(&deep), "-o", s(&m), "--frames", "1"]);
    assert_eq!(r.code, Some(0), "{}", r.text());
    // A depth image missing among them is named, not counted.
    std::fs::write(deep.join("poses.txt"), poses.clone()).unwrap();
    std::fs::rename(deep.join("depth/000000.png"), deep.join("000000.png")).unwrap();
    let r = omcl(&["map", "rgbd", s(&deep), "-o", s(&m), "--force"]);
    refused(
        &r,
        &["depth/000000.png: missing", "2 poses and 1 depth images"],
    );
    // And the replaced sequence maps.
    let map = dir.path().join("m.omcl");
    let r = omcl(&["map", "rgbd", s(&seq), "-o", s(&map)]);
    assert_eq!(r.code, Some(0), "{}", r.text());
}

#[test]
fn a_class_table_is_replaced_only_with_force() {
    let dir = tempfile::tempdir().unwrap();
    let clip = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/clip_text");
    assert!(
        Path::new(clip).is_dir(),
        "{clip}: the shared data is missing"
    );
    let classes = dir.path().join("classes.txt");
    std::fs::write(&classes, b"0 wall\n").unwrap();
    let r = omcl(&["sim", "classes", "--clip-dir", clip, "--out", s(dir.path())]);
    refused(&r, &[s(&classes), "--force"]);
    assert_eq!(std::fs::read(&classes).unwrap(), b"0 wall\n");
    assert!(!dir.path().join("embeddings.npy").exists());

    let r = omcl(&[
        "sim",
        "classes",
        "--clip-dir",
        clip,
        "--out",
        s(dir.path()),
        "--force",
    ]);
    assert_eq!(r.code, Some(0), "{}", r.text());
    assert!(std::fs::read_to_string(&classes).unwrap().lines().count() > 1);
    assert!(dir.path().join("embeddings.npy").is_file());
}
