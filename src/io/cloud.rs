//! The point cloud every reader returns, and the one error type of the
//! point-cloud and RGB-D readers.
//!
//! Points are `f64` metres: aerial LAS coordinates (UTM, hundreds of
//! kilometres) lose centimetres in `f32`. Per-point attributes are separate
//! columns, present or absent as a whole, so a reader allocates a handful of
//! vectors and never one per point.
//!
//! Readers never print. What a reader did to the file's data that the user
//! should know (units converted, points left out) goes into
//! [`PointCloud::notes`], for the command line to show.

use std::path::{Path, PathBuf};

use crate::geometry::Pose;
use crate::io::npy::{NpyError, read_npy};

/// Errors of the point-cloud and RGB-D readers; each names the file (or the
/// source) and what was wrong.
#[derive(Debug, thiserror::Error)]
pub enum CloudError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The file is not what its format promises (truncated, corrupt header,
    /// unparsable record, wrong size).
    #[error("{path}: {reason}")]
    Format { path: PathBuf, reason: String },
    /// A companion file disagrees with the cloud (label or feature count).
    #[error("{path}: {reason}")]
    Mismatch { path: PathBuf, reason: String },
    /// Parsed, but the values are unusable (NaN point, non-rigid pose).
    #[error("{source_name}: {reason}")]
    Invalid { source_name: String, reason: String },
    /// Nothing is left to use.
    #[error("{source_name}: empty result: {reason}")]
    Empty { source_name: String, reason: String },
    #[error(transparent)]
    Npy(#[from] NpyError),
    #[error(transparent)]
    Poses(#[from] crate::io::poses::PosesError),
}

impl CloudError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        CloudError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn format(path: &Path, reason: impl Into<String>) -> Self {
        CloudError::Format {
            path: path.to_path_buf(),
            reason: reason.into(),
        }
    }

    pub(crate) fn mismatch(path: &Path, reason: impl Into<String>) -> Self {
        CloudError::Mismatch {
            path: path.to_path_buf(),
            reason: reason.into(),
        }
    }
}

/// A point cloud with optional per-point columns.
///
/// Invariant (checked by [`PointCloud::validate`]): every present column has
/// one entry per point (`features`: `dim` values per point, point-major).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    /// Positions in metres, in the frame the producer states (readers return
    /// the file's frame; [`crate::io::kitti::KittiSequence`] returns world).
    pub points: Vec<[f64; 3]>,
    /// Per-point class ids (SemanticKITTI ids, LAS classification codes, ...).
    pub labels: Option<Vec<u32>>,
    /// Per-point sRGB colour, 8 bits a channel.
    pub colors: Option<Vec<[u8; 3]>>,
    /// Per-point features: `(dim, values)`, `values.len() == dim * len()`,
    /// row `i` at `values[i * dim..(i + 1) * dim]`.
    pub features: Option<(usize, Vec<f32>)>,
    /// What the reader changed or left out on the way from the file to
    /// these columns, one human-readable sentence each, naming the file
    /// (for example `autzen.laz: coordinates in international feet (WKT
    /// UNIT["foot",0.3048]) converted to metres`). Empty when the file was
    /// taken as it is. Library code never prints: the command line shows
    /// these to the user.
    pub notes: Vec<String>,
    /// Where in the file the points the reader left out were (withheld
    /// LAS points, PLY vertices with a non-finite coordinate), ascending: per-point data made for the whole file (a
    /// `--features` `.npy` with a row a point of the file) skips their
    /// rows ([`Self::attach_features_npy`]). Empty when none were.
    pub left_out: Vec<usize>,
    /// The CRS the file states (LAS/LAZ), kept for the map built from it;
    /// `None` for a local frame.
    pub georef: Option<crate::map::Georef>,
}

