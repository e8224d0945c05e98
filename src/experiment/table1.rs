//! Table I: tracking from the paper's local start, per variant (which map,
//! which features localize), with Figure 4 (trajectories coloured by APE
//! over the floor plan): the variants, a run's tracking, the rows over
//! sequences and their report.

use std::fmt::Write as _;

use super::ExperimentError;
use super::features::feature_model;
use super::mapping::{BenchMap, MapSource};
use super::report::{Ctx, plot_err, write_json};
use super::run::{RunResult, RunSpec, Start, run};
use super::sequence::SimSequence;
use super::sweep::{Planner, RunRecord, SweepError, Task, Use, map_path};
use crate::eval::localization::{SequenceSummary, summarize_sequences};
use crate::mcl::FilterConfig;
use crate::plot::{self, FloorPlan, TrajectoryPanel};
use crate::sim::features::Preset;

/// Figure 4 draws the first `FIGURE4_PANELS` sequences of a variant (a
/// grid of a thousand panels is no figure).
pub const FIGURE4_PANELS: usize = 12;

/// One variant of Table I: which map and which features localize.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Variant {
    pub name: &'static str,
    pub map: MapSource,
    pub localize: Preset,
}

/// The variants of Table I reproduced here: the paper's OMCL_GT (ground-truth
/// semantic images for both mapping and localization, as the paper defines
/// it: the simulator's `gt` preset, exact class embeddings with the label
/// bleed of real ground-truth images near boundaries), OMCL_LSeg
/// (`lseg-like`), the ungrounded OMCL_auto_LSeg (the same map without
/// grounding on the class names) and OMCL_Open_LSeg (a map from the fused
/// point cloud labelled by an OpenScene-like point encoder, localized with
/// `lseg-like` images), plus OMCL_GT_exact (a map of the world's true
/// labels, as a semantic mesh gives them, localized with every pixel's true
/// class embedding: no error at all, the bound the sensor model reaches).
pub const TABLE1_VARIANTS: [Variant; 5] = [
    Variant {
        name: "OMCL_GT",
        map: MapSource::Features(Preset::Gt),
        localize: Preset::Gt,
    },
    Variant {
        name: "OMCL_LSeg",
        map: MapSource::Features(Preset::LsegLike),
        localize: Preset::LsegLike,
    },
    Variant {
        name: "OMCL_auto_LSeg",
        map: MapSource::Auto(Preset::LsegLike),
        localize: Preset::LsegLike,
    },
    Variant {
        name: "OMCL_Open_LSeg",
        map: MapSource::PointCloud,
        localize: Preset::LsegLike,
    },
    Variant {
        name: "OMCL_GT_exact",
        map: MapSource::Labels,
        localize: Preset::Exact,
    },
];

/// One variant's tracking results over the sequences.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TrackingRow {
    pub variant: String,
    pub per_sequence: Vec<RunResult>,
    pub summary: Option<SequenceSummary>,
    pub completed: usize,
    /// Filter steps per second over all steps of all sequences (encoder
    /// excluded, as in the paper).
    pub fps: f64,
    /// Frames per second with the simulated encoder's work.
    pub fps_with_encoder: f64,
    /// Database rows (K) of the maps, mean over sequences.
    pub map_rows: f64,
}

impl TrackingRow {
    /// Gathers per-sequence results.
    pub fn new(variant: impl Into<String>, per_sequence: Vec<RunResult>) -> Self {
        let stats: Vec<_> = per_sequence.iter().map(|r| r.stats).collect();
        let steps: usize = per_sequence.iter().map(|r| r.step_seconds.len()).sum();
        let secs: f64 = per_sequence
            .iter()
            .flat_map(|r| r.step_seconds.iter())
            .sum();
        let encoder: f64 = per_sequence
            .iter()
            .flat_map(|r| r.encoder_seconds.iter())
            .sum();
        TrackingRow {
            variant: variant.into(),
            summary: summarize_sequences(&stats),
            completed: per_sequence.iter().filter(|r| r.completed).count(),
            fps: steps as f64 / secs.max(1e-12),
            fps_with_encoder: steps as f64 / (secs + encoder).max(1e-12),
            map_rows: per_sequence.iter().map(|r| r.map_rows as f64).sum::<f64>()
                / per_sequence.len().max(1) as f64,
            per_sequence,
        }
    }
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
    };
    run(seq, &map.map, map.caster.clone(), &model, &spec)
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

impl Ctx<'_> {
    pub(super) fn table1(&self) -> Result<String, SweepError> {
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
        let table = super::features::builtin_table().ok()?;
        FloorPlan::from_map(&map, table.text_feature("floor"), 0.9)
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
