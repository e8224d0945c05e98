//! KITTI / SemanticKITTI: velodyne scans, `.label` files, `calib.txt`,
//! `poses.txt`, and [`KittiSequence`], which puts scans into one world frame.
//!
//! Frames: a scan is in the LiDAR frame; `poses.txt` holds
//! `cam0_world_from_cam0_i` (left camera, KITTI camera frame: x right, y
//! down, z forward); `Tr` in `calib.txt` is `camera_from_lidar`. The LiDAR
//! pose of scan `i`, in the frame of the first LiDAR scan, is therefore
//! `world_from_lidar_i = Tr^-1 * P_i * Tr`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Matrix3x4, Translation3, UnitQuaternion, Vector3};

use crate::geometry::{Intrinsics, Pose};
use crate::io::cloud::{CloudError, PointCloud, voxel_downsample};
use crate::io::labels::{is_dropped_semantic_kitti, semantic_id};
use crate::io::poses::{PoseFormat, read_poses_in};

/// Largest accepted deviation of `R^T R` from identity in `Tr`; the same
/// bound as the pose files ([`crate::io::poses::ROTATION_TOLERANCE`]).
const RIGID_TOLERANCE: f64 = crate::io::poses::ROTATION_TOLERANCE;

/// Reads a velodyne `.bin` scan (float32 x, y, z, reflectance per point, in
/// metres, LiDAR frame). Reflectance is not kept. Errors when the size is not
/// a multiple of 16 bytes or a coordinate is not finite.
pub fn read_velodyne_bin(path: &Path) -> Result<PointCloud, CloudError> {
    let bytes = crate::io::bounded_read::read_regular(path).map_err(|e| CloudError::io(path, e))?;
    if bytes.len() % 16 != 0 {
        return Err(CloudError::format(
            path,
            format!(
                "size {} bytes is not a multiple of 16 (float32 x y z reflectance per point): \
                 truncated or not a velodyne scan",
                bytes.len()
            ),
        ));
    }
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64;
    let points: Vec<[f64; 3]> = bytes
        .chunks_exact(16)
        .map(|r| [f(&r[0..4]), f(&r[4..8]), f(&r[8..12])])
        .collect();
    let cloud = PointCloud::from_points(points);
    cloud.validate(&path.display().to_string())?;
    cloud.non_empty(&path.display().to_string(), "the scan holds no points")
}

/// Reads a SemanticKITTI `.label` file: one little-endian u32 a point
/// (semantic class in the low 16 bits, instance id in the high 16; see
/// [`crate::io::labels::semantic_id`]). `expected_points` is the scan's point
/// count; a different count is an error.
pub fn read_label_file(path: &Path, expected_points: usize) -> Result<Vec<u32>, CloudError> {
    let bytes = crate::io::bounded_read::read_regular(path).map_err(|e| CloudError::io(path, e))?;
    if bytes.len() % 4 != 0 {
        return Err(CloudError::format(
            path,
            format!(
                "size {} bytes is not a multiple of 4 (u32 labels)",
                bytes.len()
            ),
        ));
    }
    let n = bytes.len() / 4;
    if n != expected_points {
        return Err(CloudError::mismatch(
            path,
            format!("{n} labels for a scan of {expected_points} points"),
        ));
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect())
}

/// A rigid pose from a row-major 3x4 `[R | t]`; rejects non-finite values,
/// non-orthonormal `R` and reflections. `R` is re-orthonormalised so that
/// rounding in the file does not accumulate.
pub fn pose_from_3x4(m: &[f64; 12]) -> Result<Pose, String> {
    if let Some(v) = m.iter().find(|v| !v.is_finite()) {
        return Err(format!("non-finite value {v}"));
    }
    let r = Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
    let err = (r.transpose() * r - Matrix3::identity()).abs().max();
    if err > RIGID_TOLERANCE {
        return Err(format!(
            "rotation part is not orthonormal (|R^T R - I| = {err:.2e}): not a rigid pose"
        ));
    }
    if r.determinant() < 0.0 {
        return Err("rotation part is a reflection (det < 0): not a rigid pose".into());
    }
    Ok(Pose::from_parts(
        Translation3::new(m[3], m[7], m[11]),
        UnitQuaternion::from_matrix(&r),
    ))
}

