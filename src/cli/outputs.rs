//! Outputs that would replace what a command reads, or each other: refused
//! by name before anything is read or written. `omcl localize --sequence
//! seq -o seq/poses.txt` wrote its estimate over the sequence's ground
//! truth, and `omcl map floorplan m.omcl -o m.omcl` its plan over the map.

use std::path::{Path, PathBuf};

/// A file's identity: its device and inode where it exists (a symlink, a
/// hard link or a path through `..` to it is the same file), else the
/// absolute path it would be created at.
#[derive(Debug, PartialEq, Eq)]
enum Identity {
    Inode(u64, u64),
    New(PathBuf),
}

fn identity(p: &Path) -> Option<Identity> {
    use std::os::unix::fs::MetadataExt;
    if let Ok(m) = std::fs::metadata(p) {
        return Some(Identity::Inode(m.dev(), m.ino()));
    }
    absolute(p).map(Identity::New)
}

/// What [`refuse_overlaps`] calls one of [`sequence_files`]: `OUT: --out
/// is a file of the sequence, seq/poses.txt; ...`.
pub const SEQUENCE_FILE: &str = "a file of the sequence,";

/// The files of a sequence folder that its readers read besides the
/// frames (ground truth, odometry, calibration, class table, stamps), in
/// every layout.
pub fn sequence_files(dir: &Path) -> Vec<PathBuf> {
    [
        "poses.txt",
        "odometry.txt",
        "intrinsics.txt",
        "classes.txt",
        "embeddings.npy",
        "calib.txt",
        "times.txt",
        "camera-intrinsics.txt",
    ]
    .iter()
    .map(|f| dir.join(f))
    .collect()
}

/// Where `p` is or would be created: its canonical path if it exists
/// (links followed), else its folder's canonical path and its name.
fn absolute(p: &Path) -> Option<PathBuf> {
    if let Ok(c) = std::fs::canonicalize(p) {
        return Some(c);
    }
    let name = p.file_name()?;
    let parent = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    Some(std::fs::canonicalize(parent).ok()?.join(name))
}

/// Refuses an output that a reader of the sequence folder `seq` would
/// read as part of it: anything inside one of its subfolders (where the
/// frames are: `labels/`, `depth/`, `image_2/`, `velodyne/`, ...), and in
/// the folder itself one of [`sequence_files`] (even a new one: a new
/// `odometry.txt` is read as the odometry next time) or a 7-Scenes frame
/// (`frame-*`). Other files beside the frames (`seq/estimate.txt`) are
/// fine.
pub fn refuse_inside_sequence(outputs: &[(&str, &Path)], seq: &Path) -> anyhow::Result<()> {
    // A missing sequence is its reader's to report.
    let Ok(root) = std::fs::canonicalize(seq) else {
        return Ok(());
    };
    let names: Vec<PathBuf> = sequence_files(Path::new(""));
    for &(option, p) in outputs {
        let Some(abs) = absolute(p) else { continue };
        let Ok(rel) = abs.strip_prefix(&root) else {
            continue;
        };
        let parts: Vec<_> = rel.components().collect();
        let frame_name = rel.to_str().is_some_and(|n| n.starts_with("frame-"));
        if parts.len() > 1 {
            anyhow::bail!(
                "{}: {option} is inside the sequence's folder {}, where its frames are read \
                 from; writing there would replace or add to them (choose another path)",
                p.display(),
                root.join(parts[0]).display()
            );
        }
        if parts.len() == 1 && (names.iter().any(|n| n.as_path() == rel) || frame_name) {
            anyhow::bail!(
                "{}: {option} would be read as part of the sequence {} ({}); choose another \
                 name",
                p.display(),
                seq.display(),
                rel.display()
            );
        }
    }
    Ok(())
}

/// The subfolders of a sequence its readers read frames from, in every
/// layout (RGB-D, KITTI, SemanticKITTI).
const FRAME_FOLDERS: [&str; 8] = [
    "rgb", "depth", "labels", "features", "image_2", "image_3", "labels_2", "velodyne",
];

