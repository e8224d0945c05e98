//! The Python client (tools/omcl_client.py, grpcio with stubs generated
//! from proto/omcl.proto) against the real server: it streams the synthetic
//! sequence's feature frames and prints the same poses as `omcl localize
//! --use-features` with the same seed, or sends the camera images for the
//! server to encode and prints the poses of `omcl localize --image-model`,
//! or tracks with a baseline on a floor plan as `omcl localize --baseline`
//! does; its depth PNG reader gives the pixels omcl reads from real images. Needs
//! grpcio and grpcio-tools in .deps/python (`make deps`); fails if they are
//! missing.

mod common;
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
    let got = client_poses(&stdout);
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
    assert!(!stderr.contains("Traceback"), "{stderr}");
    // No server there, a missing sequence, --frames 0: one line each, no
    // traceback.
    let client_with = |args: &[&str]| {
        let r = Command::new("python3")
            .arg(&client)
            .args(["--map", "room"])
            .args(args)
            .env("OMCL_TOKEN", TOKEN)
            .output()
            .unwrap();
        (
            r.status.code(),
            String::from_utf8_lossy(&r.stderr).into_owned(),
        )
    };
    let (code, err) = client_with(&["--target", "127.0.0.1:1", "--sequence", s(&f.seq)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("UNAVAILABLE") && !err.contains("Traceback"),
        "{err}"
    );
    let grpc = server.grpc.to_string();
    let missing = f.dir.path().join("no_such_sequence");
    let (code, err) = client_with(&["--target", &grpc, "--sequence", s(&missing)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("no_such_sequence") && !err.contains("Traceback"),
        "{err}"
    );
    let (code, err) = client_with(&["--target", &grpc, "--sequence", s(&f.seq), "--frames", "0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--frames 0"), "{err}");
}

/// The client's `frame` lines, as poses.
fn client_poses(stdout: &str) -> Vec<[f64; 7]> {
    stdout
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
        .collect()
}

/// `--images`: the client sends rgb/NNNNNN.png (or .jpg) as they are, the
/// server decodes and encodes them with the map's image model, and the
/// poses are those of `omcl localize --image-model` with the same seed; an
/// image the server cannot read is named and skipped, a missing one ends
/// the run with the file named.
#[test]
fn python_client_sends_camera_images_for_the_server_to_encode() {
    let f = Fixture::new();
    let frames = 6;
    let img = f.images(4, frames);
    let (map_arg, model_arg) = (
        format!("img={}", s(&img.map)),
        format!("img={}", s(&img.model)),
    );
    let server = Server::start(&f, &["--map", &map_arg, "--image-model", &model_arg]);
    let client = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/omcl_client.py");
    let run_on = |map: &str, seq: &Path| {
        Command::new("python3")
            .arg(&client)
            .args(["--target", &server.grpc.to_string(), "--map", map])
            .args(["--sequence", s(seq), "--images", "--seed", "4"])
            .args(["--frames", &frames.to_string()])
            .args(["--particles", &PARTICLES.to_string()])
            .args(["--rays", &RAYS.to_string()])
            .env("OMCL_TOKEN", TOKEN)
            .output()
            .unwrap()
    };
    let run = |seq: &Path| run_on("img", seq);
    // Images for a map without an image model: the session's problem, not
    // a frame's; the client stops at the first answer, naming it.
    let r = run_on("room", &img.seq);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("FAILED_PRECONDITION") && stderr.contains("stopped (after 0 poses)"),
        "{stderr}"
    );
    assert_eq!(stderr.matches("FAILED_PRECONDITION").count(), 1, "{stderr}");
    let r = run(&img.seq);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&r.stdout),
        String::from_utf8_lossy(&r.stderr),
    );
    assert!(r.status.success(), "{stdout}\n{stderr}");
    let got = client_poses(&stdout);
    assert_eq!(got.len(), img.cli.len(), "{stdout}\n{stderr}");
    for (i, (g, w)) in got.iter().zip(&img.cli).enumerate() {
        for k in 0..7 {
            assert!(
                (g[k] - w[k]).abs() < 1e-9,
                "frame {i}: client {g:?}, CLI {w:?}"
            );
        }
    }

    // Frame 1 as a JPEG file (sent as it is), frame 2 truncated (refused by
    // the server, named, the run goes on), frame 4 missing (the run ends
    // naming it): three poses, exit 1.
    let broken = f.dir.path().join("seq_broken");
    std::fs::create_dir_all(broken.join("rgb")).unwrap();
    for name in ["intrinsics.txt", "poses.txt", "odometry.txt"] {
        std::fs::copy(img.seq.join(name), broken.join(name)).unwrap();
    }
    for i in 0..frames {
        let name = format!("rgb/{i:06}.png");
        let bytes = std::fs::read(img.seq.join(&name)).unwrap();
        match i {
            1 => omcl::io::rgb::read_rgb(&img.seq.join(&name))
                .unwrap()
                .save(broken.join("rgb/000001.jpg"))
                .unwrap(),
            2 => std::fs::write(broken.join(&name), &bytes[..bytes.len() / 2]).unwrap(),
            4 => {}
            _ => std::fs::write(broken.join(&name), &bytes).unwrap(),
        }
    }
    let r = run(&broken);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&r.stdout),
        String::from_utf8_lossy(&r.stderr),
    );
    assert_eq!(r.status.code(), Some(1), "{stdout}\n{stderr}");
    let lines: Vec<&str> = stdout.lines().filter(|l| l.starts_with("frame ")).collect();
    assert_eq!(lines.len(), 3, "{stdout}\n{stderr}");
    for (line, i) in lines.iter().zip(["000000", "000001", "000003"]) {
        assert!(line.starts_with(&format!("frame {i} ")), "{stdout}");
    }
    assert!(
        stderr.contains(
            "error INVALID_ARGUMENT: malformed frame: compressed image: corrupt or truncated PNG"
        ) && stderr.contains("000002.png")
            && stderr.contains("000004.png")
            && stderr.contains("after 3 poses"),
        "{stderr}"
    );
}

