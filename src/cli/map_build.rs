//! The map-building commands: file handling around `omcl::mapping`.

use omcl::encode::Encoder as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail, ensure};
use clap::{Args, ValueEnum};

use omcl::io::cloud::PointCloud;
use omcl::io::formats::CloudFormat;
use omcl::io::labels::EmbeddingTable;
use omcl::io::{ply, poses};
use omcl::map::{self, FeatureDb, LanguageMap};
use omcl::mapping::pipeline::{self, CloudInput};
use omcl::mapping::tiles::TileKind;
use omcl::mapping::{IntegrationStats, colors};

/// Options shared by the commands that build a map.
#[derive(Debug, Clone, Args)]
pub struct BuildOptions {
    /// Where to write the map (`.omcl`); written atomically, never half.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Voxel edge length, metres (paper: 0.02 indoors, 0.05 outdoors).
    #[arg(long, default_value_t = 0.05)]
    pub resolution: f64,
    /// Cosine-distance threshold of the feature database (paper: 0.02; the
    /// authors' code uses 0.1 for LSeg, 0.05 for OpenScene).
    #[arg(long, default_value_t = 0.02)]
    pub tau: f32,
    /// Cap on observation rows for raw features (memory and time bound)
    /// [default: 4096]; with a class table (label images, --classes) the
    /// rows are the table's, and it is refused.
    #[arg(long, value_parser = super::count_in::<1, { usize::MAX }>)]
    pub max_rows: Option<usize>,
    /// The class list that turns labels into features (ground-truth mode):
    /// a file (`<id> <name>` lines, or one name a line) or a built-in list,
    /// `semantickitti` (all 34 SemanticKITTI classes, `.label` ids) or
    /// `asprs` (LAS classification codes 0-22).
    #[arg(long, value_name = "FILE|semantickitti|asprs")]
    pub classes: Option<String>,
    /// The features of --classes (`.npy`, one row a class, in list order).
    /// Without it: --text-model, or for a built-in list the built-in
    /// CLIP-like table (a quick start; not real CLIP for most classes).
    #[arg(long, requires = "classes")]
    pub embeddings: Option<PathBuf>,
    /// A text encoder (`.onnx` with its `.card.json`, e.g. CLIP's) that
    /// embeds the class names of --classes.
    #[arg(
        long,
        value_name = "ONNX",
        requires = "classes",
        conflicts_with = "embeddings"
    )]
    pub text_model: Option<PathBuf>,
    /// Name of the feature space, stored in the map (e.g. clip-vit-b32).
    #[arg(long, default_value = DEFAULT_ENCODER, value_parser = super::name)]
    pub encoder: String,
    /// Replace --out even when it is a file that is not an omcl map (a map
    /// is replaced without it).
    #[arg(long)]
    pub force: bool,
}

const DEFAULT_ENCODER: &str = "clip-vit-b32";

/// `--max-rows` when not given.
const DEFAULT_MAX_ROWS: usize = 4096;

/// The files a class table is read from (the `--classes` list, its
/// `--embeddings`, a `--text-model` and its card), as
/// [`super::outputs::refuse_overlaps`] inputs.
fn table_inputs(
    classes: Option<&str>,
    embeddings: Option<&Path>,
    text_model: Option<&Path>,
) -> Vec<(String, PathBuf)> {
    let mut v = Vec::new();
    v.extend(classes.map(|c| ("the --classes list".to_string(), PathBuf::from(c))));
    v.extend(embeddings.map(|p| ("the --embeddings".to_string(), p.to_path_buf())));
    v.extend(super::outputs::model_files("--text-model", text_model));
    v
}

impl BuildOptions {
    /// The files these options read (the class list, its features, the
    /// text encoder and its card), as [`super::outputs::refuse_overlaps`]
    /// inputs.
    pub fn inputs(&self) -> Vec<(String, PathBuf)> {
        table_inputs(
            self.classes.as_deref(),
            self.embeddings.as_deref(),
            self.text_model.as_deref(),
        )
    }

    /// The class table of --classes, if given (`ort_lib`: the command's
    /// ONNX Runtime library, for --text-model), with the text encoder's
    /// name when one made it.
    fn table(
        &self,
        ort_lib: Option<&Path>,
    ) -> anyhow::Result<Option<(EmbeddingTable, Option<String>)>> {
        self.classes
            .as_deref()
            .map(|c| {
                super::encoders::class_table(
                    c,
                    self.embeddings.as_deref(),
                    self.text_model.as_deref(),
                    ort_lib,
                )
            })
            .transpose()
    }

    /// Build parameters; `text_encoder` (the name of the encoder that
    /// embedded the class names) names the feature space unless --encoder
    /// was given.
    fn params(&self, text_encoder: Option<&str>) -> pipeline::BuildParams {
        let encoder = match text_encoder {
            Some(name) if self.encoder == DEFAULT_ENCODER => name.to_string(),
            _ => self.encoder.clone(),
        };
        pipeline::BuildParams {
            resolution: self.resolution,
            tau: self.tau,
            max_rows: self.max_rows.unwrap_or(DEFAULT_MAX_ROWS),
            encoder,
            keep_strays: false,
        }
    }

    fn check(&self) -> anyhow::Result<()> {
        ensure!(
            self.resolution.is_finite() && self.resolution > 0.0,
            "--resolution must be a positive number of metres, got {}",
            self.resolution
        );
        ensure!(
            (0.0..=2.0).contains(&self.tau),
            "--tau must be in [0, 2], got {}",
            self.tau
        );
        super::outputs::check_map_out("--out", &self.out, self.force)?;
        Ok(())
    }
}

/// Saves the map and says what it holds.
fn save(m: &LanguageMap, b: &BuildOptions, stats: &IntegrationStats) -> anyhow::Result<()> {
    save_as(m, b, stats, false)
}

/// [`save`]; `strays`: the build left strays out (`map cloud`), which the
/// warning on left-out points then names.
fn save_as(
    m: &LanguageMap,
    b: &BuildOptions,
    stats: &IntegrationStats,
    strays: bool,
) -> anyhow::Result<()> {
    map::save(m, &b.out)?;
    if stats.rejected > 0 {
        let g = m.grid();
        let reach = f64::from(omcl::map::key::CELL_MAX) * g.resolution;
        let stray = if strays {
            "; strays far outside the bulk of the data (such as points at 0, 0, 0 in \
             georeferenced coordinates: more than ten times its size or 10 km out of the box \
             of its 1st to 99th percentiles; --keep-strays keeps them)"
        } else {
            ""
        };
        eprintln!(
            "warning: {} of {} points were left out: not finite{stray}; or beyond the grid's \
             reach ({:.0} m each way of its origin ({:.2}, {:.2}, {:.2}) at {} m: a coarser \
             --resolution reaches farther)",
            stats.rejected, stats.offered, reach, g.origin.x, g.origin.y, g.origin.z, g.resolution
        );
    }
    println!(
        "wrote {}: {} at {} m, {} x {} dims ({} of {} inputs integrated, {} skipped, {} rejected)",
        b.out.display(),
        super::count(m.len(), "voxel"),
        b.resolution,
        super::count(m.db().len(), "feature row"),
        m.db().dim(),
        stats.integrated,
        stats.offered,
        stats.skipped,
        stats.rejected
    );
    Ok(())
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    Ply,
    Las,
    Kitti,
    Scannet,
}

