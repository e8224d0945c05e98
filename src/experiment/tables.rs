//! The paper's experiments as functions from a benchmark (sequences and
//! their maps) to result rows. Tables are plain data (serde) so the CLI
//! can write them as JSON and Markdown.

use std::sync::Arc;

use super::ExperimentError;
use super::mapping::{MapParams, MapSource, build_map};
use super::run::{RunResult, RunSpec, Start, run};
use super::sequence::SimSequence;
use crate::eval::localization::{SequenceSummary, summarize_sequences};
use crate::map::LanguageMap;
use crate::mcl::FilterConfig;
use crate::mcl::SensorModel;
use crate::raycast::RayCaster;
use crate::sim::embeddings::ClassEmbeddings;
use crate::sim::features::{FeatureModel, Preset};

/// A map of a sequence's world with its ray caster.
pub struct BenchMap {
    pub source: MapSource,
    pub map: LanguageMap,
    pub caster: Arc<dyn RayCaster>,
}

impl BenchMap {
    /// Builds the map of `seq` from `source`.
    pub fn build(
        seq: &SimSequence,
        source: MapSource,
        params: &MapParams,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<Self, ExperimentError> {
        let model = match source {
            MapSource::Features(p) | MapSource::Auto(p) => Some(feature_model(seq, p, 0x3a9)),
            MapSource::PointCloud => Some(FeatureModel::new(
                seq.table.clone(),
                crate::sim::features::OPENSCENE_LIKE,
                seq.config.seed.wrapping_mul(0x9e37).wrapping_add(0x3d9),
            )),
            MapSource::Labels => None,
        };
        let map = build_map(seq, source, params, model.as_ref(), progress)?;
        Self::from_map(source, map)
    }

    /// A built (or loaded) map of `source` with its ray caster.
    pub fn from_map(source: MapSource, map: LanguageMap) -> Result<Self, ExperimentError> {
        let caster = Arc::new(SensorModel::embree_caster(
            map.grid().resolution as f32,
            &map.cells(),
        )?);
        Ok(BenchMap {
            source,
            map,
            caster,
        })
    }
}

/// The feature model of `preset` for `seq` (`salt` separates the mapping
/// stream from the localization stream).
pub fn feature_model(seq: &SimSequence, preset: Preset, salt: u64) -> FeatureModel {
    FeatureModel::preset(
        seq.table.clone(),
        preset,
        seq.config.seed.wrapping_mul(0x9e37).wrapping_add(salt),
    )
}

/// One variant of Table I: which map and which features localize.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Variant {
    pub name: &'static str,
    pub map: MapSource,
    pub localize: Preset,
}

/// The variants of Table I reproduced here: the paper's OMCL_GT (ground-truth
/// semantic images for both mapping and localization, as the paper defines
/// it: the simulator's `gt` preset, exact class embeddings with the label
/// bleed of real ground-truth images near boundaries), OMCL_LSeg
/// (`lseg-like`), the ungrounded OMCL_auto_LSeg (the same map without
/// grounding on the class names) and OMCL_Open_LSeg (a map from the fused
/// point cloud labelled by an OpenScene-like point encoder, localized with
/// `lseg-like` images), plus OMCL_GT_exact (a map of the world's true
/// labels, as a semantic mesh gives them, localized with every pixel's true
/// class embedding: no error at all, the bound the sensor model reaches).
pub const TABLE1_VARIANTS: [Variant; 5] = [
    Variant {
        name: "OMCL_GT",
        map: MapSource::Features(Preset::Gt),
        localize: Preset::Gt,
    },
    Variant {
        name: "OMCL_LSeg",
        map: MapSource::Features(Preset::LsegLike),
        localize: Preset::LsegLike,
    },
    Variant {
        name: "OMCL_auto_LSeg",
        map: MapSource::Auto(Preset::LsegLike),
        localize: Preset::LsegLike,
    },
    Variant {
        name: "OMCL_Open_LSeg",
        map: MapSource::PointCloud,
        localize: Preset::LsegLike,
    },
    Variant {
        name: "OMCL_GT_exact",
        map: MapSource::Labels,
        localize: Preset::Exact,
    },
];

/// One variant's tracking results over the sequences.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TrackingRow {
    pub variant: String,
    pub per_sequence: Vec<RunResult>,
    pub summary: Option<SequenceSummary>,
    pub completed: usize,
    /// Filter steps per second over all steps of all sequences (encoder
    /// excluded, as in the paper).
    pub fps: f64,
    /// Frames per second with the simulated encoder's work.
    pub fps_with_encoder: f64,
    /// Database rows (K) of the maps, mean over sequences.
    pub map_rows: f64,
}