/// Refuses a folder an option fills (`--feature-cache`) that is, or is in,
/// a part of the sequence `seq` its readers read: the sequence's folder
/// itself (7-Scenes frames, poses), a frame folder (`features/`, whose
/// `.npy` files the cache would have replaced) or anything inside one. A
/// new folder beside the frames (`seq/cache`) is fine.
pub fn refuse_folder_in_sequence(option: &str, dir: &Path, seq: &Path) -> anyhow::Result<()> {
    let (Ok(root), Some(abs)) = (std::fs::canonicalize(seq), absolute(dir)) else {
        return Ok(());
    };
    let Ok(rel) = abs.strip_prefix(&root) else {
        return Ok(());
    };
    let parts: Vec<_> = rel.components().collect();
    let frames = parts
        .first()
        .is_some_and(|c| FRAME_FOLDERS.iter().any(|f| c.as_os_str() == *f));
    anyhow::ensure!(
        !(parts.is_empty() || parts.len() > 1 || frames),
        "{}: {option} is {} the sequence {}, whose frames are read from there; filling it \
         would replace or add to them (a new folder beside them, or elsewhere, will do)",
        dir.display(),
        if parts.is_empty() {
            "the folder of"
        } else {
            "inside"
        },
        seq.display()
    );
    Ok(())
}

/// Refuses, before any work, outputs that could not be written at the
/// end: a folder that does not exist or is not a folder, and a figure
/// (`figures`: options drawn as PNG or SVG by extension) of another kind.
pub fn refuse_unwritable(outputs: &[(&str, &Path)], figures: &[&str]) -> anyhow::Result<()> {
    for &(option, p) in outputs {
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        anyhow::ensure!(
            dir.is_dir(),
            "{}: {option}'s folder {} {}",
            p.display(),
            dir.display(),
            if dir.exists() {
                "is not a folder"
            } else {
                "does not exist (create it first)"
            }
        );
        anyhow::ensure!(
            !p.is_dir(),
            "{}: {option} is a folder; give a file name",
            p.display()
        );
        refuse_read_only(option, p)?;
        if figures.contains(&option) {
            let ext = p
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase);
            anyhow::ensure!(
                matches!(ext.as_deref(), Some("png" | "svg")),
                "{}: {option} is drawn as PNG or SVG by its extension; end the name in .png or \
                 .svg",
                p.display()
            );
        }
    }
    Ok(())
}

/// Refuses text outputs (a trajectory, JSON, CSV) that would replace an
/// existing file holding data of another kind: a map or floor plan, or any
/// file that is not text (a PNG, a LAS, an `.npy`). `omcl localize -o
/// kitti.omcl` replaced a 2.8 MB map with a trajectory. An empty file, and
/// an earlier text output, are replaced as before.
pub fn refuse_replacing_data(outputs: &[(&str, &Path)]) -> anyhow::Result<()> {
    use std::io::Read;
    for &(option, p) in outputs {
        let Ok(mut f) = std::fs::File::open(p) else {
            continue;
        };
        if !f.metadata().is_ok_and(|m| m.is_file()) {
            continue;
        }
        let mut head = Vec::new();
        if f.by_ref().take(8192).read_to_end(&mut head).is_err() {
            continue;
        }
        let map = omcl::map::file::is_map_file(p).unwrap_or(false);
        // Text: UTF-8 without NUL, a last character cut at 8 KiB allowed.
        let text = !head.contains(&0)
            && match std::str::from_utf8(&head) {
                Ok(_) => true,
                Err(e) => e.error_len().is_none() && head.len() == 8192,
            };
        anyhow::ensure!(
            !map && (head.is_empty() || text),
            "{}: {option} would replace {}; omcl writes text there (remove the file first, or \
             choose another name)",
            p.display(),
            if map {
                "a map file"
            } else {
                "a file that is not text (data of another kind)"
            }
        );
    }
    Ok(())
}

