//! Shared by the `serve_*` tests: a synthetic sequence and its map made
//! with the CLI itself, the real `omcl serve` binary on loopback ports it
//! picks, and a Rust gRPC client.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use omcl::geometry::{Intrinsics, Pose};
use omcl::serve::proto::{self, localization_client::LocalizationClient};
use tonic::service::Interceptor;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::Channel;

pub const TOKEN: &str = "test-token-0123456789abcdef";
pub const FRAMES: usize = 20;
pub const PARTICLES: u32 = 64;
pub const RAYS: u32 = 128;

pub fn omcl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(args)
        .output()
        .unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The synthetic sequence of `cli_localize` (two rooms, 64 x 48 pixels)
/// and its map.
pub struct Fixture {
    pub dir: tempfile::TempDir,
    pub seq: PathBuf,
    pub map: PathBuf,
}

/// See [`Fixture::images`].
pub struct Images {
    pub seq: PathBuf,
    pub map: PathBuf,
    pub model: PathBuf,
    pub cli: Vec<[f64; 7]>,
}

impl Fixture {
    pub fn new() -> Fixture {
        Fixture::make(&[])
    }

    /// With per-frame features (features/NNNNNN.npy, 4-pixel stride).
    pub fn with_features() -> Fixture {
        Fixture::make(&["--features", "--feature-stride", "4"])
    }

    fn make(extra: &[&str]) -> Fixture {
        Fixture::sized(64, 48, 24, 2, "0.1", extra)
    }

    /// A sequence of `frames` frames of `width x height` pixels through
    /// `rooms` rooms (seed 1), its map at `resolution` metres.
    pub fn sized(
        width: u32,
        height: u32,
        frames: usize,
        rooms: usize,
        resolution: &str,
        extra: &[&str],
    ) -> Fixture {
        let dir = tempfile::tempdir().unwrap();
        let seq = dir.path().join("seq");
        let map = dir.path().join("seq.omcl");
        let (w, h, n, r) = (
            width.to_string(),
            height.to_string(),
            frames.to_string(),
            rooms.to_string(),
        );
        let sim = [
            "sim",
            "indoor",
            "--out",
            s(&seq),
            "--seed",
            "1",
            "--rooms",
            &r,
            "--frames",
            &n,
            "--width",
            &w,
            "--height",
            &h,
            "--trajectories",
            "none",
        ];
        let r = omcl(&[&sim[..], extra].concat());
        assert!(r.status.success(), "{r:?}");
        let r = omcl(&[
            "map",
            "rgbd",
            s(&seq),
            "-o",
            s(&map),
            "--resolution",
            resolution,
        ]);
        assert!(r.status.success(), "{r:?}");
        Fixture { dir, seq, map }
    }

    /// The sequence as camera images only (`seq_rgb`: rgb/, depth/,
    /// intrinsics, poses and odometry, without the labels and class table
    /// `localize` would read in another feature space), its map built with
    /// the committed tiny image model (`img.omcl`), the model, and the
    /// trajectory `omcl localize --image-model` gives with `seed` over
    /// `frames` frames.
    pub fn images(&self, seed: u64, frames: usize) -> Images {
        let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/encode/tiny_image.onnx");
        let seq = self.dir.path().join("seq_rgb");
        std::fs::create_dir(&seq).unwrap();
        let keep = [
            "rgb",
            "depth",
            "intrinsics.txt",
            "poses.txt",
            "odometry.txt",
        ];
        for e in std::fs::read_dir(&self.seq).unwrap() {
            let e = e.unwrap();
            let name = e.file_name();
            if keep.iter().any(|k| name == *k) {
                std::os::unix::fs::symlink(e.path(), seq.join(&name)).unwrap();
            }
        }
        let map = self.dir.path().join("img.omcl");
        let r = omcl(&[
            "map",
            "rgbd",
            s(&seq),
            "--image-model",
            s(&model),
            "--stride",
            "1",
            "--resolution",
            "0.1",
            "--tau",
            "0.0005",
            "-o",
            s(&map),
        ]);
        assert!(r.status.success(), "{r:?}");
        let out = self.dir.path().join("est_img.txt");
        let r = omcl(&[
            "localize",
            "--map",
            s(&map),
            "--sequence",
            s(&seq),
            "--image-model",
            s(&model),
            "-o",
            s(&out),
            "--particles",
            &PARTICLES.to_string(),
            "--rays",
            &RAYS.to_string(),
            "--seed",
            &seed.to_string(),
            "--frames",
            &frames.to_string(),
        ]);
        assert!(r.status.success(), "{r:?}");
        Images {
            seq,
            map,
            model,
            cli: read_tum(&out),
        }
    }

