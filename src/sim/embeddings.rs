//! Class embeddings with the similarity structure of real CLIP text space.
//!
//! A [`ClassEmbeddings`] table holds one unit-norm row of dimension `dim`
//! (512 for CLIP ViT-B/32) per class name. Rows come from real CLIP text
//! embeddings where the class exists in a real vocabulary (LVIS, COCO,
//! Objects365, prompt "a {name}"), and are drawn from a Gaussian fitted to the
//! real rows (their mean and full sample covariance) where it does not ("wall",
//! "floor", "road" are not object classes in those vocabularies). Drawn rows
//! therefore sit among the real ones the way an unseen CLIP class would: about
//! as similar to everything as real classes are to each other, not orthogonal.
//!
//! The same table answers text prompts ([`ClassEmbeddings::text_feature`]), so
//! "toilet" typed by a user lands on the row the synthetic images use.

use rand::SeedableRng;

use crate::io::labels::{BuiltinClasses, EmbeddingTable};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Errors building an embedding table.
#[derive(Debug, thiserror::Error)]
pub enum EmbeddingError {
    #[error("embedding table: {rows} values do not form {names} rows of dimension {dim}")]
    Shape {
        names: usize,
        dim: usize,
        rows: usize,
    },
    #[error("embedding table: row {index} ({name}) has zero or non-finite norm")]
    BadRow { index: usize, name: String },
    #[error("embedding table: class name {0:?} appears twice")]
    Duplicate(String),
    #[error("class {index} ({name:?}) is not in the embedding table")]
    Unknown { index: usize, name: String },
    #[error("real embedding bank holds no rows to fit missing classes")]
    EmptyBank,
}

/// One unit-norm embedding row per class name; class id = row index.
#[derive(Debug, Clone, PartialEq)]
pub struct ClassEmbeddings {
    /// Class names, id = index.
    pub names: Vec<String>,
    /// Feature dimension F.
    pub dim: usize,
    /// `names.len() * dim` values, row-major, every row unit norm.
    pub rows: Vec<f32>,
}

impl ClassEmbeddings {
    /// Builds a table, normalizing every row to unit length.
    pub fn new(names: Vec<String>, dim: usize, mut rows: Vec<f32>) -> Result<Self, EmbeddingError> {
        if dim == 0 || rows.len() != names.len() * dim {
            return Err(EmbeddingError::Shape {
                names: names.len(),
                dim,
                rows: rows.len(),
            });
        }
        for (i, row) in rows.chunks_mut(dim).enumerate() {
            if !normalize(row) {
                return Err(EmbeddingError::BadRow {
                    index: i,
                    name: names[i].clone(),
                });
            }
        }
        let mut seen = rustc_hash::FxHashSet::default();
        for n in &names {
            if !seen.insert(lookup_key(n)) {
                return Err(EmbeddingError::Duplicate(n.clone()));
            }
        }
        Ok(ClassEmbeddings { names, dim, rows })
    }

    /// Number of classes K.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True when the table has no classes.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// The unit-norm row of class `id`.
    pub fn row(&self, id: usize) -> &[f32] {
        &self.rows[id * self.dim..(id + 1) * self.dim]
    }

    /// Class id of `name` (case-insensitive; spaces, `_` and `-` are equal).
    pub fn index_of(&self, name: &str) -> Option<usize> {
        let key = lookup_key(name);
        self.names.iter().position(|n| lookup_key(n) == key)
    }

    /// The text feature of a class name: the same row the synthetic images
    /// use for that class, so prompts and images share one space.
    pub fn text_feature(&self, name: &str) -> Option<&[f32]> {
        self.index_of(name).map(|i| self.row(i))
    }

    /// Cosine similarity between classes `a` and `b`.
    pub fn cosine(&self, a: usize, b: usize) -> f32 {
        dot(self.row(a), self.row(b))
    }

    /// The table restricted to `names`, in that order (ids renumbered).
    pub fn subset(&self, names: &[&str]) -> Result<ClassEmbeddings, EmbeddingError> {
        let mut rows = Vec::with_capacity(names.len() * self.dim);
        for (i, n) in names.iter().enumerate() {
            let id = self.index_of(n).ok_or(EmbeddingError::Unknown {
                index: i,
                name: n.to_string(),
            })?;
            rows.extend_from_slice(self.row(id));
        }
        ClassEmbeddings::new(
            names.iter().map(|s| s.to_string()).collect(),
            self.dim,
            rows,
        )
    }