#[derive(Debug, Args)]
pub struct CloudArgs {
    /// A point-cloud file (.ply, .las, .laz, KITTI .bin with --format kitti,
    /// ScanNet .bin with --format scannet), a SemanticKITTI sequence
    /// folder (velodyne/, labels/, calib.txt, poses.txt), or a folder of
    /// LAS/LAZ tiles of one CRS or of PLY tiles, mapped together through
    /// --classes. LAS/LAZ are read a batch at a time (any size, two
    /// passes), PLY tiles one at a time; other files are read whole (about
    /// 60 bytes a point).
    pub input: PathBuf,
    #[command(flatten)]
    pub build: BuildOptions,
    /// Format of a file whose extension does not tell.
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// Per-point features (`N x F` .npy, e.g. OpenScene run elsewhere);
    /// the map is made of them, so not with --classes.
    #[arg(long, conflicts_with = "classes")]
    pub features: Option<PathBuf>,
    /// A single KITTI scan's SemanticKITTI `.label` file (default: the
    /// scan's name with `.label` beside it, or in `../labels/`).
    #[arg(long)]
    pub labels: Option<PathBuf>,
    /// Sequence folders: use at most this many scans from the start.
    #[arg(long, value_parser = super::count_in::<1, { usize::MAX }>)]
    pub frames: Option<usize>,
    /// Sequence folders: per-scan feature files NNNNNN.npy in this folder;
    /// the map is made of them, so not with --classes.
    #[arg(long, conflicts_with = "classes")]
    pub features_dir: Option<PathBuf>,
    /// Keep points the authors drop: SemanticKITTI unlabeled, outlier and
    /// moving classes; LAS noise classes 7 and 18.
    #[arg(long)]
    pub keep_all: bool,
    /// Keep strays: points far outside the bulk of the data (more than ten
    /// times its size or 10 km out of the box of its 1st to 99th
    /// percentiles, such as points at 0, 0, 0 in UTM coordinates), which
    /// are left out by default.
    #[arg(long)]
    pub keep_strays: bool,
    /// Sequence folders: ignore points farther than this from the sensor (m).
    #[arg(long)]
    pub max_range: Option<f64>,
    /// PLY files: the vertex property holding the labels, when it has
    /// another name than label, class, classification, semantic or
    /// semantic_label (DALES: sem_class), or to choose one of several.
    #[arg(long, value_name = "NAME")]
    pub label_property: Option<String>,
    /// Point encoder (`.onnx` with its `.card.json`, points and colours to
    /// per-point features), for clouds without labels or feature files.
    #[arg(long, value_name = "ONNX", conflicts_with = "features")]
    pub point_model: Option<PathBuf>,
    /// ONNX Runtime library for --point-model or --text-model.
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
}

