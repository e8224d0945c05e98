//! `omcl serve`: argument parsing and the runtime around
//! [`omcl::serve::serve`].

use omcl::encode::Encoder as _;
use std::io::Write;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, bail, ensure};
use clap::Args;

use omcl::io::labels::EmbeddingTable;
use omcl::map;
use omcl::serve::{Drained, Limits, ServeConfig, TlsFiles, Token};
use omcl::session::floorplan::{EXIT_WORDS, PlanScene};
use omcl::session::{LabelTable, SharedMap};

/// Environment variable holding the bearer token (if no --token-file).
pub const TOKEN_ENV: &str = "OMCL_TOKEN";

#[derive(Debug, Args)]
#[command(
    after_help = "Every call but GET /healthz and /readyz and gRPC's standard health \
    service (grpc.health.v1.Health) needs the header \
    `authorization: Bearer <token>` (gRPC metadata of the same name). The token \
    (16+ visible ASCII characters) comes from --token-file or the OMCL_TOKEN \
    environment variable, never from the command line. The server binds to \
    127.0.0.1 unless told otherwise; SIGINT or SIGTERM stops it after the steps \
    in flight (both planes answer until then, /readyz with 503 and gRPC health \
    NOT_SERVING), a second one \
    at once (exit 1). Sessions opened, closed and expired, and the shutdown, are \
    logged on stderr, one line each."
)]
pub struct ServeArgs {
    /// A map to serve, as NAME=FILE.omcl (or FILE.omcl, named by its file
    /// stem). Repeatable; each map is loaded once and shared by its sessions.
    #[arg(long = "map", value_name = "NAME=FILE", required = true)]
    pub maps: Vec<String>,
    /// A class table for a map, as NAME=DIR with DIR/classes.txt and
    /// DIR/embeddings.npy (e.g. the sequence folder): needed for label-image
    /// frames, prompt words and global localization ("floor").
    #[arg(long = "classes", value_name = "NAME=DIR")]
    pub classes: Vec<String>,
    /// Serve the --map NAME on its floor plan, in 2-D (Table I's 2-D block,
    /// as `omcl localize --floorplan`): NAME alone projects the map with the
    /// default band (0.10 to 2.00 m), NAME=PLAN takes the plan file `omcl
    /// map floorplan` made from it. Its sessions hold the camera level at
    /// the start pose's height (a global or prompt start's over the map's
    /// floor: the 3-D map is kept beside its plan for them), and default to the
    /// block's filter (8192 pixels, exponent 240, estimate radius 0.5 m,
    /// pixels stratified over the plan's own rows); the words "floor" and
    /// "ceiling" come from --classes NAME=DIR. Repeatable.
    #[arg(long = "floorplan", value_name = "NAME[=PLAN]")]
    pub floorplans: Vec<String>,
    /// An image encoder for a map, as NAME=MODEL.onnx (with its
    /// .card.json beside it): frames may then be raw RGB images, encoded on
    /// the server (one at a time per map) before the filter step.
    #[arg(long = "image-model", value_name = "NAME=ONNX")]
    pub image_models: Vec<String>,
    /// ONNX Runtime library for --image-model (overrides ORT_DYLIB_PATH and
    /// .deps/).
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
    /// gRPC address, HOST:PORT (a host name is resolved and its first
    /// address taken).
    #[arg(long, default_value = "127.0.0.1:50051", value_parser = socket_addr)]
    pub grpc: SocketAddr,
    /// HTTP control-plane address, HOST:PORT (HTTPS with --tls-cert).
    #[arg(long, default_value = "127.0.0.1:8080", value_parser = socket_addr)]
    pub http: SocketAddr,
    /// File whose first line is the bearer token (default: $OMCL_TOKEN).
    #[arg(long, value_name = "FILE")]
    pub token_file: Option<PathBuf>,
    /// Threads of the compute pool that runs the filter steps (default: the
    /// machine's cores; 1 to 1024).
    #[arg(long, value_parser = super::count_in::<1, 1024>)]
    pub threads: Option<usize>,
    /// Open sessions at most, in total.
    #[arg(long, default_value_t = Limits::default().max_sessions, value_parser = super::count_in::<1, { usize::MAX }>)]
    pub max_sessions: usize,
    /// Open gRPC connections at most. A connection past it is refused:
    /// for 5 s its calls are answered RESOURCE_EXHAUSTED naming the cap,
    /// then it is closed (with 8 such refusals under way, further ones are
    /// closed at once: a transport error). Each open connection may hold up
    /// to 17 MiB of unread stream data.
    #[arg(long, default_value_t = Limits::default().max_connections, value_parser = super::count_in::<1, { usize::MAX }>)]
    pub max_connections: usize,
    /// Open sessions at most on one map.
    #[arg(long, default_value_t = Limits::default().max_sessions_per_map, value_parser = super::count_in::<1, { usize::MAX }>)]
    pub max_sessions_per_map: usize,
    /// Steps queued or running on the pool before frames are refused with
    /// RESOURCE_EXHAUSTED.
    #[arg(long, default_value_t = Limits::default().max_queued)]
    pub max_queued: usize,
    /// Sessions idle this long (seconds) are closed.
    #[arg(long, default_value_t = 300.0, value_parser = super::positive_seconds)]
    pub idle_timeout_s: f64,
    /// Deadline of a frame, seconds: a `Localize` call without its pose by
    /// then is answered DEADLINE_EXCEEDED (a client's shorter grpc-timeout
    /// wins; the step, once running, ends unanswered), as is any other call
    /// by then, and a frame, called or streamed, whose turn on the compute
    /// pool comes later than this after its arrival is not stepped and is
    /// answered DEADLINE_EXCEEDED (in the stream, for a stream). A frame
    /// whose caller has gone by its turn is not stepped either.
    #[arg(long, default_value_t = 10.0, value_parser = super::positive_seconds)]
    pub deadline_s: f64,
    /// Largest gRPC message, MiB (a larger one is answered OUT_OF_RANGE;
    /// in a stream, the stream ends with it).
    #[arg(long, default_value_t = 32, value_parser = super::count_in::<1, 4096>)]
    pub max_message_mib: usize,
    /// A session's particles x rays at most (the rays a step casts):
    /// CreateSession over it is refused. A running step cannot be stopped,
    /// so this bounds what one costs (the default, 2^27, is 64 times the
    /// paper's 1024 x 2048, a few seconds on a 2-core host).
    #[arg(long, default_value_t = omcl::serve::DEFAULT_MAX_RAYS_PER_STEP,
          value_parser = super::count_in::<1, { usize::MAX }>)]
    pub max_rays_per_step: usize,
    /// PEM certificate chain for TLS on both planes, gRPC and HTTPS (with
    /// --tls-key).
    #[arg(long, requires = "tls_key")]
    pub tls_cert: Option<PathBuf>,
    /// PEM private key for TLS on both planes.
    #[arg(long, requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
    /// How long shutdown waits for calls and steps in flight, seconds; past
    /// it the server exits 1, naming the steps abandoned.
    #[arg(long, default_value_t = 10.0, value_parser = super::seconds)]
    pub drain_timeout_s: f64,
}

