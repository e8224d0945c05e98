//! RGB-D frames: 16-bit depth PNGs (TUM: 5000 units a metre; Replica:
//! 6553.5), label PNGs, intrinsics files, single-pose files, and the
//! back-projection of a depth image to camera-frame points.
//!
//! Camera frame: OpenCV (x right, y down, z forward), metres; depth is
//! z-depth. Pixel centres are at `(u + 0.5, v + 0.5)` as everywhere in the
//! crate, so intrinsics given in the integer-centre convention (TUM's
//! `cx = 319.5`) describe the same camera with `cx + 0.5`, `cy + 0.5`.

use std::path::Path;

use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use png::{BitDepth, ColorType, Transformations};

use super::bounded_png::open_png;

use crate::geometry::{Intrinsics, Pose};
use crate::io::cloud::{CloudError, PointCloud};

/// TUM RGB-D depth PNG units per metre.
pub const TUM_DEPTH_UNITS_PER_METRE: f64 = 5000.0;
/// Replica (NICE-SLAM layout) depth PNG units per metre.
pub const REPLICA_DEPTH_UNITS_PER_METRE: f64 = 6553.5;

/// A depth image: z-depth in metres, row-major, `0.0` where the sensor gave
/// no reading.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage {
    pub width: u32,
    pub height: u32,
    /// `width * height` depths, metres; 0 = invalid.
    pub depth: Vec<f32>,
}

/// Reads a 16-bit (or 8-bit) single-channel label PNG: one class id per
/// pixel, row-major.
pub fn read_label_png(path: &Path) -> Result<(u32, u32, Vec<u32>), CloudError> {
    let (info, buf) = open_png(path, Transformations::IDENTITY)?;
    if info.color_type != png::ColorType::Grayscale {
        return Err(CloudError::format(
            path,
            format!(
                "label image must be single-channel, got {:?}",
                info.color_type
            ),
        ));
    }
    let labels: Vec<u32> = match info.bit_depth {
        png::BitDepth::Sixteen => buf
            .chunks_exact(2)
            .map(|c| u16::from_be_bytes([c[0], c[1]]) as u32)
            .collect(),
        png::BitDepth::Eight => buf.iter().map(|&b| b as u32).collect(),
        d => {
            return Err(CloudError::format(
                path,
                format!("label image must have 8 or 16 bits, got {d:?}"),
            ));
        }
    };
    if labels.len() != info.width as usize * info.height as usize {
        return Err(CloudError::format(
            path,
            "label image size does not match its header",
        ));
    }
    Ok((info.width, info.height, labels))
}

/// A doubt about the scale a depth image was read at (`depth` in metres,
/// 0 for no reading; `units_per_metre` the scale): no valid depth at all,
/// or a median valid depth under 0.5 m or over 20 m, where RGB-D cameras
/// of rooms do not read (millimetres read at TUM's 5000 units a metre put
/// a 2.8 m room into a 1 m box). The words for a note, or `None`.
pub fn depth_scale_doubt(depth: &[f32], units_per_metre: f64) -> Option<String> {
    let mut valid: Vec<f32> = depth
        .iter()
        .copied()
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if valid.is_empty() {
        return Some("no pixel has a depth (all 0): is it the depth image?".into());
    }
    let mid = valid.len() / 2;
    let median = *valid.select_nth_unstable_by(mid, f32::total_cmp).1 as f64;
    if (0.5..=20.0).contains(&median) {
        return None;
    }
    // The scale that would put the median at about 2 m.
    let raw = median * units_per_metre;
    let hint = [1.0, 1000.0, 5000.0]
        .into_iter()
        .filter(|s| (0.5..=20.0).contains(&(raw / s)))
        .map(|s| format!("--depth-scale {s}"))
        .collect::<Vec<_>>();
    Some(format!(
        "its median depth is {median:.3} m at --depth-scale {units_per_metre} ({raw:.0} units); \
         RGB-D cameras of rooms read 0.5 to 20 m: is the depth in another unit{}?",
        if hint.is_empty() {
            String::new()
        } else {
            format!(" ({})", hint.join(" or "))
        }
    ))
}

