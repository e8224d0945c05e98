//! The map commands with ONNX encoders as feature sources (real inference
//! through ONNX Runtime on the committed tiny models).

mod common;

use omcl::encode::Encoder as _;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use omcl::encode::{ImageEncoder, Runtime, TextEncoder};
use omcl::map::{self, FeatureDb, GridSpec, LanguageMap};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/encode")
        .join(name)
}

fn omcl(args: &[&str]) -> (bool, String) {
    let r = common::omcl(args);
    (r.ok(), r.output())
}

#[test]
fn ground_and_query_with_a_text_encoder() {
    let rt = Runtime::init(None).unwrap_or_else(|e| panic!("{e}"));
    let mut enc = TextEncoder::load(rt, &data("tiny_text.onnx"), 1).unwrap();
    let f = enc.encode(&["a red chair", "an old table"]).unwrap();
    // A map whose rows are the two phrases' features and a third direction.
    let mut rows: Vec<f32> = f.concat();
    let mut other = vec![0.0f32; 4];
    // Orthogonal-ish third row: the component of e0 not explained by the two.
    other[0] = 1.0;
    rows.extend(other);
    let db = FeatureDb::from_rows(4, 0.0, rows).unwrap();
    let grid = GridSpec {
        resolution: 1.0,
        origin: Vector3::zeros(),
    };
    let leaves = (0..30).map(|i| ([i, 0, 0], (i % 3) as u32));
    let m = LanguageMap::from_cells(grid, db, "tiny_text", leaves).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.omcl");
    map::save(&m, &p).unwrap();
    let model = data("tiny_text.onnx");
    let g = dir.path().join("g.omcl");
    let (ok, text) = omcl(&[
        "map",
        "ground",
        p.to_str().unwrap(),
        "a red chair",
        "--text-model",
        model.to_str().unwrap(),
        "--min-similarity",
        "0.999",
        "-o",
        g.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let grounded = map::load(&g).unwrap();
    // Exactly the voxels of row 0 ("a red chair") are kept (plus any row
    // that happens to be as similar, which the check below would reveal).
    let sim = m.similarity(&f[0]).unwrap();
    assert_eq!(grounded.len(), sim.iter().filter(|&&s| s >= 0.999).count());
    assert!(grounded.len() >= 10);

    let heat = dir.path().join("h.ply");
    let (ok, text) = omcl(&[
        "map",
        "query",
        p.to_str().unwrap(),
        "an old table",
        "--text-model",
        model.to_str().unwrap(),
        "-o",
        heat.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let cloud = omcl::io::ply::read_ply(&heat).unwrap();
    let cols = cloud.colors.unwrap();
    for (i, c) in cols.iter().enumerate() {
        if i % 3 == 1 {
            assert!(
                c[0] > 200 && c[2] < 60,
                "voxel {i} of row 1 should be hottest: {c:?}"
            );
        }
    }
    // Without any word source: a clear error.
    let (ok, text) = omcl(&[
        "map",
        "query",
        p.to_str().unwrap(),
        "x",
        "-o",
        heat.to_str().unwrap(),
    ]);
    assert!(!ok && text.contains("--text-model"), "{text}");
}

fn write_png(
    path: &Path,
    w: u32,
    h: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) {
    let f = std::fs::File::create(path).unwrap();
    let mut e = png::Encoder::new(std::io::BufWriter::new(f), w, h);
    e.set_color(color);
    e.set_depth(depth);
    e.write_header().unwrap().write_image_data(data).unwrap();
}

#[test]
fn rgbd_mapping_with_an_image_encoder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (16u32, 16u32);
    std::fs::create_dir_all(d.join("rgb")).unwrap();
    std::fs::create_dir_all(d.join("depth")).unwrap();
    std::fs::write(d.join("intrinsics.txt"), "16 16 8 8 16 16\n").unwrap();
    std::fs::write(d.join("poses.txt"), "0 0 0 0 0 0 0 1\n").unwrap();
    // A wall 2 m in front (z-depth 2 m = 10000 units of 1/5000 m).
    let depth: Vec<u8> = (0..w * h).flat_map(|_| 10000u16.to_be_bytes()).collect();
    write_png(
        &d.join("depth/000000.png"),
        w,
        h,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &depth,
    );
    let rgb: Vec<u8> = (0..w * h)
        .flat_map(|i| [(i * 7 % 256) as u8, (i * 13 % 256) as u8, 90])
        .collect();
    write_png(
        &d.join("rgb/000000.png"),
        w,
        h,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &rgb,
    );
    let out = d.join("m.omcl");
    let model = data("tiny_image.onnx");
    let cache = d.join("cache");
    let (ok, text) = omcl(&[
        "map",
        "rgbd",
        d.to_str().unwrap(),
        "--image-model",
        model.to_str().unwrap(),
        "--feature-cache",
        cache.to_str().unwrap(),
        "--stride",
        "1",
        "--resolution",
        "0.1",
        "--tau",
        "0.0005",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let m = map::load(&out).unwrap();
    assert_eq!(m.encoder(), "tiny_image");
    assert_eq!(m.db().dim(), 4);
    assert!(!m.is_empty());
    // Every voxel sits on the wall plane z = 2 m (cell 19 or 20 at 0.1 m).
    assert!(
        m.cells().iter().all(|c| c[2] == 19 || c[2] == 20),
        "{:?}",
        m.cells()
    );
    assert!(cache.join("000000.npy").exists(), "features were cached");
    // Every map row is a mean of encoded pixel features: close to some pixel.
    let rt = Runtime::init(None).unwrap();
    let mut enc = ImageEncoder::load(rt, &model, 1).unwrap();
    let img = omcl::io::rgb::read_rgb(&d.join("rgb/000000.png")).unwrap();
    let fm = enc.encode(&img).unwrap();
    // The same encoder drives the localizer from raw RGB (one frame).
    let est = d.join("est.txt");
    let (ok, text) = omcl(&[
        "localize",
        "--map",
        out.to_str().unwrap(),
        "--sequence",
        d.to_str().unwrap(),
        "--image-model",
        model.to_str().unwrap(),
        "--particles",
        "16",
        "--rays",
        "32",
        "--boundary-margin",
        "1",
        "--init-sigma-m",
        "0.05",
        "--diagnostics",
        d.join("diag.csv").to_str().unwrap(),
        "-o",
        est.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    // Frame rates with and without the encoder; the encoder's time per
    // frame in the diagnostics.
    assert!(
        text.contains("filter steps/s")
            && text.contains("with reading the frames and the image encoder"),
        "{text}"
    );
    let diag = std::fs::read_to_string(d.join("diag.csv")).unwrap();
    let mut rows = diag.lines();
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    let col = header.iter().position(|&c| c == "input_ms").unwrap();
    let row: Vec<&str> = rows.next().unwrap().split(',').collect();
    let input_ms: f64 = row[col].parse().unwrap();
    assert!(input_ms > 0.0, "{diag}");
    let lines: Vec<String> = std::fs::read_to_string(&est)
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    assert_eq!(
        lines.iter().filter(|l| !l.starts_with('#')).count(),
        1,
        "{lines:?}"
    );
    assert!(text.contains("APE rmse"), "{text}");
    for r in 0..m.db().len() {
        let row = m.db().row(r);
        let best = (0..h)
            .flat_map(|v| (0..w).map(move |u| (u, v)))
            .filter_map(|(u, v)| fm.at_pixel(u, v))
            .map(|f| omcl::map::features::dot(row, f) / omcl::map::features::dot(f, f).sqrt())
            .fold(f32::MIN, f32::max);
        assert!(
            best > 0.9,
            "row {r} is far from every pixel feature: {best}"
        );
    }

    // The cache holds frame 0 of this image; another image of frame 0
    // (another sequence, or the image changed) is encoded anew: the map
    // equals one built without the cache. It had been painted with the
    // cached features.
    let rgb2: Vec<u8> = (0..w * h)
        .flat_map(|i| [(i * 13 % 256) as u8, (i * 7 % 256) as u8, 90])
        .collect();
    write_png(
        &d.join("rgb/000000.png"),
        w,
        h,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &rgb2,
    );
    let build = |out: &Path, cache: Option<&Path>| {
        let mut args: Vec<String> = [
            "map",
            "rgbd",
            d.to_str().unwrap(),
            "--image-model",
            model.to_str().unwrap(),
            "--stride",
            "1",
            "--resolution",
            "0.1",
            "--tau",
            "0.0005",
            "-o",
            out.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec();
        if let Some(c) = cache {
            args.extend(["--feature-cache".into(), c.to_str().unwrap().into()]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        omcl(&args)
    };
    let (cached, fresh) = (d.join("cached.omcl"), d.join("fresh.omcl"));
    let (ok, text) = build(&cached, Some(&cache));
    assert!(ok, "{text}");
    let (ok, text) = build(&fresh, None);
    assert!(ok, "{text}");
    let (a, b) = (map::load(&cached).unwrap(), map::load(&fresh).unwrap());
    assert_eq!(a.db().rows(), b.db().rows());
    assert_eq!(a.rows(), b.rows());
    assert_ne!(
        a.db().rows(),
        m.db().rows(),
        "the new image's features differ"
    );

    // A cache in the sequence's frame folders, or the folder itself, is
    // refused: `features/` holds a user's feature grids.
    for bad in [d.join("features"), d.join("rgb"), d.to_path_buf()] {
        let (ok, text) = build(&d.join("x.omcl"), Some(&bad));
        assert!(!ok && text.contains("--feature-cache"), "{text}");
    }
    assert!(!d.join("features").exists());

    // A colour image of another size than the intrinsics' is refused by
    // name, by the map and by the localizer (it had mapped part of it).
    let small: Vec<u8> = rgb2[..(w * h * 3 / 4) as usize].to_vec();
    write_png(
        &d.join("rgb/000000.png"),
        w / 2,
        h / 2,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &small,
    );
    let (ok, text) = build(&d.join("y.omcl"), None);
    assert!(
        !ok && text.contains("rgb/000000.png: 8x8 pixels, intrinsics say 16x16"),
        "{text}"
    );
    let localize = |extra: &[&str]| {
        let mut args = vec![
            "localize",
            "--map",
            out.to_str().unwrap(),
            "--sequence",
            d.to_str().unwrap(),
            "--image-model",
            model.to_str().unwrap(),
            "--particles",
            "16",
            "--rays",
            "32",
            "-o",
        ];
        args.extend_from_slice(extra);
        omcl(&args)
    };
    let est2 = d.join("est2.txt");
    let (ok, text) = localize(&[est2.to_str().unwrap()]);
    assert!(
        !ok && text.contains("8 x 8 pixels") && text.contains("intrinsics.txt says 16 x 16"),
        "{text}"
    );
    // Two frames but one pose: refused, not a run of the first frame.
    write_png(
        &d.join("rgb/000000.png"),
        w,
        h,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &rgb2,
    );
    std::fs::copy(d.join("rgb/000000.png"), d.join("rgb/000001.png")).unwrap();
    std::fs::copy(d.join("depth/000000.png"), d.join("depth/000001.png")).unwrap();
    let (ok, text) = localize(&[est2.to_str().unwrap()]);
    assert!(
        !ok && text.contains("2 frames in") && text.contains("--frames 1"),
        "{text}"
    );
    assert!(!est2.exists());
    let (ok, text) = localize(&[est2.to_str().unwrap(), "--frames", "1"]);
    assert!(ok, "{text}");
}

/// `omcl map cloud --classes asprs --text-model`: the class names are
/// embedded by the text encoder, the map's rows are those features and the
/// map is named after the encoder.
#[test]
fn a_builtin_class_list_embedded_by_a_text_encoder() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("c.ply");
    // Two well separated groups: ASPRS 2 (ground) at x < 0, 6 (building) at x > 5.
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 40\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar classification\nend_header\n",
    );
    for i in 0..20 {
        text.push_str(&format!("{} 0.5 0.5 2\n", -(i as f32) - 0.5));
        text.push_str(&format!("{} 0.5 0.5 6\n", i as f32 + 5.5));
    }
    std::fs::write(&ply, text).unwrap();
    let out = dir.path().join("m.omcl");
    let model = data("tiny_text.onnx");
    let (ok, text) = omcl(&[
        "map",
        "cloud",
        ply.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--resolution",
        "1",
        // The tiny model's features of two words are within the default
        // tau of each other; keep every class its own row.
        "--tau",
        "0",
        "--classes",
        "asprs",
        "--text-model",
        model.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let m = map::load(&out).unwrap();
    let rt = Runtime::init(None).unwrap_or_else(|e| panic!("{e}"));
    let mut enc = TextEncoder::load(rt, &model, 1).unwrap();
    let f = enc.encode(&["ground", "building"]).unwrap();
    assert_eq!(m.encoder(), enc.card().name);
    assert_eq!(m.db().dim(), f[0].len());
    assert_eq!(m.len(), 40);
    // Each voxel's row is the encoder's feature of its class name.
    let g = m.similarity(&f[0]).unwrap();
    let b = m.similarity(&f[1]).unwrap();
    // (The tiny model's features of two words are close: compare which one
    // a voxel is closest to, and that each at its best is 1.)
    let ground = g.iter().zip(&b).filter(|(sg, sb)| sg > sb).count();
    let building = g.iter().zip(&b).filter(|(sg, sb)| sb > sg).count();
    assert_eq!((ground, building), (20, 20));
    let best = |s: &[f32]| s.iter().copied().fold(f32::MIN, f32::max);
    assert!(best(&g) > 0.99999 && best(&b) > 0.99999, "{g:?} {b:?}");
}
