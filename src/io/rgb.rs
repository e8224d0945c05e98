//! Colour images from disk (PNG, JPEG) as 8-bit RGB.

use std::path::{Path, PathBuf};

use image::RgbImage;

/// Errors of image reading; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageReadError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a readable PNG or JPEG image: {reason}")]
    Decode { path: PathBuf, reason: String },
}

/// Reads a PNG or JPEG file as 8-bit RGB (grey and RGBA are converted;
/// 16-bit channels are scaled to 8 bits).
pub fn read_rgb(path: &Path) -> Result<RgbImage, ImageReadError> {
    let bytes = std::fs::read(path).map_err(|source| ImageReadError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let img = image::load_from_memory(&bytes).map_err(|e| ImageReadError::Decode {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    Ok(img.to_rgb8())
}

/// Reads a PNG or JPEG file as 8-bit grey values, row-major, with its
/// width and height.
pub fn read_luma(path: &Path) -> Result<(u32, u32, Vec<u8>), ImageReadError> {
    let bytes = std::fs::read(path).map_err(|source| ImageReadError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let img = image::load_from_memory(&bytes).map_err(|e| ImageReadError::Decode {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    let l = img.to_luma8();
    Ok((l.width(), l.height(), l.into_raw()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trip_and_bad_file_named() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        let img = RgbImage::from_fn(5, 3, |x, y| image::Rgb([x as u8 * 40, y as u8 * 80, 7]));
        img.save(&p).unwrap();
        assert_eq!(read_rgb(&p).unwrap(), img);
        let bad = dir.path().join("bad.png");
        std::fs::write(&bad, b"not an image").unwrap();
        let e = read_rgb(&bad).unwrap_err().to_string();
        assert!(e.contains("bad.png"), "{e}");
    }
}
