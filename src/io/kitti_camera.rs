//! A KITTI odometry sequence as camera 2 sees it, read as it is on disk:
//! `calib.txt` (camera 2 from `P2`, `Tr`), `poses.txt` (camera 0, KITTI
//! camera frame, relative to the first camera), optional `times.txt`, and
//! one input a frame in one of
//!
//! ```text
//! labels_2/NNNNNN.png    16-bit class ids (ground-truth mode), with
//!                        classes.txt (`<id> <name>` or one name a line)
//!                        and embeddings.npy (K x F) in the sequence folder
//! features_2/NNNNNN.npy  f32 h x w x F per-pixel features (any h x w; a
//!                        pixel takes the nearest cell)
//! image_2/NNNNNN.png     RGB, for an image encoder
//! ```
//!
//! Frames: the map of a SemanticKITTI sequence (`omcl map cloud` of the
//! folder) lives in the first LiDAR frame, `world = Tr^-1 * cam0_world`, so
//! camera 2 of frame `i` sits at `world_from_cam2_i = Tr^-1 * P_i * C` with
//! `C = camera0_from_camera2` (a 6 cm shift along camera-0 x).

use std::path::{Path, PathBuf};

use super::cloud::CloudError;
use super::kitti::{
    KITTI_IMAGE_SIZE, KittiCalib, KittiCamera, numbered_files, read_calib, read_kitti_poses,
};
use super::poses::read_times;
use super::rgb::read_rgb;
use super::rgbd::read_label_png;
use crate::geometry::Pose;

/// The size of camera 2's images when the sequence has them
/// (`image_2/000000.png`, its header read): KITTI's sequences differ
/// (1241 x 376 for 00-02, 1226 x 370 for 04-10). `None` without images.
pub fn camera2_image_size(dir: &Path) -> Result<Option<(u32, u32)>, CloudError> {
    let first = dir.join("image_2").join("000000.png");
    if !first.exists() {
        return Ok(None);
    }
    let bytes = std::fs::read(&first).map_err(|e| CloudError::io(&first, e))?;
    super::rgb::image_size(&bytes, &first).map(Some)
}

/// What camera 2 gives the localizer per frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraInput {
    /// `labels_2/NNNNNN.png` with the sequence's class table.
    Labels,
    /// `features_2/NNNNNN.npy`.
    Features,
    /// `image_2/NNNNNN.png` (an image encoder turns them into features).
    Images,
}

impl CameraInput {
    /// The folder of the input, inside the sequence folder.
    pub fn folder(self) -> &'static str {
        match self {
            CameraInput::Labels => "labels_2",
            CameraInput::Features => "features_2",
            CameraInput::Images => "image_2",
        }
    }

    /// The extension of its frame files.
    pub fn extension(self) -> &'static str {
        match self {
            CameraInput::Features => "npy",
            CameraInput::Labels | CameraInput::Images => "png",
        }
    }
}

/// One KITTI odometry sequence folder for camera-2 localization.
#[derive(Debug, Clone)]
pub struct KittiCameraSequence {
    pub dir: PathBuf,
    pub calib: KittiCalib,
    /// Camera 2: intrinsics (image size from frame 0's image, else
    /// [`KITTI_IMAGE_SIZE`]) and `camera0_from_camera2`.
    pub camera: KittiCamera,
    /// `poses.txt`: camera 0 of every frame, KITTI camera frame; `None`
    /// without the file (KITTI's test sequences 11-21 have none: such a
    /// sequence is localized from a given odometry and start, and not
    /// evaluated).
    pub camera0_poses: Option<Vec<Pose>>,
    /// `times.txt` (seconds), or `0.1 s` a frame when it is missing.
    pub times: Vec<f64>,
    /// Whether `times` came from `times.txt`.
    pub times_in_file: bool,
    pub input: CameraInput,
    /// Poses in `poses.txt`: more than the frames when the folder holds
    /// only the sequence's first frames (whose poses are kept); `None`
    /// without the file.
    pub poses_in_file: Option<usize>,
    /// Frames in the input folder (`000000` to `frames - 1`).
    frames: usize,
}

