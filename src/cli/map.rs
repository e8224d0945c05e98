//! `omcl map ...`: build, inspect, ground, query and export maps.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};

use omcl::map::{LanguageMap, file};

pub use super::map_build::{CloudArgs, ExportArgs, GroundArgs, QueryArgs, RgbdArgs};

#[derive(Debug, Subcommand)]
pub enum MapCommand {
    /// Print a map file's header and statistics.
    Info(InfoArgs),
    /// Build a map from posed RGB-D frames (input option 1).
    Rgbd(RgbdArgs),
    /// Build a map from a point cloud: PLY, LAS/LAZ, a KITTI/SemanticKITTI
    /// sequence folder or scan, or a ScanNet .bin (input option 2).
    Cloud(CloudArgs),
    /// Ground a map on prompt words: rows become the words' features, voxels
    /// whose best similarity is below a threshold are dropped.
    Ground(GroundArgs),
    /// Write the voxels coloured by similarity to words (heat map) as PLY or
    /// LAS/LAZ (by the extension).
    Query(QueryArgs),
    /// Write the voxels coloured by feature row as PLY or LAS/LAZ (by the
    /// extension).
    Export(ExportArgs),
    /// Convert a map file of an older format version (1: checksum over the
    /// data only) into the current one (3: header values checksummed too,
    /// room for the survey's CRS, which an old file cannot give: rebuild it
    /// from the survey for that; version 2 files read as they are).
    Upgrade(UpgradeArgs),
    /// Project a map to a floor plan: features averaged along the vertical
    /// over a height band into a 2-D grid (Table I's 2-D block), written as
    /// a versioned file and optionally a PNG.
    Floorplan(super::map_floorplan::FloorplanArgs),
    /// Print a class list (built in: semantickitti, asprs) or write it with
    /// its features as classes.txt + embeddings.npy, the table a sequence
    /// folder's label images need
    Classes(super::map_build::ClassesArgs),
    /// Project a labelled SemanticKITTI sequence (its aggregated LiDAR
    /// labels) into camera 2 at every pose: ground-truth label images
    /// labels_2/NNNNNN.png for `omcl localize` (z-buffer, splats sized to
    /// the point spacing), plus the built-in class table if none is there
    Project(super::map_build::ProjectArgs),
}

#[derive(Debug, Args)]
pub struct UpgradeArgs {
    /// The old map file; it is read and checked, never changed.
    pub file: PathBuf,
    /// Where to write the upgraded map (written atomically).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Replace --out even when it is a file that is not an omcl map (a map
    /// is replaced without it).
    #[arg(long)]
    pub force: bool,
}

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The map file (`.omcl`, safetensors), or a floor plan (`omcl map
    /// floorplan`'s `.plan`: its header, band, cells and rows).
    pub file: PathBuf,
    /// Print machine-readable JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also build the map's ray-casting scene (Embree voxel bricks, as
    /// `omcl localize` and `omcl serve` do) and report how long loading and
    /// building took and the process's peak memory.
    #[arg(long)]
    pub scene: bool,
    /// How many of the most used feature rows to list.
    #[arg(long, default_value_t = 10)]
    pub top: usize,
}

pub fn run(cmd: MapCommand) -> anyhow::Result<()> {
    match cmd {
        MapCommand::Info(a) => info(&a),
        MapCommand::Rgbd(a) => super::map_build::rgbd(&a),
        MapCommand::Cloud(a) => super::map_build::cloud(&a),
        MapCommand::Ground(a) => super::map_build::ground(&a),
        MapCommand::Query(a) => super::map_build::query(&a),
        MapCommand::Export(a) => super::map_build::export(&a),
        MapCommand::Floorplan(a) => super::map_floorplan::run(&a),
        MapCommand::Classes(a) => super::map_build::classes(&a),
        MapCommand::Project(a) => super::map_build::project(&a),
        MapCommand::Upgrade(a) => {
            super::outputs::refuse_overlaps(&[("--out", &a.out)], &[("the map", &a.file)])?;
            super::outputs::check_map_out("--out", &a.out, a.force)?;
            let map = file::upgrade(&a.file, &a.out)?;
            println!(
                "{} -> {} (format version {}, {} voxels, {} rows)",
                a.file.display(),
                a.out.display(),
                file::VERSION,
                map.len(),
                map.db().len()
            );
            Ok(())
        }
    }
}

