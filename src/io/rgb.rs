//! Colour images from disk (PNG, JPEG) as 8-bit RGB: the one colour reader
//! of the crate (RGB-D frames, KITTI camera images, encoders). PNGs go
//! through [`super::bounded_png`], whose header claims are checked against
//! the file; JPEGs through `image` with its allocation limit, after their
//! header's size is checked against the file's (one bit an 8 x 8 block at
//! least).

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageBuffer, RgbImage};
use png::{ColorType, Transformations};

use super::bounded_png::decode_png;
use super::cloud::CloudError;

/// Most bytes a JPEG decode may allocate (a 16k x 16k RGB image).
const MAX_JPEG_ALLOC: u64 = 16_384 * 16_384 * 3;

/// A PNG file's first eight bytes.
const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";

fn decode(path: &Path) -> Result<DynamicImage, CloudError> {
    let bytes = crate::io::bounded_read::read_regular(path).map_err(|e| CloudError::io(path, e))?;
    decode_bytes(&bytes, path)
}

/// A PNG or JPEG file's bytes decoded; `name` names them in errors.
fn decode_bytes(bytes: &[u8], name: &Path) -> Result<DynamicImage, CloudError> {
    if bytes.starts_with(PNG_SIGNATURE) {
        let (info, buf) = decode_png(
            Cursor::new(bytes),
            bytes.len() as u64,
            name,
            Transformations::normalize_to_color8(),
        )?;
        let (w, h) = (info.width, info.height);
        let bad = || CloudError::format(name, "PNG pixel data does not match its header");
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
                return Err(CloudError::format(name, "palette PNG was not expanded"));
            }
        });
    }
    // Every 8 x 8 block of the first component takes at least one bit of
    // entropy-coded data (its DC code), so a header that claims more
    // pixels than 512 a byte lies: refused before the decoder allocates
    // the image it claims (a 396-byte file claiming 22529 x 22783 pixels
    // asked for 2 GB; AFL++, 2026-11-28).
    let (w, h) = image_size(bytes, name)?;
    let claimed = u64::from(w) * u64::from(h);
    if claimed > 512 * bytes.len() as u64 {
        return Err(CloudError::format(
            name,
            format!(
                "corrupt JPEG: its header claims {w} x {h} pixels, more than its {} bytes can \
                 hold (at least one bit each 8 x 8 block)",
                bytes.len()
            ),
        ));
    }
    let mut reader = jpeg_reader(bytes, name)?;
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_JPEG_ALLOC);
    reader.limits(limits);
    reader
        .decode()
        .map_err(|e| CloudError::format(name, format!("not a readable PNG or JPEG image: {e}")))
}

/// A reader of `bytes` if they start as a JPEG file does and reach its
/// end-of-image marker ([`jpeg_end`]): the decoder fills a truncated
/// file's missing rows silently, so truncation is caught here.
fn jpeg_reader<'a>(
    bytes: &'a [u8],
    name: &Path,
) -> Result<image::ImageReader<Cursor<&'a [u8]>>, CloudError> {
    if !bytes.starts_with(&[0xff, 0xd8, 0xff]) {
        return Err(CloudError::format(
            name,
            "not a readable PNG or JPEG image: it starts as neither",
        ));
    }
    match jpeg_end(bytes) {
        Ok(_) => {}
        Err(JpegWalk::Truncated) => {
            return Err(CloudError::format(
                name,
                format!(
                    "truncated JPEG: its segments end without the end-of-image marker (FF D9) \
                     ({} bytes in all)",
                    bytes.len()
                ),
            ));
        }
        Err(JpegWalk::NoMarker(at)) => {
            return Err(CloudError::format(
                name,
                format!(
                    "corrupt JPEG: no valid segment at byte {at}, where the one before it ends \
                     ({} bytes in all)",
                    bytes.len()
                ),
            ));
        }
    }
    Ok(image::ImageReader::with_format(
        Cursor::new(bytes),
        image::ImageFormat::Jpeg,
    ))
}

