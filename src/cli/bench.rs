//! `omcl bench`: the paper's experiments on the synthetic benchmark,
//! written as Markdown and JSON tables and PNG/SVG figures. It plans a
//! sweep (`<out>/sweep/manifest.jsonl`), runs it locally on a bounded pool
//! (results in `<out>/sweep/results/`, maps in `<out>/sweep/cache/`) and
//! collects the tables, as `omcl sweep plan`, `run` and `collect` do.

use std::path::{Path, PathBuf};

use anyhow::Context;

use omcl::experiment::sweep::{self, Cache, Manifest, ResultDir, RunStatus};
use omcl::experiment::table4::{Table4Params, table4 as run_table4};
use omcl::experiment::{features, report};
use omcl::sim::embeddings::ClassEmbeddings;
use omcl::sim::features::Preset;

use super::bench_args::{BenchArgs, Experiment, apply_overrides};

/// Runs what `a` asks for. A folder the run makes is removed again if the
/// run fails before writing into it (a refusal found only once a map is
/// built, such as a `two_d.skirt` taller than half the room, or a missing
/// trajectory file for `table4`); `remove_dir` leaves a folder with anything
/// in it alone, so a sweep's partial results stay for `--resume`.
pub fn run(a: BenchArgs) -> anyhow::Result<()> {
    let out = a.out.clone();
    let made = !out.exists();
    // Stopped before anything is written (SIGTERM, Ctrl-C), a folder this
    // run made is not left behind empty.
    let _empty = made.then(|| omcl::io::atomic::remove_if_empty_on_interrupt(&out));
    let result = run_experiments(a);
    if result.is_err() && made {
        // The sweep folder's mark and lock alone are not a result.
        let dir = out.join("sweep");
        let only_ours = std::fs::read_dir(&dir).is_ok_and(|d| {
            d.flatten()
                .all(|e| e.file_name() == BENCH_MARK || e.file_name() == "bench.lock")
        });
        if only_ours {
            let _ = std::fs::remove_file(dir.join(BENCH_MARK));
            let _ = std::fs::remove_file(dir.join("bench.lock"));
            let _ = std::fs::remove_dir(&dir);
        }
        let _ = std::fs::remove_dir(&out);
    }
    result
}

/// Refuses options of experiments the call does not run, naming who takes
/// them (they had been ignored without a word: `--jobs 2` on the Table I
/// blocks, `--street-frames` without table4, `--set sixdof.height_m`
/// without table1-sixdof). An option given at its default value is not
/// told from one left out.
fn refuse_options_of_other_experiments(a: &BenchArgs) -> anyhow::Result<()> {
    use omcl::experiment::sweep::Experiment as S;
    let ex = &a.plan.experiments;
    let planned: Vec<S> = ex.iter().filter_map(|e| e.to_library()).collect();
    let wants = |s: S| (planned.contains(&S::All) && s.in_all()) || planned.contains(&s);
    let has = |e: Experiment| ex.contains(&e);
    let street = &a.street;
    let scenes = &a.scenes;
    // (who takes them, whether this call runs it, (option, given)).
    type Group<'a> = (&'a str, bool, &'a [(&'a str, bool)]);
    let groups: [Group; 6] = [
        (
            "the planned experiments (table1, table2, table5, table5-floorplan, particles-rays, \
             sampling, all)",
            !planned.is_empty(),
            &[
                ("--jobs", a.jobs != 1),
                ("--resume", a.resume),
                ("--force", a.force),
            ],
        ),
        (
            "table5 and table5-floorplan",
            wants(S::Table5) || wants(S::Table5Floorplan),
            &[
                ("--starts", a.plan.starts != 3),
                ("--max-steps", a.plan.max_steps != 60),
            ],
        ),
        (
            "table5, table5-floorplan, particles-rays and sampling",
            wants(S::Table5)
                || wants(S::Table5Floorplan)
                || wants(S::ParticlesRays)
                || wants(S::Sampling),
            &[("--ablation-variant", a.plan.ablation_variant != "OMCL_LSeg")],
        ),
        (
            "particles-rays and sampling",
            wants(S::ParticlesRays) || wants(S::Sampling),
            &[("--ablation-sequences", a.plan.ablation_sequences != 3)],
        ),
        (
            "table4",
            has(Experiment::Table4),
            &[
                ("--street-start", street.street_start != 0),
                ("--street-frames", street.street_frames != 300),
                ("--street-resolution", street.street_resolution != 0.1),
                ("--odometry", street.odometry != "noise,orb"),
                ("--encoder-stride", street.encoder_stride != 1),
                ("--trajectories", street.trajectories.is_some()),
            ],
        ),
        (
            "sevenscenes",
            has(Experiment::SevenScenes),
            &[
                ("--scenes", scenes.scenes.is_some()),
                ("--scenes-frames", scenes.scenes_frames.is_some()),
                ("--localize-every", scenes.localize_every != 4),
                ("--colour-classes", scenes.colour_classes != 10),
                ("--edge-radius", scenes.edge_radius != 4),
                ("--colour-shift", scenes.colour_shift != [0, 0]),
                (
                    "--scenes-seeds",
                    scenes.scenes_seeds != "1000,1001,1002,1003,1004",
                ),
            ],
        ),
    ];
    for (who, applies, options) in groups {
        for &(option, given) in options {
            anyhow::ensure!(
                !given || applies,
                "{option} is an option of {who}, which this call does not run; leave it out"
            );
        }
    }
    // The Table I blocks' own --set paths.
    let set_names = |prefix: &str| {
        a.plan
            .set
            .iter()
            .filter(|s| s.starts_with(prefix))
            .cloned()
            .collect::<Vec<_>>()
    };
    let sixdof_sets = set_names("sixdof.");
    anyhow::ensure!(
        sixdof_sets.is_empty() || has(Experiment::Table1Sixdof),
        "--set {} is table1-sixdof's, which this call does not run; leave it out",
        sixdof_sets.join(", ")
    );
    let plan_sets = [set_names("plan."), set_names("two_d.")].concat();
    anyhow::ensure!(
        plan_sets.is_empty()
            || has(Experiment::Table1Floorplan)
            || has(Experiment::Table1Sixdof)
            || has(Experiment::Planned(sweep::Experiment::Table5Floorplan)),
        "--set {} is the floor plans' (table1-floorplan, table1-sixdof, table5-floorplan), \
         which this call does not run; leave it out",
        plan_sets.join(", ")
    );
    Ok(())
}

