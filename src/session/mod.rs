//! Localization sessions: the one loop that `omcl localize` and `omcl serve`
//! both run.
//!
//! A [`SharedMap`] is opened once (the map and its Embree scene, read-only,
//! shared by `Arc` between any number of sessions and threads). A
//! [`Session`] starts on it from a pose, from prompt words or globally,
//! takes frames (any [`FrameFeatures`]: [`label_frame`], [`feature_grid`], an
//! encoder's output) with an odometry pose and a stamp, and answers each
//! with a [`PoseReport`]: the pose, its 6x6 covariance and the filter's
//! confidence. It can be reinitialized from a new pose or prompt at any
//! time; dropping it closes it. A shared map can also be a floor plan's 2-D
//! scene ([`SharedMap::floor_plan`], [`floorplan`]): its sessions hold the
//! camera level, and start from a pose, or globally or from prompt words
//! on the floor of the 3-D map the plan was projected from
//! ([`SharedMap::with_floor_map`]). On a 3-D map a session can hold the
//! camera to the ground as a robot carries it ([`SessionConfig::ground`],
//! [`ground`]).
//!
//! Odometry is given as poses (`odom_from_camera`, as a robot's odometry
//! frame publishes them); the session turns consecutive poses into the
//! filter's increments, so the first frame moves nothing
//! ([`Session::step_by`] takes the increments themselves, as the
//! benchmark's runs in [`mod@crate::experiment::run`] do). [`sequence`] reads a
//! recorded sequence from disk and localizes it (`omcl localize`). Noisy odometry
//! made from ground truth has one definition in the library,
//! [`crate::sim::paths::odometry`].

pub mod baseline;
pub mod floorplan;
pub mod frames;
pub mod ground;
pub mod scan_fit;
pub mod sequence;

use std::path::Path;
use std::sync::{Arc, Mutex};

use nalgebra::{Matrix6, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::encode::{FeatureMap as EncodedMap, ImageEncoder};
use crate::geometry::{Intrinsics, Pose, Ray};
use crate::map::{self, LanguageMap};
use crate::mcl::{
    self, Filter, FilterConfig, FloorParams, FloorSampler, FrameFeatures, MclError, Particle,
    PromptParams, SensorModel, StepReport,
};
use crate::raycast::RayCaster;
use ground::Mount;

pub use frames::{LabelTable, feature_grid, label_frame};

/// Farthest the odometry may move between two frames, metres: more is a
/// jump (a visual odometry's reset, a glitch of 1e6 m), not motion, and
/// stepping it sent the estimate 600 km away at full confidence.
pub const MAX_ODOMETRY_STEP_M: f64 = 1000.0;

/// Errors of a session. [`SessionError::BadFrame`], [`SessionError::BadOdometry`],
/// [`SessionError::OdometryJump`] and [`SessionError::BadStamp`] reject one
/// input and leave the session as it was.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error("map {path}: {source}")]
    Map {
        path: String,
        source: map::MapFileError,
    },
    #[error("building the ray-casting scene: {0}")]
    Scene(String),
    #[error("map {0:?} has no voxels: there is nothing to localize against")]
    EmptyMap(String),
    #[error("malformed frame: {0}")]
    BadFrame(String),
    #[error("class table: {0}")]
    ClassTable(String),
    #[error("odometry pose is not a finite rigid motion: {0}")]
    BadOdometry(String),
    #[error(
        "odometry moved {0:.3e} m between two frames (more than {MAX_ODOMETRY_STEP_M} m: a jump, \
         not motion); the frame is refused (a new start pose, or a new session, begins afresh)"
    )]
    OdometryJump(f64),
    #[error("stamp {0} is not a finite number")]
    BadStamp(f64),
    #[error("{0} needs the feature of \"floor\" (a class table with a \"floor\" row)")]
    NoFloorFeature(&'static str),
    #[error("initialization: {0}")]
    Init(MclError),
    #[error(
        "map {0:?} is a floor plan without the 3-D map it was projected from: sessions on it \
         start from a pose (global and prompt starts and recovery place cameras on a 3-D map's \
         floor voxels)"
    )]
    PoseStartOnly(String),
    #[error(
        "{0} starts from a pose (the paper's local start): its sensor scores class labels, and \
         global and prompt starts place cameras with the floor's feature"
    )]
    BaselineStart(&'static str),
    #[error(
        "a camera held to the ground (a floor plan, or `ground`) moves with planar motion noise, \
         not {0:?}"
    )]
    GroundMotion(mcl::MotionMode),
    #[error(
        "recovery injects level cameras, and the start pose is {0:.1} degrees from level: a \
         camera held to the ground keeps its start's tilt (start level, or without recovery)"
    )]
    TiltedRecovery(f64),
    #[error("recovery injects poses over the floor: {0}")]
    Recovery(MclError),
    #[error(transparent)]
    Filter(#[from] MclError),
    #[error("image encoder: {0}")]
    Encoder(String),
}