/// Why a JPEG's segments do not reach its end-of-image marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum JpegWalk {
    /// The data ends first.
    Truncated,
    /// No marker at this byte, where a segment ends.
    NoMarker(usize),
}

/// Where a JPEG's own end-of-image marker (`FF D9`) ends, found by walking
/// its segments from the start: a marker segment's length skips its
/// contents (an EXIF thumbnail's own markers inside APP1 among them),
/// entropy-coded data ends at the first marker that is neither a stuffed
/// `FF 00` nor a restart (`FF D0`-`D7`). Bytes after the marker (a
/// phone's appended video, a driver's padding) are the file's business;
/// [`JpegWalk`] says why not: the data ends first (a truncated file), or a
/// segment ends where no marker follows (bytes changed or inserted).
fn jpeg_end(bytes: &[u8]) -> Result<usize, JpegWalk> {
    use JpegWalk::Truncated;
    let byte = |i: usize| bytes.get(i).copied().ok_or(Truncated);
    let mut i = 2; // after SOI
    loop {
        // Fill bytes (FF FF ...) may precede a marker.
        while bytes.get(i) == Some(&0xff) && bytes.get(i + 1) == Some(&0xff) {
            i += 1;
        }
        if byte(i)? != 0xff {
            return Err(JpegWalk::NoMarker(i));
        }
        let marker = byte(i + 1)?;
        match marker {
            0xd9 => return Ok(i + 2),
            // Markers without a length: TEM and stray restarts.
            0x01 | 0xd0..=0xd7 => i += 2,
            _ => {
                let len = u16::from_be_bytes([byte(i + 2)?, byte(i + 3)?]) as usize;
                if len < 2 {
                    return Err(JpegWalk::NoMarker(i));
                }
                i += 2 + len;
                if marker == 0xda {
                    // Entropy-coded data up to the next real marker.
                    loop {
                        let rest = bytes.get(i..).ok_or(Truncated)?;
                        let at = i + rest.iter().position(|&b| b == 0xff).ok_or(Truncated)?;
                        match byte(at + 1)? {
                            0x00 | 0xd0..=0xd7 | 0xff => i = at + 1,
                            _ => {
                                i = at;
                                break;
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The width and height a PNG or JPEG file's header declares, from its
/// bytes (nothing is decoded); `name` names them in errors.
pub fn image_size(bytes: &[u8], name: &Path) -> Result<(u32, u32), CloudError> {
    let bad = |e: image::ImageError| {
        CloudError::format(name, format!("not a readable PNG or JPEG image: {e}"))
    };
    if bytes.starts_with(PNG_SIGNATURE) {
        return image::ImageReader::with_format(Cursor::new(bytes), image::ImageFormat::Png)
            .into_dimensions()
            .map_err(bad);
    }
    jpeg_reader(bytes, name)?.into_dimensions().map_err(bad)
}

/// A PNG or JPEG file's bytes (as read from disk) as 8-bit RGB, as
/// [`read_rgb`] reads the file; `name` names them in errors.
pub fn rgb_from_bytes(bytes: &[u8], name: &Path) -> Result<RgbImage, CloudError> {
    Ok(decode_bytes(bytes, name)?.to_rgb8())
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

    /// AFL++'s finds (fuzz/corpus/image_bytes): a few hundred bytes whose
    /// header claims a huge image are refused before anything is
    /// allocated for it.
    #[test]
    fn a_jpeg_claiming_more_pixels_than_its_bytes_hold_is_refused() {
        let tiny = include_bytes!("../../fuzz/corpus/image_bytes/crash-a6d37541c00a.jpg");
        let e = rgb_from_bytes(tiny, Path::new("f.jpg"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("f.jpg") && e.contains("22529 x 22783") && e.contains("396 bytes"),
            "{e}"
        );
        for (file, bytes) in [
            (
                "f3b28fb46d47",
                &include_bytes!("../../fuzz/corpus/image_bytes/crash-f3b28fb46d47.jpg")[..],
            ),
            (
                "645c403026b3",
                &include_bytes!("../../fuzz/corpus/image_bytes/crash-645c403026b3.jpg")[..],
            ),
            (
                "b3ba0a564c66",
                &include_bytes!("../../fuzz/corpus/image_bytes/crash-b3ba0a564c66.jpg")[..],
            ),
        ] {
            let e = rgb_from_bytes(bytes, Path::new(file))
                .unwrap_err()
                .to_string();
            assert!(e.contains("more than its"), "{file}: {e}");
        }
    }

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

    #[test]
    fn bytes_decode_as_the_file_does_and_the_header_gives_the_size() {
        let dir = tempfile::tempdir().unwrap();
        let img = RgbImage::from_fn(7, 4, |x, y| image::Rgb([x as u8 * 30, y as u8 * 60, 9]));
        for name in ["a.png", "a.jpg"] {
            let p = dir.path().join(name);
            img.save(&p).unwrap();
            let bytes = std::fs::read(&p).unwrap();
            let label = Path::new("frame 3");
            assert_eq!(image_size(&bytes, label).unwrap(), (7, 4), "{name}");
            assert_eq!(
                rgb_from_bytes(&bytes, label).unwrap(),
                read_rgb(&p).unwrap()
            );
            // Cut short: refused by name, also by the header's reader
            // where the cut is seen without decoding (a JPEG's missing end).
            let cut = &bytes[..bytes.len() - 20];
            let e = rgb_from_bytes(cut, label).unwrap_err().to_string();
            assert!(e.starts_with("frame 3"), "{e}");
            if name.ends_with("jpg") {
                let e = image_size(cut, label).unwrap_err().to_string();
                assert!(e.contains("truncated JPEG"), "{e}");
            }
        }
        // A valid JPEG with bytes after its end (a phone's appended video,
        // a driver's zero padding) reads; one cut before its end does not,
        // even with an end marker earlier in the file (an EXIF thumbnail's,
        // inside APP1).
        let p = dir.path().join("b.jpg");
        img.save(&p).unwrap();
        let jpeg = std::fs::read(&p).unwrap();
        let end = jpeg_end(&jpeg).unwrap();
        assert_eq!(end, jpeg.len());
        let mut trailer = jpeg.clone();
        trailer.extend((0..1000u32).map(|i| (i * 7) as u8));
        trailer.extend([0u8; 64]);
        assert_eq!(
            rgb_from_bytes(&trailer, Path::new("t")).unwrap(),
            read_rgb(&p).unwrap()
        );
        let mut thumb = jpeg[..2].to_vec();
        let inner = [&[0xff, 0xd8][..], &[0xff, 0xd9]].concat();
        thumb.extend([0xff, 0xe1]);
        thumb.extend(((inner.len() + 2) as u16).to_be_bytes());
        thumb.extend(&inner);
        thumb.extend(&jpeg[2..jpeg.len() - 30]);
        let e = rgb_from_bytes(&thumb, Path::new("t"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("truncated JPEG"), "{e}");
        thumb.extend(&jpeg[jpeg.len() - 30..]);
        assert_eq!(
            rgb_from_bytes(&thumb, Path::new("t")).unwrap(),
            read_rgb(&p).unwrap()
        );
        // Bytes inserted where a segment ends: corrupt, said as such (not
        // "truncated"), naming the byte.
        let first_end = 4 + u16::from_be_bytes([jpeg[4], jpeg[5]]) as usize;
        let mut spliced = jpeg[..first_end].to_vec();
        spliced.extend([0x12, 0x34, 0x56]);
        spliced.extend(&jpeg[first_end..]);
        let e = rgb_from_bytes(&spliced, Path::new("t"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!(
                "corrupt JPEG: no valid segment at byte {first_end},"
            )),
            "{e}"
        );
        for junk in [&b"GIF89a...."[..], b"", b"\xff\xd8"] {
            let e = image_size(junk, Path::new("frame 4"))
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("frame 4") && e.contains("PNG or JPEG"), "{e}");
            assert!(rgb_from_bytes(junk, Path::new("frame 4")).is_err());
        }
    }
}
