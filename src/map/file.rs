//! The map file: one self-describing, versioned safetensors file.
//!
//! Tensors: `codes` (U64, L leaves' Morton codes, strictly increasing),
//! `rows` (U32, L feature rows) and `features` (F32, K x F unit rows).
//! Header metadata (strings): `format` = `omcl-language-map`, `version`,
//! `resolution` (m), `origin_x`/`origin_y`/`origin_z` (m, world frame),
//! `feature_dim`, `tau`, `encoder`, `leaves`, `rows`, and `crc32`: the
//! CRC-32 (IEEE) of the header values (each of [`CHECKED_FIELDS`] as a
//! `name=value` line, in that order) followed by the three tensors' bytes in
//! order, so a flipped digit in the resolution or origin is caught as well as
//! a flipped byte in the data. Version 3 adds the georeference of a map
//! built from a survey ([`super::georef::FIELDS`], absent without one),
//! checked after [`CHECKED_FIELDS`]; version 2 files (without it) read as
//! they are. Version 1 files (CRC over the tensors only) are refused with a
//! message naming [`upgrade`] (`omcl map upgrade`).
//!
//! Python reads it with `safetensors.numpy.load_file(path)` and the header
//! with `safetensors.safe_open(path, "np").metadata()`.
//!
//! Writes go to a temporary file in the target's folder that is renamed into
//! place, so a failed write never leaves a damaged map.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};

use super::container::{Container, ContainerProblem, le_4, le_8};

use super::features::FeatureDb;
use super::key::GridSpec;
use super::octree::{LanguageMap, MapError};

/// Value of the `format` field.
pub const FORMAT: &str = super::container::MAP_FORMAT;
/// Version this build writes (and the newest it reads). Version 2 put the
/// header values under the checksum; version 3 added the georeference.
pub const VERSION: u32 = 3;

/// Header fields covered by the checksum (version 2), in checksum order.
/// `writer` (informational) and `crc32` itself are not.
pub const CHECKED_FIELDS: [&str; 11] = [
    "format",
    "version",
    "resolution",
    "origin_x",
    "origin_y",
    "origin_z",
    "feature_dim",
    "tau",
    "encoder",
    "leaves",
    "rows",
];

/// Which header fields a version's checksum covers.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Checked {
    /// Version 1: none.
    Data,
    /// Version 2: [`CHECKED_FIELDS`].
    Header,
    /// Version 3: those and the georeference's.
    HeaderAndGeoref,
}

/// The checksum of a map file: header values, then tensor bytes.
fn checksum(meta: &HashMap<String, String>, tensors: [&[u8]; 3], checked: Checked) -> u32 {
    let mut crc = crc32fast::Hasher::new();
    let georef: &[&str] = match checked {
        Checked::HeaderAndGeoref => &super::georef::FIELDS,
        _ => &[],
    };
    if checked != Checked::Data {
        for &name in CHECKED_FIELDS.iter().chain(georef) {
            crc.update(name.as_bytes());
            crc.update(b"=");
            crc.update(meta.get(name).map_or(&b""[..], |v| v.as_bytes()));
            crc.update(b"\n");
        }
    }
    for t in tensors {
        crc.update(t);
    }
    crc.finalize()
}

/// Errors reading or writing a map file; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum MapFileError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not an omcl map: not a safetensors file ({reason})")]
    NotSafetensors { path: PathBuf, reason: String },
    #[error(
        "{path}: not an omcl map: header field `format` is {}, expected \"{FORMAT}\"",
        super::container::describe_format(found)
    )]
    Foreign {
        path: PathBuf,
        found: Option<String>,
    },
    #[error(
        "{path}: map format version {found} is not supported (this build reads versions 2 to {VERSION})"
    )]
    Version { path: PathBuf, found: String },
    #[error(
        "{path}: map format version 1 (its checksum does not cover the header values); \
         convert it with `omcl map upgrade {path} -o NEW.omcl`, or rebuild the map"
    )]
    OldVersion { path: PathBuf },
    #[error("{path}: {problem}")]
    Container {
        path: PathBuf,
        problem: ContainerProblem,
    },
    #[error("{path}: inconsistent map: {source}")]
    Invalid { path: PathBuf, source: MapError },
}

