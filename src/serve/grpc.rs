//! The gRPC service: thin handlers over [`State`]. Handlers never run a
//! filter step or an initialization themselves; those go to the compute
//! pool.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use tokio::sync::{mpsc, oneshot};
use tokio_stream::wrappers::ReceiverStream;
use tonic::metadata::MetadataMap;
use tonic::{Request, Response, Status, Streaming};

use crate::geometry::{Intrinsics, Pose};
use crate::mcl::baselines::{Baseline, BaselineParams};
use crate::mcl::{FilterConfig, FilterPreset};
use crate::session::baseline::BaselineSession;
use crate::session::{Session, SessionConfig, SessionError, SharedMap, Start};

use super::auth::{MISPLACED, Token};
use super::convert;
use super::proto::{self, localization_server::Localization};
use super::state::{Reply, Slot, State};
use super::tracker::Tracker;

pub struct Service {
    pub state: Arc<State>,
}

/// The bearer-token check of every gRPC call, and the refusal of calls on
/// a connection past the cap, as a tonic interceptor (a tower layer in
/// front of the service): refused calls never reach a handler.
pub fn interceptor(
    state: Arc<State>,
    token: Token,
) -> impl FnMut(Request<()>) -> Result<Request<()>, Status> + Clone {
    move |req: Request<()>| {
        if state.shutting_down.load(Ordering::Relaxed) {
            state.metrics.reject("shutting_down");
            return Err(Status::unavailable("the server is shutting down"));
        }
        let md: &MetadataMap = req.metadata();
        let value = md.get("authorization").map(|v| v.as_bytes());
        let elsewhere = MISPLACED.iter().find(|k| md.contains_key(**k)).copied();
        if let Err(e) = token.check(value, elsewhere) {
            state.metrics.reject("unauthenticated");
            return Err(Status::unauthenticated(e.to_string()));
        }
        // A connection past the cap (counted once, when it came).
        let c = &state.connections;
        if req.remote_addr().is_some_and(|peer| c.refused(peer)) {
            return Err(Status::resource_exhausted(format!(
                "connection cap: {} gRPC connections open (--max-connections {}); \
                 this connection closes in {} s, retry when one has gone",
                c.open(),
                c.max(),
                super::connections::REFUSAL_GRACE.as_secs()
            )));
        }
        Ok(req)
    }
}

fn camera(c: Option<&proto::CameraInfo>) -> Result<Intrinsics, Status> {
    let c = c.ok_or_else(|| Status::invalid_argument("camera: missing"))?;
    let k = Intrinsics {
        fx: c.fx,
        fy: c.fy,
        cx: c.cx,
        cy: c.cy,
        width: c.width,
        height: c.height,
    };
    k.check()
        .map_err(|why| Status::invalid_argument(format!("camera: {why}")))?;
    Ok(k)
}

impl Service {
    /// DEADLINE_EXCEEDED for a call the server's deadline ended, counted
    /// as `expired`. (tonic's own timeout layer answered CANCELLED "Timeout
    /// expired", uncounted; the server sets none.)
    fn past_deadline(&self, what: &str) -> Status {
        self.state.metrics.reject("expired");
        Status::deadline_exceeded(format!(
            "{what} within the server's deadline of {:.2} s (--deadline-s)",
            self.state.limits.deadline.as_secs_f64()
        ))
    }

    /// `f`'s answer, or DEADLINE_EXCEEDED once the server's deadline has
    /// passed (a client's shorter grpc-timeout ends the call sooner).
    async fn within_deadline<T>(
        &self,
        what: &str,
        f: impl std::future::Future<Output = Result<T, Status>>,
    ) -> Result<T, Status> {
        match tokio::time::timeout(self.state.limits.deadline, f).await {
            Ok(r) => r,
            Err(_) => Err(self.past_deadline(what)),
        }
    }

