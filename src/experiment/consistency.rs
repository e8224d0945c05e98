//! Measurement-map consistency (the paper's Table II) of a benchmark map:
//! every database row is a class; a pixel is correct when the map row hit
//! by its ray from the true pose is the row most similar to the pixel's
//! feature. Metrics are computed per pose and averaged over poses, then
//! over sequences ([`crate::eval::consistency::mean_over_sequences`]).

use rayon::prelude::*;

use super::ExperimentError;
use super::sequence::SimSequence;
use super::tables::BenchMap;
use crate::eval::consistency::{ConsistencyMetrics, NO_HIT, count_frame};
use crate::geometry::camera_ray;
use crate::sim::features::FeatureModel;
use crate::sim::render::NO_LABEL;

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
                    let ctx = model.context(&frame, u, v);
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
