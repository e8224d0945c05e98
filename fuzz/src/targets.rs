//! Fuzz targets: one function a parser, each taking arbitrary bytes.
//!
//! Shared by the AFL++ binaries of this crate (`cargo afl fuzz`, the long
//! runs) and by `tests/fuzz_parsers.rs` (a short deterministic run in
//! `make test`). A target writes the bytes to a file with the extension the
//! reader dispatches on and calls the reader exactly as the command line does;
//! the result is discarded. Only a panic, an abort or an allocation beyond
//! the cap (the in-suite run checks it) is a finding: an `Err` is the right
//! answer to most inputs.
//!
//! Structure-aware targets (`ply_header`, `las_header`, `npy_header`,
//! `png_header`, `floor_plan_fields`) keep a well-formed header and let the
//! fuzzer choose its counts, types and sizes, which byte-level mutation of
//! a whole file rarely reaches (a floor plan's checksum refuses every
//! mutated byte before its values are read).

use std::io::Write;
use std::path::{Path, PathBuf};

/// Every target, by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    Ply,
    PlyHeader,
    Las,
    Laz,
    LasHeader,
    KittiBin,
    KittiLabel,
    KittiCalib,
    PosesTum,
    PosesKitti,
    Times,
    Scannet,
    Npy,
    NpyHeader,
    PngDepth,
    PngLabel,
    PngRgb,
    ImageBytes,
    PngHeader,
    Intrinsics,
    ModelCard,
    ClassTable,
    OmclMap,
    FloorPlan,
    FloorPlanFields,
}

impl Target {
    /// All targets, in the order the in-suite run takes them.
    pub const ALL: [Target; 25] = [
        Target::Ply,
        Target::PlyHeader,
        Target::Las,
        Target::Laz,
        Target::LasHeader,
        Target::KittiBin,
        Target::KittiLabel,
        Target::KittiCalib,
        Target::PosesTum,
        Target::PosesKitti,
        Target::Times,
        Target::Scannet,
        Target::Npy,
        Target::NpyHeader,
        Target::PngDepth,
        Target::PngLabel,
        Target::PngRgb,
        Target::ImageBytes,
        Target::PngHeader,
        Target::Intrinsics,
        Target::ModelCard,
        Target::ClassTable,
        Target::OmclMap,
        Target::FloorPlan,
        Target::FloorPlanFields,
    ];

    /// The target's name (the AFL++ binary's and the corpus folder's).
    pub fn name(self) -> &'static str {
        match self {
            Target::Ply => "ply",
            Target::PlyHeader => "ply_header",
            Target::Las => "las",
            Target::Laz => "laz",
            Target::LasHeader => "las_header",
            Target::KittiBin => "kitti_bin",
            Target::KittiLabel => "kitti_label",
            Target::KittiCalib => "kitti_calib",
            Target::PosesTum => "poses_tum",
            Target::PosesKitti => "poses_kitti",
            Target::Times => "times",
            Target::Scannet => "scannet",
            Target::Npy => "npy",
            Target::NpyHeader => "npy_header",
            Target::PngDepth => "png_depth",
            Target::PngLabel => "png_label",
            Target::PngRgb => "png_rgb",
            Target::ImageBytes => "image_bytes",
            Target::PngHeader => "png_header",
            Target::Intrinsics => "intrinsics",
            Target::ModelCard => "model_card",
            Target::ClassTable => "class_table",
            Target::OmclMap => "omcl_map",
            Target::FloorPlan => "floor_plan",
            Target::FloorPlanFields => "floor_plan_fields",
        }
    }

    /// The target of a name.
    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// A scratch folder for the target's files, one a thread (the in-suite run
/// and AFL++ are single-threaded a process; tests may run in parallel).
fn scratch() -> PathBuf {
    thread_local! {
        static DIR: PathBuf = {
            let base = if Path::new("/dev/shm").is_dir() {
                PathBuf::from("/dev/shm")
            } else {
                std::env::temp_dir()
            };
            let dir = base.join(format!(
                "omcl-fuzz-{}-{:?}",
                std::process::id(),
                std::thread::current().id()
            ));
            std::fs::create_dir_all(&dir).expect("scratch folder for fuzz inputs");
            dir
        };
    }
    DIR.with(|d| d.clone())
}

