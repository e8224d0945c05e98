//! The localization loop: predict, sample pixels, weigh, estimate,
//! resample. Each stage is one of the sibling modules; this file only
//! strings them together.

use std::sync::Arc;
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::anneal::Anneal;
use super::estimate::{EstimateParams, estimate};
use super::init::FloorSampler;
use super::kld::{KldParams, particle_count};
use super::motion::{MotionModel, check_pose};
use super::particles::{Particle, ess, normalize, sort_spatially};
use super::recovery::{Recovery, RecoveryParams};
use super::resample::{ResamplePolicy, resample};
use super::sampling::{SamplingParams, sample_in_strata};
use super::sensor::{RayOrder, SensorModel, SensorParams, SimilarityTable};
use super::{MAX_COUNT, MclError};
use crate::frame::FrameFeatures;
use crate::geometry::{Intrinsics, Pose};
use crate::map::{FeatureDb, LanguageMap};
use crate::raycast::RayCaster;

/// Everything the filter needs besides the map and the camera.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FilterConfig {
    pub motion: MotionModel,
    pub sampling: SamplingParams,
    pub sensor: SensorParams,
    /// Exponent applied to `max(L_i, 0)` before it multiplies the weight
    /// (1: the paper's eq. 2; larger values trust each frame more). Mean
    /// cosines of nearby poses differ by a few hundredths, so without
    /// sharpening weights barely separate them: on the rooms convergence
    /// test (256 particles x 256 rays, feature noise 0.5) the RMSE after
    /// frame 10, mean of 4 seeds, was 0.25 m at 1, 0.15 at 10, 0.10 at 40,
    /// 0.087 at 80 and 0.10 at 160; default 80.
    pub sharpen: f64,
    pub resample: ResamplePolicy,
    pub estimate: EstimateParams,
    /// Adaptive particle count at resampling (`None`: constant count).
    pub kld: Option<KldParams>,
    /// Augmented-MCL injection (needs [`Filter::with_injection`]).
    pub recovery: Option<RecoveryParams>,
    /// Progressive correction: the frame's likelihood over several layers
    /// with resampling and jitter between them (`None`: one layer, the
    /// paper's filter). The 6-DoF block uses [`Anneal::default`].
    #[serde(default)]
    pub anneal: Option<Anneal>,
    /// Seed of every random draw of the filter.
    pub seed: u64,
}

impl Default for FilterConfig {
    fn default() -> Self {
        FilterConfig {
            motion: MotionModel::default(),
            sampling: SamplingParams::default(),
            sensor: SensorParams::default(),
            sharpen: 80.0,
            resample: ResamplePolicy::default(),
            estimate: EstimateParams::default(),
            kld: None,
            recovery: None,
            anneal: None,
            seed: 0,
        }
    }
}

/// Particles of the indoor filter (the paper's setting, with
/// [`FilterConfig::default`]'s 2048 rays): `omcl localize`, `omcl serve`'s
/// sessions and the indoor benchmarks default to it.
pub const INDOOR_PARTICLES: usize = 1024;

/// Particles of the filter on streets (the paper's outdoor setting, with
/// [`FilterConfig::street`]'s 4096 rays): `omcl localize` on a KITTI
/// folder and `omcl bench table4` default to it.
pub const STREET_PARTICLES: usize = 512;

/// Sampled pixels a frame of the floor-plan filter
/// ([`FilterConfig::floor_plan`]), chosen on the 2-D block's tuning
/// sequences (docs/table1.md, "More pixels, sharper: the 2-D block's filter").
pub const FLOOR_PLAN_RAYS: usize = 8192;

/// Exponent of the floor-plan filter's likelihood (the indoor default's
/// 80 with 2048 pixels), chosen with [`FLOOR_PLAN_RAYS`]: 160 until
/// 2026-11-27; 240 since columns end below the ceiling, when the 2-D
/// sensor's likelihood at the true pose rose (tuning seeds 0-19, OMCL_GT
/// 0.109 -> 0.104 m; docs/table1.md, "Columns that end below the ceiling").
pub const FLOOR_PLAN_SHARPEN: f64 = 240.0;

