//! `omcl sweep`: `omcl bench` split into plan, run and collect, for running
//! a sweep's runs anywhere (Slurm job arrays, Ray, Dask, a shell loop).

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::{Args, Subcommand};

use omcl::experiment::report;
use omcl::experiment::slurm::{self, SlurmOptions};
use omcl::experiment::sweep::{self, Cache, Manifest, ResultDir};

use super::bench::{finish, run_with_progress};
use super::bench_args::PlanArgs;

#[derive(Debug, Subcommand)]
pub enum SweepCommand {
    /// Expand experiments x variants x parameters x seeds into a manifest
    /// (JSON lines: a header, then one run a line).
    Plan(PlanCmd),
    /// Execute runs of a manifest (all, one, or a stride); a run whose
    /// result exists is skipped.
    Run(RunCmd),
    /// Which runs are done, failed or missing.
    Status(StatusCmd),
    /// Write the tables and figures of `omcl bench` from the results.
    Collect(CollectCmd),
    /// Write (and with --submit submit) sbatch job arrays for the runs
    /// still to do.
    Slurm(SlurmCmd),
}

#[derive(Debug, Args)]
pub struct PlanCmd {
    #[command(flatten)]
    pub plan: PlanArgs,
    /// The manifest to write. An existing file is left alone unless it
    /// already holds this very plan or --force is given (its results name
    /// runs by id, so replacing a manifest orphans them).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Replace an existing manifest that holds another plan.
    #[arg(long)]
    pub force: bool,
}

/// Where results and maps are (default: beside the manifest).
#[derive(Debug, Args)]
pub struct Dirs {
    /// Result folder [default: MANIFEST's folder/results].
    #[arg(long)]
    pub results: Option<PathBuf>,
    /// Map cache folder [default: MANIFEST's folder/cache].
    #[arg(long)]
    pub cache: Option<PathBuf>,
}

impl Dirs {
    fn results(&self, manifest: &Path) -> PathBuf {
        self.results
            .clone()
            .unwrap_or_else(|| beside(manifest, "results"))
    }
    fn cache(&self, manifest: &Path) -> PathBuf {
        self.cache
            .clone()
            .unwrap_or_else(|| beside(manifest, "cache"))
    }
}

fn beside(manifest: &Path, name: &str) -> PathBuf {
    manifest
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .join(name)
}

#[derive(Debug, Args)]
pub struct RunCmd {
    /// The manifest `omcl sweep plan` wrote (`.jsonl`: one run a line).
    pub manifest: PathBuf,
    /// Run this entry (0-based: the INDEX-th run line after the header,
    /// blank lines not counted; line INDEX + 2 as `sweep plan` writes it);
    /// with --stride, the entries INDEX, INDEX + STRIDE, ... [default: all].
    #[arg(long)]
    pub index: Option<usize>,
    /// Step between the entries run (with --index).
    #[arg(long, requires = "index")]
    pub stride: Option<usize>,
    #[command(flatten)]
    pub dirs: Dirs,
    /// Runs computed at once (1 to 1024).
    #[arg(long, default_value_t = 1, value_parser = super::count_in::<1, 1024>)]
    pub jobs: usize,
    /// Fail a run whose map is not in the cache instead of building it.
    #[arg(long)]
    pub no_build_maps: bool,
}

#[derive(Debug, Args)]
pub struct StatusCmd {
    /// The manifest `omcl sweep plan` wrote (`.jsonl`: one run a line).
    pub manifest: PathBuf,
    /// Result folder [default: MANIFEST's folder/results].
    #[arg(long)]
    pub results: Option<PathBuf>,
    /// Exit non-zero (4) while runs are missing too (not run yet, or still
    /// running), not only when runs failed (1): for a script or a Slurm
    /// job that must not go on to `omcl sweep collect` before the sweep is
    /// whole.
    #[arg(long)]
    pub complete: bool,
}

#[derive(Debug, Args)]
pub struct CollectCmd {
    /// The manifest `omcl sweep plan` wrote; its runs' results are collected.
    pub manifest: PathBuf,
    #[command(flatten)]
    pub dirs: Dirs,
    /// Output folder of the tables and figures. What an earlier collect
    /// wrote there (listed in its collected.txt) is replaced; other tables
    /// or figures there are refused (see --force).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Write beside tables and figures in --out that no collect recorded.
    #[arg(long)]
    pub force: bool,
}

