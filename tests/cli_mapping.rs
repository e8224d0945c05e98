//! `omcl map cloud|ground|query|export` end to end on real data recorded by
//! others (SemanticKITTI scans, aerial LAS) and on bad input.

mod common;

use common::shared;

use std::path::{Path, PathBuf};

use omcl::io::{labels, npy, ply};
use omcl::map;

fn omcl(args: &[&str]) -> (bool, String) {
    let r = common::omcl(args);
    (r.ok(), r.output())
}

/// A class table of `ids` with orthogonal one-hot features (dimension = count).
fn one_hot_table(dir: &Path, ids: &[(u32, &str)]) -> (PathBuf, PathBuf) {
    let classes = dir.join("classes.txt");
    let text: String = ids.iter().map(|(i, n)| format!("{i} {n}\n")).collect();
    std::fs::write(&classes, text).unwrap();
    let k = ids.len();
    let data: Vec<f32> = (0..k * k)
        .map(|i| if i / k == i % k { 1.0 } else { 0.0 })
        .collect();
    let emb = dir.join("embeddings.npy");
    npy::write_npy(&emb, &[k, k], &data).unwrap();
    (classes, emb)
}

#[test]
fn semantickitti_scans_map_into_one_consistent_world_frame() {
    let seq = shared("semantickitti/sequences/00");
    let dir = tempfile::tempdir().unwrap();
    let ids: Vec<(u32, &str)> = labels::SEMANTIC_KITTI_CLASSES
        .iter()
        .map(|&(id, name)| (id, name))
        .collect();
    let (classes, emb) = one_hot_table(dir.path(), &ids);
    let out = dir.path().join("kitti.omcl");
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        seq.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--resolution",
        "0.2",
        "--classes",
        classes.to_str().unwrap(),
        "--embeddings",
        emb.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let m = map::load(&out).unwrap();
    assert!(m.len() > 50_000, "{} voxels", m.len());
    // A building point of scan 2, taken to the world frame with the scan's
    // own pose, lands in a mapped voxel whose row is "building".
    let s = omcl::io::kitti::KittiSequence::open(&seq).unwrap();
    let scan = s.load_scan(2).unwrap();
    let labels = scan.labels.as_ref().unwrap();
    let building = ids.iter().position(|&(i, _)| i == 50).unwrap();
    let (mut found, mut right, mut total) = (0, 0, 0);
    for (p, &l) in scan.points.iter().zip(labels) {
        if l != 50 {
            continue;
        }
        total += 1;
        if let Some(leaf) = m.find_point(&nalgebra::Vector3::from(*p)) {
            found += 1;
            let row = m.db().row(m.rows()[leaf] as usize);
            right += (row[building] > 0.5) as usize;
        }
    }
    assert!(total > 1000);
    assert!(
        found * 100 >= total * 99,
        "{found} of {total} building points in mapped voxels"
    );
    assert!(
        right * 100 >= found * 80,
        "{right} of {found} in building voxels"
    );
}