fn put(name: &str, data: &[u8]) -> PathBuf {
    let path = scratch().join(name);
    let mut f = std::fs::File::create(&path).expect("write fuzz input");
    f.write_all(data).expect("write fuzz input");
    path
}

/// Removes the scratch folder of this thread (the in-suite runs of
/// `tests/fuzz_parsers.rs` call it; the AFL++ binary never returns).
#[allow(dead_code)]
pub fn cleanup() {
    let _ = std::fs::remove_dir_all(scratch());
}

/// Runs one input through a target. Returns whether the reader accepted it.
pub fn run(target: Target, data: &[u8]) -> bool {
    use omcl::io;
    match target {
        Target::Ply => io::ply::read_ply(&put("in.ply", data)).is_ok(),
        Target::PlyHeader => io::ply::read_ply(&put("in.ply", &ply_from(data))).is_ok(),
        Target::Las => io::las::read_las(&put("in.las", data)).is_ok(),
        Target::Laz => io::las::read_las(&put("in.laz", data)).is_ok(),
        Target::LasHeader => io::las::read_las(&put("in.las", &las_from(data))).is_ok(),
        Target::KittiBin => io::kitti::read_velodyne_bin(&put("000000.bin", data)).is_ok(),
        Target::KittiLabel => {
            // The label reader checks the count against the scan's.
            let n = data.first().map_or(0, |&b| b as usize);
            io::kitti::read_label_file(&put("000000.label", data.get(1..).unwrap_or(&[])), n)
                .is_ok()
        }
        Target::KittiCalib => io::kitti::read_calib(&put("calib.txt", data)).is_ok(),
        Target::PosesTum => {
            io::poses::read_poses_in(&put("poses.txt", data), io::poses::PoseFormat::Tum).is_ok()
        }
        Target::PosesKitti => {
            io::poses::read_poses_in(&put("poses.txt", data), io::poses::PoseFormat::Kitti).is_ok()
        }
        Target::Times => io::poses::read_times(&put("times.txt", data)).is_ok(),
        Target::Scannet => io::scannet::read_scannet_xyzrgb_bin(&put("scan.bin", data)).is_ok(),
        Target::Npy => io::npy::read_npy(&put("in.npy", data)).is_ok(),
        Target::NpyHeader => io::npy::read_npy(&put("in.npy", &npy_from(data))).is_ok(),
        Target::PngDepth => io::rgbd::read_depth_png(&put("d.png", data), 1000.0).is_ok(),
        Target::PngLabel => io::rgbd::read_label_png(&put("l.png", data)).is_ok(),
        Target::PngRgb => io::rgb::read_rgb(&put("c.png", data)).is_ok(),
        Target::ImageBytes => {
            // `omcl serve`'s path for a frame's PNG or JPEG bytes: the
            // header's size first, then the pixels.
            let name = Path::new("frame");
            io::rgb::image_size(data, name).is_ok() && io::rgb::rgb_from_bytes(data, name).is_ok()
        }
        Target::PngHeader => {
            // Every reader of PNGs on one well-formed file.
            let p = put("h.png", &png_from(data));
            let d = io::rgbd::read_depth_png(&p, 1000.0).is_ok();
            let l = io::rgbd::read_label_png(&p).is_ok();
            let c = io::rgb::read_rgb(&p).is_ok();
            d || l || c
        }
        Target::Intrinsics => io::rgbd::read_intrinsics(&put("intrinsics.txt", data)).is_ok(),
        Target::ModelCard => {
            let text = String::from_utf8_lossy(data);
            omcl::encode::card::ModelCard::parse(&text, Path::new("model.card.json")).is_ok()
        }
        Target::ClassTable => {
            // First byte: how many bytes of the rest are the class list; the
            // remainder is the embeddings `.npy`.
            let split = data.first().map_or(0, |&b| b as usize).min(data.len());
            let (list, npy) = data
                .get(1..)
                .unwrap_or(&[])
                .split_at(split.saturating_sub(1));
            let l = put("classes.txt", list);
            let e = put("emb.npy", npy);
            io::labels::EmbeddingTable::read(&l, &e).is_ok()
        }
        Target::OmclMap => omcl::map::file::from_bytes(data, Path::new("in.omcl")).is_ok(),
        Target::FloorPlan => omcl::map::floorplan::from_bytes(data, Path::new("in.plan")).is_ok(),
        Target::FloorPlanFields => {
            omcl::map::floorplan::from_bytes(&plan_from(data), Path::new("in.plan")).is_ok()
        }
    }
}

