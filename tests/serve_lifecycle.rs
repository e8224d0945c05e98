//! `omcl serve`'s life around the calls, on loopback with the real binary:
//! deadlines, the drain after SIGTERM (the HTTP plane stays up, a second
//! signal forces the exit), its log lines, addresses and start warnings.

mod serve_common;

use std::time::{Duration, Instant};

use omcl::serve::proto;
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

/// A sequence of 320 x 240 frames, so that a session may sample 65,536
/// pixels.
fn wide_fixture() -> Fixture {
    Fixture::sized(320, 240, 2, 2, "0.1", &[])
}

/// A session of `wide_fixture` whose steps are long (2048 particles x
/// 65,536 pixels, the default --max-rays-per-step: 0.4 s on one core of
/// the 2026 Xeon this was written on) while it starts at once (2.5 ms: its
/// cost is the particles'): with `--threads 1` its step outlasts a deadline
/// or drain timeout of 0.05 s eightfold, which its CreateSession is far
/// from.
async fn very_slow_session(c: &mut Client, f: &Fixture) -> String {
    let mut req = f.create(0);
    req.particles = Some(2048);
    req.rays = Some(65_536);
    c.create_session(req).await.unwrap().into_inner().session_id
}

/// A `Localize` whose step runs past `--deadline-s` is answered
/// DEADLINE_EXCEEDED, as `--help` says (tonic's own timeout answered
/// CANCELLED "Timeout expired"), and counted once as `expired`: not again
/// as `abandoned` when the step, which cannot be stopped, ends.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_step_past_the_deadline_is_deadline_exceeded_and_counted() {
    let f = wide_fixture();
    let server = Server::start(&f, &["--deadline-s", "0.05", "--threads", "1"]);
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

/// A `SetInitialPose` that waits for its session past `--deadline-s` (a
/// step holds the session) is answered DEADLINE_EXCEEDED and is then not
/// applied when the step lets go (it was, a moment after its answer: the
/// waiting task could not be stopped). A reinitialization resets the
/// session's stamps, so the frame stepped before it being refused again as
/// a repeat shows that none happened.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reinitialization_past_the_deadline_is_not_applied() {
    let f = wide_fixture();
    let server = Server::start(&f, &["--deadline-s", "0.05", "--threads", "1"]);
    let mut c = server.client(Auth::good()).await;
    let id = very_slow_session(&mut c, &f).await;
    let e = c.localize(f.frame(&id, 0)).await.unwrap_err();
    assert_eq!(e.code(), Code::DeadlineExceeded, "{e:?}");
    let (_, gt) = f.poses("poses.txt");
    let e = c
        .set_initial_pose(initial_pose(&id, &gt[1]))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::DeadlineExceeded, "{e:?}");
    assert!(e.message().contains("no reinitialization"), "{e:?}");
    wait_until("the step ended", || {
        server.metric("omcl_queue_depth") == "0" && server.metric("omcl_frames_total") == "1"
    })
    .await;
    // Time for a reinitialization still waiting to take the lock.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let e = c.localize(f.frame(&id, 0)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
}

/// After `SetInitialPose` the session starts a new track: a frame of the
/// old one still waiting behind the running step is not stepped on the new
/// track (ABORTED, counted `reinitialized`) or, if it took the session
/// first, was stepped before the reinitialization; either way its stamp
/// no longer orders the new track's frames, so the sequence replays from
/// its first stamp (it was refused as "earlier than the frame being
/// stepped").
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reinitialization_starts_a_track_the_old_frames_do_not_block() {
    let f = wide_fixture();
    let server = Server::start(&f, &["--threads", "1"]);
    let c = server.client(Auth::good()).await;
    let (id, running) = step_in_flight(&server, &c, &f).await;
    let waiting = {
        let (mut c, frame) = (c.clone(), f.frame(&id, 1));
        tokio::spawn(async move { c.localize(frame).await })
    };
    wait_until("the frame waiting", || {
        server.metric("omcl_frames_waiting") == "1"
    })
    .await;
    let (_, gt) = f.poses("poses.txt");
    let mut c2 = c.clone();
    c2.set_initial_pose(initial_pose(&id, &gt[0]))
        .await
        .unwrap();
    // The replay's first frame: accepted, and stepped in its turn.
    let replay = c2.localize(f.frame(&id, 0)).await;
    assert!(replay.is_ok(), "{replay:?}");
    assert!(running.await.unwrap().is_ok());
    match waiting.await.unwrap() {
        Ok(_) => {}
        Err(e) => {
            assert_eq!(e.code(), Code::Aborted, "{e:?}");
            assert!(e.message().contains("reinitialized"), "{e:?}");
            assert_eq!(
                server.metric("omcl_rejected_total{reason=\"reinitialized\"}"),
                "1"
            );
        }
    }
}

