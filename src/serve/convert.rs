//! Between the wire's messages and the library's types, with the checks
//! that turn malformed input into named INVALID_ARGUMENT answers.

use std::time::{Duration, Instant};

use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use tonic::{Code, Status};

use crate::geometry::{Intrinsics, Pose};
use crate::mcl::{Particle, PromptParams};
use crate::session::{PoseReport, SessionError, SharedMap, Start};

use super::proto;
use super::stamp::Stamp;

/// The paper's initial spread when a covariance does not give one.
pub const DEFAULT_INIT_SIGMA_M: f64 = 0.3;
pub const DEFAULT_INIT_SIGMA_DEG: f64 = 17.0;

pub fn pose_msg(p: &Pose) -> proto::Pose {
    let t = p.translation.vector;
    let q = p.rotation.coords;
    proto::Pose {
        position: Some(proto::Point {
            x: t.x,
            y: t.y,
            z: t.z,
        }),
        orientation: Some(proto::Quaternion {
            x: q.x,
            y: q.y,
            z: q.z,
            w: q.w,
        }),
    }
}

/// A pose from the wire: every number finite, the quaternion of unit
/// length within 1e-3 (then normalized).
pub fn pose_from_msg(p: Option<&proto::Pose>, what: &str) -> Result<Pose, Status> {
    let p = p.ok_or_else(|| Status::invalid_argument(format!("{what}: missing")))?;
    let (Some(t), Some(q)) = (&p.position, &p.orientation) else {
        return Err(Status::invalid_argument(format!(
            "{what}: needs position and orientation"
        )));
    };
    let v = [t.x, t.y, t.z, q.x, q.y, q.z, q.w];
    if !v.iter().all(|x| x.is_finite()) {
        return Err(Status::invalid_argument(format!(
            "{what} is not finite: position ({}, {}, {}), orientation (x y z w) ({}, {}, {}, {})",
            v[0], v[1], v[2], v[3], v[4], v[5], v[6]
        )));
    }
    let quat = Quaternion::new(q.w, q.x, q.y, q.z);
    let n = quat.norm();
    if (n - 1.0).abs() > 1e-3 {
        return Err(Status::invalid_argument(format!(
            "{what}: orientation is not a unit quaternion (norm {n})"
        )));
    }
    Ok(Pose::from_parts(
        Translation3::new(t.x, t.y, t.z),
        UnitQuaternion::from_quaternion(quat),
    ))
}

/// The status code's name as gRPC spells it.
pub fn code_name(c: Code) -> &'static str {
    match c {
        Code::Ok => "OK",
        Code::Cancelled => "CANCELLED",
        Code::Unknown => "UNKNOWN",
        Code::InvalidArgument => "INVALID_ARGUMENT",
        Code::DeadlineExceeded => "DEADLINE_EXCEEDED",
        Code::NotFound => "NOT_FOUND",
        Code::AlreadyExists => "ALREADY_EXISTS",
        Code::PermissionDenied => "PERMISSION_DENIED",
        Code::ResourceExhausted => "RESOURCE_EXHAUSTED",
        Code::FailedPrecondition => "FAILED_PRECONDITION",
        Code::Aborted => "ABORTED",
        Code::OutOfRange => "OUT_OF_RANGE",
        Code::Unimplemented => "UNIMPLEMENTED",
        Code::Internal => "INTERNAL",
        Code::Unavailable => "UNAVAILABLE",
        Code::DataLoss => "DATA_LOSS",
        Code::Unauthenticated => "UNAUTHENTICATED",
    }
}

pub fn frame_error(s: &Status, stamp: Option<proto::Time>) -> proto::FrameError {
    proto::FrameError {
        code: code_name(s.code()).into(),
        message: s.message().into(),
        header: Some(proto::Header {
            stamp,
            frame_id: String::new(),
        }),
    }
}

pub fn pose_update(
    r: &PoseReport,
    frame_id: &str,
    stamp: Option<proto::Time>,
    dropped: u64,
    latency: Duration,
    particles: Option<proto::ParticleCloud>,
) -> proto::PoseUpdate {
    let t = &r.step.timings;
    let step = t.features + t.predict + t.weigh + t.update;
    proto::PoseUpdate {
        pose: Some(proto::PoseWithCovarianceStamped {
            header: Some(proto::Header {
                stamp,
                frame_id: frame_id.into(),
            }),
            pose: Some(proto::PoseWithCovariance {
                pose: Some(pose_msg(&r.pose)),
                covariance: r.covariance.to_vec(),
            }),
        }),
        confidence: r.step.confidence,
        ess: r.step.ess,
        spread_m: r.step.spread,
        frame: r.frame,
        frames_dropped: dropped,
        step_ms: 1e3 * step.as_secs_f64(),
        latency_ms: 1e3 * latency.as_secs_f64(),
        particles,
    }
}