    /// Restarts a session's filter from `start`.
    async fn reinitialize(
        &self,
        slot: Arc<Slot>,
        start: Start,
    ) -> Result<Response<proto::ReinitializeResponse>, Status> {
        slot.touch();
        let map = slot.map.clone();
        let restarted = slot.clone();
        // The call gives up (its deadline, or its client gone) only while
        // the reinitialization still waits for the session's lock: an
        // answer of DEADLINE_EXCEEDED means the filter was not touched.
        let claim = Claim::default();
        let run = claim.clone();
        let done = self.state.with_session(slot, move |s| {
            if !run.start() {
                return None;
            }
            let warning = match &start {
                Start::Pose { pose, .. } => blind_start(&map, pose, s.config()),
                _ => None,
            };
            // A new track: its frames' stamps need not follow the old's.
            Some(
                s.reinitialize(&start)
                    .map(|()| restarted.restart_stamps())
                    .map(|()| warning),
            )
        });
        tokio::pin!(done);
        let ran = match tokio::time::timeout(self.state.limits.deadline, &mut done).await {
            Ok(r) => r?,
            Err(_) if claim.abandon() => return Err(self.past_deadline("no reinitialization")),
            // Begun before the deadline: its answer, a moment later.
            Err(_) => done.await?,
        };
        let warning = ran
            .ok_or_else(|| Status::internal("reinitialization abandoned"))?
            .map_err(|e| super::state::status_of(&e))?;
        Ok(Response::new(proto::ReinitializeResponse {
            warnings: warning.into_iter().collect(),
        }))
    }
}

/// The warning for a start pose from which the camera cannot see the map
/// ([`crate::session::blind_start`], as `omcl localize` warns).
fn blind_start(map: &SharedMap, pose: &Pose, config: &SessionConfig) -> Option<String> {
    crate::session::blind_start(map, pose, config).map(|b| {
        format!(
            "map {}: {b}; every ray that misses scores alike, so the filter cannot find the \
             camera, and its confidence stays high. Is the pose the camera's, in the map's \
             frame?",
            convert::quoted(map.name()),
        )
    })
}

/// Refuses a global or prompt start on a floor plan served without the
/// 3-D map it was projected from (its starts place cameras on the 3-D
/// map's floor voxels), as the session would.
fn pose_start_only(map: &SharedMap) -> Result<(), Status> {
    match map.floor_source() {
        Some(_) => Ok(()),
        None => Err(super::state::status_of(&SessionError::PoseStartOnly(
            map.name().to_string(),
        ))),
    }
}

/// `CreateSessionRequest.baseline`'s method (`None`: OMCL), refused with
/// what a baseline cannot do: a map that is not a floor plan or has no
/// class table, a start but a pose, and OMCL's own options.
fn baseline_of(
    r: &proto::CreateSessionRequest,
    map: &SharedMap,
) -> Result<Option<Baseline>, Status> {
    if let Some(m) = r.max_depth {
        if r.baseline != "simp" {
            return Err(Status::invalid_argument(format!(
                "max_depth: {m} m given for {}: it is for a SIMP* session (baseline \"simp\", \
                 the only sensor here that places pixels at their depth)",
                match r.baseline.as_str() {
                    "" => "an OMCL session".to_string(),
                    other => format!("baseline {}", convert::quoted(other)),
                }
            )));
        }
        if !(m.is_finite() && m > 0.0) {
            return Err(Status::invalid_argument(format!(
                "max_depth: {m} m, expected a positive number of metres"
            )));
        }
    }
    let b = match r.baseline.as_str() {
        "" => return Ok(None),
        "sedar" => Baseline::Sedar,
        "simp" => Baseline::Simp,
        other => {
            return Err(Status::invalid_argument(format!(
                "baseline: unknown baseline {}: expected \"sedar\" or \"simp\" (empty: OMCL)",
                convert::quoted(other)
            )));
        }
    };
    let name = b.label();
    if map.baseline_map().is_none() {
        return Err(Status::failed_precondition(format!(
            "baseline: {name} localizes on a floor plan, and map {} is a 3-D map (serve its \
             floor plan: omcl serve --floorplan)",
            convert::quoted(map.name())
        )));
    }
    if map.classes().is_none() {
        return Err(Status::failed_precondition(format!(
            "baseline: {name} labels the plan's columns and the pixels with a class table, and \
             map {} has none",
            convert::quoted(map.name())
        )));
    }
    if !matches!(
        r.start,
        Some(proto::create_session_request::Start::InitialPose(_))
    ) {
        return Err(Status::invalid_argument(format!(
            "baseline: {name} starts from initial_pose (the paper's local start): its sensor \
             scores class labels, and global and prompt starts place cameras with the floor's \
             feature"
        )));
    }
    let omcl_only = [
        (r.recovery, "recovery"),
        (r.early_reject, "early_reject"),
        (!r.filter.is_empty(), "filter"),
    ];
    let given: Vec<&str> = omcl_only
        .iter()
        .filter(|(g, _)| *g)
        .map(|(_, f)| *f)
        .collect();
    if !given.is_empty() {
        return Err(Status::invalid_argument(format!(
            "baseline: {} set{} OMCL's filter, which {name} does not use (a baseline \
             session has the floor-plan filter's motion noise, sampling, estimate and \
             resampling)",
            given.join(", "),
            if given.len() == 1 { "s" } else { "" }
        )));
    }
    Ok(Some(b))
}

