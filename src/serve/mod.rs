//! `omcl serve`: many cameras localized at once against maps loaded once.
//!
//! - gRPC ([`proto`], from `proto/omcl.proto`): unary calls for maps and
//!   sessions, `Localize` (one frame, one pose) and `Stream` (frames in,
//!   poses out) per session, nav2 AMCL's conventions;
//! - HTTP ([`http`]): `/healthz`, `/readyz`, `/metrics`, `/v1/maps`,
//!   `/v1/sessions`;
//! - [`health`]: `grpc.health.v1.Health` on the gRPC port, NOT_SERVING
//!   through the drain;
//! - [`state`]: sessions, the bounded compute pool, latest-frame-wins
//!   queues, caps and idle expiry;
//! - [`stamp`]: frame stamps, which move forward within a session;
//! - [`tracker`]: what a session steps, OMCL's filter or a baseline;
//! - [`auth`]: bearer tokens on every call but the health checks.
//!
//! Filter steps and initializations run on a dedicated rayon pool, never
//! on the async runtime's threads.

pub mod auth;
pub mod compute;
pub mod connections;
pub mod convert;
pub mod grpc;
pub mod health;
pub mod http;
pub mod log;
pub mod metrics;
pub mod stamp;
pub mod state;
pub mod tracker;

/// Messages and the client and server stubs generated from
/// `proto/omcl.proto`.
#[allow(clippy::all, missing_docs)]
pub mod proto {
    tonic::include_proto!("omcl.v1");
}

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use tokio::net::TcpListener;
use tokio_stream::StreamExt;
use tokio_stream::wrappers::TcpListenerStream;

use crate::session::SharedMap;

pub use auth::Token;
pub use state::DEFAULT_MAX_RAYS_PER_STEP;
pub use state::{Limits, State};

/// Errors that stop the server.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    #[error("{} {addr} ({}): {}", plane.0, plane.1, bind_reason(cause))]
    Bind {
        addr: SocketAddr,
        /// The plane's flag and name.
        plane: Plane,
        cause: std::io::Error,
    },
    #[error("TLS: {0}")]
    Tls(String),
    #[error("gRPC server: {0}")]
    Grpc(String),
    #[error("HTTP server: {0}")]
    Http(std::io::Error),
    #[error("{0}")]
    Setup(String),
}

/// A plane's flag and name, for errors.
type Plane = (&'static str, &'static str);
const GRPC_PLANE: Plane = ("--grpc", "the gRPC plane");
const HTTP_PLANE: Plane = ("--http", "the HTTP plane");

/// A bind error in words (the OS's "Address already in use (os error
/// 98)" as "address already in use").
fn bind_reason(e: &std::io::Error) -> String {
    match e.kind() {
        std::io::ErrorKind::AddrInUse => "address already in use".to_string(),
        std::io::ErrorKind::AddrNotAvailable => "address not available on this machine".to_string(),
        std::io::ErrorKind::PermissionDenied => {
            "permission denied (ports below 1024 need privileges)".to_string()
        }
        _ => e.to_string(),
    }
}

/// PEM certificate chain and private key for gRPC over TLS.
#[derive(Clone)]
pub struct TlsFiles {
    pub cert_pem: Vec<u8>,
    pub key_pem: Vec<u8>,
}

pub struct ServeConfig {
    pub grpc_addr: SocketAddr,
    pub http_addr: SocketAddr,
    pub token: Token,
    pub limits: Limits,
    pub tls: Option<TlsFiles>,
    /// How long shutdown waits for in-flight calls and steps.
    pub drain_timeout: Duration,
}

/// The addresses actually bound (port 0 picks one).
#[derive(Debug, Clone, Copy)]
pub struct Bound {
    pub grpc: SocketAddr,
    pub http: SocketAddr,
}

pub fn map_infos(state: &State) -> Vec<proto::MapInfo> {
    let sessions = state.sessions();
    state
        .maps
        .iter()
        .map(|m| proto::MapInfo {
            name: m.name().into(),
            leaves: m.map().rows().len() as u64,
            feature_rows: m.map().db().len() as u64,
            feature_dim: m.map().db().dim() as u32,
            resolution: m.map().grid().resolution,
            classes: m
                .classes()
                .map(|c| c.table().names.clone())
                .unwrap_or_default(),
            sessions: sessions.iter().filter(|s| Arc::ptr_eq(&s.map, m)).count() as u32,
            floor_plan: m.is_level(),
        })
        .collect()
}