    /// The class whose row is most similar to `feature` (any length-`dim`
    /// vector; it need not be unit norm), with that cosine times `|feature|`.
    pub fn nearest(&self, feature: &[f32]) -> (usize, f32) {
        let mut best = (0, f32::NEG_INFINITY);
        for k in 0..self.len() {
            let s = dot(self.row(k), feature);
            if s > best.1 {
                best = (k, s);
            }
        }
        best
    }
}

/// Real embeddings of a vocabulary: names and unit-norm rows.
#[derive(Debug, Clone)]
pub struct ClipBank {
    /// Vocabulary names as given by the source (e.g. `car_(automobile)`).
    pub names: Vec<String>,
    /// Feature dimension.
    pub dim: usize,
    /// Unit-norm rows, `names.len() * dim` values.
    pub rows: Vec<f32>,
}

impl ClipBank {
    /// Builds a bank from raw rows (normalized here; CLIP text rows come
    /// unnormalized). Rows of zero norm are dropped with their names.
    pub fn new(names: Vec<String>, dim: usize, rows: Vec<f32>) -> Result<Self, EmbeddingError> {
        if dim == 0 || rows.len() != names.len() * dim {
            return Err(EmbeddingError::Shape {
                names: names.len(),
                dim,
                rows: rows.len(),
            });
        }
        let mut out_names = Vec::with_capacity(names.len());
        let mut out_rows = Vec::with_capacity(rows.len());
        for (name, row) in names.into_iter().zip(rows.chunks(dim)) {
            let mut r = row.to_vec();
            if normalize(&mut r) {
                out_names.push(name);
                out_rows.extend_from_slice(&r);
            }
        }
        Ok(ClipBank {
            names: out_names,
            dim,
            rows: out_rows,
        })
    }

    /// Appends another bank of the same dimension (later names never shadow
    /// earlier ones in [`ClipBank::find`]).
    pub fn extend(&mut self, other: ClipBank) -> Result<(), EmbeddingError> {
        if other.dim != self.dim {
            return Err(EmbeddingError::Shape {
                names: other.names.len(),
                dim: self.dim,
                rows: other.rows.len(),
            });
        }
        self.names.extend(other.names);
        self.rows.extend(other.rows);
        Ok(())
    }

    /// Index of the first row whose source name matches `source_name`
    /// (case-insensitive; spaces, `_`, `-` equal).
    pub fn find(&self, source_name: &str) -> Option<usize> {
        let key = lookup_key(source_name);
        self.names.iter().position(|n| lookup_key(n) == key)
    }

    fn row(&self, i: usize) -> &[f32] {
        &self.rows[i * self.dim..(i + 1) * self.dim]
    }
}

/// Where a class's row comes from: the real vocabulary entry to use, or a
/// draw from the fitted distribution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClassSource {
    /// Class name as the simulator and the user see it.
    pub name: &'static str,
    /// Name in the real vocabulary (LVIS, COCO or Objects365), or `None` when
    /// no real vocabulary has the class.
    pub source: Option<&'static str>,
}

