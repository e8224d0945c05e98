//! Pixel math that turns an RGB image into a model's input tensor:
//! resampling, cropping and per-channel normalisation.
//!
//! Resampling reproduces Pillow's `Image.resize` for 8-bit images bit for
//! bit (separable convolution with the filter support widened by the
//! downscale factor, coefficients in 22-bit fixed point, a horizontal pass
//! rounded to 8 bits, then a vertical pass). Models exported from PyTorch
//! were trained on PIL-resized images (CLIP's `preprocess` calls PIL's
//! bicubic), and other bicubic implementations differ from it by several
//! grey levels near edges, so matching PIL keeps features faithful.

use image::RgbImage;

/// CLIP's per-channel mean of [0, 1] RGB values.
pub const CLIP_MEAN: [f64; 3] = [0.481_454_66, 0.457_827_5, 0.408_210_73];
/// CLIP's per-channel standard deviation of [0, 1] RGB values.
pub const CLIP_STD: [f64; 3] = [0.268_629_54, 0.261_302_58, 0.275_777_11];
/// CLIP's square input side, pixels.
pub const CLIP_SIZE: u32 = 224;

/// Resampling filters with Pillow's names and supports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Filter {
    /// Box (area average when shrinking); support 0.5.
    Box,
    /// Triangle; support 1.
    Bilinear,
    /// Keys cubic with a = -0.5; support 2. CLIP's choice.
    Bicubic,
    /// Lanczos-3; support 3.
    Lanczos,
}

impl Filter {
    fn support(self) -> f64 {
        match self {
            Filter::Box => 0.5,
            Filter::Bilinear => 1.0,
            Filter::Bicubic => 2.0,
            Filter::Lanczos => 3.0,
        }
    }

    fn weight(self, x: f64) -> f64 {
        match self {
            Filter::Box => {
                if x > -0.5 && x <= 0.5 {
                    1.0
                } else {
                    0.0
                }
            }
            Filter::Bilinear => {
                let x = x.abs();
                if x < 1.0 { 1.0 - x } else { 0.0 }
            }
            Filter::Bicubic => {
                const A: f64 = -0.5;
                let x = x.abs();
                if x < 1.0 {
                    ((A + 2.0) * x - (A + 3.0)) * x * x + 1.0
                } else if x < 2.0 {
                    (((x - 5.0) * x + 8.0) * x - 4.0) * A
                } else {
                    0.0
                }
            }
            Filter::Lanczos => {
                if -3.0 < x && x < 3.0 {
                    sinc(x) * sinc(x / 3.0)
                } else {
                    0.0
                }
            }
        }
    }
}

fn sinc(x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else {
        let px = x * std::f64::consts::PI;
        px.sin() / px
    }
}

/// Fixed-point precision of Pillow's 8-bit resampling coefficients.
const PRECISION_BITS: u32 = 32 - 8 - 2;

/// Per output sample: first input index, number of taps, and fixed-point
/// weights (`ksize` apart).
struct Coeffs {
    ksize: usize,
    bounds: Vec<(usize, usize)>,
    weights: Vec<i32>,
}

