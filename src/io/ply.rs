//! PLY point clouds: reading (ASCII, binary little- and big-endian; headers
//! and binary records with lists via `ply-rs-bw`) and writing (binary
//! little-endian, atomic).
//!
//! A file must start with the `ply` magic line; anything else is refused
//! with what it looks like instead (a LAS file renamed `.ply`, say). The
//! `vertex` element is read; other elements (faces, ...) are skipped.
//! Recognised vertex properties:
//! - `x y z`: `float` or `double` (required), metres;
//! - `red green blue` (optional, all three or none), each `uchar` (0-255),
//!   `ushort` or `float`/`double` (0-1, clamped, times 255, rounded).
//!   `ushort` is 0-65535 and keeps its high byte, but many writers store
//!   0-255 in 16 bits: when no `ushort` channel of the file exceeds 255 its
//!   values are taken as they are (the LAS reader's rule);
//! - one label property named `label`, `class`, `classification`,
//!   `semantic` or `semantic_label`, in any letter case and with or without
//!   CloudCompare's `scalar_` prefix (`scalar_Label`,
//!   `scalar_Classification`): any integer type, or a float type holding
//!   whole numbers (CloudCompare stores scalar fields as float);
//!   non-negative (optional). A property of another name (DALES's
//!   `sem_class`) is read as the labels when named in
//!   [`PlyOptions::label_property`], which also picks one of several;
//! - features `f0 f1 ...` or `feat_0 feat_1 ...` (also `feature_0 ...`):
//!   `float` or `double`, numbered consecutively from 0 in header order
//!   (optional).
//!
//! Other properties are ignored. Vertices with a non-finite coordinate
//! (`nan`, `inf`: how PCL and Open3D write invalid points) are left out
//! with their other values, and a note on the cloud counts them.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, Write};
use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    ElementDef, Encoding, Property, PropertyAccess, PropertyAccessResult, PropertyType, ScalarType,
};

use crate::io::cloud::{CloudError, PointCloud};

/// Label property names, compared ignoring letter case, each also with
/// CloudCompare's `scalar_` prefix (see [`is_label_name`]).
const LABEL_NAMES: [&str; 5] = [
    "label",
    "class",
    "classification",
    "semantic",
    "semantic_label",
];

/// A name of [`LABEL_NAMES`] in any letter case, with or without a
/// `scalar_` prefix (CloudCompare writes its scalar field `Classification`
/// as the property `scalar_Classification`).
fn is_label_name(name: &str) -> bool {
    let base = match name.get(..7) {
        Some(p) if p.eq_ignore_ascii_case("scalar_") => &name[7..],
        _ => name,
    };
    LABEL_NAMES.iter().any(|n| n.eq_ignore_ascii_case(base))
}

/// The class id a label of -1 (the common "unlabelled", of S3DIS-style
/// and many segmentation exports) is read as: no class of any table, so
/// its points are skipped as unknown labels are, with a note.
pub const UNLABELLED: u32 = u32::MAX;

/// A label value as a class id: a whole number in `0..=u32::MAX` (the
/// last, [`UNLABELLED`], as a 32-bit -1 reads unsigned), or -1.
fn label_id(raw: f64) -> Option<u32> {
    if raw == -1.0 {
        return Some(UNLABELLED);
    }
    (raw >= 0.0 && raw <= u32::MAX as f64 && raw.fract() == 0.0).then_some(raw as u32)
}

fn label_of(path: &Path, vertex: usize, raw: f64) -> Result<u32, CloudError> {
    label_id(raw).ok_or_else(|| {
        CloudError::format(
            path,
            format!(
                "vertex {vertex}: label {raw} is not a whole number in 0..=4294967295 nor -1 \
                 (unlabelled)"
            ),
        )
    })
}

const FEATURE_PREFIXES: [&str; 3] = ["feat_", "feature_", "f"];

const COLOR_NAMES: [&str; 3] = ["red", "green", "blue"];

/// A `float`/`double` colour channel (0-1) as 8 bits: clamped, times 255,
/// rounded; NaN is 0.
fn unit_to_u8(v: f64) -> u8 {
    if v.is_nan() {
        0
    } else {
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

/// True for a float colour value [`unit_to_u8`] had to clamp (or NaN).
fn outside_unit(v: f64) -> bool {
    !(0.0..=1.0).contains(&v)
}

/// The type's name as a PLY header writes it.
fn ply_type_name(t: &ScalarType) -> &'static str {
    match t {
        ScalarType::Char => "char",
        ScalarType::UChar => "uchar",
        ScalarType::Short => "short",
        ScalarType::UShort => "ushort",
        ScalarType::Int => "int",
        ScalarType::UInt => "uint",
        ScalarType::Float => "float",
        ScalarType::Double => "double",
    }
}

/// A property's type as a PLY header writes it (`int`, `list uchar int`).
fn ply_property_type(p: &PropertyType) -> String {
    match p {
        PropertyType::Scalar(t) => ply_type_name(t).to_string(),
        PropertyType::List(count, item) => {
            format!("list {} {}", ply_type_name(count), ply_type_name(item))
        }
    }
}

/// One vertex as the parser fills it. Features go to a `Vec` only when the
/// file has them (the parser constructs a fresh element per vertex, so that
/// is the one per-point allocation, and only for feature files).
#[derive(Default)]
struct Vertex {
    xyz: [f64; 3],
    /// 8-bit values, but a `ushort` channel's raw 16 bits ([`Columns::finish`]
    /// scales them).
    rgb: [u16; 3],
    /// Float colour values outside 0-1 that were clamped.
    clamped: u8,
    /// Any PLY scalar is exact in `f64`.
    label: f64,
    feat: Vec<f32>,
}

fn feature_index(name: &str) -> Option<usize> {
    FEATURE_PREFIXES.iter().find_map(|p| {
        name.strip_prefix(p)
            .filter(|rest| !rest.is_empty() && rest.bytes().all(|b| b.is_ascii_digit()))
            .and_then(|rest| rest.parse().ok())
    })
}

impl Vertex {
    fn set_f64(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        match name {
            "x" => self.xyz[0] = v,
            "y" => self.xyz[1] = v,
            "z" => self.xyz[2] = v,
            "red" => self.set_unit_colour(0, v),
            "green" => self.set_unit_colour(1, v),
            "blue" => self.set_unit_colour(2, v),
            _ if is_label_name(name) => self.label = v,
            // The header check guarantees features arrive in index order.
            _ if feature_index(name).is_some() => self.feat.push(v as f32),
            _ => return PropertyAccessResult::Ignored,
        }
        PropertyAccessResult::Set
    }

    fn set_unit_colour(&mut self, k: usize, v: f64) {
        self.clamped += u8::from(outside_unit(v));
        self.rgb[k] = unit_to_u8(v) as u16;
    }

    fn set_int(&mut self, name: &str, v: i64) -> PropertyAccessResult {
        if is_label_name(name) {
            self.label = v as f64;
            PropertyAccessResult::Set
        } else {
            PropertyAccessResult::Ignored
        }
    }
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex::default()
    }
    fn set_property(&mut self, _name: &str, _p: Property) -> PropertyAccessResult {
        PropertyAccessResult::Ignored
    }
    fn set_uchar(&mut self, name: &str, v: u8) -> PropertyAccessResult {
        match name {
            "red" => self.rgb[0] = v as u16,
            "green" => self.rgb[1] = v as u16,
            "blue" => self.rgb[2] = v as u16,
            _ => return self.set_int(name, v as i64),
        }
        PropertyAccessResult::Set
    }
    fn set_char(&mut self, name: &str, v: i8) -> PropertyAccessResult {
        self.set_int(name, v as i64)
    }
    fn set_short(&mut self, name: &str, v: i16) -> PropertyAccessResult {
        self.set_int(name, v as i64)
    }
    fn set_ushort(&mut self, name: &str, v: u16) -> PropertyAccessResult {
        // 16-bit colour, kept whole until the file's range is known.
        match name {
            "red" => self.rgb[0] = v,
            "green" => self.rgb[1] = v,
            "blue" => self.rgb[2] = v,
            _ => return self.set_int(name, v as i64),
        }
        PropertyAccessResult::Set
    }
    fn set_int(&mut self, name: &str, v: i32) -> PropertyAccessResult {
        Vertex::set_int(self, name, v as i64)
    }
    fn set_uint(&mut self, name: &str, v: u32) -> PropertyAccessResult {
        Vertex::set_int(self, name, v as i64)
    }
    fn set_float(&mut self, name: &str, v: f32) -> PropertyAccessResult {
        self.set_f64(name, v as f64)
    }
    fn set_double(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        self.set_f64(name, v)
    }
}

