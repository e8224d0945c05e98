//! Mapping a large LAZ: the file read whole (`load_cloud` then
//! `map_from_cloud`, what `omcl map cloud` did before 2026-11-29) against
//! batch by batch (`omcl::mapping::tiles`, what it does now), one file and
//! the same points as a folder of tiles. Each run is a child process of
//! this binary, so its peak resident memory (`VmHWM`) is its own.
//!
//! The cloud is the real Autzen tile (110,000 points, feet, classes 1
//! and 2) copied `OMCL_BENCH_LAS_COPIES` times (default 100: 11 M points)
//! side by side, 1,000 feet apart, written as one LAZ and as one LAS tile
//! a copy. `cargo bench --bench las_tiles`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use omcl::io::labels::BuiltinClasses;
use omcl::mapping::pipeline::{self, BuildParams, CloudInput};
use omcl::mapping::tiles::{TileOptions, TileSource, map_from_tiles};

/// Voxel edge, metres: `OMCL_BENCH_LAS_RESOLUTION`, default 2 (aerial
/// LiDAR at 0.5 m is about a voxel a point, and the map, not the cloud,
/// is then most of the memory).
fn resolution() -> f64 {
    std::env::var("OMCL_BENCH_LAS_RESOLUTION")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2.0)
}

fn params() -> BuildParams {
    BuildParams {
        resolution: resolution(),
        tau: 0.02,
        max_rows: 4096,
        encoder: "clip-vit-b32".into(),
        keep_strays: false,
    }
}

/// Peak resident memory of this process, MiB.
fn peak_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// A child's run: maps `input` the `mode` way and prints
/// `wall_s peak_mib voxels`.
fn child(mode: &str, input: &Path) {
    let sim = omcl::sim::files::builtin_table().unwrap();
    let table = omcl::sim::embeddings::builtin_label_table(BuiltinClasses::Asprs, &sim).unwrap();
    let t = Instant::now();
    let voxels = match mode {
        "whole" => {
            let input = CloudInput {
                path: input.to_path_buf(),
                ..Default::default()
            };
            let c = pipeline::load_cloud(&input).unwrap();
            let (m, _) =
                pipeline::map_from_cloud(c, "whole", &params(), Some(&table), None).unwrap();
            m.len()
        }
        _ => {
            let src = TileSource::open(input).unwrap();
            let (m, _, _) = map_from_tiles(
                &src,
                &TileOptions::default(),
                &params(),
                Some(&table),
                &mut |_, _, _| {},
            )
            .unwrap();
            m.len()
        }
    };
    println!(
        "{:.2} {:.0} {voxels}",
        t.elapsed().as_secs_f64(),
        peak_mib()
    );
}

/// Writes the copies of autzen as one LAZ (`big.laz`) and a LAS tile
/// each (`tiles/NNN.las`); returns the point count.
fn write_inputs(dir: &Path, copies: usize) -> u64 {
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/las/autzen_trim.laz");
    let mut r = las::Reader::from_path(&src).expect("../shared/data/las/autzen_trim.laz");
    let header = r.header().clone();
    let data = r.read_all().unwrap();
    let points: Vec<las::Point> = data.points().map(|p| p.unwrap()).collect();
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    let mut one = las::Writer::from_path(dir.join("big.laz"), {
        let mut b = las::Builder::from(header.clone());
        b.point_format.is_compressed = true;
        b.into_header().unwrap()
    })
    .unwrap();
    for k in 0..copies {
        let mut b = las::Builder::from(header.clone());
        b.point_format.is_compressed = false;
        let mut tile =
            las::Writer::from_path(tiles.join(format!("{k:03}.las")), b.into_header().unwrap())
                .unwrap();
        for p in &points {
            let mut q = p.clone();
            q.x += 1000.0 * k as f64;
            one.write_point(q.clone()).unwrap();
            tile.write_point(q).unwrap();
        }
        tile.close().unwrap();
    }
    one.close().unwrap();
    (points.len() * copies) as u64
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--child") {
        child(&args[i + 1], Path::new(&args[i + 2]));
        return;
    }
    let copies: usize = std::env::var("OMCL_BENCH_LAS_COPIES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100);
    let dir = tempfile::tempdir().unwrap();
    let n = write_inputs(dir.path(), copies);
    let size = |p: &Path| std::fs::metadata(p).map_or(0, |m| m.len());
    let tiles_bytes: u64 = std::fs::read_dir(dir.path().join("tiles"))
        .unwrap()
        .flatten()
        .map(|e| size(&e.path()))
        .sum();
    println!(
        "{n} points: big.laz {:.0} MB, {copies} LAS tiles {:.0} MB; resolution {} m",
        size(&dir.path().join("big.laz")) as f64 / 1e6,
        tiles_bytes as f64 / 1e6,
        resolution()
    );
    println!("| input | path | wall, s | peak RSS, MiB | voxels |");
    println!("|---|---|---|---|---|");
    let me = std::env::current_exe().unwrap();
    for (input, mode) in [
        ("big.laz", "whole"),
        ("big.laz", "batched"),
        ("tiles", "batched"),
    ] {
        let out = std::process::Command::new(&me)
            .args(["--child", mode])
            .arg(dir.path().join(input))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        let f: Vec<&str> = text.split_whitespace().collect();
        if !out.status.success() || f.len() != 3 {
            eprintln!("{input} {mode}: {}", String::from_utf8_lossy(&out.stderr));
            std::process::exit(1);
        }
        println!("| {input} | {mode} | {} | {} | {} |", f[0], f[1], f[2]);
    }
}