impl PointCloud {
    /// A cloud of bare points.
    pub fn from_points(points: Vec<[f64; 3]>) -> Self {
        PointCloud {
            points,
            ..Default::default()
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Feature dimension, if features are present.
    pub fn feature_dim(&self) -> Option<usize> {
        self.features.as_ref().map(|(d, _)| *d)
    }

    /// Checks column lengths and that every coordinate is finite. `source`
    /// names the origin (a path) in the error.
    pub fn validate(&self, source: &str) -> Result<(), CloudError> {
        let invalid = |reason: String| CloudError::Invalid {
            source_name: source.to_string(),
            reason,
        };
        let n = self.points.len();
        if let Some(l) = &self.labels
            && l.len() != n
        {
            return Err(invalid(format!("{} labels for {n} points", l.len())));
        }
        if let Some(c) = &self.colors
            && c.len() != n
        {
            return Err(invalid(format!("{} colours for {n} points", c.len())));
        }
        if let Some((dim, f)) = &self.features {
            if *dim == 0 {
                return Err(invalid("feature dimension 0".into()));
            }
            if f.len() != dim * n {
                return Err(invalid(format!(
                    "{} feature values for {n} points of dimension {dim} (expected {})",
                    f.len(),
                    dim * n
                )));
            }
        }
        check_points(source, &self.points, 0)
    }

    /// Maps every point through `target_from_source` (for example
    /// `world_from_lidar`).
    pub fn transform(&mut self, target_from_source: &Pose) {
        let m = target_from_source.to_homogeneous();
        for p in &mut self.points {
            let [x, y, z] = *p;
            *p = [
                m[(0, 0)] * x + m[(0, 1)] * y + m[(0, 2)] * z + m[(0, 3)],
                m[(1, 0)] * x + m[(1, 1)] * y + m[(1, 2)] * z + m[(1, 3)],
                m[(2, 0)] * x + m[(2, 1)] * y + m[(2, 2)] * z + m[(2, 3)],
            ];
        }
    }

    /// Keeps the points for which `keep(index)` is true, in order, with all
    /// their columns (and every note).
    pub fn retain_indices(&mut self, mut keep: impl FnMut(usize) -> bool) {
        // The points are no longer the file's but for those left out.
        self.left_out.clear();
        let mask: Vec<bool> = (0..self.len()).map(&mut keep).collect();
        let mut it = mask.iter();
        self.points.retain(|_| *it.next().unwrap_or(&false));
        if let Some(l) = &mut self.labels {
            let mut it = mask.iter();
            l.retain(|_| *it.next().unwrap_or(&false));
        }
        if let Some(c) = &mut self.colors {
            let mut it = mask.iter();
            c.retain(|_| *it.next().unwrap_or(&false));
        }
        if let Some((dim, f)) = &mut self.features {
            let dim = *dim;
            let mut w = 0;
            for (i, &k) in mask.iter().enumerate() {
                if k {
                    f.copy_within(i * dim..(i + 1) * dim, w * dim);
                    w += 1;
                }
            }
            f.truncate(w * dim);
        }
    }

    /// Appends `other`. A column is kept only when both clouds have it
    /// (features also need equal dimensions); otherwise it is dropped, because
    /// a half-filled column would break the length invariant. Notes of both
    /// are kept, `self`'s first.
    pub fn append(&mut self, mut other: PointCloud) {
        // Two files' points: no longer one file's but for those left out.
        self.left_out.clear();
        other.left_out.clear();
        let was_empty = self.is_empty();
        if was_empty {
            let mut notes = std::mem::take(&mut self.notes);
            notes.append(&mut other.notes);
            *self = other;
            self.notes = notes;
            return;
        }
        self.notes.append(&mut other.notes);
        self.points.extend_from_slice(&other.points);
        self.labels = match (self.labels.take(), other.labels) {
            (Some(mut a), Some(b)) => {
                a.extend_from_slice(&b);
                Some(a)
            }
            _ => None,
        };
        self.colors = match (self.colors.take(), other.colors) {
            (Some(mut a), Some(b)) => {
                a.extend_from_slice(&b);
                Some(a)
            }
            _ => None,
        };
        self.features = match (self.features.take(), other.features) {
            (Some((da, mut a)), Some((db, b))) if da == db => {
                a.extend_from_slice(&b);
                Some((da, a))
            }
            _ => None,
        };
    }

    /// Attaches per-point features from an `N x F` `.npy` file (for example
    /// OpenScene features computed elsewhere). The row count must equal the
    /// number of points.
    pub fn attach_features_npy(&mut self, path: &Path) -> Result<(), CloudError> {
        let arr = read_npy(path)?;
        if arr.shape.len() != 2 {
            return Err(CloudError::mismatch(
                path,
                format!(
                    "per-point features must be a 2-D N x F array, got shape {:?}",
                    arr.shape
                ),
            ));
        }
        let (rows, dim) = (arr.shape[0], arr.shape[1]);
        // A row a point of the file: the rows of points the reader left
        // out go with them.
        let of_file = !self.left_out.is_empty() && rows == self.len() + self.left_out.len();
        if rows != self.len() && !of_file {
            let left_out = match self.left_out.len() {
                0 => String::new(),
                k => format!(
                    " ({} in the file; {k} left out by the reader)",
                    self.len() + k
                ),
            };
            return Err(CloudError::mismatch(
                path,
                format!(
                    "{rows} feature rows for a cloud of {} points{left_out} (shape {:?})",
                    self.len(),
                    arr.shape
                ),
            ));
        }
        if dim == 0 {
            return Err(CloudError::mismatch(path, "feature dimension is 0"));
        }
        if let Some(i) = arr.data.iter().position(|v| !v.is_finite()) {
            return Err(CloudError::format(
                path,
                format!("feature value of point {} is not finite", i / dim),
            ));
        }
        let data = if of_file {
            let mut skip = self.left_out.iter().peekable();
            arr.data
                .chunks_exact(dim)
                .enumerate()
                .filter(|(i, _)| {
                    let out = skip.peek() == Some(&i);
                    if out {
                        skip.next();
                    }
                    !out
                })
                .flat_map(|(_, r)| r.iter().copied())
                .collect()
        } else {
            arr.data
        };
        self.features = Some((dim, data));
        Ok(())
    }

    /// Fails with [`CloudError::Empty`] when the cloud has no points; for
    /// results that went through filters.
    pub fn non_empty(self, source: &str, reason: &str) -> Result<Self, CloudError> {
        if self.is_empty() {
            Err(CloudError::Empty {
                source_name: source.to_string(),
                reason: reason.to_string(),
            })
        } else {
            Ok(self)
        }
    }
}

/// Checks that every coordinate of `points` is finite and within
/// [`crate::geometry::MAX_COORDINATE_M`] of 0; `first` is the index of
/// `points[0]` in its cloud (for the error, which names `source`).
pub fn check_points(source: &str, points: &[[f64; 3]], first: u64) -> Result<(), CloudError> {
    // One pass: a NaN or an infinity is not within the bound either.
    let far = crate::geometry::MAX_COORDINATE_M;
    let Some(i) = points
        .iter()
        .position(|p| p.iter().any(|&v| !(v.is_finite() && v.abs() <= far)))
    else {
        return Ok(());
    };
    let p = points[i];
    let why = if p.iter().all(|v| v.is_finite()) {
        format!(
            "lies at ({}, {}, {}), farther than {far:e} m from 0 in a coordinate, \
             beyond what a map can hold (a LAS file's scale or offset wrong?)",
            p[0], p[1], p[2]
        )
    } else {
        format!("is not finite: ({}, {}, {})", p[0], p[1], p[2])
    };
    Err(CloudError::Invalid {
        source_name: source.to_string(),
        reason: format!("point {} {why}", first + i as u64),
    })
}

/// Voxel down-sampling: keeps the first point of every cubic cell of edge
/// `resolution` metres (cells `floor(p / resolution)`), with its columns.
/// Keeping a real point (not a centroid) keeps labels and colours meaningful.
pub fn voxel_downsample(cloud: &mut PointCloud, resolution: f64) {
    let mut seen = rustc_hash::FxHashSet::default();
    seen.reserve(cloud.len() / 4);
    let inv = 1.0 / resolution;
    let keep: Vec<bool> = cloud
        .points
        .iter()
        .map(|p| {
            let key = (
                (p[0] * inv).floor() as i64,
                (p[1] * inv).floor() as i64,
                (p[2] * inv).floor() as i64,
            );
            seen.insert(key)
        })
        .collect();
    cloud.retain_indices(|i| keep[i]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    fn cloud3() -> PointCloud {
        PointCloud {
            points: vec![[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [0.05, 0.05, 0.05]],
            labels: Some(vec![1, 2, 3]),
            colors: Some(vec![[1, 1, 1], [2, 2, 2], [3, 3, 3]]),
            features: Some((2, vec![0.0, 0.1, 1.0, 1.1, 2.0, 2.1])),
            notes: vec!["c: a note".into()],
            left_out: Vec::new(),
            georef: None,
        }
    }

    #[test]
    fn validate_names_source_and_index() {
        let mut c = cloud3();
        assert!(c.validate("x").is_ok());
        c.points[1][2] = f64::NAN;
        let e = c.validate("scan.ply").unwrap_err().to_string();
        assert!(e.contains("scan.ply") && e.contains("point 1"), "{e}");
        let mut c = cloud3();
        c.labels.as_mut().unwrap().pop();
        let e = c.validate("a.las").unwrap_err().to_string();
        assert!(e.contains("2 labels for 3 points"), "{e}");
        let mut c = cloud3();
        c.features.as_mut().unwrap().1.pop();
        assert!(c.validate("f").is_err());
        // Beyond any map (a PLY at x = 1e12 was mapped, and the map file
        // then refused by every reader); at the bound it is a point.
        let mut c = cloud3();
        c.points[2][0] = -1e9;
        assert!(c.validate("x").is_ok());
        c.points[2][0] = 1e12;
        let e = c.validate("far.ply").unwrap_err().to_string();
        assert!(
            e.contains("far.ply") && e.contains("point 2") && e.contains("1e9"),
            "{e}"
        );
    }

    #[test]
    fn retain_keeps_columns_aligned() {
        let mut c = cloud3();
        c.retain_indices(|i| i != 1);
        assert_eq!(c.points, vec![[0.0, 0.0, 0.0], [0.05, 0.05, 0.05]]);
        assert_eq!(c.labels, Some(vec![1, 3]));
        assert_eq!(c.colors, Some(vec![[1, 1, 1], [3, 3, 3]]));
        assert_eq!(c.features, Some((2, vec![0.0, 0.1, 2.0, 2.1])));
    }

    #[test]
    fn downsample_keeps_first_point_per_cell() {
        let mut c = cloud3();
        voxel_downsample(&mut c, 0.1);
        // Points 0 and 2 share cell (0,0,0).
        assert_eq!(c.labels, Some(vec![1, 2]));
    }

    #[test]
    fn transform_applies_rotation_then_translation() {
        let mut c = PointCloud::from_points(vec![[1.0, 0.0, 0.0]]);
        let pose = Pose::from_parts(
            Translation3::new(10.0, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
        );
        c.transform(&pose);
        let p = c.points[0];
        assert!((p[0] - 10.0).abs() < 1e-12 && (p[1] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn append_drops_columns_missing_on_one_side() {
        let mut a = cloud3();
        let mut b = cloud3();
        b.colors = None;
        a.append(b);
        assert_eq!(a.len(), 6);
        assert!(a.colors.is_none());
        assert_eq!(a.labels.as_ref().map(Vec::len), Some(6));
        assert!(a.validate("a").is_ok());
        assert_eq!(a.notes.len(), 2, "{:?}", a.notes);
    }

    #[test]
    fn append_to_an_empty_cloud_keeps_both_notes() {
        let mut a = PointCloud {
            notes: vec!["a: first".into()],
            ..Default::default()
        };
        a.append(cloud3());
        assert_eq!(a.len(), 3);
        assert_eq!(a.notes, vec!["a: first".to_string(), "c: a note".into()]);
    }
}