/// Reads a 16-bit single-channel depth PNG; `units_per_metre` converts the
/// stored integers to metres (see the constants above). Zero stays zero
/// (invalid).
pub fn read_depth_png(path: &Path, units_per_metre: f64) -> Result<DepthImage, CloudError> {
    if !(units_per_metre.is_finite() && units_per_metre > 0.0) {
        return Err(CloudError::Invalid {
            source_name: path.display().to_string(),
            reason: format!("depth scale {units_per_metre} must be positive"),
        });
    }
    let (info, buf) = open_png(path, Transformations::IDENTITY)?;
    if info.color_type != ColorType::Grayscale || info.bit_depth != BitDepth::Sixteen {
        return Err(CloudError::format(
            path,
            format!(
                "depth PNG must be 16-bit grayscale, found {:?} {:?}",
                info.color_type, info.bit_depth
            ),
        ));
    }
    let scale = (1.0 / units_per_metre) as f32;
    // PNG stores 16-bit samples big-endian.
    let depth = buf
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]) as f32 * scale)
        .collect();
    Ok(DepthImage {
        width: info.width,
        height: info.height,
        depth,
    })
}

/// Why `dir` cannot be read as it is when it is a sequence as the TUM
/// RGB-D benchmark publishes it (`rgb.txt`, `depth.txt`, frames named by
/// timestamps, no `intrinsics.txt`), with what omcl needs instead.
pub fn raw_tum_layout(dir: &Path) -> Option<String> {
    let raw = dir.join("rgb.txt").is_file()
        && dir.join("depth.txt").is_file()
        && !dir.join("intrinsics.txt").exists();
    raw.then(|| {
        format!(
            "{}: a TUM RGB-D sequence as published (rgb.txt, depth.txt, frames named by \
             timestamps), which omcl does not read as it is: an RGB-D folder has \
             intrinsics.txt (`fx fy cx cy width height`; TUM's calibrated values for its \
             camera, the images undistorted for freiburg1 and 2), poses.txt (one TUM pose a \
             frame, e.g. groundtruth.txt at each colour frame's time) and rgb/NNNNNN.png, \
             depth/NNNNNN.png numbered from 000000 (pair the frames by time as TUM's \
             associate.py does)",
            dir.display()
        )
    })
}

/// Reads an intrinsics file: `fx fy cx cy width height` (whitespace
/// separated, `#` comments), pixels, pixel centres at `u + 0.5`.
pub fn read_intrinsics(path: &Path) -> Result<Intrinsics, CloudError> {
    let text = crate::io::bounded_read::read_text(path).map_err(|e| CloudError::io(path, e))?;
    let fields: Vec<&str> = text
        .lines()
        .map(|l| l.split('#').next().unwrap_or(""))
        .flat_map(str::split_whitespace)
        .collect();
    if fields.len() != 6 {
        return Err(CloudError::format(
            path,
            format!(
                "expected 6 values 'fx fy cx cy width height', found {}",
                fields.len()
            ),
        ));
    }
    let mut f = [0.0; 4];
    for (o, s) in f.iter_mut().zip(&fields[..4]) {
        *o = s
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| CloudError::format(path, format!("'{s}' is not a finite number")))?;
    }
    // A size written as a float ("640.0", as calibration tools print
    // them) is taken when whole.
    let dim = |s: &str| {
        s.parse::<u32>()
            .ok()
            .or_else(|| {
                s.parse::<f64>()
                    .ok()
                    .filter(|v| v.fract() == 0.0 && (1.0..=u32::MAX as f64).contains(v))
                    .map(|v| v as u32)
            })
            .filter(|v| *v > 0)
            .ok_or_else(|| {
                CloudError::format(
                    path,
                    format!("'{s}' is not a positive whole image size (pixels)"),
                )
            })
    };
    let (width, height) = (dim(fields[4])?, dim(fields[5])?);
    if f[0] <= 0.0 || f[1] <= 0.0 {
        return Err(CloudError::format(path, "focal lengths must be positive"));
    }
    let k = Intrinsics {
        fx: f[0],
        fy: f[1],
        cx: f[2],
        cy: f[3],
        width,
        height,
    };
    k.check().map_err(|why| CloudError::format(path, why))?;
    Ok(k)
}