/// A session of `particles` x 2048 pixels whose first frame's step is on
/// the pool (the server's own gauge says so): its id and the pending call.
async fn step_in_flight(
    server: &Server,
    c: &Client,
    f: &Fixture,
) -> (
    String,
    tokio::task::JoinHandle<Result<tonic::Response<proto::PoseUpdate>, tonic::Status>>,
) {
    let mut c = c.clone();
    let id = very_slow_session(&mut c, f).await;
    let frame = f.frame(&id, 0);
    let call = tokio::spawn(async move { c.localize(frame).await });
    wait_until("the step on the pool", || {
        assert!(!call.is_finished(), "the step ended before it was seen");
        server.metric("omcl_queue_depth") == "1"
    })
    .await;
    (id, call)
}

fn read(p: &std::path::Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

/// The log line that says `what` (none: a panic with the whole log).
fn log_line(log: &str, what: &str) -> String {
    let line = log
        .lines()
        .find(|l| l.contains(what))
        .unwrap_or_else(|| panic!("no line with {what:?} in the log:\n{log}"));
    // Each line starts with its UTC time, 2026-11-28T08:06:02.123Z.
    let stamp = line.split(' ').next().unwrap();
    assert!(
        stamp.len() == 24 && stamp.ends_with('Z') && stamp.as_bytes()[10] == b'T',
        "{line}"
    );
    line.to_string()
}

/// After SIGTERM the HTTP plane answers until the drain ends (it was
/// closed at once): /readyz 503 with Retry-After, /healthz and /metrics
/// 200; the step in flight is answered, the process exits 0. The log has
/// one line per session opened, closed and expired, and for the shutdown
/// and the drain's end.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_http_plane_answers_through_the_drain_and_the_log_tells_it() {
    let f = wide_fixture();
    let log = f.dir.path().join("serve.log");
    let mut server = Server::start_logged(
        &f,
        &[
            "--idle-timeout-s",
            "1",
            "--drain-timeout-s",
            "600",
            "--deadline-s",
            "600",
            "--threads",
            "1",
        ],
        &log,
    );
    let mut c = server.client(Auth::good()).await;
    let a = c.create_session(f.create(0)).await.unwrap().into_inner();
    assert!(a.warnings.is_empty(), "{:?}", a.warnings);
    c.close_session(proto::CloseSessionRequest {
        session_id: a.session_id.clone(),
    })
    .await
    .unwrap();
    let b = c
        .create_session(f.create(1))
        .await
        .unwrap()
        .into_inner()
        .session_id;
    let expired = format!("session {b} expired");
    wait_until("a session idled out", || read(&log).contains(&expired)).await;

    let (_, call) = step_in_flight(&server, &c, &f).await;
    server.signal("TERM");
    // Every GET below panics if the connection is refused.
    wait_until("/readyz says 503", || server.get("/readyz", &[]).0 == 503).await;
    let head = server.get_raw("/readyz", &[]).to_ascii_lowercase();
    assert!(head.contains("\r\nretry-after: "), "{head}");
    assert!(head.contains("shutting down"), "{head}");
    assert_eq!(server.get("/healthz", &[]).0, 200);
    assert_eq!(server.metric("omcl_queue_depth"), "1");
    assert!(
        !call.is_finished(),
        "the step ended before the drain was seen"
    );
    let r = call.await.unwrap();
    assert!(r.is_ok(), "the step in flight was lost: {r:?}");
    let status = server.wait_exit(Duration::from_secs(120));
    assert!(status.success(), "{status:?}");

    let text = read(&log);
    let opened = log_line(&text, &format!("session {} opened", a.session_id));
    assert!(
        opened.contains("on map \"room\": pose start at "),
        "{opened}"
    );
    log_line(
        &text,
        &format!("session {} closed by its client", a.session_id),
    );
    log_line(&text, &expired);
    let begun = log_line(&text, "shutting down");
    assert!(begun.contains("1 step running or queued"), "{begun}");
    log_line(&text, "drain finished");
    // Nothing per frame: the lines above and the sessions' own.
    assert!(text.lines().count() <= 8, "{text}");
}