/// A map opened once for any number of sessions: the map, its ray-casting
/// scene, and optionally a class table for label frames and prompt words.
pub struct SharedMap {
    name: String,
    map: LanguageMap,
    caster: Arc<dyn RayCaster>,
    /// A 2-D scene ([`SharedMap::floor_plan`]): sessions hold the camera
    /// level.
    level: bool,
    /// The rows the sessions' pixels are stratified over
    /// ([`crate::mcl::Filter::with_strata`]; a floor plan's own rows and
    /// words); `None`: all.
    strata: Option<Vec<bool>>,
    /// A floor plan's 3-D map ([`SharedMap::with_floor_map`]), whose floor
    /// voxels global and prompt starts and recovery use.
    floor_map: Option<Arc<LanguageMap>>,
    classes: Option<LabelTable>,
    /// The image encoder raw frames go through (one at a time).
    encoder: Option<Mutex<ImageEncoder>>,
    /// A floor plan's plan, one-layer map and caster, for baseline
    /// sessions ([`baseline::BaselineSession`]).
    baseline_map: Option<Arc<baseline::BaselineMap>>,
}

impl SharedMap {
    /// Builds the ray-casting scene of `map` once.
    pub fn new(name: impl Into<String>, map: LanguageMap) -> Result<Self, SessionError> {
        let name = name.into();
        if map.is_empty() {
            return Err(SessionError::EmptyMap(name));
        }
        let caster = SensorModel::embree_caster(map.grid().resolution as f32, &map.cells())
            .map_err(|e| SessionError::Scene(e.to_string()))?;
        Ok(SharedMap {
            name,
            map,
            caster: Arc::new(caster),
            level: false,
            strata: None,
            floor_map: None,
            classes: None,
            encoder: None,
            baseline_map: None,
        })
    }

    /// A map whose scene is already built: `caster` must index `map`'s
    /// leaves in order (e.g. an experiment's own caster, or a planar one).
    pub fn from_parts(
        name: impl Into<String>,
        map: LanguageMap,
        caster: Arc<dyn RayCaster>,
    ) -> Self {
        SharedMap {
            name: name.into(),
            map,
            caster,
            level: false,
            strata: None,
            floor_map: None,
            classes: None,
            encoder: None,
            baseline_map: None,
        }
    }

