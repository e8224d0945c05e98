//! Class labels: the SemanticKITTI label set (ids, names, the 19-class
//! learning map, which classes are dropped) and label-to-embedding tables
//! (ground-truth feature mode).
//!
//! Embedding-table files are two files side by side: a text file of class
//! ids and names, one class a line (`<id> <name>`, `#` comments; names may
//! contain spaces), and an `N x F` `.npy` whose row `k` is the embedding of
//! the `k`-th class line. Python writes them with `np.save` and a loop.

use std::path::Path;

use rustc_hash::FxHashMap;

use crate::io::cloud::CloudError;
use crate::io::npy::read_npy;

/// SemanticKITTI raw class ids and names (`semantic-kitti.yaml`, `labels`).
pub const SEMANTIC_KITTI_CLASSES: [(u32, &str); 34] = [
    (0, "unlabeled"),
    (1, "outlier"),
    (10, "car"),
    (11, "bicycle"),
    (13, "bus"),
    (15, "motorcycle"),
    (16, "on-rails"),
    (18, "truck"),
    (20, "other-vehicle"),
    (30, "person"),
    (31, "bicyclist"),
    (32, "motorcyclist"),
    (40, "road"),
    (44, "parking"),
    (48, "sidewalk"),
    (49, "other-ground"),
    (50, "building"),
    (51, "fence"),
    (52, "other-structure"),
    (60, "lane-marking"),
    (70, "vegetation"),
    (71, "trunk"),
    (72, "terrain"),
    (80, "pole"),
    (81, "traffic-sign"),
    (99, "other-object"),
    (252, "moving-car"),
    (253, "moving-bicyclist"),
    (254, "moving-person"),
    (255, "moving-motorcyclist"),
    (256, "moving-on-rails"),
    (257, "moving-bus"),
    (258, "moving-truck"),
    (259, "moving-other-vehicle"),
];

/// SemanticKITTI `learning_map`: raw id to the 19 training classes
/// (0 = ignored). Moving classes map to their static counterparts.
pub const SEMANTIC_KITTI_LEARNING_MAP: [(u32, u32); 34] = [
    (0, 0),
    (1, 0),
    (10, 1),
    (11, 2),
    (13, 5),
    (15, 3),
    (16, 5),
    (18, 4),
    (20, 5),
    (30, 6),
    (31, 7),
    (32, 8),
    (40, 9),
    (44, 10),
    (48, 11),
    (49, 12),
    (50, 13),
    (51, 14),
    (52, 0),
    (60, 9),
    (70, 15),
    (71, 16),
    (72, 17),
    (80, 18),
    (81, 19),
    (99, 0),
    (252, 1),
    (253, 7),
    (254, 6),
    (255, 8),
    (256, 5),
    (257, 5),
    (258, 4),
    (259, 5),
];

/// Names of the 19 training classes, index = learning-map id - 1.
pub const SEMANTIC_KITTI_TRAIN_NAMES: [&str; 19] = [
    "car",
    "bicycle",
    "motorcycle",
    "truck",
    "other-vehicle",
    "person",
    "bicyclist",
    "motorcyclist",
    "road",
    "parking",
    "sidewalk",
    "other-ground",
    "building",
    "fence",
    "vegetation",
    "trunk",
    "terrain",
    "pole",
    "traffic-sign",
];

/// Semantic class of a raw `.label` value (low 16 bits).
pub fn semantic_id(raw: u32) -> u32 {
    raw & 0xFFFF
}

/// Instance id of a raw `.label` value (high 16 bits).
pub fn instance_id(raw: u32) -> u32 {
    raw >> 16
}

/// Name of a SemanticKITTI raw class id.
pub fn semantic_kitti_name(id: u32) -> Option<&'static str> {
    SEMANTIC_KITTI_CLASSES
        .iter()
        .find(|(i, _)| *i == id)
        .map(|(_, n)| *n)
}

/// Learning-map class (1..=19, 0 = ignored) of a raw class id; `None` for
/// ids outside the SemanticKITTI set.
pub fn semantic_kitti_learning_id(id: u32) -> Option<u32> {
    SEMANTIC_KITTI_LEARNING_MAP
        .iter()
        .find(|(i, _)| *i == id)
        .map(|(_, t)| *t)
}

