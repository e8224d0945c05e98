//! The options of `omcl bench` and `omcl sweep plan`: which experiments,
//! their parameters and the filter's overrides. Apart from the commands
//! that use them (`bench`, `bench_table1`, `sweep`), so that those need
//! not import each other.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, ValueEnum};

use omcl::experiment::plan_settings::PlanSettings;
use omcl::experiment::sweep::{self, BenchPlan};
use omcl::experiment::table1_6dof::SixDofMotion;
use omcl::experiment::table1_floorplan::TwoDParams;
use omcl::experiment::variant::named_in;
use omcl::map::FloorPlanParams;
use omcl::mcl::FilterConfig;

/// The experiments on the command line: the library's planned ones
/// ([`sweep::Experiment`]) and those that run in this process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Experiment {
    Planned(sweep::Experiment),
    Table4,
    Table1Floorplan,
    Table1Sixdof,
    SevenScenes,
}

/// The in-process experiments: value, name, help.
const IN_PROCESS: [(Experiment, &str, &str); 4] = [
    (
        Experiment::Table4,
        "table4",
        "Table IV: camera 2 on the street world along the real KITTI 00 path (--street-*), the \
         odometry variants of --odometry; translation and rotation error, completion, filter \
         steps/s, and the estimated path over the map. Runs in this process (not planned as a \
         sweep); not part of `all`",
    ),
    (
        Experiment::Table1Floorplan,
        "table1-floorplan",
        "Table I's 2-D block: OMCL variants on floor plans projected from their maps (x, y, yaw; \
         planar rays), beside the paper's rows. Runs in this process; not part of `all`",
    ),
    (
        Experiment::Table1Sixdof,
        "table1-sixdof",
        "Table I's 3-D block: the full 6-DoF pose (height, roll, pitch included) on sequences \
         with height and pitch changes and odometry noise on all six degrees of freedom. Runs in \
         this process; not part of `all`",
    ),
    (
        Experiment::SevenScenes,
        "sevenscenes",
        "A real sensor track: 7-Scenes redkitchen (Kinect v1, --scenes), map from the even \
         frames, every --localize-every-th odd frame localized in 6-DoF with the colour-class \
         ONNX encoder (not open-vocabulary); APE, Table II's consistency, with and without the \
         depth-edge filter. Runs in this process; not part of `all`",
    ),
];

impl ValueEnum for Experiment {
    fn value_variants<'a>() -> &'a [Self] {
        use sweep::Experiment as S;
        &[
            Experiment::Planned(S::Table1),
            Experiment::Planned(S::Table2),
            Experiment::Planned(S::Table5),
            Experiment::Planned(S::Table5Floorplan),
            Experiment::Planned(S::ParticlesRays),
            Experiment::Planned(S::Sampling),
            Experiment::Table4,
            Experiment::Table1Floorplan,
            Experiment::Table1Sixdof,
            Experiment::SevenScenes,
            Experiment::Planned(S::All),
        ]
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        let (name, help) = match self {
            Experiment::Planned(e) => (e.name(), e.description()),
            other => IN_PROCESS
                .iter()
                .find(|(e, ..)| e == other)
                .map(|&(_, n, h)| (n, h))?,
        };
        Some(clap::builder::PossibleValue::new(name).help(help))
    }
}

impl Experiment {
    /// The sweep's experiment; `None` for those that run in this process.
    pub fn to_library(self) -> Option<sweep::Experiment> {
        match self {
            Experiment::Planned(e) => Some(e),
            _ => None,
        }
    }
}