pub fn particle_cloud(ps: &[Particle], frame_id: &str, frame: &FrameInput) -> proto::ParticleCloud {
    proto::ParticleCloud {
        header: Some(proto::Header {
            stamp: frame.stamp_msg,
            frame_id: frame_id.into(),
        }),
        particles: ps
            .iter()
            .map(|p| proto::Particle {
                pose: Some(pose_msg(&p.pose)),
                weight: p.weight,
            })
            .collect(),
    }
}

/// A start around a pose: standard deviations from the covariance's x and
/// yaw entries (indices 0 and 35), the paper's defaults where they are 0.
pub fn initial_pose(p: &proto::PoseWithCovarianceStamped) -> Result<Start, Status> {
    let pc = p
        .pose
        .as_ref()
        .ok_or_else(|| Status::invalid_argument("initial pose: missing pose"))?;
    let pose = pose_from_msg(pc.pose.as_ref(), "initial pose")?;
    let c = &pc.covariance;
    if !(c.is_empty() || c.len() == 36) {
        return Err(Status::invalid_argument(format!(
            "initial pose: covariance has {} entries, expected 36 (or none)",
            c.len()
        )));
    }
    let var = |i: usize| c.get(i).copied().unwrap_or(0.0);
    let (vx, vyaw) = (var(0), var(35));
    if !(vx.is_finite() && vx >= 0.0 && vyaw.is_finite() && vyaw >= 0.0) {
        return Err(Status::invalid_argument(format!(
            "initial pose: variances must be finite and >= 0, got x {vx}, yaw {vyaw}"
        )));
    }
    Ok(Start::Pose {
        pose,
        sigma_m: if vx > 0.0 {
            vx.sqrt()
        } else {
            DEFAULT_INIT_SIGMA_M
        },
        sigma_rad: if vyaw > 0.0 {
            vyaw.sqrt()
        } else {
            DEFAULT_INIT_SIGMA_DEG.to_radians()
        },
    })
}

/// Most characters of a client's string an error message quotes.
const QUOTED_CHARS: usize = 64;

/// A client's string (a map or session name, a word) quoted for an error
/// message: whole up to 64 characters, else its start and its length. A
/// status message travels in an HTTP/2 header, so a megabyte-long name
/// echoed whole broke the answer into a protocol error.
pub fn quoted(s: &str) -> String {
    match s.char_indices().nth(QUOTED_CHARS) {
        None => format!("{s:?}"),
        Some((end, _)) => format!("{:?}... ({} bytes)", &s[..end], s.len()),
    }
}

/// A prompt start: the words looked up in the map's class table.
pub fn prompt(p: &proto::PromptStart, map: &SharedMap) -> Result<Start, Status> {
    let classes = map.classes().ok_or_else(|| {
        Status::failed_precondition(format!(
            "map {:?} has no class table: prompt words cannot be looked up",
            map.name()
        ))
    })?;
    if p.words.is_empty() {
        return Err(Status::invalid_argument("prompt: no words"));
    }
    let words = p
        .words
        .iter()
        .map(|w| {
            classes.word(w.trim()).map(<[f32]>::to_vec).ok_or_else(|| {
                Status::invalid_argument(format!(
                    "prompt word {} is not a class of map {:?}",
                    quoted(w),
                    map.name()
                ))
            })
        })
        .collect::<Result<_, _>>()?;
    let d = PromptParams::default();
    Ok(Start::Prompt {
        words,
        params: PromptParams {
            radius: p.radius.unwrap_or(d.radius),
            rho: p.rho.unwrap_or(d.rho),
            k: p.k.unwrap_or(d.k),
            ..d
        },
    })
}

/// A frame checked against its session, ready for the pool.
pub struct FrameInput {
    pub odom: Pose,
    /// `None`: the frame has no stamp (no header, or none in it); it is
    /// not ordered ([`super::stamp`]) and steps at 0 s.
    pub stamp: Option<Stamp>,
    pub stamp_msg: Option<proto::Time>,
    pub features: Features,
    /// z-depths of the camera's pixels (metres, 0 none), for SIMP\*.
    pub depth: Option<Vec<f32>>,
    pub want_particles: bool,
    pub received: Instant,
}

