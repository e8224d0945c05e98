//! `omcl bench`: the paper's experiments on the synthetic benchmark,
//! written as Markdown and JSON tables and PNG/SVG figures.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::{Args, ValueEnum};

use omcl::eval::localization::CONVERGENCE_THRESHOLDS;
use omcl::experiment::tables::{
    self, BenchMap, ConsistencyRow, GlobalRun, TABLE1_VARIANTS, TrackingRow, Variant,
};
use omcl::experiment::{MapParams, MapSource, RunResult, SimSequence};
use omcl::mcl::{FilterConfig, SamplingStrategy};
use omcl::plot::{self, Axes, BarGroup, FloorPlan, Series, TrajectoryPanel};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Experiment {
    /// Table I: tracking APE of the variants from the paper's local start,
    /// with Figure 4 (trajectories coloured by APE over the floor plan).
    Table1,
    /// Table II: measurement-map consistency of the variants.
    Table2,
    /// Table V: steps until global localization reaches 2 ... 0.1 m,
    /// without and with a prompt.
    Table5,
    /// Figure: APE and FPS against particles for several ray counts.
    ParticlesRays,
    /// Figure: stratified against equal and uniform ray sampling.
    Sampling,
    /// Table IV: camera 2 on the street world along the real KITTI 00
    /// path (--street-*), the odometry variants of --odometry; translation
    /// and rotation error, completion, filter steps/s, and the estimated
    /// path over the map. Not part of `all`.
    Table4,
    /// Everything above but table4.
    All,
}

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Which experiments (one or more; maps built for one are reused by
    /// the next, e.g. `omcl bench table1 table2`).
    #[arg(value_enum, required = true, num_args = 1..)]
    pub experiments: Vec<Experiment>,
    /// Number of sequences (seeds first-seed .. first-seed + n).
    #[arg(long, default_value_t = 10)]
    pub sequences: u64,
    /// First sequence seed.
    #[arg(long, default_value_t = 0)]
    pub first_seed: u64,
    /// Frames per sequence.
    #[arg(long, default_value_t = 150)]
    pub frames: usize,
    /// Frames of each map's second (mapping) path; every second frame of it
    /// and of the sequence is mapped.
    #[arg(long, default_value_t = 300)]
    pub map_frames: usize,
    /// Particles (default 1024; table4: 512, the paper's outdoor setting).
    #[arg(long)]
    pub particles: Option<usize>,
    /// Rays, sampled pixels before duplicates are dropped (default 2048;
    /// table4: 4096).
    #[arg(long)]
    pub rays: Option<usize>,
    /// table4: first frame of KITTI 00 the street starts at.
    #[arg(long, default_value_t = 0)]
    pub street_start: usize,
    /// table4: frames of the street (KITTI 00 has 4541, 3.7 km; 300 are
    /// the first 226 m).
    #[arg(long, default_value_t = 300)]
    pub street_frames: usize,
    /// table4: voxel edge of the street world and of its LiDAR map, metres
    /// (the authors' configuration for sequence 00: 0.1).
    #[arg(long, default_value_t = 0.1)]
    pub street_resolution: f64,
    /// table4: odometry variants, comma-separated: `noise` (ground truth
    /// plus the authors' 0.1 m on camera x and z and 0.1 rad yaw a frame),
    /// `orb` (the frame-to-frame motion of the real ORB-SLAM2 estimate of
    /// KITTI 00 replayed from the first true pose; stands in for the
    /// paper's Stereo DSO).
    #[arg(long, default_value = "noise,orb")]
    pub odometry: String,
    /// table4: folder with KITTI_00_gt.txt and KITTI_00_ORB.txt (default:
    /// the shared data beside the source tree).
    #[arg(long)]
    pub trajectories: Option<PathBuf>,
    /// Only these variants (comma-separated: OMCL_GT, OMCL_LSeg,
    /// OMCL_auto_LSeg, OMCL_Open_LSeg, OMCL_GT_exact; default all).
    #[arg(long)]
    pub variants: Option<String>,
    /// Localize (and score consistency) with these features instead of each
    /// variant's own: exact, gt or lseg-like.
    #[arg(long)]
    pub preset: Option<omcl::sim::features::Preset>,
    /// The variant of Table V and the ablations.
    #[arg(long, default_value = "OMCL_LSeg")]
    pub ablation_variant: String,
    /// Sequences used by the ablations (their sweeps are long).
    #[arg(long, default_value_t = 3)]
    pub ablation_sequences: u64,
    /// Start frames per sequence for Table V.
    #[arg(long, default_value_t = 3)]
    pub starts: usize,
    /// Steps of each global-localization run.
    #[arg(long, default_value_t = 60)]
    pub max_steps: usize,
    /// Override any filter parameter: `--set sharpen=40 --set
    /// sensor.miss_score=0.2` (paths into the filter configuration's JSON,
    /// printed by `--show-config`; VALUE is JSON).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// Print the filter configuration as JSON and exit.
    #[arg(long)]
    pub show_config: bool,
    /// Output folder (created if missing).
    #[arg(long, short, default_value = "bench-out")]
    pub out: PathBuf,
}