/// What to plan: the experiments and their parameters (shared by
/// `omcl bench` and `omcl sweep plan`).
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// Which experiments (one or more; runs two experiments share are
    /// planned once, e.g. `omcl bench table1 table2`).
    #[arg(value_enum, required = true, num_args = 1..)]
    pub experiments: Vec<Experiment>,
    /// Number of sequences (seeds first-seed .. first-seed + n).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    pub sequences: u64,
    /// First sequence seed. The default is the first held-out seed
    /// (reported tables); seeds 0-99 are the tuning range
    /// (`omcl::experiment::seeds`).
    #[arg(long, default_value_t = omcl::experiment::seeds::FIRST_REPORTING,
          value_parser = clap::value_parser!(u64).range(..=1_000_000_000_000))]
    pub first_seed: u64,
    /// Frames per sequence.
    #[arg(long, default_value_t = 150, value_parser = super::count_in::<1, { super::MAX_FRAMES }>)]
    pub frames: usize,
    /// Frames of each map's second (mapping) path; every second frame of it
    /// and of the sequence is mapped.
    #[arg(long, default_value_t = 300, value_parser = super::count_in::<1, { super::MAX_FRAMES }>)]
    pub map_frames: usize,
    /// Particles (default 1024, the paper's indoor setting, table1-sixdof
    /// too; table4: 512, the paper's outdoor setting).
    #[arg(long, value_parser = super::count_in::<1, { super::MAX_COUNT }>)]
    pub particles: Option<usize>,
    /// Rays, sampled pixels before duplicates are dropped (default 2048;
    /// table1-floorplan and table5-floorplan: 8192; table1-sixdof and
    /// table4: 4096; a block's
    /// point-cloud and raw-feature rows have their own: --show-config).
    #[arg(long, value_parser = super::count_in::<1, { super::MAX_COUNT }>)]
    pub rays: Option<usize>,
    /// Only these variants (comma-separated: OMCL_GT, OMCL_LSeg,
    /// OMCL_auto_LSeg, OMCL_Open_LSeg, OMCL_GT_exact; table1-floorplan's
    /// baselines SeDAR*_GT, SIMP*_GT (quote the *); `none` for no row, as
    /// for table1-sixdof's --rgbd-odometry row alone; default all).
    #[arg(long)]
    pub variants: Option<String>,
    /// Localize (and score consistency) with these features instead of each
    /// variant's own: exact, gt or lseg-like.
    #[arg(long)]
    pub preset: Option<omcl::sim::features::Preset>,
    /// The variant of Table V and the ablations.
    #[arg(long, default_value = "OMCL_LSeg")]
    pub ablation_variant: String,
    /// Sequences used by the ablations (their sweeps are long).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub ablation_sequences: u64,
    /// Start frames per sequence for Table V.
    #[arg(long, default_value_t = 3, value_parser = super::count_in::<1, 1000>)]
    pub starts: usize,
    /// Steps of each global-localization run.
    #[arg(long, default_value_t = 60, value_parser = super::count_in::<1, { super::MAX_FRAMES }>)]
    pub max_steps: usize,
    /// The kind of world of every sequence: corridor (the apartment of
    /// every table so far), open-plan (one large living, dining and
    /// kitchen space, two side rooms) or offices (24 rooms round two
    /// corridors, most of them identical offices). Table I, II and V and
    /// the ablations; table1-floorplan and table1-sixdof run on it too.
    #[arg(long, default_value = "corridor")]
    pub world: omcl::sim::indoor::WorldKind,
    /// Override any filter parameter: `--set sharpen=40 --set
    /// sensor.miss_score=0.2` (paths into the filter configuration's JSON,
    /// printed by `--show-config`; VALUE is JSON). table1-floorplan,
    /// table1-sixdof and table5-floorplan also take `plan.*` and `two_d.*`
    /// (the floor plan's band and the 2-D sensor), and table1-sixdof
    /// `sixdof.*` (the 3-D block's sequences: `height_m`,
    /// `pitch_deg`, `roll_deg`, `sigma_translation`, `sigma_rotation_deg`).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
}

impl PlanArgs {
    /// The filter configuration: defaults, `--rays`, then `--set`.
    pub fn filter(&self) -> anyhow::Result<FilterConfig> {
        self.filter_from(FilterConfig::default())
    }

    /// `base` with `--rays`, then `--set` (but the Table I blocks' own
    /// `plan.*`, `two_d.*` and `sixdof.*`, which are not the filter's).
    fn filter_from(&self, mut base: FilterConfig) -> anyhow::Result<FilterConfig> {
        if let Some(r) = self.rays {
            base.sampling.rays = r;
        }
        let filter_sets: Vec<String> = self
            .set
            .iter()
            .filter(|s| !is_block_path(s))
            .cloned()
            .collect();
        apply_overrides(base, &filter_sets)
    }

