//! *Collect*: a sweep's result files turned into the tables (Markdown and
//! JSON) and figures (PNG and SVG) `omcl bench` writes. Runs without a
//! valid result (missing, failed, corrupt, from another omcl version, or a
//! manifest line this omcl cannot read) are reported as failed and left
//! out of their cells; the rest of every table is written.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::cells::{Ctx, Slot, write_text};
use super::sweep::{
    Experiment, Manifest, ManifestLine, Outcome, ResultDir, RunEntry, RunRecord, SweepError,
};

/// What [`collect`] wrote and what it could not use.
#[derive(Debug, Clone)]
pub struct Collected {
    /// The Markdown report (also written to `path`).
    pub markdown: String,
    /// The Markdown report's file.
    pub path: PathBuf,
    /// Runs with a result.
    pub done: usize,
    /// Runs without one: (run index, why).
    pub failed: Vec<(usize, String)>,
}

/// The file in a collect's output folder that names the manifest and the
/// files that collect wrote: the next collect into the folder removes
/// those first, so that one sweep's tables never stand beside another's.
pub const COLLECTED: &str = "collected.txt";

/// Reads the results of `manifest` from `results` and writes the tables
/// and figures of its experiments into `out` (created if missing). Floor
/// plans of Figure 4 come from the maps in `cache` where they are there.
///
/// The files an earlier collect wrote into `out` (listed in its
/// [`COLLECTED`]) are removed first. Tables or figures in `out` that no
/// collect recorded (another tool's, or written before 2026-11-28) are
/// refused unless `beside_foreign`.
pub fn collect(
    manifest: &Manifest,
    results: &ResultDir,
    cache: Option<&Path>,
    out: &Path,
    beside_foreign: bool,
) -> Result<Collected, SweepError> {
    crate::io::atomic::create_folder(out).map_err(|source| SweepError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let _held = lock_folder(out)?;
    clear_previous(out, beside_foreign)?;
    let before = top_files(out);
    let collected = collect_into(manifest, results, cache, out)?;
    let after = top_files(out);
    // Tables and figures only: a file of another kind that changed
    // meanwhile is someone else's.
    let mut written: Vec<&String> = after
        .iter()
        .filter(|(name, id)| {
            before.get(*name) != Some(id) && name.as_str() != COLLECTED && is_table_or_figure(name)
        })
        .map(|(name, _)| name)
        .collect();
    written.sort();
    let mut stamp = format!(
        "# Written by omcl sweep collect (or omcl bench) from the manifest below; the next \
         collect into this folder removes these files first.\nmanifest: {}\n",
        manifest.path.display()
    );
    for name in written {
        let _ = writeln!(stamp, "{name}");
    }
    write_text(&out.join(COLLECTED), &stamp)?;
    Ok(collected)
}

/// The lock of an output folder, held while a collect writes into it
/// (two at once each removed and wrote the other's tables, or failed on a
/// file the other had just removed): a hidden file in it, locked.
fn lock_folder(out: &Path) -> Result<std::fs::File, SweepError> {
    let path = out.join(".omcl-collect.lock");
    let io = |source| SweepError::Io {
        path: path.clone(),
        source,
    };
    let lock = std::fs::File::create(&path).map_err(io)?;
    match lock.try_lock() {
        Ok(()) => Ok(lock),
        Err(std::fs::TryLockError::WouldBlock) => Err(SweepError::BadResult {
            path: out.to_path_buf(),
            reason: "another omcl sweep collect (or omcl bench) is writing its tables into \
                     this folder; wait for it to end, or collect into another folder"
                .into(),
        }),
        // A file system without locks (some NFS and Lustre mounts): go on
        // unlocked, as before the lock was there.
        Err(std::fs::TryLockError::Error(e)) if e.kind() == std::io::ErrorKind::Unsupported => {
            Ok(lock)
        }
        Err(std::fs::TryLockError::Error(e)) => Err(io(e)),
    }
}

/// The plain files at the top of `dir` by name, each with its inode and
/// modification time (a file rewritten in place of another, atomically,
/// has a new inode).
fn top_files(
    dir: &Path,
) -> std::collections::HashMap<String, (u64, Option<std::time::SystemTime>)> {
    use std::os::unix::fs::MetadataExt;
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Default::default();
    };
    entries
        .filter_map(Result::ok)
        .filter_map(|e| {
            let m = e.metadata().ok()?;
            m.is_file()
                .then(|| {
                    Some((
                        e.file_name().into_string().ok()?,
                        (m.ino(), m.modified().ok()),
                    ))
                })
                .flatten()
        })
        .collect()
}

