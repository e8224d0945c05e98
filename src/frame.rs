//! A camera frame's per-pixel features: the one interface through which
//! mapping (input option 1, every valid depth pixel) and localization (the
//! sampler's grid and sampled pixels) read them, and the pixel geometry
//! every source shares: which cell of a coarser feature grid covers a
//! pixel, and the centre pixel of a sampling-grid cell.
//!
//! Sources: [`DenseFeatures`] (owned, one feature per pixel),
//! [`crate::mapping::FeatureMap`] (borrowed, any resolution: encoders and
//! feature files), [`LabelImage`] (labels looked up through a
//! [`LabelLookup`]: the ground-truth mode, mapping and localization alike), the simulator's
//! [`crate::experiment::SimFrameFeatures`] and
//! [`crate::experiment::GridFeatures`], and the ONNX encoders' feature maps
//! (whose cells follow the encoder's resize and crop:
//! [`crate::encode::FeatureMap::cell_of_pixel`]).

/// Per-pixel features of one image, in the map's feature space.
pub trait FrameFeatures: Sync {
    /// Image width, pixels.
    fn width(&self) -> u32;
    /// Image height, pixels.
    fn height(&self) -> u32;
    /// Feature dimension F.
    fn dim(&self) -> usize;
    /// Writes the feature of pixel `(u, v)` (any norm) into `out` (length
    /// F); zeros where nothing is known.
    fn feature(&self, u: u32, v: u32, out: &mut [f32]);
    /// The most similar database row of pixel `(u, v)`, when the source
    /// knows it without computing (a label image in ground-truth mode);
    /// `None` lets the caller compute it from [`FrameFeatures::feature`].
    fn nearest_row(&self, _u: u32, _v: u32) -> Option<u32> {
        None
    }
    /// Whether anything is known at pixel `(u, v)` (an unlabelled pixel, a
    /// pixel cropped away by the encoder): mapping skips the others.
    fn known(&self, _u: u32, _v: u32) -> bool {
        true
    }
    /// The features of every centre of the sampling grid of stride
    /// `stride` ([`grid_centre`], row-major over the grid, F each), when
    /// the source holds them contiguously already: the sampler then
    /// multiplies them where they lie instead of copying each out through
    /// [`FrameFeatures::feature`]. `None` (the default): it copies.
    fn grid_features(&self, _stride: u32) -> Option<&[f32]> {
        None
    }
}

/// How a label image's class ids become features: the row a label names
/// (the database row when mapping with a class table; the nearest map row,
/// for the sampler's clustering, when localizing) and, where the source has
/// one, the label's feature. A closure `Fn(u32) -> Option<u32>` is a lookup
/// of rows only.
pub trait LabelLookup: Sync {
    /// The row label `label` names, `None` for labels without one (those
    /// pixels are unknown: mapping skips them).
    fn row(&self, label: u32) -> Option<u32>;
    /// The feature of `label`, if the lookup has features.
    fn feature(&self, _label: u32) -> Option<&[f32]> {
        None
    }
    /// Dimension of [`LabelLookup::feature`] (0 without features).
    fn dim(&self) -> usize {
        0
    }
}

impl<F: Fn(u32) -> Option<u32> + Sync> LabelLookup for F {
    fn row(&self, label: u32) -> Option<u32> {
        self(label)
    }
}

/// A class table as a lookup: the table's own rows (a map database made
/// from the table, as ground-truth mapping makes it) and its features.
impl LabelLookup for crate::io::labels::EmbeddingTable {
    fn row(&self, label: u32) -> Option<u32> {
        self.row_index(label).map(|r| r as u32)
    }
    fn feature(&self, label: u32) -> Option<&[f32]> {
        self.row(label)
    }
    fn dim(&self) -> usize {
        self.dim
    }
}

/// A label image whose pixels hold `width x height` labels the wrong length.
#[derive(Debug, Clone, thiserror::Error, PartialEq, Eq)]
#[error("label image of {width}x{height} pixels needs {needed} labels, got {got}")]
pub struct LabelImageSize {
    pub width: u32,
    pub height: u32,
    pub needed: usize,
    pub got: usize,
}

/// A label image (row-major class ids) read through a [`LabelLookup`]: the
/// one label-image frame of mapping and localization. A pixel's feature is
/// its label's (zeros where the lookup has none), its nearest row the
/// label's row, and it is known where the label has a row.
#[derive(Clone, Copy)]
pub struct LabelImage<'a> {
    width: u32,
    height: u32,
    labels: &'a [u32],
    lookup: &'a dyn LabelLookup,
}

