//! Files of the simulator: reading real CLIP embeddings and real
//! trajectories, writing datasets in the real datasets' layouts. Parsing
//! and formatting only; every write goes through a temporary file renamed
//! into place.
//!
//! # Indoor RGB-D sequence layout (`omcl sim indoor`)
//!
//! ```text
//! DIR/intrinsics.txt       fx fy cx cy width height   (pixels; one line)
//! DIR/poses.txt            TUM: t tx ty tz qx qy qz qw, world_from_camera
//!                          (OpenCV camera, world z up, metres); t = frame index / 30 s
//! DIR/odometry.txt         same format: noisy odometry poses
//! DIR/rgb/NNNNNN.png       8-bit RGB (for people; class colours, shaded)
//! DIR/depth/NNNNNN.png     16-bit z-depth, metres * 5000, 0 = invalid (TUM)
//! DIR/labels/NNNNNN.png    16-bit class id (line index of classes.txt);
//!                          65535 = no surface
//! DIR/features/NNNNNN.npy  optional (--features): f32, H' x W' x F pixel
//!                          features at every stride-th pixel (stride in sim.json)
//! DIR/classes.txt          one class name per line, id = line index
//! DIR/embeddings.npy       f32, K x F unit rows, row i = classes.txt line i
//! DIR/world/voxels.ply     ground truth: binary PLY, voxel centres (world,
//!                          float x y z) with a ushort `label` property
//! DIR/world/cells.npy      f32, N x 3 integer cell indices (grid frame)
//! DIR/world/labels.npy     f32, N class ids of those cells
//! DIR/world/world.json     resolution, origin (world of grid zero), classes
//! DIR/sim.json             generator parameters, seed, preset, summary
//! ```
//!
//! # Outdoor KITTI odometry layout (`omcl sim outdoor`)
//!
//! `DIR/sequences/00/` with `velodyne/NNNNNN.bin` (float32 x y z
//! reflectance, LiDAR frame), `labels/NNNNNN.label` (uint32, SemanticKITTI
//! class in the low 16 bits), `calib.txt` (P0..P3, Tr), `poses.txt` (KITTI
//! 3x4 camera-0 poses relative to the first camera), `times.txt`, and for
//! camera 2 `image_2/NNNNNN.png` (RGB, 1241 x 376), `labels_2/NNNNNN.png`
//! (16-bit SemanticKITTI ids of the surface each pixel sees, 0 = sky),
//! optional `features_2/NNNNNN.npy` (`--features`: f32, H' x W' x F at
//! every stride-th pixel), `classes.txt` (`<id> <name>`, SemanticKITTI ids)
//! and `embeddings.npy` (the rows of those classes); plus
//! `DIR/classes.txt`, `DIR/embeddings.npy`, `DIR/semantickitti_ids.txt`,
//! `DIR/world/` and `DIR/sim.json` as above.

use std::path::{Path, PathBuf};

use nalgebra::{Quaternion, UnitQuaternion};

use super::embeddings::{ClassEmbeddings, ClipBank, EmbeddingError};
use super::world::VoxelWorld;
use crate::geometry::{Intrinsics, Pose};
use crate::io::npy::{NpyError, read_npy, write_npy};
use crate::io::poses::{PoseFormat, format_poses, read_poses_in};
use crate::trajectory::Trajectory;