/// A little reader of fuzz bytes: structure-aware targets draw their
/// header fields from it.
struct Draw<'a>(&'a [u8]);

impl Draw<'_> {
    fn byte(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.byte(), self.byte(), self.byte(), self.byte()])
    }
    fn u64(&mut self) -> u64 {
        (self.u32() as u64) | ((self.u32() as u64) << 32)
    }
}

/// A PLY file with a well-formed header whose format, vertex count and
/// property list come from the bytes, followed by the remaining bytes.
pub fn ply_from(data: &[u8]) -> Vec<u8> {
    const TYPES: [&str; 8] = [
        "float", "double", "uchar", "int", "ushort", "char", "uint", "short",
    ];
    const NAMES: [&str; 10] = [
        "x",
        "y",
        "z",
        "red",
        "green",
        "blue",
        "label",
        "f0",
        "f1",
        "scalar_Label",
    ];
    let mut d = Draw(data);
    let format = match d.byte() % 3 {
        0 => "ascii",
        1 => "binary_little_endian",
        _ => "binary_big_endian",
    };
    let count = match d.byte() % 4 {
        0 => d.byte() as u64,
        1 => d.u32() as u64,
        2 => u32::MAX as u64,
        _ => d.u64() % (1 << 40),
    };
    let mut header = format!("ply\nformat {format} 1.0\n");
    // Sometimes an element before the vertices, which must be skipped.
    if d.byte() % 4 == 0 {
        header.push_str(&format!(
            "element face {}\nproperty list uchar {} vertex_indices\n",
            d.u32(),
            if d.byte() % 2 == 0 { "int" } else { "uint" }
        ));
    }
    header.push_str(&format!("element vertex {count}\n"));
    let nprops = 3 + d.byte() as usize % 8;
    for (i, fixed) in NAMES
        .iter()
        .chain(std::iter::repeat(&""))
        .take(nprops)
        .enumerate()
    {
        let t = TYPES[d.byte() as usize % TYPES.len()];
        let name = if i < 3 {
            *fixed
        } else {
            NAMES[d.byte() as usize % NAMES.len()]
        };
        if d.byte() % 16 == 0 {
            header.push_str(&format!("property list uint {t} {name}\n"));
        } else {
            header.push_str(&format!("property {t} {name}\n"));
        }
    }
    // Many features: the case of the 64-byte file with 512 properties.
    if d.byte() % 8 == 0 {
        for k in 0..(d.byte() as usize * 2) {
            header.push_str(&format!("property float feat_{k}\n"));
        }
    }
    header.push_str("end_header\n");
    let mut out = header.into_bytes();
    out.extend_from_slice(d.0);
    out
}

/// A LAS 1.2 file whose public header is well formed but for the fields the
/// bytes choose (point format, record length, counts, offsets, compression
/// bits), followed by the remaining bytes as point data.
pub fn las_from(data: &[u8]) -> Vec<u8> {
    let mut d = Draw(data);
    let mut h = vec![0u8; 227];
    h[0..4].copy_from_slice(b"LASF");
    h[24] = 1; // version 1.2
    h[25] = 2;
    h[94..96].copy_from_slice(&227u16.to_le_bytes()); // header size
    let offset: u32 = if d.byte() % 4 == 0 { d.u32() } else { 227 };
    h[96..100].copy_from_slice(&offset.to_le_bytes());
    let format = (d.byte() % 4) | if d.byte() % 4 == 0 { 0x80 } else { 0 };
    h[104] = format;
    let base = [20u16, 28, 26, 34][(format & 3) as usize];
    let len = if d.byte() % 4 == 0 {
        d.u32() as u16
    } else {
        base
    };
    h[105..107].copy_from_slice(&len.to_le_bytes());
    let count = match d.byte() % 3 {
        0 => d.byte() as u32,
        1 => d.u32(),
        _ => u32::MAX,
    };
    h[107..111].copy_from_slice(&count.to_le_bytes());
    for (i, scale) in [0.01f64, 0.01, 0.01].iter().enumerate() {
        h[131 + 8 * i..139 + 8 * i].copy_from_slice(&scale.to_le_bytes());
    }
    h.extend_from_slice(d.0);
    h
}

