//! Table I: tracking from the paper's local start, per variant (which map,
//! which features localize), with Figure 4 (trajectories coloured by APE
//! over the floor plan): the variants, a run's tracking, the rows over
//! sequences and their report.

use std::fmt::Write as _;

use super::ExperimentError;
use super::cells::{Ctx, plot_err, write_json};
use super::features::feature_model;
use super::mapping::BenchMap;
pub use super::run::TrackingRow;
use super::run::{RunResult, RunSpec, Start, run};
use super::sequence::SimSequence;
use super::task::{Planner, RunRecord, SweepError, Task, Use, map_path};
pub use super::variant::{TABLE1_VARIANTS, Variant};
use crate::mcl::FilterConfig;
use crate::plot::{self, FloorPlan, TrajectoryPanel};
use crate::sim::features::Preset;

/// Figure 4 draws the first `FIGURE4_PANELS` sequences of a variant (a
/// grid of a thousand panels is no figure).
pub const FIGURE4_PANELS: usize = 12;

/// One panel of Figure 4: a run's estimated path, coloured by its error,
/// over its map's floor plan, with the ground truth.
#[derive(Debug, Clone)]
pub struct Figure4Panel {
    pub title: String,
    pub plan: Option<FloorPlan>,
    pub truth_xy: Vec<[f64; 2]>,
    pub estimate_xy: Vec<[f64; 2]>,
    pub errors_m: Vec<f64>,
}

impl Figure4Panel {
    /// The panel of run `r` (estimates from frame 0) of sequence `seq`
    /// over the floor plan of `map` (none: the paths alone).
    pub fn of_run(
        title: String,
        map: Option<&crate::map::LanguageMap>,
        seq: &SimSequence,
        r: &RunResult,
    ) -> Self {
        Figure4Panel {
            title,
            plan: map.and_then(backdrop),
            truth_xy: xy(&seq.poses()[..r.estimates.len()]),
            estimate_xy: xy(&r.estimates),
            errors_m: r.errors_m.clone(),
        }
    }
}

/// A Table I block as it came out: its rows, them as Markdown beside the
/// paper's, and each row's Figure 4 panels (in the rows' order).
#[derive(Debug, Clone)]
pub struct BlockResult {
    pub rows: Vec<TrackingRow>,
    pub markdown: String,
    pub figures: Vec<Vec<Figure4Panel>>,
    /// Each sequence's seed and ground truth (`world_from_camera` a
    /// frame), in the rows' sequence order: what their estimates are
    /// scored against.
    pub truths: Vec<(u64, Vec<crate::geometry::Pose>)>,
}

/// A block's rows, their Figure 4 panels and each sequence's seed and
/// ground truth, as the blocks' runners return them.
pub(super) type BlockRuns = (
    Vec<TrackingRow>,
    Vec<Vec<Figure4Panel>>,
    Vec<(u64, Vec<crate::geometry::Pose>)>,
);

/// The (x, y) of each pose, world frame.
pub(super) fn xy(poses: &[crate::geometry::Pose]) -> Vec<[f64; 2]> {
    poses
        .iter()
        .map(|p| [p.translation.vector.x, p.translation.vector.y])
        .collect()
}

/// The floor plan Figure 4 draws under a map's paths: its voxels, floor
/// where they match the built-in "floor" text feature at 0.9.
pub fn backdrop(map: &crate::map::LanguageMap) -> Option<FloorPlan> {
    let table = super::features::builtin_table().ok()?;
    FloorPlan::from_map(map, table.text_feature("floor"), 0.9)
}

/// Writes Figure 4 of one variant as `<dir>/<stem>.png` and `.svg`: its
/// first [`FIGURE4_PANELS`] panels in a grid; nothing for no panel.
pub fn write_figure4(
    dir: &std::path::Path,
    stem: &str,
    panels: &[Figure4Panel],
) -> Result<(), plot::PlotError> {
    let drawn: Vec<TrajectoryPanel> = panels
        .iter()
        .take(FIGURE4_PANELS)
        .map(|p| TrajectoryPanel {
            title: &p.title,
            plan: p.plan.as_ref(),
            gt_xy: &p.truth_xy,
            est_xy: &p.estimate_xy,
            errors_m: &p.errors_m,
        })
        .collect();
    if drawn.is_empty() {
        return Ok(());
    }
    for ext in ["png", "svg"] {
        plot::trajectory_grid(&dir.join(format!("{stem}.{ext}")), &drawn)?;
    }
    Ok(())
}