/// Errors of simulator file I/O; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum SimIoError {
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
    #[error(transparent)]
    Npy(#[from] NpyError),
    #[error("{path}: PNG: {reason}")]
    Png { path: PathBuf, reason: String },
    #[error(transparent)]
    Poses(#[from] crate::io::poses::PosesError),
    #[error("{path}: {source}")]
    Embedding {
        path: PathBuf,
        source: EmbeddingError,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> SimIoError + '_ {
    move |source| SimIoError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn read_text(path: &Path) -> Result<String, SimIoError> {
    crate::io::bounded_read::read_text(path).map_err(io_err(path))
}

/// Writes `bytes` to `path` through a temporary file in the same directory.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), SimIoError> {
    crate::io::atomic::write(path, bytes).map_err(io_err(path))
}

/// Creates a directory and its parents.
pub fn create_dir(path: &Path) -> Result<(), SimIoError> {
    crate::io::atomic::create_folder(path).map_err(io_err(path))
}

/// Loads the real CLIP ViT-B/32 text embeddings of `dir` (the layout of
/// `shared/data/clip_text`): LVIS first, then COCO, then Objects365, so a
/// name found in several vocabularies takes its LVIS row.
pub fn load_clip_bank(dir: &Path) -> Result<ClipBank, SimIoError> {
    let lvis_names: Vec<String> = read_text(&dir.join("lvis_v1_names.txt"))?
        .lines()
        .map(|l| l.trim().to_string())
        .filter(|l| !l.is_empty())
        .collect();
    let mut bank = bank_from(&dir.join("lvis_v1_clip_a+cname.npy"), lvis_names)?;
    let coco_names: Vec<String> = read_text(&dir.join("coco_names.txt"))?
        .lines()
        .map(|l| l.trim().to_string())
        .filter(|l| !l.is_empty())
        .collect();
    let coco = bank_from(&dir.join("coco_clip_a+cname.npy"), coco_names)?;
    let csv = dir.join("Objects365_names_fix.csv");
    let mut o365_names = Vec::new();
    for (i, line) in read_text(&csv)?.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let name = line.split(',').nth(1).ok_or_else(|| SimIoError::Parse {
            path: csv.clone(),
            line: i + 1,
            reason: "expected `id,name,name`".into(),
        })?;
        o365_names.push(name.trim().to_string());
    }
    let o365 = bank_from(&dir.join("o365_clip_a+cnamefix.npy"), o365_names)?;
    let emb = |source| SimIoError::Embedding {
        path: dir.to_path_buf(),
        source,
    };
    bank.extend(coco).map_err(emb)?;
    bank.extend(o365).map_err(emb)?;
    Ok(bank)
}

fn bank_from(npy: &Path, names: Vec<String>) -> Result<ClipBank, SimIoError> {
    let arr = read_npy(npy)?;
    let (rows, dim) = arr.as_matrix_dims();
    if rows != names.len() {
        return Err(SimIoError::Parse {
            path: npy.to_path_buf(),
            line: 0,
            reason: format!("{rows} rows but {} names", names.len()),
        });
    }
    ClipBank::new(names, dim, arr.data).map_err(|source| SimIoError::Embedding {
        path: npy.to_path_buf(),
        source,
    })
}

/// Saves a table as `classes.txt` (one name a line) and `embeddings.npy`
/// (K x F f32) in `dir`.
pub fn save_table(dir: &Path, table: &ClassEmbeddings) -> Result<(), SimIoError> {
    let mut names = table.names.join("\n");
    names.push('\n');
    write_atomic(&dir.join("classes.txt"), names.as_bytes())?;
    write_npy(
        &dir.join("embeddings.npy"),
        &[table.len(), table.dim],
        &table.rows,
    )?;
    Ok(())
}

/// Loads a table saved by [`save_table`] (or written by hand in that layout).
pub fn load_table(classes: &Path, embeddings: &Path) -> Result<ClassEmbeddings, SimIoError> {
    let names: Vec<String> = read_text(classes)?
        .lines()
        .map(|l| l.trim().to_string())
        .filter(|l| !l.is_empty())
        .collect();
    let arr = read_npy(embeddings)?;
    let (rows, dim) = arr.as_matrix_dims();
    if rows != names.len() {
        return Err(SimIoError::Parse {
            path: embeddings.to_path_buf(),
            line: 0,
            reason: format!(
                "{rows} rows but {} names in {}",
                names.len(),
                classes.display()
            ),
        });
    }
    ClassEmbeddings::new(names, dim, arr.data).map_err(|source| SimIoError::Embedding {
        path: embeddings.to_path_buf(),
        source,
    })
}

const BUILTIN_NAMES: &str = include_str!("data/sim_classes.txt");
const BUILTIN_NPY: &[u8] = include_bytes!("data/sim_classes.npy");

/// The embedded table of every simulator class (built from the real CLIP
/// embeddings by `omcl sim classes`; see `src/sim/data/README.md`), so the
/// simulator works without the shared data.
pub fn builtin_table() -> Result<ClassEmbeddings, SimIoError> {
    let path = PathBuf::from("<embedded sim_classes.npy>");
    let npy = npyz::NpyFile::new(BUILTIN_NPY).map_err(|e| SimIoError::Parse {
        path: path.clone(),
        line: 0,
        reason: e.to_string(),
    })?;
    let shape: Vec<usize> = npy.shape().iter().map(|&d| d as usize).collect();
    let rows: Vec<f32> = npy.into_vec::<f32>().map_err(|e| SimIoError::Parse {
        path: path.clone(),
        line: 0,
        reason: e.to_string(),
    })?;
    let names: Vec<String> = BUILTIN_NAMES
        .lines()
        .map(|l| l.trim().to_string())
        .filter(|l| !l.is_empty())
        .collect();
    let dim = shape.get(1).copied().unwrap_or(0);
    ClassEmbeddings::new(names, dim, rows).map_err(|source| SimIoError::Embedding { path, source })
}

/// Reads a KITTI pose file through [`crate::io::poses`] (the crate's one
/// pose parser: rotations re-orthonormalized, non-rigid poses refused with
/// the file and line).
pub fn read_kitti_poses(path: &Path) -> Result<Vec<Pose>, SimIoError> {
    read_poses(path, PoseFormat::Kitti)
}

/// Reads a TUM pose file (`t tx ty tz qx qy qz qw`, `#` comments) through
/// [`crate::io::poses`].
pub fn read_tum_poses(path: &Path) -> Result<Vec<Pose>, SimIoError> {
    read_poses(path, PoseFormat::Tum)
}

fn read_poses(path: &Path, format: PoseFormat) -> Result<Vec<Pose>, SimIoError> {
    let file = read_poses_in(path, format)?;
    Ok(file.trajectory.poses().to_vec())
}

/// Pose-file text of `poses` ([`crate::io::poses::format_poses`]): TUM
/// lines stamped `i / fps`, or KITTI lines (`fps` unused).
pub fn pose_lines(poses: &[Pose], format: PoseFormat, fps: f64) -> String {
    let stamps = (0..poses.len()).map(|i| i as f64 / fps).collect();
    match Trajectory::new(stamps, poses.to_vec()) {
        Ok(t) => format_poses(&t, format),
        // Stamps i / fps increase for any positive fps; an empty path
        // writes an empty file.
        Err(_) => String::new(),
    }
}

/// Formats intrinsics as `fx fy cx cy width height`.
pub fn intrinsics_line(k: &Intrinsics) -> String {
    format!(
        "{} {} {} {} {} {}\n",
        k.fx, k.fy, k.cx, k.cy, k.width, k.height
    )
}

fn png_bytes(
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
    path: &Path,
) -> Result<Vec<u8>, SimIoError> {
    let mut buf = Vec::new();
    let perr = |e: png::EncodingError| SimIoError::Png {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    {
        let mut enc = png::Encoder::new(&mut buf, width, height);
        enc.set_color(color);
        enc.set_depth(depth);
        enc.set_compression(png::Compression::Fast);
        // Says who wrote it: a frame of omcl's, which no figure output
        // replaces (figures carry `crate::plot::FIGURE_MARK` instead).
        enc.add_text_chunk(PNG_SOFTWARE.0.into(), PNG_SOFTWARE.1.into())
            .map_err(perr)?;
        let mut w = enc.write_header().map_err(perr)?;
        w.write_image_data(data).map_err(perr)?;
        w.finish().map_err(perr)?;
    }
    Ok(buf)
}

/// The `tEXt` chunk every PNG omcl writes carries: keyword and text.
const PNG_SOFTWARE: (&str, &str) = ("Software", "omcl");

/// Writes an 8-bit RGB PNG (`data` = width * height * 3 bytes).
pub fn write_png_rgb(path: &Path, width: u32, height: u32, data: &[u8]) -> Result<(), SimIoError> {
    let b = png_bytes(
        width,
        height,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        data,
        path,
    )?;
    write_atomic(path, &b)
}

/// Writes a 16-bit grayscale PNG (big-endian samples, as PNG requires).
pub fn write_png_gray16(
    path: &Path,
    width: u32,
    height: u32,
    data: &[u16],
) -> Result<(), SimIoError> {
    let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_be_bytes()).collect();
    let b = png_bytes(
        width,
        height,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &bytes,
        path,
    )?;
    write_atomic(path, &b)
}

/// Writes the ground-truth world: `voxels.ply`, `cells.npy`, `labels.npy`
/// and `world.json` in `dir`.
pub fn write_world(dir: &Path, world: &VoxelWorld) -> Result<(), SimIoError> {
    create_dir(dir)?;
    let n = world.cells.len();
    let mut ply = format!(
        "ply\nformat binary_little_endian 1.0\ncomment omcl sim ground truth: voxel centres (world frame, metres), resolution {}\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\nproperty ushort label\nend_header\n",
        world.resolution
    )
    .into_bytes();
    ply.reserve(n * 14);
    for (c, &l) in world.cells.iter().zip(&world.labels) {
        let p = world.cell_centre(*c);
        for x in [p.x, p.y, p.z] {
            ply.extend_from_slice(&(x as f32).to_le_bytes());
        }
        ply.extend_from_slice(&l.to_le_bytes());
    }
    write_atomic(&dir.join("voxels.ply"), &ply)?;
    let cells: Vec<f32> = world
        .cells
        .iter()
        .flat_map(|c| c.map(|x| x as f32))
        .collect();
    write_npy(&dir.join("cells.npy"), &[n, 3], &cells)?;
    let labels: Vec<f32> = world.labels.iter().map(|&l| l as f32).collect();
    write_npy(&dir.join("labels.npy"), &[n], &labels)?;
    let meta = serde_json::json!({
        "resolution": world.resolution,
        "origin": [world.origin.x, world.origin.y, world.origin.z],
        "classes": world.classes,
        "cells": n,
        "frame": "cell (i,j,k) spans origin + [i,i+1)*resolution per axis; world z up, metres",
    });
    write_json(&dir.join("world.json"), &meta)
}

/// Writes pretty JSON.
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<(), SimIoError> {
    let s = serde_json::to_string_pretty(value).unwrap_or_default();
    write_atomic(path, s.as_bytes())
}

/// Writes a KITTI velodyne scan: float32 x y z reflectance per point.
pub fn write_velodyne(path: &Path, points: &[[f32; 4]]) -> Result<(), SimIoError> {
    let bytes: Vec<u8> = points
        .iter()
        .flat_map(|p| p.iter().flat_map(|x| x.to_le_bytes()))
        .collect();
    write_atomic(path, &bytes)
}

/// Writes SemanticKITTI labels: one uint32 per point (class low 16 bits).
pub fn write_labels(path: &Path, labels: &[u32]) -> Result<(), SimIoError> {
    let bytes: Vec<u8> = labels.iter().flat_map(|x| x.to_le_bytes()).collect();
    write_atomic(path, &bytes)
}

/// A camera rotation from a unit quaternion array `[qx, qy, qz, qw]`
/// (helper for readers of the TUM files written here).
pub fn quat(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_round_trip_through_tum_and_kitti_text() {
        use nalgebra::Translation3;
        let dir = tempfile::tempdir().unwrap();
        let p = Pose::from_parts(
            Translation3::new(1.0, -2.0, 0.5),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
        );
        let tum = dir.path().join("t.txt");
        write_atomic(
            &tum,
            pose_lines(&[p, p.inverse()], PoseFormat::Tum, 30.0).as_bytes(),
        )
        .unwrap();
        let back = read_tum_poses(&tum).unwrap();
        assert!((back[0].translation.vector - p.translation.vector).norm() < 1e-8);
        assert!(back[1].rotation.angle_to(&p.inverse().rotation) < 1e-8);
        let kit = dir.path().join("k.txt");
        write_atomic(&kit, pose_lines(&[p], PoseFormat::Kitti, 10.0).as_bytes()).unwrap();
        let back = read_kitti_poses(&kit).unwrap();
        assert!(back[0].rotation.angle_to(&p.rotation) < 1e-8);
        std::fs::write(&kit, "1 2 3\n").unwrap();
        let e = read_kitti_poses(&kit).unwrap_err().to_string();
        assert!(e.contains(":1:"), "{e}");
    }

    #[test]
    fn gray16_png_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.png");
        let data: Vec<u16> = (0..12).map(|i| i * 5000 + 7).collect();
        write_png_gray16(&path, 4, 3, &data).unwrap();
        let back = crate::io::rgbd::read_label_png(&path).unwrap();
        let data: Vec<u32> = data.into_iter().map(u32::from).collect();
        assert_eq!(back, (4, 3, data));
    }

    #[test]
    fn builtin_table_parses_and_knows_every_sim_class() {
        let t = builtin_table().unwrap();
        assert_eq!(t.dim, 512);
        for c in super::super::embeddings::SIM_CLASSES {
            assert!(t.index_of(c.name).is_some(), "{}", c.name);
        }
    }
}