fn parse_12(path: &Path, lineno: usize, fields: &[&str]) -> Result<[f64; 12], CloudError> {
    if fields.len() != 12 {
        return Err(CloudError::format(
            path,
            format!(
                "line {lineno}: expected 12 numbers (3x4 row-major), found {}",
                fields.len()
            ),
        ));
    }
    let mut out = [0.0; 12];
    for (o, s) in out.iter_mut().zip(fields) {
        *o = s.parse().map_err(|_| {
            CloudError::format(path, format!("line {lineno}: '{s}' is not a number"))
        })?;
    }
    Ok(out)
}

/// The SemanticKITTI label file of a single scan `NNNNNN.bin`: `labels`
/// when given, else `NNNNNN.label` beside the scan, else
/// `../labels/NNNNNN.label` (the dataset's own layout, the scan in
/// `velodyne/`); `None` when there is none.
pub fn label_path_for_scan(scan: &Path, labels: Option<&Path>) -> Option<PathBuf> {
    if let Some(l) = labels {
        return Some(l.to_path_buf());
    }
    let beside = scan.with_extension("label");
    if beside.is_file() {
        return Some(beside);
    }
    let name = scan.file_stem()?;
    let layout = scan
        .parent()?
        .parent()?
        .join("labels")
        .join(name)
        .with_extension("label");
    layout.is_file().then_some(layout)
}

/// Reads a single scan with its SemanticKITTI labels (see
/// [`label_path_for_scan`]): semantic ids (the low 16 bits) as the cloud's
/// labels, checked one a point. Without a label file the cloud has no
/// labels.
pub fn read_labelled_scan(scan: &Path, labels: Option<&Path>) -> Result<PointCloud, CloudError> {
    let mut cloud = read_velodyne_bin(scan)?;
    if let Some(lp) = label_path_for_scan(scan, labels) {
        let raw = read_label_file(&lp, cloud.len())?;
        cloud.labels = Some(raw.into_iter().map(semantic_id).collect());
    }
    Ok(cloud)
}

/// KITTI `calib.txt`: projection matrices and the LiDAR-to-camera transform.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiCalib {
    /// `P0..P3`: 3x4 projection matrices of the rectified cameras, pixels.
    pub projections: BTreeMap<String, Matrix3x4<f64>>,
    /// `Tr`: maps LiDAR coordinates to camera-0 coordinates.
    pub camera_from_lidar: Pose,
}

/// Reads `calib.txt` (`KEY: 12 numbers` lines; `Tr` required).
pub fn read_calib(path: &Path) -> Result<KittiCalib, CloudError> {
    let text = crate::io::bounded_read::read_text(path).map_err(|e| CloudError::io(path, e))?;
    parse_calib(&text, path)
}

/// Parses the text of a `calib.txt`; `path` names it in errors.
pub fn parse_calib(text: &str, path: &Path) -> Result<KittiCalib, CloudError> {
    let mut projections = BTreeMap::new();
    let mut tr = None;
    let mut seen: BTreeMap<&str, usize> = BTreeMap::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let Some((key, rest)) = line.split_once(':') else {
            return Err(CloudError::format(
                path,
                format!("line {}: expected 'KEY: 12 numbers'", i + 1),
            ));
        };
        // Which of two differing lines is right cannot be told.
        if let Some(first) = seen.insert(key, i + 1) {
            return Err(CloudError::format(
                path,
                format!("line {}: '{key}:' again (first on line {first})", i + 1),
            ));
        }
        let fields: Vec<&str> = rest.split_whitespace().collect();
        let m = parse_12(path, i + 1, &fields)?;
        if key == "Tr" || key == "Tr_velo_to_cam" {
            tr = Some(
                pose_from_3x4(&m)
                    .map_err(|r| CloudError::format(path, format!("line {}: Tr: {r}", i + 1)))?,
            );
        } else {
            if m.iter().any(|v| !v.is_finite()) {
                return Err(CloudError::format(
                    path,
                    format!("line {}: {key} has a non-finite value", i + 1),
                ));
            }
            projections.insert(key.to_string(), Matrix3x4::from_row_slice(&m));
        }
    }
    let camera_from_lidar =
        tr.ok_or_else(|| CloudError::format(path, "no 'Tr:' line (velodyne-to-camera)"))?;
    Ok(KittiCalib {
        projections,
        camera_from_lidar,
    })
}