fn run_experiments(a: BenchArgs) -> anyhow::Result<()> {
    // Tables and figures go into --out: not into a sequence's folder.
    if let Some(f) = ["intrinsics.txt", "calib.txt", "sim.json", "poses.txt"]
        .iter()
        .find(|f| a.out.join(f).is_file())
    {
        anyhow::bail!(
            "--out {}: holds {f}, a sequence's folder: give omcl bench a folder of its own",
            a.out.display()
        );
    }
    if a.show_config {
        // The filter the experiment starts from: the street's for table4,
        // the 6-DoF one for table1-sixdof, the floor plan's for
        // table1-floorplan, else the indoor default.
        let base = match a.plan.experiments.as_slice() {
            [Experiment::Table4] => Table4Params::filter_default(),
            [Experiment::Table1Sixdof] => omcl::mcl::FilterConfig::six_dof(),
            [Experiment::Table1Floorplan]
            | [Experiment::Planned(sweep::Experiment::Table5Floorplan)] => {
                omcl::mcl::FilterConfig::floor_plan()
            }
            _ => omcl::mcl::FilterConfig::default(),
        };
        // The Table I blocks' own paths (plan.*, two_d.*, sixdof.*) are not
        // the filter's.
        let sets = super::bench_args::block_overrides(&a.plan.set)?.rest;
        let with_args = |mut f: omcl::mcl::FilterConfig| {
            if let Some(r) = a.plan.rays {
                f.sampling.rays = r;
            }
            apply_overrides(f, &sets)
        };
        let config = with_args(base)?;
        println!("{}", serde_json::to_string_pretty(&config)?);
        if a.plan.experiments == [Experiment::Table1Sixdof] {
            let cloud = with_args(omcl::mcl::FilterConfig::six_dof_point_cloud())?;
            if cloud != config {
                eprintln!(
                    "(the point-cloud row, OMCL_Open_LSeg, has its own, with --rays and --set \
                     applied to it too: {} rays, exponent {})",
                    cloud.sampling.rays, cloud.sharpen
                );
            }
        }
        let t5_plan = Experiment::Planned(sweep::Experiment::Table5Floorplan);
        if a.plan.experiments.contains(&t5_plan) && a.plan.experiments != [t5_plan] {
            let plan = with_args(omcl::mcl::FilterConfig::floor_plan())?;
            eprintln!(
                "(table5-floorplan has its own, Table I's 2-D filter with --rays and --set \
                 applied to it too: {} rays, exponent {})",
                plan.sampling.rays, plan.sharpen
            );
        }
        if a.plan.experiments == [Experiment::Table1Floorplan] {
            let cloud = with_args(omcl::mcl::FilterConfig::floor_plan_point_cloud())?;
            if cloud.sampling.map_strata != config.sampling.map_strata {
                eprintln!(
                    "(the point-cloud row, OMCL_Open_LSeg, has its own, with --rays and --set \
                     applied to it too: its pixels stratified over {})",
                    if cloud.sampling.map_strata {
                        "the plan's own rows only"
                    } else {
                        "every row of the plan"
                    }
                );
            }
        }
        return Ok(());
    }
    refuse_options_of_other_experiments(&a)?;
    if let Some(dir) = &a.sixdof.export_frames {
        return super::bench_table1::export(&a, dir);
    }
    let table4 = a.plan.experiments.contains(&Experiment::Table4);
    let sweep_wanted = a.plan.experiments.iter().any(|e| e.to_library().is_some());
    let sevenscenes = super::bench_sevenscenes::run(&a)?;
    if (super::bench_table1::run(&a)? || sevenscenes) && !sweep_wanted && !table4 {
        println!("wrote {}", a.out.display());
        return Ok(());
    }
    if table4 && !sweep_wanted {
        let report = street_table4(&a, &features::builtin_table()?)?;
        println!("{report}");
        println!("wrote {}", a.out.display());
        return Ok(());
    }
    let bench = a.plan.bench_plan()?;
    let dir = a.out.join("sweep");
    let _held = claim_sweep_folder(&dir, a.force)?;
    if !a.resume {
        for d in [dir.join("results"), dir.join("cache")] {
            if d.exists() {
                std::fs::remove_dir_all(&d).with_context(|| format!("removing {}", d.display()))?;
            }
        }
    }
    let manifest_path = dir.join("manifest.jsonl");
    let entries = sweep::plan(&bench)?;
    sweep::write_manifest(&manifest_path, &bench, &entries)?;
    let manifest = Manifest::read(&manifest_path)?;
    let results = ResultDir::new(dir.join("results"));
    let cache = Cache::new(dir.join("cache"), true)?;
    let all: Vec<usize> = (0..manifest.len()).collect();
    let failures = run_with_progress(&manifest, &all, &results, &cache, a.jobs);
    // The bench's own folder: what it holds besides an earlier run's
    // recorded files is left as it is.
    let c = report::collect(&manifest, &results, Some(cache.dir()), &a.out, true)?;
    println!("{}", c.markdown);
    println!("wrote {}", a.out.display());
    if table4 {
        let report = street_table4(&a, &features::builtin_table()?)?;
        println!("{report}");
    }
    finish(&c, failures.len())
}

