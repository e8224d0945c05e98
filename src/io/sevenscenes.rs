//! Microsoft 7-Scenes sequences as the dataset ships them: one folder of
//! `frame-NNNNNN.color.jpg` (640 x 480 colour), `frame-NNNNNN.depth.png`
//! (640 x 480 16-bit depth in millimetres, 0 or 65535 = no reading) and
//! `frame-NNNNNN.pose.txt` (a 4 x 4 `world_from_camera`, metres, OpenCV
//! camera: x right, y down, z forward), with `camera-intrinsics.txt` (a
//! 3 x 3 K) and optionally `gravity-direction.txt` beside them.
//!
//! Depth and colour come from two sensors a few centimetres apart and are
//! not registered to each other; both are read with the one nominal K, as
//! the dataset's own tools do. K is given in the integer-centre convention
//! (pixel (0, 0) centred at 0), so `cx`, `cy` gain 0.5 here, where pixel
//! centres sit at `u + 0.5` (see [`super::rgbd`]).

use std::path::{Path, PathBuf};

use image::RgbImage;
use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

use super::cloud::CloudError;
use super::rgbd::{DepthImage, read_depth_png};
use crate::geometry::{Intrinsics, Pose};

/// Width and height of every 7-Scenes image (Kinect v1), pixels.
pub const IMAGE_SIZE: (u32, u32) = (640, 480);

/// Depth PNG units per metre (millimetres).
pub const DEPTH_UNITS_PER_METRE: f64 = 1000.0;

/// The depth 7-Scenes stores where the sensor had no reading, besides 0
/// (the dataset's documentation: "invalid depth is set to 65535").
pub const INVALID_DEPTH: u16 = u16::MAX;

/// Largest deviation of `R^T R` from the identity, and of `det R` from 1,
/// accepted in a pose file (the dataset's files are within 2.5e-4).
pub const ROTATION_TOLERANCE: f64 = 1e-3;

/// The files of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameFiles {
    /// The frame number `NNNNNN` of its file names.
    pub number: u32,
    pub color: PathBuf,
    pub depth: PathBuf,
    pub pose: PathBuf,
}

/// An opened 7-Scenes sequence: its intrinsics, frames (sorted by number)
/// and their ground-truth poses, all checked.
#[derive(Debug, Clone)]
pub struct SevenScenes {
    pub dir: PathBuf,
    /// The nominal K, pixel centres at `u + 0.5`, for 640 x 480 images.
    pub intrinsics: Intrinsics,
    pub frames: Vec<FrameFiles>,
    /// `world_from_camera` of each frame, in `frames`' order.
    pub poses: Vec<Pose>,
    /// The unit direction of gravity in the first frame's camera, when
    /// `gravity-direction.txt` is there.
    pub gravity_in_first_camera: Option<Vector3<f64>>,
}