/// Radius (metres) of the floor-plan filter's estimate (the weighted mean
/// of the particles this near the most likely one; the indoor default
/// 0.3 m). The estimate changes no particle, so each sequence's path is
/// the same with either: on the 2-D block's tuning seeds 0-39 (OMCL_GT,
/// before the plan's strata) 0.5 m gave 0.103 instead of 0.104 m on 0-19
/// (better on 11) and 0.113 instead of 0.115 on 20-39 (12); 0.15 m 0.111
/// on 0-19 (docs/table1.md, "Strata over the plan's own rows").
pub const FLOOR_PLAN_ESTIMATE_RADIUS: f64 = 0.5;

/// Sampled pixels a frame of the full-pose filter
/// ([`FilterConfig::six_dof`]), chosen with [`SIX_DOF_SHARPEN`] on the
/// 6-DoF block's tuning sequences (docs/table1.md, "More pixels, sharper: the
/// 6-DoF block's filter").
pub const SIX_DOF_RAYS: usize = 4096;

/// Exponent of the full-pose filter's likelihood (spread over its two
/// layers), chosen with [`SIX_DOF_RAYS`].
pub const SIX_DOF_SHARPEN: f64 = 240.0;

/// Sampled pixels a frame of the full-pose filter on a point-cloud map
/// ([`FilterConfig::six_dof_point_cloud`]), chosen with
/// [`SIX_DOF_POINT_CLOUD_SHARPEN`] on the point-cloud row's tuning
/// sequences (docs/table1.md, "The point-cloud row's own filter").
pub const SIX_DOF_POINT_CLOUD_RAYS: usize = 512;

/// Exponent of the full-pose filter's likelihood on a point-cloud map,
/// chosen with [`SIX_DOF_POINT_CLOUD_RAYS`].
pub const SIX_DOF_POINT_CLOUD_SHARPEN: f64 = 20.0;

/// Particles of the full-pose filter (with [`FilterConfig::six_dof`]'s
/// rays and a first layer on 16 copies of each particle):
/// `omcl bench table1-sixdof` defaults to it. The paper's 1024 x 2048;
/// chosen on the 6-DoF block's tuning sequences 0-5 against 4096 x 512
/// with four copies (the block's filter before 2026-11-26): OMCL_GT 0.152
/// against 0.158 m, OMCL_LSeg (0-2) 0.152 against 0.169 m, about 6.4
/// against 5.1 steps/s (docs/table1.md, "6-DoF (3-D block)").
pub const SIX_DOF_PARTICLES: usize = 1024;

impl FilterConfig {
    /// Checks the parameters (motion, early rejection, sharpening, layers,
    /// miss score, boundary margin); [`Filter::new`] does too, and a
    /// caller about to do long work first (building maps) can call it
    /// before.
    pub fn validate(&self) -> Result<(), MclError> {
        self.motion.validate()?;
        if let Some(e) = &self.sensor.early_reject {
            e.validate()?;
        }
        if !(self.sharpen.is_finite() && self.sharpen >= 0.0) {
            return Err(MclError::BadParam {
                name: "sharpen",
                why: format!("must be finite and >= 0, got {}", self.sharpen),
            });
        }
        if let Some(a) = &self.anneal {
            a.validate().map_err(|why| MclError::BadParam {
                name: "anneal",
                why,
            })?;
        }
        let width = self.sampling.boundary_margin_width;
        if !(width.is_finite() && width >= 0.0) {
            return Err(MclError::BadParam {
                name: "sampling.boundary_margin_width",
                why: format!("must be finite and >= 0, got {width}"),
            });
        }
        self.validate_ranges()
    }