/// Parses one TUM pose `tx ty tz qx qy qz qw` (an optional leading
/// timestamp makes 8 fields) into `world_from_camera`. The quaternion must
/// be within 1 % of unit length (files print 4 decimals) and is normalised.
pub fn parse_tum_pose(line: &str) -> Result<Pose, String> {
    let v: Vec<f64> = line
        .split_whitespace()
        .map(|s| {
            s.parse::<f64>()
                .map_err(|_| format!("'{s}' is not a number"))
        })
        .collect::<Result<_, _>>()?;
    let v = match v.len() {
        7 => &v[..],
        8 => &v[1..],
        n => {
            return Err(format!(
                "expected 7 numbers 'tx ty tz qx qy qz qw', found {n}"
            ));
        }
    };
    if v.iter().any(|x| !x.is_finite()) {
        return Err("non-finite value".into());
    }
    let q = Quaternion::new(v[6], v[3], v[4], v[5]);
    let n = q.norm();
    if (n - 1.0).abs() > 0.01 {
        return Err(format!("quaternion norm {n:.4} is not 1: not a rotation"));
    }
    Ok(Pose::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// Reads a file holding a single TUM pose line (`#` lines ignored).
pub fn read_single_tum_pose(path: &Path) -> Result<Pose, CloudError> {
    let text = crate::io::bounded_read::read_text(path).map_err(|e| CloudError::io(path, e))?;
    let line = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .ok_or_else(|| CloudError::format(path, "no pose line"))?;
    parse_tum_pose(line).map_err(|r| CloudError::format(path, r))
}

/// Camera-frame points of the valid pixels of `depth` (metres, OpenCV frame),
/// with the row-major pixel index of each. `depth` must match the intrinsics'
/// image size.
pub fn backproject(
    k: &Intrinsics,
    depth: &DepthImage,
) -> Result<(Vec<[f64; 3]>, Vec<u32>), String> {
    if depth.width != k.width || depth.height != k.height {
        return Err(format!(
            "depth image is {}x{}, intrinsics are for {}x{}",
            depth.width, depth.height, k.width, k.height
        ));
    }
    let mut points = Vec::with_capacity(depth.depth.len());
    let mut pixels = Vec::with_capacity(depth.depth.len());
    let w = depth.width as usize;
    for (i, &z) in depth.depth.iter().enumerate() {
        if !(z > 0.0 && z.is_finite()) {
            continue;
        }
        let p = k.back_project((i % w) as u32, (i / w) as u32, z as f64);
        points.push([p.x, p.y, p.z]);
        pixels.push(i as u32);
    }
    Ok((points, pixels))
}

/// Reads one RGB-D frame and returns its valid pixels as a coloured cloud in
/// the world frame (`world_from_camera` applied). Image sizes must match the
/// intrinsics; a frame with no valid depth is an error.
pub fn read_rgbd_frame(
    depth_path: &Path,
    color_path: &Path,
    k: &Intrinsics,
    units_per_metre: f64,
    world_from_camera: &Pose,
) -> Result<PointCloud, CloudError> {
    let depth = read_depth_png(depth_path, units_per_metre)?;
    let color = super::rgb::read_rgb(color_path)?;
    if (color.width(), color.height()) != (depth.width, depth.height) {
        return Err(CloudError::mismatch(
            color_path,
            format!(
                "colour image is {}x{}, depth image {} is {}x{}",
                color.width(),
                color.height(),
                depth_path.display(),
                depth.width,
                depth.height
            ),
        ));
    }
    let (points, pixels) =
        backproject(k, &depth).map_err(|r| CloudError::mismatch(depth_path, r))?;
    let raw = color.as_raw();
    let colors = pixels
        .iter()
        .map(|&i| {
            let j = i as usize * 3;
            [raw[j], raw[j + 1], raw[j + 2]]
        })
        .collect();
    let mut cloud = PointCloud {
        points,
        labels: None,
        colors: Some(colors),
        features: None,
        notes: Vec::new(),
        left_out: Vec::new(),
        georef: None,
    };
    cloud.transform(world_from_camera);
    cloud.non_empty(&depth_path.display().to_string(), "no valid depth pixel")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_depth_scale_off_by_a_unit_is_doubted() {
        // A room at 0.5 to 4 m, stored in millimetres.
        let mm: Vec<f32> = (500..4000).step_by(7).map(|v| v as f32).collect();
        let at = |scale: f64| -> Vec<f32> { mm.iter().map(|v| v / scale as f32).collect() };
        assert_eq!(depth_scale_doubt(&at(1000.0), 1000.0), None);
        let d = depth_scale_doubt(&at(5000.0), 5000.0).unwrap();
        assert!(
            d.contains("0.450 m") && d.contains("--depth-scale 1000"),
            "{d}"
        );
        let d = depth_scale_doubt(&at(1.0), 1.0).unwrap();
        assert!(
            d.contains("--depth-scale 1000") && !d.contains("scale 5000)"),
            "{d}"
        );
        let d = depth_scale_doubt(&[0.0; 16], 1000.0).unwrap();
        assert!(d.contains("no pixel has a depth"), "{d}");
    }
    use nalgebra::Point3;

    #[test]
    fn backprojection_inverts_projection() {
        let k = Intrinsics {
            fx: 500.0,
            fy: 400.0,
            cx: 2.0,
            cy: 1.5,
            width: 4,
            height: 3,
        };
        let mut depth = DepthImage {
            width: 4,
            height: 3,
            depth: vec![2.0; 12],
        };
        depth.depth[5] = 0.0;
        let (pts, px) = backproject(&k, &depth).unwrap();
        assert_eq!(pts.len(), 11);
        assert!(!px.contains(&5));
        for (p, &i) in pts.iter().zip(&px) {
            let (u, v) = k.project(&Point3::from(*p)).unwrap();
            assert_eq!((u.floor() as u32, v.floor() as u32), (i % 4, i / 4));
            assert!((u.fract() - 0.5).abs() < 1e-9 && (v.fract() - 0.5).abs() < 1e-9);
        }
        // Pixel (1, 2), centre (1.5, 2.5): x = (1.5 - 2) / 500 * 2,
        // y = (2.5 - 1.5) / 400 * 2.
        let j = px.iter().position(|&i| i == 2 * 4 + 1).unwrap();
        assert!((pts[j][0] + 0.002).abs() < 1e-12 && (pts[j][1] - 0.005).abs() < 1e-12);
    }

    #[test]
    fn intrinsics_sizes_may_be_whole_floats() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("k.txt");
        std::fs::write(&p, "525 525.5 319.5 239.5 640.0 480 # Kinect\n").unwrap();
        let k = read_intrinsics(&p).unwrap();
        assert_eq!((k.width, k.height, k.fy), (640, 480, 525.5));
        for bad in ["640.5", "0", "-640", "nan", "1e12"] {
            std::fs::write(&p, format!("525 525 319.5 239.5 {bad} 480")).unwrap();
            let e = read_intrinsics(&p).unwrap_err().to_string();
            assert!(
                e.contains(&format!("'{bad}' is not a positive whole image size")),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn tum_pose_parses_and_rejects_non_rotations() {
        let p = parse_tum_pose("1 2 3 0 0 0.7071068 0.7071068").unwrap();
        let q = p * Point3::new(1.0, 0.0, 0.0);
        assert!((q - Point3::new(1.0, 3.0, 3.0)).norm() < 1e-6);
        assert!(
            parse_tum_pose("0 0 0 0 0 0 2")
                .unwrap_err()
                .contains("norm")
        );
        assert!(parse_tum_pose("0 0 0 0 0 1").is_err());
        assert!(parse_tum_pose("0 0 inf 0 0 0 1").is_err());
    }
}
