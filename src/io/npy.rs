//! NumPy `.npy` matrices: per-frame feature maps, per-point features and
//! embedding tables are exchanged with Python tools in this format.
//!
//! Reading accepts little- and big-endian `f2`, `f4` and `f8` arrays in C
//! order and returns `f32`; writing produces little-endian `f4`.

use std::path::{Path, PathBuf};

use npyz::WriterBuilder;

/// Errors of `.npy` reading and writing; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum NpyError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a readable .npy file: {reason}")]
    Format { path: PathBuf, reason: String },
    #[error("{path}: unsupported array: {reason}")]
    Unsupported { path: PathBuf, reason: String },
}

/// A dense array of `f32` in C (row-major) order.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    /// Extent of each axis, outermost first.
    pub shape: Vec<usize>,
    /// `shape.iter().product()` values, last axis fastest.
    pub data: Vec<f32>,
}

impl NpyArray {
    /// Rows and columns when the array is viewed as a matrix whose columns are
    /// the last axis (an H x W x F feature map becomes (H*W) x F).
    pub fn as_matrix_dims(&self) -> (usize, usize) {
        match self.shape.split_last() {
            None => (1, 1),
            Some((&cols, rest)) => (rest.iter().product(), cols),
        }
    }
}

/// The preamble of a `.npy` file, parsed strictly: magic, version, header
/// length, and the header dictionary's `descr`, `fortran_order` and `shape`.
#[derive(Debug, Clone, PartialEq)]
struct Header {
    /// Bytes before the data.
    data_offset: usize,
    little_endian: bool,
    /// Bytes a value: 2, 4 or 8 (a float), else unsupported.
    item: usize,
    type_char: char,
    fortran: bool,
    shape: Vec<usize>,
}

/// Parses the preamble; `bytes` holds at least its first 12 bytes.
fn parse_header(bytes: &[u8]) -> Result<Header, String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("no NUMPY magic".into());
    }
    let (len, start): (usize, usize) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(format!("format version {v} (expected 1, 2 or 3)")),
    };
    let end = start
        .checked_add(len)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| format!("header of {len} bytes runs past the end of the file"))?;
    let text =
        std::str::from_utf8(&bytes[start..end]).map_err(|_| "header is not text".to_string())?;
    let value = |key: &str| -> Result<&str, String> {
        let at = text
            .find(&format!("'{key}'"))
            .or_else(|| text.find(&format!("\"{key}\"")))
            .ok_or_else(|| format!("header has no '{key}'"))?;
        let rest = &text[at + key.len() + 2..];
        let rest = rest.trim_start();
        let rest = rest
            .strip_prefix(':')
            .ok_or_else(|| format!("header: no ':' after '{key}'"))?;
        Ok(rest.trim_start())
    };
    let descr = value("descr")?;
    let quote = descr.chars().next().filter(|c| *c == '\'' || *c == '"');
    let descr = quote
        .and_then(|q| descr[1..].split_once(q))
        .map(|(d, _)| d)
        .ok_or_else(|| {
            "header: 'descr' is not a string (structured dtypes are unsupported)".to_string()
        })?;
    let fortran = match value("fortran_order")? {
        v if v.starts_with("False") => false,
        v if v.starts_with("True") => true,
        v => {
            // Characters, not bytes: the header may hold any UTF-8.
            let head: String = v.chars().take(8).collect();
            return Err(format!("header: fortran_order is '{head}'"));
        }
    };
    let shape_text = value("shape")?;
    let inner = shape_text
        .strip_prefix('(')
        .and_then(|r| r.split_once(')'))
        .map(|(i, _)| i)
        .ok_or_else(|| "header: shape is not a tuple".to_string())?;
    let mut shape = Vec::new();
    for part in inner.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let d = part.trim_end_matches('L');
        shape.push(
            d.parse::<usize>()
                .map_err(|_| format!("header: shape entry '{part}' is not a size"))?,
        );
    }
    let mut chars = descr.chars();
    let order = chars.next().unwrap_or('?');
    let little_endian = match order {
        '<' | '|' | '=' => true,
        '>' => false,
        _ => return Err(format!("dtype '{descr}' has no byte order")),
    };
    let type_char = chars.next().unwrap_or('?');
    let item = chars.as_str().parse::<usize>().unwrap_or(0);
    Ok(Header {
        data_offset: end,
        little_endian,
        item,
        type_char,
        fortran,
        shape,
    })
}

