//! Experiment sweeps as plans of independent runs: *plan* expands the
//! experiments, variants, parameter grids and seeds of `omcl bench` into a
//! manifest (JSON lines), *run* executes entries of it (idempotently, one
//! result file per run), and *collect* ([`super::report`]) turns the result
//! files back into the tables and figures. The local path (`omcl bench`)
//! and the cluster path (`omcl sweep slurm`, or any engine that can call
//! `omcl sweep run MANIFEST --index I`) share all three steps.
//!
//! The manifest: line 1 is the sweep's header ([`SweepHeader`]: what was
//! asked for, which omcl planned it), every further line one run
//! ([`RunEntry`]); run `i` (0-based, as `--index` counts) is the `i`-th
//! run line, blank lines not counted (line `i + 2` as `plan` writes it).
//! A run's id hashes the omcl version and everything the run computes
//! ([`Task`]); what it is used for ([`Use`]) is not part of it, so a run
//! two tables share is planned (and computed) once.
//!
//! The result folder holds `<id[..2]>/<id>.json` for a finished run
//! ([`RunRecord`]) and `<id[..2]>/<id>.failed` (the error) for a failed
//! one; both are written atomically. Maps are built once per (world,
//! mapping parameters) into a cache folder, under a lock file
//! ([`Cache`]); sequences are generated in memory from their seed.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use super::ExperimentError;
use super::features::builtin_table;
use super::mapping::BenchMap;
use super::run::GlobalSpec;
use super::sequence::SimSequence;
use super::task::io_err;
pub use super::task::{
    BenchPlan, Cost, Experiment, OMCL_VERSION, Outcome, Planner, RunEntry, RunRecord, SweepError,
    SweepHeader, Task, TrackOutcome, Use, Work, map_path, run_id,
};
use super::{table1, table2, table5};
use crate::sim::embeddings::ClassEmbeddings;
use crate::sim::indoor::WorldKind;

/// Expands a bench plan into its runs: Table I and II per variant and
/// seed, Table V per prompt and seed, the ablations per cell and seed.
/// Runs that compute the same thing are merged (their uses joined); the
/// order is the tables' order.
pub fn plan(bench: &BenchPlan) -> Result<Vec<RunEntry>, SweepError> {
    if bench.sequences == 0 {
        return Err(SweepError::Plan("--sequences must be at least 1".into()));
    }
    let variants = bench.table_variants()?;
    if variants.is_empty() {
        return Err(SweepError::Plan("no variant selected".into()));
    }
    let planner = Planner {
        bench,
        map_params: bench.map_params(),
    };
    let ablation = bench.ablation()?;
    let mut out: Vec<(Task, Use)> = Vec::new();
    if bench.wants(Experiment::Table1) {
        super::table1::plan(&planner, &variants, &mut out);
    }
    if bench.wants(Experiment::Table2) {
        super::table2::plan(&planner, &variants, &mut out);
    }
    if bench.wants(Experiment::Table5) {
        super::table5::plan(&planner, &ablation, false, &mut out);
    }
    if bench.wants(Experiment::Table5Floorplan) {
        super::table5::plan(&planner, &ablation, true, &mut out);
    }
    if bench.wants(Experiment::ParticlesRays) {
        super::particles_rays::plan(&planner, &ablation, &mut out);
    }
    if bench.wants(Experiment::Sampling) {
        super::sampling::plan(&planner, &ablation, &mut out);
    }
    let mut entries: Vec<RunEntry> = Vec::new();
    let mut by_id: HashMap<String, usize> = HashMap::new();
    for (task, u) in out {
        let id = run_id(OMCL_VERSION, &task);
        match by_id.get(&id) {
            Some(&i) => entries[i].uses.push(u),
            None => {
                by_id.insert(id.clone(), entries.len());
                entries.push(RunEntry {
                    id,
                    omcl: OMCL_VERSION.into(),
                    task,
                    uses: vec![u],
                });
            }
        }
    }
    Ok(entries)
}

/// Writes a manifest atomically: the header, then one line per run.
pub fn write_manifest(
    path: &Path,
    bench: &BenchPlan,
    entries: &[RunEntry],
) -> Result<(), SweepError> {
    use std::io::Write;
    let header = SweepHeader {
        omcl: OMCL_VERSION.into(),
        bench: bench.clone(),
    };
    crate::io::atomic::write_with(path, |w| {
        serde_json::to_writer(&mut *w, &header)?;
        w.write_all(b"\n")?;
        for e in entries {
            serde_json::to_writer(&mut *w, e)?;
            w.write_all(b"\n")?;
        }
        Ok(())
    })
    .map_err(io_err(path))
}

