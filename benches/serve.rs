//! Load benchmark of `omcl serve` on loopback: aggregate filter steps per
//! second and p50 / p99 step latency (client side, request to answer) for
//! 1, 4, 16 and 64 concurrent sessions on one map, against the rate of the
//! single-process `omcl localize` on the same frames; and the server's
//! resident memory per extra session.
//!
//! `cargo bench --bench serve` (about a minute). Every session is a closed
//! loop (the next frame is sent when the previous one is answered), so no
//! frame is dropped and the pool is always busy; each session first tracks
//! 10 untimed frames, then each level runs for
//! OMCL_BENCH_SECONDS (default 6) and then stops. Sizes: a 160 x 120
//! camera, the map at 5 cm, 1024 particles and 2048 sampled pixels (the
//! paper's), labels as frames.
//!
//! Then the flood line (skipped with OMCL_BENCH_FLOOD=0): one session's
//! median step latency alone, and again while a second session floods a
//! stream with frames as fast as the transport takes them (the server
//! reads the stream only when its waiting frame has been taken, keeps the
//! latest, and serves sessions in turn), on a connection of its own or,
//! with OMCL_BENCH_FLOOD=shared, on the measured session's; and the cores
//! the server and this process (the clients) used meanwhile. The README's
//! bound: beside the flood, at most 3 times the median alone plus 20 ms.

#[path = "../tests/serve_common/mod.rs"]
mod serve_common;

use std::time::{Duration, Instant};

use serve_common::*;

use omcl::serve::proto;

const WIDTH: u32 = 160;
const HEIGHT: u32 = 120;
const SEQ_FRAMES: usize = 40;
const BENCH_PARTICLES: u32 = 1024;
const BENCH_RAYS: u32 = 2048;
/// Untimed frames each session tracks before its level is measured.
const WARMUP: usize = 10;

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Frame `i` of an endless walk along the sequence and back (ping-pong),
/// so that the odometry never jumps and the filter keeps tracking.
fn ping_pong(i: usize, n: usize) -> usize {
    let k = i % (2 * n - 2);
    if k < n { k } else { 2 * n - 2 - k }
}

/// CPU time this process has used (user + system), seconds.
fn own_cpu_seconds() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap();
    let rest = &s[s.rfind(')').unwrap() + 2..];
    let v: Vec<&str> = rest.split_whitespace().collect();
    (v[11].parse::<f64>().unwrap() + v[12].parse::<f64>().unwrap()) / clock_ticks()
}

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

/// `omcl localize`'s own filter rate on the fixture.
fn cli_rate(f: &Fixture) -> f64 {
    let out = f.dir.path().join("est.txt");
    let r = omcl(&[
        "localize",
        "--map",
        f.map.to_str().unwrap(),
        "--sequence",
        f.seq.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--particles",
        &BENCH_PARTICLES.to_string(),
        "--rays",
        &BENCH_RAYS.to_string(),
    ]);
    assert!(r.status.success(), "{r:?}");
    let text = String::from_utf8_lossy(&r.stdout);
    let cli_rate: f64 = text
        .split(" filter steps/s")
        .next()
        .and_then(|s| s.split_whitespace().last())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no rate in {text:?}"));
    println!(
        "omcl localize: {cli_rate:.1} filter steps/s ({WIDTH}x{HEIGHT}, {BENCH_PARTICLES} \
         particles, {BENCH_RAYS} rays, {SEQ_FRAMES} frames); load average {}",
        load()
    );
    cli_rate
}

