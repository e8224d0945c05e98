//! The simulator's feature model seen through the filter's
//! [`FrameFeatures`] interface: features are computed only at the pixels
//! the filter asks for (the clustering grid and the sampled pixels), not
//! for the whole image, as an encoder running at reduced resolution would
//! not be either.

use crate::mcl::FrameFeatures;
use crate::sim::features::{FeatureModel, Preset};
use crate::sim::render::{Frame, NO_LABEL};

/// One rendered frame's features from a [`FeatureModel`].
pub struct SimFrameFeatures<'a> {
    pub model: &'a FeatureModel,
    pub frame: &'a Frame,
    /// Frame index (the model's draws depend on it).
    pub index: u64,
    /// For the error-free preset: the map row of every class, so the
    /// sampler needs no dot products (as with label images).
    pub exact_rows: Option<&'a [u32]>,
}

impl<'a> SimFrameFeatures<'a> {
    /// Features of `frame` (index `index`) from `model`; `class_rows` maps
    /// class ids to map rows and is used only when `preset` is exact.
    pub fn new(
        model: &'a FeatureModel,
        preset: Preset,
        frame: &'a Frame,
        index: u64,
        class_rows: &'a [u32],
    ) -> Self {
        SimFrameFeatures {
            model,
            frame,
            index,
            exact_rows: (preset == Preset::Exact).then_some(class_rows),
        }
    }
}

impl FrameFeatures for SimFrameFeatures<'_> {
    fn width(&self) -> u32 {
        self.frame.width
    }
    fn height(&self) -> u32 {
        self.frame.height
    }
    fn dim(&self) -> usize {
        self.model.dim()
    }
    fn feature(&self, u: u32, v: u32, out: &mut [f32]) {
        let ctx = self.model.context(self.frame, u, v);
        self.model.feature_at(self.index, u, v, &ctx, out);
    }
    fn nearest_row(&self, u: u32, v: u32) -> Option<u32> {
        let rows = self.exact_rows?;
        let l = self.frame.labels[self.frame.index(u, v)];
        (l != NO_LABEL)
            .then(|| rows.get(l as usize).copied())
            .flatten()
    }
}
