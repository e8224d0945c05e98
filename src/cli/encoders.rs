//! ONNX encoders as feature sources of the map and localize commands.

use omcl::encode::Encoder as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;

use omcl::encode::image::ImageEncoder;
use omcl::encode::text::TextEncoder;
use omcl::io::labels::{BuiltinClasses, EmbeddingTable, read_class_list};

/// Options that select ONNX encoders.
#[derive(Debug, Args, Default)]
pub struct EncoderArgs {
    /// Image encoder (`.onnx` with its `.card.json`): per-pixel features
    /// from the sequence's camera images (rgb/NNNNNN.png; KITTI:
    /// image_2/NNNNNN.png; 7-Scenes: frame-NNNNNN.color.jpg) instead of
    /// labels or feature files.
    #[arg(long, value_name = "ONNX")]
    pub image_model: Option<PathBuf>,
    /// Cache folder for image-encoder features (NNNNNN.npy; reused when
    /// present and made by the same encoder).
    #[arg(long, value_name = "DIR", requires = "image_model")]
    pub feature_cache: Option<PathBuf>,
    /// ONNX Runtime library (overrides ORT_DYLIB_PATH and .deps/).
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
}

impl EncoderArgs {
    /// The files these options read (the image encoder, its card, the
    /// runtime library), as [`super::outputs::refuse_overlaps`] inputs.
    pub fn inputs(&self) -> Vec<(String, PathBuf)> {
        let mut v = super::outputs::model_files("--image-model", self.image_model.as_deref());
        v.extend(
            self.ort_lib
                .clone()
                .map(|p| ("the --ort-lib".to_string(), p)),
        );
        v
    }
}

pub use omcl::encode::cache::ImageSource;

/// The image encoder of `args` with its cache, if one was given.
pub fn open_image_source(args: &EncoderArgs) -> anyhow::Result<Option<ImageSource>> {
    let Some(model) = &args.image_model else {
        return Ok(None);
    };
    let rt = super::encode::init_runtime(args.ort_lib.as_deref())?;
    let encoder = ImageEncoder::load(rt, model, 0)?;
    let stamp = match args.feature_cache {
        Some(_) => omcl::encode::cache::model_stamp(model)?,
        None => String::new(),
    };
    Ok(Some(ImageSource::new(
        encoder,
        args.feature_cache.as_deref(),
        &stamp,
    )?))
}

/// Unit text features of `words` from a text encoder.
pub fn text_features(
    model: &Path,
    ort_lib: Option<&Path>,
    words: &[String],
) -> anyhow::Result<(String, Vec<Vec<f32>>)> {
    let rt = super::encode::init_runtime(ort_lib)?;
    let mut enc = TextEncoder::load(rt, model, 0)?;
    let refs: Vec<&str> = words.iter().map(String::as_str).collect();
    let rows = enc
        .encode(&refs)
        .with_context(|| format!("encoding {words:?} with {}", model.display()))?;
    Ok((enc.card().name.clone(), rows))
}

/// The class list `classes` names: a file, or (when no file has that name)
/// a built-in list; its ids and names.
pub fn class_list(
    classes: &str,
) -> anyhow::Result<(Option<BuiltinClasses>, Vec<u32>, Vec<String>)> {
    let path = Path::new(classes);
    if !path.exists()
        && let Some(set) = BuiltinClasses::from_name(classes)
    {
        let (ids, names) = set
            .classes()
            .iter()
            .map(|&(i, n)| (i, n.to_string()))
            .unzip();
        return Ok((Some(set), ids, names));
    }
    if !path.exists() {
        anyhow::bail!(
            "{classes}: no such class list (built-in lists: {})",
            BuiltinClasses::ALL.map(|s| s.name()).join(", ")
        );
    }
    let (ids, names) = read_class_list(path)?;
    Ok((None, ids, names))
}

/// What a feature row of a map in a built-in class list's space stands
/// for, as `omcl map info` and the LAS exports say it.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RowClasses {
    /// The classes whose feature is this row's (within tau).
    pub classes: Vec<ClassRef>,
    /// For a row of no class (a voxel that held points of several: their
    /// mean): the nearest class and its cosine similarity.
    pub nearest: Option<NearestClass>,
}

/// A class of a list: its id (the code in label files) and name.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ClassRef {
    pub id: u32,
    pub name: String,
}

