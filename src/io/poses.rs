//! Pose files in the two formats evo and most SLAM tools read and write.
//!
//! - TUM: `t tx ty tz qx qy qz qw` a line (seconds, metres, unit quaternion
//!   with the scalar last); lines starting with `#` are comments.
//! - KITTI: 12 numbers a line, the first three rows of the 4x4
//!   `world_from_camera` matrix in row-major order; no time stamps (a KITTI
//!   sequence keeps them in a separate `times.txt`, see [`read_times`]).
//!
//! Both poses are `world_from_camera`. Values may be separated by spaces, tabs
//! or commas. The format is detected from the number of columns of the first
//! data line. Rotations are checked, then projected onto the nearest rotation
//! (files print only a few digits, so they are never exactly orthonormal);
//! a rotation further than [`ROTATION_TOLERANCE`] from rigid is an error.
//! Writing uses Rust's shortest round-trip float format, so a written file
//! reads back bit for bit, and goes through a temporary file renamed into
//! place.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Quaternion, Rotation3, Translation3, UnitQuaternion};

use crate::geometry::Pose;
use crate::trajectory::{Trajectory, TrajectoryError};

/// Largest accepted deviation from a rigid rotation: the largest entry of
/// `R^T R - I` for a KITTI matrix, `| |q| - 1 |` for a TUM quaternion.
/// Files printed with four decimals stay well inside it; a scaled or sheared
/// matrix does not.
pub const ROTATION_TOLERANCE: f64 = 1e-3;

/// The two pose file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum PoseFormat {
    /// `t tx ty tz qx qy qz qw` (8 columns).
    Tum,
    /// Row-major 3x4 matrix (12 columns), no stamps.
    Kitti,
}

impl PoseFormat {
    /// Whether files of this format carry time stamps.
    pub fn has_stamps(self) -> bool {
        matches!(self, PoseFormat::Tum)
    }

    fn columns(self) -> usize {
        match self {
            PoseFormat::Tum => 8,
            PoseFormat::Kitti => 12,
        }
    }
}

impl std::fmt::Display for PoseFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PoseFormat::Tum => "TUM",
            PoseFormat::Kitti => "KITTI",
        })
    }
}

/// Errors of pose-file reading and writing; each names the file and, where
/// there is one, the 1-based line.
#[derive(Debug, thiserror::Error)]
pub enum PosesError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}:{line}: {reason}")]
    Parse {
        path: PathBuf,
        line: usize,
        reason: String,
    },
    #[error("{path}: no poses (only comments or blank lines)")]
    Empty { path: PathBuf },
    #[error("{path}: {source}")]
    Trajectory {
        path: PathBuf,
        source: TrajectoryError,
    },
}

/// A pose file's trajectory and the format it was read in. Trajectories read
/// from KITTI files have the frame indices 0, 1, 2, ... as stamps.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseFile {
    pub format: PoseFormat,
    pub trajectory: Trajectory,
}

/// Reads a TUM or KITTI pose file, detecting the format from the column count
/// (8: TUM, 12: KITTI).
pub fn read_poses(path: &Path) -> Result<PoseFile, PosesError> {
    read_poses_as(path, None)
}

/// Reads a pose file that must be in `format`.
pub fn read_poses_in(path: &Path, format: PoseFormat) -> Result<PoseFile, PosesError> {
    read_poses_as(path, Some(format))
}

