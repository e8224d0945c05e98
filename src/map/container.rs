//! The container both map files use (`.omcl` language maps and floor
//! plans): a safetensors file whose header metadata names the format and
//! holds typed fields, and whose tensors have the dtype and shape the
//! header promises. Reading it is written once here; each file type maps
//! [`HeaderError`] into its own error, which names the file.

use std::collections::HashMap;
use std::str::FromStr;

use safetensors::tensor::{Dtype, SafeTensors};

/// What is wrong with a container's content, the same for both file
/// types: a header field, a tensor, or the checksum. The file's error adds
/// its name.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContainerProblem {
    #[error("header field `{0}` is missing")]
    MissingField(&'static str),
    #[error("header field `{field}` = {value:?} is not valid: {expected}")]
    BadField {
        field: &'static str,
        value: String,
        expected: &'static str,
    },
    #[error("tensor `{name}`: {reason}")]
    Tensor { name: &'static str, reason: String },
    #[error(
        "checksum mismatch (header says {stored:08x}, data gives {computed:08x}): the file is corrupt"
    )]
    Checksum { stored: u32, computed: u32 },
}

/// What is wrong with a container, before the file's name is added: not a
/// container, another format (their messages name the file type), or a
/// problem with its content.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum HeaderError {
    NotSafetensors(String),
    Foreign(Option<String>),
    Content(ContainerProblem),
}

impl From<ContainerProblem> for HeaderError {
    fn from(p: ContainerProblem) -> Self {
        HeaderError::Content(p)
    }
}

/// An opened container of the expected format.
pub(crate) struct Container<'a> {
    tensors: SafeTensors<'a>,
    /// The header's metadata (the fields and the format's name).
    pub meta: HashMap<String, String>,
}

impl<'a> Container<'a> {
    /// Opens `bytes` as a container whose `format` field is `format`.
    pub fn open(bytes: &'a [u8], format: &str) -> Result<Self, HeaderError> {
        // Files a map is often mistaken for, by their first bytes: their
        // kind said, not the safetensors parser's "header too large".
        for (magic, kind) in [
            (&b"ply"[..], "a PLY point cloud"),
            (b"LASF", "a LAS/LAZ point cloud"),
            (b"\x89PNG", "a PNG image"),
            (b"\xff\xd8\xff", "a JPEG image"),
            (b"\x93NUMPY", "a .npy array"),
        ] {
            if bytes.starts_with(magic) {
                return Err(HeaderError::NotSafetensors(format!(
                    "it is {kind}; `omcl map cloud` builds a map from a cloud"
                )));
            }
        }
        if bytes.len() < 8 {
            return Err(HeaderError::NotSafetensors(format!(
                "{} byte{}: truncated or empty",
                bytes.len(),
                if bytes.len() == 1 { "" } else { "s" }
            )));
        }
        let declared = u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes"));
        if declared <= 100 << 20 && declared > bytes.len() as u64 - 8 {
            return Err(HeaderError::NotSafetensors(format!(
                "its header takes {declared} bytes and the file has {}: truncated?",
                bytes.len()
            )));
        }
        let tensors = SafeTensors::deserialize(bytes).map_err(|e| {
            HeaderError::NotSafetensors(match e.to_string() {
                m if m.contains("incomplete metadata") => format!("{m}: truncated?"),
                // Its tensors' data and the file's end differ: cut short,
                // or bytes appended after it.
                m if m.contains("not fully covered") => {
                    format!("{m}: truncated, or bytes appended after its data?")
                }
                m => m,
            })
        })?;
        let (_, header) = SafeTensors::read_metadata(bytes)
            .map_err(|e| HeaderError::NotSafetensors(e.to_string()))?;
        let meta = header.metadata().clone().unwrap_or_default();
        let found = meta.get("format");
        if found.map(String::as_str) != Some(format) {
            return Err(HeaderError::Foreign(found.cloned()));
        }
        Ok(Container { tensors, meta })
    }

    /// The text of header field `name`.
    pub fn field(&self, name: &'static str) -> Result<&str, HeaderError> {
        self.meta
            .get(name)
            .map(String::as_str)
            .ok_or(ContainerProblem::MissingField(name).into())
    }

