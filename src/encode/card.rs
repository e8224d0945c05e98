//! Model cards: a small JSON file beside each `.onnx` (`lseg.onnx` ->
//! `lseg.card.json`) that says what the model is and how to feed it, so
//! users can bring any export without code changes.
//!
//! ```json
//! { "kind": "image", "name": "lseg_vitl16_384", "feature_dim": 512,
//!   "image": { "resize": {"mode": "longer_side", "size": 520},
//!              "filter": "bicubic",
//!              "mean": [0.5, 0.5, 0.5], "std": [0.5, 0.5, 0.5],
//!              "window": {"width": 480, "height": 480, "stride_x": 320, "stride_y": 320} } }
//! ```
//! `tools/README_encoders.md` documents every field; the export scripts
//! write cards for LSeg and CLIP's text tower.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::EncodeError;
use super::preprocess::Filter;

/// Which encoder contract a model follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// RGB image in, per-pixel features out.
    Image,
    /// CLIP token ids in, one feature per text out.
    Text,
    /// Points (and colours) in, per-point features out.
    Point,
}

impl std::fmt::Display for ModelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ModelKind::Image => "an image",
            ModelKind::Text => "a text",
            ModelKind::Point => "a point",
        })
    }
}

/// Tensor layout of an image input or a feature-map output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Layout {
    /// Batch, channels, height, width (PyTorch).
    #[default]
    Nchw,
    /// Batch, height, width, channels.
    Nhwc,
}

/// How the image is resized before the model sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case", deny_unknown_fields)]
pub enum Resize {
    /// Keep the image size.
    #[default]
    None,
    /// Exactly `width` x `height` pixels (aspect ratio not kept).
    Fixed { width: u32, height: u32 },
    /// Shorter side to `size`, aspect ratio kept (torchvision `Resize(size)`).
    ShorterSide { size: u32 },
    /// Longer side to `size`, aspect ratio kept (LSeg's "base size").
    LongerSide { size: u32 },
}

/// Sliding windows for models with a fixed input size: windows of
/// `width` x `height` pixels every `stride_x`, `stride_y` pixels; the image
/// is padded (with normalised zeros, i.e. the mean colour) to whole
/// windows, and features of overlapping windows are averaged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Window {
    pub width: u32,
    pub height: u32,
    pub stride_x: u32,
    pub stride_y: u32,
}

/// Image-encoder settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSpec {
    /// Input tensor name; the model's first input if absent.
    #[serde(default)]
    pub input: Option<String>,
    /// Output tensor name; the model's first output if absent.
    #[serde(default)]
    pub output: Option<String>,
    #[serde(default)]
    pub layout: Layout,
    #[serde(default)]
    pub output_layout: Layout,
    #[serde(default)]
    pub resize: Resize,
    #[serde(default = "default_filter")]
    pub filter: Filter,
    /// Centre crop `[width, height]` after resizing (torchvision
    /// `CenterCrop`); the feature map then covers only the crop.
    #[serde(default)]
    pub center_crop: Option<[u32; 2]>,
    /// Per-channel mean of [0, 1] RGB, subtracted before dividing by `std`.
    #[serde(default)]
    pub mean: [f64; 3],
    #[serde(default = "ones")]
    pub std: [f64; 3],
    #[serde(default)]
    pub window: Option<Window>,
}

/// Text-encoder settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextSpec {
    /// Token-id input name; the model's first input if absent.
    #[serde(default)]
    pub input: Option<String>,
    /// Attention-mask input (Hugging Face exports), fed 1 for real tokens.
    #[serde(default)]
    pub attention_mask: Option<String>,
    #[serde(default)]
    pub output: Option<String>,
    #[serde(default = "default_context")]
    pub context_length: usize,
    /// Prompt template with `{}` for the word, e.g. `"a photo of a {}"`.
    #[serde(default)]
    pub template: Option<String>,
}

/// Point-encoder settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointSpec {
    /// Input for xyz (metres, map frame), `[N, 3]` or `[1, N, 3]`.
    #[serde(default = "default_points")]
    pub points_input: String,
    /// Input for RGB in [0, 1], same layout; absent if the model takes none.
    #[serde(default)]
    pub colors_input: Option<String>,
    #[serde(default)]
    pub output: Option<String>,
    /// Largest number of points per run; larger clouds are split.
    #[serde(default)]
    pub chunk: Option<usize>,
}

/// A parsed and checked model card.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelCard {
    pub kind: ModelKind,
    /// Encoder name recorded in maps ("lseg_vitl16_384", "clip_vitb32").
    pub name: String,
    /// Length F of every feature the model produces.
    pub feature_dim: usize,
    /// Scale every output feature to unit length (the map stores unit rows).
    #[serde(default = "yes")]
    pub normalize: bool,
    #[serde(default)]
    pub image: Option<ImageSpec>,
    #[serde(default)]
    pub text: Option<TextSpec>,
    #[serde(default)]
    pub point: Option<PointSpec>,
}

fn default_filter() -> Filter {
    Filter::Bicubic
}
fn ones() -> [f64; 3] {
    [1.0; 3]
}
fn default_context() -> usize {
    super::tokenize::CONTEXT_LENGTH
}
fn default_points() -> String {
    "points".into()
}
fn yes() -> bool {
    true
}

/// The card path for a model: `x/lseg.onnx` -> `x/lseg.card.json`.
pub fn card_path_for(model: &Path) -> PathBuf {
    model.with_extension("card.json")
}