/// Every class the simulator uses, with its source in the real vocabularies.
/// Indoor classes first, then outdoor ones. Where a vocabulary has a near
/// synonym rather than the name itself the synonym is used (LVIS has no
/// "shelving", its "bookcase" is the same object to CLIP).
pub const SIM_CLASSES: &[ClassSource] = &[
    ClassSource {
        name: "wall",
        source: None,
    },
    ClassSource {
        name: "floor",
        source: None,
    },
    ClassSource {
        name: "ceiling",
        source: None,
    },
    ClassSource {
        name: "door",
        source: None,
    },
    ClassSource {
        name: "window",
        source: None,
    },
    ClassSource {
        name: "table",
        source: Some("table"),
    },
    ClassSource {
        name: "chair",
        source: Some("chair"),
    },
    ClassSource {
        name: "sofa",
        source: Some("sofa"),
    },
    ClassSource {
        name: "bed",
        source: Some("bed"),
    },
    ClassSource {
        name: "cabinet",
        source: Some("cabinet"),
    },
    ClassSource {
        name: "shelving",
        source: Some("bookcase"),
    },
    ClassSource {
        name: "toilet",
        source: Some("toilet"),
    },
    ClassSource {
        name: "sink",
        source: Some("sink"),
    },
    ClassSource {
        name: "mirror",
        source: Some("mirror"),
    },
    ClassSource {
        name: "towel",
        source: Some("towel"),
    },
    ClassSource {
        name: "tv monitor",
        source: Some("television_set"),
    },
    ClassSource {
        name: "picture",
        source: Some("painting"),
    },
    ClassSource {
        name: "plant",
        source: Some("potted plant"),
    },
    ClassSource {
        name: "rug",
        source: Some("carpet"),
    },
    ClassSource {
        name: "lamp",
        source: Some("lamp"),
    },
    ClassSource {
        name: "counter",
        source: None,
    },
    ClassSource {
        name: "stove",
        source: Some("stove"),
    },
    ClassSource {
        name: "fridge",
        source: Some("refrigerator"),
    },
    ClassSource {
        name: "bathtub",
        source: Some("bathtub"),
    },
    ClassSource {
        name: "cushion",
        source: Some("cushion"),
    },
    ClassSource {
        name: "desk",
        source: Some("desk"),
    },
    ClassSource {
        name: "wardrobe",
        source: Some("wardrobe"),
    },
    ClassSource {
        name: "nightstand",
        source: Some("nightstand"),
    },
    ClassSource {
        name: "curtain",
        source: Some("curtain"),
    },
    ClassSource {
        name: "road",
        source: None,
    },
    ClassSource {
        name: "sidewalk",
        source: None,
    },
    ClassSource {
        name: "building",
        source: None,
    },
    ClassSource {
        name: "vegetation",
        source: None,
    },
    ClassSource {
        name: "terrain",
        source: None,
    },
    ClassSource {
        name: "car",
        source: Some("car_(automobile)"),
    },
    ClassSource {
        name: "pole",
        source: Some("pole"),
    },
    ClassSource {
        name: "traffic sign",
        source: Some("traffic sign"),
    },
    ClassSource {
        name: "fence",
        source: None,
    },
];