    /// The rest of [`FilterConfig::validate`]: every count and number
    /// within the bounds the command lines give them (a configuration also
    /// comes as JSON, from `--set` and sweep manifests, where
    /// `sampling.rays=100000000000` asked for 800 GB and aborted).
    fn validate_ranges(&self) -> Result<(), MclError> {
        let check = |ok: bool, name: &'static str, why: String| {
            if ok {
                Ok(())
            } else {
                Err(MclError::BadParam { name, why })
            }
        };
        let rays = self.sampling.rays;
        check(
            (1..=MAX_COUNT).contains(&rays),
            "sampling.rays",
            format!("must be 1 to {MAX_COUNT}, got {rays}"),
        )?;
        let stride = self.sampling.stride;
        check(
            (1..=1024).contains(&stride),
            "sampling.stride",
            format!("must be 1 to 1024 pixels, got {stride}"),
        )?;
        let miss = self.sensor.miss_score;
        check(
            (0.0..=1.0).contains(&miss),
            "sensor.miss_score",
            format!("must be in [0, 1], got {miss}"),
        )?;
        let range = self.sensor.max_range;
        check(
            range > 0.0,
            "sensor.max_range",
            format!("must be above 0 metres (null: unlimited), got {range}"),
        )?;
        let ess = self.resample.ess_fraction;
        check(
            ess.is_finite() && ess >= 0.0,
            "resample.ess_fraction",
            format!("must be finite and at least 0 (1 or more: every step), got {ess}"),
        )?;
        let radius = self.estimate.radius;
        check(
            radius > 0.0,
            "estimate.radius",
            format!("must be above 0 metres (inf: all particles), got {radius}"),
        )?;
        if let Some(k) = &self.kld {
            k.validate()?;
        }
        if let Some(r) = &self.recovery {
            r.validate()?;
        }
        Ok(())
    }

    /// The filter for the full camera pose (Table I's 3-D block, with
    /// [`SIX_DOF_PARTICLES`]): noise on all six degrees of freedom
    /// ([`super::MotionMode::Full`]), two layers of progressive correction
    /// ([`Anneal::default`]), the first on 16 copies of each particle and
    /// every 16th pixel ([`Anneal::expand`]), [`SIX_DOF_RAYS`] sampled
    /// pixels and the exponent [`SIX_DOF_SHARPEN`] (the paper's 2048 and
    /// the indoor 80 before 2026-11-26). The six-dimensional particle cloud
    /// is what limits the estimate: the layers and the copies put particles
    /// where the likelihood is high, and the second layer weighs them with
    /// every ray (docs/table1.md, "6-DoF (3-D block)"); twice the pixels give a steadier mean
    /// cosine, which the sharper exponent uses.
    pub fn six_dof() -> Self {
        let mut config = FilterConfig::default();
        config.motion.mode = super::motion::MotionMode::Full;
        config.anneal = Some(Anneal {
            expand: 16,
            ..Anneal::default()
        });
        config.sampling.rays = SIX_DOF_RAYS;
        config.sharpen = SIX_DOF_SHARPEN;
        config
    }

    /// The full-pose filter on a map whose features come from a point
    /// encoder rather than the camera's image encoder (a labelled point
    /// cloud, Table I's OMCL_Open_LSeg row): [`FilterConfig::six_dof`]
    /// with [`SIX_DOF_POINT_CLOUD_RAYS`] pixels and the softer exponent
    /// [`SIX_DOF_POINT_CLOUD_SHARPEN`]. The two encoders agree less, so a
    /// particle's mean cosine is a weaker cue and more of its modes must
    /// stay alive; chosen on the row's tuning sequences, where the sharp
    /// filter of the frame-built maps completed 3 of 10 (docs/table1.md, "The
    /// point-cloud row's own filter").
    pub fn six_dof_point_cloud() -> Self {
        let mut config = FilterConfig::six_dof();
        config.sampling.rays = SIX_DOF_POINT_CLOUD_RAYS;
        config.sharpen = SIX_DOF_POINT_CLOUD_SHARPEN;
        config
    }

    /// The filter of Table I's 2-D block (OMCL on a floor plan, with
    /// [`INDOOR_PARTICLES`]): [`FLOOR_PLAN_RAYS`] sampled pixels and the
    /// exponent [`FLOOR_PLAN_SHARPEN`], planar motion. A planar cast walks
    /// each image column once a particle and reads every pixel of the
    /// column off that walk, so more pixels cost little there (8192
    /// instead of 2048: the cast 1.5 times dearer, where the 3-D one is 3
    /// times), and their mean cosine is steadier, which a sharper exponent
    /// then uses (docs/table1.md, "More pixels, sharper: the 2-D block's filter");
    /// the estimate's radius [`FLOOR_PLAN_ESTIMATE_RADIUS`].
    pub fn floor_plan() -> Self {
        let mut config = FilterConfig::default();
        config.sampling.rays = FLOOR_PLAN_RAYS;
        config.sharpen = FLOOR_PLAN_SHARPEN;
        config.estimate.radius = FLOOR_PLAN_ESTIMATE_RADIUS;
        config
    }

    /// [`FilterConfig::floor_plan`] for a plan whose rows are raw image
    /// features rather than classes (an ungrounded map, Table I's
    /// OMCL_auto_LSeg row): pixels drawn uniformly over the image
    /// ([`SamplingStrategy::Uniform`](super::SamplingStrategy::Uniform))
    /// instead of stratified over the rows. Noisy raw features rarely come
    /// within tau of each other, so such a plan has hundreds of rows, most
    /// of them near-duplicates or blends; stratified over them, every
    /// small cluster of odd pixels (edges, blends) draws as many pixels as
    /// the walls do. On tuning sequences 0-2 the row went from 1.77 m (1 of
    /// 3 completed) to 0.331 m (2 of 3) (docs/table1.md, "The raw-feature row's
    /// own sampling").
    pub fn floor_plan_raw_features() -> Self {
        let mut config = FilterConfig::floor_plan();
        config.sampling.strategy = super::SamplingStrategy::Uniform;
        config
    }

    /// [`FilterConfig::floor_plan`] for a plan projected from a map made
    /// from a labelled point cloud, localized with frames from an image
    /// encoder (Table I's OMCL_Open_LSeg row): pixels stratified over every
    /// row of the sighted plan, not only over the plan's own rows and the
    /// words ([`super::SamplingParams::map_strata`] off). On tuning
    /// sequences 0-19 the row's strata over the plan's own rows lost two
    /// runs (0.213 m, 18 of 20 completed); over every row it kept all
    /// twenty (0.173 m; 0.176 with the estimate's radius of 0.3 m before).
    /// Per sequence the strata were better on 11 of 20, by up to 4.5 cm,
    /// and lost 2 (README, "Where Table I stands").
    pub fn floor_plan_point_cloud() -> Self {
        let mut config = FilterConfig::floor_plan();
        config.sampling.map_strata = false;
        config
    }

    /// The filter for a car's camera on streets (KITTI camera 2, the
    /// paper's outdoor setting, with [`STREET_PARTICLES`]): 4096 rays, road motion (planar noise plus
    /// a little height, pitch and roll: the road climbs and pitches),
    /// no boundary margin ([`super::sampling::STREET_BOUNDARY_MARGIN`]),
    /// two-pass likelihoods with the street split
    /// ([`super::sensor::EarlyReject::STREET`]) and misses scored
    /// [`super::sensor::STREET_MISS_SCORE`]. `omcl localize` on a KITTI
    /// folder and `omcl bench table4` start from it.
    pub fn street() -> Self {
        let mut config = FilterConfig::default();
        config.sampling.rays = 4096;
        config.sampling.boundary_margin = Some(super::sampling::STREET_BOUNDARY_MARGIN);
        config.motion.mode = super::motion::MotionMode::Road;
        config.sensor.early_reject = Some(super::sensor::EarlyReject::STREET);
        config.sensor.miss_score = super::sensor::STREET_MISS_SCORE;
        config
    }
}

