//! PNG decoding with the header's claims checked against the file: the
//! one place every PNG reader (depth, labels, colour) opens its file.

use std::fs::File;
use std::io::{BufRead, BufReader, Seek};
use std::path::Path;

use png::Transformations;

use super::cloud::CloudError;

/// Deflate's largest expansion (258-byte matches coded in 2 bits: about
/// 1032 to 1), rounded up.
const MAX_DEFLATE_RATIO: u64 = 1100;

/// Most pixels a PNG may declare (8192 x 8192; a 4K frame is 8.3
/// million): a 760 KB file of zeros declaring 20000 x 20000 16-bit pixels
/// was decoded (2.4 GB) before its size was compared with the camera's.
pub const MAX_PNG_PIXELS: u64 = 1 << 26;

/// A PNG file's header without decoding it: width, height, bit depth and
/// colour type (IHDR), after checking that the file holds the IEND chunk
/// near its end, as every complete PNG does (a file cut short does not;
/// bytes some writers append after IEND are allowed).
pub(crate) fn png_header(path: &Path) -> Result<(u32, u32, u8, u8), CloudError> {
    use std::io::{Read, SeekFrom};
    /// IEND's type and CRC: the same 8 bytes in every PNG.
    const IEND: [u8; 8] = [b'I', b'E', b'N', b'D', 0xAE, 0x42, 0x60, 0x82];
    /// How far from the end IEND is looked for.
    const TAIL: u64 = 64 << 10;
    let io = |e| CloudError::io(path, e);
    let mut f = File::open(path).map_err(io)?;
    let len = f.metadata().map_err(io)?.len();
    let mut head = [0u8; 29];
    if f.read_exact(&mut head).is_err()
        || &head[..8] != b"\x89PNG\r\n\x1a\n"
        || &head[12..16] != b"IHDR"
    {
        return Err(CloudError::format(path, "not a PNG file (no PNG header)"));
    }
    let mut tail = Vec::new();
    f.seek(SeekFrom::Start(len.saturating_sub(TAIL).max(29)))
        .map_err(io)?;
    f.take(TAIL).read_to_end(&mut tail).map_err(io)?;
    if !tail.windows(IEND.len()).any(|w| w == IEND) {
        return Err(CloudError::format(
            path,
            "truncated PNG: it does not hold the IEND chunk that ends every PNG",
        ));
    }
    let be = |i: usize| u32::from_be_bytes([head[i], head[i + 1], head[i + 2], head[i + 3]]);
    Ok((be(16), be(20), head[24], head[25]))
}

pub(crate) fn open_png(
    path: &Path,
    transform: Transformations,
) -> Result<(png::OutputInfo, Vec<u8>), CloudError> {
    let file = File::open(path).map_err(|e| CloudError::io(path, e))?;
    let file_len = file.metadata().map_err(|e| CloudError::io(path, e))?.len();
    decode_png(BufReader::new(file), file_len, path, transform)
}

/// [`open_png`] of a PNG of `file_len` bytes read from `source`; `path`
/// names it in errors.
pub(crate) fn decode_png(
    source: impl BufRead + Seek,
    file_len: u64,
    path: &Path,
    transform: Transformations,
) -> Result<(png::OutputInfo, Vec<u8>), CloudError> {
    let mut decoder = png::Decoder::new(source);
    decoder.set_transformations(transform);
    let mut reader = decoder
        .read_info()
        .map_err(|e| CloudError::format(path, format!("not a readable PNG: {e}")))?;
    let (w, h) = (reader.info().width, reader.info().height);
    if w as u64 * h as u64 > MAX_PNG_PIXELS {
        return Err(CloudError::format(
            path,
            format!(
                "its header declares {w} x {h} pixels, more than the {MAX_PNG_PIXELS} an image may have here"
            ),
        ));
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| CloudError::format(path, "PNG image too large"))?;
    // The header's width and height are untrusted: deflate expands at most
    // 1032-fold, so a larger image cannot come out of this file's bytes.
    let most = file_len.saturating_mul(MAX_DEFLATE_RATIO).max(1 << 16);
    if size as u64 > most {
        let info = reader.info();
        return Err(CloudError::format(
            path,
            format!(
                "corrupt PNG: its header declares {} x {} pixels ({size} bytes), more than \
                 the {file_len}-byte file can hold",
                info.width, info.height
            ),
        ));
    }
    let mut buf = vec![0u8; size];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| CloudError::format(path, format!("corrupt or truncated PNG: {e}")))?;
    buf.truncate(info.buffer_size());
    Ok((info, buf))
}