impl<'a> LabelImage<'a> {
    /// A `width x height` image; fails if `labels` has another length or
    /// the image is empty.
    pub fn new(
        width: u32,
        height: u32,
        labels: &'a [u32],
        lookup: &'a dyn LabelLookup,
    ) -> Result<Self, LabelImageSize> {
        let needed = width as usize * height as usize;
        if needed == 0 || labels.len() != needed {
            return Err(LabelImageSize {
                width,
                height,
                needed,
                got: labels.len(),
            });
        }
        Ok(LabelImage {
            width,
            height,
            labels,
            lookup,
        })
    }

    fn label(&self, u: u32, v: u32) -> u32 {
        self.labels[v as usize * self.width as usize + u as usize]
    }
}

impl FrameFeatures for LabelImage<'_> {
    fn width(&self) -> u32 {
        self.width
    }
    fn height(&self) -> u32 {
        self.height
    }
    fn dim(&self) -> usize {
        self.lookup.dim()
    }
    fn feature(&self, u: u32, v: u32, out: &mut [f32]) {
        match self.lookup.feature(self.label(u, v)) {
            Some(f) => out.copy_from_slice(f),
            None => out.fill(0.0),
        }
    }
    fn nearest_row(&self, u: u32, v: u32) -> Option<u32> {
        self.lookup.row(self.label(u, v))
    }
    fn known(&self, u: u32, v: u32) -> bool {
        self.nearest_row(u, v).is_some()
    }
}

/// The cell of a `cells`-long axis of a feature grid covering the centre of
/// pixel `u` of a `pixels`-long image axis (nearest cell, as an encoder's
/// output upsampled to the image is read): `floor((u + 1/2) cells /
/// pixels)`, clamped. Integer arithmetic, so equal sizes give `u` itself.
pub fn cell_of(u: u32, pixels: u32, cells: usize) -> usize {
    let c = (2 * u as u64 + 1) * cells as u64 / (2 * pixels.max(1) as u64);
    (c as usize).min(cells.saturating_sub(1))
}

/// The pixel at the centre of cell `(gx, gy)` of a sampling grid of stride
/// `s` over a `w x h` image (`(gx s + s / 2, gy s + s / 2)`, clamped to the
/// image): the grid's candidate pixels, where features are computed ahead.
pub fn grid_centre(s: u32, w: u32, h: u32, gx: u32, gy: u32) -> (u32, u32) {
    ((gx * s + s / 2).min(w - 1), (gy * s + s / 2).min(h - 1))
}

/// A dense `height x width x F` feature image, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseFeatures {
    pub width: u32,
    pub height: u32,
    pub dim: usize,
    pub data: Vec<f32>,
}

impl FrameFeatures for DenseFeatures {
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
        let i = (v as usize * self.width as usize + u as usize) * self.dim;
        match self.data.get(i..i + self.dim) {
            Some(f) => out.copy_from_slice(f),
            None => out.fill(0.0),
        }
    }
    /// Stride 1's grid is the image itself.
    fn grid_features(&self, stride: u32) -> Option<&[f32]> {
        let n = self.width as usize * self.height as usize * self.dim;
        (stride == 1 && self.data.len() == n).then_some(&self.data[..])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_of_pixel_centres() {
        // 8 pixels onto 2 cells: pixels 0-3 -> 0, 4-7 -> 1.
        let got: Vec<usize> = (0..8).map(|u| cell_of(u, 8, 2)).collect();
        assert_eq!(got, [0, 0, 0, 0, 1, 1, 1, 1]);
        // 3 pixels onto 2 cells: centres 0.5, 1.5, 2.5 of 3 -> 0.33, 1.0, 1.67.
        assert_eq!(
            (0..3).map(|u| cell_of(u, 3, 2)).collect::<Vec<_>>(),
            [0, 1, 1]
        );
        // Equal sizes: the pixel itself; past the image: the last cell.
        assert!((0..7).all(|u| cell_of(u, 7, 7) == u as usize));
        assert_eq!(cell_of(100, 8, 2), 1);
        assert_eq!(cell_of(0, 0, 0), 0);
    }

    #[test]
    fn grid_centres_clamp_to_the_image() {
        assert_eq!(grid_centre(4, 10, 6, 0, 0), (2, 2));
        assert_eq!(grid_centre(4, 10, 6, 2, 1), (9, 5));
    }
}
