//! The simulator's feature model seen through the filter's
//! [`FrameFeatures`] interface: features are computed only at the pixels
//! the filter asks for (the clustering grid and the sampled pixels), not
//! for the whole image, as an encoder running at reduced resolution would
//! not be either. [`GridFeatures`] computes them ahead of the filter step
//! (the encoder's work, timed apart), [`SimFrameFeatures`] on demand.

use super::ExperimentError;
use super::sequence::SimSequence;
use crate::frame::{FrameFeatures, grid_centre};
use crate::sim::embeddings::ClassEmbeddings;
use crate::sim::features::{FeatureModel, LabelEdges, Preset};
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
    /// Output stride of the simulated encoder: every pixel reads the
    /// feature of the centre pixel of its `s x s` block (`(u / s) s + s / 2`,
    /// clamped), as an encoder whose output map has `1 / s` of the image's
    /// resolution, upsampled by nearest neighbour, and as the feature files
    /// `omcl sim --features` writes at `--feature-stride s`. 1: every pixel
    /// its own feature.
    pub encoder_stride: u32,
    /// The frame's label edges (the pixel contexts' shortcut).
    edges: LabelEdges,
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
            encoder_stride: 1,
            edges: LabelEdges::new(frame),
        }
    }

    /// The same features seen through an encoder of output stride `s`
    /// (see [`SimFrameFeatures::encoder_stride`]; 0 counts as 1).
    pub fn with_encoder_stride(mut self, s: u32) -> Self {
        self.encoder_stride = s.max(1);
        self
    }

    /// The pixel whose feature `(u, v)` reads.
    fn source(&self, u: u32, v: u32) -> (u32, u32) {
        let s = self.encoder_stride;
        if s <= 1 {
            return (u, v);
        }
        let block = |x: u32, n: u32| ((x / s) * s + s / 2).min(n.saturating_sub(1));
        (block(u, self.frame.width), block(v, self.frame.height))
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
        let (u, v) = self.source(u, v);
        let ctx = self.model.context_near(self.frame, &self.edges, u, v);
        self.model.feature_at(self.index, u, v, &ctx, out);
    }
    fn nearest_row(&self, u: u32, v: u32) -> Option<u32> {
        let rows = self.exact_rows?;
        let (u, v) = self.source(u, v);
        let l = self.frame.labels[self.frame.index(u, v)];
        (l != NO_LABEL)
            .then(|| rows.get(l as usize).copied())
            .flatten()
    }
}

/// A frame's features at the centres of the sampling grid (stride `s`:
/// pixel `(gx s + s / 2, gy s + s / 2)`, clamped to the image), computed
/// up front as an encoder producing a feature map at reduced resolution
/// does, so the filter step that reads them does no encoder work. Pixels
/// off the grid are computed on demand.
pub struct GridFeatures<'a> {
    inner: SimFrameFeatures<'a>,
    stride: u32,
    grid_w: u32,
    features: Vec<f32>,
}

impl<'a> GridFeatures<'a> {
    /// Computes `inner`'s features at every grid centre of stride `stride`
    /// (in parallel).
    pub fn new(inner: SimFrameFeatures<'a>, stride: u32) -> Self {
        use rayon::prelude::*;
        let s = stride.max(1);
        let (w, h) = (inner.width(), inner.height());
        let (gw, gh) = (w.div_ceil(s), h.div_ceil(s));
        let dim = inner.dim();
        let mut features = vec![0.0f32; gw as usize * gh as usize * dim];
        features
            .par_chunks_mut(dim)
            .enumerate()
            .for_each(|(i, out)| {
                let (gx, gy) = (i as u32 % gw, i as u32 / gw);
                let (u, v) = grid_centre(s, w, h, gx, gy);
                inner.feature(u, v, out);
            });
        GridFeatures {
            inner,
            stride: s,
            grid_w: gw,
            features,
        }
    }

    /// The cached feature of `(u, v)` if it is a grid centre.
    fn cached(&self, u: u32, v: u32) -> Option<&[f32]> {
        let (gx, gy) = (u / self.stride, v / self.stride);
        let (w, h) = (self.inner.width(), self.inner.height());
        if grid_centre(self.stride, w, h, gx, gy) != (u, v) {
            return None;
        }
        let dim = self.inner.dim();
        let i = (gy * self.grid_w + gx) as usize * dim;
        self.features.get(i..i + dim)
    }
}

