//! Writes the seed corpora of the fuzz targets into `fuzz/corpus/<target>/`:
//! small valid files of every format, from `tests/data/`, from the real data
//! in `../shared/data/` (cut to a few records) and from omcl's own writers.
//! Run once from the repository root (`cargo run --example fuzz_corpus`);
//! the corpora are committed, and crash inputs found later are added beside
//! the seeds.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use nalgebra::Vector3;
use omcl::io::cloud::PointCloud;
use omcl::map::features::FeatureDb;
use omcl::map::key::GridSpec;
use omcl::map::octree::LanguageMap;

fn out(target: &str, name: &str, bytes: &[u8]) -> Result<()> {
    let dir = PathBuf::from("fuzz/corpus").join(target);
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join(name), bytes).with_context(|| format!("{target}/{name}"))
}

fn first_lines(path: &Path, n: usize) -> Result<Vec<u8>> {
    let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    let mut s: String = text.lines().take(n).collect::<Vec<_>>().join("\n");
    s.push('\n');
    Ok(s.into_bytes())
}

fn png(
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) -> Vec<u8> {
    let mut buf = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut buf, width, height);
        enc.set_color(color);
        enc.set_depth(depth);
        let mut w = enc.write_header().expect("png header");
        w.write_image_data(data).expect("png data");
    }
    buf
}

