//! Clouds mapped a batch of points at a time (`omcl map cloud FILE.laz`
//! or `omcl map cloud TILES/`): a LAS/LAZ file of any size, or a folder of
//! LAS/LAZ or PLY tiles of one survey, in the memory of the map being
//! built and one batch (a LAS batch, or one PLY tile read whole), never the
//! whole cloud (read whole, a cloud takes about 60 bytes a point: 10^9
//! points would not fit).
//!
//! As for a SemanticKITTI sequence ([`super::pipeline::map_from_sequence`]),
//! two passes: the first reads every point for the centre of the kept
//! points (the grid's origin, [`OriginEstimate`]), the second integrates
//! them batch by batch. The points, their order and the grid are those of
//! the whole-file path (`map_from_cloud(load_cloud(..))`) on the same file,
//! or on the tiles merged in file-name order, so the map is the same, bit
//! for bit, wherever a voxel sees at most [`crate::map::integrate::SLOTS`] classes; a
//! voxel that sees more keeps its heaviest rows by the integrator's
//! space-saving sketch, whose pick may depend on where the batches are cut
//! (as for a sequence read scan by scan).
//! Labels become rows through the class table (LAS classification codes,
//! PLY label properties); per-point features (`--features`, PLY feature
//! properties) and point encoders need the whole cloud and take the
//! whole-file path.

use std::path::{Path, PathBuf};

use super::IntegrationStats;
use super::pipeline::{BuildParams, LabelRows, OriginEstimate, PipelineError, SequencePass};
use crate::io::cloud::{CloudError, check_points};
use crate::io::labels::EmbeddingTable;
use crate::io::las::{CrsRecords, LasChunk, LasChunks, is_asprs_noise, withheld_note};
use crate::io::ply::{PlyOptions, read_ply_with};
use crate::map::{FeatureDb, Georef, Integrator, LanguageMap};

/// The kind of files a [`TileSource`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TileKind {
    /// LAS/LAZ, read a batch of points at a time.
    Las,
    /// PLY, a tile read whole at a time.
    Ply,
}

/// One LAS/LAZ file or a folder of tiles, their headers checked.
#[derive(Debug, Clone)]
pub struct TileSource {
    name: String,
    /// A folder of tiles, not a file.
    folder: bool,
    kind: TileKind,
    files: Vec<PathBuf>,
    declared: u64,
    notes: Vec<String>,
    georef: Option<Georef>,
}

/// The point-cloud files of folder `dir` in name order, when they are all
/// LAS/LAZ (`.las`, `.laz`) or all PLY, and `dir` is not a KITTI sequence
/// (`calib.txt`); `None` otherwise (no such files, or both kinds). Hidden
/// files (a name starting with a dot, such as macOS's `._tile.las`),
/// subfolders and links to nothing are not tiles ([`TileSource::open`]
/// names them in a note).
pub fn cloud_tiles(dir: &Path) -> Option<(TileKind, Vec<PathBuf>)> {
    scan(dir)?.tiles()
}

/// What a tile folder holds.
struct Scan {
    las: Vec<PathBuf>,
    ply: Vec<PathBuf>,
    /// Entries not read, each with why.
    skipped: Vec<String>,
}

impl Scan {
    /// The tiles, when they are of one kind.
    fn tiles(self) -> Option<(TileKind, Vec<PathBuf>)> {
        match (self.las.is_empty(), self.ply.is_empty()) {
            (false, true) => Some((TileKind::Las, self.las)),
            (true, false) => Some((TileKind::Ply, self.ply)),
            _ => None,
        }
    }
}

fn scan(dir: &Path) -> Option<Scan> {
    if !dir.is_dir() || dir.join("calib.txt").exists() {
        return None;
    }
    let (mut las, mut ply) = (Vec::new(), Vec::new());
    let (mut hidden, mut folders, mut dangling) = (Vec::new(), Vec::new(), Vec::new());
    for e in std::fs::read_dir(dir).ok()?.flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        let ext = p
            .extension()
            .and_then(|x| x.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let cloud = matches!(ext.as_str(), "las" | "laz" | "ply");
        if p.is_dir() {
            folders.push(format!("{name}/"));
        } else if !cloud {
        } else if name.starts_with('.') {
            hidden.push(name);
        } else if !p.is_file() {
            dangling.push(name);
        } else if ext == "ply" {
            ply.push(p);
        } else {
            las.push(p);
        }
    }
    las.sort();
    ply.sort();
    // A link to a tile already listed (the same file twice would count its
    // points twice): the first name in order is read.
    let mut twice = Vec::new();
    for list in [&mut las, &mut ply] {
        let mut seen = std::collections::HashSet::new();
        list.retain(|p| {
            let fresh = std::fs::canonicalize(p).map_or(true, |c| seen.insert(c));
            if !fresh {
                twice.push(
                    p.file_name()
                        .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
                );
            }
            fresh
        });
    }
    let mut skipped = Vec::new();
    for (mut v, why) in [
        (hidden, "hidden files"),
        (folders, "subfolders are not read"),
        (dangling, "links to nothing"),
        (twice, "the same file as a tile before them"),
    ] {
        if !v.is_empty() {
            v.sort();
            let n = v.len();
            v.truncate(5);
            let more = if n > 5 {
                format!(" and {} more", n - 5)
            } else {
                String::new()
            };
            skipped.push(format!("{}{more} ({why})", v.join(", ")));
        }
    }
    Some(Scan { las, ply, skipped })
}

