//! Ray casting throughput on a ~1 M-voxel map at 5 cm (issue 2 targets):
//! full camera images, MCL-shaped sparse rays in two packet orders (and
//! with the filter's own caster, `SensorModel::embree_caster`), scene build
//! time, and the reference traversal for the ratio. The criterion groups
//! use the default geometry (bricks of edge 4).
//!
//! Run: `cargo bench --bench raycast`. Sizes of map, primitives and BVH are
//! printed once before the measurements.
//!
//! With `OMCL_BENCH_GEOMETRIES=R` set, a table comparing the Embree
//! geometries (boxes, bricks of edge 2, 4, 8) is printed first: R rounds,
//! each measuring every geometry on every workload in turn for about a
//! second (interleaved, so load from other processes on a shared machine
//! hits all variants alike), reported as the median over rounds of rays
//! per CPU-second of this process (utime + stime, all threads) and per
//! wall second.

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;
use omcl::geometry::{Intrinsics, Pose, Ray, camera_ray, level_camera};
use omcl::raycast::{
    BrickEdge, BuildOptions, EmbreeCaster, Geometry, Hit, Packet, RayCaster, ReferenceCaster,
};
use omcl::scene::{RoomsConfig, Scene, rooms};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn scene() -> Scene {
    rooms(&RoomsConfig::million())
}

fn camera(s: &Scene) -> Pose {
    let [x, y] = s.free_spots[s.free_spots.len() / 2];
    level_camera(Vector3::new(x, y, 1.5), 0.3)
}

/// Morton order of pixel coordinates, so that 16 consecutive pixels are a
/// 4 x 4 tile.
fn pixel_order(px: &mut [(u32, u32)]) {
    let spread = |v: u32| -> u64 {
        let mut x = v as u64 & 0xffff;
        x = (x | (x << 8)) & 0x00ff00ff;
        x = (x | (x << 4)) & 0x0f0f0f0f;
        x = (x | (x << 2)) & 0x33333333;
        (x | (x << 1)) & 0x55555555
    };
    px.sort_unstable_by_key(|&(u, v)| spread(u) | (spread(v) << 1));
}

fn full_image_rays(k: &Intrinsics, pose: &Pose) -> Vec<Ray> {
    let mut px: Vec<(u32, u32)> = (0..k.height)
        .flat_map(|v| (0..k.width).map(move |u| (u, v)))
        .collect();
    pixel_order(&mut px);
    px.iter()
        .map(|&(u, v)| camera_ray(k, pose, &Vector3::zeros(), u, v))
        .collect()
}

/// Interleaves the low 10 bits of three values (a 3-D Morton key).
fn morton3(a: u32, b: u32, c: u32) -> u64 {
    let sp = |v: u32| -> u64 { (0..10).map(|i| (((v >> i) & 1) as u64) << (3 * i)).sum() };
    sp(a) | (sp(b) << 1) | (sp(c) << 2)
}

/// 1024 particles around `pose` (0.3 m, 17 degrees of yaw), 2048 pixels
/// drawn uniformly from the image. Returns rays particle-major (same
/// particle, nearby pixels) and pixel-major (same pixel, particles that are
/// near each other in position and yaw).
fn mcl_rays(k: &Intrinsics, pose: &Pose, base_yaw: f64) -> (Vec<Ray>, Vec<Ray>) {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let t = Normal::new(0.0, 0.3).expect("valid sigma");
    let yaw = Normal::new(0.0, 17f64.to_radians()).expect("valid sigma");
    let base = pose.translation.vector;
    let mut particles: Vec<(Pose, f64)> = (0..1024)
        .map(|_| {
            let p = base + Vector3::new(t.sample(&mut rng), t.sample(&mut rng), 0.0);
            let y = yaw.sample(&mut rng);
            (level_camera(p, base_yaw + y), y)
        })
        .collect();
    let q = |x: f64, step: f64| ((x / step + 512.0).max(0.0) as u32).min(1023);
    particles.sort_by_key(|(p, y)| {
        let v = p.translation.vector - base;
        morton3(q(v.x, 0.05), q(v.y, 0.05), q(*y, 0.02))
    });
    let mut px: Vec<(u32, u32)> = (0..2048)
        .map(|_| (rng.random_range(0..k.width), rng.random_range(0..k.height)))
        .collect();
    pixel_order(&mut px);
    let o = Vector3::zeros();
    let by_particle = particles
        .iter()
        .flat_map(|(p, _)| px.iter().map(move |&(u, v)| camera_ray(k, p, &o, u, v)))
        .collect();
    let by_pixel = px
        .iter()
        .flat_map(|&(u, v)| {
            particles
                .iter()
                .map(move |(p, _)| camera_ray(k, p, &o, u, v))
        })
        .collect();
    (by_particle, by_pixel)
}