/// The class nearest a row, and how near (cosine similarity).
#[derive(Debug, Clone, serde::Serialize)]
pub struct NearestClass {
    pub id: u32,
    pub name: String,
    pub similarity: f32,
}

impl RowClasses {
    /// The class code a LAS export gives the row's voxels: its class, or
    /// the nearest one for a mix.
    pub fn code(&self) -> Option<u32> {
        self.classes
            .first()
            .map(|c| c.id)
            .or(self.nearest.as_ref().map(|n| n.id))
    }
}

/// The classes each feature row of `map` stands for, when the map is in a
/// built-in class list's feature space (its encoder is
/// `omcl-builtin-<list>`, as `map cloud --classes asprs` writes it): the
/// list, and every row's [`RowClasses`]. `None` for any other map: its
/// rows' classes are not known.
pub fn builtin_row_classes(
    map: &omcl::map::LanguageMap,
) -> anyhow::Result<Option<(BuiltinClasses, Vec<RowClasses>)>> {
    let Some(set) = map
        .encoder()
        .strip_prefix("omcl-builtin-")
        .and_then(BuiltinClasses::from_name)
    else {
        return Ok(None);
    };
    let sim = omcl::sim::files::builtin_table()?;
    let table = omcl::sim::embeddings::builtin_label_table(set, &sim)?;
    if table.dim != map.db().dim() {
        return Ok(None);
    }
    let classes = omcl::map::FeatureDb::from_rows(table.dim, 0.0, table.data.clone())?;
    let rows = omcl::map::classes_of_rows(map.db(), &classes)?;
    let class = |c: usize| ClassRef {
        id: table.ids[c],
        name: table.names[c].clone(),
    };
    let mut named = Vec::with_capacity(rows.len());
    for (r, cs) in rows.into_iter().enumerate() {
        let nearest = match cs.is_empty() {
            true => classes
                .nearest(map.db().row(r))?
                .map(|(c, similarity)| NearestClass {
                    id: table.ids[c],
                    name: table.names[c].clone(),
                    similarity,
                }),
            false => None,
        };
        named.push(RowClasses {
            classes: cs.into_iter().map(class).collect(),
            nearest,
        });
    }
    Ok(Some((set, named)))
}

/// A class list with one feature row per class, as the commands take it:
/// `classes` is a class-list file or a built-in list's name (`semantickitti`,
/// `asprs`; a file of that name wins); the rows come from `embeddings`
/// (`N x F` `.npy`), from a text encoder embedding the class names, or, for
/// a built-in list with neither, from the built-in CLIP-like table
/// ([`omcl::sim::embeddings::builtin_label_table`]). With a text encoder,
/// its name (the feature space the table is in) comes too; with the
/// built-in table, `omcl-builtin-<list>`.
pub fn class_table(
    classes: &str,
    embeddings: Option<&Path>,
    text_model: Option<&Path>,
    ort_lib: Option<&Path>,
) -> anyhow::Result<(EmbeddingTable, Option<String>)> {
    let path = Path::new(classes);
    let (builtin, ids, names) = class_list(classes)?;
    match (embeddings, text_model, builtin) {
        (Some(npy), _, _) => Ok((EmbeddingTable::with_npy(ids, names, path, npy)?, None)),
        (None, Some(model), _) => {
            let (name, rows) = text_features(model, ort_lib, &names)?;
            let dim = rows.first().map_or(0, Vec::len);
            let t = EmbeddingTable::new(ids, names, dim, rows.concat())
                .map_err(|e| anyhow::anyhow!("{}: {e}", model.display()))?;
            Ok((t, Some(name)))
        }
        (None, None, Some(set)) => {
            // Part CLIP text rows, part synthetic draws: the map says so
            // rather than claim a CLIP feature space.
            let sim = omcl::sim::files::builtin_table()?;
            let table = omcl::sim::embeddings::builtin_label_table(set, &sim)?;
            Ok((table, Some(format!("omcl-builtin-{}", set.name()))))
        }
        (None, None, None) => anyhow::bail!(
            "{classes}: a class list needs its features: --embeddings NPY (one row a class) or \
             --text-model ONNX (the built-in lists {} work without)",
            BuiltinClasses::ALL.map(|s| s.name()).join(", ")
        ),
    }
}