/// Height of the KITTI car's Velodyne above the road, metres (the
/// dataset's set-up description: 1.73 m).
pub const VELODYNE_HEIGHT_M: f64 = 1.73;

/// Image size of KITTI odometry sequences 00 to 02 (camera 2), pixels.
pub const KITTI_IMAGE_SIZE: (u32, u32) = (1241, 376);

/// One rectified KITTI camera: its intrinsics and where it sits relative
/// to camera 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KittiCamera {
    /// Pinhole intrinsics in this project's convention (pixel centres at
    /// `u + 0.5`): `cx` and `cy` are `P[0][2] + 0.5` and `P[1][2] + 0.5`,
    /// since KITTI (like OpenCV) puts pixel centres at integers.
    pub intrinsics: Intrinsics,
    /// `camera0_from_camera`: a pure translation along camera-0 x by
    /// `-P[0][3] / P[0][0]` metres (KITTI camera 2: about 6 cm to the left,
    /// -0.0631 m). The rectified cameras share camera 0's orientation. The
    /// small y and z terms of `K^-1 P[:, 3]` (about 1 mm and 4 mm for
    /// camera 2) are ignored, as the KITTI devkit and pykitti do.
    pub camera0_from_camera: Pose,
}

impl KittiCalib {
    /// Camera `key` (`"P2"` for the left colour camera) of an image of
    /// `width x height` pixels. `path` names the calibration in errors: a
    /// missing key, a zero or negative focal length, a non-zero skew or a
    /// third row other than `(0, 0, 1, t)` is refused.
    pub fn camera(
        &self,
        key: &str,
        width: u32,
        height: u32,
        path: &Path,
    ) -> Result<KittiCamera, CloudError> {
        let Some(p) = self.projections.get(key) else {
            let have: Vec<&str> = self.projections.keys().map(String::as_str).collect();
            return Err(CloudError::format(
                path,
                format!(
                    "no '{key}:' line (the camera's 3x4 projection matrix); the file has {}",
                    if have.is_empty() {
                        "no projection matrices".to_string()
                    } else {
                        have.join(", ")
                    }
                ),
            ));
        };
        let (fx, fy) = (p[(0, 0)], p[(1, 1)]);
        if !(fx > 0.0 && fy > 0.0) {
            return Err(CloudError::format(
                path,
                format!("{key}: focal lengths {fx} and {fy} must be positive"),
            ));
        }
        let row3_ok = p[(2, 0)] == 0.0 && p[(2, 1)] == 0.0 && p[(2, 2)] == 1.0;
        if p[(0, 1)] != 0.0 || p[(1, 0)] != 0.0 || !row3_ok {
            return Err(CloudError::format(
                path,
                format!(
                    "{key}: not a rectified projection [fx 0 cx tx; 0 fy cy ty; 0 0 1 tz] \
                     (skew or third row differ)"
                ),
            ));
        }
        if width == 0 || height == 0 {
            return Err(CloudError::format(
                path,
                format!("{key}: image size {width}x{height} must be positive"),
            ));
        }
        let intrinsics = Intrinsics {
            fx,
            fy,
            cx: p[(0, 2)] + 0.5,
            cy: p[(1, 2)] + 0.5,
            width,
            height,
        };
        intrinsics
            .check()
            .map_err(|why| CloudError::format(path, format!("{key}: {why}")))?;
        Ok(KittiCamera {
            intrinsics,
            camera0_from_camera: Pose::translation(-p[(0, 3)] / fx, 0.0, 0.0),
        })
    }
}