    /// A floor plan's 2-D scene ([`floorplan::PlanScene`]: its sighted map
    /// and planar caster). A pose on it is x, y and yaw of a camera held
    /// level, as a robot carries it: its sessions level the start pose at
    /// its own height and every odometry pose and increment
    /// ([`ground::level`]), so the odometry's horizontal motion and
    /// heading move the particles and its height, roll and pitch do not.
    /// They start from a pose; global and prompt starts and recovery need
    /// the 3-D map the plan was projected from ([`SharedMap::with_floor_map`]).
    /// Its pixels are stratified over the plan's own rows and the floor
    /// and ceiling words ([`floorplan::PlanScene::strata`]).
    /// The plan itself, its one-layer map and caster are kept for the
    /// baselines' sessions ([`SharedMap::baseline_map`]).
    pub fn floor_plan(name: impl Into<String>, scene: floorplan::PlanScene) -> Self {
        let floorplan::PlanScene {
            plan,
            map,
            caster,
            sighted_map,
            sighted,
            strata,
        } = scene;
        SharedMap {
            level: true,
            strata: Some(strata),
            baseline_map: Some(Arc::new(baseline::BaselineMap::new(plan, map, caster))),
            ..Self::from_parts(name, sighted_map, sighted)
        }
    }

    /// A floor plan's plan, one-layer map and caster, which Table I's
    /// baselines localize on (`None`: not a floor plan).
    pub fn baseline_map(&self) -> Option<&Arc<baseline::BaselineMap>> {
        self.baseline_map.as_ref()
    }

    /// The same map with its sessions' pixels stratified over the rows
    /// `strata` marks only (`None`: all; see
    /// [`crate::mcl::Filter::with_strata`]).
    pub fn with_strata(mut self, strata: Option<Vec<bool>>) -> Self {
        self.strata = strata;
        self
    }

    /// Whether sessions on this map hold the camera level (a floor plan).
    pub fn is_level(&self) -> bool {
        self.level
    }

    /// For a floor plan: `map3`, the 3-D map it was projected from. Global
    /// and prompt starts and recovery then find the floor voxels in it and
    /// place their level cameras over them at the floor's camera height
    /// ([`FloorParams`]), as on the 3-D map itself, and the sessions hold
    /// each particle at its own start height. (On a 3-D map this changes
    /// nothing: its own floor voxels are used.)
    pub fn with_floor_map(mut self, map3: Arc<LanguageMap>) -> Self {
        self.floor_map = Some(map3);
        self
    }

    /// The map whose floor voxels global and prompt starts and recovery
    /// use: the map itself, a floor plan's 3-D map, or `None` (a floor plan
    /// without one).
    pub fn floor_source(&self) -> Option<&LanguageMap> {
        match self.level {
            false => Some(&self.map),
            true => self.floor_map.as_deref(),
        }
    }

    /// Reads the map file at `path` and builds its scene.
    pub fn open(name: impl Into<String>, path: &Path) -> Result<Self, SessionError> {
        let map = map::load(path).map_err(|source| SessionError::Map {
            path: path.display().to_string(),
            source,
        })?;
        Self::new(name, map)
    }

    /// Attaches a class table (for label frames and prompt words).
    pub fn with_classes(mut self, classes: LabelTable) -> Self {
        self.classes = Some(classes);
        self
    }

    /// Attaches an image encoder for raw RGB frames; its features must
    /// have the map's dimension.
    pub fn with_encoder(mut self, encoder: ImageEncoder) -> Result<Self, SessionError> {
        let (got, want) = (encoder.feature_dim(), self.map.db().dim());
        if got != want {
            return Err(SessionError::Encoder(format!(
                "{} gives {got}-dimensional features, map {:?} has {want}",
                encoder.card().name,
                self.name
            )));
        }
        self.encoder = Some(Mutex::new(encoder));
        Ok(self)
    }

    /// Whether raw RGB frames can be encoded for this map.
    pub fn has_encoder(&self) -> bool {
        self.encoder.is_some()
    }