/// Refuses an output `p` that would replace a file holding something
/// (a non-empty regular file) that `ours` does not recognise as `kind`
/// omcl wrote, unless `force`: an earlier output of the same kind, an
/// empty file (`mktemp`'s) and a new name are fine.
pub fn refuse_replacing_other(
    option: &str,
    p: &Path,
    kind: &str,
    ours: impl Fn(&Path) -> bool,
    force: bool,
) -> anyhow::Result<()> {
    let holds_something = std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.len() > 0);
    anyhow::ensure!(
        !holds_something || force || ours(p),
        "{}: {option} exists and is not {kind}; pass --force to replace it, or choose \
         another name",
        p.display()
    );
    Ok(())
}

/// The kinds of text omcl writes, each recognised in a file it would
/// replace ([`refuse_replacing_unlike`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TextOutput {
    /// A trajectory (`omcl localize -o`): TUM or KITTI poses.
    Trajectory,
    /// Metrics JSON (`--metrics`, `omcl eval --json`): an object with a
    /// `"metric"`.
    Metrics,
    /// `omcl localize --diagnostics` CSV.
    Diagnostics,
}

impl TextOutput {
    fn what(self) -> &'static str {
        match self {
            TextOutput::Trajectory => "a trajectory (TUM or KITTI poses)",
            TextOutput::Metrics => "metrics JSON omcl wrote",
            TextOutput::Diagnostics => "diagnostics CSV omcl wrote",
        }
    }

    fn recognises(self, p: &Path) -> bool {
        match self {
            TextOutput::Trajectory => omcl::io::poses::read_poses(p).is_ok(),
            TextOutput::Metrics => omcl::io::bounded_read::read_text(p)
                .ok()
                .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
                .is_some_and(|v| v.get("metric").is_some()),
            TextOutput::Diagnostics => {
                use std::io::Read;
                let mut head = Vec::new();
                std::fs::File::open(p)
                    .and_then(|f| f.take(64).read_to_end(&mut head))
                    .is_ok()
                    && head.starts_with(b"frame,ess,")
            }
        }
    }
}

/// Files of a TUM RGB-D sequence as published, beside [`sequence_files`].
const TUM_FILES: [&str; 4] = [
    "groundtruth.txt",
    "rgb.txt",
    "depth.txt",
    "accelerometer.txt",
];

/// Whether `p` (links followed: a link is the file it names) is a file a
/// dataset's readers read: one of [`sequence_files`] or of a TUM
/// sequence's lists in a camera sequence's folder (RGB-D, KITTI, 7-Scenes,
/// TUM), or a KITTI ground truth `poses/NN.txt` beside `sequences/`.
fn is_dataset_file(p: &Path) -> bool {
    let p = omcl::io::atomic::follow_links(p).unwrap_or_else(|_| p.to_path_buf());
    let dir = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Some(name) = p.file_name().and_then(|n| n.to_str()) else {
        return false;
    };
    let kitti_poses = dir.file_name().is_some_and(|n| n == "poses")
        && dir.parent().is_some_and(|d| d.join("sequences").is_dir())
        && name.len() == 6
        && name.ends_with(".txt")
        && name[..2].bytes().all(|b| b.is_ascii_digit());
    let listed = sequence_files(Path::new(""))
        .iter()
        .any(|f| f.as_os_str() == name)
        || TUM_FILES.contains(&name)
        || name == "sim.json";
    kitti_poses || (listed && is_sequence_folder(dir))
}

/// Whether `dir` is a camera sequence's folder (RGB-D, KITTI or 7-Scenes):
/// it has frame folders or a calibration file.
pub fn is_sequence_folder(dir: &Path) -> bool {
    ["depth", "labels", "features", "rgb", "image_2", "velodyne"]
        .iter()
        .any(|d| dir.join(d).is_dir())
        || ["intrinsics.txt", "calib.txt", "camera-intrinsics.txt"]
            .iter()
            .any(|f| dir.join(f).is_file())
}

