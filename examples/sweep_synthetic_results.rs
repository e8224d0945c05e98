//! Fills a result folder with synthetic results for every tracking run of
//! a manifest (errors, step times and positions of the run's length drawn
//! from a seeded generator; nothing is localized), to measure `omcl sweep
//! collect` at scale:
//!
//! ```sh
//! omcl sweep plan table1 --variants OMCL_LSeg --sequences 100000 --first-seed 1000 -o big/m.jsonl
//! cargo run --release --example sweep_synthetic_results -- big/m.jsonl big/results
//! omcl sweep collect big/m.jsonl -o big/tables
//! ```

use anyhow::Context;
use rand::{Rng, SeedableRng};

use omcl::eval::ErrorStats;
use omcl::experiment::RunResult;
use omcl::experiment::sweep::{
    Cost, Manifest, ManifestLine, OMCL_VERSION, Outcome, RunRecord, TrackOutcome, Work,
};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    anyhow::ensure!(
        args.len() == 3,
        "usage: sweep_synthetic_results MANIFEST RESULT_DIR"
    );
    let manifest = Manifest::read(args[1].as_ref())?;
    let results = std::path::Path::new(&args[2]);
    let mut n = 0;
    for line in &manifest.lines {
        let ManifestLine::Run(e) = line else { continue };
        let Work::Track { .. } = e.task.work else {
            continue;
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(e.task.seed);
        let f = e.task.frames;
        let errors: Vec<f64> = (0..f).map(|_| rng.random_range(0.0..0.3)).collect();
        let xy: Vec<[f64; 2]> = (0..f)
            .map(|_| [rng.random_range(0.0..10.0), rng.random_range(0.0..10.0)])
            .collect();
        let r = RunRecord {
            id: e.id.clone(),
            omcl: OMCL_VERSION.into(),
            task: e.task.clone(),
            outcome: Outcome::Track(Box::new(TrackOutcome {
                result: RunResult {
                    estimates: Vec::new(),
                    stats: ErrorStats::from_errors(&errors).context("no frames")?,
                    completed: Some(true),
                    step_seconds: (0..f).map(|_| rng.random_range(0.05..0.1)).collect(),
                    encoder_seconds: (0..f).map(|_| rng.random_range(0.05..0.1)).collect(),
                    errors_m: errors,
                    mean_rays: 1900.0,
                    map_rows: 29,
                },
                truth_xy: xy.clone(),
                estimate_xy: xy,
            })),
            cost: Cost::default(),
        };
        let dir = results.join(&e.id[..2]);
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let path = dir.join(format!("{}.json", e.id));
        std::fs::write(&path, serde_json::to_vec(&r)?)
            .with_context(|| format!("writing {}", path.display()))?;
        n += 1;
    }
    println!("wrote {n} synthetic results into {}", results.display());
    Ok(())
}