/// Builds the table for `classes`: real rows where the bank has the source
/// name, otherwise a draw from N(mean, covariance) of the bank's rows,
/// normalized. The draw uses `x = mean + sum_i z_i (x_i - mean) / sqrt(n-1)`
/// with `z_i ~ N(0, 1)`, which has exactly the sample mean and covariance
/// without forming the 512 x 512 covariance matrix. Deterministic in `seed`;
/// the i-th missing class always uses the i-th draw of the stream.
pub fn build_table(
    bank: &ClipBank,
    classes: &[ClassSource],
    seed: u64,
) -> Result<ClassEmbeddings, EmbeddingError> {
    let n = bank.names.len();
    if n < 2 {
        return Err(EmbeddingError::EmptyBank);
    }
    let dim = bank.dim;
    let mut mean = vec![0.0f64; dim];
    for i in 0..n {
        for (m, &x) in mean.iter_mut().zip(bank.row(i)) {
            *m += x as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n as f64);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let scale = 1.0 / ((n - 1) as f64).sqrt();
    let mut rows = Vec::with_capacity(classes.len() * dim);
    for c in classes {
        match c.source.and_then(|s| bank.find(s)) {
            Some(i) => rows.extend_from_slice(bank.row(i)),
            None => {
                let mut v = mean.clone();
                for i in 0..n {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    let w = z * scale;
                    for ((acc, &x), &m) in v.iter_mut().zip(bank.row(i)).zip(&mean) {
                        *acc += w * (x as f64 - m);
                    }
                }
                rows.extend(v.iter().map(|&x| x as f32));
            }
        }
    }
    ClassEmbeddings::new(
        classes.iter().map(|c| c.name.to_string()).collect(),
        dim,
        rows,
    )
}

/// The built-in CLIP-like table of a built-in class list, for a quick
/// start without a text encoder (`--classes semantickitti` or `asprs`
/// without `--embeddings`): a class the simulator's table has under the
/// same meaning (road, building, car, ...) gets that row, so simulated and
/// real maps share them; a moving class (SemanticKITTI 252-259) gets its
/// static class's row; every other class is a draw from a Gaussian fitted
/// to `sim_table`'s rows ([`build_table`] with `sim_table` as the bank),
/// deterministic per list. Only the simulator's real rows are real CLIP
/// features: for real images or text, embed the list with a text encoder.
pub fn builtin_label_table(
    set: BuiltinClasses,
    sim_table: &ClassEmbeddings,
) -> Result<EmbeddingTable, EmbeddingError> {
    // Classes whose meaning a simulator class shares.
    let alias = |id: u32| -> Option<&'static str> {
        match (set, id) {
            (BuiltinClasses::SemanticKitti, 10) => Some("car"),
            (BuiltinClasses::SemanticKitti, 40) => Some("road"),
            (BuiltinClasses::SemanticKitti, 48) => Some("sidewalk"),
            (BuiltinClasses::SemanticKitti, 50) => Some("building"),
            (BuiltinClasses::SemanticKitti, 51) => Some("fence"),
            (BuiltinClasses::SemanticKitti, 70) => Some("vegetation"),
            (BuiltinClasses::SemanticKitti, 72) => Some("terrain"),
            (BuiltinClasses::SemanticKitti, 80) => Some("pole"),
            (BuiltinClasses::SemanticKitti, 81) => Some("traffic sign"),
            (BuiltinClasses::Asprs, 3) => Some("terrain"),
            (BuiltinClasses::Asprs, 5) => Some("vegetation"),
            (BuiltinClasses::Asprs, 6) => Some("building"),
            (BuiltinClasses::Asprs, 11) => Some("road"),
            _ => None,
        }
    };
    // SemanticKITTI's moving classes and their static counterparts.
    let moving = |id: u32| -> Option<u32> {
        match (set, id) {
            (BuiltinClasses::SemanticKitti, 252) => Some(10),
            (BuiltinClasses::SemanticKitti, 253) => Some(31),
            (BuiltinClasses::SemanticKitti, 254) => Some(30),
            (BuiltinClasses::SemanticKitti, 255) => Some(32),
            (BuiltinClasses::SemanticKitti, 256) => Some(16),
            (BuiltinClasses::SemanticKitti, 257) => Some(13),
            (BuiltinClasses::SemanticKitti, 258) => Some(18),
            (BuiltinClasses::SemanticKitti, 259) => Some(20),
            _ => None,
        }
    };
    let bank = ClipBank::new(
        sim_table.names.clone(),
        sim_table.dim,
        sim_table.rows.clone(),
    )?;
    let own: Vec<(u32, &str)> = set
        .classes()
        .iter()
        .copied()
        .filter(|(id, _)| moving(*id).is_none())
        .collect();
    let sources: Vec<ClassSource> = own
        .iter()
        .map(|&(id, name)| ClassSource {
            name,
            source: alias(id),
        })
        .collect();
    let seed = match set {
        BuiltinClasses::SemanticKitti => 1,
        BuiltinClasses::Asprs => 2,
    };
    let table = build_table(&bank, &sources, seed)?;
    let dim = table.dim;
    let row_of = |id: u32| own.iter().position(|(i, _)| *i == id).map(|r| table.row(r));
    let mut ids = Vec::new();
    let mut names = Vec::new();
    let mut data = Vec::new();
    for &(id, name) in set.classes() {
        let static_id = moving(id).unwrap_or(id);
        // The simulator's own row, to the bit (the bank renormalizes).
        let exact = alias(static_id).and_then(|n| sim_table.text_feature(n));
        let row = exact
            .or_else(|| row_of(static_id))
            .ok_or(EmbeddingError::Unknown {
                index: ids.len(),
                name: name.to_string(),
            })?;
        ids.push(id);
        names.push(name.to_string());
        data.extend_from_slice(row);
    }
    EmbeddingTable::new(ids, names, dim, data).map_err(|_| EmbeddingError::Shape {
        names: set.classes().len(),
        dim,
        rows: 0,
    })
}

