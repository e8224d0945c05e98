//! Per-frame feature cache: an image encoder runs once per frame and its
//! feature map is reused by later runs (mapping, then many localisation
//! sweeps over the same frames).
//!
//! Each frame is two files in the cache directory: `<frame>.npy`, the
//! `H x W x F` float32 feature map (what Python tools read and write), and
//! `<frame>.json`, its placement on the image and the encoder that made it,
//! so a cache filled by another encoder is refused rather than mixed in.
//! Since 2026-11-29 the `.json` also holds a CRC-32 of the image file and
//! of the model's files: an entry of another image (another sequence's
//! frame of the same number) or of another model of the same name is
//! computed anew and replaced, where it had been returned. Features
//! computed by any external tool can be dropped in as `.npy` with a
//! matching `.json` (without the two stamps: trusted as they are). A
//! `.npy` without its `.json` is not the cache's and is never replaced.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::EncodeError;
use super::image::FeatureMap;
use crate::io::npy::{read_npy, write_npy};

/// Placement and provenance of a cached feature map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CacheMeta {
    /// Encoder name from the model card.
    pub encoder: String,
    /// See [`FeatureMap::origin`].
    pub origin: [f32; 2],
    /// See [`FeatureMap::cell_size`].
    pub cell_size: [f32; 2],
    /// The image file's [`stamp`], when omcl made the entry.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image: Option<String>,
    /// The model files' [`stamp`], when omcl made the entry.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
}

/// A file's content stamp: its length and CRC-32, as `len:crc` (hex).
/// Several files (a model and its card) stamp in order, `;`-separated.
pub fn stamp(paths: &[&Path]) -> Result<String, EncodeError> {
    let mut parts = Vec::with_capacity(paths.len());
    for p in paths {
        use std::io::Read;
        let io = |err| EncodeError::Io {
            path: p.to_path_buf(),
            err,
        };
        let mut f = std::fs::File::open(p).map_err(io)?;
        let mut crc = crc32fast::Hasher::new();
        let mut buf = vec![0u8; 1 << 16];
        let mut len = 0u64;
        loop {
            let n = f.read(&mut buf).map_err(io)?;
            if n == 0 {
                break;
            }
            crc.update(&buf[..n]);
            len += n as u64;
        }
        parts.push(format!("{len}:{:08x}", crc.finalize()));
    }
    Ok(parts.join(";"))
}

/// The [`stamp`] of an encoder's files: its ONNX model and, when there
/// is one, its card.
pub fn model_stamp(model: &Path) -> Result<String, EncodeError> {
    let card = super::card::card_path_for(model);
    if card.is_file() {
        stamp(&[model, &card])
    } else {
        stamp(&[model])
    }
}

/// A directory of cached feature maps for one encoder.
#[derive(Debug, Clone)]
pub struct FeatureCache {
    dir: PathBuf,
    encoder: String,
    /// The model files' [`stamp`].
    model: String,
}

impl FeatureCache {
    /// A cache in `dir` (created if missing) for features of `encoder`,
    /// whose model files stamp as `model`.
    pub fn new(dir: &Path, encoder: &str, model: &str) -> Result<FeatureCache, EncodeError> {
        crate::io::atomic::create_folder(dir).map_err(|err| EncodeError::Io {
            path: dir.to_path_buf(),
            err,
        })?;
        Ok(FeatureCache {
            dir: dir.to_path_buf(),
            encoder: encoder.to_string(),
            model: model.to_string(),
        })
    }

    /// The `.npy` file of frame `frame` (a frame id such as `000042`).
    pub fn npy_path(&self, frame: &str) -> PathBuf {
        self.dir.join(format!("{frame}.npy"))
    }

    fn meta_path(&self, frame: &str) -> PathBuf {
        self.dir.join(format!("{frame}.json"))
    }

