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
                "classes": m.classes, "sessions": m.sessions,
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
                "frames_dropped": s.frames_dropped, "idle_s": s.idle_s,
            })
        })
        .collect();
    Json(serde_json::json!({ "sessions": v })).into_response()
}
