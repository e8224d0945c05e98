//! Monte Carlo Localization in a language map: the particle filter of the
//! paper (section "Localization") as small composable pieces.
//!
//! - [`particles`]: particles (camera poses and weights), normalization, ESS;
//! - [`motion`]: odometry composition with per-particle noise (planar, 6-DoF);
//! - [`sampling`]: which pixels are cast (stratified, uniform, equal with
//!   duplicates);
//! - [`sensor`]: the paper's eq. 2 via a per-frame similarity table;
//! - [`resample`]: low-variance resampling triggered by ESS;
//! - [`mod@estimate`]: weighted mean near the best particle, quaternion averaging;
//! - [`init`]: local, global (floor) and prompt-augmented initialization;
//! - [`kld`]: KLD-adaptive particle count;
//! - [`recovery`]: augmented-MCL injection after track loss;
//! - [`anneal`]: progressive correction (the likelihood over layers, for
//!   6-DoF);
//! - [`filter`]: the loop that strings them together;
//! - [`preset`]: the tuned filters by name.
//!
//! # Parameters the paper leaves open, and the defaults
//!
//! Defaults were chosen on the rooms convergence test in `tests.rs` (60
//! frames, 0.13 m and 8 degrees a frame, odometry noise 0.10 m / 6 degrees,
//! 256 particles x 256 rays, feature noise 0.5, 4 seeds); the full synthetic
//! benchmark may move them.
//!
//! | parameter | default | what it does |
//! |---|---|---|
//! | `SensorParams::miss_score` | 0 (streets 0.5) | score of a ray that hits nothing (a ray out of a window, into the sky or beyond `max_range`); with contrast scoring a hit scores 0 to 1, so 0 ranks a miss with the worst hit and negative penalizes poses looking out of the map; streets ([`FilterConfig::street`]) score misses 0.5, see [`sensor::STREET_MISS_SCORE`] |
//! | `SensorParams::max_range` | inf | rays longer than this (m) count as misses |
//! | `FilterConfig::sharpen` | 80 | exponent on `max(L, 0)`; 1 is the paper's eq. 2. RMSE 0.25 m at 1, 0.15 at 10, 0.10 at 40, 0.087 at 80, 0.10 at 160 |
//! | `ResamplePolicy::ess_fraction` | 0.5 | resample when ESS < fraction x n (>= 1: every step, as the authors); with sharpening 40+ it made no difference, without sharpening every step was better (0.18 vs 0.25 m) |
//! | `ResamplePolicy::reset_weights` | true | weights 1/n after resampling; `false` keeps old weights (authors' code): 0.110 vs 0.087 m at sharpen 80 |
//! | `EstimateParams::radius` | 0.3 m | particles within this distance of the best one enter the weighted mean; 0.2-0.3 best, 1 m up to 30 % worse |
//! | `MotionModel` | planar, 0.10 m, 6 deg | per-step noise sigmas (paper) |
//! | `SamplingParams` | stratified, 2048 draws, stride 4, boundary margin 0.75 % of the image width | draws are split equally over the clusters present, duplicates dropped, so the distinct rays are fewer than the draws; clusters are formed on a stride-4 pixel grid; the boundary margin skips pixels whose grid cell has a cell of another cluster within that many cells: 1 cell on the 540 x 540 benchmark (better there for gt and lseg-like features), 0 on images below about 270 px (where it would discard the boundaries that locate the camera); `boundary_margin: Some(n)` fixes it, `Some(0)` is the paper's sampling |
//! | `PromptParams` | R 2 m, rho 0.9, k 500 at 2 cm | `k` scales by `(k_resolution / res)^2` (80 voxels at 5 cm); distances are horizontal, walls are not considered |
//! | `FloorParams` | rho 0.9, camera 1.5 m, full yaw circle | floor detection and camera placement for global / prompt init |
//! | `KldParams` | AMCL's: epsilon 0.01, z 2.326, bins 0.5 m / 10 deg | particle count at resampling when `FilterConfig::kld` is set |
//! | `Anneal` | off (6-DoF: 2 layers, half the exponent each, jitter a third of the motion noise, the first layer on 16 copies of each particle and every 16th pixel) | progressive correction: the frame weighed with part of the exponent, resampled, jittered, weighed with the rest; `FilterConfig::six_dof` turns it on. Table I's 6-DoF block, tuning sequences 0-2: APE RMSE 0.246 m with one layer, 0.197 with two (jitter 1/3; 0.209 with 1/5), 0.195 with three; each layer casts every ray again. With 4096 x 512: 0.171 m, 0.162 with the first layer's 4 copies (`expand`, the same rays); 1024 x 2048 with 16 copies, the block's filter since 2026-11-26: 0.158 m (0.152 over sequences 0-5, against 0.158 with 4096 x 512 and 4 copies) |
//! | `RecoveryParams` | alpha 0.01 / 0.3, at most 30 %, 8 candidates an injected particle | augmented-MCL injection when `FilterConfig::recovery` is set and a `FloorSampler` is given; the best-scoring of 8 floor candidates are injected (sensor resetting). Kidnapped-camera test, 10 seeds: 0.001 / 0.1 / 20 % / plain injection found 7; these values 9, within 3 to 30 frames |
//!
//! Confidence per frame: [`StepReport`] carries the ESS, the spread (RMS
//! distance of the particles from the estimate, m) and the mean likelihood;
//! a spread above ~1 m or a sharp drop of the likelihood means the filter is
//! lost: re-initialize with [`Filter::reinitialize`] (e.g. from a new prompt).