impl SevenScenes {
    /// Opens `dir`: finds every `frame-NNNNNN.pose.txt`, checks that its
    /// colour and depth images exist, parses every pose and the
    /// intrinsics. Images are read on demand ([`Self::read_depth`],
    /// [`Self::read_color`]).
    pub fn open(dir: &Path) -> Result<SevenScenes, CloudError> {
        let entries = std::fs::read_dir(dir).map_err(|e| CloudError::io(dir, e))?;
        let mut numbers = Vec::new();
        // Frames with images: each must have its pose (a frame without one
        // had been left out without a word), and every `frame-` file must
        // be named as the dataset names them (`frame-23.pose.txt` was too).
        let mut imaged = Vec::new();
        for e in entries {
            let e = e.map_err(|e| CloudError::io(dir, e))?;
            let name = e.file_name();
            let Some(name) = name.to_str() else { continue };
            let Some(rest) = name.strip_prefix("frame-") else {
                continue;
            };
            let (digits, kind) = rest.split_once('.').unwrap_or((rest, ""));
            let number = digits
                .parse::<u32>()
                .ok()
                .filter(|_| digits.len() == 6 && digits.bytes().all(|b| b.is_ascii_digit()));
            match (number, kind) {
                (Some(n), "pose.txt") => numbers.push(n),
                (Some(n), "color.jpg" | "color.png" | "depth.png") => imaged.push(n),
                _ => {
                    return Err(CloudError::format(
                        &dir.join(name),
                        "not a 7-Scenes frame file (frame-NNNNNN.color.jpg, .depth.png or \
                         .pose.txt)",
                    ));
                }
            }
        }
        numbers.sort_unstable();
        if let Some(&n) = imaged.iter().find(|n| numbers.binary_search(n).is_err()) {
            return Err(CloudError::Mismatch {
                path: dir.join(format!("frame-{n:06}.pose.txt")),
                reason: format!(
                    "the pose of frame {n:06} is missing (its images exist): restore it, or \
                     move the frame's files out of the folder"
                ),
            });
        }
        if numbers.is_empty() {
            return Err(CloudError::Empty {
                source_name: dir.display().to_string(),
                reason: "no frame-NNNNNN.pose.txt: not a 7-Scenes sequence folder".into(),
            });
        }
        let k_path = dir.join("camera-intrinsics.txt");
        let k_text =
            crate::io::bounded_read::read_text(&k_path).map_err(|e| CloudError::io(&k_path, e))?;
        let intrinsics = parse_intrinsics(&k_text).map_err(|r| CloudError::format(&k_path, r))?;
        let mut frames = Vec::with_capacity(numbers.len());
        let mut poses = Vec::with_capacity(numbers.len());
        for n in numbers {
            let f = FrameFiles {
                number: n,
                color: dir.join(format!("frame-{n:06}.color.jpg")),
                depth: dir.join(format!("frame-{n:06}.depth.png")),
                pose: dir.join(format!("frame-{n:06}.pose.txt")),
            };
            for (p, what) in [(&f.color, "colour image"), (&f.depth, "depth image")] {
                if !p.is_file() {
                    return Err(CloudError::Mismatch {
                        path: p.clone(),
                        reason: format!(
                            "the {what} of frame {n:06} is missing ({} exists)",
                            f.pose.display()
                        ),
                    });
                }
            }
            let text = crate::io::bounded_read::read_text(&f.pose)
                .map_err(|e| CloudError::io(&f.pose, e))?;
            poses.push(parse_pose(&text).map_err(|r| CloudError::format(&f.pose, r))?);
            frames.push(f);
        }
        let g_path = dir.join("gravity-direction.txt");
        let gravity_in_first_camera = if g_path.exists() {
            let text = crate::io::bounded_read::read_text(&g_path)
                .map_err(|e| CloudError::io(&g_path, e))?;
            Some(parse_gravity(&text).map_err(|r| CloudError::format(&g_path, r))?)
        } else {
            None
        };
        Ok(SevenScenes {
            dir: dir.to_path_buf(),
            intrinsics,
            frames,
            poses,
            gravity_in_first_camera,
        })
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether there are no frames (never, once opened).
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// The depth of frame `i` (position in `frames`), metres, 0 = none:
    /// the dataset's invalid value, 65535 mm, reads as none too (not as a
    /// point 65.5 m away).
    pub fn read_depth(&self, i: usize) -> Result<DepthImage, CloudError> {
        let f = self.frame(i)?;
        let mut d = read_depth_png(&f.depth, DEPTH_UNITS_PER_METRE)?;
        check_size(&f.depth, "depth image", (d.width, d.height))?;
        // The same product `read_depth_png` forms for the stored 65535.
        let invalid = f32::from(INVALID_DEPTH) * (1.0 / DEPTH_UNITS_PER_METRE) as f32;
        for z in &mut d.depth {
            if *z == invalid {
                *z = 0.0;
            }
        }
        Ok(d)
    }

    /// The colour image of frame `i` (8-bit sRGB).
    pub fn read_color(&self, i: usize) -> Result<RgbImage, CloudError> {
        let f = self.frame(i)?;
        let c = super::rgb::read_rgb(&f.color)?;
        check_size(&f.color, "colour image", c.dimensions())?;
        Ok(c)
    }

    /// The positions `pick` takes among the frames; picking none is an
    /// error naming the folder.
    pub fn pick(&self, pick: &FramePick) -> Result<Vec<usize>, CloudError> {
        let picked = pick.positions(self.len());
        if picked.is_empty() {
            return Err(CloudError::Invalid {
                source_name: self.dir.display().to_string(),
                reason: format!(
                    "no frames picked (offset {}, step {}) of its {} frames",
                    pick.offset,
                    pick.step.max(1),
                    self.len()
                ),
            });
        }
        Ok(picked)
    }

    /// Checks the colour image of frame `i` without decoding it: a whole
    /// JPEG of 640 x 480 pixels (for readers that decode it themselves,
    /// such as an image encoder's).
    pub fn check_color(&self, i: usize) -> Result<(), CloudError> {
        let f = self.frame(i)?;
        let bytes = crate::io::bounded_read::read_regular(&f.color)
            .map_err(|e| CloudError::io(&f.color, e))?;
        let size = super::rgb::image_size(&bytes, &f.color)?;
        check_size(&f.color, "colour image", size)
    }

    /// The ground-truth poses turned into the z-up world omcl maps a
    /// 7-Scenes folder in: one rotation of the whole dataset taking gravity
    /// (`gravity-direction.txt`, in the first frame's camera) to -z, so
    /// that floor, height and the paper's local start mean what they mean
    /// indoors. Without the gravity file, the dataset's own world.
    pub fn poses_z_up(&self) -> Vec<Pose> {
        let up = match &self.gravity_in_first_camera {
            Some(g) => z_up_from_world(&self.poses[0], g),
            None => Pose::identity(),
        };
        self.poses.iter().map(|p| up * p).collect()
    }

    fn frame(&self, i: usize) -> Result<&FrameFiles, CloudError> {
        self.frames.get(i).ok_or_else(|| CloudError::Invalid {
            source_name: self.dir.display().to_string(),
            reason: format!("frame {i} asked for, the sequence has {}", self.len()),
        })
    }
}

/// The rotation taking the dataset's world to one whose z points up
/// (against gravity), given gravity in the first camera's frame.
pub fn z_up_from_world(world_from_first: &Pose, gravity_in_first: &Vector3<f64>) -> Pose {
    let down = world_from_first.rotation * gravity_in_first;
    let rot = UnitQuaternion::rotation_between(&(-down), &Vector3::z()).unwrap_or_else(|| {
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
    });
    Pose::from_parts(Translation3::identity(), rot)
}

/// Which frames of a 7-Scenes folder a run uses: positions `offset`,
/// `offset + step`, ... of the sorted frames, at most `limit` of them
/// (e.g. step 2 for a map from the even frames; step 8, offset 1 to
/// localize every 4th odd frame, so a step moves several centimetres).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FramePick {
    pub step: usize,
    pub offset: usize,
    pub limit: Option<usize>,
}