    /// Refuses a `--variants` name that is not a variant of the sweep's
    /// tables (a typo would otherwise drop a row of the table unnoticed).
    pub fn check_sweep_variants(&self) -> anyhow::Result<()> {
        let names = self.variants.iter().flat_map(|l| l.split(','));
        for n in names.map(str::trim).filter(|n| !n.is_empty()) {
            anyhow::ensure!(
                TABLE_VARIANT_NAMES.contains(&n),
                "--variants: {n:?} is not a variant; they are {}",
                TABLE_VARIANT_NAMES.join(", ")
            );
        }
        Ok(())
    }

    /// The sweep these options ask for.
    pub fn bench_plan(&self) -> anyhow::Result<BenchPlan> {
        let names = TABLE_VARIANT_NAMES;
        let variants: Vec<String> = names
            .iter()
            .filter(|n| named_in(self.variants.as_deref(), n))
            .map(|n| n.to_string())
            .collect();
        anyhow::ensure!(!variants.is_empty(), "--variants matches none of {names:?}");
        anyhow::ensure!(
            names.contains(&self.ablation_variant.as_str()),
            "--ablation-variant {:?} is not a variant",
            self.ablation_variant
        );
        anyhow::ensure!(self.sequences > 0, "--sequences must be at least 1");
        let mut experiments: Vec<sweep::Experiment> = self
            .experiments
            .iter()
            .filter_map(|e| e.to_library())
            .collect();
        experiments.sort();
        experiments.dedup();
        let floor_plan_filter = experiments
            .contains(&sweep::Experiment::Table5Floorplan)
            .then(|| self.filter_from(FilterConfig::floor_plan()))
            .transpose()?;
        if let Some(f) = &floor_plan_filter {
            anyhow::ensure!(
                f.motion.mode == omcl::mcl::MotionMode::Planar,
                "table5-floorplan estimates x, y and yaw: its motion noise stays planar (--set \
                 motion.mode={:?} given)",
                f.motion.mode
            );
        }
        // table5-floorplan's plans: the 2-D block's `plan.*` and `two_d.*`,
        // kept only where they change the defaults (so that a plan without
        // them gives the runs' ids of before).
        let floor_plan_scene = match floor_plan_filter {
            Some(_) => Some(block_overrides(&self.set)?.plan_settings()?)
                .filter(|s| *s != PlanSettings::default()),
            None => None,
        };
        Ok(BenchPlan {
            experiments,
            sequences: self.sequences,
            first_seed: self.first_seed,
            frames: self.frames,
            map_frames: self.map_frames,
            particles: self.particles.unwrap_or(omcl::mcl::INDOOR_PARTICLES),
            rays: self.rays.unwrap_or(FilterConfig::default().sampling.rays),
            variants,
            preset: self.preset,
            ablation_variant: self.ablation_variant.clone(),
            ablation_sequences: self.ablation_sequences,
            starts: self.starts,
            max_steps: self.max_steps,
            filter: self.filter()?,
            floor_plan_filter,
            floor_plan_scene,
            world: self.world,
        })
    }
}

const TABLE_VARIANT_NAMES: [&str; 5] = {
    let v = omcl::experiment::table1::TABLE1_VARIANTS;
    [v[0].name, v[1].name, v[2].name, v[3].name, v[4].name]
};

