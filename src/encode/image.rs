//! Image encoder: an RGB image to a grid of per-pixel language features
//! (LSeg, X-Decoder, NARADIO, ... exported to ONNX).
//!
//! The feature map is kept at the model's output resolution, not upsampled
//! to the image: a 640 x 480 image with 512-d features would take 630 MB as
//! `f32`, while pipelines only read the features of sampled or depth-valid
//! pixels. [`FeatureMap::at_pixel`] maps an image pixel to its cell.

use std::path::Path;

use image::RgbImage;

use super::card::{ImageSpec, Layout, ModelCard, ModelKind, Resize};
use super::preprocess::{self, normalize_chw, normalize_hwc};
use super::runtime::{InputData, OnnxModel};
use super::{EncodeError, ensure_feature_dim, normalize_in_place};

/// Per-pixel features of one image: `height` x `width` cells of `dim`
/// values each, row-major (`data[(row * width + col) * dim + k]`), placed
/// on the image by `origin` and `cell_size` (image pixels, x right, y
/// down; pixel (u, v) covers [u, u+1) x [v, v+1)).
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureMap {
    pub height: usize,
    pub width: usize,
    pub dim: usize,
    pub data: Vec<f32>,
    /// Image coordinates (x, y) of the top-left corner of cell (0, 0).
    pub origin: [f32; 2],
    /// Width and height of one cell, in image pixels.
    pub cell_size: [f32; 2],
}

impl FeatureMap {
    /// The feature of cell (`row`, `col`).
    pub fn cell(&self, row: usize, col: usize) -> Option<&[f32]> {
        if row < self.height && col < self.width {
            let i = (row * self.width + col) * self.dim;
            Some(&self.data[i..i + self.dim])
        } else {
            None
        }
    }

    /// The cell (row, col) holding the centre of image pixel (`u`, `v`),
    /// or `None` when the pixel lies outside the map (e.g. cropped away).
    pub fn cell_of_pixel(&self, u: u32, v: u32) -> Option<(usize, usize)> {
        let x = (u as f32 + 0.5 - self.origin[0]) / self.cell_size[0];
        let y = (v as f32 + 0.5 - self.origin[1]) / self.cell_size[1];
        if x < 0.0 || y < 0.0 {
            return None;
        }
        let (col, row) = (x.floor() as usize, y.floor() as usize);
        (row < self.height && col < self.width).then_some((row, col))
    }

    /// The feature seen at image pixel (`u`, `v`) (nearest cell).
    pub fn at_pixel(&self, u: u32, v: u32) -> Option<&[f32]> {
        self.cell_of_pixel(u, v).and_then(|(r, c)| self.cell(r, c))
    }

    /// Shape `[height, width, dim]`, as written to `.npy`.
    pub fn shape(&self) -> [usize; 3] {
        [self.height, self.width, self.dim]
    }
}

/// An encoded frame as a feature source of mapping and localization (its
/// cells follow the encoder's resize and crop; image size from the
/// intrinsics).
pub struct EncodedFrame<'a> {
    pub map: &'a FeatureMap,
    pub width: u32,
    pub height: u32,
}

impl crate::frame::FrameFeatures for EncodedFrame<'_> {
    fn width(&self) -> u32 {
        self.width
    }
    fn height(&self) -> u32 {
        self.height
    }
    fn dim(&self) -> usize {
        self.map.dim
    }
    fn feature(&self, u: u32, v: u32, out: &mut [f32]) {
        match self.map.at_pixel(u, v) {
            Some(f) => out.copy_from_slice(f),
            None => out.fill(0.0),
        }
    }
    fn known(&self, u: u32, v: u32) -> bool {
        self.map.at_pixel(u, v).is_some()
    }
}

/// Builds the encoder's image type from rows of RGB pixels (as
/// `io::rgbd::RgbImage` holds them); `None` if the count is not
/// `width * height`.
pub fn rgb_from_pixels(width: u32, height: u32, pixels: &[[u8; 3]]) -> Option<RgbImage> {
    if pixels.len() != width as usize * height as usize {
        return None;
    }
    RgbImage::from_raw(width, height, pixels.iter().flatten().copied().collect())
}

/// An ONNX image encoder with its model card.
pub struct ImageEncoder {
    model: OnnxModel,
    card: ModelCard,
    spec: ImageSpec,
    input: String,
    output: String,
}

