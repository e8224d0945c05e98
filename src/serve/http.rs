//! The HTTP control plane: `/healthz` and `/readyz` (no token), and with a
//! token `/metrics` (Prometheus), `/v1/maps`, `/v1/sessions` (JSON).

use std::sync::Arc;
use std::sync::atomic::Ordering;

use axum::extract::{Request, State as AxState};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};

use super::auth::{MISPLACED, Token};
use super::state::State;

#[derive(Clone)]
struct Ctx {
    state: Arc<State>,
    token: Token,
}

pub fn router(state: Arc<State>, token: Token) -> Router {
    let ctx = Ctx { state, token };
    let private = Router::new()
        .route("/metrics", get(metrics))
        .route("/v1/maps", get(maps))
        .route("/v1/sessions", get(sessions))
        .route_layer(middleware::from_fn_with_state(ctx.clone(), auth));
    Router::new()
        .route("/healthz", get(|| async { "ok\n" }))
        .route("/readyz", get(ready))
        .merge(private)
        .with_state(ctx)
}

async fn auth(AxState(ctx): AxState<Ctx>, req: Request, next: Next) -> Response {
    let h: &HeaderMap = req.headers();
    let in_query = req
        .uri()
        .query()
        .is_some_and(|q| q.split('&').any(|kv| kv.starts_with("token=")));
    let elsewhere = MISPLACED
        .iter()
        .find(|k| h.contains_key(**k))
        .map(|k| format!("header {k}"))
        .or_else(|| in_query.then(|| "the query string".to_string()));
    let value = h.get(header::AUTHORIZATION).map(|v| v.as_bytes());
    match ctx.token.check(value, elsewhere.as_deref()) {
        Ok(()) => next.run(req).await,
        Err(e) => {
            ctx.state.metrics.reject("unauthenticated");
            let mut r = (StatusCode::UNAUTHORIZED, format!("{e}\n")).into_response();
            r.headers_mut()
                .insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
            r
        }
    }
}

/// 503 with Retry-After while shutting down or while the pool's queue is
/// full; 200 otherwise.
async fn ready(AxState(ctx): AxState<Ctx>) -> Response {
    let s = &ctx.state;
    let (queued, _) = s.queue_depth();
    let why = if s.shutting_down.load(Ordering::Relaxed) {
        Some("shutting down")
    } else if queued >= s.limits.max_queued {
        Some("overloaded: the compute queue is full")
    } else {
        None
    };
    match why {
        None => (StatusCode::OK, "ready\n").into_response(),
        Some(why) => {
            let secs = s.limits.retry_after.as_secs().max(1).to_string();
            let mut r = (StatusCode::SERVICE_UNAVAILABLE, format!("{why}\n")).into_response();
            if let Ok(v) = HeaderValue::from_str(&secs) {
                r.headers_mut().insert(header::RETRY_AFTER, v);
            }
            r
        }
    }
}

async fn metrics(AxState(ctx): AxState<Ctx>) -> Response {
    let s = &ctx.state;
    let (queued, waiting) = s.queue_depth();
    let text = s.metrics.render(&[
        ("omcl_sessions", "Open sessions.", s.sessions().len() as f64),
        (
            "omcl_connections",
            "Open gRPC connections.",
            s.connections.open() as f64,
        ),
        (
            "omcl_queue_depth",
            "Steps queued or running on the compute pool.",
            queued as f64,
        ),
        (
            "omcl_frames_waiting",
            "Frames waiting behind their session's step.",
            waiting as f64,
        ),
        ("omcl_maps", "Maps served.", s.maps.len() as f64),
        (
            "omcl_compute_threads",
            "Threads of the compute pool.",
            s.limits.threads as f64,
        ),
    ]);
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response()
}

async fn maps(AxState(ctx): AxState<Ctx>) -> Response {
    let v: Vec<_> = super::map_infos(&ctx.state)
        .into_iter()
        .map(|m| {
            serde_json::json!({
                "name": m.name, "leaves": m.leaves, "feature_rows": m.feature_rows,
                "feature_dim": m.feature_dim, "resolution": m.resolution,
                "classes": m.classes, "sessions": m.sessions, "floor_plan": m.floor_plan,
            })
        })
        .collect();
    Json(serde_json::json!({ "maps": v })).into_response()
}

