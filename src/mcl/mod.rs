//! Monte Carlo Localization in a language map: the particle filter of the
//! paper (section "Localization") as small composable pieces.
//!
//! - [`particles`]: particles (camera poses and weights), normalization, ESS;
//! - [`motion`]: odometry composition with per-particle noise (planar, 6-DoF);
//! - [`sampling`]: which pixels are cast (stratified, uniform, equal with
//!   duplicates);
//! - [`sensor`]: the paper's eq. 2 via a per-frame similarity table;
//! - [`resample`]: low-variance resampling triggered by ESS;
//! - [`estimate`]: weighted mean near the best particle, quaternion averaging;
//! - [`init`]: local, global (floor) and prompt-augmented initialization;
//! - [`kld`]: KLD-adaptive particle count;
//! - [`recovery`]: augmented-MCL injection after track loss;
//! - [`filter`]: the loop that strings them together.

pub mod estimate;
pub mod filter;
pub mod init;
pub mod kld;
pub mod motion;
pub mod particles;
pub mod recovery;
pub mod resample;
pub mod sampling;
pub mod sensor;

pub use estimate::{Estimate, EstimateParams, average_rotations, estimate};
pub use filter::{Filter, FilterConfig, StepReport, StepTimings};
pub use init::{FloorParams, FloorSampler, PromptParams, global_init, local_init, prompt_init};
pub use motion::{MotionMode, MotionModel};
pub use particles::Particle;
pub use resample::ResamplePolicy;
pub use sampling::{DenseFeatures, FrameFeatures, SamplingParams, SamplingStrategy};
pub use sensor::{SensorModel, SensorParams, SimilarityTable};

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
        "no map voxel is similar enough to \"floor\" (similarity >= {rho}); cannot place particles"
    )]
    NoFloor { rho: f32 },
    #[error(
        "no floor voxel has at least {k:.0} voxels matching every prompt word within {radius} m; \
         fall back to global initialization or relax rho / k"
    )]
    NoPromptMatch { k: f64, radius: f64 },
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