impl ModelCard {
    /// Parses and checks card text; `path` is only used in errors.
    pub fn parse(text: &str, path: &Path) -> Result<ModelCard, EncodeError> {
        let card: ModelCard = serde_json::from_str(text).map_err(|e| EncodeError::Card {
            path: path.to_path_buf(),
            reason: format!("line {}, column {}: {e}", e.line(), e.column()),
        })?;
        card.check(path)?;
        Ok(card)
    }

    /// Reads the card beside `model` (see [`card_path_for`]).
    pub fn for_model(model: &Path) -> Result<ModelCard, EncodeError> {
        // The model itself first: a mistyped model name is not a missing card.
        std::fs::metadata(model).map_err(|err| match err.kind() {
            std::io::ErrorKind::NotFound => EncodeError::MissingModel {
                path: model.to_path_buf(),
            },
            _ => EncodeError::Io {
                path: model.to_path_buf(),
                err,
            },
        })?;
        let path = card_path_for(model);
        let text = crate::io::bounded_read::read_text(&path).map_err(|err| {
            if err.kind() == std::io::ErrorKind::NotFound {
                EncodeError::Card {
                    path: path.clone(),
                    reason: format!(
                        "missing; every model needs a card beside it saying how to feed it \
                         (kind, name, feature_dim, ...; see tools/README_encoders.md) for {}",
                        model.display()
                    ),
                }
            } else {
                EncodeError::Io {
                    path: path.clone(),
                    err,
                }
            }
        })?;
        ModelCard::parse(&text, &path)
    }

    fn check(&self, path: &Path) -> Result<(), EncodeError> {
        let bad = |reason: String| EncodeError::Card {
            path: path.to_path_buf(),
            reason,
        };
        if self.feature_dim == 0 {
            return Err(bad("feature_dim must be at least 1".into()));
        }
        match self.kind {
            ModelKind::Image => {
                let spec = self
                    .image
                    .as_ref()
                    .ok_or_else(|| bad("kind \"image\" needs an \"image\" section".into()))?;
                if spec.std.iter().any(|&s| !(s.is_finite() && s > 0.0)) {
                    return Err(bad(format!("std {:?} must be positive", spec.std)));
                }
                let zero = match spec.resize {
                    Resize::None => false,
                    Resize::Fixed { width, height } => width == 0 || height == 0,
                    Resize::ShorterSide { size } | Resize::LongerSide { size } => size == 0,
                };
                if zero {
                    return Err(bad("resize sizes must be at least 1".into()));
                }
                if let Some(w) = spec.window
                    && (w.width == 0 || w.height == 0 || w.stride_x == 0 || w.stride_y == 0)
                {
                    return Err(bad("window sizes and strides must be at least 1".into()));
                }
                if spec.center_crop.is_some_and(|[w, h]| w == 0 || h == 0) {
                    return Err(bad("center_crop must be at least 1 x 1".into()));
                }
            }
            ModelKind::Text => {
                let spec = self
                    .text
                    .as_ref()
                    .ok_or_else(|| bad("kind \"text\" needs a \"text\" section".into()))?;
                if spec.context_length < 3 {
                    return Err(bad("context_length must be at least 3".into()));
                }
                if let Some(t) = &spec.template
                    && !t.contains("{}")
                {
                    return Err(bad(format!("template {t:?} has no {{}} for the word")));
                }
            }
            ModelKind::Point => {
                let spec = self
                    .point
                    .as_ref()
                    .ok_or_else(|| bad("kind \"point\" needs a \"point\" section".into()))?;
                if spec.chunk == Some(0) {
                    return Err(bad("chunk must be at least 1".into()));
                }
            }
        }
        Ok(())
    }

    /// Errors unless the card is of `kind`.
    pub fn expect_kind(&self, kind: ModelKind, path: &Path) -> Result<(), EncodeError> {
        if self.kind == kind {
            Ok(())
        } else {
            Err(EncodeError::Card {
                path: path.to_path_buf(),
                reason: format!("card is for {} encoder, not {kind} encoder", self.kind),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_image_card_parses_with_defaults() {
        let c = ModelCard::parse(
            r#"{"kind":"image","name":"lseg","feature_dim":512,
                "image":{"resize":{"mode":"longer_side","size":520},
                         "mean":[0.5,0.5,0.5],"std":[0.5,0.5,0.5],
                         "window":{"width":480,"height":480,"stride_x":320,"stride_y":320}}}"#,
            Path::new("m.card.json"),
        )
        .unwrap();
        let spec = c.image.unwrap();
        assert_eq!(spec.resize, Resize::LongerSide { size: 520 });
        assert_eq!(spec.filter, Filter::Bicubic);
        assert_eq!(spec.layout, Layout::Nchw);
        assert!(c.normalize);
    }

    #[test]
    fn errors_name_the_file_and_the_problem() {
        let p = Path::new("dir/m.card.json");
        let e = ModelCard::parse(r#"{"kind":"image","name":"x","feature_dim":4}"#, p)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("dir/m.card.json") && e.contains("\"image\" section"),
            "{e}"
        );
        let e = ModelCard::parse(
            r#"{"kind":"text","name":"x","feature_dim":4,"text":{"colour":1}}"#,
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("colour") && e.contains("line 1"), "{e}");
        let e = ModelCard::parse(
            r#"{"kind":"text","name":"x","feature_dim":4,"text":{"template":"a photo"}}"#,
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("template"), "{e}");
        assert_eq!(
            card_path_for(Path::new("a/b.onnx")),
            Path::new("a/b.card.json")
        );
    }
}