/// The gRPC plane's standard health service, without a token: SERVING
/// for the server ("") and for omcl.v1.Localization while up, NOT_FOUND
/// for another name; after SIGTERM, while the step in flight runs,
/// NOT_SERVING, to a `Check` on a new connection and to a `Watch` begun
/// before, and other calls UNAVAILABLE; the step is answered, the watch
/// ends and the process exits 0 (a watch that held the gRPC plane open
/// would keep it for the 600 s drain timeout).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grpc_health_is_serving_then_not_serving_through_the_drain() {
    use tonic_health::pb::health_check_response::ServingStatus;
    use tonic_health::pb::{HealthCheckRequest, health_client::HealthClient};
    let f = wide_fixture();
    // Steps four times very_slow_session's (8192 particles), so that the
    // checks below meet the drain with the step still running.
    let args = [
        &drain_args("600")[..],
        &["--max-rays-per-step", "1073741824"],
    ]
    .concat();
    let mut server = Server::start(&f, &args);
    let health = || async {
        let ch = tonic::transport::Channel::from_shared(format!("http://{}", server.grpc))
            .unwrap()
            .connect()
            .await
            .unwrap();
        HealthClient::new(ch)
    };
    let check = |mut h: HealthClient<tonic::transport::Channel>, service: &str| {
        let service = service.to_string();
        async move { h.check(HealthCheckRequest { service }).await }
    };
    let status = |r: Result<tonic::Response<_>, tonic::Status>| {
        let r: tonic_health::pb::HealthCheckResponse = r.unwrap().into_inner();
        r.status()
    };
    let h = health().await;
    assert_eq!(status(check(h.clone(), "").await), ServingStatus::Serving);
    let named = check(h.clone(), "omcl.v1.Localization").await;
    assert_eq!(status(named), ServingStatus::Serving);
    let e = check(h.clone(), "omcl.v1.Nothing").await.unwrap_err();
    assert_eq!(e.code(), Code::NotFound, "{e:?}");
    let mut watch = h
        .clone()
        .watch(HealthCheckRequest {
            service: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    let first = watch.message().await.unwrap().unwrap();
    assert_eq!(first.status(), ServingStatus::Serving);

    let mut c = server.client(Auth::good()).await;
    let mut req = f.create(0);
    req.particles = Some(8192);
    req.rays = Some(65_536);
    let id = c.create_session(req).await.unwrap().into_inner().session_id;
    let frame = f.frame(&id, 0);
    let call = tokio::spawn(async move { c.localize(frame).await });
    wait_until("the step on the pool", || {
        assert!(!call.is_finished(), "the step ended before it was seen");
        server.metric("omcl_queue_depth") == "1"
    })
    .await;
    server.signal("TERM");
    let t0 = Instant::now();
    loop {
        // A new connection each time, as a probe makes.
        match status(check(health().await, "").await) {
            ServingStatus::NotServing => break,
            s => assert_eq!(s, ServingStatus::Serving),
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "never NOT_SERVING");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let named = check(health().await, "omcl.v1.Localization").await;
    assert_eq!(status(named), ServingStatus::NotServing);
    let told = watch.message().await.unwrap().unwrap();
    assert_eq!(told.status(), ServingStatus::NotServing);
    let e = server
        .client(Auth::good())
        .await
        .list_maps(proto::ListMapsRequest {})
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::Unavailable, "{e:?}");
    assert!(e.message().contains("shutting down"), "{e:?}");
    assert!(
        !call.is_finished(),
        "the step ended before the drain was seen"
    );
    let r = call.await.unwrap();
    assert!(r.is_ok(), "the step in flight was lost: {r:?}");
    let end = watch.message().await;
    assert!(matches!(end, Ok(None)), "the watch did not end: {end:?}");
    let status = server.wait_exit(Duration::from_secs(120));
    assert!(status.success(), "{status:?}");
}

/// A server on one thread whose drain waits `timeout_s` and whose calls
/// never meet the deadline.
fn drain_args(timeout_s: &str) -> [&str; 6] {
    [
        "--drain-timeout-s",
        timeout_s,
        "--deadline-s",
        "600",
        "--threads",
        "1",
    ]
}

/// A `Stream` open but idle (the client sends nothing) at SIGTERM is
/// ended with UNAVAILABLE after its answers, and the drain finishes at
/// once (exit 0); it waited for the stream to the drain timeout, and then
/// logged "drain finished" and exited 0 with the call cut.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_idle_stream_is_ended_at_shutdown_and_does_not_hold_the_drain() {
    let f = wide_fixture();
    let log = f.dir.path().join("serve.log");
    let mut server = Server::start_logged(&f, &drain_args("600"), &log);
    let mut c = server.client(Auth::good()).await;
    let id = c
        .create_session(f.create(0))
        .await
        .unwrap()
        .into_inner()
        .session_id;
    let (frames, mut answers) = open_stream(&c).await;
    frames.send(f.frame(&id, 0)).await.unwrap();
    let first = answers.message().await.unwrap().unwrap();
    assert!(
        matches!(first.result, Some(proto::stream_response::Result::Pose(_))),
        "{first:?}"
    );
    let t0 = Instant::now();
    server.signal("TERM");
    let end = answers.message().await.unwrap_err();
    assert_eq!(end.code(), Code::Unavailable, "{end:?}");
    assert!(end.message().contains("shutting down"), "{end:?}");
    let status = server.wait_exit(Duration::from_secs(120));
    assert!(status.success(), "{status:?}");
    assert!(t0.elapsed() < Duration::from_secs(60), "{:?}", t0.elapsed());
    let text = read(&log);
    log_line(&text, "drain finished");
    drop(frames);
}