/// Sequences and maps, made once and shared by the experiments.
struct Bench {
    table: omcl::sim::embeddings::ClassEmbeddings,
    frames: usize,
    map_params: MapParams,
    sequences: HashMap<u64, SimSequence>,
    maps: HashMap<(u64, String), BenchMap>,
}

impl Bench {
    fn sequence(&mut self, seed: u64) -> anyhow::Result<&SimSequence> {
        if !self.sequences.contains_key(&seed) {
            let s = SimSequence::generate(seed, self.frames, &self.table)
                .with_context(|| format!("sequence {seed}"))?;
            self.sequences.insert(seed, s);
        }
        Ok(&self.sequences[&seed])
    }

    fn map(&mut self, seed: u64, source: MapSource) -> anyhow::Result<(&SimSequence, &BenchMap)> {
        self.sequence(seed)?;
        let key = (seed, source.name());
        if !self.maps.contains_key(&key) {
            let seq = &self.sequences[&seed];
            let params = self.map_params;
            let n =
                params.frames.div_ceil(params.frame_step) + seq.len().div_ceil(params.frame_step);
            let pb = super::progress::bar(n as u64, &format!("map {seed}"));
            let m = BenchMap::build(seq, source, &params, &|i| pb.set_position(i as u64))
                .with_context(|| format!("map of sequence {seed} from {}", source.name()))?;
            pb.finish_and_clear();
            self.maps.insert(key.clone(), m);
        }
        Ok((&self.sequences[&seed], &self.maps[&key]))
    }
}