pub fn cloud(a: &CloudArgs) -> anyhow::Result<()> {
    let mut inputs = vec![("the input".to_string(), a.input.clone())];
    inputs.extend(a.labels.clone().map(|p| ("--labels".to_string(), p)));
    inputs.extend(a.features.clone().map(|p| ("--features".to_string(), p)));
    inputs.extend(a.build.inputs());
    inputs.extend(super::outputs::model_files(
        "--point-model",
        a.point_model.as_deref(),
    ));
    inputs.extend(a.ort_lib.clone().map(|p| ("the --ort-lib".to_string(), p)));
    super::outputs::refuse_overlaps(&[("--out", &a.build.out)], &inputs)?;
    // A folder of LAS/LAZ or PLY tiles, mapped together a batch at a time.
    let tiles = omcl::mapping::tiles::cloud_tiles(&a.input);
    let ply_tiles = matches!(tiles, Some((TileKind::Ply, _)));
    // (An output named like a tile is refused as any non-.omcl name is.)
    if tiles.is_none() && a.input.is_dir() {
        // A sequence folder: its scans, labels, poses and calibration.
        super::outputs::refuse_inside_sequence(&[("--out", &a.build.out)], &a.input)?;
    }
    a.build.check()?;
    // Before a text model is loaded for the class table.
    ensure!(
        a.input.exists(),
        "{}: no such file or folder",
        a.input.display()
    );
    if !a.input.is_dir() || tiles.is_some() {
        let what_it_is = if tiles.is_some() {
            "a folder of tiles"
        } else {
            "a file"
        };
        for (given, what) in [
            (a.frames.is_some(), "--frames"),
            (a.max_range.is_some(), "--max-range"),
            (a.features_dir.is_some(), "--features-dir"),
        ] {
            ensure!(
                !given,
                "{what} is for a KITTI sequence folder (scan by scan); {} is {what_it_is}",
                a.input.display()
            );
        }
    }
    ensure!(
        a.label_property.is_none() || ply_tiles || (!a.input.is_dir() && !las_file_given(a)),
        "--label-property is for PLY files; {} is {}",
        a.input.display(),
        if a.input.is_dir() {
            "a folder without PLY tiles"
        } else {
            "a LAS/LAZ file (its labels are its classification codes)"
        }
    );
    ensure!(
        a.build.max_rows.is_none() || a.build.classes.is_none(),
        "--max-rows caps the rows made from raw features (--features, --point-model, a \
         cloud's own features); with --classes the rows are the class table's"
    );
    ensure!(
        a.ort_lib.is_none() || a.point_model.is_some() || a.build.text_model.is_some(),
        "--ort-lib is for --point-model or --text-model, and neither is given"
    );
    let ply_file = !a.input.is_dir()
        && match a.format {
            Some(f) => matches!(f, FormatArg::Ply | FormatArg::Scannet),
            None => CloudFormat::from_path(&a.input) == Some(CloudFormat::Ply),
        };
    ensure!(
        !(a.keep_all && (ply_tiles || ply_file)),
        "--keep-all is for KITTI scans and sequences (unlabeled, outlier and moving points) and \
         LAS/LAZ (noise classes 7 and 18); from {} nothing is dropped by class",
        a.input.display()
    );
    if tiles.is_none() && a.input.is_dir() {
        // A KITTI sequence folder.
        for (given, what, instead) in [
            (a.labels.is_some(), "--labels", "its labels are in labels/"),
            (a.format.is_some(), "--format", "its scans are KITTI .bin"),
            (
                a.features.is_some(),
                "--features",
                "per-scan feature files go in a folder given with --features-dir",
            ),
        ] {
            ensure!(
                !given,
                "{what} is for one cloud file; {} is a sequence folder: {instead}",
                a.input.display()
            );
        }
    }
    if tiles.is_some() {
        for (given, what) in [
            (a.features.is_some(), "--features"),
            (a.point_model.is_some(), "--point-model"),
            (a.labels.is_some(), "--labels"),
            (a.format.is_some(), "--format"),
        ] {
            ensure!(
                !given,
                "{what} is for one cloud file; {} is a folder of tiles, mapped from their \
                 labels through a class table (--classes); merge the tiles into one file \
                 (e.g. `pdal merge`) for {what}",
                a.input.display()
            );
        }
    }
    if let Some(r) = a.max_range {
        ensure!(
            r.is_finite() && r > 0.0,
            "--max-range must be a positive number of metres, got {r}"
        );
    }
    let input = CloudInput {
        path: a.input.clone(),
        format: a.format.map(|f| match f {
            FormatArg::Ply => CloudFormat::Ply,
            FormatArg::Las => CloudFormat::Las,
            FormatArg::Kitti => CloudFormat::KittiBin,
            FormatArg::Scannet => CloudFormat::ScannetBin,
        }),
        labels: a.labels.clone(),
        features: a.features.clone(),
        frames: a.frames,
        features_dir: a.features_dir.clone(),
        keep_all: a.keep_all,
        max_range: a.max_range,
        label_property: a.label_property.clone(),
    };
    let (table, text_encoder) = a.build.table(a.ort_lib.as_deref())?.unzip();
    let text_encoder = text_encoder.flatten();
    let las_file = las_file_given(a);
    ensure!(
        !(las_file && a.labels.is_some()),
        "--labels is for a single KITTI scan (--format kitti); {} is a LAS/LAZ file, whose labels \
         are its classification codes",
        a.input.display()
    );
    if tiles.is_some() || (las_file && a.features.is_none() && a.point_model.is_none()) {
        // LAS/LAZ labels through the class table: a batch at a time,
        // never the whole cloud in memory.
        return map_tiles(a, table.as_ref(), text_encoder.as_deref());
    }
    if a.input.is_dir() && a.point_model.is_none() {
        // A sequence folder: scan by scan, never the merged cloud in memory.
        let mut bar = super::progress::TwoPasses::new(0, "scans");
        let (m, stats) = pipeline::map_from_sequence(
            &input,
            &cloud_params(a, text_encoder.as_deref()),
            table.as_ref(),
            &mut |pass, done, total| {
                let mapping = pass == pipeline::SequencePass::Mapping;
                bar.update(mapping, done as u64, total as u64)
            },
        )?;
        bar.finish();
        save_as(&m, &a.build, &stats, !a.keep_strays)?;
        warn_labels(
            &m,
            &a.build,
            &stats,
            table.is_some() && a.features_dir.is_none(),
        );
        return Ok(());
    }
    // A KITTI scan mapped by labels needs its .label file: say where it
    // was looked for (the error had told to pass --classes, given).
    if table.is_some()
        && a.format == Some(FormatArg::Kitti)
        && omcl::io::kitti::label_path_for_scan(&a.input, a.labels.as_deref()).is_none()
    {
        let beside = a.input.with_extension("label");
        let layout = a
            .input
            .parent()
            .and_then(Path::parent)
            .zip(a.input.file_stem())
            .map(|(d, n)| d.join("labels").join(n).with_extension("label"));
        anyhow::bail!(
            "{}: --classes maps the scan's labels, and no label file is at {}{}: pass --labels \
             FILE",
            a.input.display(),
            beside.display(),
            layout.map_or(String::new(), |l| format!(" nor {}", l.display()))
        );
    }
    let pb = super::progress::spinner(&format!("reading {}", a.input.display()));
    let mut c = pipeline::load_cloud(&input)?;
    // A cloud with feature columns of its own is mapped from them, but
    // --classes asks for its labels: they are used, and the features left
    // out, said (the features had been used and --classes ignored).
    if let (Some(_), Some((dim, _))) = (&table, &c.features) {
        ensure!(
            c.labels.is_some(),
            "{}: its points carry features ({dim} values a point) but no labels, and --classes \
             maps labels: leave --classes out to map the features",
            a.input.display()
        );
        c.notes.push(format!(
            "{}: its points carry features ({dim} values a point) and labels; --classes maps \
             the labels, the features are left out (leave --classes out to map them)",
            a.input.display()
        ));
        c.features = None;
    }
    // A cloud with feature columns of its own is mapped from them.
    let own_features = c.features.is_some();
    pb.suspend(|| {
        for n in &c.notes {
            eprintln!("note: {n}");
        }
    });
    let mut encoder = match &a.point_model {
        Some(model) => {
            let rt = super::encode::init_runtime(a.ort_lib.as_deref())?;
            Some(omcl::encode::PointEncoder::load(rt, model, 0)?)
        }
        None => None,
    };
    // A bar over the points (512-dimensional features take minutes a
    // million points; a spinner had said nothing of how far it was).
    super::progress::finish(&pb);
    let bar = super::progress::bar_of(c.len() as u64, "mapping", "points");
    let (m, stats) = pipeline::map_from_cloud_with(
        c,
        &a.input.display().to_string(),
        &cloud_params(a, text_encoder.as_deref()),
        table.as_ref(),
        encoder.as_mut(),
        &mut |done, _| bar.set_position(done as u64),
    )?;
    super::progress::finish(&bar);
    save_as(&m, &a.build, &stats, !a.keep_strays)?;
    let labelled = table.is_some() && !own_features && a.point_model.is_none();
    warn_labels(&m, &a.build, &stats, labelled);
    Ok(())
}

/// How `map cloud` builds: the shared options and `--keep-strays`.
fn cloud_params(a: &CloudArgs, text_encoder: Option<&str>) -> pipeline::BuildParams {
    pipeline::BuildParams {
        keep_strays: a.keep_strays,
        ..a.build.params(text_encoder)
    }
}

/// Whether `a`'s input is a LAS/LAZ file (by `--format` or extension).
fn las_file_given(a: &CloudArgs) -> bool {
    !a.input.is_dir()
        && match a.format {
            Some(f) => matches!(f, FormatArg::Las),
            None => CloudFormat::from_path(&a.input) == Some(CloudFormat::Las),
        }
}

/// Maps a LAS/LAZ file or a folder of tiles a batch at a time
/// (`omcl::mapping::tiles`): two passes over the points, each a bar.
fn map_tiles(
    a: &CloudArgs,
    table: Option<&EmbeddingTable>,
    text_encoder: Option<&str>,
) -> anyhow::Result<()> {
    use omcl::mapping::tiles::{TileOptions, TileSource, map_from_tiles};
    let pb = super::progress::spinner(&format!("reading the headers of {}", a.input.display()));
    let src = TileSource::open(&a.input)?;
    super::progress::finish(&pb);
    for n in src.notes() {
        eprintln!("note: {n}");
    }
    let what = match (src.kind(), src.files().len()) {
        (TileKind::Las, n) if n > 1 => format!("points of {n} tiles"),
        _ => src.unit().to_string(),
    };
    let mut bar = super::progress::TwoPasses::new(src.declared(), &what);
    let (m, stats, notes) = map_from_tiles(
        &src,
        &TileOptions {
            keep_all: a.keep_all,
            label_property: a.label_property.clone(),
            ..Default::default()
        },
        &cloud_params(a, text_encoder),
        table,
        &mut |pass, done, total| bar.update(pass == pipeline::SequencePass::Mapping, done, total),
    )?;
    bar.finish();
    for n in &notes {
        eprintln!("note: {n}");
    }
    save_as(&m, &a.build, &stats, !a.keep_strays)?;
    warn_labels(&m, &a.build, &stats, true);
    Ok(())
}

