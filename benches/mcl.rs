//! One full filter step (predict, sample pixels, weigh, estimate, resample)
//! with 1024 particles and 2048 rays on a ~1 M-voxel map, and prompt
//! initialization on the same map (issue 5 speed targets: >= 10 steps/s,
//! prompt init < 1 s). Features come from a label image rendered at the
//! true pose with 512-d label embeddings (encoder time excluded).
//!
//! Run: `cargo bench --bench mcl`. Also prints the per-stage times and rays
//! per CPU-second (user + system time of the process, from /proc), which
//! stays meaningful on a shared machine.

use std::hint::black_box;
use std::sync::Arc;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use omcl::frame::{LabelImage, LabelLookup};
use omcl::geometry::{Intrinsics, Pose, camera_ray, level_camera};
use omcl::map::{FeatureDb, GridSpec, LanguageMap};
use omcl::mcl::{
    Filter, FilterConfig, FloorParams, PromptParams, RayOrder, SensorModel, local_init, prompt_init,
};
use omcl::raycast::{Packet, RayCaster};
use omcl::scene::{self, RoomsConfig, rooms};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

const DIM: usize = 512;

/// Label to feature (the map's rows); no row known ahead, so the sampler
/// computes each pixel's nearest row as it would for an encoder's output.
struct MapRows<'a>(&'a [f32]);

impl LabelLookup for MapRows<'_> {
    fn row(&self, _label: u32) -> Option<u32> {
        None
    }
    fn feature(&self, label: u32) -> Option<&[f32]> {
        let l = label as usize;
        self.0.get(l * DIM..(l + 1) * DIM)
    }
    fn dim(&self) -> usize {
        DIM
    }
}

/// Process CPU time (user + system), seconds.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = after
        .split_whitespace()
        .map(|s| s.parse().unwrap_or(0.0))
        .collect();
    // Fields 14 and 15 of stat (utime, stime) are 11 and 12 after ')'.
    (f.get(11).copied().unwrap_or(0.0) + f.get(12).copied().unwrap_or(0.0)) / 100.0
}