impl KittiCameraSequence {
    /// Opens `dir` for `input`: reads the calibration (a missing `P2` is
    /// an error naming `calib.txt`), the poses (when `poses.txt` is
    /// there) and times, and checks that the input folder holds frames
    /// `000000`, `000001`, ... without a gap: all of the sequence's or
    /// its first ones (a copy of the first scans), whose poses and times
    /// are kept; more frames than poses, or none, is an error naming both
    /// files. `times.txt` may run longer than `poses.txt` (the whole
    /// drive's stamps), not shorter.
    pub fn open(dir: &Path, input: CameraInput) -> Result<Self, CloudError> {
        let calib_path = dir.join("calib.txt");
        let calib = read_calib(&calib_path)?;
        let folder = dir.join(input.folder());
        let count = count_frames(&folder, input.extension())?;
        if count == 0 {
            let problem = format!("no frames (NNNNNN.{}) in it", input.extension());
            return Err(CloudError::mismatch(&folder, problem));
        }
        let poses_path = dir.join("poses.txt");
        // There (a link that leads nowhere included: its read names it) or
        // not: a folder without ground truth.
        let camera0_poses = match std::fs::symlink_metadata(&poses_path).is_ok() {
            true => Some(read_kitti_poses(&poses_path)?),
            false => None,
        };
        let poses_in_file = camera0_poses.as_ref().map(Vec::len);
        if let Some(n) = poses_in_file.filter(|&n| count > n) {
            let problem = format!(
                "{count} frames (NNNNNN.{}) but only {n} poses in {}: every frame needs its pose",
                input.extension(),
                poses_path.display()
            );
            return Err(CloudError::mismatch(&folder, problem));
        }
        // Stamps for the poses, else for the frames.
        let n = poses_in_file.unwrap_or(count);
        let times_path = dir.join("times.txt");
        let times_in_file = times_path.exists();
        let times = if times_in_file {
            let mut t = read_times(&times_path)?;
            // The whole drive's stamps with poses.txt cut to the frames
            // at hand: the first stamps are theirs.
            if t.len() < n {
                let problem = match poses_in_file {
                    Some(_) => format!(
                        "{} time stamps for {n} poses in {}: every pose needs its stamp",
                        t.len(),
                        poses_path.display()
                    ),
                    None => format!(
                        "{} time stamps for {n} frames in {}: every frame needs its stamp",
                        t.len(),
                        folder.display()
                    ),
                };
                return Err(CloudError::mismatch(&times_path, problem));
            }
            t.truncate(n);
            t
        } else {
            (0..n).map(|i| i as f64 * 0.1).collect()
        };
        let (mut camera0_poses, mut times) = (camera0_poses, times);
        if let Some(p) = camera0_poses.as_mut() {
            p.truncate(count);
        }
        times.truncate(count);
        let first = folder.join(format!("000000.{}", input.extension()));
        let (w, h) = match input {
            CameraInput::Labels => {
                let (w, h, _) = read_label_png(&first)?;
                (w, h)
            }
            CameraInput::Images => {
                let img = read_rgb(&first)?;
                img.dimensions()
            }
            CameraInput::Features => KITTI_IMAGE_SIZE,
        };
        let camera = calib.camera("P2", w, h, &calib_path)?;
        if input != CameraInput::Features {
            check_principal_point(&camera, &first, &calib_path)?;
        }
        Ok(KittiCameraSequence {
            dir: dir.to_path_buf(),
            calib,
            camera,
            camera0_poses,
            times,
            times_in_file,
            input,
            poses_in_file,
            frames: count,
        })
    }

    /// Checks the headers of the first `n` frames (those a run reads)
    /// before any is localized, so that a bad frame late in a long drive
    /// fails the run at once instead of after the work: label and camera
    /// images of the camera's size, label images grey with 8 or 16 bits,
    /// every file complete, feature grids all of frame 0's shape and not
    /// standing against the camera (transposed).
    pub fn check_frames(&self, n: usize) -> Result<(), CloudError> {
        let k = &self.camera.intrinsics;
        check_frames(
            &self.dir.join(self.input.folder()),
            self.input,
            n.min(self.frames),
            (k.width, k.height),
            None,
        )
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.frames
    }

    /// Whether the sequence has no frames.
    pub fn is_empty(&self) -> bool {
        self.frames == 0
    }

    /// The input file of frame `i`.
    pub fn frame_path(&self, i: usize) -> PathBuf {
        self.dir
            .join(self.input.folder())
            .join(format!("{i:06}.{}", self.input.extension()))
    }