/// Statistics of a map, as printed by `omcl map info`.
#[derive(Debug, serde::Serialize)]
pub struct MapInfo {
    pub file: String,
    pub file_bytes: u64,
    pub format: String,
    pub version: String,
    pub encoder: String,
    pub resolution_m: f64,
    pub origin_m: [f64; 3],
    pub feature_dim: usize,
    pub tau: f32,
    pub leaves: usize,
    pub rows: usize,
    pub bounds_min_m: Option<[f64; 3]>,
    pub bounds_max_m: Option<[f64; 3]>,
    pub memory_bytes: usize,
    pub top_rows: Vec<(usize, usize)>,
    /// For a map in a built-in class list's feature space: the classes
    /// each of `top_rows` stands for, in its order.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub top_row_classes: Option<Vec<super::encoders::RowClasses>>,
    pub unused_rows: usize,
    /// The survey's CRS, for a map built from one that states it.
    pub crs: Option<CrsInfo>,
}

/// A map's georeference, as `omcl map info` prints it.
#[derive(Debug, serde::Serialize)]
pub struct CrsInfo {
    /// The CRS in words, as the survey names it.
    pub name: String,
    /// Which record governs: "WKT" or "GeoTIFF".
    pub governing: &'static str,
    /// The CRS records kept (LAS record ids).
    pub records: Vec<u16>,
    /// Metres per survey unit: x and y, z.
    pub metres_per_unit: [f64; 2],
    /// The survey's units in words, with their size when not metres.
    pub survey_units: String,
}

pub fn map_info(path: &std::path::Path, map: &LanguageMap, top: usize) -> anyhow::Result<MapInfo> {
    let header = file::read_header(path)?;
    let g = map.grid();
    let bounds = map.world_bounds();
    let counts = map.row_counts();
    let mut ranked: Vec<(usize, usize)> = counts.iter().copied().enumerate().collect();
    ranked.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    let unused_rows = counts.iter().filter(|&&c| c == 0).count();
    ranked.truncate(top);
    let top_row_classes = super::encoders::builtin_row_classes(map)?
        .map(|(_, rows)| ranked.iter().map(|&(r, _)| rows[r].clone()).collect());
    Ok(MapInfo {
        file: path.display().to_string(),
        file_bytes: std::fs::metadata(path).map(|m| m.len()).unwrap_or(0),
        format: header.get("format").cloned().unwrap_or_default(),
        version: header.get("version").cloned().unwrap_or_default(),
        encoder: map.encoder().to_string(),
        resolution_m: g.resolution,
        origin_m: [g.origin.x, g.origin.y, g.origin.z],
        feature_dim: map.db().dim(),
        tau: map.db().tau(),
        leaves: map.len(),
        rows: map.db().len(),
        bounds_min_m: bounds.map(|b| b.0),
        bounds_max_m: bounds.map(|b| b.1),
        memory_bytes: map.memory_bytes(),
        top_rows: ranked,
        top_row_classes,
        unused_rows,
        crs: map.georef().map(|g| {
            let ids: Vec<u16> = g.records.iter().map(|r| r.0).collect();
            let [xy, z] = g.metres_per_unit;
            let words = |m: f64| {
                let w = omcl::io::las::unit_words(m);
                if m == 1.0 {
                    w
                } else {
                    format!("{w} (1 = {m} m)")
                }
            };
            CrsInfo {
                name: g.crs.clone(),
                governing: if g.wkt_governs() { "WKT" } else { "GeoTIFF" },
                records: ids,
                metres_per_unit: g.metres_per_unit,
                survey_units: if xy == z {
                    words(xy)
                } else {
                    format!("x, y in {}, z in {}", words(xy), words(z))
                },
            }
        }),
    })
}

/// What `omcl map info` prints of a floor plan.
#[derive(Debug, serde::Serialize)]
pub struct PlanInfo {
    pub file: String,
    pub file_bytes: u64,
    pub format: String,
    pub version: String,
    pub encoder: String,
    pub resolution_m: f64,
    pub origin_m: [f64; 2],
    pub floor_z_m: f64,
    /// The height band averaged, metres above the floor.
    pub band_m: [f64; 2],
    pub feature_dim: usize,
    pub tau: f32,
    pub cells: usize,
    pub rows: usize,
    /// World x, y of the occupied cells' bounding rectangle's corners.
    pub bounds_min_m: Option<[f64; 2]>,
    pub bounds_max_m: Option<[f64; 2]>,
    /// (row, cells) of the most used rows, most first.
    pub top_rows: Vec<(usize, usize)>,
}

