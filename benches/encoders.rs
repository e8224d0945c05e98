//! Encoder throughput: the model alone (`OnnxModel::run` on a ready tensor)
//! against the whole encoder call (preprocessing, windows, layout changes,
//! normalisation), so the Rust pipeline's overhead around ONNX Runtime shows.
//! Models: the tiny test models of tests/data/encode/ and the real MNIST CNN
//! of ../shared/data/onnx/. Run: `cargo bench --bench encoders`.

use omcl::encode::Encoder as _;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use image::RgbImage;

use omcl::encode::card::{ModelCard, Resize};
use omcl::encode::preprocess::{self, CLIP_MEAN, CLIP_STD, Filter};
use omcl::encode::runtime::InputData;
use omcl::encode::{ClipTokenizer, ImageEncoder, OnnxModel, PointEncoder, Runtime, TextEncoder};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/encode")
        .join(name)
}

fn shared(rel: &str) -> Option<PathBuf> {
    let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data")).join(rel);
    p.exists().then_some(p)
}

/// A 640 x 480 test image with structure (not constant, not noise).
fn vga() -> RgbImage {
    RgbImage::from_fn(640, 480, |x, y| {
        image::Rgb([(x % 256) as u8, (y % 256) as u8, ((x * y) % 251) as u8])
    })
}

fn preprocessing(c: &mut Criterion) {
    let mut g = c.benchmark_group("preprocess");
    let img = shared("clip_tokenizer/franz-kafka.jpg")
        .and_then(|p| omcl::io::rgb::read_rgb(&p).ok())
        .unwrap_or_else(vga);
    g.throughput(Throughput::Elements(1));
    g.bench_function("clip_preprocess_450x655", |b| {
        b.iter(|| preprocess::clip_preprocess(black_box(&img)))
    });
    let img = vga();
    g.bench_function("resize_bicubic_640x480_to_520x390", |b| {
        b.iter(|| preprocess::resize(black_box(&img), 520, 390, Filter::Bicubic))
    });
    g.bench_function("normalize_chw_640x480", |b| {
        b.iter(|| preprocess::normalize_chw(black_box(&img), CLIP_MEAN, CLIP_STD))
    });
    g.finish();

    let tok = ClipTokenizer::new();
    let words = [
        "toilet",
        "mirror",
        "sink",
        "a photo of a chair",
        "sofa",
        "bed",
        "floor",
        "wall",
        "kitchen counter",
        "potted plant",
    ];
    let mut g = c.benchmark_group("tokenize");
    g.throughput(Throughput::Elements(words.len() as u64));
    g.bench_function("clip_10_prompts", |b| {
        b.iter(|| {
            for w in words {
                black_box(tok.tokenize(w, 77));
            }
        })
    });
    g.finish();
}

