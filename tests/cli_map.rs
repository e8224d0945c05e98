//! The `omcl` binary on map files: info on a good map, clear errors and a
//! non-zero exit on bad ones.

mod common;

use std::path::Path;

use nalgebra::Vector3;
use omcl::map::{self, FeatureDb, GridSpec, LanguageMap};

fn omcl(args: &[&str]) -> (bool, String, String) {
    let r = common::omcl(args);
    (r.ok(), r.stdout, r.stderr)
}

fn write_map(path: &Path) -> LanguageMap {
    let db = FeatureDb::from_rows(2, 0.05, vec![1.0, 0.0, 0.0, 1.0, 0.6, 0.8]).unwrap();
    let grid = GridSpec {
        resolution: 0.25,
        origin: Vector3::new(10.0, -2.0, 0.5),
    };
    let leaves = (0..40).map(|i| ([i % 4, i / 4, 0], (i % 2) as u32));
    let m = LanguageMap::from_cells(grid, db, "unit-test", leaves).unwrap();
    map::save(&m, path).unwrap();
    m
}

#[test]
fn info_prints_header_and_statistics() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.omcl");
    write_map(&p);
    let (ok, out, err) = omcl(&["map", "info", p.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(out.contains("unit-test"), "{out}");
    assert!(out.contains("40 voxels"), "{out}");
    assert!(out.contains("3 rows x 2 dims"), "{out}");
    // Bounds: origin + cells 0..3 / 0..9 at 0.25 m.
    assert!(out.contains("[10.00, 11.00] x [-2.00, 0.50]"), "{out}");
    assert!(out.contains("1 unused"), "{out}");

    let (ok, json, _) = omcl(&["map", "info", p.to_str().unwrap(), "--json"]);
    assert!(ok);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["leaves"], 40);
    assert_eq!(v["rows"], 3);
    assert_eq!(v["resolution_m"], 0.25);

    // --scene builds the ray-casting scene and says how long it took; the
    // JSON on stdout stays one document.
    let (ok, json, err) = omcl(&["map", "info", p.to_str().unwrap(), "--json", "--scene"]);
    assert!(ok, "{err}");
    assert!(
        serde_json::from_str::<serde_json::Value>(&json).is_ok(),
        "{json}"
    );
    assert!(
        err.contains("Embree scene built in") && err.contains("(40 voxels)"),
        "{err}"
    );
}

#[test]
fn corrupt_truncated_and_foreign_files_fail_with_the_file_named() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.omcl");
    write_map(&p);
    let bytes = std::fs::read(&p).unwrap();

    let corrupt = dir.path().join("corrupt.omcl");
    let mut b = bytes.clone();
    let n = b.len();
    b[n - 3] ^= 0xff;
    std::fs::write(&corrupt, &b).unwrap();

    let truncated = dir.path().join("truncated.omcl");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();

    let foreign = dir.path().join("cloud.ply");
    std::fs::write(&foreign, "ply\nformat ascii 1.0\nend_header\n").unwrap();

    for (file, what) in [
        (&corrupt, "checksum"),
        (&truncated, "not a safetensors file"),
        (&foreign, "not an omcl map"),
    ] {
        let (ok, _, err) = omcl(&["map", "info", file.to_str().unwrap()]);
        assert!(!ok, "{} should fail", file.display());
        assert!(err.contains(file.to_str().unwrap()), "{err}");
        assert!(err.contains(what), "{err}");
    }
    let (ok, _, err) = omcl(&["map", "info", "/nonexistent/x.omcl"]);
    assert!(!ok && err.contains("/nonexistent/x.omcl"), "{err}");
}

