//! Real inference through ONNX Runtime (the library `make deps` installs):
//! a trained model nobody here made, and tiny models from
//! tools/make_encoder_testdata.py whose expected outputs numpy computed.

mod common;

use common::shared;

use omcl::encode::Encoder as _;
use std::path::{Path, PathBuf};

use omcl::encode::card::ModelCard;
use omcl::encode::runtime::InputData;
use omcl::encode::{
    EncodeError, FeatureCache, ImageEncoder, OnnxModel, PointEncoder, Runtime, TextEncoder,
};
use omcl::io::npy::read_npy;
use omcl::io::rgb::{read_luma, read_rgb};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/encode")
        .join(name)
}

fn rt() -> &'static Runtime {
    Runtime::init(None).unwrap_or_else(|e| panic!("{e}"))
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0f32, f32::max)
}

#[test]
fn mnist_model_reproduces_onnxruntime_python_logits() {
    let dir = shared("onnx");
    let mut model = OnnxModel::load(rt(), &dir.join("opt-mnist.onnx"), 1).unwrap();
    assert_eq!(model.input(None).unwrap().dims_text(), "[1, 1, 28, 28]");
    let reference = std::fs::read_to_string(dir.join("reference_outputs.txt")).unwrap();
    // Pillow-decoded pixels of the same four images (what the reference used).
    let pil = read_npy(&data("mnist_pil_pixels.npy")).unwrap();
    assert_eq!(pil.shape, vec![4, 28, 28]);
    let mut checked = 0;
    for line in reference
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let mut parts = line.split_whitespace();
        let file = parts.next().unwrap();
        let argmax: usize = parts
            .next()
            .unwrap()
            .trim_start_matches("argmax=")
            .parse()
            .unwrap();
        let logits: Vec<f32> = std::iter::once(parts.next().unwrap().trim_start_matches("logits="))
            .chain(parts)
            .map(|v| v.parse().unwrap())
            .collect();
        // Same pixels as the reference: the ort path must agree to float
        // rounding.
        let x = pil.data[checked * 784..(checked + 1) * 784].to_vec();
        let out = model
            .run(
                vec![("Input3", &[1, 1, 28, 28][..], InputData::F32(x))],
                &["Plus214_Output_0"],
            )
            .unwrap();
        assert_eq!(out[0].shape, vec![1, 10]);
        assert!(
            max_diff(&out[0].data, &logits) < 1e-4,
            "{file}: {:?} vs {logits:?}",
            out[0].data
        );
        // Our own JPEG decoding differs from libjpeg-turbo by at most one grey
        // level on a few pixels: the class and the logits barely move.
        let (w, h, px) = read_luma(&dir.join(file)).unwrap();
        assert_eq!((w, h), (28, 28));
        let x: Vec<f32> = px.iter().map(|&v| f32::from(v) / 255.0).collect();
        let out = model
            .run(
                vec![("Input3", &[1, 1, 28, 28][..], InputData::F32(x))],
                &["Plus214_Output_0"],
            )
            .unwrap();
        let got = &out[0].data;
        let best = (0..10).max_by(|&a, &b| got[a].total_cmp(&got[b])).unwrap();
        assert_eq!(best, argmax, "{file}");
        assert!(
            max_diff(got, &logits) < 0.05,
            "{file}: {got:?} vs {logits:?}"
        );
        checked += 1;
    }
    assert_eq!(checked, 4);
}

