//! Table I's 2-D block: localization on the floor plan made from each
//! variant's Octree Language Map (features averaged along the vertical,
//! [`crate::map::floorplan`]), with the pose reduced to x, y and yaw.
//!
//! The OMCL rows run the 3-D filter's own pieces on the plan: the plan is
//! a one-layer language map ([`FloorPlan::to_language_map`]) cast by a
//! [`PlanarCaster`] (each sampled pixel's ray projected to the horizontal
//! plane, see [`crate::raycast::PlanarCaster`]); motion
//! ([`MotionMode::Planar`]: noise on x, y and yaw only, height, roll and
//! pitch follow the odometry), pixel sampling, the eq. 2 sensor model,
//! estimate, resampling and the paper's local start are those of the 3-D
//! rows. The error is the horizontal (x, y) distance to the ground truth,
//! the completion rule the 3-D rows' one.

use std::sync::Arc;

use super::ExperimentError;
use super::features::{builtin_table, feature_model};
use super::mapping::BenchMap;
use super::run::{RunResult, TrackingRow};
use super::sequence::SimSequence;
use super::table1::{PaperRow, block_markdown};
use super::variant::{TABLE1_VARIANTS, named_in};
use crate::eval::ErrorStats;
use crate::eval::localization::CompletionRule;
use crate::map::{FloorPlan, FloorPlanParams, LanguageMap};
use crate::mcl::baselines::Baseline;
use crate::mcl::{FilterConfig, FrameFeatures, MotionMode};
use crate::raycast::{PlanarCaster, RayCaster};
use crate::sim::embeddings::ClassEmbeddings;
use crate::sim::features::Preset;
use crate::sim::render::Frame;

/// A variant's floor plan with its one-layer map and planar caster.
pub struct PlanBench {
    pub plan: FloorPlan,
    pub map: LanguageMap,
    pub caster: Arc<PlanarCaster>,
}

impl PlanBench {
    /// Projects a 3-D map to its floor plan.
    pub fn from_map(map: &LanguageMap, params: &FloorPlanParams) -> Result<Self, ExperimentError> {
        let cfg = |e: crate::map::floorplan::FloorPlanError| ExperimentError::Config(e.to_string());
        let plan = FloorPlan::from_map(map, params).map_err(cfg)?;
        Self::from_plan(plan)
    }

    /// A plan with its one-layer map and caster.
    pub fn from_plan(plan: FloorPlan) -> Result<Self, ExperimentError> {
        let map = plan
            .to_language_map()
            .map_err(|e| ExperimentError::Config(e.to_string()))?;
        let caster = Arc::new(PlanarCaster::new(
            map.grid().resolution as f32,
            &map.cells(),
        ));
        Ok(PlanBench { plan, map, caster })
    }

    /// Projects a benchmark map.
    pub fn from_bench(map: &BenchMap, params: &FloorPlanParams) -> Result<Self, ExperimentError> {
        Self::from_map(&map.map, params)
    }
}

/// Replaces a run's errors with horizontal ones (x, y only) and recomputes
/// its statistics and completion.
pub fn planar_errors(result: &mut RunResult, truth: &[crate::geometry::Pose], first: usize) {
    let errors: Vec<f64> = result
        .estimates
        .iter()
        .zip(&truth[first..])
        .map(|(e, t)| {
            let d = e.translation.vector - t.translation.vector;
            d.x.hypot(d.y)
        })
        .collect();
    if let Some(s) = ErrorStats::from_errors(&errors) {
        result.stats = s;
    }
    result.completed = CompletionRule::default().is_completed(&errors);
    result.errors_m = errors;
}

/// A frame's features with the pixels a floor plan cannot explain
/// silenced: a pixel whose feature has cosine `rho` or more with one of the
/// `out_of_band` text features (by default "floor" and "ceiling", which
/// the plan's height band leaves out) reads as zero, which the eq. 2
/// sensor model scores 0 at every pose (no evidence), so it weighs no
/// particle up or down. `rho` is the floor detection's threshold
/// ([`crate::mcl::FloorParams`]).
pub struct InBandFeatures<'a> {
    pub inner: &'a dyn FrameFeatures,
    /// The camera, and the largest elevation (radians, either side of
    /// the camera's horizontal plane) of a pixel ray that is cast; pixels
    /// beyond it read as zero too.
    pub intrinsics: crate::geometry::Intrinsics,
    pub max_elevation: f64,
    /// Unit text features of the words the plan leaves out.
    pub out_of_band: Vec<Vec<f32>>,
    pub rho: f32,
}

