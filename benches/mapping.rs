//! Mapping throughput and memory (issue 4 targets): option 2 (points into
//! voxels) in points/s, option 1 (540 x 540 RGB-D frames) in frames/s, and
//! the memory of a ~1 M-voxel map while integrating and when finished; and
//! `omcl map query`'s work on that map (issue 21: under 1 s).
//!
//! Run: `cargo bench --bench mapping`.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;
use omcl::geometry::{Intrinsics, level_camera};
use omcl::map::{FeatureDb, GridSpec, Integrator};
use omcl::mapping::{self, Feature, LabelImage};
use omcl::raycast::EmbreeCaster;
use omcl::scene::{FURNITURE_BASE, FURNITURE_KINDS, RoomsConfig, rooms};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn table(dim: usize) -> FeatureDb {
    let k = (FURNITURE_BASE + FURNITURE_KINDS) as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let rows: Vec<f32> = (0..k * dim).map(|_| rng.random_range(-1.0..1.0)).collect();
    FeatureDb::from_rows(dim, 0.02, rows).expect("table")
}

fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(0.0, |kb| kb / 1024.0)
}

fn bench(c: &mut Criterion) {
    let s = rooms(&RoomsConfig::million());
    let grid = GridSpec {
        resolution: s.resolution,
        origin: Vector3::zeros(),
    };
    // Five points per voxel, uniformly inside it: a dense LiDAR-like cloud.
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut points = Vec::with_capacity(s.cells.len() * 5);
    let mut rows = Vec::with_capacity(s.cells.len() * 5);
    for (c, &l) in s.cells.iter().zip(&s.labels) {
        for _ in 0..5 {
            let p = [
                (c[0] as f64 + rng.random::<f64>()) * s.resolution,
                (c[1] as f64 + rng.random::<f64>()) * s.resolution,
                (c[2] as f64 + rng.random::<f64>()) * s.resolution,
            ];
            points.push(p);
            rows.push(l);
        }
    }
    let db = table(512);
    let rows: Vec<Option<u32>> = rows.into_iter().map(Some).collect();
    let mut integ = Integrator::new(grid, db.clone()).expect("grid");
    mapping::cloud::integrate_point_rows(&mut integ, &points, &rows);
    let integrating = integ.memory_bytes();
    let voxels = integ.voxel_count();
    let m = integ.finish("bench", 0.02).expect("map");
    println!(
        "1M-voxel map: {voxels} voxels from {} points; integrator {:.1} MB ({:.1} B/voxel); \
         finished map {:.1} MB ({:.1} B/voxel incl. {} x 512 rows); peak RSS so far {:.0} MB",
        points.len(),
        integrating as f64 / 1e6,
        integrating as f64 / voxels as f64,
        m.memory_bytes() as f64 / 1e6,
        m.memory_bytes() as f64 / voxels as f64,
        m.db().len(),
        peak_rss_mb()
    );

    let mut g = c.benchmark_group("option2_points");
    g.sample_size(10);
    g.throughput(Throughput::Elements(points.len() as u64));
    g.bench_function("label_rows_integrate_and_finish", |b| {
        b.iter(|| {
            let mut integ = Integrator::new(grid, db.clone()).expect("grid");
            mapping::cloud::integrate_point_rows(&mut integ, black_box(&points), &rows);
            integ.finish("bench", 0.02).expect("map")
        })
    });
    // Features, one 512-d vector per point, quantized by the admission rule
    // (every point of a class carries its class vector): the cost of raw
    // feature files such as OpenScene's.
    let feats: Vec<f32> = rows
        .iter()
        .take(500_000)
        .flat_map(|r| db.row(r.unwrap_or(0) as usize).to_vec())
        .collect();
    g.throughput(Throughput::Elements(500_000));
    g.bench_function("features_512d_500k_points", |b| {
        b.iter(|| {
            let mut integ =
                Integrator::new(grid, FeatureDb::new(512, 0.02).expect("db")).expect("grid");
            mapping::cloud::integrate_points(&mut integ, black_box(&points[..500_000]), |i| {
                Feature::Vector(&feats[i * 512..(i + 1) * 512])
            })
            .expect("features")
        })
    });
    g.finish();

    // Option 1: depth and labels rendered from the scene at 540 x 540.
    let k = Intrinsics::from_hfov(540, 540, 90.0);
    let caster = EmbreeCaster::new(s.resolution as f32, &s.cells).expect("scene");
    let [x, y] = s.free_spots[0];
    let pose = level_camera(Vector3::new(x, y, 1.5), 0.7);
    let omcl::scene::View { depth, labels, .. } = omcl::scene::render(&s, &caster, &k, &pose);
    let row_of = |l: u32| (l != u32::MAX).then_some(l);
    let img = LabelImage::new(k.width, k.height, &labels, &row_of).expect("one label a pixel");
    let mut g = c.benchmark_group("option1_rgbd_540");
    g.sample_size(20);
    g.throughput(Throughput::Elements(1));
    let opt = mapping::rgbd::FrameOptions::default();
    let mut integ = Integrator::new(grid, db.clone()).expect("grid");
    g.bench_function("label_frame_stride1", |b| {
        b.iter(|| {
            mapping::rgbd::integrate_frame(&mut integ, &k, black_box(&depth), &pose, &img, &opt)
                .expect("frame")
        })
    });
    g.finish();

    // `omcl map query` on the ~1 M-voxel map: every voxel's best similarity
    // to two words, the count near the best, and the heat-map PLY.
    let map = omcl::map::LanguageMap::from_cells(
        grid,
        db.clone(),
        "bench",
        s.cells.iter().copied().zip(s.labels.iter().copied()),
    )
    .expect("map");
    let words = FeatureDb::from_rows(512, 0.02, [db.row(3), db.row(7)].concat()).expect("words");
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("heat.ply");
    let mut g = c.benchmark_group("map_query_1m");
    g.sample_size(10);
    g.bench_function("scores", |b| {
        b.iter(|| {
            let best = omcl::map::query::best_similarity(&map, black_box(&words)).expect("query");
            omcl::map::query::count_near_best(&best, 0.9)
        })
    });
    g.bench_function("scores_and_ply", |b| {
        b.iter(|| {
            let best = omcl::map::query::best_similarity(&map, black_box(&words)).expect("query");
            let heat = omcl::mapping::colors::normalize_range(&best);
            let g = map.grid();
            let mut cloud = omcl::io::cloud::PointCloud::from_points(
                map.cells().iter().map(|&c| g.center(c).into()).collect(),
            );
            cloud.colors = Some(
                heat.iter()
                    .map(|&t| omcl::mapping::colors::heat_color(t))
                    .collect(),
            );
            cloud.labels = Some(map.rows().to_vec());
            omcl::io::ply::write_ply(&out, &cloud).expect("ply");
            omcl::map::query::count_near_best(&best, 0.9)
        })
    });
    g.finish();
    println!("map_query_1m: {} voxels", map.len());
}

criterion_group!(benches, bench);
criterion_main!(benches);