/// User + system CPU seconds of this process (all threads).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = after
        .split_whitespace()
        .map(|s| s.parse().unwrap_or(0.0))
        .collect();
    // Fields 14 and 15 of stat (utime, stime) are 11 and 12 after ')'.
    let ticks = f.get(11).copied().unwrap_or(0.0) + f.get(12).copied().unwrap_or(0.0);
    ticks / 100.0
}

/// Casts `rays` repeatedly for about a second; returns (M rays per
/// CPU-second, M rays per wall second).
fn rate(e: &EmbreeCaster, rays: &[Ray], hits: &mut [Hit]) -> (f64, f64) {
    e.cast(rays, hits); // warm the caches
    let (c0, t0) = (cpu_seconds(), Instant::now());
    let mut n = 0usize;
    while t0.elapsed().as_secs_f64() < 1.0 {
        e.cast(black_box(rays), hits);
        n += rays.len();
    }
    let (cpu, wall) = (cpu_seconds() - c0, t0.elapsed().as_secs_f64());
    (n as f64 / cpu.max(1e-9) / 1e6, n as f64 / wall / 1e6)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The interleaved comparison of the Embree geometries (see the module doc).
fn geometry_table(s: &Scene, rounds: usize) {
    let res = s.resolution as f32;
    let n = s.cells.len();
    let k = Intrinsics::from_hfov(540, 540, 90.0);
    let pose = camera(s);
    let image = full_image_rays(&k, &pose);
    let (by_particle, by_pixel) = mcl_rays(&k, &pose, 0.3);
    let d = BuildOptions::default();
    let variants: Vec<(&str, BuildOptions)> = [
        ("boxes", Geometry::Boxes),
        ("bricks2", Geometry::Bricks(BrickEdge::Two)),
        ("bricks4", Geometry::Bricks(BrickEdge::Four)),
        ("bricks8", Geometry::Bricks(BrickEdge::Eight)),
    ]
    .into_iter()
    .map(|(name, geometry)| (name, BuildOptions { geometry, ..d }))
    .collect();
    for (name, o) in &variants {
        let (c0, t0) = (cpu_seconds(), Instant::now());
        let e = EmbreeCaster::with_options(res, &s.cells, *o).expect("Embree scene");
        println!(
            "{name}: build {:.3} s wall / {:.3} CPU-s; {} primitives ({:.1} voxels each); \
             primitive data {:.1} B/voxel; Embree {:.1} B/voxel ({:.1} MB)",
            t0.elapsed().as_secs_f64(),
            cpu_seconds() - c0,
            e.primitives(),
            n as f64 / e.primitives() as f64,
            e.box_bytes() as f64 / n as f64,
            e.embree_bytes() as f64 / n as f64,
            e.embree_bytes() as f64 / 1e6,
        );
    }
    let work: [(&str, Packet, &[Ray]); 8] = [
        ("image 540x540", Packet::Eight, &image),
        ("image 540x540", Packet::Sixteen, &image),
        ("MCL pixel-major", Packet::Single, &by_pixel),
        ("MCL particle-major", Packet::Single, &by_particle),
        ("MCL pixel-major", Packet::Eight, &by_pixel),
        ("MCL particle-major", Packet::Four, &by_particle),
        ("MCL particle-major", Packet::Eight, &by_particle),
        ("MCL particle-major", Packet::Sixteen, &by_particle),
    ];
    // One caster per (workload, variant): the packet width is the caster's.
    let casters: Vec<Vec<EmbreeCaster>> = work
        .iter()
        .map(|(_, p, _)| {
            variants
                .iter()
                .map(|(_, o)| {
                    EmbreeCaster::with_options(res, &s.cells, *o)
                        .expect("Embree scene")
                        .with_packet(*p)
                })
                .collect()
        })
        .collect();
    let mut hits = vec![Hit::miss(); image.len().max(by_pixel.len())];
    let mut cpu = vec![vec![Vec::new(); variants.len()]; work.len()];
    let mut wall = cpu.clone();
    for _ in 0..rounds {
        for (w, (_, _, rays)) in work.iter().enumerate() {
            for (g, e) in casters[w].iter().enumerate() {
                let (c, t) = rate(e, rays, &mut hits[..rays.len()]);
                cpu[w][g].push(c);
                wall[w][g].push(t);
            }
        }
    }
    println!("M rays per CPU-second (per wall second), median of {rounds} rounds:");
    for (w, (name, packet, _)) in work.iter().enumerate() {
        let row: Vec<String> = variants
            .iter()
            .enumerate()
            .map(|(g, (v, _))| {
                format!(
                    "{v} {:.1} ({:.1})",
                    median(&mut cpu[w][g]),
                    median(&mut wall[w][g])
                )
            })
            .collect();
        println!("  {name:<19} {packet:?}: {}", row.join(", "));
    }
}

fn bench(c: &mut Criterion) {
    let s = scene();
    if let Some(rounds) = std::env::var("OMCL_BENCH_GEOMETRIES")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
    {
        geometry_table(&s, rounds.max(1));
    }
    let res = s.resolution as f32;
    let t0 = Instant::now();
    let embree = EmbreeCaster::new(res, &s.cells).expect("Embree scene");
    let build = t0.elapsed();
    let reference = ReferenceCaster::new(res, &s.cells);
    let n = s.cells.len();
    println!(
        "scene: {n} voxels at {res} m; first build {:.3} s; map {:.1} B/voxel (code 8 + row 4); \
         {:?}: {} primitives, primitive data {:.1} B/voxel; Embree BVH {:.1} B/voxel ({:.1} MB)",
        build.as_secs_f64(),
        12.0,
        embree.geometry(),
        embree.primitives(),
        embree.box_bytes() as f64 / n as f64,
        embree.embree_bytes() as f64 / n as f64,
        embree.embree_bytes() as f64 / 1e6,
    );

    let k = Intrinsics::from_hfov(540, 540, 90.0);
    let pose = camera(&s);
    let image = full_image_rays(&k, &pose);
    let mut hits = vec![Hit::miss(); image.len()];
    embree.cast(&image, &mut hits);
    let hit_rate = hits.iter().filter(|h| h.is_hit()).count() as f64 / hits.len() as f64;
    println!(
        "full image: {} rays, {:.1} % hit",
        image.len(),
        100.0 * hit_rate
    );

    let mut g = c.benchmark_group("full_image_540");
    g.sample_size(20);
    g.throughput(Throughput::Elements(image.len() as u64));
    for p in [Packet::Sixteen, Packet::Eight, Packet::Single] {
        let e = EmbreeCaster::new(res, &s.cells)
            .expect("scene")
            .with_packet(p);
        g.bench_function(format!("embree_{p:?}"), |b| {
            b.iter(|| e.cast(black_box(&image), &mut hits))
        });
    }
    // The reference on a sixteenth of the rays (same kind of work).
    let sub: Vec<Ray> = image.iter().step_by(16).copied().collect();
    let mut sub_hits = vec![Hit::miss(); sub.len()];
    g.throughput(Throughput::Elements(sub.len() as u64));
    g.sample_size(10);
    g.bench_function("reference_dda", |b| {
        b.iter(|| reference.cast(black_box(&sub), &mut sub_hits))
    });
    g.finish();

    let (by_particle, by_pixel) = mcl_rays(&k, &pose, 0.3);
    let mut hits = vec![Hit::miss(); by_particle.len()];
    let mut g = c.benchmark_group("mcl_1024x2048");
    g.sample_size(10);
    g.throughput(Throughput::Elements(by_particle.len() as u64));
    for p in [Packet::Single, Packet::Eight, Packet::Sixteen] {
        let e = EmbreeCaster::new(res, &s.cells)
            .expect("scene")
            .with_packet(p);
        g.bench_function(format!("embree_{p:?}_particle_major"), |b| {
            b.iter(|| e.cast(black_box(&by_particle), &mut hits))
        });
        g.bench_function(format!("embree_{p:?}_pixel_major"), |b| {
            b.iter(|| e.cast(black_box(&by_pixel), &mut hits))
        });
    }
    // What the filter uses: its own caster (bricks of edge 8, 8-wide
    // packets) and particle-major order.
    let f = omcl::mcl::SensorModel::embree_caster(res, &s.cells).expect("scene");
    g.bench_function("filter_caster_particle_major", |b| {
        b.iter(|| f.cast(black_box(&by_particle), &mut hits))
    });
    let sub: Vec<Ray> = by_pixel.iter().step_by(64).copied().collect();
    let mut sub_hits = vec![Hit::miss(); sub.len()];
    g.throughput(Throughput::Elements(sub.len() as u64));
    g.bench_function("reference_dda", |b| {
        b.iter(|| reference.cast(black_box(&sub), &mut sub_hits))
    });
    g.finish();

    let mut g = c.benchmark_group("build_1M");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("embree_scene", |b| {
        b.iter(|| EmbreeCaster::new(res, black_box(&s.cells)).expect("scene"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