/// Refuses, unless `force`, a text output that would replace an existing
/// file (non-empty) other than an earlier output of its kind, or a file a
/// dataset's readers read: `omcl localize -o other_seq/poses.txt` replaced
/// another sequence's ground truth, `--metrics classes.txt` a class table,
/// `omcl eval ape --json notes.md` a note.
pub fn refuse_replacing_unlike(
    option: &str,
    p: &Path,
    kind: TextOutput,
    force: bool,
) -> anyhow::Result<()> {
    if force {
        return Ok(());
    }
    // A new file of that name too: the dataset's readers would read it
    // (`-o other_seq/odometry.txt` is that sequence's odometry next time).
    anyhow::ensure!(
        !is_dataset_file(p),
        "{}: {option} would {} a dataset's file (ground truth, odometry, calibration or a \
         class table); pass --force to write it, or choose another name",
        p.display(),
        if p.exists() { "replace" } else { "add" }
    );
    let holds_something = std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.len() > 0);
    if !holds_something {
        return Ok(());
    }
    anyhow::ensure!(
        kind.recognises(p),
        "{}: {option} exists and is not {}; pass --force to replace it, or choose another name",
        p.display(),
        kind.what()
    );
    Ok(())
}

/// Refuses, unless `force`, a figure output (PNG or SVG) that would
/// replace an existing file (non-empty) omcl did not draw as a figure or
/// picture ([`omcl::plot::is_omcl_figure`]): a photo, a depth or label
/// frame (the simulator's too), anyone's image.
pub fn refuse_replacing_figure(option: &str, p: &Path, force: bool) -> anyhow::Result<()> {
    refuse_replacing_other(
        option,
        p,
        "a figure omcl drew",
        omcl::plot::is_omcl_figure,
        force,
    )
}

/// Extensions of data omcl reads, which a map or a floor plan is never
/// named: `-o cloud.ply` is a slip for `map export`, or would replace the
/// survey.
const DATA_EXTENSIONS: [&str; 9] = [
    "ply", "las", "laz", "bin", "npy", "png", "jpg", "jpeg", "txt",
];

/// The checks of an output that is a map (`map cloud`, `map rgbd`, `map
/// ground`, `map upgrade`): writable, not named as a point cloud or other
/// data, and not replacing a file that is not a map unless `force`.
pub fn check_map_out(option: &str, out: &Path, force: bool) -> anyhow::Result<()> {
    refuse_unwritable(&[(option, out)], &[])?;
    let ext = out.extension().and_then(|e| e.to_str()).unwrap_or("");
    anyhow::ensure!(
        !DATA_EXTENSIONS.iter().any(|e| ext.eq_ignore_ascii_case(e)),
        "{option} {}: a map is an .omcl file, not a .{ext} (to see a map as a point cloud, \
         after building it: `omcl map export MAP -o FILE.ply` or `omcl map query MAP WORDS \
         -o FILE.ply`; .las/.laz as well)",
        out.display()
    );
    refuse_replacing_other(
        option,
        out,
        "an omcl map",
        |p| omcl::map::file::is_map_file(p).unwrap_or(false),
        force,
    )
}

/// The checks of a floor plan's outputs (`map floorplan -o PLAN --png
/// IMAGE`): writable, the plan not named as data, and neither replacing a
/// file omcl did not write as such (a map, a photo, a depth frame)
/// unless `force`.
pub fn check_plan_out(out: &Path, png: Option<&Path>, force: bool) -> anyhow::Result<()> {
    let mut outputs = vec![("--out", out)];
    outputs.extend(png.map(|p| ("--png", p)));
    refuse_unwritable(&outputs, &[])?;
    let ext = out.extension().and_then(|e| e.to_str()).unwrap_or("");
    anyhow::ensure!(
        !DATA_EXTENSIONS.iter().any(|e| ext.eq_ignore_ascii_case(e)),
        "--out {}: a floor plan is not a .{ext} (name it .plan; --png writes the picture)",
        out.display()
    );
    refuse_replacing_other(
        "--out",
        out,
        "an omcl floor plan",
        |p| omcl::map::floorplan::is_plan_file(p).unwrap_or(false),
        force,
    )?;
    if let Some(png) = png {
        let ext = png.extension().and_then(|e| e.to_str()).unwrap_or("");
        anyhow::ensure!(
            ext.eq_ignore_ascii_case("png"),
            "--png {}: the picture is a PNG: name it .png",
            png.display()
        );
        refuse_replacing_figure("--png", png, force)?;
    }
    Ok(())
}

