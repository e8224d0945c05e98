//! Text encoder: words or prompts to unit-length features with CLIP's text
//! tower exported to ONNX (`tools/export_clip_text.py`).
//!
//! Contract: input `[N, context_length]` token ids (int64 or int32, CLIP's
//! tokenisation, zero-padded), optional attention mask of the same shape,
//! output `[N, F]` float32.

use std::path::Path;

use super::card::{ModelCard, ModelKind, TextSpec};
use super::runtime::{ElemKind, InputData, OnnxModel};
use super::tokenize::ClipTokenizer;
use super::{EncodeError, ensure_feature_dim, normalize_in_place};

/// An ONNX text encoder with CLIP's tokeniser.
pub struct TextEncoder {
    model: OnnxModel,
    card: ModelCard,
    spec: TextSpec,
    tokenizer: ClipTokenizer,
    input: String,
    elem: ElemKind,
    output: String,
    /// The model takes exactly one text per run (batch axis fixed to 1).
    single: bool,
}

impl super::Encoder for TextEncoder {
    const KIND: ModelKind = ModelKind::Text;
    type Spec = TextSpec;

    fn spec(card: &ModelCard) -> Option<&TextSpec> {
        card.text.as_ref()
    }

    fn from_parts(
        model: &Path,
        card: ModelCard,
        spec: TextSpec,
        onnx: OnnxModel,
    ) -> Result<TextEncoder, EncodeError> {
        let input = onnx.input(spec.input.as_deref())?.clone();
        let contract = |reason: String| EncodeError::Contract {
            path: model.to_path_buf(),
            reason,
        };
        if !matches!(input.elem, ElemKind::I64 | ElemKind::I32) {
            return Err(contract(format!(
                "token input `{}` is {:?}, expected int64 or int32 token ids",
                input.name, input.elem
            )));
        }
        if input.dims.len() != 2 || input.dims[1].is_some_and(|d| d != spec.context_length) {
            return Err(contract(format!(
                "token input `{}` has shape {}, expected [N, {}] (context_length)",
                input.name,
                input.dims_text(),
                spec.context_length
            )));
        }
        if let Some(mask) = &spec.attention_mask {
            onnx.input(Some(mask))?;
        }
        let output = onnx.output(spec.output.as_deref())?.name.clone();
        Ok(TextEncoder {
            single: input.dims[0] == Some(1),
            input: input.name,
            elem: input.elem,
            output,
            model: onnx,
            card,
            spec,
            tokenizer: ClipTokenizer::new(),
        })
    }
}

impl TextEncoder {
    /// The model card.
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// Length of each text feature.
    pub fn feature_dim(&self) -> usize {
        self.card.feature_dim
    }

    /// The token ids fed for `text` (after the card's template).
    pub fn token_ids(&self, text: &str) -> Vec<u32> {
        let prompt = match &self.spec.template {
            Some(t) => t.replace("{}", text),
            None => text.to_string(),
        };
        self.tokenizer.tokenize(&prompt, self.spec.context_length).0
    }

    /// One feature per text, unit length when the card says `normalize`
    /// (the default), in the order given.
    pub fn encode(&mut self, texts: &[&str]) -> Result<Vec<Vec<f32>>, EncodeError> {
        if texts.is_empty() {
            return Ok(Vec::new());
        }
        let mut out = Vec::with_capacity(texts.len());
        if self.single {
            for t in texts {
                out.extend(self.run_batch(&[t])?);
            }
        } else {
            out = self.run_batch(texts)?;
        }
        Ok(out)
    }

    fn run_batch(&mut self, texts: &[&str]) -> Result<Vec<Vec<f32>>, EncodeError> {
        let l = self.spec.context_length;
        let ids: Vec<u32> = texts.iter().flat_map(|t| self.token_ids(t)).collect();
        let shape = [texts.len(), l];
        let feed = |v: &[u32]| match self.elem {
            ElemKind::I32 => InputData::I32(v.iter().map(|&x| x as i32).collect()),
            _ => InputData::I64(v.iter().map(|&x| i64::from(x)).collect()),
        };
        let mut inputs = vec![(self.input.as_str(), &shape[..], feed(&ids))];
        let mask: Vec<u32>;
        if let Some(name) = &self.spec.attention_mask {
            // Real tokens run up to and including the end marker. Padding is
            // id 0, but so is "!", hence positions, not values.
            let eot = self.tokenizer.end_of_text();
            mask = ids
                .chunks(l)
                .flat_map(|row| {
                    let end = row.iter().position(|&x| x == eot).unwrap_or(l - 1);
                    (0..l).map(move |j| u32::from(j <= end))
                })
                .collect();
            inputs.push((name.as_str(), &shape[..], feed(&mask)));
        }
        let out = self.model.run(inputs, &[&self.output])?;
        let out = out
            .into_iter()
            .next()
            .ok_or_else(|| EncodeError::Contract {
                path: self.model.path().to_path_buf(),
                reason: "model returned no output".into(),
            })?;
        if out.shape.len() != 2 || out.shape[0] != texts.len() {
            return Err(EncodeError::Shape {
                path: self.model.path().to_path_buf(),
                what: format!("output `{}`", self.output),
                got: out.shape,
                expected: format!("[{}, F]", texts.len()),
            });
        }
        ensure_feature_dim(
            &self.model.path().display().to_string(),
            out.shape[1],
            "its model card",
            self.card.feature_dim,
        )?;
        let f = out.shape[1];
        Ok(out
            .data
            .chunks_exact(f)
            .map(|row| {
                let mut v = row.to_vec();
                if self.card.normalize {
                    normalize_in_place(&mut v);
                }
                v
            })
            .collect())
    }
}
