//! Open-vocabulary encoders run through ONNX Runtime: RGB images to per-pixel
//! language features (LSeg, X-Decoder, NARADIO exports), words to text
//! features (CLIP's text tower) and points with colours to per-point
//! features (any ONNX model honouring the point contract).
//!
//! Users bring exported `.onnx` models; a small JSON model card beside each
//! (`model.onnx` -> `model.card.json`, see [`card`]) says how to feed it.
//! The runtime library is loaded at run time (ort's `load-dynamic`), found by
//! [`runtime::find_library`]; nothing is downloaded at build time.
//!
//! Layout: [`runtime`] owns the ONNX Runtime environment and runs models;
//! [`preprocess`] is the pixel math (PIL-compatible resampling, CLIP
//! normalisation); [`tokenize`] is CLIP's BPE tokenisation; [`image`],
//! [`text`] and [`point`] are the three encoders; [`cache`] stores per-frame
//! features as `.npy` so a model runs once per frame.

pub mod cache;
pub mod card;
pub mod colour;
pub mod colour_model;
pub mod image;
pub mod onnx_proto;
pub mod point;
pub mod preprocess;
pub mod runtime;
pub mod text;
pub mod tokenize;

use std::path::{Path, PathBuf};

pub use self::cache::FeatureCache;
pub use self::card::{ModelCard, ModelKind};
pub use self::image::{FeatureMap, ImageEncoder, rgb_from_pixels};
pub use self::point::PointEncoder;
pub use self::runtime::{OnnxModel, Runtime};
pub use self::text::TextEncoder;
pub use self::tokenize::ClipTokenizer;

/// The one loading path of the three encoders: the card beside the model
/// (or one given by the caller) is checked to be of the encoder's kind, its
/// section for that kind taken, the ONNX session opened; each encoder then
/// checks the model's own contract in [`Encoder::from_parts`].
pub trait Encoder: Sized {
    /// The card's kind this encoder reads.
    const KIND: ModelKind;
    /// The card's section for this kind.
    type Spec: Clone;
    /// The card's section for this kind, if it has one.
    fn spec(card: &ModelCard) -> Option<&Self::Spec>;
    /// The encoder, once its card and session are open: checks the model's
    /// inputs and outputs against the contract.
    fn from_parts(
        model: &Path,
        card: ModelCard,
        spec: Self::Spec,
        onnx: OnnxModel,
    ) -> Result<Self, EncodeError>;

    /// Loads `model` and the card beside it (`model.card.json`).
    fn load(runtime: &Runtime, model: &Path, threads: usize) -> Result<Self, EncodeError> {
        let card = ModelCard::for_model(model)?;
        Self::with_card(runtime, model, card, threads)
    }

    /// Loads `model` with a card given by the caller; `threads` ONNX
    /// Runtime intra-op threads (0: its default).
    fn with_card(
        runtime: &Runtime,
        model: &Path,
        card: ModelCard,
        threads: usize,
    ) -> Result<Self, EncodeError> {
        card.expect_kind(Self::KIND, model)?;
        let spec = Self::spec(&card)
            .cloned()
            .ok_or_else(|| EncodeError::Card {
                path: model.to_path_buf(),
                reason: format!("no {} section", kind_word(Self::KIND)),
            })?;
        let onnx = OnnxModel::load(runtime, model, threads)?;
        Self::from_parts(model, card, spec, onnx)
    }
}

fn kind_word(kind: ModelKind) -> &'static str {
    match kind {
        ModelKind::Image => "image",
        ModelKind::Text => "text",
        ModelKind::Point => "point",
    }
}