/// A cloud `map query` or `map export` writes is PLY, LAS or LAZ, as its
/// name says: another name (`heat.txt`, `heat`) is refused rather than
/// given a PLY the reader did not ask for.
pub fn check_cloud_name(option: &str, p: &Path) -> anyhow::Result<()> {
    let ext = p
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("ply" | "las" | "laz") => Ok(()),
        Some(e) => anyhow::bail!(
            "{}: {option} names a .{e} file; omcl writes clouds as .ply, .las or .laz, \
             the format the name says",
            p.display()
        ),
        None => anyhow::bail!(
            "{}: {option} has no extension; name it .ply, .las or .laz (the format \
             the name says)",
            p.display()
        ),
    }
}

/// Refuses a point-cloud output (`option` at `p`) that would replace a
/// file omcl did not write: a map, a survey (`omcl map export m.omcl -o
/// survey.las`, or `-o survey.ply` over the PLY the map came from), or
/// anything else by that name. An earlier export (a LAS whose header names
/// omcl as its generating software, a PLY with omcl's comment) is
/// replaced as before.
pub fn refuse_replacing_survey(option: &str, p: &Path) -> anyhow::Result<()> {
    use std::io::Read;
    if !p.is_file() {
        return Ok(());
    }
    anyhow::ensure!(
        !omcl::map::file::is_map_file(p).unwrap_or(false),
        "{}: {option} would replace a map file (choose another name)",
        p.display()
    );
    let mut head = Vec::new();
    std::fs::File::open(p)
        .and_then(|f| f.take(256).read_to_end(&mut head))
        .map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?;
    // An empty file (`mktemp`'s) holds nothing to lose.
    let ours = if head.is_empty() {
        true
    } else if head.starts_with(b"LASF") && head.len() >= 90 {
        String::from_utf8_lossy(&head[58..90]).starts_with("omcl")
    } else if head.starts_with(b"ply") {
        let text = String::from_utf8_lossy(&head);
        text.lines()
            .take(3)
            .any(|l| l.trim() == "comment written by omcl")
    } else {
        false
    };
    anyhow::ensure!(
        ours,
        "{}: {option} would replace a file omcl did not write ({}); choose another name",
        p.display(),
        if head.starts_with(b"LASF") {
            "a LAS file: a survey?"
        } else if head.starts_with(b"ply") {
            "a PLY file: the cloud the map came from?"
        } else {
            "not an export of omcl's"
        }
    );
    Ok(())
}

/// Refuses to write at `p` (a file or folder, existing or to be made;
/// a link is followed as the writer follows it) when the folder it is or
/// would go in is marked read-only (`io::atomic::read_only_folder`: a
/// shared data folder of mode 555 stays as it is, even for root).
pub fn refuse_read_only(option: &str, p: &Path) -> anyhow::Result<()> {
    let target = omcl::io::atomic::follow_links(p).unwrap_or_else(|_| p.to_path_buf());
    if let Some((dir, mode)) = omcl::io::atomic::read_only_folder(&target) {
        anyhow::bail!(
            "{}: {option} would write into {}, which is marked read-only (mode {mode:o}); omcl \
             does not write there, even as root (choose another path; a copy made with `cp -r` \
             keeps the mode: `chmod -R u+w` it)",
            p.display(),
            dir.display()
        );
    }
    Ok(())
}

