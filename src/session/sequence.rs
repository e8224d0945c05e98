//! A recorded camera sequence localized frame by frame: the pipeline of
//! `omcl localize`, in the library.
//!
//! [`CameraSequence`] reads either layout as it is on disk:
//!
//! ```text
//! RGB-D folder  intrinsics.txt, poses.txt (TUM, ground truth, optional),
//!               labels/NNNNNN.png | features/NNNNNN.npy | rgb/NNNNNN.png,
//!               classes.txt + embeddings.npy for label images
//! KITTI folder  calib.txt (camera 2 from P2), poses.txt (camera 0,
//!               ground truth, optional),
//!               times.txt, labels_2/ | features_2/ | image_2/
//!               (see crate::io::kitti_camera)
//! 7-Scenes      camera-intrinsics.txt, frame-NNNNNN.{color.jpg,
//!               depth.png,pose.txt} (see crate::io::sevenscenes): the
//!               colour images through an image encoder, the picked
//!               frames only, ground truth turned z-up
//! ```
//!
//! [`FrameSource`] says what each frame is read as (label images through a
//! class table, feature files, or RGB images through an image encoder) and
//! [`localize`] runs a [`Session`] over the frames: the same loop
//! `omcl serve` runs per camera and the benchmark's experiments run in
//! memory. Odometry comes from a pose file or from ground truth with the
//! library's one definition of odometry noise ([`Odometry`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::baseline::BaselineSession;
use super::{LabelTable, PoseReport, Session, SessionError, feature_grid, label_frame};
use crate::encode::EncodeError;
use crate::encode::cache::ImageSource;
use crate::encode::image::EncodedFrame;
use crate::frame::FrameFeatures;
use crate::geometry::{Intrinsics, Pose};
use crate::io::cloud::CloudError;
use crate::io::kitti_camera::{CameraInput, KittiCameraSequence};
use crate::io::npy::{NpyError, read_npy};
use crate::io::poses::{self, PosesError};
use crate::io::rgbd;
use crate::io::sevenscenes::{FramePick, SevenScenes};
use crate::sim::paths::OdometryConfig;
use crate::trajectory::{Trajectory, TrajectoryError};

