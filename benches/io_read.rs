//! Reader throughput: binary PLY of one million synthetic points, ASCII
//! PLY of 200,000, the real KITTI scan and the real Autzen LAZ tile.
use std::path::Path;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use omcl::io::cloud::PointCloud;
use omcl::io::{kitti, las, ply};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn synthetic(n: usize, dim: usize) -> PointCloud {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    PointCloud {
        points: (0..n)
            .map(|_| {
                [
                    rng.random::<f64>() * 100.0,
                    rng.random::<f64>() * 100.0,
                    rng.random(),
                ]
            })
            .collect(),
        labels: Some((0..n).map(|_| rng.random_range(0..30)).collect()),
        colors: Some((0..n).map(|_| rng.random()).collect()),
        features: (dim > 0).then(|| (dim, (0..n * dim).map(|_| rng.random()).collect())),
        notes: Vec::new(),
        left_out: Vec::new(),
        georef: None,
    }
}

/// `cloud` as an ASCII PLY (double xyz, uchar rgb, int label).
fn ascii_ply(cloud: &PointCloud) -> String {
    use std::fmt::Write;
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
         property int label\nend_header\n",
        cloud.len()
    );
    let (labels, colors) = (
        cloud.labels.as_ref().unwrap(),
        cloud.colors.as_ref().unwrap(),
    );
    for ((p, c), l) in cloud.points.iter().zip(colors).zip(labels) {
        let _ = writeln!(
            s,
            "{} {} {} {} {} {} {l}",
            p[0], p[1], p[2], c[0], c[1], c[2]
        );
    }
    s
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let mut g = c.benchmark_group("read");
    g.sample_size(10);
    let n = 1_000_000;
    let p = dir.path().join("a.ply");
    ply::write_ply(&p, &synthetic(n, 0)).unwrap();
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("ply_binary_1M_xyz_rgb_label", |b| {
        b.iter(|| ply::read_ply(&p).unwrap())
    });
    let pf = dir.path().join("f.ply");
    let nf = 100_000;
    ply::write_ply(&pf, &synthetic(nf, 16)).unwrap();
    g.throughput(Throughput::Elements(nf as u64));
    g.bench_function("ply_binary_100k_16_features", |b| {
        b.iter(|| ply::read_ply(&pf).unwrap())
    });
    // ASCII (CloudCompare, MeshLab and PCL write it): omcl's own tokenizer.
    let pa = dir.path().join("ascii.ply");
    let na = 200_000;
    std::fs::write(&pa, ascii_ply(&synthetic(na, 0))).unwrap();
    g.throughput(Throughput::Elements(na as u64));
    g.bench_function("ply_ascii_200k_xyz_rgb_label", |b| {
        b.iter(|| ply::read_ply(&pa).unwrap())
    });
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("ply_write_1M_xyz_rgb_label", |b| {
        let cloud = synthetic(n, 0);
        let out = dir.path().join("w.ply");
        b.iter(|| ply::write_ply(&out, &cloud).unwrap())
    });
    let shared = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data"));
    let scan = shared.join("semantickitti/sequences/00/velodyne/000000.bin");
    if scan.exists() {
        g.throughput(Throughput::Elements(124_668));
        g.bench_function("kitti_bin_124k", |b| {
            b.iter(|| kitti::read_velodyne_bin(&scan).unwrap())
        });
    }
    let laz = shared.join("las/autzen_trim.laz");
    if laz.exists() {
        g.throughput(Throughput::Elements(110_000));
        g.bench_function("laz_autzen_110k", |b| {
            b.iter(|| las::read_las(&laz).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