    /// Encodes a raw RGB frame with the map's image encoder.
    pub fn encode(&self, image: &image::RgbImage) -> Result<EncodedMap, SessionError> {
        let enc = self.encoder.as_ref().ok_or_else(|| {
            SessionError::BadFrame(format!(
                "map {:?} has no image encoder for raw frames (serve it with --image-model)",
                self.name
            ))
        })?;
        let mut enc = enc.lock().unwrap_or_else(|e| e.into_inner());
        enc.encode(image)
            .map_err(|e| SessionError::Encoder(e.to_string()))
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn map(&self) -> &LanguageMap {
        &self.map
    }

    /// The class table, if one was attached.
    pub fn classes(&self) -> Option<&LabelTable> {
        self.classes.as_ref()
    }

    /// The ray-casting scene shared by the sessions.
    pub fn caster(&self) -> &Arc<dyn RayCaster> {
        &self.caster
    }

    /// The share, in `[0, 1]`, of a camera's view from `world_from_camera`
    /// that meets the map within `max_range` metres: rays through a grid
    /// of 32 x 24 pixels. Near 0 when the pose lies outside the map or
    /// faces away from it, which is what a start pose given in another
    /// frame than the map's looks like (every ray then misses, and the
    /// filter's likelihoods are all alike).
    pub fn view_share(
        &self,
        world_from_camera: &Pose,
        intrinsics: &Intrinsics,
        max_range: f64,
    ) -> f64 {
        const COLS: u32 = 32;
        const ROWS: u32 = 24;
        let o = world_from_camera.translation.vector - self.map.grid().origin;
        let origin = [o.x as f32, o.y as f32, o.z as f32];
        let rays: Vec<Ray> = (0..ROWS)
            .flat_map(|r| (0..COLS).map(move |c| (c, r)))
            .map(|(c, r)| {
                let u = ((c as f64 + 0.5) * intrinsics.width as f64 / COLS as f64) as u32;
                let v = ((r as f64 + 0.5) * intrinsics.height as f64 / ROWS as f64) as u32;
                let d = world_from_camera.rotation * intrinsics.pixel_dir(u, v);
                Ray {
                    t_max: max_range as f32,
                    ..Ray::new(origin, [d.x as f32, d.y as f32, d.z as f32])
                }
            })
            .collect();
        let mut hits = vec![crate::raycast::Hit::miss(); rays.len()];
        self.caster.cast_serial(&rays, &mut hits);
        // A backend error leaves misses, which is what this measures; taken
        // here so that a filter's next step does not report it as its own.
        let _ = self.caster.take_error();
        let met = hits.iter().filter(|h| h.is_hit()).count();
        met as f64 / rays.len() as f64
    }
}

/// A start pose from which less than this share of the camera's view
/// meets the map ([`SharedMap::view_share`]) is warned about (`omcl
/// localize`, `omcl serve`): the filter cannot find the camera from it.
pub const BLIND_START_SHARE: f64 = 0.05;

/// The start of a session whose camera sees almost none of the map
/// ([`blind_start`]): what it sees and where the map is, for a warning.
#[derive(Debug, Clone, PartialEq)]
pub struct BlindStart {
    /// The share of its view that meets the map.
    pub share: f64,
    /// How far it was looked, metres.
    pub range_m: f64,
    /// The start's position.
    pub at: [f64; 3],
    /// The box of the map's voxels ([`LanguageMap::world_bounds`]).
    pub bounds: Option<([f64; 3], [f64; 3])>,
}

impl std::fmt::Display for BlindStart {
    /// `from the start pose (at x y z m) N % of the camera's view meets
    /// the map within R m (its voxels span ...)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [x, y, z] = self.at;
        write!(
            f,
            "from the start pose (at {x:.2} {y:.2} {z:.2} m) {:.0} % of the camera's view meets \
             the map within {:.0} m",
            100.0 * self.share,
            self.range_m
        )?;
        if let Some((lo, hi)) = self.bounds {
            write!(
                f,
                " (its voxels span x {:.1} to {:.1}, y {:.1} to {:.1}, z {:.1} to {:.1} m)",
                lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
            )?;
        }
        Ok(())
    }
}