    /// KITTI camera-0 poses (`poses.txt`'s frame) as camera-2 poses in the
    /// map frame: `Tr^-1 * P_i * C`.
    pub fn camera2_in_map(&self, camera0_poses: &[Pose]) -> Vec<Pose> {
        camera_in_map(&self.calib, &self.camera, camera0_poses)
    }

    /// The inverse of [`Self::camera2_in_map`]: camera-2 poses in the map
    /// frame as KITTI camera-0 poses (to write results `poses.txt` compares
    /// with, e.g. in evo).
    pub fn camera0_in_kitti(&self, camera2_in_map: &[Pose]) -> Vec<Pose> {
        let kitti_from_map = self.calib.camera_from_lidar;
        let c_inv = self.camera.camera0_from_camera.inverse();
        camera2_in_map
            .iter()
            .map(|p| kitti_from_map * p * c_inv)
            .collect()
    }

    /// Ground truth: camera 2 of every frame in the map frame (`None`
    /// without `poses.txt`).
    pub fn ground_truth(&self) -> Option<Vec<Pose>> {
        self.camera0_poses.as_ref().map(|p| self.camera2_in_map(p))
    }
}

/// KITTI camera-0 poses as poses of `camera` in the map frame (the first
/// LiDAR frame): `Tr^-1 * P_i * C`.
pub fn camera_in_map(
    calib: &KittiCalib,
    camera: &KittiCamera,
    camera0_poses: &[Pose],
) -> Vec<Pose> {
    let map_from_kitti = calib.camera_from_lidar.inverse();
    let c = camera.camera0_from_camera;
    camera0_poses
        .iter()
        .map(|p| map_from_kitti * p * c)
        .collect()
}

/// Refuses images whose size is not the calibration's: P2's principal
/// point far from their middle (outside 30-70 % of the width or height)
/// says they were scaled or cropped without P2 (KITTI's is at 49 % x
/// 49 %); tracking then failed with a warning that blamed the pose.
fn check_principal_point(
    camera: &super::kitti::KittiCamera,
    first: &Path,
    calib: &Path,
) -> Result<(), CloudError> {
    let k = &camera.intrinsics;
    let (fx, fy) = (k.cx / k.width as f64, k.cy / k.height as f64);
    let near_middle = |f: f64| (0.3..=0.7).contains(&f);
    if near_middle(fx) && near_middle(fy) {
        return Ok(());
    }
    Err(CloudError::mismatch(
        first,
        format!(
            "{} x {} pixels, but P2 of {} puts the principal point at ({:.1}, {:.1}), {:.0} % \
             across and {:.0} % down, which is not near their middle: the images are not at \
             the calibration's resolution (P2 implies about {:.0} x {:.0}); resize them to it, or \
             scale P2 with them",
            k.width,
            k.height,
            calib.display(),
            k.cx,
            k.cy,
            100.0 * fx,
            100.0 * fy,
            2.0 * k.cx,
            2.0 * k.cy
        ),
    ))
}

