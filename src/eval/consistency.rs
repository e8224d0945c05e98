//! Measurement-map consistency (paper, Table II) as per-class
//! classification scores.
//!
//! Every feature-database row is a class. For a pixel seen from the true
//! pose, the *reference* class is the row of the map voxel its ray hits and
//! the *predicted* class is the row most similar to the pixel's own feature;
//! the pixel is correct when they agree. Rays that hit nothing have no
//! reference class; callers leave them out (and may report their share).
//!
//! Definitions (per class `c`: `TP` pixels with reference and prediction
//! `c`, `FP` predicted `c` with another reference, `FN` reference `c`
//! predicted as another class):
//! - accuracy = correct pixels / pixels;
//! - precision, recall and IoU are *macro* averages over the classes
//!   **present**, those with `TP + FP + FN > 0` (seen in the reference or in
//!   the prediction). Classes absent from both are left out of the average
//!   (a database has many rows a given view never shows). For a present
//!   class, a ratio whose denominator is zero (precision of a class never
//!   predicted, recall of a class never in the reference) counts as 0.
//! - Averaging over poses and sequences (paper: "averaged over all poses and
//!   sequences"; [`mean_over_sequences`]): each pose's metrics are computed
//!   from that pose's pixels, averaged over the poses of a sequence (each pose
//!   weighs the same), and the sequence means are averaged over sequences
//!   (each sequence weighs the same). [`ConsistencyMetrics::mean`] over all
//!   poses of all sequences weighs long sequences more; pooling all pixels
//!   first ([`ClassCounts::merge`]) weighs poses by their pixel count.

/// Errors of the consistency counters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConsistencyError {
    #[error("class {class} is out of range for {classes} classes")]
    ClassOutOfRange { class: usize, classes: usize },
    #[error("{map} map rows but {measured} measured rows: one of each per pixel")]
    PixelCountMismatch { map: usize, measured: usize },
    #[error("cannot merge counts of {left} and {right} classes")]
    ClassCountMismatch { left: usize, right: usize },
}

/// Accuracy and macro precision / recall / IoU (fractions in [0, 1]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ConsistencyMetrics {
    pub accuracy: f64,
    pub precision: f64,
    pub recall: f64,
    pub iou: f64,
    /// Number of classes present (the macro averages' denominator).
    pub classes_present: usize,
    /// Number of pixels scored.
    pub pixels: u64,
}

impl ConsistencyMetrics {
    /// Unweighted mean of each score (pixels and classes are summed).
    /// Use it over poses, then again over the per-sequence means. `None` for
    /// an empty slice.
    pub fn mean(items: &[ConsistencyMetrics]) -> Option<ConsistencyMetrics> {
        if items.is_empty() {
            return None;
        }
        let n = items.len() as f64;
        let avg = |f: fn(&ConsistencyMetrics) -> f64| items.iter().map(f).sum::<f64>() / n;
        Some(ConsistencyMetrics {
            accuracy: avg(|m| m.accuracy),
            precision: avg(|m| m.precision),
            recall: avg(|m| m.recall),
            iou: avg(|m| m.iou),
            classes_present: items.iter().map(|m| m.classes_present).sum(),
            pixels: items.iter().map(|m| m.pixels).sum(),
        })
    }
}

/// The paper's Table II averaging: per-pose metrics averaged within each
/// sequence, then the sequence means averaged. Sequences with no scored pose
/// are left out; `None` when none is left.
pub fn mean_over_sequences(per_pose: &[Vec<ConsistencyMetrics>]) -> Option<ConsistencyMetrics> {
    let per_sequence: Vec<ConsistencyMetrics> = per_pose
        .iter()
        .filter_map(|poses| ConsistencyMetrics::mean(poses))
        .collect();
    ConsistencyMetrics::mean(&per_sequence)
}

/// Marks a pixel whose ray hit no map voxel in [`count_frame`].
pub const NO_HIT: u32 = u32::MAX;

/// Counts one frame: `map_rows[j]` is the database row of the voxel hit by
/// pixel `j`'s ray from the true pose ([`NO_HIT`] for a miss) and
/// `measured_rows[j]` the row most similar to pixel `j`'s feature. Misses are
/// not scored; their number is returned with the counts.
pub fn count_frame(
    classes: usize,
    map_rows: &[u32],
    measured_rows: &[u32],
) -> Result<(ClassCounts, usize), ConsistencyError> {
    if map_rows.len() != measured_rows.len() {
        return Err(ConsistencyError::PixelCountMismatch {
            map: map_rows.len(),
            measured: measured_rows.len(),
        });
    }
    let mut counts = ClassCounts::new(classes);
    let mut misses = 0;
    for (&m, &f) in map_rows.iter().zip(measured_rows) {
        if m == NO_HIT {
            misses += 1;
        } else {
            counts.add(m as usize, f as usize)?;
        }
    }
    Ok((counts, misses))
}