/// Wall-clock time of each stage of a step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepTimings {
    pub predict: Duration,
    /// Pixel sampling and the similarity table.
    pub features: Duration,
    /// Ray generation, casting and scoring.
    pub weigh: Duration,
    /// The ray cast alone (part of `weigh`).
    pub cast: Duration,
    /// Estimate, resampling, injection.
    pub update: Duration,
}

impl std::ops::AddAssign for StepTimings {
    fn add_assign(&mut self, o: Self) {
        self.predict += o.predict;
        self.features += o.features;
        self.weigh += o.weigh;
        self.cast += o.cast;
        self.update += o.update;
    }
}

impl StepTimings {
    /// `features / predict / weigh (cast) / update` in milliseconds, each
    /// divided by `steps` (the mean step of a sum of `steps` steps).
    pub fn per_step_ms(&self, steps: usize) -> String {
        let ms = |d: Duration| 1e3 * d.as_secs_f64() / steps.max(1) as f64;
        format!(
            "features {:.1} / predict {:.1} / weigh {:.1} (cast {:.1}) / update {:.1} ms",
            ms(self.features),
            ms(self.predict),
            ms(self.weigh),
            ms(self.cast),
            ms(self.update)
        )
    }
}

/// The outcome of one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    /// Estimated `world_from_camera`.
    pub estimate: Pose,
    /// Effective sample size after weighing, before resampling.
    pub ess: f64,
    /// Weighted RMS distance of the particles from the estimate, metres: a
    /// large spread or a small ESS means the filter is not sure (lost).
    pub spread: f64,
    /// Mean likelihood `L` over the particles (the frame's agreement with
    /// the map; a sudden drop suggests track loss).
    pub mean_likelihood: f64,
    /// Confidence in `[0, 1]`: the short-term over the long-term average of
    /// the mean likelihood (augmented MCL's `w_fast / w_slow`, capped at 1).
    /// Near 1 while the frames agree with the map as well as they have;
    /// it falls when they suddenly agree less (track loss, a kidnapped
    /// camera) and returns once the filter has found the camera again.
    pub confidence: f64,
    /// Particles after this step.
    pub n_particles: usize,
    /// Rays cast per particle (distinct sampled pixels).
    pub n_rays: usize,
    /// Whether the set was resampled.
    pub resampled: bool,
    /// Particles replaced by injection.
    pub injected: usize,
    pub timings: StepTimings,
}