/// Whether a start at `pose` leaves the camera blind to `map` (under
/// [`BLIND_START_SHARE`] of its view meets it, looked at to the sensor's
/// range or, unbounded, 100 m): outside the map, facing away from it, or
/// given in another frame. Every ray then misses and scores alike, so
/// the filter cannot find the camera, and its confidence stays high.
pub fn blind_start(map: &SharedMap, pose: &Pose, config: &SessionConfig) -> Option<BlindStart> {
    let range_m = match config.filter.sensor.max_range {
        r if r.is_finite() => f64::from(r),
        _ => 100.0,
    };
    let share = map.view_share(pose, &config.intrinsics, range_m);
    let t = pose.translation.vector;
    (share < BLIND_START_SHARE).then(|| BlindStart {
        share,
        range_m,
        at: [t.x, t.y, t.z],
        bounds: map.map().world_bounds(),
    })
}

/// How a session places its particles.
#[derive(Debug, Clone)]
pub enum Start {
    /// Gaussian around `pose` (`world_from_camera`): `sigma_m` on the ground
    /// plane, `sigma_rad` on yaw.
    Pose {
        pose: Pose,
        sigma_m: f64,
        sigma_rad: f64,
    },
    /// Uniformly over the floor voxels.
    Global,
    /// Over the floor voxels near voxels matching every word's feature.
    Prompt {
        words: Vec<Vec<f32>>,
        params: PromptParams,
    },
}

/// Everything fixed for the life of a session.
#[derive(Debug, Clone)]
pub struct SessionConfig {
    pub intrinsics: Intrinsics,
    /// Particles at the start (and after each reinitialization).
    pub particles: usize,
    /// The filter; `filter.seed` seeds every random draw of the session.
    pub filter: FilterConfig,
    /// Floor detection and camera placement of global and prompt starts.
    pub floor: FloorParams,
    /// The feature of "floor", needed by global and prompt starts and by
    /// recovery (`filter.recovery`).
    pub floor_feature: Option<Vec<f32>>,
    /// Hold the camera to the ground, as a robot on a flat floor carries
    /// it ([`ground`]): its height, roll and pitch stay the start's (a
    /// pose start's own; a global or prompt start's cameras are level),
    /// and only the odometry's horizontal motion and turn move it. Needs
    /// planar motion noise. A floor plan's sessions always do, with the
    /// camera level.
    pub ground: bool,
}

/// The answer to one frame.
#[derive(Debug, Clone, Copy)]
pub struct PoseReport {
    /// The frame's stamp, echoed.
    pub stamp: f64,
    /// Frames stepped so far, this one included.
    pub frame: u64,
    /// Estimated `world_from_camera`.
    pub pose: Pose,
    /// Covariance of the particles about `pose`, row-major 6x6 over
    /// (x, y, z, rotation about world x, y, z), metres and radians, as
    /// `geometry_msgs/PoseWithCovariance`.
    pub covariance: [f64; 36],
    /// The filter's own numbers (ESS, spread, confidence, timings).
    pub step: StepReport,
}

/// A filter step's refusal in the session's terms: a frame of the wrong
/// size or dimension is the frame's fault, bad odometry the odometry's.
pub(crate) fn step_error(e: MclError) -> SessionError {
    match e {
        MclError::DimMismatch { .. } | MclError::ImageSize { .. } => {
            SessionError::BadFrame(e.to_string())
        }
        MclError::BadOdometry(s) => SessionError::BadOdometry(s),
        e => SessionError::Filter(e),
    }
}

impl PoseReport {
    /// The report of frame `frame` (stamped `stamp`) from its filter
    /// step and the particles after it.
    pub(crate) fn of(stamp: f64, frame: u64, step: StepReport, particles: &[Particle]) -> Self {
        PoseReport {
            stamp,
            frame,
            pose: step.estimate,
            covariance: covariance(particles, &step.estimate),
            step,
        }
    }
}

/// One camera localized in a shared map.
pub struct Session {
    map: Arc<SharedMap>,
    config: SessionConfig,
    filter: Filter,
    /// Draws of the initializations (the filter has its own generator).
    init_rng: ChaCha8Rng,
    /// How the camera is held to the ground (floor plans, `ground`).
    mount: Option<Mount>,
    last_odom: Option<Pose>,
    frames: u64,
}