/// A PNG whose chunks are well formed (right lengths and CRCs) but whose
/// IHDR fields (width, height, bit depth, colour type, interlace) come from
/// the bytes; the remaining bytes, zlib-stored, are its IDAT.
pub fn png_from(data: &[u8]) -> Vec<u8> {
    let mut d = Draw(data);
    let width = match d.byte() % 4 {
        0 => 1 + d.byte() as u32 % 16,
        1 => d.u32(),
        2 => 100_000,
        _ => 1 + d.byte() as u32,
    };
    let height = match d.byte() % 4 {
        0 => 1 + d.byte() as u32 % 16,
        1 => d.u32(),
        2 => 100_000,
        _ => 1 + d.byte() as u32,
    };
    let depth = [8u8, 16, 1, 2, 4][d.byte() as usize % 5];
    let color = [0u8, 2, 3, 4, 6][d.byte() as usize % 5];
    let interlace = d.byte() % 2;
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[depth, color, 0, 0, interlace]);
    // zlib "stored" blocks of the rest: a valid stream of those bytes.
    let body = d.0;
    let mut z = vec![0x78, 0x01];
    let mut chunks = body.chunks(65_535).peekable();
    if chunks.peek().is_none() {
        z.extend_from_slice(&[1, 0, 0, 0xff, 0xff]);
    }
    while let Some(c) = chunks.next() {
        z.push(u8::from(chunks.peek().is_none()));
        let n = c.len() as u16;
        z.extend_from_slice(&n.to_le_bytes());
        z.extend_from_slice(&(!n).to_le_bytes());
        z.extend_from_slice(c);
    }
    let adler = {
        let (mut a, mut b) = (1u32, 0u32);
        for &x in body {
            a = (a + x as u32) % 65_521;
            b = (b + a) % 65_521;
        }
        (b << 16) | a
    };
    z.extend_from_slice(&adler.to_be_bytes());
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    for (kind, payload) in [(&b"IHDR"[..], &ihdr[..]), (b"IDAT", &z), (b"IEND", &[])] {
        out.extend_from_slice(&(payload.len() as u32).to_be_bytes());
        let start = out.len();
        out.extend_from_slice(kind);
        out.extend_from_slice(payload);
        let crc = crc32fast::hash(&out[start..]);
        out.extend_from_slice(&crc.to_be_bytes());
    }
    out
}

/// A `.npy` file with a well-formed preamble whose dtype and shape come from
/// the bytes, followed by the remaining bytes as data.
pub fn npy_from(data: &[u8]) -> Vec<u8> {
    let mut d = Draw(data);
    let dtype = ["<f4", "<f2", "<f8", ">f4", "<i4", "|u1"][d.byte() as usize % 6];
    let dims = d.byte() as usize % 4;
    let shape: Vec<String> = (0..dims)
        .map(|_| match d.byte() % 4 {
            0 => (d.byte() % 8).to_string(),
            1 => d.u32().to_string(),
            2 => (u64::MAX / 3).to_string(),
            _ => d.u64().to_string(),
        })
        .collect();
    let shape = match shape.len() {
        1 => format!("({},)", shape[0]),
        _ => format!("({})", shape.join(", ")),
    };
    let order = if d.byte() % 8 == 0 { "True" } else { "False" };
    let mut dict = format!("{{'descr': '{dtype}', 'fortran_order': {order}, 'shape': {shape}, }}");
    while !(10 + dict.len() + 1).is_multiple_of(64) {
        dict.push(' ');
    }
    dict.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.extend_from_slice(d.0);
    out
}