/// Reads a KITTI pose file (one row-major 3x4 `world_from_camera` a line)
/// through [`crate::io::poses`], which rejects non-finite and non-rigid
/// poses with the file and line.
pub fn read_kitti_poses(path: &Path) -> Result<Vec<Pose>, CloudError> {
    let file = read_poses_in(path, PoseFormat::Kitti)?;
    Ok(file.trajectory.poses().to_vec())
}

/// One SemanticKITTI sequence directory (`velodyne/`, optional `labels/`,
/// `calib.txt`, `poses.txt`).
#[derive(Debug, Clone)]
pub struct KittiSequence {
    /// The sequence directory.
    pub dir: PathBuf,
    pub calib: KittiCalib,
    /// `cam0_world_from_cam0_i`, one per frame number.
    pub camera_poses: Vec<Pose>,
    /// Frame numbers of the scans present, ascending.
    pub frames: Vec<usize>,
}

/// What [`KittiSequence::aggregate`] keeps.
#[derive(Debug, Clone, PartialEq)]
pub struct AggregateOptions {
    /// Voxel edge in metres for down-sampling the merged map (first point
    /// per voxel kept); `None` keeps every point.
    pub voxel_size: Option<f64>,
    /// Drop unlabeled, outlier and moving points (needs label files).
    pub drop_unlabeled_outlier_moving: bool,
    /// Ignore points farther than this from the sensor (metres); `None` keeps
    /// all.
    pub max_range: Option<f64>,
    /// Directory of per-scan feature files `NNNNNN.npy` (`N x F`, one row a
    /// point of the scan, e.g. OpenScene features computed elsewhere);
    /// attached before filtering so rows stay with their points.
    pub features_dir: Option<PathBuf>,
}

impl Default for AggregateOptions {
    fn default() -> Self {
        AggregateOptions {
            voxel_size: Some(0.1),
            drop_unlabeled_outlier_moving: true,
            max_range: None,
            features_dir: None,
        }
    }
}

/// The `NNNNNN.ext` files of `folder` with their frame numbers, in frame
/// order; a file of that extension whose name is not six digits is an
/// error (`19.png` would be read as frame 19 and then looked for as
/// `000019.png`). Hidden files (macOS's `._000000.bin` beside each file
/// copied from its disks) are not frames and are passed over.
pub(crate) fn numbered_files(
    folder: &Path,
    ext: &str,
) -> Result<Vec<(usize, PathBuf)>, CloudError> {
    let entries = std::fs::read_dir(folder).map_err(|e| CloudError::io(folder, e))?;
    let mut frames = Vec::new();
    for entry in entries {
        let p = entry.map_err(|e| CloudError::io(folder, e))?.path();
        let hidden = p
            .file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with('.'));
        if hidden || p.extension().and_then(|e| e.to_str()) != Some(ext) {
            continue;
        }
        let frame = p
            .file_stem()
            .and_then(|s| s.to_str())
            .filter(|s| s.len() == 6 && s.bytes().all(|b| b.is_ascii_digit()))
            .and_then(|s| s.parse::<usize>().ok())
            .ok_or_else(|| {
                CloudError::format(
                    &p,
                    format!("file name is not a frame number (NNNNNN.{ext})"),
                )
            })?;
        frames.push((frame, p));
    }
    frames.sort_unstable();
    Ok(frames)
}