/// Pillow's `precompute_coeffs` followed by `normalize_coeffs_8bpc`.
fn precompute(in_size: usize, out_size: usize, filter: Filter) -> Coeffs {
    let (in0, in1) = (0.0f64, in_size as f64);
    let scale = (in1 - in0) / out_size as f64;
    let filterscale = scale.max(1.0);
    let support = filter.support() * filterscale;
    let ksize = support.ceil() as usize * 2 + 1;
    let mut bounds = Vec::with_capacity(out_size);
    let mut weights = vec![0i32; out_size * ksize];
    let mut k = vec![0f64; ksize];
    for xx in 0..out_size {
        let center = in0 + (xx as f64 + 0.5) * scale;
        let ss = 1.0 / filterscale;
        // C's (int) cast truncates toward zero; both ends are clamped after.
        let xmin = ((center - support + 0.5) as i64).max(0) as usize;
        let xmax = ((center + support + 0.5) as i64).min(in_size as i64).max(0) as usize;
        let n = xmax.saturating_sub(xmin);
        let mut ww = 0.0;
        for (x, kx) in k.iter_mut().enumerate().take(n) {
            let w = filter.weight((x as f64 + xmin as f64 - center + 0.5) * ss);
            *kx = w;
            ww += w;
        }
        for (x, &kx) in k.iter().enumerate().take(n) {
            let v = if ww != 0.0 { kx / ww } else { kx };
            let fixed = v * f64::from(1u32 << PRECISION_BITS);
            weights[xx * ksize + x] = if v < 0.0 {
                (-0.5 + fixed) as i32
            } else {
                (0.5 + fixed) as i32
            };
        }
        bounds.push((xmin, n));
    }
    Coeffs {
        ksize,
        bounds,
        weights,
    }
}

fn clip8(v: i32) -> u8 {
    if v >= (1 << PRECISION_BITS << 8) {
        255
    } else if v <= 0 {
        0
    } else {
        (v >> PRECISION_BITS) as u8
    }
}

/// Resizes an RGB image to `width` x `height` exactly as Pillow's
/// `Image.resize((width, height), filter)` does on an `RGB` image.
/// Returns `None` for a zero target size.
pub fn resize(img: &RgbImage, width: u32, height: u32, filter: Filter) -> Option<RgbImage> {
    if width == 0 || height == 0 || img.width() == 0 || img.height() == 0 {
        return None;
    }
    let (iw, ih) = (img.width() as usize, img.height() as usize);
    let (ow, oh) = (width as usize, height as usize);
    if (iw, ih) == (ow, oh) {
        return Some(img.clone());
    }
    let src = img.as_raw();
    let horiz = precompute(iw, ow, filter);
    let mut vert = precompute(ih, oh, filter);
    let need_h = ow != iw;
    let need_v = oh != ih;

    // Horizontal pass over only the rows the vertical pass will read.
    let (mut cur, mut cur_w) = (src.to_vec(), iw);
    if need_h {
        let first = vert.bounds[0].0;
        let last = vert.bounds[oh - 1].0 + vert.bounds[oh - 1].1;
        let rows = last - first;
        let mut tmp = vec![0u8; rows * ow * 3];
        for y in 0..rows {
            let row = &src[(y + first) * iw * 3..(y + first + 1) * iw * 3];
            for (xx, &(xmin, n)) in horiz.bounds.iter().enumerate() {
                let k = &horiz.weights[xx * horiz.ksize..xx * horiz.ksize + n];
                let mut ss = [1i32 << (PRECISION_BITS - 1); 3];
                for (x, &kx) in k.iter().enumerate() {
                    let p = (x + xmin) * 3;
                    for c in 0..3 {
                        ss[c] += i32::from(row[p + c]) * kx;
                    }
                }
                for c in 0..3 {
                    tmp[(y * ow + xx) * 3 + c] = clip8(ss[c]);
                }
            }
        }
        for b in &mut vert.bounds {
            b.0 -= first;
        }
        cur = tmp;
        cur_w = ow;
    }
    if need_v {
        let mut out = vec![0u8; oh * cur_w * 3];
        for (yy, &(ymin, n)) in vert.bounds.iter().enumerate() {
            let k = &vert.weights[yy * vert.ksize..yy * vert.ksize + n];
            for xx in 0..cur_w {
                let mut ss = [1i32 << (PRECISION_BITS - 1); 3];
                for (y, &ky) in k.iter().enumerate() {
                    let p = ((y + ymin) * cur_w + xx) * 3;
                    for c in 0..3 {
                        ss[c] += i32::from(cur[p + c]) * ky;
                    }
                }
                for c in 0..3 {
                    out[(yy * cur_w + xx) * 3 + c] = clip8(ss[c]);
                }
            }
        }
        cur = out;
    }
    RgbImage::from_raw(width, height, cur)
}

