//! Evaluation: trajectory error metrics (as evo and the KITTI devkit compute
//! them) and measurement-map consistency.
//!
//! Everything here is pure computation on [`crate::trajectory::Trajectory`]
//! values and counts; reading files is [`crate::io::poses`]'s job.

pub mod align;
pub mod ape;
pub mod associate;
pub mod consistency;
pub mod kitti_metric;
pub mod localization;
pub mod outdoor;
pub mod rpe;
pub mod stats;

pub use align::{Alignment, AlignmentResult, Similarity, align_trajectory, umeyama};
pub use ape::{PoseErrors, PoseRelation, ape};
pub use associate::{associate, matching_time_indices};
pub use consistency::{
    ClassCounts, ConfusionMatrix, ConsistencyMetrics, count_frame, mean_over_sequences,
};
pub use kitti_metric::{KittiMetric, kitti_metric};
pub use localization::{CompletionRule, SequenceSummary, steps_to_reach, summarize_sequences};
pub use outdoor::{OutdoorMetric, outdoor_metric};
pub use rpe::{Delta, RpeOptions, rpe};
pub use stats::ErrorStats;

/// Errors of the trajectory metrics.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EvalError {
    #[error("reference has {reference} poses but estimate has {estimate}; associate them first")]
    LengthMismatch { reference: usize, estimate: usize },
    #[error("no poses to evaluate")]
    Empty,
    #[error(
        "no matching time stamps between reference and estimate within {max_diff} s \
         (offset {offset} s)"
    )]
    NoMatches { max_diff: f64, offset: f64 },
    #[error(
        "Umeyama alignment is not possible: the positions are degenerate (collinear or fewer than 2 distinct points)"
    )]
    DegenerateAlignment,
    #[error("delta {delta} gives no pose pairs for {poses} poses")]
    NoPairs { delta: String, poses: usize },
    #[error(
        "the reference path is shorter than the shortest KITTI segment (100 m); no segments to evaluate"
    )]
    NoSegments,
}