fn plan_info(a: &InfoArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        !a.scene,
        "{}: a floor plan; --scene builds a 3-D map's Embree scene (a plan is cast in 2-D)",
        a.file.display()
    );
    let header = file::read_header(&a.file)?;
    let plan = omcl::map::floorplan::load(&a.file)?;
    let mut counts = vec![0usize; plan.db().len()];
    plan.rows().iter().for_each(|&r| counts[r as usize] += 1);
    let mut ranked: Vec<(usize, usize)> = counts.into_iter().enumerate().collect();
    ranked.sort_by(|x, y| y.1.cmp(&x.1).then(x.0.cmp(&y.0)));
    ranked.truncate(a.top);
    let (r, o) = (plan.resolution, plan.origin);
    let corner = |f: fn(i32, i32) -> i32, edge: i32| {
        plan.cells()
            .iter()
            .copied()
            .reduce(|p, c| [f(p[0], c[0]), f(p[1], c[1])])
            .map(|c| {
                [
                    o[0] + (c[0] + edge) as f64 * r,
                    o[1] + (c[1] + edge) as f64 * r,
                ]
            })
    };
    let i = PlanInfo {
        file: a.file.display().to_string(),
        file_bytes: std::fs::metadata(&a.file).map(|m| m.len()).unwrap_or(0),
        format: header.get("format").cloned().unwrap_or_default(),
        version: header.get("version").cloned().unwrap_or_default(),
        encoder: plan.encoder().to_string(),
        resolution_m: r,
        origin_m: o,
        floor_z_m: plan.floor_z,
        band_m: [plan.params.band_min, plan.params.band_max],
        feature_dim: plan.db().dim(),
        tau: plan.db().tau(),
        cells: plan.len(),
        rows: plan.db().len(),
        bounds_min_m: corner(i32::min, 0),
        bounds_max_m: corner(i32::max, 1),
        top_rows: ranked,
    };
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&i).context("serializing plan info")?
        );
        return Ok(());
    }
    let mut s = String::new();
    use std::fmt::Write as _;
    let _ = writeln!(s, "file         {} ({} bytes)", i.file, i.file_bytes);
    let _ = writeln!(
        s,
        "format       {} v{} (a floor plan, checksum ok)",
        i.format, i.version
    );
    let _ = writeln!(s, "encoder      {}", i.encoder);
    let _ = writeln!(
        s,
        "grid         {} m cells, origin ({:.3}, {:.3}) m",
        i.resolution_m, i.origin_m[0], i.origin_m[1]
    );
    let _ = writeln!(
        s,
        "band         {} to {} m above the floor at z = {:.3} m",
        i.band_m[0], i.band_m[1], i.floor_z_m
    );
    let _ = writeln!(
        s,
        "features     {} x {}, tau {}",
        super::count(i.rows, "row"),
        super::count(i.feature_dim, "dim"),
        i.tau
    );
    let _ = writeln!(s, "columns      {}", super::count(i.cells, "cell"));
    if let (Some(lo), Some(hi)) = (i.bounds_min_m, i.bounds_max_m) {
        let _ = writeln!(
            s,
            "bounds       x {:.3} .. {:.3}, y {:.3} .. {:.3} m",
            lo[0], hi[0], lo[1], hi[1]
        );
    }
    let _ = writeln!(s, "top rows     (row: cells)");
    for (row, n) in &i.top_rows {
        let _ = writeln!(s, "  {row:>6}: {n}");
    }
    print!("{s}");
    Ok(())
}