impl KittiSequence {
    /// Opens a sequence: reads calibration and poses and lists the scans.
    pub fn open(dir: &Path) -> Result<Self, CloudError> {
        check_sequence_folder(dir)?;
        check_near_misses(dir)?;
        let calib = read_calib(&dir.join("calib.txt"))?;
        let poses_path = dir.join("poses.txt");
        if let Some(there) = benchmark_poses(dir).filter(|_| !poses_path.exists()) {
            // Absolute: a relative target would be read from the link's
            // own folder, not from where the user types the command.
            let target = std::fs::canonicalize(&there).unwrap_or(there.clone());
            return Err(CloudError::format(
                &poses_path,
                format!(
                    "missing; the odometry benchmark's layout keeps this sequence's poses in \
                     {}: link it here (ln -s {} {})",
                    there.display(),
                    target.display(),
                    poses_path.display()
                ),
            ));
        }
        let camera_poses = read_kitti_poses(&poses_path)?;
        let vel = dir.join("velodyne");
        let mut frames = Vec::new();
        for (frame, p) in numbered_files(&vel, "bin")? {
            if frame >= camera_poses.len() {
                return Err(CloudError::mismatch(
                    &dir.join("poses.txt"),
                    format!(
                        "{} poses, but scan {} needs pose {frame}",
                        camera_poses.len(),
                        p.display()
                    ),
                ));
            }
            frames.push(frame);
        }
        if frames.is_empty() {
            return Err(CloudError::Empty {
                source_name: vel.display().to_string(),
                reason: "no .bin scans".into(),
            });
        }
        Ok(KittiSequence {
            dir: dir.to_path_buf(),
            calib,
            camera_poses,
            frames,
        })
    }

    /// Path of the scan of `frame`.
    pub fn scan_path(&self, frame: usize) -> PathBuf {
        self.dir.join("velodyne").join(format!("{frame:06}.bin"))
    }

    /// Path of the label file of `frame` (it may not exist).
    pub fn label_path(&self, frame: usize) -> PathBuf {
        self.dir.join("labels").join(format!("{frame:06}.label"))
    }

    /// `world_from_lidar` of `frame`: `Tr^-1 * P_frame * Tr`; the world is
    /// the first LiDAR frame of the sequence. `None` past the pose file.
    pub fn world_from_lidar(&self, frame: usize) -> Option<Pose> {
        let tr = &self.calib.camera_from_lidar;
        self.camera_poses.get(frame).map(|p| tr.inverse() * p * tr)
    }

    /// Scan `frame` in the world frame, with semantic ids (low 16 bits of
    /// the `.label` file) as labels when the label file exists.
    pub fn load_scan(&self, frame: usize) -> Result<PointCloud, CloudError> {
        let (cloud, _) = self.load_scan_with_range(frame)?;
        Ok(cloud)
    }

    /// As [`Self::load_scan`], also returning each point's range from the
    /// sensor in metres.
    fn load_scan_with_range(&self, frame: usize) -> Result<(PointCloud, Vec<f64>), CloudError> {
        let path = self.scan_path(frame);
        let mut cloud = read_velodyne_bin(&path)?;
        let range = cloud
            .points
            .iter()
            .map(|p| Vector3::from(*p).norm())
            .collect();
        let lp = self.label_path(frame);
        if lp.exists() {
            let raw = read_label_file(&lp, cloud.len())?;
            cloud.labels = Some(raw.into_iter().map(semantic_id).collect());
        }
        let pose = self.world_from_lidar(frame).ok_or_else(|| {
            CloudError::mismatch(
                &self.dir.join("poses.txt"),
                format!("no pose for frame {frame}"),
            )
        })?;
        cloud.transform(&pose);
        Ok((cloud, range))
    }