/// The file a bench leaves in its sweep folder: what holds it is the
/// bench's to replace.
const BENCH_MARK: &str = "made-by-omcl-bench";

/// Makes `dir` (`<out>/sweep`) this bench's: refuses a sweep folder that
/// another omcl bench is writing into (a lock held for the bench's life,
/// returned) and one no bench made (`omcl sweep plan`'s, whose results
/// and maps the bench would delete) unless `force`; then marks it.
fn claim_sweep_folder(dir: &Path, force: bool) -> anyhow::Result<std::fs::File> {
    let out = dir.parent().unwrap_or(Path::new("."));
    let foreign = dir.is_dir()
        && !dir.join(BENCH_MARK).exists()
        && std::fs::read_dir(dir)
            .with_context(|| format!("reading {}", dir.display()))?
            .next()
            .is_some();
    if foreign && !force {
        anyhow::bail!(
            "{}: holds a sweep that no omcl bench made (`omcl sweep plan`'s, or a bench's \
             from before 2026-11-28): omcl bench would replace its manifest and delete its \
             results and maps. Give another --out, or --force to replace it",
            dir.display()
        );
    }
    super::outputs::create_folder("--out", dir)?;
    let lock_path = dir.join("bench.lock");
    let lock = std::fs::File::create(&lock_path)
        .with_context(|| format!("creating {}", lock_path.display()))?;
    match lock.try_lock() {
        Ok(()) => {}
        Err(std::fs::TryLockError::WouldBlock) => anyhow::bail!(
            "{}: another omcl bench is writing into it (it holds {}); wait for it to end or \
             give another --out",
            out.display(),
            lock_path.display()
        ),
        Err(std::fs::TryLockError::Error(e)) => {
            return Err(e).with_context(|| format!("locking {}", lock_path.display()));
        }
    }
    let mark = dir.join(BENCH_MARK);
    std::fs::write(
        &mark,
        "This sweep folder is omcl bench's: the next `omcl bench -o` into its parent \
         replaces its manifest, results and maps (unless --resume).\n",
    )
    .with_context(|| format!("writing {}", mark.display()))?;
    Ok(lock)
}