/// Warns when a map made from labels through a class table says little:
/// most points' labels are not in the table (the table of another
/// dataset), or every point has the same class (a LAS file never
/// classified).
fn warn_labels(m: &LanguageMap, b: &BuildOptions, stats: &IntegrationStats, labelled: bool) {
    let table = b.classes.as_deref().unwrap_or("");
    if !labelled || stats.offered == 0 {
        return;
    }
    let share = stats.skipped as f64 / stats.offered as f64;
    if share > 0.2 {
        eprintln!(
            "warning: {:.0} % of the points were skipped: their labels are not in the class \
             table {table}; is it the table of the cloud's dataset? (`omcl map classes \
             {table}` lists its ids)",
            100.0 * share
        );
    }
    let used: std::collections::BTreeSet<u32> = m.rows().iter().copied().collect();
    if used.len() == 1 && m.len() > 1 {
        // Real CLIP text features of distinct classes lie at cosine
        // distances of 0.035 and more (the closest pair of the LVIS table
        // in ../shared/data): below that, --tau merges none of them.
        let merged = if b.tau >= 0.035 {
            format!(", or --tau {} merged the classes' features into one", b.tau)
        } else {
            String::new()
        };
        eprintln!(
            "warning: the map holds one feature, so it cannot tell places apart by meaning: \
             every mapped point has the same class (a LAS file whose points were never \
             classified has only class 0){merged}"
        );
    }
}

#[derive(Debug, Args)]
pub struct RgbdArgs {
    /// An RGB-D sequence folder: intrinsics.txt (`fx fy cx cy width
    /// height`), poses.txt (TUM, world_from_camera), depth/NNNNNN.png
    /// (16-bit), and labels/NNNNNN.png with classes.txt + embeddings.npy,
    /// or features/NNNNNN.npy (`h x w x F`, any h x w). Or a Microsoft
    /// 7-Scenes folder (camera-intrinsics.txt, frame-NNNNNN.color.jpg,
    /// .depth.png in mm, .pose.txt) with --image-model: the map is built in
    /// the z-up world of its gravity-direction.txt, where `omcl localize`
    /// reads its ground truth.
    pub dir: PathBuf,
    #[command(flatten)]
    pub build: BuildOptions,
    /// Depth PNG units per metre (TUM: 5000; Replica: 6553.5; 7-Scenes
    /// folders are read in millimetres whatever this says).
    #[arg(long, default_value_t = 5000.0, value_parser = super::positive)]
    pub depth_scale: f64,
    /// Ignore depths beyond this many metres.
    #[arg(long, default_value_t = 10.0)]
    pub max_depth: f32,
    /// Ignore points above this world height (crop the ceiling), metres.
    #[arg(long, value_parser = super::finite)]
    pub max_height: Option<f64>,
    /// Use every n-th pixel in each direction.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..))]
    pub stride: u32,
    /// Use per-frame feature files from features/ even if labels exist.
    #[arg(long)]
    pub use_features: bool,
    /// Use at most this many frames (7-Scenes: picked frames).
    #[arg(long, value_parser = super::count_in::<1, { usize::MAX }>)]
    pub frames: Option<usize>,
    /// 7-Scenes folders: map every n-th frame (2: the even frames, leaving
    /// the odd ones to localize).
    #[arg(long, default_value_t = 1, value_name = "N", value_parser = super::count_in::<1, { usize::MAX }>)]
    pub frame_step: usize,
    /// 7-Scenes folders: the first frame mapped (position among the sorted
    /// frames).
    #[arg(long, default_value_t = 0, value_name = "K")]
    pub frame_offset: usize,
    /// 7-Scenes folders: drop depth within this many pixels of a depth edge
    /// (a jump above 3 % of the depth, or a hole) before mapping, where the
    /// unregistered colour camera sees the other side of the edge (4 in
    /// the README's track; default: keep all depth).
    #[arg(long, value_name = "PIXELS")]
    pub drop_depth_edges: Option<usize>,
    #[command(flatten)]
    pub encoder: super::encoders::EncoderArgs,
}

/// `omcl map rgbd` on a 7-Scenes folder.
fn sevenscenes(a: &RgbdArgs) -> anyhow::Result<()> {
    let seq = omcl::io::sevenscenes::SevenScenes::open(&a.dir)?;
    if seq.gravity_in_first_camera.is_none() {
        eprintln!(
            "note: {}: no gravity-direction.txt: the map is in the first camera's frame, not \
             z-up (a floor plan, --max-height and planar motion take z as up)",
            a.dir.display()
        );
    }
    let Some(mut src) = super::encoders::open_image_source(&a.encoder)? else {
        anyhow::bail!(
            "{}: a 7-Scenes folder gives colour images only: pass --image-model (e.g. the \
             colour classes of `omcl encode colour-model`)",
            a.dir.display()
        );
    };
    let input = pipeline::SevenScenesInput {
        pick: omcl::io::sevenscenes::FramePick {
            step: a.frame_step,
            offset: a.frame_offset,
            limit: a.frames,
        },
        max_depth: a.max_depth,
        max_height: a.max_height,
        stride: a.stride,
        depth_edges: a.drop_depth_edges.map(|r| (r, 0.03)),
    };
    let n = input.pick.positions(seq.len()).len();
    let pb = super::progress::bar(n as u64, "frames");
    let (m, stats, dropped) =
        pipeline::map_from_sevenscenes(&seq, &input, &a.build.params(None), &mut src, &mut |_| {
            pb.inc(1)
        })?;
    super::progress::finish(&pb);
    if a.drop_depth_edges.is_some() {
        println!("dropped {dropped} depth pixels at depth edges");
    }
    let mut b = a.build.clone();
    b.encoder = m.encoder().to_string();
    save(&m, &b, &stats)
}