pub enum Features {
    Grid {
        shape: [usize; 3],
        data: Vec<f32>,
    },
    Labels {
        width: u32,
        height: u32,
        labels: Vec<u32>,
    },
    /// A raw RGB image for the map's encoder.
    Image(image::RgbImage),
    /// A PNG or JPEG file for the map's encoder, its header checked,
    /// decoded when the frame is stepped ([`Features::decode`]).
    Compressed(Vec<u8>),
}

impl FrameInput {
    /// The stamp in seconds, as the session takes it (0 without one).
    pub fn seconds(&self) -> f64 {
        self.stamp.map_or(0.0, Stamp::seconds)
    }
}

/// How errors name a [`Features::Compressed`] frame's bytes.
const COMPRESSED: &str = "compressed image";

impl Features {
    /// Turns a [`Features::Compressed`] frame into the [`Features::Image`]
    /// its bytes decode to (others stay as they are), or says why not.
    pub fn decode(&mut self) -> Result<(), SessionError> {
        if let Features::Compressed(bytes) = self {
            let rgb = crate::io::rgb::rgb_from_bytes(bytes, std::path::Path::new(COMPRESSED))
                .map_err(|e| SessionError::BadFrame(e.to_string()))?;
            *self = Features::Image(rgb);
        }
        Ok(())
    }
}

/// A frame checked against its session: stamp, sizes, dimensions,
/// odometry. (Its stamp's order among the session's frames is the
/// queue's to check, [`super::stamp::follows`].)
pub fn frame_input(f: proto::Frame, k: &Intrinsics, map: &SharedMap) -> Result<FrameInput, Status> {
    let received = Instant::now();
    let stamp_msg = f.header.as_ref().and_then(|h| h.stamp);
    let stamp = stamp_msg.as_ref().map(Stamp::from_msg).transpose()?;
    let odom = pose_from_msg(f.odometry.as_ref(), "odometry")?;
    let features = match f.features {
        Some(proto::frame::Features::Grid(g)) => grid_features(g, map)?,
        Some(proto::frame::Features::Labels(l)) => label_features(l, k, map)?,
        Some(proto::frame::Features::Image(img)) => image_features(img, k, map)?,
        Some(proto::frame::Features::Compressed(c)) => compressed_features(c, k, map)?,
        None => return Err(Status::invalid_argument("frame without features")),
    };
    let depth = f.depth.map(|d| depth_image(d, k)).transpose()?;
    Ok(FrameInput {
        odom,
        stamp,
        stamp_msg,
        features,
        depth,
        want_particles: f.want_particles,
        received,
    })
}

/// A depth image of the camera's size, every depth finite and >= 0.
fn depth_image(d: proto::DepthImage, k: &Intrinsics) -> Result<Vec<f32>, Status> {
    if (d.width, d.height) != (k.width, k.height) {
        return Err(Status::invalid_argument(format!(
            "depth image of {}x{}, the session's camera is {}x{}",
            d.width, d.height, k.width, k.height
        )));
    }
    let want = k.width as usize * k.height as usize;
    if d.depth.len() != want {
        return Err(Status::invalid_argument(format!(
            "depth image of {}x{} needs {want} values, got {}",
            d.width,
            d.height,
            d.depth.len()
        )));
    }
    if let Some(i) = d.depth.iter().position(|z| !(z.is_finite() && *z >= 0.0)) {
        return Err(Status::invalid_argument(format!(
            "depth value {i} (row {}, column {}) must be finite and >= 0 (0: no depth), got {}",
            i / k.width as usize,
            i % k.width as usize,
            d.depth[i]
        )));
    }
    Ok(d.depth)
}

/// A feature grid of the map's dimension, every value finite, some cell
/// with a direction.
fn grid_features(g: proto::FeatureGrid, map: &SharedMap) -> Result<Features, Status> {
    let dim = map.map().db().dim();
    let shape = [g.height as usize, g.width as usize, g.dim as usize];
    if g.dim as usize != dim {
        return Err(Status::invalid_argument(format!(
            "feature dimension {} does not match map {:?}'s {dim}",
            g.dim,
            map.name()
        )));
    }
    if shape.contains(&0) {
        return Err(Status::invalid_argument(format!(
            "feature grid of {}x{}x{}: every size must be above 0",
            g.height, g.width, g.dim
        )));
    }
    let want = shape[0] * shape[1] * shape[2];
    if g.data.len() != want {
        return Err(Status::invalid_argument(format!(
            "feature grid of {}x{}x{} needs {want} values, got {}",
            g.height,
            g.width,
            g.dim,
            g.data.len()
        )));
    }
    if let Some(i) = g.data.iter().position(|x| !x.is_finite()) {
        let (cell, k) = (i / shape[2], i % shape[2]);
        return Err(Status::invalid_argument(format!(
            "feature grid value {i} (row {}, column {}, feature {k}) is not finite: {}",
            cell / shape[1],
            cell % shape[1],
            g.data[i]
        )));
    }
    // A cell without a direction scores 0 against every map row, hit or
    // miss (the sensor model's rule: a zero norm, or one that overflows
    // f32): it adds nothing to any particle's weight. A few such cells
    // (a mask, padding) are harmless; a grid of nothing else would step
    // the filter on odometry alone while it looks as sure as before.
    if !g.data.chunks_exact(shape[2]).any(has_direction) {
        return Err(Status::invalid_argument(format!(
            "feature grid of {}x{}x{} is all zero: none of its {} cells has a feature with a \
             direction, so every cosine would be 0 and the frame would tell the filter nothing \
             (an encoder that failed, or a buffer never filled?)",
            g.height,
            g.width,
            g.dim,
            shape[0] * shape[1]
        )));
    }
    Ok(Features::Grid {
        shape,
        data: g.data,
    })
}

