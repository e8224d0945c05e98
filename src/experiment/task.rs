//! A sweep's vocabulary, shared by the planner ([`super::sweep`]), the
//! experiments (each plans its runs and reads its results) and the
//! collector ([`super::report`]): what a bench asks for ([`BenchPlan`]),
//! what one run computes ([`Task`]) and where its result goes ([`Use`]),
//! what it produced ([`RunRecord`]), and the errors of all of them.

use std::path::{Path, PathBuf};

use super::ExperimentError;
use super::mapping::{MapParams, MapSource};
use super::plan_settings::PlanSettings;
use super::run::{GlobalRun, RunResult};
use super::variant::{TABLE1_VARIANTS, Variant};
use crate::eval::ConsistencyMetrics;
use crate::mcl::FilterConfig;
use crate::sim::features::Preset;
use crate::sim::indoor::WorldKind;

/// The version of omcl every manifest line and result file carries.
pub const OMCL_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Errors of planning, running and collecting sweeps; each names the file
/// (and the run) it concerns.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path} line {line}: {reason}")]
    Manifest {
        path: PathBuf,
        line: usize,
        reason: String,
    },
    #[error("{path}: run index {index} is out of range (the manifest has {runs} runs)")]
    Index {
        path: PathBuf,
        index: usize,
        runs: usize,
    },
    #[error("run {id}: map file {path} is missing (runs without --no-build-maps build it)")]
    MissingMap { id: String, path: PathBuf },
    #[error("run {id}: map file {path}: {reason}")]
    BadMap {
        id: String,
        path: PathBuf,
        reason: String,
    },
    #[error("run {id}: {source}")]
    Run { id: String, source: ExperimentError },
    #[error("{path}: {reason}")]
    BadResult { path: PathBuf, reason: String },
    #[error("{0}")]
    Plan(String),
    #[error("{path}: {source}")]
    Plot {
        path: PathBuf,
        source: crate::plot::PlotError,
    },
}

pub(super) fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> SweepError + '_ {
    move |source| SweepError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The experiments of `omcl bench` that are planned as sweeps of runs
/// (the others run in one process: `omcl bench table4`, `table1-floorplan`,
/// `table1-sixdof`). [`Experiment::description`] says what each gives.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum Experiment {
    Table1,
    Table2,
    Table5,
    Table5Floorplan,
    ParticlesRays,
    Sampling,
    All,
}

impl Experiment {
    /// Every experiment, `All` last.
    pub const ALL: [Experiment; 7] = [
        Experiment::Table1,
        Experiment::Table2,
        Experiment::Table5,
        Experiment::Table5Floorplan,
        Experiment::ParticlesRays,
        Experiment::Sampling,
        Experiment::All,
    ];

    /// Whether `all` plans it (`table5-floorplan` is left out).
    pub fn in_all(self) -> bool {
        self != Experiment::Table5Floorplan
    }

    /// The name on the command line and in file names.
    pub fn name(self) -> &'static str {
        match self {
            Experiment::Table1 => "table1",
            Experiment::Table2 => "table2",
            Experiment::Table5 => "table5",
            Experiment::Table5Floorplan => "table5-floorplan",
            Experiment::ParticlesRays => "particles-rays",
            Experiment::Sampling => "sampling",
            Experiment::All => "all",
        }
    }

    /// What the experiment gives, in a sentence.
    pub fn description(self) -> &'static str {
        match self {
            Experiment::Table1 => {
                "Table I's variants tracked in the 3-D map with planar motion from the \
                 paper's local start, with Figure 4 (trajectories coloured by APE over the \
                 floor plan). The paper's Table I is its two blocks: `omcl bench \
                 table1-floorplan table1-sixdof` prints both"
            }
            Experiment::Table2 => "Table II: measurement-map consistency of the variants",
            Experiment::Table5 => {
                "Table V: steps until global localization reaches 2 ... 0.1 m, without and \
                 with a prompt"
            }
            Experiment::Table5Floorplan => {
                "Table V on the floor plan, in 2-D (x, y, yaw, as table1-floorplan and \
                 `omcl localize --floorplan`): the same starts and prompts over the 3-D \
                 map's floor, Table I's 2-D filter, horizontal errors. Not part of `all`"
            }
            Experiment::ParticlesRays => {
                "Figure: APE and FPS against particles for several ray counts"
            }
            Experiment::Sampling => "Figure: stratified against equal and uniform ray sampling",
            Experiment::All => {
                "Everything above but table5-floorplan, table4, table1-floorplan, \
                 table1-sixdof and sevenscenes"
            }
        }
    }
}