impl FrameFeatures for GridFeatures<'_> {
    fn width(&self) -> u32 {
        self.inner.width()
    }
    fn height(&self) -> u32 {
        self.inner.height()
    }
    fn dim(&self) -> usize {
        self.inner.dim()
    }
    fn feature(&self, u: u32, v: u32, out: &mut [f32]) {
        match self.cached(u, v) {
            Some(f) => out.copy_from_slice(f),
            None => self.inner.feature(u, v, out),
        }
    }
    fn nearest_row(&self, u: u32, v: u32) -> Option<u32> {
        self.inner.nearest_row(u, v)
    }
    fn grid_features(&self, stride: u32) -> Option<&[f32]> {
        (stride.max(1) == self.stride).then_some(&self.features[..])
    }
}

/// The feature model of `preset` for `seq` (`salt` separates the mapping
/// stream from the localization stream).
pub fn feature_model(seq: &SimSequence, preset: Preset, salt: u64) -> FeatureModel {
    FeatureModel::preset(
        seq.table.clone(),
        preset,
        seq.config.seed.wrapping_mul(0x9e37).wrapping_add(salt),
    )
}

/// The class table every benchmark uses: the simulator's built-in one.
pub fn builtin_table() -> Result<ClassEmbeddings, ExperimentError> {
    crate::sim::files::builtin_table()
        .map_err(|e| ExperimentError::Sim(crate::sim::dataset::SimError::Io(e)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::features::Preset;

    /// Cached and on-demand features agree at grid centres (the last
    /// column and row clamped) and off the grid.
    #[test]
    fn grid_features_equal_on_demand_features() {
        let t = crate::sim::files::builtin_table().unwrap();
        let model = FeatureModel::preset(t, Preset::LsegLike, 3);
        let (w, h) = (23u32, 10u32);
        let labels: Vec<u16> = (0..w * h)
            .map(|i| ((i % w) / 5 + i / w / 4) as u16)
            .collect();
        let n = labels.len();
        let frame = Frame {
            width: w,
            height: h,
            depth: vec![2.0; n],
            labels,
            leaves: vec![0; n],
            incidence: vec![1.0; n],
        };
        let direct = SimFrameFeatures::new(&model, Preset::LsegLike, &frame, 4, &[]);
        let grid = GridFeatures::new(
            SimFrameFeatures::new(&model, Preset::LsegLike, &frame, 4, &[]),
            4,
        );
        let (mut a, mut b) = (vec![0.0; model.dim()], vec![0.0; model.dim()]);
        let mut cached = 0;
        for v in 0..h {
            for u in 0..w {
                cached += usize::from(grid.cached(u, v).is_some());
                direct.feature(u, v, &mut a);
                grid.feature(u, v, &mut b);
                assert_eq!(a, b, "pixel ({u}, {v})");
            }
        }
        // 6 x 3 grid cells, each with one centre.
        assert_eq!(cached, 18);
        assert!(grid.cached(22, 9).is_some() && grid.cached(2, 2).is_some());
    }

    /// Through an encoder of stride 8, every pixel reads what the feature
    /// files `omcl sim --features` writes at stride 8 give it when read back
    /// (`FeatureMap`, the nearest cell): the in-memory runs and the file
    /// runs see the same features.
    #[test]
    fn encoder_stride_equals_the_written_feature_files() {
        let t = crate::sim::files::builtin_table().unwrap();
        let model = FeatureModel::preset(t, Preset::LsegLike, 5);
        let (w, h, s) = (24u32, 16u32, 8u32);
        let labels: Vec<u16> = (0..w * h)
            .map(|i| ((i % w) / 3 + i / w / 5) as u16 % 7)
            .collect();
        let n = labels.len();
        let frame = Frame {
            width: w,
            height: h,
            depth: vec![3.0; n],
            labels,
            leaves: vec![0; n],
            incidence: vec![0.7; n],
        };
        let (file, fw, fh) = model.image_features(9, &frame, s);
        let read = crate::mapping::FeatureMap::new(fh, fw, model.dim(), &file, w, h).unwrap();
        let strided =
            SimFrameFeatures::new(&model, Preset::LsegLike, &frame, 9, &[]).with_encoder_stride(s);
        let plain = SimFrameFeatures::new(&model, Preset::LsegLike, &frame, 9, &[]);
        let (mut a, mut b, mut c) = (
            vec![0.0; model.dim()],
            vec![0.0; model.dim()],
            vec![0.0; model.dim()],
        );
        let mut differs = 0;
        for v in 0..h {
            for u in 0..w {
                strided.feature(u, v, &mut a);
                read.feature(u, v, &mut b);
                assert_eq!(a, b, "pixel ({u}, {v})");
                plain.feature(u, v, &mut c);
                differs += usize::from(a != c);
            }
        }
        // Only the block centres read their own feature.
        assert_eq!(differs, (w * h - (w / s) * (h / s)) as usize);
    }
}