/// Dot product, summed in order (not `map::features::dot`, whose
/// vectorized summation order would change the built-in table's bits).
pub fn dot(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

pub use crate::map::features::normalize;

fn lookup_key(name: &str) -> String {
    name.trim()
        .chars()
        .map(|c| match c {
            '_' | '-' => ' ',
            c => c.to_ascii_lowercase(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bank() -> ClipBank {
        // Four real-looking rows in 3-D: two close pairs.
        ClipBank::new(
            vec!["a".into(), "b_b".into(), "c".into(), "d".into()],
            3,
            vec![1.0, 0.1, 0.0, 0.9, 0.2, 0.0, 0.0, 0.1, 1.0, 0.1, 0.0, 0.9],
        )
        .unwrap()
    }

    #[test]
    fn real_rows_are_copied_and_names_match_loosely() {
        let classes = [
            ClassSource {
                name: "B B",
                source: Some("b-b"),
            },
            ClassSource {
                name: "x",
                source: None,
            },
        ];
        let t = build_table(&bank(), &classes, 7).unwrap();
        let b = bank();
        assert_eq!(t.row(0), b.row(1));
        assert_eq!(t.index_of("b_b"), Some(0));
        assert_eq!(t.text_feature("X").unwrap(), t.row(1));
        let n: f32 = t.row(1).iter().map(|x| x * x).sum();
        assert!((n - 1.0).abs() < 1e-5);
    }

    #[test]
    fn drawn_rows_stay_in_the_span_of_the_bank() {
        // Every bank row has y small and x, z >= 0; a draw from the fitted
        // Gaussian lies in mean + span(deviations), here the x-z plane up to
        // the small y spread, so it cannot point along -y.
        let classes = [ClassSource {
            name: "x",
            source: None,
        }];
        let t = build_table(&bank(), &classes, 1).unwrap();
        assert!(t.row(0)[1].abs() < 0.5, "{:?}", t.row(0));
        let t2 = build_table(&bank(), &classes, 1).unwrap();
        assert_eq!(t, t2);
        let t3 = build_table(&bank(), &classes, 2).unwrap();
        assert_ne!(t, t3);
    }

    #[test]
    fn builtin_label_tables_share_the_simulator_rows_and_draw_the_rest() {
        let sim = crate::sim::files::builtin_table().unwrap();
        for set in BuiltinClasses::ALL {
            let t = builtin_label_table(set, &sim).unwrap();
            assert_eq!(t.ids.len(), set.classes().len());
            assert_eq!(t.dim, sim.dim);
            for r in t.data.chunks(t.dim) {
                let n: f32 = r.iter().map(|x| x * x).sum();
                assert!((n - 1.0).abs() < 1e-4, "{set:?}: norm {n}");
            }
            // Deterministic.
            assert_eq!(t, builtin_label_table(set, &sim).unwrap());
        }
        let k = builtin_label_table(BuiltinClasses::SemanticKitti, &sim).unwrap();
        let s = |n: &str| sim.text_feature(n).unwrap();
        assert_eq!(k.row(40).unwrap(), s("road"));
        assert_eq!(k.row(81).unwrap(), s("traffic sign"));
        assert_eq!(k.row(252).unwrap(), k.row(10).unwrap());
        assert_eq!(k.row(254).unwrap(), k.row(30).unwrap());
        // Drawn rows are new: no two static classes share a row, and a drawn
        // row is as similar to the others as the simulator's rows are to
        // each other (CLIP-like: positive, well below 1).
        let statics: Vec<u32> = k.ids.iter().copied().filter(|i| *i < 252).collect();
        let mut cos = Vec::new();
        for (a, &i) in statics.iter().enumerate() {
            for &j in &statics[a + 1..] {
                let c = dot(k.row(i).unwrap(), k.row(j).unwrap());
                assert!(c < 0.999, "{i} and {j}: {c}");
                cos.push(c);
            }
        }
        let mean = cos.iter().sum::<f32>() / cos.len() as f32;
        let mut sim_cos = Vec::new();
        for i in 0..sim.len() {
            for j in i + 1..sim.len() {
                sim_cos.push(sim.cosine(i, j));
            }
        }
        let sim_mean = sim_cos.iter().sum::<f32>() / sim_cos.len() as f32;
        assert!((mean - sim_mean).abs() < 0.15, "{mean} vs {sim_mean}");
        let a = builtin_label_table(BuiltinClasses::Asprs, &sim).unwrap();
        assert_eq!(a.row(6).unwrap(), s("building"));
        assert_eq!(a.row(11).unwrap(), s("road"));
        assert_ne!(a.row(2).unwrap(), a.row(20).unwrap());
    }

    #[test]
    fn bad_tables_are_rejected() {
        assert!(ClassEmbeddings::new(vec!["a".into()], 2, vec![0.0, 0.0]).is_err());
        assert!(ClassEmbeddings::new(vec!["a".into()], 2, vec![1.0]).is_err());
        assert!(ClassEmbeddings::new(vec!["a".into(), "A".into()], 1, vec![1.0, 1.0]).is_err());
        let t = ClassEmbeddings::new(vec!["a".into(), "b".into()], 2, vec![3.0, 4.0, 0.0, 2.0])
            .unwrap();
        assert!((t.cosine(0, 1) - 0.8).abs() < 1e-6);
        assert_eq!(t.nearest(&[0.0, 1.0]).0, 1);
    }
}