fn bench(c: &mut Criterion) {
    let s = rooms(&RoomsConfig::million());
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let n_labels = (scene::FURNITURE_BASE + scene::FURNITURE_KINDS) as usize;
    let rows: Vec<f32> = (0..n_labels * DIM)
        .map(|_| rng.sample::<f32, _>(StandardNormal))
        .collect();
    let db = FeatureDb::from_rows(DIM, 0.02, rows).expect("rows");
    let grid = GridSpec {
        resolution: s.resolution,
        origin: Vector3::zeros(),
    };
    let map = LanguageMap::from_cells(
        grid,
        db,
        "bench",
        s.cells.iter().copied().zip(s.labels.iter().copied()),
    )
    .expect("map");
    let caster: Arc<dyn RayCaster> =
        Arc::new(SensorModel::embree_caster(s.resolution as f32, &map.cells()).expect("embree"));
    println!("map: {} voxels at {} m", map.len(), s.resolution);

    let k = Intrinsics::from_hfov(540, 540, 90.0);
    let [x, y] = s.free_spots[s.free_spots.len() / 2];
    let truth = level_camera(Vector3::new(x, y, 1.5), 0.3);
    let rays: Vec<_> = (0..k.height)
        .flat_map(|v| (0..k.width).map(move |u| (u, v)))
        .map(|(u, v)| camera_ray(&k, &truth, &Vector3::zeros(), u, v))
        .collect();
    let labels: Vec<u32> = caster
        .cast_vec(&rays)
        .iter()
        .map(|h| map.rows().get(h.leaf as usize).copied().unwrap_or(u32::MAX))
        .collect();
    let rows = MapRows(map.db().rows());
    let frame = LabelImage::new(k.width, k.height, &labels, &rows).unwrap();

    let config = FilterConfig {
        resample: omcl::mcl::ResamplePolicy {
            ess_fraction: 1.1,
            ..Default::default()
        },
        ..Default::default()
    };
    let init = local_init(&truth, 1024, 0.3, 17f64.to_radians(), &mut rng);
    let mut filter = Filter::new(&map, caster.clone(), k, config, init).expect("filter");
    let inc = Pose::from_parts(Translation3::new(0.0, 0.0, 0.0), UnitQuaternion::identity());

    // Stage times and rays per CPU-second over a fixed number of steps.
    let steps = 20;
    let (cpu0, t0) = (cpu_seconds(), Instant::now());
    let mut sum = omcl::mcl::StepTimings::default();
    let mut rays_cast = 0usize;
    for _ in 0..steps {
        let r = filter.step(&inc, &frame).expect("step");
        rays_cast += r.n_rays * r.n_particles;
        sum.features += r.timings.features;
        sum.predict += r.timings.predict;
        sum.weigh += r.timings.weigh;
        sum.cast += r.timings.cast;
        sum.update += r.timings.update;
    }
    let (cpu, wall) = (cpu_seconds() - cpu0, t0.elapsed().as_secs_f64());
    let ms = |d: std::time::Duration| 1e3 * d.as_secs_f64() / steps as f64;
    println!(
        "step: {:.1} ms wall ({:.1} steps/s), {:.2} CPU-s/step; features {:.1} ms, predict {:.1} ms, \
         weigh {:.1} ms (cast {:.1} ms), update {:.1} ms; {:.0} rays/step; {:.2} M rays per CPU-second",
        1e3 * wall / steps as f64,
        steps as f64 / wall,
        cpu / steps as f64,
        ms(sum.features),
        ms(sum.predict),
        ms(sum.weigh),
        ms(sum.cast),
        ms(sum.update),
        rays_cast as f64 / steps as f64,
        rays_cast as f64 / cpu.max(1e-9) / 1e6,
    );

    // The ray orders (RayOrder) on two particle clouds: the steady state
    // reached above and the spread of local initialization. One step from
    // the same cloud each time, the orders interleaved; median cast time.
    let steady = filter.particles().to_vec();
    let spread = local_init(&truth, 1024, 0.3, 17f64.to_radians(), &mut rng);
    for (name, cloud) in [
        ("steady state", &steady),
        ("local init 0.3 m / 17 deg", &spread),
    ] {
        let orders = [
            RayOrder::Auto,
            RayOrder::ParticleMajor,
            RayOrder::PixelMajor,
        ];
        let mut filters: Vec<Filter> = orders
            .iter()
            .map(|&o| {
                Filter::new(&map, caster.clone(), k, config, cloud.clone())
                    .expect("filter")
                    .with_ray_order(o)
            })
            .collect();
        let mut times = vec![Vec::new(); orders.len()];
        let mut auto_pixel_major = 0;
        let rounds = 9;
        for round in 0..rounds {
            // Each order leads a round in turn.
            for i in (0..orders.len()).map(|i| (i + round) % orders.len()) {
                let f = &mut filters[i];
                f.reinitialize(cloud.clone()).expect("particles");
                let r = f.step(&inc, &frame).expect("step");
                times[i].push(1e3 * r.timings.cast.as_secs_f64());
                if i == 0 && f.last_pixel_major() {
                    auto_pixel_major += 1;
                }
            }
        }
        let row: Vec<String> = orders
            .iter()
            .zip(&mut times)
            .map(|(o, t)| {
                t.sort_by(f64::total_cmp);
                format!("{o:?} {:.1} ms", t[t.len() / 2])
            })
            .collect();
        println!(
            "ray order, {name}: cast {} (median of {rounds}); Auto chose pixel-major {auto_pixel_major} of {rounds} times",
            row.join(", ")
        );
    }

    // The same step with other packet widths, for the record.
    for packet in [Packet::Single, Packet::Sixteen] {
        let other: Arc<dyn RayCaster> = Arc::new(
            SensorModel::embree_caster(s.resolution as f32, &map.cells())
                .expect("embree")
                .with_packet(packet),
        );
        let init = local_init(&truth, 1024, 0.3, 17f64.to_radians(), &mut rng);
        let mut f = Filter::new(&map, other, k, config, init).expect("filter");
        let cpu0 = cpu_seconds();
        let mut cast = std::time::Duration::ZERO;
        let mut n = 0usize;
        for _ in 0..5 {
            let r = f.step(&inc, &frame).expect("step");
            cast += r.timings.cast;
            n += r.n_rays * r.n_particles;
        }
        println!(
            "{packet:?}: cast {:.1} ms/step, {:.2} M rays per CPU-second (whole step)",
            1e3 * cast.as_secs_f64() / 5.0,
            n as f64 / (cpu_seconds() - cpu0).max(1e-9) / 1e6
        );
    }

    let mut g = c.benchmark_group("mcl_1M");
    g.sample_size(10);
    g.bench_function("step_1024x2048", |b| {
        b.iter(|| black_box(filter.step(&inc, &frame).expect("step")))
    });
    let floor = map.db().row(scene::FLOOR as usize).to_vec();
    let word = map.db().row(scene::FURNITURE_BASE as usize).to_vec();
    let t0 = Instant::now();
    let ps = prompt_init(
        &map,
        &floor,
        std::slice::from_ref(&word),
        &FloorParams::default(),
        &PromptParams::default(),
        1024,
        &mut rng,
    )
    .expect("prompt");
    println!(
        "prompt init: {} particles in {:.3} s",
        ps.len(),
        t0.elapsed().as_secs_f64()
    );
    g.bench_function("prompt_init_1_word", |b| {
        b.iter(|| {
            prompt_init(
                &map,
                &floor,
                std::slice::from_ref(&word),
                &FloorParams::default(),
                &PromptParams::default(),
                1024,
                &mut rng,
            )
            .expect("prompt")
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