impl FrameFeatures for InBandFeatures<'_> {
    fn width(&self) -> u32 {
        self.inner.width()
    }
    fn height(&self) -> u32 {
        self.inner.height()
    }
    fn dim(&self) -> usize {
        self.inner.dim()
    }
    fn feature(&self, u: u32, v: u32, out: &mut [f32]) {
        self.inner.feature(u, v, out);
        let k = &self.intrinsics;
        let elevation = ((v as f64 + 0.5 - k.cy) / k.fy).atan().abs();
        if elevation > self.max_elevation {
            out.fill(0.0);
            return;
        }
        let n = crate::map::features::dot(out, out).sqrt();
        if n > 0.0
            && self
                .out_of_band
                .iter()
                .any(|w| crate::map::features::dot(out, w) >= self.rho * n)
        {
            out.fill(0.0);
        }
    }
}

/// Which pixels OMCL's 2-D mode casts.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TwoDParams {
    /// Largest elevation of a cast pixel's ray above or below the camera's
    /// horizontal plane, degrees (the camera is level in planar mode).
    pub max_elevation_deg: f64,
}

impl Default for TwoDParams {
    fn default() -> Self {
        TwoDParams {
            max_elevation_deg: 90.0,
        }
    }
}

/// Words whose pixels OMCL's 2-D mode does not cast (see [`InBandFeatures`]).
pub const OUT_OF_BAND_WORDS: [&str; 2] = ["floor", "ceiling"];

/// Tracks `seq` on the floor plan `plan` with OMCL (the paper's local
/// start, planar motion forced), features of `preset`, the pixels
/// [`TwoDParams`] and [`OUT_OF_BAND_WORDS`] exclude silenced
/// ([`InBandFeatures`]). Returns the run and its total cast time, seconds.
pub fn track_2d(
    seq: &SimSequence,
    plan: &PlanBench,
    preset: Preset,
    filter: FilterConfig,
    particles: usize,
    two_d: &TwoDParams,
) -> Result<(RunResult, f64), ExperimentError> {
    let caster: Arc<dyn RayCaster> = plan.caster.clone();
    let (mut r, cast) = track_with(
        seq,
        &plan.map,
        caster,
        preset,
        filter,
        particles,
        Some(two_d),
    )?;
    planar_errors(&mut r, seq.poses(), 0);
    Ok((r, cast))
}

/// The session loop of [`super::run::run`] from the paper's local start with
/// planar motion, on any map and caster, optionally with the 2-D mode's
/// pixel selection; returns the run and its total cast time, seconds (for
/// comparing 2-D and 3-D casting on the same sequence).
pub fn track_with(
    seq: &SimSequence,
    map: &LanguageMap,
    caster: Arc<dyn RayCaster>,
    preset: Preset,
    filter: FilterConfig,
    particles: usize,
    two_d: Option<&TwoDParams>,
) -> Result<(RunResult, f64), ExperimentError> {
    use crate::session::{self, Session, SessionConfig, SharedMap};
    use std::time::Instant;
    let model = feature_model(seq, preset, 0x10c);
    let mut filter = filter;
    filter.motion.mode = MotionMode::Planar;
    // The session loop, as every run steps it, on this map and caster.
    let start = session::Start::Pose {
        pose: seq.poses()[0],
        sigma_m: 0.3,
        sigma_rad: 17f64.to_radians(),
    };
    let config = SessionConfig {
        intrinsics: seq.intrinsics,
        particles,
        filter,
        floor: crate::mcl::FloorParams::default(),
        floor_feature: None,
    };
    let shared = Arc::new(SharedMap::from_parts("floor plan", map.clone(), caster));
    let mut f = Session::with_init_seed(shared, config, &start, filter.seed ^ 0x57a7)
        .map_err(super::run::session_error)?;
    let out_of_band: Vec<Vec<f32>> = match two_d {
        Some(_) => OUT_OF_BAND_WORDS
            .iter()
            .filter_map(|w| seq.table.text_feature(w).map(<[f32]>::to_vec))
            .collect(),
        None => Vec::new(),
    };
    let max_elevation = two_d.map_or(std::f64::consts::PI, |t| t.max_elevation_deg.to_radians());
    let rho = crate::mcl::FloorParams::default().rho;
    let rows = super::run::class_rows(seq, map);
    let (mut estimates, mut step_seconds, mut encoder_seconds) = (vec![], vec![], vec![]);
    let (mut rays, mut cast) = (0usize, 0.0f64);
    let mut errors = Vec::new();
    for i in 0..seq.len() {
        let frame = seq.render(i);
        let t = Instant::now();
        let g = super::features::GridFeatures::new(
            super::features::SimFrameFeatures::new(&model, preset, &frame, i as u64, &rows),
            filter.sampling.stride,
        );
        encoder_seconds.push(t.elapsed().as_secs_f64());
        let inband = InBandFeatures {
            inner: &g,
            intrinsics: seq.intrinsics,
            max_elevation,
            out_of_band: out_of_band.clone(),
            rho,
        };
        let t = Instant::now();
        let r = f
            .step_by(&seq.increment(i), i as f64, &inband)
            .map_err(super::run::session_error)?
            .step;
        step_seconds.push(t.elapsed().as_secs_f64());
        cast += r.timings.cast.as_secs_f64();
        rays += r.n_rays;
        errors.push((r.estimate.translation.vector - seq.poses()[i].translation.vector).norm());
        estimates.push(r.estimate);
    }
    let n = estimates.len().max(1);
    let stats = ErrorStats::from_errors(&errors)
        .ok_or_else(|| ExperimentError::Config("the run has no frames".into()))?;
    Ok((
        RunResult {
            completed: CompletionRule::default().is_completed(&errors),
            errors_m: errors,
            stats,
            step_seconds,
            encoder_seconds,
            mean_rays: rays as f64 / n as f64,
            map_rows: map.db().len(),
            estimates,
        },
        cast,
    ))
}