pub fn session_infos(state: &State) -> Vec<proto::SessionInfo> {
    state
        .sessions()
        .iter()
        .map(|s| proto::SessionInfo {
            session_id: s.id.clone(),
            map: s.map.name().into(),
            frames: s.frames(),
            frames_dropped: s.frames_dropped.load(Ordering::Relaxed),
            idle_s: s.idle().as_secs_f64(),
            method: s.method.into(),
        })
        .collect()
}

/// How the drain after the stop ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Drained {
    /// Every call and step in flight finished.
    Finished,
    /// The drain timeout passed first, with `steps` still queued or
    /// running, and gRPC calls still open if `calls_open`.
    TimedOut { steps: usize, calls_open: bool },
    /// `force` (a second signal) came first, with `steps` still queued or
    /// running.
    Forced { steps: usize },
}

/// Runs the server until `shutdown` completes, then stops taking calls,
/// finishes the steps in flight (at most `drain_timeout`, or until `force`
/// completes) and returns how the drain ended. Both planes answer until
/// then: the HTTP plane's `/readyz` 503, the gRPC plane's health service
/// NOT_SERVING and its other calls UNAVAILABLE. `on_bound` is told the
/// bound addresses once both listen.
pub async fn serve(
    config: ServeConfig,
    maps: Vec<SharedMap>,
    on_bound: impl FnOnce(Bound),
    shutdown: impl Future<Output = ()> + Send + 'static,
    force: impl Future<Output = ()>,
) -> Result<Drained, ServeError> {
    let maps: Vec<Arc<SharedMap>> = maps.into_iter().map(Arc::new).collect();
    let state = State::new(maps, config.limits.clone()).map_err(ServeError::Setup)?;
    let bind = |addr: SocketAddr, plane: Plane| async move {
        TcpListener::bind(addr)
            .await
            .map_err(|cause| ServeError::Bind { addr, plane, cause })
    };
    let grpc_l = bind(config.grpc_addr, GRPC_PLANE).await?;
    let http_l = bind(config.http_addr, HTTP_PLANE).await?;
    let local = |l: &TcpListener, addr, plane| {
        l.local_addr()
            .map_err(|cause| ServeError::Bind { addr, plane, cause })
    };
    let bound = Bound {
        grpc: local(&grpc_l, config.grpc_addr, GRPC_PLANE)?,
        http: local(&http_l, config.http_addr, HTTP_PLANE)?,
    };

    let (health, health_service) = health::Health::serving().await;
    let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
    {
        let state = state.clone();
        let health = health.clone();
        let drain_s = config.drain_timeout.as_secs_f64();
        tokio::spawn(async move {
            shutdown.await;
            state.begin_shutdown();
            health.draining().await;
            let (steps, waiting) = state.queue_depth();
            log::event(format_args!(
                "shutting down: {} running or queued, {} waiting; draining for at most \
                 {drain_s} s (--drain-timeout-s; a second Ctrl-C or SIGTERM exits at once)",
                log::count(steps as u64, "step"),
                log::count(waiting as u64, "frame"),
            ));
            let _ = stop_tx.send(true);
        });
    }
    // Neither plane stops when the drain begins: a load balancer polls
    // /readyz (503 now), /metrics and the gRPC health service (NOT_SERVING
    // now) through it, and a gRPC client gets UNAVAILABLE, not a refused
    // connection. The gRPC plane stops once the steps in flight are
    // answered, the HTTP plane after the drain.
    let (grpc_stop_tx, grpc_stop_rx) = tokio::sync::watch::channel(false);
    let (http_stop_tx, http_stop_rx) = tokio::sync::watch::channel(false);
    let stopped = |mut rx: tokio::sync::watch::Receiver<bool>| async move {
        let _ = rx.wait_for(|s| *s).await;
    };

    spawn_expiry(state.clone(), config.limits.idle_timeout);

    let grpc_task = tokio::spawn(grpc_server(
        &config,
        &state,
        health_service,
        grpc_l,
        stopped(grpc_stop_rx),
    )?);
    let http_task = spawn_http(&config, &state, http_l, stopped(http_stop_rx))?;
    on_bound(bound);

    stopped(stop_rx).await;
    let drained = tokio::select! {
        r = drain(&state, config.drain_timeout, health, &grpc_stop_tx, grpc_task) => r,
        () = force => Ok(Drained::Forced { steps: in_flight(&state) }),
    };
    let _ = grpc_stop_tx.send(true);
    log::event(match drained {
        Ok(Drained::Finished) => "drain finished: every step in flight answered".to_string(),
        Ok(Drained::TimedOut { steps, calls_open }) => format!(
            "drain timeout ({} s, --drain-timeout-s) reached: {} abandoned{}",
            config.drain_timeout.as_secs_f64(),
            log::count(steps as u64, "step"),
            if calls_open {
                ", gRPC calls still open cut"
            } else {
                ""
            }
        ),
        Ok(Drained::Forced { steps }) => format!(
            "second signal: exiting at once, {} abandoned",
            log::count(steps as u64, "step")
        ),
        Err(ref e) => format!("stopped: {e}"),
    });
    if !matches!(drained, Ok(Drained::Finished)) {
        // A pool thread still running a step must never drop the last
        // reference to a map (its Embree scene would be released while the
        // process exits): the state is kept to the end.
        std::mem::forget(state.clone());
    }
    let _ = http_stop_tx.send(true);
    if http_task.is_finished()
        && let Ok(Err(e)) = http_task.await
    {
        return Err(ServeError::Http(e));
    }
    drained
}