    pub fn intrinsics(&self) -> Intrinsics {
        omcl::io::rgbd::read_intrinsics(&self.seq.join("intrinsics.txt")).unwrap()
    }

    pub fn camera(&self) -> proto::CameraInfo {
        let k = self.intrinsics();
        proto::CameraInfo {
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            width: k.width,
            height: k.height,
        }
    }

    /// (stamps, poses) of a TUM file.
    pub fn poses(&self, name: &str) -> (Vec<f64>, Vec<Pose>) {
        let f = omcl::io::poses::read_poses(&self.seq.join(name)).unwrap();
        (
            f.trajectory.stamps().to_vec(),
            f.trajectory.poses().to_vec(),
        )
    }

    pub fn labels(&self, i: usize) -> proto::LabelImage {
        let (w, h, labels) =
            omcl::io::rgbd::read_label_png(&self.seq.join(format!("labels/{i:06}.png"))).unwrap();
        proto::LabelImage {
            width: w,
            height: h,
            labels,
        }
    }

    /// Frame `i`'s depth image (TUM's 5000 units a metre).
    pub fn depth(&self, i: usize) -> proto::DepthImage {
        let d = omcl::io::rgbd::read_depth_png(
            &self.seq.join(format!("depth/{i:06}.png")),
            omcl::io::rgbd::TUM_DEPTH_UNITS_PER_METRE,
        )
        .unwrap();
        proto::DepthImage {
            width: d.width,
            height: d.height,
            depth: d.depth,
        }
    }

    /// Frame `i` for `session`: labels, the sequence's odometry, the ground
    /// truth's stamp.
    pub fn frame(&self, session: &str, i: usize) -> proto::Frame {
        let (stamps, _) = self.poses("poses.txt");
        let (_, odom) = self.poses("odometry.txt");
        proto::Frame {
            session_id: session.into(),
            header: Some(header(stamps[i])),
            odometry: Some(pose_msg(&odom[i])),
            features: Some(proto::frame::Features::Labels(self.labels(i))),
            want_particles: false,
            depth: None,
        }
    }

    /// A session request starting at the first ground-truth pose with the
    /// paper's spread, as `omcl localize --init local` does.
    pub fn create(&self, seed: u64) -> proto::CreateSessionRequest {
        let (stamps, gt) = self.poses("poses.txt");
        proto::CreateSessionRequest {
            map: "room".into(),
            camera: Some(self.camera()),
            particles: Some(PARTICLES),
            rays: Some(RAYS),
            seed,
            start: Some(proto::create_session_request::Start::InitialPose(
                proto::PoseWithCovarianceStamped {
                    header: Some(header(stamps[0])),
                    pose: Some(proto::PoseWithCovariance {
                        pose: Some(pose_msg(&gt[0])),
                        covariance: vec![],
                    }),
                },
            )),
            recovery: false,
            frame_id: String::new(),
            early_reject: false,
            ground: false,
            filter: String::new(),
            baseline: String::new(),
            max_depth: None,
        }
    }
}

pub fn header(t: f64) -> proto::Header {
    proto::Header {
        stamp: Some(proto::Time {
            sec: t.floor() as i64,
            nanosec: ((t - t.floor()) * 1e9).round().min(999_999_999.0) as u32,
        }),
        frame_id: "camera".into(),
    }
}

/// `SetInitialPose` of `session` at `pose`, no covariance (the server's
/// default spread).
pub fn initial_pose(session: &str, pose: &Pose) -> proto::SetInitialPoseRequest {
    proto::SetInitialPoseRequest {
        session_id: session.into(),
        pose: Some(proto::PoseWithCovarianceStamped {
            header: None,
            pose: Some(proto::PoseWithCovariance {
                pose: Some(pose_msg(pose)),
                covariance: vec![],
            }),
        }),
    }
}

pub fn pose_msg(p: &Pose) -> proto::Pose {
    omcl::serve::convert::pose_msg(p)
}

/// `omcl serve` on loopback ports of its choosing, stopped when dropped.
pub struct Server {
    pub child: Child,
    pub grpc: SocketAddr,
    pub http: SocketAddr,
    /// The line the server printed once it listened.
    pub banner: String,
}

impl Server {
    /// With `extra` options (default: 2 compute threads).
    pub fn start(f: &Fixture, extra: &[&str]) -> Server {
        Server::spawn(f, extra, Stdio::inherit())
    }

    /// As [`Server::start`], its stderr (the log) written to `log`.
    pub fn start_logged(f: &Fixture, extra: &[&str], log: &Path) -> Server {
        let file = std::fs::File::create(log).unwrap();
        Server::spawn(f, extra, Stdio::from(file))
    }

