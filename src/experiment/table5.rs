//! Table V: steps until global localization reaches each accuracy, from
//! start frames spread over each sequence, without and with a prompt drawn
//! as the paper draws them (words of the objects around the start).

use std::fmt::Write as _;
use std::sync::Arc;

use super::ExperimentError;
use super::cells::{Ctx, write_json};
use super::features::feature_model;
use super::mapping::BenchMap;
pub use super::run::{GlobalRun, GlobalSpec};
use super::run::{RunSpec, Start, run_on};
use super::sequence::SimSequence;
use super::task::{Outcome, Planner, SweepError, Task, Use, Work};
use super::variant::Variant;
use crate::eval::localization::CONVERGENCE_THRESHOLDS;
use crate::mcl::FilterConfig;
use crate::session::SharedMap;

/// Global localization (Table V): from `spec.starts` start frames of `seq`,
/// the filter starts over all floor voxels (`prompt: false`) or over the
/// floor voxels matching a prompt of 3 to 5 object classes found within 2 m
/// of the start (`prompt: true`, as the paper draws its prompts), and runs
/// for at most `max_steps` frames. Returns, per start, the steps to reach each
/// of [`crate::eval::localization::CONVERGENCE_THRESHOLDS`].
///
/// With `spec.floor_plan` the runs are in 2-D on the map's floor plan
/// (Table I's 2-D scene, [`super::table1_floorplan::plan_scene`] with its
/// settings, by default the band and sight `omcl localize --floorplan`
/// projects with): the
/// particles start level over the same 3-D map's floor voxels, at the
/// floor's camera height, and the errors are horizontal.
pub fn global_runs(
    seq: &SimSequence,
    map: &BenchMap,
    spec: &GlobalSpec,
) -> Result<Vec<GlobalRun>, ExperimentError> {
    use crate::eval::localization::{CONVERGENCE_THRESHOLDS, steps_to_reach};
    let GlobalSpec {
        preset,
        filter,
        particles,
        starts,
        max_steps,
        prompt,
        floor_plan,
    } = *spec;
    let model = feature_model(seq, preset, 0x10c);
    let shared = Arc::new(match floor_plan {
        Some(s) => {
            let scene = super::table1_floorplan::plan_scene(map, &s.plan, &seq.table, &s.two_d)?;
            SharedMap::floor_plan("floor plan", scene).with_floor_map(Arc::new(map.map.clone()))
        }
        None => SharedMap::from_parts("benchmark", map.map.clone(), map.caster.clone()),
    });
    let span = seq.len().saturating_sub(max_steps).max(1);
    let mut out = Vec::new();
    for s in 0..starts {
        let first = s * span / starts.max(1);
        let words = if prompt {
            prompt_words(seq, first, 0x5eed ^ s as u64)
        } else {
            Vec::new()
        };
        let start = if prompt {
            Start::Prompt(words.clone())
        } else {
            Start::Global
        };
        let spec = RunSpec {
            filter: FilterConfig {
                seed: filter.seed ^ (s as u64).wrapping_mul(0x9e37_79b9),
                ..filter
            },
            particles,
            start,
            first,
            frames: max_steps,
            preset,
            encoder_stride: 1,
        };
        let (steps, error) = match run_on(seq, shared.clone(), &model, &spec) {
            Ok(r) => (steps_to_reach(&r.errors_m, &CONVERGENCE_THRESHOLDS), None),
            Err(ExperimentError::Filter(e)) => (
                vec![None; CONVERGENCE_THRESHOLDS.len()],
                Some(e.to_string()),
            ),
            Err(e) => return Err(e),
        };
        out.push(GlobalRun {
            first,
            words,
            steps,
            error,
        });
    }
    Ok(out)
}

/// A prompt as the paper draws them: 3 to 5 words (`seed` picks how many
/// and which) drawn at random from the probable words of the start, frame
/// `first` of `seq`: the object classes (not walls, floor, ceiling, doors,
/// windows) that the world's ground truth has within the prompt radius R
/// (the paper's 2 m, horizontally) of the camera, whether or not the map
/// holds them or the initialization finds them. Fewer when fewer are
/// there; empty when none are (the run then reports that the prompt could
/// not place particles). No map is consulted.
pub fn prompt_words(seq: &SimSequence, first: usize, seed: u64) -> Vec<String> {
    use rand::SeedableRng;
    use rand::seq::SliceRandom;
    use std::collections::BTreeSet;
    let radius = crate::mcl::PromptParams::default().radius;
    let world = &seq.scene.world.voxels;
    let cam = seq.poses()[first].translation.vector;
    let mut present: BTreeSet<u16> = BTreeSet::new();
    for (c, &l) in world.cells.iter().zip(&world.labels) {
        let p = world.cell_centre(*c);
        if (p.x - cam.x).hypot(p.y - cam.y) <= radius {
            present.insert(l);
        }
    }
    let mut candidates: Vec<String> = present
        .into_iter()
        .filter_map(|l| world.classes.get(l as usize))
        .filter(|n| {
            !crate::sim::features::STUFF_CLASSES
                .iter()
                .any(|s| s.eq_ignore_ascii_case(n))
                && *n != "door"
                && *n != "window"
                && seq.table.text_feature(n).is_some()
        })
        .cloned()
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    candidates.shuffle(&mut rng);
    candidates.truncate(3 + (seed % 3) as usize);
    candidates
}

