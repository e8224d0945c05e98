//! `omcl sim`: synthetic worlds and sensor data in real datasets' layouts.

use std::path::{Path, PathBuf};

use anyhow::Context;

use omcl::sim::dataset::{self, IndoorDatasetConfig};
use omcl::sim::features::Preset;
use omcl::sim::files;

/// Synthetic benchmark generation.
#[derive(Debug, clap::Subcommand)]
pub enum SimCommand {
    /// An indoor world (--world: corridor apartment, open-plan home or
    /// office floor) and an RGB-D sequence through its rooms.
    Indoor(IndoorArgs),

    /// A street along a real driving path and a KITTI odometry sequence
    /// (LiDAR scans, SemanticKITTI labels, camera-2 images) on it.
    Outdoor(OutdoorArgs),

    /// Writes the simulator's class embedding table from real CLIP text
    /// embeddings (folder in the layout of shared/data/clip_text).
    Classes(ClassesArgs),
}

/// The options of `omcl sim indoor`.
#[derive(Debug, clap::Args)]
pub struct IndoorArgs {
    /// Output directory (created; a non-empty one is refused unless it
    /// holds an earlier simulation and --force is given).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an earlier simulation in --out (its frames and files are
    /// removed once the new one is whole). A folder with other files and
    /// no sim.json is refused either way.
    #[arg(long)]
    pub force: bool,
    /// Seed of every random draw (world, path, noise): the same seed, the
    /// same files.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// The kind of world: corridor, open-plan or offices.
    #[arg(long, default_value = "corridor")]
    pub world: omcl::sim::indoor::WorldKind,
    /// Number of rooms (corridor: default 5; offices: at least 20, rounded
    /// up to a multiple of 4, default 24; the open plan has its own).
    #[arg(long, value_parser = super::count_in::<1, 200>)]
    pub rooms: Option<usize>,
    /// Voxel edge, metres.
    #[arg(long, default_value_t = 0.05)]
    pub resolution: f64,
    /// Number of frames.
    #[arg(long, default_value_t = 300, value_parser = super::count_in::<1, { super::MAX_FRAMES }>)]
    pub frames: usize,
    /// Image width, pixels.
    #[arg(long, default_value_t = 540, value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 540, value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub height: u32,
    /// Horizontal field of view, degrees.
    #[arg(long, default_value_t = 90.0)]
    pub hfov: f64,
    /// Feature preset: exact, gt or lseg-like.
    #[arg(long, default_value = "lseg-like")]
    pub preset: Preset,
    /// Write per-frame feature .npy files (large: 9.2 MB a 540x540 frame
    /// at stride 8, 600 MB at stride 1).
    #[arg(long)]
    pub features: bool,
    /// Pixel stride of the written features (at most the image's height
    /// and width).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub feature_stride: u32,
    /// Odometry translation noise per frame, metres (--odom-sigma-r is the
    /// rotation's); where KITTI drift is replayed (--trajectories) this
    /// noise is added to it.
    #[arg(long, default_value_t = 0.10, allow_negative_numbers = true, value_parser = super::metres)]
    pub odom_sigma_t: f64,
    /// Odometry rotation noise per frame, degrees (as --odom-sigma-t, added
    /// to replayed drift).
    #[arg(long, default_value_t = 6.0, allow_negative_numbers = true, value_parser = super::degrees)]
    pub odom_sigma_r: f64,
    /// Folder with KITTI_00_gt.txt and KITTI_00_ORB.txt whose relative
    /// motion errors are replayed as odometry drift; default: the shared
    /// data beside the source tree when it exists; `none` disables.
    #[arg(long)]
    pub trajectories: Option<String>,
    /// Embedding table (classes.txt + embeddings.npy folder); default:
    /// the built-in table made from real CLIP text embeddings.
    #[arg(long)]
    pub table: Option<PathBuf>,
}