/// A session of baseline `b` on `map` (a floor plan with a class table,
/// [`baseline_of`]) with `pixels` sampled a frame, placing (SIMP\*) pixels
/// at most `max_depth` deep.
fn baseline_session(
    map: &SharedMap,
    b: Baseline,
    pixels: usize,
    max_depth: Option<f64>,
    config: SessionConfig,
    start: &Start,
) -> Result<Tracker, SessionError> {
    let (Some(on), Some(classes)) = (map.baseline_map(), map.classes()) else {
        return Err(SessionError::ClassTable(format!(
            "map {:?} is not a floor plan with a class table",
            map.name()
        )));
    };
    let params = BaselineParams {
        pixels,
        max_depth,
        ..BaselineParams::default()
    };
    let session = BaselineSession::new(on, classes.table(), b, params, &config, start)?;
    Ok(Tracker::Baseline {
        session: Box::new(session),
        config: Box::new(config),
    })
}

/// Who settles a reinitialization waiting for its session's lock: the
/// task that runs it ([`Claim::start`]) or the call that asked for it,
/// giving up ([`Claim::abandon`]; also when the call is dropped, its
/// client gone). Whichever comes first wins; the other learns it.
#[derive(Clone, Default)]
struct Claim(Arc<std::sync::atomic::AtomicU8>);

impl Claim {
    const WAITING: u8 = 0;
    const STARTED: u8 = 1;
    const ABANDONED: u8 = 2;

    fn settle(&self, to: u8) -> bool {
        self.0
            .compare_exchange(Self::WAITING, to, Ordering::AcqRel, Ordering::Acquire)
            .is_ok()
    }

    /// Whether the reinitialization may run (the call has not given up).
    fn start(&self) -> bool {
        self.settle(Self::STARTED)
    }

    /// Whether the call gave up in time (the reinitialization had not
    /// started, and now will not).
    fn abandon(&self) -> bool {
        self.settle(Self::ABANDONED)
    }
}

impl Drop for Claim {
    fn drop(&mut self) {
        // The call's own copy going (the call dropped): give up if still
        // waiting. The running task's copy finds it settled already.
        self.abandon();
    }
}

/// A session's start for the log: its kind, and where or what.
fn start_kind(start: Option<&proto::create_session_request::Start>) -> String {
    use proto::create_session_request::Start as S;
    match start {
        Some(S::InitialPose(p)) => {
            let t = p
                .pose
                .as_ref()
                .and_then(|p| p.pose.as_ref())
                .and_then(|p| p.position.as_ref());
            match t {
                Some(t) => format!("pose start at {:.2} {:.2} {:.2} m", t.x, t.y, t.z),
                None => "pose start".to_string(),
            }
        }
        Some(S::Global(_)) => "global start".to_string(),
        Some(S::Prompt(p)) => {
            const SHOWN: usize = 8;
            let mut words: Vec<String> = p
                .words
                .iter()
                .take(SHOWN)
                .map(|w| convert::quoted(w))
                .collect();
            if p.words.len() > SHOWN {
                words.push(format!("and {} more", p.words.len() - SHOWN));
            }
            format!("prompt start ({})", words.join(", "))
        }
        None => "no start".to_string(),
    }
}

#[tonic::async_trait]
impl Localization for Service {
    async fn list_maps(
        &self,
        _req: Request<proto::ListMapsRequest>,
    ) -> Result<Response<proto::ListMapsResponse>, Status> {
        Ok(Response::new(proto::ListMapsResponse {
            maps: super::map_infos(&self.state),
        }))
    }

    async fn list_sessions(
        &self,
        _req: Request<proto::ListSessionsRequest>,
    ) -> Result<Response<proto::ListSessionsResponse>, Status> {
        Ok(Response::new(proto::ListSessionsResponse {
            sessions: super::session_infos(&self.state),
        }))
    }