pub fn run(a: BenchArgs) -> anyhow::Result<()> {
    let mut config = FilterConfig::default();
    config.sampling.rays = a.rays.unwrap_or(2048);
    let config = apply_overrides(config, &a.set)?;
    if a.show_config {
        println!("{}", serde_json::to_string_pretty(&config)?);
        return Ok(());
    }
    anyhow::ensure!(a.sequences > 0, "--sequences must be at least 1");
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut bench = Bench {
        table: tables::builtin_table()?,
        frames: a.frames,
        map_params: MapParams {
            frames: a.map_frames,
            ..MapParams::default()
        },
        sequences: HashMap::new(),
        maps: HashMap::new(),
    };
    let variants: Vec<Variant> = TABLE1_VARIANTS
        .iter()
        .filter(|v| {
            a.variants
                .as_deref()
                .is_none_or(|s| s.split(',').any(|n| n.trim() == v.name))
        })
        .map(|v| Variant {
            localize: a.preset.unwrap_or(v.localize),
            ..*v
        })
        .collect();
    anyhow::ensure!(
        !variants.is_empty(),
        "--variants matches none of {:?}",
        TABLE1_VARIANTS.map(|v| v.name)
    );
    let ablation = *TABLE1_VARIANTS
        .iter()
        .find(|v| v.name == a.ablation_variant)
        .with_context(|| {
            format!(
                "--ablation-variant {:?} is not a variant",
                a.ablation_variant
            )
        })?;
    let mut e = a.experiments.clone();
    e.sort_by_key(|x| *x as u8);
    e.dedup();
    let all = e.contains(&Experiment::All);
    let wants = |x: Experiment| all || e.contains(&x);
    let mut report = if e.as_slice() == [Experiment::Table4] {
        String::from("# omcl bench\n\n")
    } else {
        format!(
            "# omcl bench ({} sequences of {} frames, {} particles, {} rays)\n\n",
            a.sequences,
            a.frames,
            a.particles.unwrap_or(1024),
            config.sampling.rays
        )
    };
    if wants(Experiment::Table1) {
        report += &table1(&a, &mut bench, &variants, config)?;
    }
    if wants(Experiment::Table2) {
        report += &table2(&a, &mut bench, &variants)?;
    }
    if wants(Experiment::Table5) {
        report += &table5(&a, &mut bench, ablation, config)?;
    }
    if wants(Experiment::ParticlesRays) {
        report += &particles_rays(&a, &mut bench, ablation, config)?;
    }
    if wants(Experiment::Sampling) {
        report += &sampling(&a, &mut bench, ablation, config)?;
    }
    if e.contains(&Experiment::Table4) {
        report += &super::bench_table4::table4(&a, &bench.table)?;
    }
    let name = match e.as_slice() {
        _ if all => "all.md".into(),
        [one] => format!(
            "{}.md",
            one.to_possible_value()
                .map_or("bench".into(), |v| v.get_name().to_string())
        ),
        _ => "bench.md".into(),
    };
    write_text(&a.out.join(&name), &report)?;
    println!("{report}");
    println!("wrote {}", a.out.display());
    Ok(())
}

fn seeds(a: &BenchArgs, n: u64) -> std::ops::Range<u64> {
    a.first_seed..a.first_seed + n
}

fn write_text(path: &Path, text: &str) -> anyhow::Result<()> {
    omcl::sim::files::write_atomic(path, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    write_text(path, &serde_json::to_string_pretty(value)?)
}

fn table1(
    a: &BenchArgs,
    bench: &mut Bench,
    variants: &[Variant],
    config: FilterConfig,
) -> anyhow::Result<String> {
    let mut rows = Vec::new();
    for v in variants {
        let mut runs: Vec<RunResult> = Vec::new();
        let mut panels_data = Vec::new();
        for s in seeds(a, a.sequences) {
            let (seq, map) = bench.map(s, v.map)?;
            let pb = super::progress::spinner(&format!("{} sequence {s}", v.name));
            let r = tables::track(
                seq,
                map,
                v.localize,
                FilterConfig { seed: s, ..config },
                a.particles.unwrap_or(1024),
            )?;
            pb.finish_and_clear();
            eprintln!(
                "{} sequence {s}: APE rmse {:.3} m, max {:.3}, completed {}, {:.1} steps/s \
                 ({:.1} with the simulated encoder), K = {}",
                v.name,
                r.stats.rmse,
                r.stats.max,
                r.completed,
                r.fps(),
                r.fps_with_encoder(),
                r.map_rows
            );
            panels_data.push((
                s,
                floor_plan(seq, map),
                xy(seq.poses()),
                xy(&r.estimates),
                r.errors_m.clone(),
            ));
            runs.push(r);
        }
        let titles: Vec<String> = panels_data
            .iter()
            .map(|(s, ..)| format!("{} sequence {s}", v.name))
            .collect();
        let panels: Vec<TrajectoryPanel> = panels_data
            .iter()
            .zip(&titles)
            .map(|((_, plan, gt, est, err), t)| TrajectoryPanel {
                title: t,
                plan: plan.as_ref(),
                gt_xy: &gt[..est.len()],
                est_xy: est,
                errors_m: err,
            })
            .collect();
        for ext in ["png", "svg"] {
            plot::trajectory_grid(&a.out.join(format!("figure4_{}.{ext}", v.name)), &panels)?;
        }
        rows.push(TrackingRow::new(v.name, runs));
    }
    write_json(&a.out.join("table1.json"), &rows)?;
    Ok(table1_markdown(&rows))
}

/// Table I as Markdown.
fn table1_markdown(rows: &[TrackingRow]) -> String {
    let mut s = String::from(
        "## Table I: APE of tracking (m), averaged over sequences\n\n\
         | variant | RMSE | STD | Mean | Median | min RMSE | max RMSE | SSE (m^2) | completed | steps/s | with encoder | K |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        if let Some(m) = &r.summary {
            let _ = writeln!(
                s,
                "| {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {}/{} | {:.1} | {:.1} | {:.0} |",
                r.variant,
                m.mean.rmse,
                m.mean.std,
                m.mean.mean,
                m.mean.median,
                m.min_rmse,
                m.max_rmse,
                m.mean.sse,
                r.completed,
                r.per_sequence.len(),
                r.fps,
                r.fps_with_encoder,
                r.map_rows
            );
        }
    }
    s.push('\n');
    s
}