/// Steps queued or running, and session set-ups on the pool.
fn in_flight(state: &State) -> usize {
    state.queue_depth().0.max(state.pool_running())
}

/// Expires idle sessions, checking a few times per idle timeout.
fn spawn_expiry(state: Arc<State>, idle_timeout: Duration) {
    let every = (idle_timeout / 4).clamp(Duration::from_millis(50), Duration::from_secs(5));
    tokio::spawn(async move {
        let mut t = tokio::time::interval(every);
        loop {
            t.tick().await;
            state.expire_idle();
        }
    });
}

/// HTTP/2 flow-control window of a gRPC stream, bytes (hyper's default);
/// also what a stream reader reads at most after each take (`grpc`).
const STREAM_WINDOW: u32 = 1 << 20;
/// Stream windows in a connection's window (see `grpc_server`): 16 held
/// back, and one for the connection's other calls.
const STREAM_WINDOWS_PER_CONNECTION: u32 = 17;

/// The gRPC server on `listener` (message caps, bearer tokens, TLS,
/// TCP_NODELAY, flow-control windows) with `health` beside the
/// localization service (no token), until `stop`. The server's deadline
/// is the handlers' (`grpc`): tonic's `timeout` answers CANCELLED.
fn grpc_server(
    config: &ServeConfig,
    state: &Arc<State>,
    health: tonic_health::pb::health_server::HealthServer<tonic_health::server::HealthService>,
    listener: TcpListener,
    stop: impl Future<Output = ()> + Send + 'static,
) -> Result<impl Future<Output = Result<(), tonic::transport::Error>> + Send + 'static, ServeError>
{
    let n = config.limits.max_message_bytes;
    let svc = proto::localization_server::LocalizationServer::new(grpc::Service {
        state: state.clone(),
    })
    .max_decoding_message_size(n)
    .max_encoding_message_size(n);
    let svc = tonic::service::interceptor::InterceptedService::new(
        svc,
        grpc::interceptor(state.clone(), config.token.clone()),
    );
    let mut builder = tonic::transport::Server::builder();
    if let Some(tls) = &config.tls {
        // rustls says which file is wrong; tonic only "transport error".
        http::tls_config(tls)?;
        let id = tonic::transport::Identity::from_pem(&tls.cert_pem, &tls.key_pem);
        builder = builder
            .tls_config(tonic::transport::ServerTlsConfig::new().identity(id))
            .map_err(|e| ServeError::Tls(e.to_string()))?;
    }
    // Small answers go out at once: without TCP_NODELAY, Nagle's algorithm
    // and the client's delayed ACK add about 40 ms to every pose.
    // Past --max-connections a connection is refused: served a few
    // seconds with every call answered RESOURCE_EXHAUSTED, then closed
    // (dropped at once when too many are being refused; `connections`).
    let st = state.clone();
    let incoming = TcpListenerStream::new(listener).filter_map(move |s| {
        let s = match s.and_then(|s| s.set_nodelay(true).map(|()| s)) {
            Ok(s) => s,
            Err(e) => return Some(Err(e)),
        };
        use connections::Admission;
        match st.connections.admit(s) {
            Admission::Open(c) => Some(Ok::<_, std::io::Error>(c)),
            Admission::Refused(c) => {
                st.metrics.reject("connection_cap");
                Some(Ok(c))
            }
            Admission::Dropped => {
                st.metrics.reject("connection_cap");
                None
            }
        }
    });
    // Flow control: a stream whose session has a frame waiting is not read
    // (`state`), so what its client sends next stays in the stream's
    // window, unread, and counts against the connection's window too. A
    // connection window of STREAM_WINDOWS_PER_CONNECTION stream windows
    // keeps 16 held-back streams from stalling the other calls of their
    // connection (with hyper's default, one stream's window and the
    // connection's were the same 1 MiB); unread data of a connection stays
    // below 17 MiB.
    Ok(builder
        .initial_stream_window_size(STREAM_WINDOW)
        .initial_connection_window_size(STREAM_WINDOW * STREAM_WINDOWS_PER_CONNECTION)
        .add_service(svc)
        .add_service(health)
        .serve_with_incoming_shutdown(incoming, stop))
}

