//! From a figure to a file: the format from the extension, rendering into
//! memory with the matching plotters backend, and the atomic write.

use std::path::Path;

use plotters::backend::RGBPixel;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::PlotError;
use super::style;

/// The file formats a figure can be written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Format {
    Png,
    Svg,
}

impl Format {
    /// The format named by `path`'s extension (case-insensitive).
    pub(crate) fn of(path: &Path) -> Result<Format, PlotError> {
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match extension.as_str() {
            "png" => Ok(Format::Png),
            "svg" => Ok(Format::Svg),
            _ => Err(PlotError::UnknownFormat {
                path: path.to_path_buf(),
                extension,
            }),
        }
    }
}

/// A drawing failure from plotters, as text: its error types are generic
/// over the backend, and the caller only needs to report them.
#[derive(Debug)]
pub(crate) struct DrawError(pub(crate) String);

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for DrawError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        DrawError(e.to_string())
    }
}

/// A validated figure that can draw itself on any plotters backend.
pub(crate) trait Figure {
    /// What drawing reports back (pixel positions, for the tests).
    type Layout;
    /// Canvas size in pixels (width, height).
    fn size(&self) -> (u32, u32);
    /// Draws on `root`, which is already filled white.
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> Result<Self::Layout, DrawError>;
}

/// Renders `figure` in the format of `path` and writes it there atomically.
pub(crate) fn write_figure<F: Figure>(path: &Path, figure: &F) -> Result<F::Layout, PlotError> {
    let format = Format::of(path)?;
    let draw_err = |e: DrawError| PlotError::Draw {
        path: path.to_path_buf(),
        message: e.0,
    };
    style::ensure_font().map_err(|m| draw_err(DrawError(m)))?;
    let (width, height) = figure.size();
    match format {
        Format::Png => {
            let mut rgb = vec![255u8; width as usize * height as usize * 3];
            let layout = {
                let backend =
                    BitMapBackend::<RGBPixel>::with_buffer_and_format(&mut rgb, (width, height))
                        .map_err(|e| draw_err(DrawError(e.to_string())))?;
                let root = backend.into_drawing_area();
                let layout = draw_on(&root, figure).map_err(draw_err)?;
                root.present().map_err(|e| draw_err(DrawError::from(e)))?;
                layout
            };
            let bytes = encode_png(&rgb, width, height).map_err(|source| PlotError::Png {
                path: path.to_path_buf(),
                source,
            })?;
            write_atomic(path, &bytes)?;
            Ok(layout)
        }
        Format::Svg => {
            let mut svg = svg_mark();
            let layout = {
                let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
                let layout = draw_on(&root, figure).map_err(draw_err)?;
                root.present().map_err(|e| draw_err(DrawError::from(e)))?;
                layout
            };
            write_atomic(path, svg.as_bytes())?;
            Ok(layout)
        }
    }
}

fn draw_on<DB: DrawingBackend, F: Figure>(
    root: &DrawingArea<DB, Shift>,
    figure: &F,
) -> Result<F::Layout, DrawError> {
    root.fill(&WHITE)?;
    figure.draw(root)
}

/// The mark every figure and picture omcl draws carries (a PNG `tEXt`
/// `Software` chunk, an SVG's first comment), so that a later run may
/// replace its own figure but not a photo, a depth or label frame (which
/// the simulator marks `Software: omcl`) or anyone else's file
/// ([`is_omcl_figure`]).
pub const FIGURE_MARK: &str = "omcl figure";

/// Whether `path` is a figure or picture omcl drew ([`FIGURE_MARK`]
/// within its first 4 KiB: the PNG chunk comes before the image data, the
/// SVG comment first).
pub fn is_omcl_figure(path: &Path) -> bool {
    use std::io::Read;
    let mut head = Vec::new();
    if std::fs::File::open(path)
        .and_then(|f| f.take(4096).read_to_end(&mut head))
        .is_err()
    {
        return false;
    }
    if head.starts_with(b"\x89PNG\r\n\x1a\n") {
        let mut needle = b"tEXtSoftware\0".to_vec();
        needle.extend(FIGURE_MARK.bytes());
        return head.windows(needle.len()).any(|w| w == needle.as_slice());
    }
    head.starts_with(svg_mark().as_bytes())
}

fn svg_mark() -> String {
    format!("<!-- {FIGURE_MARK} -->\n")
}

/// Writes an 8-bit RGB picture (`rgb` = width * height * 3 bytes) as a
/// PNG with [`FIGURE_MARK`], atomically.
pub fn write_picture_png(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[u8],
) -> Result<(), PlotError> {
    let bytes = encode_png(rgb, width, height).map_err(|source| PlotError::Png {
        path: path.to_path_buf(),
        source,
    })?;
    write_atomic(path, &bytes)
}

fn encode_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>, png::EncodingError> {
    let mut bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut bytes, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.add_text_chunk("Software".into(), FIGURE_MARK.into())?;
        let mut writer = encoder.write_header()?;
        writer.write_image_data(rgb)?;
        writer.finish()?;
    }
    Ok(bytes)
}

/// Writes `bytes` to a temporary file in `path`'s directory and renames it
/// onto `path`, so readers see either the old file or the whole new one.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), PlotError> {
    crate::io::atomic::write(path, bytes).map_err(|source| PlotError::Io {
        path: path.to_path_buf(),
        source,
    })
}