fn le_bytes_u64(v: &[u64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn le_bytes_u32(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn le_bytes_f32(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Serializes a map into the bytes of a map file.
pub fn to_bytes(map: &LanguageMap) -> Vec<u8> {
    let codes = le_bytes_u64(map.codes());
    let rows = le_bytes_u32(map.rows());
    let features = le_bytes_f32(map.db().rows());
    let g = map.grid();
    let mut meta: HashMap<String, String> = [
        ("format", FORMAT.to_string()),
        ("version", VERSION.to_string()),
        ("resolution", format!("{:?}", g.resolution)),
        ("origin_x", format!("{:?}", g.origin.x)),
        ("origin_y", format!("{:?}", g.origin.y)),
        ("origin_z", format!("{:?}", g.origin.z)),
        ("feature_dim", map.db().dim().to_string()),
        ("tau", format!("{:?}", map.db().tau())),
        ("encoder", map.encoder().to_string()),
        ("leaves", map.len().to_string()),
        ("rows", map.db().len().to_string()),
        ("writer", format!("omcl {}", env!("CARGO_PKG_VERSION"))),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    if let Some(g) = map.georef() {
        let fields = super::georef::FIELDS.iter().map(|k| k.to_string());
        meta.extend(fields.zip(g.to_fields()));
    }
    let crc = checksum(&meta, [&codes, &rows, &features], Checked::HeaderAndGeoref);
    meta.insert("crc32".into(), format!("{crc:08x}"));
    let l = map.len();
    let views = [
        ("codes", TensorView::new(Dtype::U64, vec![l], &codes)),
        ("rows", TensorView::new(Dtype::U32, vec![l], &rows)),
        (
            "features",
            TensorView::new(Dtype::F32, vec![map.db().len(), map.db().dim()], &features),
        ),
    ];
    let views = views.into_iter().map(|(n, v)| {
        (
            n,
            v.expect("tensor sizes follow from the map's own lengths"),
        )
    });
    let bytes = safetensors::serialize(views, Some(meta))
        .expect("a map always has a valid safetensors layout");
    sorted_header(bytes)
}

/// The same safetensors bytes with the header's JSON keys sorted: the
/// metadata is a `HashMap`, serialized in a per-process random order, so
/// the same map would otherwise give different files from run to run.
/// Sorting keeps the header's length (the same keys and values, compact),
/// hence every offset.
fn sorted_header(mut bytes: Vec<u8>) -> Vec<u8> {
    let n = u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes")) as usize;
    let header = &bytes[8..8 + n];
    let Ok(value) = serde_json::from_slice::<serde_json::Value>(header) else {
        return bytes;
    };
    // serde_json's map is a BTreeMap (no `preserve_order`): keys sorted.
    let Ok(text) = serde_json::to_string(&value) else {
        return bytes;
    };
    if text.len() > n {
        return bytes;
    }
    let mut sorted = text.into_bytes();
    sorted.resize(n, b' ');
    bytes[8..8 + n].copy_from_slice(&sorted);
    bytes
}

/// Writes `map` to `path` atomically.
pub fn save(map: &LanguageMap, path: &Path) -> Result<(), MapFileError> {
    let io = |source| MapFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    crate::io::atomic::write(path, &to_bytes(map)).map_err(io)
}

/// Reads a map file.
pub fn load(path: &Path) -> Result<LanguageMap, MapFileError> {
    let bytes = crate::io::bounded_read::read_regular(path).map_err(|source| MapFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    from_bytes(&bytes, path)
}

/// The header fields of a map file, without reading its tensors.
pub fn read_header(path: &Path) -> Result<HashMap<String, String>, MapFileError> {
    let bytes = crate::io::bounded_read::read_regular(path).map_err(|source| MapFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let (_, meta) =
        SafeTensors::read_metadata(&bytes).map_err(|e| MapFileError::NotSafetensors {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
    Ok(meta.metadata().clone().unwrap_or_default())
}

/// Whether `path` holds a 3-D language map: a safetensors header whose
/// `format` is [`FORMAT`], read from the file's first bytes only (at most
/// 16 MiB of header; the tensors are not read). A floor plan, another
/// safetensors file or any other file is not one.
pub fn is_map_file(path: &Path) -> std::io::Result<bool> {
    is_container_of(path, FORMAT)
}

/// Whether `path` is a safetensors container whose header names `format`
/// (a map's or a floor plan's), from its header alone.
pub fn is_container_of(path: &Path, format: &str) -> std::io::Result<bool> {
    use std::io::Read;
    let mut f = std::fs::File::open(path)?;
    let mut len = [0u8; 8];
    if f.read_exact(&mut len).is_err() {
        return Ok(false);
    }
    let n = u64::from_le_bytes(len);
    if n == 0 || n > 16 << 20 {
        return Ok(false);
    }
    let mut header = Vec::new();
    f.take(n).read_to_end(&mut header)?;
    let found = serde_json::from_slice::<serde_json::Value>(&header)
        .ok()
        .and_then(|v| v["__metadata__"]["format"].as_str().map(str::to_string));
    Ok(found.as_deref() == Some(format))
}

/// Parses the bytes of a map file; `path` names it in errors.
pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<LanguageMap, MapFileError> {
    parse_map(bytes, path, false)
}

/// Reads a map file of version 1, 2 or 3 (each checked by its own checksum
/// rule) and writes it as the current version to `out`, atomically.
pub fn upgrade(path: &Path, out: &Path) -> Result<LanguageMap, MapFileError> {
    let bytes = crate::io::bounded_read::read_regular(path).map_err(|source| MapFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let map = parse_map(&bytes, path, true)?;
    save(&map, out)?;
    Ok(map)
}

fn parse_map(bytes: &[u8], path: &Path, accept_v1: bool) -> Result<LanguageMap, MapFileError> {
    let p = || path.to_path_buf();
    let header = |e| MapFileError::from_header(path, e);
    let c = Container::open(bytes, FORMAT).map_err(header)?;
    let version = c.field("version").map_err(header)?;
    let checked = match version.parse::<u32>() {
        Ok(VERSION) => Checked::HeaderAndGeoref,
        Ok(2) => Checked::Header,
        Ok(1) if accept_v1 => Checked::Data,
        Ok(1) => return Err(MapFileError::OldVersion { path: p() }),
        _ => {
            return Err(MapFileError::Version {
                path: p(),
                found: version.to_string(),
            });
        }
    };
    let resolution = c.positive("resolution").map_err(header)?;
    let origin_in = |key: &'static str| {
        c.parse(
            key,
            "a finite number of metres within 1e9 of 0",
            |v: &f64| v.is_finite() && v.abs() <= crate::geometry::MAX_COORDINATE_M,
        )
    };
    let origin = Vector3::new(
        origin_in("origin_x").map_err(header)?,
        origin_in("origin_y").map_err(header)?,
        origin_in("origin_z").map_err(header)?,
    );
    let dim: usize = c
        .parse("feature_dim", "a positive integer", |d| *d > 0)
        .map_err(header)?;
    let tau: f32 = c
        .parse("tau", "a cosine distance in [0, 2]", |t: &f32| {
            (0.0..=2.0).contains(t)
        })
        .map_err(header)?;
    let leaves: usize = c.parse("leaves", "an integer", |_| true).map_err(header)?;
    let nrows: usize = c.parse("rows", "an integer", |_| true).map_err(header)?;
    let stored = c.crc32().map_err(header)?;
    let encoder = c.field("encoder").map_err(header)?.to_string();
    let codes_b = c.tensor("codes", Dtype::U64, &[leaves]).map_err(header)?;
    let rows_b = c.tensor("rows", Dtype::U32, &[leaves]).map_err(header)?;
    let feat_b = c
        .tensor("features", Dtype::F32, &[nrows, dim])
        .map_err(header)?;
    let computed = checksum(&c.meta, [codes_b, rows_b, feat_b], checked);
    if computed != stored {
        return Err(MapFileError::Container {
            path: p(),
            problem: ContainerProblem::Checksum { stored, computed },
        });
    }
    let codes = le_8(codes_b, u64::from_le_bytes);
    let rows = le_4(rows_b, u32::from_le_bytes);
    let feats = le_4(feat_b, f32::from_le_bytes);
    let invalid = |source: MapError| MapFileError::Invalid { path: p(), source };
    let db = FeatureDb::from_rows(dim, tau, feats).map_err(|e| invalid(e.into()))?;
    let georef = if checked == Checked::HeaderAndGeoref {
        let field = |k: &str| c.meta.get(k).map(String::as_str);
        super::georef::Georef::from_fields(field).map_err(|f| MapFileError::Container {
            path: p(),
            problem: match f.value {
                None => ContainerProblem::MissingField(f.field),
                Some(value) => ContainerProblem::BadField {
                    field: f.field,
                    value,
                    expected: f.expected,
                },
            },
        })?
    } else {
        None
    };
    let grid = GridSpec { resolution, origin };
    Ok(LanguageMap::from_sorted(grid, db, encoder, codes, rows)
        .map_err(invalid)?
        .with_georef(georef))
}

super::container::header_errors!(MapFileError);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_map_gives_the_same_bytes_and_reads_back() {
        use crate::map::{FeatureDb, GridSpec};
        let db = FeatureDb::from_rows(2, 0.0, vec![1.0, 0.0, 0.0, 1.0]).unwrap();
        let grid = GridSpec {
            resolution: 0.05,
            origin: nalgebra::Vector3::new(1.0, -2.0, 3.0),
        };
        let m =
            LanguageMap::from_cells(grid, db, "enc", (0..10).map(|i| ([i, 0, 1], i as u32 % 2)))
                .unwrap();
        let a = to_bytes(&m);
        // Headers in every key order the HashMap may produce serialize the
        // same: the header's keys are sorted.
        let n = u64::from_le_bytes(a[..8].try_into().unwrap()) as usize;
        let header: serde_json::Value = serde_json::from_slice(&a[8..8 + n]).unwrap();
        let keys: Vec<&String> = header["__metadata__"].as_object().unwrap().keys().collect();
        let mut sorted = keys.clone();
        sorted.sort();
        assert_eq!(keys, sorted);
        let text = std::str::from_utf8(&a[8..8 + n]).unwrap();
        let pos = |k: &str| text.find(&format!("\"{k}\"")).unwrap();
        assert!(
            pos("crc32") < pos("encoder") && pos("encoder") < pos("writer"),
            "{text}"
        );
        for _ in 0..5 {
            assert_eq!(to_bytes(&m), a);
        }
        assert_eq!(from_bytes(&a, Path::new("m.omcl")).unwrap(), m);
    }

    #[test]
    fn an_origin_beyond_any_place_on_earth_is_refused_by_name() {
        use crate::map::{FeatureDb, GridSpec};
        let db = FeatureDb::from_rows(2, 0.0, vec![1.0, 0.0, 0.0, 1.0]).unwrap();
        let map = |x: f64| {
            let grid = GridSpec {
                resolution: 0.05,
                origin: Vector3::new(x, 0.0, 0.0),
            };
            LanguageMap::from_cells(grid, db.clone(), "enc", [([0, 0, 0], 0)]).unwrap()
        };
        let utm = map(5.2e6);
        assert_eq!(
            from_bytes(&to_bytes(&utm), Path::new("m.omcl")).unwrap(),
            utm
        );
        let e = from_bytes(&to_bytes(&map(1e308)), Path::new("far.omcl"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("far.omcl") && e.contains("origin_x"), "{e}");
    }

    fn sample() -> LanguageMap {
        let db = FeatureDb::from_rows(3, 0.05, vec![1.0, 0.0, 0.0, 0.0, 0.6, 0.8]).unwrap();
        let grid = GridSpec {
            resolution: 0.05,
            origin: Vector3::new(-12.345678901234, 0.1, 1e6 + 0.3),
        };
        LanguageMap::from_cells(
            grid,
            db,
            "clip-vit-b32",
            vec![([0, 0, 0], 0), ([-3, 7, 2], 1), ([100, -100, 5], 1)],
        )
        .unwrap()
    }

    #[test]
    fn round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.omcl");
        let m = sample();
        save(&m, &path).unwrap();
        let back = load(&path).unwrap();
        assert_eq!(back, m);
        let h = read_header(&path).unwrap();
        assert_eq!(h["encoder"], "clip-vit-b32");
        assert_eq!(h["leaves"], "3");
        // No temporary file is left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn round_trip_of_a_realistic_map_is_bit_exact() {
        // Rows produced by normalization are unit only within float error.
        let mut db = FeatureDb::new(7, 0.02).unwrap();
        for i in 0..20 {
            let f: Vec<f32> = (0..7).map(|j| ((i * 7 + j) as f32 * 0.731).sin()).collect();
            db.admit(&f).unwrap();
        }
        let k = db.len() as u32;
        let grid = GridSpec {
            resolution: 0.02,
            origin: Vector3::new(0.1, 0.2, 0.3),
        };
        let leaves = (0..500).map(|i| ([i % 13 - 6, i / 13, i % 5], i as u32 % k));
        let m = LanguageMap::from_cells(grid, db, "x", leaves).unwrap();
        let back = from_bytes(&to_bytes(&m), Path::new("r")).unwrap();
        assert_eq!(back, m);
    }

    #[test]
    fn empty_map_round_trips() {
        let db = FeatureDb::new(4, 0.02).unwrap();
        let grid = GridSpec {
            resolution: 1.0,
            origin: Vector3::zeros(),
        };
        let m = LanguageMap::from_sorted(grid, db, "none", vec![], vec![]).unwrap();
        let back = from_bytes(&to_bytes(&m), Path::new("e")).unwrap();
        assert_eq!(back, m);
    }

    #[test]
    fn every_flipped_data_byte_is_caught() {
        let bytes = to_bytes(&sample());
        let header_len = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
        for i in (8 + header_len)..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x10;
            let e = from_bytes(&b, Path::new("x.omcl")).unwrap_err();
            assert!(
                matches!(
                    e,
                    MapFileError::Container {
                        problem: ContainerProblem::Checksum { .. },
                        ..
                    }
                ),
                "byte {i}: {e}"
            );
            assert!(e.to_string().contains("x.omcl"));
        }
    }

    #[test]
    fn truncation_is_caught_at_every_length() {
        let bytes = to_bytes(&sample());
        for n in 0..bytes.len() {
            assert!(
                from_bytes(&bytes[..n], Path::new("t")).is_err(),
                "length {n}"
            );
        }
    }

    #[test]
    fn wrong_version_and_foreign_files_are_named() {
        let bytes = to_bytes(&sample());
        // Same-length edit of the version inside the JSON header.
        let needle = b"\"version\":\"3\"";
        let at = bytes
            .windows(needle.len())
            .position(|w| w == needle)
            .expect("header holds the version");
        let mut edited = bytes.clone();
        edited[at + needle.len() - 2] = b'9';
        let e = from_bytes(&edited, Path::new("v.omcl")).unwrap_err();
        assert!(matches!(e, MapFileError::Version { .. }), "{e}");
        assert!(e.to_string().contains("version 9"));

        let other = safetensors::serialize(
            [(
                "x",
                TensorView::new(Dtype::F32, vec![1], &[0u8; 4]).unwrap(),
            )],
            None,
        )
        .unwrap();
        let e = from_bytes(&other, Path::new("model.safetensors")).unwrap_err();
        assert!(matches!(e, MapFileError::Foreign { .. }), "{e}");

        let e = from_bytes(b"ply\nformat ascii 1.0\n", Path::new("cloud.ply")).unwrap_err();
        assert!(matches!(e, MapFileError::NotSafetensors { .. }), "{e}");
        assert!(e.to_string().contains("cloud.ply"));
        // What such a file is, said (the parser had said "header too
        // large"), and a cut file called truncated.
        assert!(e.to_string().contains("it is a PLY point cloud"), "{e}");
        let e = from_bytes(b"LASF\0\0\0\0\0\0", Path::new("s.omcl")).unwrap_err();
        assert!(e.to_string().contains("a LAS/LAZ point cloud"), "{e}");
        let whole = to_bytes(&sample());
        let e = from_bytes(&whole[..whole.len() / 2], Path::new("cut.omcl")).unwrap_err();
        assert!(e.to_string().contains("truncated"), "{e}");
    }

    /// `bytes` with the first occurrence of `from` replaced by `to` (same
    /// length, so the safetensors layout stays valid).
    fn edit(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
        assert_eq!(from.len(), to.len());
        let at = bytes
            .windows(from.len())
            .position(|w| w == from.as_bytes())
            .unwrap_or_else(|| panic!("{from} not in the file"));
        let mut out = bytes.to_vec();
        out[at..at + to.len()].copy_from_slice(to.as_bytes());
        out
    }

    #[test]
    fn a_changed_header_value_fails_the_checksum() {
        let bytes = to_bytes(&sample());
        // resolution 0.05 -> 0.06; origin_y 0.1 -> 0.2; tau 0.05 -> 0.07;
        // the encoder's name; every one a valid value, so only the checksum
        // can tell.
        for (from, to) in [
            ("\"resolution\":\"0.05\"", "\"resolution\":\"0.06\""),
            ("\"origin_y\":\"0.1\"", "\"origin_y\":\"0.2\""),
            ("\"tau\":\"0.05\"", "\"tau\":\"0.07\""),
            ("clip-vit-b32", "clip-vit-b16"),
        ] {
            let e = from_bytes(&edit(&bytes, from, to), Path::new("h.omcl")).unwrap_err();
            assert!(
                matches!(
                    e,
                    MapFileError::Container {
                        problem: ContainerProblem::Checksum { .. },
                        ..
                    }
                ),
                "{to}: {e}"
            );
        }
        // The informational writer field is not covered.
        let w = format!("omcl {}", env!("CARGO_PKG_VERSION"));
        let other = format!("omcX {}", env!("CARGO_PKG_VERSION"));
        assert!(from_bytes(&edit(&bytes, &w, &other), Path::new("h.omcl")).is_ok());
    }

    /// A version-1 file of `map`: the old checksum over the tensors only.
    fn version_1_bytes(map: &LanguageMap) -> Vec<u8> {
        old_bytes(map, "1", Checked::Data)
    }

    /// A file of `map` as an older `version` wrote it, its checksum by
    /// that version's rule.
    fn old_bytes(map: &LanguageMap, version: &str, checked: Checked) -> Vec<u8> {
        let codes = le_bytes_u64(map.codes());
        let rows = le_bytes_u32(map.rows());
        let features = le_bytes_f32(map.db().rows());
        let (_, header) = SafeTensors::read_metadata(&to_bytes(map)).unwrap();
        let mut meta = header.metadata().clone().unwrap();
        meta.insert("version".into(), version.into());
        let crc = checksum(&meta, [&codes, &rows, &features], checked);
        meta.insert("crc32".into(), format!("{crc:08x}"));
        let l = map.len();
        let views = [
            (
                "codes",
                TensorView::new(Dtype::U64, vec![l], &codes).unwrap(),
            ),
            ("rows", TensorView::new(Dtype::U32, vec![l], &rows).unwrap()),
            (
                "features",
                TensorView::new(Dtype::F32, vec![map.db().len(), map.db().dim()], &features)
                    .unwrap(),
            ),
        ];
        safetensors::serialize(views, Some(meta)).unwrap()
    }

    fn georeferenced() -> LanguageMap {
        sample().with_georef(Some(crate::map::Georef {
            crs: "ETRS89 / UTM zone 32N (EPSG:25832)".into(),
            records: vec![(34735, vec![1, 0, 1, 0, 0, 0]), (34737, b"UTM|".to_vec())],
            wkt: false,
            metres_per_unit: [0.3048, 1.0],
        }))
    }

    #[test]
    fn a_georeference_round_trips_under_the_checksum() {
        let m = georeferenced();
        let bytes = to_bytes(&m);
        let back = from_bytes(&bytes, Path::new("g.omcl")).unwrap();
        assert_eq!(back, m);
        assert_eq!(back.georef(), m.georef());
        for (from, to) in [
            ("zone 32N", "zone 33N"),
            ("\"crs_wkt\":\"false\"", "\"crs_wkt\":\"true!\""),
            (
                "\"metres_per_unit_xy\":\"0.3048\"",
                "\"metres_per_unit_xy\":\"0.3049\"",
            ),
            ("34737:", "34736:"),
        ] {
            let e = from_bytes(&edit(&bytes, from, to), Path::new("g.omcl")).unwrap_err();
            assert!(
                matches!(
                    e,
                    MapFileError::Container {
                        problem: ContainerProblem::Checksum { .. },
                        ..
                    }
                ),
                "{to}: {e}"
            );
        }
    }

    #[test]
    fn version_2_files_read_as_they_are_without_a_georeference() {
        let m = sample();
        let v2 = old_bytes(&m, "2", Checked::Header);
        let back = from_bytes(&v2, Path::new("v2.omcl")).unwrap();
        assert_eq!(back, m);
        assert_eq!(back.georef(), None);
        // Its header values are still under its checksum.
        let e = from_bytes(
            &edit(&v2, "clip-vit-b32", "clip-vit-b16"),
            Path::new("v2.omcl"),
        );
        assert!(e.is_err());
        // A version-3 file checked by the version-2 rule is not one.
        let v3_rule = old_bytes(&georeferenced(), "2", Checked::HeaderAndGeoref);
        assert!(from_bytes(&v3_rule, Path::new("x.omcl")).is_err());
    }

    #[test]
    fn version_1_files_are_refused_with_the_way_out_and_upgrade() {
        let dir = tempfile::tempdir().unwrap();
        let old = dir.path().join("old.omcl");
        let new = dir.path().join("new.omcl");
        let m = sample();
        std::fs::write(&old, version_1_bytes(&m)).unwrap();
        let e = load(&old).unwrap_err();
        assert!(matches!(e, MapFileError::OldVersion { .. }), "{e}");
        let msg = e.to_string();
        assert!(
            msg.contains("old.omcl") && msg.contains("omcl map upgrade"),
            "{msg}"
        );
        let up = upgrade(&old, &new).unwrap();
        assert_eq!(up, m);
        assert_eq!(load(&new).unwrap(), m);
        assert_eq!(read_header(&new).unwrap()["version"], VERSION.to_string());
        // A version-1 file with a flipped tensor byte is still caught.
        let mut bad = version_1_bytes(&m);
        let last = bad.len() - 1;
        bad[last] ^= 1;
        std::fs::write(&old, bad).unwrap();
        assert!(matches!(
            upgrade(&old, &new),
            Err(MapFileError::Container {
                problem: ContainerProblem::Checksum { .. },
                ..
            })
        ));
    }

    #[test]
    fn a_failed_save_leaves_the_old_file_intact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.omcl");
        save(&sample(), &path).unwrap();
        let before = std::fs::read(&path).unwrap();
        // Saving into a missing folder fails without touching anything else.
        assert!(save(&sample(), &dir.path().join("missing/m.omcl")).is_err());
        assert_eq!(std::fs::read(&path).unwrap(), before);
    }
}
