//! A session flooded with frames leaves the others alone, and the server's
//! memory stays bounded: a session keeps only its latest waiting frame (the
//! others are counted as dropped), the compute pool serves sessions in
//! turn, and a session beside the flood gets the very poses it gets
//! without it; the server reads a stream no further while its frame
//! waits (backpressure), so a flood is held back by flow control; and a
//! frame whose turn comes past the deadline, or after its caller has gone,
//! is not stepped. How much
//! the flood slows the others is measured by the load benchmark (`cargo
//! bench --bench serve`, its flood line), not here.

mod serve_common;

use std::time::Duration;

use serve_common::*;

use omcl::serve::proto;

/// Frames the flooding session sends at most, as fast as the transport
/// takes them, for as long as the measured session runs.
const FLOOD: usize = 20_000;
/// Frames of the measured session in each phase.
const MEASURED: usize = 14;

/// The poses of `MEASURED` frames of session `id`, each answered within a
/// minute: a hang guard (a step here takes tens of milliseconds; a session
/// starved behind the flood's thousands of frames would wait minutes).
async fn track(c: &mut Client, f: &Fixture, id: &str) -> Vec<[f64; 7]> {
    let mut poses = Vec::new();
    for i in 0..MEASURED {
        let answer = tokio::time::timeout(Duration::from_secs(60), c.localize(f.frame(id, i)))
            .await
            .unwrap_or_else(|_| panic!("frame {i} of session {id} not answered within 60 s"));
        poses.push(pose_of(&answer.unwrap().into_inner()));
    }
    poses
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flooding_session_does_not_starve_the_others() {
    let f = Fixture::new();
    let server = Server::start(&f, &["--threads", "2"]);
    let mut c = server.client(Auth::good()).await;
    let mut req = f.create(0);
    req.particles = Some(512);
    let session = || {
        let (mut c, req) = (c.clone(), req.clone());
        async move { c.create_session(req).await.unwrap().into_inner().session_id }
    };
    let (alone, beside, b) = (session().await, session().await, session().await);

    // The same session (same request and seed) alone, then beside b's flood.
    let poses_alone = track(&mut c, &f, &alone).await;
    let rss_before = server.rss();
    let flood = Flood::start(&c, (0..24).map(|i| f.frame(&b, i)).collect(), FLOOD);
    let poses_beside = track(&mut c, &f, &beside).await;
    let rss_during = server.rss();
    let (sent, read) = flood.stop().await;

    for (i, (p, q)) in poses_alone.iter().zip(&poses_beside).enumerate() {
        for k in 0..7 {
            assert!(
                (p[k] - q[k]).abs() < 1e-9,
                "frame {i}: {p:?} alone, {q:?} beside the flood"
            );
        }
    }
    let grown = rss_during.saturating_sub(rss_before) as f64 / (1 << 20) as f64;
    assert!(
        grown < 64.0,
        "resident memory grew {grown:.1} MiB under the flood"
    );

    let list = c
        .list_sessions(proto::ListSessionsRequest {})
        .await
        .unwrap()
        .into_inner();
    let sb = list.sessions.iter().find(|s| s.session_id == b).unwrap();
    assert!(
        sb.frames > 0 && sb.frames_dropped > 0,
        "the flood was not both stepped and dropped: {sb:?}"
    );
    assert!(sb.frames + sb.frames_dropped <= sent as u64, "{sb:?}");
    eprintln!(
        "flood: {sent} sent, {} stepped, {} dropped, answers read {read:?}; RSS {:.1} -> {:.1} MiB",
        sb.frames,
        sb.frames_dropped,
        rss_before as f64 / (1 << 20) as f64,
        rss_during as f64 / (1 << 20) as f64
    );
}

/// Backpressure: while a stream's frame waits behind a running step, the
/// server reads no more of that stream, so a flooding client is held back by
/// HTTP/2 flow control instead of having its frames read, decoded and
/// dropped by the thousand on the cores the steps need. Frames of 393 KB
/// (a 16 x 12 grid of 512 features) and steps of about a second (50,000
/// particles x 2048 pixels): each time a step takes the waiting frame the
/// server reads at most a stream window (1 MiB) of what has arrived, three
/// such frames, and keeps the latest, so it drops at most 3 frames a step;
/// reading everything, it dropped hundreds.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stream_is_not_read_while_its_frame_waits() {
    let f = Fixture::new();
    let server = Server::start(&f, &["--threads", "2"]);
    let mut c = server.client(Auth::good()).await;
    let b = slow_session(&mut c, &f).await;
    let frames = (0..4)
        .map(|i| {
            let mut fr = f.frame(&b, i);
            fr.features = Some(proto::frame::Features::Grid(proto::FeatureGrid {
                height: 12,
                width: 16,
                dim: 512,
                data: vec![0.1 + i as f32 * 0.01; 12 * 16 * 512],
            }));
            fr
        })
        .collect();
    let flood = Flood::start(&c, frames, usize::MAX);
    // Until three steps of b have ended (a hang guard of two minutes).
    let t0 = std::time::Instant::now();
    let sb = loop {
        tokio::time::sleep(Duration::from_millis(100)).await;
        let list = c
            .list_sessions(proto::ListSessionsRequest {})
            .await
            .unwrap()
            .into_inner();
        let sb = list
            .sessions
            .into_iter()
            .find(|s| s.session_id == b)
            .unwrap();
        if sb.frames >= 3 {
            break sb;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "3 steps not done in 2 minutes: {sb:?}"
        );
    };
    let (sent, _) = flood.stop().await;
    eprintln!(
        "backpressure: {sent} frames sent, {} stepped, {} dropped",
        sb.frames, sb.frames_dropped
    );
    assert!(
        sb.frames_dropped <= 4 * (sb.frames + 2),
        "the server read {} frames of the stream while {} steps ran: not held back",
        sb.frames + sb.frames_dropped,
        sb.frames
    );
}