/// Checks a parsed header against what this reader supports and the
/// file's size (`file_len` bytes); the number of values.
fn checked_layout(path: &Path, h: &Header, file_len: usize) -> Result<usize, NpyError> {
    let fmt = |reason: String| NpyError::Format {
        path: path.to_path_buf(),
        reason,
    };
    let unsupported = |reason: String| NpyError::Unsupported {
        path: path.to_path_buf(),
        reason,
    };
    if h.fortran {
        return Err(unsupported(
            "Fortran order; save with np.ascontiguousarray".into(),
        ));
    }
    if h.type_char != 'f' || !matches!(h.item, 2 | 4 | 8) {
        return Err(unsupported(format!(
            "dtype {}{}{} (expected float16, float32 or float64)",
            if h.little_endian { '<' } else { '>' },
            h.type_char,
            h.item
        )));
    }
    let shape = &h.shape;
    let data_bytes = file_len - h.data_offset;
    shape
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .filter(|n| n.checked_mul(h.item).is_some_and(|b| b <= data_bytes))
        .ok_or_else(|| {
            fmt(format!(
                "truncated or corrupt data: shape {shape:?} of {}-byte values needs more than \
                 the {data_bytes} bytes the file holds",
                h.item
            ))
        })
}

/// The shape of a floating-point `.npy` file, from its header and size
/// alone (the data are not read): what [`read_npy`] would refuse is
/// refused the same way, a truncated file included.
pub fn read_npy_shape(path: &Path) -> Result<Vec<usize>, NpyError> {
    use std::io::Read;
    let io_err = |source| NpyError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut f = std::fs::File::open(path).map_err(io_err)?;
    let len = f.metadata().map_err(io_err)?.len() as usize;
    // The preamble: 12 bytes hold the header's length (version 1: 10).
    let mut head = Vec::new();
    f.by_ref().take(12).read_to_end(&mut head).map_err(io_err)?;
    let header_len = match head.get(6) {
        Some(1) if head.len() >= 10 => u16::from_le_bytes([head[8], head[9]]) as u64,
        Some(2 | 3) if head.len() >= 12 => {
            u32::from_le_bytes([head[8], head[9], head[10], head[11]]) as u64
        }
        _ => 0,
    };
    f.by_ref()
        .take(header_len.min(1 << 20))
        .read_to_end(&mut head)
        .map_err(io_err)?;
    let h = parse_header(&head).map_err(|reason| NpyError::Format {
        path: path.to_path_buf(),
        reason,
    })?;
    checked_layout(path, &h, len)?;
    Ok(h.shape)
}

/// Reads a floating-point `.npy` file as `f32`. The shape's product is
/// checked against the file's size before any memory is sized by it.
pub fn read_npy(path: &Path) -> Result<NpyArray, NpyError> {
    let io_err = |source| NpyError::Io {
        path: path.to_path_buf(),
        source,
    };
    let fmt = |reason: String| NpyError::Format {
        path: path.to_path_buf(),
        reason,
    };
    let bytes = crate::io::bounded_read::read_regular(path).map_err(io_err)?;
    let h = parse_header(&bytes).map_err(fmt)?;
    let expected = checked_layout(path, &h, bytes.len())?;
    let shape = h.shape;
    let raw = &bytes[h.data_offset..h.data_offset + expected * h.item];
    let le = h.little_endian;
    let data: Vec<f32> = match h.item {
        2 => raw
            .chunks_exact(2)
            .map(|b| {
                let v = [b[0], b[1]];
                f32::from(half::f16::from_bits(if le {
                    u16::from_le_bytes(v)
                } else {
                    u16::from_be_bytes(v)
                }))
            })
            .collect(),
        4 => raw
            .chunks_exact(4)
            .map(|b| {
                let v = [b[0], b[1], b[2], b[3]];
                if le {
                    f32::from_le_bytes(v)
                } else {
                    f32::from_be_bytes(v)
                }
            })
            .collect(),
        _ => raw
            .chunks_exact(8)
            .map(|b| {
                let v: [u8; 8] = b.try_into().unwrap_or([0; 8]);
                (if le {
                    f64::from_le_bytes(v)
                } else {
                    f64::from_be_bytes(v)
                }) as f32
            })
            .collect(),
    };
    Ok(NpyArray { shape, data })
}