/// What a sweep asks for: `omcl bench`'s options (line 1 of a manifest).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BenchPlan {
    /// Sorted, without duplicates.
    pub experiments: Vec<Experiment>,
    /// Sequences `first_seed .. first_seed + sequences`.
    pub sequences: u64,
    pub first_seed: u64,
    /// Frames per sequence.
    pub frames: usize,
    /// Frames of each map's mapping path.
    pub map_frames: usize,
    pub particles: usize,
    /// Rays (also in `filter.sampling.rays`).
    pub rays: usize,
    /// Names of the Table I variants, in table order.
    pub variants: Vec<String>,
    /// Localize with these features instead of each variant's own.
    pub preset: Option<Preset>,
    /// The variant of Table V and the ablations.
    pub ablation_variant: String,
    /// Sequences of the ablations.
    pub ablation_sequences: u64,
    /// Start frames per sequence for Table V.
    pub starts: usize,
    /// Steps of each global-localization run.
    pub max_steps: usize,
    /// The filter's configuration (overrides applied; the seed is set per
    /// sequence).
    pub filter: FilterConfig,
    /// The filter of `table5-floorplan` (Table I's 2-D block's,
    /// [`FilterConfig::floor_plan`], with the same `--rays` and `--set`);
    /// left out of the manifest when that experiment is not planned.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor_plan_filter: Option<FilterConfig>,
    /// How `table5-floorplan` projects its plans and casts on them, where
    /// `--set plan.*` or `two_d.*` changed the defaults; left out of the
    /// manifest otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor_plan_scene: Option<PlanSettings>,
    /// The kind of world every sequence is in (left out of the manifest
    /// for the corridor apartment, as before there were kinds).
    #[serde(default, skip_serializing_if = "WorldKind::is_corridor")]
    pub world: WorldKind,
}

impl BenchPlan {
    /// The filter of `table5-floorplan`: [`BenchPlan::floor_plan_filter`],
    /// or the 2-D block's own ([`FilterConfig::floor_plan`]) in a plan
    /// made without one.
    pub fn two_d_filter(&self) -> FilterConfig {
        self.floor_plan_filter
            .unwrap_or_else(FilterConfig::floor_plan)
    }

    /// Whether `e` is among the planned experiments.
    pub fn wants(&self, e: Experiment) -> bool {
        self.experiments.contains(&e) || (self.experiments.contains(&Experiment::All) && e.in_all())
    }

    /// The variants, in table order, with the preset override applied.
    pub fn table_variants(&self) -> Result<Vec<Variant>, SweepError> {
        self.variants
            .iter()
            .map(|n| self.variant(n))
            .collect::<Result<_, _>>()
    }

    /// The variant called `name`, with the preset override applied to
    /// Table I and II variants.
    fn variant(&self, name: &str) -> Result<Variant, SweepError> {
        let v = find_variant(name)?;
        Ok(Variant {
            localize: self.preset.unwrap_or(v.localize),
            ..v
        })
    }

    /// The variant of Table V and the ablations (its own features).
    pub fn ablation(&self) -> Result<Variant, SweepError> {
        find_variant(&self.ablation_variant)
    }

    /// The mapping parameters of every map.
    pub fn map_params(&self) -> MapParams {
        MapParams {
            frames: self.map_frames,
            ..MapParams::default()
        }
    }

    /// Seeds of the tables.
    pub fn seeds(&self) -> std::ops::Range<u64> {
        self.first_seed..self.first_seed + self.sequences
    }

    /// Seeds of the ablations.
    pub fn ablation_seeds(&self) -> std::ops::Range<u64> {
        self.first_seed..self.first_seed + self.ablation_sequences
    }
}

fn find_variant(name: &str) -> Result<Variant, SweepError> {
    TABLE1_VARIANTS
        .iter()
        .find(|v| v.name == name)
        .copied()
        .ok_or_else(|| {
            SweepError::Plan(format!(
                "{name:?} is not a variant (one of {:?})",
                TABLE1_VARIANTS.map(|v| v.name)
            ))
        })
}

