//! Per-frame feature cache: an image encoder runs once per frame and its
//! feature map is reused by later runs (mapping, then many localisation
//! sweeps over the same frames).
//!
//! Each frame is two files in the cache directory: `<frame>.npy`, the
//! `H x W x F` float32 feature map (what Python tools read and write), and
//! `<frame>.json`, its placement on the image and the encoder that made it,
//! so a cache filled by another encoder is refused rather than mixed in.
//! Features computed by any external tool can be dropped in as `.npy` with
//! a matching `.json`.

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
}

/// A directory of cached feature maps for one encoder.
#[derive(Debug, Clone)]
pub struct FeatureCache {
    dir: PathBuf,
    encoder: String,
}

impl FeatureCache {
    /// A cache in `dir` (created if missing) for features of `encoder`.
    pub fn new(dir: &Path, encoder: &str) -> Result<FeatureCache, EncodeError> {
        crate::io::atomic::create_folder(dir).map_err(|err| EncodeError::Io {
            path: dir.to_path_buf(),
            err,
        })?;
        Ok(FeatureCache {
            dir: dir.to_path_buf(),
            encoder: encoder.to_string(),
        })
    }

    /// The `.npy` file of frame `frame` (a frame id such as `000042`).
    pub fn npy_path(&self, frame: &str) -> PathBuf {
        self.dir.join(format!("{frame}.npy"))
    }

    fn meta_path(&self, frame: &str) -> PathBuf {
        self.dir.join(format!("{frame}.json"))
    }

    /// The cached map of `frame`, or `None` if it is not cached. A cached
    /// map from another encoder, or whose files disagree, is an error.
    pub fn load(&self, frame: &str) -> Result<Option<FeatureMap>, EncodeError> {
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

    /// Writes `map` for `frame` (both files atomically; the `.json` last,
    /// so a crash between them leaves the frame uncached, not half-cached).
    pub fn store(&self, frame: &str, map: &FeatureMap) -> Result<(), EncodeError> {
        write_npy(&self.npy_path(frame), &map.shape(), &map.data)?;
        let meta = CacheMeta {
            encoder: self.encoder.clone(),
            origin: map.origin,
            cell_size: map.cell_size,
        };
        let path = self.meta_path(frame);
        let io = |err| EncodeError::Io {
            path: path.clone(),
            err,
        };
        let text = serde_json::to_string_pretty(&meta)
            .map_err(|e| EncodeError::Input(format!("cache metadata: {e}")))?;
        crate::io::atomic::write(&path, text.as_bytes()).map_err(io)
    }

    /// The cached map of `frame`, or `compute()`'s result, stored first.
    pub fn get_or_compute(
        &self,
        frame: &str,
        compute: impl FnOnce() -> Result<FeatureMap, EncodeError>,
    ) -> Result<FeatureMap, EncodeError> {
        if let Some(m) = self.load(frame)? {
            return Ok(m);
        }
        let m = compute()?;
        self.store(frame, &m)?;
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
    /// `encoder` with a cache in `cache_dir`, if given.
    pub fn new(
        encoder: super::ImageEncoder,
        cache_dir: Option<&Path>,
    ) -> Result<ImageSource, EncodeError> {
        let name = encoder.card().name.clone();
        let cache = cache_dir.map(|d| FeatureCache::new(d, &name)).transpose()?;
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
            Some(c) => c.get_or_compute(&id, compute),
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
        let cache = FeatureCache::new(&dir.path().join("c"), "enc").unwrap();
        assert!(cache.load("000001").unwrap().is_none());
        let mut calls = 0;
        let a = cache
            .get_or_compute("000001", || {
                calls += 1;
                Ok(map())
            })
            .unwrap();
        let b = cache
            .get_or_compute("000001", || {
                calls += 1;
                Ok(map())
            })
            .unwrap();
        assert_eq!(calls, 1);
        assert_eq!(a, b);
        assert_eq!(
            read_npy(&cache.npy_path("000001")).unwrap().shape,
            vec![2, 3, 4]
        );
    }

    #[test]
    fn other_encoders_cache_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        FeatureCache::new(dir.path(), "a")
            .unwrap()
            .store("f", &map())
            .unwrap();
        let e = FeatureCache::new(dir.path(), "b")
            .unwrap()
            .load("f")
            .unwrap_err()
            .to_string();
        assert!(e.contains("`a`") && e.contains("`b`"), "{e}");
    }
}