/// What the 2-D block runs.
#[derive(Debug, Clone)]
pub struct BlockSpec {
    pub seeds: std::ops::Range<u64>,
    pub frames: usize,
    pub map_params: super::mapping::MapParams,
    /// The filter (its seed is replaced by each sequence's seed, as the
    /// 3-D rows do).
    pub filter: FilterConfig,
    pub particles: usize,
    pub plan: FloorPlanParams,
    pub two_d: TwoDParams,
    /// Also track the first sequence's first variant in 3-D to compare
    /// step and cast times.
    pub compare_3d: bool,
}

/// Runs the OMCL rows of the 2-D block: per sequence, each variant's 3-D
/// map is built, projected to its floor plan and tracked on. `progress` is
/// told what finished. Returns one row per variant, in `variants`' order.
pub fn omcl_rows(
    spec: &BlockSpec,
    variants: &[super::variant::Variant],
    baselines: &[crate::mcl::baselines::Baseline],
    progress: &dyn Fn(&str),
) -> Result<Vec<super::run::TrackingRow>, ExperimentError> {
    let table = builtin_table()?;
    let mut runs: Vec<Vec<RunResult>> = vec![Vec::new(); variants.len()];
    let mut base_runs: Vec<Vec<RunResult>> = vec![Vec::new(); baselines.len()];
    for seed in spec.seeds.clone() {
        let seq = SimSequence::generate(seed, spec.frames, &table)?;
        if !baselines.is_empty() {
            // The baselines localize on the OMCL_GT map's plan with
            // ground-truth images (the paper's SeDAR*_GT and SIMP*_GT).
            let map = BenchMap::build(
                &seq,
                super::mapping::MapSource::Features(Preset::Gt),
                &spec.map_params,
                &|_| {},
            )?;
            let plan = PlanBench::from_bench(&map, &spec.plan)?;
            for (k, &b) in baselines.iter().enumerate() {
                let filter = FilterConfig {
                    seed,
                    ..spec.filter
                };
                let r = track_baseline(
                    &seq,
                    &plan,
                    b,
                    &Default::default(),
                    Preset::Gt,
                    filter,
                    spec.particles,
                )?;
                progress(&format!(
                    "seed {seed} {}: 2-D RMSE {:.3} m, {:.1} steps/s",
                    b.name(),
                    r.stats.rmse,
                    r.fps()
                ));
                base_runs[k].push(r);
            }
        }
        for (k, v) in variants.iter().enumerate() {
            let map = BenchMap::build(&seq, v.map, &spec.map_params, &|_| {})?;
            let plan = PlanBench::from_bench(&map, &spec.plan)?;
            let filter = FilterConfig {
                seed,
                ..spec.filter
            };
            let (r, cast) = track_2d(&seq, &plan, v.localize, filter, spec.particles, &spec.two_d)?;
            progress(&format!(
                "seed {seed} {}: 2-D RMSE {:.3} m, {} columns, K {}, {:.1} steps/s, cast {:.1} ms a step",
                v.name,
                r.stats.rmse,
                plan.plan.len(),
                plan.plan.db().len(),
                r.fps(),
                1e3 * cast / r.step_seconds.len().max(1) as f64
            ));
            if spec.compare_3d && k == 0 && seed == spec.seeds.start {
                let (r3, cast3) = track_with(
                    &seq,
                    &map.map,
                    map.caster.clone(),
                    v.localize,
                    filter,
                    spec.particles,
                    None,
                )?;
                progress(&format!(
                    "speed, seed {seed} {}, {} particles: 3-D {:.1} steps/s, cast {:.1} ms a step; 2-D {:.1} steps/s, cast {:.1} ms a step ({:.1}x faster step, {:.1}x faster cast)",
                    v.name,
                    spec.particles,
                    r3.fps(),
                    1e3 * cast3 / r3.step_seconds.len().max(1) as f64,
                    r.fps(),
                    1e3 * cast / r.step_seconds.len().max(1) as f64,
                    r.fps() / r3.fps(),
                    cast3 / cast.max(1e-12)
                ));
            }
            runs[k].push(r);
        }
    }
    Ok(variants
        .iter()
        .map(|v| v.name)
        .zip(runs)
        .chain(baselines.iter().map(|b| b.name()).zip(base_runs))
        .map(|(name, r)| super::run::TrackingRow::new(name, r))
        .collect())
}