fn main() -> Result<()> {
    let io = Path::new("tests/data/io");
    let shared = Path::new("../shared/data");

    for f in [
        "plyfile_ascii_rgb_label.ply",
        "plyfile_binbe_rgb_scalar_label.ply",
        "plyfile_binle_double_class_feat.ply",
    ] {
        out("ply", f, &std::fs::read(io.join(f))?)?;
    }
    let tmp = tempfile::tempdir()?;
    let cloud = PointCloud {
        points: vec![[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]],
        labels: Some(vec![1, 2]),
        colors: Some(vec![[1, 2, 3], [4, 5, 6]]),
        features: Some((2, vec![0.5, 0.5, 1.0, 0.0])),
        notes: Vec::new(),
        left_out: Vec::new(),
        georef: None,
    };
    let p = tmp.path().join("w.ply");
    omcl::io::ply::write_ply(&p, &cloud)?;
    out("ply", "omcl_binle_feat.ply", &std::fs::read(&p)?)?;

    // ply_header (`ply_from`'s draws): ascii, count kind 0 -> 1 vertex, no
    // face element, 3 properties x y z, each a float (type 0) and a scalar
    // (list byte 1), no features, then one vertex line.
    out(
        "ply_header",
        "ascii_one_vertex",
        b"\x00\x00\x01\x01\x00\x00\x01\x00\x01\x00\x01\x011 2 3\n",
    )?;
    // binary little endian, 2 vertices of 3 floats.
    let mut b = b"\x01\x00\x02\x01\x00\x00\x01\x00\x01\x00\x01\x01".to_vec();
    for v in [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    out("ply_header", "binle_two_vertices", &b)?;

    out(
        "las",
        "laspy_pf3_rgb.las",
        &std::fs::read(io.join("laspy_pf3_rgb.las"))?,
    )?;
    out(
        "las",
        "laspy_14_pf6.las",
        &std::fs::read(io.join("laspy_14_pf6_extended_class.las"))?,
    )?;
    out(
        "laz",
        "laspy_pf3_rgb.laz",
        &std::fs::read(io.join("laspy_pf3_rgb.laz"))?,
    )?;
    out(
        "laz",
        "simple.laz",
        &std::fs::read(shared.join("las/simple.laz"))?,
    )?;
    // las_header: offset 227, format 0, base record length, 2 points.
    let mut b = vec![1u8, 0, 0, 1, 0, 2];
    b.extend(std::iter::repeat_n(0u8, 40));
    out("las_header", "format0_two_points", &b)?;

    let scan = std::fs::read(shared.join("semantickitti/sequences/00/velodyne/000000.bin"))?;
    out("kitti_bin", "real_000000_first200.bin", &scan[..200 * 16])?;
    let labels = std::fs::read(shared.join("semantickitti/sequences/00/labels/000000.label"))?;
    let mut b = vec![50u8];
    b.extend_from_slice(&labels[..50 * 4]);
    out("kitti_label", "real_000000_first50", &b)?;
    out(
        "kitti_calib",
        "real_calib.txt",
        &std::fs::read(shared.join("semantickitti/sequences/00/calib.txt"))?,
    )?;
    out(
        "poses_tum",
        "fr1_xyz_first20.txt",
        &first_lines(
            &shared.join("trajectories/freiburg1_xyz-groundtruth.txt"),
            24,
        )?,
    )?;
    out(
        "poses_kitti",
        "kitti00_first20.txt",
        &first_lines(&shared.join("trajectories/KITTI_00_gt.txt"), 20)?,
    )?;
    out(
        "times",
        "kitti00_first20.txt",
        &first_lines(&shared.join("trajectories/KITTI_00_gt_times.txt"), 20)?,
    )?;
    let scannet = std::fs::read(shared.join("pointclouds/scannet_scene0000_00_xyzrgb.bin"))?;
    out("scannet", "real_first100.bin", &scannet[..100 * 24])?;

    let p = tmp.path().join("a.npy");
    omcl::io::npy::write_npy(&p, &[2, 3], &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0])?;
    out("npy", "f4_2x3.npy", &std::fs::read(&p)?)?;
    out(
        "npy",
        "f2_mnist.npy",
        &std::fs::read("tests/data/encode/mnist_pil_pixels.npy")?,
    )?;
    let mut b = vec![0u8, 2, 0, 2, 0, 3, 1];
    for v in [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    out("npy_header", "f4_2x3", &b)?;

    let depth: Vec<u8> = (0..48u16)
        .flat_map(|v| (1000 + v * 10).to_be_bytes())
        .collect();
    out(
        "png_depth",
        "d16_8x6.png",
        &png(
            8,
            6,
            png::ColorType::Grayscale,
            png::BitDepth::Sixteen,
            &depth,
        ),
    )?;
    let lab: Vec<u8> = (0..48u16).flat_map(|v| (v % 5).to_be_bytes()).collect();
    out(
        "png_label",
        "l16_8x6.png",
        &png(
            8,
            6,
            png::ColorType::Grayscale,
            png::BitDepth::Sixteen,
            &lab,
        ),
    )?;
    let lab8: Vec<u8> = (0..48u8).map(|v| v % 3).collect();
    out(
        "png_label",
        "l8_8x6.png",
        &png(8, 6, png::ColorType::Grayscale, png::BitDepth::Eight, &lab8),
    )?;
    // png_rgb, and image_bytes (a frame's PNG or JPEG bytes, as `omcl
    // serve` takes them) the same PNGs; image_bytes also gets the first
    // real 7-Scenes colour frame cut to 16 x 12 as a colour and a grey JPEG.
    let rgb: Vec<u8> = (0..144u8).collect();
    for target in ["png_rgb", "image_bytes"] {
        out(
            target,
            "rgb8_8x6.png",
            &png(8, 6, png::ColorType::Rgb, png::BitDepth::Eight, &rgb),
        )?;
        out(
            target,
            "tiny_image_input.png",
            &std::fs::read("tests/data/encode/tiny_image_input.png")?,
        )?;
    }
    let kitchen = omcl::io::rgb::read_rgb(&shared.join("rgbd_7scenes/frame-000000.color.jpg"))?;
    let small = image::imageops::resize(&kitchen, 16, 12, image::imageops::FilterType::Triangle);
    let jpeg = |img: image::DynamicImage| -> Result<Vec<u8>> {
        let mut buf = std::io::Cursor::new(Vec::new());
        img.write_to(&mut buf, image::ImageFormat::Jpeg)?;
        Ok(buf.into_inner())
    };
    let colour = image::DynamicImage::ImageRgb8(small);
    out("image_bytes", "kitchen_16x12.jpg", &jpeg(colour.clone())?)?;
    out(
        "image_bytes",
        "kitchen_16x12_grey.jpg",
        &jpeg(image::DynamicImage::ImageLuma8(colour.to_luma8()))?,
    )?;

    // png_header: 8 x 6 grey 8-bit, not interlaced, then 6 rows of a filter
    // byte and 8 pixels; and a 4 x 2 RGB 8-bit.
    let mut b = vec![0u8, 7, 0, 5, 0, 0, 0];
    for r in 0..6u8 {
        b.push(0);
        b.extend((0..8u8).map(|x| x * 10 + r));
    }
    out("png_header", "grey8_8x6", &b)?;
    let mut b = vec![0u8, 3, 0, 1, 0, 1, 0];
    for r in 0..2u8 {
        b.push(0);
        b.extend((0..12u8).map(|x| x * 7 + r));
    }
    out("png_header", "rgb8_4x2", &b)?;
    out(
        "intrinsics",
        "plain.txt",
        b"525.0 525.0 319.5 239.5 640 480\n",
    )?;
    out(
        "intrinsics",
        "commented.txt",
        b"# fx fy cx cy width height\n540 540 270 270 540 540\n",
    )?;

    for f in [
        "tiny_image",
        "tiny_text",
        "tiny_point",
        "tiny_image_dyn",
        "tiny_text_mask",
    ] {
        let name = format!("{f}.card.json");
        out(
            "model_card",
            &name,
            &std::fs::read(Path::new("tests/data/encode").join(&name))?,
        )?;
    }

    let list = b"0 floor\n1 wall\n2 tv monitor\n";
    let p = tmp.path().join("e.npy");
    omcl::io::npy::write_npy(&p, &[3, 2], &[1.0, 0.0, 0.0, 1.0, 0.6, 0.8])?;
    let mut b = vec![(list.len() + 1) as u8];
    b.extend_from_slice(list);
    b.extend_from_slice(&std::fs::read(&p)?);
    out("class_table", "three_classes", &b)?;

    let db = FeatureDb::from_rows(3, 0.05, vec![1.0, 0.0, 0.0, 0.0, 0.6, 0.8])?;
    let grid = GridSpec {
        resolution: 0.05,
        origin: Vector3::new(-1.5, 0.25, 3.0),
    };
    let map = LanguageMap::from_cells(
        grid,
        db,
        "none",
        vec![([0, 0, 0], 0), ([-3, 7, 2], 1), ([10, -10, 5], 1)],
    )?;
    out(
        "omcl_map",
        "three_voxels.omcl",
        &omcl::map::file::to_bytes(&map),
    )?;
    // A floor plan of two columns, the wall's row and a mixture's, as
    // `omcl map floorplan` writes it.
    let db = FeatureDb::from_rows(3, 0.05, vec![0.0, 1.0, 0.0, 0.0, 0.6, 0.8])?;
    let plan = omcl::map::FloorPlan::from_parts(
        0.05,
        [-1.5, 0.25],
        3.0,
        omcl::map::FloorPlanParams::default(),
        db,
        "none",
        vec![[0, 0], [-3, 7]],
        vec![0, 1],
    )?;
    out(
        "floor_plan",
        "two_columns.plan",
        &omcl::map::floorplan::to_bytes(&plan),
    )?;
    // The same two columns as `floor_plan_fields` draws them: version 1,
    // resolution 0.05, origin (-1.5, 0), floor 0, band 0 to 2 m, dimension
    // 3, tau 0.05, 2 columns, 2 rows, the promised shapes; cells (0, 0) and
    // (1, 0), rows 0 and 1, features (1, 0, 0) and (0, 1, 0).
    out(
        "floor_plan_fields",
        "two_columns",
        &[
            0, 9, 1, 0, 0, 0, 8, 2, 2, 0, 2, 2, 2, 1, 8, 1, 8, 1, 9, 1, 8, 1, 0, 1, 1, 4, 192, 4,
            128, 4, 128, 4, 128, 4, 192, 4, 128,
        ],
    )?;
    println!("corpora written to fuzz/corpus/");
    Ok(())
}