#[test]
fn aerial_las_converts_and_grounds_queries_and_exports() {
    let las = shared("las/autzen_trim.laz");
    let dir = tempfile::tempdir().unwrap();
    let (classes, emb) = one_hot_table(dir.path(), &[(1, "unclassified"), (2, "ground")]);
    let (c, e) = (classes.to_str().unwrap(), emb.to_str().unwrap());
    let out = dir.path().join("autzen.omcl");
    let o = out.to_str().unwrap();
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        las.to_str().unwrap(),
        "-o",
        o,
        "--resolution",
        "1.0",
        "--classes",
        c,
        "--embeddings",
        e,
    ]);
    assert!(ok, "{text}");
    let m = map::load(&out).unwrap();
    // Two classes, plus means of voxels that hold both.
    assert!(m.db().len() >= 2, "{}", m.db().len());
    // UTM coordinates: the origin is snapped near the data, not at zero.
    assert!(m.grid().origin.x.abs() > 1e5, "{}", m.grid().origin);

    let grounded = dir.path().join("ground.omcl");
    let (ok, text) = omcl(&[
        "map",
        "ground",
        o,
        "ground",
        "--classes",
        c,
        "--embeddings",
        e,
        "--min-similarity",
        "0.9",
        "-o",
        grounded.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let g = map::load(&grounded).unwrap();
    assert_eq!(g.db().len(), 1);
    // Kept: exactly the voxels at least 0.9 similar to "ground" (one-hot [0, 1]).
    let sim = m.similarity(&[0.0, 1.0]).unwrap();
    assert_eq!(g.len(), sim.iter().filter(|&&s| s >= 0.9).count());
    assert!(g.len() < m.len() && !g.is_empty());

    let heat = dir.path().join("heat.ply");
    let (ok, text) = omcl(&[
        "map",
        "query",
        o,
        "ground",
        "--classes",
        c,
        "--embeddings",
        e,
        "-o",
        heat.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let h = ply::read_ply(&heat).unwrap();
    assert_eq!(h.len(), m.len());
    // Pure ground voxels are hot (red), pure unclassified ones cold (blue).
    let cols = h.colors.unwrap();
    for (c, s) in cols.iter().zip(&sim) {
        if *s > 0.999 {
            assert!(c[0] > 200 && c[2] < 60, "{c:?}");
        } else if *s < 0.001 {
            assert!(c[2] > c[0], "{c:?}");
        }
    }

    let export = dir.path().join("rows.ply");
    let (ok, text) = omcl(&["map", "export", o, "-o", export.to_str().unwrap()]);
    assert!(ok, "{text}");
    assert_eq!(ply::read_ply(&export).unwrap().len(), m.len());

    let (ok, text) = omcl(&[
        "map",
        "ground",
        o,
        "river",
        "--classes",
        c,
        "--embeddings",
        e,
        "-o",
        grounded.to_str().unwrap(),
    ]);
    assert!(
        !ok && text.contains("\"river\"") && text.contains("classes.txt"),
        "{text}"
    );
}

#[test]
fn las_noise_classes_are_dropped_unless_asked_to_keep() {
    // 32-1-472-150-76.laz holds classes 1, 2, 7 (noise) and 9.
    let las = shared("las/32-1-472-150-76.laz");
    let dir = tempfile::tempdir().unwrap();
    let (classes, emb) = one_hot_table(
        dir.path(),
        &[
            (1, "unclassified"),
            (2, "ground"),
            (7, "noise"),
            (9, "water"),
        ],
    );
    let run = |extra: &[&str]| {
        let out = dir.path().join("n.omcl");
        let mut args = vec![
            "map",
            "cloud",
            las.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--resolution",
            "0.5",
            "--classes",
            classes.to_str().unwrap(),
            "--embeddings",
            emb.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let (ok, text) = omcl(&args);
        assert!(ok, "{text}");
        let m = map::load(&out).unwrap();
        m.similarity(&[0.0, 0.0, 1.0, 0.0])
            .unwrap()
            .iter()
            .filter(|&&s| s > 0.5)
            .count()
    };
    assert_eq!(run(&[]), 0, "noise voxels must be dropped by default");
    assert!(run(&["--keep-all"]) > 0, "--keep-all keeps the noise class");
}

#[test]
fn scannet_scan_converts_through_a_point_encoder() {
    let bin = shared("pointclouds/scannet_scene0000_00_xyzrgb.bin");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scannet.omcl");
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/encode/tiny_point.onnx");
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        bin.to_str().unwrap(),
        "--format",
        "scannet",
        "--point-model",
        model.to_str().unwrap(),
        "--resolution",
        "0.05",
        "--tau",
        "0.01",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let m = map::load(&out).unwrap();
    assert_eq!(m.encoder(), "tiny_point");
    assert_eq!(m.db().dim(), 5);
    // 40,684 points at 5 cm: fewer voxels than points, but thousands.
    assert!(m.len() > 5_000 && m.len() < 40_684, "{}", m.len());
    assert!(m.db().len() > 1);
    // Without labels, features or an encoder: a clear error.
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        bin.to_str().unwrap(),
        "--format",
        "scannet",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(
        !ok && text.contains("neither features nor labels"),
        "{text}"
    );
}

#[test]
fn bad_input_fails_clearly_and_writes_nothing() {
    let las = shared("las/simple.las");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.omcl");
    let o = out.to_str().unwrap();
    // Labels but no table.
    let (ok, text) = omcl(&["map", "cloud", las.to_str().unwrap(), "-o", o]);
    assert!(!ok && text.contains("--classes"), "{text}");
    // A table none of whose classes occur: both sides named.
    let (c, e) = one_hot_table(dir.path(), &[(77, "nothing")]);
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        las.to_str().unwrap(),
        "-o",
        o,
        "--classes",
        c.to_str().unwrap(),
        "--embeddings",
        e.to_str().unwrap(),
    ]);
    assert!(
        !ok && text.contains("none of the 1065 points' labels is a class of the table")
            && text.contains("the points carry 1, 2;")
            && text.contains("the table's ids are 77 nothing.")
            && !out.exists(),
        "{text}"
    );
    // The same through a PLY read whole and a sequence read scan by scan.
    let ply_path = dir.path().join("labelled.ply");
    labelled_ply(&ply_path, &[([0.0, 0.0, 0.0], 2), ([1.0, 0.0, 0.0], 5)]);
    let seq = shared("semantickitti/sequences/00");
    for input in [&ply_path, &seq] {
        let (ok, text) = omcl(&[
            "map",
            "cloud",
            input.to_str().unwrap(),
            "-o",
            o,
            "--classes",
            c.to_str().unwrap(),
            "--embeddings",
            e.to_str().unwrap(),
        ]);
        assert!(
            !ok && text.contains("labels is a class of the table: the points carry ")
                && text.contains("the table's ids are 77 nothing.")
                && !out.exists(),
            "{}: {text}",
            input.display()
        );
    }
    let (_, text) = omcl(&[
        "map",
        "cloud",
        ply_path.to_str().unwrap(),
        "-o",
        o,
        "--classes",
        c.to_str().unwrap(),
        "--embeddings",
        e.to_str().unwrap(),
    ]);
    assert!(text.contains("the points carry 2, 5;"), "{text}");
    // A truncated PLY.
    let bad = dir.path().join("bad.ply");
    std::fs::write(&bad, "ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nproperty float y\nproperty float z\nend_header\n\x00\x00").unwrap();
    let (ok, text) = omcl(&["map", "cloud", bad.to_str().unwrap(), "-o", o]);
    assert!(!ok && text.contains("bad.ply"), "{text}");
    // A feature file of the wrong length.
    let feats = dir.path().join("f.npy");
    npy::write_npy(&feats, &[3, 4], &[0.5; 12]).unwrap();
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        las.to_str().unwrap(),
        "-o",
        o,
        "--features",
        feats.to_str().unwrap(),
    ]);
    assert!(!ok && text.contains("f.npy"), "{text}");
    assert!(!out.exists(), "no map may be written on failure");
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        las.to_str().unwrap(),
        "-o",
        o,
        "--resolution=-1",
    ]);
    assert!(!ok && text.contains("--resolution"), "{text}");
    // A map is never written over a file the command reads: the feature
    // file, or a sequence folder's ground truth.
    let before = std::fs::read(&feats).unwrap();
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        las.to_str().unwrap(),
        "-o",
        feats.to_str().unwrap(),
        "--features",
        feats.to_str().unwrap(),
    ]);
    assert!(!ok && text.contains("--out is --features"), "{text}");
    let seq = dir.path().join("seq");
    std::fs::create_dir(&seq).unwrap();
    std::fs::write(seq.join("poses.txt"), "0 0 0 0 0 0 0 1\n").unwrap();
    let gt = seq.join("poses.txt");
    let (ok, text) = omcl(&[
        "map",
        "rgbd",
        seq.to_str().unwrap(),
        "-o",
        gt.to_str().unwrap(),
    ]);
    assert!(
        !ok && text.contains("--out is a file of the sequence"),
        "{text}"
    );
    assert_eq!(std::fs::read_to_string(&gt).unwrap(), "0 0 0 0 0 0 0 1\n");
    assert_eq!(
        std::fs::read(&feats).unwrap(),
        before,
        "the feature file changed"
    );
}

