//! Small files whose headers declare enormous counts, in every format the
//! command line reads: each run must end with a one-line error naming the
//! file, exit status 1, no output written, and (all runs of this binary
//! together) a peak resident memory under 100 MB. Before the bounds, the
//! PLY, LAS and LAZ cases aborted on allocations of 26 to 69 GB.

mod common;

use common::{Run, omcl};

use std::path::{Path, PathBuf};

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/io");

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// The run failed cleanly: exit 1, one line on stderr naming `file`, no
/// panic, and `out` (if any) not written.
fn refused(r: &Run, file: &Path, out: Option<&Path>) {
    let text = format!("stdout:\n{}\nstderr:\n{}", r.stdout, r.stderr);
    assert_eq!(r.code, Some(1), "exit status, {}:\n{text}", file.display());
    let lines: Vec<&str> = r.stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line of error:\n{text}");
    assert!(lines[0].starts_with("error: "), "{text}");
    println!("{}", lines[0]);
    assert!(lines[0].contains(s(file)), "names the file:\n{text}");
    assert!(!r.stderr.contains("panicked"), "{text}");
    if let Some(out) = out {
        assert!(!out.exists(), "{} was written:\n{text}", out.display());
    }
}

fn ply_header(format: &str, vertices: u64, features: usize) -> Vec<u8> {
    let mut h = format!(
        "ply\nformat {format} 1.0\nelement vertex {vertices}\n\
         property float x\nproperty float y\nproperty float z\n"
    );
    for k in 0..features {
        h.push_str(&format!("property float feat_{k}\n"));
    }
    h.push_str("end_header\n");
    h.into_bytes()
}

fn patched(name: &str, at: usize, bytes: &[u8]) -> Vec<u8> {
    let mut b = std::fs::read(Path::new(DATA).join(name)).expect("test data");
    b[at..at + bytes.len()].copy_from_slice(bytes);
    b
}

/// A 16-bit greyscale PNG whose header declares `w x h` pixels, with the
/// data of a 1 x 1 image (every chunk's CRC right).
fn png_claiming(w: u32, h: u32) -> Vec<u8> {
    let mut buf = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut buf, 1, 1);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        enc.write_header()
            .unwrap()
            .write_image_data(&[0, 7])
            .unwrap();
    }
    // Signature (8), IHDR length and type (8), then width and height.
    buf[16..20].copy_from_slice(&w.to_be_bytes());
    buf[20..24].copy_from_slice(&h.to_be_bytes());
    let crc = crc32fast::hash(&buf[12..29]);
    buf[29..33].copy_from_slice(&crc.to_be_bytes());
    buf
}

fn peak_rss_of_children_kb() -> i64 {
    // SAFETY: getrusage writes the struct we pass; RUSAGE_CHILDREN covers
    // the children this process has waited for.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut u) };
    assert_eq!(rc, 0);
    u.ru_maxrss
}