#[test]
fn wrong_input_shape_and_missing_names_are_clear_errors() {
    let mut model = OnnxModel::load(rt(), &data("tiny_image.onnx"), 1).unwrap();
    let e = model
        .run(
            vec![("image", &[1, 3, 9, 8][..], InputData::F32(vec![0.0; 216]))],
            &["features"],
        )
        .unwrap_err();
    assert!(matches!(e, EncodeError::Shape { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("[1, 3, 8, 8]") && msg.contains("tiny_image.onnx"),
        "{msg}"
    );
    let e = model
        .run(
            vec![("pixels", &[1, 3, 8, 8][..], InputData::F32(vec![0.0; 192]))],
            &["features"],
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("`pixels`") && e.contains("image"), "{e}");
}

#[test]
fn a_file_that_is_not_onnx_is_named_as_such() {
    let e = OnnxModel::load(rt(), &data("not_a_model.onnx"), 1)
        .err()
        .unwrap();
    assert!(matches!(e, EncodeError::NotOnnx { .. }), "{e}");
    assert!(e.to_string().contains("not_a_model.onnx"));
    let e = OnnxModel::load(rt(), &data("no_such_model.onnx"), 1)
        .err()
        .unwrap();
    assert!(matches!(e, EncodeError::Io { .. }), "{e}");
}

#[test]
fn image_encoder_stitches_sliding_windows_like_the_whole_image() {
    let mut enc = ImageEncoder::load(rt(), &data("tiny_image.onnx"), 1).unwrap();
    let img = read_rgb(&data("tiny_image_input.png")).unwrap();
    assert_eq!((img.width(), img.height()), (22, 13));
    let map = enc.encode(&img).unwrap();
    let want = read_npy(&data("tiny_image_expected.npy")).unwrap();
    assert_eq!(want.shape, vec![7, 11, 4]);
    assert_eq!(map.shape(), [7, 11, 4]);
    assert!(
        max_diff(&map.data, &want.data) < 1e-5,
        "max diff {}",
        max_diff(&map.data, &want.data)
    );
    // 2x2 pooling: each cell covers 2x2 image pixels.
    assert_eq!(map.cell_size, [2.0, 2.0]);
    assert_eq!(map.cell_of_pixel(21, 12), Some((6, 10)));
    assert_eq!(map.at_pixel(3, 5), map.cell(2, 1));
}

#[test]
fn image_encoder_resizes_like_pillow_and_reads_channel_last() {
    let mut enc = ImageEncoder::load(rt(), &data("tiny_image_dyn.onnx"), 1).unwrap();
    let img = read_rgb(&data("tiny_image_input.png")).unwrap();
    let map = enc.encode(&img).unwrap();
    let want = read_npy(&data("tiny_image_dyn_expected.npy")).unwrap();
    assert_eq!(map.shape(), [7, 10, 5]);
    assert!(
        max_diff(&map.data, &want.data) < 1e-4,
        "max diff {}",
        max_diff(&map.data, &want.data)
    );
    // 22x13 resized to 10x7: a cell spans 2.2 x 13/7 image pixels.
    assert!((map.cell_size[0] - 2.2).abs() < 1e-6 && (map.cell_size[1] - 13.0 / 7.0).abs() < 1e-6);
}

#[test]
fn image_encoder_errors_on_wrong_output_rank_dimension_and_input_size() {
    let img = read_rgb(&data("tiny_image_input.png")).unwrap();
    let mut flat = ImageEncoder::load(rt(), &data("tiny_flat.onnx"), 1).unwrap();
    let e = flat.encode(&img).unwrap_err();
    assert!(matches!(e, EncodeError::Shape { .. }), "{e}");
    assert!(e.to_string().contains("[1, 3]"), "{e}");

    let path = data("tiny_image.onnx");
    let mut card = ModelCard::for_model(&path).unwrap();
    card.feature_dim = 512;
    let mut enc = ImageEncoder::with_card(rt(), &path, card.clone(), 1).unwrap();
    let e = enc.encode(&img).unwrap_err();
    assert!(
        matches!(
            e,
            EncodeError::FeatureDim {
                got: 4,
                expected: 512,
                ..
            }
        ),
        "{e}"
    );

    // Without the window the 22x13 image does not fit the fixed 8x8 input.
    card.feature_dim = 4;
    card.image.as_mut().unwrap().window = None;
    let mut enc = ImageEncoder::with_card(rt(), &path, card, 1).unwrap();
    let e = enc.encode(&img).unwrap_err().to_string();
    assert!(
        e.contains("[1, 3, 13, 22]") && e.contains("[1, 3, 8, 8]"),
        "{e}"
    );

    // A text card on an image model.
    let e = ImageEncoder::with_card(
        rt(),
        &path,
        ModelCard::for_model(&data("tiny_text.onnx")).unwrap(),
        1,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("a text encoder, not an image encoder"), "{e}");
}

#[test]
fn text_encoder_feeds_clip_tokens_and_normalises() {
    let mut enc = TextEncoder::load(rt(), &data("tiny_text.onnx"), 1).unwrap();
    let got = enc
        .encode(&["a photo of a cat", "toilet, mirror, sink", "floor"])
        .unwrap();
    let want = read_npy(&data("tiny_text_expected.npy")).unwrap();
    assert_eq!(want.shape, vec![3, 4]);
    let flat: Vec<f32> = got.iter().flatten().copied().collect();
    assert!(
        max_diff(&flat, &want.data) < 1e-5,
        "{flat:?} vs {:?}",
        want.data
    );
    for v in &got {
        let n: f32 = v.iter().map(|x| x * x).sum::<f32>().sqrt();
        assert!((n - 1.0).abs() < 1e-5);
    }
    assert!(enc.encode(&[]).unwrap().is_empty());
}

#[test]
fn text_encoder_with_int32_mask_template_and_batch_of_one() {
    let mut enc = TextEncoder::load(rt(), &data("tiny_text_mask.onnx"), 1).unwrap();
    let got = enc.encode(&["chair", "sofa!"]).unwrap();
    let want = read_npy(&data("tiny_text_mask_expected.npy")).unwrap();
    let flat: Vec<f32> = got.iter().flatten().copied().collect();
    assert!(
        max_diff(&flat, &want.data) < 1e-5,
        "{flat:?} vs {:?}",
        want.data
    );
}

#[test]
fn point_encoder_matches_numpy_across_chunks() {
    let mut enc = PointEncoder::load(rt(), &data("tiny_point.onnx"), 1).unwrap();
    let p = read_npy(&data("tiny_point_points.npy")).unwrap();
    let c = read_npy(&data("tiny_point_colors.npy")).unwrap();
    let pts: Vec<[f32; 3]> = p.data.chunks_exact(3).map(|v| [v[0], v[1], v[2]]).collect();
    let cols: Vec<[f32; 3]> = c.data.chunks_exact(3).map(|v| [v[0], v[1], v[2]]).collect();
    let got = enc.encode(&pts, &cols).unwrap();
    let want = read_npy(&data("tiny_point_expected.npy")).unwrap();
    assert_eq!(want.shape, vec![20, 5]);
    assert!(max_diff(&got, &want.data) < 1e-5);
    let e = enc.encode(&pts, &cols[..3]).unwrap_err().to_string();
    assert!(e.contains("20 points but 3 colours"), "{e}");
}

#[test]
fn cached_features_are_reused_without_running_the_model() {
    let mut enc = ImageEncoder::load(rt(), &data("tiny_image.onnx"), 1).unwrap();
    let img = read_rgb(&data("tiny_image_input.png")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let model = omcl::encode::cache::model_stamp(&data("tiny_image.onnx")).unwrap();
    let image = omcl::encode::cache::stamp(&[&data("tiny_image_input.png")]).unwrap();
    let cache = FeatureCache::new(dir.path(), &enc.card().name, &model).unwrap();
    let first = cache
        .get_or_compute("000000", Some(&image), || enc.encode(&img))
        .unwrap();
    let again = cache
        .get_or_compute("000000", Some(&image), || {
            panic!("cached frame must not be recomputed")
        })
        .unwrap();
    assert_eq!(first, again);
    let want = read_npy(&data("tiny_image_expected.npy")).unwrap();
    assert!(max_diff(&again.data, &want.data) < 1e-5);
}