    fn spawn(f: &Fixture, extra: &[&str], stderr: Stdio) -> Server {
        let threads: &[&str] = if extra.contains(&"--threads") {
            &[]
        } else {
            &["--threads", "2"]
        };
        let map = format!("room={}", s(&f.map));
        let classes = format!("room={}", s(&f.seq));
        let mut child = Command::new(env!("CARGO_BIN_EXE_omcl"))
            .args([
                "serve",
                "--map",
                &map,
                "--classes",
                &classes,
                "--grpc",
                "127.0.0.1:0",
                "--http",
                "127.0.0.1:0",
            ])
            .args(threads)
            .args(extra)
            .env("OMCL_TOKEN", TOKEN)
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.as_mut().unwrap())
            .read_line(&mut line)
            .unwrap();
        // "omcl serve: gRPC on A, HTTP on B (...)" (HTTPS with TLS)
        let addr = |key: &str| -> SocketAddr {
            let rest = line
                .split(key)
                .nth(1)
                .unwrap_or_else(|| panic!("no {key:?} in {line:?}"));
            rest.split([',', ' '])
                .next()
                .unwrap()
                .parse()
                .unwrap_or_else(|e| panic!("{line:?}: {e}"))
        };
        let http_key = if line.contains("HTTPS on ") {
            "HTTPS on "
        } else {
            "HTTP on "
        };
        let (grpc, http) = (addr("gRPC on "), addr(http_key));
        Server {
            child,
            grpc,
            http,
            banner: line,
        }
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Sends `signal` ("TERM", "INT") by the `kill` command (no `unsafe`
    /// outside the Embree module).
    pub fn signal(&self, signal: &str) {
        let st = Command::new("kill")
            .args([&format!("-{signal}"), &self.pid().to_string()])
            .status()
            .unwrap();
        assert!(st.success(), "kill -{signal}");
    }

    /// Waits for the process to end (a hang guard of `guard`, not a time
    /// bound): its exit status.
    pub fn wait_exit(&mut self, guard: Duration) -> std::process::ExitStatus {
        let t0 = std::time::Instant::now();
        loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                return s;
            }
            assert!(t0.elapsed() < guard, "still running after {guard:?}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// CPU time the server has used (user + system), seconds.
    pub fn cpu_seconds(&self) -> f64 {
        let s = std::fs::read_to_string(format!("/proc/{}/stat", self.pid())).unwrap();
        // Fields after the command's closing parenthesis; utime and stime
        // are the 14th and 15th fields of the line.
        let rest = &s[s.rfind(')').unwrap() + 2..];
        let v: Vec<&str> = rest.split_whitespace().collect();
        let ticks: f64 = v[11].parse::<f64>().unwrap() + v[12].parse::<f64>().unwrap();
        ticks / clock_ticks()
    }

    /// Resident memory of the server, bytes.
    pub fn rss(&self) -> u64 {
        let s = std::fs::read_to_string(format!("/proc/{}/status", self.pid())).unwrap();
        let kb: u64 = s
            .lines()
            .find_map(|l| l.strip_prefix("VmRSS:"))
            .and_then(|v| v.split_whitespace().next())
            .and_then(|v| v.parse().ok())
            .unwrap();
        kb * 1024
    }

    pub async fn client(&self, auth: Auth) -> Client {
        self.try_client(auth).await.unwrap()
    }

    /// A client on a connection of its own, or why it could not connect.
    pub async fn try_client(&self, auth: Auth) -> Result<Client, tonic::transport::Error> {
        let ch = Channel::from_shared(format!("http://{}", self.grpc))
            .unwrap()
            .connect()
            .await?;
        Ok(LocalizationClient::with_interceptor(ch, auth).max_decoding_message_size(64 << 20))
    }

    /// The value of the `/metrics` line that starts with `name` and a
    /// space (`""` when there is none).
    pub fn metric(&self, name: &str) -> String {
        let bearer = format!("Bearer {TOKEN}");
        let (_, m) = self.get("/metrics", &[("Authorization", &bearer)]);
        let prefix = format!("{name} ");
        m.lines()
            .find_map(|l| l.strip_prefix(&prefix))
            .map(|v| v.trim().to_string())
            .unwrap_or_default()
    }

    /// A GET on the HTTP port: (status, body).
    pub fn get(&self, path: &str, headers: &[(&str, &str)]) -> (u16, String) {
        let text = self.get_raw(path, headers);
        let status = text
            .split_whitespace()
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        let body = text.split("\r\n\r\n").nth(1).unwrap_or("").to_string();
        (status, body)
    }

    /// A GET on the HTTP port: the whole answer, head and body.
    pub fn get_raw(&self, path: &str, headers: &[(&str, &str)]) -> String {
        let mut c = TcpStream::connect(self.http)
            .unwrap_or_else(|e| panic!("GET {path}: {} refused: {e}", self.http));
        c.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let mut req = format!("GET {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n");
        for (k, v) in headers {
            req.push_str(&format!("{k}: {v}\r\n"));
        }
        req.push_str("\r\n");
        c.write_all(req.as_bytes()).unwrap();
        let mut text = String::new();
        c.read_to_string(&mut text).unwrap();
        text
    }
}

/// Clock ticks per second of /proc's times (`getconf CLK_TCK`).
pub fn clock_ticks() -> f64 {
    let out = Command::new("getconf").arg("CLK_TCK").output().unwrap();
    String::from_utf8_lossy(&out.stdout).trim().parse().unwrap()
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A session of `f` whose steps take a second or more (50,000 particles
/// x 2048 pixels), so that frames sent behind one meet it running.
pub async fn slow_session(c: &mut Client, f: &Fixture) -> String {
    let mut req = f.create(0);
    req.particles = Some(50_000);
    req.rays = Some(2048);
    c.create_session(req).await.unwrap().into_inner().session_id
}

/// A `Stream` call: where its frames go in, and its answers.
pub async fn open_stream(
    c: &Client,
) -> (
    tokio::sync::mpsc::Sender<proto::Frame>,
    tonic::Streaming<proto::StreamResponse>,
) {
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let answers = c
        .clone()
        .stream(tokio_stream::wrappers::ReceiverStream::new(rx))
        .await
        .unwrap()
        .into_inner();
    (tx, answers)
}

/// Puts `key: value` into every request's metadata (or nothing).
#[derive(Clone)]
pub struct Auth(pub Option<(&'static str, String)>);

impl Auth {
    pub fn bearer(token: &str) -> Auth {
        Auth(Some(("authorization", format!("Bearer {token}"))))
    }
    pub fn good() -> Auth {
        Auth::bearer(TOKEN)
    }
}

impl Interceptor for Auth {
    fn call(&mut self, mut req: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        if let Some((k, v)) = &self.0 {
            req.metadata_mut().insert(*k, v.parse().unwrap());
        }
        Ok(req)
    }
}

pub type Client = LocalizationClient<InterceptedService<Channel, Auth>>;

/// The pose of an answer.
pub fn pose_of(u: &proto::PoseUpdate) -> [f64; 7] {
    let p = u.pose.as_ref().unwrap().pose.as_ref().unwrap();
    let p = p.pose.as_ref().unwrap();
    let (t, q) = (
        p.position.as_ref().unwrap(),
        p.orientation.as_ref().unwrap(),
    );
    [t.x, t.y, t.z, q.x, q.y, q.z, q.w]
}

/// Poses of a TUM file written by `omcl localize`.
pub fn read_tum(p: &Path) -> Vec<[f64; 7]> {
    std::fs::read_to_string(p)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [v[1], v[2], v[3], v[4], v[5], v[6], v[7]]
        })
        .collect()
}

/// A session flooding the server: one `Stream` call sending `frames` round
/// and round as fast as the transport takes them, until stopped or `limit`
/// frames are sent, its answers read and counted. Each is stamped with its
/// count (0 s, 1 s, ...): a session's stamps must increase.
pub struct Flood {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    writer: tokio::task::JoinHandle<usize>,
    reader: tokio::task::JoinHandle<usize>,
}

impl Flood {
    pub fn start(c: &Client, frames: Vec<proto::Frame>, limit: usize) -> Flood {
        use std::sync::atomic::{AtomicBool, Ordering};
        let stop = std::sync::Arc::new(AtomicBool::new(false));
        let (tx, rx) = tokio::sync::mpsc::channel(64);
        let mut c = c.clone();
        let reader = tokio::spawn(async move {
            let mut answers = c
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
        let halt = stop.clone();
        let writer = tokio::spawn(async move {
            let mut sent = 0usize;
            while sent < limit && !halt.load(Ordering::Relaxed) {
                let mut frame = frames[sent % frames.len()].clone();
                frame.header = Some(header(sent as f64));
                if tx.send(frame).await.is_err() {
                    break;
                }
                sent += 1;
                tokio::task::yield_now().await;
            }
            sent
        });
        Flood {
            stop,
            writer,
            reader,
        }
    }

    /// Stops sending: the frames sent, and the answers read once the
    /// stream has ended (`None` if it had not within 30 s).
    pub async fn stop(self) -> (usize, Option<usize>) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        let sent = self.writer.await.unwrap();
        let read = tokio::time::timeout(Duration::from_secs(30), self.reader)
            .await
            .ok()
            .and_then(|r| r.ok());
        (sent, read)
    }
}
