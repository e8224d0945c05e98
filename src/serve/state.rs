//! The server's state: maps, sessions, the compute pool and its bounded
//! queues, and the metrics.
//!
//! Scheduling: every session has at most one step running or queued on the
//! compute pool and at most one frame waiting behind it. A frame that
//! arrives while one is waiting replaces it (latest frame wins) and the
//! replaced one is counted as dropped. A step that finds a waiting frame
//! when it ends queues it at the back of the pool (round robin between
//! sessions: a flooding session gets its share, no more). The pool's queue
//! therefore holds at most one task per session, and sessions are capped;
//! past `max_queued` tasks a new frame is refused (RESOURCE_EXHAUSTED).
//!
//! Streams are read with backpressure (`grpc`): once a frame of the
//! session a stream last sent for waits, the stream is read no further
//! until a step of that session takes a waiting frame ([`Slot::takes`]);
//! then what has arrived in the meantime is read, at most a stream window's
//! worth of messages, and the latest kept. HTTP/2 flow control holds a
//! flooding client to what its window holds instead of the server reading,
//! decoding and dropping thousands of frames a second on the cores the
//! steps need.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use tokio::sync::{mpsc, oneshot};
use tonic::Status;

use super::tracker::Tracker;
use crate::geometry::Intrinsics;
use crate::session::{SessionError, SharedMap, feature_grid, label_frame};

use super::convert::{Features, FrameInput};
use super::metrics::Metrics;
use super::proto;
use super::stamp::{Seen, Stamp};

/// Limits and sizes of a server.
#[derive(Debug, Clone)]
pub struct Limits {
    /// Threads of the compute pool (filter steps run only there).
    pub threads: usize,
    pub max_sessions: usize,
    pub max_sessions_per_map: usize,
    /// Open gRPC connections at most; more are closed at once.
    pub max_connections: usize,
    /// Steps queued or running on the pool, in total, before new frames
    /// are refused.
    pub max_queued: usize,
    /// Sessions without a frame or call for this long are closed.
    pub idle_timeout: Duration,
    /// Deadline of a unary call (a client's shorter grpc-timeout wins),
    /// and of any frame's turn on the pool (a frame whose turn comes later
    /// is not stepped).
    pub deadline: Duration,
    /// Largest message accepted, bytes.
    pub max_message_bytes: usize,
    /// Answers of a stream buffered for a slow reader; more are dropped.
    pub stream_buffer: usize,
    /// A session's particles x rays at most: the rays one step casts. A
    /// step cannot be stopped once it runs; this bounds how long one takes.
    pub max_rays_per_step: usize,
    /// The retry hint sent with RESOURCE_EXHAUSTED / 503.
    pub retry_after: Duration,
}

/// 2^27 rays a step: 64 times the paper's 1024 particles x 2048 rays, a
/// few seconds of a 2-core host's time (a step at the paper's size
/// takes about 50 ms on one).
pub const DEFAULT_MAX_RAYS_PER_STEP: usize = 1 << 27;

impl Default for Limits {
    fn default() -> Self {
        Limits {
            threads: std::thread::available_parallelism().map_or(2, |n| n.get()),
            max_sessions: 256,
            max_sessions_per_map: 128,
            max_connections: 512,
            max_queued: 256,
            idle_timeout: Duration::from_secs(300),
            deadline: Duration::from_secs(10),
            max_message_bytes: 32 << 20,
            stream_buffer: 16,
            max_rays_per_step: DEFAULT_MAX_RAYS_PER_STEP,
            retry_after: Duration::from_millis(200),
        }
    }
}

/// Where a step's answer goes.
pub enum Reply {
    /// A `Localize` call, and its flag the call sets when it answers
    /// DEADLINE_EXCEEDED itself (counted then as `expired`, not again when
    /// the frame's turn finds it gone).
    Unary(
        oneshot::Sender<Result<proto::PoseUpdate, Status>>,
        Arc<AtomicBool>,
    ),
    Stream(mpsc::Sender<Result<proto::StreamResponse, Status>>),
}

impl Reply {
    /// The caller has already counted this frame as expired.
    fn expired(&self) -> bool {
        matches!(self, Reply::Unary(_, e) if e.load(Ordering::SeqCst))
    }
}

struct Job {
    frame: FrameInput,
    reply: Reply,
    /// The session's track when the frame arrived ([`Queue::track`]).
    track: u64,
}

