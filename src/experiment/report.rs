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

/// Reads the results of `manifest` from `results` and writes the tables
/// and figures of its experiments into `out` (created if missing). Floor
/// plans of Figure 4 come from the maps in `cache` where they are there.
pub fn collect(
    manifest: &Manifest,
    results: &ResultDir,
    cache: Option<&Path>,
    out: &Path,
) -> Result<Collected, SweepError> {
    std::fs::create_dir_all(out).map_err(|source| SweepError::Io {
        path: out.to_path_buf(),
        source,
    })?;
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
    let mut md = format!(
        "# omcl bench ({} sequences of {} frames, {} particles, {} rays)\n\n",
        b.sequences, b.frames, b.particles, b.rays
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
        md += &ctx.table5()?;
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