/// `omcl map floorplan`: a hand-made room (a floor layer, a wall column up
/// to 3 m, a ceiling) projects to the wall's cells only (the default band,
/// 0.10 to 2.00 m above the floor, leaves floor and ceiling out), with the
/// wall's feature; the plan file reads back and the PNG has one pixel a
/// cell; a file that is not a map is refused by name with nothing written.
#[test]
fn floorplan_projects_the_band_and_refuses_a_non_map() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("room.omcl");
    // Rows: floor (1, 0, 0), wall (0, 1, 0), ceiling (0, 0, 1).
    let db =
        FeatureDb::from_rows(3, 0.0, vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]).unwrap();
    let grid = GridSpec {
        resolution: 0.1,
        origin: Vector3::new(0.0, 0.0, 0.0),
    };
    let mut leaves = Vec::new();
    for i in 0..6 {
        for j in 0..4 {
            leaves.push(([i, j, 0], 0u32)); // floor, z in [0, 0.1)
            leaves.push(([i, j, 29], 2u32)); // ceiling, z in [2.9, 3.0)
        }
    }
    for j in 0..4 {
        for k in 1..29 {
            leaves.push(([4, j, k], 1u32)); // wall at x in [0.4, 0.5)
        }
    }
    let m = LanguageMap::from_cells(grid, db, "unit-test", leaves).unwrap();
    map::save(&m, &p).unwrap();
    let plan = dir.path().join("room.plan");
    let png = dir.path().join("room.png");
    let (ok, out, err) = omcl(&[
        "map",
        "floorplan",
        p.to_str().unwrap(),
        "-o",
        plan.to_str().unwrap(),
        "--png",
        png.to_str().unwrap(),
    ]);
    assert!(ok, "{out}{err}");
    let f = omcl::map::floorplan::load(&plan).unwrap();
    assert_eq!(f.len(), 4, "{:?}", f.cells());
    for c in f.cells() {
        let x = f.origin[0] + (c[0] as f64 + 0.5) * f.resolution;
        assert!((x - 0.45).abs() < 1e-9, "cell {c:?} at x = {x}");
    }
    for &r in f.rows() {
        let feat = f.db().row(r as usize);
        assert!(feat[1] > 0.999 && feat[0].abs() < 1e-6, "{feat:?}");
    }
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (1, 4));

    let bad_plan = dir.path().join("bad.plan");
    let not_a_map = dir.path().join("cloud.ply");
    std::fs::write(&not_a_map, "ply\nformat ascii 1.0\nend_header\n").unwrap();
    let (ok, _, err) = omcl(&[
        "map",
        "floorplan",
        not_a_map.to_str().unwrap(),
        "-o",
        bad_plan.to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("cloud.ply"), "{err}");
    assert!(!bad_plan.exists());
}

/// Every map command that writes a file refuses to write it over the map
/// it reads, through whatever path names it (here `sub/../m.omcl`), and
/// `floorplan` its PNG over its plan: exit 1, both named, the map intact
/// byte for byte. `floorplan -o m.omcl` once replaced the map by its plan.
#[test]
fn map_commands_refuse_to_write_over_their_map() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.omcl");
    write_map(&p);
    let before = std::fs::read(&p).unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let same = dir.path().join("sub/../m.omcl");
    let (map, same) = (p.to_str().unwrap(), same.to_str().unwrap());
    for args in [
        vec!["map", "floorplan", map, "-o", same],
        vec!["map", "export", map, "-o", same],
        vec!["map", "query", map, "wall", "-o", same],
        vec!["map", "ground", map, "wall", "-o", same],
        vec!["map", "upgrade", map, "-o", same],
        vec!["map", "cloud", map, "-o", same],
    ] {
        let (ok, out, err) = omcl(&args);
        assert!(!ok, "{args:?} wrote over its map: {out}");
        assert!(
            err.contains("--out is") && err.contains("m.omcl") && err.contains("replace"),
            "{args:?}: {err}"
        );
        assert_eq!(
            std::fs::read(&p).unwrap(),
            before,
            "{args:?} changed the map"
        );
    }
    let plan = dir.path().join("m.plan");
    let (ok, _, err) = omcl(&[
        "map",
        "floorplan",
        map,
        "-o",
        plan.to_str().unwrap(),
        "--png",
        plan.to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("--png and --out"), "{err}");
    assert!(!plan.exists());
}

