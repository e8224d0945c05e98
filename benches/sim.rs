//! Synthetic benchmark generation: the default indoor world plus a 300-frame
//! 540 x 540 RGB-D sequence written to disk (rendering through Embree, PNG
//! encoding, ground-truth export), and the pieces on their own.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};

use omcl::raycast::EmbreeCaster;
use omcl::sim::dataset::{IndoorDatasetConfig, write_indoor};
use omcl::sim::features::{FeatureModel, Preset};
use omcl::sim::files::builtin_table;
use omcl::sim::indoor::{INDOOR_CLASSES, IndoorConfig, generate};
use omcl::sim::paths::{IndoorPathConfig, indoor_path};
use omcl::sim::render::render_frame;

fn bench(c: &mut Criterion) {
    let table = builtin_table().expect("built-in table");
    let mut g = c.benchmark_group("sim");
    g.sample_size(10);
    g.bench_function("indoor_world_default", |b| {
        b.iter(|| black_box(generate(&IndoorConfig::default())))
    });
    let world = generate(&IndoorConfig::default());
    let caster =
        EmbreeCaster::new(world.voxels.resolution as f32, &world.voxels.cells).expect("embree");
    let path = indoor_path(&world.layout, &IndoorPathConfig::default());
    let k = IndoorDatasetConfig::new(0).intrinsics();
    g.bench_function("render_frame_540", |b| {
        b.iter(|| black_box(render_frame(&caster, &world.voxels, &k, &path[100])))
    });
    let frame = render_frame(&caster, &world.voxels, &k, &path[100]);
    let model = FeatureModel::preset(
        table.subset(INDOOR_CLASSES).expect("classes"),
        Preset::LsegLike,
        0,
    );
    g.bench_function("lseg_like_features_2048_pixels", |b| {
        let mut out = vec![0.0f32; model.dim()];
        b.iter(|| {
            for i in 0..2048u32 {
                let (u, v) = ((i * 7919) % 540, (i * 104_729) % 540);
                let ctx = model.context(&frame, u, v);
                model.feature_at(100, u, v, &ctx, &mut out);
            }
            black_box(out[0])
        })
    });
    g.sample_size(10);
    g.measurement_time(std::time::Duration::from_secs(60));
    g.bench_function("indoor_dataset_default_300_frames", |b| {
        b.iter(|| {
            let dir = tempfile::tempdir().expect("tempdir");
            let cfg = IndoorDatasetConfig::new(0);
            black_box(write_indoor(dir.path(), &cfg, &table, (&[], None), &|_| {}).expect("write"))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