/// Table IV's street (`omcl bench table4`).
#[derive(Debug, Args)]
pub struct StreetArgs {
    /// table4: first frame of KITTI 00 the street starts at.
    #[arg(long, default_value_t = 0)]
    pub street_start: usize,
    /// table4: frames of the street (KITTI 00 has 4541, 3.7 km; 300 are
    /// the first 216 m).
    #[arg(long, default_value_t = 300)]
    pub street_frames: usize,
    /// table4: voxel edge of the street world and of its LiDAR map, metres
    /// (the paper's is 0.05, about four times the map; 0.1 keeps a
    /// segment's run to minutes).
    #[arg(long, default_value_t = 0.1)]
    pub street_resolution: f64,
    /// table4: odometry variants, comma-separated: `noise` (ground truth
    /// plus the authors' 0.1 m on camera x and z and 0.1 rad yaw a frame),
    /// `orb` (the frame-to-frame motion of the real ORB-SLAM2 estimate of
    /// KITTI 00 replayed from the first true pose; stands in for the
    /// paper's Stereo DSO).
    #[arg(long, default_value = "noise,orb")]
    pub odometry: String,
    /// table4: output stride of the simulated camera encoder: every pixel
    /// reads the feature of its stride x stride block's centre, as an
    /// encoder with an output map at 1/stride resolution (and the feature
    /// files `omcl sim outdoor --features` writes at stride 8) gives; 1: a
    /// feature per pixel.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub encoder_stride: u32,
    /// table4: folder with KITTI_00_gt.txt and KITTI_00_ORB.txt (default:
    /// the shared data beside the source tree).
    #[arg(long)]
    pub trajectories: Option<PathBuf>,
}

/// The real sensor track (`omcl bench sevenscenes`).
#[derive(Debug, Args)]
pub struct SevenScenesArgs {
    /// sevenscenes: the 7-Scenes folder (default: the shared redkitchen
    /// frames beside the source tree).
    #[arg(long)]
    pub scenes: Option<PathBuf>,
    /// sevenscenes: use only the first N frames of the folder.
    #[arg(long)]
    pub scenes_frames: Option<usize>,
    /// sevenscenes: localize every n-th odd frame (a step spans 2n frames).
    #[arg(long, default_value_t = 4, value_parser = super::count_in::<1, 1000>)]
    pub localize_every: usize,
    /// sevenscenes: colour classes of the encoder.
    #[arg(long, default_value_t = 10,
          value_parser = super::count_in::<1, { omcl::encode::colour::MAX_CLASSES }>)]
    pub colour_classes: usize,
    /// sevenscenes: depth pixels within this many pixels (Chebyshev) of a
    /// depth edge are dropped before mapping (`omcl map rgbd
    /// --drop-depth-edges`).
    #[arg(long, default_value_t = 4, value_parser = super::count_in::<0, 64>)]
    pub edge_radius: usize,
    /// sevenscenes: shift DX,DY (pixels) from a depth pixel to the colour
    /// pixel it takes its feature from while mapping.
    #[arg(
        long,
        value_name = "DX,DY",
        value_delimiter = ',',
        default_value = "0,0",
        allow_negative_numbers = true
    )]
    pub colour_shift: Vec<i32>,
    /// sevenscenes: seeds of the runs (odometry noise, start, filter). The
    /// default is held out (seeds 1 to 3, in the tuning range, are where
    /// the depth-edge filter and the colour-lookup shift were looked at).
    #[arg(long, default_value = "1000,1001,1002,1003,1004")]
    pub scenes_seeds: String,
}

/// Table I's 3-D block and its geometric odometry row
/// (`omcl bench table1-sixdof`).
#[derive(Debug, Args)]
pub struct SixDofArgs {
    /// table1-sixdof: write the block's sequences (seeds, frames and 6-DoF
    /// motion as the block runs them; frames rendered as the filter sees
    /// them) to DIR/seq_<seed>/ in the RGB-D layout of `omcl sim indoor`,
    /// and track nothing. Input of tools/rgbd_odometry.py.
    #[arg(long, value_name = "DIR")]
    pub export_frames: Option<PathBuf>,
    /// table1-sixdof: add the geometric RGB-D odometry row (Open3D, frame
    /// to frame, no map; the stand-in for the paper's RTAB-Map) from
    /// tools/rgbd_odometry.py's results, DIR/seq_<seed>/estimate.txt, scored
    /// as the filter's runs. With `--variants none` only that row is made.
    #[arg(long, value_name = "DIR")]
    pub rgbd_odometry: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub plan: PlanArgs,
    #[command(flatten)]
    pub street: StreetArgs,
    #[command(flatten)]
    pub scenes: SevenScenesArgs,
    #[command(flatten)]
    pub sixdof: SixDofArgs,
    /// Runs computed at once (each also uses every core for its rays; more
    /// than one makes the measured steps/s smaller; 1 to 1024).
    #[arg(long, default_value_t = 1, value_parser = super::count_in::<1, 1024>)]
    pub jobs: usize,
    /// Print the filter configuration as JSON and exit.
    #[arg(long)]
    pub show_config: bool,
    /// Output folder (created if missing).
    #[arg(long, short, default_value = "bench-out")]
    pub out: PathBuf,
    /// Reuse the results and maps of an earlier bench in `<out>/sweep/`
    /// (only with the same build: run ids know the omcl version, not the
    /// code). Without it they are deleted first.
    #[arg(long)]
    pub resume: bool,
    /// Replace a sweep in `<out>/sweep/` that no `omcl bench` made (one
    /// `omcl sweep plan` wrote there, with its results and maps).
    #[arg(long)]
    pub force: bool,
}