/// The class table as a feature database (a row a class): the baselines
/// label each pixel with its nearest class.
fn class_db(table: &ClassEmbeddings) -> Result<crate::map::FeatureDb, ExperimentError> {
    let dim = table.row(0).len();
    Ok(crate::map::FeatureDb::from_rows(
        dim,
        0.0,
        (0..table.len())
            .flat_map(|c| table.row(c).to_vec())
            .collect(),
    )?)
}

/// The baselines' observations of the sampled pixels: each pixel's
/// direction, nearest class and (simulated sensor) depth.
fn observe(
    f: &dyn FrameFeatures,
    frame: &Frame,
    pixels: &[(u32, u32)],
    classes: &crate::map::FeatureDb,
    k: &crate::geometry::Intrinsics,
) -> Result<Vec<crate::mcl::baselines::PixelObservation>, ExperimentError> {
    use crate::mcl::baselines::{NO_LABEL, observations};
    let mut buf = vec![0.0f32; classes.dim()];
    let mut labels = Vec::with_capacity(pixels.len());
    let mut depths = Vec::with_capacity(pixels.len());
    for &(u, v) in pixels {
        f.feature(u, v, &mut buf);
        labels.push(classes.nearest(&buf)?.map_or(NO_LABEL, |(c, _)| c as u16));
        depths.push(frame.depth[(v * frame.width + u) as usize]);
    }
    Ok(observations(k, pixels, &labels, &depths))
}