    /// Header field `name` parsed as a `T` that passes `ok` (`expected`
    /// says what a valid value is).
    pub fn parse<T: FromStr>(
        &self,
        name: &'static str,
        expected: &'static str,
        ok: impl Fn(&T) -> bool,
    ) -> Result<T, HeaderError> {
        let v = self.field(name)?;
        v.parse::<T>().ok().filter(|x| ok(x)).ok_or_else(|| {
            ContainerProblem::BadField {
                field: name,
                value: v.to_string(),
                expected,
            }
            .into()
        })
    }

    /// A finite number.
    pub fn finite(&self, name: &'static str) -> Result<f64, HeaderError> {
        self.parse(name, "a finite number", |x: &f64| x.is_finite())
    }

    /// A positive finite number (a resolution).
    pub fn positive(&self, name: &'static str) -> Result<f64, HeaderError> {
        self.parse(name, "a positive number", |x: &f64| {
            x.is_finite() && *x > 0.0
        })
    }

    /// The stored CRC-32 (`crc32`, 8 hex digits).
    pub fn crc32(&self) -> Result<u32, HeaderError> {
        let v = self.field("crc32")?;
        u32::from_str_radix(v, 16).map_err(|_| {
            ContainerProblem::BadField {
                field: "crc32",
                value: v.to_string(),
                expected: "8 hex digits",
            }
            .into()
        })
    }

    /// The bytes of tensor `name`, which must be of `dtype` and `shape`.
    pub fn tensor(
        &self,
        name: &'static str,
        dtype: Dtype,
        shape: &[usize],
    ) -> Result<&'a [u8], HeaderError> {
        let t = self
            .tensors
            .tensor(name)
            .map_err(|e| ContainerProblem::Tensor {
                name,
                reason: e.to_string(),
            })?;
        if t.dtype() != dtype || t.shape() != shape {
            return Err(ContainerProblem::Tensor {
                name,
                reason: format!(
                    "is {:?} {:?}, header promises {:?} {:?}",
                    t.dtype(),
                    t.shape(),
                    dtype,
                    shape
                ),
            }
            .into());
        }
        Ok(t.data())
    }
}

/// The `format` field of a 3-D language map file ([`super::file`]).
pub(crate) const MAP_FORMAT: &str = "omcl-language-map";

/// The `format` field of a floor-plan file ([`super::floorplan`]).
pub(crate) const PLAN_FORMAT: &str = "omcl-floor-plan";

/// A file's `format` field as an error names it: quoted, with what it is
/// when it is one of omcl's own ("missing" when there is none).
pub(crate) fn describe_format(found: &Option<String>) -> String {
    match found.as_deref() {
        None => "missing".into(),
        Some(f) if f == MAP_FORMAT => format!("{f:?} (a 3-D language map)"),
        Some(f) if f == PLAN_FORMAT => {
            format!("{f:?} (a floor plan, `omcl map floorplan`'s output)")
        }
        Some(f) => format!("{f:?}"),
    }
}

/// Little-endian 4-byte values.
pub(crate) fn le_4<T>(bytes: &[u8], from: fn([u8; 4]) -> T) -> Vec<T> {
    bytes
        .chunks_exact(4)
        .map(|c| from(c.try_into().expect("chunks of 4")))
        .collect()
}

/// Little-endian 8-byte values.
pub(crate) fn le_8<T>(bytes: &[u8], from: fn([u8; 8]) -> T) -> Vec<T> {
    bytes
        .chunks_exact(8)
        .map(|c| from(c.try_into().expect("chunks of 8")))
        .collect()
}

/// `impl $ty { fn from_header(path, HeaderError) -> $ty }` for a file
/// type's error enum with the variants `NotSafetensors`, `Foreign` (whose
/// messages name the file type) and `Container`, each with the file's
/// `path`.
macro_rules! header_errors {
    ($ty:ident) => {
        impl $ty {
            /// The error of container problem `e` in the file at `path`.
            fn from_header(path: &std::path::Path, e: super::container::HeaderError) -> Self {
                use super::container::HeaderError as H;
                let path = path.to_path_buf();
                match e {
                    H::NotSafetensors(reason) => Self::NotSafetensors { path, reason },
                    H::Foreign(found) => Self::Foreign { path, found },
                    H::Content(problem) => Self::Container { path, problem },
                }
            }
        }
    };
}
pub(crate) use header_errors;
