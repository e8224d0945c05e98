//! Clouds mapped a batch at a time (`omcl::mapping::tiles`): a real LAZ,
//! and folders of LAS or PLY tiles cut from real data, give the map of the
//! file read whole; tiles that cannot be merged are refused by name.

mod common;

use common::shared;

use std::path::Path;

use omcl::io::labels::{BuiltinClasses, EmbeddingTable};
use omcl::map::LanguageMap;
use omcl::mapping::pipeline::{self, BuildParams, CloudInput, SequencePass};
use omcl::mapping::tiles::{TileKind, TileOptions, TileSource, cloud_tiles, map_from_tiles};

fn asprs() -> EmbeddingTable {
    let sim = omcl::sim::files::builtin_table().unwrap();
    omcl::sim::embeddings::builtin_label_table(BuiltinClasses::Asprs, &sim).unwrap()
}

fn params(resolution: f64) -> BuildParams {
    BuildParams {
        resolution,
        tau: 0.02,
        max_rows: 4096,
        encoder: "clip-vit-b32".into(),
        keep_strays: false,
    }
}

/// The map of `path` read whole (`load_cloud` then `map_from_cloud`).
fn whole(path: &Path, keep_all: bool, resolution: f64) -> (LanguageMap, [usize; 4]) {
    let input = CloudInput {
        path: path.to_path_buf(),
        keep_all,
        ..Default::default()
    };
    let c = pipeline::load_cloud(&input).unwrap();
    let (m, s) =
        pipeline::map_from_cloud(c, "whole", &params(resolution), Some(&asprs()), None).unwrap();
    (m, [s.offered, s.integrated, s.skipped, s.rejected])
}

/// A progress call: pass, records read, records declared.
type Call = (SequencePass, u64, u64);

/// The map of `path` (a file or a folder of tiles) batch by batch, with
/// its counts, notes and progress calls.
fn batched(
    path: &Path,
    keep_all: bool,
    batch_points: u64,
    resolution: f64,
) -> (LanguageMap, [usize; 4], Vec<String>, Vec<Call>) {
    let src = TileSource::open(path).unwrap();
    let mut calls = Vec::new();
    let (m, s, notes) = map_from_tiles(
        &src,
        &TileOptions {
            keep_all,
            batch_points,
            ..Default::default()
        },
        &params(resolution),
        Some(&asprs()),
        &mut |p, d, t| calls.push((p, d, t)),
    )
    .unwrap();
    (
        m,
        [s.offered, s.integrated, s.skipped, s.rejected],
        notes,
        calls,
    )
}

/// The same grid, voxels and rows (label rows counted the same way give
/// the same features, bit for bit).
fn assert_same_map(a: &LanguageMap, b: &LanguageMap) {
    assert_eq!(a.grid(), b.grid());
    assert_eq!(a.codes(), b.codes());
    assert_eq!(a.db().len(), b.db().len());
    for (i, (&ra, &rb)) in a.rows().iter().zip(b.rows()).enumerate() {
        assert_eq!(
            a.db().row(ra as usize),
            b.db().row(rb as usize),
            "voxel {i}: features differ"
        );
    }
}

/// Progress: one pass then the other, records read growing to the count
/// declared.
fn assert_progress(calls: &[Call], declared: u64, batches: usize) {
    let bounds: Vec<_> = calls
        .iter()
        .filter(|c| c.0 == SequencePass::Bounds)
        .collect();
    assert_eq!(bounds.len(), batches, "{calls:?}");
    assert_eq!(calls.len(), 2 * batches);
    assert!(calls[..batches].iter().all(|c| c.0 == SequencePass::Bounds));
    for pass in calls.chunks(batches) {
        assert!(pass.windows(2).all(|w| w[0].1 < w[1].1), "{calls:?}");
        assert_eq!(pass.last().unwrap().1, declared);
        assert!(pass.iter().all(|c| c.2 == declared));
    }
}

