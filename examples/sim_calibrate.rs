//! Calibration of the synthetic feature model against the paper's Table II.
//!
//! `cargo run --release --example sim_calibrate -- [preset] [frames] [stride] [json overrides]`
//! renders the default indoor world along the default path and prints the
//! measurement-map consistency (accuracy, precision, recall, IoU) of the
//! preset's features. Overrides are a JSON object of `FeatureParams` fields.

use omcl::geometry::Intrinsics;
use omcl::raycast::EmbreeCaster;
use omcl::sim::consistency::measure;
use omcl::sim::features::{FeatureModel, FeatureParams, Preset};
use omcl::sim::files::builtin_table;
use omcl::sim::indoor::{INDOOR_CLASSES, IndoorConfig, generate};
use omcl::sim::paths::{IndoorPathConfig, indoor_path};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let preset: Preset = args
        .get(1)
        .map_or("lseg-like", |s| s.as_str())
        .parse()
        .map_err(anyhow::Error::msg)?;
    let frames: usize = args.get(2).map_or(Ok(30), |s| s.parse())?;
    let stride: u32 = args.get(3).map_or(Ok(4), |s| s.parse())?;
    let mut params = serde_json::to_value(preset.params())?;
    if let Some(o) = args.get(4) {
        let over: serde_json::Value = serde_json::from_str(o)?;
        if let (Some(p), Some(o)) = (params.as_object_mut(), over.as_object()) {
            for (k, v) in o {
                p.insert(k.clone(), v.clone());
            }
        }
    }
    let params: FeatureParams = serde_json::from_value(params)?;
    let mut total = [0.0f64; 4];
    // Calibration looks at tuning seeds only (omcl::experiment::seeds).
    let seeds = [0u64, 1, 2];
    assert!(
        seeds
            .iter()
            .all(|s| omcl::experiment::seeds::TUNING.contains(s))
    );
    for &seed in &seeds {
        let world = generate(&IndoorConfig {
            seed,
            ..Default::default()
        });
        let path = indoor_path(
            &world.layout,
            &IndoorPathConfig {
                seed: seed + 1,
                ..Default::default()
            },
        );
        let caster = EmbreeCaster::new(world.voxels.resolution as f32, &world.voxels.cells)?;
        let table = builtin_table()?.subset(INDOOR_CLASSES)?;
        let model = FeatureModel::new(table, params, seed + 3);
        let k = Intrinsics::from_hfov(540, 540, 90.0);
        let step = (path.len() / frames).max(1);
        let poses: Vec<_> = path
            .iter()
            .enumerate()
            .step_by(step)
            .map(|(i, p)| (i as u64, *p))
            .collect();
        let s = measure(&model, &world.voxels, &caster, &k, &poses, stride);
        println!(
            "seed {seed}: accuracy {:.2} precision {:.2} recall {:.2} IoU {:.2}",
            100.0 * s.accuracy,
            100.0 * s.precision,
            100.0 * s.recall,
            100.0 * s.iou
        );
        for (t, v) in total
            .iter_mut()
            .zip([s.accuracy, s.precision, s.recall, s.iou])
        {
            *t += 100.0 * v / seeds.len() as f64;
        }
    }
    println!(
        "{} mean: accuracy {:.2} precision {:.2} recall {:.2} IoU {:.2}",
        preset.name(),
        total[0],
        total[1],
        total[2],
        total[3]
    );
    Ok(())
}