/// A single real SemanticKITTI scan maps with its labels found beside it,
/// in the dataset's own `../labels/` folder, or named by `--labels`: the
/// same map each time. Without labels it is refused, and a label file of
/// another scan (another point count) is named.
#[test]
fn a_single_kitti_scan_reads_the_labels_beside_it() {
    let seq = shared("semantickitti/sequences/00");
    let dir = tempfile::tempdir().unwrap();
    let ids: Vec<(u32, &str)> = labels::SEMANTIC_KITTI_CLASSES
        .iter()
        .map(|&(id, name)| (id, name))
        .collect();
    let (classes, emb) = one_hot_table(dir.path(), &ids);
    let scan = seq.join("velodyne/000000.bin");
    let label = seq.join("labels/000000.label");
    let map_of = |input: &Path, extra: &[&str], out: &Path| {
        let args = [
            &[
                "map",
                "cloud",
                input.to_str().unwrap(),
                "--format",
                "kitti",
                "--resolution",
                "0.2",
                "--classes",
                classes.to_str().unwrap(),
                "--embeddings",
                emb.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ][..],
            extra,
        ]
        .concat();
        omcl(&args)
    };
    // The dataset's layout: velodyne/000000.bin with labels/000000.label.
    let a = dir.path().join("a.omcl");
    let (ok, text) = map_of(&scan, &[], &a);
    assert!(ok, "{text}");
    // Copied alone with its label file beside it.
    let alone = dir.path().join("alone");
    std::fs::create_dir_all(&alone).unwrap();
    std::fs::copy(&scan, alone.join("000000.bin")).unwrap();
    std::fs::copy(&label, alone.join("000000.label")).unwrap();
    let b = dir.path().join("b.omcl");
    let (ok, text) = map_of(&alone.join("000000.bin"), &[], &b);
    assert!(ok, "{text}");
    // Named explicitly.
    let bare = dir.path().join("bare");
    std::fs::create_dir_all(&bare).unwrap();
    std::fs::copy(&scan, bare.join("000000.bin")).unwrap();
    let c = dir.path().join("c.omcl");
    let (ok, text) = map_of(
        &bare.join("000000.bin"),
        &["--labels", label.to_str().unwrap()],
        &c,
    );
    assert!(ok, "{text}");
    let (ma, mb, mc) = (
        map::load(&a).unwrap(),
        map::load(&b).unwrap(),
        map::load(&c).unwrap(),
    );
    assert!(ma.len() > 5_000, "{} voxels", ma.len());
    assert_eq!(ma, mb);
    assert_eq!(ma, mc);
    // Road voxels (class 40) are there, below the sensor.
    let road = ids.iter().position(|&(i, _)| i == 40).unwrap();
    let road_voxels = ma
        .rows()
        .iter()
        .filter(|&&r| ma.db().row(r as usize)[road] > 0.5)
        .count();
    assert!(road_voxels > 500, "{road_voxels} road voxels");

    // No labels anywhere: refused, where they were looked for named,
    // nothing written.
    let d = dir.path().join("d.omcl");
    let (ok, text) = map_of(&bare.join("000000.bin"), &[], &d);
    assert!(
        !ok && text.contains("bare/000000.label") && text.contains("--labels FILE"),
        "{text}"
    );
    assert!(!d.exists());
    // Another scan's labels: the count differs, the file is named.
    let other = seq.join("labels/000001.label");
    let (ok, text) = map_of(
        &bare.join("000000.bin"),
        &["--labels", other.to_str().unwrap()],
        &d,
    );
    assert!(!ok && text.contains("000001.label"), "{text}");
    assert!(!d.exists());
}

