//! `omcl serve` end to end on loopback: the real binary, a Rust client.
//! Same trajectories as `omcl localize`; tokens; malformed input answered
//! with named errors while the session lives on; caps, overload, idle
//! expiry and graceful shutdown.

mod serve_common;

use std::time::{Duration, Instant};

use serve_common::*;
use tonic::Code;

use omcl::serve::proto;

fn s(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}

/// `got` equals `want` in its first `n` entries to 1e-9 (frame `i`).
fn assert_close(got: &[f64; 7], want: &[f64; 7], n: usize, i: usize) {
    for k in 0..n {
        assert!(
            (got[k] - want[k]).abs() < 1e-9,
            "frame {i}: server {got:?}, CLI {want:?}"
        );
    }
}

/// Sends the fixture's frames to `session` one by one and checks each
/// answer's pose against the CLI's, to 1e-9.
async fn assert_session_gives(c: &mut Client, f: &Fixture, session: &str, cli: &[[f64; 7]]) {
    for (i, want) in cli.iter().enumerate() {
        let u = c.localize(f.frame(session, i)).await.unwrap().into_inner();
        assert_close(&pose_of(&u), want, 7, i);
    }
}

/// `omcl localize` on the fixture with the sessions' particles, rays and
/// frames, seed `seed` and `extra` options: its trajectory.
fn cli_localize(f: &Fixture, seed: u64, extra: &[&str]) -> Vec<[f64; 7]> {
    let out = f
        .dir
        .path()
        .join(format!("est{seed}{}.txt", extra.join("")));
    let (particles, rays, seed_s, frames) = (
        PARTICLES.to_string(),
        RAYS.to_string(),
        seed.to_string(),
        FRAMES.to_string(),
    );
    let args = [
        "localize",
        "--map",
        s(&f.map),
        "--sequence",
        s(&f.seq),
        "-o",
        s(&out),
        "--particles",
        &particles,
        "--rays",
        &rays,
        "--seed",
        &seed_s,
        "--frames",
        &frames,
    ];
    let r = omcl(&[&args[..], extra].concat());
    assert!(r.status.success(), "{r:?}");
    read_tum(&out)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_sessions_give_the_trajectories_of_two_cli_runs() {
    let f = Fixture::new();
    // The CLI, seeds 3 and 4 (4 with two-pass likelihoods).
    let cli = [
        cli_localize(&f, 3, &[]),
        cli_localize(&f, 4, &["--early-reject"]),
    ];
    assert_ne!(cli[0], cli[1], "seeds 3 and 4 should differ");

    let server = Server::start(&f, &[]);
    let mut c = server.client(Auth::good()).await;
    let a = c.create_session(f.create(3)).await.unwrap().into_inner();
    let b = c
        .create_session(proto::CreateSessionRequest {
            early_reject: true,
            ..f.create(4)
        })
        .await
        .unwrap()
        .into_inner();
    // Session a through unary calls, session b through a stream, frame by
    // frame side by side.
    let (tx, mut answers) = open_stream(&c).await;
    let (mut got_a, mut got_b) = (Vec::new(), Vec::new());
    for i in 0..FRAMES {
        tx.send(f.frame(&b.session_id, i)).await.unwrap();
        let ua = c
            .localize(f.frame(&a.session_id, i))
            .await
            .unwrap()
            .into_inner();
        let ub = match answers.message().await.unwrap().unwrap().result.unwrap() {
            proto::stream_response::Result::Pose(p) => p,
            proto::stream_response::Result::Error(e) => panic!("frame {i}: {e:?}"),
        };
        assert_eq!((ua.frame, ub.frame), (i as u64 + 1, i as u64 + 1));
        assert_eq!(ub.frames_dropped, 0);
        let cov = &ua.pose.as_ref().unwrap().pose.as_ref().unwrap().covariance;
        assert_eq!(cov.len(), 36);
        assert!(cov[0] >= 0.0 && cov[7] >= 0.0 && cov[35] >= 0.0, "{cov:?}");
        assert!((0.0..=1.0).contains(&ua.confidence));
        assert_eq!(
            ua.pose.as_ref().unwrap().header.as_ref().unwrap().frame_id,
            "map"
        );
        got_a.push(pose_of(&ua));
        got_b.push(pose_of(&ub));
    }
    for (name, got, want) in [("a", &got_a, &cli[0]), ("b", &got_b, &cli[1])] {
        assert_eq!(got.len(), want.len());
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            for k in 0..7 {
                assert!(
                    (g[k] - w[k]).abs() < 1e-9,
                    "session {name} frame {i}: server {g:?}, CLI {w:?}"
                );
            }
        }
    }
    let list = c
        .list_sessions(proto::ListSessionsRequest {})
        .await
        .unwrap()
        .into_inner();
    assert_eq!(list.sessions.len(), 2);
    assert!(list.sessions.iter().all(|s| s.frames == FRAMES as u64));
    let closed = c
        .close_session(proto::CloseSessionRequest {
            session_id: a.session_id.clone(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(closed.frames, FRAMES as u64);
    let e = c.localize(f.frame(&a.session_id, 0)).await.unwrap_err();
    assert_eq!(e.code(), Code::NotFound, "{e:?}");
    // The particle cloud on request.
    let mut fr = f.frame(&b.session_id, FRAMES);
    fr.want_particles = true;
    let u = c.localize(fr).await.unwrap().into_inner();
    let cloud = u.particles.unwrap();
    assert_eq!(cloud.particles.len(), PARTICLES as usize);
    let w: f64 = cloud.particles.iter().map(|p| p.weight).sum();
    assert!((w - 1.0).abs() < 1e-9, "weights sum to {w}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn calls_without_the_right_token_get_nothing() {
    let f = Fixture::new();
    let server = Server::start(&f, &[]);
    let cases = [
        (Auth(None), "missing credentials"),
        (
            Auth::bearer("wrong-token-0123456789abcdef"),
            "invalid token",
        ),
        (Auth(Some(("authorization", TOKEN.to_string()))), "Bearer"),
        (Auth(Some(("x-api-key", TOKEN.to_string()))), "wrong place"),
    ];
    for (auth, needle) in cases {
        let mut c = server.client(auth.clone()).await;
        let e = c
            .list_maps(proto::ListMapsRequest {})
            .await
            .expect_err("refused");
        assert_eq!(e.code(), Code::Unauthenticated, "{e:?}");
        assert!(e.message().contains(needle), "{needle:?} not in {e:?}");
        assert!(!e.message().contains("room"), "leaks the map's name: {e:?}");
        let e = c.create_session(f.create(0)).await.unwrap_err();
        assert_eq!(e.code(), Code::Unauthenticated);
        let e = c.localize(f.frame("s1", 0)).await.unwrap_err();
        assert_eq!(e.code(), Code::Unauthenticated);
    }
    let mut c = server.client(Auth::good()).await;
    let maps = c
        .list_maps(proto::ListMapsRequest {})
        .await
        .unwrap()
        .into_inner()
        .maps;
    assert_eq!(maps.len(), 1);
    assert_eq!(maps[0].name, "room");
    assert!(maps[0].classes.iter().any(|c| c == "floor"));

    // HTTP: health without a token; the rest only with it, in its place.
    assert_eq!(server.get("/healthz", &[]).0, 200);
    assert_eq!(server.get("/readyz", &[]).0, 200);
    let bearer = format!("Bearer {TOKEN}");
    for path in ["/metrics", "/v1/maps", "/v1/sessions"] {
        let (code, body) = server.get(path, &[]);
        assert_eq!(code, 401, "{path}: {body}");
        assert!(!body.contains("room"), "{path} leaks: {body}");
        let (code, body) = server.get(&format!("{path}?token={TOKEN}"), &[]);
        assert_eq!(code, 401, "{path}: {body}");
        assert!(body.contains("query string"), "{path}: {body}");
        let (code, _) = server.get(path, &[("Authorization", "Bearer nope-nope-nope-nope")]);
        assert_eq!(code, 401, "{path}");
        let (code, body) = server.get(path, &[("Authorization", &bearer)]);
        assert_eq!(code, 200, "{path}: {body}");
    }
    let (_, maps) = server.get("/v1/maps", &[("Authorization", &bearer)]);
    assert!(maps.contains("\"room\""), "{maps}");
    let (_, metrics) = server.get("/metrics", &[("Authorization", &bearer)]);
    assert!(
        metrics.contains("omcl_rejected_total{reason=\"unauthenticated\"}"),
        "{metrics}"
    );
    assert!(!metrics.contains("omcl_rejected_total{reason=\"unauthenticated\"} 0"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_input_is_named_and_the_session_lives_on() {
    let f = Fixture::new();
    let server = Server::start(&f, &[]);
    let mut c = server.client(Auth::good()).await;
    let id = c
        .create_session(f.create(0))
        .await
        .unwrap()
        .into_inner()
        .session_id;
    let k = f.intrinsics();
    let grid = |h: u32, w: u32, dim: u32, n: usize| {
        proto::frame::Features::Grid(proto::FeatureGrid {
            height: h,
            width: w,
            dim,
            data: vec![0.1; n],
        })
    };
    let mut cases: Vec<(proto::Frame, Code, &str)> = Vec::new();
    let mut fr = f.frame(&id, 0);
    fr.features = Some(grid(4, 4, 512, 4 * 4 * 512 - 1));
    cases.push((fr, Code::InvalidArgument, "needs 8192 values, got 8191"));
    let mut fr = f.frame(&id, 0);
    fr.features = Some(grid(4, 4, 7, 4 * 4 * 7));
    cases.push((fr, Code::InvalidArgument, "feature dimension 7"));
    let mut fr = f.frame(&id, 0);
    fr.features = Some(proto::frame::Features::Labels(proto::LabelImage {
        width: k.width + 1,
        height: k.height,
        labels: vec![0; (k.width as usize + 1) * k.height as usize],
    }));
    cases.push((fr, Code::InvalidArgument, "label image is 65x48"));
    let mut fr = f.frame(&id, 0);
    if let Some(proto::frame::Features::Labels(l)) = &mut fr.features {
        l.labels.pop();
    }
    cases.push((fr, Code::InvalidArgument, "needs 3072 labels, got 3071"));
    let mut fr = f.frame(&id, 0);
    fr.odometry.as_mut().unwrap().position.as_mut().unwrap().x = f64::NAN;
    cases.push((fr, Code::InvalidArgument, "odometry is not finite"));
    let mut fr = f.frame(&id, 0);
    fr.odometry
        .as_mut()
        .unwrap()
        .orientation
        .as_mut()
        .unwrap()
        .w = 3.0;
    cases.push((fr, Code::InvalidArgument, "not a unit quaternion"));
    let mut fr = f.frame(&id, 0);
    fr.features = None;
    cases.push((fr, Code::InvalidArgument, "without features"));
    // A grid of zero vectors: every cosine 0, no evidence for the filter.
    let mut fr = f.frame(&id, 0);
    fr.features = Some(proto::frame::Features::Grid(proto::FeatureGrid {
        height: 4,
        width: 4,
        dim: 512,
        data: vec![0.0; 4 * 4 * 512],
    }));
    cases.push((
        fr,
        Code::InvalidArgument,
        "feature grid of 4x4x512 is all zero: none of its 16 cells",
    ));
    let mut fr = f.frame(&id, 0);
    let mut data = vec![0.1; 4 * 4 * 512];
    data[(4 + 3) * 512 + 7] = f32::NAN;
    fr.features = Some(proto::frame::Features::Grid(proto::FeatureGrid {
        height: 4,
        width: 4,
        dim: 512,
        data,
    }));
    cases.push((
        fr,
        Code::InvalidArgument,
        "feature grid value 3591 (row 1, column 3, feature 7) is not finite: NaN",
    ));
    cases.push((
        f.frame("no-such-session", 0),
        Code::NotFound,
        "unknown session \"no-such-session\"",
    ));
    for (fr, code, needle) in cases.clone() {
        let e = c.localize(fr).await.unwrap_err();
        assert_eq!(e.code(), code, "{e:?}");
        assert!(e.message().contains(needle), "{needle:?} not in {e:?}");
    }
    // The session lives on: the good frames still step, from frame 1.
    for i in 0..3 {
        let u = c.localize(f.frame(&id, i)).await.unwrap().into_inner();
        assert_eq!(u.frame, i as u64 + 1);
    }
    // Odometry that jumps a thousand kilometres between two frames (a
    // glitch) is refused, not stepped (the estimate went 600 km away at
    // full confidence); the next frame steps from the last good one.
    let mut fr = f.frame(&id, 3);
    fr.odometry.as_mut().unwrap().position.as_mut().unwrap().x += 1e6;
    let e = c.localize(fr).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(e.message().contains("a jump, not motion"), "{e:?}");
    // In a stream the errors come in the stream, which goes on.
    let (tx, mut answers) = open_stream(&c).await;
    for (fr, code, needle) in cases {
        tx.send(fr).await.unwrap();
        match answers.message().await.unwrap().unwrap().result.unwrap() {
            proto::stream_response::Result::Error(e) => {
                let want = omcl::serve::convert::code_name(code);
                assert_eq!(e.code, want, "{e:?}");
                assert!(e.message.contains(needle), "{needle:?} not in {e:?}");
            }
            other => panic!("expected an error, got {other:?}"),
        }
    }
    tx.send(f.frame(&id, 3)).await.unwrap();
    match answers.message().await.unwrap().unwrap().result.unwrap() {
        proto::stream_response::Result::Pose(p) => assert_eq!(p.frame, 4),
        other => panic!("expected a pose, got {other:?}"),
    }

    // Bad sessions requests.
    let mut r = f.create(0);
    r.map = "atlantis".into();
    let e = c.create_session(r).await.unwrap_err();
    assert_eq!(e.code(), Code::NotFound);
    assert!(e.message().contains("unknown map \"atlantis\""), "{e:?}");
    let mut r = f.create(0);
    r.camera.as_mut().unwrap().fx = f64::NAN;
    let e = c.create_session(r).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert!(e.message().contains("camera"), "{e:?}");
    let mut r = f.create(0);
    r.start = Some(proto::create_session_request::Start::Prompt(
        proto::PromptStart {
            words: vec!["unicorn".into()],
            ..Default::default()
        },
    ));
    let e = c.create_session(r).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert!(e.message().contains("\"unicorn\""), "{e:?}");
    // Global localization and a new initial pose on the live session.
    c.global_localization(proto::GlobalLocalizationRequest {
        session_id: id.clone(),
        prompt: None,
    })
    .await
    .unwrap();
    let u = c.localize(f.frame(&id, 4)).await.unwrap().into_inner();
    assert_eq!(u.frame, 5, "{u:?}");
    let (_, gt) = f.poses("poses.txt");
    c.set_initial_pose(initial_pose(&id, &gt[5])).await.unwrap();
    let u = c.localize(f.frame(&id, 5)).await.unwrap().into_inner();
    let p = pose_of(&u);
    let t = gt[5].translation.vector;
    let d = ((p[0] - t.x).powi(2) + (p[1] - t.y).powi(2)).sqrt();
    assert!(d < 0.6, "{d} m from the pose given");
    // Zero cells beside others (a mask, padding) are stepped: only a grid
    // with no direction anywhere is refused.
    let mut fr = f.frame(&id, 6);
    let mut data = vec![0.0; 4 * 4 * 512];
    data[..512].fill(0.1);
    fr.features = Some(proto::frame::Features::Grid(proto::FeatureGrid {
        height: 4,
        width: 4,
        dim: 512,
        data,
    }));
    assert_eq!(c.localize(fr).await.unwrap().into_inner().frame, 7);
}

/// Fixture frame `i`'s stamp as the server writes it.
fn stamp_text(f: &Fixture, i: usize) -> String {
    let (stamps, _) = f.poses("poses.txt");
    let msg = header(stamps[i]).stamp.unwrap();
    omcl::serve::stamp::Stamp::from_msg(&msg)
        .unwrap()
        .to_string()
}

/// The next answer of a stream within two minutes (a hang guard).
async fn next_answer(
    answers: &mut tonic::Streaming<proto::StreamResponse>,
) -> proto::stream_response::Result {
    tokio::time::timeout(Duration::from_secs(120), answers.message())
        .await
        .expect("an answer within 2 minutes")
        .unwrap()
        .unwrap()
        .result
        .unwrap()
}

/// A session's stamps move forward. A frame stamped earlier than the last
/// frame stepped, or the same, is INVALID_ARGUMENT naming both stamps and
/// the session (in a stream, in the stream, which goes on) and is not
/// stepped; a frame refused may come again; a frame earlier than the one
/// waiting behind a step is refused instead of replacing it, and one sent
/// again while its first copy steps is refused at its turn; a stamp of
/// 10^9 nanoseconds is refused; a frame without a stamp is not ordered;
/// a reinitialization starts the stamps afresh.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stamps_move_forward_within_a_session() {
    use proto::stream_response::Result::{Error, Pose};
    let f = Fixture::new();
    let server = Server::start(&f, &[]);
    let mut c = server.client(Auth::good()).await;
    let t = |i: usize| stamp_text(&f, i);
    let id = c
        .create_session(f.create(0))
        .await
        .unwrap()
        .into_inner()
        .session_id;
    assert_eq!(
        c.localize(f.frame(&id, 2))
            .await
            .unwrap()
            .into_inner()
            .frame,
        1
    );
    let e = c.localize(f.frame(&id, 1)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    let want = format!(
        "session {id:?}: frame stamped {} is earlier than {}, the stamp of the last frame stepped",
        t(1),
        t(2)
    );
    assert!(e.message().contains(&want), "{want:?} not in {e:?}");
    let e = c.localize(f.frame(&id, 2)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    let want = format!("frame stamped {} repeats {}", t(2), t(2));
    assert!(e.message().contains(&want), "{want:?} not in {e:?}");

    let (tx, mut answers) = open_stream(&c).await;
    tx.send(f.frame(&id, 0)).await.unwrap();
    match next_answer(&mut answers).await {
        Error(e) => {
            assert_eq!(e.code, "INVALID_ARGUMENT", "{e:?}");
            let want = format!("frame stamped {} is earlier than {}", t(0), t(2));
            assert!(e.message.contains(&want), "{want:?} not in {e:?}");
        }
        other => panic!("a frame from the past was stepped: {other:?}"),
    }
    tx.send(f.frame(&id, 3)).await.unwrap();
    match next_answer(&mut answers).await {
        // The refused frames were not stepped.
        Pose(p) => assert_eq!(p.frame, 2, "{p:?}"),
        other => panic!("expected a pose, got {other:?}"),
    }

    let mut fr = f.frame(&id, 4);
    fr.header.as_mut().unwrap().stamp.as_mut().unwrap().nanosec = 1_000_000_000;
    let e = c.localize(fr).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(e.message().contains("nanosec 1000000000"), "{e:?}");
    // Without a stamp: stepped, and the order stays frame 3's.
    let mut fr = f.frame(&id, 4);
    fr.header = None;
    assert_eq!(c.localize(fr).await.unwrap().into_inner().frame, 3);
    let e = c.localize(f.frame(&id, 3)).await.unwrap_err();
    assert!(e.message().contains("repeats"), "{e:?}");
    // A new initial pose starts a new track, at any stamp.
    let Some(proto::create_session_request::Start::InitialPose(start)) = f.create(0).start else {
        unreachable!("the fixture starts from a pose")
    };
    c.set_initial_pose(proto::SetInitialPoseRequest {
        session_id: id.clone(),
        pose: Some(start),
    })
    .await
    .unwrap();
    assert_eq!(
        c.localize(f.frame(&id, 0))
            .await
            .unwrap()
            .into_inner()
            .frame,
        4
    );

    // Frame 0 steps (a second or more), frame 5 waits behind it: frame 4,
    // older, is refused rather than taking frame 5's place.
    let slow = slow_session(&mut c, &f).await;
    let (tx, mut answers) = open_stream(&c).await;
    tx.send(f.frame(&slow, 0)).await.unwrap();
    tx.send(f.frame(&slow, 5)).await.unwrap();
    let t0 = Instant::now();
    while server.metric("omcl_frames_waiting") != "1" {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "frame 5 never waited"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let e = c.localize(f.frame(&slow, 4)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    let want = format!("frame stamped {} is earlier than {}", t(4), t(5));
    assert!(e.message().contains(&want), "{want:?} not in {e:?}");
    for (n, i) in [(1, 0), (2, 5)] {
        match next_answer(&mut answers).await {
            Pose(p) => {
                assert_eq!((p.frame, p.frames_dropped), (n, 0), "{p:?}");
                let stamp = p.pose.unwrap().header.unwrap().stamp;
                assert_eq!(stamp, f.frame(&slow, i).header.unwrap().stamp);
            }
            other => panic!("frame {i}: expected a pose, got {other:?}"),
        }
    }
    // Frame 6 sent again while its first copy steps: let in beside it, and
    // refused at its turn, once the first has been stepped.
    tx.send(f.frame(&slow, 6)).await.unwrap();
    let t0 = Instant::now();
    while server.metric("omcl_queue_depth") != "1" {
        assert!(t0.elapsed() < Duration::from_secs(60), "frame 6 never ran");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let e = c.localize(f.frame(&slow, 6)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    let want = format!("frame stamped {} repeats {}", t(6), t(6));
    assert!(e.message().contains(&want), "{want:?} not in {e:?}");
    match next_answer(&mut answers).await {
        Pose(p) => assert_eq!(p.frame, 3, "{p:?}"),
        other => panic!("frame 6: expected a pose, got {other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn caps_overload_idle_expiry_and_shutdown() {
    let f = Fixture::new();
    let server = Server::start(
        &f,
        &[
            "--max-sessions",
            "2",
            "--max-queued",
            "1",
            "--idle-timeout-s",
            "1.0",
            "--threads",
            "1",
            "--max-message-mib",
            "1",
        ],
    );
    let mut c = server.client(Auth::good()).await;
    // Slow steps (many particles), so that a second session's frame finds
    // the queue full.
    let mut big = f.create(0);
    big.particles = Some(20_000);
    big.rays = Some(2048);
    let a = c.create_session(big).await.unwrap().into_inner().session_id;
    let b = c
        .create_session(f.create(1))
        .await
        .unwrap()
        .into_inner()
        .session_id;
    let e = c.create_session(f.create(2)).await.unwrap_err();
    assert_eq!(e.code(), Code::ResourceExhausted);
    assert!(e.message().contains("session cap"), "{e:?}");
    assert!(e.metadata().get("retry-after-ms").is_some(), "{e:?}");

    let mut exhausted = None;
    for i in 0..16 {
        let mut ca = c.clone();
        let fa = f.frame(&a, i);
        let slow = tokio::spawn(async move { ca.localize(fa).await });
        tokio::time::sleep(Duration::from_millis(5)).await;
        let r = c.localize(f.frame(&b, i)).await;
        slow.await.unwrap().unwrap();
        if let Err(e) = r {
            exhausted = Some((i, e));
            break;
        }
    }
    // b's frames go on from the one refused (b's stamps must increase;
    // the refused frame was not stepped, so it may come again).
    let (next, e) = exhausted.expect("a frame behind a full queue is refused");
    assert_eq!(e.code(), Code::ResourceExhausted, "{e:?}");
    assert!(e.message().contains("overloaded"), "{e:?}");
    assert!(e.metadata().get("retry-after-ms").is_some(), "{e:?}");

    // A message over the size limit (1 MiB) is refused, the session lives.
    let mut fr = f.frame(&b, next);
    fr.features = Some(proto::frame::Features::Grid(proto::FeatureGrid {
        height: 24,
        width: 32,
        dim: 512,
        data: vec![0.5; 24 * 32 * 512],
    }));
    let e = c.localize(fr.clone()).await.unwrap_err();
    assert_eq!(e.code(), Code::OutOfRange, "{e:?}");
    c.localize(f.frame(&b, next)).await.unwrap();
    // In a stream, the stream ends with that status, not with OK and the
    // frames after it silently unread.
    let frames = vec![
        f.frame(&b, next + 1),
        fr,
        f.frame(&b, next + 2),
        f.frame(&b, next + 3),
    ];
    let mut answers = c
        .stream(tokio_stream::iter(frames))
        .await
        .unwrap()
        .into_inner();
    let mut poses = 0;
    let end = loop {
        match answers.message().await {
            Ok(Some(_)) => poses += 1,
            Ok(None) => break None,
            Err(e) => break Some(e),
        }
    };
    let e = end.expect("the stream ended with OK after an oversized frame");
    // The frame before it was answered first.
    assert_eq!(poses, 1, "{e:?}");
    assert_eq!(e.code(), Code::OutOfRange, "{e:?}");
    assert!(e.message().contains("too large"), "{e:?}");
    // The option that sets the limit is named, with its value.
    assert!(e.message().contains("--max-message-mib is 1"), "{e:?}");
    c.localize(f.frame(&b, next + 4)).await.unwrap();
    // A session whose step would cast more rays than --max-rays-per-step
    // (here 2^27) is refused up front: a running step cannot be stopped.
    let mut huge = f.create(0);
    huge.particles = Some(1_000_000);
    huge.rays = Some(1_000_000);
    let e = c.create_session(huge).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(e.message().contains("--max-rays-per-step"), "{e:?}");

    // Idle sessions expire (1 s): wait until the server says none is open
    // (a hang guard of a minute, not a time bound).
    let bearer = format!("Bearer {TOKEN}");
    let t0 = Instant::now();
    let metrics = loop {
        let (_, metrics) = server.get("/metrics", &[("Authorization", &bearer)]);
        if metrics.contains("omcl_sessions 0") {
            break metrics;
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "{metrics}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    let e = c.localize(f.frame(&a, 0)).await.unwrap_err();
    assert_eq!(e.code(), Code::NotFound, "{e:?}");
    assert!(e.message().contains("--idle-timeout-s"), "{e:?}");
    assert!(
        metrics.contains("omcl_sessions_expired_total 2"),
        "{metrics}"
    );
    let e = c.localize(f.frame("s999-00000000", 0)).await.unwrap_err();
    assert!(e.message().contains("unknown session"), "{e:?}");

    // Closing a session whose long step runs answers at once (it waited
    // for the step, and a shutdown waited for the close): the close
    // returns while the step's call is still pending.
    let (long, stepping) = step_in_flight(&server, &c, &f, 30_000).await;
    c.close_session(proto::CloseSessionRequest {
        session_id: long.clone(),
    })
    .await
    .unwrap();
    assert!(
        !stepping.is_finished(),
        "the close waited for the step to end"
    );
    // The gauge counts a step from its submission: on a loaded host the
    // close can come before the pool's thread has begun it, and the frame
    // is then answered NOT_FOUND at its turn, as CloseSession says.
    match stepping.await.unwrap() {
        Ok(_) => {}
        Err(e) => assert!(
            e.code() == Code::NotFound && e.message().contains("was closed"),
            "{e:?}"
        ),
    }

    // Graceful shutdown: a step in flight is answered, then the process
    // exits by itself with status 0.
    // SIGTERM once the step is on the pool (the server's own gauge), so
    // the in-flight path is the one tested.
    let (_, inflight) = step_in_flight(&server, &c, &f, 20_000).await;
    let mut server = server;
    unsafe_free_sigterm(server.pid());
    let r = inflight.await.unwrap();
    assert!(r.is_ok(), "the step in flight was lost: {r:?}");
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = server.child.try_wait().unwrap() {
            break s;
        }
        // A hang guard, not a time bound.
        assert!(t0.elapsed() < Duration::from_secs(60), "still running");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "{status:?}");
}

/// A session of `particles` whose first frame's step is on the pool (the
/// server's own gauge says so): its id and the pending call.
async fn step_in_flight(
    server: &Server,
    c: &Client,
    f: &Fixture,
    particles: u32,
) -> (
    String,
    tokio::task::JoinHandle<Result<tonic::Response<proto::PoseUpdate>, tonic::Status>>,
) {
    let mut req = f.create(0);
    req.particles = Some(particles);
    let mut c = c.clone();
    let id = c.create_session(req).await.unwrap().into_inner().session_id;
    let frame = f.frame(&id, 0);
    let call = tokio::spawn(async move { c.localize(frame).await });
    let bearer = format!("Bearer {TOKEN}");
    let t0 = Instant::now();
    loop {
        let (_, metrics) = server.get("/metrics", &[("Authorization", &bearer)]);
        if metrics.contains("omcl_queue_depth 1") {
            return (id, call);
        }
        assert!(
            !call.is_finished(),
            "the step finished before it was seen in flight"
        );
        assert!(t0.elapsed() < Duration::from_secs(60), "{metrics}");
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
}

/// SIGTERM by the `kill` command (no `unsafe` outside the Embree module).
fn unsafe_free_sigterm(pid: u32) {
    let st = std::process::Command::new("kill")
        .args(["-TERM", &pid.to_string()])
        .status()
        .unwrap();
    assert!(st.success());
}

/// Raw RGB frames go through the map's image encoder on the server: the
/// same poses as `omcl localize --image-model` on the same images, sent
/// as pixels or as the PNG files' bytes; a wrong-size, truncated or
/// foreign image is INVALID_ARGUMENT and the session lives on; a map
/// served without an encoder refuses camera images.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn camera_images_are_encoded_on_the_server_as_localize_encodes_them() {
    let f = Fixture::new();
    let Images {
        map: img_map,
        model,
        cli,
        ..
    } = f.images(3, FRAMES);
    let img_arg = format!("img={}", s(&img_map));
    let model_arg = format!("img={}", s(&model));
    let server = Server::start(&f, &["--map", &img_arg, "--image-model", &model_arg]);
    let mut c = server.client(Auth::good()).await;
    let mut req = f.create(3);
    req.map = "img".into();
    let sid = c.create_session(req).await.unwrap().into_inner().session_id;
    let rgb_frame = |i: usize| {
        let mut fr = f.frame(&sid, i);
        let img = omcl::io::rgb::read_rgb(&f.seq.join(format!("rgb/{i:06}.png"))).unwrap();
        fr.features = Some(proto::frame::Features::Image(proto::RgbImage {
            width: img.width(),
            height: img.height(),
            rgb: img.into_raw(),
        }));
        fr
    };
    // A truncated image first: refused, the session unchanged.
    let mut bad = rgb_frame(0);
    if let Some(proto::frame::Features::Image(img)) = &mut bad.features {
        img.rgb.truncate(10);
    }
    let e = c.localize(bad).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(e.message().contains("bytes"), "{e:?}");
    for (i, want) in cli.iter().enumerate() {
        let u = c.localize(rgb_frame(i)).await.unwrap().into_inner();
        assert_eq!(u.frame, i as u64 + 1);
        assert_close(&pose_of(&u), want, 7, i);
    }
    // The same frames as the PNG files' bytes (a camera driver's
    // CompressedImage): the same poses, in a second session.
    let mut req = f.create(3);
    req.map = "img".into();
    let sid2 = c.create_session(req).await.unwrap().into_inner().session_id;
    let file_frame = |i: usize, data: Vec<u8>| {
        let mut fr = f.frame(&sid2, i);
        fr.features = Some(proto::frame::Features::Compressed(proto::CompressedImage {
            format: "png".into(),
            data,
        }));
        fr
    };
    let png = |i: usize| std::fs::read(f.seq.join(format!("rgb/{i:06}.png"))).unwrap();
    // Hostile files first, each named, the session unchanged: not an
    // image, a truncated JPEG (caught by its header's reader), a JPEG of
    // another size, and a PNG whose pixels are cut (caught when stepped).
    let jpeg = |w: u32, h: u32| {
        let mut out = std::io::Cursor::new(Vec::new());
        image::RgbImage::from_pixel(w, h, image::Rgb([90, 120, 30]))
            .write_to(&mut out, image::ImageFormat::Jpeg)
            .unwrap();
        out.into_inner()
    };
    let (cw, ch) = {
        let first = omcl::io::rgb::read_rgb(&f.seq.join("rgb/000000.png")).unwrap();
        first.dimensions()
    };
    let mut cut_jpeg = jpeg(cw, ch);
    cut_jpeg.truncate(cut_jpeg.len() - 40);
    let mut cut_png = png(0);
    cut_png.truncate(cut_png.len() * 3 / 4);
    let cases = [
        (b"GIF89a".to_vec(), "starts as neither"),
        (cut_jpeg, "truncated JPEG"),
        (
            jpeg(cw + 1, ch),
            &format!("{}x{ch} pixels, the session's camera", cw + 1),
        ),
        // Its header reads: caught when the frame is stepped.
        (cut_png, "corrupt or truncated PNG"),
    ];
    for (data, want) in cases {
        let e = c.localize(file_frame(0, data)).await.unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
        assert!(
            e.message().contains("compressed image") && e.message().contains(want),
            "{e:?}"
        );
    }
    // A JPEG of the camera's size is stepped, on a session of its own.
    let mut req = f.create(3);
    req.map = "img".into();
    let sid3 = c.create_session(req).await.unwrap().into_inner().session_id;
    let mut fr = file_frame(0, jpeg(cw, ch));
    fr.session_id = sid3;
    assert_eq!(c.localize(fr).await.unwrap().into_inner().frame, 1);
    for (i, want) in cli.iter().enumerate() {
        let u = c
            .localize(file_frame(i, png(i)))
            .await
            .unwrap()
            .into_inner();
        assert_eq!(u.frame, i as u64 + 1);
        assert_close(&pose_of(&u), want, 7, i);
    }
    // The labels map has no encoder.
    let room = c.create_session(f.create(3)).await.unwrap().into_inner();
    let mut fr = rgb_frame(0);
    fr.session_id = room.session_id;
    let e = c.localize(fr).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert!(e.message().contains("image encoder"), "{e:?}");
}

/// `omcl serve --floorplan`: a session on the floor plan gives the
/// trajectory of `omcl localize --floorplan` with the same seed (the same
/// library scene, levelled camera and 2-D filter); the map is listed as a
/// floor plan; a global start on it (refused until 2026-12-01) gives the
/// trajectory of `omcl localize --floorplan --init global`: both place
/// their level cameras over the 3-D map's floor, kept beside the plan.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_floor_plan_session_gives_the_trajectory_of_the_cli() {
    let f = Fixture::new();
    let cli = cli_localize(&f, 3, &["--floorplan"]);
    assert_eq!(cli.len(), FRAMES);
    let cli_global = cli_localize(&f, 4, &["--floorplan", "--init", "global"]);

    let server = Server::start(&f, &["--floorplan", "room"]);
    let mut c = server.client(Auth::good()).await;
    let maps = c
        .list_maps(proto::ListMapsRequest {})
        .await
        .unwrap()
        .into_inner()
        .maps;
    assert!(maps.len() == 1 && maps[0].floor_plan, "{maps:?}");
    let (_, http_maps) = server.get("/v1/maps", &[("authorization", &format!("Bearer {TOKEN}"))]);
    assert!(http_maps.contains("\"floor_plan\":true"), "{http_maps}");

    let a = c.create_session(f.create(3)).await.unwrap().into_inner();
    assert_session_gives(&mut c, &f, &a.session_id, &cli).await;
    let g = c
        .create_session(proto::CreateSessionRequest {
            start: Some(proto::create_session_request::Start::Global(
                proto::GlobalStart {},
            )),
            ..f.create(4)
        })
        .await
        .unwrap()
        .into_inner();
    assert_session_gives(&mut c, &f, &g.session_id, &cli_global).await;
}

/// Table I's baselines behind `omcl serve --floorplan`
/// (`CreateSessionRequest.baseline`): a SeDAR* session gives `omcl
/// localize --floorplan --baseline sedar`'s trajectory with the same seed,
/// a SIMP* session fed each frame's depth gives `--baseline simp`'s (a
/// frame without depth, or with depth of another size, is refused and
/// steps nothing). SetInitialPose restarts a baseline session; what a
/// baseline cannot do is refused by name: a global restart or start,
/// OMCL's options, an unknown method, a 3-D map.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn baseline_sessions_give_the_trajectories_of_the_cli() {
    let f = Fixture::new();
    let sedar = cli_localize(&f, 3, &["--floorplan", "--baseline", "sedar"]);
    let simp = cli_localize(&f, 4, &["--floorplan", "--baseline", "simp"]);
    assert_eq!((sedar.len(), simp.len()), (FRAMES, FRAMES));
    let moved = sedar
        .iter()
        .zip(&simp)
        .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
        .fold(0.0, f64::max);
    assert!(
        moved > 1e-3,
        "the two baselines' trajectories agree: {moved}"
    );

    // "bare": the same map on its floor plan, without a class table.
    let bare = format!("bare={}", f.map.display());
    let server = Server::start(
        &f,
        &["--floorplan", "room", "--map", &bare, "--floorplan", "bare"],
    );
    let mut c = server.client(Auth::good()).await;
    let create = |seed: u64, b: &str| proto::CreateSessionRequest {
        baseline: b.into(),
        ..f.create(seed)
    };
    let a_id = c
        .create_session(create(3, "sedar"))
        .await
        .unwrap()
        .into_inner()
        .session_id;
    assert_session_gives(&mut c, &f, &a_id, &sedar).await;

    let b = c
        .create_session(create(4, "simp"))
        .await
        .unwrap()
        .into_inner()
        .session_id;
    let with_depth = |i: usize, depth: Option<proto::DepthImage>| proto::Frame {
        depth,
        ..f.frame(&b, i)
    };
    let e = c.localize(with_depth(0, None)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(e.message().contains("depth"), "{e:?}");
    let small = proto::DepthImage {
        width: 2,
        height: 2,
        depth: vec![1.0; 4],
    };
    let e = c.localize(with_depth(0, Some(small))).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(
        e.message()
            .contains("depth image of 2x2, the session's camera is 64x48"),
        "{e:?}"
    );
    let mut bad = f.depth(0);
    bad.depth[64 + 3] = f32::NAN;
    let e = c.localize(with_depth(0, Some(bad))).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(
        e.message()
            .contains("depth value 67 (row 1, column 3) must be finite"),
        "{e:?}"
    );
    let mut bad = f.depth(0);
    bad.depth.pop();
    let e = c.localize(with_depth(0, Some(bad))).await.unwrap_err();
    assert!(e.message().contains("needs 3072 values, got 3071"), "{e:?}");
    for (i, want) in simp.iter().enumerate() {
        let u = c
            .localize(with_depth(i, Some(f.depth(i))))
            .await
            .unwrap()
            .into_inner();
        assert_eq!(u.frame, i as u64 + 1);
        assert_close(&pose_of(&u), want, 7, i);
    }

    // max_depth reaches the sensor: beyond every depth of the room the
    // poses are the CLI's, below every depth SIMP* places no pixel and
    // the poses are others.
    for (max_depth, same) in [(100.0, true), (0.05, false)] {
        let id = c
            .create_session(proto::CreateSessionRequest {
                max_depth: Some(max_depth),
                ..create(4, "simp")
            })
            .await
            .unwrap()
            .into_inner()
            .session_id;
        let mut moved = 0.0f64;
        for (i, want) in simp.iter().enumerate() {
            let frame = proto::Frame {
                depth: Some(f.depth(i)),
                ..f.frame(&id, i)
            };
            let u = c.localize(frame).await.unwrap().into_inner();
            let p = pose_of(&u);
            if same {
                assert_close(&p, want, 7, i);
            }
            moved = moved.max((p[0] - want[0]).hypot(p[1] - want[1]));
        }
        assert_eq!(moved > 0.01, !same, "max_depth {max_depth}: {moved} m");
        c.close_session(proto::CloseSessionRequest { session_id: id })
            .await
            .unwrap();
    }

    // Restarted at the first frame's pose: the session steps on from it.
    let (_, gt) = f.poses("poses.txt");
    c.set_initial_pose(initial_pose(&b, &gt[0])).await.unwrap();
    let u = c
        .localize(with_depth(0, Some(f.depth(0))))
        .await
        .unwrap()
        .into_inner();
    assert_eq!(u.frame, FRAMES as u64 + 1);
    let p = pose_of(&u);
    let off = (p[0] - gt[0].translation.x).hypot(p[1] - gt[0].translation.y);
    assert!(off < 0.5, "{off} m from the restart pose");
    let listed = c
        .list_sessions(proto::ListSessionsRequest {})
        .await
        .unwrap()
        .into_inner()
        .sessions;
    let method = |id: &str| {
        listed
            .iter()
            .find(|s| s.session_id == id)
            .map(|s| s.method.clone())
    };
    assert_eq!(method(&a_id).as_deref(), Some("SeDAR*"), "{listed:?}");
    assert_eq!(method(&b).as_deref(), Some("SIMP*"), "{listed:?}");
    let (_, http) = server.get(
        "/v1/sessions",
        &[("authorization", &format!("Bearer {TOKEN}"))],
    );
    assert!(http.contains("\"method\":\"SIMP*\""), "{http}");
    let e = c
        .global_localization(proto::GlobalLocalizationRequest {
            session_id: b.clone(),
            prompt: None,
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert!(e.message().contains("SIMP* starts from a pose"), "{e:?}");
    // A prompt start, its words the map's or not: the same refusal (the
    // words were looked up first, and one the map lacks answered
    // INVALID_ARGUMENT as if another word would do).
    for word in ["floor", "no such word"] {
        let e = c
            .global_localization(proto::GlobalLocalizationRequest {
                session_id: b.clone(),
                prompt: Some(proto::PromptStart {
                    words: vec![word.into()],
                    ..Default::default()
                }),
            })
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::FailedPrecondition, "{word}: {e:?}");
        assert!(e.message().contains("SIMP* starts from a pose"), "{e:?}");
    }

    let refused = |req: proto::CreateSessionRequest| {
        let mut c = c.clone();
        async move { c.create_session(req).await.unwrap_err() }
    };
    let e = refused(proto::CreateSessionRequest {
        start: Some(proto::create_session_request::Start::Global(
            proto::GlobalStart {},
        )),
        ..create(3, "sedar")
    })
    .await;
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(
        e.message().contains("SeDAR* starts from initial_pose"),
        "{e:?}"
    );
    let e = refused(proto::CreateSessionRequest {
        recovery: true,
        early_reject: true,
        ..create(3, "simp")
    })
    .await;
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(
        e.message()
            .contains("recovery, early_reject set OMCL's filter, which SIMP* does not use"),
        "{e:?}"
    );
    for (b, max_depth, why) in [
        ("sedar", 3.0, "max_depth: 3 m given for baseline \"sedar\""),
        ("", 3.0, "given for an OMCL session"),
        ("simp", -1.0, "max_depth: -1 m, expected a positive number"),
        ("simp", f64::NAN, "max_depth: NaN m"),
    ] {
        let e = refused(proto::CreateSessionRequest {
            max_depth: Some(max_depth),
            ..create(3, b)
        })
        .await;
        assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
        assert!(e.message().contains(why), "{e:?}");
    }
    let e = refused(create(3, "amcl")).await;
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(e.message().contains("unknown baseline \"amcl\""), "{e:?}");
    let e = refused(proto::CreateSessionRequest {
        map: "bare".into(),
        ..create(3, "sedar")
    })
    .await;
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert!(
        e.message()
            .contains("SeDAR* labels the plan's columns and the pixels with a class table, and map \"bare\" has none"),
        "{e:?}"
    );
    drop(server);

    let server = Server::start(&f, &[]);
    let mut c = server.client(Auth::good()).await;
    let e = c.create_session(create(3, "sedar")).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert!(e.message().contains("is a 3-D map"), "{e:?}");
}

/// A session created with `ground` holds the camera at the start's height
/// and tilt: fed odometry that sinks 2 cm a frame, it gives the trajectory
/// of `omcl localize` on the undrifted odometry (positions to 1e-9 m), where
/// a session without it sinks. A tilted start with recovery (which injects
/// level cameras) is refused.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_ground_session_holds_the_camera_against_drifting_odometry() {
    let f = Fixture::new();
    let cli = cli_localize(&f, 3, &[]);
    let server = Server::start(&f, &[]);
    let mut c = server.client(Auth::good()).await;
    let sinking = |session: &str, i: usize| {
        let mut fr = f.frame(session, i);
        let p = fr.odometry.as_mut().unwrap().position.as_mut().unwrap();
        p.z -= 0.02 * i as f64;
        fr
    };
    let held = c
        .create_session(proto::CreateSessionRequest {
            ground: true,
            ..f.create(3)
        })
        .await
        .unwrap()
        .into_inner();
    let free = c.create_session(f.create(3)).await.unwrap().into_inner();
    let mut last_free = 0.0;
    for (i, want) in cli.iter().enumerate() {
        let u = c
            .localize(sinking(&held.session_id, i))
            .await
            .unwrap()
            .into_inner();
        assert_close(&pose_of(&u), want, 3, i);
        let u = c
            .localize(sinking(&free.session_id, i))
            .await
            .unwrap()
            .into_inner();
        last_free = pose_of(&u)[2];
    }
    assert!(
        cli[0][2] - last_free > 0.2,
        "the free session's height {last_free}, the start's {}",
        cli[0][2]
    );

    let mut tilted = f.create(5);
    if let Some(proto::create_session_request::Start::InitialPose(p)) = &mut tilted.start {
        let q = p.pose.as_mut().unwrap().pose.as_mut().unwrap();
        let o = q.orientation.as_mut().unwrap();
        let r = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            o.w, o.x, o.y, o.z,
        )) * nalgebra::UnitQuaternion::from_euler_angles(15f64.to_radians(), 0.0, 0.0);
        (o.x, o.y, o.z, o.w) = (r.i, r.j, r.k, r.w);
    }
    let e = c
        .create_session(proto::CreateSessionRequest {
            ground: true,
            recovery: true,
            ..tilted
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert!(e.message().contains("15.0 degrees from level"), "{e:?}");
}

/// A session created with a named filter runs that tuned filter: with
/// `six-dof` (full motion, two layers, the first on 16 copies) its poses,
/// rotations included, equal `omcl localize --filter six-dof`'s with the
/// same seed. An unknown name is refused naming the known ones; a filter
/// whose motion is not planar is refused with `ground`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_named_filter_session_equals_the_cli_with_that_filter() {
    let f = Fixture::new();
    let cli = cli_localize(&f, 6, &["--filter", "six-dof"]);
    let plain = cli_localize(&f, 6, &[]);
    let server = Server::start(&f, &[]);
    let mut c = server.client(Auth::good()).await;
    let a = c
        .create_session(proto::CreateSessionRequest {
            filter: "six-dof".into(),
            ..f.create(6)
        })
        .await
        .unwrap()
        .into_inner();
    assert_session_gives(&mut c, &f, &a.session_id, &cli).await;
    // The filter made a difference: the default's path is another.
    let apart = cli
        .iter()
        .zip(&plain)
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    assert!(apart > 1e-6, "six-dof and indoor gave the same path");

    let e = c
        .create_session(proto::CreateSessionRequest {
            filter: "6dof".into(),
            ..f.create(6)
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    for name in [
        "\"6dof\"",
        "six-dof-point-cloud",
        "floor-plan",
        "floor-plan-point-cloud",
        "street",
    ] {
        assert!(e.message().contains(name), "{e:?}");
    }
    let e = c
        .create_session(proto::CreateSessionRequest {
            filter: "six-dof".into(),
            ground: true,
            ..f.create(6)
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "{e:?}");
    assert!(e.message().contains("planar"), "{e:?}");
}

/// Names a client sends (map, session, filter, prompt word) come back in error
/// messages cut to a readable length: a megabyte-long name is refused with
/// a short message, and the server serves on.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn long_names_are_refused_with_short_messages() {
    let f = Fixture::new();
    let server = Server::start(&f, &[]);
    let mut c = server.client(Auth::good()).await;
    let long = "x".repeat(1 << 20);
    let cases = [
        (
            proto::CreateSessionRequest {
                map: long.clone(),
                ..f.create(1)
            },
            Code::NotFound,
        ),
        (
            proto::CreateSessionRequest {
                filter: long.clone(),
                ..f.create(1)
            },
            Code::InvalidArgument,
        ),
        (
            proto::CreateSessionRequest {
                start: Some(proto::create_session_request::Start::Prompt(
                    proto::PromptStart {
                        words: vec![long.clone()],
                        ..Default::default()
                    },
                )),
                ..f.create(1)
            },
            Code::InvalidArgument,
        ),
    ];
    for (req, code) in cases {
        let e = c.create_session(req).await.unwrap_err();
        assert_eq!(e.code(), code, "{:.200}", e.message());
        assert!(e.message().len() < 400, "{:.200}...", e.message());
        assert!(e.message().contains("xxxx"), "{:.200}", e.message());
    }
    let e = c
        .close_session(proto::CloseSessionRequest {
            session_id: long.clone(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::NotFound, "{:.200}", e.message());
    assert!(e.message().len() < 400, "{:.200}...", e.message());
    let e = c.localize(f.frame(&long, 0)).await.unwrap_err();
    assert_eq!(e.code(), Code::NotFound, "{:.200}", e.message());
    assert!(
        e.message().contains("(1048576 bytes)"),
        "{:.200}",
        e.message()
    );
    assert_eq!(
        c.list_maps(proto::ListMapsRequest {})
            .await
            .unwrap()
            .into_inner()
            .maps
            .len(),
        1
    );
}

/// `--max-connections 2`: a third gRPC connection is refused by name (its
/// call answered RESOURCE_EXHAUSTED, the cap in the message), counted,
/// and closed by the server after its grace; once one of the two has gone,
/// a new one is served. The HTTP plane is not counted.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn connections_past_the_cap_are_refused_by_name_and_counted() {
    let f = Fixture::new();
    let server = Server::start(&f, &["--max-connections", "2"]);
    let mut a = server.client(Auth::good()).await;
    let mut b = server.client(Auth::good()).await;
    a.list_maps(proto::ListMapsRequest {}).await.unwrap();
    b.list_maps(proto::ListMapsRequest {}).await.unwrap();
    assert_eq!(server.metric("omcl_connections"), "2");
    // A call that has not answered in 20 s counts as not refused by name
    // (the server answers a refused call at once).
    let mut c = server.client(Auth::good()).await;
    let third = tokio::time::timeout(
        Duration::from_secs(20),
        c.list_maps(proto::ListMapsRequest {}),
    )
    .await
    .expect("the refused call was answered");
    let status = third.expect_err("a third connection was served");
    assert_eq!(status.code(), tonic::Code::ResourceExhausted, "{status:?}");
    assert!(
        status
            .message()
            .contains("connection cap: 2 gRPC connections open")
            && status.message().contains("--max-connections 2"),
        "{status:?}"
    );
    assert_eq!(server.metric("omcl_connections"), "2");
    let rejected = server.metric("omcl_rejected_total{reason=\"connection_cap\"}");
    assert_eq!(rejected, "1", "one connection past the cap, counted once");
    drop(c);
    // After its grace (5 s) the server closes a refused connection: a raw
    // one past the cap that sends nothing reads the end of the stream.
    let addr = server.grpc;
    let (closed_after, got) = tokio::task::spawn_blocking(move || {
        use std::io::Read;
        let mut raw = std::net::TcpStream::connect(addr).unwrap();
        raw.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        let t0 = Instant::now();
        // The server's HTTP/2 settings may come first; then the end.
        let mut buf = [0u8; 256];
        let got = loop {
            match raw.read(&mut buf) {
                Ok(0) => break Ok(0),
                Ok(_) => continue,
                Err(e) => break Err(e.to_string()),
            }
        };
        (t0.elapsed(), got)
    })
    .await
    .unwrap();
    assert!(
        got.as_ref().is_ok_and(|&n| n == 0)
            && closed_after >= Duration::from_millis(4500)
            && closed_after < Duration::from_secs(25),
        "raw connection past the cap: {got:?} after {closed_after:?}"
    );
    let rejected = server.metric("omcl_rejected_total{reason=\"connection_cap\"}");
    assert_eq!(rejected, "2", "each connection past the cap counted once");
    drop(a);
    let t0 = Instant::now();
    while server.metric("omcl_connections") != "1" {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "a's connection never closed"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let mut c = server.client(Auth::good()).await;
    c.list_maps(proto::ListMapsRequest {}).await.unwrap();
    b.list_maps(proto::ListMapsRequest {}).await.unwrap();
}