/// Which optional columns the vertex element declares.
struct Layout {
    colors: bool,
    /// The colour channels of type `ushort`.
    wide_colours: [bool; 3],
    label: bool,
    feature_dim: usize,
}

fn scalar(p: &PropertyType) -> Option<&ScalarType> {
    match p {
        PropertyType::Scalar(s) => Some(s),
        PropertyType::List(..) => None,
    }
}

fn check_vertex_layout(path: &Path, def: &ElementDef) -> Result<Layout, CloudError> {
    let fmt = |r: String| CloudError::format(path, r);
    let find = |n: &str| def.properties.get(n).map(|p| &p.data_type);
    for axis in ["x", "y", "z"] {
        match find(axis).and_then(scalar) {
            Some(ScalarType::Float | ScalarType::Double) => {}
            Some(t) => {
                return Err(fmt(format!(
                    "vertex property '{axis}' has type {}, expected float or double",
                    ply_type_name(t)
                )));
            }
            None => {
                let names: Vec<&str> = def.properties.keys().map(String::as_str).collect();
                return Err(fmt(format!(
                    "vertex element lacks a scalar '{axis}' property; the vertex has {}",
                    match names.is_empty() {
                        true => "no properties".to_string(),
                        false => names.join(", "),
                    }
                )));
            }
        }
    }
    let rgb = COLOR_NAMES.map(find);
    let colors = rgb.iter().all(Option::is_some);
    if !colors && rgb.iter().any(Option::is_some) {
        return Err(fmt("vertex has some but not all of red, green, blue".into()));
    }
    for (n, t) in COLOR_NAMES.iter().zip(&rgb) {
        if let Some(t) = t
            && !matches!(
                scalar(t),
                Some(
                    ScalarType::UChar | ScalarType::UShort | ScalarType::Float | ScalarType::Double
                )
            )
        {
            return Err(fmt(format!(
                "vertex property '{n}' has type {}; colours must be uchar (0-255), \
                 ushort (0-65535), or float or double (0-1)",
                ply_property_type(t)
            )));
        }
    }
    let labels: Vec<&str> = def
        .properties
        .keys()
        .map(String::as_str)
        .filter(|n| is_label_name(n))
        .collect();
    if labels.len() > 1 {
        return Err(fmt(format!(
            "vertex has several label properties {labels:?}: choose one with \
             --label-property NAME"
        )));
    }
    if let Some(n) = labels.first()
        && find(n).and_then(scalar).is_none()
    {
        return Err(fmt(format!(
            "label property '{n}' must be a scalar, not a list"
        )));
    }
    let mut feature_dim = 0;
    for (name, p) in &def.properties {
        if let Some(i) = feature_index(name) {
            if i != feature_dim {
                return Err(fmt(format!(
                    "feature property '{name}' out of order: expected index {feature_dim}"
                )));
            }
            if !matches!(
                scalar(&p.data_type),
                Some(ScalarType::Float | ScalarType::Double)
            ) {
                return Err(fmt(format!(
                    "feature property '{name}' must be float or double"
                )));
            }
            feature_dim += 1;
        }
    }
    let wide_colours = rgb.map(|t| matches!(t.and_then(scalar), Some(ScalarType::UShort)));
    Ok(Layout {
        colors,
        wide_colours,
        label: !labels.is_empty(),
        feature_dim,
    })
}

/// Why a file named `.ply` is not one, from its first bytes: what it
/// looks like instead, when that is recognisable.
fn not_ply(head: &[u8]) -> String {
    if head.is_empty() {
        return "not a PLY file: it is empty".into();
    }
    let like = if head.starts_with(b"LASF") {
        Some("a LAS/LAZ file: use the .las or .laz extension, or --format las")
    } else if head.starts_with(b"# .PCD") || head.starts_with(b"VERSION") {
        Some("a PCL .pcd file: convert it to PLY first (pcl_pcd2ply, CloudCompare)")
    } else if head.starts_with(b"\x93NUMPY") {
        Some("a NumPy .npy array")
    } else if head.starts_with(b"\x89PNG") {
        Some("a PNG image")
    } else if head.starts_with(&[0x1f, 0x8b]) {
        Some("a gzip-compressed file: decompress it first")
    } else if head.starts_with(b"PK\x03\x04") {
        Some("a zip archive: extract it first")
    } else {
        None
    };
    let why = "not a PLY file: it does not start with the \"ply\" header line";
    match like {
        Some(like) => format!("{why} (it starts like {like})"),
        None => why.to_string(),
    }
}

/// The first property an element of the header in `head` declares twice,
/// said with the two lines (the header parser keeps one of them, so the
/// records then seemed to hold a value more than the header's properties).
/// Looks at the header as far as `head` holds it.
fn duplicate_property(head: &[u8]) -> Option<String> {
    let mut element = String::new();
    let mut seen: Vec<(String, usize)> = Vec::new();
    for (i, line) in head.split(|b| *b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.first().copied() {
            Some("end_header") => return None,
            Some("element") => {
                element = words.get(1).unwrap_or(&"").to_string();
                seen.clear();
            }
            Some("property") if words.len() >= 3 => {
                let name = words[words.len() - 1];
                if let Some((_, first)) = seen.iter().find(|(n, _)| n == name) {
                    return Some(format!(
                        "element '{element}' declares the property '{name}' twice (header \
                         lines {} and {}): rename one",
                        first + 1,
                        i + 1
                    ));
                }
                seen.push((name.to_string(), i));
            }
            _ => {}
        }
    }
    None
}

/// The names omcl reads as coordinates and colours, taken in any letter
/// case and, for colours, with the `diffuse_` prefix of some scanners'
/// files (PDAL's PLY writer writes `X`, `Y`, `Z`, `Red`, ...): each such
/// property is renamed to its lowercase name, unless the vertex has that
/// name itself or the match is ambiguous.
fn fold_standard_names(def: &mut ElementDef) {
    let canon = |k: &str| -> Option<&'static str> {
        let base = match k.get(..8) {
            Some(p) if p.eq_ignore_ascii_case("diffuse_") => &k[8..],
            _ => k,
        };
        ["x", "y", "z"]
            .into_iter()
            .chain(COLOR_NAMES)
            .find(|n| n.eq_ignore_ascii_case(base))
            .filter(|n| *n != k)
    };
    let renames: Vec<(String, &str)> = def
        .properties
        .keys()
        .filter_map(|k| canon(k).map(|c| (k.clone(), c)))
        .filter(|(_, c)| !def.properties.contains_key(*c))
        .collect();
    // The property a name is taken from: the only candidate, or of
    // several (`Red` and `diffuse_red`) the only one without the prefix.
    let chosen = |c: &str| -> Option<&String> {
        let all: Vec<&String> = renames
            .iter()
            .filter(|(_, d)| *d == c)
            .map(|(k, _)| k)
            .collect();
        match all.as_slice() {
            [one] => Some(*one),
            _ => {
                let plain: Vec<&String> = all
                    .into_iter()
                    .filter(|k| k.eq_ignore_ascii_case(c))
                    .collect();
                (plain.len() == 1).then(|| plain[0])
            }
        }
    };
    let props = std::mem::take(&mut def.properties);
    def.properties = props
        .into_iter()
        .map(|(k, mut p)| {
            let name = match renames
                .iter()
                .find(|(r, c)| *r == k && chosen(c) == Some(&k))
            {
                Some((_, c)) => c.to_string(),
                None => k,
            };
            p.name = name.clone();
            (name, p)
        })
        .collect();
}