/// A line of a manifest that is not a run this omcl can execute.
#[derive(Debug, Clone, PartialEq)]
pub struct BadLine {
    /// 1-based line number.
    pub line: usize,
    /// The run's id, where the line names one.
    pub id: Option<String>,
    pub reason: String,
}

/// A manifest's line after line 1.
#[derive(Debug, Clone, PartialEq)]
pub enum ManifestLine {
    Run(Box<RunEntry>),
    Bad(BadLine),
}

/// A parsed manifest. Bad run lines (another omcl version, unreadable
/// JSON, an id that does not match its task) are kept as [`ManifestLine::Bad`]:
/// running them fails, collecting reports them as failed.
#[derive(Debug, Clone)]
pub struct Manifest {
    pub path: PathBuf,
    pub header: SweepHeader,
    pub lines: Vec<ManifestLine>,
}

impl Manifest {
    /// Reads a manifest; only an unreadable file or header is an error.
    pub fn read(path: &Path) -> Result<Manifest, SweepError> {
        let bad = |line: usize, reason: String| SweepError::Manifest {
            path: path.to_path_buf(),
            line,
            reason,
        };
        if path.is_dir() {
            let inside = path.join("manifest.jsonl");
            let hint = if inside.is_file() {
                format!("; give the manifest in it, {}", inside.display())
            } else {
                String::new()
            };
            return Err(SweepError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::other(format!("a folder, not a sweep manifest{hint}")),
            });
        }
        let f = File::open(path).map_err(io_err(path))?;
        let mut lines = BufReader::new(f).lines();
        let not_text = |e: std::io::Error| match e.kind() {
            std::io::ErrorKind::InvalidData => SweepError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::other(
                    "not a sweep manifest (not text; `omcl sweep plan` writes one)",
                ),
            },
            _ => io_err(path)(e),
        };
        let first = lines
            .next()
            .ok_or_else(|| bad(1, "empty file: expected the sweep header".into()))?
            .map_err(not_text)?;
        let header: SweepHeader =
            serde_json::from_str(&first).map_err(|e| bad(1, format!("not a sweep header: {e}")))?;
        if header.omcl != OMCL_VERSION {
            return Err(bad(
                1,
                format!(
                    "the sweep was planned by omcl {}, this is omcl {OMCL_VERSION}: plan it again",
                    header.omcl
                ),
            ));
        }
        let (mut out, mut at) = (Vec::new(), Vec::new());
        for (i, l) in lines.enumerate() {
            let l = l.map_err(not_text)?;
            if l.trim().is_empty() {
                continue;
            }
            out.push(parse_line(&l, i + 2));
            at.push(i + 2);
        }
        check_against_header(&header, &mut out, &at).map_err(|(line, reason)| bad(line, reason))?;
        Ok(Manifest {
            path: path.to_path_buf(),
            header,
            lines: out,
        })
    }

    /// Number of run lines.
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// Whether the manifest has no runs.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// Run `index` (0-based), or an error naming the line.
    pub fn entry(&self, index: usize) -> Result<&RunEntry, SweepError> {
        match self.lines.get(index) {
            None => Err(SweepError::Index {
                path: self.path.clone(),
                index,
                runs: self.lines.len(),
            }),
            Some(ManifestLine::Run(e)) => Ok(e),
            Some(ManifestLine::Bad(b)) => Err(SweepError::Manifest {
                path: self.path.clone(),
                line: b.line,
                reason: b.reason.clone(),
            }),
        }
    }
}

