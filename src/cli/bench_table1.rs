//! `omcl bench table1-floorplan` and `omcl bench table1-6dof`: Table I's
//! 2-D block (floor plans; OMCL and the SeDAR* and SIMP* baselines) and
//! its 3-D block (full 6-DoF pose), run in this process beside the
//! paper's rows, written as Markdown and JSON into `<out>/`.

use std::path::Path;

use anyhow::Context;

use omcl::experiment::plan_settings::PlanSettings;
use omcl::experiment::table1::{BlockResult, write_figure4};
use omcl::experiment::table1_6dof;
use omcl::experiment::table1_floorplan::{self, BlockSpec};

use super::bench_args::{BenchArgs, Experiment, block_overrides};
use omcl::mcl::{FilterConfig, INDOOR_PARTICLES, SIX_DOF_PARTICLES};

/// `--export-frames DIR`: writes the 3-D block's sequences to `DIR` and
/// runs nothing.
pub fn export(a: &BenchArgs, dir: &Path) -> anyhow::Result<()> {
    anyhow::ensure!(
        a.plan.experiments == [Experiment::Table1Sixdof],
        "--export-frames writes the sequences of table1-sixdof and runs nothing; name that \
         experiment alone"
    );
    let progress = |m: &str| eprintln!("{m}");
    let motion = block_overrides(&a.plan.set)?.sixdof;
    let dirs = table1_6dof::export_block(
        &block_spec(a, six_dof_filters(), SIX_DOF_PARTICLES)?,
        &motion,
        dir,
        &progress,
    )?;
    println!(
        "wrote {} to {}",
        super::count(dirs.len(), "sequence"),
        dir.display()
    );
    Ok(())
}

/// Runs the Table I blocks `a` asks for; returns whether any ran.
pub fn run(a: &BenchArgs) -> anyhow::Result<bool> {
    let e = &a.plan.experiments;
    anyhow::ensure!(
        a.sixdof.rgbd_odometry.is_none() || e.contains(&Experiment::Table1Sixdof),
        "--rgbd-odometry adds a row to table1-sixdof, which is not asked for"
    );
    check_variants(a)?;
    // Both blocks' filters are checked (`--set`) before anything is made.
    let plan_spec = e
        .contains(&Experiment::Table1Floorplan)
        .then(|| block_spec(a, floor_plan_filters(), INDOOR_PARTICLES))
        .transpose()?;
    let six_spec = e
        .contains(&Experiment::Table1Sixdof)
        .then(|| block_spec(a, six_dof_filters(), SIX_DOF_PARTICLES))
        .transpose()?;
    if plan_spec.is_none() && six_spec.is_none() {
        return Ok(false);
    }
    // (A folder made here and left empty by a failure is removed by
    // `bench::run`.)
    super::outputs::create_folder("--out", &a.out)?;
    let names = a.plan.variants.as_deref();
    let progress = |m: &str| eprintln!("{m}");
    if let Some(spec) = plan_spec {
        let b = table1_floorplan::block(&spec, names, &progress)?;
        // Every row the block can have, OMCL_GT_exact by --variants.
        let rows: Vec<&str> = table1_floorplan::OMCL_ROWS
            .into_iter()
            .chain(["OMCL_GT_exact"])
            .chain(table1_floorplan::BASELINES.map(|b| b.name()))
            .collect();
        let run = serde_json::json!({ "spec": spec });
        write(a, "table1_floorplan", "2d", &rows, &b, run)?;
        println!("{}", b.markdown);
    }
    if let Some(spec) = six_spec {
        let motion = block_overrides(&a.plan.set)?.sixdof;
        let odometry = a.sixdof.rgbd_odometry.as_deref();
        let b = table1_6dof::block(&spec, &motion, names, odometry, &progress)?;
        let run = serde_json::json!({ "spec": spec, "motion": motion, "rgbd_odometry": odometry });
        write(a, "table1_6dof", "6dof", &table1_6dof::ROWS, &b, run)?;
        println!("{}", b.markdown);
    }
    Ok(true)
}