    /// The cached map of `frame` made from the image whose [`stamp`] is
    /// `image` (`None`: any), or `None` if it is not cached or was made
    /// from another image or by another model (stamps that differ). A
    /// cached map from another encoder, or whose files disagree, is an
    /// error.
    pub fn load(
        &self,
        frame: &str,
        image: Option<&str>,
    ) -> Result<Option<FeatureMap>, EncodeError> {
        let npy = self.npy_path(frame);
        let meta_path = self.meta_path(frame);
        if !npy.is_file() || !meta_path.is_file() {
            return Ok(None);
        }
        let text =
            crate::io::bounded_read::read_text(&meta_path).map_err(|err| EncodeError::Io {
                path: meta_path.clone(),
                err,
            })?;
        let meta: CacheMeta = serde_json::from_str(&text).map_err(|e| EncodeError::Card {
            path: meta_path.clone(),
            reason: format!("cache metadata: line {}: {e}", e.line()),
        })?;
        if meta.encoder != self.encoder {
            return Err(EncodeError::Input(format!(
                "{}: cached features come from encoder `{}`, not `{}`; use another cache directory",
                meta_path.display(),
                meta.encoder,
                self.encoder
            )));
        }
        let stale = |entry: &Option<String>, now: Option<&str>| matches!((entry, now), (Some(e), Some(n)) if e != n);
        if stale(&meta.model, Some(&self.model)) || stale(&meta.image, image) {
            return Ok(None);
        }
        let arr = read_npy(&npy)?;
        let [h, w, f] = arr.shape[..] else {
            return Err(EncodeError::Shape {
                path: npy,
                what: "cached feature map".into(),
                got: arr.shape,
                expected: "[H, W, F]".into(),
            });
        };
        Ok(Some(FeatureMap {
            height: h,
            width: w,
            dim: f,
            data: arr.data,
            origin: meta.origin,
            cell_size: meta.cell_size,
        }))
    }

    /// Writes `map` for `frame`, made from the image of [`stamp`] `image`
    /// (both files atomically; the `.json` last, so a crash between them
    /// leaves the frame uncached, not half-cached). A `.npy` there without
    /// its `.json` is not the cache's (a sequence's own `features/`, say):
    /// an error, never replaced.
    pub fn store(
        &self,
        frame: &str,
        map: &FeatureMap,
        image: Option<&str>,
    ) -> Result<(), EncodeError> {
        let npy = self.npy_path(frame);
        let path = self.meta_path(frame);
        if npy.exists() && !path.is_file() {
            return Err(EncodeError::Input(format!(
                "{}: a .npy that is no cache entry (no {} beside it) would be replaced: use an \
                 empty or new folder as the feature cache",
                npy.display(),
                path.file_name().unwrap_or_default().to_string_lossy()
            )));
        }
        write_npy(&npy, &map.shape(), &map.data)?;
        let meta = CacheMeta {
            encoder: self.encoder.clone(),
            origin: map.origin,
            cell_size: map.cell_size,
            image: image.map(str::to_string),
            model: Some(self.model.clone()),
        };
        let io = |err| EncodeError::Io {
            path: path.clone(),
            err,
        };
        let text = serde_json::to_string_pretty(&meta)
            .map_err(|e| EncodeError::Input(format!("cache metadata: {e}")))?;
        crate::io::atomic::write(&path, text.as_bytes()).map_err(io)
    }

    /// The cached map of `frame` from the image of [`stamp`] `image`, or
    /// `compute()`'s result, stored first.
    pub fn get_or_compute(
        &self,
        frame: &str,
        image: Option<&str>,
        compute: impl FnOnce() -> Result<FeatureMap, EncodeError>,
    ) -> Result<FeatureMap, EncodeError> {
        if let Some(m) = self.load(frame, image)? {
            return Ok(m);
        }
        let m = compute()?;
        self.store(frame, &m, image)?;
        Ok(m)
    }
}

/// An image encoder over a sequence's frames with its optional feature
/// cache: frame `i`'s features are read from the cache when the same
/// encoder made them, computed from its image file otherwise.
pub struct ImageSource {
    encoder: super::ImageEncoder,
    cache: Option<FeatureCache>,
    /// The encoder's name (its card's), the map's feature space.
    pub name: String,
}

impl ImageSource {
    /// `encoder` with a cache in `cache_dir`, if given; `model` is the
    /// [`stamp`] of the encoder's files (its ONNX model and card).
    pub fn new(
        encoder: super::ImageEncoder,
        cache_dir: Option<&Path>,
        model: &str,
    ) -> Result<ImageSource, EncodeError> {
        let name = encoder.card().name.clone();
        let cache = cache_dir
            .map(|d| FeatureCache::new(d, &name, model))
            .transpose()?;
        Ok(ImageSource {
            encoder,
            cache,
            name,
        })
    }