#[derive(Default)]
struct Queue {
    /// A step of this session is queued or running on the pool.
    busy: bool,
    /// The stamp of that step's frame.
    on_pool: Option<Stamp>,
    /// The frame waiting behind it.
    pending: Option<Job>,
    /// The stamp of the last frame the session stepped since it started or
    /// was last reinitialized (written under the session's lock too, so a
    /// reinitialization and a step agree on it).
    stepped: Option<Stamp>,
    /// How many times the session was reinitialized: a frame that arrived
    /// on an earlier track (its odometry and stamp are the old track's) is
    /// not stepped on the new one, and its stamp orders nothing.
    track: u64,
}

impl Queue {
    /// What a new frame's stamp must follow ([`super::stamp::follows`]).
    fn seen(&self) -> Seen {
        Seen {
            stepped: self.stepped,
            on_pool: self.on_pool,
            waiting: self
                .pending
                .as_ref()
                .filter(|j| j.track == self.track)
                .and_then(|j| j.frame.stamp),
        }
    }
}

/// One open session.
pub struct Slot {
    pub id: String,
    pub map: Arc<SharedMap>,
    /// frame_id of the estimates.
    pub frame_id: String,
    /// What tracks the camera ([`Tracker::method`]).
    pub method: &'static str,
    camera: Intrinsics,
    session: Mutex<Tracker>,
    queue: Mutex<Queue>,
    pub frames_dropped: AtomicU64,
    /// Frames stepped, as the session counts them after each step: read
    /// without the session's lock, which a long step holds (closing a
    /// session or listing them waited for it).
    frames: AtomicU64,
    last_used: Mutex<Instant>,
    closed: AtomicBool,
    /// How many times a step has taken the frame waiting behind it (stream
    /// readers wait for it to move, `grpc`).
    taken: tokio::sync::watch::Sender<u64>,
}

impl Slot {
    /// Whether a baseline (SeDAR*, SIMP*) tracks the camera, not OMCL.
    pub fn is_baseline(&self) -> bool {
        self.method != super::tracker::OMCL
    }
    /// The session's camera.
    pub fn camera(&self) -> Intrinsics {
        self.camera
    }
    pub fn touch(&self) {
        *lock(&self.last_used) = Instant::now();
    }
    pub fn idle(&self) -> Duration {
        lock(&self.last_used).elapsed()
    }
    pub fn frames(&self) -> u64 {
        self.frames.load(Ordering::Relaxed)
    }
    /// The count of takes, seen as it is now: `changed()` returns at the
    /// next take (every receiver is told, so any number of streams may
    /// wait on one session).
    pub fn takes(&self) -> tokio::sync::watch::Receiver<u64> {
        self.taken.subscribe()
    }
    /// A frame of this session waits behind its step.
    pub fn frame_waiting(&self) -> bool {
        lock(&self.queue).pending.is_some()
    }
    fn busy(&self) -> bool {
        lock(&self.queue).busy
    }
    /// Starts a new track: after a reinitialization, under the session's
    /// lock, the next frame may have any stamp, and the frames still on
    /// the pool or waiting (the old track's) are answered ABORTED at their
    /// turn instead of being stepped.
    pub fn restart_stamps(&self) {
        let mut q = lock(&self.queue);
        q.stepped = None;
        q.on_pool = None;
        q.track += 1;
    }
}

/// A poisoned lock means a panic in a step; the data is still consistent
/// (a step changes the session only when it succeeds), so go on.
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Everything the handlers share.
pub struct State {
    pub maps: Vec<Arc<SharedMap>>,
    pub limits: Limits,
    pub metrics: Metrics,
    /// Open gRPC connections, capped.
    pub connections: super::connections::Connections,
    sessions: Mutex<HashMap<String, Arc<Slot>>>,
    /// Ids of the sessions closed for idling, the latest
    /// [`EXPIRED_REMEMBERED`], so that a call for one says why it is gone.
    expired: Mutex<std::collections::VecDeque<String>>,
    compute: super::compute::Compute,
    /// Steps queued or running on the pool.
    queued: AtomicUsize,
    next_id: AtomicU64,
    pub shutting_down: AtomicBool,
    /// Turns `true` with `shutting_down` ([`State::begin_shutdown`]):
    /// stream readers waiting for a client's next frame end their streams.
    shutdown: tokio::sync::watch::Sender<bool>,
}

/// Idled-out session ids remembered for their message (ids are about 20
/// bytes: 80 KB at most).
const EXPIRED_REMEMBERED: usize = 4096;