/// Checks the headers of frames `0..count`: label and camera images of
/// the camera's size (`size`, frame 0's), label images grey with 8 or 16
/// bits, every file complete (a PNG holds its IEND chunk; an `.npy` what
/// its header declares), feature grids all of frame 0's shape and not
/// turned against the camera (a portrait grid for a landscape camera: a
/// transposed one; any other h x w is taken, each axis stretched).
pub(crate) fn check_frames(
    folder: &Path,
    input: CameraInput,
    count: usize,
    size: (u32, u32),
    size_from: Option<&Path>,
) -> Result<(), CloudError> {
    let path = |i: usize| folder.join(format!("{i:06}.{}", input.extension()));
    match input {
        CameraInput::Labels | CameraInput::Images => {
            for i in 0..count {
                let p = path(i);
                let (w, h, depth, colour) = super::bounded_png::png_header(&p)?;
                if (w, h) != size {
                    let whose = match size_from {
                        Some(file) => format!("{} says", file.display()),
                        None => format!("frame 0 ({}) has", path(0).display()),
                    };
                    return Err(CloudError::mismatch(
                        &p,
                        format!(
                            "{w} x {h} pixels, {whose} {} x {}: every frame of a sequence has \
                             its camera's size",
                            size.0, size.1
                        ),
                    ));
                }
                if input == CameraInput::Labels && (colour != 0 || !matches!(depth, 8 | 16)) {
                    return Err(CloudError::format(
                        &p,
                        format!(
                            "label image must be single-channel grey with 8 or 16 bits (PNG \
                             colour type {colour}, {depth} bits)"
                        ),
                    ));
                }
            }
        }
        CameraInput::Features => {
            let npy = |i: usize| {
                let p = path(i);
                super::npy::read_npy_shape(&p)
                    .map_err(CloudError::from)
                    .map(|s| (p, s))
            };
            let (p0, first) = npy(0)?;
            if first.len() != 3 || first.contains(&0) {
                return Err(CloudError::format(
                    &p0,
                    format!("expected h x w x F features with every size above 0, got {first:?}"),
                ));
            }
            let (gw, gh) = (first[1] as f64, first[0] as f64);
            let (iw, ih) = (size.0 as f64, size.1 as f64);
            if (gw - gh) * (iw - ih) < 0.0 {
                return Err(CloudError::mismatch(
                    &p0,
                    format!(
                        "a {} x {} grid (h x w) for a {} x {} camera: it stands the other way \
                         (rows first: h x w x F; is it transposed?)",
                        first[0], first[1], size.0, size.1
                    ),
                ));
            }
            for i in 1..count {
                let (p, shape) = npy(i)?;
                if shape.len() != 3 || shape.contains(&0) {
                    return Err(CloudError::format(
                        &p,
                        format!(
                            "expected h x w x F features with every size above 0, got {shape:?}"
                        ),
                    ));
                }
                if shape.len() == 3 && shape[..2] == first[..2] && shape[2] != first[2] {
                    return Err(CloudError::mismatch(
                        &p,
                        format!(
                            "feature dimension {}, frame 0 ({}) has {}: every frame's features \
                             have one dimension, the map's",
                            shape[2],
                            p0.display(),
                            first[2]
                        ),
                    ));
                }
                if shape != first {
                    return Err(CloudError::mismatch(
                        &p,
                        format!(
                            "shape {shape:?}, frame 0 ({}) has {first:?}: every frame's \
                             features have one shape",
                            p0.display()
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Number of `NNNNNN.ext` files in `folder`, which must be `000000` to
/// `count - 1` without gaps.
fn count_frames(folder: &Path, ext: &str) -> Result<usize, CloudError> {
    let frames: Vec<usize> = numbered_files(folder, ext)?
        .into_iter()
        .map(|(f, _)| f)
        .collect();
    if let Some((i, f)) = frames.iter().enumerate().find(|(i, f)| *i != **f) {
        return Err(CloudError::format(
            folder,
            format!("frames are not numbered 0, 1, 2, ...: frame {i} is missing (next is {f})"),
        ));
    }
    Ok(frames.len())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn map_and_kitti_frames_round_trip() {
        let calib = super::super::kitti::parse_calib(
            crate::sim::dataset::KITTI00_CALIB,
            Path::new("calib.txt"),
        )
        .unwrap();
        let camera = calib
            .camera("P2", 1241, 376, Path::new("calib.txt"))
            .unwrap();
        let seq = KittiCameraSequence {
            dir: PathBuf::new(),
            calib,
            camera,
            camera0_poses: Some(vec![Pose::identity()]),
            times: vec![0.0],
            times_in_file: false,
            input: CameraInput::Labels,
            poses_in_file: Some(1),
            frames: 1,
        };
        // Frame 0: camera 0 at the KITTI origin; the map origin is the first
        // LiDAR frame, so camera 2 sits at Tr^-1 applied to (-0.063, 0, 0).
        let g = seq.ground_truth().unwrap()[0];
        let expect =
            seq.calib.camera_from_lidar.inverse() * nalgebra::Point3::new(-0.063_131_211, 0.0, 0.0);
        assert!((g.translation.vector - expect.coords).norm() < 1e-8);
        // Camera 2 looks along LiDAR x (forward), its y points down (-z).
        let fwd = g.rotation * nalgebra::Vector3::z();
        assert!((fwd - nalgebra::Vector3::x()).norm() < 0.02, "{fwd:?}");
        let p = Pose::from_parts(
            Translation3::new(1.0, -0.2, 30.0),
            UnitQuaternion::from_euler_angles(0.01, 0.3, -0.02),
        );
        let back = seq.camera0_in_kitti(&seq.camera2_in_map(&[p]))[0];
        assert!((back.translation.vector - p.translation.vector).norm() < 1e-9);
        assert!(back.rotation.angle_to(&p.rotation) < 1e-9);
    }
}