fn models(c: &mut Criterion) {
    let rt = match Runtime::init(None) {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("skipping model benchmarks: {e}");
            return;
        }
    };
    let mut g = c.benchmark_group("encoders");
    g.sample_size(20).measurement_time(Duration::from_secs(3));

    if let Some(dir) = shared("onnx") {
        let mut m = OnnxModel::load(rt, &dir.join("opt-mnist.onnx"), 1).expect("mnist");
        let x = vec![0.5f32; 784];
        g.throughput(Throughput::Elements(1));
        g.bench_function("mnist_run", |b| {
            b.iter(|| {
                m.run(
                    vec![("Input3", &[1, 1, 28, 28][..], InputData::F32(x.clone()))],
                    &["Plus214_Output_0"],
                )
                .expect("run")
            })
        });
    }

    // Per-pixel model on a whole 640 x 480 image: model alone vs encoder.
    let path = data("tiny_image_dyn.onnx");
    let mut card = ModelCard::for_model(&path).expect("card");
    if let Some(spec) = card.image.as_mut() {
        spec.resize = Resize::None;
    }
    let img = vga();
    let mut enc = ImageEncoder::with_card(rt, &path, card, 1).expect("encoder");
    let mut raw = OnnxModel::load(rt, &path, 1).expect("model");
    let x = preprocess::normalize_hwc(&img, CLIP_MEAN, CLIP_STD);
    g.throughput(Throughput::Elements(640 * 480));
    g.bench_function("image_per_pixel_640x480_model_only", |b| {
        b.iter(|| {
            raw.run(
                vec![("pixels", &[1, 480, 640, 3][..], InputData::F32(x.clone()))],
                &["feat"],
            )
            .expect("run")
        })
    });
    g.bench_function("image_per_pixel_640x480_encoder", |b| {
        b.iter(|| enc.encode(black_box(&img)).expect("encode"))
    });

    // Sliding 8x8 windows over 64 x 48 pixels: 165 model runs per image,
    // which measures the per-run cost of the window loop.
    let mut win = ImageEncoder::load(rt, &data("tiny_image.onnx"), 1).expect("encoder");
    let small = RgbImage::from_fn(64, 48, |x, y| image::Rgb([x as u8 * 4, y as u8 * 5, 9]));
    g.throughput(Throughput::Elements(1));
    g.bench_function("image_windows_64x48_165_runs", |b| {
        b.iter(|| win.encode(black_box(&small)).expect("encode"))
    });

    let mut text = TextEncoder::load(rt, &data("tiny_text.onnx"), 1).expect("text");
    let words = [
        "toilet",
        "mirror",
        "sink",
        "a photo of a chair",
        "sofa",
        "bed",
        "floor",
        "wall",
    ];
    g.throughput(Throughput::Elements(words.len() as u64));
    g.bench_function("text_8_prompts_encoder", |b| {
        b.iter(|| text.encode(black_box(&words)).expect("encode"))
    });
    let mut raw_text = OnnxModel::load(rt, &data("tiny_text.onnx"), 1).expect("model");
    let ids = vec![1i64; 8 * 77];
    g.bench_function("text_8_prompts_model_only", |b| {
        b.iter(|| {
            raw_text
                .run(
                    vec![("input_ids", &[8, 77][..], InputData::I64(ids.clone()))],
                    &["text_features"],
                )
                .expect("run")
        })
    });

    if let Some(cloud) = shared("pointclouds/scannet_scene0000_00_xyzrgb.bin") {
        let bytes = std::fs::read(cloud).expect("cloud");
        let v: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let pts: Vec<[f32; 3]> = v.chunks_exact(6).map(|r| [r[0], r[1], r[2]]).collect();
        let cols: Vec<[f32; 3]> = v
            .chunks_exact(6)
            .map(|r| [r[3] / 255.0, r[4] / 255.0, r[5] / 255.0])
            .collect();
        let path = data("tiny_point.onnx");
        let mut card = ModelCard::for_model(&path).expect("card");
        if let Some(p) = card.point.as_mut() {
            p.chunk = None;
        }
        let mut enc = PointEncoder::with_card(rt, &path, card, 1).expect("encoder");
        g.throughput(Throughput::Elements(pts.len() as u64));
        g.bench_function("points_scannet_40684_encoder", |b| {
            b.iter(|| {
                enc.encode(black_box(&pts), black_box(&cols))
                    .expect("encode")
            })
        });
        let mut raw = OnnxModel::load(rt, &path, 1).expect("model");
        let n = pts.len();
        let p: Vec<f32> = pts.iter().flatten().copied().collect();
        let c: Vec<f32> = cols.iter().flatten().copied().collect();
        g.bench_function("points_scannet_40684_model_only", |b| {
            b.iter(|| {
                raw.run(
                    vec![
                        ("points", &[1, n, 3][..], InputData::F32(p.clone())),
                        ("colors", &[1, n, 3][..], InputData::F32(c.clone())),
                    ],
                    &["point_features"],
                )
                .expect("run")
            })
        });
    }
    g.finish();
}

criterion_group!(benches, preprocessing, models);
criterion_main!(benches);