fn xy(poses: &[omcl::geometry::Pose]) -> Vec<[f64; 2]> {
    poses
        .iter()
        .map(|p| [p.translation.vector.x, p.translation.vector.y])
        .collect()
}

/// The map's floor plan, floor voxels by similarity to "floor".
fn floor_plan(seq: &SimSequence, map: &BenchMap) -> Option<FloorPlan> {
    FloorPlan::from_map(&map.map, seq.table.text_feature("floor"), 0.9)
}

fn table2(a: &BenchArgs, bench: &mut Bench, variants: &[Variant]) -> anyhow::Result<String> {
    let mut rows = Vec::new();
    for v in variants {
        let mut per_seq = Vec::new();
        for s in seeds(a, a.sequences) {
            let (seq, map) = bench.map(s, v.map)?;
            per_seq.push(tables::consistency(seq, map, v.localize, 10)?);
        }
        rows.push(ConsistencyRow::new(v.name, per_seq));
    }
    write_json(&a.out.join("table2.json"), &rows)?;
    let mut s = String::from(
        "## Table II: measurement-map consistency (%), per pose, averaged over poses then sequences\n\n\
         | variant | Accuracy | Precision | Recall | IoU |\n|---|---|---|---|---|\n",
    );
    for r in &rows {
        if let Some(m) = &r.mean {
            let _ = writeln!(
                s,
                "| {} | {:.1} | {:.1} | {:.1} | {:.1} |",
                r.variant,
                100.0 * m.accuracy,
                100.0 * m.precision,
                100.0 * m.recall,
                100.0 * m.iou
            );
        }
    }
    s.push('\n');
    Ok(s)
}

fn table5(
    a: &BenchArgs,
    bench: &mut Bench,
    v: Variant,
    config: FilterConfig,
) -> anyhow::Result<String> {
    let mut all: Vec<(bool, Vec<GlobalRun>)> = Vec::new();
    for prompt in [false, true] {
        let mut runs = Vec::new();
        for s in seeds(a, a.sequences) {
            let (seq, map) = bench.map(s, v.map)?;
            let pb = super::progress::spinner(&format!(
                "global localization{} in sequence {s}",
                if prompt { " with a prompt" } else { "" }
            ));
            let spec = tables::GlobalSpec {
                preset: v.localize,
                filter: FilterConfig { seed: s, ..config },
                particles: a.particles.unwrap_or(1024),
                starts: a.starts,
                max_steps: a.max_steps,
                prompt,
            };
            runs.extend(tables::global_runs(seq, map, &spec)?);
            pb.finish_and_clear();
        }
        all.push((prompt, runs));
    }
    let table: Vec<_> = all
        .iter()
        .map(|(p, runs)| serde_json::json!({"prompt": p, "rows": tables::steps_rows(runs), "runs": runs}))
        .collect();
    write_json(&a.out.join("table5.json"), &table)?;
    let mut s = format!(
        "## Table V: steps until global localization reaches each accuracy ({}, {} runs of at most {} steps)\n\n\
         | start | accuracy | mean | std | min | max | reached |\n|---|---|---|---|---|---|---|\n",
        v.name,
        all.first().map_or(0, |x| x.1.len()),
        a.max_steps
    );
    for (prompt, runs) in &all {
        for r in tables::steps_rows(runs) {
            let f = |x: Option<f64>| x.map_or("-".into(), |x| format!("{x:.1}"));
            let _ = writeln!(
                s,
                "| {} | {} m | {} | {} | {} | {} | {}/{} |",
                if *prompt { "prompt" } else { "global" },
                r.threshold_m,
                f(r.mean),
                f(r.std),
                f(r.min.map(|x| x as f64)),
                f(r.max.map(|x| x as f64)),
                r.reached,
                r.runs
            );
        }
    }
    let _ = writeln!(
        s,
        "\nThresholds: {CONVERGENCE_THRESHOLDS:?} m; a run counts for a threshold once its error first falls to or below it.\n"
    );
    Ok(s)
}