/// `map floorplan` (its plan and its PNG), `map ground` and `map upgrade`
/// never replace a file they did not write as such without `--force`: a
/// photo, a depth frame, notes, a map under a plan's name or a plan under
/// a map's; nor name a plan or a map as data (`-o notes.txt`). Their own
/// earlier outputs and empty files are replaced; `--force` replaces the
/// rest. All three once wrote over anything they were given.
#[test]
fn map_outputs_replace_only_their_own_kind() {
    let dir = tempfile::tempdir().unwrap();
    let path = |n: &str| dir.path().join(n);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let map = path("m.omcl");
    write_map(&map);
    // A real depth frame, a photo-like PNG omcl did not write.
    let photo = path("photo.png");
    std::fs::copy(
        common::shared("rgbd_7scenes/frame-000000.depth.png"),
        &photo,
    )
    .unwrap();
    let notes = path("notes.plan");
    std::fs::write(&notes, "my notes\n").unwrap();
    let other_map = path("other.omcl");
    write_map(&other_map);
    let refused = |args: Vec<String>, kept: &Path, words: &str| {
        let before = std::fs::read(kept).unwrap();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (ok, out, err) = omcl(&args);
        assert!(!ok, "{args:?}: {out}");
        assert!(err.contains(words), "{args:?}: {err}");
        assert_eq!(std::fs::read(kept).unwrap(), before, "{args:?}");
    };
    let floorplan = |extra: &[&Path]| {
        let mut v = vec!["map".to_string(), "floorplan".into(), s(&map), "-o".into()];
        v.extend(extra.iter().map(|p| s(p)));
        v
    };
    let plan = path("m.plan");
    refused(
        floorplan(&[&notes]),
        &notes,
        "is not an omcl floor plan; pass --force",
    );
    refused(
        floorplan(&[&other_map]),
        &other_map,
        "is not an omcl floor plan",
    );
    let mut with_png = floorplan(&[&plan]);
    with_png.extend(["--png".into(), s(&photo)]);
    refused(
        with_png.clone(),
        &photo,
        "--png exists and is not a figure omcl drew",
    );
    // A simulated depth frame (marked as written by omcl) is data, not a
    // picture: refused as a photo is.
    let frame = path("000003.png");
    omcl::sim::files::write_png_gray16(&frame, 4, 3, &[1000; 12]).unwrap();
    let mut over_frame = floorplan(&[&plan]);
    over_frame.extend(["--png".into(), s(&frame)]);
    refused(
        over_frame,
        &frame,
        "--png exists and is not a figure omcl drew",
    );
    assert!(
        !plan.exists(),
        "the plan was written before the PNG was refused"
    );
    let txt = path("plan.txt");
    let (ok, _, err) = omcl(&["map", "floorplan", &s(&map), "-o", &s(&txt)]);
    assert!(
        !ok && err.contains("a floor plan is not a .txt") && !txt.exists(),
        "{err}"
    );
    // Its own outputs, twice: replaced.
    let own_png = path("own.png");
    for _ in 0..2 {
        let (ok, out, err) = omcl(&[
            "map",
            "floorplan",
            &s(&map),
            "-o",
            &s(&plan),
            "--png",
            &s(&own_png),
        ]);
        assert!(ok, "{out}{err}");
    }
    // `map ground` and `map upgrade`: a plan or notes are not maps.
    for cmd in [
        vec!["map", "ground", &s(&map), "wall", "--classes", "asprs"],
        vec!["map", "upgrade", &s(&map)],
    ] {
        let args: Vec<String> = cmd.iter().map(|a| a.to_string()).collect();
        let mut over_plan = args.clone();
        over_plan.extend(["-o".into(), s(&plan)]);
        refused(over_plan, &plan, "is not an omcl map; pass --force");
    }
    // --force replaces a foreign file.
    with_png.push("--force".into());
    let args: Vec<&str> = with_png.iter().map(String::as_str).collect();
    let (ok, out, err) = omcl(&args);
    assert!(ok, "{out}{err}");
    assert!(omcl::plot::is_omcl_figure(&photo));
}
