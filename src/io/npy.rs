//! NumPy `.npy` matrices: per-frame feature maps, per-point features and
//! embedding tables are exchanged with Python tools in this format.
//!
//! Reading accepts little- and big-endian `f2`, `f4` and `f8` arrays in C
//! order and returns `f32`; writing produces little-endian `f4`.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use npyz::{DType, NpyFile, TypeChar, WriterBuilder};

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

/// Reads a floating-point `.npy` file as `f32`.
pub fn read_npy(path: &Path) -> Result<NpyArray, NpyError> {
    let io_err = |source| NpyError::Io {
        path: path.to_path_buf(),
        source,
    };
    let fmt = |reason: String| NpyError::Format {
        path: path.to_path_buf(),
        reason,
    };
    let unsupported = |reason: String| NpyError::Unsupported {
        path: path.to_path_buf(),
        reason,
    };
    let file = File::open(path).map_err(io_err)?;
    let npy = NpyFile::new(BufReader::new(file)).map_err(|e| fmt(e.to_string()))?;
    if npy.order() != npyz::Order::C {
        return Err(unsupported(
            "Fortran order; save with np.ascontiguousarray".into(),
        ));
    }
    let shape: Vec<usize> = npy.shape().iter().map(|&d| d as usize).collect();
    let expected: usize = shape.iter().product();
    let kind = match npy.dtype() {
        DType::Plain(ts) if ts.type_char() == TypeChar::Float => ts.size_field(),
        other => {
            return Err(unsupported(format!(
                "dtype {} (expected float16, float32 or float64)",
                other.descr()
            )));
        }
    };
    let data: Vec<f32> = match kind {
        2 => npy
            .into_vec::<half::f16>()
            .map(|v| v.into_iter().map(f32::from).collect()),
        4 => npy.into_vec::<f32>(),
        8 => npy
            .into_vec::<f64>()
            .map(|v| v.into_iter().map(|x| x as f32).collect()),
        n => return Err(unsupported(format!("float of {n} bytes"))),
    }
    .map_err(|e| fmt(format!("truncated or corrupt data: {e}")))?;
    if data.len() != expected {
        return Err(fmt(format!(
            "shape {shape:?} needs {expected} values, file holds {}",
            data.len()
        )));
    }
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