/// HOST:PORT as `std::net::ToSocketAddrs` resolves it: an IP address
/// with its port, or a host name's first address.
fn socket_addr(s: &str) -> Result<SocketAddr, String> {
    use std::net::ToSocketAddrs;
    if let Ok(a) = s.parse() {
        return Ok(a);
    }
    match s.rsplit_once(':') {
        Some((host, port)) if !host.is_empty() && port.parse::<u16>().is_ok() => {}
        _ => {
            return Err(format!(
                "expected HOST:PORT (127.0.0.1:50051, localhost:50051), got {s:?}"
            ));
        }
    }
    s.to_socket_addrs()
        .map_err(|e| format!("{s:?}: {e}"))?
        .next()
        .ok_or_else(|| format!("{s:?}: the host name has no address"))
}

fn seconds(v: f64, name: &str) -> anyhow::Result<Duration> {
    Duration::try_from_secs_f64(v).map_err(|_| anyhow::anyhow!("--{name} {v}: not a duration"))
}

fn split(spec: &str, what: &str) -> anyhow::Result<(String, PathBuf)> {
    match spec.split_once('=') {
        Some((n, p)) if !n.is_empty() && !p.is_empty() => Ok((n.to_string(), p.into())),
        Some(_) => bail!("{what} {spec:?}: expected NAME=PATH"),
        None => {
            let p = PathBuf::from(spec);
            let name = p
                .file_stem()
                .and_then(|s| s.to_str())
                .with_context(|| format!("{what} {spec:?}: no file name to name it by"))?
                .to_string();
            Ok((name, p))
        }
    }
}