    async fn create_session(
        &self,
        req: Request<proto::CreateSessionRequest>,
    ) -> Result<Response<proto::CreateSessionResponse>, Status> {
        let r = req.into_inner();
        let map = self.state.map(&r.map)?.clone();
        let baseline = baseline_of(&r, &map)?;
        let max_depth = r.max_depth;
        let intrinsics = camera(r.camera.as_ref())?;
        let particles = r
            .particles
            .map_or(crate::mcl::INDOOR_PARTICLES, |p| p as usize);
        if !(1..=crate::mcl::MAX_COUNT).contains(&particles) {
            return Err(Status::invalid_argument(format!(
                "particles: {particles}, expected 1..={}",
                crate::mcl::MAX_COUNT
            )));
        }
        // A floor plan's sessions default to Table I's 2-D filter (a
        // baseline's too: it names no filter, and samples 2048 pixels).
        let base = if r.filter.is_empty() {
            if map.is_level() {
                FilterConfig::floor_plan()
            } else {
                FilterConfig::default()
            }
        } else {
            r.filter
                .parse::<FilterPreset>()
                .map_err(|_| {
                    Status::invalid_argument(format!(
                        "filter: unknown filter {}: expected one of {}",
                        convert::quoted(&r.filter),
                        FilterPreset::names()
                    ))
                })?
                .config()
        };
        let default_rays = match baseline {
            Some(_) => BaselineParams::default().pixels,
            None => base.sampling.rays,
        };
        let rays = r.rays.map_or(default_rays, |r| r as usize);
        if !(1..=crate::mcl::MAX_COUNT).contains(&rays) {
            return Err(Status::invalid_argument(format!(
                "rays: {rays}, expected 1..={}",
                crate::mcl::MAX_COUNT
            )));
        }
        // A step cannot be stopped once it runs (its caller may give up,
        // its session may close, the server may be told to stop): what one
        // may cost is bounded here.
        let most = particles.max(base.kld.as_ref().map_or(0, |k| k.max_particles));
        let cap = self.state.limits.max_rays_per_step;
        if most.saturating_mul(rays) > cap {
            return Err(Status::invalid_argument(format!(
                "particles x rays: {most} x {rays} = {} rays a step, over the server's \
                 --max-rays-per-step {cap}",
                most.saturating_mul(rays)
            )));
        }
        let start = match &r.start {
            Some(proto::create_session_request::Start::InitialPose(p)) => convert::initial_pose(p)?,
            Some(proto::create_session_request::Start::Global(_)) => Start::Global,
            Some(proto::create_session_request::Start::Prompt(p)) => {
                pose_start_only(&map)?;
                convert::prompt(p, &map)?
            }
            None => {
                return Err(Status::invalid_argument(
                    "start: give initial_pose, global or prompt",
                ));
            }
        };
        let mut filter = FilterConfig {
            seed: r.seed,
            ..base
        };
        filter.sampling.rays = rays;
        if r.recovery {
            filter.recovery = Some(crate::mcl::recovery::RecoveryParams::default());
        }
        if r.early_reject {
            filter.sensor.early_reject = Some(crate::mcl::EarlyReject::default());
        }
        let config = SessionConfig {
            intrinsics,
            particles,
            filter,
            floor: crate::mcl::FloorParams::default(),
            floor_feature: map
                .classes()
                .and_then(|c| c.word("floor"))
                .map(<[f32]>::to_vec),
            ground: r.ground,
        };
        let m = map.clone();
        let made = self.state.on_pool(move || {
            let warning = match &start {
                Start::Pose { pose, .. } => blind_start(&m, pose, &config),
                _ => None,
            };
            match baseline {
                None => Session::new(m, config, &start).map(|s| Tracker::Omcl(Box::new(s))),
                Some(b) => baseline_session(&m, b, rays, max_depth, config, &start),
            }
            .map(|s| (s, warning))
        });
        let (session, warning) = self
            .within_deadline("no session", made)
            .await?
            .map_err(|e| super::state::status_of(&e))?;
        let frame_id = if r.frame_id.is_empty() {
            "map".to_string()
        } else {
            r.frame_id
        };
        let id = self.state.add_session(map.clone(), session, frame_id)?;
        super::log::event(format_args!(
            "session {id} opened on map {}: {}{}, {particles} particles x {rays} rays{}",
            convert::quoted(map.name()),
            start_kind(r.start.as_ref()),
            baseline.map_or(String::new(), |b| format!(", {}", b.label())),
            if warning.is_some() {
                " (warned: the camera cannot see the map from the start pose)"
            } else {
                ""
            }
        ));
        Ok(Response::new(proto::CreateSessionResponse {
            session_id: id,
            warnings: warning.into_iter().collect(),
        }))
    }