/// Steps statistics of one threshold over runs (Table V's row).
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct StepsRow {
    pub threshold_m: f64,
    /// Over the runs that reached the threshold; `None` if none did.
    pub mean: Option<f64>,
    pub std: Option<f64>,
    pub min: Option<usize>,
    pub max: Option<usize>,
    /// Runs that reached the threshold, of all runs.
    pub reached: usize,
    pub runs: usize,
}

/// Table V rows from global runs: statistics over the runs that reached
/// each threshold (population std).
pub fn steps_rows(runs: &[GlobalRun]) -> Vec<StepsRow> {
    use crate::eval::localization::CONVERGENCE_THRESHOLDS;
    CONVERGENCE_THRESHOLDS
        .iter()
        .enumerate()
        .map(|(t, &threshold_m)| {
            let s: Vec<usize> = runs
                .iter()
                .filter_map(|r| r.steps.get(t).copied().flatten())
                .collect();
            let stats = crate::eval::ErrorStats::from_errors(
                &s.iter().map(|&x| x as f64).collect::<Vec<_>>(),
            );
            StepsRow {
                threshold_m,
                mean: stats.map(|x| x.mean),
                std: stats.map(|x| x.std),
                min: s.iter().copied().min(),
                max: s.iter().copied().max(),
                reached: s.len(),
                runs: runs.len(),
            }
        })
        .collect()
}

impl Ctx<'_> {
    /// Table V (`floor_plan`: on the floor plan, in 2-D) as Markdown, and
    /// `table5.json` (`table5_floorplan.json`).
    pub(super) fn table5(&self, floor_plan: bool) -> Result<String, SweepError> {
        let v = self.bench.ablation()?;
        let all: Vec<(bool, Vec<GlobalRun>)> = [false, true]
            .into_iter()
            .map(|prompt| {
                let runs = self
                    .records(&Use::Table5 { prompt, floor_plan })
                    .filter_map(|r| match &r.outcome {
                        Outcome::Global(g) => Some(g.clone()),
                        _ => None,
                    })
                    .flatten()
                    .collect();
                (prompt, runs)
            })
            .collect();
        let table: Vec<_> = all
            .iter()
            .map(|(p, runs)| serde_json::json!({"prompt": p, "rows": steps_rows(runs), "runs": runs}))
            .collect();
        let (file, title, errors) = match floor_plan {
            false => ("table5.json", "Table V", String::new()),
            true => (
                "table5_floorplan.json",
                "Table V on the floor plan (2-D: x, y, yaw)",
                format!(
                    "; {} rays, horizontal errors{}",
                    self.bench.two_d_filter().sampling.rays,
                    self.bench
                        .floor_plan_scene
                        .map_or(String::new(), |s| format!(
                            "; plans of the band {:.2} to {:.2} m{}",
                            s.plan.band_min,
                            s.plan.band_max,
                            if s.two_d == Default::default() {
                                ""
                            } else {
                                ", two_d.* as --set gave them (the manifest's floor_plan_scene)"
                            }
                        ))
                ),
            ),
        };
        write_json(&self.out.join(file), &table)?;
        let mut s = format!(
            "## {title}: steps until global localization reaches each accuracy ({}, {} runs of at most {} steps{errors})\n\n\
             | start | accuracy | mean | std | min | max | reached |\n|---|---|---|---|---|---|---|\n",
            v.name,
            all.first().map_or(0, |x| x.1.len()),
            self.bench.max_steps
        );
        for (prompt, runs) in &all {
            for r in steps_rows(runs) {
                let f = |x: Option<f64>| x.map_or("-".into(), |x| format!("{x:.1}"));
                let _ = writeln!(
                    s,
                    "| {} | {} m | {} | {} | {} | {} | {}/{} |",
                    if *prompt { "prompt" } else { "global" },
                    r.threshold_m,
                    f(r.mean),
                    f(r.std),
                    f(r.min.map(|x| x as f64)),
                    f(r.max.map(|x| x as f64)),
                    r.reached,
                    r.runs
                );
            }
        }
        let _ = writeln!(
            s,
            "\nThresholds: {CONVERGENCE_THRESHOLDS:?} m; a run counts for a threshold once its error first falls to or below it.\n"
        );
        Ok(s)
    }
}