/// The size torchvision's `Resize(side)` gives an image: the shorter side
/// becomes `side`, the longer keeps the aspect ratio, truncated.
pub fn shorter_side_size(width: u32, height: u32, side: u32) -> (u32, u32) {
    if width <= height {
        let h = (u64::from(side) * u64::from(height) / u64::from(width.max(1))) as u32;
        (side, h)
    } else {
        let w = (u64::from(side) * u64::from(width) / u64::from(height.max(1))) as u32;
        (w, side)
    }
}

/// The size that makes the longer side `side`, the shorter keeping the
/// aspect ratio (rounded): the "base size" of LSeg/VLMaps evaluation.
pub fn longer_side_size(width: u32, height: u32, side: u32) -> (u32, u32) {
    if width >= height {
        let h = (f64::from(side) * f64::from(height) / f64::from(width.max(1))).round() as u32;
        (side, h.max(1))
    } else {
        let w = (f64::from(side) * f64::from(width) / f64::from(height.max(1))).round() as u32;
        (w.max(1), side)
    }
}

/// Top-left corner of torchvision's `CenterCrop`: `round((len - crop) / 2)`
/// with Python's round-half-to-even.
pub fn center_crop_offset(len: u32, crop: u32) -> u32 {
    let d = len.saturating_sub(crop);
    let half = d / 2;
    // d odd: x.5 rounds to the even neighbour.
    if d % 2 == 1 && half % 2 == 1 {
        half + 1
    } else {
        half
    }
}

/// Crops a `width` x `height` window at (`x0`, `y0`); `None` if it does not
/// fit inside the image.
pub fn crop(img: &RgbImage, x0: u32, y0: u32, width: u32, height: u32) -> Option<RgbImage> {
    if x0.checked_add(width)? > img.width() || y0.checked_add(height)? > img.height() {
        return None;
    }
    Some(image::imageops::crop_imm(img, x0, y0, width, height).to_image())
}

/// Scales 8-bit RGB to [0, 1], subtracts `mean` and divides by `std` per
/// channel, and lays the result out channel-first (C x H x W), as PyTorch
/// models expect. The arithmetic follows numpy's `float32(x) / 255` then
/// `(v - mean) / std` in double precision, so values match Python's to the
/// last bit where the pixels match.
pub fn normalize_chw(img: &RgbImage, mean: [f64; 3], std: [f64; 3]) -> Vec<f32> {
    let lut = normalize_table(mean, std);
    let plane = img.width() as usize * img.height() as usize;
    let mut out = vec![0f32; 3 * plane];
    let (r, rest) = out.split_at_mut(plane);
    let (g, b) = rest.split_at_mut(plane);
    for (i, px) in img.as_raw().chunks_exact(3).enumerate() {
        r[i] = lut[0][usize::from(px[0])];
        g[i] = lut[1][usize::from(px[1])];
        b[i] = lut[2][usize::from(px[2])];
    }
    out
}

/// As [`normalize_chw`] but channel-last (H x W x C).
pub fn normalize_hwc(img: &RgbImage, mean: [f64; 3], std: [f64; 3]) -> Vec<f32> {
    let lut = normalize_table(mean, std);
    img.as_raw()
        .chunks_exact(3)
        .flat_map(|px| {
            [
                lut[0][usize::from(px[0])],
                lut[1][usize::from(px[1])],
                lut[2][usize::from(px[2])],
            ]
        })
        .collect()
}

/// The normalised value of every 8-bit level per channel: a pixel costs
/// three look-ups instead of three double-precision divisions.
fn normalize_table(mean: [f64; 3], std: [f64; 3]) -> [[f32; 256]; 3] {
    let mut lut = [[0f32; 256]; 3];
    for (c, table) in lut.iter_mut().enumerate() {
        for (level, v) in table.iter_mut().enumerate() {
            let x = f64::from(level as f32 / 255.0);
            *v = ((x - mean[c]) / std[c]) as f32;
        }
    }
    lut
}