/// True for classes a static map leaves out: unlabeled (0), outlier (1) and
/// moving objects (252-259), as the OMCL authors do.
pub fn is_dropped_semantic_kitti(semantic: u32) -> bool {
    semantic == 0 || semantic == 1 || (252..=259).contains(&semantic)
}

/// ASPRS LAS point classification codes 0-22 (LAS 1.4 R15, table 17;
/// point formats 6-10). Formats 0-5 share 0-12 (8 "model key-point", 12
/// "overlap" there; here their 1.4 names).
pub const ASPRS_CLASSES: [(u32, &str); 23] = [
    (0, "never classified"),
    (1, "unclassified"),
    (2, "ground"),
    (3, "low vegetation"),
    (4, "medium vegetation"),
    (5, "high vegetation"),
    (6, "building"),
    (7, "low point"),
    (8, "model key-point"),
    (9, "water"),
    (10, "rail"),
    (11, "road surface"),
    (12, "overlap"),
    (13, "wire guard"),
    (14, "wire conductor"),
    (15, "transmission tower"),
    (16, "wire-structure connector"),
    (17, "bridge deck"),
    (18, "high noise"),
    (19, "overhead structure"),
    (20, "ignored ground"),
    (21, "snow"),
    (22, "temporal exclusion"),
];

/// The class lists built in, usable wherever a class list file is asked
/// for (`--classes semantickitti`, `--classes asprs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BuiltinClasses {
    /// Every SemanticKITTI raw class (34, ids as in `.label` files).
    SemanticKitti,
    /// ASPRS LAS classification codes 0-22.
    Asprs,
}

impl BuiltinClasses {
    /// Every built-in list.
    pub const ALL: [BuiltinClasses; 2] = [BuiltinClasses::SemanticKitti, BuiltinClasses::Asprs];

    /// The list named `name` (`semantickitti`, `semantic-kitti`, `asprs`,
    /// `las`; case-insensitive).
    pub fn from_name(name: &str) -> Option<Self> {
        match name
            .trim()
            .to_ascii_lowercase()
            .replace(['-', '_'], "")
            .as_str()
        {
            "semantickitti" | "kitti" => Some(BuiltinClasses::SemanticKitti),
            "asprs" | "las" => Some(BuiltinClasses::Asprs),
            _ => None,
        }
    }

    /// The name users pass.
    pub fn name(self) -> &'static str {
        match self {
            BuiltinClasses::SemanticKitti => "semantickitti",
            BuiltinClasses::Asprs => "asprs",
        }
    }

    /// `(id, name)` of every class, in row order.
    pub fn classes(self) -> &'static [(u32, &'static str)] {
        match self {
            BuiltinClasses::SemanticKitti => &SEMANTIC_KITTI_CLASSES,
            BuiltinClasses::Asprs => &ASPRS_CLASSES,
        }
    }

    /// The list as `classes.txt` text (`<id> <name>` lines), the form
    /// [`EmbeddingTable::read`] reads.
    pub fn to_text(self) -> String {
        self.classes()
            .iter()
            .map(|(id, n)| format!("{id} {n}\n"))
            .collect()
    }
}

/// Class names mapped to embedding vectors (ground-truth feature mode).
#[derive(Debug, Clone, PartialEq)]
pub struct EmbeddingTable {
    /// Class ids, in row order.
    pub ids: Vec<u32>,
    /// Class names, in row order.
    pub names: Vec<String>,
    /// Embedding dimension.
    pub dim: usize,
    /// `ids.len() x dim` values, row-major.
    pub data: Vec<f32>,
    row_of: FxHashMap<u32, usize>,
}

