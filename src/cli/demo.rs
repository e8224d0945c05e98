//! `omcl demo`: the main job on the built-in synthetic world, end to end.
//!
//! Runs the same commands a user would type, in-process: generate an
//! apartment and an RGB-D sequence (`omcl sim indoor`), build a map from it
//! (`omcl map rgbd`), inspect it (`omcl map info`), localize the sequence in
//! it with the particle filter (`omcl localize`), evaluate the trajectory
//! (`omcl eval ape`), write a heat map of a word (`omcl map query`), then
//! outdoors: a street along the real KITTI 00 path (`omcl sim outdoor`),
//! its LiDAR map (`omcl map cloud`) and camera 2 localized in it from the
//! KITTI folder as it is (`omcl localize`); and reproduce Table I with its
//! figures on fresh apartments (`omcl bench`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use clap::{Args, Parser};

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Folder for the demo's outputs (created if missing).
    #[arg(long, default_value = "demo-out")]
    pub out: PathBuf,
    /// Seed of the synthetic world and of the filter (a held-out seed: no
    /// default was tuned on it).
    #[arg(long, default_value_t = omcl::experiment::seeds::FIRST_REPORTING + 7)]
    pub seed: u64,
    /// Frames of the synthetic sequence.
    #[arg(long, default_value_t = 120, value_parser = super::count_in::<1, 100_000>)]
    pub frames: usize,
    /// Sequences of the closing Table I run (0 skips it).
    #[arg(long, default_value_t = 2)]
    pub bench_sequences: u64,
    /// Frames of the outdoor part: a street along the real KITTI 00 path
    /// (300 frames: its first 216 m), camera 2 localized in the map of its
    /// LiDAR scans (0 skips it).
    #[arg(long, default_value_t = 300)]
    pub street_frames: usize,
}