/// The RESOURCE_EXHAUSTED answer with its retry hint (`retry-after-ms`).
pub fn exhausted(msg: impl Into<String>, retry_after: Duration) -> Status {
    let mut s = Status::resource_exhausted(msg);
    if let Ok(v) = retry_after.as_millis().to_string().parse() {
        s.metadata_mut().insert("retry-after-ms", v);
    }
    s
}

/// The gRPC status of a session error.
/// The answer to a frame that arrived before its session was
/// reinitialized.
fn reinitialized(id: &str) -> Status {
    Status::aborted(format!(
        "session {id:?} was reinitialized after this frame arrived: not stepped (its odometry \
         and stamp belong to the track before)"
    ))
}

pub fn status_of(e: &SessionError) -> Status {
    match e {
        // What to change, in the request's own fields.
        SessionError::Init(crate::mcl::MclError::NoPromptMatch { .. }) => {
            Status::failed_precondition(format!(
                "{e}; try fewer or other words, a lower PromptStart.k or PromptStart.rho, a \
                 larger PromptStart.radius, or a global or initial_pose start"
            ))
        }
        SessionError::BadFrame(_)
        | SessionError::BadOdometry(_)
        | SessionError::OdometryJump(_)
        | SessionError::BadStamp(_) => Status::invalid_argument(e.to_string()),
        SessionError::NoFloorFeature(_)
        | SessionError::ClassTable(_)
        | SessionError::Init(_)
        | SessionError::Recovery(_)
        | SessionError::PoseStartOnly(_)
        | SessionError::BaselineStart(_)
        | SessionError::GroundMotion(_)
        | SessionError::TiltedRecovery(_) => Status::failed_precondition(e.to_string()),
        _ => Status::internal(e.to_string()),
    }
}

impl State {
    pub fn new(maps: Vec<Arc<SharedMap>>, limits: Limits) -> Result<Arc<State>, String> {
        let compute = super::compute::Compute::new(limits.threads)?;
        let connections = super::connections::Connections::new(limits.max_connections);
        Ok(Arc::new(State {
            maps,
            limits,
            metrics: Metrics::default(),
            connections,
            sessions: Mutex::new(HashMap::new()),
            expired: Mutex::default(),
            compute,
            queued: AtomicUsize::new(0),
            next_id: AtomicU64::new(1),
            shutting_down: AtomicBool::new(false),
            shutdown: tokio::sync::watch::Sender::new(false),
        }))
    }

    /// Marks the server as shutting down (new calls UNAVAILABLE, waiting
    /// frames not stepped) and tells the streams' readers.
    pub fn begin_shutdown(&self) {
        self.shutting_down.store(true, Ordering::Relaxed);
        self.shutdown.send_replace(true);
    }

