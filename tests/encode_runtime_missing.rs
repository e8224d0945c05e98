//! A runtime library that cannot be loaded gives an error that says how to
//! install one. Its own test binary: ONNX Runtime loads once per process, so
//! no other test here may load the real library first.

use omcl::encode::Runtime;

#[test]
fn a_file_that_is_not_the_runtime_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let fake = dir.path().join("libonnxruntime.so.1.99.0");
    std::fs::write(&fake, b"not a shared library").unwrap();
    let e = Runtime::init(Some(&fake))
        .err()
        .expect("loading a text file must fail")
        .to_string();
    assert!(e.contains("libonnxruntime.so.1.99.0"), "{e}");
    assert!(e.contains("make deps") && e.contains("--ort-lib"), "{e}");
    let e = Runtime::init(Some(&dir.path().join("missing.so")))
        .err()
        .expect("missing file")
        .to_string();
    assert!(e.contains("missing.so") && e.contains("make deps"), "{e}");
}
