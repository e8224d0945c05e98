//! ONNX encoders as feature sources of the map and localize commands.

use omcl::encode::Encoder as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;

use omcl::encode::image::ImageEncoder;
use omcl::encode::text::TextEncoder;

/// Options that select ONNX encoders.
#[derive(Debug, Args, Default)]
pub struct EncoderArgs {
    /// Image encoder (`.onnx` with its `.card.json`): per-pixel features
    /// from the sequence's rgb/NNNNNN.png instead of labels or feature files.
    #[arg(long, value_name = "ONNX")]
    pub image_model: Option<PathBuf>,
    /// Cache folder for image-encoder features (NNNNNN.npy; reused when
    /// present and made by the same encoder).
    #[arg(long, value_name = "DIR")]
    pub feature_cache: Option<PathBuf>,
    /// ONNX Runtime library (overrides ORT_DYLIB_PATH and .deps/).
    #[arg(long, value_name = "PATH")]
    pub ort_lib: Option<PathBuf>,
}

pub use omcl::encode::cache::ImageSource;

/// The image encoder of `args` with its cache, if one was given.
pub fn open_image_source(args: &EncoderArgs) -> anyhow::Result<Option<ImageSource>> {
    let Some(model) = &args.image_model else {
        return Ok(None);
    };
    let rt = super::encode::init_runtime(args.ort_lib.as_deref())?;
    let encoder = ImageEncoder::load(rt, model, 0)?;
    Ok(Some(ImageSource::new(
        encoder,
        args.feature_cache.as_deref(),
    )?))
}

pub use omcl::encode::image::EncodedFrame;

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