#[derive(Debug, Args)]
pub struct SlurmCmd {
    /// The manifest `omcl sweep plan` wrote; its runs without a result are
    /// submitted.
    pub manifest: PathBuf,
    #[command(flatten)]
    pub dirs: Dirs,
    /// Per-task logs [default: MANIFEST's folder/logs].
    #[arg(long)]
    pub logs: Option<PathBuf>,
    /// The batch script to write [default: MANIFEST's folder/sweep.sbatch];
    /// `submit.sh` beside it holds the sbatch commands.
    #[arg(long)]
    pub script: Option<PathBuf>,
    /// Submit the arrays (else only write the scripts). Refused while
    /// jobs of this sweep's script are still in the queue (their runs
    /// would be submitted twice), unless --force.
    #[arg(long)]
    pub submit: bool,
    /// Submit even while jobs of this sweep's script are queued.
    #[arg(long, requires = "submit")]
    pub force: bool,
    /// The omcl binary the tasks run [default: this one].
    #[arg(long)]
    pub omcl: Option<PathBuf>,
    /// CPUs per task (`--cpus-per-task`; each run's thread pool takes
    /// them).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..))]
    pub cpus_per_task: u32,
    /// Memory per task, MB.
    #[arg(long, default_value_t = 2000)]
    pub mem_mb: u64,
    /// Time limit per task.
    #[arg(long, default_value = "01:00:00")]
    pub time: String,
    /// Slurm partition [default: the cluster's default partition].
    #[arg(long)]
    pub partition: Option<String>,
    /// At most this many tasks of each array at once (`%P`).
    #[arg(long)]
    pub concurrency: Option<u32>,
    /// Array ids stay below this [default: the cluster's MaxArraySize with
    /// --submit, else 1001, Slurm's default].
    #[arg(long)]
    pub max_array_size: Option<usize>,
    /// Requeues of a failed task.
    #[arg(long, default_value_t = 2)]
    pub retries: u32,
    /// Name of the array jobs in the queue (`--job-name`).
    #[arg(long, default_value = "omcl-sweep")]
    pub job_name: String,
}

pub fn run(cmd: SweepCommand) -> anyhow::Result<()> {
    match cmd {
        SweepCommand::Plan(c) => plan(c),
        SweepCommand::Run(c) => run_entries(c),
        SweepCommand::Status(c) => status(c),
        SweepCommand::Collect(c) => collect(c),
        SweepCommand::Slurm(c) => slurm_cmd(c),
    }
}

fn plan(c: PlanCmd) -> anyhow::Result<()> {
    let in_process: Vec<String> = c
        .plan
        .experiments
        .iter()
        .filter(|e| e.to_library().is_none())
        .filter_map(|e| clap::ValueEnum::to_possible_value(e).map(|v| v.get_name().to_string()))
        .collect();
    anyhow::ensure!(
        in_process.is_empty(),
        "{} {} in one process only, with `omcl bench {}`; a sweep plans table1, table2, \
         table5, table5-floorplan, particles-rays, sampling and all",
        in_process.join(", "),
        if in_process.len() == 1 { "runs" } else { "run" },
        in_process[0]
    );
    c.plan.check_sweep_variants()?;
    anyhow::ensure!(
        !c.out.is_dir(),
        "--out {}: is a folder; give the manifest's file name (e.g. {})",
        c.out.display(),
        c.out.join("manifest.jsonl").display()
    );
    let bench = c.plan.bench_plan()?;
    if let Some(dir) = c.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        super::outputs::create_folder("--out's folder", dir)?;
    }
    let entries = sweep::plan(&bench)?;
    if c.out.exists() && !c.force {
        let same = Manifest::read(&c.out).is_ok_and(|m| {
            m.header.bench == bench
                && m.len() == entries.len()
                && (0..m.len()).all(|i| m.entry(i).is_ok_and(|e| e.id == entries[i].id))
        });
        anyhow::ensure!(
            same,
            "{}: exists and holds {}; pass --force to replace it, or choose another --out",
            c.out.display(),
            match Manifest::read(&c.out) {
                Ok(m) => format!("another plan ({} runs)", m.len()),
                Err(_) => "something other than a manifest".to_string(),
            }
        );
        println!(
            "{} already holds this plan ({} runs); left as it is",
            c.out.display(),
            entries.len()
        );
        return Ok(());
    }
    sweep::write_manifest(&c.out, &bench, &entries)?;
    let runs = if entries.len() == 1 { "run" } else { "runs" };
    println!("planned {} {runs} into {}", entries.len(), c.out.display());
    Ok(())
}

