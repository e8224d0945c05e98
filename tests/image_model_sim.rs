//! An image encoder end to end on a synthetic sequence that also carries a
//! class table: a colour model fitted on the real 7-Scenes frames
//! (../shared/data), a map built with it, and `omcl localize
//! --image-model` on the folder, whose 512-d class table is in another
//! feature space than the map's and must not stop the run.

mod common;

use common::{omcl, shared};

#[test]
fn a_sequence_s_class_table_of_another_space_does_not_stop_an_image_model_run() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let seq = p("seq");
    let r = omcl(&[
        "sim", "indoor", "--out", &seq, "--seed", "3", "--frames", "30",
    ]);
    assert!(r.ok(), "{}", r.text());
    let scenes = shared("rgbd_7scenes");
    let model = p("colour.onnx");
    let r = omcl(&[
        "encode",
        "colour-model",
        "--frames",
        scenes.to_str().unwrap(),
        "--first",
        "20",
        "-o",
        &model,
    ]);
    assert!(r.ok(), "{}", r.text());
    let map = p("m.omcl");
    let r = omcl(&["map", "rgbd", &seq, "--image-model", &model, "-o", &map]);
    assert!(r.ok(), "{}", r.text());
    let est = p("est.txt");
    let r = omcl(&[
        "localize",
        "--map",
        &map,
        "--sequence",
        &seq,
        "--image-model",
        &model,
        "--particles",
        "256",
        "--frames",
        "20",
        "-o",
        &est,
    ]);
    assert!(r.ok(), "{}", r.text());
    assert!(
        r.stderr.contains("embeddings.npy") && r.stderr.contains("not used"),
        "{}",
        r.stderr
    );
    // The run tracks: every estimate within 0.5 m of the truth.
    let read = |f: &str| {
        omcl::io::poses::read_poses(std::path::Path::new(f))
            .unwrap()
            .trajectory
    };
    let (gt, est) = (read(&format!("{seq}/poses.txt")), read(&est));
    assert_eq!(est.len(), 20);
    for (e, g) in est.poses().iter().zip(gt.poses()) {
        let d = (e.translation.vector - g.translation.vector).norm();
        assert!(d < 0.5, "{d}");
    }
}
