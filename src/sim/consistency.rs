//! Measurement-map consistency (the paper's Table II), as used to calibrate
//! the feature model: every database row is a class; a pixel is correct
//! when the row most similar to its feature is the row of the voxel its ray
//! hits from the true pose.
//!
//! Scores are computed per frame and averaged over frames ("averaged over
//! all poses", as the paper says). Within a frame, precision, recall and
//! IoU are macro-averaged over the classes that occur in the reference or
//! the prediction of that frame; a class never predicted has precision 0,
//! one never referenced has recall 0 (scikit-learn's `zero_division=0`).

use rayon::prelude::*;

use super::features::FeatureModel;
use super::render::{self, NO_LABEL};
use super::world::VoxelWorld;
use crate::geometry::{Intrinsics, Pose};
use crate::raycast::RayCaster;

/// Measures the consistency of `model`'s features with a map whose
/// database is the model's class table and whose voxels carry the world's
/// labels: for every `stride`-th pixel (both directions) of every frame
/// rendered at `poses`, the reference is the class of the voxel hit from
/// the true pose, the prediction the table row most similar to the pixel's
/// feature. Pixels that see nothing are skipped. Frame `i` uses feature
/// frame index `i`.
pub fn measure(
    model: &FeatureModel,
    world: &VoxelWorld,
    caster: &dyn RayCaster,
    k: &Intrinsics,
    poses: &[(u64, Pose)],
    stride: u32,
) -> Scores {
    let s = stride.max(1);
    let mut mean = ScoreMean::default();
    for (frame_index, pose) in poses {
        let frame = render::render_frame(caster, world, k, pose);
        let rows: Vec<u32> = (0..frame.height).step_by(s as usize).collect();
        let conf = rows
            .par_iter()
            .fold(
                || Confusion::new(model.table.len()),
                |mut c, &v| {
                    for u in (0..frame.width).step_by(s as usize) {
                        let ctx = model.context(&frame, u, v);
                        if ctx.label == NO_LABEL {
                            continue;
                        }
                        if let Some(p) = model.predicted_class(*frame_index, u, v, &ctx) {
                            c.add(ctx.label as usize, p);
                        }
                    }
                    c
                },
            )
            .reduce(|| Confusion::new(model.table.len()), |a, b| a.merged(&b));
        if conf.total() > 0 {
            mean.add(conf.scores());
        }
    }
    mean.mean()
}

/// Counts of (reference, predicted) class pairs.
#[derive(Debug, Clone, PartialEq)]
pub struct Confusion {
    k: usize,
    counts: Vec<u64>,
}

/// Accuracy, macro precision, recall and IoU, each in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Scores {
    pub accuracy: f64,
    pub precision: f64,
    pub recall: f64,
    pub iou: f64,
}

impl Confusion {
    /// An empty matrix over `k` classes.
    pub fn new(k: usize) -> Self {
        Confusion {
            k,
            counts: vec![0; k * k],
        }
    }

    /// Counts one pixel; classes out of range are ignored.
    pub fn add(&mut self, reference: usize, predicted: usize) {
        if reference < self.k && predicted < self.k {
            self.counts[reference * self.k + predicted] += 1;
        }
    }

    /// The sum of two matrices over the same classes.
    pub fn merged(mut self, other: &Confusion) -> Confusion {
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a += b;
        }
        self
    }

    /// Number of counted pixels.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// The scores of the counted pixels (all zero when nothing was counted).
    pub fn scores(&self) -> Scores {
        let k = self.k;
        let total = self.total();
        if total == 0 {
            return Scores::default();
        }
        let mut correct = 0u64;
        let (mut p, mut r, mut iou, mut n) = (0.0, 0.0, 0.0, 0usize);
        for c in 0..k {
            let tp = self.counts[c * k + c];
            correct += tp;
            let refs: u64 = (0..k).map(|j| self.counts[c * k + j]).sum();
            let preds: u64 = (0..k).map(|i| self.counts[i * k + c]).sum();
            if refs == 0 && preds == 0 {
                continue;
            }
            n += 1;
            let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
            p += ratio(tp, preds);
            r += ratio(tp, refs);
            iou += ratio(tp, refs + preds - tp);
        }
        let n = n as f64;
        Scores {
            accuracy: correct as f64 / total as f64,
            precision: p / n,
            recall: r / n,
            iou: iou / n,
        }
    }
}

/// Mean of per-frame scores.
#[derive(Debug, Clone, Copy, Default)]
pub struct ScoreMean {
    sum: Scores,
    frames: usize,
}

impl ScoreMean {
    /// Adds one frame's scores.
    pub fn add(&mut self, s: Scores) {
        self.sum.accuracy += s.accuracy;
        self.sum.precision += s.precision;
        self.sum.recall += s.recall;
        self.sum.iou += s.iou;
        self.frames += 1;
    }

    /// The mean over the added frames.
    pub fn mean(&self) -> Scores {
        let n = self.frames.max(1) as f64;
        Scores {
            accuracy: self.sum.accuracy / n,
            precision: self.sum.precision / n,
            recall: self.sum.recall / n,
            iou: self.sum.iou / n,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_scores() {
        // Reference: 6 of class 0, 2 of class 1. Predicted: class 0 -> 5 right,
        // 1 wrong (as 1); class 1 -> 1 right, 1 as class 2.
        let mut c = Confusion::new(3);
        for _ in 0..5 {
            c.add(0, 0);
        }
        c.add(0, 1);
        c.add(1, 1);
        c.add(1, 2);
        let s = c.scores();
        assert!((s.accuracy - 6.0 / 8.0).abs() < 1e-12);
        // Precision: class 0 5/5, class 1 1/2, class 2 0/1 -> mean 0.5.
        assert!((s.precision - 0.5).abs() < 1e-12);
        // Recall: 5/6, 1/2, class 2 has no reference -> 0; mean (5/6 + 1/2) / 3.
        assert!((s.recall - (5.0 / 6.0 + 0.5) / 3.0).abs() < 1e-12);
        // IoU: 5/6, 1/3, 0.
        assert!((s.iou - (5.0 / 6.0 + 1.0 / 3.0) / 3.0).abs() < 1e-12);
        let mut m = ScoreMean::default();
        m.add(s);
        m.add(Scores {
            accuracy: 1.0,
            precision: 1.0,
            recall: 1.0,
            iou: 1.0,
        });
        assert!((m.mean().accuracy - 0.875).abs() < 1e-12);
    }
}