/// The image as the model sees it, with how it sits on the original.
struct Prepared {
    width: usize,
    height: usize,
    /// Normalised values in the card's input layout (no batch axis).
    values: Vec<f32>,
    /// Original-image pixels per prepared pixel, x and y.
    scale: [f32; 2],
    /// Top-left of the prepared image in original-image pixels.
    origin: [f32; 2],
}

impl super::Encoder for ImageEncoder {
    const KIND: ModelKind = ModelKind::Image;
    type Spec = ImageSpec;

    fn spec(card: &ModelCard) -> Option<&ImageSpec> {
        card.image.as_ref()
    }

    fn from_parts(
        model: &Path,
        card: ModelCard,
        spec: ImageSpec,
        onnx: OnnxModel,
    ) -> Result<ImageEncoder, EncodeError> {
        let input = onnx.input(spec.input.as_deref())?;
        if input.dims.len() != 4 {
            return Err(EncodeError::Contract {
                path: model.to_path_buf(),
                reason: format!(
                    "image input `{}` has shape {}, expected 4 axes ({:?})",
                    input.name,
                    input.dims_text(),
                    spec.layout
                ),
            });
        }
        let input = input.name.clone();
        let output = onnx.output(spec.output.as_deref())?.name.clone();
        Ok(ImageEncoder {
            model: onnx,
            card,
            spec,
            input,
            output,
        })
    }
}

impl ImageEncoder {
    /// The model card.
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// Length of each per-pixel feature.
    pub fn feature_dim(&self) -> usize {
        self.card.feature_dim
    }

    /// The model file.
    pub fn model_path(&self) -> &Path {
        self.model.path()
    }

    /// Encodes one RGB image into per-pixel features.
    pub fn encode(&mut self, img: &RgbImage) -> Result<FeatureMap, EncodeError> {
        if img.width() == 0 || img.height() == 0 {
            return Err(EncodeError::Input("empty image (0 pixels)".into()));
        }
        let mut prepared = prepare(img, &self.spec).ok_or_else(|| {
            EncodeError::Input(format!(
                "image of {}x{} is too small for the card's resize/crop",
                img.width(),
                img.height()
            ))
        })?;
        let grid = match self.spec.window {
            None => self.run_whole(&mut prepared)?,
            Some(w) => self.run_windows(&prepared, w)?,
        };
        let Grid {
            mut data,
            rows,
            cols,
            cell,
        } = grid;
        if self.card.normalize {
            data.chunks_exact_mut(self.card.feature_dim)
                .for_each(normalize_in_place);
        }
        Ok(FeatureMap {
            height: rows,
            width: cols,
            dim: self.card.feature_dim,
            data,
            origin: prepared.origin,
            cell_size: [cell[0] * prepared.scale[0], cell[1] * prepared.scale[1]],
        })
    }

    fn input_shape(&self, w: usize, h: usize) -> [usize; 4] {
        match self.spec.layout {
            Layout::Nchw => [1, 3, h, w],
            Layout::Nhwc => [1, h, w, 3],
        }
    }

    /// Runs the model once and returns its output as (rows, cols, H x W x F).
    fn run_model(
        &mut self,
        values: Vec<f32>,
        w: usize,
        h: usize,
    ) -> Result<(usize, usize, Vec<f32>), EncodeError> {
        let shape = self.input_shape(w, h);
        let out = self.model.run(
            vec![(self.input.as_str(), &shape[..], InputData::F32(values))],
            &[&self.output],
        )?;
        let out = out
            .into_iter()
            .next()
            .ok_or_else(|| EncodeError::Contract {
                path: self.model.path().to_path_buf(),
                reason: "model returned no output".into(),
            })?;
        let path = self.model.path().to_path_buf();
        let expected = match self.spec.output_layout {
            Layout::Nchw => "[1, F, h, w] (output_layout nchw)",
            Layout::Nhwc => "[1, h, w, F] (output_layout nhwc)",
        };
        if out.shape.len() != 4 || out.shape[0] != 1 {
            return Err(EncodeError::Shape {
                path,
                what: format!("output `{}`", self.output),
                got: out.shape,
                expected: expected.into(),
            });
        }
        let (f, oh, ow) = match self.spec.output_layout {
            Layout::Nchw => (out.shape[1], out.shape[2], out.shape[3]),
            Layout::Nhwc => (out.shape[3], out.shape[1], out.shape[2]),
        };
        ensure_feature_dim(
            &path.display().to_string(),
            f,
            "its model card",
            self.card.feature_dim,
        )?;
        let hwc = match self.spec.output_layout {
            Layout::Nhwc => out.data,
            Layout::Nchw => {
                let plane = oh * ow;
                let mut v = vec![0f32; out.data.len()];
                for k in 0..f {
                    for i in 0..plane {
                        v[i * f + k] = out.data[k * plane + i];
                    }
                }
                v
            }
        };
        Ok((oh, ow, hwc))
    }