/// What the vertex readers left out or changed, for the cloud's notes.
#[derive(Default)]
struct Tally {
    /// Vertices left out for a non-finite coordinate.
    non_finite: usize,
    /// Float colour values outside 0-1, clamped.
    clamped: usize,
}

/// Reads the vertices of a PLY file (any encoding) into a [`PointCloud`] in
/// the file's frame, then validates it (non-negative whole labels, every
/// coordinate within a map's reach). Vertices with a non-finite coordinate
/// are left out, and [`PointCloud::notes`] says how many; so does it when
/// float colours had to be clamped to 0-1.
pub fn read_ply(path: &Path) -> Result<PointCloud, CloudError> {
    read_ply_with(path, &PlyOptions::default())
}

/// How [`read_ply_with`] reads a file.
#[derive(Debug, Clone, Default)]
pub struct PlyOptions {
    /// The vertex property that holds the labels (any name, e.g. DALES's
    /// `sem_class`), instead of the one of the recognised names; the other
    /// label-like properties are then ignored.
    pub label_property: Option<String>,
}

/// Makes `choice` the vertex element's label property: renamed `label`,
/// every other property with a label-like name renamed out of the way.
fn choose_label(path: &Path, def: &mut ElementDef, choice: &str) -> Result<(), CloudError> {
    let names: Vec<&str> = def.properties.keys().map(String::as_str).collect();
    let found = names
        .iter()
        .find(|n| **n == choice)
        .or_else(|| {
            let mut ci = names.iter().filter(|n| n.eq_ignore_ascii_case(choice));
            ci.next().filter(|_| ci.next().is_none())
        })
        .map(|n| n.to_string());
    let Some(found) = found else {
        return Err(CloudError::format(
            path,
            format!(
                "no vertex property '{choice}' (--label-property); the vertex has {}",
                names.join(", ")
            ),
        ));
    };
    let reserved = ["x", "y", "z"]
        .iter()
        .chain(COLOR_NAMES.iter())
        .any(|n| *n == found)
        || feature_index(&found).is_some();
    if reserved {
        return Err(CloudError::format(
            path,
            format!("vertex property '{found}' is a coordinate, colour or feature, not labels"),
        ));
    }
    if def
        .properties
        .get(&found)
        .is_some_and(|p| scalar(&p.data_type).is_none())
    {
        return Err(CloudError::format(
            path,
            format!("label property '{found}' (--label-property) must be a scalar, not a list"),
        ));
    }
    let props = std::mem::take(&mut def.properties);
    def.properties = props
        .into_iter()
        .map(|(k, mut p)| {
            let name = if k == found {
                "label".to_string()
            } else if is_label_name(&k) {
                // Not a PLY name (no spaces in those): matches nothing.
                format!("{k} (not the labels)")
            } else {
                k
            };
            p.name = name.clone();
            (name, p)
        })
        .collect();
    Ok(())
}

/// [`read_ply`] with `opts`.
pub fn read_ply_with(path: &Path, opts: &PlyOptions) -> Result<PointCloud, CloudError> {
    let file = File::open(path).map_err(|e| CloudError::io(path, e))?;
    let file_len = file.metadata().map_err(|e| CloudError::io(path, e))?.len();
    let mut buffered = BufReader::with_capacity(1 << 20, file);
    let head = buffered.fill_buf().map_err(|e| CloudError::io(path, e))?;
    if !head.starts_with(b"ply") {
        return Err(CloudError::format(path, not_ply(head)));
    }
    if let Some(why) = duplicate_property(head) {
        return Err(CloudError::format(path, why));
    }
    let mut reader = Reader::new(buffered);
    let parser = Parser::<Vertex>::new();
    let mut header = parser
        .read_header(&mut reader)
        .map_err(|e| CloudError::format(path, format!("bad PLY header: {}", header_error(&e))))?;
    let Some(vertex_pos) = header.elements.get_index_of("vertex") else {
        return Err(CloudError::format(path, "no 'vertex' element in header"));
    };
    if let Some(def) = header.elements.get_mut("vertex") {
        fold_standard_names(def);
    }
    if let (Some(choice), Some(def)) = (&opts.label_property, header.elements.get_mut("vertex")) {
        choose_label(path, def, choice)?;
    }
    let skip = Parser::<Skip>::new();
    let mut cloud = PointCloud::default();
    let mut tally = Tally::default();
    let mut declared = 0;
    let mut float_axes = [false; 3];
    let mut note_after = None;
    for (pos, (_, def)) in header.elements.iter().enumerate() {
        if pos < vertex_pos {
            // Elements before the vertices must be consumed to reach them.
            // A binary element without properties takes no bytes, however
            // many it declares (a count of 2^64 - 1 spun for ever here).
            if def.properties.is_empty() && header.encoding != Encoding::Ascii {
                continue;
            }
            for i in 0..def.count {
                read_one(&skip, &mut reader, def, header.encoding).map_err(|e| {
                    // The parser's words span lines and tabs; its end of
                    // file is a truncation.
                    let words = e
                        .to_string()
                        .split_whitespace()
                        .collect::<Vec<_>>()
                        .join(" ");
                    let why = if words.contains("fill whole buffer") || words.contains("EOF") {
                        format!(
                            "truncated: the file ends inside it ({} declared, before the \
                             vertices)",
                            def.count
                        )
                    } else {
                        words
                    };
                    CloudError::format(path, format!("element '{}' {i}: {why}", def.name))
                })?;
            }
            continue;
        }
        declared = def.count;
        let layout = check_vertex_layout(path, def)?;
        // A list property is read by nothing: a feature vector stored as
        // one (a list named feat..., emb...) had been ignored without a
        // word (said when no features are read otherwise).
        let lists: Vec<&str> = def
            .properties
            .iter()
            .filter(|(n, p)| {
                let n = n.to_ascii_lowercase();
                scalar(&p.data_type).is_none() && (n.contains("feat") || n.contains("emb"))
            })
            .map(|(n, _)| n.as_str())
            .collect();
        let list_note = (!lists.is_empty() && layout.feature_dim == 0).then(|| {
            format!(
                "{}: the vertex list properties {lists:?} are not read (features are read from \
                 scalar properties f0, f1, ... or feat_0, ... or feature_0, ...)",
                path.display()
            )
        });
        float_axes = ["x", "y", "z"].map(|a| {
            def.properties
                .get(a)
                .is_some_and(|p| matches!(p.data_type, PropertyType::Scalar(ScalarType::Float)))
        });
        let big_endian = match header.encoding {
            Encoding::Ascii => None,
            Encoding::BinaryLittleEndian => Some(false),
            Encoding::BinaryBigEndian => Some(true),
        };
        let cols = match (big_endian, FixedRecord::new(def)) {
            // Scalar-only binary vertices have a fixed record size: decode
            // them in bulk instead of one property call at a time.
            (Some(big), Some(rec)) => {
                let need = (def.count as u64).saturating_mul(rec.len as u64);
                if need > file_len {
                    return Err(CloudError::format(
                        path,
                        format!(
                            "truncated or corrupt: the header declares {} vertices of {} bytes \
                             ({need} bytes), but the file has {file_len} bytes",
                            def.count, rec.len
                        ),
                    ));
                }
                // `n` records fit in the file (checked just above).
                let cols = Columns::new(&layout, def.count);
                read_fixed_vertices(path, reader.get_mut(), def, cols, &rec, big)?
            }
            _ => {
                // A vertex takes at least a byte a property (ASCII: a digit and
                // a separator): the file's size bounds what the count may
                // reserve; the records themselves still have to arrive.
                let cap = usize::try_from(file_len / def.properties.len().max(1) as u64)
                    .unwrap_or(usize::MAX)
                    .min(def.count);
                let cols = Columns::new(&layout, cap);
                read_vertices(path, &parser, &mut reader, def, header.encoding, cols)?
            }
        };
        (cloud, tally) = cols.finish();
        cloud.notes.extend(list_note);
        // Elements after the vertices (a mesh's faces) are not read; a
        // file too short to hold them even at their smallest is truncated
        // (it had been taken without a word).
        if pos + 1 < header.elements.len()
            && let Ok(at) = reader.get_mut().stream_position()
        {
            let need = header
                .elements
                .values()
                .skip(pos + 1)
                .map(|d| (d.count as u64).saturating_mul(min_record(d, header.encoding)))
                .fold(0u64, u64::saturating_add);
            if file_len.saturating_sub(at) < need {
                let names: Vec<String> = header
                    .elements
                    .values()
                    .skip(pos + 1)
                    .map(|d| format!("{} {}", d.count, d.name))
                    .collect();
                note_after = Some(format!(
                    "{}: the file ends before the elements its header declares after the \
                     vertices ({}): truncated, or a wrong count; the vertices were read whole",
                    path.display(),
                    names.join(", ")
                ));
            }
        }
        if pos + 1 == header.elements.len() {
            // Nothing may follow the last element: more data means the
            // header's count or properties do not describe the file, and
            // reading on would take one column for another.
            refuse_trailing_data(path, reader.get_mut(), def, header.encoding)?;
        }
        break;
    }
    cloud.notes.extend(note_after);
    let name = path.display().to_string();
    if tally.non_finite > 0 {
        if cloud.is_empty() {
            return Err(CloudError::Empty {
                source_name: name,
                reason: format!(
                    "all {declared} vertices have a non-finite coordinate (NaN or infinity)"
                ),
            });
        }
        cloud.notes.push(format!(
            "{name}: {} of {declared} vertices have a non-finite coordinate (NaN or \
             infinity, as PCL and Open3D write invalid points) and were left out",
            tally.non_finite
        ));
    }
    if let Some(note) = float_precision_note(&name, &cloud.points, float_axes) {
        cloud.notes.push(note);
    }
    if header.encoding != Encoding::Ascii
        && let Some(note) = byte_order_note(&name, &cloud.points, float_axes)
    {
        cloud.notes.push(note);
    }
    let unlabelled = cloud
        .labels
        .as_ref()
        .map_or(0, |l| l.iter().filter(|&&c| c == UNLABELLED).count());
    if unlabelled > 0 {
        cloud.notes.push(format!(
            "{name}: {} the label -1 (or 4294967295, a 32-bit -1: \
             unlabelled); they belong to no class and are skipped",
            if unlabelled == 1 {
                "1 vertex has".to_string()
            } else {
                format!("{unlabelled} vertices have")
            }
        ));
    }
    if tally.clamped > 0 {
        cloud.notes.push(format!(
            "{name}: {} float colour values lie outside 0-1 and were clamped to it \
             (colours stored as 0-255 in float properties come out white)",
            tally.clamped
        ));
    }
    cloud.validate(&name)?;
    cloud.non_empty(&name, "the file holds no vertices")
}

