//! Measurement-map consistency (the paper's Table II), as used to calibrate
//! the feature model: every database row is a class; a pixel is correct
//! when the row most similar to its feature is the row of the voxel its ray
//! hits from the true pose.
//!
//! Scores are computed per frame and averaged over frames ("averaged over
//! all poses", as the paper says), with the definitions and counting of
//! [`crate::eval::consistency`], the crate's one implementation of them.

use rayon::prelude::*;

use super::features::FeatureModel;
use super::render::{self, NO_LABEL};
use super::world::VoxelWorld;
use crate::eval::consistency::{ClassCounts, ConsistencyMetrics};
use crate::geometry::{Intrinsics, Pose};
use crate::raycast::RayCaster;

/// Measures the consistency of `model`'s features with a map whose
/// database is the model's class table and whose voxels carry the world's
/// labels: for every `stride`-th pixel (both directions) of every frame
/// rendered at `poses`, the reference is the class of the voxel hit from
/// the true pose, the prediction the table row most similar to the pixel's
/// feature. Pixels that see nothing are skipped; frames with no scored
/// pixel are left out of the mean (all zero when none is left). Frame `i`
/// uses feature frame index `i`.
pub fn measure(
    model: &FeatureModel,
    world: &VoxelWorld,
    caster: &dyn RayCaster,
    k: &Intrinsics,
    poses: &[(u64, Pose)],
    stride: u32,
) -> ConsistencyMetrics {
    let s = stride.max(1);
    let classes = model.table.len();
    let mut per_frame = Vec::new();
    for (frame_index, pose) in poses {
        let frame = render::render_frame(caster, world, k, pose);
        let rows: Vec<u32> = (0..frame.height).step_by(s as usize).collect();
        let counts = rows
            .par_iter()
            .fold(
                || ClassCounts::new(classes),
                |mut c, &v| {
                    for u in (0..frame.width).step_by(s as usize) {
                        let ctx = model.context(&frame, u, v);
                        if ctx.label == NO_LABEL {
                            continue;
                        }
                        if let Some(p) = model.predicted_class(*frame_index, u, v, &ctx) {
                            // Labels and predictions are rows of the model's
                            // own table: never out of range.
                            c.add(ctx.label as usize, p)
                                .expect("class of the model's table");
                        }
                    }
                    c
                },
            )
            .reduce(
                || ClassCounts::new(classes),
                |mut a, b| {
                    a.merge(&b).expect("same class count");
                    a
                },
            );
        per_frame.extend(counts.metrics());
    }
    ConsistencyMetrics::mean(&per_frame).unwrap_or(ConsistencyMetrics {
        accuracy: 0.0,
        precision: 0.0,
        recall: 0.0,
        iou: 0.0,
        classes_present: 0,
        pixels: 0,
    })
}