/// Errors reading or localizing a sequence; each names its file or frame.
#[derive(Debug, thiserror::Error)]
pub enum SequenceError {
    #[error(transparent)]
    Cloud(#[from] CloudError),
    #[error(transparent)]
    Poses(#[from] PosesError),
    #[error(transparent)]
    Npy(#[from] NpyError),
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
    #[error("{path}: {source}")]
    Encode { path: String, source: EncodeError },
    #[error("frame {frame} ({path}): {source}")]
    Frame {
        frame: usize,
        path: String,
        source: Box<SessionError>,
    },
    #[error("{0}")]
    Input(String),
}

/// What an RGB-D folder with none of its frame folders is told.
pub const NO_FRAMES: &str = "no labels/ and no features/ folder: the frames are label images \
     (labels/NNNNNN.png with classes.txt and embeddings.npy), feature grids \
     (features/NNNNNN.npy) or, through --image-model, colour images (rgb/NNNNNN.png)";

/// The layouts a sequence folder can be in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// `intrinsics.txt`, `poses.txt`, `labels/` | `features/` | `rgb/`.
    Rgbd,
    /// A KITTI odometry folder (it has `calib.txt`).
    Kitti,
    /// A Microsoft 7-Scenes folder (it has `camera-intrinsics.txt`).
    SevenScenes,
}

impl Layout {
    /// The layout `dir` is in.
    pub fn of(dir: &Path) -> Layout {
        if dir.join("calib.txt").exists() {
            Layout::Kitti
        } else if dir.join("camera-intrinsics.txt").exists() {
            Layout::SevenScenes
        } else {
            Layout::Rgbd
        }
    }
}

/// The frames of a 7-Scenes folder a run uses.
#[derive(Debug)]
pub struct SevenScenesFrames {
    pub seq: SevenScenes,
    /// Positions in `seq.frames` of the run's frames, in order.
    pub picked: Vec<usize>,
}

/// Where a sequence's files are, in any layout, and what it says.
#[derive(Debug)]
pub struct CameraSequence {
    /// The sequence folder.
    pub dir: PathBuf,
    /// The camera (KITTI: camera 2).
    pub intrinsics: Intrinsics,
    /// Ground truth, `world_from_camera` in the map frame.
    pub ground_truth: Option<Trajectory>,
    /// Where ground truth is (or would be).
    pub ground_truth_path: PathBuf,
    /// The class table of label images: `classes.txt`, `embeddings.npy`.
    pub classes: PathBuf,
    pub embeddings: PathBuf,
    /// Folders of label images, feature files and RGB images.
    pub labels_dir: PathBuf,
    pub features_dir: PathBuf,
    pub rgb_dir: PathBuf,
    /// The KITTI sequence, for a KITTI layout.
    pub kitti: Option<KittiCameraSequence>,
    /// The 7-Scenes folder and its picked frames, for that layout.
    pub sevenscenes: Option<SevenScenesFrames>,
}

/// Odometry poses of a sequence's frames ([`CameraSequence::odometry`]).
#[derive(Debug, Clone)]
pub struct OdometryPoses {
    /// From the first frame on, in the map frame (camera 2 on KITTI).
    pub poses: Vec<Pose>,
    /// The pose file they were read from, whole (`None`: made from ground
    /// truth).
    pub file: Option<poses::PoseFile>,
}

impl CameraSequence {
    /// The folder `dir` in the layout it is in; on KITTI, `input` picks
    /// the camera-2 folder read; on 7-Scenes, `pick` the frames (the other
    /// layouts use every frame: any other `pick` is an error).
    pub fn open(dir: &Path, input: CameraInput, pick: FramePick) -> Result<Self, SequenceError> {
        crate::io::kitti::check_sequence_folder(dir)?;
        let layout = Layout::of(dir);
        if layout != Layout::SevenScenes && (pick.step > 1 || pick.offset > 0) {
            return Err(SequenceError::Input(format!(
                "{}: picking frames (step {}, offset {}) applies to 7-Scenes folders \
                 (with camera-intrinsics.txt) only",
                dir.display(),
                pick.step,
                pick.offset
            )));
        }
        match layout {
            Layout::Kitti => Self::kitti(dir, input),
            Layout::SevenScenes => Self::sevenscenes(dir, pick),
            Layout::Rgbd => Self::rgbd(dir),
        }
    }

    /// A 7-Scenes folder: the frames `pick` takes, ground truth in the
    /// z-up world ([`SevenScenes::poses_z_up`], the frame `omcl map rgbd`
    /// builds such a folder's map in), stamped with the frame numbers.
    pub fn sevenscenes(d: &Path, pick: FramePick) -> Result<Self, SequenceError> {
        let seq = SevenScenes::open(d)?;
        let picked = seq.pick(&pick)?;
        let poses = seq.poses_z_up();
        let gt = Trajectory::new(
            picked
                .iter()
                .map(|&i| f64::from(seq.frames[i].number))
                .collect(),
            picked.iter().map(|&i| poses[i]).collect(),
        )?;
        Ok(CameraSequence {
            dir: d.to_path_buf(),
            intrinsics: seq.intrinsics,
            ground_truth: Some(gt),
            ground_truth_path: seq.frames[picked[0]].pose.clone(),
            classes: d.join("classes.txt"),
            embeddings: d.join("embeddings.npy"),
            labels_dir: d.join("labels"),
            features_dir: d.join("features"),
            rgb_dir: d.to_path_buf(),
            kitti: None,
            sevenscenes: Some(SevenScenesFrames { seq, picked }),
        })
    }

    /// The layout the sequence is in.
    pub fn layout(&self) -> Layout {
        if self.kitti.is_some() {
            Layout::Kitti
        } else if self.sevenscenes.is_some() {
            Layout::SevenScenes
        } else {
            Layout::Rgbd
        }
    }

    /// The position in a 7-Scenes folder's frames of the run's frame `i`.
    fn picked(&self, s: &SevenScenesFrames, i: usize) -> Result<usize, SequenceError> {
        s.picked.get(i).copied().ok_or_else(|| {
            SequenceError::Input(format!(
                "{}: frame {i} asked for, {} picked",
                self.dir.display(),
                s.picked.len()
            ))
        })
    }

    /// The RGB image of frame `i` (7-Scenes: the picked frame's colour
    /// JPEG, checked whole and of the dataset's size).
    pub fn image_path(&self, i: usize) -> Result<PathBuf, SequenceError> {
        match &self.sevenscenes {
            Some(s) => {
                let j = self.picked(s, i)?;
                s.seq.check_color(j)?;
                Ok(s.seq.frames[j].color.clone())
            }
            None => Ok(self.rgb_dir.join(format!("{i:06}.png"))),
        }
    }

    /// The depth image of frame `i`, in metres: an RGB-D folder's
    /// `depth/NNNNNN.png` in `units_per_metre`, a 7-Scenes folder's picked
    /// frame in millimetres (whatever `units_per_metre` says); it must be
    /// of the camera's size. KITTI sequences have none.
    pub fn read_depth(
        &self,
        i: usize,
        units_per_metre: f64,
    ) -> Result<rgbd::DepthImage, SequenceError> {
        let k = self.intrinsics;
        let (path, d) = match (&self.sevenscenes, &self.kitti) {
            (Some(s), _) => {
                let j = self.picked(s, i)?;
                (s.seq.frames[j].depth.clone(), s.seq.read_depth(j)?)
            }
            (None, Some(_)) => {
                return Err(SequenceError::Input(format!(
                    "{}: a KITTI sequence has no depth images",
                    self.dir.display()
                )));
            }
            (None, None) => {
                let p = self.dir.join("depth").join(format!("{i:06}.png"));
                let d = rgbd::read_depth_png(&p, units_per_metre)?;
                (p, d)
            }
        };
        if (d.width, d.height) != (k.width, k.height) {
            return Err(SequenceError::Input(format!(
                "{}: a {} x {} depth image, the camera is {} x {} (intrinsics)",
                path.display(),
                d.width,
                d.height,
                k.width,
                k.height
            )));
        }
        Ok(d)
    }

    /// An RGB-D folder.
    pub fn rgbd(d: &Path) -> Result<Self, SequenceError> {
        let intrinsics_path = d.join("intrinsics.txt");
        if !intrinsics_path.exists() {
            // A folder of KITTI sequences, or one inside a sequence.
            crate::io::kitti::check_kitti_near_misses(d)?;
        }
        // A KITTI folder without its calib.txt is not an RGB-D folder
        // without intrinsics.txt: say which file is missing.
        if !intrinsics_path.exists()
            && ["image_2", "labels_2", "features_2", "velodyne", "times.txt"]
                .iter()
                .any(|k| d.join(k).exists())
        {
            return Err(SequenceError::Input(format!(
                "{}: a KITTI sequence folder (it has image_2/, labels_2/, velodyne/ or \
                 times.txt) needs calib.txt (with P2) for camera 2; it is missing",
                d.display()
            )));
        }
        if let Some(why) = rgbd::raw_tum_layout(d) {
            return Err(SequenceError::Input(why));
        }
        // Nothing of any layout: name them all, not one missing file.
        let rgbd_parts = ["labels", "features", "rgb", "depth", "poses.txt"];
        if !intrinsics_path.exists() && !rgbd_parts.iter().any(|k| d.join(k).exists()) {
            return Err(SequenceError::Input(format!(
                "{}: not a camera sequence: none of an RGB-D folder (intrinsics.txt with \
                 labels/, features/ or rgb/; `omcl sim indoor` writes one), a KITTI sequence \
                 (calib.txt with labels_2/, features_2/ or image_2/) or a 7-Scenes folder \
                 (camera-intrinsics.txt with frame-NNNNNN.color.jpg)",
                d.display()
            )));
        }
        let intrinsics = rgbd::read_intrinsics(&intrinsics_path)?;
        let gt_path = d.join("poses.txt");
        let ground_truth = gt_path
            .exists()
            .then(|| poses::read_poses(&gt_path))
            .transpose()?
            .map(|p| p.trajectory);
        Ok(CameraSequence {
            dir: d.to_path_buf(),
            intrinsics,
            ground_truth,
            ground_truth_path: gt_path,
            classes: d.join("classes.txt"),
            embeddings: d.join("embeddings.npy"),
            labels_dir: d.join("labels"),
            features_dir: d.join("features"),
            rgb_dir: d.join("rgb"),
            kitti: None,
            sevenscenes: None,
        })
    }

    /// A KITTI odometry folder; `input` picks the camera-2 folder read.
    pub fn kitti(d: &Path, input: CameraInput) -> Result<Self, SequenceError> {
        let folder = d.join(input.folder());
        if input != CameraInput::Images && !folder.exists() {
            // No label images and no feature files (the caller falls back
            // from labels_2/ to features_2/): say what would do.
            let images = if d.join(CameraInput::Images.folder()).is_dir() {
                "; its image_2/ localizes with --image-model ONNX"
            } else {
                ""
            };
            return Err(SequenceError::Input(format!(
                "{}: no camera-2 frames to localize from: labels_2/ (label images; `omcl map \
                 project {}` makes them from the labelled scans) or features_2/ (per-pixel \
                 features, --use-features){images}",
                d.display(),
                d.display()
            )));
        }
        let seq = KittiCameraSequence::open(d, input)?;
        let gt = seq
            .ground_truth()
            .map(|g| Trajectory::new(seq.times.clone(), g))
            .transpose()?;
        Ok(CameraSequence {
            dir: d.to_path_buf(),
            intrinsics: seq.camera.intrinsics,
            ground_truth: gt,
            ground_truth_path: d.join("poses.txt"),
            classes: d.join("classes.txt"),
            embeddings: d.join("embeddings.npy"),
            labels_dir: d.join(CameraInput::Labels.folder()),
            features_dir: d.join(CameraInput::Features.folder()),
            rgb_dir: d.join(CameraInput::Images.folder()),
            kitti: Some(seq),
            sevenscenes: None,
        })
    }

    /// The odometry poses of the frames, in the map frame (camera 2 on
    /// KITTI), with the file they were read from (read once: its stamps
    /// are [`CameraSequence::odometry_remarks`]' too).
    pub fn odometry(&self, odometry: &Odometry) -> Result<OdometryPoses, SequenceError> {
        match odometry {
            Odometry::File { path, first } => {
                let file = poses::read_poses(path)?;
                let all = file.trajectory.poses();
                if *first >= all.len() {
                    return Err(SequenceError::Input(format!(
                        "{}: --odom-first {first} is past its {} poses",
                        path.display(),
                        all.len()
                    )));
                }
                let own = &all[*first..];
                let poses = match &self.kitti {
                    Some(seq) => seq.camera2_in_map(own),
                    None => own.to_vec(),
                };
                Ok(OdometryPoses {
                    poses,
                    file: Some(file),
                })
            }
            Odometry::FromTruth(cfg) => {
                let g = self.ground_truth.as_ref().ok_or_else(|| {
                    let hint = crate::io::kitti::benchmark_poses(&self.dir)
                        .map(|p| {
                            format!(
                                " (the odometry benchmark's layout keeps them in {}: link it \
                                 as poses.txt)",
                                p.display()
                            )
                        })
                        .unwrap_or_default();
                    SequenceError::Input(format!(
                        "{}: no odometry: pass --odometry FILE, or provide poses.txt to make \
                         it from ground truth{hint}",
                        self.dir.display()
                    ))
                })?;
                Ok(OdometryPoses {
                    poses: crate::sim::paths::odometry(g.poses(), &[], cfg),
                    file: None,
                })
            }
        }
    }

    /// Checks the headers of the first `n` frames of `input` before any is
    /// localized (KITTI folders: [`KittiCameraSequence::check_frames`]; an
    /// RGB-D folder's `labels/` or `features/` alike), so that a bad frame
    /// late in a long sequence fails the run before the work.
    pub fn check_frames(&self, n: usize, input: CameraInput) -> Result<(), SequenceError> {
        if let Some(k) = &self.kitti {
            return Ok(k.check_frames(n)?);
        }
        // An RGB-D folder's label images, feature grids and colour images
        // by the same rules, against its intrinsics (an encoder's image of
        // another size had mapped and localized on a part of the frame).
        let folder = self.input_folder(input);
        if self.sevenscenes.is_some() || !folder.is_dir() {
            return Ok(());
        }
        let k = &self.intrinsics;
        crate::io::kitti_camera::check_frames(
            folder,
            input,
            n,
            (k.width, k.height),
            Some(&self.dir.join("intrinsics.txt")),
        )?;
        Ok(())
    }

    /// The folder of an RGB-D folder's frames of `input`.
    pub fn input_folder(&self, input: CameraInput) -> &Path {
        match input {
            CameraInput::Labels => &self.labels_dir,
            CameraInput::Features => &self.features_dir,
            CameraInput::Images => &self.rgb_dir,
        }
    }

    /// How many frames an RGB-D folder holds for `input` (its
    /// `NNNNNN.png` or `.npy` files; another name is an error); `None` for
    /// a KITTI or 7-Scenes folder, whose readers count their own, and for
    /// a missing folder.
    pub fn stored_frames(&self, input: CameraInput) -> Result<Option<usize>, SequenceError> {
        let folder = self.input_folder(input);
        if self.kitti.is_some() || self.sevenscenes.is_some() || !folder.is_dir() {
            return Ok(None);
        }
        Ok(Some(
            crate::io::kitti::numbered_files(folder, input.extension())?.len(),
        ))
    }

    /// Frames that can be localized: the odometry's, capped by `limit`
    /// and the KITTI folder's frame count; ground truth, when present, must
    /// cover them (checked before any work, not after the output).
    /// An odometry shorter than the frames asked for (all of them without
    /// `limit`) is refused, not a shorter run.
    pub fn frames(&self, odometry: usize, limit: Option<usize>) -> Result<usize, SequenceError> {
        // The frames the folder holds, where its layout says.
        let stored = [
            self.kitti.as_ref().map(|s| s.len()),
            self.sevenscenes.as_ref().map(|s| s.picked.len()),
        ]
        .into_iter()
        .flatten()
        .min()
        .unwrap_or(usize::MAX);
        let limit = limit.unwrap_or(usize::MAX);
        let held = stored.min(self.ground_truth.as_ref().map_or(usize::MAX, |g| g.len()));
        let wanted = held.min(limit);
        if odometry < wanted && wanted != usize::MAX {
            return Err(SequenceError::Input(format!(
                "{}: the odometry gives {odometry} pose{} for {wanted} frames; pass --frames \
                 {odometry} to localize only those, or a complete odometry",
                self.dir.display(),
                if odometry == 1 { "" } else { "s" }
            )));
        }
        let n = odometry.min(limit).min(stored);
        if n == 0 {
            return Err(SequenceError::Input(format!(
                "{}: the sequence has no frames",
                self.dir.display()
            )));
        }
        if let Some(g) = &self.ground_truth
            && g.len() < n
        {
            return Err(SequenceError::Input(format!(
                "{}: {} ground-truth poses, but the odometry gives {n} frames; pass --frames \
                 {}, or an odometry and a poses.txt of the same length",
                self.ground_truth_path.display(),
                g.len(),
                g.len()
            )));
        }
        Ok(n)
    }

    /// What a user should know about how `odometry` meets the first `n`
    /// frames (each a sentence for a note; none for odometry made from
    /// ground truth): a file with more poses than the folder has frames
    /// from `first` on (a sequence cut from a longer drive needs
    /// `--odom-first`), and a TUM file whose stamps are not the frames'
    /// (rows are paired with frames by order, never by time).
    /// `read` is what [`CameraSequence::odometry`] read for `odometry`.
    pub fn odometry_remarks(
        &self,
        odometry: &Odometry,
        read: &OdometryPoses,
        n: usize,
    ) -> Vec<String> {
        let (Odometry::File { path, first }, Some(file)) = (odometry, &read.file) else {
            return Vec::new();
        };
        let rows = file.trajectory.len();
        let held = [
            self.kitti.as_ref().map(|s| s.len()),
            self.sevenscenes.as_ref().map(|s| s.picked.len()),
            self.ground_truth.as_ref().map(|g| g.len()),
        ]
        .into_iter()
        .flatten()
        .min();
        let mut remarks = Vec::new();
        if let Some(held) = held.filter(|&h| rows.saturating_sub(*first) > h) {
            remarks.push(format!(
                "{} has {rows} poses for the sequence's {held} frames: its poses {first} to {} \
                 are the frames' (for a sequence cut from a longer drive, --odom-first K names \
                 the pose of its frame 0)",
                path.display(),
                first + held - 1
            ));
        }
        // The frames' own stamps: times.txt on KITTI, ground truth's elsewhere.
        let own: Option<Vec<f64>> = match &self.kitti {
            Some(k) => k.times_in_file.then(|| k.times.clone()),
            None => self.ground_truth.as_ref().map(|g| g.stamps().to_vec()),
        };
        if let (poses::PoseFormat::Tum, Some(own)) = (file.format, own) {
            let stamps = &file.trajectory.stamps()[*first..];
            let m = n.min(own.len()).min(stamps.len());
            let mut gaps: Vec<f64> = own[..m].windows(2).map(|w| (w[1] - w[0]).abs()).collect();
            gaps.sort_by(f64::total_cmp);
            let period = gaps.get(gaps.len() / 2).copied().unwrap_or(0.1);
            let tolerance = (0.5 * period).max(1e-3);
            if let Some(i) = (0..m).find(|&i| (stamps[i] - own[i]).abs() > tolerance) {
                remarks.push(format!(
                    "{}'s time stamps are not the frames': its pose {} is stamped {:.3} s, \
                     frame {i} {:.3} s; poses are paired with frames in order (pose {first} \
                     with frame 0, --odom-first), not by time",
                    path.display(),
                    first + i,
                    stamps[i],
                    own[i]
                ));
            }
        }
        remarks
    }

    /// How the first frame's LiDAR scan, placed where `start` (camera 2 of
    /// frame 0 in the map's frame) puts it, meets `map`
    /// ([`super::scan_fit`]): `Ok(None)` for a folder that is not KITTI's,
    /// has no `velodyne/000000.bin`, or whose scan has too few points to
    /// tell. A scan that cannot be read is an error naming it.
    pub fn first_scan_fit(
        &self,
        map: &crate::map::LanguageMap,
        start: &Pose,
    ) -> Result<Option<super::scan_fit::ScanFit>, SequenceError> {
        let Some(k) = &self.kitti else {
            return Ok(None);
        };
        let path = k.dir.join("velodyne").join("000000.bin");
        if !path.is_file() {
            return Ok(None);
        }
        let scan = crate::io::kitti::read_velodyne_bin(&path)?;
        // Camera 2 from the LiDAR: camera 2 from camera 0, then Tr.
        let camera_from_lidar = k.camera.camera0_from_camera.inverse() * k.calib.camera_from_lidar;
        Ok(super::scan_fit::scan_fit(
            map,
            &(start * camera_from_lidar),
            &scan.points,
            crate::io::kitti::VELODYNE_HEIGHT_M,
        ))
    }

    /// The stamps of the first `n` frames (ground truth's, else indices).
    pub fn stamps(&self, n: usize) -> Vec<f64> {
        match &self.ground_truth {
            Some(g) => g.stamps()[..n].to_vec(),
            None => (0..n).map(|i| i as f64).collect(),
        }
    }
}

/// Where the odometry comes from.
#[derive(Debug, Clone)]
pub enum Odometry {
    /// A pose file (TUM or KITTI; KITTI poses are camera 0's), from its
    /// pose `first` on.
    File { path: PathBuf, first: usize },
    /// Ground truth with noise ([`crate::sim::paths::odometry`]).
    FromTruth(OdometryConfig),
}

/// What the frames are read as.
pub enum FrameSource<'a> {
    /// Label images through the sequence's class table.
    Labels(&'a LabelTable),
    /// Per-pixel feature files (`h x w x F`).
    Features,
    /// RGB images through an image encoder.
    Images(&'a mut ImageSource),
}

/// One localized frame.
#[derive(Debug, Clone, Copy)]
pub struct LocalizedFrame {
    pub report: PoseReport,
    /// Seconds reading the frame (and encoding it, for images).
    pub input_seconds: f64,
}

/// Reads frame `i` of `seq` as `source` says and steps `session` with it.
pub fn step_frame(
    session: &mut Session,
    seq: &CameraSequence,
    source: &mut FrameSource<'_>,
    i: usize,
    odom: &Pose,
    stamp: f64,
) -> Result<LocalizedFrame, SequenceError> {
    let (report, input_seconds) =
        with_frame(seq, source, i, &mut |f| session.step(odom, stamp, f))?;
    Ok(LocalizedFrame {
        report,
        input_seconds,
    })
}

/// Reads frame `i` of `seq` as `source` says (and, with `depth_scale`,
/// its depth image: depth PNG units per metre, 7-Scenes folders in
/// millimetres whatever it says) and steps the baseline's `session` with
/// it.
pub fn step_baseline_frame(
    session: &mut BaselineSession,
    seq: &CameraSequence,
    source: &mut FrameSource<'_>,
    i: usize,
    odom: &Pose,
    stamp: f64,
    depth_scale: Option<f64>,
) -> Result<LocalizedFrame, SequenceError> {
    let t = Instant::now();
    let depth = depth_scale.map(|d| seq.read_depth(i, d)).transpose()?;
    let depth_seconds = t.elapsed().as_secs_f64();
    let depth = depth.as_ref().map(|d| d.depth.as_slice());
    let (report, input_seconds) =
        with_frame(seq, source, i, &mut |f| session.step(odom, stamp, f, depth))?;
    Ok(LocalizedFrame {
        report,
        input_seconds: input_seconds + depth_seconds,
    })
}

/// Reads frame `i` of `seq` as `source` says and gives it to `step`;
/// returns what `step` did and the seconds spent reading the frame (and
/// encoding it, for images).
fn with_frame(
    seq: &CameraSequence,
    source: &mut FrameSource<'_>,
    i: usize,
    step: &mut dyn FnMut(&dyn FrameFeatures) -> Result<PoseReport, SessionError>,
) -> Result<(PoseReport, f64), SequenceError> {
    let k = seq.intrinsics;
    let t_in = Instant::now();
    let frame_error = |path: &Path, source: SessionError| SequenceError::Frame {
        frame: i,
        path: path.display().to_string(),
        source: Box::new(source),
    };
    match source {
        FrameSource::Images(src) => {
            let p = seq.image_path(i)?;
            let fm = src.encode(&p, i).map_err(|source| SequenceError::Encode {
                path: p.display().to_string(),
                source,
            })?;
            let input = t_in.elapsed().as_secs_f64();
            let f = EncodedFrame {
                map: &fm,
                width: k.width,
                height: k.height,
            };
            let r = step(&f).map_err(|e| frame_error(&p, e))?;
            Ok((r, input))
        }
        FrameSource::Labels(t) => {
            let p = seq.labels_dir.join(format!("{i:06}.png"));
            let (w, h, labels) = rgbd::read_label_png(&p)?;
            let input = t_in.elapsed().as_secs_f64();
            let f = label_frame(w, h, &labels, t).map_err(|e| frame_error(&p, e))?;
            let r = step(&f).map_err(|e| frame_error(&p, e))?;
            Ok((r, input))
        }
        FrameSource::Features => {
            let p = seq.features_dir.join(format!("{i:06}.npy"));
            let arr = read_npy(&p)?;
            let input = t_in.elapsed().as_secs_f64();
            if arr.shape.len() != 3 || arr.shape.contains(&0) {
                return Err(SequenceError::Input(format!(
                    "{}: expected h x w x F features with every size above 0, got shape {:?}",
                    p.display(),
                    arr.shape
                )));
            }
            let shape = [arr.shape[0], arr.shape[1], arr.shape[2]];
            let f = feature_grid(k.width, k.height, shape, &arr.data)
                .map_err(|e| frame_error(&p, e))?;
            let r = step(&f).map_err(|e| frame_error(&p, e))?;
            Ok((r, input))
        }
    }
}

/// Localizes frames `0..odom.len()` of `seq`: every frame read as
/// `source` says and stepped with its odometry pose and stamp;
/// `progress(i)` after frame `i`.
pub fn localize(
    session: &mut Session,
    seq: &CameraSequence,
    source: &mut FrameSource<'_>,
    odom: &[Pose],
    stamps: &[f64],
    progress: &mut dyn FnMut(usize),
) -> Result<Vec<LocalizedFrame>, SequenceError> {
    let mut out = Vec::with_capacity(odom.len());
    for (i, (o, &stamp)) in odom.iter().zip(stamps).enumerate() {
        out.push(step_frame(session, seq, source, i, o, stamp)?);
        progress(i);
    }
    Ok(out)
}

/// [`localize`] with a baseline's session ([`step_baseline_frame`]).
pub fn localize_baseline(
    session: &mut BaselineSession,
    seq: &CameraSequence,
    source: &mut FrameSource<'_>,
    odom: &[Pose],
    stamps: &[f64],
    depth_scale: Option<f64>,
    progress: &mut dyn FnMut(usize),
) -> Result<Vec<LocalizedFrame>, SequenceError> {
    let mut out = Vec::with_capacity(odom.len());
    for (i, (o, &stamp)) in odom.iter().zip(stamps).enumerate() {
        out.push(step_baseline_frame(
            session,
            seq,
            source,
            i,
            o,
            stamp,
            depth_scale,
        )?);
        progress(i);
    }
    Ok(out)
}