/// The PLY parser's header error on one line: its first line and the
/// text it could not parse, without the parser's internal state (a
/// `ParseError { location: .., expected: .. }` dump) that follows.
fn header_error(e: &dyn std::fmt::Display) -> String {
    let text = e.to_string();
    let mut lines = text.lines();
    let first = lines.next().unwrap_or("").trim();
    match lines.find_map(|l| l.trim().strip_prefix("String:")) {
        // The parser quotes the line with its newline: `'element x\n'`.
        Some(line) => format!("{first} (the line: '{}')", line.trim().trim_matches('\'')),
        None => first.to_string(),
    }
}

/// A note when most nonzero `float` coordinates of a binary file are
/// absurdly small or large (below 1e-30 or above 1e30 in magnitude), as
/// floats read in the other byte order come out: a file declared
/// `binary_big_endian` and written little-endian was mapped as one voxel.
fn byte_order_note(name: &str, points: &[[f64; 3]], float_axes: [bool; 3]) -> Option<String> {
    let (mut nonzero, mut absurd) = (0usize, 0usize);
    for p in points {
        for a in (0..3).filter(|&a| float_axes[a]) {
            let v = p[a].abs();
            if v != 0.0 {
                nonzero += 1;
                absurd += usize::from(!(1e-30..=1e30).contains(&v));
            }
        }
    }
    (nonzero > 0 && 2 * absurd > nonzero).then(|| {
        format!(
            "{name}: {absurd} of {nonzero} nonzero coordinates are below 1e-30 or above 1e30 \
             in magnitude, as floats read in the wrong byte order are: is the header's format \
             (binary_little_endian or binary_big_endian) the file's?"
        )
    })
}

/// A note when coordinates stored as `float` lie so far from 0 (UTM
/// metres) that neighbouring `float` values are more than a centimetre
/// apart: the file itself has quantized the positions.
fn float_precision_note(name: &str, points: &[[f64; 3]], float_axes: [bool; 3]) -> Option<String> {
    let far = points
        .iter()
        .flat_map(|p| (0..3).filter(|&a| float_axes[a]).map(move |a| p[a].abs()))
        .fold(0.0f64, f64::max);
    // The spacing of f32 values near `far`.
    let step = (far as f32).next_up() as f64 - (far as f32) as f64;
    (step > 0.01).then(|| {
        format!(
            "{name}: coordinates stored as float (32-bit) reach {far:.0} m, where such values \
             are {step:.3} m apart: positions are rounded to that in the file (write double \
             coordinates, or coordinates relative to a local origin)"
        )
    })
}

/// An element whose every property is ignored.
struct Skip;
impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

/// Refuses bytes after the last element's records: whitespace, NUL
/// padding and a DOS end-of-file byte (0x1a) aside, which some writers
/// leave.
fn refuse_trailing_data(
    path: &Path,
    r: &mut impl BufRead,
    def: &ElementDef,
    encoding: Encoding,
) -> Result<(), CloudError> {
    let mut rest = Vec::new();
    // 64 KiB tell enough; a bigger tail is refused all the same.
    r.take(1 << 16)
        .read_to_end(&mut rest)
        .map_err(|e| CloudError::io(path, e))?;
    if rest
        .iter()
        .all(|b| b.is_ascii_whitespace() || *b == 0 || *b == 0x1a)
    {
        return Ok(());
    }
    let what = match encoding {
        Encoding::Ascii => {
            let first = String::from_utf8_lossy(&rest);
            let first = first.trim_start().lines().next().unwrap_or_default();
            let shown: String = first.chars().take(60).collect();
            format!("more lines follow (the first: '{shown}')")
        }
        _ => "more bytes follow".to_string(),
    };
    Err(CloudError::format(
        path,
        format!(
            "the header declares {} {} records, but {what}: the header's count \
             or properties do not describe the file",
            def.count, def.name
        ),
    ))
}

