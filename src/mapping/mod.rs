//! Building maps: the paper's two input options, fed into
//! [`crate::map::Integrator`], and the colours used to look at the result.
//!
//! - Option 1, posed RGB-D ([`rgbd`]): depth back-projected with the
//!   intrinsics and `world_from_camera`, each valid pixel's feature added to
//!   the voxel it falls in.
//! - Option 2, point clouds ([`cloud`]): each point's feature (or label row)
//!   added to its voxel.
//!
//! The pipelines users run read the inputs: [`pipeline`] (a cloud read
//! whole, a SemanticKITTI sequence scan by scan, RGB-D frames) and
//! [`tiles`] (LAS/LAZ files and folders of tiles a batch at a time).
//!
//! Frames give features through [`FrameFeatures`], points one [`Feature`] each: a row of
//! a fixed table (labels with an embedding table: the ground-truth mode) or
//! a feature vector (feature files, encoders). No I/O here.

pub mod cloud;
pub mod colors;
pub mod pipeline;
pub mod projection;
pub mod rgbd;
pub mod tiles;

/// Errors of the mapping front doors: inputs whose sizes disagree, and the
/// feature database's own errors.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MappingError {
    #[error(transparent)]
    Db(#[from] crate::map::FeatureDbError),
    #[error("depth image has {got} values, the intrinsics say {width} x {height} = {want}")]
    DepthSize {
        got: usize,
        want: usize,
        width: u32,
        height: u32,
    },
    #[error("feature map is {h} x {w} x {dim}: every extent must be at least 1")]
    EmptyFeatureMap { h: u32, w: u32, dim: usize },
    #[error("feature map of {h} x {w} x {dim} needs {want} values, got {got}")]
    FeatureMapSize {
        h: u32,
        w: u32,
        dim: usize,
        want: usize,
        got: usize,
    },
    #[error("image size {width} x {height}: both must be at least 1")]
    EmptyImage { width: u32, height: u32 },
}

/// The feature of one pixel or point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Feature<'a> {
    /// A row of the integrator's observation database (label mode).
    Row(u32),
    /// A feature vector, quantized by the integrator's admission rule.
    Vector(&'a [f32]),
    /// Nothing known here (unlabelled, unknown class): skipped.
    Unknown,
}

pub use crate::frame::FrameFeatures;

/// The feature pixel `(u, v)` of `f` adds to its voxel: the row the source
/// names, else its vector (copied into `buf`, of length `f.dim()`), or
/// nothing where the source knows nothing.
pub fn pixel_feature<'b>(f: &dyn FrameFeatures, u: u32, v: u32, buf: &'b mut [f32]) -> Feature<'b> {
    if !f.known(u, v) {
        return Feature::Unknown;
    }
    if let Some(r) = f.nearest_row(u, v) {
        return Feature::Row(r);
    }
    f.feature(u, v, buf);
    Feature::Vector(buf)
}

pub use crate::frame::{LabelImage, LabelLookup};

/// A dense `h x w x dim` feature map, possibly smaller than the depth image
/// (encoders often work at reduced resolution): pixel `(u, v)` of a
/// `width x height` image reads the feature-map cell covering its centre.
pub struct FeatureMap<'a> {
    pub h: u32,
    pub w: u32,
    pub dim: usize,
    pub data: &'a [f32],
    /// Size of the image the features describe.
    pub width: u32,
    pub height: u32,
}

impl<'a> FeatureMap<'a> {
    /// A feature map of `h x w x dim` values describing a `width x height`
    /// image; every extent must be at least 1 and `data` hold exactly the
    /// map's values.
    pub fn new(
        h: u32,
        w: u32,
        dim: usize,
        data: &'a [f32],
        width: u32,
        height: u32,
    ) -> Result<Self, MappingError> {
        if h == 0 || w == 0 || dim == 0 {
            return Err(MappingError::EmptyFeatureMap { h, w, dim });
        }
        if width == 0 || height == 0 {
            return Err(MappingError::EmptyImage { width, height });
        }
        let want = (h as usize)
            .checked_mul(w as usize)
            .and_then(|n| n.checked_mul(dim));
        if want != Some(data.len()) {
            return Err(MappingError::FeatureMapSize {
                h,
                w,
                dim,
                want: want.unwrap_or(usize::MAX),
                got: data.len(),
            });
        }
        Ok(FeatureMap {
            h,
            w,
            dim,
            data,
            width,
            height,
        })
    }
}

impl FeatureMap<'_> {
    /// The features of the cell covering pixel `(u, v)`'s centre
    /// ([`crate::frame::cell_of`]); `None` for a map without cells (the
    /// fields are public: one built without `new`).
    fn cell(&self, u: u32, v: u32) -> Option<&[f32]> {
        if self.h == 0 || self.w == 0 {
            return None;
        }
        let fu = crate::frame::cell_of(u, self.width, self.w as usize);
        let fv = crate::frame::cell_of(v, self.height, self.h as usize);
        let i = (fv * self.w as usize + fu) * self.dim;
        self.data.get(i..i + self.dim)
    }
}

impl FrameFeatures for FeatureMap<'_> {
    fn width(&self) -> u32 {
        self.width
    }
    fn height(&self) -> u32 {
        self.height
    }
    fn dim(&self) -> usize {
        self.dim
    }
    fn feature(&self, u: u32, v: u32, out: &mut [f32]) {
        match self.cell(u, v) {
            Some(f) => out.copy_from_slice(f),
            None => out.fill(0.0),
        }
    }
    fn known(&self, u: u32, v: u32) -> bool {
        self.cell(u, v).is_some()
    }
}

/// What an integration pass did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct IntegrationStats {
    /// Points or pixels offered.
    pub offered: usize,
    /// Added to a voxel.
    pub integrated: usize,
    /// Skipped: no feature, invalid depth, outside the depth or height crop.
    pub skipped: usize,
    /// Rejected by the integrator: non-finite or out of the grid's range.
    pub rejected: usize,
}

impl IntegrationStats {
    /// Adds one observation at world point `p` to `integ` and counts it.
    pub(crate) fn add(
        &mut self,
        integ: &mut crate::map::Integrator,
        p: &nalgebra::Vector3<f64>,
        feature: Feature<'_>,
    ) -> Result<(), crate::map::FeatureDbError> {
        let ok = match feature {
            Feature::Row(r) => integ.add_row(p, r),
            Feature::Vector(f) => integ.add_feature(p, f)?,
            Feature::Unknown => {
                self.skipped += 1;
                return Ok(());
            }
        };
        if ok {
            self.integrated += 1;
        } else {
            self.rejected += 1;
        }
        Ok(())
    }
}

impl std::ops::AddAssign for IntegrationStats {
    fn add_assign(&mut self, o: Self) {
        self.offered += o.offered;
        self.integrated += o.integrated;
        self.skipped += o.skipped;
        self.rejected += o.rejected;
    }
}