fn run_entries(c: RunCmd) -> anyhow::Result<()> {
    let manifest = Manifest::read(&c.manifest)?;
    let indices: Vec<usize> = match (c.index, c.stride) {
        (Some(i), None) => vec![i],
        (Some(i), Some(s)) => {
            anyhow::ensure!(s > 0, "--stride must be at least 1");
            // A fixed pool of workers (`--index $i --stride N`) may have
            // more workers than runs: the extra ones have nothing to do.
            if i >= manifest.len() {
                eprintln!(
                    "note: --index {i} --stride {s}: none of the {} runs of {} falls to this \
                     worker",
                    manifest.len(),
                    c.manifest.display()
                );
                return Ok(());
            }
            (i..manifest.len()).step_by(s).collect()
        }
        _ => (0..manifest.len()).collect(),
    };
    let results = ResultDir::new(c.dirs.results(&c.manifest));
    let cache = Cache::new(c.dirs.cache(&c.manifest), !c.no_build_maps)?;
    let failures = run_with_progress(&manifest, &indices, &results, &cache, c.jobs);
    // Runs whose manifest line is unusable fail the same way every time:
    // said by the exit code, so that a Slurm task does not requeue them.
    let hopeless = |e: &sweep::SweepError| {
        matches!(
            e,
            sweep::SweepError::Manifest { .. } | sweep::SweepError::Index { .. }
        )
    };
    if !failures.is_empty() && failures.iter().all(|(_, e)| hopeless(e)) {
        let (i, e) = &failures[0];
        return Err(super::Exit::cannot_succeed(format!(
            "{} of {} runs cannot run (their manifest lines; a retry cannot mend them); the \
             first, run {i}: {e}",
            failures.len(),
            indices.len()
        ))
        .into());
    }
    if let Some((i, e)) = failures.first() {
        anyhow::bail!(
            "{} of {} runs failed; the first, run {i}: {e}",
            failures.len(),
            indices.len()
        );
    }
    Ok(())
}

fn status(c: StatusCmd) -> anyhow::Result<()> {
    let manifest = Manifest::read(&c.manifest)?;
    let results = ResultDir::new(c.results.unwrap_or_else(|| beside(&c.manifest, "results")));
    let s = sweep::status(&manifest, &results);
    warn_no_results(&results);
    println!(
        "{} runs: {} done, {} failed, {} missing",
        manifest.len(),
        s.done.len(),
        s.failed.len(),
        s.missing.len()
    );
    for (i, why) in &s.failed {
        println!("failed run {i}: {why}");
    }
    if !s.missing.is_empty() {
        println!("missing runs: {}", slurm::ranges(&s.missing));
    }
    // A script waiting on the sweep learns of failures from the exit code.
    // A manifest line omcl cannot run fails the same way every time.
    let bad_lines = manifest
        .lines
        .iter()
        .filter(|l| matches!(l, sweep::ManifestLine::Bad(_)))
        .count();
    let advice = match (bad_lines, s.failed.len() - bad_lines) {
        (0, _) => "`omcl sweep run` again reruns them".to_string(),
        (b, 0) => format!(
            "{} manifest line{} omcl cannot run: plan the sweep again (`omcl sweep plan`)",
            if b == 1 { "it is a" } else { "they are" },
            if b == 1 { "" } else { "s" }
        ),
        (b, _) => format!(
            "{b} of them cannot run as their manifest lines stand (plan the sweep again); \
             `omcl sweep run` again reruns the rest"
        ),
    };
    anyhow::ensure!(
        s.failed.is_empty(),
        "{} of {} runs failed (listed above); {advice}",
        s.failed.len(),
        manifest.len()
    );
    if c.complete && !s.missing.is_empty() {
        return Err(super::Exit::not_yet(format!(
            "the sweep is not complete: {} of {} runs missing (not run yet, or still running; \
             `omcl sweep run` or `omcl sweep slurm` runs them)",
            s.missing.len(),
            manifest.len()
        ))
        .into());
    }
    Ok(())
}