/// `--variants` against the Table I blocks asked for: each block must get
/// at least one row (the 3-D block none with `--variants none` and
/// `--rgbd-odometry`, whose row it then is alone), and each name must be a
/// row of some experiment asked for (the sweep's tables' variants when no
/// block is). A name no block has would otherwise leave a block empty or a
/// typo unnoticed.
fn check_variants(a: &BenchArgs) -> anyhow::Result<()> {
    let Some(list) = a.plan.variants.as_deref() else {
        return Ok(());
    };
    let e = &a.plan.experiments;
    let mut blocks: Vec<(&str, Vec<&str>)> = Vec::new();
    if e.contains(&Experiment::Table1Floorplan) {
        blocks.push(("table1-floorplan", table1_floorplan::row_names()));
    }
    if e.contains(&Experiment::Table1Sixdof) {
        blocks.push(("table1-sixdof", table1_6dof::ROWS.to_vec()));
    }
    let named: Vec<&str> = list.split(',').map(str::trim).collect();
    let odometry_alone = named == ["none"] && a.sixdof.rgbd_odometry.is_some();
    for (name, rows) in &blocks {
        let alone = *name == "table1-sixdof" && odometry_alone;
        anyhow::ensure!(
            alone || rows.iter().any(|r| named.contains(r)),
            "--variants {list:?} names no row of {name}; its rows are {}{}",
            rows.join(", "),
            if *name == "table1-sixdof" {
                " (or `none` with --rgbd-odometry for that row alone)"
            } else {
                ""
            }
        );
    }
    // Other experiments asked for take the variants of the sweep's tables.
    let others = e
        .iter()
        .any(|x| !matches!(x, Experiment::Table1Floorplan | Experiment::Table1Sixdof));
    let sweep = omcl::experiment::variant::TABLE1_VARIANTS.map(|v| v.name);
    let mut known: Vec<&str> = Vec::new();
    for n in blocks
        .iter()
        .flat_map(|(_, r)| r.iter().copied())
        .chain(sweep.into_iter().filter(|_| others))
        .chain(odometry_alone.then_some("none"))
    {
        if !known.contains(&n) {
            known.push(n);
        }
    }
    for n in &named {
        anyhow::ensure!(
            known.contains(n),
            "--variants: no row {n:?} in the experiments asked for; their rows are {}",
            known.join(", ")
        );
    }
    Ok(())
}

/// The 6-DoF block's filters: the frame-built maps' and the point-cloud
/// map's.
fn six_dof_filters() -> [FilterConfig; 3] {
    [
        FilterConfig::six_dof(),
        FilterConfig::six_dof_point_cloud(),
        FilterConfig::six_dof(),
    ]
}

/// The 2-D block's filters: [`FilterConfig::floor_plan`], the same for the
/// point-cloud row, [`FilterConfig::floor_plan_raw_features`] for the
/// raw-feature row.
fn floor_plan_filters() -> [FilterConfig; 3] {
    [
        FilterConfig::floor_plan(),
        FilterConfig::floor_plan_point_cloud(),
        FilterConfig::floor_plan_raw_features(),
    ]
}

/// The block's sequences and filters: `base` (the rows', the point-cloud
/// row's and the raw-feature row's: [`floor_plan_filters`],
/// [`six_dof_filters`]) with `--rays` and `--set` applied to each, and
/// `--particles` or the block's `particles` ([`INDOOR_PARTICLES`],
/// [`SIX_DOF_PARTICLES`]).
fn block_spec(
    a: &BenchArgs,
    base: [FilterConfig; 3],
    particles: usize,
) -> anyhow::Result<BlockSpec> {
    let overrides = block_overrides(&a.plan.set)?;
    let PlanSettings { plan, two_d } = overrides.plan_settings()?;
    let rest = overrides.rest;
    let [filter, point_cloud_filter, raw_feature_filter] = base.map(|mut f| {
        if let Some(r) = a.plan.rays {
            f.sampling.rays = r;
        }
        super::bench_args::apply_overrides(f, &rest)
    });
    let (filter, point_cloud_filter, raw_feature_filter) =
        (filter?, point_cloud_filter?, raw_feature_filter?);
    Ok(BlockSpec {
        seeds: a.plan.first_seed..a.plan.first_seed + a.plan.sequences,
        world: a.plan.world,
        frames: a.plan.frames,
        map_params: omcl::experiment::MapParams {
            frames: a.plan.map_frames,
            ..Default::default()
        },
        filter,
        point_cloud_filter,
        raw_feature_filter,
        particles: a.plan.particles.unwrap_or(particles),
        plan,
        two_d,
        compare_3d: true,
        preset: a.plan.preset,
    })
}

/// Writes `<out>/<name>.md`, `<name>.json` and each row's Figure 4,
/// `figure4_<tag>_<variant>.png` and `.svg` (the variant's name without
/// `*`).
fn write(
    a: &BenchArgs,
    name: &str,
    tag: &str,
    block_rows: &[&str],
    b: &BlockResult,
    mut run: serde_json::Value,
) -> anyhow::Result<()> {
    // SeDAR*_GT -> SeDAR_GT: no shell pattern in a file name.
    let stem = |variant: &str| format!("figure4_{tag}_{}", variant.replace('*', ""));
    let stems: Vec<String> = b.rows.iter().map(|row| stem(&row.variant)).collect();
    let known: Vec<String> = block_rows.iter().map(|v| stem(v)).collect();
    remove_stale_figures(&a.out, name, &known, &stems)?;
    let p = a.out.join(format!("{name}.md"));
    omcl::io::atomic::write(&p, b.markdown.as_bytes())
        .with_context(|| format!("writing {}", p.display()))?;
    let p = a.out.join(format!("{name}.json"));
    omcl::io::atomic::write(&p, serde_json::to_string_pretty(&b.rows)?.as_bytes())
        .with_context(|| format!("writing {}", p.display()))?;
    for (stem, panels) in stems.iter().zip(&b.figures) {
        write_figure4(&a.out, stem, panels)
            .with_context(|| format!("drawing {}", a.out.join(stem).display()))?;
    }
    write_trajectories(&a.out.join(format!("{name}_trajectories")), b)?;
    // What ran, to run it again: the command, the build, the block's
    // sequences and filters.
    run["omcl"] = serde_json::json!(env!("CARGO_PKG_VERSION"));
    run["command"] = serde_json::json!(std::env::args().collect::<Vec<_>>());
    run["rows"] = serde_json::json!(b.rows.iter().map(|r| &r.variant).collect::<Vec<_>>());
    run["seeds"] = serde_json::json!(b.truths.iter().map(|(s, _)| s).collect::<Vec<_>>());
    let p = a.out.join(format!("{name}.run.json"));
    omcl::io::atomic::write(&p, serde_json::to_string_pretty(&run)?.as_bytes())
        .with_context(|| format!("writing {}", p.display()))?;
    Ok(())
}

