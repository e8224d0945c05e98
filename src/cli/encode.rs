//! `omcl encode ...`: run ONNX encoders on words, images and point clouds
//! and write the features as `.npy`.

use omcl::encode::Encoder as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail, ensure};
use clap::{Args, Subcommand};

use omcl::encode::runtime::find_library;
use omcl::encode::tokenize::CONTEXT_LENGTH;
use omcl::encode::{
    ClipTokenizer, FeatureCache, ImageEncoder, OnnxModel, PointEncoder, Runtime, TextEncoder,
};
use omcl::io::npy::{read_npy, write_npy};
use omcl::io::rgb::read_rgb;

#[derive(Debug, Subcommand)]
pub enum EncodeCommand {
    /// Words or prompts to unit-length features, one row each ([N, F] .npy).
    Text(TextArgs),
    /// RGB images to per-pixel features ([H, W, F] .npy each).
    Image(ImageArgs),
    /// A point cloud to per-point features ([N, F] .npy).
    Points(PointArgs),
    /// CLIP token ids of words (no model needed).
    Tokens(TokensArgs),
    /// The ONNX Runtime library in use and a model's inputs and outputs.
    Info(InfoArgs),
    /// Fit colour classes (CIE Lab k-means) on a 7-Scenes folder's mapping
    /// (even) frames and write them as an ONNX image encoder with its card.
    /// Not open-vocabulary: no words map to its features.
    ColourModel(ColourModelArgs),
}

#[derive(Debug, Args)]
pub struct ColourModelArgs {
    /// A 7-Scenes sequence folder (frame-NNNNNN.color.jpg, .depth.png,
    /// .pose.txt, camera-intrinsics.txt).
    #[arg(long)]
    pub frames: PathBuf,
    /// Number of colour classes.
    #[arg(short, long, default_value_t = 10,
          value_parser = super::count_in::<1, { omcl::encode::colour::MAX_CLASSES }>)]
    pub k: usize,
    /// Length of each class's embedding (seeded Gaussian draws, unit length).
    #[arg(long, default_value_t = 32,
          value_parser = super::count_in::<2, { omcl::encode::colour::MAX_DIM }>)]
    pub dim: usize,
    /// Seed of k-means and the embeddings.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Fit on the first N frames only (their even ones).
    #[arg(long)]
    pub first: Option<usize>,
    /// The model's input size WIDTHxHEIGHT (the card resizes to it with a
    /// box filter).
    #[arg(long, default_value = "320x240")]
    pub size: String,
    /// Output model (.onnx); the card is written beside it (.card.json).
    #[arg(short, long)]
    pub out: PathBuf,
    /// Also write the classes as a class table in this folder
    /// (classes.txt, one `<id> colour-<id>` line a class, and embeddings.npy,
    /// `K x F`): the table `omcl localize --baseline --baseline-classes`
    /// labels pixels and plan columns with (a 7-Scenes folder has none).
    /// An existing table there is refused, never replaced.
    #[arg(long, value_name = "DIR")]
    pub class_table: Option<PathBuf>,
}

/// Options every command that runs a model shares.
#[derive(Debug, Clone, Args)]
pub struct OrtArgs {
    /// ONNX Runtime shared library (libonnxruntime.so.*); overrides
    /// ORT_DYLIB_PATH and the copy `make deps` installs in .deps/.
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
    /// Threads per model run (0 = one per physical core; at most 1024).
    #[arg(long, default_value_t = 0, value_parser = super::count_in::<0, 1024>)]
    pub threads: usize,
}

#[derive(Debug, Args)]
pub struct TextArgs {
    /// Words or prompts; each becomes one feature row.
    #[arg(required = true)]
    pub words: Vec<String>,
    /// Text encoder (.onnx with a .card.json beside it).
    #[arg(long)]
    pub model: PathBuf,
    /// Output .npy, [N, F] float32.
    #[arg(short, long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub ort: OrtArgs,
}

#[derive(Debug, Args)]
pub struct ImageArgs {
    /// PNG or JPEG images.
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Image encoder (.onnx with a .card.json beside it).
    #[arg(long)]
    pub model: PathBuf,
    /// Output .npy for a single image.
    #[arg(short, long, conflicts_with = "cache")]
    pub out: Option<PathBuf>,
    /// Feature cache directory: `<image stem>.npy` + `.json` per image;
    /// images already cached are skipped.
    #[arg(long)]
    pub cache: Option<PathBuf>,
    #[command(flatten)]
    pub ort: OrtArgs,
}