fn step(title: &str, args: &[&str]) -> anyhow::Result<()> {
    println!("\n== {title}\n$ omcl {}", args.join(" "));
    let t = Instant::now();
    let cli = super::Cli::try_parse_from(std::iter::once("omcl").chain(args.iter().copied()))
        .with_context(|| format!("demo step {title}: bad arguments"))?;
    super::run(cli).with_context(|| format!("demo step {title}"))?;
    println!("   ({:.1} s)", t.elapsed().as_secs_f64());
    Ok(())
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

pub fn run(a: DemoArgs) -> anyhow::Result<()> {
    super::outputs::create_folder("--out", &a.out)?;
    let t = Instant::now();
    indoor(&a)?;
    if a.street_frames > 0 {
        outdoor(&a)?;
    }
    if a.bench_sequences > 0 {
        let n = a.bench_sequences.to_string();
        step(
            "7/7 the paper's Table I and Figure 4 on fresh synthetic apartments (omcl bench)",
            &[
                "bench",
                "table1",
                "--variants",
                "OMCL_GT,OMCL_LSeg,OMCL_Open_LSeg",
                "--sequences",
                &n,
                "--frames",
                "100",
                "--particles",
                "512",
                "-o",
                &s(&a.out.join("bench")),
            ],
        )?;
    }
    println!(
        "\ndemo done in {:.0} s; outputs in {}/",
        t.elapsed().as_secs_f64(),
        a.out.display()
    );
    Ok(())
}

/// Steps 1 to 6: an apartment and a camera path through it, its map, the
/// camera localized in it, the error, and a query.
fn indoor(a: &DemoArgs) -> anyhow::Result<()> {
    // The steps counted: the bench's seventh only when it runs.
    let total = if a.bench_sequences > 0 { 7 } else { 6 };
    let seq = a.out.join("apartment");
    let map = a.out.join("apartment.omcl");
    let est = a.out.join("estimate.txt");
    let (seed, frames) = (a.seed.to_string(), a.frames.to_string());
    let (classes, emb) = (s(&seq.join("classes.txt")), s(&seq.join("embeddings.npy")));
    step(
        &format!("1/{total} a synthetic apartment and a camera sequence through it"),
        &[
            "sim",
            "indoor",
            "--force",
            "--out",
            &s(&seq),
            "--seed",
            &seed,
            "--frames",
            &frames,
        ],
    )?;
    step(
        // The ceiling is kept: cropped, the camera's upward rays find nothing
        // to match their ceiling pixels (APE 0.18 m instead of 0.15 m here).
        &format!("2/{total} an Octree Language Map from the posed RGB-D frames"),
        &[
            "map",
            "rgbd",
            &s(&seq),
            "-o",
            &s(&map),
            "--resolution",
            "0.05",
        ],
    )?;
    step(
        &format!("3/{total} the map"),
        &["map", "info", &s(&map), "--top", "5"],
    )?;
    step(
        &format!(
            "4/{total} localization from 0.3 m / 17 deg around the first pose (1024 particles x 2048 rays)"
        ),
        &[
            "localize",
            "--map",
            &s(&map),
            "--sequence",
            &s(&seq),
            "-o",
            &s(&est),
            "--seed",
            &seed,
            "--diagnostics",
            &s(&a.out.join("diagnostics.csv")),
            "--plot",
            &s(&a.out.join("trajectory.png")),
            // The demo's own folder: its outputs of an older build
            // (figures without the mark) are replaced.
            "--force",
        ],
    )?;
    step(
        &format!("5/{total} the trajectory against ground truth (evo's statistics)"),
        &["eval", "ape", &s(&seq.join("poses.txt")), &s(&est)],
    )?;
    step(
        &format!("6/{total} where is the toilet? a heat map (open in CloudCompare or MeshLab)"),
        &[
            "map",
            "query",
            &s(&map),
            "toilet",
            "--classes",
            &classes,
            "--embeddings",
            &emb,
            "-o",
            &s(&a.out.join("toilet_heat.ply")),
        ],
    )?;
    Ok(())
}

/// The outdoor part: street, LiDAR map, camera-2 localization.
fn outdoor(a: &DemoArgs) -> anyhow::Result<()> {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/trajectories/KITTI_00_gt.txt");
    if !path.exists() {
        println!(
            "\n== outdoor part skipped: the KITTI 00 path {} is not here",
            path.display()
        );
        return Ok(());
    }
    let street = a.out.join("street");
    let seq = street.join("sequences").join("00");
    let map = a.out.join("street.omcl");
    let (seed, frames) = (a.seed.to_string(), a.street_frames.to_string());
    step(
        "outdoor 1/3 a street along the real KITTI 00 path: LiDAR scans, camera-2 labels",
        &[
            "sim",
            "outdoor",
            "--force",
            "--out",
            &s(&street),
            "--seed",
            &seed,
            "--frames",
            &frames,
            "--resolution",
            "0.1",
            "--path",
            &s(&path),
        ],
    )?;
    step(
        "outdoor 2/3 a map from the street's labelled LiDAR scans",
        &[
            "map",
            "cloud",
            &s(&seq),
            "--classes",
            &s(&street.join("semantickitti_ids.txt")),
            "--embeddings",
            &s(&street.join("embeddings.npy")),
            "-o",
            &s(&map),
            "--resolution",
            "0.1",
        ],
    )?;
    step(
        "outdoor 3/3 camera 2 localized from the KITTI folder as it is \
         (512 particles x 4096 rays, the authors' odometry noise)",
        &[
            "localize",
            "--map",
            &s(&map),
            "--sequence",
            &s(&seq),
            "-o",
            &s(&a.out.join("street_estimate.txt")),
            "--particles",
            "512",
            "--rays",
            "4096",
            "--seed",
            &seed,
            "--metrics",
            &s(&a.out.join("street_metrics.json")),
            "--plot",
            &s(&a.out.join("street_trajectory.png")),
            "--force",
        ],
    )
}