    /// Resolves once [`State::begin_shutdown`] has been called.
    pub fn shutdown_begun(&self) -> impl std::future::Future<Output = ()> + Send + 'static {
        let mut rx = self.shutdown.subscribe();
        async move {
            let _ = rx.wait_for(|s| *s).await;
        }
    }

    pub fn map(&self, name: &str) -> Result<&Arc<SharedMap>, Status> {
        self.maps.iter().find(|m| m.name() == name).ok_or_else(|| {
            Status::not_found(format!("unknown map {}", super::convert::quoted(name)))
        })
    }

    pub fn session(&self, id: &str) -> Result<Arc<Slot>, Status> {
        let s = lock(&self.sessions).get(id).cloned();
        s.ok_or_else(|| self.unknown_session(id))
    }

    /// NOT_FOUND for a session id, saying so when it idled out.
    fn unknown_session(&self, id: &str) -> Status {
        let quoted = super::convert::quoted(id);
        if lock(&self.expired).iter().any(|e| e == id) {
            return Status::not_found(format!(
                "session {quoted} was closed after {:.0} s without a frame or call (the \
                 server's --idle-timeout-s); create a new one",
                self.limits.idle_timeout.as_secs_f64()
            ));
        }
        Status::not_found(format!("unknown session {quoted}"))
    }

    pub fn sessions(&self) -> Vec<Arc<Slot>> {
        let mut v: Vec<_> = lock(&self.sessions).values().cloned().collect();
        v.sort_by(|a, b| a.id.cmp(&b.id));
        v
    }

    /// Tasks on the compute pool (steps, session set-ups) not yet finished,
    /// what they hold dropped included ([`super::compute::Compute::running`]).
    pub fn pool_running(&self) -> usize {
        self.compute.running()
    }

    /// Steps queued or running, and frames waiting behind them.
    pub fn queue_depth(&self) -> (usize, usize) {
        let waiting = lock(&self.sessions)
            .values()
            .filter(|s| s.frame_waiting())
            .count();
        (self.queued.load(Ordering::Relaxed), waiting)
    }

    /// Registers a session made on the pool; refused past the caps.
    pub fn add_session(
        &self,
        map: Arc<SharedMap>,
        session: Tracker,
        frame_id: String,
    ) -> Result<String, Status> {
        let mut all = lock(&self.sessions);
        let on_map = all.values().filter(|s| Arc::ptr_eq(&s.map, &map)).count();
        if all.len() >= self.limits.max_sessions {
            self.metrics.reject("session_cap");
            return Err(exhausted(
                format!("session cap: {} sessions open", all.len()),
                self.limits.retry_after,
            ));
        }
        if on_map >= self.limits.max_sessions_per_map {
            self.metrics.reject("session_cap");
            return Err(exhausted(
                format!("session cap: {on_map} sessions on map {:?}", map.name()),
                self.limits.retry_after,
            ));
        }
        let n = self.next_id.fetch_add(1, Ordering::Relaxed);
        let id = format!("s{n}-{:08x}", rand::random::<u32>());
        all.insert(
            id.clone(),
            Arc::new(Slot {
                id: id.clone(),
                map,
                frame_id,
                method: session.method(),
                camera: session.config().intrinsics,
                frames: AtomicU64::new(session.frames()),
                session: Mutex::new(session),
                queue: Mutex::new(Queue::default()),
                frames_dropped: AtomicU64::new(0),
                last_used: Mutex::new(Instant::now()),
                closed: AtomicBool::new(false),
                taken: tokio::sync::watch::Sender::new(0),
            }),
        );
        self.metrics
            .sessions_created
            .fetch_add(1, Ordering::Relaxed);
        Ok(id)
    }

    pub fn remove_session(&self, id: &str) -> Result<Arc<Slot>, Status> {
        let s = lock(&self.sessions).remove(id);
        let s = s.ok_or_else(|| self.unknown_session(id))?;
        s.closed.store(true, Ordering::Relaxed);
        Ok(s)
    }

    /// Closes sessions idle for longer than the limit (not while a step of
    /// theirs is queued or running). Returns how many.
    pub fn expire_idle(&self) -> usize {
        let mut all = lock(&self.sessions);
        let mut gone = Vec::new();
        all.retain(|id, s| {
            let idle = s.idle();
            let keep = s.busy() || idle < self.limits.idle_timeout;
            if !keep {
                s.closed.store(true, Ordering::Relaxed);
                gone.push((id.clone(), idle, s.frames()));
            }
            keep
        });
        drop(all);
        let n = gone.len();
        let mut expired = lock(&self.expired);
        for (id, idle, frames) in gone {
            super::log::event(format_args!(
                "session {id} expired: no frame or call for {:.0} s (--idle-timeout-s); {} \
                 stepped",
                idle.as_secs_f64(),
                super::log::count(frames, "frame")
            ));
            if expired.len() == EXPIRED_REMEMBERED {
                expired.pop_front();
            }
            expired.push_back(id);
        }
        self.metrics
            .sessions_expired
            .fetch_add(n as u64, Ordering::Relaxed);
        n
    }

    /// Runs `f` on the compute pool and waits for it without blocking the
    /// async runtime.
    pub async fn on_pool<T: Send + 'static>(
        &self,
        f: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, Status> {
        let (tx, rx) = oneshot::channel();
        self.compute.spawn_lane(move || {
            let _ = tx.send(f());
        });
        rx.await
            .map_err(|_| Status::internal("the compute pool dropped the task"))
    }

    /// Runs `f` on a session (reinitialization) on a blocking thread of the
    /// runtime, not on the compute pool: it waits for the session's lock,
    /// and a pool thread waiting inside a step (rayon steals work while it
    /// joins) could otherwise take this task while its own step holds that
    /// lock.
    pub async fn with_session<T: Send + 'static>(
        &self,
        slot: Arc<Slot>,
        f: impl FnOnce(&mut Tracker) -> T + Send + 'static,
    ) -> Result<T, Status> {
        tokio::task::spawn_blocking(move || f(&mut lock(&slot.session)))
            .await
            .map_err(|e| Status::internal(format!("reinitialization failed: {e}")))
    }

    /// Hands a frame to its session (see the module's scheduling notes),
    /// or refuses it when its stamp does not follow the session's frames
    /// ([`super::stamp`]; checked under the queue's lock, so two streams of
    /// one session cannot both pass with the same stamp).
    pub fn submit(self: &Arc<Self>, slot: Arc<Slot>, frame: FrameInput, reply: Reply) {
        slot.touch();
        let mut q = lock(&slot.queue);
        let job = Job {
            frame,
            reply,
            track: q.track,
        };
        if let Some(stamp) = job.frame.stamp
            && let Err(st) = super::stamp::follows(stamp, &q.seen(), &slot.id)
        {
            drop(q);
            self.metrics.reject("invalid_frame");
            send(job.reply, Err(st), &job.frame);
            return;
        }
        if q.busy {
            if let Some(old) = q.pending.replace(job) {
                // A frame of the track before a reinitialization is not
                // stepped whatever comes after it: answered as such, as its
                // turn would have answered it, not as dropped.
                let answer = if old.track != q.track {
                    self.metrics.reject("reinitialized");
                    reinitialized(&slot.id)
                } else {
                    slot.frames_dropped.fetch_add(1, Ordering::Relaxed);
                    self.metrics.frames_dropped.fetch_add(1, Ordering::Relaxed);
                    Status::resource_exhausted(
                        "dropped: a newer frame of this session arrived before this one ran \
                         (latest frame wins)",
                    )
                };
                if let Reply::Unary(tx, _) = old.reply {
                    let _ = tx.send(Err(answer));
                }
            }
            return;
        }
        if self.queued.load(Ordering::Relaxed) >= self.limits.max_queued {
            drop(q);
            self.metrics.reject("overload");
            let st = exhausted(
                format!(
                    "overloaded: {} steps queued on {} threads",
                    self.limits.max_queued, self.limits.threads
                ),
                self.limits.retry_after,
            );
            send(job.reply, Err(st), &job.frame);
            return;
        }
        q.busy = true;
        q.on_pool = job.frame.stamp;
        drop(q);
        self.queued.fetch_add(1, Ordering::Relaxed);
        self.spawn_step(slot, job);
    }

    fn spawn_step(self: &Arc<Self>, slot: Arc<Slot>, job: Job) {
        let state = self.clone();
        let task = move || {
            let (reply, answer, frame) = state.run_step(&slot, job);
            let mut q = lock(&slot.queue);
            let next = q.pending.take();
            if next.is_some() {
                slot.taken.send_modify(|n| *n += 1);
            }
            q.on_pool = next
                .as_ref()
                .filter(|j| j.track == q.track)
                .and_then(|j| j.frame.stamp);
            if state.shutting_down.load(Ordering::Relaxed) || next.is_none() {
                q.busy = false;
                q.on_pool = None;
                drop(q);
                state.queued.fetch_sub(1, Ordering::Relaxed);
                // The answer only once the step has left the queue: a
                // client that sends its next frame on the answer must not
                // find the queue still counting this step (a loaded host
                // showed that race as a spurious "overloaded").
                send(reply, answer, &frame);
                // A frame that waited behind the last step is not stepped
                // once shutdown began; it is told so.
                if let Some(job) = next {
                    let st = Status::unavailable("the server is shutting down");
                    send(job.reply, Err(st), &job.frame);
                }
            } else if let Some(next) = next {
                drop(q);
                send(reply, answer, &frame);
                // To the back of the pool's queue: round robin.
                state.spawn_step(slot.clone(), next);
            }
        };
        // Alone, a step gets every thread; with others waiting, one each.
        if self.queued.load(Ordering::Relaxed) <= 1 {
            self.compute.spawn_shared(task);
        } else {
            self.compute.spawn_lane(task);
        }
    }

    /// Steps the frame; returns the answer and where it goes (the caller
    /// sends it once the queue has let go of the step).
    fn run_step(
        &self,
        slot: &Slot,
        job: Job,
    ) -> (Reply, Result<proto::PoseUpdate, Status>, FrameInput) {
        let Job {
            mut frame,
            reply,
            track,
        } = job;
        if slot.closed.load(Ordering::Relaxed) {
            let st = Status::not_found(format!("session {:?} was closed", slot.id));
            return (reply, Err(st), frame);
        }
        // A frame nobody waits for, or one that waited past the deadline, is
        // not stepped (as if dropped: the next frame's odometry covers its
        // motion); on an overloaded server this keeps the pool on frames
        // whose poses are still wanted.
        let gone = match &reply {
            Reply::Unary(tx, _) => tx.is_closed(),
            Reply::Stream(tx) => tx.is_closed(),
        };
        if gone {
            if !reply.expired() {
                self.metrics.reject("abandoned");
            }
            let st = Status::cancelled("the caller had gone before the frame's turn");
            return (reply, Err(st), frame);
        }
        let waited = frame.received.elapsed();
        if waited > self.limits.deadline {
            self.metrics.reject("expired");
            let st = Status::deadline_exceeded(format!(
                "the frame waited {:.2} s for its turn, past the server's deadline of {:.2} s \
                 (--deadline-s); not stepped",
                waited.as_secs_f64(),
                self.limits.deadline.as_secs_f64()
            ));
            return (reply, Err(st), frame);
        }
        // A file's pixels are the frame's own work: decoded before the
        // session is locked.
        if let Err(e) = frame.features.decode() {
            self.metrics.reject("invalid_frame");
            return (reply, Err(status_of(&e)), frame);
        }
        let mut session = lock(&slot.session);
        // The frame's turn may come after a frame of the same stamp it was
        // let in beside (a frame sent again while its first copy ran).
        let (stepped, now_track) = {
            let q = lock(&slot.queue);
            (q.stepped, q.track)
        };
        if track != now_track {
            drop(session);
            self.metrics.reject("reinitialized");
            return (reply, Err(reinitialized(&slot.id)), frame);
        }
        let seen = Seen {
            stepped,
            ..Seen::default()
        };
        if let Some(stamp) = frame.stamp
            && let Err(st) = super::stamp::follows(stamp, &seen, &slot.id)
        {
            drop(session);
            self.metrics.reject("invalid_frame");
            return (reply, Err(st), frame);
        }
        let classes = slot.map.classes();
        let seconds = frame.seconds();
        let depth = frame.depth.as_deref();
        let result = match &frame.features {
            Features::Grid { shape, data } => {
                let k = session.config().intrinsics;
                feature_grid(k.width, k.height, *shape, data)
                    .and_then(|f| session.step(&frame.odom, seconds, &f, depth))
            }
            Features::Labels {
                width,
                height,
                labels,
            } => match classes {
                Some(t) => label_frame(*width, *height, labels, t)
                    .and_then(|f| session.step(&frame.odom, seconds, &f, depth)),
                None => Err(SessionError::BadFrame(format!(
                    "map {:?} has no class table for label images",
                    slot.map.name()
                ))),
            },
            Features::Compressed(_) => Err(SessionError::BadFrame(
                "a compressed image reached the step undecoded".into(),
            )),
            Features::Image(rgb) => {
                let k = session.config().intrinsics;
                slot.map.encode(rgb).and_then(|m| {
                    let f = crate::encode::image::EncodedFrame {
                        map: &m,
                        width: k.width,
                        height: k.height,
                    };
                    session.step(&frame.odom, seconds, &f, depth)
                })
            }
        };
        let answer = match result {
            Ok(r) => {
                if frame.stamp.is_some() {
                    lock(&slot.queue).stepped = frame.stamp;
                }
                let latency = frame.received.elapsed();
                self.metrics.observe_step(latency);
                let particles = frame.want_particles.then(|| {
                    super::convert::particle_cloud(session.particles(), &slot.frame_id, &frame)
                });
                Ok(super::convert::pose_update(
                    &r,
                    &slot.frame_id,
                    frame.stamp_msg,
                    slot.frames_dropped.load(Ordering::Relaxed),
                    latency,
                    particles,
                ))
            }
            Err(e) => {
                self.metrics.reject("invalid_frame");
                Err(status_of(&e))
            }
        };
        slot.frames.store(session.frames(), Ordering::Relaxed);
        drop(session);
        slot.touch();
        (reply, answer, frame)
    }
}

fn send(reply: Reply, answer: Result<proto::PoseUpdate, Status>, frame: &FrameInput) {
    match reply {
        Reply::Unary(tx, _) => {
            let _ = tx.send(answer);
        }
        Reply::Stream(tx) => {
            let msg = match answer {
                Ok(p) => proto::StreamResponse {
                    result: Some(proto::stream_response::Result::Pose(p)),
                },
                Err(s) => proto::StreamResponse {
                    result: Some(proto::stream_response::Result::Error(
                        super::convert::frame_error(&s, frame.stamp_msg),
                    )),
                },
            };
            // A reader slower than the stream's buffer loses answers; the
            // pool never waits for it.
            let _ = tx.try_send(Ok(msg));
        }
    }
}