/// A frame must have the camera `k`'s size.
pub(crate) fn check_frame_size(k: &Intrinsics, frame: &dyn FrameFeatures) -> Result<(), MclError> {
    if (frame.width(), frame.height()) != (k.width, k.height) {
        return Err(MclError::ImageSize {
            got_w: frame.width(),
            got_h: frame.height(),
            want_w: k.width,
            want_h: k.height,
        });
    }
    Ok(())
}

/// The particle filter.
pub struct Filter {
    config: FilterConfig,
    db: FeatureDb,
    sensor: SensorModel,
    particles: Vec<Particle>,
    rng: ChaCha8Rng,
    sort_cell: f64,
    recovery: Recovery,
    injection: Option<FloorSampler>,
    /// Whether the last step's own cast (not the scoring of injection
    /// candidates) went pixel-major.
    pixel_major: bool,
    /// The particles before this step's motion, for undoing the step on a
    /// casting error (kept across steps so it is not allocated each time).
    undo: Vec<Particle>,
    /// The rows pixels are stratified over ([`Filter::with_strata`]);
    /// `None`: all.
    strata: Option<Vec<bool>>,
}

impl Filter {
    /// A filter on `map`, whose leaves `caster` was built from (same order),
    /// starting from `particles` (see [`super::init`]).
    pub fn new(
        map: &LanguageMap,
        caster: Arc<dyn RayCaster>,
        intrinsics: Intrinsics,
        config: FilterConfig,
        particles: Vec<Particle>,
    ) -> Result<Self, MclError> {
        config.validate()?;
        if map.db().is_empty() {
            return Err(MclError::EmptyDb);
        }
        if caster.len() != map.rows().len() {
            // A caster of another map would return voxel indices into the
            // wrong rows: every likelihood garbage, and no error.
            return Err(MclError::CasterMismatch {
                caster: caster.len(),
                map: map.rows().len(),
            });
        }
        if particles.is_empty() {
            return Err(MclError::NoParticles);
        }
        let sensor = SensorModel::new(
            caster,
            map.rows().into(),
            map.grid().origin,
            intrinsics,
            config.sensor,
        );
        let mut f = Filter {
            config,
            db: map.db().clone(),
            sensor,
            particles,
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            sort_cell: map.grid().resolution.max(0.05),
            recovery: Recovery::default(),
            injection: None,
            pixel_major: false,
            undo: Vec::new(),
            strata: None,
        };
        normalize(&mut f.particles);
        Ok(f)
    }

    /// Enables injection of particles drawn by `sampler` when the
    /// likelihood drops (needs `config.recovery`).
    pub fn with_injection(mut self, sampler: FloorSampler) -> Self {
        self.set_injection(sampler);
        self
    }

    /// Replaces the injection sampler (e.g. after a new start).
    pub fn set_injection(&mut self, sampler: FloorSampler) {
        self.injection = Some(sampler);
    }

    /// Stratifies the sampled pixels over the database rows `strata` marks
    /// only ([`super::sampling::sample_in_strata`]; a floor plan's 2-D map
    /// marks its own rows and the floor and ceiling words), unless the
    /// filter's [`super::SamplingParams::map_strata`] is off. Every row is
    /// still scored.
    pub fn with_strata(mut self, strata: Option<Vec<bool>>) -> Self {
        self.strata = strata;
        self
    }