impl Default for FramePick {
    /// Every frame.
    fn default() -> Self {
        FramePick {
            step: 1,
            offset: 0,
            limit: None,
        }
    }
}

impl FramePick {
    /// The picked positions among `n` frames (`step` 0 is taken as 1).
    pub fn positions(&self, n: usize) -> Vec<usize> {
        (self.offset..n)
            .step_by(self.step.max(1))
            .take(self.limit.unwrap_or(usize::MAX))
            .collect()
    }
}

fn check_size(path: &Path, what: &str, got: (u32, u32)) -> Result<(), CloudError> {
    if got != IMAGE_SIZE {
        return Err(CloudError::format(
            path,
            format!(
                "{what} is {}x{} pixels, 7-Scenes images are {}x{}",
                got.0, got.1, IMAGE_SIZE.0, IMAGE_SIZE.1
            ),
        ));
    }
    Ok(())
}

/// Whitespace-separated finite numbers of `text`, exactly `n` of them.
fn numbers(text: &str, n: usize, what: &str) -> Result<Vec<f64>, String> {
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|s| {
            s.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("'{s}' is not a finite number"))
        })
        .collect::<Result<_, _>>()?;
    if v.len() != n {
        return Err(format!("expected {what} ({n} numbers), found {}", v.len()));
    }
    Ok(v)
}