impl Session {
    /// Starts a session on `map`.
    pub fn new(
        map: Arc<SharedMap>,
        config: SessionConfig,
        start: &Start,
    ) -> Result<Self, SessionError> {
        let seed = config.filter.seed;
        Self::with_init_seed(map, config, start, seed)
    }

    /// [`Session::new`] with the initializations drawn from `init_seed`
    /// rather than `config.filter.seed` (the benchmark's runs keep their
    /// own stream).
    pub fn with_init_seed(
        map: Arc<SharedMap>,
        config: SessionConfig,
        start: &Start,
        init_seed: u64,
    ) -> Result<Self, SessionError> {
        let mount = mount(&map, &config, start)?;
        let mut init_rng = ChaCha8Rng::seed_from_u64(init_seed);
        let particles = initial_particles(&map, &config, start, &mut init_rng)?;
        let mut filter = Filter::new(
            &map.map,
            map.caster.clone(),
            config.intrinsics,
            config.filter,
            particles,
        )?
        .with_strata(map.strata.clone());
        if let Some(sampler) = injection(&map, &config, start, mount.as_ref())? {
            filter = filter.with_injection(sampler);
        }
        Ok(Session {
            map,
            config,
            filter,
            init_rng,
            mount,
            last_odom: None,
            frames: 0,
        })
    }

    /// The map this session localizes in.
    pub fn map(&self) -> &Arc<SharedMap> {
        &self.map
    }

    pub fn config(&self) -> &SessionConfig {
        &self.config
    }

    /// Frames stepped so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// The particles (normalized weights), e.g. for a particle cloud.
    pub fn particles(&self) -> &[Particle] {
        self.filter.particles()
    }

    /// Replaces the particles as `start` says (after track loss, or a user's
    /// new pose or prompt). The next frame's odometry is taken as the new
    /// reference (it moves nothing).
    pub fn reinitialize(&mut self, start: &Start) -> Result<(), SessionError> {
        let mount = mount(&self.map, &self.config, start)?;
        let particles = initial_particles(&self.map, &self.config, start, &mut self.init_rng)?;
        let sampler = injection(&self.map, &self.config, start, mount.as_ref())?;
        self.filter.reinitialize(particles)?;
        if let Some(sampler) = sampler {
            self.filter.set_injection(sampler);
        }
        self.mount = mount;
        self.last_odom = None;
        Ok(())
    }

    /// One frame: `odom` is the odometry pose of the frame's camera
    /// (`odom_from_camera`), `stamp` its time. A rejected frame leaves the
    /// session as it was.
    pub fn step(
        &mut self,
        odom: &Pose,
        stamp: f64,
        frame: &dyn FrameFeatures,
    ) -> Result<PoseReport, SessionError> {
        check_input(odom, stamp)?;
        let odom = match &self.mount {
            Some(m) => m.hold(odom),
            None => *odom,
        };
        let increment = match &self.last_odom {
            Some(prev) => prev.inverse() * odom,
            None => Pose::identity(),
        };
        let report = self.step_held(&increment, stamp, frame)?;
        self.last_odom = Some(odom);
        Ok(report)
    }

    /// One frame with the odometry given as the increment since the
    /// previous frame (`camera_prev_from_camera`, e.g. a visual odometry's
    /// frame-to-frame motion). The next [`Session::step`] takes its
    /// odometry pose as a new reference.
    pub fn step_by(
        &mut self,
        increment: &Pose,
        stamp: f64,
        frame: &dyn FrameFeatures,
    ) -> Result<PoseReport, SessionError> {
        check_input(increment, stamp)?;
        let increment = match &self.mount {
            Some(m) => m.hold_increment(increment),
            None => *increment,
        };
        self.step_held(&increment, stamp, frame)
    }