pub fn run(a: ServeArgs) -> anyhow::Result<()> {
    let token = read_token(&a)?;
    let maps = open_maps(&a)?;
    let tls = match (&a.tls_cert, &a.tls_key) {
        (Some(c), Some(k)) => Some(TlsFiles {
            cert_pem: omcl::io::bounded_read::read_text(c)
                .map(String::into_bytes)
                .with_context(|| format!("--tls-cert {}", c.display()))?,
            key_pem: omcl::io::bounded_read::read_text(k)
                .map(String::into_bytes)
                .with_context(|| format!("--tls-key {}", k.display()))?,
        }),
        _ => None,
    };
    if let (Some(t), Some(c), Some(k)) = (&tls, &a.tls_cert, &a.tls_key) {
        omcl::serve::http::tls_config(t).with_context(|| {
            format!("--tls-cert {} with --tls-key {}", c.display(), k.display())
        })?;
    }
    let mut limits = Limits {
        max_sessions: a.max_sessions,
        max_sessions_per_map: a.max_sessions_per_map,
        max_connections: a.max_connections,
        max_queued: a.max_queued.max(1),
        idle_timeout: seconds(a.idle_timeout_s, "idle-timeout-s")?,
        deadline: seconds(a.deadline_s, "deadline-s")?,
        max_message_bytes: a.max_message_mib.max(1) << 20,
        max_rays_per_step: a.max_rays_per_step,
        ..Limits::default()
    };
    if let Some(t) = a.threads {
        limits.threads = t.max(1);
    }
    let threads = limits.threads;
    ensure!(
        a.grpc != a.http || a.grpc.port() == 0,
        "--grpc and --http are both {}: the two planes need two ports",
        a.grpc
    );
    for addr in [a.grpc, a.http] {
        if !addr.ip().is_loopback() && tls.is_none() {
            eprintln!(
                "warning: listening on {addr}, beyond this machine, without TLS: tokens and \
                 frames cross the network in clear (give --tls-cert and --tls-key)"
            );
        }
    }
    let config = ServeConfig {
        grpc_addr: a.grpc,
        http_addr: a.http,
        token,
        limits,
        tls,
        drain_timeout: seconds(a.drain_timeout_s, "drain-timeout-s")?,
    };
    let n_maps = maps.len();
    // The async runtime only moves bytes; the filter runs on the server's
    // own compute pool.
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .max_blocking_threads(8)
        .thread_name("omcl-io")
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    let http = if config.tls.is_some() {
        "HTTPS"
    } else {
        "HTTP"
    };
    let drained = rt.block_on(async {
        // The first SIGINT or SIGTERM starts the drain, a second forces the
        // exit.
        let (count_tx, count_rx) = tokio::sync::watch::channel(0u32);
        tokio::spawn(count_signals(count_tx));
        let nth = |n: u32| {
            let mut rx = count_rx.clone();
            async move {
                let _ = rx.wait_for(|c| *c >= n).await;
            }
        };
        omcl::serve::serve(
            config,
            maps,
            |b| {
                println!(
                    "omcl serve: gRPC on {}, {http} on {} ({n_maps} map(s), {threads} compute \
                     threads)",
                    b.grpc, b.http
                );
                let _ = std::io::stdout().flush();
            },
            nth(1),
            nth(2),
        )
        .await
    });
    match &drained {
        // Steps left running are not waited for (the runtime's blocking
        // threads included); the server keeps its maps to the end.
        Ok(Drained::TimedOut { .. } | Drained::Forced { .. }) => rt.shutdown_background(),
        // Every task is let go of before the process exits: the last
        // reference to a map may be a task's, and its Embree scene must
        // not be released while the process exits (the runtime waits).
        _ => drop(rt),
    }
    match drained? {
        Drained::Finished => {
            println!("omcl serve: stopped");
            Ok(())
        }
        Drained::TimedOut { steps, calls_open } => {
            let calls = if calls_open {
                ", gRPC calls still open cut"
            } else {
                ""
            };
            bail!("the drain timeout was reached: {steps} step(s) in flight abandoned{calls}")
        }
        Drained::Forced { steps } => {
            bail!("stopped by a second signal: {steps} step(s) in flight abandoned")
        }
    }
}

/// The bearer token, from --token-file or the environment (never from the
/// command line).
fn read_token(a: &ServeArgs) -> anyhow::Result<Token> {
    Ok(match (&a.token_file, std::env::var(TOKEN_ENV)) {
        (Some(p), _) => Token::from_file(p).map_err(anyhow::Error::msg)?,
        (None, Ok(t)) => Token::new(&t).map_err(|e| anyhow::anyhow!("${TOKEN_ENV}: {e}"))?,
        (None, Err(_)) => bail!(
            "no token: pass --token-file FILE or set {TOKEN_ENV} (tokens are never taken from \
             the command line)"
        ),
    })
}