/// Parses a 4 x 4 row-major `world_from_camera`: the last row must be
/// `0 0 0 1` and the upper-left 3 x 3 a rotation (orthonormal and
/// `det = +1` within [`ROTATION_TOLERANCE`]); it is re-orthonormalised.
pub fn parse_pose(text: &str) -> Result<Pose, String> {
    let v = numbers(text, 16, "a 4x4 matrix")?;
    if v[12..16] != [0.0, 0.0, 0.0, 1.0] {
        return Err(format!(
            "last row is {:?}, expected 0 0 0 1: not a rigid transform",
            &v[12..16]
        ));
    }
    let r = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
    let ortho = (r.transpose() * r - Matrix3::identity()).abs().max();
    let det = r.determinant();
    if ortho > ROTATION_TOLERANCE || (det - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(format!(
            "the upper-left 3x3 is not a rotation (|R^T R - I| = {ortho:.2e}, det = {det:.4})"
        ));
    }
    // The matrix is only nearly orthonormal: its quaternion is normalised
    // (the filter checks unit length to 1e-6).
    let rot = UnitQuaternion::new_normalize(
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)).into_inner(),
    );
    Ok(Pose::from_parts(Translation3::new(v[3], v[7], v[11]), rot))
}

/// Parses `camera-intrinsics.txt`: a 3 x 3 K `fx 0 cx; 0 fy cy; 0 0 1`
/// for 640 x 480 images, integer-centre convention.
pub fn parse_intrinsics(text: &str) -> Result<Intrinsics, String> {
    let v = numbers(text, 9, "a 3x3 camera matrix")?;
    if [v[1], v[3], v[6], v[7], v[8]] != [0.0, 0.0, 0.0, 0.0, 1.0] {
        return Err("expected a camera matrix 'fx 0 cx / 0 fy cy / 0 0 1'".into());
    }
    if v[0] <= 0.0 || v[4] <= 0.0 {
        return Err("focal lengths must be positive".into());
    }
    let k = Intrinsics {
        fx: v[0],
        fy: v[4],
        cx: v[2] + 0.5,
        cy: v[5] + 0.5,
        width: IMAGE_SIZE.0,
        height: IMAGE_SIZE.1,
    };
    k.check()?;
    Ok(k)
}