/// Creates the folder `dir` that `option` names (and its parents), or
/// says by name that a file is in the way or that the folder it would go
/// in is marked read-only ([`refuse_read_only`]).
pub fn create_folder(option: &str, dir: &Path) -> anyhow::Result<()> {
    anyhow::ensure!(
        !dir.exists() || dir.is_dir(),
        "{}: {option} names a folder, and this is a file (choose another path)",
        dir.display()
    );
    refuse_read_only(option, dir)?;
    std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("creating {}: {e}", dir.display()))
}

/// The files an ONNX model option (`--text-model` ...) reads, if given:
/// the model and its card, as [`refuse_overlaps`] inputs.
pub fn model_files(option: &str, model: Option<&Path>) -> Vec<(String, PathBuf)> {
    model
        .map(|m| {
            vec![
                (format!("the {option}"), m.to_path_buf()),
                (
                    format!("the {option}'s card"),
                    omcl::encode::card::card_path_for(m),
                ),
            ]
        })
        .unwrap_or_default()
}

/// Refuses when an output (`(option, path)`) is one of the `inputs`
/// (`(what, path)`, files the command reads; those that do not exist are
/// skipped, their readers say so) or another output, naming both.
pub fn refuse_overlaps<S: AsRef<str>, P: AsRef<Path>>(
    outputs: &[(&str, &Path)],
    inputs: &[(S, P)],
) -> anyhow::Result<()> {
    // A character device or a pipe (`/dev/null`) is written into, not
    // replaced: several outputs may go there.
    let special = |p: &Path| {
        use std::os::unix::fs::FileTypeExt;
        std::fs::metadata(p)
            .is_ok_and(|m| m.file_type().is_char_device() || m.file_type().is_fifo())
    };
    let outs: Vec<_> = outputs
        .iter()
        .map(|&(o, p)| (o, p, if special(p) { None } else { identity(p) }))
        .collect();
    // Only inputs that exist: a missing one has no inode to share.
    let ins: Vec<_> = inputs
        .iter()
        .filter_map(|(what, p)| match identity(p.as_ref()) {
            Some(id @ Identity::Inode(..)) => Some((what.as_ref(), p.as_ref(), id)),
            _ => None,
        })
        .collect();
    for (i, (option, path, id)) in outs.iter().enumerate() {
        let Some(id) = id else { continue };
        for (what, input, input_id) in &ins {
            if input_id == id {
                anyhow::bail!(
                    "{}: {option} is {what} {}; writing there would replace it (choose another path)",
                    path.display(),
                    input.display()
                );
            }
        }
        for (other, other_path, other_id) in &outs[..i] {
            if other_id.as_ref() == Some(id) {
                anyhow::bail!(
                    "{}: {option} and {other} ({}) are the same file; one would replace the other",
                    path.display(),
                    other_path.display()
                );
            }
        }
    }
    Ok(())
}

/// A simulation's folder while it is written: the simulation writes into
/// a hidden folder beside `--out` ([`SimStaging::path`]) and
/// [`SimStaging::commit`] moves what it wrote into place, so a run that
/// fails or is stopped midway leaves no half sequence and, with `--force`,
/// the earlier simulation as it was.
pub struct SimStaging {
    out: PathBuf,
    /// Removed if the run is interrupted (dropped before `temp`).
    _interrupt: omcl::io::atomic::RemoveOnInterrupt,
    temp: tempfile::TempDir,
    /// Entries of an earlier simulation to remove at commit (`--force`).
    replace: Vec<&'static str>,
}

/// What an earlier simulation of omcl's in `out` wrote there, by the
/// `generator` its `sim.json` names (`omcl sim indoor`, `omcl sim
/// outdoor`, a sequence `omcl bench table1-sixdof --export-frames` wrote
/// in the indoor layout); `None` when `out` has no such `sim.json` (none,
/// one another program or the user wrote, one that is not omcl's JSON).
fn earlier_simulation(out: &Path) -> Option<&'static [&'static str]> {
    use omcl::sim::dataset::{
        EXPORT_GENERATOR, INDOOR_ENTRIES, INDOOR_GENERATOR, OUTDOOR_ENTRIES, OUTDOOR_GENERATOR,
    };
    // A simulation's sim.json is a few kilobytes; more is not one.
    let bytes = omcl::io::bounded_read::read_capped(&out.join("sim.json"), 1 << 20).ok()?;
    let meta: serde_json::Value = serde_json::from_slice(&bytes).ok()?;
    match meta.get("generator")?.as_str()? {
        g if g == INDOOR_GENERATOR || g == EXPORT_GENERATOR => Some(&INDOOR_ENTRIES),
        g if g == OUTDOOR_GENERATOR => Some(&OUTDOOR_ENTRIES),
        _ => None,
    }
}

