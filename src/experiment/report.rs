//! *Collect*: a sweep's result files turned into the tables (Markdown and
//! JSON) and figures (PNG and SVG) `omcl bench` writes. Runs without a
//! valid result (missing, failed, corrupt, from another omcl version, or a
//! manifest line this omcl cannot read) are reported as failed and left
//! out of their cells; the rest of every table is written.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::sweep::{
    ABLATION_PARTICLES, ABLATION_RAYS, BenchPlan, Experiment, Manifest, ManifestLine, Outcome,
    ResultDir, RunEntry, RunRecord, SAMPLING_PARTICLES, SAMPLING_STRATEGIES, SweepError,
    TrackOutcome, Use, map_path,
};
use super::tables::{self, ConsistencyRow, GlobalRun, TrackingRow};
use crate::eval::ConsistencyMetrics;
use crate::eval::localization::CONVERGENCE_THRESHOLDS;
use crate::plot::{self, Axes, BarGroup, FloorPlan, Series, TrajectoryPanel};

/// Figure 4 draws the first `FIGURE4_PANELS` sequences of a variant (a
/// grid of a thousand panels is no figure).
pub const FIGURE4_PANELS: usize = 12;

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

/// One run's place in the manifest and its result, if valid.
struct Slot<'a> {
    entry: &'a RunEntry,
    record: Option<RunRecord>,
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
                let record = match results.read(&entry.id) {
                    Ok(Some(r)) if outcome_fits(&r, entry) => Some(r),
                    Ok(Some(_)) => {
                        let p = results.result_path(&entry.id);
                        failed.push((
                            i,
                            format!(
                                "{}: run {}: the result is of another kind",
                                p.display(),
                                entry.id
                            ),
                        ));
                        None
                    }
                    Ok(None) => {
                        let why = results.failure(&entry.id).map_or_else(
                            || "no result".to_string(),
                            |w| format!("failed: {}", w.trim()),
                        );
                        failed.push((
                            i,
                            format!(
                                "{}: run {}: {why}",
                                results.result_path(&entry.id).display(),
                                entry.id
                            ),
                        ));
                        None
                    }
                    Err(e) => {
                        failed.push((i, e.to_string()));
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

fn write_text(path: &Path, text: &str) -> Result<(), SweepError> {
    crate::io::atomic::write(path, text.as_bytes()).map_err(|source| SweepError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<(), SweepError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| SweepError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    })?;
    write_text(path, &text)
}

fn plot_err(path: PathBuf) -> impl FnOnce(plot::PlotError) -> SweepError {
    move |source| SweepError::Plot { path, source }
}

struct Ctx<'a> {
    bench: &'a BenchPlan,
    slots: &'a [Slot<'a>],
    cache: Option<&'a Path>,
    out: &'a Path,
}