/// The built-in class lists: the real SemanticKITTI scans map with every
/// labelled point kept (all 34 classes are known), an aerial LAS maps with
/// its ASPRS codes, and words find their class in the built-in table.
#[test]
fn builtin_class_lists_convert_real_scans_and_las_without_a_table() {
    let seq = shared("semantickitti/sequences/00");
    let las = shared("las/autzen_trim.laz");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("kitti.omcl");
    let o = out.to_str().unwrap();
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        seq.to_str().unwrap(),
        "-o",
        o,
        "--resolution",
        "0.2",
        "--classes",
        "semantickitti",
    ]);
    assert!(ok, "{text}");
    // Every point of a static class is integrated: none skipped as an
    // unknown class (a 9-class table skipped 7 %).
    assert!(text.contains(" 0 skipped"), "{text}");
    let m = map::load(&out).unwrap();
    assert_eq!(m.db().dim(), 512);
    // Not all of the built-in table is CLIP: the map is not stamped with a
    // CLIP model's name.
    assert_eq!(m.encoder(), "omcl-builtin-semantickitti");
    // `omcl map classes` writes the same table as files: the map made from
    // them is the same (voxels, rows, features to the bit; named alike
    // with --encoder).
    let (ok, text) = omcl(&[
        "map",
        "classes",
        "semantickitti",
        "-o",
        dir.path().to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let again = dir.path().join("again.omcl");
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        seq.to_str().unwrap(),
        "-o",
        again.to_str().unwrap(),
        "--resolution",
        "0.2",
        "--classes",
        dir.path().join("classes.txt").to_str().unwrap(),
        "--embeddings",
        dir.path().join("embeddings.npy").to_str().unwrap(),
        "--encoder",
        "omcl-builtin-semantickitti",
    ]);
    assert!(ok, "{text}");
    assert!(m == map::load(&again).unwrap(), "the maps differ");
    let listed = std::fs::read_to_string(dir.path().join("classes.txt")).unwrap();
    assert_eq!(listed.lines().count(), 34);
    assert!(listed.lines().any(|l| l == "252 moving-car"), "{listed}");
    // "road" and "traffic-sign" are known words of the same table; the road
    // covers a large part of a street scan, a sign a small one.
    let q = dir.path().join("q.ply");
    let within = |word: &str| -> usize {
        let (ok, text) = omcl(&[
            "map",
            "query",
            o,
            word,
            "--classes",
            "semantickitti",
            "-o",
            q.to_str().unwrap(),
        ]);
        assert!(ok, "{text}");
        text.split('(')
            .nth(1)
            .and_then(|t| t.split_whitespace().next())
            .and_then(|t| t.parse().ok())
            .unwrap_or_else(|| panic!("{text}"))
    };
    let road = within("road");
    let sign = within("traffic sign");
    assert!(road * 10 > m.len(), "road {road} of {}", m.len());
    assert!(
        sign * 50 < m.len() && sign > 0,
        "sign {sign} of {}",
        m.len()
    );

    let out = dir.path().join("autzen.omcl");
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        las.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--resolution",
        "1.0",
        "--classes",
        "asprs",
    ]);
    assert!(ok, "{text}");
    assert!(text.contains(" 0 skipped"), "{text}");

    // A list file needs its features; a name that is neither a file nor a
    // built-in list is named.
    let list = dir.path().join("classes.txt");
    std::fs::write(&list, "1 unclassified\n2 ground\n").unwrap();
    let bad = dir.path().join("bad.omcl");
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        las.to_str().unwrap(),
        "-o",
        bad.to_str().unwrap(),
        "--classes",
        list.to_str().unwrap(),
    ]);
    assert!(!ok && text.contains("--embeddings NPY"), "{text}");
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        las.to_str().unwrap(),
        "-o",
        bad.to_str().unwrap(),
        "--classes",
        "semantic-kitty",
    ]);
    assert!(
        !ok && text.contains("semantic-kitty: no such class list"),
        "{text}"
    );
    assert!(!bad.exists());
}