impl TileSource {
    /// A `.las`/`.laz` file, or a folder of tiles ([`cloud_tiles`]). LAS
    /// headers are checked against their file's size and read for their
    /// units, and LAS tiles must state the same coordinate reference
    /// system (the same `LASF_Projection` records), since each counts its
    /// coordinates in that system. PLY tiles state none: they are taken to
    /// share one frame, in metres.
    pub fn open(path: &Path) -> Result<Self, PipelineError> {
        let name = path.display().to_string();
        let (kind, files, skipped) = if path.is_dir() {
            let s = scan(path);
            let skipped = s.as_ref().map(|s| s.skipped.clone()).unwrap_or_default();
            let (kind, files) = s.and_then(Scan::tiles).ok_or_else(|| {
                PipelineError::Input(format!(
                    "{name}: no tiles in this folder (.las and .laz, or .ply, not both)"
                ))
            })?;
            (kind, files, skipped)
        } else {
            (TileKind::Las, vec![path.to_path_buf()], Vec::new())
        };
        let mut notes: Vec<String> = skipped
            .iter()
            .map(|s| format!("{name}: not read as tiles: {s}"))
            .collect();
        if kind == TileKind::Ply {
            // Read in the passes; a tile a batch.
            return Ok(Self {
                name,
                folder: path.is_dir(),
                kind,
                declared: files.len() as u64,
                files,
                notes,
                georef: None,
            });
        }
        let mut declared = 0u64;
        let mut converted = false;
        let mut first: Option<(PathBuf, CrsRecords)> = None;
        let mut georef = None;
        for f in &files {
            let r = LasChunks::open(f)?;
            declared = declared.saturating_add(r.declared());
            match &first {
                None => {
                    converted = !r.notes().is_empty();
                    notes.extend(r.notes().iter().cloned());
                    first = Some((f.clone(), r.crs_records().to_vec()));
                    georef = r.georef().cloned();
                }
                Some((f0, crs)) if crs.as_slice() != r.crs_records() => {
                    return Err(PipelineError::Input(format!(
                        "{name}: its tiles state different coordinate reference systems: {} \
                         and {} ({}); map the tiles of one CRS together (reproject the others \
                         first, e.g. with PDAL or LAStools)",
                        f0.display(),
                        f.display(),
                        crs_difference(crs, r.crs_records())
                    )));
                }
                Some(_) => {}
            }
        }
        if files.len() > 1 && converted {
            notes.push(format!(
                "{name}: its other {} tiles state the same CRS and were converted the same way",
                files.len() - 1
            ));
        }
        Ok(Self {
            name,
            folder: path.is_dir(),
            kind,
            files,
            declared,
            notes,
            georef,
        })
    }

    /// The kind of its files.
    pub fn kind(&self) -> TileKind {
        self.kind
    }

    /// What progress counts: LAS point records, or PLY tiles.
    pub fn unit(&self) -> &'static str {
        match self.kind {
            TileKind::Las => "points",
            TileKind::Ply => "tiles",
        }
    }

    /// The files, in the order their points are read.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// The length of the passes: point records the LAS headers declare
    /// (withheld ones included), or PLY tiles.
    pub fn declared(&self) -> u64 {
        self.declared
    }

    /// What was converted on the way (units), one line each.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The CRS its (first) LAS tile states, which the others share;
    /// `None` for PLY tiles and LAS without one.
    pub fn georef(&self) -> Option<&Georef> {
        self.georef.as_ref()
    }
}