pub mod anneal;
pub mod baseline_filter;
pub mod baselines;
pub mod estimate;
pub mod filter;
pub mod init;
pub mod kld;
pub mod motion;
pub mod particles;
pub mod preset;
pub mod recovery;
pub mod resample;
pub mod sampling;
pub mod sensor;

pub use crate::frame::{DenseFeatures, FrameFeatures};

/// Most particles, and most sampled pixels a frame, a filter takes from a
/// caller (`omcl localize`, `omcl bench`, `omcl serve`'s sessions, a
/// configuration's JSON): the bound keeps a mistyped count from sizing
/// terabytes.
pub const MAX_COUNT: usize = 1_000_000;
pub use anneal::Anneal;
pub use estimate::{Estimate, EstimateParams, average_rotations, estimate};
pub use filter::{
    FLOOR_PLAN_ESTIMATE_RADIUS, FLOOR_PLAN_RAYS, FLOOR_PLAN_SHARPEN, Filter, FilterConfig,
    INDOOR_PARTICLES, SIX_DOF_PARTICLES, SIX_DOF_POINT_CLOUD_RAYS, SIX_DOF_POINT_CLOUD_SHARPEN,
    SIX_DOF_RAYS, SIX_DOF_SHARPEN, STREET_PARTICLES, StepReport, StepTimings,
};
pub use init::{FloorParams, FloorSampler, PromptParams, global_init, local_init, prompt_init};
pub use motion::{MotionMode, MotionModel};
pub use particles::Particle;
pub use preset::{FilterPreset, UnknownFilter};
pub use resample::ResamplePolicy;
pub use sampling::{SamplingParams, SamplingStrategy};
pub use sensor::{
    EarlyReject, FOOTPRINT_DEPTH, RAY_GROUP, RayOrder, SensorModel, SensorParams, SimilarityTable,
    packet_order, pixel_major_pays,
};

/// Errors of the localization filter.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MclError {
    #[error("odometry increment is not finite: {0}")]
    BadOdometry(String),
    #[error("image features have dimension {got}, the map's database has {expected}")]
    DimMismatch { expected: usize, got: usize },
    #[error("image is {got_w}x{got_h} pixels, the intrinsics say {want_w}x{want_h}")]
    ImageSize {
        got_w: u32,
        got_h: u32,
        want_w: u32,
        want_h: u32,
    },
    #[error("the map's database is empty: nothing to compare features with")]
    EmptyDb,
    #[error(
        "the ray caster was built from {caster} voxels, the map has {map}: build the caster from \
         this map"
    )]
    CasterMismatch { caster: usize, map: usize },
    #[error("ray casting failed: {0}")]
    Cast(String),
    #[error(
        "no map voxel is similar enough to \"floor\" (similarity >= {rho}); cannot place particles"
    )]
    NoFloor { rho: f32 },
    /// `radius`: the one searched, at most the map's horizontal diagonal
    /// (`whole_map` when the asked one was wider and so capped).
    #[error(
        "no floor voxel has at least {k:.0} voxels matching every prompt word within {radius:.2} m{}",
        if *whole_map { " (the whole map: the radius asked for is wider than it)" } else { "" }
    )]
    NoPromptMatch {
        k: f64,
        radius: f64,
        whole_map: bool,
    },
    #[error("prompt word {index} has dimension {got}, the map's database has {expected}")]
    PromptDim {
        index: usize,
        expected: usize,
        got: usize,
    },
    #[error("the prompt has no words")]
    EmptyPrompt,
    #[error("invalid parameter {name}: {why}")]
    BadParam { name: &'static str, why: String },
    #[error("the particle set is empty")]
    NoParticles,
    #[error("no pixel could be sampled from the frame (image of zero size?)")]
    NoPixels,
}

#[cfg(test)]
mod tests;