pub fn rgbd(a: &RgbdArgs) -> anyhow::Result<()> {
    omcl::io::kitti::check_sequence_folder(&a.dir)?;
    let files = super::outputs::sequence_files(&a.dir);
    let mut inputs: Vec<_> = files
        .into_iter()
        .map(|p| (super::outputs::SEQUENCE_FILE.to_string(), p))
        .collect();
    inputs.extend(a.build.inputs());
    inputs.extend(a.encoder.inputs());
    // What --out would overwrite first: it says more than its extension.
    super::outputs::refuse_overlaps(&[("--out", &a.build.out)], &inputs)?;
    super::outputs::refuse_inside_sequence(&[("--out", &a.build.out)], &a.dir)?;
    if let Some(cache) = &a.encoder.feature_cache {
        super::outputs::refuse_folder_in_sequence("--feature-cache", cache, &a.dir)?;
    }
    a.build.check()?;
    let d = &a.dir;
    let is_sevenscenes =
        omcl::session::sequence::Layout::of(d) == omcl::session::sequence::Layout::SevenScenes;
    if is_sevenscenes {
        return sevenscenes(a);
    }
    if let Some(why) = omcl::io::rgbd::raw_tum_layout(d) {
        anyhow::bail!(why);
    }
    anyhow::ensure!(
        d.is_dir(),
        "{}: {} (map rgbd reads a sequence folder)",
        d.display(),
        if d.exists() {
            "not a folder"
        } else {
            "no such folder"
        }
    );
    anyhow::ensure!(
        ["intrinsics.txt", "poses.txt", "depth"]
            .iter()
            .any(|f| d.join(f).exists()),
        "{}: not an RGB-D sequence folder (no intrinsics.txt, poses.txt or depth/): map rgbd \
         reads intrinsics.txt, poses.txt (TUM), depth/NNNNNN.png and the frames, label images \
         (labels/ with classes.txt and embeddings.npy), feature grids (features/) or, through \
         --image-model, colour images (rgb/); a 7-Scenes folder has camera-intrinsics.txt",
        d.display()
    );
    anyhow::ensure!(
        a.frame_step <= 1 && a.frame_offset == 0 && a.drop_depth_edges.is_none(),
        "{}: --frame-step, --frame-offset and --drop-depth-edges apply to 7-Scenes folders \
         (with camera-intrinsics.txt) only",
        d.display()
    );
    let mut image = super::encoders::open_image_source(&a.encoder)?;
    let use_labels = image.is_none() && !a.use_features && d.join("labels").is_dir();
    ensure!(
        a.build.max_rows.is_none() || !use_labels,
        "--max-rows caps the rows made from raw features (features/ files, --use-features, \
         --image-model); {}'s frames are label images, whose rows are the class table's",
        d.display()
    );
    let (table, text_encoder) = if use_labels {
        match a.build.table(a.encoder.ort_lib.as_deref())? {
            Some((t, name)) => (Some(t), name),
            None => (
                Some(EmbeddingTable::read(
                    &d.join("classes.txt"),
                    &d.join("embeddings.npy"),
                )?),
                None,
            ),
        }
    } else {
        (None, None)
    };
    let features = match (&table, image.as_mut()) {
        (Some(t), _) => pipeline::RgbdFeatures::Labels(t),
        (None, Some(src)) => pipeline::RgbdFeatures::Encoder(src),
        (None, None) => pipeline::RgbdFeatures::Files,
    };
    let input = pipeline::RgbdInput {
        dir: d.clone(),
        depth_scale: a.depth_scale,
        max_depth: a.max_depth,
        max_height: a.max_height,
        stride: a.stride,
        frames: a.frames,
    };
    let n = poses::read_poses(&d.join("poses.txt"))?.trajectory.len();
    // Depth in another unit than --depth-scale says maps a room into a
    // box of a metre, or of a kilometre, without an error: said.
    if let Ok(depth) = omcl::io::rgbd::read_depth_png(&d.join("depth/000000.png"), a.depth_scale)
        && let Some(doubt) = omcl::io::rgbd::depth_scale_doubt(&depth.depth, a.depth_scale)
    {
        eprintln!("note: {}: {doubt}", d.join("depth/000000.png").display());
    }
    let pb = super::progress::bar(n.min(a.frames.unwrap_or(usize::MAX)) as u64, "frames");
    let (m, stats) = pipeline::map_from_rgbd(
        &input,
        &a.build.params(text_encoder.as_deref()),
        features,
        &mut |_| pb.inc(1),
    )?;
    super::progress::finish(&pb);
    let mut b = a.build.clone();
    b.encoder = m.encoder().to_string();
    save(&m, &b, &stats)
}

/// Where prompt words get their features: a class table, or a text encoder.
#[derive(Debug, Args)]
pub struct WordSource {
    /// Class list whose names the words are looked up in: a file (`<id>
    /// <name>` or one name a line) or a built-in list (`semantickitti`,
    /// `asprs`).
    #[arg(long, value_name = "FILE|semantickitti|asprs")]
    pub classes: Option<String>,
    /// Text features, one row per class of --classes (`.npy`); a built-in
    /// list without it uses the built-in CLIP-like table (as `omcl map
    /// cloud` does).
    #[arg(long, requires = "classes")]
    pub embeddings: Option<PathBuf>,
    /// A text encoder (`.onnx` with its `.card.json`, e.g. CLIP's) instead
    /// of a class table: any words work.
    #[arg(long, value_name = "ONNX", conflicts_with = "classes")]
    pub text_model: Option<PathBuf>,
    /// ONNX Runtime library for --text-model.
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
}

impl WordSource {
    /// The files the words' features are read from, as
    /// [`super::outputs::refuse_overlaps`] inputs.
    fn inputs(&self) -> Vec<(String, PathBuf)> {
        let mut v = table_inputs(
            self.classes.as_deref(),
            self.embeddings.as_deref(),
            self.text_model.as_deref(),
        );
        v.extend(
            self.ort_lib
                .clone()
                .map(|p| ("the --ort-lib".to_string(), p)),
        );
        v
    }

    /// Unit features of `words`, in order, for the map `m`; an unknown
    /// word is an error that lists a few known names. Words from the
    /// built-in CLIP-like table against a map in another feature space (or
    /// the other way round) are said: their similarities mean little.
    fn features(&self, words: &[String], m: &map::LanguageMap) -> anyhow::Result<FeatureDb> {
        let dim = m.db().dim();
        let (space, rows) = match (&self.text_model, &self.classes, &self.embeddings) {
            (Some(model), _, _) => {
                let (name, rows) =
                    super::encoders::text_features(model, self.ort_lib.as_deref(), words)?;
                if let Some(r) = rows.first() {
                    ensure!(
                        r.len() == dim,
                        "text encoder {name} gives {}-d features, the map has {dim}",
                        r.len()
                    );
                }
                (Some(name), rows.concat())
            }
            (None, Some(classes), embeddings) => {
                let (t, space) =
                    super::encoders::class_table(classes, embeddings.as_deref(), None, None)?;
                ensure!(
                    t.dim == dim,
                    "{}: text features have dimension {}, the map {dim}",
                    embeddings
                        .as_deref()
                        .unwrap_or(Path::new(classes))
                        .display(),
                    t.dim
                );
                let key = |n: &str| n.trim().to_ascii_lowercase().replace(['_', '-'], " ");
                let mut rows = Vec::with_capacity(words.len() * dim);
                for w in words {
                    let i = t
                        .names
                        .iter()
                        .position(|n| key(n) == key(w))
                        .with_context(|| {
                            let some: Vec<&str> =
                                t.names.iter().take(12).map(String::as_str).collect();
                            format!(
                                "word {w:?} is not in {classes} (known: {}, ...)",
                                some.join(", ")
                            )
                        })?;
                    rows.extend_from_slice(&t.data[i * dim..(i + 1) * dim]);
                }
                (space, rows)
            }
            _ => bail!(
                "words need features: pass --classes (with --embeddings for a file), or --text-model"
            ),
        };
        let builtin = |n: &str| n.starts_with("omcl-builtin-");
        let map_space = m.encoder();
        if let Some(space) = space
            && space != map_space
            && (builtin(&space) || builtin(map_space))
        {
            eprintln!(
                "note: the words' features are {}, the map's rows {}: two feature spaces, whose \
                 similarities mean little; give the words from the table the map was built with \
                 (its --embeddings, or its --text-model)",
                match builtin(&space) {
                    true => format!("the built-in CLIP-like table's ({space})"),
                    false => format!("{space}'s"),
                },
                match builtin(map_space) {
                    true => format!("the built-in CLIP-like table's ({map_space})"),
                    false => format!("in {map_space}'s space"),
                }
            );
        }
        Ok(FeatureDb::from_rows(dim, 0.0, rows)?)
    }
}

