//! `omcl serve`'s life around the calls, on loopback with the real binary:
//! deadlines.

mod serve_common;

use std::time::{Duration, Instant};

use serve_common::*;
use tonic::Code;

/// Polls `cond` every 20 ms until it holds (a hang guard of a minute, not
/// a time bound).
async fn wait_until(what: &str, mut cond: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !cond() {
        assert!(t0.elapsed() < Duration::from_secs(60), "never: {what}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// A session whose steps take seconds on any host (65,000 particles x
/// 2048 pixels, just under the default --max-rays-per-step).
async fn very_slow_session(c: &mut Client, f: &Fixture) -> String {
    let mut req = f.create(0);
    req.particles = Some(65_000);
    req.rays = Some(2048);
    c.create_session(req).await.unwrap().into_inner().session_id
}

/// A `Localize` whose step runs past `--deadline-s` is answered
/// DEADLINE_EXCEEDED, as `--help` says (tonic's own timeout answered
/// CANCELLED "Timeout expired"), and counted once as `expired`: not again
/// as `abandoned` when the step, which cannot be stopped, ends.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_step_past_the_deadline_is_deadline_exceeded_and_counted() {
    let f = Fixture::new();
    let server = Server::start(&f, &["--deadline-s", "0.2"]);
    let mut c = server.client(Auth::good()).await;
    let id = very_slow_session(&mut c, &f).await;
    let e = c.localize(f.frame(&id, 0)).await.unwrap_err();
    assert_eq!(e.code(), Code::DeadlineExceeded, "{e:?}");
    assert!(e.message().contains("--deadline-s"), "{e:?}");
    let expired = "omcl_rejected_total{reason=\"expired\"}";
    assert_eq!(server.metric(expired), "1");
    // The step goes on to its end; its answer has nowhere to go.
    wait_until("the step ended", || {
        server.metric("omcl_queue_depth") == "0" && server.metric("omcl_frames_total") == "1"
    })
    .await;
    assert_eq!(server.metric(expired), "1");
    assert_eq!(
        server.metric("omcl_rejected_total{reason=\"abandoned\"}"),
        "0"
    );
}