#[derive(Debug, Args)]
pub struct PointArgs {
    /// Point cloud: .npy [N, 3] or [N, 6] (xyz, rgb), or .bin float32 rows of
    /// x y z r g b (ScanNet export).
    pub cloud: PathBuf,
    /// Point encoder (.onnx with a .card.json beside it).
    #[arg(long)]
    pub model: PathBuf,
    /// Output .npy, [N, F] float32.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Value of full colour intensity in the file (255 for 8-bit colours,
    /// 1 for [0, 1]); by default 255 if any colour exceeds 1, else 1.
    #[arg(long)]
    pub color_max: Option<f32>,
    #[command(flatten)]
    pub ort: OrtArgs,
}

#[derive(Debug, Args)]
pub struct TokensArgs {
    /// Words or prompts.
    #[arg(required = true)]
    pub words: Vec<String>,
}

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// A model to describe (optional).
    pub model: Option<PathBuf>,
    #[command(flatten)]
    pub ort: OrtArgs,
}

/// Loads ONNX Runtime once for the process: `--ort-lib` if given, else
/// `ORT_DYLIB_PATH`, else the copy `make deps` installs. Call before any
/// encoder is built; later calls return the runtime already loaded.
pub fn init_runtime(ort_lib: Option<&Path>) -> anyhow::Result<&'static Runtime> {
    Ok(Runtime::init(ort_lib)?)
}

pub fn run(cmd: EncodeCommand) -> anyhow::Result<()> {
    match cmd {
        EncodeCommand::Text(a) => text(&a),
        EncodeCommand::Image(a) => image(&a),
        EncodeCommand::Points(a) => points(&a),
        EncodeCommand::Tokens(a) => tokens(&a),
        EncodeCommand::Info(a) => info(&a),
        EncodeCommand::ColourModel(a) => colour_model(&a),
    }
}

fn text(a: &TextArgs) -> anyhow::Result<()> {
    super::outputs::refuse_overlaps(
        &[("--out", &a.out)],
        &super::outputs::model_files("--model", Some(&a.model)),
    )?;
    let rt = init_runtime(a.ort.ort_lib.as_deref())?;
    let mut enc = TextEncoder::load(rt, &a.model, a.ort.threads)?;
    let words: Vec<&str> = a.words.iter().map(String::as_str).collect();
    let feats = enc.encode(&words)?;
    let data: Vec<f32> = feats.iter().flatten().copied().collect();
    write_npy(&a.out, &[feats.len(), enc.feature_dim()], &data)?;
    eprintln!(
        "wrote {} ({} x {}, encoder {})",
        a.out.display(),
        feats.len(),
        enc.feature_dim(),
        enc.card().name
    );
    Ok(())
}

fn image(a: &ImageArgs) -> anyhow::Result<()> {
    if a.out.is_none() && a.cache.is_none() {
        bail!("give --out FILE.npy (one image) or --cache DIR (any number)");
    }
    if a.out.is_some() && a.images.len() != 1 {
        bail!(
            "--out takes one image; use --cache DIR for {} images",
            a.images.len()
        );
    }
    if let Some(out) = &a.out {
        let mut inputs = super::outputs::model_files("--model", Some(&a.model));
        inputs.push(("the image".to_string(), a.images[0].clone()));
        super::outputs::refuse_overlaps(&[("--out", out)], &inputs)?;
    }
    let rt = init_runtime(a.ort.ort_lib.as_deref())?;
    let mut enc = ImageEncoder::load(rt, &a.model, a.ort.threads)?;
    if let Some(out) = &a.out {
        let img = read_rgb(&a.images[0])?;
        let map = enc.encode(&img)?;
        write_npy(out, &map.shape(), &map.data)?;
        eprintln!(
            "wrote {} ({:?}; cell (0, 0) at image ({}, {}), cells {} x {} pixels)",
            out.display(),
            map.shape(),
            map.origin[0],
            map.origin[1],
            map.cell_size[0],
            map.cell_size[1]
        );
        return Ok(());
    }
    let dir = a.cache.as_deref().context("no cache directory")?;
    let model = omcl::encode::cache::model_stamp(&a.model)?;
    let cache = FeatureCache::new(dir, &enc.card().name, &model)?;
    let (mut computed, mut reused) = (0usize, 0usize);
    for path in &a.images {
        let frame = path
            .file_stem()
            .and_then(|s| s.to_str())
            .with_context(|| format!("{}: no usable file name", path.display()))?;
        let image = omcl::encode::cache::stamp(&[path])?;
        if cache.load(frame, Some(&image))?.is_some() {
            reused += 1;
            continue;
        }
        let img = read_rgb(path)?;
        let map = enc
            .encode(&img)
            .with_context(|| format!("encoding {}", path.display()))?;
        cache.store(frame, &map, Some(&image))?;
        computed += 1;
    }
    eprintln!(
        "{}: {} encoded, {reused} already cached",
        dir.display(),
        super::count(computed, "image")
    );
    Ok(())
}