/// The next value of an ASCII record, counted in `used`.
fn next_value<'a>(
    tokens: &mut std::str::SplitAsciiWhitespace<'a>,
    used: &mut usize,
    property: &str,
) -> Result<&'a str, String> {
    let t = tokens.next().ok_or_else(|| {
        format!("the line ends before property '{property}' (after {used} values)")
    })?;
    *used += 1;
    Ok(t)
}

/// Parses `token` as a number of PLY type `t`.
fn ascii_number<T: std::str::FromStr>(
    property: &str,
    t: &ScalarType,
    token: &str,
) -> Result<T, String> {
    token.parse().map_err(|_| {
        let want = match t {
            ScalarType::Float | ScalarType::Double => "a number".to_string(),
            _ => format!("a whole number in the range of {}", ply_type_name(t)),
        };
        let shown: String = token.chars().take(40).collect();
        format!("property '{property}': '{shown}' is not {want}")
    })
}

/// Parses one ASCII record of `def`: every property in header order (a
/// list: its count, then that many values), and nothing more. Floats take
/// `nan` and `inf` (PCL and Open3D write them for invalid points); integers
/// must be whole numbers of their type.
fn parse_ascii_element<E: PropertyAccess>(line: &str, def: &ElementDef) -> Result<E, String> {
    let mut tokens = line.split_ascii_whitespace();
    let mut used = 0usize;
    let mut e = E::new();
    for (name, p) in &def.properties {
        let token = next_value(&mut tokens, &mut used, name)?;
        match &p.data_type {
            PropertyType::Scalar(t) => {
                let n = name.as_str();
                // What the element does with a value (set or ignore) is its
                // own business, as with ply-rs-bw's binary reader.
                let _ = match t {
                    ScalarType::Char => e.set_char(n, ascii_number(n, t, token)?),
                    ScalarType::UChar => e.set_uchar(n, ascii_number(n, t, token)?),
                    ScalarType::Short => e.set_short(n, ascii_number(n, t, token)?),
                    ScalarType::UShort => e.set_ushort(n, ascii_number(n, t, token)?),
                    ScalarType::Int => e.set_int(n, ascii_number(n, t, token)?),
                    ScalarType::UInt => e.set_uint(n, ascii_number(n, t, token)?),
                    ScalarType::Float => e.set_float(n, ascii_number(n, t, token)?),
                    ScalarType::Double => e.set_double(n, ascii_number(n, t, token)?),
                };
            }
            // Lists are read past: no element of ours keeps one.
            PropertyType::List(count, item) => {
                let len: usize = ascii_number(name, count, token)?;
                for _ in 0..len {
                    let v = next_value(&mut tokens, &mut used, name)?;
                    ascii_number::<f64>(name, item, v)?;
                }
            }
        }
    }
    let extra = tokens.count();
    if extra > 0 {
        return Err(format!(
            "{} values on the line, but the header's properties take {used}",
            used + extra
        ));
    }
    Ok(e)
}

fn read_one<E: PropertyAccess, R: BufRead>(
    parser: &Parser<E>,
    reader: &mut Reader<R>,
    def: &ElementDef,
    encoding: Encoding,
) -> Result<E, String> {
    let r = reader.get_mut();
    match encoding {
        Encoding::BinaryLittleEndian => parser
            .read_little_endian_element(r, def)
            .map_err(|e| e.to_string()),
        Encoding::BinaryBigEndian => parser
            .read_big_endian_element(r, def)
            .map_err(|e| e.to_string()),
        Encoding::Ascii => {
            let mut line = String::new();
            // Blank lines between records carry nothing; skip them.
            loop {
                line.clear();
                let n = r.read_line(&mut line).map_err(|e| e.to_string())?;
                if n == 0 {
                    return Err("unexpected end of file".into());
                }
                if !line.trim().is_empty() {
                    break;
                }
            }
            parse_ascii_element(&line, def)
        }
    }
}

/// The vertex columns being filled, and what was left out on the way.
struct Columns {
    points: Vec<[f64; 3]>,
    labels: Option<Vec<u32>>,
    /// As [`Vertex::rgb`].
    colors: Option<Vec<[u16; 3]>>,
    /// The `ushort` channels.
    wide_colours: [bool; 3],
    dim: usize,
    feats: Option<Vec<f32>>,
    tally: Tally,
    /// File indices of the vertices left out ([`PointCloud::left_out`]).
    left_out: Vec<usize>,
}

impl Columns {
    /// Empty columns for `layout`, room for `cap` vertices (at most 2^24 up
    /// front: the rest grows as vertices arrive).
    fn new(layout: &Layout, cap: usize) -> Self {
        let cap = cap.min(1 << 24);
        let dim = layout.feature_dim;
        Columns {
            points: Vec::with_capacity(cap),
            labels: layout.label.then(|| Vec::with_capacity(cap)),
            colors: layout.colors.then(|| Vec::with_capacity(cap)),
            wide_colours: layout.wide_colours,
            dim,
            feats: (dim > 0).then(|| Vec::with_capacity(cap.saturating_mul(dim))),
            tally: Tally::default(),
            left_out: Vec::new(),
        }
    }

    /// Counts a vertex with a non-finite coordinate, which is left out
    /// (its index in the file noted); true when `xyz` is to be kept.
    /// Called once a vertex, in file order, before a kept one is pushed.
    fn keep(&mut self, xyz: &[f64; 3]) -> bool {
        let finite = xyz.iter().all(|c| c.is_finite());
        if !finite {
            self.left_out.push(self.points.len() + self.left_out.len());
            self.tally.non_finite += 1;
        }
        finite
    }

    fn finish(self) -> (PointCloud, Tally) {
        let wide = self.wide_colours;
        let colors = self.colors.map(|c| {
            // 0-255 stored in 16 bits (no `ushort` value above 255) is taken
            // as it is, as the LAS reader does; else the high byte.
            let eight_bit = c.iter().all(|v| (0..3).all(|k| !wide[k] || v[k] <= 255));
            let shift = |k: usize| if wide[k] && !eight_bit { 8 } else { 0 };
            let shifts = [shift(0), shift(1), shift(2)];
            c.into_iter()
                .map(|v| [0, 1, 2].map(|k| (v[k] >> shifts[k]) as u8))
                .collect()
        });
        let cloud = PointCloud {
            points: self.points,
            labels: self.labels,
            colors,
            features: self.feats.map(|f| (self.dim, f)),
            notes: Vec::new(),
            left_out: self.left_out,
            georef: None,
        };
        (cloud, self.tally)
    }
}

fn read_vertices<R: BufRead>(
    path: &Path,
    parser: &Parser<Vertex>,
    reader: &mut Reader<R>,
    def: &ElementDef,
    encoding: Encoding,
    mut cols: Columns,
) -> Result<Columns, CloudError> {
    for i in 0..def.count {
        let v = read_one(parser, reader, def, encoding).map_err(|e| {
            if e.contains("failed to fill whole buffer") || e.contains("end of file") {
                CloudError::format(
                    path,
                    format!(
                        "truncated: file ends in vertex {i} (header declares {})",
                        def.count
                    ),
                )
            } else {
                CloudError::format(path, format!("vertex {i}: {}", first_line(&e)))
            }
        })?;
        if !cols.keep(&v.xyz) {
            continue;
        }
        cols.points.push(v.xyz);
        if let Some(l) = &mut cols.labels {
            l.push(label_of(path, i, v.label)?);
        }
        if let Some(c) = &mut cols.colors {
            c.push(v.rgb);
            cols.tally.clamped += v.clamped as usize;
        }
        if let Some(f) = &mut cols.feats {
            f.extend_from_slice(&v.feat);
        }
    }
    Ok(cols)
}

/// Byte offsets of the used properties in a fixed-size binary record.
struct FixedRecord {
    len: usize,
    xyz: [(usize, ScalarType); 3],
    rgb: [(usize, ScalarType); 3],
    label: Option<(usize, ScalarType)>,
    features: Vec<(usize, ScalarType)>,
}

