//! The Python client (tools/omcl_client.py, grpcio with stubs generated
//! from proto/omcl.proto) against the real server: it streams the synthetic
//! sequence's feature frames and prints the same poses as `omcl localize
//! --use-features` with the same seed. Needs grpcio and grpcio-tools in
//! .deps/python (`make deps`); fails if they are missing.

mod serve_common;

use std::path::Path;
use std::process::Command;

use serve_common::*;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn python_client_streams_the_sequence_and_prints_the_cli_poses() {
    let f = Fixture::with_features();
    let frames = "8";
    let out = f.dir.path().join("est.txt");
    let r = omcl(&[
        "localize",
        "--map",
        s(&f.map),
        "--sequence",
        s(&f.seq),
        "-o",
        s(&out),
        "--particles",
        &PARTICLES.to_string(),
        "--rays",
        &RAYS.to_string(),
        "--seed",
        "5",
        "--frames",
        frames,
        "--use-features",
        // Two-pass likelihoods and the 6-DoF filter on both sides: the
        // client's flags reach the session (the plain filter is compared
        // in serve_grpc.rs).
        "--early-reject",
        "--filter",
        "six-dof",
    ]);
    assert!(r.status.success(), "{r:?}");
    let want = read_tum(&out);

    let server = Server::start(&f, &[]);
    let client = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/omcl_client.py");
    let run = |token: &str| {
        Command::new("python3")
            .arg(&client)
            .args(["--target", &server.grpc.to_string(), "--map", "room"])
            .args(["--sequence", s(&f.seq), "--frames", frames, "--seed", "5"])
            .args(["--particles", &PARTICLES.to_string()])
            .args(["--rays", &RAYS.to_string()])
            .args(["--early-reject", "--filter", "six-dof"])
            .env("OMCL_TOKEN", token)
            .output()
            .unwrap()
    };
    let r = run(TOKEN);
    let stdout = String::from_utf8_lossy(&r.stdout);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{stdout}\n{stderr}");
    let got: Vec<[f64; 7]> = stdout
        .lines()
        .filter(|l| l.starts_with("frame "))
        .map(|l| {
            let v: Vec<&str> = l.split_whitespace().collect();
            let i = v.iter().position(|w| *w == "pose").unwrap();
            let mut p = [0.0; 7];
            for (k, x) in p.iter_mut().enumerate() {
                *x = v[i + 1 + k].parse().unwrap();
            }
            p
        })
        .collect();
    assert_eq!(got.len(), want.len(), "{stdout}\n{stderr}");
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        for k in 0..7 {
            assert!(
                (g[k] - w[k]).abs() < 1e-9,
                "frame {i}: client {g:?}, CLI {w:?}"
            );
        }
    }
    // A wrong token: a named refusal, no poses.
    let r = run("wrong-token-0123456789abcdef");
    let stdout = String::from_utf8_lossy(&r.stdout);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success());
    assert!(stderr.contains("UNAUTHENTICATED"), "{stderr}");
    assert!(!stdout.contains("pose"), "{stdout}");
}