/// A sequence folder mapped scan by scan (bounded memory) gives the map of
/// the merged cloud: same grid, voxels and features, with and without the
/// authors' class filter and a range cut.
#[test]
fn a_sequence_mapped_scan_by_scan_equals_the_merged_cloud() {
    use omcl::mapping::pipeline::{self, BuildParams, CloudInput, SequencePass};
    let seq = shared("semantickitti/sequences/00");
    let sim = omcl::sim::files::builtin_table().unwrap();
    let table = omcl::sim::embeddings::builtin_label_table(
        omcl::io::labels::BuiltinClasses::SemanticKitti,
        &sim,
    )
    .unwrap();
    let params = BuildParams {
        resolution: 0.1,
        tau: 0.02,
        max_rows: 4096,
        encoder: "clip-vit-b32".into(),
        keep_strays: false,
    };
    for (keep_all, max_range) in [(false, None), (true, Some(30.0))] {
        let input = CloudInput {
            path: seq.clone(),
            keep_all,
            max_range,
            ..Default::default()
        };
        let merged = pipeline::load_cloud(&input).unwrap();
        let n = merged.len();
        let (a, sa) =
            pipeline::map_from_cloud(merged, "merged", &params, Some(&table), None).unwrap();
        let mut calls = Vec::new();
        let (b, sb) = pipeline::map_from_sequence(&input, &params, Some(&table), &mut |p, d, t| {
            calls.push((p, d, t))
        })
        .unwrap();
        assert_eq!(sa.offered, n);
        assert_eq!(
            (sa.offered, sa.integrated, sa.skipped, sa.rejected),
            (sb.offered, sb.integrated, sb.skipped, sb.rejected)
        );
        // The same voxels with the same features; a voxel seen by several
        // scans sums its rows in another order, so equal to float error.
        assert_eq!(a.grid(), b.grid());
        assert_eq!(a.codes(), b.codes());
        assert_eq!(a.db().len(), b.db().len());
        for (i, (&ra, &rb)) in a.rows().iter().zip(b.rows()).enumerate() {
            let (fa, fb) = (a.db().row(ra as usize), b.db().row(rb as usize));
            let c: f32 = fa.iter().zip(fb).map(|(x, y)| x * y).sum();
            assert!(c > 0.99999, "keep_all {keep_all}: voxel {i}: cosine {c}");
        }
        assert_eq!(
            calls,
            vec![
                (SequencePass::Bounds, 1, 3),
                (SequencePass::Bounds, 2, 3),
                (SequencePass::Bounds, 3, 3),
                (SequencePass::Mapping, 1, 3),
                (SequencePass::Mapping, 2, 3),
                (SequencePass::Mapping, 3, 3),
            ]
        );
    }
}

/// An ASCII PLY of `points` with an ASPRS `classification` each.
fn labelled_ply(path: &Path, points: &[([f64; 3], u32)]) {
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\nproperty uchar classification\nend_header\n",
        points.len()
    );
    for ([x, y, z], c) in points {
        text += &format!("{x} {y} {z} {c}\n");
    }
    std::fs::write(path, text).unwrap();
}