fn parse_words(words: &[String], file: Option<&Path>) -> anyhow::Result<Vec<String>> {
    let mut out: Vec<String> = words
        .iter()
        .flat_map(|w| w.split(','))
        .map(|w| w.trim().to_string())
        .filter(|w| !w.is_empty())
        .collect();
    if let Some(f) = file {
        let text = omcl::io::bounded_read::read_text(f)
            .with_context(|| format!("reading {}", f.display()))?;
        out.extend(
            text.lines()
                .flat_map(|l| l.split(','))
                .map(|w| w.trim().to_string())
                .filter(|w| !w.is_empty() && !w.starts_with('#')),
        );
    }
    ensure!(!out.is_empty(), "no prompt words given");
    Ok(out)
}

#[derive(Debug, Args)]
pub struct GroundArgs {
    /// The map to ground.
    pub map: PathBuf,
    /// Prompt words, separated by commas or spaces as separate arguments.
    pub words: Vec<String>,
    /// A file of prompt words (one per line or comma-separated).
    #[arg(long)]
    pub prompt_file: Option<PathBuf>,
    #[command(flatten)]
    pub source: WordSource,
    /// Drop voxels whose best similarity to any word is below this.
    #[arg(long, default_value_t = 0.5, value_parser = super::cosine)]
    pub min_similarity: f32,
    /// Where to write the grounded map.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Replace --out even when it is a file that is not an omcl map (a map
    /// is replaced without it).
    #[arg(long)]
    pub force: bool,
}

pub fn ground(a: &GroundArgs) -> anyhow::Result<()> {
    let mut inputs = vec![("the map".to_string(), a.map.clone())];
    inputs.extend(
        a.prompt_file
            .clone()
            .map(|p| ("the --prompt-file".to_string(), p)),
    );
    inputs.extend(a.source.inputs());
    super::outputs::refuse_overlaps(&[("--out", &a.out)], &inputs)?;
    super::outputs::check_map_out("--out", &a.out, a.force)?;
    let mut m = map::load(&a.map)?;
    let words = parse_words(&a.words, a.prompt_file.as_deref())?;
    let prompts = a.source.features(&words, &m)?;
    let old_counts = m.row_counts();
    let rep = map::ground(&mut m, &prompts, a.min_similarity)?;
    ensure!(
        !m.is_empty(),
        "grounding on {words:?} at --min-similarity {} dropped every voxel; no map written",
        a.min_similarity
    );
    map::save(&m, &a.out)?;
    println!(
        "wrote {}: {} -> {}, kept {}, dropped {}",
        a.out.display(),
        super::count(rep.old_rows, "row"),
        super::count(rep.new_rows, "word"),
        super::count(rep.kept, "voxel"),
        rep.dropped
    );
    // Every row takes its most similar word, however loosely it is
    // described: voxels whose row no word describes closely (the paper's
    // rho, 0.9) mean the words leave out what the map mostly is.
    let mut weak = vec![0usize; words.len()];
    for (r, m) in rep.row_map.iter().enumerate() {
        if let Some((p, sim)) = *m
            && sim < CLOSE
        {
            weak[p as usize] += old_counts.get(r).copied().unwrap_or(0);
        }
    }
    let loose: usize = weak.iter().sum();
    if loose * 4 > rep.kept
        && let Some((w, &n)) = weak.iter().enumerate().max_by_key(|(_, n)| **n)
    {
        eprintln!(
            "note: {:.1} % of the voxels kept are described by no word closer than a cosine of \
             {CLOSE} ({:.1} % now labelled {:?}, the closest of the words); name what the map \
             mostly is (walls, floor, road, ...) among the words, or raise --min-similarity \
             (now {}) to drop what none of them describes",
            100.0 * loose as f64 / rep.kept.max(1) as f64,
            100.0 * n as f64 / rep.kept.max(1) as f64,
            words[w],
            a.min_similarity
        );
    }
    Ok(())
}

/// A word describes a map row closely from this cosine on (the paper's
/// prompt threshold rho).
const CLOSE: f32 = 0.9;

#[derive(Debug, Args)]
pub struct QueryArgs {
    /// The map to query.
    pub map: PathBuf,
    /// Words; a voxel's heat is its best similarity to any of them.
    pub words: Vec<String>,
    #[command(flatten)]
    pub source: WordSource,
    /// The file to write, in the format its name says: `.ply` (voxel
    /// centres coloured blue to red), or `.las`/`.laz`: the same in the survey's CRS
    /// and units (a map built from LAS keeps them), the similarity as
    /// intensity (0-65535 for 0-1) and the feature row as point source id.
    #[arg(long, short)]
    pub out: PathBuf,
}

fn voxel_cloud(m: &LanguageMap, colors: Vec<[u8; 3]>) -> PointCloud {
    let g = m.grid();
    let points = m.cells().iter().map(|&c| g.center(c).into()).collect();
    let mut cloud = PointCloud::from_points(points);
    cloud.colors = Some(colors);
    cloud.labels = Some(m.rows().to_vec());
    cloud
}