    fn run_whole(&mut self, p: &mut Prepared) -> Result<Grid, EncodeError> {
        // The model consumes the values; `p` keeps only its geometry after.
        let values = std::mem::take(&mut p.values);
        let (oh, ow, data) = self.run_model(values, p.width, p.height)?;
        Ok(Grid {
            data,
            rows: oh,
            cols: ow,
            cell: [p.width as f32 / ow as f32, p.height as f32 / oh as f32],
        })
    }

    fn run_windows(&mut self, p: &Prepared, win: super::card::Window) -> Result<Grid, EncodeError> {
        let (ww, wh) = (win.width as usize, win.height as usize);
        let (sx, sy) = (win.stride_x as usize, win.stride_y as usize);
        let xs = window_starts(p.width, ww, sx);
        let ys = window_starts(p.height, wh, sy);
        let padded_w = xs.last().copied().unwrap_or(0) + ww;
        let padded_h = ys.last().copied().unwrap_or(0) + wh;
        let f = self.card.feature_dim;
        let mut sum: Vec<f32> = Vec::new();
        let mut count: Vec<u32> = Vec::new();
        let mut ratio = (0usize, 0usize);
        for &y0 in &ys {
            for &x0 in &xs {
                let values = window_values(p, self.spec.layout, x0, y0, ww, wh);
                let (oh, ow, out) = self.run_model(values, ww, wh)?;
                if sum.is_empty() {
                    ratio = self.check_window_ratio(ww, wh, sx, sy, ow, oh)?;
                    sum = vec![0f32; (padded_h / ratio.1) * (padded_w / ratio.0) * f];
                    count = vec![0u32; (padded_h / ratio.1) * (padded_w / ratio.0)];
                }
                let gw = padded_w / ratio.0;
                let (cx, cy) = (x0 / ratio.0, y0 / ratio.1);
                for r in 0..oh {
                    for c in 0..ow {
                        let g = (cy + r) * gw + cx + c;
                        count[g] += 1;
                        let src = &out[(r * ow + c) * f..(r * ow + c + 1) * f];
                        sum[g * f..(g + 1) * f]
                            .iter_mut()
                            .zip(src)
                            .for_each(|(s, &v)| *s += v);
                    }
                }
            }
        }
        // Keep only cells that touch the real image, not the padding.
        let rows = p.height.div_ceil(ratio.1);
        let cols = p.width.div_ceil(ratio.0);
        let gw = padded_w / ratio.0;
        let mut data = Vec::with_capacity(rows * cols * f);
        for r in 0..rows {
            for c in 0..cols {
                let g = r * gw + c;
                let n = count[g].max(1) as f32;
                data.extend(sum[g * f..(g + 1) * f].iter().map(|&s| s / n));
            }
        }
        Ok(Grid {
            data,
            rows,
            cols,
            cell: [ratio.0 as f32, ratio.1 as f32],
        })
    }

    /// Windows must map onto whole output cells so overlaps line up.
    fn check_window_ratio(
        &self,
        ww: usize,
        wh: usize,
        sx: usize,
        sy: usize,
        ow: usize,
        oh: usize,
    ) -> Result<(usize, usize), EncodeError> {
        let ok = ow > 0 && oh > 0 && ww.is_multiple_of(ow) && wh.is_multiple_of(oh);
        let (rx, ry) = if ok { (ww / ow, wh / oh) } else { (0, 0) };
        if !ok || !sx.is_multiple_of(rx) || !sy.is_multiple_of(ry) {
            return Err(EncodeError::Contract {
                path: self.model.path().to_path_buf(),
                reason: format!(
                    "a {ww}x{wh} window gives a {ow}x{oh} feature map; window and stride \
                     ({sx}, {sy}) must be whole multiples of the output stride"
                ),
            });
        }
        Ok((rx, ry))
    }
}

struct Grid {
    data: Vec<f32>,
    rows: usize,
    cols: usize,
    /// Prepared-image pixels per output cell, x and y.
    cell: [f32; 2],
}