/// A results folder that is not there (a typo in --results, or no run
/// yet): every run counts as missing, which status and slurm say.
fn warn_no_results(results: &ResultDir) {
    if !results.dir.exists() {
        eprintln!(
            "note: {} does not exist yet: every run counts as missing (check --results if runs \
             were done)",
            results.dir.display()
        );
    }
}

fn collect(c: CollectCmd) -> anyhow::Result<()> {
    let manifest = Manifest::read(&c.manifest)?;
    let results = ResultDir::new(c.dirs.results(&c.manifest));
    warn_no_results(&results);
    let cache = c.dirs.cache(&c.manifest);
    let r = report::collect(&manifest, &results, Some(&cache), &c.out, c.force)?;
    println!("{}", r.markdown);
    if manifest.header.bench.wants(sweep::Experiment::Table1) && !cache.is_dir() {
        eprintln!(
            "note: {} is not there: Figure 4 is drawn without the maps' floor plans (they \
             come from the cached maps; --cache names the folder)",
            cache.display()
        );
    }
    println!("wrote {}", c.out.display());
    finish(&r, 0)
}

fn absolute(p: &Path) -> anyhow::Result<PathBuf> {
    std::path::absolute(p)
        .with_context(|| format!("{}: cannot make the path absolute", p.display()))
}

fn slurm_cmd(c: SlurmCmd) -> anyhow::Result<()> {
    let manifest = Manifest::read(&c.manifest)?;
    let results = c.dirs.results(&c.manifest);
    let logs = c
        .logs
        .clone()
        .unwrap_or_else(|| beside(&c.manifest, "logs"));
    let script = absolute(
        &c.script
            .clone()
            .unwrap_or_else(|| beside(&c.manifest, "sweep.sbatch")),
    )?;
    let submit_sh = beside(&script, "submit.sh");
    super::outputs::refuse_overlaps(
        &[
            ("--script", &script),
            ("submit.sh beside --script", &submit_sh),
        ],
        &[("the manifest", &c.manifest)],
    )?;
    let omcl = match &c.omcl {
        Some(p) => p.clone(),
        None => std::env::current_exe().context("locating this omcl binary")?,
    };
    let max_array_size = match c.max_array_size {
        Some(n) => n,
        None if c.submit => slurm::max_array_size()?,
        None => 1001,
    };
    let o = SlurmOptions {
        omcl: absolute(&omcl)?,
        manifest: absolute(&c.manifest)?,
        results: absolute(&results)?,
        cache: absolute(&c.dirs.cache(&c.manifest))?,
        logs: absolute(&logs)?,
        job_name: c.job_name,
        cpus_per_task: c.cpus_per_task,
        mem_mb: c.mem_mb,
        time: c.time,
        partition: c.partition,
        concurrency: c.concurrency,
        max_array_size,
        retries: c.retries,
    };
    o.check()?;
    warn_no_results(&ResultDir::new(&results));
    for (option, d) in [("--results", &results), ("--logs", &logs)] {
        super::outputs::create_folder(option, d)?;
    }
    let s = sweep::status(&manifest, &ResultDir::new(&results));
    let to_do = s.to_do();
    let chunks = slurm::chunks(&to_do, max_array_size);
    if c.submit && !chunks.is_empty() && !c.force {
        // Runs of jobs still queued count as to do: submitting them again
        // would run them twice. Refused before the scripts are rewritten.
        let queued = slurm::queued_jobs(&script)?;
        anyhow::ensure!(
            queued.is_empty(),
            "job(s) {} of this sweep ({}) are still queued or running: submitting now \
             would run their runs twice; wait for them (squeue), cancel them (scancel {}), \
             or pass --force",
            queued.join(" "),
            script.display(),
            queued.join(" ")
        );
    }
    omcl::io::atomic::write(&script, slurm::script(&o).as_bytes())
        .with_context(|| format!("writing {}", script.display()))?;
    omcl::io::atomic::write(
        &submit_sh,
        slurm::submit_script(&chunks, &o, &script).as_bytes(),
    )
    .with_context(|| format!("writing {}", submit_sh.display()))?;
    println!(
        "{} runs: {} done, {} to do in {} array(s); wrote {} and {}",
        manifest.len(),
        s.done.len(),
        to_do.len(),
        chunks.len(),
        script.display(),
        submit_sh.display()
    );
    if c.submit && !chunks.is_empty() {
        let jobs = slurm::submit(&chunks, &o, &script)?;
        println!("submitted job(s) {}", jobs.join(" "));
    }
    Ok(())
}