/// The next answer of a stream, a pose, within two minutes (a hang guard).
async fn pose_answer(stream: &mut tonic::Streaming<proto::StreamResponse>, what: &str) {
    match tokio::time::timeout(Duration::from_secs(120), stream.message()).await {
        Ok(Ok(Some(r))) => assert!(
            matches!(r.result, Some(proto::stream_response::Result::Pose(_))),
            "{what}: {r:?}"
        ),
        other => panic!("{what}: no answer within 2 minutes: {other:?}"),
    }
}

/// Two streams of one session (a client that reconnected, say): each
/// waits while a frame of the session waits, and each is read again once a
/// step takes it. Until 2026-11-27 only the first waiter was woken, and
/// the second stream was never read again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_streams_of_one_session_are_both_read_again() {
    let f = Fixture::new();
    let server = Server::start(&f, &["--threads", "2"]);
    let mut c = server.client(Auth::good()).await;
    let s = slow_session(&mut c, &f).await;

    // Stream 1: frame 0 steps, frame 1 waits behind it.
    let (tx1, mut answers1) = open_stream(&c).await;
    tx1.send(f.frame(&s, 0)).await.unwrap();
    tx1.send(f.frame(&s, 1)).await.unwrap();
    let t0 = std::time::Instant::now();
    while server.metric("omcl_frames_waiting") != "1" {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "frame 1 never waited"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    // Stream 2: its frame replaces frame 1 while frame 0 still steps.
    let (tx2, mut answers2) = open_stream(&c).await;
    tx2.send(f.frame(&s, 2)).await.unwrap();
    pose_answer(&mut answers1, "frame 0 on stream 1").await;
    pose_answer(&mut answers2, "frame 2 on stream 2").await;
    // Both streams are read again.
    tx2.send(f.frame(&s, 3)).await.unwrap();
    pose_answer(&mut answers2, "frame 3 on stream 2").await;
    tx1.send(f.frame(&s, 4)).await.unwrap();
    pose_answer(&mut answers1, "frame 4 on stream 1").await;
}

/// An overloaded server spends no step on a frame nobody can use: with
/// `--deadline-s 0.3` and steps of a second or more (50,000 particles), a
/// streamed frame that waited behind a step is answered DEADLINE_EXCEEDED
/// in the stream and not stepped; a `Localize` call whose client gave up
/// (its own 100 ms timeout) before its turn is not stepped either. The
/// server's counters say which was which.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_past_the_deadline_or_without_a_caller_are_not_stepped() {
    let f = Fixture::new();
    let server = Server::start(&f, &["--threads", "2", "--deadline-s", "0.3"]);
    let mut c = server.client(Auth::good()).await;
    let s = slow_session(&mut c, &f).await;
    let (tx, mut answers) = open_stream(&c).await;
    // Frame 0 steps; frame 1 waits behind it, past the deadline.
    tx.send(f.frame(&s, 0)).await.unwrap();
    tx.send(f.frame(&s, 1)).await.unwrap();
    pose_answer(&mut answers, "frame 0").await;
    let r = tokio::time::timeout(Duration::from_secs(120), answers.message())
        .await
        .expect("frame 1 answered within 2 minutes")
        .unwrap()
        .unwrap();
    match r.result {
        Some(proto::stream_response::Result::Error(e)) => {
            assert_eq!(e.code, "DEADLINE_EXCEEDED", "{e:?}");
            assert!(e.message.contains("deadline-s"), "{e:?}");
        }
        other => panic!("frame 1 was stepped: {other:?}"),
    }
    // Frame 2 steps; frame 3, a call whose client waits 100 ms only, waits
    // behind it and is abandoned.
    tx.send(f.frame(&s, 2)).await.unwrap();
    let t0 = std::time::Instant::now();
    while server.metric("omcl_queue_depth") != "1" {
        assert!(t0.elapsed() < Duration::from_secs(60), "frame 2 never ran");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let mut call = tonic::Request::new(f.frame(&s, 3));
    call.set_timeout(Duration::from_millis(100));
    let e = c.localize(call).await.unwrap_err();
    // tonic's client reports its own timeout as CANCELLED ("Timeout
    // expired"); the server may have answered DEADLINE_EXCEEDED first.
    assert!(
        matches!(
            e.code(),
            tonic::Code::Cancelled | tonic::Code::DeadlineExceeded
        ),
        "{e:?}"
    );
    pose_answer(&mut answers, "frame 2").await;
    // Frame 3's turn has come and gone once the pool is idle.
    let t0 = std::time::Instant::now();
    while server.metric("omcl_queue_depth") != "0" {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "the pool never emptied"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let list = c
        .list_sessions(proto::ListSessionsRequest {})
        .await
        .unwrap()
        .into_inner();
    let st = list.sessions.iter().find(|x| x.session_id == s).unwrap();
    assert_eq!(st.frames, 2, "only frames 0 and 2 were stepped: {st:?}");
    assert_eq!(
        server.metric("omcl_rejected_total{reason=\"expired\"}"),
        "1"
    );
    assert_eq!(
        server.metric("omcl_rejected_total{reason=\"abandoned\"}"),
        "1"
    );
}