impl EmbeddingTable {
    /// Builds a table; ids must be unique and `data.len() == ids.len() * dim`.
    pub fn new(
        ids: Vec<u32>,
        names: Vec<String>,
        dim: usize,
        data: Vec<f32>,
    ) -> Result<Self, String> {
        if ids.len() != names.len() || data.len() != ids.len() * dim || dim == 0 {
            return Err(format!(
                "{} ids, {} names, {} values for dimension {dim}",
                ids.len(),
                names.len(),
                data.len()
            ));
        }
        let mut row_of = FxHashMap::default();
        for (row, &id) in ids.iter().enumerate() {
            if row_of.insert(id, row).is_some() {
                return Err(format!("class id {id} appears twice"));
            }
        }
        Ok(EmbeddingTable {
            ids,
            names,
            dim,
            data,
            row_of,
        })
    }

    /// Reads a class list and its `N x F` `.npy`. The list has either
    /// `<id> <name>` lines, or one name a line with the id its line index
    /// (counting only non-empty, non-comment lines); the first line decides,
    /// and mixing the two is an error.
    pub fn read(classes_path: &Path, npy_path: &Path) -> Result<Self, CloudError> {
        let (ids, names) = read_class_list(classes_path)?;
        Self::with_npy(ids, names, classes_path, npy_path)
    }

    /// The table of a class list (`ids`, `names`, read from `classes_path`
    /// or built in) whose rows are in `npy_path` (`N x F`, one row a class).
    pub fn with_npy(
        ids: Vec<u32>,
        names: Vec<String>,
        classes_path: &Path,
        npy_path: &Path,
    ) -> Result<Self, CloudError> {
        let arr = read_npy(npy_path)?;
        if arr.shape.len() != 2 || arr.shape[0] != ids.len() {
            return Err(CloudError::mismatch(
                npy_path,
                format!(
                    "embedding table must be {} x F (one row per class in {}), got shape {:?}",
                    ids.len(),
                    classes_path.display(),
                    arr.shape
                ),
            ));
        }
        if arr.data.iter().any(|v| !v.is_finite()) {
            return Err(CloudError::format(npy_path, "non-finite embedding value"));
        }
        if let Some(row) = arr
            .data
            .chunks(arr.shape[1].max(1))
            .position(|r| !has_direction(r))
        {
            let r = &arr.data[row * arr.shape[1]..(row + 1) * arr.shape[1]];
            let largest = r.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            return Err(CloudError::format(
                npy_path,
                format!(
                    "row {row} (class '{}') {}: a feature needs a direction",
                    names[row],
                    if largest == 0.0 {
                        "is all zeros".to_string()
                    } else {
                        format!(
                            "has a length f32 cannot hold (largest value {largest:e}); scale \
                             the table"
                        )
                    }
                ),
            ));
        }
        EmbeddingTable::new(ids, names, arr.shape[1], arr.data)
            .map_err(|r| CloudError::format(classes_path, r))
    }

    /// Row index of class `id` (for feature databases built from this
    /// table in the same row order).
    pub fn row_index(&self, id: u32) -> Option<usize> {
        self.row_of.get(&id).copied()
    }

    /// The embedding of the class named `name` (case-insensitive).
    pub fn word(&self, name: &str) -> Option<&[f32]> {
        let r = self
            .names
            .iter()
            .position(|n| n.eq_ignore_ascii_case(name))?;
        Some(&self.data[r * self.dim..(r + 1) * self.dim])
    }

    /// The embedding of class `id`.
    pub fn row(&self, id: u32) -> Option<&[f32]> {
        self.row_of
            .get(&id)
            .map(|&r| &self.data[r * self.dim..(r + 1) * self.dim])
    }

    /// Per-point features for `labels` (`labels.len() x dim`, row-major).
    /// A label missing from the table is an error naming `source`, the point
    /// and the label.
    pub fn features_for(&self, labels: &[u32], source: &str) -> Result<Vec<f32>, CloudError> {
        let mut out = Vec::with_capacity(labels.len() * self.dim);
        for (i, &l) in labels.iter().enumerate() {
            let row = self.row(l).ok_or_else(|| CloudError::Invalid {
                source_name: source.to_string(),
                reason: format!("point {i} has label {l}, which the embedding table lacks"),
            })?;
            out.extend_from_slice(row);
        }
        Ok(out)
    }
}