/// Runs `indices` locally, printing one line per run.
pub fn run_with_progress(
    manifest: &Manifest,
    indices: &[usize],
    results: &ResultDir,
    cache: &Cache,
    jobs: usize,
) -> Vec<(usize, sweep::SweepError)> {
    let n = indices.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let pb = super::progress::bar(n as u64, "runs");
    // A run takes seconds to minutes: the bar ticks on its own, so a log
    // (a Slurm job's) gets its line every interval with the run under way.
    pb.enable_steady_tick(std::time::Duration::from_millis(500));
    let started = |i: usize| {
        if let Ok(e) = manifest.entry(i) {
            pb.set_message(format!("(now run {i}{})", describe_task(e)));
        }
    };
    let failures = sweep::run_local(
        manifest,
        indices,
        results,
        cache,
        jobs,
        &started,
        &|i, r| {
            let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            pb.set_position(k as u64);
            let what = match manifest.entry(i) {
                Ok(e) => describe(e, results),
                Err(_) => String::new(),
            };
            // (A hidden bar's println prints nothing; suspend prints always.)
            pb.suspend(|| match r {
                Ok(RunStatus::Ran) => eprintln!("[{k}/{n}] run {i}{what}"),
                Ok(RunStatus::Skipped) => eprintln!("[{k}/{n}] run {i}{what} (result there)"),
                Ok(RunStatus::Busy) => {
                    eprintln!("[{k}/{n}] run {i}{what} (another process is running it; left to it)")
                }
                Err(e) => eprintln!("[{k}/{n}] run {i} failed: {e}"),
            });
        },
    );
    pb.set_message("");
    super::progress::finish(&pb);
    failures
}

/// A run's uses, sequence and, for tracking, its APE.
fn describe(e: &sweep::RunEntry, results: &ResultDir) -> String {
    let mut s = describe_task(e);
    if let Ok(Some(r)) = results.read(&e.id) {
        if let sweep::Outcome::Track(t) = &r.outcome {
            let r = &t.result;
            s += &format!(
                ": APE rmse {:.3} m, max {:.3}, completed {}, {:.1} steps/s ({:.1} with the simulated encoder), K = {}",
                r.stats.rmse,
                r.stats.max,
                omcl::eval::CompletionRule::default().verdict(r.completed),
                r.fps(),
                r.fps_with_encoder(),
                r.map_rows
            );
        }
        s += &format!(" [{:.1} s]", r.cost.wall_seconds);
    }
    s
}

/// A run's uses and sequence.
fn describe_task(e: &sweep::RunEntry) -> String {
    let uses: Vec<String> = e
        .uses
        .iter()
        .map(|u| match u {
            sweep::Use::Table1 { variant } => format!("table1 {variant}"),
            sweep::Use::Table2 { variant } => format!("table2 {variant}"),
            sweep::Use::Table5 {
                prompt,
                floor_plan: false,
            } => format!("table5 prompt={prompt}"),
            sweep::Use::Table5 {
                prompt,
                floor_plan: true,
            } => format!("table5-floorplan prompt={prompt}"),
            sweep::Use::ParticlesRays { particles, rays } => {
                format!("particles-rays {particles}x{rays}")
            }
            sweep::Use::Sampling {
                particles,
                strategy,
            } => format!("sampling {strategy} {particles}"),
        })
        .collect();
    format!(" ({}) sequence {}", uses.join(", "), e.task.seed)
}

/// Reports failed runs (the tables were written without them).
pub fn finish(c: &report::Collected, failed_runs: usize) -> anyhow::Result<()> {
    for (i, why) in &c.failed {
        eprintln!("run {i}: {why}");
    }
    anyhow::ensure!(
        c.failed.is_empty() && failed_runs == 0,
        "{} of {} runs have no result; {} was written without them",
        c.failed.len().max(failed_runs),
        c.done + c.failed.len(),
        c.path.display()
    );
    Ok(())
}

fn default_trajectories() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/trajectories")
}

/// Runs Table IV and returns its Markdown; writes `table4.json`,
/// `table4.md` and `table4_<odometry>.png` (the first seed's path).
fn street_table4(a: &BenchArgs, table: &ClassEmbeddings) -> anyhow::Result<String> {
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
        particles: a.plan.particles.unwrap_or(omcl::mcl::STREET_PARTICLES),
        filter: {
            let mut f = Table4Params::filter_default();
            if let Some(r) = a.plan.rays {
                f.sampling.rays = r;
            }
            apply_overrides(f, &a.plan.set)?
        },
        preset: a.plan.preset.unwrap_or(Preset::Gt),
        encoder_stride: a.street.encoder_stride,
        out: a.out.clone(),
    };
    // After `--set` was checked: nothing is made for a refused filter.
    super::outputs::create_folder("--out", &params.out)?;
    let pb = super::progress::spinner("Table IV");
    let t = run_table4(
        &params,
        table,
        &|msg| pb.set_message(msg.to_string()),
        &|line| pb.suspend(|| eprintln!("{line}")),
    )?;
    super::progress::finish(&pb);
    Ok(t.markdown)
}