/// Plans Table V: global runs on each sequence, without and with a prompt;
/// with `floor_plan` on the floor plan, with the 2-D filter
/// ([`super::task::BenchPlan::two_d_filter`]) and the plans' settings
/// ([`super::task::BenchPlan::floor_plan_scene`]).
pub(super) fn plan(p: &Planner, v: &Variant, floor_plan: bool, out: &mut Vec<(Task, Use)>) {
    let filter = match floor_plan {
        true => p.bench.two_d_filter(),
        false => p.bench.filter,
    };
    for prompt in [false, true] {
        for s in p.bench.seeds() {
            let work = Work::Global {
                filter: FilterConfig { seed: s, ..filter },
                particles: p.bench.particles,
                starts: p.bench.starts,
                max_steps: p.bench.max_steps,
                prompt,
                floor_plan,
                plan: p.bench.floor_plan_scene.filter(|_| floor_plan),
            };
            out.push((p.task(s, v, work), Use::Table5 { prompt, floor_plan }));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::features::builtin_table;

    /// Table V's statistics by hand: steps 2, 4 and 9 at 2 m (mean 5,
    /// population std sqrt(26 / 3)), one run of three at 0.1 m, none at 1 m.
    #[test]
    fn steps_rows_by_hand() {
        let run = |steps: Vec<Option<usize>>| GlobalRun {
            first: 0,
            words: Vec::new(),
            steps,
            error: None,
        };
        let runs = [
            run(vec![Some(2), None, None, None, None]),
            run(vec![Some(4), None, Some(5), Some(6), Some(7)]),
            run(vec![Some(9), None, None, None, None]),
        ];
        let rows = steps_rows(&runs);
        assert_eq!(rows.len(), 5);
        assert_eq!(rows[0].threshold_m, 2.0);
        assert_eq!(rows[0].mean, Some(5.0));
        assert!((rows[0].std.unwrap() - (26.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!((rows[0].min, rows[0].max), (Some(2), Some(9)));
        assert_eq!((rows[0].reached, rows[0].runs), (3, 3));
        assert_eq!(
            (rows[1].mean, rows[1].std, rows[1].reached),
            (None, None, 0)
        );
        assert_eq!((rows[4].mean, rows[4].std), (Some(7.0), Some(0.0)));
        assert_eq!(rows[4].reached, 1);
    }

    /// Prompt words are 3 to 5 distinct object classes that the ground
    /// truth has within the prompt radius of the start, chosen without the
    /// map; where the map and the initialization agree with the words, the
    /// initialization places particles.
    #[test]
    fn prompt_words_come_from_the_ground_truth_around_the_start() {
        let table = builtin_table().unwrap();
        let seq = SimSequence::generate(3, 40, &table).unwrap();
        let world = &seq.scene.world.voxels;
        let radius = crate::mcl::PromptParams::default().radius;
        let mut nonempty = 0;
        for first in [0, 13, 27, 39] {
            let cam = seq.poses()[first].translation.vector;
            for seed in 0..6u64 {
                let words = prompt_words(&seq, first, seed);
                assert!(words.len() <= 3 + (seed % 3) as usize, "{words:?}");
                for (i, word) in words.iter().enumerate() {
                    assert!(!words[..i].contains(word), "{words:?}");
                    assert!(
                        !crate::sim::features::STUFF_CLASSES.contains(&word.as_str()),
                        "{word}"
                    );
                    // Some voxel of the class lies within R of the camera.
                    let id = world.classes.iter().position(|n| n == word).unwrap() as u16;
                    let near = world.cells.iter().zip(&world.labels).any(|(c, &l)| {
                        let p = world.cell_centre(*c);
                        l == id && (p.x - cam.x).hypot(p.y - cam.y) <= radius
                    });
                    assert!(near, "start {first}: {word} is not within {radius} m");
                }
                // The same seed draws the same prompt.
                assert_eq!(words, prompt_words(&seq, first, seed));
                nonempty += usize::from(!words.is_empty());
            }
        }
        assert!(nonempty >= 12, "only {nonempty} of 24 prompts have words");
    }
}