    /// Sets the order in which the sensor model casts rays (speed only;
    /// the default [`RayOrder::Auto`] picks per step).
    pub fn with_ray_order(mut self, order: RayOrder) -> Self {
        self.sensor = self.sensor.with_ray_order(order);
        self
    }

    /// Whether the last step cast its rays pixel-major (see [`RayOrder`]).
    pub fn last_pixel_major(&self) -> bool {
        self.pixel_major
    }

    /// The particles (normalized weights).
    pub fn particles(&self) -> &[Particle] {
        &self.particles
    }

    /// The configuration.
    pub fn config(&self) -> &FilterConfig {
        &self.config
    }

    /// Replaces the particle set, e.g. after a new prompt (re-initialization
    /// after track loss). Fails on an empty set.
    pub fn reinitialize(&mut self, particles: Vec<Particle>) -> Result<(), MclError> {
        if particles.is_empty() {
            return Err(MclError::NoParticles);
        }
        self.particles = particles;
        normalize(&mut self.particles);
        self.recovery = Recovery::default();
        Ok(())
    }

    /// The frame must have the camera's size.
    fn check_frame_size(&self, frame: &dyn FrameFeatures) -> Result<(), MclError> {
        check_frame_size(self.sensor.intrinsics(), frame)
    }

    /// Measurement update (Eq. 5-7): each particle's weight times its
    /// likelihood raised to the sharpening exponent. Returns the mean
    /// likelihood; on a casting error the particles are put back as they
    /// were before the step.
    fn weigh(
        &mut self,
        pixels: &[(u32, u32)],
        table: &SimilarityTable,
        sharpen: f64,
    ) -> Result<f64, MclError> {
        let l = self.sensor.likelihoods(&self.particles, pixels, table);
        let mean_l = l.iter().map(|&x| x as f64).sum::<f64>() / l.len().max(1) as f64;
        for (p, &li) in self.particles.iter_mut().zip(l) {
            p.weight *= (li.max(0.0) as f64).powf(sharpen);
        }
        self.undo_on_cast_error()?;
        Ok(mean_l)
    }

    /// After a cast: on a casting error, the particles as they were before
    /// the step, and the error.
    fn undo_on_cast_error(&mut self) -> Result<(), MclError> {
        if let Some(e) = self.sensor.take_cast_error() {
            std::mem::swap(&mut self.particles, &mut self.undo);
            return Err(MclError::Cast(e));
        }
        Ok(())
    }

    /// Recovery: each particle is replaced with probability `fraction` by a
    /// pose from the injection sampler; with `per` > 1 candidates a slot, the
    /// ones this frame agrees with most are kept. Returns how many were
    /// injected.
    fn inject(
        &mut self,
        fraction: f64,
        per: usize,
        pixels: &[(u32, u32)],
        table: &SimilarityTable,
    ) -> Result<usize, MclError> {
        let Some(sampler) = self.injection.as_ref() else {
            return Ok(0);
        };
        let slots: Vec<usize> = (0..self.particles.len())
            .filter(|_| self.rng.random::<f64>() < fraction)
            .collect();
        let per = per.max(1);
        let mut candidates: Vec<Particle> = (0..slots.len() * per)
            .filter_map(|_| sampler.sample(&mut self.rng))
            .map(|pose| Particle::new(pose, 1.0))
            .collect();
        if per > 1 && !candidates.is_empty() {
            let l = self.sensor.likelihoods(&candidates, pixels, table);
            let mut order: Vec<usize> = (0..candidates.len()).collect();
            order.sort_by(|&a, &b| l[b].total_cmp(&l[a]).then(a.cmp(&b)));
            order.truncate(slots.len());
            candidates = order.into_iter().map(|i| candidates[i]).collect();
            self.undo_on_cast_error()?;
        }
        let w = 1.0 / self.particles.len() as f64;
        let mut injected = 0;
        for (&slot, c) in slots.iter().zip(candidates) {
            self.particles[slot] = Particle::new(c.pose, w);
            injected += 1;
        }
        normalize(&mut self.particles);
        Ok(injected)
    }