/// Everything that can go wrong while loading or running an encoder. Each
/// variant names the file (model, card or library) and what was expected.
#[derive(Debug, thiserror::Error)]
pub enum EncodeError {
    /// No ONNX Runtime shared library was found anywhere we looked.
    #[error(
        "ONNX Runtime library (libonnxruntime.so) not found; looked at: {tried}.\n\
         Install it with `make deps` (puts the PyPI `onnxruntime` wheel's library in \
         .deps/onnxruntime/), or point `--ort-lib` or ORT_DYLIB_PATH at a \
         libonnxruntime.so.* (version 1.17 or newer)"
    )]
    RuntimeNotFound { tried: String },
    /// A library was found but could not be loaded or is too old.
    #[error(
        "{path}: cannot load ONNX Runtime: {reason}.\n\
         Run `make deps`, or point `--ort-lib` or ORT_DYLIB_PATH at a \
         libonnxruntime.so.* of version 1.17 or newer"
    )]
    RuntimeLoad { path: PathBuf, reason: String },
    /// ONNX Runtime itself failed outside any one model.
    #[error("ONNX Runtime: {0}")]
    Runtime(String),
    // `err`, not `source`: the message already carries it, and anyhow
    // would print a `source` twice.
    #[error("{path}: {err}")]
    Io { path: PathBuf, err: std::io::Error },
    /// The model file is not there.
    #[error(
        "{path}: no such model file. omcl's encoders are ONNX models exported once where \
         torch and the weights are (tools/README_encoders.md: export_clip_text.py, \
         export_lseg.py; nothing here downloads them), or written by `omcl encode \
         colour-model`"
    )]
    MissingModel { path: PathBuf },
    /// The file exists but ONNX Runtime cannot parse it as a model.
    #[error("{path}: not a loadable ONNX model: {reason}")]
    NotOnnx { path: PathBuf, reason: String },
    /// The model card is missing a field, has a bad value or does not match
    /// the model.
    #[error("{path}: model card: {reason}")]
    Card { path: PathBuf, reason: String },
    /// The model's inputs or outputs are not what the encoder contract needs.
    #[error("{path}: {reason}")]
    Contract { path: PathBuf, reason: String },
    /// A tensor given to or returned by the model has the wrong shape.
    #[error("{path}: {what} has shape {got:?}, expected {expected}")]
    Shape {
        path: PathBuf,
        what: String,
        got: Vec<usize>,
        expected: String,
    },
    /// Inference failed inside ONNX Runtime.
    #[error("{path}: inference failed: {reason}")]
    Run { path: PathBuf, reason: String },
    /// Encoder features and the map (or the card) disagree on the dimension.
    #[error(
        "feature dimension mismatch: {encoder} produces {got}-d features but {against} \
         holds {expected}-d features; use the encoder the map was built with"
    )]
    FeatureDim {
        encoder: String,
        against: String,
        got: usize,
        expected: usize,
    },
    /// An input the caller passed is unusable (empty image, mismatched
    /// points and colours, ...).
    #[error("{0}")]
    Input(String),
    #[error(transparent)]
    Npy(#[from] crate::io::npy::NpyError),
}

/// Scales `v` to unit Euclidean length in place; a zero vector stays zero
/// (it then scores cosine 0 against everything, which is the honest answer
/// for "no information").
pub fn normalize_in_place(v: &mut [f32]) {
    let n2: f64 = v.iter().map(|&x| f64::from(x) * f64::from(x)).sum();
    if n2 > 0.0 {
        let inv = (1.0 / n2.sqrt()) as f32;
        v.iter_mut().for_each(|x| *x *= inv);
    }
}

/// Checks that an encoder's feature dimension equals the map's (or any other
/// store's) before features are compared; cosine similarity between vectors
/// of different models is meaningless even when the lengths happen to match,
/// but a length mismatch is the error we can detect.
pub fn ensure_feature_dim(
    encoder: &str,
    got: usize,
    against: &str,
    expected: usize,
) -> Result<(), EncodeError> {
    if got == expected {
        Ok(())
    } else {
        Err(EncodeError::FeatureDim {
            encoder: encoder.to_string(),
            against: against.to_string(),
            got,
            expected,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalize_gives_unit_length_and_keeps_zero() {
        let mut v = [3.0f32, 4.0];
        normalize_in_place(&mut v);
        assert!((v[0] - 0.6).abs() < 1e-7 && (v[1] - 0.8).abs() < 1e-7);
        let mut z = [0.0f32; 3];
        normalize_in_place(&mut z);
        assert_eq!(z, [0.0; 3]);
    }

    #[test]
    fn feature_dim_mismatch_names_both_sides() {
        assert!(ensure_feature_dim("lseg", 512, "map", 512).is_ok());
        let e = ensure_feature_dim("lseg", 512, "map.omcl", 768)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("512") && e.contains("768") && e.contains("map.omcl"),
            "{e}"
        );
    }
}