/// What a user converting real LiDAR gets told: a stray point at 0, 0, 0
/// in UTM data is left out with a warning (the data mapped, not the other
/// way round); most points' classes missing from the table, or every
/// point of one class, are warned about; `-o` does not replace a file that
/// is not a map without `--force`, nor take an input's extension.
#[test]
fn map_cloud_warns_about_strays_and_tables_and_guards_its_output() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    // `map cloud INPUT --classes asprs -o OUT` in this folder.
    let asprs = |input: &str, out: &str, extra: &[&str]| {
        let input = p(input);
        let args = [
            &["map", "cloud", &input, "--classes", "asprs", "-o", out][..],
            extra,
        ]
        .concat();
        omcl(&args)
    };
    // 40 x 50 points 0.1 m apart near (630000, 4830000), classes 2, 5 and
    // 6, and one point at the origin.
    let mut pts: Vec<([f64; 3], u32)> = (0..2000)
        .map(|i| {
            let (x, y) = ((i % 40) as f64 * 0.1, (i / 40) as f64 * 0.1);
            ([630_000.0 + x, 4_830_000.0 + y, 12.0], [2, 5, 6][i % 3])
        })
        .collect();
    pts.insert(0, ([0.0; 3], 2));
    labelled_ply(&dir.path().join("utm.ply"), &pts);
    let (ok, text) = asprs("utm.ply", &p("utm.omcl"), &[]);
    assert!(ok, "{text}");
    assert!(text.contains("2000 of 2001 inputs integrated"), "{text}");
    assert!(
        text.contains("warning: 1 of 2001 points were left out") && text.contains("reach"),
        "{text}"
    );
    let m = map::load(Path::new(&p("utm.omcl"))).unwrap();
    assert_eq!(m.len(), 2000);
    assert!(
        (m.grid().origin.x - 630_002.0).abs() < 0.2,
        "{:?}",
        m.grid().origin
    );
    assert!(!text.contains("skipped: their labels"), "{text}");
    // At 10 m the stray is within the grid's reach (2^20 cells): the
    // data's box leaves it out all the same (the map spanned 4,830 km);
    // --keep-strays keeps it.
    for (extra, voxels) in [(&[][..], 1), (&["--keep-strays"][..], 2)] {
        let (ok, text) = asprs(
            "utm.ply",
            &p("coarse.omcl"),
            &[&["--resolution", "10"][..], extra].concat(),
        );
        assert!(ok, "{text}");
        assert_eq!(
            text.contains("warning: 1 of 2001 points were left out")
                && text.contains("strays far outside the bulk of the data"),
            voxels == 1,
            "{text}"
        );
        let m = map::load(Path::new(&p("coarse.omcl"))).unwrap();
        assert_eq!(m.len(), voxels, "{extra:?}");
    }
    // A third of the points of a class the table does not have (ASPRS
    // codes end at 22 here): warned, with the table named.
    let half: Vec<_> = pts[1..]
        .iter()
        .map(|&(q, c)| (q, if c == 6 { 200 } else { c }))
        .collect();
    labelled_ply(&dir.path().join("half.ply"), &half);
    let (ok, text) = asprs("half.ply", &p("half.omcl"), &[]);
    assert!(ok, "{text}");
    assert!(
        text.contains("33 % of the points were skipped") && text.contains("asprs"),
        "{text}"
    );
    assert!(!text.contains("same class"), "{text}");
    // Never classified: one class, one feature.
    let never: Vec<_> = pts[1..].iter().map(|&(q, _)| (q, 0)).collect();
    labelled_ply(&dir.path().join("never.ply"), &never);
    let (ok, text) = asprs("never.ply", &p("never.omcl"), &[]);
    assert!(ok, "{text}");
    assert!(
        text.contains("every mapped point has the same class"),
        "{text}"
    );
    // -o over a file that is not a map, and with an input's extension.
    std::fs::write(dir.path().join("notes.omcl"), "my notes\n").unwrap();
    let (ok, text) = asprs("half.ply", &p("notes.omcl"), &[]);
    assert!(
        !ok && text.contains("notes.omcl")
            && text.contains("not an omcl map")
            && text.contains("--force"),
        "{text}"
    );
    assert_eq!(
        std::fs::read_to_string(dir.path().join("notes.omcl")).unwrap(),
        "my notes\n"
    );
    let (ok, text) = asprs("half.ply", &p("notes.omcl"), &["--force"]);
    assert!(ok, "{text}");
    assert!(map::load(&dir.path().join("notes.omcl")).is_ok());
    // A floor plan (the same container, another format) is not a map; an
    // empty file (`mktemp`'s) holds nothing to lose.
    let plan = p("utm.plan");
    let (ok, text) = omcl(&[
        "map",
        "floorplan",
        &p("utm.omcl"),
        "-o",
        &plan,
        "--band-min",
        "0",
        "--band-max",
        "1",
    ]);
    assert!(ok, "{text}");
    let before = std::fs::read(&plan).unwrap();
    let (ok, text) = asprs("half.ply", &plan, &[]);
    assert!(!ok && text.contains("not an omcl map"), "{text}");
    assert_eq!(std::fs::read(&plan).unwrap(), before);
    std::fs::write(dir.path().join("empty.omcl"), b"").unwrap();
    let (ok, text) = asprs("half.ply", &p("empty.omcl"), &[]);
    assert!(ok, "{text}");
    // A map replaces a map without --force.
    let (ok, text) = asprs("utm.ply", &p("half.omcl"), &[]);
    assert!(ok, "{text}");
    let (ok, text) = asprs("utm.ply", &p("map.ply"), &[]);
    assert!(
        !ok && text.contains("map.ply") && text.contains(".omcl file"),
        "{text}"
    );
    assert!(!dir.path().join("map.ply").exists());
}