/// Tracks sequence `seq` in `map` from the paper's local start with
/// `filter`, `particles` and the features of `preset`.
pub fn track(
    seq: &SimSequence,
    map: &BenchMap,
    preset: Preset,
    filter: FilterConfig,
    particles: usize,
) -> Result<RunResult, ExperimentError> {
    let model = feature_model(seq, preset, 0x10c);
    let spec = RunSpec {
        filter,
        particles,
        start: Start::paper_local(),
        first: 0,
        frames: seq.len(),
        preset,
        encoder_stride: 1,
    };
    run(seq, &map.map, map.caster.clone(), &model, &spec)
}

/// A row of the paper's Table I: variant, APE RMSE, STD, Mean, Median, min
/// RMSE, max RMSE (m), SSE (m^2), and how many sequences completed.
pub struct PaperRow {
    pub variant: &'static str,
    pub ape: [f64; 7],
    pub completed: &'static str,
}

/// A tracking row's APE cells: RMSE, STD, Mean, Median, min and max RMSE,
/// SSE and the completed sequences, `|`-separated.
pub(super) fn ape_cells(r: &TrackingRow) -> Option<String> {
    let m = r.summary.as_ref()?;
    Some(format!(
        "{:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {}",
        m.mean.rmse,
        m.mean.std,
        m.mean.mean,
        m.mean.median,
        m.min_rmse,
        m.max_rmse,
        m.mean.sse,
        r.completed_cell,
    ))
}

/// Table I as Markdown.
pub fn table1_markdown(rows: &[TrackingRow]) -> String {
    let mut s = String::from(
        "## Table I: APE of tracking (m), averaged over sequences\n\n\
         | variant | RMSE | STD | Mean | Median | min RMSE | max RMSE | SSE (m^2) | completed | steps/s | with encoder | K |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        if let Some(cells) = ape_cells(r) {
            let _ = writeln!(
                s,
                "| {} | {cells} | {:.1} | {:.1} | {:.0} |",
                r.variant, r.fps, r.fps_with_encoder, r.map_rows
            );
        }
    }
    s.push('\n');
    s
}

/// One of Table I's blocks as Markdown: each of our rows followed by the
/// paper's row of the same variant.
pub fn block_markdown(title: &str, ours: &[TrackingRow], paper: &[PaperRow]) -> String {
    let mut s = format!(
        "## {title}\n\n| variant | RMSE | STD | Mean | Median | min RMSE | max RMSE | SSE (m^2) | completed | steps/s |\n|---|---|---|---|---|---|---|---|---|---|\n"
    );
    for r in ours {
        if let Some(cells) = ape_cells(r) {
            let _ = writeln!(s, "| {}, omcl | {cells} | {:.1} |", r.variant, r.fps);
        }
        for p in paper.iter().filter(|p| p.variant == r.variant) {
            let v = p.ape;
            let _ = writeln!(
                s,
                "| {}, paper | {} | {} | {} | {} | {} | {} | {} | {} | |",
                p.variant, v[0], v[1], v[2], v[3], v[4], v[5], v[6], p.completed
            );
        }
    }
    s
}

impl Ctx<'_> {
    pub(super) fn table1(&self) -> Result<String, SweepError> {
        let mut rows = Vec::new();
        for v in self.bench.table_variants()? {
            let u = Use::Table1 {
                variant: v.name.into(),
            };
            let panels: Vec<Figure4Panel> = self
                .tracks(&u)
                .iter()
                .take(FIGURE4_PANELS)
                .map(|(r, t)| Figure4Panel {
                    title: format!("{} sequence {}", v.name, r.task.seed),
                    plan: self.floor_plan(r),
                    truth_xy: t.truth_xy.clone(),
                    estimate_xy: t.estimate_xy.clone(),
                    errors_m: t.result.errors_m.clone(),
                })
                .collect();
            let stem = format!("figure4_{}", v.name);
            write_figure4(self.out, &stem, &panels)
                .map_err(plot_err(self.out.join(format!("{stem}.png"))))?;
            rows.push(self.tracking_row(v.name, &u));
        }
        write_json(&self.out.join("table1.json"), &rows)?;
        Ok(table1_markdown(&rows))
    }

    /// The floor plan of a run's map, if the map is in the cache.
    fn floor_plan(&self, r: &RunRecord) -> Option<FloorPlan> {
        let path = map_path(self.cache?, &r.task);
        backdrop(&crate::map::file::load(&path).ok()?)
    }
}

/// Plans Table I: each variant tracks each sequence.
pub(super) fn plan(p: &Planner, variants: &[Variant], out: &mut Vec<(Task, Use)>) {
    for v in variants {
        for s in p.bench.seeds() {
            let t = p.track(s, v, p.bench.filter, p.bench.particles);
            out.push((
                t,
                Use::Table1 {
                    variant: v.name.into(),
                },
            ));
        }
    }
}