    /// One frame with an increment already checked, and held to the ground
    /// when the session holds the camera ([`Session::step`] holds the poses,
    /// [`Session::step_by`] the increment).
    fn step_held(
        &mut self,
        increment: &Pose,
        stamp: f64,
        frame: &dyn FrameFeatures,
    ) -> Result<PoseReport, SessionError> {
        let moved = increment.translation.vector.norm();
        if moved > MAX_ODOMETRY_STEP_M {
            return Err(SessionError::OdometryJump(moved));
        }
        let step = self.filter.step(increment, frame).map_err(step_error)?;
        self.last_odom = None;
        self.frames += 1;
        Ok(PoseReport::of(
            stamp,
            self.frames,
            step,
            self.filter.particles(),
        ))
    }
}

/// How a session on `map` with `config` holds its camera from `start`:
/// `None` free; a floor plan's level; with `config.ground` the pose
/// start's tilt, or level for global and prompt starts (their cameras are
/// level).
fn mount(
    map: &SharedMap,
    config: &SessionConfig,
    start: &Start,
) -> Result<Option<Mount>, SessionError> {
    if !(map.level || config.ground) {
        return Ok(None);
    }
    let mode = config.filter.motion.mode;
    if mode != mcl::MotionMode::Planar {
        return Err(SessionError::GroundMotion(mode));
    }
    let mount = match start {
        Start::Pose { pose, .. } if !map.level => Mount::of(pose),
        _ => Mount::level(),
    };
    let tilt = mount.tilt_deg();
    if config.filter.recovery.is_some() && tilt > 1e-6 {
        return Err(SessionError::TiltedRecovery(tilt));
    }
    Ok(Some(mount))
}

/// Recovery's sampler, when `config` asks for recovery: level cameras over
/// the floor voxels of `map`'s floor source, at the floor's camera height;
/// for a held camera (`mount`) from a pose start at that pose's height, where
/// the session holds the tracked ones.
fn injection(
    map: &SharedMap,
    config: &SessionConfig,
    start: &Start,
    mount: Option<&Mount>,
) -> Result<Option<FloorSampler>, SessionError> {
    if config.filter.recovery.is_none() {
        return Ok(None);
    }
    let floor = config
        .floor_feature
        .as_deref()
        .ok_or(SessionError::NoFloorFeature("recovery"))?;
    let floor_map = map
        .floor_source()
        .ok_or_else(|| SessionError::PoseStartOnly(map.name.clone()))?;
    let voxels = mcl::init::floor_voxels(floor_map, floor, config.floor.rho)
        .map_err(SessionError::Recovery)?;
    let sampler = FloorSampler::new(floor_map, &voxels, config.floor);
    Ok(Some(match (mount, start) {
        (Some(_), Start::Pose { pose, .. }) => sampler.at_height(pose.translation.vector.z),
        _ => sampler,
    }))
}

/// A frame's stamp must be finite and its odometry a finite rigid motion.
fn check_input(odometry: &Pose, stamp: f64) -> Result<(), SessionError> {
    if !stamp.is_finite() {
        return Err(SessionError::BadStamp(stamp));
    }
    mcl::motion::check_pose(odometry).map_err(|e| match e {
        MclError::BadOdometry(s) => SessionError::BadOdometry(s),
        e => SessionError::Filter(e),
    })
}