/// Points (metres) and their colours in [0, 1].
type Cloud = (Vec<[f32; 3]>, Vec<[f32; 3]>);

/// Reads xyz and rgb (scaled to [0, 1]) from a .npy or ScanNet-style .bin.
fn read_cloud(path: &Path, color_max: Option<f32>) -> anyhow::Result<Cloud> {
    let (rows, cols, data) = if path.extension().is_some_and(|e| e == "npy") {
        let a = read_npy(path)?;
        let [n, c] = a.shape[..] else {
            bail!(
                "{}: shape {:?}, expected [N, 3] or [N, 6]",
                path.display(),
                a.shape
            );
        };
        (n, c, a.data)
    } else {
        let bytes = omcl::io::bounded_read::read_regular(path)
            .with_context(|| path.display().to_string())?;
        if bytes.len() % 24 != 0 {
            bail!(
                "{}: {} bytes is not a whole number of float32 x y z r g b rows",
                path.display(),
                bytes.len()
            );
        }
        let data: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        (data.len() / 6, 6, data)
    };
    if cols != 3 && cols != 6 {
        bail!(
            "{}: {cols} columns, expected 3 (xyz) or 6 (xyz rgb)",
            path.display()
        );
    }
    let mut pts = Vec::with_capacity(rows);
    let mut rgb = Vec::with_capacity(rows);
    for r in data.chunks_exact(cols) {
        pts.push([r[0], r[1], r[2]]);
        if cols == 6 {
            rgb.push([r[3], r[4], r[5]]);
        }
    }
    let max = color_max.unwrap_or_else(|| {
        if rgb.iter().flatten().any(|&c| c > 1.0) {
            255.0
        } else {
            1.0
        }
    });
    if !(max.is_finite() && max > 0.0) {
        bail!("--color-max must be positive");
    }
    rgb.iter_mut().flatten().for_each(|c| *c /= max);
    Ok((pts, rgb))
}

fn points(a: &PointArgs) -> anyhow::Result<()> {
    super::outputs::refuse_overlaps(
        &[("--out", &a.out)],
        &[("the cloud", &a.cloud), ("the model", &a.model)],
    )?;
    let (pts, rgb) = read_cloud(&a.cloud, a.color_max)?;
    let rt = init_runtime(a.ort.ort_lib.as_deref())?;
    let mut enc = PointEncoder::load(rt, &a.model, a.ort.threads)?;
    let feats = enc.encode(&pts, &rgb)?;
    write_npy(&a.out, &[pts.len(), enc.feature_dim()], &feats)?;
    eprintln!(
        "wrote {} ({} x {})",
        a.out.display(),
        pts.len(),
        enc.feature_dim()
    );
    Ok(())
}

fn tokens(a: &TokensArgs) -> anyhow::Result<()> {
    let tok = ClipTokenizer::new();
    for w in &a.words {
        let (ids, cut) = tok.tokenize(w, CONTEXT_LENGTH);
        let end = ids.iter().rposition(|&x| x != 0).map_or(0, |i| i + 1);
        let shown: Vec<String> = ids[..end].iter().map(u32::to_string).collect();
        println!(
            "{w:?}: {}{}",
            shown.join(" "),
            if cut { " (truncated)" } else { "" }
        );
    }
    Ok(())
}