/// Which projection record differs between two tiles' (their governing
/// records, [`LasChunks::crs_records`]), in words.
fn crs_difference(a: &[(u16, Vec<u8>)], b: &[(u16, Vec<u8>)]) -> String {
    let what = |id: u16| match id {
        2112 => "the WKT record 2112 differs",
        34735 => "the GeoTIFF keys (record 34735) differ",
        34736 => "the GeoTIFF doubles (record 34736) differ",
        _ => "a projection record differs",
    };
    let ids = |c: &[(u16, Vec<u8>)]| c.iter().map(|(id, _)| *id).collect::<Vec<_>>();
    if ids(a) != ids(b) {
        let name = |c: &[(u16, Vec<u8>)]| match ids(c).first() {
            None => "no CRS record".to_string(),
            Some(2112) => "a WKT record".to_string(),
            Some(_) => "GeoTIFF keys".to_string(),
        };
        return format!("the first states {}, the second {}", name(a), name(b));
    }
    let id = a
        .iter()
        .zip(b)
        .find(|(x, y)| x != y)
        .map_or(0, |(x, _)| x.0);
    what(id).to_string()
}

/// How the points of a [`TileSource`] are read.
#[derive(Debug, Clone)]
pub struct TileOptions {
    /// LAS: keep ASPRS noise (classes 7 and 18).
    pub keep_all: bool,
    /// LAS: points decoded a batch, at most
    /// ([`LasChunks::with_batch_points`]).
    pub batch_points: u64,
    /// PLY: the vertex property holding the labels
    /// ([`PlyOptions::label_property`]).
    pub label_property: Option<String>,
}

impl Default for TileOptions {
    fn default() -> Self {
        Self {
            keep_all: false,
            batch_points: u64::MAX,
            label_property: None,
        }
    }
}

/// What a pass left out, for the notes.
#[derive(Debug, Default)]
struct LeftOut {
    withheld: u64,
    withheld_files: usize,
    noise: u64,
    /// Per file, the points kept before noise (a single file without any
    /// is an error, as read whole).
    kept: Vec<u64>,
    /// Per file, the points mapped (after noise; a tile without any is
    /// named in a note).
    mapped: Vec<u64>,
    /// The PLY readers' notes (vertices left out, float precision).
    read: Vec<String>,
}

/// Reads every batch of `src`, the kept points (withheld and, unless
/// `keep_all`, noise left out) handed to `each` with their labels, in the
/// file order; `progress(records read, declared)` after each batch.
fn each_batch(
    src: &TileSource,
    opts: &TileOptions,
    mut progress: impl FnMut(u64, u64),
    mut each: impl FnMut(&[[f64; 3]], &[u32]),
) -> Result<LeftOut, PipelineError> {
    if src.kind == TileKind::Ply {
        return each_ply_tile(src, opts, progress, each);
    }
    let mut left = LeftOut::default();
    let mut done = 0u64;
    let (mut pts, mut labels) = (Vec::new(), Vec::new());
    for f in &src.files {
        let mut r = LasChunks::open(f)?.with_batch_points(opts.batch_points);
        let name = f.display().to_string();
        let withheld_before = left.withheld;
        let (mut kept, mut mapped) = (0u64, 0u64);
        while let Some(c) = r.next_chunk()? {
            let LasChunk {
                first_kept,
                points,
                labels: classes,
                withheld,
                ..
            } = c;
            check_points(&name, &points, first_kept)?;
            left.withheld += withheld.len() as u64;
            kept += points.len() as u64;
            pts.clear();
            labels.clear();
            for (p, &l) in points.iter().zip(&classes) {
                if opts.keep_all || !is_asprs_noise(l) {
                    pts.push(*p);
                    labels.push(l);
                }
            }
            left.noise += (points.len() - pts.len()) as u64;
            mapped += pts.len() as u64;
            each(&pts, &labels);
            progress(done + r.read(), src.declared);
        }
        done += r.declared();
        if left.withheld > withheld_before {
            left.withheld_files += 1;
        }
        left.kept.push(kept);
        left.mapped.push(mapped);
    }
    Ok(left)
}

/// [`each_batch`] of PLY tiles: a tile read whole at a time, its labels
/// required (and no feature properties: those are mapped from the whole
/// file).
fn each_ply_tile(
    src: &TileSource,
    opts: &TileOptions,
    mut progress: impl FnMut(u64, u64),
    mut each: impl FnMut(&[[f64; 3]], &[u32]),
) -> Result<LeftOut, PipelineError> {
    let mut left = LeftOut::default();
    let ply = PlyOptions {
        label_property: opts.label_property.clone(),
    };
    for (i, f) in src.files.iter().enumerate() {
        let c = match read_ply_with(f, &ply) {
            Ok(c) => c,
            // A tile with no point to map is noted, as an empty LAS tile.
            Err(CloudError::Empty {
                source_name,
                reason,
            }) => {
                left.kept.push(0);
                left.mapped.push(0);
                left.read.push(format!("{source_name}: {reason}"));
                progress(i as u64 + 1, src.declared);
                continue;
            }
            Err(e) => return Err(e.into()),
        };
        let why = if c.features.is_some() {
            Some(
                "carries feature properties (f0 or feat_0, ...), which are mapped from one \
                 file",
            )
        } else if c.labels.is_none() {
            Some(
                "carries no labels (a property label, class, classification, semantic or \
                 semantic_label, or another one named with --label-property)",
            )
        } else {
            None
        };
        if let Some(why) = why {
            return Err(PipelineError::Input(format!(
                "{}: this tile {why}; a folder of tiles is mapped from its labels through the \
                 class table (map the tile alone, or merge the tiles first)",
                f.display()
            )));
        }
        let labels = c.labels.as_deref().unwrap_or_default();
        left.kept.push(c.len() as u64);
        left.mapped.push(c.len() as u64);
        left.read.extend(c.notes.iter().cloned());
        each(&c.points, labels);
        progress(i as u64 + 1, src.declared);
    }
    Ok(left)
}