fn info(a: &InfoArgs) -> anyhow::Result<()> {
    if omcl::map::floorplan::is_plan_file(&a.file).unwrap_or(false) {
        return plan_info(a);
    }
    let t0 = std::time::Instant::now();
    let map = file::load(&a.file)?;
    let load_s = t0.elapsed().as_secs_f64();
    let scene = if a.scene {
        let t1 = std::time::Instant::now();
        let caster =
            omcl::mcl::SensorModel::embree_caster(map.grid().resolution as f32, &map.cells())?;
        let build_s = t1.elapsed().as_secs_f64();
        drop(caster);
        Some((load_s, build_s, peak_rss_mib()))
    } else {
        None
    };
    let i = map_info(&a.file, &map, a.top)?;
    if let Some((load_s, build_s, peak)) = scene {
        // On stderr, so --json stays one JSON document on stdout.
        eprintln!(
            "scene        loaded in {load_s:.2} s, Embree scene built in {build_s:.2} s \
             ({} voxels), peak memory {}",
            map.len(),
            peak.map_or("unknown".into(), |m| format!("{m:.0} MiB"))
        );
    }
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&i).context("serializing map info")?
        );
        return Ok(());
    }
    print!("{}", render_info(&i));
    Ok(())
}

/// The text form of `omcl map info`.
pub fn render_info(i: &MapInfo) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "map          {} ({:.2} MB)",
        i.file,
        i.file_bytes as f64 / 1e6
    );
    let _ = writeln!(s, "format       {} v{} (checksum ok)", i.format, i.version);
    let _ = writeln!(s, "encoder      {}", i.encoder);
    let _ = writeln!(s, "resolution   {} m", i.resolution_m);
    let _ = writeln!(
        s,
        "origin       {:.3} {:.3} {:.3} m",
        i.origin_m[0], i.origin_m[1], i.origin_m[2]
    );
    match &i.crs {
        Some(c) => {
            let _ = writeln!(
                s,
                "crs          {}, as the survey's {} record states it",
                c.name, c.governing
            );
            let _ = writeln!(
                s,
                "             coordinates here in metres; the survey's: {}",
                c.survey_units
            );
        }
        None if i.version == "2" => {
            let _ = writeln!(
                s,
                "crs          not recorded (a version-2 map file, written before maps kept \
                 their survey's CRS: rebuild it from the survey to keep it)"
            );
        }
        None => {
            let _ = writeln!(s, "crs          none stated (a local frame)");
        }
    }
    let _ = writeln!(
        s,
        "features     {} x {}, tau {}",
        super::count(i.rows, "row"),
        super::count(i.feature_dim, "dim"),
        i.tau
    );
    let _ = writeln!(s, "leaves       {} voxels", i.leaves);
    if let (Some(lo), Some(hi)) = (i.bounds_min_m, i.bounds_max_m) {
        let _ = writeln!(
            s,
            "bounds       [{:.2}, {:.2}] x [{:.2}, {:.2}] x [{:.2}, {:.2}] m (extent {:.2} x {:.2} x {:.2} m)",
            lo[0],
            hi[0],
            lo[1],
            hi[1],
            lo[2],
            hi[2],
            hi[0] - lo[0],
            hi[1] - lo[1],
            hi[2] - lo[2]
        );
    }
    let _ = writeln!(
        s,
        "memory       {:.2} MB in RAM ({:.1} B/voxel)",
        i.memory_bytes as f64 / 1e6,
        i.memory_bytes as f64 / i.leaves.max(1) as f64
    );
    let _ = writeln!(s, "rows by use  (row: voxels)  {} unused", i.unused_rows);
    for (k, (r, n)) in i.top_rows.iter().enumerate() {
        // The classes a row stands for, for a built-in class list's map.
        let classes = i.top_row_classes.as_ref().map_or(String::new(), |c| {
            let c = &c[k];
            match (&c.classes[..], &c.nearest) {
                ([], Some(n)) => format!(
                    "  a mix of classes; nearest {} ({}), similarity {:.2}",
                    n.name, n.id, n.similarity
                ),
                ([], None) => String::new(),
                (named, _) => {
                    let words: Vec<String> = named
                        .iter()
                        .map(|c| format!("{} ({})", c.name, c.id))
                        .collect();
                    format!("  {}", words.join(", "))
                }
            }
        });
        let _ = writeln!(
            s,
            "  {r:>6}: {n:>9} ({:.1} %){classes}",
            100.0 * *n as f64 / i.leaves.max(1) as f64
        );
    }
    s
}

/// The process's peak resident memory (Linux `VmHWM`), MiB.
fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}