/// Writes each sequence's ground truth and each row's estimate as TUM
/// files, stamped at 30 frames a second as `--export-frames` stamps its
/// `poses.txt`, so that `omcl eval ape` (or evo) scores any row again:
/// `DIR/seq_<seed>/groundtruth.txt` and `DIR/seq_<seed>/<row>.txt` (the
/// row's name without `*`). The folder of an earlier run is replaced
/// whole when it holds only such files; anything else in it is refused.
fn write_trajectories(dir: &std::path::Path, b: &BlockResult) -> anyhow::Result<()> {
    use omcl::io::poses::PoseFormat;
    use omcl::sim::files::pose_lines;
    if dir.exists() {
        let ours = std::fs::read_dir(dir)?.flatten().all(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            e.file_type().is_ok_and(|t| t.is_dir())
                && name.starts_with("seq_")
                && std::fs::read_dir(e.path()).is_ok_and(|d| {
                    d.flatten().all(|f| {
                        f.file_type().is_ok_and(|t| t.is_file())
                            && f.file_name().to_string_lossy().ends_with(".txt")
                    })
                })
        });
        anyhow::ensure!(
            ours,
            "{}: holds files of its own (not only seq_*/ folders of .txt trajectories); \
             move them away, the bench writes its trajectories there",
            dir.display()
        );
        std::fs::remove_dir_all(dir).with_context(|| format!("removing {}", dir.display()))?;
    }
    for (k, (seed, truth)) in b.truths.iter().enumerate() {
        let d = dir.join(format!("seq_{seed}"));
        std::fs::create_dir_all(&d).with_context(|| format!("creating {}", d.display()))?;
        let mut files = vec![("groundtruth".to_string(), truth.as_slice())];
        for row in &b.rows {
            if let Some(r) = row.per_sequence.get(k) {
                let name = match row.variant.as_str() {
                    table1_6dof::ODOMETRY_ROW => "rgbd_odometry".to_string(),
                    v => v.replace('*', ""),
                };
                files.push((name, r.estimates.as_slice()));
            }
        }
        for (name, poses) in files {
            let p = d.join(format!("{name}.txt"));
            omcl::io::atomic::write(&p, pose_lines(poses, PoseFormat::Tum, 30.0).as_bytes())
                .with_context(|| format!("writing {}", p.display()))?;
        }
    }
    Ok(())
}

/// Removes the block's Figure 4 files of an earlier run in `out` (the
/// `known` stems of the block's rows, `.png` or `.svg`, drawn by omcl)
/// whose rows this run does not write (`stems`): a second run of other
/// variants into the same folder had left the first run's figures beside
/// a table without their rows. No other file is touched (a renamed copy,
/// a figure of `omcl localize --plot`). Said when any is removed.
fn remove_stale_figures(
    out: &std::path::Path,
    name: &str,
    known: &[String],
    stems: &[String],
) -> anyhow::Result<()> {
    let Ok(entries) = std::fs::read_dir(out) else {
        return Ok(());
    };
    let mut removed = Vec::new();
    for e in entries.flatten() {
        let p = e.path();
        let file = e.file_name().to_string_lossy().into_owned();
        let stem = p.file_stem().and_then(|f| f.to_str()).unwrap_or("");
        let stale = (file.ends_with(".png") || file.ends_with(".svg"))
            && known.iter().any(|k| k == stem)
            && !stems.iter().any(|s| s == stem)
            && e.file_type().is_ok_and(|t| t.is_file())
            && omcl::plot::is_omcl_figure(&p);
        if stale {
            std::fs::remove_file(&p).with_context(|| format!("removing {}", p.display()))?;
            removed.push(file);
        }
    }
    if !removed.is_empty() {
        removed.sort();
        println!(
            "note: {}: {name}.md of an earlier run is replaced; its Figure 4 files of rows not \
             run now are removed: {}",
            out.display(),
            removed.join(", ")
        );
    }
    Ok(())
}
