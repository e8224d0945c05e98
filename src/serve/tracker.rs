//! What a served session steps: OMCL's filter ([`Session`]) or one of
//! Table I's semantic MCL baselines on a floor plan ([`BaselineSession`],
//! `CreateSessionRequest.baseline`).

use crate::frame::FrameFeatures;
use crate::geometry::Pose;
use crate::mcl::Particle;
use crate::session::baseline::BaselineSession;
use crate::session::{PoseReport, Session, SessionConfig, SessionError, Start};

/// [`Tracker::method`] of OMCL's own filter.
pub const OMCL: &str = "OMCL";

/// One session's filter.
pub enum Tracker {
    Omcl(Box<Session>),
    /// A baseline, with the configuration it was made with (its camera,
    /// for the blind-start warning).
    Baseline {
        session: Box<BaselineSession>,
        config: Box<SessionConfig>,
    },
}

impl Tracker {
    /// The configuration the session was made with.
    pub fn config(&self) -> &SessionConfig {
        match self {
            Tracker::Omcl(s) => s.config(),
            Tracker::Baseline { config, .. } => config,
        }
    }

    /// What tracks the camera, as `SessionInfo.method` names it.
    pub fn method(&self) -> &'static str {
        match self {
            Tracker::Omcl(_) => OMCL,
            Tracker::Baseline { session, .. } => session.baseline().label(),
        }
    }

    /// Frames stepped so far.
    pub fn frames(&self) -> u64 {
        match self {
            Tracker::Omcl(s) => s.frames(),
            Tracker::Baseline { session, .. } => session.frames(),
        }
    }

    /// The particles (normalized weights).
    pub fn particles(&self) -> &[Particle] {
        match self {
            Tracker::Omcl(s) => s.particles(),
            Tracker::Baseline { session, .. } => session.particles(),
        }
    }

    /// Steps one frame; `depth` (the camera's z-depths, metres) is read by
    /// SIMP\* and ignored by the others. A rejected frame leaves the
    /// session as it was.
    pub fn step(
        &mut self,
        odom: &Pose,
        stamp: f64,
        frame: &dyn FrameFeatures,
        depth: Option<&[f32]>,
    ) -> Result<PoseReport, SessionError> {
        match self {
            Tracker::Omcl(s) => s.step(odom, stamp, frame),
            Tracker::Baseline { session, .. } => session.step(odom, stamp, frame, depth),
        }
    }

    /// Restarts the filter from `start` (a baseline: from a pose only).
    pub fn reinitialize(&mut self, start: &Start) -> Result<(), SessionError> {
        match self {
            Tracker::Omcl(s) => s.reinitialize(start),
            Tracker::Baseline { session, .. } => session.reinitialize(start),
        }
    }
}