/// The HTTP control plane on `listener` (HTTPS with TLS), until `stop`.
fn spawn_http(
    config: &ServeConfig,
    state: &Arc<State>,
    listener: TcpListener,
    stop: impl Future<Output = ()> + Send + 'static,
) -> Result<tokio::task::JoinHandle<std::io::Result<()>>, ServeError> {
    let router = http::router(state.clone(), config.token.clone());
    Ok(match &config.tls {
        Some(tls) => {
            let cfg = http::tls_config(tls)?;
            tokio::spawn(http::serve_https(listener, router, cfg, stop))
        }
        None => {
            let http_fut = axum::serve(listener, router).with_graceful_shutdown(stop);
            tokio::spawn(async move { http_fut.await })
        }
    })
}

/// Drain after the stop (bounded by `timeout`): the pool's steps, whose
/// answers go out while the gRPC plane still answers (new calls
/// UNAVAILABLE, `health` NOT_SERVING); then the gRPC plane's graceful stop
/// (`grpc_stop`), which waits for the calls in flight, and the pool again
/// for a step a call queued meanwhile; the gRPC server's error.
async fn drain(
    state: &State,
    timeout: Duration,
    health: health::Health,
    grpc_stop: &tokio::sync::watch::Sender<bool>,
    grpc_task: tokio::task::JoinHandle<Result<(), tonic::transport::Error>>,
) -> Result<Drained, ServeError> {
    // A timeout past what an `Instant` can hold waits for ever.
    let now = Instant::now();
    let deadline = now
        .checked_add(timeout)
        .unwrap_or_else(|| now + Duration::from_secs(1 << 40));
    let left = || deadline.saturating_duration_since(Instant::now());
    if let Some(timed_out) = pool_idle(state, deadline).await {
        return Ok(timed_out);
    }
    let _ = grpc_stop.send(true);
    // Watch calls end (the graceful stop would wait for them). The stop
    // is only signalled above, not yet sent as GOAWAY: a Check on an open
    // connection in between is answered NOT_FOUND, which a probe takes
    // as not serving too.
    health.stop().await;
    let grpc_res = tokio::time::timeout(left(), grpc_task).await;
    if let Some(timed_out) = pool_idle(state, deadline).await {
        return Ok(timed_out);
    }
    if grpc_res.is_err() {
        // Calls still open at the timeout (a client's call that does not
        // end): cut, which is no clean drain.
        return Ok(Drained::TimedOut {
            steps: in_flight(state),
            calls_open: true,
        });
    }
    if let Ok(Ok(Err(e))) = grpc_res {
        return Err(ServeError::Grpc(e.to_string()));
    }
    Ok(Drained::Finished)
}

/// Waits until every pool task has finished and dropped what it held (the
/// last reference to a map may be a step's, and the process must not exit
/// while a pool thread releases its Embree scene): `None`, or the time out
/// at `deadline` with the steps left.
async fn pool_idle(state: &State, deadline: Instant) -> Option<Drained> {
    while state.queue_depth().0 > 0 || state.pool_running() > 0 {
        if Instant::now() >= deadline {
            return Some(Drained::TimedOut {
                steps: in_flight(state),
                calls_open: false,
            });
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    None
}
