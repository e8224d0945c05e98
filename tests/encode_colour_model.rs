//! The colour-class encoder omcl writes as ONNX, run by ONNX Runtime on
//! real 7-Scenes pixels, against the pure-Rust reference of the same Lab
//! and nearest-centroid computation.

use omcl::encode::Encoder as _;
use std::path::{Path, PathBuf};

use omcl::encode::colour::{ColourClasses, srgb8_to_lab};
use omcl::encode::runtime::InputData;
use omcl::encode::{ImageEncoder, OnnxModel, Runtime};
use omcl::experiment::sevenscenes::{lab_samples, write_colour_model};
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

fn rt() -> &'static Runtime {
    Runtime::init(None).unwrap_or_else(|e| panic!("{e}"))
}

/// Classes fitted on the even frames 0..40 of the real sequence.
fn fitted(seq: &SevenScenes) -> ColourClasses {
    let images: Vec<_> = (0..40)
        .step_by(2)
        .map(|i| seq.read_color(i).unwrap())
        .collect();
    ColourClasses::fit(&lab_samples(&images, 8), 10, 32, 50, 7).unwrap()
}

fn score(c: &ColourClasses, lab: &[f32; 3], k: usize) -> f32 {
    let m = c.centroids[k];
    2.0 * (lab[0] * m[0] + lab[1] * m[1] + lab[2] * m[2])
        - (m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
}

#[test]
fn onnx_graph_matches_the_rust_reference_on_real_pixels() {
    let seq = SevenScenes::open(&scenes()).unwrap();
    let classes = fitted(&seq);
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("colour.onnx");
    write_colour_model(&classes, (320, 240), &model).unwrap();
    let mut onnx = OnnxModel::load(rt(), &model, 1).unwrap();
    // Frame 41: odd, not among the fitting frames; every pixel at full size.
    let img = seq.read_color(41).unwrap();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let mut chw = vec![0f32; 3 * w * h];
    for (i, p) in img.pixels().enumerate() {
        for c in 0..3 {
            chw[c * w * h + i] = p.0[c] as f32 / 255.0;
        }
    }
    let out = onnx
        .run(
            vec![("rgb", &[1, 3, h, w][..], InputData::F32(chw))],
            &["lab", "features"],
        )
        .unwrap();
    assert_eq!(out[0].shape, vec![1, h, w, 3]);
    assert_eq!(out[1].shape, vec![1, h, w, 32]);
    let (mut max_lab, mut disagree, mut worst_gap) = (0f32, 0usize, 0f32);
    let mut seen = vec![false; classes.len()];
    for (i, p) in img.pixels().enumerate() {
        let want = srgb8_to_lab(p.0);
        let got = &out[0].data[3 * i..3 * i + 3];
        for c in 0..3 {
            max_lab = max_lab.max((want[c] - got[c]).abs());
        }
        let f = &out[1].data[32 * i..32 * i + 32];
        // The output is exactly one class's embedding.
        let k = (0..classes.len())
            .find(|&k| classes.embedding(k) == f)
            .expect("feature is not an embedding row");
        seen[k] = true;
        let r = classes.classify(p.0);
        if k != r {
            disagree += 1;
            // Only a near tie may go the other way.
            worst_gap =
                worst_gap.max((score(&classes, &want, r) - score(&classes, &want, k)).abs());
        }
    }
    eprintln!(
        "max |Lab onnx - Lab rust| = {max_lab:.2e}; {disagree} of {} pixels in another class \
         (score gap at most {worst_gap:.2e})",
        w * h
    );
    assert!(max_lab < 1e-3, "Lab differs by {max_lab}");
    assert!(disagree * 10_000 <= w * h, "{disagree} pixels disagree");
    assert!(worst_gap < 0.05, "a disagreement is no tie: {worst_gap}");
    assert!(seen.iter().filter(|&&s| s).count() >= 5, "{seen:?}");
}

#[test]
fn the_card_makes_it_an_image_encoder_of_box_averaged_pixels() {
    let seq = SevenScenes::open(&scenes()).unwrap();
    let classes = fitted(&seq);
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("colour.onnx");
    write_colour_model(&classes, (320, 240), &model).unwrap();
    let mut enc = ImageEncoder::load(rt(), &model, 1).unwrap();
    assert_eq!(enc.feature_dim(), 32);
    // Classes, dimension and the model's CRC-32: another fit is another
    // name.
    let name = enc.card().name.clone();
    let crc = crc32fast::hash(&std::fs::read(&model).unwrap());
    assert_eq!(name, format!("omcl-colour-lab-k10-d32-{crc:08x}"));
    let img = seq.read_color(41).unwrap();
    let fm = enc.encode(&img).unwrap();
    assert_eq!(fm.shape(), [240, 320, 32]);
    assert_eq!(fm.cell_size, [2.0, 2.0]);
    // Each cell is the class of its 2 x 2 pixels' box average (Pillow's
    // box filter on exact halves: the rounded mean of the four).
    let mut agree = 0;
    for r in 0..240u32 {
        for c in 0..320u32 {
            let mut m = [0u32; 3];
            for (du, dv) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let p = img.get_pixel(2 * c + du, 2 * r + dv).0;
                (0..3).for_each(|k| m[k] += p[k] as u32);
            }
            let avg = m.map(|s| ((s as f32 / 4.0).round()) as u8);
            let f = fm.cell(r as usize, c as usize).unwrap();
            let want = classes.embedding(classes.classify(avg));
            let dot: f32 = f.iter().zip(want).map(|(a, b)| a * b).sum();
            agree += usize::from(dot > 0.9999);
        }
    }
    let share = agree as f64 / (240.0 * 320.0);
    eprintln!(
        "{:.4} of the cells agree with the reference on box-averaged pixels",
        share
    );
    assert!(share > 0.99, "{share}");
}