/// Two real aerial files (autzen: 110,000 points in international feet,
/// colour; 32-1-472-150-76: classes 1, 2, 7 noise and 9) mapped in
/// batches of 1,000 points give the map of the file read whole, with and
/// without the noise class, with the same counts and notes.
#[test]
fn a_laz_mapped_batch_by_batch_equals_the_file_read_whole() {
    for (file, resolution) in [
        ("las/autzen_trim.laz", 1.0),
        ("las/32-1-472-150-76.laz", 0.5),
    ] {
        let path = shared(file);
        for keep_all in [false, true] {
            let (a, sa) = whole(&path, keep_all, resolution);
            let (b, sb, notes, calls) = batched(&path, keep_all, 1000, resolution);
            assert_eq!(sa, sb, "{file}");
            assert_same_map(&a, &b);
            let declared = TileSource::open(&path).unwrap().declared();
            assert_progress(&calls, declared, declared.div_ceil(1000) as usize);
            // The whole-file path's notes on what was left out.
            let input = CloudInput {
                path: path.clone(),
                keep_all,
                ..Default::default()
            };
            let c = pipeline::load_cloud(&input).unwrap();
            let src = TileSource::open(&path).unwrap();
            let mut all: Vec<String> = src.notes().to_vec();
            all.extend(notes);
            assert_eq!(all, c.notes, "{file} keep_all {keep_all}");
        }
    }
    // The noise file's note is there (the loop compared it).
    let path = shared("las/32-1-472-150-76.laz");
    let (_, _, notes, _) = batched(&path, false, 1 << 20, 0.5);
    assert!(
        notes
            .iter()
            .any(|n| n.contains("noise (ASPRS classes 7 and 18)")),
        "{notes:?}"
    );
}

/// Writes the points `range` of the LAS/LAZ `src` as an uncompressed LAS
/// `out` with `src`'s header (scale, offset, CRS records).
fn cut(src: &Path, out: &Path, range: std::ops::Range<usize>) {
    cut_with(src, out, range, |_, _| {});
}

/// [`cut`], each point `i` (index in `src`) changed by `edit` first.
fn cut_with(
    src: &Path,
    out: &Path,
    range: std::ops::Range<usize>,
    mut edit: impl FnMut(usize, &mut las::Point),
) {
    let mut r = las::Reader::from_path(src).unwrap();
    let mut b = las::Builder::from(r.header().clone());
    b.point_format.is_compressed = false;
    let header = b.into_header().unwrap();
    let data = r.read_all().unwrap();
    let mut w = las::Writer::from_path(out, header).unwrap();
    for (i, p) in data
        .points()
        .enumerate()
        .skip(range.start)
        .take(range.len())
    {
        let mut p = p.unwrap();
        edit(i, &mut p);
        w.write_point(p).unwrap();
    }
    w.close().unwrap();
}

