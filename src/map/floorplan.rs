//! Floor-plan maps: the Octree Language Map projected to a 2-D grid by
//! averaging its features along the vertical (the paper's 2-D block of
//! Table I, on which OMCL, SeDAR* and SIMP* are compared).
//!
//! # Construction
//!
//! Every column `(i, j)` of the map's grid (same resolution and horizontal
//! origin) gets the mean of the features of its leaves whose centres lie in
//! a height band `[floor + band_min, floor + band_max]`, where `floor` is
//! the bottom of the map's lowest occupied layer. Each leaf counts once
//! with its (unit) database row; the sum is normalized. The band leaves out
//! the floor and the ceiling: they cover every column of a room, so with
//! them every free column would be occupied and a horizontal ray would stop
//! in the camera's own cell. Columns with no leaf in the band are free.
//!
//! The database is rebuilt from the averaged column features with the
//! map's own `tau`: each averaged feature is admitted in column order
//! (`j` then `i`) into an empty [`FeatureDb`] of the same dimension (a new
//! row when it is farther than `tau` in cosine distance from every row,
//! else the nearest row represents it), so a wall column keeps the wall's
//! row and a column of a table under a shelf gets the blend of the two.
//!
//! # File
//!
//! One safetensors file, like the 3-D map ([`super::file`]): tensors
//! `cells` (I32, P x 2 column indices, strictly increasing in `(j, i)`),
//! `rows` (U32, P feature rows), `features` (F32, K x F unit rows); header
//! `format` = `omcl-floor-plan`, `version`, `resolution`, `origin_x`,
//! `origin_y`, `floor_z`, `band_min`, `band_max` (m), `feature_dim`, `tau`,
//! `encoder`, `cells`, `rows`, and `crc32`: CRC-32 of the header values of
//! [`CHECKED_FIELDS`] (each as a `name=value` line) followed by the three
//! tensors' bytes. A file of another version or with a wrong checksum is
//! refused with a named error.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use safetensors::tensor::{Dtype, TensorView};

use super::container::{Container, ContainerProblem, le_4};

use super::features::{FeatureDb, FeatureDbError};
use super::key::GridSpec;
use super::octree::{LanguageMap, MapError};

/// Value of the `format` field.
pub const FORMAT: &str = super::container::PLAN_FORMAT;
/// Version this build writes and reads.
pub const VERSION: u32 = 1;

/// Header fields covered by the checksum, in checksum order.
pub const CHECKED_FIELDS: [&str; 13] = [
    "format",
    "version",
    "resolution",
    "origin_x",
    "origin_y",
    "floor_z",
    "band_min",
    "band_max",
    "feature_dim",
    "tau",
    "encoder",
    "cells",
    "rows",
];

/// The height band whose leaves are averaged, metres above the bottom of
/// the map's lowest occupied layer.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FloorPlanParams {
    pub band_min: f64,
    pub band_max: f64,
}

impl Default for FloorPlanParams {
    /// 0.10 to 2.00 m: above a 5 cm floor slab and its skirting, below the
    /// ceiling and below the wall over doorways (the synthetic doors are
    /// 2.05 m high; a band up to 2.3 m closed every doorway in the plan).
    fn default() -> Self {
        FloorPlanParams {
            band_min: 0.10,
            band_max: 2.00,
        }
    }
}

impl FloorPlanParams {
    /// Refuses a band that is empty or not finite
    /// ([`FloorPlanError::BadBand`]).
    pub fn validate(&self) -> Result<(), FloorPlanError> {
        let (lo, hi) = (self.band_min, self.band_max);
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(FloorPlanError::BadBand(lo, hi));
        }
        Ok(())
    }
}