/// Whether a cell's feature has a direction as the sensor model sees it:
/// its norm in `f32` above 0 and finite.
fn has_direction(f: &[f32]) -> bool {
    let n: f32 = f.iter().map(|x| x * x).sum();
    n > 0.0 && n.is_finite()
}

/// A label image of the camera's size, for a map with a class table.
fn label_features(
    l: proto::LabelImage,
    k: &Intrinsics,
    map: &SharedMap,
) -> Result<Features, Status> {
    if (l.width, l.height) != (k.width, k.height) {
        return Err(Status::invalid_argument(format!(
            "label image is {}x{} pixels, the session's camera {}x{}",
            l.width, l.height, k.width, k.height
        )));
    }
    if l.labels.len() != l.width as usize * l.height as usize {
        return Err(Status::invalid_argument(format!(
            "label image of {}x{} pixels needs {} labels, got {}",
            l.width,
            l.height,
            l.width as usize * l.height as usize,
            l.labels.len()
        )));
    }
    if map.classes().is_none() {
        return Err(Status::failed_precondition(format!(
            "map {:?} has no class table for label images (serve it with --classes)",
            map.name()
        )));
    }
    Ok(Features::Labels {
        width: l.width,
        height: l.height,
        labels: l.labels,
    })
}

/// An image of `size` pixels, for a map with an image encoder, or why not.
fn check_image(
    what: &str,
    size: (u32, u32),
    k: &Intrinsics,
    map: &SharedMap,
) -> Result<(), Status> {
    if size != (k.width, k.height) {
        return Err(Status::invalid_argument(format!(
            "{what} is {}x{} pixels, the session's camera {}x{}",
            size.0, size.1, k.width, k.height
        )));
    }
    if !map.has_encoder() {
        return Err(Status::failed_precondition(format!(
            "map {:?} has no image encoder for camera images (serve it with --image-model)",
            map.name()
        )));
    }
    Ok(())
}

/// A PNG or JPEG file of the camera's size (by its header), for a map
/// with an image encoder; decoded when stepped.
fn compressed_features(
    c: proto::CompressedImage,
    k: &Intrinsics,
    map: &SharedMap,
) -> Result<Features, Status> {
    let size = crate::io::rgb::image_size(&c.data, std::path::Path::new(COMPRESSED))
        .map_err(|e| Status::invalid_argument(e.to_string()))?;
    check_image(COMPRESSED, size, k, map)?;
    Ok(Features::Compressed(c.data))
}

/// An RGB image of the camera's size, for a map with an image encoder.
fn image_features(
    img: proto::RgbImage,
    k: &Intrinsics,
    map: &SharedMap,
) -> Result<Features, Status> {
    check_image("RGB image", (img.width, img.height), k, map)?;
    let want = img.width as usize * img.height as usize * 3;
    let got = img.rgb.len();
    let rgb = image::RgbImage::from_raw(img.width, img.height, img.rgb)
        .filter(|_| got == want)
        .ok_or_else(|| {
            Status::invalid_argument(format!(
                "RGB image of {}x{} pixels needs {want} bytes, got {got}",
                img.width, img.height
            ))
        })?;
    Ok(Features::Image(rgb))
}

#[cfg(test)]
mod tests {
    use super::quoted;

    #[test]
    fn quoted_names_are_whole_when_short_and_cut_on_a_character_when_long() {
        assert_eq!(quoted("room"), "\"room\"");
        let edge = "é".repeat(64);
        assert_eq!(quoted(&edge), format!("{edge:?}"));
        let long = "é".repeat(65);
        let q = quoted(&long);
        assert_eq!(q, format!("{:?}... (130 bytes)", "é".repeat(64)));
    }
}