/// Near misses of `map cloud`'s input, each told what to give instead,
/// and options that do not apply to the input refused rather than
/// ignored.
#[test]
fn map_cloud_names_near_misses_and_options_that_do_not_apply() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.omcl");
    let o = out.to_str().unwrap();
    let run = |input: &Path, extra: &[&str]| {
        let args = [
            &["map", "cloud", input.to_str().unwrap(), "-o", o][..],
            extra,
        ]
        .concat();
        omcl(&args)
    };
    let seq = shared("semantickitti/sequences/00");
    let cases: [(PathBuf, &[&str], &[&str]); 3] = [
        (
            shared("semantickitti/sequences"),
            &[],
            &["a folder of KITTI sequences (1 of them)", "sequences/00"],
        ),
        (
            seq.join("velodyne"),
            &[],
            &[
                "a folder inside the KITTI sequence",
                "give the sequence's folder",
            ],
        ),
        (
            shared("las"),
            &["--classes", "asprs"],
            &[
                "its tiles state different coordinate reference systems",
                "32-1-472-150-76.laz",
                "autzen_trim.laz",
            ],
        ),
    ];
    for (input, extra, needles) in cases {
        let (ok, text) = run(&input, extra);
        assert!(!ok, "{text}");
        for n in needles {
            assert!(text.contains(n), "{}: lacks {n:?}: {text}", input.display());
        }
    }
    let las = shared("las/simple.las");
    for (extra, needle) in [
        (
            &["--frames", "2"][..],
            "--frames is for a KITTI sequence folder",
        ),
        (
            &["--max-range", "30"][..],
            "--max-range is for a KITTI sequence folder",
        ),
        (&["--frames", "0"][..], "0 is less than 1"),
    ] {
        let (ok, text) = run(&las, &[&["--classes", "asprs"][..], extra].concat());
        assert!(!ok && text.contains(needle), "{extra:?}: {text}");
    }
    let (ok, text) = run(&seq, &["--classes", "semantickitti", "--max-range", "nan"]);
    assert!(
        !ok && text.contains("--max-range must be a positive"),
        "{text}"
    );
    let feats = dir.path().join("f.npy");
    npy::write_npy(&feats, &[1, 2], &[1.0, 0.0]).unwrap();
    let (ok, text) = run(
        &las,
        &["--classes", "asprs", "--features", feats.to_str().unwrap()],
    );
    assert!(
        !ok && text.contains("--features") && text.contains("--classes"),
        "{text}"
    );
    let bin = dir.path().join("scan.bin");
    std::fs::write(&bin, [0u8; 16]).unwrap();
    let (ok, text) = run(&bin, &[]);
    assert!(
        !ok && text.contains("--format kitti") && text.contains("--format scannet"),
        "{text}"
    );
    let (ok, text) = run(&dir.path().join("missing.laz"), &["--classes", "asprs"]);
    assert!(
        !ok && text.contains("missing.laz: no such file or folder"),
        "{text}"
    );
    assert!(!out.exists());
}

/// `--label-property` from the command line: a DALES-like PLY whose labels
/// are `sem_class` maps through the ASPRS table with it (without it, the
/// points carry no labels and the map is refused); it is refused for a LAS
/// file and a folder.
#[test]
fn map_cloud_reads_labels_from_a_named_ply_property() {
    let dir = tempfile::tempdir().unwrap();
    let ply_path = dir.path().join("dales.ply");
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\n\
         property double z\nproperty int sem_class\nend_header\n",
    );
    for (x, c) in [(0.0, 2), (0.1, 2), (5.0, 6), (5.1, 6)] {
        text += &format!("{x} 0 0 {c}\n");
    }
    std::fs::write(&ply_path, text).unwrap();
    let out = dir.path().join("m.omcl");
    let run = |input: &Path, extra: &[&str]| {
        let args = [
            &[
                "map",
                "cloud",
                input.to_str().unwrap(),
                "--classes",
                "asprs",
                "--resolution",
                "1",
                "-o",
                out.to_str().unwrap(),
            ][..],
            extra,
        ]
        .concat();
        omcl(&args)
    };
    let (ok, text) = run(&ply_path, &[]);
    assert!(
        !ok && text.contains("neither features nor labels") && text.contains("--label-property"),
        "{text}"
    );
    let (ok, text) = run(&ply_path, &["--label-property", "sem_class"]);
    assert!(ok, "{text}");
    let m = map::load(&out).unwrap();
    // Ground (2) and building (6): two voxels, two rows.
    assert_eq!(m.len(), 2);
    let rows: std::collections::BTreeSet<u32> = m.rows().iter().copied().collect();
    assert_eq!(rows.len(), 2);
    std::fs::remove_file(&out).unwrap();
    for input in [shared("las/simple.las"), shared("las")] {
        let (ok, text) = run(&input, &["--label-property", "sem_class"]);
        assert!(
            !ok && text.contains("--label-property is for PLY files") && !out.exists(),
            "{text}"
        );
    }
}