/// Removes what the collect recorded in `out`'s [`COLLECTED`] wrote, or
/// refuses tables and figures no collect recorded.
fn clear_previous(out: &Path, beside_foreign: bool) -> Result<(), SweepError> {
    let stamp = out.join(COLLECTED);
    match std::fs::read_to_string(&stamp) {
        Ok(text) => {
            for name in text.lines().skip(2) {
                // Plain names only: never a path out of the folder.
                if name.is_empty() || name.contains('/') || name == ".." || name == "." {
                    continue;
                }
                let p = out.join(name);
                if p.is_file() {
                    std::fs::remove_file(&p)
                        .map_err(|source| SweepError::Io { path: p, source })?;
                }
            }
            Ok(())
        }
        Err(_) if beside_foreign => Ok(()),
        Err(_) => {
            let mut foreign: Vec<String> = top_files(out)
                .into_keys()
                .filter(|n| is_table_or_figure(n))
                .collect();
            foreign.sort();
            match foreign.first() {
                None => Ok(()),
                Some(first) => Err(SweepError::Plan(format!(
                    "{}: holds tables or figures no collect recorded ({first}{}): another \
                     sweep's or your own, which this sweep's would stand beside; collect into \
                     another folder, or pass --force to write beside them",
                    out.display(),
                    if foreign.len() > 1 {
                        format!(" and {} more", foreign.len() - 1)
                    } else {
                        String::new()
                    }
                ))),
            }
        }
    }
}

/// What a collect writes: Markdown and JSON tables, PNG and SVG figures.
fn is_table_or_figure(name: &str) -> bool {
    [".md", ".json", ".png", ".svg"]
        .iter()
        .any(|x| name.ends_with(x))
}

/// [`collect`]'s tables and figures, written into `out`.
fn collect_into(
    manifest: &Manifest,
    results: &ResultDir,
    cache: Option<&Path>,
    out: &Path,
) -> Result<Collected, SweepError> {
    let mut failed = Vec::new();
    let mut slots = Vec::new();
    for (i, line) in manifest.lines.iter().enumerate() {
        match line {
            ManifestLine::Bad(b) => failed.push((
                i,
                format!("{} line {}: {}", manifest.path.display(), b.line, b.reason),
            )),
            ManifestLine::Run(entry) => {
                let record = match read_result(results, entry) {
                    Ok(r) => Some(r),
                    Err(why) => {
                        failed.push((i, why));
                        None
                    }
                };
                slots.push(Slot { entry, record });
            }
        }
    }
    let done = slots.iter().filter(|s| s.record.is_some()).count();
    let b = &manifest.header.bench;
    // The rays of the 3-D filter; table5-floorplan alone: of its 2-D one
    // (its table's heading gives them beside others).
    let rays = match b.experiments[..] {
        [Experiment::Table5Floorplan] => b.two_d_filter().sampling.rays,
        _ => b.rays,
    };
    let mut md = format!(
        "# omcl bench ({} sequence{} of {} frames, {} particles, {} rays)\n\n",
        b.sequences,
        if b.sequences == 1 { "" } else { "s" },
        b.frames,
        b.particles,
        rays
    );
    let ctx = Ctx {
        bench: b,
        slots: &slots,
        cache,
        out,
    };
    if b.wants(Experiment::Table1) {
        md += &ctx.table1()?;
    }
    if b.wants(Experiment::Table2) {
        md += &ctx.table2()?;
    }
    if b.wants(Experiment::Table5) {
        md += &ctx.table5(false)?;
    }
    if b.wants(Experiment::Table5Floorplan) {
        md += &ctx.table5(true)?;
    }
    if b.wants(Experiment::ParticlesRays) {
        md += &ctx.particles_rays()?;
    }
    if b.wants(Experiment::Sampling) {
        md += &ctx.sampling()?;
    }
    if !failed.is_empty() {
        let _ = writeln!(
            md,
            "## Failed runs ({} of {}; left out of the tables above)\n",
            failed.len(),
            manifest.len()
        );
        for (i, why) in &failed {
            let _ = writeln!(md, "- run {i}: {why}");
        }
        md.push('\n');
    }
    let path = out.join(report_name(&b.experiments));
    write_text(&path, &md)?;
    Ok(Collected {
        markdown: md,
        path,
        done,
        failed,
    })
}

/// A run's result, or why there is none: missing, failed (with the
/// failure's text), unreadable, or of another kind than the run.
fn read_result(results: &ResultDir, entry: &RunEntry) -> Result<RunRecord, String> {
    match results.read(&entry.id) {
        Ok(Some(r)) if outcome_fits(&r, entry) => Ok(r),
        Ok(Some(_)) => Err(format!(
            "{}: run {}: the result is of another kind",
            results.result_path(&entry.id).display(),
            entry.id
        )),
        Ok(None) => {
            let why = results.failure(&entry.id).map_or_else(
                || "no result".to_string(),
                |w| format!("failed: {}", w.trim()),
            );
            Err(format!(
                "{}: run {}: {why}",
                results.result_path(&entry.id).display(),
                entry.id
            ))
        }
        Err(e) => Err(e.to_string()),
    }
}

/// The Markdown report's file name: `all.md`, `<experiment>.md` for one,
/// `bench.md` for several.
pub fn report_name(experiments: &[Experiment]) -> String {
    match experiments {
        e if e.contains(&Experiment::All) => "all.md".into(),
        [one] => format!("{}.md", one.name()),
        _ => "bench.md".into(),
    }
}

fn outcome_fits(r: &RunRecord, e: &RunEntry) -> bool {
    r.task == e.task
        && matches!(
            (&r.outcome, &e.task.work),
            (Outcome::Track(_), super::sweep::Work::Track { .. })
                | (
                    Outcome::Consistency(_),
                    super::sweep::Work::Consistency { .. }
                )
                | (Outcome::Global(_), super::sweep::Work::Global { .. })
        )
}