/// The fewest bytes an element of `def` takes: binary, its scalars' sizes
/// and its lists' count fields (an empty list); ASCII, a character and a
/// separator a property.
fn min_record(def: &ElementDef, encoding: Encoding) -> u64 {
    match encoding {
        Encoding::Ascii => 2 * def.properties.len() as u64,
        _ => def
            .properties
            .values()
            .map(|p| match &p.data_type {
                PropertyType::Scalar(t) => scalar_size(t) as u64,
                PropertyType::List(count, _) => scalar_size(count) as u64,
            })
            .sum(),
    }
}

fn scalar_size(t: &ScalarType) -> usize {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

impl FixedRecord {
    /// `None` when the element has a list property (variable record size).
    fn new(def: &ElementDef) -> Option<Self> {
        let mut rec = FixedRecord {
            len: 0,
            xyz: [
                (0, ScalarType::Float),
                (0, ScalarType::Float),
                (0, ScalarType::Float),
            ],
            rgb: [
                (0, ScalarType::UChar),
                (0, ScalarType::UChar),
                (0, ScalarType::UChar),
            ],
            label: None,
            features: Vec::new(),
        };
        for (name, p) in &def.properties {
            let t = scalar(&p.data_type)?.clone();
            let at = rec.len;
            rec.len += scalar_size(&t);
            match name.as_str() {
                "x" => rec.xyz[0] = (at, t),
                "y" => rec.xyz[1] = (at, t),
                "z" => rec.xyz[2] = (at, t),
                "red" => rec.rgb[0] = (at, t),
                "green" => rec.rgb[1] = (at, t),
                "blue" => rec.rgb[2] = (at, t),
                n if is_label_name(n) => rec.label = Some((at, t)),
                n if feature_index(n).is_some() => rec.features.push((at, t)),
                _ => {}
            }
        }
        Some(rec)
    }
}

fn bytes_at<const N: usize>(r: &[u8], at: usize) -> [u8; N] {
    let mut b = [0u8; N];
    b.copy_from_slice(&r[at..at + N]);
    b
}

/// A scalar of type `t` at `at` in record `r`, as `f64` (exact for every
/// PLY type).
fn decode(r: &[u8], at: usize, t: &ScalarType, big: bool) -> f64 {
    macro_rules! num {
        ($ty:ty, $n:literal) => {{
            let b = bytes_at::<$n>(r, at);
            (if big {
                <$ty>::from_be_bytes(b)
            } else {
                <$ty>::from_le_bytes(b)
            }) as f64
        }};
    }
    match t {
        ScalarType::Char => r[at] as i8 as f64,
        ScalarType::UChar => r[at] as f64,
        ScalarType::Short => num!(i16, 2),
        ScalarType::UShort => num!(u16, 2),
        ScalarType::Int => num!(i32, 4),
        ScalarType::UInt => num!(u32, 4),
        ScalarType::Float => num!(f32, 4),
        ScalarType::Double => num!(f64, 8),
    }
}

/// A colour channel of type `t` (uchar, ushort or float/double, as the
/// layout check admits) at `at` in record `r`, as [`Vertex::rgb`] keeps it:
/// 8 bits, or a `ushort`'s 16; counts clamped floats.
fn channel(r: &[u8], at: usize, t: &ScalarType, big: bool, clamped: &mut usize) -> u16 {
    match t {
        ScalarType::UChar => r[at] as u16,
        ScalarType::UShort => decode(r, at, t, big) as u16,
        _ => {
            let v = decode(r, at, t, big);
            *clamped += usize::from(outside_unit(v));
            unit_to_u8(v) as u16
        }
    }
}

/// Reads until `buf` is full or the input ends; returns the bytes read.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

fn read_fixed_vertices(
    path: &Path,
    r: &mut impl Read,
    def: &ElementDef,
    mut cols: Columns,
    rec: &FixedRecord,
    big: bool,
) -> Result<Columns, CloudError> {
    let n = def.count;
    let chunk = (1usize << 20) / rec.len.max(1) + 1;
    let mut buf = vec![0u8; chunk * rec.len];
    let mut done = 0;
    while done < n {
        let k = chunk.min(n - done);
        let want = k * rec.len;
        let got = read_full(r, &mut buf[..want]).map_err(|e| CloudError::io(path, e))?;
        if got < want {
            return Err(CloudError::format(
                path,
                format!(
                    "truncated: file ends in vertex {} (header declares {n})",
                    done + got / rec.len
                ),
            ));
        }
        for (j, v) in buf[..want].chunks_exact(rec.len).enumerate() {
            let xyz = rec.xyz.each_ref().map(|(at, t)| decode(v, *at, t, big));
            if !cols.keep(&xyz) {
                continue;
            }
            cols.points.push(xyz);
            if let (Some(l), Some((at, t))) = (&mut cols.labels, &rec.label) {
                l.push(label_of(path, done + j, decode(v, *at, t, big))?);
            }
            if let Some(c) = &mut cols.colors {
                let clamped = &mut cols.tally.clamped;
                c.push(
                    rec.rgb
                        .each_ref()
                        .map(|(at, t)| channel(v, *at, t, big, clamped)),
                );
            }
            if let Some(f) = &mut cols.feats {
                f.extend(
                    rec.features
                        .iter()
                        .map(|(at, t)| decode(v, *at, t, big) as f32),
                );
            }
        }
        done += k;
    }
    Ok(cols)
}

fn first_line(s: &str) -> String {
    s.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" | ")
}