/// The maps of --map, with their --classes tables and --image-model
/// encoders; those of --floorplan as their floor plans.
fn open_maps(a: &ServeArgs) -> anyhow::Result<Vec<SharedMap>> {
    let mut specs: Vec<(String, PathBuf)> = Vec::new();
    for spec in &a.maps {
        let (name, path) = split(spec, "--map")?;
        if specs.iter().any(|(n, _)| *n == name) {
            bail!("--map {spec:?}: a map named {name:?} is already given");
        }
        specs.push((name, path));
    }
    let known = |name: &str| specs.iter().any(|(n, _)| n == name);
    let mut tables: Vec<(String, EmbeddingTable)> = Vec::new();
    for spec in &a.classes {
        let (name, dir) = split(spec, "--classes")?;
        if !known(&name) {
            bail!("--classes {spec:?}: no --map named {name:?}");
        }
        let table = EmbeddingTable::read(&dir.join("classes.txt"), &dir.join("embeddings.npy"))
            .with_context(|| {
                format!(
                    "--classes {spec}: DIR must hold classes.txt and embeddings.npy (a sequence \
                     folder of `omcl sim`, or one `omcl map classes -o DIR` wrote)"
                )
            })?;
        tables.push((name, table));
    }
    let mut plans: Vec<(String, Option<PathBuf>)> = Vec::new();
    for spec in &a.floorplans {
        let (name, plan) = match spec.split_once('=') {
            Some((n, p)) if !n.is_empty() && !p.is_empty() => (n.to_string(), Some(p.into())),
            Some(_) => bail!("--floorplan {spec:?}: expected NAME or NAME=PLAN"),
            None => (spec.clone(), None),
        };
        if !known(&name) {
            bail!("--floorplan {spec:?}: no --map named {name:?}");
        }
        if plans.iter().any(|(n, _)| *n == name) {
            bail!("--floorplan {spec:?}: map {name:?} is already served as a floor plan");
        }
        plans.push((name, plan));
    }
    let mut maps: Vec<SharedMap> = Vec::new();
    for (name, path) in specs {
        let table = tables.iter().find(|(n, _)| *n == name).map(|(_, t)| t);
        let mut shared = match plans.iter().find(|(n, _)| *n == name) {
            Some((_, plan)) => floor_plan_map(&name, &path, plan.as_deref(), table)?,
            None => SharedMap::open(name.clone(), &path)?,
        };
        if let Some(t) = table {
            let bound = LabelTable::new(t.clone(), shared.map())
                .with_context(|| format!("--classes for map {name:?}"))?;
            shared = shared.with_classes(bound);
        }
        maps.push(shared);
    }
    for spec in &a.image_models {
        let (name, model) = split(spec, "--image-model")?;
        let i = maps
            .iter()
            .position(|m| m.name() == name)
            .with_context(|| format!("--image-model {spec:?}: no --map named {name:?}"))?;
        let rt = super::encode::init_runtime(a.ort_lib.as_deref())?;
        let enc = omcl::encode::ImageEncoder::load(rt, &model, 0)
            .with_context(|| format!("--image-model {spec:?}"))?;
        let m = maps.remove(i);
        maps.insert(
            i,
            m.with_encoder(enc)
                .with_context(|| format!("--image-model {spec:?}"))?,
        );
    }
    Ok(maps)
}

/// Map `name` (the 3-D map at `path`) served on its floor plan: `plan` (a
/// plan file made from it) or its projection with the default band, the
/// words "floor" and "ceiling" from its class table.
fn floor_plan_map(
    name: &str,
    path: &Path,
    plan: Option<&Path>,
    table: Option<&EmbeddingTable>,
) -> anyhow::Result<SharedMap> {
    let m = map::load(path)?;
    let exits = table.and_then(|t| match EXIT_WORDS.map(|w| t.word(w)) {
        [Some(f), Some(c)] => Some([f, c]),
        _ => None,
    });
    if exits.is_none() {
        eprintln!(
            "note: map {name:?}: no features of \"floor\" and \"ceiling\" (--classes \
             {name}=DIR with both): rays leaving the plan's height window score only the \
             columns' own floors and ceilings"
        );
    }
    let file = plan.map(map::floorplan::load).transpose()?;
    let scene = PlanScene::for_map(&m, file, exits).with_context(|| match plan {
        Some(p) => format!(
            "--floorplan {name}={} with --map {}",
            p.display(),
            path.display()
        ),
        None => format!("--floorplan {name}: the floor plan of {}", path.display()),
    })?;
    Ok(SharedMap::floor_plan(name, scene).with_floor_map(std::sync::Arc::new(m)))
}

/// Counts the SIGINTs and SIGTERMs received into `count`.
async fn count_signals(count: tokio::sync::watch::Sender<u32>) {
    use tokio::signal::unix::{SignalKind, signal};
    let (Ok(mut int), Ok(mut term)) = (
        signal(SignalKind::interrupt()),
        signal(SignalKind::terminate()),
    ) else {
        eprintln!("warning: cannot listen for SIGINT and SIGTERM: no graceful shutdown");
        // Holding `count`: a dropped sender would read as a signal.
        return std::future::pending().await;
    };
    loop {
        tokio::select! {
            _ = int.recv() => {}
            _ = term.recv() => {}
        }
        count.send_modify(|c| *c += 1);
    }
}