    /// Feature dimension of the encoder.
    pub fn dim(&self) -> usize {
        self.encoder.feature_dim()
    }

    /// Features of the image file `rgb` (frame `frame` of its sequence).
    pub fn encode(&mut self, rgb: &Path, frame: usize) -> Result<FeatureMap, EncodeError> {
        let id = format!("{frame:06}");
        let enc = &mut self.encoder;
        let mut compute = || {
            let img =
                crate::io::rgb::read_rgb(rgb).map_err(|e| EncodeError::Input(e.to_string()))?;
            enc.encode(&img)
        };
        match &self.cache {
            Some(c) => c.get_or_compute(&id, Some(&stamp(&[rgb])?), compute),
            None => compute(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map() -> FeatureMap {
        FeatureMap {
            height: 2,
            width: 3,
            dim: 4,
            data: (0..24).map(|i| i as f32 * 0.25).collect(),
            origin: [1.0, 2.0],
            cell_size: [8.0, 8.0],
        }
    }

    #[test]
    fn round_trip_and_compute_once() {
        let dir = tempfile::tempdir().unwrap();
        let cache = FeatureCache::new(&dir.path().join("c"), "enc", "m1").unwrap();
        assert!(cache.load("000001", Some("i1")).unwrap().is_none());
        let calls = std::cell::Cell::new(0);
        let get = |image: &str| {
            cache
                .get_or_compute("000001", Some(image), || {
                    calls.set(calls.get() + 1);
                    Ok(map())
                })
                .unwrap()
        };
        let a = get("i1");
        let b = get("i1");
        assert_eq!(a, b);
        assert_eq!(calls.get(), 1);
        // Another image of the same frame number: computed anew.
        get("i2");
        assert_eq!(calls.get(), 2);
        assert_eq!(
            read_npy(&cache.npy_path("000001")).unwrap().shape,
            vec![2, 3, 4]
        );
        // Another model of the same name: not returned.
        let other = FeatureCache::new(&dir.path().join("c"), "enc", "m2").unwrap();
        assert!(other.load("000001", Some("i2")).unwrap().is_none());
        assert!(cache.load("000001", Some("i2")).unwrap().is_some());
        // An entry without stamps (an external tool's) is trusted.
        let meta = cache.meta_path("000001");
        let text = std::fs::read_to_string(&meta).unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v.as_object_mut().unwrap().remove("image");
        v.as_object_mut().unwrap().remove("model");
        std::fs::write(&meta, v.to_string()).unwrap();
        assert!(other.load("000001", Some("i9")).unwrap().is_some());
    }

    #[test]
    fn a_npy_without_its_json_is_never_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let npy = dir.path().join("000000.npy");
        write_npy(&npy, &[1, 1, 1], &[7.0]).unwrap();
        let before = std::fs::read(&npy).unwrap();
        let cache = FeatureCache::new(dir.path(), "enc", "m").unwrap();
        let e = cache
            .get_or_compute("000000", Some("i"), || Ok(map()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no cache entry"), "{e}");
        assert_eq!(std::fs::read(&npy).unwrap(), before);
    }

    #[test]
    fn stamps_tell_contents_apart() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        std::fs::write(&a, b"abc").unwrap();
        std::fs::write(&b, b"abd").unwrap();
        assert_eq!(stamp(&[&a]).unwrap(), "3:352441c2");
        assert_ne!(stamp(&[&a]).unwrap(), stamp(&[&b]).unwrap());
        assert_eq!(stamp(&[&a, &b]).unwrap().split(';').count(), 2);
    }

    #[test]
    fn other_encoders_cache_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        FeatureCache::new(dir.path(), "a", "m")
            .unwrap()
            .store("f", &map(), None)
            .unwrap();
        let e = FeatureCache::new(dir.path(), "b", "m")
            .unwrap()
            .load("f", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`a`") && e.contains("`b`"), "{e}");
    }
}
