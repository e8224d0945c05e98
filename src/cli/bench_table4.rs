//! `omcl bench table4`: the paper's Table IV on the street world (a
//! synthetic street along the real KITTI 00 path, not KITTI's images); the
//! experiment is [`omcl::experiment::table4::table4`], this file turns the
//! options into its parameters and shows its progress.

use std::path::{Path, PathBuf};

use omcl::experiment::table4::{Table4Params, table4 as run_table4};
use omcl::sim::embeddings::ClassEmbeddings;
use omcl::sim::features::Preset;

use super::bench::{BenchArgs, apply_overrides};

fn default_trajectories() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/trajectories")
}

/// Runs Table IV and returns its Markdown; writes `table4.json` and
/// `table4_<odometry>.png` (the first seed's path).
pub fn table4(a: &BenchArgs, table: &ClassEmbeddings) -> anyhow::Result<String> {
    let params = Table4Params {
        trajectories: a
            .street
            .trajectories
            .clone()
            .unwrap_or_else(default_trajectories),
        street_start: a.street.street_start,
        street_frames: a.street.street_frames,
        street_resolution: a.street.street_resolution,
        odometry: a.street.odometry.split(',').map(str::to_string).collect(),
        first_seed: a.plan.first_seed,
        sequences: a.plan.sequences,
        particles: a.plan.particles.unwrap_or(512),
        filter: {
            let mut f = Table4Params::filter_default();
            if let Some(r) = a.plan.rays {
                f.sampling.rays = r;
            }
            apply_overrides(f, &a.plan.set)?
        },
        preset: a.plan.preset.unwrap_or(Preset::Gt),
        out: a.out.clone(),
    };
    let pb = super::progress::spinner("Table IV");
    let t = run_table4(
        &params,
        table,
        &|msg| pb.set_message(msg.to_string()),
        &|line| pb.suspend(|| eprintln!("{line}")),
    )?;
    pb.finish_and_clear();
    Ok(t.markdown)
}