/// The path prefixes of `--set` that are the Table I blocks' own (the floor
/// plan, the 2-D sensor, the 6-DoF sequences), not the filter's.
pub const BLOCK_PATHS: [&str; 3] = ["plan.", "two_d.", "sixdof."];

/// Whether a `--set PATH=VALUE` is one of the blocks' ([`BLOCK_PATHS`]).
pub fn is_block_path(set: &str) -> bool {
    set.split_once('=')
        .is_some_and(|(path, _)| BLOCK_PATHS.iter().any(|p| path.starts_with(p)))
}

/// The blocks' own `--set` paths: `plan.band_min`, `plan.band_max` (the
/// floor plan's height band, m), `two_d.max_elevation_deg`,
/// `two_d.silence_rho`, `two_d.heights` (OMCL's 2-D pixel selection and
/// sensor) and `sixdof.*` (the 3-D block's sequences: `height_m`,
/// `pitch_deg`, `roll_deg`, `periods`, `sigma_translation`,
/// `sigma_rotation_deg`; [`SixDofMotion`]); every other path goes to the
/// filter.
#[derive(serde::Serialize, serde::Deserialize)]
pub(super) struct BlockOverrides {
    pub(super) plan: FloorPlanParams,
    pub(super) two_d: TwoDParams,
    pub(super) sixdof: SixDofMotion,
    /// The `--set` paths that are the filter's.
    #[serde(skip)]
    pub(super) rest: Vec<String>,
}

impl BlockOverrides {
    /// The floor plans' band and 2-D sensor, each checked (by its `--set`
    /// paths' names).
    pub(super) fn plan_settings(&self) -> anyhow::Result<PlanSettings> {
        self.plan.validate().context("--set plan.*")?;
        self.two_d.validate().context("--set")?;
        Ok(PlanSettings {
            plan: self.plan,
            two_d: self.two_d,
        })
    }
}

pub(super) fn block_overrides(sets: &[String]) -> anyhow::Result<BlockOverrides> {
    let mut v = serde_json::to_value(BlockOverrides {
        plan: FloorPlanParams::default(),
        two_d: Default::default(),
        sixdof: SixDofMotion::default(),
        rest: Vec::new(),
    })?;
    let mut rest = Vec::new();
    for s in sets {
        let Some((path, value)) = s.split_once('=').filter(|_| is_block_path(s)) else {
            rest.push(s.clone());
            continue;
        };
        let value: serde_json::Value = serde_json::from_str(value)
            .with_context(|| format!("--set {s:?}: VALUE must be JSON"))?;
        let mut slot = &mut v;
        for key in path.split('.') {
            slot = slot
                .get_mut(key)
                .with_context(|| format!("--set {s:?}: no parameter {path:?}"))?;
        }
        *slot = value;
    }
    let mut b: BlockOverrides =
        serde_json::from_value(v).context("--set: the block's parameters are invalid")?;
    b.rest = rest;
    Ok(b)
}

