//! ScanNet point clouds as mmdetection3d stores them: a headerless `.bin` of
//! float32 rows `x y z r g b` (metres in the scan's frame, colour 0-255).

use std::path::Path;

use crate::io::cloud::{CloudError, PointCloud};

/// Reads a float32 `x y z r g b` `.bin`. The size must be a multiple of 24
/// bytes; colours must lie in 0-255 (rounded to the nearest integer).
pub fn read_scannet_xyzrgb_bin(path: &Path) -> Result<PointCloud, CloudError> {
    let bytes = crate::io::bounded_read::read_regular(path).map_err(|e| CloudError::io(path, e))?;
    if bytes.len() % 24 != 0 {
        return Err(CloudError::format(
            path,
            format!(
                "size {} bytes is not a multiple of 24 (float32 x y z r g b per point): \
                 truncated or another layout",
                bytes.len()
            ),
        ));
    }
    let n = bytes.len() / 24;
    let mut points = Vec::with_capacity(n);
    let mut colors = Vec::with_capacity(n);
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    for (i, r) in bytes.chunks_exact(24).enumerate() {
        points.push([f(&r[0..4]) as f64, f(&r[4..8]) as f64, f(&r[8..12]) as f64]);
        let mut c = [0u8; 3];
        for (k, ch) in c.iter_mut().enumerate() {
            let v = f(&r[12 + 4 * k..16 + 4 * k]);
            if !(-0.5..255.5).contains(&v) {
                return Err(CloudError::format(
                    path,
                    format!("point {i}: colour channel {k} is {v}, expected 0-255"),
                ));
            }
            *ch = v.round() as u8;
        }
        colors.push(c);
    }
    let cloud = PointCloud {
        points,
        labels: None,
        colors: Some(colors),
        features: None,
        notes: Vec::new(),
        left_out: Vec::new(),
        georef: None,
    };
    cloud.validate(&path.display().to_string())?;
    cloud.non_empty(&path.display().to_string(), "the file holds no points")
}
