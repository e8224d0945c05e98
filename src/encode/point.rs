//! Point encoder: points with colours to per-point features.
//!
//! Contract: input `points` `[N, 3]` or `[1, N, 3]` float32 (metres, the
//! cloud's frame moved to its lower corner snapped to the map's
//! resolution, so georeferenced coordinates keep float precision), optional input `colors` of the same shape with RGB in
//! [0, 1], output `[N, F]` or `[1, N, F]` float32. OpenScene's own network
//! (sparse convolutions) does not export to ONNX; its per-point features are
//! read as `.npy` files instead, and any ONNX model honouring this contract
//! runs here.

use std::path::Path;

use super::card::{ModelCard, ModelKind, PointSpec};
use super::runtime::{InputData, OnnxModel};
use super::{EncodeError, ensure_feature_dim, normalize_in_place};

/// An ONNX point encoder with its model card.
pub struct PointEncoder {
    model: OnnxModel,
    card: ModelCard,
    spec: PointSpec,
    output: String,
    /// Inputs carry a leading batch axis of 1.
    batched: bool,
}

impl super::Encoder for PointEncoder {
    const KIND: ModelKind = ModelKind::Point;
    type Spec = PointSpec;

    fn spec(card: &ModelCard) -> Option<&PointSpec> {
        card.point.as_ref()
    }

    fn from_parts(
        model: &Path,
        card: ModelCard,
        spec: PointSpec,
        onnx: OnnxModel,
    ) -> Result<PointEncoder, EncodeError> {
        let pts = onnx.input(Some(&spec.points_input))?;
        let batched = match pts.dims.len() {
            2 => false,
            3 => true,
            _ => {
                return Err(EncodeError::Contract {
                    path: model.to_path_buf(),
                    reason: format!(
                        "points input `{}` has shape {}, expected [N, 3] or [1, N, 3]",
                        pts.name,
                        pts.dims_text()
                    ),
                });
            }
        };
        if let Some(c) = &spec.colors_input {
            onnx.input(Some(c))?;
        }
        let output = onnx.output(spec.output.as_deref())?.name.clone();
        Ok(PointEncoder {
            model: onnx,
            card,
            spec,
            output,
            batched,
        })
    }
}

impl PointEncoder {
    /// The model card.
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// Length of each per-point feature.
    pub fn feature_dim(&self) -> usize {
        self.card.feature_dim
    }

    /// Features of every point, `points.len()` x F row-major. `colors` are
    /// RGB in [0, 1], one per point; ignored when the model takes none.
    pub fn encode(
        &mut self,
        points: &[[f32; 3]],
        colors: &[[f32; 3]],
    ) -> Result<Vec<f32>, EncodeError> {
        if self.spec.colors_input.is_some() && colors.len() != points.len() {
            return Err(EncodeError::Input(format!(
                "{} points but {} colours; the point encoder needs one colour per point",
                points.len(),
                colors.len()
            )));
        }
        if points.is_empty() {
            return Ok(Vec::new());
        }
        let chunk = self.spec.chunk.unwrap_or(points.len()).max(1);
        let mut out = Vec::with_capacity(points.len() * self.card.feature_dim);
        for start in (0..points.len()).step_by(chunk) {
            let end = (start + chunk).min(points.len());
            let cols = if self.spec.colors_input.is_some() {
                &colors[start..end]
            } else {
                &[][..]
            };
            out.extend(self.run_chunk(&points[start..end], cols)?);
        }
        Ok(out)
    }

    fn run_chunk(
        &mut self,
        points: &[[f32; 3]],
        colors: &[[f32; 3]],
    ) -> Result<Vec<f32>, EncodeError> {
        let n = points.len();
        let shape: Vec<usize> = if self.batched {
            vec![1, n, 3]
        } else {
            vec![n, 3]
        };
        let flat = |v: &[[f32; 3]]| InputData::F32(v.iter().flatten().copied().collect());
        let mut inputs = vec![(self.spec.points_input.as_str(), &shape[..], flat(points))];
        if let Some(c) = &self.spec.colors_input {
            inputs.push((c.as_str(), &shape[..], flat(colors)));
        }
        let out = self.model.run(inputs, &[&self.output])?;
        let out = out
            .into_iter()
            .next()
            .ok_or_else(|| EncodeError::Contract {
                path: self.model.path().to_path_buf(),
                reason: "model returned no output".into(),
            })?;
        let ok = match out.shape.as_slice() {
            [m, _] => !self.batched && *m == n,
            [1, m, _] => self.batched && *m == n,
            _ => false,
        };
        if !ok {
            return Err(EncodeError::Shape {
                path: self.model.path().to_path_buf(),
                what: format!("output `{}`", self.output),
                got: out.shape,
                expected: if self.batched {
                    format!("[1, {n}, F]")
                } else {
                    format!("[{n}, F]")
                },
            });
        }
        let f = out.shape[out.shape.len() - 1];
        ensure_feature_dim(
            &self.model.path().display().to_string(),
            f,
            "its model card",
            self.card.feature_dim,
        )?;
        let mut data = out.data;
        if self.card.normalize {
            data.chunks_exact_mut(f).for_each(normalize_in_place);
        }
        Ok(data)
    }
}