/// Applies `PATH=VALUE` overrides to a filter configuration through its
/// JSON form (`VALUE` is JSON; a bare word is taken as a string).
pub fn apply_overrides(config: FilterConfig, sets: &[String]) -> anyhow::Result<FilterConfig> {
    let mut v = serde_json::to_value(config)?;
    for s in sets {
        let (path, value) = s
            .split_once('=')
            .with_context(|| format!("--set {s:?}: expected PATH=VALUE"))?;
        let value: serde_json::Value = serde_json::from_str(value)
            .unwrap_or_else(|_| serde_json::Value::String(value.to_string()));
        let mut slot = &mut v;
        for key in path.split('.') {
            slot = slot.get_mut(key).with_context(|| {
                format!("--set {s:?}: no parameter {path:?} (see --show-config)")
            })?;
        }
        *slot = value;
    }
    let config: FilterConfig =
        serde_json::from_value(v).context("--set: the resulting configuration is invalid")?;
    // Refused here, before any map is built, not at the first run.
    config
        .validate()
        .context("--set: the filter would refuse this configuration")?;
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::TwoDParams;
    use clap::Parser;

    fn plan_args(args: &[&str]) -> super::PlanArgs {
        let cli = crate::cli::Cli::try_parse_from(["omcl", "bench"].iter().chain(args)).unwrap();
        match cli.command {
            crate::cli::Command::Bench(b) => b.plan,
            _ => unreachable!(),
        }
    }

    /// The planned experiments' filters leave the Table I blocks' own
    /// `--set` paths to the blocks (a `plan.*` beside table1-floorplan
    /// made the planned part fail with "no parameter"); table5-floorplan's
    /// filter is the 2-D block's with `--rays` and the filter's `--set`
    /// applied, and only when it is planned.
    #[test]
    fn planned_filters_take_the_filters_paths_only() {
        let a = plan_args(&[
            "table1",
            "table1-floorplan",
            "table5-floorplan",
            "--set",
            "plan.band_min=0.2",
            "--set",
            "sharpen=50",
            "--rays",
            "999",
            "-o",
            "x",
        ]);
        let b = a.bench_plan().unwrap();
        assert_eq!((b.filter.sharpen, b.filter.sampling.rays), (50.0, 999));
        let f = b.floor_plan_filter.unwrap();
        assert_eq!((f.sharpen, f.sampling.rays), (50.0, 999));
        let base = omcl::mcl::FilterConfig::floor_plan();
        assert_eq!(f.estimate, base.estimate);
        assert_ne!(f, b.filter);
        let b = plan_args(&["table5", "-o", "x"]).bench_plan().unwrap();
        assert!(b.floor_plan_filter.is_none());
    }

    /// table5-floorplan projects its plans with the 2-D block's `plan.*`
    /// and `two_d.*`, kept in the plan only where they change the
    /// defaults (and only with table5-floorplan); an invalid `two_d` is
    /// refused by name.
    #[test]
    fn table5_floorplan_takes_the_blocks_plan_settings() {
        let planned = |args: &[&str]| plan_args(args).bench_plan();
        let s = planned(&[
            "table5-floorplan",
            "--set",
            "plan.band_min=0.2",
            "--set",
            "two_d.max_elevation_deg=20",
            "-o",
            "x",
        ])
        .unwrap()
        .floor_plan_scene
        .unwrap();
        assert_eq!((s.plan.band_min, s.plan.band_max), (0.2, 2.0));
        assert_eq!(s.two_d.max_elevation_deg, 20.0);
        assert_eq!(
            TwoDParams {
                max_elevation_deg: TwoDParams::default().max_elevation_deg,
                ..s.two_d
            },
            TwoDParams::default()
        );
        let none = planned(&["table5-floorplan", "-o", "x"]).unwrap();
        assert!(none.floor_plan_scene.is_none());
        let elsewhere = planned(&["table5", "--set", "plan.band_min=0.2", "-o", "x"]).unwrap();
        assert!(elsewhere.floor_plan_scene.is_none());
        let e = planned(&["table5-floorplan", "--set", "two_d.skirt=-1", "-o", "x"]).unwrap_err();
        assert!(format!("{e:#}").contains("two_d.skirt"), "{e:#}");
        let e = planned(&["table5-floorplan", "--set", "plan.band_min=3", "-o", "x"]).unwrap_err();
        assert!(format!("{e:#}").contains("height band [3, 2]"), "{e:#}");
    }
}
