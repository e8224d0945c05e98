//! `omcl encode` end to end through the built binary, on the tiny test
//! models (expected values from tools/make_encoder_testdata.py).

use std::path::{Path, PathBuf};
use std::process::Command;

use omcl::io::npy::read_npy;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/encode")
        .join(name)
}

fn omcl(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(args)
        .env_remove("ORT_DYLIB_PATH")
        .output()
        .expect("run omcl");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr),
    )
}

fn p(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

#[test]
fn encode_text_and_image_write_the_expected_npy() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.npy");
    let (ok, log) = omcl(&[
        "encode",
        "text",
        "a photo of a cat",
        "toilet, mirror, sink",
        "floor",
        "--model",
        p(&data("tiny_text.onnx")),
        "--out",
        p(&out),
    ]);
    assert!(ok, "{log}");
    let got = read_npy(&out).unwrap();
    let want = read_npy(&data("tiny_text_expected.npy")).unwrap();
    assert_eq!(got.shape, want.shape);
    assert!(
        got.data
            .iter()
            .zip(&want.data)
            .all(|(a, b)| (a - b).abs() < 1e-5)
    );

    let cache = dir.path().join("cache");
    let (img, model) = (data("tiny_image_input.png"), data("tiny_image.onnx"));
    let args = [
        "encode",
        "image",
        p(&img),
        "--model",
        p(&model),
        "--cache",
        p(&cache),
    ];
    let (ok, log) = omcl(&args);
    assert!(
        ok && log.contains("1 image encoded, 0 already cached"),
        "{log}"
    );
    let (ok, log) = omcl(&args);
    assert!(
        ok && log.contains("0 images encoded, 1 already cached"),
        "{log}"
    );
    let got = read_npy(&cache.join("tiny_image_input.npy")).unwrap();
    let want = read_npy(&data("tiny_image_expected.npy")).unwrap();
    assert_eq!(got.shape, vec![7, 11, 4]);
    assert!(
        got.data
            .iter()
            .zip(&want.data)
            .all(|(a, b)| (a - b).abs() < 1e-5)
    );
}

#[test]
fn encode_errors_exit_non_zero_with_a_useful_message() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.npy");
    let (ok, log) = omcl(&[
        "encode",
        "text",
        "chair",
        "--model",
        p(&data("tiny_text.onnx")),
        "--out",
        p(&out),
        "--ort-lib",
        "/nonexistent/libonnxruntime.so",
    ]);
    assert!(!ok && log.contains("make deps"), "{log}");
    let (ok, log) = omcl(&[
        "encode",
        "text",
        "chair",
        "--model",
        p(&data("not_a_model.onnx")),
        "--out",
        p(&out),
    ]);
    assert!(
        !ok && log.contains("not_a_model.card.json") && log.contains("missing"),
        "{log}"
    );
    assert!(!out.exists());
    // A point cloud's features are never written over the cloud.
    let cloud = dir.path().join("cloud.npy");
    std::fs::write(&cloud, b"kept").unwrap();
    let (ok, log) = omcl(&[
        "encode",
        "points",
        p(&cloud),
        "--model",
        p(&data("tiny_text.onnx")),
        "--out",
        p(&dir.path().join("./cloud.npy")),
    ]);
    assert!(!ok && log.contains("--out is the cloud"), "{log}");
    assert_eq!(std::fs::read(&cloud).unwrap(), b"kept");
    let (ok, log) = omcl(&["encode", "tokens", "Hi there"]);
    assert!(ok && log.contains("49406 1883 997 49407"), "{log}");
}