/// The options of `omcl sim outdoor`.
#[derive(Debug, clap::Args)]
pub struct OutdoorArgs {
    /// Output directory (created); the sequence goes to DIR/sequences/00.
    /// A non-empty one is refused unless it holds an earlier simulation
    /// and --force is given.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an earlier simulation in --out (its frames and files are
    /// removed once the new one is whole). A folder with other files and
    /// no sim.json is refused either way.
    #[arg(long)]
    pub force: bool,
    /// Seed of every random draw (world, path, noise): the same seed, the
    /// same files.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// KITTI poses file of the driving path (default: KITTI 00 ground
    /// truth in the shared data beside the source tree).
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// First frame of the driving path.
    #[arg(long, default_value_t = 0)]
    pub start: usize,
    /// Number of frames from --start.
    #[arg(long, default_value_t = 200, value_parser = super::count_in::<1, { super::MAX_FRAMES }>)]
    pub frames: usize,
    /// Voxel edge, metres.
    #[arg(long, default_value_t = 0.2)]
    pub resolution: f64,
    /// LiDAR directions per revolution (64 beams each).
    #[arg(long, default_value_t = 2048, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub azimuth_steps: u32,
    /// Skip camera 2 (its images, label images and features).
    #[arg(long)]
    pub no_images: bool,
    /// Write camera 2's per-pixel features (features_2/NNNNNN.npy;
    /// 15 MB of float32 a 1241 x 376 frame at stride 8).
    #[arg(long, conflicts_with = "no_images")]
    pub features: bool,
    /// Feature preset of --features: exact, gt or lseg-like.
    #[arg(long, default_value = "gt")]
    pub preset: Preset,
    /// Pixel stride of the written features (at most the image's height
    /// and width).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub feature_stride: u32,
    /// Embedding table folder (classes.txt + embeddings.npy); default built in.
    #[arg(long)]
    pub table: Option<PathBuf>,
}

/// The options of `omcl sim classes`.
#[derive(Debug, clap::Args)]
pub struct ClassesArgs {
    /// Folder in the layout of shared/data/clip_text.
    #[arg(long)]
    pub clip_dir: PathBuf,
    /// Folder to write classes.txt and embeddings.npy into (created).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace a class table already in --out.
    #[arg(long)]
    pub force: bool,
    /// Seed of every random draw (world, path, noise): the same seed, the
    /// same files.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

fn default_trajectories() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/trajectories");
    p.join("KITTI_00_ORB.txt").exists().then_some(p)
}

fn load_table(dir: Option<&Path>) -> anyhow::Result<omcl::sim::embeddings::ClassEmbeddings> {
    Ok(match dir {
        Some(d) => files::load_table(&d.join("classes.txt"), &d.join("embeddings.npy"))?,
        None => files::builtin_table()?,
    })
}

/// Runs one `omcl sim` command.
pub fn run(cmd: SimCommand) -> anyhow::Result<()> {
    match cmd {
        SimCommand::Indoor(a) => indoor(a),
        SimCommand::Outdoor(a) => outdoor(a),
        SimCommand::Classes(a) => classes(a),
    }
}

fn indoor(a: IndoorArgs) -> anyhow::Result<()> {
    let IndoorArgs {
        out,
        force,
        seed,
        world,
        rooms,
        resolution,
        frames,
        width,
        height,
        hfov,
        preset,
        features,
        feature_stride,
        odom_sigma_t,
        odom_sigma_r,
        trajectories,
        table,
    } = a;
    anyhow::ensure!(rooms != Some(0), "--rooms must be at least 1");
    anyhow::ensure!(
        resolution > 0.005 && resolution <= 0.5,
        "--resolution {resolution} m is outside (0.005, 0.5]"
    );
    let mut cfg = IndoorDatasetConfig::of_kind(world, seed);
    if let Some(n) = rooms {
        cfg.world.rooms = n;
    }
    cfg.world.resolution = resolution;
    cfg.path.frames = frames;
    cfg.width = width;
    cfg.height = height;
    cfg.hfov_deg = hfov;
    cfg.preset = preset;
    cfg.features = features;
    anyhow::ensure!(
        feature_stride <= width.min(height),
        "the {width} x {height} image is smaller than --feature-stride {feature_stride} (the \
         default is 8): no pixel would get a feature (a larger image, or a smaller \
         --feature-stride)"
    );
    cfg.feature_stride = feature_stride;
    cfg.odometry.sigma_t = odom_sigma_t;
    cfg.odometry.sigma_r_deg = odom_sigma_r;
    let traj = match trajectories.as_deref() {
        Some("none") => None,
        Some(p) => Some(PathBuf::from(p)),
        None => default_trajectories(),
    };
    let (drift, source) = match traj {
        Some(p) => {
            let (d, s) = dataset::load_drift(&p)
                .with_context(|| format!("reading drift from {}", p.display()))?;
            (d, Some(s))
        }
        None => (Vec::new(), None),
    };
    let staging = super::outputs::stage_sim_folder(&out, &dataset::INDOOR_ENTRIES, force)?;
    let table = load_table(table.as_deref())?;
    if features {
        eprintln!(
            "note: --features writes {} MB of float32 per frame",
            (width / cfg.feature_stride) as usize
                * (height / cfg.feature_stride) as usize
                * table.dim
                * 4
                / 1_000_000
        );
    }
    let pb = super::progress::bar_of(frames as u64, "rendering", "frames");
    let mut summary = dataset::write_indoor(staging.path(), &cfg, &table, (&drift, source), &|n| {
        pb.set_position(n as u64)
    })
    .with_context(|| format!("writing the indoor dataset to {}", out.display()))?;
    super::progress::finish(&pb);
    staging.commit()?;
    summary.dir = out;
    println!("{summary}");
    Ok(())
}