/// Errors building a floor plan.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FloorPlanError {
    #[error("the height band [{0}, {1}] m is empty or not finite")]
    BadBand(f64, f64),
    #[error("the map has no leaf in the height band [{0}, {1}] m above its floor")]
    EmptyBand(f64, f64),
    #[error("column indices must be strictly increasing in (j, i) (at column {0})")]
    Unsorted(usize),
    #[error("the encoder's name {0:?} holds control characters")]
    BadEncoderName(String),
    #[error("{cells} cells but {rows} row indices")]
    LengthMismatch { cells: usize, rows: usize },
    #[error("column {cell} points at feature row {row}, but the database has {rows} rows")]
    RowOutOfRange { cell: usize, row: u32, rows: usize },
    #[error("resolution must be a positive finite number of metres, got {0}")]
    BadResolution(f64),
    #[error(
        "the columns span {width} x {height} cells ({:.0} x {:.0} m at {resolution} m), more \
         than {MAX_PLAN_CELLS} in all: is a voxel far from the rest (an outlier of the cloud)?",
        *width as f64 * resolution,
        *height as f64 * resolution
    )]
    TooLarge {
        width: u64,
        height: u64,
        resolution: f64,
    },
    #[error(transparent)]
    Features(#[from] FeatureDbError),
    #[error(transparent)]
    Map(#[from] MapError),
}

/// Most cells a plan's bounding rectangle may hold (2^28: 1.6 km square
/// at 0.1 m). The planar caster and the plan's image are dense over that
/// rectangle; one outlier 100 km away made a 4 TB grid.
pub const MAX_PLAN_CELLS: u64 = 1 << 28;

/// A floor plan: occupied columns of a 2-D grid and their feature rows.
#[derive(Debug, Clone, PartialEq)]
pub struct FloorPlan {
    /// Cell edge, metres.
    pub resolution: f64,
    /// World x, y of the corner of cell (0, 0).
    pub origin: [f64; 2],
    /// World z of the floor the band is measured from.
    pub floor_z: f64,
    pub params: FloorPlanParams,
    cells: Vec<[i32; 2]>,
    rows: Vec<u32>,
    db: FeatureDb,
    encoder: String,
}

impl FloorPlan {
    /// A plan from columns already sorted by `(j, i)`.
    #[allow(clippy::too_many_arguments)]
    pub fn from_parts(
        resolution: f64,
        origin: [f64; 2],
        floor_z: f64,
        params: FloorPlanParams,
        db: FeatureDb,
        encoder: impl Into<String>,
        cells: Vec<[i32; 2]>,
        rows: Vec<u32>,
    ) -> Result<Self, FloorPlanError> {
        if !(resolution.is_finite() && resolution > 0.0) {
            return Err(FloorPlanError::BadResolution(resolution));
        }
        if cells.len() != rows.len() {
            return Err(FloorPlanError::LengthMismatch {
                cells: cells.len(),
                rows: rows.len(),
            });
        }
        if let Some(i) = cells
            .windows(2)
            .position(|w| (w[0][1], w[0][0]) >= (w[1][1], w[1][0]))
        {
            return Err(FloorPlanError::Unsorted(i + 1));
        }
        if let (Some(first), Some(last)) = (cells.first(), cells.last()) {
            // Sorted by (j, i): j's range is the ends'; i's needs a pass.
            let (mut i_lo, mut i_hi) = (i64::MAX, i64::MIN);
            for c in &cells {
                i_lo = i_lo.min(c[0] as i64);
                i_hi = i_hi.max(c[0] as i64);
            }
            let width = (i_hi - i_lo + 1) as u64;
            let height = (last[1] as i64 - first[1] as i64 + 1) as u64;
            if width.saturating_mul(height) > MAX_PLAN_CELLS {
                return Err(FloorPlanError::TooLarge {
                    width,
                    height,
                    resolution,
                });
            }
        }
        let encoder = encoder.into();
        if encoder.chars().any(char::is_control) {
            return Err(FloorPlanError::BadEncoderName(encoder));
        }
        if let Some((cell, &row)) = rows
            .iter()
            .enumerate()
            .find(|(_, r)| **r as usize >= db.len())
        {
            return Err(FloorPlanError::RowOutOfRange {
                cell,
                row,
                rows: db.len(),
            });
        }
        Ok(FloorPlan {
            resolution,
            origin,
            floor_z,
            params,
            cells,
            rows,
            db,
            encoder,
        })
    }

    /// Projects `map` to a floor plan (see the module documentation).
    pub fn from_map(map: &LanguageMap, params: &FloorPlanParams) -> Result<Self, FloorPlanError> {
        params.validate()?;
        let (lo, hi) = (params.band_min, params.band_max);
        let g = map.grid();
        let r = g.resolution;
        let Some((min, _)) = map.cell_bounds() else {
            return Err(FloorPlanError::EmptyBand(lo, hi));
        };
        let floor_z = g.origin.z + min[2] as f64 * r;
        let dim = map.db().dim();
        // Sum of unit rows per column.
        let mut sums: HashMap<(i32, i32), Vec<f32>> = HashMap::new();
        for (c, &row) in map.cells().iter().zip(map.rows()) {
            let centre = g.origin.z + (c[2] as f64 + 0.5) * r - floor_z;
            if centre < lo || centre > hi {
                continue;
            }
            let s = sums.entry((c[1], c[0])).or_insert_with(|| vec![0.0; dim]);
            for (a, b) in s.iter_mut().zip(map.db().row(row as usize)) {
                *a += b;
            }
        }
        if sums.is_empty() {
            return Err(FloorPlanError::EmptyBand(lo, hi));
        }
        let mut keys: Vec<(i32, i32)> = sums.keys().copied().collect();
        keys.sort_unstable();
        let mut db = FeatureDb::new(dim, map.db().tau())?;
        let mut cells = Vec::with_capacity(keys.len());
        let mut rows = Vec::with_capacity(keys.len());
        for k in keys {
            let f = &sums[&k];
            // A column whose features cancel exactly has no direction: it
            // is left free.
            match db.admit(f) {
                Ok(row) => {
                    cells.push([k.1, k.0]);
                    rows.push(row as u32);
                }
                Err(FeatureDbError::Degenerate { .. }) => continue,
                Err(e) => return Err(e.into()),
            }
        }
        Self::from_parts(
            r,
            [g.origin.x, g.origin.y],
            floor_z,
            *params,
            db,
            map.encoder(),
            cells,
            rows,
        )
    }

    /// The vertical extent of every column's in-band leaves in `map` (the
    /// map the plan was projected from), metres above `floor_z`, in the
    /// order of [`FloorPlan::cells`]: `[bottom of the lowest leaf, top of
    /// the highest]`. A column reaching within one cell of the band's
    /// bottom gets `-inf` (it stands on the floor). One reaching within one
    /// cell of the band's top goes on up through its leaves above the band
    /// (over holes of at most one cell): to `+inf` if they reach within
    /// one cell of the ceiling ([`FloorPlan::ceiling_height`]; walls), else
    /// to the top of the last of them (a 2.0 m wardrobe under a 2.6 m
    /// ceiling ends at 2.0 m, and the pixels that see the ceiling above it
    /// are followed over it). The plan file does not hold these; they are
    /// for what a camera pixel sees in plan view
    /// ([`crate::raycast::PlanarCaster::with_heights`]).
    pub fn column_extents(&self, map: &LanguageMap) -> Vec<[f32; 2]> {
        let g = map.grid();
        let r = g.resolution;
        let (lo, hi) = (self.params.band_min, self.params.band_max);
        let mut ext = vec![[f64::INFINITY, f64::NEG_INFINITY]; self.cells.len()];
        // Each column's leaves above the band (their centres): where a
        // column reaching the band's top really ends.
        let mut above: Vec<Vec<f64>> = vec![Vec::new(); self.cells.len()];
        for c in map.cells() {
            let centre = g.origin.z + (c[2] as f64 + 0.5) * r - self.floor_z;
            if centre < lo {
                continue;
            }
            let Ok(k) = self
                .cells
                .binary_search_by_key(&(c[1], c[0]), |p| (p[1], p[0]))
            else {
                continue;
            };
            if centre > hi {
                above[k].push(centre);
                continue;
            }
            ext[k][0] = ext[k][0].min(centre - r / 2.0);
            ext[k][1] = ext[k][1].max(centre + r / 2.0);
        }
        let ceiling = self.ceiling_height(map).unwrap_or(f64::INFINITY);
        ext.into_iter()
            .zip(above)
            .map(|([b, t], mut above)| {
                let b = if b <= lo + r {
                    f32::NEG_INFINITY
                } else {
                    b as f32
                };
                if t < hi - r {
                    return [b, t as f32];
                }
                // Up from the band's top through the column's leaves,
                // over gaps of at most one cell (holes of the map).
                above.sort_unstable_by(f64::total_cmp);
                let mut top = t;
                for z in above {
                    if z - r / 2.0 > top + r * 1.01 {
                        break;
                    }
                    top = top.max(z + r / 2.0);
                }
                let t = if top >= ceiling - r * 1.01 {
                    f32::INFINITY
                } else {
                    top as f32
                };
                [b, t]
            })
            .collect()
    }

    /// The floor and the ceiling the band leaves out, per column of `map`
    /// (the map the plan was projected from): for every `[i, j]` with
    /// leaves below the band (the floor) or in the map's highest occupied
    /// layer (the ceiling), the sum of those leaves' rows, sorted by
    /// `(j, i)`. Free columns of the plan have them too. Like
    /// [`FloorPlan::column_extents`], not in the plan file; for what a
    /// camera pixel looking down or up sees in plan view.
    pub fn surface_features(&self, map: &LanguageMap) -> [Vec<([i32; 2], Vec<f32>)>; 2] {
        let (lo, hi) = (self.params.band_min, self.params.band_max);
        self.column_sums(map, |_, centre, in_top| {
            if centre < lo {
                Some(0)
            } else if in_top && centre > hi {
                Some(1)
            } else {
                None
            }
        })
    }

    /// Per occupied column of the plan, the sum of the rows of `map`'s
    /// leaves (the map the plan was projected from) whose centres lie in
    /// `[lo, hi)` metres above `floor_z`, leaving out the map's highest
    /// occupied layer (the ceiling); sorted by `(j, i)`. For a column's own
    /// base and top ([`crate::raycast::PlanarCaster::with_skirts`]); not in
    /// the plan file.
    pub fn slab_features(&self, map: &LanguageMap, lo: f64, hi: f64) -> Vec<([i32; 2], Vec<f32>)> {
        let [slab, _] = self.column_sums(map, |c, centre, in_top| {
            let occupied = || {
                self.cells
                    .binary_search_by_key(&(c[1], c[0]), |p| (p[1], p[0]))
                    .is_ok()
            };
            (!in_top && (lo..hi).contains(&centre) && occupied()).then_some(0)
        });
        slab
    }

    /// The sums of `map`'s rows per column `[i, j]` in two lists, sorted by
    /// `(j, i)`: each leaf goes to the list `side(cell, centre height above
    /// floor_z, whether it is in the map's highest occupied layer)` names,
    /// or to none.
    fn column_sums(
        &self,
        map: &LanguageMap,
        mut side: impl FnMut(&crate::map::Cell, f64, bool) -> Option<usize>,
    ) -> [Vec<([i32; 2], Vec<f32>)>; 2] {
        let g = map.grid();
        let r = g.resolution;
        let top = map.cell_bounds().map_or(i32::MAX, |(_, max)| max[2]);
        let dim = map.db().dim();
        let mut sums: [HashMap<(i32, i32), Vec<f32>>; 2] = [HashMap::new(), HashMap::new()];
        for (c, &row) in map.cells().iter().zip(map.rows()) {
            let centre = g.origin.z + (c[2] as f64 + 0.5) * r - self.floor_z;
            let Some(k) = side(c, centre, c[2] == top) else {
                continue;
            };
            let s = sums[k]
                .entry((c[1], c[0]))
                .or_insert_with(|| vec![0.0; dim]);
            for (a, b) in s.iter_mut().zip(map.db().row(row as usize)) {
                *a += b;
            }
        }
        sums.map(|m| {
            let mut v: Vec<([i32; 2], Vec<f32>)> =
                m.into_iter().map(|((j, i), f)| ([i, j], f)).collect();
            v.sort_unstable_by_key(|(c, _)| (c[1], c[0]));
            v
        })
    }

    /// Height of `map`'s ceiling above `floor_z`, metres: the bottom of its
    /// highest occupied layer (the map the plan was projected from).
    pub fn ceiling_height(&self, map: &LanguageMap) -> Option<f64> {
        let g = map.grid();
        let (_, max) = map.cell_bounds()?;
        Some(g.origin.z + max[2] as f64 * g.resolution - self.floor_z)
    }

    /// Occupied columns `[i, j]`, sorted by `(j, i)`.
    pub fn cells(&self) -> &[[i32; 2]] {
        &self.cells
    }

    /// Feature row of every column.
    pub fn rows(&self) -> &[u32] {
        &self.rows
    }

    /// The feature database.
    pub fn db(&self) -> &FeatureDb {
        &self.db
    }

    /// Name of the encoder whose feature space the rows live in.
    pub fn encoder(&self) -> &str {
        &self.encoder
    }

    /// Number of occupied columns.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether no column is occupied.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// Row of column `[i, j]`, if occupied.
    pub fn row_at(&self, cell: [i32; 2]) -> Option<u32> {
        self.cells
            .binary_search_by_key(&(cell[1], cell[0]), |c| (c[1], c[0]))
            .ok()
            .map(|k| self.rows[k])
    }

    /// The plan as a one-layer language map (cells `[i, j, 0]`, origin at
    /// `floor_z`), so that the 3-D filter's pieces (motion, sampling, the
    /// eq. 2 sensor model, estimate) run on it unchanged with a
    /// [`crate::raycast::PlanarCaster`] built from its leaves.
    pub fn to_language_map(&self) -> Result<LanguageMap, FloorPlanError> {
        let grid = GridSpec {
            resolution: self.resolution,
            origin: Vector3::new(self.origin[0], self.origin[1], self.floor_z),
        };
        Ok(LanguageMap::from_cells(
            grid,
            self.db.clone(),
            self.encoder.clone(),
            self.cells
                .iter()
                .zip(&self.rows)
                .map(|(c, &r)| ([c[0], c[1], 0], r)),
        )?)
    }

    /// An RGB image of the plan, one pixel a cell, north (+y) up: free
    /// cells white, occupied cells coloured by feature row (golden-ratio
    /// hues, so neighbouring rows differ). Returns `(width, height, rgb)`.
    pub fn image(&self) -> (u32, u32, Vec<u8>) {
        if self.cells.is_empty() {
            return (1, 1, vec![255; 3]);
        }
        let (mut lo, mut hi) = ([i32::MAX; 2], [i32::MIN; 2]);
        for c in &self.cells {
            for a in 0..2 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        // At most MAX_PLAN_CELLS (checked at construction): no overflow.
        let w = (hi[0] as i64 - lo[0] as i64 + 1) as usize;
        let h = (hi[1] as i64 - lo[1] as i64 + 1) as usize;
        let mut rgb = vec![255u8; w * h * 3];
        for (c, &row) in self.cells.iter().zip(&self.rows) {
            let x = (c[0] as i64 - lo[0] as i64) as usize;
            let y = (hi[1] as i64 - c[1] as i64) as usize;
            let k = (y * w + x) * 3;
            rgb[k..k + 3].copy_from_slice(&row_colour(row));
        }
        (w as u32, h as u32, rgb)
    }
}

/// A colour per feature row: hue `row x 0.618` turns, saturation 0.65,
/// value 0.85.
pub fn row_colour(row: u32) -> [u8; 3] {
    let h = (row as f64 * 0.618_033_988_75).fract() * 6.0;
    let (s, v) = (0.65, 0.85);
    let c = v * s;
    let x = c * (1.0 - ((h % 2.0) - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r, g, b].map(|u| ((u + m) * 255.0).round() as u8)
}

/// Errors reading or writing a floor-plan file; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum FloorPlanFileError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not an omcl floor plan: not a safetensors file ({reason})")]
    NotSafetensors { path: PathBuf, reason: String },
    #[error(
        "{path}: not an omcl floor plan: header field `format` is {}, expected \"{FORMAT}\"",
        super::container::describe_format(found)
    )]
    Foreign {
        path: PathBuf,
        found: Option<String>,
    },
    #[error(
        "{path}: floor-plan format version {found} is not supported (this build reads version {VERSION})"
    )]
    Version { path: PathBuf, found: String },
    #[error("{path}: {problem}")]
    Container {
        path: PathBuf,
        problem: ContainerProblem,
    },
    #[error("{path}: inconsistent floor plan: {source}")]
    Invalid {
        path: PathBuf,
        source: FloorPlanError,
    },
}