/// A second signal during the drain ends it at once: a non-zero exit and
/// a line saying the step was abandoned (a drain that waited for the step
/// would exit 0).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_signal_ends_the_drain_at_once() {
    let f = wide_fixture();
    let log = f.dir.path().join("serve.log");
    let mut server = Server::start_logged(&f, &drain_args("600"), &log);
    let c = server.client(Auth::good()).await;
    let (_, _call) = step_in_flight(&server, &c, &f).await;
    server.signal("TERM");
    wait_until("/readyz says 503", || server.get("/readyz", &[]).0 == 503).await;
    server.signal("INT");
    let status = server.wait_exit(Duration::from_secs(120));
    assert!(!status.success(), "{status:?}");
    let text = read(&log);
    let line = log_line(&text, "second signal");
    assert!(line.contains("1 step abandoned"), "{line}");
    assert!(text.contains("1 step(s) in flight abandoned"), "{text}");
    assert!(!text.contains("drain finished"), "{text}");
}

/// The drain timeout reached with a step running: a non-zero exit and a
/// line naming --drain-timeout-s and the step abandoned.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_drain_timeout_abandons_the_step_and_says_so() {
    let f = wide_fixture();
    let log = f.dir.path().join("serve.log");
    let mut server = Server::start_logged(&f, &drain_args("0.05"), &log);
    let c = server.client(Auth::good()).await;
    let (_, _call) = step_in_flight(&server, &c, &f).await;
    server.signal("TERM");
    let status = server.wait_exit(Duration::from_secs(120));
    assert!(!status.success(), "{status:?}");
    let text = read(&log);
    let line = log_line(&text, "drain timeout");
    assert!(line.contains("--drain-timeout-s"), "{line}");
    assert!(line.contains("1 step abandoned"), "{line}");
}