/// Per-class true positives, false positives and false negatives: all the
/// scores need, in memory linear in the number of classes (a full confusion
/// matrix of a large feature database would be quadratic).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ClassCounts {
    tp: Vec<u64>,
    fp: Vec<u64>,
    fn_: Vec<u64>,
}

impl ClassCounts {
    /// Zero counts for `classes` classes.
    pub fn new(classes: usize) -> Self {
        ClassCounts {
            tp: vec![0; classes],
            fp: vec![0; classes],
            fn_: vec![0; classes],
        }
    }

    /// Number of classes.
    pub fn classes(&self) -> usize {
        self.tp.len()
    }

    /// Counts one pixel.
    pub fn add(&mut self, reference: usize, predicted: usize) -> Result<(), ConsistencyError> {
        let classes = self.classes();
        for class in [reference, predicted] {
            if class >= classes {
                return Err(ConsistencyError::ClassOutOfRange { class, classes });
            }
        }
        if reference == predicted {
            self.tp[reference] += 1;
        } else {
            self.fp[predicted] += 1;
            self.fn_[reference] += 1;
        }
        Ok(())
    }

    /// Counts `(reference, predicted)` pairs.
    pub fn from_pairs(
        classes: usize,
        pairs: impl IntoIterator<Item = (usize, usize)>,
    ) -> Result<Self, ConsistencyError> {
        let mut c = ClassCounts::new(classes);
        for (r, p) in pairs {
            c.add(r, p)?;
        }
        Ok(c)
    }

    /// Adds another set of counts (pooling pixels).
    pub fn merge(&mut self, other: &ClassCounts) -> Result<(), ConsistencyError> {
        if other.classes() != self.classes() {
            return Err(ConsistencyError::ClassCountMismatch {
                left: self.classes(),
                right: other.classes(),
            });
        }
        for i in 0..self.classes() {
            self.tp[i] += other.tp[i];
            self.fp[i] += other.fp[i];
            self.fn_[i] += other.fn_[i];
        }
        Ok(())
    }

    /// `(TP, FP, FN)` of class `c`.
    pub fn class(&self, c: usize) -> Option<(u64, u64, u64)> {
        Some((*self.tp.get(c)?, self.fp[c], self.fn_[c]))
    }

    /// The scores defined in the module docs; `None` when no pixel was
    /// counted.
    pub fn metrics(&self) -> Option<ConsistencyMetrics> {
        let correct: u64 = self.tp.iter().sum();
        let wrong: u64 = self.fp.iter().sum();
        let pixels = correct + wrong;
        if pixels == 0 {
            return None;
        }
        let ratio = |num: u64, den: u64| {
            if den == 0 {
                0.0
            } else {
                num as f64 / den as f64
            }
        };
        let (mut precision, mut recall, mut iou, mut present) = (0.0, 0.0, 0.0, 0usize);
        for c in 0..self.classes() {
            let (tp, fp, fn_) = (self.tp[c], self.fp[c], self.fn_[c]);
            if tp + fp + fn_ == 0 {
                continue;
            }
            present += 1;
            precision += ratio(tp, tp + fp);
            recall += ratio(tp, tp + fn_);
            iou += ratio(tp, tp + fp + fn_);
        }
        let k = present as f64;
        Some(ConsistencyMetrics {
            accuracy: correct as f64 / pixels as f64,
            precision: precision / k,
            recall: recall / k,
            iou: iou / k,
            classes_present: present,
            pixels,
        })
    }
}

/// A dense confusion matrix, `counts[reference][predicted]`, for small
/// class counts (reports, tests); [`ConfusionMatrix::class_counts`] gives
/// the scores.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfusionMatrix {
    classes: usize,
    counts: Vec<u64>,
}

impl ConfusionMatrix {
    /// Zero counts for `classes` classes.
    pub fn new(classes: usize) -> Self {
        ConfusionMatrix {
            classes,
            counts: vec![0; classes * classes],
        }
    }

    /// A matrix from rows (`rows[reference][predicted]`); `None` unless it is
    /// square.
    pub fn from_rows(rows: &[Vec<u64>]) -> Option<Self> {
        let classes = rows.len();
        if rows.iter().any(|r| r.len() != classes) {
            return None;
        }
        Some(ConfusionMatrix {
            classes,
            counts: rows.concat(),
        })
    }

    /// Counts one pixel.
    pub fn add(&mut self, reference: usize, predicted: usize) -> Result<(), ConsistencyError> {
        for class in [reference, predicted] {
            if class >= self.classes {
                return Err(ConsistencyError::ClassOutOfRange {
                    class,
                    classes: self.classes,
                });
            }
        }
        self.counts[reference * self.classes + predicted] += 1;
        Ok(())
    }

    /// Pixels with this reference and predicted class.
    pub fn get(&self, reference: usize, predicted: usize) -> u64 {
        if reference < self.classes && predicted < self.classes {
            self.counts[reference * self.classes + predicted]
        } else {
            0
        }
    }