/// Window start positions covering `len` with windows of `win` every
/// `stride`; the last window may hang over the end (padding fills it).
pub fn window_starts(len: usize, win: usize, stride: usize) -> Vec<usize> {
    let mut starts = vec![0];
    while starts.last().copied().unwrap_or(0) + win < len {
        let next = starts.last().copied().unwrap_or(0) + stride.max(1);
        starts.push(next);
    }
    starts
}

/// The normalised values of one window, zero-padded past the image.
fn window_values(
    p: &Prepared,
    layout: Layout,
    x0: usize,
    y0: usize,
    ww: usize,
    wh: usize,
) -> Vec<f32> {
    let mut v = vec![0f32; 3 * ww * wh];
    let rows = wh.min(p.height.saturating_sub(y0));
    let cols = ww.min(p.width.saturating_sub(x0));
    for r in 0..rows {
        for c in 0..cols {
            for k in 0..3 {
                let (src, dst) = match layout {
                    Layout::Nchw => (
                        k * p.height * p.width + (y0 + r) * p.width + x0 + c,
                        k * wh * ww + r * ww + c,
                    ),
                    Layout::Nhwc => (((y0 + r) * p.width + x0 + c) * 3 + k, (r * ww + c) * 3 + k),
                };
                v[dst] = p.values[src];
            }
        }
    }
    v
}

/// Resizes, crops and normalises per the card.
fn prepare(img: &RgbImage, spec: &ImageSpec) -> Option<Prepared> {
    let (w0, h0) = (img.width(), img.height());
    let (rw, rh) = match spec.resize {
        Resize::None => (w0, h0),
        Resize::Fixed { width, height } => (width, height),
        Resize::ShorterSide { size } => preprocess::shorter_side_size(w0, h0, size),
        Resize::LongerSide { size } => preprocess::longer_side_size(w0, h0, size),
    };
    let resized = if (rw, rh) == (w0, h0) {
        img.clone()
    } else {
        preprocess::resize(img, rw, rh, spec.filter)?
    };
    let scale = [w0 as f32 / rw as f32, h0 as f32 / rh as f32];
    let (img2, off) = match spec.center_crop {
        None => (resized, [0u32, 0u32]),
        Some([cw, ch]) => {
            let x0 = preprocess::center_crop_offset(rw, cw);
            let y0 = preprocess::center_crop_offset(rh, ch);
            (preprocess::crop(&resized, x0, y0, cw, ch)?, [x0, y0])
        }
    };
    let values = match spec.layout {
        Layout::Nchw => normalize_chw(&img2, spec.mean, spec.std),
        Layout::Nhwc => normalize_hwc(&img2, spec.mean, spec.std),
    };
    Some(Prepared {
        width: img2.width() as usize,
        height: img2.height() as usize,
        values,
        scale,
        origin: [off[0] as f32 * scale[0], off[1] as f32 * scale[1]],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_convert_row_major() {
        let px = [
            [1, 2, 3],
            [4, 5, 6],
            [7, 8, 9],
            [10, 11, 12],
            [13, 14, 15],
            [16, 17, 18],
        ];
        let img = rgb_from_pixels(3, 2, &px).unwrap();
        assert_eq!(img.get_pixel(2, 0).0, [7, 8, 9]);
        assert_eq!(img.get_pixel(0, 1).0, [10, 11, 12]);
        assert!(rgb_from_pixels(4, 2, &px).is_none());
    }

    #[test]
    fn windows_cover_the_length() {
        assert_eq!(window_starts(20, 8, 4), vec![0, 4, 8, 12]);
        assert_eq!(window_starts(8, 8, 4), vec![0]);
        assert_eq!(window_starts(5, 8, 4), vec![0]);
        assert_eq!(window_starts(9, 8, 4), vec![0, 4]);
    }

    #[test]
    fn pixel_to_cell_uses_origin_and_cell_size() {
        let m = FeatureMap {
            height: 2,
            width: 3,
            dim: 1,
            data: (0..6).map(|i| i as f32).collect(),
            origin: [10.0, 0.0],
            cell_size: [4.0, 5.0],
        };
        assert_eq!(m.cell_of_pixel(10, 0), Some((0, 0)));
        assert_eq!(m.cell_of_pixel(13, 4), Some((0, 0)));
        assert_eq!(m.cell_of_pixel(14, 5), Some((1, 1)));
        assert_eq!(m.at_pixel(21, 9), Some(&[5.0f32][..]));
        assert_eq!(m.cell_of_pixel(9, 0), None);
        assert_eq!(m.cell_of_pixel(22, 0), None);
        assert_eq!(m.cell_of_pixel(10, 10), None);
    }
}