/// Parses `gravity-direction.txt`: three numbers, a non-zero vector,
/// returned at unit length.
pub fn parse_gravity(text: &str) -> Result<Vector3<f64>, String> {
    let v = numbers(text, 3, "a gravity vector")?;
    let g = Vector3::new(v[0], v[1], v[2]);
    g.try_normalize(1e-9)
        .ok_or_else(|| "the gravity vector is zero".to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pose_parses_and_non_rotations_are_refused() {
        let p = parse_pose("0 -1 0 1\n1 0 0 2\n0 0 1 3\n0 0 0 1\n").unwrap();
        let q = p * nalgebra::Point3::new(1.0, 0.0, 0.0);
        assert!((q - nalgebra::Point3::new(1.0, 3.0, 3.0)).norm() < 1e-12);
        // A matrix 2e-4 off orthonormal (as the dataset's) gives a unit
        // quaternion.
        let near = parse_pose("1.0002 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1").unwrap();
        assert!((near.rotation.coords.norm() - 1.0).abs() < 1e-12);
        // A scaled matrix, a reflection, a bad last row, a NaN, too few.
        let scaled = parse_pose("2 0 0 0 0 2 0 0 0 0 2 0 0 0 0 1").unwrap_err();
        assert!(scaled.contains("not a rotation"), "{scaled}");
        let mirror = parse_pose("-1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1").unwrap_err();
        assert!(mirror.contains("det = -1"), "{mirror}");
        assert!(
            parse_pose("1 0 0 0 0 1 0 0 0 0 1 0 0 0 1 1")
                .unwrap_err()
                .contains("last row")
        );
        assert!(
            parse_pose("1 0 0 nan 0 1 0 0 0 0 1 0 0 0 0 1")
                .unwrap_err()
                .contains("finite")
        );
        assert!(parse_pose("1 0 0 0").unwrap_err().contains("found 4"));
    }

    #[test]
    fn intrinsics_move_to_pixel_centres_at_half() {
        let k = parse_intrinsics("585 0 320\n0 585 240\n0 0 1\n").unwrap();
        assert_eq!((k.fx, k.fy, k.cx, k.cy), (585.0, 585.0, 320.5, 240.5));
        assert!(parse_intrinsics("585 1 320 0 585 240 0 0 1").is_err());
        assert!(parse_intrinsics("-5 0 320 0 585 240 0 0 1").is_err());
    }

    proptest::proptest! {
        #[test]
        fn any_rigid_transform_round_trips(
            angles in proptest::array::uniform3(-3.1f64..3.1),
            t in proptest::array::uniform3(-10.0f64..10.0),
        ) {
            let r = Rotation3::from_euler_angles(angles[0], angles[1], angles[2]);
            let m = r.matrix();
            let text = (0..3)
                .map(|i| format!("{:e} {:e} {:e} {:e}\n", m[(i, 0)], m[(i, 1)], m[(i, 2)], t[i]))
                .collect::<String>()
                + "0 0 0 1\n";
            let p = parse_pose(&text).unwrap();
            proptest::prop_assert!((p.translation.vector - Vector3::from(t)).norm() < 1e-12);
            proptest::prop_assert!(p.rotation.to_rotation_matrix().matrix().relative_eq(m, 1e-12, 1e-12));
        }

        #[test]
        fn arbitrary_text_is_an_error_or_a_value_never_a_panic(s in "[0-9eE+\\-. \n]{0,120}|.{0,60}") {
            let _ = parse_pose(&s);
            let _ = parse_intrinsics(&s);
            let _ = parse_gravity(&s);
        }
    }

    #[test]
    fn gravity_turns_into_minus_z() {
        let first = Pose::from_parts(
            Translation3::new(1.0, 2.0, 3.0),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0),
        );
        let g = Vector3::new(0.1, 0.9, 0.4).normalize();
        let up = z_up_from_world(&first, &g);
        let down_world = first.rotation * g;
        let d = up.rotation * down_world;
        assert!((d - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
    }

    #[test]
    fn frame_pick_takes_every_step_from_the_offset_up_to_the_limit() {
        let p = |step, offset, limit| {
            FramePick {
                step,
                offset,
                limit,
            }
            .positions(20)
        };
        assert_eq!(p(8, 1, None), vec![1, 9, 17]);
        assert_eq!(p(2, 0, Some(3)), vec![0, 2, 4]);
        assert_eq!(p(0, 18, None), vec![18, 19]);
        assert!(p(1, 20, None).is_empty());
        assert_eq!(FramePick::default().positions(3), vec![0, 1, 2]);
    }

    #[test]
    fn gravity_is_unit_and_zero_is_refused() {
        let g = parse_gravity("0 3 4").unwrap();
        assert!((g - Vector3::new(0.0, 0.6, 0.8)).norm() < 1e-12);
        assert!(parse_gravity("0 0 0").is_err());
    }
}