impl Ctx<'_> {
    /// Results of the runs used by `u`, in manifest (seed) order.
    fn records(&self, u: &Use) -> impl Iterator<Item = &RunRecord> {
        self.slots
            .iter()
            .filter(move |s| s.entry.uses.contains(u))
            .filter_map(|s| s.record.as_ref())
    }

    fn tracks(&self, u: &Use) -> Vec<(&RunRecord, &TrackOutcome)> {
        self.records(u)
            .filter_map(|r| match &r.outcome {
                Outcome::Track(t) => Some((r, &**t)),
                _ => None,
            })
            .collect()
    }

    fn tracking_row(&self, variant: &str, u: &Use) -> TrackingRow {
        let runs = self
            .tracks(u)
            .into_iter()
            .map(|(_, t)| t.result.clone())
            .collect();
        TrackingRow::new(variant, runs)
    }

    fn table1(&self) -> Result<String, SweepError> {
        let mut rows = Vec::new();
        for v in self.bench.table_variants()? {
            let u = Use::Table1 {
                variant: v.name.into(),
            };
            let tracks = self.tracks(&u);
            let plans: Vec<Option<FloorPlan>> = tracks
                .iter()
                .take(FIGURE4_PANELS)
                .map(|(r, _)| self.floor_plan(r))
                .collect();
            let titles: Vec<String> = tracks
                .iter()
                .map(|(r, _)| format!("{} sequence {}", v.name, r.task.seed))
                .collect();
            let panels: Vec<TrajectoryPanel> = tracks
                .iter()
                .zip(&plans)
                .zip(&titles)
                .map(|(((_, t), plan), title)| TrajectoryPanel {
                    title,
                    plan: plan.as_ref(),
                    gt_xy: &t.truth_xy,
                    est_xy: &t.estimate_xy,
                    errors_m: &t.result.errors_m,
                })
                .collect();
            if !panels.is_empty() {
                for ext in ["png", "svg"] {
                    let path = self.out.join(format!("figure4_{}.{ext}", v.name));
                    plot::trajectory_grid(&path, &panels).map_err(plot_err(path.clone()))?;
                }
            }
            rows.push(self.tracking_row(v.name, &u));
        }
        write_json(&self.out.join("table1.json"), &rows)?;
        Ok(table1_markdown(&rows))
    }

    /// The floor plan of a run's map, if the map is in the cache.
    fn floor_plan(&self, r: &RunRecord) -> Option<FloorPlan> {
        let path = map_path(self.cache?, &r.task);
        let map = crate::map::file::load(&path).ok()?;
        let table = tables::builtin_table().ok()?;
        FloorPlan::from_map(&map, table.text_feature("floor"), 0.9)
    }

    fn table2(&self) -> Result<String, SweepError> {
        let mut rows = Vec::new();
        for v in self.bench.table_variants()? {
            let u = Use::Table2 {
                variant: v.name.into(),
            };
            let per_seq: Vec<Vec<ConsistencyMetrics>> = self
                .records(&u)
                .filter_map(|r| match &r.outcome {
                    Outcome::Consistency(c) => Some(c.clone()),
                    _ => None,
                })
                .collect();
            rows.push(ConsistencyRow::new(v.name, per_seq));
        }
        write_json(&self.out.join("table2.json"), &rows)?;
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

    fn table5(&self) -> Result<String, SweepError> {
        let v = self.bench.ablation()?;
        let all: Vec<(bool, Vec<GlobalRun>)> = [false, true]
            .into_iter()
            .map(|prompt| {
                let runs = self
                    .records(&Use::Table5 { prompt })
                    .filter_map(|r| match &r.outcome {
                        Outcome::Global(g) => Some(g.clone()),
                        _ => None,
                    })
                    .flatten()
                    .collect();
                (prompt, runs)
            })
            .collect();
        let table: Vec<_> = all
            .iter()
            .map(|(p, runs)| serde_json::json!({"prompt": p, "rows": tables::steps_rows(runs), "runs": runs}))
            .collect();
        write_json(&self.out.join("table5.json"), &table)?;
        let mut s = format!(
            "## Table V: steps until global localization reaches each accuracy ({}, {} runs of at most {} steps)\n\n\
             | start | accuracy | mean | std | min | max | reached |\n|---|---|---|---|---|---|---|\n",
            v.name,
            all.first().map_or(0, |x| x.1.len()),
            self.bench.max_steps
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

    fn particles_rays(&self) -> Result<String, SweepError> {
        let v = self.bench.ablation()?;
        let mut cells = Vec::new();
        for rays in ABLATION_RAYS {
            for particles in ABLATION_PARTICLES {
                let row = self.tracking_row(v.name, &Use::ParticlesRays { particles, rays });
                cells.push((particles, rays, row));
            }
        }
        let rmse = |r: &TrackingRow| r.summary.map_or(f64::NAN, |s| s.mean.rmse);
        let series = |f: &dyn Fn(&TrackingRow) -> f64| -> Vec<Series> {
            ABLATION_RAYS
                .iter()
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
            let path = self.out.join(format!("ablation_particles_ape.{ext}"));
            plot::line_plot(
                &path,
                &Axes {
                    title: format!("APE RMSE against particles ({})", v.name),
                    x_label: "particles".into(),
                    y_label: "APE RMSE [m]".into(),
                    log_x: true,
                    log_y: false,
                },
                &series(&rmse),
            )
            .map_err(plot_err(path.clone()))?;
            let path = self.out.join(format!("ablation_particles_fps.{ext}"));
            plot::line_plot(
                &path,
                &Axes {
                    title: format!("Filter steps per second against particles ({})", v.name),
                    x_label: "particles".into(),
                    y_label: "steps/s".into(),
                    log_x: true,
                    log_y: true,
                },
                &series(&|r| r.fps),
            )
            .map_err(plot_err(path.clone()))?;
        }
        let json: Vec<_> = cells
            .iter()
            .map(|(n, rays, r)| serde_json::json!({"particles": n, "rays": rays, "rmse": rmse(r), "fps": r.fps, "completed": r.completed, "sequences": r.per_sequence.len()}))
            .collect();
        write_json(&self.out.join("ablation_particles_rays.json"), &json)?;
        let mut s = format!(
            "## Ablation: particles x rays ({}, {} sequences; APE RMSE m / steps per second)\n\n| rays \\ particles |",
            v.name, self.bench.ablation_sequences
        );
        for n in ABLATION_PARTICLES {
            let _ = write!(s, " {n} |");
        }
        s += "\n|---|";
        s += &"---|".repeat(ABLATION_PARTICLES.len());
        s.push('\n');
        for rays in ABLATION_RAYS {
            let _ = write!(s, "| {rays} |");
            for c in cells.iter().filter(|c| c.1 == rays) {
                let _ = write!(s, " {:.3} / {:.1} |", rmse(&c.2), c.2.fps);
            }
            s.push('\n');
        }
        s.push('\n');
        Ok(s)
    }

    fn sampling(&self) -> Result<String, SweepError> {
        let v = self.bench.ablation()?;
        let mut groups = Vec::new();
        let mut json = Vec::new();
        let mut s = format!(
            "## Ablation: ray sampling ({}, {} rays, {} sequences; APE RMSE m, completed)\n\n| particles | stratified | equal | uniform |\n|---|---|---|---|\n",
            v.name, self.bench.filter.sampling.rays, self.bench.ablation_sequences
        );
        for n in SAMPLING_PARTICLES {
            let mut bars = Vec::new();
            let _ = write!(s, "| {n} |");
            for (name, _) in SAMPLING_STRATEGIES {
                let row = self.tracking_row(
                    v.name,
                    &Use::Sampling {
                        particles: n,
                        strategy: name.into(),
                    },
                );
                let rmses: Vec<f64> = row.per_sequence.iter().map(|r| r.stats.rmse).collect();
                let (mean, std) = crate::eval::ErrorStats::from_errors(&rmses)
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
            let path = self.out.join(format!("ablation_sampling.{ext}"));
            plot::bar_plot(
                &path,
                &Axes {
                    title: format!("Ray sampling strategies ({})", v.name),
                    x_label: "particles".into(),
                    y_label: "APE RMSE [m]".into(),
                    log_x: false,
                    log_y: false,
                },
                &groups,
            )
            .map_err(plot_err(path.clone()))?;
        }
        write_json(&self.out.join("ablation_sampling.json"), &json)?;
        s.push('\n');
        Ok(s)
    }
}

/// Table I as Markdown.
pub fn table1_markdown(rows: &[TrackingRow]) -> String {
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