/// Whether a feature row has a direction in f32: its squared length is
/// finite and above 0 (all zeros has none; values near 1e38 overflow, near
/// 1e-30 underflow), the condition [`crate::map::features::normalize`] needs.
pub fn has_direction(row: &[f32]) -> bool {
    let n2: f32 = row.iter().map(|x| x * x).sum();
    n2.is_finite() && n2 > 0.0
}

/// Reads a class list: `<id> <name>` lines, or one name a line with the
/// id its line index (counting only non-empty, non-comment lines); the
/// first line decides, and mixing the two is an error.
pub fn read_class_list(classes_path: &Path) -> Result<(Vec<u32>, Vec<String>), CloudError> {
    let text = crate::io::bounded_read::read_text(classes_path)
        .map_err(|e| CloudError::io(classes_path, e))?;
    let mut ids = Vec::new();
    let mut names = Vec::new();
    let mut with_ids: Option<bool> = None;
    for (lineno, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if let Some((id, _)) = line.split_once(char::is_whitespace)
            && id.bytes().all(|b| b.is_ascii_digit())
            && id.parse::<u32>().is_err()
        {
            return Err(CloudError::format(
                classes_path,
                format!(
                    "line {}: class id {id} is out of range (0 to {})",
                    lineno + 1,
                    u32::MAX
                ),
            ));
        }
        let split = line
            .split_once(char::is_whitespace)
            .and_then(|(id, name)| Some((id.parse::<u32>().ok()?, name.trim())));
        let this_has_id = split.is_some();
        let mode = *with_ids.get_or_insert(this_has_id);
        if mode != this_has_id {
            return Err(CloudError::format(
                classes_path,
                format!(
                    "line {}: expected {}, got '{line}' (a file uses one form throughout)",
                    lineno + 1,
                    if mode {
                        "'<id> <name>'"
                    } else {
                        "a class name without an id"
                    }
                ),
            ));
        }
        match split {
            Some((id, name)) => {
                if let Some(k) = ids.iter().position(|&i| i == id) {
                    return Err(CloudError::format(
                        classes_path,
                        format!(
                            "line {}: class id {id} is given twice ('{}' and '{name}'); each \
                             id names one class",
                            lineno + 1,
                            names[k]
                        ),
                    ));
                }
                ids.push(id);
                names.push(name.to_string());
            }
            None => {
                ids.push(names.len() as u32);
                names.push(line.to_string());
            }
        }
    }
    if ids.is_empty() {
        return Err(CloudError::format(classes_path, "no classes in the list"));
    }
    Ok((ids, names))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_lists_have_unique_ids_and_names_and_parse_by_name() {
        for set in BuiltinClasses::ALL {
            let c = set.classes();
            let ids: std::collections::BTreeSet<u32> = c.iter().map(|(i, _)| *i).collect();
            let names: std::collections::BTreeSet<&str> = c.iter().map(|(_, n)| *n).collect();
            assert_eq!(ids.len(), c.len(), "{set:?}");
            assert_eq!(names.len(), c.len(), "{set:?}");
            assert_eq!(BuiltinClasses::from_name(set.name()), Some(set));
        }
        assert_eq!(
            BuiltinClasses::from_name("Semantic-KITTI"),
            Some(BuiltinClasses::SemanticKitti)
        );
        assert_eq!(BuiltinClasses::from_name("classes.txt"), None);
        // ASPRS: codes 0..=22 in order, the ones the LAS readers see.
        let codes: Vec<u32> = ASPRS_CLASSES.iter().map(|(i, _)| *i).collect();
        assert_eq!(codes, (0..=22).collect::<Vec<u32>>());
        assert_eq!(ASPRS_CLASSES[2].1, "ground");
        assert_eq!(ASPRS_CLASSES[6].1, "building");
        // The text form reads back as the same ids and names.
        let dir = tempfile::tempdir().unwrap();
        let txt = dir.path().join("classes.txt");
        std::fs::write(&txt, BuiltinClasses::Asprs.to_text()).unwrap();
        let npy = dir.path().join("e.npy");
        crate::io::npy::write_npy(&npy, &[23, 1], &[1.0; 23]).unwrap();
        let t = EmbeddingTable::read(&txt, &npy).unwrap();
        assert_eq!(t.ids, codes);
        assert_eq!(t.names[16], "wire-structure connector");
    }

    #[test]
    fn class_lists_with_a_repeated_or_oversized_id_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let list = |text: &str| {
            let p = dir.path().join("classes.txt");
            std::fs::write(&p, text).unwrap();
            read_class_list(&p).map_err(|e| e.to_string())
        };
        assert_eq!(
            list("0 wall\n1 floor\n").unwrap(),
            (vec![0, 1], vec!["wall".to_string(), "floor".to_string()])
        );
        let e = list("0 wall\n0 floor\n").unwrap_err();
        assert!(
            e.contains("classes.txt") && e.contains("line 2") && e.contains("given twice"),
            "{e}"
        );
        let e = list("99999999999999999999 wall\n").unwrap_err();
        assert!(
            e.contains("classes.txt") && e.contains("line 1") && e.contains("out of range"),
            "{e}"
        );
    }

    #[test]
    fn label_bits_split() {
        let raw = (7u32 << 16) | 252;
        assert_eq!(semantic_id(raw), 252);
        assert_eq!(instance_id(raw), 7);
        assert!(is_dropped_semantic_kitti(semantic_id(raw)));
        assert!(!is_dropped_semantic_kitti(50));
    }

    #[test]
    fn tables_agree() {
        for (id, name) in SEMANTIC_KITTI_CLASSES {
            let t = semantic_kitti_learning_id(id).unwrap();
            if t > 0 && id < 252 {
                // Static classes keep their names through the learning map,
                // except those merged into a broader class.
                let merged = matches!(id, 16 | 13 | 60);
                assert!(
                    merged || SEMANTIC_KITTI_TRAIN_NAMES[t as usize - 1] == name,
                    "{id} {name}"
                );
            }
        }
        assert_eq!(semantic_kitti_name(70), Some("vegetation"));
    }

    #[test]
    fn table_reads_and_maps_labels() {
        let d = tempfile::tempdir().unwrap();
        let c = d.path().join("classes.txt");
        let n = d.path().join("emb.npy");
        std::fs::write(&c, "# id name\n40 road\n50 tall building\n").unwrap();
        crate::io::npy::write_npy(&n, &[2, 2], &[1.0, 0.0, 0.0, 1.0]).unwrap();
        let t = EmbeddingTable::read(&c, &n).unwrap();
        assert_eq!(t.names[1], "tall building");
        assert_eq!((t.row_index(50), t.row_index(41)), (Some(1), None));
        assert_eq!(
            t.features_for(&[50, 40], "s").unwrap(),
            vec![0.0, 1.0, 1.0, 0.0]
        );
        let e = t.features_for(&[40, 10], "scan7").unwrap_err().to_string();
        assert!(
            e.contains("scan7") && e.contains("point 1") && e.contains("10"),
            "{e}"
        );
        crate::io::npy::write_npy(&n, &[3, 2], &[0.0; 6]).unwrap();
        let e = EmbeddingTable::read(&c, &n).unwrap_err().to_string();
        assert!(e.contains("emb.npy") && e.contains("[3, 2]"), "{e}");
    }

    #[test]
    fn names_only_lists_take_line_indices_and_forms_do_not_mix() {
        let d = tempfile::tempdir().unwrap();
        let c = d.path().join("classes.txt");
        let n = d.path().join("emb.npy");
        std::fs::write(
            &c,
            "floor
# comment
tv monitor
",
        )
        .unwrap();
        crate::io::npy::write_npy(&n, &[2, 2], &[1.0, 0.0, 0.0, 1.0]).unwrap();
        let t = EmbeddingTable::read(&c, &n).unwrap();
        assert_eq!(t.ids, vec![0, 1]);
        assert_eq!(t.names, vec!["floor", "tv monitor"]);
        std::fs::write(
            &c,
            "floor
7 wall
",
        )
        .unwrap();
        let e = EmbeddingTable::read(&c, &n).unwrap_err().to_string();
        assert!(e.contains("classes.txt") && e.contains("line 2"), "{e}");
    }
}