/// One ablation cell: tracking over the ablation sequences.
fn ablation_cell(
    a: &BenchArgs,
    bench: &mut Bench,
    v: Variant,
    config: FilterConfig,
    particles: usize,
) -> anyhow::Result<TrackingRow> {
    let mut runs = Vec::new();
    for s in seeds(a, a.ablation_sequences) {
        let (seq, map) = bench.map(s, v.map)?;
        runs.push(tables::track(
            seq,
            map,
            v.localize,
            FilterConfig { seed: s, ..config },
            particles,
        )?);
    }
    Ok(TrackingRow::new(v.name, runs))
}

const PARTICLES: [usize; 4] = [256, 512, 1024, 2048];
const RAYS: [usize; 4] = [512, 1024, 2048, 4096];

fn particles_rays(
    a: &BenchArgs,
    bench: &mut Bench,
    v: Variant,
    config: FilterConfig,
) -> anyhow::Result<String> {
    let mut cells = Vec::new();
    let pb = super::progress::bar((PARTICLES.len() * RAYS.len()) as u64, "particles x rays");
    for &rays in &RAYS {
        for &n in &PARTICLES {
            let mut c = config;
            c.sampling.rays = rays;
            let row = ablation_cell(a, bench, v, c, n)?;
            cells.push((n, rays, row));
            pb.inc(1);
        }
    }
    pb.finish_and_clear();
    let rmse = |r: &TrackingRow| r.summary.map_or(f64::NAN, |s| s.mean.rmse);
    let series = |f: &dyn Fn(&TrackingRow) -> f64| -> Vec<Series> {
        RAYS.iter()
            .map(|&rays| Series {
                label: format!("{rays} rays"),
                points: cells
                    .iter()
                    .filter(|c| c.1 == rays)
                    .map(|c| (c.0 as f64, f(&c.2)))
                    .collect(),
            })
            .collect()
    };
    for ext in ["png", "svg"] {
        plot::line_plot(
            &a.out.join(format!("ablation_particles_ape.{ext}")),
            &Axes {
                title: format!("APE RMSE against particles ({})", v.name),
                x_label: "particles".into(),
                y_label: "APE RMSE [m]".into(),
                log_x: true,
                log_y: false,
            },
            &series(&rmse),
        )?;
        plot::line_plot(
            &a.out.join(format!("ablation_particles_fps.{ext}")),
            &Axes {
                title: format!("Filter steps per second against particles ({})", v.name),
                x_label: "particles".into(),
                y_label: "steps/s".into(),
                log_x: true,
                log_y: true,
            },
            &series(&|r| r.fps),
        )?;
    }
    let json: Vec<_> = cells
        .iter()
        .map(|(n, rays, r)| serde_json::json!({"particles": n, "rays": rays, "rmse": rmse(r), "fps": r.fps, "completed": r.completed, "sequences": r.per_sequence.len()}))
        .collect();
    write_json(&a.out.join("ablation_particles_rays.json"), &json)?;
    let mut s = format!(
        "## Ablation: particles x rays ({}, {} sequences; APE RMSE m / steps per second)\n\n| rays \\ particles |",
        v.name, a.ablation_sequences
    );
    for n in PARTICLES {
        let _ = write!(s, " {n} |");
    }
    s += "\n|---|";
    s += &"---|".repeat(PARTICLES.len());
    s.push('\n');
    for rays in RAYS {
        let _ = write!(s, "| {rays} |");
        for c in cells.iter().filter(|c| c.1 == rays) {
            let _ = write!(s, " {:.3} / {:.1} |", rmse(&c.2), c.2.fps);
        }
        s.push('\n');
    }
    s.push('\n');
    Ok(s)
}