/// Writes `cloud` as a binary little-endian PLY: `double x y z`, then
/// `uchar red green blue`, `uint label` and `float f0..f{F-1}` when present.
/// Coordinates stay `double` so georeferenced maps keep their precision. The
/// file is written to a temporary file beside `path` and renamed into place.
pub fn write_ply(path: &Path, cloud: &PointCloud) -> Result<(), CloudError> {
    cloud.validate(&path.display().to_string())?;
    crate::io::atomic::write_with(path, |w| {
        let mut header = format!(
            "ply\nformat binary_little_endian 1.0\ncomment written by omcl\nelement vertex {}\n\
             property double x\nproperty double y\nproperty double z\n",
            cloud.len()
        );
        if cloud.colors.is_some() {
            header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
        }
        if cloud.labels.is_some() {
            header.push_str("property uint label\n");
        }
        let dim = cloud.feature_dim().unwrap_or(0);
        for k in 0..dim {
            header.push_str(&format!("property float f{k}\n"));
        }
        header.push_str("end_header\n");
        w.write_all(header.as_bytes())?;
        let mut rec = Vec::with_capacity(24 + 3 + 4 + 4 * dim);
        for i in 0..cloud.len() {
            rec.clear();
            for c in cloud.points[i] {
                rec.extend_from_slice(&c.to_le_bytes());
            }
            if let Some(c) = &cloud.colors {
                rec.extend_from_slice(&c[i]);
            }
            if let Some(l) = &cloud.labels {
                rec.extend_from_slice(&l[i].to_le_bytes());
            }
            if let Some((d, f)) = &cloud.features {
                for v in &f[i * d..(i + 1) * d] {
                    rec.extend_from_slice(&v.to_le_bytes());
                }
            }
            w.write_all(&rec)?;
        }
        Ok(())
    })
    .map_err(|e| CloudError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn feature_names_parse() {
        assert_eq!(feature_index("f0"), Some(0));
        assert_eq!(feature_index("feat_12"), Some(12));
        assert_eq!(feature_index("feature_3"), Some(3));
        assert_eq!(feature_index("face"), None);
        assert_eq!(feature_index("f"), None);
    }

    #[test]
    fn ascii_with_faces_before_and_after() {
        let d = tempfile::tempdir().unwrap();
        let p = write(
            d.path(),
            "a.ply",
            b"ply\nformat ascii 1.0\nelement camera 1\nproperty float k\n\
              element vertex 2\nproperty float x\nproperty float y\nproperty float z\n\
              property uchar red\nproperty uchar green\nproperty uchar blue\nproperty int label\n\
              element face 1\nproperty list uchar int vertex_indices\nend_header\n\
              7.5\n1 2 3 10 20 30 5\n-1 0.5 2 255 0 1 40\n3 0 1 1\n",
        );
        let c = read_ply(&p).unwrap();
        assert_eq!(c.points, vec![[1.0, 2.0, 3.0], [-1.0, 0.5, 2.0]]);
        assert_eq!(c.colors, Some(vec![[10, 20, 30], [255, 0, 1]]));
        assert_eq!(c.labels, Some(vec![5, 40]));
        assert!(c.features.is_none());
    }

    #[test]
    fn pdal_style_capitals_read_as_coordinates_and_colours() {
        let d = tempfile::tempdir().unwrap();
        // PDAL's PLY writer: capitals, colours before coordinates, a
        // Classification; binary, so the fixed-record path reads it.
        let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\n\
              property uchar Red\nproperty uchar Green\nproperty uchar Blue\n\
              property float X\nproperty float Y\nproperty float Z\n\
              property uchar Classification\nend_header\n"
            .to_vec();
        for (rgb, xyz, class) in [
            ([1u8, 2, 3], [1.5f32, -2.0, 3.25], 6u8),
            ([9, 8, 7], [0.0, 1.0, 2.0], 2),
        ] {
            b.extend_from_slice(&rgb);
            xyz.iter()
                .for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
            b.push(class);
        }
        let c = read_ply(&write(d.path(), "pdal.ply", &b)).unwrap();
        assert_eq!(c.points, vec![[1.5, -2.0, 3.25], [0.0, 1.0, 2.0]]);
        assert_eq!(c.colors, Some(vec![[1, 2, 3], [9, 8, 7]]));
        assert_eq!(c.labels, Some(vec![6, 2]));
        // ASCII, older scanners' diffuse_ colours.
        let p = write(
            d.path(),
            "diffuse.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty double X\nproperty double Y\n\
              property double Z\nproperty uchar diffuse_red\nproperty uchar diffuse_green\n\
              property uchar diffuse_blue\nend_header\n4 5 6 10 20 30\n",
        );
        let c = read_ply(&p).unwrap();
        assert_eq!(c.points, vec![[4.0, 5.0, 6.0]]);
        assert_eq!(c.colors, Some(vec![[10, 20, 30]]));
        // Red beside diffuse_red: Red is the colour.
        let p = write(
            d.path(),
            "amb.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
              property float z\nproperty uchar Red\nproperty uchar Green\nproperty uchar Blue\n\
              property uchar diffuse_red\nend_header\n0 0 0 1 2 3 9\n",
        );
        assert_eq!(read_ply(&p).unwrap().colors, Some(vec![[1, 2, 3]]));
        // A vertex with both x and X keeps x as the coordinate.
        let p = write(
            d.path(),
            "both.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float X\nproperty float x\n\
              property float y\nproperty float z\nend_header\n9 1 2 3\n",
        );
        assert_eq!(read_ply(&p).unwrap().points, vec![[1.0, 2.0, 3.0]]);
    }

    #[test]
    fn a_property_declared_twice_is_named_with_its_lines() {
        let d = tempfile::tempdir().unwrap();
        let p = write(
            d.path(),
            "dup.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
              property float z\nproperty float x\nend_header\n0 0 0 5\n",
        );
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(
            e.contains("element 'vertex' declares the property 'x' twice (header lines 4 and 7)"),
            "{e}"
        );
        // The same name in two elements is no duplicate.
        let p = write(
            d.path(),
            "two.ply",
            b"ply\nformat ascii 1.0\nelement camera 1\nproperty float x\n\
              element vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
              end_header\n7\n1 2 3\n",
        );
        assert_eq!(read_ply(&p).unwrap().points, vec![[1.0, 2.0, 3.0]]);
    }

    #[test]
    fn a_label_of_minus_one_is_unlabelled_other_negatives_are_errors() {
        let d = tempfile::tempdir().unwrap();
        let ply = |labels: &str| {
            let mut t = String::from(
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nproperty int label\nend_header\n",
            );
            for (i, l) in labels.split(' ').enumerate() {
                t.push_str(&format!("{i} 0 0 {l}\n"));
            }
            write(d.path(), "l.ply", t.as_bytes())
        };
        let c = read_ply(&ply("2 -1 -1")).unwrap();
        assert_eq!(c.labels, Some(vec![2, UNLABELLED, UNLABELLED]));
        assert!(
            c.notes
                .iter()
                .any(|n| n.contains("2 vertices have the label -1")),
            "{:?}",
            c.notes
        );
        let e = read_ply(&ply("2 -2 1")).unwrap_err().to_string();
        assert!(e.contains("label -2 is not a whole number"), "{e}");
    }

    #[test]
    fn a_list_property_is_said_unread_and_named_when_chosen_as_labels() {
        let d = tempfile::tempdir().unwrap();
        let p = write(
            d.path(),
            "fl.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
              property float z\nproperty list uchar float feature\nend_header\n0 0 0 2 1 0\n",
        );
        let c = read_ply(&p).unwrap();
        assert!(
            c.notes
                .iter()
                .any(|n| n.contains("list properties [\"feature\"] are not read")),
            "{:?}",
            c.notes
        );
        let opts = PlyOptions {
            label_property: Some("feature".into()),
        };
        let e = read_ply_with(&p, &opts).unwrap_err().to_string();
        assert!(
            e.contains("label property 'feature' (--label-property)"),
            "{e}"
        );
    }

    #[test]
    fn elements_the_file_cannot_hold_are_said_or_refused() {
        let d = tempfile::tempdir().unwrap();
        // Faces after the vertices, 4e9 declared, none there: a note.
        let p = write(
            d.path(),
            "after.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
              property float z\nelement face 4000000000\nproperty list uchar int \
              vertex_indices\nend_header\n1 2 3\n",
        );
        let c = read_ply(&p).unwrap();
        assert_eq!(c.points, vec![[1.0, 2.0, 3.0]]);
        assert!(
            c.notes
                .iter()
                .any(|n| n.contains("ends before the elements") && n.contains("4000000000 face")),
            "{:?}",
            c.notes
        );
        // Before the vertices: refused as truncated, in one line.
        let p = write(
            d.path(),
            "before.ply",
            b"ply\nformat binary_little_endian 1.0\nelement face 4000000000\nproperty list \
              uchar int vertex_indices\nelement vertex 1\nproperty float x\nproperty float \
              y\nproperty float z\nend_header\n\x03\x00\x00",
        );
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(
            e.contains("truncated") && !e.contains('\n') && !e.contains('\t'),
            "{e}"
        );
    }

    #[test]
    fn write_then_read_round_trips() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("out.ply");
        let cloud = PointCloud {
            points: vec![[637_000.123_456, -5.0, 1e-3], [0.0, 1.0, 2.0]],
            labels: Some(vec![7, u32::MAX - 1]),
            colors: Some(vec![[1, 2, 3], [4, 5, 6]]),
            features: Some((3, vec![0.5, -1.0, 2.0, 0.0, 0.25, 9.0])),
            notes: Vec::new(),
            left_out: Vec::new(),
            georef: None,
        };
        write_ply(&p, &cloud).unwrap();
        assert_eq!(read_ply(&p).unwrap(), cloud);
        let bytes = std::fs::read(&p).unwrap();
        assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    }

    /// The same vertices with and without a list property: the first goes
    /// through ply-rs-bw element by element, the second through the
    /// fixed-record decoder; both must agree, in both byte orders.
    #[test]
    fn generic_and_fixed_record_binary_paths_agree() {
        let d = tempfile::tempdir().unwrap();
        for (enc, big) in [("binary_little_endian", false), ("binary_big_endian", true)] {
            let mut files = Vec::new();
            for with_list in [true, false] {
                let mut b = format!(
                    "ply\nformat {enc} 1.0\nelement vertex 3\nproperty double x\n\
                     property float y\nproperty float z\nproperty short label\n{}\
                     property uchar red\nproperty uchar green\nproperty uchar blue\n\
                     property double feat_0\nproperty float feat_1\nend_header\n",
                    if with_list {
                        "property list uchar int extra\n"
                    } else {
                        ""
                    }
                )
                .into_bytes();
                for i in 0..3u8 {
                    let f = i as f32;
                    let put4 = |b: &mut Vec<u8>, v: f32| {
                        b.extend(if big {
                            v.to_be_bytes()
                        } else {
                            v.to_le_bytes()
                        })
                    };
                    let x = 1e6 + i as f64 * 0.125;
                    b.extend(if big {
                        x.to_be_bytes()
                    } else {
                        x.to_le_bytes()
                    });
                    put4(&mut b, -f);
                    put4(&mut b, 2.5 * f);
                    let l = 300i16 * i as i16;
                    b.extend(if big {
                        l.to_be_bytes()
                    } else {
                        l.to_le_bytes()
                    });
                    if with_list {
                        b.push(i);
                        for k in 0..i as i32 {
                            b.extend(if big {
                                k.to_be_bytes()
                            } else {
                                k.to_le_bytes()
                            });
                        }
                    }
                    b.extend([i, 2 * i, 200 + i]);
                    let f0 = 0.1 * i as f64;
                    b.extend(if big {
                        f0.to_be_bytes()
                    } else {
                        f0.to_le_bytes()
                    });
                    put4(&mut b, 7.0 - f);
                }
                let p = write(d.path(), &format!("{enc}_{with_list}.ply"), &b);
                files.push(read_ply(&p).unwrap());
            }
            assert_eq!(files[0], files[1], "{enc}");
            let c = &files[0];
            assert_eq!(c.points[2], [1e6 + 0.25, -2.0, 5.0]);
            assert_eq!(c.labels, Some(vec![0, 300, 600]));
            assert_eq!(c.colors.as_ref().unwrap()[1], [1, 2, 201]);
            assert_eq!(c.features, Some((2, vec![0.0, 7.0, 0.1, 6.0, 0.2, 5.0])));
        }
    }

    #[test]
    fn float_labels_in_any_case_are_accepted_when_whole() {
        let d = tempfile::tempdir().unwrap();
        let head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                    property float z\nproperty float scalar_Label\nend_header\n";
        let p = write(
            d.path(),
            "cc.ply",
            format!("{head}0 0 0 3\n1 1 1 7.0\n").as_bytes(),
        );
        assert_eq!(read_ply(&p).unwrap().labels, Some(vec![3, 7]));
        let p = write(
            d.path(),
            "half.ply",
            format!("{head}0 0 0 3\n1 1 1 2.5\n").as_bytes(),
        );
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(
            e.contains("half.ply") && e.contains("vertex 1") && e.contains("2.5"),
            "{e}"
        );
        // Binary float label through the fixed-record path.
        let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n\
                      property float y\nproperty float z\nproperty float class\nend_header\n"
            .to_vec();
        for v in [1.0f32, 2.0, 3.0, -4.0] {
            b.extend(v.to_le_bytes());
        }
        let p = write(d.path(), "neg_bin.ply", &b);
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(
            e.contains("neg_bin.ply") && e.contains("vertex 0") && e.contains("-4"),
            "{e}"
        );
    }

    #[test]
    fn label_names_match_in_any_case_with_or_without_scalar_prefix() {
        for n in [
            "label",
            "Label",
            "scalar_Label",
            "scalar_Classification",
            "SCALAR_CLASS",
            "classification",
            "semantic",
            "semantic_label",
            "scalar_semantic",
        ] {
            assert!(is_label_name(n), "{n}");
        }
        for n in [
            "scalar_",
            "scalar_scalar_label",
            "labels",
            "x",
            "scalar_Intensity",
            "sémantic",
        ] {
            assert!(!is_label_name(n), "{n}");
        }
    }

    #[test]
    fn ascii_values_that_do_not_parse_are_named() {
        let d = tempfile::tempdir().unwrap();
        let head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                    property float z\nproperty uchar label\nend_header\n0 0 0 1\n";
        for (line, want) in [
            (
                "1 zwei 3 4",
                "vertex 1: property 'y': 'zwei' is not a number",
            ),
            (
                "1 2 3 2.5",
                "vertex 1: property 'label': '2.5' is not a whole number in the range of uchar",
            ),
            ("1 2 3 256", "in the range of uchar"),
            (
                "1 2",
                "vertex 1: the line ends before property 'z' (after 2 values)",
            ),
        ] {
            let p = write(d.path(), "v.ply", format!("{head}{line}\n").as_bytes());
            let e = read_ply(&p).unwrap_err().to_string();
            assert!(e.contains("v.ply") && e.contains(want), "{line}: {e}");
        }
    }

    #[test]
    fn negative_label_is_an_error() {
        let d = tempfile::tempdir().unwrap();
        let p = write(
            d.path(),
            "neg.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
              property float z\nproperty int label\nend_header\n0 0 0 -3\n",
        );
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(
            e.contains("neg.ply") && e.contains("vertex 0") && e.contains("-3"),
            "{e}"
        );
    }

    #[test]
    fn data_the_header_does_not_describe_is_refused() {
        let d = tempfile::tempdir().unwrap();
        let head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n\
                    property float y\nproperty float z\nend_header\n";
        // Trailing blank lines, NUL padding and a DOS end-of-file byte are
        // fine.
        for tail in ["\n \n", "\0\0\0\0", "\x1a"] {
            let p = write(
                d.path(),
                "ok.ply",
                format!("{head}0 0 0\n1 1 1\n{tail}").as_bytes(),
            );
            assert_eq!(read_ply(&p).unwrap().points.len(), 2, "{tail:?}");
        }
        // A column the header does not declare (say normals): refused,
        // not read as if the header were right.
        let p = write(
            d.path(),
            "col.ply",
            format!("{head}0 0 0 0.5\n1 1 1 0.5\n").as_bytes(),
        );
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(
            e.contains("col.ply") && e.contains("vertex 0") && e.contains("4 values"),
            "{e}"
        );
        // More vertex lines than the header's count.
        let p = write(
            d.path(),
            "lines.ply",
            format!("{head}0 0 0\n1 1 1\n2 2 2\n").as_bytes(),
        );
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(
            e.contains("lines.ply") && e.contains("declares 2 vertex") && e.contains("'2 2 2'"),
            "{e}"
        );
        // Faces after the vertices are still read past.
        let p = write(
            d.path(),
            "faces.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0\n3 0 0 0\n",
        );
        assert_eq!(read_ply(&p).unwrap().points.len(), 1);
        // Binary: a header that leaves out a property (records of 12 bytes
        // declared, 16 written) leaves bytes over.
        let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n\
                      property float y\nproperty float z\nend_header\n"
            .to_vec();
        for v in [1.0f32, 2.0, 3.0, 9.0, 4.0, 5.0, 6.0, 9.0] {
            b.extend(v.to_le_bytes());
        }
        let p = write(d.path(), "bin.ply", &b);
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(
            e.contains("bin.ply") && e.contains("more bytes follow"),
            "{e}"
        );
    }
}
