//! Table II: measurement-map consistency of each variant's map with its
//! features. Every database row is a class; a pixel is correct when the
//! map row hit by its ray from the true pose is the row most similar to the
//! pixel's feature. Metrics are computed per pose and averaged over poses,
//! then over sequences ([`crate::eval::consistency::mean_over_sequences`],
//! the crate's one implementation of the scores).

use std::fmt::Write as _;

use rayon::prelude::*;

use super::ExperimentError;
use super::cells::{Ctx, write_json};
use super::features::feature_model;
use super::mapping::BenchMap;
use super::sequence::SimSequence;
use super::task::{Outcome, Planner, SweepError, Task, Use, Work};
use super::variant::Variant;
use crate::eval::consistency::{ConsistencyMetrics, NO_HIT, count_frame};
use crate::geometry::camera_ray;
use crate::sim::features::{FeatureModel, LabelEdges, Preset};
use crate::sim::render::NO_LABEL;

/// Table II scores every `CONSISTENCY_FRAME_STEP`-th frame.
pub const CONSISTENCY_FRAME_STEP: usize = 10;

/// Table II: consistency of each variant's map with its features.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ConsistencyRow {
    pub variant: String,
    /// Per sequence, per pose.
    pub per_pose: Vec<Vec<crate::eval::ConsistencyMetrics>>,
    /// Averaged over poses, then over sequences.
    pub mean: Option<crate::eval::ConsistencyMetrics>,
}

impl ConsistencyRow {
    /// Gathers per-pose metrics of the sequences.
    pub fn new(
        variant: impl Into<String>,
        per_pose: Vec<Vec<crate::eval::ConsistencyMetrics>>,
    ) -> Self {
        ConsistencyRow {
            variant: variant.into(),
            mean: crate::eval::mean_over_sequences(&per_pose),
            per_pose,
        }
    }
}

/// The consistency of `map` with the features of `preset` on `seq`, every
/// `frame_step`-th frame, every 8th pixel.
pub fn consistency(
    seq: &SimSequence,
    map: &BenchMap,
    preset: Preset,
    frame_step: usize,
) -> Result<Vec<crate::eval::ConsistencyMetrics>, ExperimentError> {
    let model = feature_model(seq, preset, 0x10c);
    per_pose(seq, map, &model, frame_step, 8)
}

/// Per-pose consistency of `map` with `model`'s features at every
/// `frame_step`-th frame of `seq`, on a grid of every `stride`-th pixel.
/// Pixels that see nothing from the true pose are not scored.
pub fn per_pose(
    seq: &SimSequence,
    map: &BenchMap,
    model: &FeatureModel,
    frame_step: usize,
    stride: u32,
) -> Result<Vec<ConsistencyMetrics>, ExperimentError> {
    let db = map.map.db();
    let origin = map.map.grid().origin;
    let mut out = Vec::new();
    for i in (0..seq.len()).step_by(frame_step.max(1)) {
        let frame = seq.render(i);
        let edges = LabelEdges::new(&frame);
        let pose = seq.poses()[i];
        let px: Vec<(u32, u32)> = (0..frame.height)
            .step_by(stride.max(1) as usize)
            .flat_map(|v| {
                (0..frame.width)
                    .step_by(stride.max(1) as usize)
                    .map(move |u| (u, v))
            })
            .filter(|&(u, v)| frame.labels[frame.index(u, v)] != NO_LABEL)
            .collect();
        let rays: Vec<_> = px
            .iter()
            .map(|&(u, v)| camera_ray(&seq.intrinsics, &pose, &origin, u, v))
            .collect();
        let hits = map.caster.cast_vec(&rays);
        let map_rows: Vec<u32> = hits
            .iter()
            .map(|h| {
                map.map
                    .rows()
                    .get(h.leaf as usize)
                    .copied()
                    .unwrap_or(NO_HIT)
            })
            .collect();
        let measured: Vec<u32> = px
            .par_iter()
            .map_init(
                || vec![0.0f32; model.dim()],
                |buf, &(u, v)| {
                    let ctx = model.context_near(&frame, &edges, u, v);
                    model.feature_at(i as u64, u, v, &ctx, buf);
                    db.nearest(buf)
                        .ok()
                        .flatten()
                        .map_or(NO_HIT, |(r, _)| r as u32)
                },
            )
            .collect();
        // A pixel without a feature direction is not scored either.
        let map_rows: Vec<u32> = map_rows
            .iter()
            .zip(&measured)
            .map(|(&m, &f)| if f == NO_HIT { NO_HIT } else { m })
            .collect();
        let (counts, _misses) = count_frame(db.len(), &map_rows, &measured)
            .map_err(|e| ExperimentError::Config(e.to_string()))?;
        if let Some(m) = counts.metrics() {
            out.push(m);
        }
    }
    Ok(out)
}

impl Ctx<'_> {
    pub(super) fn table2(&self) -> Result<String, SweepError> {
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
}

/// Plans Table II: each variant's consistency on each sequence.
pub(super) fn plan(p: &Planner, variants: &[Variant], out: &mut Vec<(Task, Use)>) {
    for v in variants {
        for s in p.bench.seeds() {
            let work = Work::Consistency {
                frame_step: CONSISTENCY_FRAME_STEP,
            };
            out.push((
                p.task(s, v, work),
                Use::Table2 {
                    variant: v.name.into(),
                },
            ));
        }
    }
}