/// The run lines against the runs the header plans (the tables are
/// collected under the header's title, so the two must agree): a second
/// line of one run becomes a bad line; a run the header does not plan as
/// written, or a planned run with no line, is an error (`(line, reason)`):
/// the header or the lines were edited by hand. `at` is each line's
/// number in the file (blank lines are skipped).
fn check_against_header(
    header: &SweepHeader,
    lines: &mut [ManifestLine],
    at: &[usize],
) -> Result<(), (usize, String)> {
    let again = "plan the sweep again (`omcl sweep plan`)";
    // Every sequence of an experiment that runs on it is at least one run
    // (the tables on `sequences`, the ablations on `ablation_sequences`):
    // a header that names more than the file has lines cannot be the
    // lines' (and is not planned: a count edited to a billion would plan a
    // billion runs).
    let b = &header.bench;
    let tables = [
        Experiment::Table1,
        Experiment::Table2,
        Experiment::Table5,
        Experiment::Table5Floorplan,
    ];
    let ablations = [Experiment::ParticlesRays, Experiment::Sampling];
    let counts = [
        (&tables[..], b.sequences, "sequences"),
        (&ablations[..], b.ablation_sequences, "ablation sequences"),
    ];
    for (experiments, count, what) in counts {
        if experiments.iter().any(|&e| b.wants(e)) && count > lines.len() as u64 {
            return Err((
                1,
                format!(
                    "the header names {count} {what}, more than the {} run lines below it: \
                     the header or the lines were edited; {again}",
                    lines.len()
                ),
            ));
        }
    }
    let planned = plan(&header.bench).map_err(|e| (1, format!("its header plans no runs: {e}")))?;
    let planned: HashMap<&str, &RunEntry> = planned.iter().map(|e| (e.id.as_str(), e)).collect();
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut bad_lines = 0;
    for (l, &at) in lines.iter_mut().zip(at) {
        let entry = match l {
            ManifestLine::Run(e) => e,
            // A bad line (an edited id, say) stands for one planned run.
            ManifestLine::Bad(_) => {
                bad_lines += 1;
                continue;
            }
        };
        if let Some(first) = seen.get(&entry.id) {
            *l = ManifestLine::Bad(BadLine {
                line: at,
                id: Some(entry.id.clone()),
                reason: format!(
                    "run {} again (its line is {first}): a line written twice",
                    entry.id
                ),
            });
            continue;
        }
        seen.insert(entry.id.clone(), at);
        if planned.get(entry.id.as_str()) != Some(&&**entry) {
            return Err((
                at,
                format!(
                    "run {} is not a run the header (line 1) plans as written: the header or \
                     the line was edited; {again}",
                    entry.id
                ),
            ));
        }
    }
    let missing = planned.len().saturating_sub(seen.len() + bad_lines);
    if missing > 0 {
        return Err((
            1,
            format!(
                "the header plans {} runs, {missing} of which have no line: the header or the \
                 lines were edited; {again}",
                planned.len()
            ),
        ));
    }
    Ok(())
}

fn parse_line(text: &str, line: usize) -> ManifestLine {
    let value: serde_json::Value = match serde_json::from_str(text) {
        Ok(v) => v,
        Err(e) => {
            return ManifestLine::Bad(BadLine {
                line,
                id: None,
                reason: format!("not JSON: {e}"),
            });
        }
    };
    let id = value.get("id").and_then(|v| v.as_str()).map(String::from);
    let bad = |reason: String| {
        ManifestLine::Bad(BadLine {
            line,
            id: id.clone(),
            reason,
        })
    };
    let name = id.as_deref().unwrap_or("?");
    match value.get("omcl").and_then(|v| v.as_str()) {
        Some(v) if v == OMCL_VERSION => {}
        Some(v) => {
            return bad(format!(
                "run {name} was planned by omcl {v}, this is omcl {OMCL_VERSION}: plan it again"
            ));
        }
        None => return bad(format!("run {name}: no field `omcl`")),
    }
    let entry: RunEntry = match serde_json::from_value(value) {
        Ok(e) => e,
        Err(e) => return bad(format!("run {name}: not a run: {e}")),
    };
    if run_id(&entry.omcl, &entry.task) != entry.id {
        return bad(format!(
            "run {name}: the id does not match the task (the line was edited)"
        ));
    }
    ManifestLine::Run(Box::new(entry))
}

/// Where results go: `<dir>/<id[..2]>/<id>.json` and `.failed`.
#[derive(Debug, Clone)]
pub struct ResultDir {
    pub dir: PathBuf,
}