/// autzen cut into three tiles: the folder maps to the file's map, through the
/// library and the command line (the same map file, byte for byte).
#[test]
fn tiles_cut_from_a_file_map_like_the_file() {
    let src = shared("las/autzen_trim.laz");
    let dir = tempfile::tempdir().unwrap();
    let tiles = dir.path().join("tiles");
    std::fs::create_dir(&tiles).unwrap();
    let n = TileSource::open(&src).unwrap().declared() as usize;
    // Name order is read order.
    cut(&src, &tiles.join("a.las"), 0..40_000);
    cut(&src, &tiles.join("b.LAS"), 40_000..75_000);
    cut(&src, &tiles.join("c.las"), 75_000..n);
    std::fs::write(tiles.join("README.txt"), "not a tile").unwrap();
    assert_eq!(
        cloud_tiles(&tiles).unwrap(),
        (
            TileKind::Las,
            ["a.las", "b.LAS", "c.las"].map(|f| tiles.join(f)).to_vec()
        )
    );
    let (a, sa) = whole(&src, false, 1.0);
    let (b, sb, notes, calls) = batched(&tiles, false, 1 << 20, 1.0);
    assert_eq!(sa, sb);
    assert_same_map(&a, &b);
    assert_eq!(calls.len(), 6, "{calls:?}");
    assert!(notes.is_empty(), "{notes:?}");
    let open = TileSource::open(&tiles).unwrap();
    assert_eq!(open.declared() as usize, n);
    // Units: the first tile's note and one line for the others.
    assert_eq!(open.notes().len(), 2, "{:?}", open.notes());
    assert!(open.notes()[0].contains("international feet"));
    assert!(open.notes()[1].contains("other 2 tiles state the same CRS"));

    // The command line: the file and the folder give the same map file.
    let map = |input: &Path, out: &Path| {
        let r = common::omcl(&[
            "map",
            "cloud",
            input.to_str().unwrap(),
            "--classes",
            "asprs",
            "--resolution",
            "1",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(r.ok(), "{}", r.output());
        r.output()
    };
    let (m1, m2) = (dir.path().join("file.omcl"), dir.path().join("tiles.omcl"));
    map(&src, &m1);
    let text = map(&tiles, &m2);
    assert!(text.contains("other 2 tiles state the same CRS"), "{text}");
    assert_eq!(std::fs::read(&m1).unwrap(), std::fs::read(&m2).unwrap());
}

/// A folder whose tiles state different CRS records is refused naming
/// both tiles; a truncated tile is named; options that need one file are
/// refused; an output that would become a tile is refused; a folder with
/// PLY files is not taken for tiles. Nothing is written.
#[test]
fn tiles_that_cannot_be_merged_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.omcl");
    let run = |args: &[&str]| {
        let r = common::omcl(args);
        assert!(!r.ok(), "{}", r.output());
        assert_eq!(r.code, Some(1), "{}", r.output());
        assert!(!out.exists());
        r.output()
    };
    let map = |input: &Path, extra: &[&str]| {
        let mut args = vec![
            "map",
            "cloud",
            input.to_str().unwrap(),
            "--classes",
            "asprs",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        run(&args)
    };
    // autzen (international feet, GeoTIFF keys) beside test1_4 (US feet).
    let mixed = dir.path().join("mixed");
    std::fs::create_dir(&mixed).unwrap();
    cut(&shared("las/autzen_trim.laz"), &mixed.join("1.las"), 0..100);
    std::fs::copy(shared("las/test1_4.las"), mixed.join("2.las")).unwrap();
    let text = map(&mixed, &[]);
    assert!(
        text.contains("different coordinate reference systems")
            && text.contains("1.las")
            && text.contains("2.las"),
        "{text}"
    );
    // A truncated tile.
    let broken = dir.path().join("broken");
    std::fs::create_dir(&broken).unwrap();
    cut(
        &shared("las/autzen_trim.laz"),
        &broken.join("1.las"),
        0..100,
    );
    cut(
        &shared("las/autzen_trim.laz"),
        &broken.join("2.las"),
        100..200,
    );
    let bytes = std::fs::read(broken.join("2.las")).unwrap();
    std::fs::write(broken.join("2.las"), &bytes[..bytes.len() - 500]).unwrap();
    let text = map(&broken, &[]);
    assert!(
        text.contains("2.las") && text.contains("truncated"),
        "{text}"
    );
    // Options for one file.
    let good = dir.path().join("good");
    std::fs::create_dir(&good).unwrap();
    cut(&shared("las/autzen_trim.laz"), &good.join("1.las"), 0..100);
    for extra in [
        &["--format", "las"][..],
        &["--frames", "2"][..],
        &["--labels", "x.label"][..],
    ] {
        let text = map(&good, extra);
        assert!(
            text.contains(extra[0]) && text.contains("is a folder of tiles"),
            "{extra:?}: {text}"
        );
    }
    // --features conflicts with --classes at parsing; alone it is refused.
    let text = run(&[
        "map",
        "cloud",
        good.to_str().unwrap(),
        "--features",
        "f.npy",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(text.contains("--features is for one cloud file"), "{text}");
    // An output named like a tile in the folder.
    let inside = good.join("map.laz");
    let r = common::omcl(&[
        "map",
        "cloud",
        good.to_str().unwrap(),
        "--classes",
        "asprs",
        "-o",
        inside.to_str().unwrap(),
    ]);
    assert!(
        !r.ok() && r.output().contains("a map is an .omcl file"),
        "{}",
        r.output()
    );
    assert!(!inside.exists());
    // PLY beside LAS: not tiles, and said so.
    std::fs::write(good.join("x.ply"), "ply\n").unwrap();
    assert!(cloud_tiles(&good).is_none());
    let text = map(&good, &[]);
    assert!(text.contains("all LAS/LAZ or all PLY, not both"), "{text}");
}

/// The real SemanticKITTI scan 0 (124,668 labelled points) written as one
/// PLY and cut into three PLY tiles: the folder maps to the file's map.
#[test]
fn ply_tiles_map_like_the_merged_file() {
    let scan = shared("semantickitti/sequences/00/velodyne/000000.bin");
    let c = omcl::io::kitti::read_labelled_scan(&scan, None).unwrap();
    let labels = c.labels.clone().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let tiles = dir.path().join("tiles");
    std::fs::create_dir(&tiles).unwrap();
    let n = c.len();
    let cuts = [0, n / 3, n / 2, n];
    for (k, w) in cuts.windows(2).enumerate() {
        let part = omcl::io::cloud::PointCloud {
            points: c.points[w[0]..w[1]].to_vec(),
            labels: Some(labels[w[0]..w[1]].to_vec()),
            ..Default::default()
        };
        omcl::io::ply::write_ply(&tiles.join(format!("{k}.ply")), &part).unwrap();
    }
    let merged = dir.path().join("merged.ply");
    let whole_cloud = omcl::io::cloud::PointCloud {
        points: c.points.clone(),
        labels: Some(labels),
        ..Default::default()
    };
    omcl::io::ply::write_ply(&merged, &whole_cloud).unwrap();
    let sim = omcl::sim::files::builtin_table().unwrap();
    let table =
        omcl::sim::embeddings::builtin_label_table(BuiltinClasses::SemanticKitti, &sim).unwrap();
    let input = CloudInput {
        path: merged,
        ..Default::default()
    };
    let cloud = pipeline::load_cloud(&input).unwrap();
    let (a, sa) =
        pipeline::map_from_cloud(cloud, "merged", &params(0.2), Some(&table), None).unwrap();
    let src = TileSource::open(&tiles).unwrap();
    assert_eq!(
        (src.kind(), src.declared(), src.unit()),
        (TileKind::Ply, 3, "tiles")
    );
    let mut calls = Vec::new();
    let (b, sb, notes) = map_from_tiles(
        &src,
        &TileOptions::default(),
        &params(0.2),
        Some(&table),
        &mut |p, d, t| calls.push((p, d, t)),
    )
    .unwrap();
    assert_same_map(&a, &b);
    assert_eq!(
        [sa.offered, sa.integrated, sa.skipped, sa.rejected],
        [sb.offered, sb.integrated, sb.skipped, sb.rejected]
    );
    assert_eq!(sb.offered, n);
    assert!(notes.is_empty(), "{notes:?}");
    assert_progress(&calls, 3, 3);
}

/// PLY tiles from the command line: labels under another name with
/// `--label-property`; a tile without labels, or with features, refused
/// naming the tile; nothing written.
#[test]
fn ply_tiles_need_labels_and_take_a_label_property() {
    let dir = tempfile::tempdir().unwrap();
    let tiles = dir.path().join("dales");
    std::fs::create_dir(&tiles).unwrap();
    let tile = |name: &str, extra: &str, rows: &[&str]| {
        let mut t = format!(
            "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
             property double z\n{extra}end_header\n",
            rows.len()
        );
        for r in rows {
            t += r;
            t += "\n";
        }
        std::fs::write(tiles.join(name), t).unwrap();
    };
    tile(
        "a.ply",
        "property int sem_class\n",
        &["0 0 0 2", "0.2 0 0 2"],
    );
    tile(
        "b.ply",
        "property int sem_class\n",
        &["5 0 0 6", "5.2 0 0 6"],
    );
    let out = dir.path().join("m.omcl");
    let run = |extra: &[&str]| {
        let args = [
            &[
                "map",
                "cloud",
                tiles.to_str().unwrap(),
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
        common::omcl(&args)
    };
    let r = run(&[]);
    assert!(
        !r.ok() && r.output().contains("a.ply: this tile carries no labels") && !out.exists(),
        "{}",
        r.output()
    );
    let r = run(&["--label-property", "sem_class"]);
    assert!(r.ok(), "{}", r.output());
    let m = omcl::map::load(&out).unwrap();
    assert_eq!(m.len(), 2);
    std::fs::remove_file(&out).unwrap();
    // Nothing is dropped by class from PLY: --keep-all is refused.
    let r = run(&["--label-property", "sem_class", "--keep-all"]);
    assert!(
        !r.ok() && r.output().contains("nothing is dropped by class") && !out.exists(),
        "{}",
        r.output()
    );
    tile(
        "c.ply",
        "property int sem_class\nproperty float f0\n",
        &["9 0 0 2 1.0"],
    );
    let r = run(&["--label-property", "sem_class"]);
    assert!(
        !r.ok()
            && r.output()
                .contains("c.ply: this tile carries feature properties")
            && !out.exists(),
        "{}",
        r.output()
    );
}

/// Withheld and noise points through both paths: a LAS with every 7th
/// point withheld and every 5th made noise gives, read whole and in
/// batches, the same map and the same notes; as tiles, a tile of noise
/// alone is named as holding no point to map, the notes count the
/// withheld points over the tiles, and an output beside them is fine.
#[test]
fn withheld_and_noise_points_agree_between_the_paths() {
    let src = shared("las/autzen_trim.laz");
    let dir = tempfile::tempdir().unwrap();
    let edit = |i: usize, p: &mut las::Point| {
        p.is_withheld = i.is_multiple_of(7);
        if i.is_multiple_of(5) {
            p.classification = las::point::Classification::new(7).unwrap();
        }
    };
    let one = dir.path().join("one.las");
    cut_with(&src, &one, 0..20_000, edit);
    let (a, sa) = whole(&one, false, 1.0);
    let (b, sb, notes, _) = batched(&one, false, 3000, 1.0);
    assert_eq!(sa, sb);
    assert_same_map(&a, &b);
    let c = pipeline::load_cloud(&CloudInput {
        path: one.clone(),
        ..Default::default()
    })
    .unwrap();
    let mut all = TileSource::open(&one).unwrap().notes().to_vec();
    all.extend(notes.iter().cloned());
    assert_eq!(all, c.notes);
    assert!(
        notes[0].contains("2858 of 20000 points are flagged withheld"),
        "{notes:?}"
    );
    // Multiples of 5 below 20,000 (4,000) but not of 7 (withheld: 572 of 35).
    assert!(notes[1].contains("3428 noise"), "{notes:?}");

    let tiles = dir.path().join("tiles");
    std::fs::create_dir(&tiles).unwrap();
    cut_with(&src, &tiles.join("a.las"), 0..10_000, edit);
    cut_with(&src, &tiles.join("b.las"), 10_000..10_100, |_, p| {
        p.classification = las::point::Classification::new(7).unwrap();
    });
    cut_with(&src, &tiles.join("c.las"), 10_100..20_000, edit);
    let (_, _, notes, _) = batched(&tiles, false, 1 << 20, 1.0);
    let text = notes.join("\n");
    assert!(text.contains("of its 3 tiles have some"), "{text}");
    assert!(
        text.contains("1 of its 3 tiles hold no point to map") && text.contains("b.las"),
        "{text}"
    );
    // Every point noise: the error keeps the notes.
    let noise = dir.path().join("noise");
    std::fs::create_dir(&noise).unwrap();
    cut_with(&src, &noise.join("n.las"), 0..100, |_, p| {
        p.classification = las::point::Classification::new(18).unwrap();
    });
    let e = map_from_tiles(
        &TileSource::open(&noise).unwrap(),
        &TileOptions::default(),
        &params(1.0),
        Some(&asprs()),
        &mut |_, _, _| {},
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("empty result") && e.contains("100 noise"), "{e}");
}

/// Tile folders as users keep them: macOS's `._` files and other hidden
/// files, a subfolder, a link to nothing and a second name of a tile are
/// not read, and a note says so; GeoTIFF citations that differ do not split one CRS; a folder with
/// nothing to read says what it is not; `--labels` on one LAS file is
/// refused, not ignored.
#[test]
fn tile_folders_as_users_keep_them() {
    let src = shared("las/autzen_trim.laz");
    let dir = tempfile::tempdir().unwrap();
    let tiles = dir.path().join("tiles");
    std::fs::create_dir_all(tiles.join("more")).unwrap();
    cut(&src, &tiles.join("a.las"), 0..1000);
    cut(&src, &tiles.join("more/b.las"), 1000..2000);
    std::fs::write(tiles.join("._a.las"), [0u8, 5, 22, 7]).unwrap();
    std::fs::write(tiles.join(".hidden.las"), b"junk").unwrap();
    std::os::unix::fs::symlink(dir.path().join("gone.las"), tiles.join("gone.las")).unwrap();
    std::os::unix::fs::symlink(tiles.join("a.las"), tiles.join("z_again.las")).unwrap();
    // The same GeoTIFF keys, another citation text (record 34737).
    let mut r = las::Reader::from_path(&src).unwrap();
    let mut b = las::Builder::from(r.header().clone());
    b.point_format.is_compressed = false;
    for v in b.vlrs.iter_mut().filter(|v| v.record_id == 34737) {
        v.data = b"another citation|\0".to_vec();
    }
    let data = r.read_all().unwrap();
    let mut w = las::Writer::from_path(tiles.join("c.las"), b.into_header().unwrap()).unwrap();
    for p in data.points().skip(2000).take(1000) {
        w.write_point(p.unwrap()).unwrap();
    }
    w.close().unwrap();
    let open = TileSource::open(&tiles).unwrap();
    assert_eq!(open.files(), [tiles.join("a.las"), tiles.join("c.las")]);
    let skipped = open.notes().join("\n");
    for n in [
        "._a.las, .hidden.las (hidden files)",
        "more/ (subfolders are not read)",
        "gone.las (links to nothing)",
        "z_again.las (the same file as a tile before them)",
    ] {
        assert!(skipped.contains(n), "{n}: {skipped}");
    }
    let out = dir.path().join("m.omcl");
    let run = |input: &Path, extra: &[&str]| {
        let args = [
            &[
                "map",
                "cloud",
                input.to_str().unwrap(),
                "--classes",
                "asprs",
                "-o",
                out.to_str().unwrap(),
            ][..],
            extra,
        ]
        .concat();
        common::omcl(&args)
    };
    let r = run(&tiles, &[]);
    assert!(r.ok(), "{}", r.output());
    std::fs::remove_file(&out).unwrap();
    // Nothing to read.
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(empty.join("2019")).unwrap();
    let r = run(&empty, &[]);
    assert!(
        !r.ok()
            && r.output().contains("neither a KITTI sequence")
            && r.output().contains("subfolders"),
        "{}",
        r.output()
    );
    // A sequence folder does not take one file's options.
    let seq = shared("semantickitti/sequences/00");
    for (extra, says) in [
        (
            &["--labels", "/etc/hostname"][..],
            "its labels are in labels/",
        ),
        (&["--format", "ply"][..], "its scans are KITTI .bin"),
        (&["--features", "f.npy"][..], "--features-dir"),
    ] {
        let args = [
            &[
                "map",
                "cloud",
                seq.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ][..],
            extra,
        ]
        .concat();
        let r = common::omcl(&args);
        assert!(
            !r.ok() && r.output().contains(says) && !out.exists(),
            "{extra:?}: {}",
            r.output()
        );
    }
    // Options that would be ignored are refused.
    for (extra, says) in [
        (
            &["--labels", "x.label"][..],
            "--labels is for a single KITTI scan",
        ),
        (
            &["--max-rows", "2"][..],
            "with --classes the rows are the class table's",
        ),
        (
            &["--ort-lib", "/no/such.so"][..],
            "--ort-lib is for --point-model or --text-model",
        ),
    ] {
        let r = run(&shared("las/simple.las"), extra);
        assert!(
            !r.ok() && r.output().contains(says) && !out.exists(),
            "{extra:?}: {}",
            r.output()
        );
    }
}