/// Builds the map of `src` (module page): labels through `table` (a
/// class table is required: the points carry class codes).
/// `progress(pass, records read, records declared)` after every batch.
/// Returns the map, the integration's counts and notes on what was left
/// out.
pub fn map_from_tiles(
    src: &TileSource,
    opts: &TileOptions,
    params: &BuildParams,
    table: Option<&EmbeddingTable>,
    progress: &mut dyn FnMut(SequencePass, u64, u64),
) -> Result<(LanguageMap, IntegrationStats, Vec<String>), PipelineError> {
    let name = &src.name;
    let Some(table) = table else {
        return Err(PipelineError::Input(format!(
            "{name}: points carry labels but no class table was given: pass --classes asprs \
             (LAS codes) or semantickitti, or a class list file with --embeddings NPY or \
             --text-model ONNX"
        )));
    };
    let mut origin = OriginEstimate::default();
    let left = each_batch(
        src,
        opts,
        |done, total| progress(SequencePass::Bounds, done, total),
        |pts, _| origin.add(pts),
    )?;
    let notes = left_out_notes(src, &left)?;
    let centre = origin.finish(params.resolution).ok_or_else(|| {
        let why = if notes.is_empty() {
            String::new()
        } else {
            format!(" ({})", notes.join("; "))
        };
        PipelineError::Input(format!(
            "{name}: empty result: no points left to map{why}; no map written"
        ))
    })?;
    let mut integ = Integrator::new(
        centre.grid,
        FeatureDb::from_rows(table.dim, params.tau, table.data.clone())?,
    )?
    .keeping(params.keep(&centre));
    let mut stats = IntegrationStats::default();
    let mut rows = LabelRows::new(table);
    each_batch(
        src,
        opts,
        |done, total| progress(SequencePass::Mapping, done, total),
        |pts, labels| {
            stats += super::cloud::integrate_point_rows(&mut integ, pts, rows.rows(labels));
        },
    )?;
    rows.check(name, &stats)?;
    let map = super::pipeline::finish(integ, &params.encoder, params.tau, &stats)?
        .with_georef(src.georef.clone());
    Ok((map, stats, notes))
}

/// The notes on withheld and noise points, or the error of a single file
/// with no point left (as the whole-file reader words it).
fn left_out_notes(src: &TileSource, left: &LeftOut) -> Result<Vec<String>, PipelineError> {
    let name = &src.name;
    let tiles = src.files.len();
    let kept: u64 = left.kept.iter().sum();
    // A file given alone, not a folder of one tile.
    if !src.folder && kept == 0 {
        let reason = if left.withheld > 0 {
            format!("all {} points are flagged withheld (deleted)", src.declared)
        } else {
            "the file holds no points".to_string()
        };
        return Err(CloudError::Empty {
            source_name: name.clone(),
            reason,
        }
        .into());
    }
    let mut notes = left.read.clone();
    if left.withheld > 0 {
        let mut n = withheld_note(name, left.withheld, src.declared);
        if tiles > 1 {
            n.push_str(&format!(
                " ({} of its {tiles} tiles have some)",
                left.withheld_files
            ));
        }
        notes.push(n);
    }
    if tiles > 1 {
        let empty: Vec<String> = src
            .files
            .iter()
            .zip(&left.mapped)
            .filter(|(_, k)| **k == 0)
            .map(|(f, _)| f.display().to_string())
            .collect();
        if !empty.is_empty() {
            notes.push(format!(
                "{name}: {} of its {tiles} tiles hold no point to map: {}",
                empty.len(),
                empty.join(", ")
            ));
        }
    }
    if left.noise > 0 {
        notes.push(format!(
            "{name}: {} noise (ASPRS classes 7 and 18) points left out (--keep-all keeps them)",
            left.noise
        ));
    }
    Ok(notes)
}