/// The client run on `f`'s sequence with a session slow enough (20,000
/// particles x 2048 pixels) to be signalled mid-stream, once its first
/// pose line is out: the process and a thread reading the rest of its
/// stdout (a full pipe must not stop the client).
fn client_mid_stream(
    server: &Server,
    f: &Fixture,
) -> (std::process::Child, std::thread::JoinHandle<String>) {
    use std::io::{BufRead, Read};
    let client = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/omcl_client.py");
    let mut child = Command::new("python3")
        .arg(&client)
        .args(["--target", &server.grpc.to_string(), "--map", "room"])
        .args(["--sequence", s(&f.seq), "--particles", "20000"])
        .env("OMCL_TOKEN", TOKEN)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut first = String::new();
    out.read_line(&mut first).unwrap();
    assert!(first.starts_with("frame 000000 "), "{first:?}");
    let rest = std::thread::spawn(move || {
        let mut s = first;
        let _ = out.read_to_string(&mut s);
        s
    });
    (child, rest)
}

/// SIGINT or SIGTERM by the `kill` command.
fn kill(pid: u32, signal: &str) {
    let st = Command::new("kill")
        .args([&format!("-{signal}"), &pid.to_string()])
        .status()
        .unwrap();
    assert!(st.success());
}

/// Ctrl-C (SIGINT) and SIGTERM end the client quietly, 130 and 143 (a
/// KeyboardInterrupt traceback before), its session closed first; when
/// the server shuts down, the client says so with the poses it received.
#[test]
fn python_client_closes_its_session_on_signals_and_counts_poses_at_shutdown() {
    let f = Fixture::with_features();
    let mut server = Server::start(&f, &[]);
    for (signal, code) in [("INT", 130), ("TERM", 143)] {
        let (child, rest) = client_mid_stream(&server, &f);
        kill(child.id(), signal);
        let r = child.wait_with_output().unwrap();
        let (stdout, stderr) = (rest.join().unwrap(), String::from_utf8_lossy(&r.stderr));
        assert_eq!(r.status.code(), Some(code), "{stdout}\n{stderr}");
        assert!(!stderr.contains("Traceback"), "{stderr}");
        // Closed by the client before it exited (it idles out in 300 s).
        assert_eq!(server.metric("omcl_sessions"), "0", "SIG{signal}");
    }
    let (child, rest) = client_mid_stream(&server, &f);
    server.signal("TERM");
    let r = child.wait_with_output().unwrap();
    let (stdout, stderr) = (rest.join().unwrap(), String::from_utf8_lossy(&r.stderr));
    assert_eq!(r.status.code(), Some(1), "{stdout}\n{stderr}");
    let poses = stdout.lines().filter(|l| l.starts_with("frame ")).count();
    assert!(
        stderr.contains("UNAVAILABLE: the server is shutting down")
            && stderr.contains(&format!("after {poses} poses from session")),
        "{stdout}\n{stderr}"
    );
    assert!(!stderr.contains("Traceback"), "{stderr}");
    assert!(
        server
            .wait_exit(std::time::Duration::from_secs(120))
            .success()
    );
}