    /// Scan `frame` in the world frame, filtered as `opts` says (features
    /// attached, dropped classes and far points gone; no down-sampling).
    pub fn filtered_scan(
        &self,
        frame: usize,
        opts: &AggregateOptions,
    ) -> Result<PointCloud, CloudError> {
        let (mut scan, range) = self.load_scan_with_range(frame)?;
        if let Some(dir) = &opts.features_dir {
            scan.attach_features_npy(&dir.join(format!("{frame:06}.npy")))?;
        }
        if opts.drop_unlabeled_outlier_moving {
            let Some(labels) = scan.labels.as_ref() else {
                return Err(CloudError::mismatch(
                    &self.label_path(frame),
                    "missing: a SemanticKITTI sequence's labels/ give its points their \
                     classes (and mark the unlabeled, outlier and moving ones, which are \
                     left out); a sequence without labels maps from point features \
                     (--point-model ONNX or --features-dir DIR, with --keep-all)",
                ));
            };
            let keep: Vec<bool> = labels
                .iter()
                .map(|&l| !is_dropped_semantic_kitti(l))
                .collect();
            scan.retain_indices(|i| keep[i]);
            let kept_range: Vec<f64> = range
                .iter()
                .zip(&keep)
                .filter(|(_, k)| **k)
                .map(|(r, _)| *r)
                .collect();
            if let Some(max) = opts.max_range {
                scan.retain_indices(|i| kept_range[i] <= max);
            }
        } else if let Some(max) = opts.max_range {
            scan.retain_indices(|i| range[i] <= max);
        }
        Ok(scan)
    }

    /// Merges the scans of `frames` (all scans when empty) into one world-
    /// frame cloud, filtered and down-sampled as `opts` says. An empty result
    /// is an error.
    pub fn aggregate(
        &self,
        frames: &[usize],
        opts: &AggregateOptions,
    ) -> Result<PointCloud, CloudError> {
        let frames = if frames.is_empty() {
            &self.frames[..]
        } else {
            frames
        };
        let mut map = PointCloud::default();
        for &frame in frames {
            map.append(self.filtered_scan(frame, opts)?);
            // Down-sampling as we go bounds memory for long sequences.
            if let Some(v) = opts.voxel_size {
                voxel_downsample(&mut map, v);
            }
        }
        map.non_empty(
            &self.dir.display().to_string(),
            "no points left after filtering",
        )
    }
}