/// Tracks `seq` on `plan` with a baseline sensor model
/// ([`crate::mcl::baselines`]): the same local start, planar motion
/// model, pixel sampling (on the plan's database), estimate and
/// resampling policy as OMCL's 2-D rows, the pixels' labels the classes
/// nearest to their `preset` features.
pub fn track_baseline(
    seq: &SimSequence,
    plan: &PlanBench,
    baseline: crate::mcl::baselines::Baseline,
    params: &crate::mcl::baselines::BaselineParams,
    preset: Preset,
    filter: FilterConfig,
    particles: usize,
) -> Result<RunResult, ExperimentError> {
    use crate::mcl::baselines::{self, LabelledPlan};
    use crate::mcl::{estimate, local_init, motion::MotionModel, resample, sampling};
    use rand::SeedableRng;
    use rayon::prelude::*;
    use std::time::Instant;

    let model = feature_model(seq, preset, 0x10c);
    let classes = class_db(&seq.table)?;
    let cells = plan.map.cells();
    let labelled = LabelledPlan::new(
        &plan.plan,
        &cells,
        plan.map.rows(),
        &classes,
        params.max_distance,
    );
    let origin = plan.map.grid().origin;
    let motion = MotionModel {
        mode: MotionMode::Planar,
        ..filter.motion
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(filter.seed ^ 0x57a7);
    let start = super::run::Start::paper_local();
    let super::run::Start::Local { sigma_m, sigma_deg } = start else {
        unreachable!("the paper's start is local")
    };
    let mut ps = local_init(
        &seq.poses()[0],
        particles,
        sigma_m,
        sigma_deg.to_radians(),
        &mut rng,
    );
    let rows = super::run::class_rows(seq, &plan.map);
    let (mut estimates, mut step_seconds, mut encoder_seconds) = (vec![], vec![], vec![]);
    let mut rays = 0usize;
    for i in 0..seq.len() {
        let frame = seq.render(i);
        let t = Instant::now();
        let f = super::features::GridFeatures::new(
            super::features::SimFrameFeatures::new(&model, preset, &frame, i as u64, &rows),
            filter.sampling.stride,
        );
        encoder_seconds.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        if i > 0 {
            motion.predict(&mut ps, &seq.increment(i), &mut rng)?;
        }
        let pixels = sampling::sample_pixels(&f, plan.map.db(), &filter.sampling, &mut rng)?;
        let obs = observe(&f, &frame, &pixels, &classes, &seq.intrinsics)?;
        let log_l: Vec<f64> = ps
            .par_iter()
            .map(|p| {
                baselines::log_likelihood(
                    baseline,
                    &p.pose,
                    &obs,
                    &labelled,
                    &plan.caster,
                    &origin,
                    params,
                )
            })
            .collect();
        baselines::weigh(&mut ps, &log_l);
        let est = estimate(&ps, &filter.estimate).ok_or(crate::mcl::MclError::NoParticles)?;
        if filter.resample.due(&ps) {
            let n = ps.len();
            resample::resample(&mut ps, n, filter.resample.reset_weights, &mut rng);
        }
        step_seconds.push(t.elapsed().as_secs_f64());
        rays += pixels.len();
        estimates.push(est.pose);
    }
    let n = estimates.len().max(1);
    let mut r = RunResult {
        errors_m: Vec::new(),
        stats: ErrorStats::from_errors(&[0.0]).expect("one error"),
        completed: false,
        step_seconds,
        encoder_seconds,
        mean_rays: rays as f64 / n as f64,
        map_rows: plan.map.db().len(),
        estimates,
    };
    planar_errors(&mut r, seq.poses(), 0);
    Ok(r)
}

/// The paper's 2-D rows of Table I.
pub const PAPER_2D: [PaperRow; 6] = [
    PaperRow {
        variant: "OMCL_GT",
        ape: [0.11, 0.07, 0.09, 0.08, 0.08, 0.18, 17.38],
        completed: "10/10",
    },
    PaperRow {
        variant: "OMCL_LSeg",
        ape: [0.15, 0.09, 0.13, 0.12, 0.11, 0.28, 33.07],
        completed: "10/10",
    },
    PaperRow {
        variant: "OMCL_auto_LSeg",
        ape: [0.24, 0.15, 0.18, 0.15, 0.14, 0.52, 95.0],
        completed: "10/10",
    },
    PaperRow {
        variant: "OMCL_Open_LSeg",
        ape: [0.36, 0.24, 0.27, 0.22, 0.15, 0.62, 164.07],
        completed: "8/10",
    },
    PaperRow {
        variant: "SeDAR*_GT",
        ape: [0.79, 0.46, 0.64, 0.54, 0.24, 2.33, 1891.2],
        completed: "6/10",
    },
    PaperRow {
        variant: "SIMP*_GT",
        ape: [1.39, 1.03, 0.79, 0.94, 0.45, 2.81, 2898.15],
        completed: "4/10",
    },
];

/// Table I's 2-D block: the OMCL variants (OMCL_GT_exact aside) and the
/// baselines whose names are in `names` (comma-separated; `None`: all),
/// and the block as Markdown beside the paper's rows.
pub fn block(
    spec: &BlockSpec,
    names: Option<&str>,
    progress: &dyn Fn(&str),
) -> Result<(Vec<TrackingRow>, String), ExperimentError> {
    let variants: Vec<_> = TABLE1_VARIANTS
        .iter()
        .filter(|v| v.name != "OMCL_GT_exact" && named_in(names, v.name))
        .copied()
        .collect();
    let baselines: Vec<Baseline> = [Baseline::Sedar, Baseline::Simp]
        .into_iter()
        .filter(|b| named_in(names, b.name()))
        .collect();
    let rows = omcl_rows(spec, &variants, &baselines, progress)?;
    let md = block_markdown(
        "Table I, 2-D block: APE (m, horizontal) on floor plans",
        &rows,
        &PAPER_2D,
    );
    Ok((rows, md))
}