/// A floor-plan file (safetensors) whose header values, tensor shapes and
/// contents come from the bytes, sealed with the checksum the reader
/// expects ([`omcl::map::floorplan::CHECKED_FIELDS`], then the tensors), so
/// that the values reach the plan's own checks.
pub fn plan_from(data: &[u8]) -> Vec<u8> {
    let mut d = Draw(data);
    let number = |d: &mut Draw| -> String {
        match d.byte() % 10 {
            0 => "0".into(),
            1 => "-1.5".into(),
            2 => "NaN".into(),
            3 => "inf".into(),
            4 => "1e-300".into(),
            5 => "1e300".into(),
            6 => f32::from_bits(d.u32()).to_string(),
            7 => (d.u32() as i32).to_string(),
            8 => "2.0".into(),
            _ => "0.05".into(),
        }
    };
    let version = ["1", "1", "1", "2", "0", "x"][d.byte() as usize % 6];
    let resolution = number(&mut d);
    let (ox, oy, fz) = (number(&mut d), number(&mut d), number(&mut d));
    let (b0, b1) = (number(&mut d), number(&mut d));
    let dim = match d.byte() % 4 {
        0 => 0,
        1 => d.u32() as usize % 1_000_000,
        _ => 1 + d.byte() as usize % 8,
    };
    let tau = ["0.05", "0", "2", "3", "NaN", "-1"][d.byte() as usize % 6];
    let n = d.byte() as usize % 24;
    let k = d.byte() as usize % 8;
    // Mostly the shapes the header promises; sometimes not.
    let (n_t, k_t, dim_t) = match d.byte() % 8 {
        0 => (n + 1, k, dim),
        1 => (n, k + 1, dim),
        _ => (n, k, dim.min(64)),
    };
    let mut cells = Vec::new();
    for _ in 0..n_t * 2 {
        let v = match d.byte() % 4 {
            0 => d.u32() as i32,
            _ => (d.byte() % 16) as i32 - 8,
        };
        cells.extend_from_slice(&v.to_le_bytes());
    }
    let mut rows = Vec::new();
    for _ in 0..n_t {
        let v = match d.byte() % 8 {
            0 => d.u32(),
            _ => d.byte() as u32 % (k as u32 + 1).max(1),
        };
        rows.extend_from_slice(&v.to_le_bytes());
    }
    let mut features = Vec::new();
    for _ in 0..k_t * dim_t {
        let v = match d.byte() % 8 {
            0 => f32::NAN,
            1 => f32::INFINITY,
            2 => 0.0,
            3 => f32::from_bits(d.u32()),
            _ => (d.byte() as f32 - 128.0) / 64.0,
        };
        features.extend_from_slice(&v.to_le_bytes());
    }
    let meta: Vec<(&str, String)> = vec![
        ("format", omcl::map::floorplan::FORMAT.into()),
        ("version", version.into()),
        ("resolution", resolution),
        ("origin_x", ox),
        ("origin_y", oy),
        ("floor_z", fz),
        ("band_min", b0),
        ("band_max", b1),
        ("feature_dim", dim.to_string()),
        ("tau", tau.into()),
        ("encoder", "fuzz".into()),
        ("cells", n.to_string()),
        ("rows", k.to_string()),
    ];
    let mut crc = crc32fast::Hasher::new();
    for name in omcl::map::floorplan::CHECKED_FIELDS {
        let v = meta.iter().find(|(k, _)| *k == name).map_or("", |(_, v)| v);
        crc.update(format!("{name}={v}\n").as_bytes());
    }
    for t in [&cells, &rows, &features] {
        crc.update(t);
    }
    let mut json = String::from("{\"__metadata__\":{");
    for (k, v) in &meta {
        json.push_str(&format!("\"{k}\":\"{v}\","));
    }
    json.push_str(&format!("\"crc32\":\"{:08x}\"}}", crc.finalize()));
    let mut at = 0;
    for (name, dtype, shape, bytes) in [
        ("cells", "I32", format!("[{n_t},2]"), &cells),
        ("rows", "U32", format!("[{n_t}]"), &rows),
        ("features", "F32", format!("[{k_t},{dim_t}]"), &features),
    ] {
        json.push_str(&format!(
            ",\"{name}\":{{\"dtype\":\"{dtype}\",\"shape\":{shape},\"data_offsets\":[{at},{}]}}",
            at + bytes.len()
        ));
        at += bytes.len();
    }
    json.push('}');
    while json.len() % 8 != 0 {
        json.push(' ');
    }
    let mut out = (json.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(json.as_bytes());
    for t in [cells, rows, features] {
        out.extend_from_slice(&t);
    }
    out
}