/// `omcl serve` with `args` after the map and the token: its output once
/// it has ended (it is expected to fail at start).
fn serve_fails(f: &Fixture, args: &[&str]) -> String {
    let map = format!("room={}", f.map.to_str().unwrap());
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(["serve", "--map", &map])
        .args(args)
        .env("OMCL_TOKEN", TOKEN)
        .output()
        .unwrap();
    assert!(!out.status.success(), "{out:?}");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Host names are resolved (`localhost:0` was "invalid socket address
/// syntax"); a port in use names the plane and its flag.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn addresses_take_host_names_and_a_busy_port_names_its_plane() {
    let f = Fixture::new();
    let map = format!("room={}", f.map.to_str().unwrap());
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args([
            "serve",
            "--map",
            &map,
            "--grpc",
            "localhost:0",
            "--http",
            "localhost:0",
        ])
        .env("OMCL_TOKEN", TOKEN)
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut banner = String::new();
    std::io::BufRead::read_line(
        &mut std::io::BufReader::new(child.stdout.as_mut().unwrap()),
        &mut banner,
    )
    .unwrap();
    let _ = child.kill();
    let _ = child.wait();
    assert!(banner.contains("gRPC on "), "{banner}");
    let grpc: std::net::SocketAddr = banner
        .split("gRPC on ")
        .nth(1)
        .and_then(|r| r.split(',').next())
        .unwrap()
        .parse()
        .unwrap();
    assert!(grpc.ip().is_loopback(), "{banner}");

    let server = Server::start(&f, &[]);
    let http = server.http.to_string();
    let err = serve_fails(&f, &["--grpc", "127.0.0.1:0", "--http", &http]);
    assert!(
        err.contains(&format!(
            "--http {http} (the HTTP plane): address already in use"
        )),
        "{err}"
    );
    let grpc = server.grpc.to_string();
    let err = serve_fails(&f, &["--grpc", &grpc, "--http", "127.0.0.1:0"]);
    assert!(
        err.contains(&format!(
            "--grpc {grpc} (the gRPC plane): address already in use"
        )),
        "{err}"
    );
    let err = serve_fails(&f, &["--grpc", "localhost"]);
    assert!(err.contains("expected HOST:PORT"), "{err}");
}

/// A start pose from which the camera sees nothing of the map (here far
/// outside it) is warned about in the answer, for CreateSession and
/// SetInitialPose; a good one is not. A prompt start that matches nothing
/// names the request's fields to change.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_blind_start_is_warned_and_a_failed_prompt_names_its_fields() {
    let f = Fixture::new();
    let server = Server::start(&f, &[]);
    let mut c = server.client(Auth::good()).await;
    let far = proto::PoseWithCovarianceStamped {
        header: Some(header(0.0)),
        pose: Some(proto::PoseWithCovariance {
            pose: Some(proto::Pose {
                position: Some(proto::Point {
                    x: 100.0,
                    y: 100.0,
                    z: 100.0,
                }),
                orientation: Some(proto::Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    w: 1.0,
                }),
            }),
            covariance: vec![],
        }),
    };
    let mut req = f.create(0);
    req.start = Some(proto::create_session_request::Start::InitialPose(
        far.clone(),
    ));
    let r = c.create_session(req).await.unwrap().into_inner();
    assert_eq!(r.warnings.len(), 1, "{r:?}");
    let w = &r.warnings[0];
    assert!(w.contains("at 100.00 100.00 100.00 m) 0 %"), "{w}");
    assert!(w.contains("in the map's frame"), "{w}");
    let good = c.create_session(f.create(0)).await.unwrap().into_inner();
    assert!(good.warnings.is_empty(), "{good:?}");
    let re = c
        .set_initial_pose(proto::SetInitialPoseRequest {
            session_id: good.session_id.clone(),
            pose: Some(far),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(re.warnings.len(), 1, "{re:?}");

    let mut req = f.create(0);
    req.start = Some(proto::create_session_request::Start::Prompt(
        proto::PromptStart {
            words: vec!["floor".into()],
            k: Some(1e12),
            ..Default::default()
        },
    ));
    let e = c.create_session(req).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert!(e.message().contains("PromptStart.k"), "{e:?}");
    assert!(!e.message().contains("PromptParams"), "{e:?}");
}