fn outdoor(a: OutdoorArgs) -> anyhow::Result<()> {
    let OutdoorArgs {
        out,
        force,
        seed,
        path,
        start,
        frames,
        resolution,
        azimuth_steps,
        no_images,
        features,
        preset,
        feature_stride,
        table,
    } = a;
    anyhow::ensure!(
        (0.02..=1.0).contains(&resolution),
        "--resolution {resolution} m is outside [0.02, 1]"
    );
    let path = match path {
        Some(p) => p,
        None => Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/data/trajectories/KITTI_00_gt.txt"),
    };
    let gt = files::read_kitti_poses(&path)
        .with_context(|| format!("reading the driving path {}", path.display()))?;
    anyhow::ensure!(
        start < gt.len(),
        "{}: --start {start} is past the path's {} poses",
        path.display(),
        gt.len()
    );
    anyhow::ensure!(
        frames <= gt.len() - start,
        "{}: --frames {frames} from --start {start} needs {} poses; the path has {} (at most \
         --frames {})",
        path.display(),
        start + frames,
        gt.len(),
        gt.len() - start
    );
    let mut cfg = dataset::OutdoorDatasetConfig::new(seed);
    cfg.world.start = start;
    cfg.world.frames = frames;
    cfg.world.resolution = resolution;
    cfg.lidar.azimuth_steps = azimuth_steps;
    cfg.images = !no_images;
    cfg.features = features;
    cfg.preset = preset;
    let (w, h) = omcl::io::kitti::KITTI_IMAGE_SIZE;
    anyhow::ensure!(
        feature_stride <= w.min(h),
        "--feature-stride {feature_stride} is larger than the {w} x {h} image: no pixel would \
         get a feature"
    );
    cfg.feature_stride = feature_stride;
    let table = load_table(table.as_deref())?;
    let staging = super::outputs::stage_sim_folder(&out, &dataset::OUTDOOR_ENTRIES, force)?;
    let pb = super::progress::bar_of(frames as u64, "scanning", "frames");
    let mut summary = dataset::write_outdoor(staging.path(), &cfg, &gt, &table, &|n| {
        pb.set_position(n as u64)
    })
    .with_context(|| format!("writing the outdoor dataset to {}", out.display()))?;
    super::progress::finish(&pb);
    staging.commit()?;
    summary.dir = out;
    println!("{summary}");
    Ok(())
}

fn classes(a: ClassesArgs) -> anyhow::Result<()> {
    let ClassesArgs {
        clip_dir,
        out,
        force,
        seed,
    } = a;
    for name in ["classes.txt", "embeddings.npy"] {
        let p = out.join(name);
        anyhow::ensure!(
            force || !p.exists(),
            "{}: a class table is already there; pass --force to replace it, or choose another --out",
            p.display()
        );
    }
    let bank = files::load_clip_bank(&clip_dir)?;
    let table =
        omcl::sim::embeddings::build_table(&bank, omcl::sim::embeddings::SIM_CLASSES, seed)?;
    files::create_dir(&out)?;
    files::save_table(&out, &table)?;
    println!(
        "{}: {} classes x {} from {} real rows",
        out.display(),
        table.len(),
        table.dim,
        bank.names.len()
    );
    Ok(())
}