fn checksum(meta: &HashMap<String, String>, tensors: [&[u8]; 3]) -> u32 {
    let mut crc = crc32fast::Hasher::new();
    for name in CHECKED_FIELDS {
        crc.update(name.as_bytes());
        crc.update(b"=");
        crc.update(meta.get(name).map_or(&b""[..], |v| v.as_bytes()));
        crc.update(b"\n");
    }
    for t in tensors {
        crc.update(t);
    }
    crc.finalize()
}

/// Serializes a plan into the bytes of a floor-plan file.
pub fn to_bytes(plan: &FloorPlan) -> Vec<u8> {
    let cells: Vec<u8> = plan
        .cells
        .iter()
        .flat_map(|c| c.iter().flat_map(|v| v.to_le_bytes()))
        .collect();
    let rows: Vec<u8> = plan.rows.iter().flat_map(|v| v.to_le_bytes()).collect();
    let features: Vec<u8> = plan
        .db
        .rows()
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let mut meta: HashMap<String, String> = [
        ("format", FORMAT.to_string()),
        ("version", VERSION.to_string()),
        ("resolution", format!("{:?}", plan.resolution)),
        ("origin_x", format!("{:?}", plan.origin[0])),
        ("origin_y", format!("{:?}", plan.origin[1])),
        ("floor_z", format!("{:?}", plan.floor_z)),
        ("band_min", format!("{:?}", plan.params.band_min)),
        ("band_max", format!("{:?}", plan.params.band_max)),
        ("feature_dim", plan.db.dim().to_string()),
        ("tau", format!("{:?}", plan.db.tau())),
        ("encoder", plan.encoder.clone()),
        ("cells", plan.len().to_string()),
        ("rows", plan.db.len().to_string()),
        ("writer", format!("omcl {}", env!("CARGO_PKG_VERSION"))),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let crc = checksum(&meta, [&cells, &rows, &features]);
    meta.insert("crc32".into(), format!("{crc:08x}"));
    let n = plan.len();
    let views = [
        ("cells", TensorView::new(Dtype::I32, vec![n, 2], &cells)),
        ("rows", TensorView::new(Dtype::U32, vec![n], &rows)),
        (
            "features",
            TensorView::new(Dtype::F32, vec![plan.db.len(), plan.db.dim()], &features),
        ),
    ];
    let views = views
        .into_iter()
        .map(|(n, v)| (n, v.expect("tensor sizes follow from the plan's lengths")));
    safetensors::serialize(views, Some(meta)).expect("a plan always has a valid safetensors layout")
}

/// Whether `path` is a floor-plan file, from its header alone.
pub fn is_plan_file(path: &Path) -> std::io::Result<bool> {
    super::file::is_container_of(path, FORMAT)
}

/// Writes `plan` to `path` atomically.
pub fn save(plan: &FloorPlan, path: &Path) -> Result<(), FloorPlanFileError> {
    crate::io::atomic::write(path, &to_bytes(plan)).map_err(|source| FloorPlanFileError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads a floor-plan file.
pub fn load(path: &Path) -> Result<FloorPlan, FloorPlanFileError> {
    let bytes =
        crate::io::bounded_read::read_regular(path).map_err(|source| FloorPlanFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    from_bytes(&bytes, path)
}

/// Parses the bytes of a floor-plan file; `path` names it in errors.
pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<FloorPlan, FloorPlanFileError> {
    use FloorPlanFileError as E;
    let p = || path.to_path_buf();
    let header = |e| E::from_header(path, e);
    let c = Container::open(bytes, FORMAT).map_err(header)?;
    let version = c.field("version").map_err(header)?;
    if version.parse::<u32>().ok() != Some(VERSION) {
        return Err(E::Version {
            path: p(),
            found: version.to_string(),
        });
    }
    let resolution = c.positive("resolution").map_err(header)?;
    let origin = [
        c.finite("origin_x").map_err(header)?,
        c.finite("origin_y").map_err(header)?,
    ];
    let floor_z = c.finite("floor_z").map_err(header)?;
    let params = FloorPlanParams {
        band_min: c.finite("band_min").map_err(header)?,
        band_max: c.finite("band_max").map_err(header)?,
    };
    let dim: usize = c
        .parse("feature_dim", "a positive integer", |d| *d > 0)
        .map_err(header)?;
    let tau: f32 = c
        .parse("tau", "a cosine distance in [0, 2]", |t: &f32| {
            (0.0..=2.0).contains(t)
        })
        .map_err(header)?;
    let n: usize = c.parse("cells", "an integer", |_| true).map_err(header)?;
    let k: usize = c.parse("rows", "an integer", |_| true).map_err(header)?;
    let stored = c.crc32().map_err(header)?;
    let encoder = c.field("encoder").map_err(header)?.to_string();
    let cells_b = c.tensor("cells", Dtype::I32, &[n, 2]).map_err(header)?;
    let rows_b = c.tensor("rows", Dtype::U32, &[n]).map_err(header)?;
    let feat_b = c
        .tensor("features", Dtype::F32, &[k, dim])
        .map_err(header)?;
    let computed = checksum(&c.meta, [cells_b, rows_b, feat_b]);
    if computed != stored {
        return Err(E::Container {
            path: p(),
            problem: ContainerProblem::Checksum { stored, computed },
        });
    }
    let i32s = le_4(cells_b, i32::from_le_bytes);
    let cells: Vec<[i32; 2]> = i32s.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
    let rows = le_4(rows_b, u32::from_le_bytes);
    let feats = le_4(feat_b, f32::from_le_bytes);
    let invalid = |source: FloorPlanError| E::Invalid { path: p(), source };
    let db = FeatureDb::from_rows(dim, tau, feats).map_err(|e| invalid(e.into()))?;
    FloorPlan::from_parts(
        resolution, origin, floor_z, params, db, encoder, cells, rows,
    )
    .map_err(invalid)
}

super::container::header_errors!(FloorPlanFileError);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::features::dot;

    fn grid() -> GridSpec {
        GridSpec {
            resolution: 0.5,
            origin: Vector3::new(1.0, -2.0, 0.0),
        }
    }

    /// A hand-made map at 0.5 m: a floor layer (z index 0, bottom at 0 m)
    /// under everything, a wall column at (0, 0) of row 1 over z 1..=3, a
    /// column at (2, 1) with row 1 at z 1 and row 2 at z 2 and z 3, and a
    /// ceiling (row 3) at z 5 over (0, 0). Band 0.6 to 2.0 m: centres 0.75,
    /// 1.25, 1.75 (z 1..=3) are in; the floor (0.25) and ceiling (2.75) are
    /// out.
    fn hand_map() -> LanguageMap {
        let rows = vec![
            1.0, 0.0, 0.0, // 0 floor
            0.0, 1.0, 0.0, // 1 wall
            0.0, 0.0, 1.0, // 2 shelf
            0.6, 0.0, 0.8, // 3 ceiling
        ];
        let db = FeatureDb::from_rows(3, 0.05, rows).unwrap();
        let mut leaves = vec![];
        for i in 0..4 {
            for j in 0..3 {
                leaves.push(([i, j, 0], 0));
            }
        }
        for z in 1..=3 {
            leaves.push(([0, 0, z], 1));
        }
        leaves.push(([2, 1, 1], 1));
        leaves.push(([2, 1, 2], 2));
        leaves.push(([2, 1, 3], 2));
        leaves.push(([0, 0, 5], 3));
        LanguageMap::from_cells(grid(), db, "hand", leaves).unwrap()
    }

    fn band() -> FloorPlanParams {
        FloorPlanParams {
            band_min: 0.6,
            band_max: 2.0,
        }
    }

    #[test]
    fn averaging_a_hand_made_map_gives_the_known_plan() {
        let plan = FloorPlan::from_map(&hand_map(), &band()).unwrap();
        assert_eq!(plan.floor_z, 0.0);
        assert_eq!(plan.origin, [1.0, -2.0]);
        // Two occupied columns, (j, i) order: (0, 0) then (2, 1).
        assert_eq!(plan.cells(), &[[0, 0], [2, 1]]);
        // (0, 0): three wall leaves: the wall's direction.
        let a = plan.db().row(plan.rows()[0] as usize);
        assert!((a[0]).abs() < 1e-6 && (a[1] - 1.0).abs() < 1e-6 && a[2].abs() < 1e-6);
        // (2, 1): one wall + two shelf leaves: (0, 1, 2) / sqrt 5.
        let b = plan.db().row(plan.rows()[1] as usize);
        let s = 5f32.sqrt();
        assert!(
            b[0].abs() < 1e-6 && (b[1] - 1.0 / s).abs() < 1e-6 && (b[2] - 2.0 / s).abs() < 1e-6
        );
        assert_eq!(plan.db().len(), 2);
        assert_eq!(plan.row_at([2, 1]), Some(plan.rows()[1]));
        assert_eq!(plan.row_at([1, 1]), None);
        // A band holding only the floor layer is an error; so is an empty one.
        let floor_only = FloorPlanParams {
            band_min: 3.5,
            band_max: 4.0,
        };
        assert_eq!(
            FloorPlan::from_map(&hand_map(), &floor_only),
            Err(FloorPlanError::EmptyBand(3.5, 4.0))
        );
        assert!(matches!(
            FloorPlan::from_map(
                &hand_map(),
                &FloorPlanParams {
                    band_min: 1.0,
                    band_max: 1.0
                }
            ),
            Err(FloorPlanError::BadBand(..))
        ));
    }

    /// A map with one voxel far from the rest (an outlier of a cloud) is
    /// refused by name before any dense grid is made; its image would
    /// have overflowed 32 bits.
    #[test]
    fn a_plan_spanning_too_many_cells_is_refused() {
        let m = hand_map();
        let mut leaves: Vec<([i32; 3], u32)> = m
            .cells()
            .iter()
            .copied()
            .zip(m.rows().iter().copied())
            .collect();
        leaves.push(([1 << 19, 1 << 19, 1], 1));
        let far = LanguageMap::from_cells(grid(), m.db().clone(), "hand", leaves).unwrap();
        let e = FloorPlan::from_map(&far, &band()).unwrap_err();
        assert!(matches!(e, FloorPlanError::TooLarge { .. }), "{e}");
        assert!(e.to_string().contains("outlier"), "{e}");
        // The same columns a little apart are a plan, and its image is
        // one pixel a cell.
        let plan = FloorPlan::from_map(&hand_map(), &band()).unwrap();
        let (w, h, rgb) = plan.image();
        assert_eq!((w, h, rgb.len()), (3, 2, 18));
        // A name with control characters (a plan file's) is refused.
        let db = hand_map().db().clone();
        let e = FloorPlan::from_parts(0.5, [0.0; 2], 0.0, band(), db, "a\x1b[2Jb", vec![], vec![]);
        assert!(matches!(e, Err(FloorPlanError::BadEncoderName(_))), "{e:?}");
    }

    /// The hand-made map's columns plus a low one (a table top at z 1 of
    /// (3, 2)) and a hanging one (a cabinet at z 3 of (1, 2)); band 0.6 to
    /// 2.0 m at 0.5 m cells, so bottoms within 1.1 m stand on the floor and
    /// tops from 1.5 m reach the ceiling.
    #[test]
    fn column_extents_and_ceiling_by_hand() {
        let m = hand_map();
        let mut leaves: Vec<_> = m
            .cells()
            .into_iter()
            .zip(m.rows().iter().copied())
            .collect();
        leaves.push(([3, 2, 1], 2));
        leaves.push(([1, 2, 3], 2));
        let m = LanguageMap::from_cells(*m.grid(), m.db().clone(), "hand", leaves).unwrap();
        let plan = FloorPlan::from_map(&m, &band()).unwrap();
        assert_eq!(plan.cells(), &[[0, 0], [2, 1], [1, 2], [3, 2]]);
        let inf = f32::INFINITY;
        assert_eq!(
            plan.column_extents(&m),
            vec![[-inf, inf], [-inf, inf], [1.5, inf], [-inf, 1.0]]
        );
        // The highest layer, z 5, starts at 2.5 m.
        assert_eq!(plan.ceiling_height(&m), Some(2.5));
    }

    /// Columns reaching the band's top end where their leaves above it
    /// end: the hand-made map's columns under a ceiling at z 7 (3.5 m) with
    /// the wall (0, 0) going on up to it over z 4 and z 6 (a one-cell hole
    /// at z 5 is bridged), the column (2, 1) ending at the band's top (a
    /// wardrobe under a higher ceiling), a hanging cabinet at z 3 of
    /// (1, 2), and a column at (3, 2) over z 1..=3 with one more leaf two
    /// cells above (at z 6: not part of it).
    #[test]
    fn columns_end_where_their_leaves_above_the_band_end() {
        let m = hand_map();
        let mut leaves: Vec<_> = m
            .cells()
            .into_iter()
            .zip(m.rows().iter().copied())
            .filter(|(c, _)| c[2] != 5)
            .collect();
        leaves.extend([
            ([0, 0, 4], 1),
            ([0, 0, 6], 1),
            ([0, 0, 7], 3),
            ([1, 2, 3], 2),
            ([3, 2, 1], 1),
            ([3, 2, 2], 1),
            ([3, 2, 3], 1),
            ([3, 2, 6], 2),
        ]);
        let m = LanguageMap::from_cells(*m.grid(), m.db().clone(), "hand", leaves).unwrap();
        let plan = FloorPlan::from_map(&m, &band()).unwrap();
        assert_eq!(plan.cells(), &[[0, 0], [2, 1], [1, 2], [3, 2]]);
        assert_eq!(plan.ceiling_height(&m), Some(3.5));
        let inf = f32::INFINITY;
        assert_eq!(
            plan.column_extents(&m),
            vec![[-inf, inf], [-inf, 2.0], [1.5, 2.0], [-inf, 2.0]]
        );
    }

    /// The hand-made map's floor and ceiling per column: every one of the
    /// 12 floor cells (z 0, centre 0.25 m, below the 0.6 m band) holds the
    /// floor row once; the ceiling (row 3 at z 5, the top layer) is over
    /// (0, 0) only. A leaf in the top layer but inside the band is no
    /// ceiling, and a second floor leaf in a column adds to its sum.
    #[test]
    fn floor_and_ceiling_per_column_by_hand() {
        let m = hand_map();
        let plan = FloorPlan::from_map(&m, &band()).unwrap();
        let [floor, ceiling] = plan.surface_features(&m);
        assert_eq!(floor.len(), 12);
        assert_eq!(floor[0].0, [0, 0]);
        assert_eq!(floor[11].0, [3, 2]);
        assert!(
            floor
                .windows(2)
                .all(|w| (w[0].0[1], w[0].0[0]) < (w[1].0[1], w[1].0[0]))
        );
        assert!(floor.iter().all(|(_, f)| f == &[1.0, 0.0, 0.0]));
        assert_eq!(ceiling, vec![([0, 0], vec![0.6, 0.0, 0.8])]);
        // A map whose top layer is in the band has no ceiling; a second
        // leaf below the band (a rug, row 2 at z 0 would clash, so the
        // band starts higher) adds to the column's floor.
        let mut leaves: Vec<_> = m
            .cells()
            .into_iter()
            .zip(m.rows().iter().copied())
            .filter(|(c, _)| c[2] < 5)
            .collect();
        leaves.push(([1, 1, 1], 2));
        let m = LanguageMap::from_cells(*m.grid(), m.db().clone(), "hand", leaves).unwrap();
        let high = FloorPlanParams {
            band_min: 1.0,
            band_max: 2.0,
        };
        let plan = FloorPlan::from_map(&m, &high).unwrap();
        let [floor, ceiling] = plan.surface_features(&m);
        assert!(ceiling.is_empty());
        let rug = floor.iter().find(|(c, _)| *c == [1, 1]).unwrap();
        assert_eq!(rug.1, vec![1.0, 0.0, 1.0]);
        // (0, 0)'s wall leaf at z 1 (centre 0.75 m) is below this band too.
        let wall = floor.iter().find(|(c, _)| *c == [0, 0]).unwrap();
        assert_eq!(wall.1, vec![1.0, 1.0, 0.0]);
    }

    /// The hand-made map's slabs per occupied column: [0.6, 1.0) m holds
    /// the leaves at z 1 (centre 0.75): the wall row in both columns;
    /// [1.5, 3.0) the leaves at z 3 (centre 1.75), the wall's and the
    /// shelf's, but not the ceiling at z 5 (the top layer); [0, 1.5) sums
    /// z 0 to 2 of the occupied columns only (the floor under the 10 free
    /// ones is left out).
    #[test]
    fn slabs_per_occupied_column_by_hand() {
        let m = hand_map();
        let plan = FloorPlan::from_map(&m, &band()).unwrap();
        let base = plan.slab_features(&m, 0.6, 1.0);
        assert_eq!(
            base,
            vec![([0, 0], vec![0.0, 1.0, 0.0]), ([2, 1], vec![0.0, 1.0, 0.0])]
        );
        let top = plan.slab_features(&m, 1.5, 3.0);
        assert_eq!(
            top,
            vec![([0, 0], vec![0.0, 1.0, 0.0]), ([2, 1], vec![0.0, 0.0, 1.0])]
        );
        let low = plan.slab_features(&m, 0.0, 1.5);
        assert_eq!(
            low,
            vec![([0, 0], vec![1.0, 2.0, 0.0]), ([2, 1], vec![1.0, 1.0, 1.0])]
        );
        assert!(plan.slab_features(&m, 2.0, 2.5).is_empty());
    }

    #[test]
    fn tau_merges_columns_whose_averages_are_close() {
        // With tau 0.2 the blend (0, 1, 2)/sqrt 5 is 0.553 from the wall
        // (cos 0.447): kept apart; with tau 0.6 it merges into the wall row.
        let m = hand_map();
        let loose = LanguageMap::from_cells(
            *m.grid(),
            FeatureDb::from_rows(3, 0.6, m.db().rows().to_vec()).unwrap(),
            "hand",
            m.cells().into_iter().zip(m.rows().iter().copied()),
        )
        .unwrap();
        let plan = FloorPlan::from_map(&loose, &band()).unwrap();
        assert_eq!(plan.db().len(), 1);
        assert_eq!(plan.rows(), &[0, 0]);
        assert!((dot(plan.db().row(0), &[0.0, 1.0, 0.0]) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn the_one_layer_map_keeps_columns_and_rows() {
        let plan = FloorPlan::from_map(&hand_map(), &band()).unwrap();
        let m = plan.to_language_map().unwrap();
        assert_eq!(m.len(), 2);
        assert_eq!(m.grid().origin, Vector3::new(1.0, -2.0, 0.0));
        for (c, r) in m.cells().iter().zip(m.rows()) {
            assert_eq!(c[2], 0);
            assert_eq!(plan.row_at([c[0], c[1]]), Some(*r));
        }
        let (w, h, rgb) = plan.image();
        assert_eq!((w, h), (3, 2));
        // Top-left pixel is column (0, 1): free, white; bottom-left (0, 0).
        assert_eq!(&rgb[0..3], &[255, 255, 255]);
        assert_eq!(&rgb[9..12], &row_colour(plan.rows()[0]));
    }

    #[test]
    fn file_round_trip_and_corruption_refused() {
        let plan = FloorPlan::from_map(&hand_map(), &band()).unwrap();
        let path = Path::new("plan.omclplan");
        let bytes = to_bytes(&plan);
        assert_eq!(from_bytes(&bytes, path).unwrap(), plan);
        // A flipped byte in the last feature value: checksum error.
        let mut bad = bytes.clone();
        let n = bad.len();
        bad[n - 2] ^= 0x40;
        assert!(matches!(
            from_bytes(&bad, path),
            Err(FloorPlanFileError::Container {
                problem: ContainerProblem::Checksum { .. },
                ..
            })
        ));
        // A future version is refused by name.
        let find = |pat: &[u8]| bytes.windows(pat.len()).position(|w| w == pat).unwrap();
        let at = find(b"\"version\":\"1\"");
        let mut future = bytes.clone();
        future[at + 11] = b'9';
        let e = from_bytes(&future, path).unwrap_err();
        assert!(matches!(e, FloorPlanFileError::Version { .. }), "{e}");
        assert!(e.to_string().contains("plan.omclplan") && e.to_string().contains("version 9"));
        // A 3-D map file is not a plan.
        let map_bytes = crate::map::file::to_bytes(&hand_map());
        assert!(matches!(
            from_bytes(&map_bytes, path),
            Err(FloorPlanFileError::Foreign { .. })
        ));
        // A changed origin digit is caught by the header checksum.
        let at = find(b"\"origin_x\":\"1.0\"");
        let mut moved = bytes.clone();
        moved[at + 12] = b'3';
        assert!(matches!(
            from_bytes(&moved, path),
            Err(FloorPlanFileError::Container {
                problem: ContainerProblem::Checksum { .. },
                ..
            })
        ));
    }
}