impl ResultDir {
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        ResultDir { dir: dir.into() }
    }

    /// The result file of run `id`.
    pub fn result_path(&self, id: &str) -> PathBuf {
        self.dir.join(shard(id)).join(format!("{id}.json"))
    }

    /// The failure note of run `id`.
    pub fn failed_path(&self, id: &str) -> PathBuf {
        self.dir.join(shard(id)).join(format!("{id}.failed"))
    }

    /// Reads run `id`'s result: `Ok(None)` if there is none, an error
    /// naming the file if it is unreadable, corrupt, from another omcl
    /// version or of another run.
    pub fn read(&self, id: &str) -> Result<Option<RunRecord>, SweepError> {
        let path = self.result_path(id);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(io_err(&path)(e)),
        };
        let bad = |reason: String| SweepError::BadResult {
            path: path.clone(),
            reason,
        };
        let r: RunRecord = serde_json::from_slice(&bytes)
            .map_err(|e| bad(format!("run {id}: corrupt result file: {e}")))?;
        if r.id != id {
            return Err(bad(format!("run {id}: the file holds run {}", r.id)));
        }
        if r.omcl != OMCL_VERSION {
            return Err(bad(format!(
                "run {id}: written by omcl {}, this is omcl {OMCL_VERSION}",
                r.omcl
            )));
        }
        Ok(Some(r))
    }

    /// The failure note of run `id`, if any.
    pub fn failure(&self, id: &str) -> Option<String> {
        std::fs::read_to_string(self.failed_path(id)).ok()
    }

    fn write(&self, r: &RunRecord) -> Result<(), SweepError> {
        let path = self.result_path(&r.id);
        let dir = self.dir.join(shard(&r.id));
        crate::io::atomic::create_folder(&dir).map_err(io_err(&dir))?;
        crate::io::atomic::write_with(&path, |w| {
            serde_json::to_writer(w, r).map_err(std::io::Error::other)
        })
        .map_err(io_err(&path))?;
        let failed = self.failed_path(&r.id);
        match std::fs::remove_file(&failed) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(io_err(&failed)(e)),
            _ => Ok(()),
        }
    }

    fn write_failure(&self, id: &str, message: &str) -> Result<(), SweepError> {
        let dir = self.dir.join(shard(id));
        crate::io::atomic::create_folder(&dir).map_err(io_err(&dir))?;
        let path = self.failed_path(id);
        crate::io::atomic::write(&path, message.as_bytes()).map_err(io_err(&path))
    }
}

fn shard(id: &str) -> &str {
    id.get(..2).unwrap_or("__")
}

/// Sequences and maps of runs: maps are built once per (world, frames,
/// source, mapping parameters) into `dir`, under a lock file, and loaded
/// from there by every run (so a run computes the same thing whether its
/// map was built by its own process or another). Sequences are generated
/// from their seed in memory (deterministic). Both are kept in memory for
/// the next run of the process.
pub struct Cache {
    dir: PathBuf,
    table: ClassEmbeddings,
    /// Build maps that are missing (else a missing map is an error).
    build: bool,
    sequences: Mutex<HashMap<(WorldKind, u64, usize), Arc<SimSequence>>>,
    maps: Mutex<HashMap<PathBuf, Arc<BenchMap>>>,
    built: std::sync::atomic::AtomicUsize,
}

/// Maps kept in memory by a [`Cache`] before it drops them all.
const MAPS_IN_MEMORY: usize = 64;

impl Cache {
    /// A cache in `dir` (created if missing); `build`: build missing maps.
    pub fn new(dir: impl Into<PathBuf>, build: bool) -> Result<Cache, SweepError> {
        let dir = dir.into();
        if dir.exists() && !dir.is_dir() {
            return Err(SweepError::Plan(format!(
                "{}: the map cache is a folder, and this is a file (--cache)",
                dir.display()
            )));
        }
        crate::io::atomic::create_folder(&dir).map_err(io_err(&dir))?;
        let table = builtin_table().map_err(|e| SweepError::Plan(e.to_string()))?;
        Ok(Cache {
            dir,
            table,
            build,
            sequences: Mutex::new(HashMap::new()),
            maps: Mutex::new(HashMap::new()),
            built: std::sync::atomic::AtomicUsize::new(0),
        })
    }