    /// One filter step with the odometry `increment`
    /// (`prev_camera_from_camera`) and the new frame's features. On error
    /// the particles are unchanged.
    pub fn step(
        &mut self,
        increment: &Pose,
        frame: &dyn FrameFeatures,
    ) -> Result<StepReport, MclError> {
        check_pose(increment)?;
        self.check_frame_size(frame)?;
        let t0 = Instant::now();
        let sampled = sample_in_strata(
            frame,
            &self.db,
            &self.config.sampling,
            &mut self.rng,
            self.strata
                .as_deref()
                .filter(|_| self.config.sampling.map_strata),
        )?;
        let table =
            SimilarityTable::of_sample(frame, &sampled, &self.db, self.config.sensor.contrast)?;
        let pixels = sampled.pixels;
        let t1 = Instant::now();
        // Kept so that a casting error leaves the particles as they were.
        self.undo.clone_from(&self.particles);
        let n = self.particles.len();
        let expand = self.config.anneal.map_or(1, |a| a.expand.max(1)) as usize;
        if expand > 1 {
            // Copies of each particle, each to get its own motion noise.
            let w = 1.0 / expand as f64;
            self.particles = self
                .undo
                .iter()
                .flat_map(|p| std::iter::repeat_n(Particle::new(p.pose, p.weight * w), expand))
                .collect();
        }
        self.config
            .motion
            .predict(&mut self.particles, increment, &mut self.rng)?;
        sort_spatially(&mut self.particles, self.sort_cell);
        let t2 = Instant::now();
        let layers = match &self.config.anneal {
            Some(a) => a.fractions(),
            None => vec![1.0],
        };
        let sharpen = self.config.sharpen;
        // The first layer's mean likelihood drives recovery: it is that of
        // the predicted set, as without layers.
        let mean_l = if expand > 1 {
            let first: Vec<(u32, u32)> = pixels.iter().step_by(expand).copied().collect();
            self.weigh(&first, &table.every(expand), sharpen * layers[0])?
        } else {
            self.weigh(&pixels, &table, sharpen * layers[0])?
        };
        // Read now: scoring injection candidates below casts again.
        let mut cast = self.sensor.last_cast();
        // All-zero weights (every particle disagrees with the frame): keep
        // no information from this frame; `normalize` makes them uniform.
        normalize(&mut self.particles);
        if let Some(a) = self.config.anneal {
            for (layer, &fraction) in (1..).zip(&layers[1..]) {
                // Back to the filter's count after an expanded first layer.
                resample(&mut self.particles, n, true, &mut self.rng);
                a.jitter(
                    layer,
                    &self.config.motion,
                    &mut self.particles,
                    &mut self.rng,
                );
                sort_spatially(&mut self.particles, self.sort_cell);
                self.weigh(&pixels, &table, sharpen * fraction)?;
                cast += self.sensor.last_cast();
                normalize(&mut self.particles);
            }
        }
        self.pixel_major = self.sensor.last_pixel_major();
        let t3 = Instant::now();
        let est = estimate(&self.particles, &self.config.estimate).ok_or(MclError::NoParticles)?;
        let ess_now = ess(&self.particles);
        // The averages run whether or not injection is on: they give the
        // step's confidence.
        let rates = self.config.recovery.unwrap_or_default();
        let fraction = self.recovery.update(mean_l, &rates);
        let inject = match (&self.config.recovery, &self.injection) {
            (Some(_), Some(_)) => fraction,
            _ => 0.0,
        };
        let confidence = self.recovery.confidence();
        let n_next = match &self.config.kld {
            Some(p) => particle_count(&self.particles, p, &mut self.rng),
            None => self.particles.len(),
        };
        let resampled = self.config.resample.due(&self.particles)
            || n_next != self.particles.len()
            || inject > 0.0;
        if resampled {
            resample(
                &mut self.particles,
                n_next,
                self.config.resample.reset_weights,
                &mut self.rng,
            );
        }
        let injected = if inject > 0.0 {
            self.inject(inject, rates.candidates, &pixels, &table)?
        } else {
            0
        };
        let t4 = Instant::now();
        Ok(StepReport {
            estimate: est.pose,
            ess: ess_now,
            spread: est.spread,
            mean_likelihood: mean_l,
            confidence,
            n_particles: self.particles.len(),
            n_rays: pixels.len(),
            resampled,
            injected,
            timings: StepTimings {
                features: t1 - t0,
                predict: t2 - t1,
                weigh: t3 - t2,
                cast,
                update: t4 - t3,
            },
        })
    }
}
