//! One localization run over a benchmark sequence: the filter fed with the
//! sequence's odometry and simulated features, its estimates scored
//! against ground truth.

use std::sync::Arc;
use std::time::Instant;

use super::ExperimentError;
use super::features::{GridFeatures, SimFrameFeatures};
use super::sequence::BenchSequence;
use crate::eval::ErrorStats;
use crate::eval::localization::CompletionRule;
use crate::eval::localization::{SequenceSummary, summarize_sequences};
use crate::geometry::Pose;
use crate::map::LanguageMap;
use crate::mcl::{FilterConfig, FloorParams, PromptParams};
use crate::raycast::RayCaster;
use crate::session::{self, Session, SessionConfig, SessionError, SharedMap};
use crate::sim::features::{FeatureModel, Preset};

/// How the particles start.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Start {
    /// Around the true first pose: Gaussian 0.3 m / 17 degrees (paper).
    Local { sigma_m: f64, sigma_deg: f64 },
    /// Uniformly over the map's floor voxels.
    Global,
    /// Over the floor voxels near the prompt's classes (names of the
    /// sequence's class table).
    Prompt(Vec<String>),
}

impl Start {
    /// The paper's local start.
    pub fn paper_local() -> Self {
        Start::Local {
            sigma_m: 0.3,
            sigma_deg: 17.0,
        }
    }
}

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpec {
    pub filter: FilterConfig,
    pub particles: usize,
    pub start: Start,
    /// First frame of the run and number of frames (clipped to the
    /// sequence).
    pub first: usize,
    pub frames: usize,
    /// Features the localizer sees.
    pub preset: Preset,
    /// Output stride of the simulated encoder (1: a feature per pixel; see
    /// [`SimFrameFeatures::encoder_stride`]).
    pub encoder_stride: u32,
}

/// The outcome of a run.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct RunResult {
    /// Estimated `world_from_camera` per frame.
    #[serde(skip)]
    pub estimates: Vec<Pose>,
    /// Translation error per frame, metres.
    pub errors_m: Vec<f64>,
    pub stats: ErrorStats,
    /// [`CompletionRule::judge`]: `None` (null) for a run too short to
    /// judge.
    pub completed: Option<bool>,
    /// Filter time per step (pixel sampling and similarity table, predict,
    /// weigh, resample, estimate; rendering and the encoder excluded),
    /// seconds.
    pub step_seconds: Vec<f64>,
    /// The (simulated) encoder's time per step: the features of the
    /// sampling grid, computed before the step, seconds.
    pub encoder_seconds: Vec<f64>,
    /// Distinct rays per particle, mean over steps.
    pub mean_rays: f64,
    /// Rows of the map's feature database (K).
    pub map_rows: usize,
}

impl RunResult {
    /// Filter steps per second (mean step time), encoder excluded.
    pub fn fps(&self) -> f64 {
        let n = self.step_seconds.len().max(1) as f64;
        n / self.step_seconds.iter().sum::<f64>().max(1e-12)
    }

    /// Frames per second with the (simulated) encoder: filter and encoder
    /// one after the other.
    pub fn fps_with_encoder(&self) -> f64 {
        let n = self.step_seconds.len().max(1) as f64;
        let t: f64 = self.step_seconds.iter().chain(&self.encoder_seconds).sum();
        n / t.max(1e-12)
    }
}

/// The map row most similar to each class of the sequence's table.
pub fn class_rows(seq: &dyn BenchSequence, map: &LanguageMap) -> Vec<u32> {
    seq.class_rows(map)
}

fn text(seq: &dyn BenchSequence, name: &str) -> Result<Vec<f32>, ExperimentError> {
    seq.table()
        .text_feature(name)
        .map(<[f32]>::to_vec)
        .ok_or_else(|| ExperimentError::Config(format!("class {name:?} is not in the table")))
}

/// The filter's own errors keep their kind (Table V records them per run).
pub(crate) fn session_error(e: SessionError) -> ExperimentError {
    match e {
        SessionError::Init(e) | SessionError::Filter(e) => ExperimentError::Filter(e),
        e => ExperimentError::Config(e.to_string()),
    }
}

/// Runs the filter over `seq` in `map` (whose leaves `caster` indexes).
pub fn run(
    seq: &dyn BenchSequence,
    map: &LanguageMap,
    caster: Arc<dyn RayCaster>,
    model: &FeatureModel,
    spec: &RunSpec,
) -> Result<RunResult, ExperimentError> {
    let shared = SharedMap::from_parts("benchmark", map.clone(), caster);
    run_on(seq, Arc::new(shared), model, spec)
}