    /// The cache folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Maps this cache has built (not loaded).
    pub fn maps_built(&self) -> usize {
        self.built.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// The map file of `task`'s world and map.
    pub fn map_path(&self, task: &Task) -> PathBuf {
        map_path(&self.dir, task)
    }

    /// Sequence `seed` of `frames` frames in a world of `world`.
    pub fn sequence(
        &self,
        world: WorldKind,
        seed: u64,
        frames: usize,
    ) -> Result<Arc<SimSequence>, ExperimentError> {
        if let Some(s) = lock(&self.sequences).get(&(world, seed, frames)) {
            return Ok(s.clone());
        }
        let s = Arc::new(SimSequence::generate_in(world, seed, frames, &self.table)?);
        lock(&self.sequences).insert((world, seed, frames), s.clone());
        Ok(s)
    }

    /// The map of `task`, loaded from the cache folder (built into it
    /// first, under the lock, if missing and building is allowed).
    pub fn map(
        &self,
        id: &str,
        task: &Task,
        seq: &SimSequence,
    ) -> Result<Arc<BenchMap>, SweepError> {
        let path = self.map_path(task);
        if let Some(m) = lock(&self.maps).get(&path) {
            return Ok(m.clone());
        }
        let lock_path = path.with_extension("lock");
        let lock_file = File::create(&lock_path).map_err(io_err(&lock_path))?;
        // Released when the file is closed, also when the process dies.
        lock_file.lock().map_err(io_err(&lock_path))?;
        if !path.exists() {
            if !self.build {
                return Err(SweepError::MissingMap {
                    id: id.into(),
                    path,
                });
            }
            let m =
                BenchMap::build(seq, task.map, &task.map_params, &|_| {}).map_err(|source| {
                    SweepError::Run {
                        id: id.into(),
                        source,
                    }
                })?;
            crate::map::file::save(&m.map, &path).map_err(|e| SweepError::BadMap {
                id: id.into(),
                path: path.clone(),
                reason: e.to_string(),
            })?;
            self.built
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        drop(lock_file);
        let map = crate::map::file::load(&path).map_err(|e| {
            // The error names the file; the message names it once.
            let full = e.to_string();
            let prefix = format!("{}: ", path.display());
            let why = full.strip_prefix(&prefix).unwrap_or(&full);
            SweepError::BadMap {
                id: id.into(),
                path: path.clone(),
                reason: format!(
                    "{why} (a cached map: delete it, and the next run that needs it builds it \
                     again)"
                ),
            }
        })?;
        let m = Arc::new(
            BenchMap::from_map(task.map, map).map_err(|source| SweepError::Run {
                id: id.into(),
                source,
            })?,
        );
        let mut maps = lock(&self.maps);
        if maps.len() >= MAPS_IN_MEMORY {
            maps.clear();
        }
        maps.insert(path, m.clone());
        Ok(m)
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // A panic in another thread leaves the cache's data valid.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// What [`run_entry`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunStatus {
    /// A valid result was already there.
    Skipped,
    /// The run was computed and its result written.
    Ran,
    /// Another process is computing it (it holds the run's lock): left to
    /// it, so that two workers on one manifest never compute a run twice
    /// nor measure its speed beside each other.
    Busy,
}

/// Executes one run unless its result exists: computes it, writes its
/// result atomically and removes an earlier failure note. A failed run
/// leaves a failure note (the error) and no result.
pub fn run_entry(
    entry: &RunEntry,
    results: &ResultDir,
    cache: &Cache,
) -> Result<RunStatus, SweepError> {
    if let Ok(Some(_)) = results.read(&entry.id) {
        return Ok(RunStatus::Skipped);
    }
    // One process a run: a lock file beside its result (`flock`, released
    // when the process ends, however it ends).
    let lock_path = results.result_path(&entry.id).with_extension("lock");
    if let Some(d) = lock_path.parent() {
        std::fs::create_dir_all(d).map_err(io_err(d))?;
    }
    let lock = File::create(&lock_path).map_err(io_err(&lock_path))?;
    match lock.try_lock() {
        Ok(()) => {}
        Err(std::fs::TryLockError::WouldBlock) => return Ok(RunStatus::Busy),
        Err(std::fs::TryLockError::Error(e)) => return Err(io_err(&lock_path)(e)),
    }
    // Finished by another process while this one waited for its turn.
    if let Ok(Some(_)) = results.read(&entry.id) {
        return Ok(RunStatus::Skipped);
    }
    match compute(entry, cache) {
        Ok(record) => {
            results.write(&record)?;
            Ok(RunStatus::Ran)
        }
        Err(e) => {
            // The run's error is the one to report; failing to note it (or
            // to remove a corrupt result it was to replace) is secondary.
            let _ = std::fs::remove_file(results.result_path(&entry.id));
            let _ = results.write_failure(&entry.id, &e.to_string());
            Err(e)
        }
    }
}

fn compute(entry: &RunEntry, cache: &Cache) -> Result<RunRecord, SweepError> {
    let id = entry.id.as_str();
    let t = &entry.task;
    let run_err = |source| SweepError::Run {
        id: id.into(),
        source,
    };
    let start = Instant::now();
    let cpu0 = process_cpu_seconds();
    let seq = cache.sequence(t.world, t.seed, t.frames).map_err(run_err)?;
    let map = cache.map(id, t, &seq)?;
    let outcome = match &t.work {
        Work::Track { filter, particles } => {
            let r = table1::track(&seq, &map, t.preset, *filter, *particles).map_err(run_err)?;
            TrackOutcome {
                truth_xy: table1::xy(&seq.poses()[..r.estimates.len()]),
                estimate_xy: table1::xy(&r.estimates),
                result: r,
            }
            .into()
        }
        Work::Consistency { frame_step } => Outcome::Consistency(
            table2::consistency(&seq, &map, t.preset, *frame_step).map_err(run_err)?,
        ),
        Work::Global {
            filter,
            particles,
            starts,
            max_steps,
            prompt,
            floor_plan,
            plan,
        } => {
            let spec = GlobalSpec {
                preset: t.preset,
                filter: *filter,
                particles: *particles,
                starts: *starts,
                max_steps: *max_steps,
                prompt: *prompt,
                floor_plan: floor_plan.then(|| plan.unwrap_or_default()),
            };
            Outcome::Global(table5::global_runs(&seq, &map, &spec).map_err(run_err)?)
        }
    };
    let cpu_seconds = match (cpu0, process_cpu_seconds()) {
        (Some(a), Some(b)) => Some(b - a),
        _ => None,
    };
    Ok(RunRecord {
        id: id.into(),
        omcl: OMCL_VERSION.into(),
        task: t.clone(),
        outcome,
        cost: Cost {
            wall_seconds: start.elapsed().as_secs_f64(),
            cpu_seconds,
            peak_rss_mb: peak_rss_mb(),
        },
    })
}

/// CPU time (user + system) of this process, seconds (Linux
/// `/proc/self/stat`, clock ticks of 1/100 s).
fn process_cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name, which is in parentheses.
    let rest = s.get(s.rfind(')')? + 2..)?;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// Peak resident memory of this process (`VmHWM`), MB.
fn peak_rss_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Runs entries `indices` of `manifest` on a pool of `jobs` threads (each
/// run also uses the rayon pool inside), calling `report` after each run.
/// Returns the failures; the other runs still ran.
pub fn run_local(
    manifest: &Manifest,
    indices: &[usize],
    results: &ResultDir,
    cache: &Cache,
    jobs: usize,
    started: &(dyn Fn(usize) + Sync),
    report: &(dyn Fn(usize, &Result<RunStatus, SweepError>) + Sync),
) -> Vec<(usize, SweepError)> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..jobs.clamp(1, indices.len().max(1)) {
            scope.spawn(|| {
                while let Some(&i) = indices.get(next.fetch_add(1, Ordering::Relaxed)) {
                    started(i);
                    let r = manifest.entry(i).and_then(|e| run_entry(e, results, cache));
                    report(i, &r);
                    if let Err(e) = r {
                        lock(&failures).push((i, e));
                    }
                }
            });
        }
    });
    let mut f = failures.into_inner().unwrap_or_else(|e| e.into_inner());
    f.sort_by_key(|x| x.0);
    f
}

/// Which runs of a manifest are done, failed or missing.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SweepStatus {
    /// Indices (0-based) of runs with a valid result.
    pub done: Vec<usize>,
    /// Runs that failed, with why: a failure note, a corrupt result file,
    /// or a manifest line this omcl cannot run.
    pub failed: Vec<(usize, String)>,
    /// Runs with neither result nor failure note.
    pub missing: Vec<usize>,
}