async fn sessions(AxState(ctx): AxState<Ctx>) -> Response {
    let v: Vec<_> = super::session_infos(&ctx.state)
        .into_iter()
        .map(|s| {
            serde_json::json!({
                "session_id": s.session_id, "map": s.map, "frames": s.frames,
                "frames_dropped": s.frames_dropped, "idle_s": s.idle_s, "method": s.method,
            })
        })
        .collect();
    Json(serde_json::json!({ "sessions": v })).into_response()
}

/// The server's TLS configuration for HTTPS from the PEM files of
/// `--tls-cert` and `--tls-key` (ring, ALPN h2 and http/1.1).
pub fn tls_config(
    tls: &super::TlsFiles,
) -> Result<std::sync::Arc<tokio_rustls::rustls::ServerConfig>, super::ServeError> {
    use rustls::pki_types::pem::Error as PemError;
    use rustls::pki_types::pem::PemObject;
    use rustls::pki_types::{CertificateDer, PrivateKeyDer};
    use tokio_rustls::rustls;
    let bad = |what: &str, e: String| super::ServeError::Tls(format!("{what}: {e}"));
    let certs = CertificateDer::pem_slice_iter(&tls.cert_pem)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| bad("--tls-cert", e.to_string()))?;
    // A swapped pair is the likely mistake: say which file holds what.
    if certs.is_empty() {
        let hint = if PrivateKeyDer::from_pem_slice(&tls.cert_pem).is_ok() {
            " (it holds a private key: is it the --tls-key file?)"
        } else {
            ""
        };
        return Err(bad(
            "--tls-cert",
            format!("the file holds no PEM certificate (BEGIN CERTIFICATE){hint}"),
        ));
    }
    let key = PrivateKeyDer::from_pem_slice(&tls.key_pem).map_err(|e| match e {
        PemError::NoItemsFound => {
            let hint = if CertificateDer::pem_slice_iter(&tls.key_pem).any(|c| c.is_ok()) {
                " (it holds a certificate: is it the --tls-cert file?)"
            } else {
                ""
            };
            bad(
                "--tls-key",
                format!("the file holds no PEM private key (BEGIN PRIVATE KEY){hint}"),
            )
        }
        e => bad("--tls-key", e.to_string()),
    })?;
    let provider = std::sync::Arc::new(rustls::crypto::ring::default_provider());
    let mut cfg = rustls::ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| bad("TLS", e.to_string()))?
        .with_no_client_auth()
        .with_single_cert(certs, key)
        .map_err(|e| bad("--tls-cert/--tls-key", e.to_string()))?;
    cfg.alpn_protocols = vec![b"h2".to_vec(), b"http/1.1".to_vec()];
    Ok(std::sync::Arc::new(cfg))
}

/// Serves `router` over TLS on `listener` until `stop` resolves: every
/// accepted connection's handshake and requests run on their own task; a
/// failed handshake (a plaintext client) closes that connection only.
pub async fn serve_https(
    listener: tokio::net::TcpListener,
    router: axum::Router,
    cfg: std::sync::Arc<tokio_rustls::rustls::ServerConfig>,
    stop: impl std::future::Future<Output = ()>,
) -> std::io::Result<()> {
    let acceptor = tokio_rustls::TlsAcceptor::from(cfg);
    tokio::pin!(stop);
    loop {
        let (tcp, _) = tokio::select! {
            _ = &mut stop => return Ok(()),
            r = listener.accept() => match r {
                Ok(c) => c,
                Err(_) => continue,
            },
        };
        let (acceptor, router) = (acceptor.clone(), router.clone());
        tokio::spawn(async move {
            let Ok(tls) = acceptor.accept(tcp).await else {
                return;
            };
            let svc = hyper_util::service::TowerToHyperService::new(router);
            let _ =
                hyper_util::server::conn::auto::Builder::new(hyper_util::rt::TokioExecutor::new())
                    .serve_connection(hyper_util::rt::TokioIo::new(tls), svc)
                    .await;
        });
    }
}