    /// The per-class counts of this matrix.
    pub fn class_counts(&self) -> ClassCounts {
        let k = self.classes;
        let mut c = ClassCounts::new(k);
        for r in 0..k {
            for p in 0..k {
                let n = self.counts[r * k + p];
                if r == p {
                    c.tp[r] += n;
                } else {
                    c.fp[p] += n;
                    c.fn_[r] += n;
                }
            }
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_confusion_matrix() {
        // 4 classes; class 3 appears nowhere.
        //            pred 0  1  2  3
        // ref 0         5  1  0  0
        // ref 1         2  3  1  0
        // ref 2         0  0  0  0
        let m = ConfusionMatrix::from_rows(&[
            vec![5, 1, 0, 0],
            vec![2, 3, 1, 0],
            vec![0, 0, 0, 0],
            vec![0, 0, 0, 0],
        ])
        .unwrap();
        let c = m.class_counts();
        assert_eq!(c.class(0), Some((5, 2, 1)));
        assert_eq!(c.class(1), Some((3, 1, 3)));
        assert_eq!(c.class(2), Some((0, 1, 0)));
        assert_eq!(c.class(3), Some((0, 0, 0)));
        let s = c.metrics().unwrap();
        // 8 of 12 pixels correct.
        assert!((s.accuracy - 8.0 / 12.0).abs() < 1e-15);
        // Classes 0, 1, 2 present (2 only predicted), class 3 left out.
        assert_eq!(s.classes_present, 3);
        // precision: 5/7, 3/4, 0/1 ; recall: 5/6, 3/6, 0/0 -> 0 ;
        // IoU: 5/8, 3/7, 0/1.
        assert!((s.precision - (5.0 / 7.0 + 3.0 / 4.0) / 3.0).abs() < 1e-15);
        assert!((s.recall - (5.0 / 6.0 + 0.5) / 3.0).abs() < 1e-15);
        assert!((s.iou - (5.0 / 8.0 + 3.0 / 7.0) / 3.0).abs() < 1e-15);
        assert_eq!(s.pixels, 12);
    }

    #[test]
    fn pairs_match_the_matrix_and_averaging_is_per_pose() {
        let pose_a = [(0, 0), (0, 0), (1, 0)];
        let pose_b = [(1, 1)];
        let a = ClassCounts::from_pairs(2, pose_a).unwrap();
        let b = ClassCounts::from_pairs(2, pose_b).unwrap();
        let mut dense = ConfusionMatrix::new(2);
        for (r, p) in pose_a {
            dense.add(r, p).unwrap();
        }
        assert_eq!(dense.get(1, 0), 1);
        assert_eq!(dense.class_counts(), a);
        let (ma, mb) = (a.metrics().unwrap(), b.metrics().unwrap());
        // Pose a: accuracy 2/3; class 0: P 2/3, R 1, IoU 2/3; class 1: 0.
        assert!((ma.precision - 1.0 / 3.0).abs() < 1e-15);
        assert!((ma.iou - 1.0 / 3.0).abs() < 1e-15);
        // Pose b: one class, perfect.
        assert_eq!((mb.accuracy, mb.iou, mb.classes_present), (1.0, 1.0, 1));
        // Per-pose mean: accuracy (2/3 + 1) / 2; pooled: 3 of 4.
        let mean = ConsistencyMetrics::mean(&[ma, mb]).unwrap();
        assert!((mean.accuracy - 5.0 / 6.0).abs() < 1e-15);
        let mut pooled = a.clone();
        pooled.merge(&b).unwrap();
        assert!((pooled.metrics().unwrap().accuracy - 0.75).abs() < 1e-15);
        assert!(ClassCounts::new(3).metrics().is_none());
        assert_eq!(
            ClassCounts::from_pairs(2, [(0, 2)]),
            Err(ConsistencyError::ClassOutOfRange {
                class: 2,
                classes: 2
            })
        );
        assert!(pooled.merge(&ClassCounts::new(3)).is_err());
        // Two sequences: [a, b] and [b]: sequence means 5/6 and 1 -> 11/12,
        // while the flat mean over the three poses is (2/3 + 1 + 1) / 3.
        let two = mean_over_sequences(&[vec![ma, mb], vec![mb], vec![]]).unwrap();
        assert!((two.accuracy - 11.0 / 12.0).abs() < 1e-15);
        let flat = ConsistencyMetrics::mean(&[ma, mb, mb]).unwrap();
        assert!((flat.accuracy - 8.0 / 9.0).abs() < 1e-15);
    }

    #[test]
    fn frame_counting_skips_misses() {
        let (c, misses) = count_frame(3, &[0, NO_HIT, 2, 2], &[0, 1, 1, 2]).unwrap();
        assert_eq!(misses, 1);
        assert_eq!(c.class(2), Some((1, 0, 1)));
        assert_eq!(c.class(1), Some((0, 1, 0)));
        assert!((c.metrics().unwrap().accuracy - 2.0 / 3.0).abs() < 1e-15);
        assert!(count_frame(3, &[0], &[0, 1]).is_err());
        assert!(count_frame(3, &[3], &[0]).is_err());
    }
}
