//! `omcl bench sevenscenes`: the real sensor track (7-Scenes "redkitchen",
//! Kinect v1), mapped and localized with the colour-class encoder, with
//! and without the depth-edge filter, written as Markdown, JSON and a
//! trajectory figure into `<out>/`.

use std::path::{Path, PathBuf};

use anyhow::Context;

use omcl::experiment::sevenscenes::{self, TrackResult, TrackSpec};
use omcl::io::sevenscenes::SevenScenes;

use super::bench_args::{BenchArgs, Experiment};

/// The two mappings compared: all depth, and depth edges dropped.
fn variants(a: &BenchArgs) -> Vec<(&'static str, Option<usize>)> {
    vec![
        ("all depth", None),
        ("depth edges dropped", Some(a.scenes.edge_radius)),
    ]
}

fn default_scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/rgbd_7scenes")
}

/// Runs the track if `a` asks for it; returns whether it ran.
pub fn run(a: &BenchArgs) -> anyhow::Result<bool> {
    if !a.plan.experiments.contains(&Experiment::SevenScenes) {
        return Ok(false);
    }
    let s = &a.scenes;
    let dir = s.scenes.clone().unwrap_or_else(default_scenes);
    let seq = SevenScenes::open(&dir)?;
    super::outputs::create_folder("--out", &a.out)?;
    let seeds: Vec<u64> = s
        .scenes_seeds
        .split(',')
        .map(|v| v.trim().parse::<u64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--scenes-seeds {:?}: expected numbers", s.scenes_seeds))?;
    anyhow::ensure!(!seeds.is_empty(), "--scenes-seeds is empty");
    anyhow::ensure!(
        s.colour_shift.len() == 2,
        "--colour-shift takes DX,DY (two whole numbers of pixels), got {:?}",
        s.colour_shift
    );
    let mut spec = TrackSpec {
        frames: s.scenes_frames,
        localize_every: s.localize_every,
        classes: s.colour_classes,
        colour_shift: (s.colour_shift[0], s.colour_shift[1]),
        particles: a.plan.particles.unwrap_or(omcl::mcl::INDOOR_PARTICLES),
        rays: a
            .plan
            .rays
            .unwrap_or(omcl::mcl::FilterConfig::default().sampling.rays),
        ..TrackSpec::default()
    };
    let n = seq.len().min(spec.frames.unwrap_or(usize::MAX));
    let (mapping, localized) = sevenscenes::split(n, spec.localize_every);
    // Checked before the model is written: a run that cannot localize
    // leaves nothing behind.
    anyhow::ensure!(
        localized.len() >= 2,
        "{}: {n} frames leave {} to localize with --localize-every {}; need 2 or more",
        dir.display(),
        localized.len(),
        spec.localize_every
    );
    let model = sevenscenes::default_model_path(&a.out);
    let classes = sevenscenes::fit_colour_model(&seq, &mapping, &spec, &model)?;
    eprintln!(
        "{} colour classes fitted, model {}",
        classes.len(),
        model.display()
    );
    let progress = |m: &str| eprintln!("{m}");
    let mut rows: Vec<(String, u64, TrackResult)> = Vec::new();
    for (name, edge) in variants(a) {
        spec.edge_radius = edge;
        for &seed in &seeds {
            spec.seed = seed;
            let r = sevenscenes::run_track(&seq, &spec, &classes, &model, None, &progress)?;
            eprintln!(
                "{name}, seed {seed}: APE rmse {:.3} m, max {:.3}, completed {}",
                r.ape.rmse,
                r.ape.max,
                omcl::eval::CompletionRule::default().verdict(r.completed)
            );
            rows.push((name.to_string(), seed, r));
        }
    }
    let md = markdown(&dir, &spec, &rows);
    omcl::io::atomic::write(&a.out.join("sevenscenes.md"), md.as_bytes())
        .with_context(|| format!("writing {}", a.out.join("sevenscenes.md").display()))?;
    let json = serde_json::json!({
        "spec": spec,
        "colour_classes": classes,
        "runs": rows.iter().map(|(v, s, r)| serde_json::json!({"variant": v, "seed": s, "result": r})).collect::<Vec<_>>(),
    });
    let p = a.out.join("sevenscenes.json");
    omcl::io::atomic::write(&p, serde_json::to_string_pretty(&json)?.as_bytes())
        .with_context(|| format!("writing {}", p.display()))?;
    for (k, (name, _)) in variants(a).iter().enumerate() {
        if let Some((_, seed, r)) = rows.iter().find(|(v, ..)| v == name) {
            let p = a.out.join(format!("sevenscenes_{k}.png"));
            plot(&p, &format!("7-Scenes redkitchen, {name}, seed {seed}"), r)?;
        }
    }
    println!("{md}");
    Ok(true)
}

fn plot(p: &Path, title: &str, r: &TrackResult) -> anyhow::Result<()> {
    let xy = |v: &[omcl::geometry::Pose]| -> Vec<[f64; 2]> {
        v.iter()
            .map(|p| [p.translation.vector.x, p.translation.vector.y])
            .collect()
    };
    let title = format!("{title} (APE rmse {:.3} m)", r.ape.rmse);
    omcl::plot::trajectory_plot(
        p,
        &omcl::plot::TrajectoryPanel {
            title: &title,
            plan: None,
            gt_xy: &xy(&r.ground_truth),
            est_xy: &xy(&r.estimate),
            errors_m: &r.errors_m,
        },
    )?;
    Ok(())
}

fn markdown(dir: &Path, spec: &TrackSpec, rows: &[(String, u64, TrackResult)]) -> String {
    let mut s = String::new();
    if let Some((_, _, r)) = rows.first() {
        s += &format!(
            "7-Scenes {}: map from {} even frames, {} odd frames localized (every {}th), \
             {:.3} m and {:.1} deg of motion a step, odometry noise {:.3} m and {:.2} deg per \
             axis, start 0.3 m / 17 deg, {} particles x {} rays, {} colour classes\n\n",
            dir.display(),
            r.map_frames,
            r.localized.len(),
            spec.localize_every,
            r.step_motion.0,
            r.step_motion.1,
            r.odometry_sigma.0,
            r.odometry_sigma.1,
            spec.particles,
            spec.rays,
            spec.classes
        );
    }
    s += "| mapping | seed | APE rmse (m) | mean | median | max | rot. rmse (deg) | completed | accuracy | precision | recall | IoU | voxels | steps/s |\n";
    s += "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
    for (v, seed, r) in rows {
        let c = r.consistency;
        let f = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:.3}"));
        s += &format!(
            "| {v} | {seed} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {} | {} | {} | {} | {} | {} | {:.1} |\n",
            r.ape.rmse,
            r.ape.mean,
            r.ape.median,
            r.ape.max,
            r.ape_rotation_deg.rmse,
            match r.completed {
                Some(true) => "yes",
                Some(false) => "no",
                None => "not judged",
            },
            f(c.map(|c| c.accuracy)),
            f(c.map(|c| c.precision)),
            f(c.map(|c| c.recall)),
            f(c.map(|c| c.iou)),
            r.voxels,
            r.filter_steps_per_s
        );
    }
    s
}