/// The ASPRS class code of every voxel of `m`, for a map built on the
/// built-in `asprs` list's features (`map cloud --classes asprs`): its
/// row's class, or for a row that mixes classes (a voxel that held points
/// of several) the nearest class, which a note says. `None` for any other
/// map (its LAS export leaves classification 0, "never classified").
fn asprs_classification(out: &Path, m: &LanguageMap) -> anyhow::Result<Option<Vec<u8>>> {
    let Some((omcl::io::labels::BuiltinClasses::Asprs, rows)) =
        super::encoders::builtin_row_classes(m)?
    else {
        return Ok(None);
    };
    // ASPRS codes fit LAS's legacy 5 bits (the built-in list ends at 22).
    let codes: Vec<u8> = rows
        .iter()
        .map(|r| {
            r.code()
                .and_then(|c| u8::try_from(c).ok())
                .filter(|&c| c < 32)
        })
        .map(|c| c.unwrap_or(0))
        .collect();
    let counts = m.row_counts();
    let mixed: usize = rows
        .iter()
        .zip(&counts)
        .filter(|(r, _)| r.classes.is_empty())
        .map(|(_, &n)| n)
        .sum();
    if mixed > 0 {
        eprintln!(
            "note: {}: {mixed} of {} voxels held points of several classes (their feature a \
             mix): each is classified as the class nearest its feature",
            out.display(),
            m.len()
        );
    }
    // A coarse --tau merges classes whose features are near (water and
    // snow at 0.1): their voxels are one row, classified as its first.
    let merged: Vec<String> = rows
        .iter()
        .zip(&counts)
        .filter(|(r, n)| r.classes.len() > 1 && **n > 0)
        .map(|(r, n)| {
            let names: Vec<String> = r
                .classes
                .iter()
                .map(|c| format!("{} ({})", c.name, c.id))
                .collect();
            format!(
                "{n} voxels of {} as {}",
                names.join(" or "),
                r.classes[0].id
            )
        })
        .collect();
    if !merged.is_empty() {
        eprintln!(
            "note: {}: the map's tau ({}) merged classes into one row: {}",
            out.display(),
            m.db().tau(),
            merged.join("; ")
        );
    }
    Ok(Some(m.rows().iter().map(|&r| codes[r as usize]).collect()))
}

/// Writes the voxel centres of `m` with `colors` to `out`: LAS/LAZ (by
/// its name) in the survey's CRS and units, the feature row as point
/// source id (when rows fit 16 bits) and `intensity` if given; else PLY,
/// the row as `label`.
fn write_voxels(
    out: &Path,
    m: &LanguageMap,
    colors: Vec<[u8; 3]>,
    intensity: Option<Vec<u16>>,
) -> anyhow::Result<()> {
    let ext = out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if matches!(ext.as_deref(), Some("las" | "laz")) {
        let g = m.grid();
        if m.db().len() > 1 << 16 {
            eprintln!(
                "note: {}: {} feature rows do not fit LAS's 16-bit point source id: it is left 0",
                out.display(),
                m.db().len()
            );
        }
        let pts = omcl::io::las::LasPoints {
            points: m.cells().iter().map(|&c| g.center(c).into()).collect(),
            colors,
            intensity,
            source_id: (m.db().len() <= 1 << 16)
                .then(|| m.rows().iter().map(|&r| r as u16).collect()),
            classification: asprs_classification(out, m)?,
        };
        omcl::io::las::write_las(out, &pts, m.georef())?;
        return Ok(());
    }
    ply::write_ply(out, &voxel_cloud(m, colors))?;
    if let Some(geo) = m.georef() {
        eprintln!(
            "note: {}: coordinates in metres of {} (a PLY carries no CRS); write .las or .laz \
             for the survey's own units and CRS records",
            out.display(),
            geo.crs
        );
    }
    Ok(())
}

pub fn query(a: &QueryArgs) -> anyhow::Result<()> {
    let mut inputs = vec![("the map".to_string(), a.map.clone())];
    inputs.extend(a.source.inputs());
    super::outputs::refuse_overlaps(&[("--out", &a.out)], &inputs)?;
    super::outputs::refuse_replacing_survey("--out", &a.out)?;
    super::outputs::check_cloud_name("--out", &a.out)?;
    let m = map::load(&a.map)?;
    let words = parse_words(&a.words, None)?;
    let prompts = a.source.features(&words, &m)?;
    let best = map::query::best_similarity(&m, &prompts)?;
    let heat = colors::normalize_range(&best);
    let cols = heat.iter().map(|&t| colors::heat_color(t)).collect();
    // LAS intensity: the similarity, 0 (or below) to 1.
    let intensity = best
        .iter()
        .map(|&b| (b.clamp(0.0, 1.0) * 65535.0).round() as u16)
        .collect();
    write_voxels(&a.out, &m, cols, Some(intensity))?;
    let hot = map::query::count_near_best(&best, 0.9);
    println!(
        "wrote {}: {} voxels coloured by similarity to {words:?} ({hot} within 10 % of the best)",
        a.out.display(),
        m.len()
    );
    Ok(())
}

#[derive(Debug, Args)]
pub struct ExportArgs {
    /// The map to export.
    pub map: PathBuf,
    /// The file to write, in the format its name says: `.ply` (voxel
    /// centres coloured by feature row, the row also as the `label`
    /// property), or `.las`/`.laz`: the same in the survey's CRS and units (a map built from
    /// LAS keeps them), the row as point source id.
    #[arg(long, short)]
    pub out: PathBuf,
}

pub fn export(a: &ExportArgs) -> anyhow::Result<()> {
    super::outputs::refuse_overlaps(&[("--out", &a.out)], &[("the map", &a.map)])?;
    super::outputs::refuse_replacing_survey("--out", &a.out)?;
    super::outputs::check_cloud_name("--out", &a.out)?;
    let m = map::load(&a.map)?;
    let cols = m.rows().iter().map(|&r| colors::row_color(r)).collect();
    write_voxels(&a.out, &m, cols, None)?;
    println!(
        "wrote {}: {}, {}",
        a.out.display(),
        super::count(m.len(), "voxel"),
        super::count(m.db().len(), "row")
    );
    Ok(())
}

#[derive(Debug, Args)]
pub struct ClassesArgs {
    /// A built-in class list (`semantickitti`, `asprs`) or a class-list file.
    #[arg(value_name = "semantickitti|asprs|FILE")]
    pub list: String,
    /// Write `classes.txt` and `embeddings.npy` into this folder, made if
    /// missing (e.g. a KITTI sequence whose labels_2/ label images `omcl
    /// localize` reads); without it the list is printed.
    #[arg(long, short, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// The features of the list (`.npy`, one row a class); default for a
    /// built-in list: the built-in CLIP-like table.
    #[arg(long)]
    pub embeddings: Option<PathBuf>,
    /// A text encoder (`.onnx` with its `.card.json`) that embeds the names.
    #[arg(long, value_name = "ONNX", conflicts_with = "embeddings")]
    pub text_model: Option<PathBuf>,
    /// ONNX Runtime library for --text-model.
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
    /// Replace classes.txt and embeddings.npy if they exist.
    #[arg(long)]
    pub force: bool,
}

pub fn classes(a: &ClassesArgs) -> anyhow::Result<()> {
    let Some(dir) = &a.out else {
        let (_, ids, names) = super::encoders::class_list(&a.list)?;
        for (i, n) in ids.iter().zip(&names) {
            println!("{i} {n}");
        }
        return Ok(());
    };
    let (t, _) = super::encoders::class_table(
        &a.list,
        a.embeddings.as_deref(),
        a.text_model.as_deref(),
        a.ort_lib.as_deref(),
    )?;
    write_table(dir, &t, a.force)
}