#[test]
fn huge_declared_counts_fail_fast_with_the_file_named() {
    let dir = tempfile::tempdir().unwrap();
    let put = |name: &str, bytes: &[u8]| -> PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let out = dir.path().join("out.omcl");

    // Point clouds through `map cloud`.
    let mut clouds: Vec<PathBuf> = Vec::new();
    let mut bin = ply_header("binary_little_endian", 4_000_000_000, 512);
    bin.extend_from_slice(&[0u8; 64]);
    clouds.push(put("huge_binary.ply", &bin));
    let mut tiny = ply_header("binary_little_endian", 4_000_000_000, 0);
    tiny.extend_from_slice(&[0u8; 12]);
    clouds.push(put("huge_tiny.ply", &tiny));
    let mut ascii = ply_header("ascii", 4_000_000_000, 512);
    ascii.extend_from_slice(b"1 2 3\n");
    clouds.push(put("huge_ascii.ply", &ascii));
    // LAS 1.2: legacy point count at byte 107.
    let count = 4_000_000_000u32.to_le_bytes();
    clouds.push(put("huge.las", &patched("laspy_pf3_rgb.las", 107, &count)));
    clouds.push(put("huge.laz", &patched("laspy_pf3_rgb.laz", 107, &count)));
    // LAS 1.4 with one extended VLR (at byte 400) whose 64-bit length is
    // 2^60 (found by AFL++: the las crate sized a buffer from it).
    let mut evlr = patched(
        "laspy_14_pf6_extended_class.las",
        235,
        &400u64.to_le_bytes(),
    );
    evlr[243..247].copy_from_slice(&1u32.to_le_bytes());
    evlr[420..428].copy_from_slice(&(1u64 << 60).to_le_bytes());
    clouds.push(put("huge_evlr.las", &evlr));
    for c in &clouds {
        refused(&omcl(&["map", "cloud", s(c), "-o", s(&out)]), c, Some(&out));
    }
    // A KITTI scan and a ScanNet scan that are not whole records.
    let bin = put("000000.bin", &[0u8; 17]);
    for format in ["kitti", "scannet"] {
        let r = omcl(&["map", "cloud", s(&bin), "--format", format, "-o", s(&out)]);
        refused(&r, &bin, Some(&out));
    }

    // Per-point features declaring 4e9 x 512 values.
    let mut npy = b"\x93NUMPY\x01\x00".to_vec();
    let mut dict =
        "{'descr': '<f4', 'fortran_order': False, 'shape': (4000000000, 512), }".to_string();
    while !(10 + dict.len() + 1).is_multiple_of(64) {
        dict.push(' ');
    }
    dict.push('\n');
    npy.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    npy.extend_from_slice(dict.as_bytes());
    npy.extend_from_slice(&[0u8; 64]);
    let feats = put("huge.npy", &npy);
    let ply = Path::new(DATA).join("plyfile_ascii_rgb_label.ply");
    let r = omcl(&[
        "map",
        "cloud",
        s(&ply),
        "--features",
        s(&feats),
        "-o",
        s(&out),
    ]);
    refused(&r, &feats, Some(&out));

    // A map file whose header promises 4e9 voxels.
    let mut st = Vec::new();
    let header = r#"{"codes":{"dtype":"U64","shape":[4000000000],"data_offsets":[0,32000000000]}}"#;
    st.extend_from_slice(&(header.len() as u64).to_le_bytes());
    st.extend_from_slice(header.as_bytes());
    st.extend_from_slice(&[0u8; 64]);
    let map = put("huge.omcl", &st);
    refused(&omcl(&["map", "info", s(&map)]), &map, None);

    // A pose file of one absurd line.
    let poses = put("poses.txt", b"0 1e309 0 0 0 0 0 1\n");
    let gt = put("gt.txt", b"0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n");
    refused(&omcl(&["eval", "ape", s(&gt), s(&poses)]), &poses, None);

    // The peak over every run above.
    let kb = peak_rss_of_children_kb();
    println!("peak resident memory of the runs: {} MB", kb / 1024);
    assert!(kb < 100 * 1024, "peak RSS {kb} kB");
}

#[test]
fn a_png_declaring_ten_billion_pixels_is_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("depth.png");
    std::fs::write(&p, png_claiming(100_000, 100_000)).unwrap();
    let e = omcl::io::rgbd::read_depth_png(&p, 1000.0).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("depth.png") && msg.contains("100000 x 100000"),
        "{msg}"
    );
    // A real image of zeros, 10000 x 7000 pixels in a file of about 70
    // KB (deflate's ratio allows it): refused by its header's size before
    // its 70 MB are decoded.
    let (w, h) = (10_000u32, 7_000u32);
    {
        let file = std::fs::File::create(&p).unwrap();
        let mut enc = png::Encoder::new(file, w, h);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::High);
        let mut out = enc.write_header().unwrap().into_stream_writer().unwrap();
        use std::io::Write;
        let row = vec![0u8; w as usize];
        for _ in 0..h {
            out.write_all(&row).unwrap();
        }
        out.finish().unwrap();
    }
    let len = std::fs::metadata(&p).unwrap().len();
    assert!(len < 1 << 20, "{len} bytes");
    for e in [
        omcl::io::rgbd::read_label_png(&p).map(|_| ()).unwrap_err(),
        omcl::io::rgbd::read_depth_png(&p, 1000.0)
            .map(|_| ())
            .unwrap_err(),
    ] {
        let msg = e.to_string();
        assert!(
            msg.contains("depth.png") && msg.contains("10000 x 7000") && msg.contains("more than"),
            "{msg}"
        );
    }
    // The same file at its true size reads.
    std::fs::write(&p, png_claiming(1, 1)).unwrap();
    let d = omcl::io::rgbd::read_depth_png(&p, 1000.0).unwrap();
    assert_eq!((d.width, d.height, d.depth.len()), (1, 1, 1));
    assert!((d.depth[0] - 0.007).abs() < 1e-6);
}