impl TrackingRow {
    /// Gathers per-sequence results.
    pub fn new(variant: impl Into<String>, per_sequence: Vec<RunResult>) -> Self {
        let stats: Vec<_> = per_sequence.iter().map(|r| r.stats).collect();
        let steps: usize = per_sequence.iter().map(|r| r.step_seconds.len()).sum();
        let secs: f64 = per_sequence
            .iter()
            .flat_map(|r| r.step_seconds.iter())
            .sum();
        let encoder: f64 = per_sequence
            .iter()
            .flat_map(|r| r.encoder_seconds.iter())
            .sum();
        TrackingRow {
            variant: variant.into(),
            summary: summarize_sequences(&stats),
            completed: per_sequence.iter().filter(|r| r.completed).count(),
            fps: steps as f64 / secs.max(1e-12),
            fps_with_encoder: steps as f64 / (secs + encoder).max(1e-12),
            map_rows: per_sequence.iter().map(|r| r.map_rows as f64).sum::<f64>()
                / per_sequence.len().max(1) as f64,
            per_sequence,
        }
    }
}

/// Tracks sequence `seq` in `map` from the paper's local start with
/// `filter`, `particles` and the features of `preset`.
pub fn track(
    seq: &SimSequence,
    map: &BenchMap,
    preset: Preset,
    filter: FilterConfig,
    particles: usize,
) -> Result<RunResult, ExperimentError> {
    let model = feature_model(seq, preset, 0x10c);
    let spec = RunSpec {
        filter,
        particles,
        start: Start::paper_local(),
        first: 0,
        frames: seq.len(),
        preset,
    };
    run(seq, &map.map, map.caster.clone(), &model, &spec)
}

/// The class table every benchmark uses: the simulator's built-in one.
pub fn builtin_table() -> Result<ClassEmbeddings, ExperimentError> {
    crate::sim::files::builtin_table()
        .map_err(|e| ExperimentError::Sim(crate::sim::dataset::SimError::Io(e)))
}

/// Table II: consistency of each variant's map with its features.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ConsistencyRow {
    pub variant: String,
    /// Per sequence, per pose.
    pub per_pose: Vec<Vec<crate::eval::ConsistencyMetrics>>,
    /// Averaged over poses, then over sequences.
    pub mean: Option<crate::eval::ConsistencyMetrics>,
}

impl ConsistencyRow {
    /// Gathers per-pose metrics of the sequences.
    pub fn new(
        variant: impl Into<String>,
        per_pose: Vec<Vec<crate::eval::ConsistencyMetrics>>,
    ) -> Self {
        ConsistencyRow {
            variant: variant.into(),
            mean: crate::eval::mean_over_sequences(&per_pose),
            per_pose,
        }
    }
}

/// The consistency of `map` with the features of `preset` on `seq`, every
/// `frame_step`-th frame, every 8th pixel.
pub fn consistency(
    seq: &SimSequence,
    map: &BenchMap,
    preset: Preset,
    frame_step: usize,
) -> Result<Vec<crate::eval::ConsistencyMetrics>, ExperimentError> {
    let model = feature_model(seq, preset, 0x10c);
    super::consistency::per_pose(seq, map, &model, frame_step, 8)
}

/// Global localization (Table V): from `spec.starts` start frames of `seq`,
/// the filter starts over all floor voxels (`prompt: false`) or over the
/// floor voxels matching a prompt of 3 to 5 object classes found within 2 m
/// of the start (`prompt: true`, as the paper draws its prompts), and runs
/// for at most `max_steps` frames. Returns, per start, the steps to reach each
/// of [`crate::eval::localization::CONVERGENCE_THRESHOLDS`].
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
    } = *spec;
    let model = feature_model(seq, preset, 0x10c);
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
        };
        let (steps, error) = match run(seq, &map.map, map.caster.clone(), &model, &spec) {
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

/// What [`global_runs`] does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalSpec {
    /// Features the localizer sees.
    pub preset: Preset,
    pub filter: FilterConfig,
    pub particles: usize,
    /// Start frames per sequence, spread evenly over it.
    pub starts: usize,
    /// Steps of each run.
    pub max_steps: usize,
    /// Start over the floor voxels matching a prompt (else all floor).
    pub prompt: bool,
}

/// One global-localization run.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct GlobalRun {
    /// Start frame.
    pub first: usize,
    /// Prompt words (empty without a prompt).
    pub words: Vec<String>,
    /// Steps to reach each threshold (`None`: not within the run).
    pub steps: Vec<Option<usize>>,
    /// Why the run could not start (e.g. no floor voxel matches the prompt).
    pub error: Option<String>,
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

#[cfg(test)]
mod tests {
    use super::*;

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