/// Writes `dir/classes.txt` and `dir/embeddings.npy` (refusing to replace
/// them unless `force`).
fn write_table(dir: &Path, t: &EmbeddingTable, force: bool) -> anyhow::Result<()> {
    let (txt, npy) = (dir.join("classes.txt"), dir.join("embeddings.npy"));
    for p in [&txt, &npy] {
        ensure!(
            force || !p.exists(),
            "{} exists; pass --force to replace it",
            p.display()
        );
    }
    // Made where missing, as `omcl sim --out` makes its folder.
    super::outputs::create_folder("--out", dir)?;
    let text: String = t
        .ids
        .iter()
        .zip(&t.names)
        .map(|(i, n)| format!("{i} {n}\n"))
        .collect();
    omcl::io::npy::write_npy(&npy, &[t.ids.len(), t.dim], &t.data)?;
    omcl::io::atomic::write(&txt, text.as_bytes())
        .with_context(|| format!("writing {}", txt.display()))?;
    println!(
        "wrote {} and {}: {} classes x {} dims",
        txt.display(),
        npy.display(),
        t.ids.len(),
        t.dim
    );
    Ok(())
}

#[derive(Debug, Args)]
pub struct ProjectArgs {
    /// A SemanticKITTI sequence folder: velodyne/, labels/, calib.txt (with
    /// P2), poses.txt.
    pub sequence: PathBuf,
    /// Folder of the label images (default: SEQUENCE/labels_2, what
    /// `omcl localize` reads). The folder that holds it (SEQUENCE by
    /// default) also gets the built-in SemanticKITTI class table
    /// (classes.txt, embeddings.npy), which `omcl localize` reads beside
    /// labels_2/, unless it has one. Nothing is written into SEQUENCE
    /// when OUT is elsewhere, nor into a folder marked read-only.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Use at most this many scans (and make that many images).
    #[arg(long, value_parser = super::count_in::<1, { usize::MAX }>)]
    pub frames: Option<usize>,
    /// Points farther than this from the camera are left out (m).
    #[arg(long, default_value_t = 80.0)]
    pub max_range: f64,
    /// Spacing the aggregated scans are down-sampled to, which sizes the
    /// splats (m).
    #[arg(long, default_value_t = 0.1)]
    pub spacing: f64,
    /// Keep the classes the authors drop (unlabeled, outlier, moving).
    #[arg(long)]
    pub keep_all: bool,
    /// Replace label images already in the output folder.
    #[arg(long)]
    pub force: bool,
}

pub fn project(a: &ProjectArgs) -> anyhow::Result<()> {
    use omcl::mapping::projection::ProjectionParams;
    ensure!(
        a.max_range.is_finite() && a.max_range > 0.0,
        "--max-range must be a positive number of metres, got {}",
        a.max_range
    );
    ensure!(
        a.spacing.is_finite() && a.spacing > 0.0,
        "--spacing must be a positive number of metres, got {}",
        a.spacing
    );
    let out = a.out.clone().unwrap_or_else(|| a.sequence.join("labels_2"));
    omcl::mapping::pipeline::refuse_sequence_input(&out, &a.sequence)?;
    let has_images = std::fs::read_dir(&out)
        .map(|mut d| d.any(|e| e.is_ok_and(|e| e.path().extension().is_some_and(|x| x == "png"))))
        .unwrap_or(false);
    ensure!(
        a.force || !has_images,
        "{} already holds label images; pass --force to replace them",
        out.display()
    );
    let input = CloudInput {
        path: a.sequence.clone(),
        frames: a.frames,
        keep_all: a.keep_all,
        ..Default::default()
    };
    let params = ProjectionParams {
        max_range: a.max_range,
        spacing: a.spacing,
        ..ProjectionParams::default()
    };
    // Checked before anything is written: the folder opens as a sequence.
    omcl::io::kitti::KittiSequence::open(&a.sequence)?;
    // The class table goes beside the label images' folder.
    let table_dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let needs_table =
        !table_dir.join("classes.txt").exists() && !table_dir.join("embeddings.npy").exists();
    super::outputs::refuse_read_only("--out", &out)?;
    if needs_table {
        super::outputs::refuse_read_only("the class table's folder", &table_dir)?;
    }
    // The outermost folder this run makes: `out`, or a missing parent of
    // it (`-o new/sub/labels_2`).
    let made = out
        .ancestors()
        .take_while(|d| !d.as_os_str().is_empty() && !d.exists())
        .last()
        .map(Path::to_path_buf);
    super::outputs::create_folder("--out", &out)?;
    // The folder of the images goes if the run is interrupted, not only
    // when it fails (with what is in it: only this run writes there). Its
    // new parents are not registered: another run may write into them
    // meanwhile (`-o copies/01/labels_2` beside `-o copies/00/labels_2`).
    let _interrupt = made
        .is_some()
        .then(|| omcl::io::atomic::remove_on_interrupt(&out));
    let t0 = std::time::Instant::now();
    // The scans are read and merged before the first frame is projected.
    let reading = super::progress::spinner("merging the scans");
    let pb = super::progress::bar_of(0, "projecting", "frames");
    let s = pipeline::project_sequence_labels(&input, &params, &out, &mut |done, total| {
        super::progress::finish(&reading);
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    });
    match &s {
        Ok(_) => super::progress::finish(&pb),
        Err(_) => {
            reading.finish_and_clear();
            pb.finish_and_clear();
        }
    }
    let s = s.inspect_err(|_| {
        if let Some(top) = &made {
            // Nothing is written before the scans are read: a failure
            // leaves the new folders empty, and they go (only empty ones).
            for d in out.ancestors() {
                let _ = std::fs::remove_dir(d);
                if d == top.as_path() {
                    break;
                }
            }
        }
    })?;
    let secs = t0.elapsed().as_secs_f64();
    println!(
        "wrote {} label images to {} from {} labelled points ({:.1} % of pixels labelled; {:.2} s, {:.0} ms a frame)",
        s.frames,
        out.display(),
        s.points,
        100.0 * s.coverage,
        secs,
        1e3 * secs / s.frames.max(1) as f64
    );
    if needs_table {
        let (t, _) = super::encoders::class_table("semantickitti", None, None, None)?;
        write_table(&table_dir, &t, false)?;
    }
    // Label images written into a copy (`-o COPY/labels_2`): the copy
    // gets the sequence's calibration, poses and times as links, so that
    // `omcl localize --sequence COPY` reads it.
    let same = |p: &Path, q: &Path| match (p.canonicalize(), q.canonicalize()) {
        (Ok(p), Ok(q)) => p == q,
        _ => false,
    };
    if out.file_name().is_some_and(|n| n == "labels_2") && !same(&table_dir, &a.sequence) {
        let linked =
            omcl::io::kitti::link_sequence_files(&a.sequence, &table_dir).with_context(|| {
                format!("linking the sequence's files into {}", table_dir.display())
            })?;
        if !linked.is_empty() {
            println!(
                "linked {} of {} into {}: `omcl localize --sequence {}` reads it",
                linked.join(", "),
                a.sequence.display(),
                table_dir.display(),
                table_dir.display()
            );
        }
    }
    Ok(())
}
