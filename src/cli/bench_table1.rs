//! `omcl bench table1-floorplan` and `omcl bench table1-6dof`: Table I's
//! 2-D block (floor plans; OMCL and the SeDAR* and SIMP* baselines) and
//! its 3-D block (full 6-DoF pose), run in this process beside the
//! paper's rows, written as Markdown and JSON into `<out>/`.

use std::fmt::Write as _;

use anyhow::Context;

use omcl::experiment::run::TrackingRow;
use omcl::experiment::table1_6dof::{self, SixDofMotion};
use omcl::experiment::table1_floorplan::{self, BlockSpec};
use omcl::experiment::variant::TABLE1_VARIANTS;
use omcl::map::FloorPlanParams;
use omcl::mcl::baselines::Baseline;

use super::bench_args::{BenchArgs, Experiment};

/// The paper's 2-D rows: name, RMSE, STD, Mean, Median, min, max, SSE,
/// completed.
const PAPER_2D: [(&str, [f64; 7], &str); 6] = [
    (
        "OMCL_GT",
        [0.11, 0.07, 0.09, 0.08, 0.08, 0.18, 17.38],
        "10/10",
    ),
    (
        "OMCL_LSeg",
        [0.15, 0.09, 0.13, 0.12, 0.11, 0.28, 33.07],
        "10/10",
    ),
    (
        "OMCL_auto_LSeg",
        [0.24, 0.15, 0.18, 0.15, 0.14, 0.52, 95.0],
        "10/10",
    ),
    (
        "OMCL_Open_LSeg",
        [0.36, 0.24, 0.27, 0.22, 0.15, 0.62, 164.07],
        "8/10",
    ),
    (
        "SeDAR*_GT",
        [0.79, 0.46, 0.64, 0.54, 0.24, 2.33, 1891.2],
        "6/10",
    ),
    (
        "SIMP*_GT",
        [1.39, 1.03, 0.79, 0.94, 0.45, 2.81, 2898.15],
        "4/10",
    ),
];

/// The paper's 3-D rows.
const PAPER_3D: [(&str, [f64; 7], &str); 4] = [
    ("OMCL_GT", [0.15, 0.09, 0.12, 0.1, 0.1, 0.3, 30.45], "10/10"),
    (
        "OMCL_LSeg",
        [0.2, 0.1, 0.18, 0.17, 0.17, 0.41, 59.53],
        "10/10",
    ),
    (
        "OMCL_Open_LSeg",
        [0.42, 0.25, 0.31, 0.25, 0.22, 0.75, 223.32],
        "8/10",
    ),
    (
        "RTAB-Map",
        [5.23, 2.97, 4.30, 3.6, 0.31, 8.14, 25781.93],
        "10/10",
    ),
];

/// Rows of ours and the paper's, one Markdown table.
pub fn markdown(title: &str, ours: &[TrackingRow], paper: &[(&str, [f64; 7], &str)]) -> String {
    let mut s = format!(
        "## {title}\n\n| variant | RMSE | STD | Mean | Median | min RMSE | max RMSE | SSE (m^2) | completed | steps/s |\n|---|---|---|---|---|---|---|---|---|---|\n"
    );
    for r in ours {
        if let Some(m) = &r.summary {
            let _ = writeln!(
                s,
                "| {}, omcl | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {}/{} | {:.1} |",
                r.variant,
                m.mean.rmse,
                m.mean.std,
                m.mean.mean,
                m.mean.median,
                m.min_rmse,
                m.max_rmse,
                m.mean.sse,
                r.completed,
                r.per_sequence.len(),
                r.fps
            );
        }
        for p in paper.iter().filter(|p| p.0 == r.variant) {
            let v = p.1;
            let _ = writeln!(
                s,
                "| {}, paper | {} | {} | {} | {} | {} | {} | {} | {} | |",
                p.0, v[0], v[1], v[2], v[3], v[4], v[5], v[6], p.2
            );
        }
    }
    s
}

/// Runs the Table I blocks `a` asks for; returns whether any ran.
pub fn run(a: &BenchArgs) -> anyhow::Result<bool> {
    let e = &a.plan.experiments;
    let mut ran = false;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    if e.contains(&Experiment::Table1Floorplan) {
        let spec = block_spec(a)?;
        let variants: Vec<_> = TABLE1_VARIANTS
            .iter()
            .filter(|v| v.name != "OMCL_GT_exact")
            .filter(|v| {
                a.plan
                    .variants
                    .as_deref()
                    .is_none_or(|s| s.split(',').any(|x| x.trim() == v.name))
            })
            .copied()
            .collect();
        let baselines: Vec<Baseline> = [Baseline::Sedar, Baseline::Simp]
            .into_iter()
            .filter(|b| {
                a.plan
                    .variants
                    .as_deref()
                    .is_none_or(|s| s.split(',').any(|x| x.trim() == b.name()))
            })
            .collect();
        let rows =
            table1_floorplan::omcl_rows(&spec, &variants, &baselines, &|m| eprintln!("{m}"))?;
        let md = markdown(
            "Table I, 2-D block: APE (m, horizontal) on floor plans",
            &rows,
            &PAPER_2D,
        );
        write(a, "table1_floorplan", &md, &rows)?;
        println!("{md}");
        ran = true;
    }
    if e.contains(&Experiment::Table1Sixdof) {
        let spec = block_spec(a)?;
        let variants: Vec<_> = TABLE1_VARIANTS
            .iter()
            .filter(|v| ["OMCL_GT", "OMCL_LSeg", "OMCL_Open_LSeg"].contains(&v.name))
            .filter(|v| {
                a.plan
                    .variants
                    .as_deref()
                    .is_none_or(|s| s.split(',').any(|x| x.trim() == v.name))
            })
            .copied()
            .collect();
        let rows = table1_6dof::rows_3d(&spec, &SixDofMotion::default(), &variants, &|m| {
            eprintln!("{m}")
        })?;
        let md = markdown(
            "Table I, 3-D block: APE (m) of the full 6-DoF pose",
            &rows,
            &PAPER_3D,
        );
        write(a, "table1_6dof", &md, &rows)?;
        println!("{md}");
        ran = true;
    }
    Ok(ran)
}

fn block_spec(a: &BenchArgs) -> anyhow::Result<BlockSpec> {
    Ok(BlockSpec {
        seeds: a.plan.first_seed..a.plan.first_seed + a.plan.sequences,
        frames: a.plan.frames,
        map_params: omcl::experiment::MapParams {
            frames: a.plan.map_frames,
            ..Default::default()
        },
        filter: a.plan.filter()?,
        particles: a.plan.particles.unwrap_or(1024),
        plan: FloorPlanParams::default(),
        two_d: Default::default(),
        compare_3d: true,
    })
}

fn write(a: &BenchArgs, name: &str, md: &str, rows: &[TrackingRow]) -> anyhow::Result<()> {
    let p = a.out.join(format!("{name}.md"));
    std::fs::write(&p, md).with_context(|| format!("writing {}", p.display()))?;
    let p = a.out.join(format!("{name}.json"));
    std::fs::write(&p, serde_json::to_string_pretty(rows)?)
        .with_context(|| format!("writing {}", p.display()))?;
    Ok(())
}