/// Line 1 of a manifest.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SweepHeader {
    /// The omcl version that planned the sweep.
    pub omcl: String,
    pub bench: BenchPlan,
}

/// What one run computes: everything its result depends on.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Task {
    /// Sequence (world) seed.
    pub seed: u64,
    /// The kind of world (left out of the JSON, and so of the run id, for
    /// the corridor apartment: its runs keep the ids they had).
    #[serde(default, skip_serializing_if = "WorldKind::is_corridor")]
    pub world: WorldKind,
    /// Frames of the sequence.
    pub frames: usize,
    /// The map's source and mapping parameters.
    pub map: MapSource,
    pub map_params: MapParams,
    /// Features the localizer sees.
    pub preset: Preset,
    pub work: Work,
}

/// The kind of work of a run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Work {
    /// Tracking from the paper's local start over the whole sequence.
    Track {
        filter: FilterConfig,
        particles: usize,
    },
    /// Measurement-map consistency every `frame_step`-th frame.
    Consistency { frame_step: usize },
    /// Global localization from `starts` start frames, with or without a
    /// prompt.
    Global {
        filter: FilterConfig,
        particles: usize,
        starts: usize,
        max_steps: usize,
        prompt: bool,
        /// On the floor plan, in 2-D (`table5-floorplan`); left out of the
        /// manifest for the 3-D runs, so their ids are as before.
        #[serde(default, skip_serializing_if = "is_false")]
        floor_plan: bool,
        /// With `floor_plan`, the plans' settings where they are not the
        /// defaults ([`BenchPlan::floor_plan_scene`]); left out of the
        /// manifest otherwise, so the ids are as before they could be set.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        plan: Option<PlanSettings>,
    },
}

fn is_false(b: &bool) -> bool {
    !b
}

/// Where a run's result goes in the tables.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Use {
    Table1 {
        variant: String,
    },
    Table2 {
        variant: String,
    },
    Table5 {
        prompt: bool,
        #[serde(default, skip_serializing_if = "is_false")]
        floor_plan: bool,
    },
    ParticlesRays {
        particles: usize,
        rays: usize,
    },
    Sampling {
        particles: usize,
        strategy: String,
    },
}

/// One line of a manifest after line 1.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunEntry {
    /// [`run_id`] of `omcl` and `task`.
    pub id: String,
    /// The omcl version that planned the run.
    pub omcl: String,
    pub task: Task,
    /// Table cells that use the result.
    pub uses: Vec<Use>,
}

/// A run's stable id: 32 hex digits hashing the omcl version and the
/// task's canonical JSON (two FNV-1a 64-bit hashes with different offset
/// bases; collisions are negligible at millions of runs).
pub fn run_id(omcl: &str, task: &Task) -> String {
    #[derive(serde::Serialize)]
    struct Key<'a> {
        omcl: &'a str,
        task: &'a Task,
    }
    // Serializing plain data into a Vec cannot fail.
    let bytes = serde_json::to_vec(&Key { omcl, task }).unwrap_or_default();
    format!(
        "{:016x}{:016x}",
        fnv1a(&bytes, 0xcbf2_9ce4_8422_2325),
        fnv1a(&bytes, 0x6c62_272e_07bb_0142)
    )
}

pub(super) fn fnv1a(bytes: &[u8], basis: u64) -> u64 {
    bytes.iter().fold(basis, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// What every experiment's planner needs: the bench and the tasks it
/// makes for a seed and a variant.
pub struct Planner<'a> {
    pub(super) bench: &'a BenchPlan,
    pub(super) map_params: MapParams,
}

impl Planner<'_> {
    /// The task of `work` on sequence `seed` with `v`'s map and features.
    pub(super) fn task(&self, seed: u64, v: &Variant, work: Work) -> Task {
        Task {
            seed,
            world: self.bench.world,
            frames: self.bench.frames,
            map: v.map,
            map_params: self.map_params,
            preset: v.localize,
            work,
        }
    }

    /// A tracking task: `filter` with the sequence's seed, `particles`.
    pub(super) fn track(
        &self,
        seed: u64,
        v: &Variant,
        filter: FilterConfig,
        particles: usize,
    ) -> Task {
        self.task(
            seed,
            v,
            Work::Track {
                filter: FilterConfig { seed, ..filter },
                particles,
            },
        )
    }
}

