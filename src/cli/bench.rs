//! `omcl bench`: the paper's experiments on the synthetic benchmark.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, ValueEnum};

use omcl::experiment::tables::{self, BenchMap, TABLE1_VARIANTS, TrackingRow};
use omcl::experiment::{MapParams, SimSequence};
use omcl::mcl::FilterConfig;

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Experiment {
    /// Table I: tracking APE of the variants over the sequences.
    Table1,
}

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Which experiment.
    #[arg(value_enum)]
    pub experiment: Experiment,
    /// Number of sequences (seeds 0..n).
    #[arg(long, default_value_t = 10)]
    pub sequences: u64,
    /// First sequence seed.
    #[arg(long, default_value_t = 0)]
    pub first_seed: u64,
    /// Frames per sequence.
    #[arg(long, default_value_t = 150)]
    pub frames: usize,
    /// Particles.
    #[arg(long, default_value_t = 1024)]
    pub particles: usize,
    /// Rays (sampled pixels before duplicates are dropped).
    #[arg(long, default_value_t = 2048)]
    pub rays: usize,
    /// Likelihood exponent.
    #[arg(long)]
    pub sharpen: Option<f64>,
    /// Plain cosine sensor (paper's eq. 2).
    #[arg(long)]
    pub no_contrast: bool,
    /// Only these Table I variants (comma-separated names).
    #[arg(long)]
    pub variants: Option<String>,
    /// Localize with these features instead of the variant's (exact, gt, lseg-like).
    #[arg(long)]
    pub preset: Option<omcl::sim::features::Preset>,
    /// Output folder.
    #[arg(long, short, default_value = "bench-out")]
    pub out: PathBuf,
}

pub fn run(a: BenchArgs) -> anyhow::Result<()> {
    let table = tables::builtin_table()?;
    let mut config = FilterConfig::default();
    config.sampling.rays = a.rays;
    if let Some(s) = a.sharpen {
        config.sharpen = s;
    }
    config.sensor.contrast = !a.no_contrast;
    let variants: Vec<_> = TABLE1_VARIANTS
        .iter()
        .filter(|v| {
            a.variants
                .as_deref()
                .is_none_or(|s| s.split(',').any(|n| n.trim() == v.name))
        })
        .collect();
    let mut results: Vec<Vec<_>> = vec![Vec::new(); variants.len()];
    for s in a.first_seed..a.first_seed + a.sequences {
        let seq =
            SimSequence::generate(s, a.frames, &table).with_context(|| format!("sequence {s}"))?;
        for (vi, v) in variants.iter().enumerate() {
            let t = std::time::Instant::now();
            let map = BenchMap::build(&seq, v.map, &MapParams::default(), &|_| {})?;
            let tm = t.elapsed().as_secs_f64();
            let r = tables::track(
                &seq,
                &map,
                a.preset.unwrap_or(v.localize),
                FilterConfig { seed: s, ..config },
                a.particles,
            )?;
            println!(
                "seq {s} {}: rmse {:.3} max {:.3} completed {} fps {:.1} rays {:.0} (map {tm:.1}s, {} voxels, {} rows)",
                v.name,
                r.stats.rmse,
                r.stats.max,
                r.completed,
                r.fps(),
                r.mean_rays,
                map.map.len(),
                map.map.db().len()
            );
            if std::env::var_os("OMCL_BENCH_DEBUG").is_some() {
                let e: Vec<String> = r.errors_m.iter().map(|e| format!("{e:.2}")).collect();
                println!("  errors: {}", e.join(" "));
            }
            results[vi].push(r);
        }
    }
    for (v, rs) in variants.iter().zip(results) {
        let row = TrackingRow::new(v.name, rs);
        if let Some(s) = &row.summary {
            println!(
                "{}: RMSE {:.3} STD {:.3} mean {:.3} median {:.3} min RMSE {:.3} max RMSE {:.3} SSE {:.2} completed {}/{} fps {:.1}",
                row.variant,
                s.mean.rmse,
                s.mean.std,
                s.mean.mean,
                s.mean.median,
                s.min_rmse,
                s.max_rmse,
                s.mean.sse,
                row.completed,
                row.per_sequence.len(),
                row.fps
            );
        }
    }
    let _ = &a.out;
    Ok(())
}
