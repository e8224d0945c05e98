//! A session flooded with frames does not slow the others beyond a stated
//! bound, and the server's memory stays bounded: a session keeps only its
//! latest waiting frame (the others are counted as dropped) and the compute
//! pool serves sessions in turn. Alone in its test binary so that no other
//! test competes for the cores.

mod serve_common;

use std::time::{Duration, Instant};

use serve_common::*;

use omcl::serve::proto;

/// Frames the flooding session sends at most, as fast as the transport
/// takes them, for as long as the measurement lasts.
const FLOOD: usize = 20_000;
/// Frames of the measured session in each phase.
const MEASURED: usize = 14;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

async fn measure(c: &mut Client, f: &Fixture, id: &str, from: usize) -> Vec<f64> {
    let mut ms = Vec::new();
    for i in 0..MEASURED {
        let fr = f.frame(id, (from + i) % 24);
        let t = Instant::now();
        c.localize(fr).await.unwrap();
        ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    ms
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flooding_session_does_not_starve_the_others() {
    let f = Fixture::new();
    let server = Server::start(&f, &["--threads", "2"]);
    let mut c = server.client(Auth::good()).await;
    let mut req = f.create(0);
    req.particles = Some(512);
    let a = c
        .create_session(req.clone())
        .await
        .unwrap()
        .into_inner()
        .session_id;
    let b = c.create_session(req).await.unwrap().into_inner().session_id;

    // Warm up, then session a alone.
    measure(&mut c, &f, &a, 0).await;
    let mut alone = measure(&mut c, &f, &a, 0).await;
    let rss_before = server.rss();

    // Session b floods through a stream while a is measured again.
    let frames: Vec<proto::Frame> = (0..24).map(|i| f.frame(&b, i)).collect();
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let (tx, rx) = tokio::sync::mpsc::channel(64);
    let mut cb = c.clone();
    let reader = tokio::spawn(async move {
        let mut answers = cb
            .stream(tokio_stream::wrappers::ReceiverStream::new(rx))
            .await
            .unwrap()
            .into_inner();
        let mut n = 0usize;
        while let Ok(Some(_)) = answers.message().await {
            n += 1;
        }
        n
    });
    let stop = done.clone();
    let writer = tokio::spawn(async move {
        let mut sent = 0usize;
        while sent < FLOOD && !stop.load(std::sync::atomic::Ordering::Relaxed) {
            if tx.send(frames[sent % 24].clone()).await.is_err() {
                break;
            }
            sent += 1;
            tokio::task::yield_now().await;
        }
        sent
    });
    let mut flooded = measure(&mut c, &f, &a, 0).await;
    let rss_during = server.rss();
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    let sent = writer.await.unwrap();

    let (m_alone, m_flooded) = (median(&mut alone), median(&mut flooded));
    // The bound: a flooding session adds at most about one of its own steps
    // (same size as a's) to each of a's, on 2 threads: 3x the median alone
    // plus 20 ms of scheduling slack.
    assert!(
        m_flooded <= 3.0 * m_alone + 20.0,
        "median step of session a: {m_alone:.1} ms alone, {m_flooded:.1} ms beside a flood"
    );
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
        sb.frames_dropped > 0,
        "no frame of the flood was dropped: {sb:?}"
    );
    assert!(sb.frames + sb.frames_dropped <= sent as u64, "{sb:?}");
    drop(c);
    let answered = tokio::time::timeout(Duration::from_secs(30), reader).await;
    eprintln!(
        "session a: median {m_alone:.1} ms alone, {m_flooded:.1} ms beside the flood; \
         flood: {sent} sent, {} stepped, {} dropped, answers read {:?}; RSS {:.1} -> {:.1} MiB",
        sb.frames,
        sb.frames_dropped,
        answered.ok().and_then(|r| r.ok()),
        rss_before as f64 / (1 << 20) as f64,
        rss_during as f64 / (1 << 20) as f64
    );
}