fn sampling(
    a: &BenchArgs,
    bench: &mut Bench,
    v: Variant,
    config: FilterConfig,
) -> anyhow::Result<String> {
    let strategies = [
        ("stratified", SamplingStrategy::Stratified),
        ("equal", SamplingStrategy::EqualWithDuplicates),
        ("uniform", SamplingStrategy::Uniform),
    ];
    let particles = [256, 512, 1024];
    let mut groups = Vec::new();
    let mut json = Vec::new();
    let mut s = format!(
        "## Ablation: ray sampling ({}, {} rays, {} sequences; APE RMSE m, completed)\n\n| particles | stratified | equal | uniform |\n|---|---|---|---|\n",
        v.name, config.sampling.rays, a.ablation_sequences
    );
    for n in particles {
        let mut bars = Vec::new();
        let _ = write!(s, "| {n} |");
        for (name, st) in strategies {
            let mut c = config;
            c.sampling.strategy = st;
            let row = ablation_cell(a, bench, v, c, n)?;
            let rmses: Vec<f64> = row.per_sequence.iter().map(|r| r.stats.rmse).collect();
            let (mean, std) = omcl::eval::ErrorStats::from_errors(&rmses)
                .map_or((f64::NAN, f64::NAN), |s| (s.mean, s.std));
            let _ = write!(
                s,
                " {mean:.3} ({}/{}) |",
                row.completed,
                row.per_sequence.len()
            );
            bars.push((name.to_string(), mean, Some(std)));
            json.push(serde_json::json!({"particles": n, "strategy": name, "rmse_mean": mean, "rmse_std": std, "completed": row.completed, "fps": row.fps}));
        }
        s.push('\n');
        groups.push(BarGroup {
            label: format!("{n} particles"),
            bars,
        });
    }
    for ext in ["png", "svg"] {
        plot::bar_plot(
            &a.out.join(format!("ablation_sampling.{ext}")),
            &Axes {
                title: format!("Ray sampling strategies ({})", v.name),
                x_label: "particles".into(),
                y_label: "APE RMSE [m]".into(),
                log_x: false,
                log_y: false,
            },
            &groups,
        )?;
    }
    write_json(&a.out.join("ablation_sampling.json"), &json)?;
    s.push('\n');
    Ok(s)
}

/// Applies `PATH=VALUE` overrides to a filter configuration through its
/// JSON form (`VALUE` is JSON; a bare word is taken as a string).
pub fn apply_overrides(config: FilterConfig, sets: &[String]) -> anyhow::Result<FilterConfig> {
    let mut v = serde_json::to_value(config)?;
    for s in sets {
        let (path, value) = s
            .split_once('=')
            .with_context(|| format!("--set {s:?}: expected PATH=VALUE"))?;
        let value: serde_json::Value = serde_json::from_str(value)
            .unwrap_or_else(|_| serde_json::Value::String(value.to_string()));
        let mut slot = &mut v;
        for key in path.split('.') {
            slot = slot.get_mut(key).with_context(|| {
                format!("--set {s:?}: no parameter {path:?} (see --show-config)")
            })?;
        }
        *slot = value;
    }
    serde_json::from_value(v).context("--set: the resulting configuration is invalid")
}
