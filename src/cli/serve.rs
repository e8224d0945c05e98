//! `omcl serve`: argument parsing and the runtime around
//! [`omcl::serve::serve`].

use omcl::encode::Encoder as _;
use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::Args;

use omcl::io::labels::EmbeddingTable;
use omcl::serve::{Limits, ServeConfig, TlsFiles, Token};
use omcl::session::{LabelTable, SharedMap};

/// Environment variable holding the bearer token (if no --token-file).
pub const TOKEN_ENV: &str = "OMCL_TOKEN";

#[derive(Debug, Args)]
#[command(
    after_help = "Every call but GET /healthz and /readyz needs the header \
    `authorization: Bearer <token>` (gRPC metadata of the same name). The token \
    (16+ visible ASCII characters) comes from --token-file or the OMCL_TOKEN \
    environment variable, never from the command line. The server binds to \
    127.0.0.1 unless told otherwise; SIGINT or SIGTERM stops it after the steps \
    in flight."
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
    /// An image encoder for a map, as NAME=MODEL.onnx (with its
    /// .card.json beside it): frames may then be raw RGB images, encoded on
    /// the server (one at a time per map) before the filter step.
    #[arg(long = "image-model", value_name = "NAME=ONNX")]
    pub image_models: Vec<String>,
    /// ONNX Runtime library for --image-model (overrides ORT_DYLIB_PATH and
    /// .deps/).
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
    /// gRPC address.
    #[arg(long, default_value = "127.0.0.1:50051")]
    pub grpc: SocketAddr,
    /// HTTP control-plane address.
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub http: SocketAddr,
    /// File whose first line is the bearer token (default: $OMCL_TOKEN).
    #[arg(long, value_name = "FILE")]
    pub token_file: Option<PathBuf>,
    /// Threads of the compute pool that runs the filter steps (default: the
    /// machine's cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Open sessions at most, in total.
    #[arg(long, default_value_t = Limits::default().max_sessions)]
    pub max_sessions: usize,
    /// Open sessions at most on one map.
    #[arg(long, default_value_t = Limits::default().max_sessions_per_map)]
    pub max_sessions_per_map: usize,
    /// Steps queued or running on the pool before frames are refused with
    /// RESOURCE_EXHAUSTED.
    #[arg(long, default_value_t = Limits::default().max_queued)]
    pub max_queued: usize,
    /// Sessions idle this long (seconds) are closed.
    #[arg(long, default_value_t = 300.0)]
    pub idle_timeout_s: f64,
    /// Deadline of a unary call, seconds.
    #[arg(long, default_value_t = 10.0)]
    pub deadline_s: f64,
    /// Largest gRPC message, MiB.
    #[arg(long, default_value_t = 32)]
    pub max_message_mib: usize,
    /// PEM certificate chain for TLS on both planes, gRPC and HTTPS (with
    /// --tls-key).
    #[arg(long, requires = "tls_key")]
    pub tls_cert: Option<PathBuf>,
    /// PEM private key for TLS on both planes.
    #[arg(long, requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
    /// How long shutdown waits for calls and steps in flight, seconds.
    #[arg(long, default_value_t = 10.0)]
    pub drain_timeout_s: f64,
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
            cert_pem: std::fs::read(c).with_context(|| format!("--tls-cert {}", c.display()))?,
            key_pem: std::fs::read(k).with_context(|| format!("--tls-key {}", k.display()))?,
        }),
        _ => None,
    };
    let mut limits = Limits {
        max_sessions: a.max_sessions,
        max_sessions_per_map: a.max_sessions_per_map,
        max_queued: a.max_queued.max(1),
        idle_timeout: seconds(a.idle_timeout_s, "idle-timeout-s")?,
        deadline: seconds(a.deadline_s, "deadline-s")?,
        max_message_bytes: a.max_message_mib.max(1) << 20,
        ..Limits::default()
    };
    if let Some(t) = a.threads {
        limits.threads = t.max(1);
    }
    let threads = limits.threads;
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
    rt.block_on(omcl::serve::serve(
        config,
        maps,
        |b| {
            println!(
                "omcl serve: gRPC on {}, HTTP on {} ({n_maps} map(s), {threads} compute threads)",
                b.grpc, b.http
            );
            let _ = std::io::stdout().flush();
        },
        shutdown_signal(),
    ))?;
    println!("omcl serve: stopped");
    Ok(())
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
/// encoders.
fn open_maps(a: &ServeArgs) -> anyhow::Result<Vec<SharedMap>> {
    let mut maps: Vec<SharedMap> = Vec::new();
    for spec in &a.maps {
        let (name, path) = split(spec, "--map")?;
        if maps.iter().any(|m| m.name() == name) {
            bail!("--map {spec:?}: a map named {name:?} is already given");
        }
        maps.push(SharedMap::open(name, &path)?);
    }
    for spec in &a.classes {
        let (name, dir) = split(spec, "--classes")?;
        let i = maps
            .iter()
            .position(|m| m.name() == name)
            .with_context(|| format!("--classes {spec:?}: no --map named {name:?}"))?;
        let table = EmbeddingTable::read(&dir.join("classes.txt"), &dir.join("embeddings.npy"))?;
        let bound =
            LabelTable::new(table, maps[i].map()).with_context(|| format!("--classes {spec:?}"))?;
        let m = maps.remove(i);
        maps.insert(i, m.with_classes(bound));
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

async fn shutdown_signal() {
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        _ = term => {}
    }
}