/// [`run`] on a shared map: a 3-D map, or a floor plan's 2-D scene
/// ([`SharedMap::floor_plan`], whose errors are then horizontal: its
/// cameras are held at their start's height).
pub fn run_on(
    seq: &dyn BenchSequence,
    shared: Arc<SharedMap>,
    model: &FeatureModel,
    spec: &RunSpec,
) -> Result<RunResult, ExperimentError> {
    let first = spec.first.min(seq.frames().saturating_sub(1));
    let last = (first + spec.frames).min(seq.frames());
    if last <= first {
        return Err(ExperimentError::Config("the run has no frames".into()));
    }
    // The session loop `omcl localize` and `omcl serve` run, fed with the
    // sequence's odometry increments; the initializations keep the
    // benchmark's own random stream.
    let (start, floor_feature) = match &spec.start {
        Start::Local { sigma_m, sigma_deg } => (
            session::Start::Pose {
                pose: seq.poses()[first],
                sigma_m: *sigma_m,
                sigma_rad: sigma_deg.to_radians(),
            },
            None,
        ),
        Start::Global => (session::Start::Global, Some(text(seq, "floor")?)),
        Start::Prompt(words) => (
            session::Start::Prompt {
                words: words
                    .iter()
                    .map(|n| text(seq, n))
                    .collect::<Result<_, _>>()?,
                params: PromptParams::default(),
            },
            Some(text(seq, "floor")?),
        ),
    };
    let config = SessionConfig {
        intrinsics: seq.intrinsics(),
        particles: spec.particles,
        filter: spec.filter,
        floor: FloorParams::default(),
        floor_feature,
        ground: false,
    };
    let horizontal = shared.is_level();
    let rows = class_rows(seq, shared.map());
    let map_rows = shared.map().db().len();
    let mut session = Session::with_init_seed(shared, config, &start, spec.filter.seed ^ 0x57a7)
        .map_err(session_error)?;
    let mut estimates = Vec::with_capacity(last - first);
    let mut errors = Vec::with_capacity(last - first);
    let mut step_seconds = Vec::with_capacity(last - first);
    let mut encoder_seconds = Vec::with_capacity(last - first);
    let mut rays = 0usize;
    for i in first..last {
        let frame = seq.render(i);
        let t = Instant::now();
        let f = GridFeatures::new(
            SimFrameFeatures::new(model, spec.preset, &frame, i as u64, &rows)
                .with_encoder_stride(spec.encoder_stride),
            spec.filter.sampling.stride,
        );
        encoder_seconds.push(t.elapsed().as_secs_f64());
        let inc = if i == first {
            Pose::identity()
        } else {
            seq.increment(i)
        };
        let t = Instant::now();
        let r = session
            .step_by(&inc, i as f64, &f)
            .map_err(session_error)?
            .step;
        step_seconds.push(t.elapsed().as_secs_f64());
        rays += r.n_rays;
        let d = r.estimate.translation.vector - seq.poses()[i].translation.vector;
        errors.push(match horizontal {
            true => d.x.hypot(d.y),
            false => d.norm(),
        });
        estimates.push(r.estimate);
    }
    let stats = ErrorStats::from_errors(&errors)
        .ok_or_else(|| ExperimentError::Config("the run has no frames".into()))?;
    Ok(RunResult {
        completed: CompletionRule::default().judge(&errors),
        mean_rays: rays as f64 / estimates.len() as f64,
        map_rows,
        estimates,
        errors_m: errors,
        stats,
        step_seconds,
        encoder_seconds,
    })
}

/// What [`super::table5::global_runs`] does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalSpec {
    /// Features the localizer sees.
    pub preset: Preset,
    pub filter: FilterConfig,
    pub particles: usize,
    /// Start frames per sequence, spread evenly over it.
    pub starts: usize,
    /// Steps of each run.
    pub max_steps: usize,
    /// Start over the floor voxels matching a prompt (else all floor).
    pub prompt: bool,
    /// In 2-D, on the map's floor plan projected and cast with these
    /// settings ([`super::table5::global_runs`]); `None`: in 3-D.
    pub floor_plan: Option<super::plan_settings::PlanSettings>,
}

/// One global-localization run.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct GlobalRun {
    /// Start frame.
    pub first: usize,
    /// Prompt words (empty without a prompt).
    pub words: Vec<String>,
    /// Steps to reach each threshold (`None`: not within the run).
    pub steps: Vec<Option<usize>>,
    /// Why the run could not start (e.g. no floor voxel matches the prompt).
    pub error: Option<String>,
}

/// One variant's tracking results over the sequences.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TrackingRow {
    pub variant: String,
    pub per_sequence: Vec<RunResult>,
    pub summary: Option<SequenceSummary>,
    /// Sequences completed (judged and completed).
    pub completed: usize,
    /// The completed cell: `k/n`, and the runs too short to judge
    /// ([`CompletionRule::tally`]).
    pub completed_cell: String,
    /// Filter steps per second over all steps of all sequences (encoder
    /// excluded, as in the paper).
    pub fps: f64,
    /// Frames per second with the simulated encoder's work.
    pub fps_with_encoder: f64,
    /// Database rows (K) of the maps, mean over sequences.
    pub map_rows: f64,
}

impl TrackingRow {
    /// Gathers per-sequence results.
    pub fn new(variant: impl Into<String>, per_sequence: Vec<RunResult>) -> Self {
        let stats: Vec<_> = per_sequence.iter().map(|r| r.stats).collect();
        let steps: usize = per_sequence.iter().map(|r| r.step_seconds.len()).sum();
        let secs: f64 = per_sequence
            .iter()
            .flat_map(|r| r.step_seconds.iter())
            .sum();
        let encoder: f64 = per_sequence
            .iter()
            .flat_map(|r| r.encoder_seconds.iter())
            .sum();
        TrackingRow {
            variant: variant.into(),
            summary: summarize_sequences(&stats),
            completed: per_sequence
                .iter()
                .filter(|r| r.completed == Some(true))
                .count(),
            completed_cell: CompletionRule::default()
                .tally(per_sequence.iter().map(|r| r.completed)),
            fps: steps as f64 / secs.max(1e-12),
            fps_with_encoder: steps as f64 / (secs + encoder).max(1e-12),
            map_rows: per_sequence.iter().map(|r| r.map_rows as f64).sum::<f64>()
                / per_sequence.len().max(1) as f64,
            per_sequence,
        }
    }
}