fn read_poses_as(path: &Path, expected: Option<PoseFormat>) -> Result<PoseFile, PosesError> {
    let text = crate::io::bounded_read::read_text(path).map_err(|source| PosesError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_poses(&text, path, expected)
}

/// Parses pose-file text; `path` is only used in error messages.
pub fn parse_poses(
    text: &str,
    path: &Path,
    expected: Option<PoseFormat>,
) -> Result<PoseFile, PosesError> {
    let parse_err = |line: usize, reason: String| PosesError::Parse {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut format = expected;
    let mut stamps = Vec::new();
    let mut poses = Vec::new();
    let mut values = Vec::with_capacity(12);
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.trim().trim_start_matches('\u{feff}');
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        numbers(line, &mut values).map_err(|r| parse_err(line_no, r))?;
        let fmt = match format {
            Some(f) => f,
            None => *format.insert(format_of(values.len()).map_err(|r| parse_err(line_no, r))?),
        };
        if values.len() != fmt.columns() {
            return Err(parse_err(
                line_no,
                format!(
                    "{} columns, expected {} for a {fmt} file",
                    values.len(),
                    fmt.columns()
                ),
            ));
        }
        let pose = match fmt {
            PoseFormat::Tum => {
                if let Some(why) = goes_back(&stamps, values[0]) {
                    return Err(parse_err(line_no, why));
                }
                stamps.push(values[0]);
                tum_pose(&values[1..]).map_err(|r| parse_err(line_no, r))?
            }
            PoseFormat::Kitti => {
                stamps.push(poses.len() as f64);
                kitti_pose(&values).map_err(|r| parse_err(line_no, r))?
            }
        };
        poses.push(pose);
    }
    let Some(format) = format.filter(|_| !poses.is_empty()) else {
        return Err(PosesError::Empty {
            path: path.to_path_buf(),
        });
    };
    let trajectory = Trajectory::new(stamps, poses).map_err(|source| PosesError::Trajectory {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(PoseFile { format, trajectory })
}

/// A line's numbers (separated by white space or commas) into `values`;
/// each must be finite.
fn numbers(line: &str, values: &mut Vec<f64>) -> Result<(), String> {
    values.clear();
    for (col, tok) in line
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty())
        .enumerate()
    {
        let v: f64 = tok
            .parse()
            .map_err(|_| format!("column {}: '{tok}' is not a number", col + 1))?;
        if !v.is_finite() {
            return Err(format!("column {}: '{tok}' is not finite", col + 1));
        }
        values.push(v);
    }
    Ok(())
}

/// The format a first line of `n` columns says.
fn format_of(n: usize) -> Result<PoseFormat, String> {
    match n {
        8 => Ok(PoseFormat::Tum),
        12 => Ok(PoseFormat::Kitti),
        n => Err(format!(
            "{n} columns: expected 8 (TUM: t tx ty tz qx qy qz qw) \
             or 12 (KITTI: row-major 3x4 matrix)"
        )),
    }
}

/// `tx ty tz qx qy qz qw` to a pose, normalizing the quaternion.
fn tum_pose(v: &[f64]) -> Result<Pose, String> {
    let q = Quaternion::new(v[6], v[3], v[4], v[5]);
    let norm = q.norm();
    if (norm - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(format!(
            "quaternion (qx qy qz qw) = ({} {} {} {}) has norm {norm}, expected 1 within {ROTATION_TOLERANCE}",
            v[3], v[4], v[5], v[6]
        ));
    }
    Ok(Pose::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// Row-major 3x4 to a pose, projecting the rotation onto SO(3).
fn kitti_pose(v: &[f64]) -> Result<Pose, String> {
    let r = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
    let deviation = (r.transpose() * r - Matrix3::identity()).abs().max();
    let det = r.determinant();
    if deviation > ROTATION_TOLERANCE || det <= 0.0 {
        // Three significant digits whatever the size (1e300 printed 300).
        return Err(format!(
            "rotation part is not a rotation: max |R^T R - I| = {deviation:.3e} \
             (tolerance {ROTATION_TOLERANCE}), det = {det:.3e}"
        ));
    }
    let rotation = nearest_rotation(&r).ok_or_else(|| "rotation part is degenerate".to_string())?;
    Ok(Pose::from_parts(
        Translation3::new(v[3], v[7], v[11]),
        UnitQuaternion::from_rotation_matrix(&rotation),
    ))
}

/// The rotation closest to `m` in the Frobenius norm (`U V^T` of its SVD,
/// with the sign fixed so the determinant is +1).
fn nearest_rotation(m: &Matrix3<f64>) -> Option<Rotation3<f64>> {
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    Some(Rotation3::from_matrix_unchecked(u * d * v_t))
}

/// Reads a KITTI `times.txt`: one time stamp (seconds) a line.
pub fn read_times(path: &Path) -> Result<Vec<f64>, PosesError> {
    let text = crate::io::bounded_read::read_text(path).map_err(|source| PosesError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let v: f64 = line
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| PosesError::Parse {
                path: path.to_path_buf(),
                line: i + 1,
                reason: format!("'{line}' is not a finite time stamp (one number a line)"),
            })?;
        if let Some(reason) = goes_back(&out, v) {
            return Err(PosesError::Parse {
                path: path.to_path_buf(),
                line: i + 1,
                reason,
            });
        }
        out.push(v);
    }
    Ok(out)
}

/// Why `stamp` cannot follow `stamps` (it is before the last), if it
/// cannot.
fn goes_back(stamps: &[f64], stamp: f64) -> Option<String> {
    let &prev = stamps.last()?;
    (stamp < prev).then(|| {
        format!(
            "time stamp {stamp} s is before the previous one, {prev} s (stamps must not decrease)"
        )
    })
}

/// Formats a trajectory as pose-file text (no comment header, so that every
/// tool reads it).
pub fn format_poses(trajectory: &Trajectory, format: PoseFormat) -> String {
    let mut s = String::with_capacity(trajectory.len() * 120);
    for (t, p) in trajectory.stamps().iter().zip(trajectory.poses()) {
        let x = &p.translation.vector;
        // `write!` into a String cannot fail.
        let _ = match format {
            PoseFormat::Tum => {
                let q = p.rotation.quaternion();
                writeln!(
                    s,
                    "{t} {} {} {} {} {} {} {}",
                    x.x, x.y, x.z, q.i, q.j, q.k, q.w
                )
            }
            PoseFormat::Kitti => {
                let r = p.rotation.to_rotation_matrix();
                let r = r.matrix();
                writeln!(
                    s,
                    "{} {} {} {} {} {} {} {} {} {} {} {}",
                    r[(0, 0)],
                    r[(0, 1)],
                    r[(0, 2)],
                    x.x,
                    r[(1, 0)],
                    r[(1, 1)],
                    r[(1, 2)],
                    x.y,
                    r[(2, 0)],
                    r[(2, 1)],
                    r[(2, 2)],
                    x.z
                )
            }
        };
    }
    s
}

/// Writes a trajectory as a TUM or KITTI file (KITTI drops the stamps),
/// atomically: through a temporary file in the same directory renamed into
/// place, so a failed write leaves any existing file untouched.
pub fn write_poses(
    path: &Path,
    trajectory: &Trajectory,
    format: PoseFormat,
) -> Result<(), PosesError> {
    write_atomic(path, format_poses(trajectory, format).as_bytes())
}

/// Writes `bytes` to `path` through a temporary file renamed into place.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), PosesError> {
    crate::io::atomic::write(path, bytes).map_err(|source| PosesError::Io {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<PoseFile, PosesError> {
        parse_poses(text, Path::new("mem.txt"), None)
    }

    #[test]
    fn detects_tum_and_skips_comments() {
        let f =
            parse("# header\n\n1.5 1 2 3 0 0 0 1\n2.5,4,5,6,0,0,0.7071068,0.7071068\n").unwrap();
        assert_eq!(f.format, PoseFormat::Tum);
        assert_eq!(f.trajectory.stamps(), &[1.5, 2.5]);
        let p = f.trajectory.poses()[1];
        assert_eq!(p.translation.vector.z, 6.0);
        // 90 degrees about z maps x to y.
        let y = p.rotation * nalgebra::Vector3::x();
        assert!((y - nalgebra::Vector3::y()).norm() < 1e-6);
    }

    #[test]
    fn detects_kitti_and_orthonormalizes() {
        // A rotation about z by 90 degrees printed with 7 digits.
        let f = parse("0 -1.000000 0 1  1.0000001 0 0 2  0 0 1 3\n").unwrap();
        assert_eq!(f.format, PoseFormat::Kitti);
        assert_eq!(f.trajectory.stamps(), &[0.0]);
        let p = f.trajectory.poses()[0];
        assert_eq!(p.translation.vector, nalgebra::Vector3::new(1.0, 2.0, 3.0));
        let m = p.rotation.to_rotation_matrix();
        assert!(
            (m.matrix() - Matrix3::new(0., -1., 0., 1., 0., 0., 0., 0., 1.))
                .abs()
                .max()
                < 1e-12
        );
    }

    #[test]
    fn errors_name_file_line_and_problem() {
        let e = parse("1 2 3 0 0 0 1\n").unwrap_err().to_string();
        assert!(
            e.starts_with("mem.txt:1:") && e.contains("7 columns"),
            "{e}"
        );
        let e = parse("# c\n0 1 2 3 0 0 0 1\n1 1 2 3 0 0 0\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("mem.txt:3:") && e.contains("expected 8"),
            "{e}"
        );
        let e = parse("0 1 2 nan 0 0 0 1\n").unwrap_err().to_string();
        assert!(e.contains("column 4") && e.contains("not finite"), "{e}");
        let e = parse("0 1 2 x 0 0 0 1\n").unwrap_err().to_string();
        assert!(e.contains("'x' is not a number"), "{e}");
        let e = parse("0 1 2 3 0 0 0 0.5\n").unwrap_err().to_string();
        assert!(e.contains("norm 0.5"), "{e}");
        // A uniformly scaled matrix is a similarity, not a rotation.
        let e = parse("2 0 0 0 0 2 0 0 0 0 2 0\n").unwrap_err().to_string();
        assert!(e.contains("not a rotation"), "{e}");
        // A reflection.
        let e = parse("-1 0 0 0 0 1 0 0 0 0 1 0\n").unwrap_err().to_string();
        assert!(e.contains("not a rotation"), "{e}");
        let e = parse("1 0 0 0 0 0 0 1\n0 0 0 0 0 0 0 1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("mem.txt:2:") && e.contains("before the previous one"),
            "{e}"
        );
        assert!(matches!(parse("# only\n"), Err(PosesError::Empty { .. })));
        let e = parse_poses(
            "0 1 2 3 0 0 0 1\n",
            Path::new("k.txt"),
            Some(PoseFormat::Kitti),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("expected 12 for a KITTI file"), "{e}");
    }

    #[test]
    fn write_then_read_is_exact() {
        let f =
            parse("0.25 1 2 3 0.1 0.2 0.3 0.9273618495495703\n7.75 -1 0.5 1e-3 0 0 0 1\n").unwrap();
        let dir = tempfile::tempdir().unwrap();
        for format in [PoseFormat::Tum, PoseFormat::Kitti] {
            let p = dir.path().join("out.txt");
            write_poses(&p, &f.trajectory, format).unwrap();
            let back = read_poses(&p).unwrap();
            assert_eq!(back.format, format);
            for (a, b) in back.trajectory.poses().iter().zip(f.trajectory.poses()) {
                assert_eq!(a.translation, b.translation);
                assert!(a.rotation.angle_to(&b.rotation) < 1e-12);
            }
            if format == PoseFormat::Tum {
                assert_eq!(back.trajectory, f.trajectory);
            }
        }
    }

    #[test]
    fn times_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("times.txt");
        std::fs::write(&p, "0.000000e+00\n1.037359e-01\n").unwrap();
        assert_eq!(read_times(&p).unwrap(), vec![0.0, 0.1037359]);
        std::fs::write(&p, "0\noops\n").unwrap();
        let e = read_times(&p).unwrap_err().to_string();
        assert!(e.contains("times.txt:2:"), "{e}");
    }
}
