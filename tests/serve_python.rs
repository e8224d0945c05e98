//! The Python client (tools/omcl_client.py, grpcio with stubs generated
//! from proto/omcl.proto) against the real server: it streams the synthetic
//! sequence's feature frames and prints the same poses as `omcl localize
//! --use-features` with the same seed, or sends the camera images for the
//! server to encode and prints the poses of `omcl localize --image-model`;
//! its PNG reader gives the pixels omcl reads from real images. Needs
//! grpcio and grpcio-tools in .deps/python (`make deps`); fails if they are
//! missing.

mod common;
mod serve_common;

use std::path::{Path, PathBuf};
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

/// `--images`: the client sends rgb/NNNNNN.png as raw RGB, the server
/// encodes them with the map's image model, and the poses are those of
/// `omcl localize --image-model` with the same seed; an image it cannot read
/// ends the run with the file named.
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
    let run = |seq: &Path| {
        Command::new("python3")
            .arg(&client)
            .args(["--target", &server.grpc.to_string(), "--map", "img"])
            .args(["--sequence", s(seq), "--images", "--seed", "4"])
            .args(["--frames", &frames.to_string()])
            .args(["--particles", &PARTICLES.to_string()])
            .args(["--rays", &RAYS.to_string()])
            .env("OMCL_TOKEN", TOKEN)
            .output()
            .unwrap()
    };
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

    // The third image truncated: two poses, then the file named, exit 1.
    let broken = f.dir.path().join("seq_broken");
    std::fs::create_dir_all(broken.join("rgb")).unwrap();
    for name in ["intrinsics.txt", "poses.txt", "odometry.txt"] {
        std::fs::copy(img.seq.join(name), broken.join(name)).unwrap();
    }
    for i in 0..frames {
        let name = format!("rgb/{i:06}.png");
        let bytes = std::fs::read(img.seq.join(&name)).unwrap();
        let keep = if i == 2 { bytes.len() / 2 } else { bytes.len() };
        std::fs::write(broken.join(&name), &bytes[..keep]).unwrap();
    }
    let r = run(&broken);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&r.stdout),
        String::from_utf8_lossy(&r.stderr),
    );
    assert_eq!(r.status.code(), Some(1), "{stdout}\n{stderr}");
    assert_eq!(client_poses(&stdout).len(), 2, "{stdout}\n{stderr}");
    assert!(
        stderr.contains("000002.png") && stderr.contains("after 2 poses"),
        "{stderr}"
    );
}

/// Runs the client's PNG reader on `pngs` (one Python process): for each,
/// its "width height" line, and its pixels written to `<png>.raw`; or the
/// reader's error on standard error, exit 1.
fn python_read_pngs(pngs: &[PathBuf]) -> std::process::Output {
    let tools = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools");
    let code = format!(
        "import sys; sys.path.insert(0, {tools:?}); import omcl_client as c\n\
         for p in sys.argv[1:]:\n    \
         w, h, b = c.read_png_rgb(p); open(p + '.raw', 'wb').write(b); print(w, h)",
        tools = s(&tools)
    );
    Command::new("python3")
        .args(["-c", &code])
        .args(pngs)
        .output()
        .unwrap()
}

/// The client's PNG reader (pure Python, no imaging library) against
/// omcl's: real TUM RGB-D colour frames give the very bytes
/// `omcl::io::rgb::read_rgb` gives; so do images written with each of the
/// five PNG row filters (and the encoder's adaptive choice) in grey, grey
/// with alpha, RGB and RGBA; a 16-bit depth image is refused by name.
#[test]
fn python_png_reader_gives_omcls_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let mut pngs = Vec::new();
    for case in [
        "case_1/img_curr.png",
        "case_1/img_prev.png",
        "case_2/img_curr.png",
    ] {
        let png = dir.path().join(case.replace('/', "_"));
        std::fs::copy(common::shared(&format!("rgbd_tum_fr1_xyz/{case}")), &png).unwrap();
        pngs.push(png);
    }
    use png::{BitDepth, ColorType, Filter};
    let (w, h) = (13u32, 9u32);
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    for (colour, channels) in [
        (ColorType::Grayscale, 1),
        (ColorType::GrayscaleAlpha, 2),
        (ColorType::Rgb, 3),
        (ColorType::Rgba, 4),
    ] {
        for filter in [
            Filter::NoFilter,
            Filter::Sub,
            Filter::Up,
            Filter::Avg,
            Filter::Paeth,
            Filter::Adaptive,
        ] {
            let data: Vec<u8> = (0..(w * h) as usize * channels)
                .map(|_| {
                    rng ^= rng << 13;
                    rng ^= rng >> 7;
                    rng ^= rng << 17;
                    (rng >> 56) as u8
                })
                .collect();
            let png = dir.path().join(format!("{colour:?}_{filter:?}.png"));
            let file = std::io::BufWriter::new(std::fs::File::create(&png).unwrap());
            let mut e = png::Encoder::new(file, w, h);
            e.set_color(colour);
            e.set_depth(BitDepth::Eight);
            e.set_filter(filter);
            let mut writer = e.write_header().unwrap();
            writer.write_image_data(&data).unwrap();
            writer.finish().unwrap();
            pngs.push(png);
        }
    }
    let r = python_read_pngs(&pngs);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{stderr}");
    let sizes: Vec<String> = String::from_utf8_lossy(&r.stdout)
        .lines()
        .map(String::from)
        .collect();
    assert_eq!(sizes.len(), pngs.len());
    for (png, size) in pngs.iter().zip(&sizes) {
        let want = omcl::io::rgb::read_rgb(png).unwrap();
        let name = png.file_name().unwrap().to_string_lossy();
        assert_eq!(
            *size,
            format!("{} {}", want.width(), want.height()),
            "{name}"
        );
        let mut raw = png.as_os_str().to_owned();
        raw.push(".raw");
        let got = std::fs::read(&raw).unwrap();
        assert!(got == want.as_raw().as_slice(), "{name}: other pixels");
    }

    // Hostile headers: an IHDR chunk of 4 bytes, and a 0 x 0 image; each
    // refused by name (the reader checks no CRC, so none is right here).
    let chunk = |kind: &[u8], body: &[u8]| {
        let mut c = (body.len() as u32).to_be_bytes().to_vec();
        c.extend_from_slice(kind);
        c.extend_from_slice(body);
        c.extend_from_slice(&[0; 4]);
        c
    };
    let signature = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut zero_size = [0u8; 13];
    zero_size[8] = 8;
    zero_size[9] = 2;
    for (name, ihdr, why) in [
        (
            "short_ihdr.png",
            &[0u8, 0, 0, 1][..],
            "IHDR chunk of 4 bytes",
        ),
        ("zero_size.png", &zero_size[..], "0 x 0 pixels"),
    ] {
        let png = dir.path().join(name);
        let bytes = [
            signature.clone(),
            chunk(b"IHDR", ihdr),
            chunk(b"IDAT", b"x"),
            chunk(b"IEND", b""),
        ]
        .concat();
        std::fs::write(&png, bytes).unwrap();
        let r = python_read_pngs(&[png]);
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "{name} was read");
        assert!(stderr.contains(name) && stderr.contains(why), "{stderr}");
    }

    let r = python_read_pngs(&[common::shared("rgbd_tum_fr1_xyz/case_1/dep_curr.png")]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success());
    assert!(
        stderr.contains("dep_curr.png") && stderr.contains("bit depth 16"),
        "{stderr}"
    );
}
