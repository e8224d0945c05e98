//! Colour images from disk (PNG, JPEG) as 8-bit RGB: the one colour reader
//! of the crate (RGB-D frames, KITTI camera images, encoders). PNGs go
//! through [`super::bounded_png`], whose header claims are checked against
//! the file; JPEGs through `image` with its allocation limit.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageBuffer, RgbImage};
use png::{ColorType, Transformations};

use super::bounded_png::open_png;
use super::cloud::CloudError;

/// Most bytes a JPEG decode may allocate (a 16k x 16k RGB image).
const MAX_JPEG_ALLOC: u64 = 16_384 * 16_384 * 3;

fn decode(path: &Path) -> Result<DynamicImage, CloudError> {
    let mut head = [0u8; 8];
    let is_png = {
        use std::io::Read;
        let mut f = std::fs::File::open(path).map_err(|e| CloudError::io(path, e))?;
        f.read(&mut head).map_err(|e| CloudError::io(path, e))? == 8
            && head == *b"\x89PNG\r\n\x1a\n"
    };
    if is_png {
        let (info, buf) = open_png(path, Transformations::normalize_to_color8())?;
        let (w, h) = (info.width, info.height);
        let bad = || CloudError::format(path, "PNG pixel data does not match its header");
        return Ok(match info.color_type {
            ColorType::Grayscale => {
                DynamicImage::ImageLuma8(ImageBuffer::from_raw(w, h, buf).ok_or_else(bad)?)
            }
            ColorType::GrayscaleAlpha => {
                DynamicImage::ImageLumaA8(ImageBuffer::from_raw(w, h, buf).ok_or_else(bad)?)
            }
            ColorType::Rgb => {
                DynamicImage::ImageRgb8(ImageBuffer::from_raw(w, h, buf).ok_or_else(bad)?)
            }
            ColorType::Rgba => {
                DynamicImage::ImageRgba8(ImageBuffer::from_raw(w, h, buf).ok_or_else(bad)?)
            }
            ColorType::Indexed => {
                return Err(CloudError::format(path, "palette PNG was not expanded"));
            }
        });
    }
    let bytes = crate::io::bounded_read::read_regular(path).map_err(|e| CloudError::io(path, e))?;
    let mut reader = image::ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| CloudError::io(path, e))?;
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_JPEG_ALLOC);
    reader.limits(limits);
    reader
        .decode()
        .map_err(|e| CloudError::format(path, format!("not a readable PNG or JPEG image: {e}")))
}

/// Reads a PNG (palette, grey, RGB, with or without alpha, 8 or 16 bits)
/// or JPEG file as 8-bit RGB (grey is repeated, alpha dropped, 16-bit
/// channels scaled to 8 bits).
pub fn read_rgb(path: &Path) -> Result<RgbImage, CloudError> {
    Ok(decode(path)?.to_rgb8())
}

/// Reads a PNG or JPEG file as 8-bit grey values, row-major, with its
/// width and height.
pub fn read_luma(path: &Path) -> Result<(u32, u32, Vec<u8>), CloudError> {
    let l = decode(path)?.to_luma8();
    Ok((l.width(), l.height(), l.into_raw()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_and_jpeg_read_and_bad_file_named() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        let img = RgbImage::from_fn(5, 3, |x, y| image::Rgb([x as u8 * 40, y as u8 * 80, 7]));
        img.save(&p).unwrap();
        assert_eq!(read_rgb(&p).unwrap(), img);
        // Grey PNG: the value repeated in every channel.
        let g = dir.path().join("g.png");
        image::GrayImage::from_fn(2, 2, |x, y| image::Luma([(x * 100 + y * 10) as u8]))
            .save(&g)
            .unwrap();
        assert_eq!(read_rgb(&g).unwrap().get_pixel(1, 1).0, [110, 110, 110]);
        assert_eq!(read_luma(&g).unwrap(), (2, 2, vec![0, 100, 10, 110]));
        // JPEG (lossy): a flat image stays close to its colour.
        let j = dir.path().join("a.jpg");
        RgbImage::from_pixel(16, 16, image::Rgb([200, 40, 90]))
            .save(&j)
            .unwrap();
        let back = read_rgb(&j).unwrap();
        assert_eq!(back.dimensions(), (16, 16));
        let px = back.get_pixel(8, 8).0;
        assert!(
            px.iter()
                .zip([200u8, 40, 90])
                .all(|(&a, b)| a.abs_diff(b) <= 6),
            "{px:?}"
        );
        let bad = dir.path().join("bad.png");
        std::fs::write(&bad, b"not an image").unwrap();
        let e = read_rgb(&bad).unwrap_err().to_string();
        assert!(e.contains("bad.png"), "{e}");
    }
}