/// A PLY whose points carry both labels and features, mapped with
/// `--classes`: the labels are mapped (the table's rows), the features
/// left out and said; without labels, refused. The features had been
/// mapped and `--classes` ignored, the map's rows of another dimension
/// than the table's. A sequence's `--features-dir` with `--classes` is
/// refused by the command line.
#[test]
fn classes_map_a_cloud_s_labels_not_its_own_features() {
    let dir = tempfile::tempdir().unwrap();
    let (classes, emb) = one_hot_table(dir.path(), &[(1, "wall"), (2, "floor"), (3, "door")]);
    let ply = |name: &str, labels: bool| {
        let p = dir.path().join(name);
        let mut t = String::from("ply\nformat ascii 1.0\nelement vertex 20\n");
        t.push_str("property float x\nproperty float y\nproperty float z\n");
        if labels {
            t.push_str("property int label\n");
        }
        for f in 0..8 {
            t.push_str(&format!("property float feature_{f}\n"));
        }
        t.push_str("end_header\n");
        for i in 0..20 {
            t.push_str(&format!("{} 0.5 0.5", i as f32 + 0.5));
            if labels {
                t.push_str(&format!(" {}", 1 + i % 2));
            }
            for f in 0..8 {
                t.push_str(if f == i % 8 { " 1" } else { " 0" });
            }
            t.push('\n');
        }
        std::fs::write(&p, t).unwrap();
        p
    };
    let build = |input: &Path, out: &Path| {
        omcl(&[
            "map",
            "cloud",
            input.to_str().unwrap(),
            "--classes",
            classes.to_str().unwrap(),
            "--embeddings",
            emb.to_str().unwrap(),
            "--resolution",
            "1",
            "-o",
            out.to_str().unwrap(),
        ])
    };
    let out = dir.path().join("m.omcl");
    let (ok, text) = build(&ply("both.ply", true), &out);
    assert!(ok, "{text}");
    assert!(
        text.contains("--classes maps the labels, the features are left out"),
        "{text}"
    );
    let m = map::load(&out).unwrap();
    assert_eq!(
        (m.db().dim(), m.db().len()),
        (3, 2),
        "the table's rows, two classes"
    );
    let out2 = dir.path().join("n.omcl");
    let (ok, text) = build(&ply("features.ply", false), &out2);
    assert!(
        !ok && text.contains("no labels") && !out2.exists(),
        "{text}"
    );
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        shared("semantickitti/sequences/00").to_str().unwrap(),
        "--classes",
        "semantickitti",
        "--features-dir",
        dir.path().to_str().unwrap(),
        "-o",
        out2.to_str().unwrap(),
    ]);
    assert!(!ok && text.contains("cannot be used with"), "{text}");
}

/// Words of the built-in CLIP-like table against a map built in another
/// feature space (its own embeddings named `my-clip`), and the other way
/// round, are said; words from the map's own table are not.
#[test]
fn words_from_another_feature_space_than_the_map_are_said() {
    let d = tempfile::tempdir().unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let ply = d.path().join("c.ply");
    labelled_ply(
        &ply,
        &[
            ([0.0, 0.0, 0.0], 2),
            ([1.0, 0.0, 0.0], 2),
            ([0.0, 1.0, 1.0], 6),
        ],
    );
    let table = d.path().join("table");
    let (ok, out) = omcl(&["map", "classes", "asprs", "-o", &s(&table)]);
    assert!(ok, "{out}");
    let (classes, emb) = (table.join("classes.txt"), table.join("embeddings.npy"));
    let builtin_map = d.path().join("b.omcl");
    let own_map = d.path().join("o.omcl");
    let (ok, out) = omcl(&[
        "map",
        "cloud",
        &s(&ply),
        "--classes",
        "asprs",
        "-o",
        &s(&builtin_map),
    ]);
    assert!(ok, "{out}");
    let (ok, out) = omcl(&[
        "map",
        "cloud",
        &s(&ply),
        "--classes",
        &s(&classes),
        "--embeddings",
        &s(&emb),
        "--encoder",
        "my-clip",
        "-o",
        &s(&own_map),
    ]);
    assert!(ok, "{out}");
    let heat = d.path().join("h.ply");
    let query = |map: &Path, extra: &[&str]| {
        let mut a = vec!["map".to_string(), "query".into(), s(map), "ground".into()];
        a.extend(extra.iter().map(|x| x.to_string()));
        a.extend(["-o".into(), s(&heat)]);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        omcl(&a)
    };
    let note = "two feature spaces, whose similarities mean little";
    let (ok, out) = query(&own_map, &["--classes", "asprs"]);
    assert!(
        ok && out.contains(note)
            && out.contains("(omcl-builtin-asprs), the map's rows in my-clip's space"),
        "{out}"
    );
    let (ok, out) = query(&builtin_map, &["--classes", "asprs"]);
    assert!(ok && !out.contains(note), "{out}");
    let (ok, out) = query(
        &own_map,
        &["--classes", &s(&classes), "--embeddings", &s(&emb)],
    );
    assert!(ok && !out.contains(note), "{out}");
}
