//! The street filter through KITTI 00's left turn at frame 1545 with noisy
//! (`lseg-like`) camera features: the car slows at a crossing and turns
//! 90 degrees while a third of its image is sky. The map has nothing
//! where the sky is, so at the true pose those rays miss; scored 0, a
//! miss ranks below a hit on any facade, and the filter turned 20
//! degrees off the road and lost the car there on three of four tuning
//! streets (README, "Misses on streets"). Tuning streets 1 and 2, frames
//! 1490 to 1559 (in the tuning range, seeds 0-99). Reads the KITTI 00 path
//! from ../shared/data: without it the test fails.

use std::path::Path;

use omcl::experiment::features::builtin_table;
use omcl::experiment::table4::{Table4Params, table4};
use omcl::sim::features::Preset;

fn run(seed: u64, miss_score: Option<f32>, out: &Path) -> omcl::experiment::table4::Table4Run {
    let trajectories = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/trajectories");
    assert!(
        trajectories.join("KITTI_00_gt.txt").exists(),
        "{} is missing: the test needs ../shared/data",
        trajectories.display()
    );
    let mut filter = Table4Params::filter_default();
    if let Some(m) = miss_score {
        filter.sensor.miss_score = m;
    }
    let p = Table4Params {
        trajectories,
        street_start: 1490,
        street_frames: 70,
        street_resolution: 0.1,
        odometry: vec!["noise".into()],
        first_seed: seed,
        sequences: 1,
        particles: 512,
        filter,
        preset: Preset::LsegLike,
        encoder_stride: 1,
        out: out.to_path_buf(),
    };
    std::fs::create_dir_all(out).unwrap();
    let table = builtin_table().unwrap();
    let mut t = table4(&p, &table, &|_| {}, &|_| {}).unwrap();
    assert_eq!(t.runs.len(), 1);
    t.runs.remove(0)
}

#[test]
fn the_street_filter_keeps_its_heading_through_a_sky_filled_turn() {
    let dir = tempfile::tempdir().unwrap();
    // Measured on street 2: 0.301 m, 0.78 degrees, at most 1.12 m (0.278
    // m, 0.74 degrees before the products went through faer, 0.373 m,
    // 1.01 degrees before they went through the database's span: each
    // rounds otherwise and takes the filter down another path); street 1:
    // 0.320 m, 0.90 degrees, at most 0.75 m.
    let mut lost = Vec::new();
    for seed in [1, 2] {
        let out = dir.path().join(format!("street{seed}"));
        let street = run(seed, None, &out);
        assert_eq!(street.frames, 70);
        assert!(
            street.completed == Some(true)
                && street.translation_mean_m < 0.5
                && street.translation_max_m < 1.2
                && street.rotation_mean_deg < 1.6,
            "{street:?}"
        );
        // Misses at 0, as indoors: the heading goes off in the turn and
        // the worst error is larger than the street filter's, on three of
        // the four tuning streets (README). Measured with faer's rounding:
        // street 1 11.2 degrees, up to 2.54 m, not completed; street 2
        // kept its heading this time (1.58 degrees, up to 0.69 m; 4.05
        // degrees and 1.85 m with the rounding before). So one of the two
        // must lose it, not each.
        let zero = run(seed, Some(0.0), &dir.path().join(format!("zero{seed}")));
        if zero.rotation_mean_deg > 3.0 && zero.translation_max_m > street.translation_max_m {
            lost.push(seed);
        }
    }
    assert!(
        !lost.is_empty(),
        "misses scored 0 kept the heading on both streets"
    );
}