fn info(a: &InfoArgs) -> anyhow::Result<()> {
    let lib = find_library(a.ort.ort_lib.as_deref())?;
    println!("ONNX Runtime library: {}", lib.display());
    let rt = init_runtime(a.ort.ort_lib.as_deref())?;
    if let Some(model) = &a.model {
        let m = OnnxModel::load(rt, model, a.ort.threads)?;
        for s in m.inputs() {
            println!("input  {}: {:?} {}", s.name, s.elem, s.dims_text());
        }
        for s in m.outputs() {
            println!("output {}: {:?} {}", s.name, s.elem, s.dims_text());
        }
        match omcl::encode::ModelCard::for_model(model) {
            Ok(card) => println!(
                "card: {} encoder `{}`, {}-d features",
                format!("{:?}", card.kind).to_lowercase(),
                card.name,
                card.feature_dim
            ),
            Err(e) => println!("card: {e}"),
        }
    }
    Ok(())
}

/// Parses `WIDTHxHEIGHT` (both positive).
pub fn parse_size(s: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .with_context(|| format!("size {s:?}: expected WIDTHxHEIGHT, e.g. 320x240"))?;
    let p = |v: &str| {
        v.parse::<u32>()
            .ok()
            .filter(|n| *n > 0)
            .with_context(|| format!("size {s:?}: {v:?} is not a positive number of pixels"))
    };
    Ok((p(w)?, p(h)?))
}

fn colour_model(a: &ColourModelArgs) -> anyhow::Result<()> {
    use omcl::experiment::sevenscenes::{TrackSpec, fit_colour_model, split};
    let size = parse_size(&a.size)?;
    let card = omcl::encode::card::card_path_for(&a.out);
    let table = a
        .class_table
        .as_ref()
        .map(|d| (d.join("classes.txt"), d.join("embeddings.npy")));
    let mut outputs = vec![("--out", a.out.as_path()), ("--out's card", card.as_path())];
    if let Some((c, e)) = &table {
        outputs.push(("--class-table's classes.txt", c.as_path()));
        outputs.push(("--class-table's embeddings.npy", e.as_path()));
    }
    super::outputs::refuse_overlaps(&outputs, &[] as &[(&str, &Path)])?;
    if let Some((c, e)) = &table {
        // A class table is data (a sequence's labels are read through it):
        // never replaced, and its folder made before the fit.
        for f in [c, e] {
            ensure!(
                !f.exists(),
                "{} exists: --class-table writes a new class table and replaces none (a \
                 sequence's labels are read through its table); give a new folder",
                f.display()
            );
        }
        let dir = a.class_table.as_deref().unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    super::outputs::refuse_inside_sequence(&outputs, &a.frames)?;
    let seq = omcl::io::sevenscenes::SevenScenes::open(&a.frames)?;
    let n = seq.len().min(a.first.unwrap_or(usize::MAX));
    let (mapping, _) = split(n, 1);
    let spec = TrackSpec {
        classes: a.k,
        dim: a.dim,
        colour_seed: a.seed,
        model_size: size,
        ..TrackSpec::default()
    };
    let classes = fit_colour_model(&seq, &mapping, &spec, &a.out)?;
    println!(
        "wrote {} and {}: {} colour classes (CIE Lab k-means on {} mapping frames), {}-d embeddings",
        a.out.display(),
        omcl::encode::card::card_path_for(&a.out).display(),
        classes.len(),
        mapping.len(),
        classes.dim
    );
    for (i, c) in classes.centroids.iter().enumerate() {
        println!("class {i}: L {:.1} a {:.1} b {:.1}", c[0], c[1], c[2]);
    }
    if let Some((c, e)) = &table {
        let list: String = (0..classes.len())
            .map(|i| format!("{i} colour-{i}\n"))
            .collect();
        omcl::io::atomic::write(c, list.as_bytes())
            .with_context(|| format!("writing {}", c.display()))?;
        omcl::io::npy::write_npy(e, &[classes.len(), classes.dim], &classes.embeddings)
            .with_context(|| format!("writing {}", e.display()))?;
        println!("wrote the class table {} and {}", c.display(), e.display());
    }
    Ok(())
}
