//! A session flooded with frames leaves the others alone, and the server's
//! memory stays bounded: a session keeps only its latest waiting frame (the
//! others are counted as dropped), the compute pool serves sessions in
//! turn, and a session beside the flood gets the very poses it gets
//! without it. How much the flood slows the others is measured by the load
//! benchmark (`cargo bench --bench serve`, its flood line), not here.

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