/// Refuses, by name, a sequence folder that is not there or not a
/// folder, and the KITTI dataset's root (a `sequences/` folder inside and
/// no `calib.txt`) with the way to one of its sequences: a typo or the
/// root otherwise read as a folder missing `calib.txt` or `intrinsics.txt`.
pub fn check_sequence_folder(dir: &Path) -> Result<(), CloudError> {
    if !dir.exists() {
        return Err(CloudError::format(dir, "no such folder"));
    }
    if !dir.is_dir() {
        return Err(CloudError::format(
            dir,
            "not a folder (a sequence is a folder)",
        ));
    }
    let sequences = dir.join("sequences");
    if sequences.is_dir() && !dir.join("calib.txt").exists() {
        let mut names: Vec<String> = std::fs::read_dir(&sequences)
            .map(|d| {
                d.filter_map(|e| e.ok())
                    .filter(|e| e.path().is_dir())
                    .filter_map(|e| e.file_name().to_str().map(str::to_string))
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        let example = names.first().map_or("00", String::as_str);
        return Err(CloudError::format(
            dir,
            format!(
                "a KITTI dataset's root (sequences/ holds {}); give one sequence's folder, \
                 e.g. {}",
                names.len(),
                sequences.join(example).display()
            ),
        ));
    }
    Ok(())
}

/// Makes `into` (a copy's folder, where `omcl map project -o
/// into/labels_2` wrote the label images) open as the sequence `seq`:
/// links `seq`'s `calib.txt`, `poses.txt`, `times.txt` and `velodyne/`
/// (whose first scan `omcl localize` checks the map against) into it where
/// `into` has nothing of that name. Returns the names linked.
pub fn link_sequence_files(seq: &Path, into: &Path) -> std::io::Result<Vec<&'static str>> {
    let mut linked = Vec::new();
    for name in ["calib.txt", "poses.txt", "times.txt", "velodyne"] {
        let (from, to) = (seq.join(name), into.join(name));
        let there = if name == "velodyne" {
            from.is_dir()
        } else {
            from.is_file()
        };
        if there && std::fs::symlink_metadata(&to).is_err() {
            std::os::unix::fs::symlink(std::path::absolute(&from)?, &to)?;
            linked.push(name);
        }
    }
    Ok(linked)
}

/// Where KITTI's odometry benchmark keeps the poses of the sequence
/// `.../sequences/NN` (`.../poses/NN.txt`, not in the sequence's folder),
/// when that file is there.
pub fn benchmark_poses(dir: &Path) -> Option<PathBuf> {
    let name = dir.file_name()?.to_str()?;
    let sequences = dir.parent()?;
    if sequences.file_name()? != "sequences" {
        return None;
    }
    let poses = sequences
        .parent()?
        .join("poses")
        .join(format!("{name}.txt"));
    poses.is_file().then_some(poses)
}

/// The near misses of a KITTI sequence folder that any reader of one
/// names before `calib.txt` is found missing: a folder of sequences (the
/// `sequences/` folder itself), a folder inside a sequence (`velodyne/`,
/// `labels_2/`).
pub fn check_kitti_near_misses(dir: &Path) -> Result<(), CloudError> {
    if dir.join("calib.txt").exists() {
        return Ok(());
    }
    let mut sequences: Vec<String> = std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .filter(|e| e.path().join("calib.txt").is_file())
                .filter_map(|e| e.file_name().to_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default();
    sequences.sort();
    if let Some(first) = sequences.first() {
        return Err(CloudError::format(
            dir,
            format!(
                "a folder of KITTI sequences ({} of them); give one sequence's folder, e.g. {}",
                sequences.len(),
                dir.join(first).display()
            ),
        ));
    }
    if let Some(seq) = dir.parent().filter(|p| p.join("calib.txt").is_file()) {
        return Err(CloudError::format(
            dir,
            format!(
                "a folder inside the KITTI sequence {}; give the sequence's folder",
                seq.display()
            ),
        ));
    }
    Ok(())
}

/// A LiDAR sequence folder's near misses, named before `calib.txt` is
/// found missing: the `sequences/` folder itself, a sequence's subfolder
/// (`velodyne/`), a folder of point-cloud files (LAS tiles).
fn check_near_misses(dir: &Path) -> Result<(), CloudError> {
    if dir.join("calib.txt").exists() {
        return Ok(());
    }
    check_kitti_near_misses(dir)?;
    let clouds = std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .filter(|e| {
                    let p = e.path();
                    let ext = p.extension().and_then(|x| x.to_str()).unwrap_or("");
                    let hidden = e.file_name().to_string_lossy().starts_with('.');
                    !hidden
                        && ["las", "laz", "ply"]
                            .iter()
                            .any(|k| ext.eq_ignore_ascii_case(k))
                })
                .count()
        })
        .unwrap_or(0);
    if clouds == 0 && !dir.join("velodyne").is_dir() {
        return Err(CloudError::format(
            dir,
            "neither a KITTI sequence (no calib.txt, no velodyne/) nor a folder of LAS/LAZ or \
             PLY tiles (none in it; subfolders and hidden files are not read)",
        ));
    }
    if clouds > 0 {
        return Err(CloudError::format(
            dir,
            format!(
                "a folder of {clouds} point-cloud files, not a KITTI sequence (no calib.txt): \
                 a folder of tiles is mapped together when they are all LAS/LAZ or all PLY, \
                 not both (give one kind, or one file)"
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rigid_check_accepts_rotation_and_rejects_scale_and_reflection() {
        let ok = [0.0, -1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0, 1.0, 3.0];
        let p = pose_from_3x4(&ok).unwrap();
        let q = p * nalgebra::Point3::new(1.0, 0.0, 0.0);
        assert!((q - nalgebra::Point3::new(1.0, 3.0, 3.0)).norm() < 1e-12);
        let scaled = [2.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        assert!(pose_from_3x4(&scaled).unwrap_err().contains("not a rigid"));
        let mirror = [-1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        assert!(pose_from_3x4(&mirror).unwrap_err().contains("reflection"));
        let mut nan = ok;
        nan[3] = f64::NAN;
        assert!(pose_from_3x4(&nan).unwrap_err().contains("non-finite"));
    }
}