    async fn close_session(
        &self,
        req: Request<proto::CloseSessionRequest>,
    ) -> Result<Response<proto::CloseSessionResponse>, Status> {
        let slot = self.state.remove_session(&req.get_ref().session_id)?;
        super::log::event(format_args!(
            "session {} closed by its client; {} stepped",
            slot.id,
            super::log::count(slot.frames(), "frame")
        ));
        Ok(Response::new(proto::CloseSessionResponse {
            frames: slot.frames(),
        }))
    }

    async fn set_initial_pose(
        &self,
        req: Request<proto::SetInitialPoseRequest>,
    ) -> Result<Response<proto::ReinitializeResponse>, Status> {
        let r = req.into_inner();
        let slot = self.state.session(&r.session_id)?;
        let pose = r
            .pose
            .as_ref()
            .ok_or_else(|| Status::invalid_argument("pose: missing"))?;
        let start = convert::initial_pose(pose)?;
        self.reinitialize(slot, start).await
    }

    async fn global_localization(
        &self,
        req: Request<proto::GlobalLocalizationRequest>,
    ) -> Result<Response<proto::ReinitializeResponse>, Status> {
        let r = req.into_inner();
        let slot = self.state.session(&r.session_id)?;
        slot.touch();
        // A baseline, or a floor plan without its 3-D map, starts from a
        // pose only: said before a prompt's words are looked up (a word
        // the map lacks is not what to change).
        if slot.is_baseline() {
            return Err(super::state::status_of(&SessionError::BaselineStart(
                slot.method,
            )));
        }
        pose_start_only(&slot.map)?;
        let start = match &r.prompt {
            Some(p) if !p.words.is_empty() => convert::prompt(p, &slot.map)?,
            _ => Start::Global,
        };
        self.reinitialize(slot, start).await
    }

    async fn localize(
        &self,
        req: Request<proto::Frame>,
    ) -> Result<Response<proto::PoseUpdate>, Status> {
        let f = req.into_inner();
        let slot = self.state.session(&f.session_id)?;
        let input = convert::frame_input(f, &slot.camera(), &slot.map).inspect_err(|_| {
            self.state.metrics.reject("invalid_frame");
        })?;
        let (tx, rx) = oneshot::channel();
        let expired = Arc::new(AtomicBool::new(false));
        self.state
            .submit(slot, input, Reply::Unary(tx, expired.clone()));
        match tokio::time::timeout(self.state.limits.deadline, rx).await {
            Ok(Ok(answer)) => answer.map(Response::new),
            Ok(Err(_)) => Err(Status::internal("the step's answer was lost")),
            Err(_) => {
                // Before the receiver is dropped: a turn that finds the
                // call gone then knows it was counted here.
                expired.store(true, Ordering::SeqCst);
                Err(self.past_deadline("no pose"))
            }
        }
    }

    type StreamStream = ReceiverStream<Result<proto::StreamResponse, Status>>;