impl SweepStatus {
    /// Indices of the runs still to do (failed or missing), sorted.
    pub fn to_do(&self) -> Vec<usize> {
        let mut v: Vec<usize> = self
            .failed
            .iter()
            .map(|f| f.0)
            .chain(self.missing.iter().copied())
            .collect();
        v.sort_unstable();
        v
    }
}

/// The status of every run of `manifest` in `results`.
pub fn status(manifest: &Manifest, results: &ResultDir) -> SweepStatus {
    let mut s = SweepStatus::default();
    for (i, line) in manifest.lines.iter().enumerate() {
        match line {
            ManifestLine::Bad(b) => s.failed.push((
                i,
                format!("{} line {}: {}", manifest.path.display(), b.line, b.reason),
            )),
            ManifestLine::Run(e) => match results.read(&e.id) {
                Ok(Some(_)) => s.done.push(i),
                Err(err) => s.failed.push((i, err.to_string())),
                Ok(None) => match results.failure(&e.id) {
                    Some(why) => s.failed.push((
                        i,
                        format!("{}: {}", results.failed_path(&e.id).display(), why.trim()),
                    )),
                    None => s.missing.push(i),
                },
            },
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::task::fnv1a;
    use crate::mcl::FilterConfig;

    fn small_plan() -> BenchPlan {
        BenchPlan {
            experiments: vec![Experiment::Table1, Experiment::Sampling],
            sequences: 2,
            first_seed: 1000,
            frames: 6,
            map_frames: 20,
            particles: 1024,
            rays: 2048,
            variants: vec!["OMCL_LSeg".into(), "OMCL_GT_exact".into()],
            preset: None,
            ablation_variant: "OMCL_LSeg".into(),
            ablation_sequences: 1,
            starts: 3,
            max_steps: 60,
            filter: FilterConfig::default(),
            floor_plan_filter: None,
            floor_plan_scene: None,
            world: Default::default(),
        }
    }

    /// Two caches on one folder (two processes, as far as the lock is
    /// concerned) asking for the same map at once: one builds it, the
    /// other waits and loads it; both get the same map, and a third cache
    /// finds it. A corrupt map file is an error naming the run and file.
    #[test]
    fn a_map_is_built_once_under_the_lock() {
        let dir = tempfile::tempdir().unwrap();
        let mut b = small_plan();
        b.variants = vec!["OMCL_GT_exact".into()];
        b.experiments = vec![Experiment::Table1];
        b.sequences = 1;
        let e = plan(&b).unwrap().remove(0);
        let caches: Vec<Cache> = (0..2)
            .map(|_| Cache::new(dir.path(), true).unwrap())
            .collect();
        let maps: Vec<Arc<BenchMap>> = std::thread::scope(|s| {
            let h: Vec<_> = caches
                .iter()
                .map(|c| {
                    s.spawn(|| {
                        let seq = c
                            .sequence(e.task.world, e.task.seed, e.task.frames)
                            .unwrap();
                        c.map(&e.id, &e.task, &seq).unwrap()
                    })
                })
                .collect();
            h.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert_eq!(caches.iter().map(Cache::maps_built).sum::<usize>(), 1);
        assert_eq!(maps[0].map.codes(), maps[1].map.codes());
        assert_eq!(maps[0].map.rows(), maps[1].map.rows());
        let third = Cache::new(dir.path(), false).unwrap();
        let seq = third
            .sequence(e.task.world, e.task.seed, e.task.frames)
            .unwrap();
        third.map(&e.id, &e.task, &seq).unwrap();
        assert_eq!(third.maps_built(), 0);

        std::fs::write(third.map_path(&e.task), b"not a map").unwrap();
        let fourth = Cache::new(dir.path(), true).unwrap();
        let Err(err) = fourth.map(&e.id, &e.task, &seq) else {
            panic!("a corrupt map file was loaded");
        };
        let err = err.to_string();
        assert!(err.contains(&e.id) && err.contains(".omcl"), "{err}");
    }

    /// FNV-1a 64 of "a" is 0xaf63dc4c8601ec8c (the reference value).
    #[test]
    fn fnv1a_matches_the_reference() {
        assert_eq!(fnv1a(b"a", 0xcbf2_9ce4_8422_2325), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"", 0xcbf2_9ce4_8422_2325), 0xcbf2_9ce4_8422_2325);
    }

    /// Table I: 2 variants x 2 seeds; the sampling ablation: 3 particle
    /// counts x 3 strategies x 1 seed, of which the stratified 1024-particle
    /// cell is Table I's OMCL_LSeg run of seed 1000 (same filter, same
    /// particles): 4 + 9 - 1 = 12 distinct runs, ids distinct and stable.
    #[test]
    fn plan_merges_runs_two_tables_share() {
        let mut b = small_plan();
        b.filter.sampling.rays = b.rays;
        let entries = plan(&b).unwrap();
        assert_eq!(entries.len(), 12);
        let shared: Vec<&RunEntry> = entries.iter().filter(|e| e.uses.len() == 2).collect();
        assert_eq!(shared.len(), 1);
        assert_eq!(shared[0].task.seed, 1000);
        assert_eq!(
            shared[0].uses,
            vec![
                Use::Table1 {
                    variant: "OMCL_LSeg".into()
                },
                Use::Sampling {
                    particles: 1024,
                    strategy: "stratified".into()
                }
            ]
        );
        let mut ids: Vec<&str> = entries.iter().map(|e| e.id.as_str()).collect();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), 12);
        assert_eq!(plan(&b).unwrap(), entries, "planning is deterministic");
        // The id changes with anything the run computes and with the version.
        let t = &entries[0].task;
        let mut t2 = t.clone();
        t2.frames += 1;
        assert_ne!(run_id(OMCL_VERSION, t), run_id(OMCL_VERSION, &t2));
        assert_ne!(run_id(OMCL_VERSION, t), run_id("0.0.0", t));
        assert_eq!(entries[0].id, run_id(OMCL_VERSION, t));
    }

    /// `table5-floorplan` plans its own runs beside Table V's (the same
    /// sequences, starts and steps, `floor_plan` set, the 2-D filter), which
    /// `all` leaves out; a 3-D run's task is written without the
    /// `floor_plan` key, so its id is the one planned before the key existed.
    #[test]
    fn table5_floorplan_plans_its_own_runs_and_all_leaves_them_out() {
        let mut b = small_plan();
        b.experiments = vec![Experiment::Table5, Experiment::Table5Floorplan];
        b.floor_plan_filter = Some(FilterConfig::floor_plan());
        let entries = plan(&b).unwrap();
        // Two sequences, without and with a prompt, 3-D and 2-D.
        assert_eq!(entries.len(), 8);
        let two_d: Vec<&RunEntry> = entries
            .iter()
            .filter(|e| {
                matches!(
                    e.task.work,
                    Work::Global {
                        floor_plan: true,
                        ..
                    }
                )
            })
            .collect();
        assert_eq!(two_d.len(), 4);
        for e in &two_d {
            let Work::Global { filter, .. } = &e.task.work else {
                unreachable!()
            };
            assert_eq!(
                filter.sampling.rays,
                FilterConfig::floor_plan().sampling.rays
            );
            assert!(matches!(
                e.uses[..],
                [Use::Table5 {
                    floor_plan: true,
                    ..
                }]
            ));
        }
        for e in entries.iter().filter(|e| !two_d.contains(e)) {
            let json = serde_json::to_string(&e.task).unwrap();
            assert!(!json.contains("floor_plan"), "{json}");
            assert!(matches!(
                e.uses[..],
                [Use::Table5 {
                    floor_plan: false,
                    ..
                }]
            ));
        }
        // The plans' settings (`--set plan.*`) go into the 2-D runs' tasks
        // and so their ids, and into no 3-D run's.
        let mut set = b.clone();
        let settings = super::super::plan_settings::PlanSettings {
            plan: crate::map::FloorPlanParams {
                band_min: 0.2,
                ..Default::default()
            },
            two_d: Default::default(),
        };
        set.floor_plan_scene = Some(settings);
        let with = plan(&set).unwrap();
        assert_eq!(with.len(), entries.len());
        for (a, e) in entries.iter().zip(&with) {
            match &e.task.work {
                Work::Global {
                    floor_plan: true,
                    plan,
                    ..
                } => {
                    assert_eq!(*plan, Some(settings));
                    assert_ne!(a.id, e.id);
                }
                Work::Global { plan, .. } => {
                    assert_eq!(*plan, None);
                    assert_eq!(a.id, e.id);
                }
                w => panic!("{w:?}"),
            }
        }
        for e in &two_d {
            assert!(matches!(e.task.work, Work::Global { plan: None, .. }));
        }
        b.experiments = vec![Experiment::All];
        assert!(!b.wants(Experiment::Table5Floorplan));
        let all = plan(&b).unwrap();
        assert!(all.iter().all(|e| !matches!(
            e.task.work,
            Work::Global {
                floor_plan: true,
                ..
            }
        )));
        assert!(all.iter().any(|e| matches!(
            e.task.work,
            Work::Global {
                floor_plan: false,
                ..
            }
        )));
    }

    /// A manifest survives writing and reading; a line from another
    /// version, an edited line and a non-JSON line are kept as bad lines
    /// naming their line number and run.
    #[test]
    fn manifest_round_trip_and_bad_lines() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.jsonl");
        let b = small_plan();
        let entries = plan(&b).unwrap();
        write_manifest(&path, &b, &entries).unwrap();
        let m = Manifest::read(&path).unwrap();
        assert_eq!(m.header.bench, b);
        assert_eq!(m.len(), entries.len());
        assert_eq!(m.entry(3).unwrap(), &entries[3]);
        assert!(matches!(
            m.entry(99),
            Err(SweepError::Index { index: 99, .. })
        ));

        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        lines[2] = lines[2].replace(
            &format!("\"omcl\":\"{OMCL_VERSION}\""),
            "\"omcl\":\"0.0.1\"",
        );
        lines[3] = lines[3].replace("\"frames\":6", "\"frames\":7");
        lines[4] = "{not json".into();
        std::fs::write(&path, lines.join("\n")).unwrap();
        let m = Manifest::read(&path).unwrap();
        let err = m.entry(1).unwrap_err().to_string();
        assert!(err.contains("line 3"), "{err}");
        assert!(err.contains(&entries[1].id), "{err}");
        assert!(err.contains("omcl 0.0.1"), "{err}");
        let err = m.entry(2).unwrap_err().to_string();
        assert!(err.contains("line 4") && err.contains("edited"), "{err}");
        let err = m.entry(3).unwrap_err().to_string();
        assert!(err.contains("line 5") && err.contains("not JSON"), "{err}");
        assert_eq!(m.entry(0).unwrap(), &entries[0]);
        let s = status(&m, &ResultDir::new(dir.path().join("r")));
        assert_eq!(s.failed.iter().map(|f| f.0).collect::<Vec<_>>(), [1, 2, 3]);
        assert_eq!(s.missing.len(), entries.len() - 3);
    }
}