/// CLIP's image preprocessing: bicubic resize of the shorter side to 224,
/// centre crop to 224 x 224, normalisation with CLIP's mean and std.
/// Returns 3 x 224 x 224 values, channel-first; `None` for an empty image.
pub fn clip_preprocess(img: &RgbImage) -> Option<Vec<f32>> {
    let (w, h) = shorter_side_size(img.width(), img.height(), CLIP_SIZE);
    let resized = resize(img, w, h, Filter::Bicubic)?;
    let x0 = center_crop_offset(w, CLIP_SIZE);
    let y0 = center_crop_offset(h, CLIP_SIZE);
    let cropped = crop(&resized, x0, y0, CLIP_SIZE, CLIP_SIZE)?;
    Some(normalize_chw(&cropped, CLIP_MEAN, CLIP_STD))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| {
            image::Rgb([(x * 255 / w.max(1)) as u8, (y * 255 / h.max(1)) as u8, 77])
        })
    }

    #[test]
    fn constant_image_stays_constant_under_every_filter() {
        let img = RgbImage::from_pixel(13, 7, image::Rgb([10, 200, 99]));
        for f in [
            Filter::Box,
            Filter::Bilinear,
            Filter::Bicubic,
            Filter::Lanczos,
        ] {
            for (w, h) in [(5, 3), (29, 17), (13, 2), (1, 1)] {
                let r = resize(&img, w, h, f).unwrap();
                assert!(r.pixels().all(|p| p.0 == [10, 200, 99]), "{f:?} {w}x{h}");
            }
        }
    }

    #[test]
    fn box_halving_averages_pixel_pairs() {
        // 4x1 -> 2x1 with a box filter averages (0, 100) and (200, 255):
        // (50, 227.5) -> PIL rounds half up in fixed point.
        let img = RgbImage::from_fn(4, 1, |x, _| {
            let v = [0u8, 100, 200, 255][x as usize];
            image::Rgb([v, v, v])
        });
        let r = resize(&img, 2, 1, Filter::Box).unwrap();
        assert_eq!(r.get_pixel(0, 0).0[0], 50);
        assert_eq!(r.get_pixel(1, 0).0[0], 228);
    }

    #[test]
    fn sizes_follow_torchvision() {
        assert_eq!(shorter_side_size(450, 655, 224), (224, 326));
        assert_eq!(shorter_side_size(655, 450, 224), (326, 224));
        assert_eq!(center_crop_offset(326, 224), 51);
        assert_eq!(center_crop_offset(325, 224), 50); // 50.5 -> 50 (even)
        assert_eq!(center_crop_offset(327, 224), 52); // 51.5 -> 52 (even)
        assert_eq!(longer_side_size(640, 480, 520), (520, 390));
    }

    #[test]
    fn normalisation_inverts_to_pixels() {
        let img = gradient(6, 4);
        let chw = normalize_chw(&img, CLIP_MEAN, CLIP_STD);
        let hwc = normalize_hwc(&img, CLIP_MEAN, CLIP_STD);
        for (i, px) in img.pixels().enumerate() {
            for c in 0..3 {
                let v = chw[c * 24 + i];
                assert_eq!(v, hwc[i * 3 + c]);
                let back = (f64::from(v) * CLIP_STD[c] + CLIP_MEAN[c]) * 255.0;
                assert!((back - f64::from(px.0[c])).abs() < 1e-3);
            }
        }
    }

    #[test]
    fn crop_outside_is_refused() {
        let img = gradient(10, 10);
        assert!(crop(&img, 5, 5, 6, 2).is_none());
        assert_eq!(
            crop(&img, 2, 3, 4, 5).unwrap().get_pixel(0, 0),
            img.get_pixel(2, 3)
        );
    }
}