fn initial_particles(
    map: &SharedMap,
    config: &SessionConfig,
    start: &Start,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<Particle>, SessionError> {
    let n = config.particles;
    if n == 0 {
        return Err(SessionError::Init(MclError::NoParticles));
    }
    let floor = |what| {
        config
            .floor_feature
            .as_deref()
            .ok_or(SessionError::NoFloorFeature(what))
    };
    let floor_map = || {
        map.floor_source()
            .ok_or_else(|| SessionError::PoseStartOnly(map.name.clone()))
    };
    match start {
        Start::Pose {
            pose,
            sigma_m,
            sigma_rad,
        } => {
            mcl::motion::check_pose(pose).map_err(SessionError::Init)?;
            let level;
            let pose = if map.level {
                level = ground::level(pose, pose.translation.vector.z);
                &level
            } else {
                pose
            };
            if !(sigma_m.is_finite()
                && *sigma_m >= 0.0
                && sigma_rad.is_finite()
                && *sigma_rad >= 0.0)
            {
                return Err(SessionError::Init(MclError::BadParam {
                    name: "initial spread",
                    why: format!("must be finite and >= 0, got {sigma_m} m, {sigma_rad} rad"),
                }));
            }
            Ok(mcl::local_init(pose, n, *sigma_m, *sigma_rad, rng))
        }
        Start::Global => mcl::global_init(
            floor_map()?,
            floor("global initialization")?,
            &config.floor,
            n,
            rng,
        )
        .map_err(SessionError::Init),
        Start::Prompt { words, params } => mcl::prompt_init(
            floor_map()?,
            floor("prompt initialization")?,
            words,
            &config.floor,
            params,
            n,
            rng,
        )
        .map_err(SessionError::Init),
    }
}

/// Weighted covariance of the particles about `center`, row-major 6x6 over
/// (translation x, y, z; rotation vector of `R_particle R_center^T` about
/// the world axes).
pub fn covariance(particles: &[Particle], center: &Pose) -> [f64; 36] {
    let total: f64 = particles.iter().map(|p| p.weight).sum();
    let mut c = Matrix6::<f64>::zeros();
    if total > 0.0 {
        let inv_r = center.rotation.inverse();
        for p in particles {
            let t = p.pose.translation.vector - center.translation.vector;
            let r = (p.pose.rotation * inv_r).scaled_axis();
            let d = Vector6::new(t.x, t.y, t.z, r.x, r.y, r.z);
            c += (p.weight / total) * d * d.transpose();
        }
    }
    let mut out = [0.0; 36];
    for i in 0..6 {
        for j in 0..6 {
            out[6 * i + j] = c[(i, j)];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    #[test]
    fn a_map_without_voxels_is_refused_by_name() {
        use crate::map::{FeatureDb, GridSpec};
        let db = FeatureDb::from_rows(2, 0.0, vec![1.0, 0.0]).unwrap();
        let grid = GridSpec {
            resolution: 0.05,
            origin: Vector3::zeros(),
        };
        let empty = LanguageMap::from_cells(grid, db.clone(), "enc", []).unwrap();
        let e = SharedMap::new("hall", empty).err().unwrap().to_string();
        assert!(e.contains("\"hall\"") && e.contains("no voxels"), "{e}");
        let one = LanguageMap::from_cells(grid, db, "enc", [([0, 0, 0], 0)]).unwrap();
        SharedMap::new("hall", one).unwrap();
    }

    #[test]
    fn covariance_of_known_particles() {
        // Four particles of weight 1/4: two at x = +-0.5 m, two at yaw
        // +-0.1 rad, about the origin: 2 x 0.25 x 0.25 = 0.125 m^2 on x,
        // 2 x 0.25 x 0.01 = 0.005 rad^2 on rotation about z, nothing else.
        let at = |x: f64, yaw: f64| Particle {
            pose: Pose::from_parts(
                Translation3::new(x, 0.0, 0.0),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
            ),
            weight: 0.25,
        };
        let ps = [at(0.5, 0.0), at(-0.5, 0.0), at(0.0, 0.1), at(0.0, -0.1)];
        let c = covariance(&ps, &Pose::identity());
        assert!((c[0] - 0.125).abs() < 1e-12, "{c:?}");
        assert!((c[35] - 0.005).abs() < 1e-12, "{c:?}");
        for (i, v) in c.iter().enumerate() {
            if i != 0 && i != 35 {
                assert!(v.abs() < 1e-12, "entry {i}: {v}");
            }
        }
    }
}