    async fn stream(
        &self,
        req: Request<Streaming<proto::Frame>>,
    ) -> Result<Response<Self::StreamStream>, Status> {
        let mut inbound = req.into_inner();
        let (tx, rx) = mpsc::channel(self.state.limits.stream_buffer.max(1));
        let state = self.state.clone();
        tokio::spawn(async move {
            // The session this stream last sent a frame for, and its count
            // of takes from just before that frame was submitted.
            let mut waiting: Option<(Arc<Slot>, tokio::sync::watch::Receiver<u64>)> = None;
            // Bytes still to be read before waiting again, while a frame
            // waits (a stream window's worth after each take: what the
            // client could send meanwhile, no more however fast it refills
            // the window).
            let mut budget = super::STREAM_WINDOW as usize;
            loop {
                // Backpressure (see `state`): while the frame waits, what
                // has already arrived is read, up to the budget, so that the
                // latest wins; then nothing until a step takes a frame.
                let ready = if budget > 0 {
                    ready_now(inbound.message())
                } else {
                    None
                };
                let next = match ready {
                    Some(m) => m,
                    None => {
                        if let Some((slot, mut takes)) = waiting.take() {
                            if slot.frame_waiting() {
                                tokio::select! {
                                    _ = takes.changed() => {}
                                    // The client is gone: no answer can
                                    // reach it.
                                    _ = tx.closed() => break,
                                }
                            }
                            budget = super::STREAM_WINDOW as usize;
                            continue;
                        }
                        budget = super::STREAM_WINDOW as usize;
                        tokio::select! {
                            m = inbound.message() => m,
                            // Shutdown while the client sends nothing: the
                            // stream ends (UNAVAILABLE, after the answers
                            // of its frames on the pool), else the drain
                            // would wait for it to its timeout.
                            () = state.shutdown_begun() => {
                                Err(Status::unavailable("the server is shutting down"))
                            }
                        }
                    }
                };
                let f = match next {
                    Ok(Some(f)) => f,
                    // End of the client's stream.
                    Ok(None) => break,
                    // A message that could not be read (over
                    // --max-message-mib: OUT_OF_RANGE), after which the
                    // stream carries nothing more: it ends with that
                    // status, not an OK that hides the frames after it. A
                    // transport error (the client gone) goes nowhere.
                    Err(s) => {
                        if !matches!(
                            s.code(),
                            tonic::Code::Cancelled
                                | tonic::Code::Unavailable
                                | tonic::Code::Unknown
                        ) {
                            state.metrics.reject("invalid_frame");
                        }
                        // The codec's words name no option: say which.
                        let s = if s.code() == tonic::Code::OutOfRange {
                            Status::out_of_range(format!(
                                "{} (the server's --max-message-mib is {})",
                                s.message(),
                                state.limits.max_message_bytes >> 20
                            ))
                        } else {
                            s
                        };
                        // The answers of frames already handed to the pool
                        // go out first (each job holds a clone of `tx`
                        // until it has answered or been dropped); the
                        // error ends the stream after them.
                        while tx.strong_count() > 1 {
                            tokio::select! {
                                _ = tokio::time::sleep(std::time::Duration::from_millis(5)) => {}
                                _ = tx.closed() => break,
                            }
                        }
                        let _ = tx.send(Err(s)).await;
                        break;
                    }
                };
                budget = budget.saturating_sub(prost::Message::encoded_len(&f));
                if state.shutting_down.load(Ordering::Relaxed) {
                    let _ = tx
                        .send(Err(Status::unavailable("the server is shutting down")))
                        .await;
                    break;
                }
                let stamp = f.header.as_ref().and_then(|h| h.stamp);
                let checked = state.session(&f.session_id).and_then(|slot| {
                    convert::frame_input(f, &slot.camera(), &slot.map).map(|i| (slot, i))
                });
                match checked {
                    Ok((slot, input)) => {
                        let takes = slot.takes();
                        state.submit(slot.clone(), input, Reply::Stream(tx.clone()));
                        waiting = Some((slot, takes));
                    }
                    Err(s) => {
                        state.metrics.reject("invalid_frame");
                        let msg = proto::StreamResponse {
                            result: Some(proto::stream_response::Result::Error(
                                convert::frame_error(&s, stamp),
                            )),
                        };
                        let _ = tx.try_send(Ok(msg));
                    }
                }
            }
        });
        Ok(Response::new(ReceiverStream::new(rx)))
    }
}

/// `f`'s output if it is ready at the first poll (for a future that keeps
/// its state outside itself, such as `Streaming::message`, dropping it
/// unfinished loses nothing).
fn ready_now<F: std::future::Future>(f: F) -> Option<F::Output> {
    let mut f = std::pin::pin!(f);
    let mut cx = std::task::Context::from_waker(std::task::Waker::noop());
    match f.as_mut().poll(&mut cx) {
        std::task::Poll::Ready(v) => Some(v),
        std::task::Poll::Pending => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::session::floorplan::PlanScene;

    /// A floor plan served without its 3-D map refuses global and prompt
    /// starts as its session would (`FAILED_PRECONDITION`, naming the map),
    /// before a prompt's words are looked up; with the 3-D map beside it,
    /// they go on.
    #[test]
    fn a_plan_without_its_3d_map_starts_from_a_pose_only() {
        let (plan, one, _) = crate::mcl::baselines::tests::scene();
        let bare = SharedMap::floor_plan("plan", PlanScene::from_plan(plan.clone()).unwrap());
        let e = pose_start_only(&bare).unwrap_err();
        assert_eq!(e.code(), tonic::Code::FailedPrecondition, "{e:?}");
        assert!(
            e.message()
                .contains("map \"plan\" is a floor plan without the 3-D map"),
            "{e:?}"
        );
        let with = SharedMap::floor_plan("plan", PlanScene::from_plan(plan).unwrap())
            .with_floor_map(Arc::new(one));
        assert!(pose_start_only(&with).is_ok());
    }
}