/// Checks `out` for a simulation that writes `entries` into it (`omcl sim
/// indoor` and `outdoor`, whose frames would otherwise mix with or replace
/// what is there) and stages its writing. A missing or empty folder is
/// fine. A folder holding an earlier simulation (a `sim.json` omcl's
/// simulator wrote, by its content, not its name) is replaced with
/// `force`: at commit what either simulation writes is removed first, so
/// no frame of an earlier, longer run (or of the other kind) is left
/// beside the new one; without `force` it is refused. Any other folder
/// with something in it (a real sequence, say, even with a `sim.json` of
/// its own) is refused, `force` or not, and nothing in it is touched.
pub fn stage_sim_folder(
    out: &Path,
    entries: &'static [&'static str],
    force: bool,
) -> anyhow::Result<SimStaging> {
    refuse_read_only("--out", out)?;
    let mut replace: Vec<&'static str> = Vec::new();
    match std::fs::read_dir(out) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(_) if out.is_file() => {
            anyhow::bail!("{}: --out is a file, not a folder", out.display())
        }
        Err(e) => anyhow::bail!("{}: cannot read the --out folder: {e}", out.display()),
        Ok(listing) => {
            let mut names: Vec<String> = listing
                .filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect();
            names.sort();
            if names.is_empty() {
                // An empty folder: nothing to keep or replace.
            } else if let Some(earlier) = earlier_simulation(out) {
                anyhow::ensure!(
                    force,
                    "{}: --out holds an earlier simulation (sim.json); pass --force to replace \
                     it (its frames and files are removed once the new one is written), or \
                     choose a new folder",
                    out.display()
                );
                replace = entries.to_vec();
                replace.extend(earlier.iter().filter(|e| !entries.contains(e)));
            } else {
                let shown = names.iter().take(4).cloned().collect::<Vec<_>>().join(", ");
                let more = if names.len() > 4 { ", ..." } else { "" };
                let mark = if out.join("sim.json").exists() {
                    "whose sim.json is not one omcl's simulator wrote"
                } else {
                    "and no earlier simulation (sim.json)"
                };
                anyhow::bail!(
                    "{}: --out is a folder with other files in it ({shown}{more}) {mark}; a \
                     simulation writes {} there and would mix with or replace them: choose a \
                     new or empty folder",
                    out.display(),
                    entries.join(", ")
                );
            }
        }
    }
    let parent = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    omcl::io::atomic::create_folder(parent)
        .map_err(|e| anyhow::anyhow!("{}: cannot create the folder: {e}", parent.display()))?;
    let temp = tempfile::Builder::new()
        .prefix(".omcl-sim-")
        .tempdir_in(parent)
        .map_err(|e| anyhow::anyhow!("{}: cannot write there: {e}", parent.display()))?;
    Ok(SimStaging {
        out: out.to_path_buf(),
        _interrupt: omcl::io::atomic::remove_on_interrupt(temp.path()),
        temp,
        replace,
    })
}

impl SimStaging {
    /// Where the simulation writes.
    pub fn path(&self) -> &Path {
        self.temp.path()
    }