fn main() {
    let secs: f64 = std::env::var("OMCL_BENCH_SECONDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(6.0);
    let f = Fixture::sized(WIDTH, HEIGHT, SEQ_FRAMES, 3, "0.05", &[]);
    let cli_before = cli_rate(&f);

    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    let server = Server::start(&f, &["--threads", &threads.to_string()]);
    let frames: Vec<proto::Frame> = (0..SEQ_FRAMES).map(|i| f.frame("", i)).collect();
    println!(
        "| sessions | steps/s (all) | vs CLI | p50 ms | p99 ms | filter step ms (mean) | \
         server cores used | steps per server CPU-second | server RSS MiB | load average |\n\
         |---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"
    );
    let mut rss_one = 0u64;
    // OMCL_BENCH_SESSIONS="1,4" picks levels (default 1, 4, 16, 64).
    let levels: Vec<usize> = std::env::var("OMCL_BENCH_SESSIONS")
        .ok()
        .map(|v| v.split(',').filter_map(|x| x.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![1, 4, 16, 64]);
    for n in levels {
        let (cores_used, per_cpu_s, step_ms, rate, p50, p99, rss) = rt.block_on(async {
            let mut c = server.client(Auth::good()).await;
            let mut ids = Vec::new();
            for s in 0..n {
                let mut req = f.create(s as u64);
                req.particles = Some(BENCH_PARTICLES);
                req.rays = Some(BENCH_RAYS);
                ids.push(c.create_session(req).await.unwrap().into_inner().session_id);
            }
            // Every session first tracks WARMUP frames, untimed: a step
            // costs more while the particles are still spread, and the
            // levels would otherwise compare young filters with old ones.
            let mut warm = Vec::new();
            for id in &ids {
                let mut c = c.clone();
                let id = id.clone();
                let frames = frames.clone();
                warm.push(tokio::spawn(async move {
                    for (i, f) in frames.iter().take(WARMUP).enumerate() {
                        let mut fr = f.clone();
                        fr.session_id = id.clone();
                        // Stamps move forward (the server refuses one that
                        // goes back) while the walk turns round.
                        fr.header = Some(header(i as f64));
                        c.localize(fr).await.unwrap();
                    }
                }));
            }
            for w in warm {
                w.await.unwrap();
            }
            let cpu0 = server.cpu_seconds();
            let t0 = Instant::now();
            let stop = t0 + Duration::from_secs_f64(secs);
            let mut tasks = Vec::new();
            for id in &ids {
                let mut c = c.clone();
                let id = id.clone();
                let frames = frames.clone();
                tasks.push(tokio::spawn(async move {
                    let mut lat = Vec::new();
                    let mut i = WARMUP;
                    while Instant::now() < stop {
                        let mut fr = frames[ping_pong(i, frames.len())].clone();
                        fr.session_id = id.clone();
                        fr.header = Some(header(i as f64));
                        let t = Instant::now();
                        let u = c.localize(fr).await.unwrap().into_inner();
                        lat.push((t.elapsed().as_secs_f64() * 1e3, u.step_ms));
                        i += 1;
                    }
                    lat
                }));
            }
            let mut lat = Vec::new();
            for t in tasks {
                lat.extend(t.await.unwrap());
            }
            let elapsed = t0.elapsed().as_secs_f64();
            let cpu = server.cpu_seconds() - cpu0;
            let rss = server.rss();
            for id in ids {
                c.close_session(proto::CloseSessionRequest { session_id: id })
                    .await
                    .unwrap();
            }
            let step_ms = lat.iter().map(|l| l.1).sum::<f64>() / lat.len() as f64;
            let mut lat: Vec<f64> = lat.into_iter().map(|l| l.0).collect();
            lat.sort_by(|a, b| a.total_cmp(b));
            (
                cpu / elapsed,
                lat.len() as f64 / cpu,
                step_ms,
                lat.len() as f64 / elapsed,
                percentile(&lat, 0.5),
                percentile(&lat, 0.99),
                rss,
            )
        });
        if n == 1 {
            rss_one = rss;
        }
        println!(
            "| {n} | {rate:.1} | {:.0} % | {p50:.1} | {p99:.1} | {step_ms:.1} | {cores_used:.2} | \
             {per_cpu_s:.1} | {:.1} | {} |",
            100.0 * rate / cli_before,
            rss as f64 / (1 << 20) as f64,
            load()
        );
        if n == 64 && rss_one > 0 {
            let per = (rss.saturating_sub(rss_one)) as f64 / 63.0 / (1 << 20) as f64;
            println!(
                "memory per extra session: {per:.2} MiB (RSS at 64 sessions minus at 1, / 63)"
            );
        }
    }
    if std::env::var("OMCL_BENCH_FLOOD").as_deref() != Ok("0") {
        rt.block_on(flood_line(&server, &f, &frames));
    }
    drop(server);
    let cli_after = cli_rate(&f);
    println!(
        "vs CLI: against the CLI's rate before the server ran ({cli_before:.1}); after it: \
         {cli_after:.1}"
    );
}

/// Frames of the measured session in each phase of the flood line.
const FLOOD_MEASURED: usize = 30;

/// Session a's median latency alone and beside session b's flood.
async fn flood_line(server: &Server, f: &Fixture, frames: &[proto::Frame]) {
    let mut c = server.client(Auth::good()).await;
    let mut ids = Vec::new();
    for s in 0..2 {
        let mut req = f.create(s);
        req.particles = Some(BENCH_PARTICLES);
        req.rays = Some(BENCH_RAYS);
        ids.push(c.create_session(req).await.unwrap().into_inner().session_id);
    }
    let (a, b) = (ids[0].clone(), ids[1].clone());
    let mut i = 0;
    // Medians of the latency (client side) and of the step itself (the
    // server's `step_ms`): their difference is waiting for a turn.
    let mut measure = async |c: &mut Client, n: usize| {
        let (mut ms, mut step) = (Vec::new(), Vec::new());
        for _ in 0..n {
            let mut fr = frames[ping_pong(i, frames.len())].clone();
            fr.session_id = a.clone();
            let t = Instant::now();
            let u = c.localize(fr).await.unwrap().into_inner();
            ms.push(t.elapsed().as_secs_f64() * 1e3);
            step.push(u.step_ms);
            i += 1;
        }
        for v in [&mut ms, &mut step] {
            v.sort_by(|x, y| x.total_cmp(y));
        }
        (ms[ms.len() / 2], step[step.len() / 2])
    };
    measure(&mut c, WARMUP).await;
    let (alone, alone_step) = measure(&mut c, FLOOD_MEASURED).await;
    let flood_frames = (0..frames.len())
        .map(|k| {
            let mut fr = frames[k].clone();
            fr.session_id = b.clone();
            fr
        })
        .collect();
    // Where the cores go beside the flood: the server's and this
    // process's (the flooding client's) CPU time over the wall time.
    let (cpu0, own0, t0) = (server.cpu_seconds(), own_cpu_seconds(), Instant::now());
    // The flood on a connection of its own (another camera), unless
    // OMCL_BENCH_FLOOD=shared puts it on a's.
    let flooder = if std::env::var("OMCL_BENCH_FLOOD").as_deref() == Ok("shared") {
        c.clone()
    } else {
        server.client(Auth::good()).await
    };
    let flood = Flood::start(&flooder, flood_frames, usize::MAX);
    let (beside, beside_step) = measure(&mut c, FLOOD_MEASURED).await;
    let wall = t0.elapsed().as_secs_f64();
    let (server_cores, client_cores) = (
        (server.cpu_seconds() - cpu0) / wall,
        (own_cpu_seconds() - own0) / wall,
    );
    let (sent, read) = flood.stop().await;
    let bound = 3.0 * alone + 20.0;
    println!(
        "flood: session a's median step latency {alone:.1} ms alone, {beside:.1} ms beside a \
         flood of {sent} frames ({} answered; the rest dropped); the step itself \
         {alone_step:.1} and {beside_step:.1} ms; cores used beside the flood: server \
         {server_cores:.2}, this process (the clients) {client_cores:.2}; bound 3 x alone + \
         20 ms = {bound:.1} ms: {}; load average {}",
        read.map_or("?".into(), |n| n.to_string()),
        if beside <= bound {
            "within"
        } else {
            "NOT within"
        },
        load()
    );
}