/// What a run produced.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    Track(Box<TrackOutcome>),
    Consistency(Vec<ConsistencyMetrics>),
    Global(Vec<GlobalRun>),
}

/// A tracking run's result with the positions Figure 4 draws.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TrackOutcome {
    pub result: RunResult,
    /// Ground-truth camera (x, y) per frame, world frame, metres.
    pub truth_xy: Vec<[f64; 2]>,
    /// Estimated camera (x, y) per frame, world frame, metres.
    pub estimate_xy: Vec<[f64; 2]>,
}

/// What a run cost.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct Cost {
    /// Wall-clock time of the run (map loading or building included), s.
    pub wall_seconds: f64,
    /// CPU time (user + system) of the process while the run ran, s; exact
    /// when the process runs one run at a time (`omcl sweep run --index`).
    pub cpu_seconds: Option<f64>,
    /// Peak resident memory of the process so far, MB.
    pub peak_rss_mb: Option<f64>,
}

/// A finished run's result file.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct RunRecord {
    pub id: String,
    pub omcl: String,
    pub task: Task,
    pub outcome: Outcome,
    pub cost: Cost,
}

/// The map file of `task` in cache folder `dir`: named by world (but the
/// corridor apartment's), seed, frames, source and a hash of the mapping parameters and the omcl version.
pub fn map_path(dir: &Path, task: &Task) -> PathBuf {
    #[derive(serde::Serialize)]
    struct Key<'a> {
        omcl: &'a str,
        seed: u64,
        #[serde(skip_serializing_if = "WorldKind::is_corridor")]
        world: WorldKind,
        frames: usize,
        map: MapSource,
        params: &'a MapParams,
    }
    let key = serde_json::to_vec(&Key {
        omcl: OMCL_VERSION,
        seed: task.seed,
        world: task.world,
        frames: task.frames,
        map: task.map,
        params: &task.map_params,
    })
    .unwrap_or_default();
    let world = if task.world.is_corridor() {
        String::new()
    } else {
        format!("{}-", task.world)
    };
    dir.join(format!(
        "map-{world}{}-{}f-{}-{:08x}.omcl",
        task.seed,
        task.frames,
        task.map.name(),
        fnv1a(&key, 0xcbf2_9ce4_8422_2325) as u32
    ))
}

impl From<TrackOutcome> for Outcome {
    fn from(t: TrackOutcome) -> Self {
        Outcome::Track(Box::new(t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::mapping::MapSource;

    fn task(world: WorldKind) -> Task {
        Task {
            seed: 1000,
            world,
            frames: 150,
            map: MapSource::Labels,
            map_params: MapParams::default(),
            preset: Preset::Gt,
            work: Work::Consistency { frame_step: 10 },
        }
    }

    /// A corridor task serializes as it did before worlds had kinds (so its
    /// run id and map file stay what they were); other kinds get their own
    /// ids and map files, and a manifest line without a world reads back
    /// as the corridor.
    #[test]
    fn the_world_kind_separates_runs_and_maps_but_leaves_corridor_ids_alone() {
        let c = task(WorldKind::Corridor);
        let json = serde_json::to_string(&c).unwrap();
        assert!(!json.contains("world"), "{json}");
        let back: Task = serde_json::from_str(&json).unwrap();
        assert_eq!(back, c);
        let dir = Path::new("cache");
        let mut ids = vec![run_id("v", &c)];
        let mut maps = vec![map_path(dir, &c)];
        for k in [WorldKind::OpenPlan, WorldKind::Offices] {
            let t = task(k);
            let json = serde_json::to_string(&t).unwrap();
            assert!(json.contains(k.name()), "{json}");
            assert_eq!(serde_json::from_str::<Task>(&json).unwrap(), t);
            ids.push(run_id("v", &t));
            maps.push(map_path(dir, &t));
        }
        ids.dedup();
        maps.dedup();
        assert_eq!((ids.len(), maps.len()), (3, 3), "{maps:?}");
        let name = maps[0].file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with("map-1000-150f-"), "{name}");
    }
}