/// Where .deps/pyproto cannot be made (here .deps is a file), the stubs
/// go to $XDG_CACHE_HOME/omcl/pyproto/, one folder per .proto content, and
/// the client runs.
#[test]
fn python_client_writes_its_stubs_to_the_user_cache_when_deps_is_not_writable() {
    let f = Fixture::with_features();
    let server = Server::start(&f, &[]);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let copy = f.dir.path().join("checkout");
    std::fs::create_dir_all(copy.join("tools")).unwrap();
    std::fs::create_dir_all(copy.join("proto")).unwrap();
    std::fs::copy(
        root.join("tools/omcl_client.py"),
        copy.join("tools/omcl_client.py"),
    )
    .unwrap();
    std::fs::copy(root.join("proto/omcl.proto"), copy.join("proto/omcl.proto")).unwrap();
    std::fs::write(copy.join(".deps"), "not a folder").unwrap();
    let cache = f.dir.path().join("cache");
    let r = Command::new("python3")
        .arg(copy.join("tools/omcl_client.py"))
        .args(["--target", &server.grpc.to_string(), "--map", "room"])
        .args(["--sequence", s(&f.seq), "--frames", "1"])
        .env("OMCL_TOKEN", TOKEN)
        .env("XDG_CACHE_HOME", &cache)
        .env("PYTHONPATH", root.join(".deps/python"))
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&r.stdout),
        String::from_utf8_lossy(&r.stderr),
    );
    assert!(r.status.success(), "{stdout}\n{stderr}");
    assert_eq!(client_poses(&stdout).len(), 1, "{stdout}");
    let dirs: Vec<_> = std::fs::read_dir(cache.join("omcl/pyproto"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(dirs.len(), 1, "{dirs:?}");
    assert!(dirs[0].join("omcl_pb2_grpc.py").exists(), "{dirs:?}");
}

/// `--baseline simp`: the client opens a SIMP* session on a map served on
/// its floor plan and sends each frame's depth/NNNNNN.png with its
/// features; the poses are those of `omcl localize --floorplan --baseline
/// simp --use-features` with the same seed. A baseline on a 3-D map is
/// refused in one line.
#[test]
fn python_client_tracks_with_a_baseline_on_a_floor_plan() {
    let f = Fixture::with_features();
    let frames = "8";
    let out = f.dir.path().join("simp.txt");
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
        "--floorplan",
        "--baseline",
        "simp",
    ]);
    assert!(r.status.success(), "{r:?}");
    let want = read_tum(&out);
    let client = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/omcl_client.py");
    let run = |server: &Server, baseline: &[&str]| {
        Command::new("python3")
            .arg(&client)
            .args(["--target", &server.grpc.to_string(), "--map", "room"])
            .args(["--sequence", s(&f.seq), "--frames", frames, "--seed", "5"])
            .args(["--particles", &PARTICLES.to_string()])
            .args(["--rays", &RAYS.to_string()])
            .arg("--baseline")
            .args(baseline)
            .env("OMCL_TOKEN", TOKEN)
            .output()
            .unwrap()
    };
    let server = Server::start(&f, &["--floorplan", "room"]);
    let r = run(&server, &["simp"]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{stdout}\n{stderr}");
    let got = client_poses(&stdout);
    assert_eq!(got.len(), want.len(), "{stdout}\n{stderr}");
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        for k in 0..7 {
            assert!(
                (g[k] - w[k]).abs() < 1e-9,
                "frame {i}: client {g:?}, CLI {w:?}"
            );
        }
    }
    // --max-depth reaches the server, which refuses it for SeDAR* in one
    // line.
    let r = run(&server, &["sedar", "--max-depth", "3"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("INVALID_ARGUMENT") && stderr.contains("max_depth: 3 m given for baseline"),
        "{stderr}"
    );
    assert!(!stderr.contains("Traceback"), "{stderr}");
    // A truncated depth image ends the run naming it, after the poses
    // before it.
    let depth = f.seq.join("depth/000002.png");
    let bytes = std::fs::read(&depth).unwrap();
    std::fs::write(&depth, &bytes[..bytes.len() / 2]).unwrap();
    let r = run(&server, &["simp"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("000002.png") && stderr.contains("(after 2 poses)"),
        "{stderr}"
    );
    assert!(!stderr.contains("Traceback"), "{stderr}");
    drop(server);
    let server = Server::start(&f, &[]);
    let r = run(&server, &["sedar"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("FAILED_PRECONDITION") && stderr.contains("is a 3-D map"),
        "{stderr}"
    );
    assert!(!stderr.contains("Traceback"), "{stderr}");
}

/// The client's depth reader (pure Python: zlib and PNG's row filters)
/// gives the values omcl reads from real 16-bit depth PNGs: TUM fr1/xyz
/// and 7-Scenes redkitchen, every pixel, as samples and in metres.
#[test]
fn python_client_reads_real_depth_pngs_as_omcl_does() {
    let client = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/omcl_client.py");
    let dir = tempfile::tempdir().unwrap();
    for png in [
        common::shared("rgbd_tum_fr1_xyz/case_1/dep_curr.png"),
        common::shared("rgbd_7scenes/frame-000150.depth.png"),
    ] {
        let text = dir.path().join("values.txt");
        let script = format!(
            "import importlib.util, sys\n\
             spec = importlib.util.spec_from_file_location('c', {client:?})\n\
             c = importlib.util.module_from_spec(spec); spec.loader.exec_module(c)\n\
             w, h, v = c.read_png_gray16({png:?})\n\
             open({text:?}, 'w').write(f'{{w}} {{h}}\\n' + ' '.join(map(str, v)))\n",
        );
        let r = Command::new("python3")
            .args(["-c", &script])
            .output()
            .unwrap();
        assert!(r.status.success(), "{r:?}");
        let got = std::fs::read_to_string(&text).unwrap();
        let (head, values) = got.split_once('\n').unwrap();
        // 1.0 units a metre: the PNG's own values.
        let d = omcl::io::rgbd::read_depth_png(&png, 1.0).unwrap();
        assert_eq!(head, format!("{} {}", d.width, d.height), "{png:?}");
        let values: Vec<f32> = values
            .split(' ')
            .map(|x| x.parse::<u16>().unwrap() as f32)
            .collect();
        assert_eq!(values.len(), d.depth.len(), "{png:?}");
        let differ = values.iter().zip(&d.depth).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{png:?}: {differ} pixels differ");
        assert!(
            values.iter().filter(|&&x| x > 0.0).count() > 100_000,
            "{png:?}"
        );
        // In metres, to the bit (float32, as omcl scales them), at TUM's
        // 5000 units a metre and at millimetres.
        let seq = dir.path().join("seq");
        std::fs::create_dir_all(seq.join("depth")).unwrap();
        std::fs::copy(&png, seq.join("depth/000000.png")).unwrap();
        for units in [5000.0, 1000.0] {
            let script = format!(
                "import importlib.util, sys\n\
                 spec = importlib.util.spec_from_file_location('c', {client:?})\n\
                 c = importlib.util.module_from_spec(spec); spec.loader.exec_module(c)\n\
                 w, h, v = c.read_depth({seq:?}, 0, {units:?}, ({w}, {h}))\n\
                 open({text:?}, 'w').write(' '.join(map(repr, v)))\n",
                w = d.width,
                h = d.height,
            );
            let r = Command::new("python3")
                .args(["-c", &script])
                .output()
                .unwrap();
            assert!(r.status.success(), "{r:?}");
            let got: Vec<f32> = std::fs::read_to_string(&text)
                .unwrap()
                .split(' ')
                .map(|x| x.parse::<f64>().unwrap() as f32)
                .collect();
            let want = omcl::io::rgbd::read_depth_png(&png, units).unwrap();
            assert_eq!(got.len(), want.depth.len(), "{png:?}");
            let differ = got
                .iter()
                .zip(&want.depth)
                .filter(|(a, b)| a.to_bits() != b.to_bits())
                .count();
            assert_eq!(
                differ, 0,
                "{png:?} at {units} a metre: {differ} pixels differ"
            );
        }
    }
}