/// Writes `data` with `shape` as a little-endian `f4` `.npy` file, through a
/// temporary file renamed into place so that a failed write leaves no
/// half-written file.
pub fn write_npy(path: &Path, shape: &[usize], data: &[f32]) -> Result<(), NpyError> {
    let io_err = |source| NpyError::Io {
        path: path.to_path_buf(),
        source,
    };
    let expected: usize = shape.iter().product();
    if expected != data.len() {
        return Err(NpyError::Unsupported {
            path: path.to_path_buf(),
            reason: format!(
                "shape {shape:?} needs {expected} values, got {}",
                data.len()
            ),
        });
    }
    crate::io::atomic::write_with(path, |buf| {
        let dims: Vec<u64> = shape.iter().map(|&d| d as u64).collect();
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(&dims)
            .writer(buf)
            .begin_nd()?;
        w.extend(data.iter().copied())?;
        w.finish()
    })
    .map_err(io_err)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A version-1 `.npy` file: the header dictionary `dict` (padded as
    /// NumPy pads it) followed by `data`.
    fn npy_bytes(dict: &str, data: &[u8]) -> Vec<u8> {
        let mut dict = dict.to_string();
        while !(10 + dict.len() + 1).is_multiple_of(64) {
            dict.push(' ');
        }
        dict.push('\n');
        let mut b = b"\x93NUMPY\x01\x00".to_vec();
        b.extend_from_slice(&(dict.len() as u16).to_le_bytes());
        b.extend_from_slice(dict.as_bytes());
        b.extend_from_slice(data);
        b
    }

    /// Found by the fuzzer: a multi-byte character where the error message
    /// cut the header.
    #[test]
    fn a_header_with_non_ascii_text_is_an_error_not_a_panic() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("u.npy");
        let dict = "{'descr': '<f4', 'fortran_order': Tru\u{b4}e, 'shape': (2,), }";
        std::fs::write(&p, npy_bytes(dict, &[0u8; 8])).unwrap();
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains("u.npy") && e.contains("fortran_order"), "{e}");
    }

    #[test]
    fn shapes_whose_product_overflows_or_exceeds_the_file_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.npy");
        for shape in ["(4611686019492773631, 7, 2)", "(4000000000, 512)", "(3, 3)"] {
            let dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
            std::fs::write(&p, npy_bytes(&dict, &[0u8; 16])).unwrap();
            let e = read_npy(&p).unwrap_err().to_string();
            assert!(
                e.contains("big.npy") && e.contains("needs more than"),
                "{shape}: {e}"
            );
        }
    }

    #[test]
    fn big_endian_half_and_double_arrays_read_as_f32() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("e.npy");
        let write = |descr: &str, data: &[u8]| {
            let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': (2,), }}");
            std::fs::write(&p, npy_bytes(&dict, data)).unwrap();
            read_npy(&p).unwrap().data
        };
        let be: Vec<u8> = [1.5f32, -2.0]
            .iter()
            .flat_map(|v| v.to_be_bytes())
            .collect();
        assert_eq!(write(">f4", &be), vec![1.5, -2.0]);
        let f8: Vec<u8> = [0.25f64, 3.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        assert_eq!(write("<f8", &f8), vec![0.25, 3.0]);
        let f2: Vec<u8> = [half::f16::from_f32(0.5), half::f16::from_f32(-1.0)]
            .iter()
            .flat_map(|v| v.to_bits().to_le_bytes())
            .collect();
        assert_eq!(write("<f2", &f2), vec![0.5, -1.0]);
    }

    #[test]
    fn round_trip_keeps_shape_and_values() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.npy");
        let data: Vec<f32> = (0..24).map(|i| i as f32 * 0.5 - 3.0).collect();
        write_npy(&p, &[2, 3, 4], &data).unwrap();
        let a = read_npy(&p).unwrap();
        assert_eq!(a.shape, vec![2, 3, 4]);
        assert_eq!(a.data, data);
        assert_eq!(a.as_matrix_dims(), (6, 4));
    }

    #[test]
    fn truncated_file_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.npy");
        write_npy(&p, &[10, 10], &[1.0; 100]).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 40]).unwrap();
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains("t.npy"), "{e}");
    }

    #[test]
    fn shape_mismatch_on_write_is_rejected() {
        let dir = tempfile::tempdir().unwrap();
        assert!(write_npy(&dir.path().join("x.npy"), &[3, 3], &[0.0; 8]).is_err());
        assert!(!dir.path().join("x.npy").exists());
    }
}