    /// Moves what was written into `--out` (created if missing), after
    /// removing the earlier simulation's entries; the staging folder goes.
    pub fn commit(self) -> anyhow::Result<()> {
        let out = &self.out;
        let fail =
            |what: &str, e: std::io::Error| anyhow::anyhow!("{}: {what}: {e}", out.display());
        omcl::io::atomic::create_folder(out).map_err(|e| fail("cannot create the folder", e))?;
        for name in &self.replace {
            let p = out.join(name);
            let removed = match std::fs::symlink_metadata(&p) {
                Ok(m) if m.is_dir() => std::fs::remove_dir_all(&p),
                Ok(_) => std::fs::remove_file(&p),
                Err(_) => continue,
            };
            removed
                .map_err(|e| fail(&format!("cannot remove the earlier simulation's {name}"), e))?;
        }
        let staged = std::fs::read_dir(self.temp.path())
            .map_err(|e| fail("cannot read the staged simulation", e))?;
        for entry in staged {
            let entry = entry.map_err(|e| fail("cannot read the staged simulation", e))?;
            std::fs::rename(entry.path(), out.join(entry.file_name()))
                .map_err(|e| fail("cannot move the new simulation into place", e))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_over_inputs_or_each_other_are_refused_through_any_path() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let input = d.join("map.omcl");
        std::fs::write(&input, b"map").unwrap();
        std::fs::create_dir(d.join("sub")).unwrap();
        std::os::unix::fs::symlink(&input, d.join("link.omcl")).unwrap();
        std::fs::hard_link(&input, d.join("hard.omcl")).unwrap();
        let ins = [("the map", input.as_path())];
        for same in [
            input.clone(),
            d.join("sub/../map.omcl"),
            d.join("link.omcl"),
            d.join("hard.omcl"),
        ] {
            let e = refuse_overlaps(&[("--out", &same)], &ins).unwrap_err();
            let text = e.to_string();
            assert!(
                text.contains("--out is the map") && text.contains("map.omcl"),
                "{text}"
            );
        }
        // Another file, new or existing, and a missing input: fine.
        std::fs::write(d.join("other.omcl"), b"x").unwrap();
        for other in [d.join("new.plan"), d.join("other.omcl")] {
            refuse_overlaps(&[("--out", &other)], &ins).unwrap();
        }
        refuse_overlaps(&[("--out", &input)], &[("the plan", &d.join("none"))]).unwrap();
        // Two outputs naming one new file, through different paths.
        let (a, b) = (d.join("plan.png"), d.join("sub/../plan.png"));
        let e =
            refuse_overlaps(&[("--out", &a), ("--png", &b)], &[] as &[(&str, &Path)]).unwrap_err();
        assert!(e.to_string().contains("--png and --out"), "{e}");
        // Nothing was written or removed.
        assert_eq!(std::fs::read(&input).unwrap(), b"map");
        assert!(!a.exists());
    }

    #[test]
    fn outputs_among_a_sequences_frames_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let seq = dir.path().join("seq");
        std::fs::create_dir_all(seq.join("labels")).unwrap();
        std::fs::write(seq.join("labels/000005.png"), b"png").unwrap();
        let refused = |p: &Path, needle: &str| {
            let e = refuse_inside_sequence(&[("--out", p)], &seq).unwrap_err();
            assert!(e.to_string().contains(needle), "{e}");
        };
        refused(
            &seq.join("labels/000005.png"),
            "inside the sequence's folder",
        );
        refused(&seq.join("labels/new.txt"), "inside the sequence's folder");
        refused(&seq.join("labels/../labels/000009.png"), "labels");
        refused(&seq.join("odometry.txt"), "read as part of the sequence");
        refused(
            &seq.join("frame-000001.pose.txt"),
            "read as part of the sequence",
        );
        // Through a link to a frame from outside.
        std::os::unix::fs::symlink(seq.join("labels/000005.png"), dir.path().join("l.png"))
            .unwrap();
        refused(&dir.path().join("l.png"), "inside");
        // Beside the frames, or elsewhere: fine.
        for ok in [seq.join("estimate.txt"), dir.path().join("est.txt")] {
            refuse_inside_sequence(&[("--out", &ok)], &seq).unwrap();
        }
        assert_eq!(
            std::fs::read(seq.join("labels/000005.png")).unwrap(),
            b"png"
        );
    }
}
