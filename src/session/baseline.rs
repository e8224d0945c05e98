//! A camera tracked on a floor plan by one of Table I's baselines, SeDAR\*
//! or SIMP\* ([`crate::mcl::baselines`]), with the session's conventions:
//! odometry poses in, level pose reports out. `omcl localize --floorplan
//! --baseline` runs it on a recorded sequence.
//!
//! Like a floor plan's OMCL session ([`super::SharedMap::floor_plan`]) it
//! holds the camera level at the start's height: the start pose is
//! levelled ([`super::ground::level`]) and so is every odometry pose, so the
//! odometry's horizontal motion and heading move the particles. It starts
//! from a pose only, as both baselines do in the paper (the local start);
//! their sensors score labels, not the floor's feature that global and
//! prompt starts place cameras with.

use std::sync::Arc;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::floorplan::PlanScene;
use super::ground::{self, Mount};
use super::{MAX_ODOMETRY_STEP_M, PoseReport, SessionConfig, SessionError, Start};
use crate::frame::FrameFeatures;
use crate::geometry::Pose;
use crate::io::labels::EmbeddingTable;
use crate::map::FeatureDb;
use crate::mcl::baseline_filter::{BaselineFilter, BaselinePlan};
use crate::mcl::baselines::{Baseline, BaselineParams};
use crate::mcl::{self, MclError, Particle};

/// One camera tracked by a baseline on a floor plan.
pub struct BaselineSession {
    filter: BaselineFilter,
    mount: Mount,
    last_odom: Option<Pose>,
    frames: u64,
}

impl BaselineSession {
    /// `baseline` on `scene`'s plan (its one-layer map and caster), the
    /// plan's columns and the frames' pixels labelled with `classes`, from
    /// `start` (a pose: Gaussian about it, levelled), with `config`'s
    /// camera, particle count and filter (motion noise, sampling, estimate,
    /// resampling; `config.filter.seed` seeds every draw).
    pub fn new(
        scene: &PlanScene,
        classes: &EmbeddingTable,
        baseline: Baseline,
        params: BaselineParams,
        config: &SessionConfig,
        start: &Start,
    ) -> Result<Self, SessionError> {
        let Start::Pose {
            pose,
            sigma_m,
            sigma_rad,
        } = start
        else {
            return Err(SessionError::BaselineStart(baseline.name()));
        };
        mcl::motion::check_pose(pose).map_err(SessionError::Init)?;
        if !(sigma_m.is_finite() && *sigma_m >= 0.0 && sigma_rad.is_finite() && *sigma_rad >= 0.0) {
            return Err(SessionError::Init(MclError::BadParam {
                name: "initial spread",
                why: format!("must be finite and >= 0, got {sigma_m} m, {sigma_rad} rad"),
            }));
        }
        if config.particles == 0 {
            return Err(SessionError::Init(MclError::NoParticles));
        }
        if classes.dim != scene.map.db().dim() {
            return Err(SessionError::ClassTable(format!(
                "{}-d class embeddings, the floor plan's features are {}-d: {} labels the plan's \
                 columns and the pixels with the classes nearest to their features",
                classes.dim,
                scene.map.db().dim(),
                baseline.name()
            )));
        }
        let db = FeatureDb::from_rows(classes.dim, 0.0, classes.data.clone())
            .map_err(|e| SessionError::ClassTable(e.to_string()))?;
        let plan = BaselinePlan::new(&scene.plan, &scene.map, scene.caster.clone(), db, &params)?;
        let mut rng = ChaCha8Rng::seed_from_u64(config.filter.seed);
        let level = ground::level(pose, pose.translation.vector.z);
        let particles: Vec<Particle> =
            mcl::local_init(&level, config.particles, *sigma_m, *sigma_rad, &mut rng);
        let filter = BaselineFilter::new(
            baseline,
            params,
            Arc::new(plan),
            config.intrinsics,
            config.filter,
            particles,
            rng,
        )?;
        Ok(BaselineSession {
            filter,
            mount: Mount::level(),
            last_odom: None,
            frames: 0,
        })
    }

    /// The particles (normalized weights).
    pub fn particles(&self) -> &[Particle] {
        self.filter.particles()
    }

    /// Frames stepped so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// One frame: `odom` the odometry pose of its camera
    /// (`odom_from_camera`), `stamp` its time, `depth` its z-depths
    /// (`width * height`, metres, 0 none; SIMP\* places the pixels with
    /// them and skips pixels without). A rejected frame leaves the
    /// session as it was.
    pub fn step(
        &mut self,
        odom: &Pose,
        stamp: f64,
        frame: &dyn FrameFeatures,
        depth: Option<&[f32]>,
    ) -> Result<PoseReport, SessionError> {
        super::check_input(odom, stamp)?;
        let odom = self.mount.hold(odom);
        let increment = self.last_odom.map(|prev| prev.inverse() * odom);
        if let Some(inc) = &increment {
            let moved = inc.translation.vector.norm();
            if moved > MAX_ODOMETRY_STEP_M {
                return Err(SessionError::OdometryJump(moved));
            }
        }
        let step = self
            .filter
            .step(increment.as_ref(), frame, depth)
            .map_err(|e| match e {
                MclError::DimMismatch { .. }
                | MclError::ImageSize { .. }
                | MclError::BadParam { .. } => SessionError::BadFrame(e.to_string()),
                MclError::BadOdometry(s) => SessionError::BadOdometry(s),
                e => SessionError::Filter(e),
            })?;
        self.last_odom = Some(odom);
        self.frames += 1;
        Ok(PoseReport::of(
            stamp,
            self.frames,
            step,
            self.filter.particles(),
        ))
    }
}
