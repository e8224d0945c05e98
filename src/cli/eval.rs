//! `omcl eval ...`: trajectory metrics on pose files, printed as a table and
//! optionally written as JSON (and the aligned estimate as a pose file).

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail, ensure};
use clap::{Args, Subcommand, ValueEnum};
use omcl::eval::align::{Alignment, AlignmentResult, align_trajectory};
use omcl::eval::ape::{PoseErrors, PoseRelation, ape};
use omcl::eval::associate::{DEFAULT_MAX_DIFF, associate, repeated_stamps};
use omcl::eval::kitti_metric::{KITTI_LENGTHS, KITTI_STEP, KittiMetric, kitti_metric_with};
use omcl::eval::localization::CompletionRule;
use omcl::eval::rpe::{Delta, RpeOptions, rpe};
use omcl::io::poses::{PoseFile, PoseFormat, read_poses, read_times, write_poses};
use omcl::trajectory::Trajectory;

/// Appends a formatted line to a `String` (writing to a `String` cannot fail).
macro_rules! outln {
    ($out:expr, $($arg:tt)*) => {{
        use std::fmt::Write as _;
        let _ = writeln!($out, $($arg)*);
    }};
}

/// `omcl eval` subcommands.
#[derive(Debug, Subcommand)]
pub enum EvalCommand {
    /// Absolute pose error (as evo_ape): per-pose error after alignment.
    Ape {
        #[command(flatten)]
        pair: PairArgs,
        /// How the estimate is aligned to the reference first.
        #[arg(long, value_enum, default_value_t = AlignArg::None)]
        align: AlignArg,
        /// Fit the alignment to the first N pose pairs only (evo
        /// --n_to_align); with --align.
        #[arg(long, value_name = "N", value_parser = super::count_in::<1, { usize::MAX }>)]
        n_to_align: Option<usize>,
        /// Error measured: translation (m) or rotation angle (deg).
        #[arg(long, value_enum, default_value_t = RelationArg::Trans)]
        relation: RelationArg,
        /// Write the aligned estimate to this pose file (the estimate's format).
        #[arg(long, value_name = "FILE")]
        save_aligned: Option<PathBuf>,
        /// Horizontal translation errors: heights set to 0 after the
        /// alignment (the error of a floor plan's 2-D estimate, as `omcl
        /// localize --floorplan` prints it and Table I's 2-D block measures
        /// it); with --relation trans
        #[arg(long)]
        horizontal: bool,
        #[command(flatten)]
        out: OutArgs,
    },
    /// Relative pose error (as evo_rpe), delta in frames or metres of path.
    Rpe {
        #[command(flatten)]
        pair: PairArgs,
        /// Spacing of the two poses of a pair, in --delta-unit.
        #[arg(long, default_value_t = 1.0)]
        delta: f64,
        /// Unit of --delta: frames or metres of travelled path.
        #[arg(long, value_enum, default_value_t = DeltaUnitArg::F)]
        delta_unit: DeltaUnitArg,
        /// Use all pairs (i, i + delta) instead of consecutive ones.
        #[arg(long)]
        all_pairs: bool,
        /// Measure metric deltas on the reference path (default: estimate, as evo).
        #[arg(long)]
        pairs_from_reference: bool,
        /// Alignment before the metric (only Sim(3)'s scale changes RPE).
        #[arg(long, value_enum, default_value_t = AlignArg::None)]
        align: AlignArg,
        /// Error measured: translation (m) or rotation angle (deg).
        #[arg(long, value_enum, default_value_t = RelationArg::Trans)]
        relation: RelationArg,
        /// Horizontal translation errors: heights set to 0 after the
        /// alignment, as `ape --horizontal` (a floor plan's 2-D estimate
        /// holds the camera at one height, which the reference's need not
        /// keep); metric deltas are then horizontal path lengths; with
        /// --relation trans
        #[arg(long)]
        horizontal: bool,
        #[command(flatten)]
        out: OutArgs,
    },
    /// KITTI odometry metric: translation (%) and rotation (deg/m) errors
    /// over 100..800 m segments starting every 10th frame.
    Kitti {
        #[command(flatten)]
        pair: PairArgs,
        /// Frames between segment starts.
        #[arg(long, default_value_t = KITTI_STEP, value_parser = super::count_in::<1, { usize::MAX }>)]
        step: usize,
        #[command(flatten)]
        out: OutArgs,
    },
}

/// The two pose files and how their poses are paired.
#[derive(Debug, Args)]
pub struct PairArgs {
    /// Reference (ground-truth) pose file, TUM or KITTI (detected).
    pub reference: PathBuf,
    /// Estimated pose file, TUM or KITTI (detected).
    pub estimate: PathBuf,
    /// Time stamps (one a line) for a KITTI reference file.
    #[arg(long, value_name = "FILE")]
    pub ref_times: Option<PathBuf>,
    /// Time stamps (one a line) for a KITTI estimate file.
    #[arg(long, value_name = "FILE")]
    pub est_times: Option<PathBuf>,
    /// Largest stamp difference for association, seconds.
    #[arg(long, default_value_t = DEFAULT_MAX_DIFF, value_parser = super::seconds)]
    pub t_max_diff: f64,
    /// Added to the estimate's stamps before association, seconds.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = super::finite)]
    pub t_offset: f64,
}

/// Output options.
#[derive(Debug, Args)]
pub struct OutArgs {
    /// Write the statistics (and per-pose errors) as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Replace --json (and, for `ape`, --save-aligned) even when it holds a
    /// file that is not an earlier output of its kind, or a file of a
    /// dataset folder.
    #[arg(long)]
    pub force: bool,
}

impl PairArgs {
    /// What an alignment failure is about: the two files.
    fn aligning(&self) -> String {
        format!(
            "aligning {} to {}",
            self.estimate.display(),
            self.reference.display()
        )
    }
}

impl OutArgs {
    /// The files written, by option.
    fn outputs(&self) -> Vec<(&'static str, &Path)> {
        self.json
            .as_deref()
            .map(|p| ("--json", p))
            .into_iter()
            .collect()
    }
}

impl PairArgs {
    /// Refuses, before any work, `outputs` over the pose and time files
    /// read or over each other ([`super::outputs::refuse_overlaps`]), and
    /// outputs that could not be written at the end
    /// ([`super::outputs::refuse_unwritable`]: a missing folder failed
    /// after the results were printed and another output written).
    fn refuse_overlaps(&self, outputs: &[(&str, &Path)], force: bool) -> anyhow::Result<()> {
        let mut inputs = vec![
            ("the reference", self.reference.as_path()),
            ("the estimate", self.estimate.as_path()),
        ];
        inputs.extend(self.ref_times.as_deref().map(|p| ("--ref-times", p)));
        inputs.extend(self.est_times.as_deref().map(|p| ("--est-times", p)));
        super::outputs::refuse_overlaps(outputs, &inputs)?;
        super::outputs::refuse_replacing_data(outputs)?;
        for &(option, p) in outputs {
            let kind = if option == "--save-aligned" {
                super::outputs::TextOutput::Trajectory
            } else {
                super::outputs::TextOutput::Metrics
            };
            super::outputs::refuse_replacing_unlike(option, p, kind, force)?;
        }
        super::outputs::refuse_unwritable(outputs, &[])
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AlignArg {
    None,
    Se3,
    Sim3,
    Origin,
}

impl From<AlignArg> for Alignment {
    fn from(a: AlignArg) -> Self {
        match a {
            AlignArg::None => Alignment::None,
            AlignArg::Se3 => Alignment::Se3,
            AlignArg::Sim3 => Alignment::Sim3,
            AlignArg::Origin => Alignment::Origin,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DeltaUnitArg {
    /// Frames.
    F,
    /// Metres of travelled path.
    M,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RelationArg {
    /// Translation part, metres.
    Trans,
    /// Rotation angle, degrees.
    AngleDeg,
}

impl From<RelationArg> for PoseRelation {
    fn from(r: RelationArg) -> Self {
        match r {
            RelationArg::Trans => PoseRelation::Translation,
            RelationArg::AngleDeg => PoseRelation::RotationAngleDeg,
        }
    }
}

/// Runs one `omcl eval` subcommand.
pub fn run(cmd: EvalCommand) -> anyhow::Result<()> {
    match cmd {
        EvalCommand::Ape {
            pair,
            align,
            n_to_align,
            relation,
            save_aligned,
            horizontal,
            out,
        } => {
            ensure!(
                !horizontal || relation == RelationArg::Trans,
                "--horizontal measures translation: it takes --relation trans"
            );
            ensure!(
                n_to_align.is_none() || align != AlignArg::None,
                "--n-to-align fits the alignment to the first poses: give --align too (se3, \
                 sim3 or origin); without it nothing is aligned"
            );
            let mut outputs = out.outputs();
            outputs.extend(save_aligned.as_deref().map(|p| ("--save-aligned", p)));
            pair.refuse_overlaps(&outputs, out.force)?;
            let paired = load_pair(&pair)?;
            let (aligned, alignment) = align_trajectory(
                &paired.estimate,
                &paired.reference,
                align.into(),
                n_to_align,
            )
            .with_context(|| pair.aligning())?;
            warn_line_alignment(&paired.reference, &alignment);
            let errors = match horizontal {
                true => ape(
                    &paired.reference.horizontal(),
                    &aligned.horizontal(),
                    relation.into(),
                )?,
                false => ape(&paired.reference, &aligned, relation.into())?,
            };
            // The repo's completion rule (as `omcl localize` and the bench
            // apply it) on translation errors in pose order.
            // `None` for another relation, `Some(None)` for too few poses
            // (not judged; `null` in JSON).
            let rule = CompletionRule::default();
            let completed =
                (errors.relation == PoseRelation::Translation).then(|| rule.judge(&errors.errors));
            let label = if horizontal {
                "APE (horizontal)"
            } else {
                "APE"
            };
            print_errors(label, &pair, &paired, &alignment, &errors, None);
            if let Some(c) = completed {
                let verdict = match c {
                    Some(true) => "yes".to_string(),
                    Some(false) => "no".to_string(),
                    None => format!(
                        "not judged ({} poses or more needed)",
                        rule.frames_to_judge()
                    ),
                };
                emit(&format!(
                    "  {:>8}  {:>14}  (after the first {} poses, never above {} m for more than {} in a row)\n",
                    "completed", verdict, rule.skip_frames, rule.max_error_m, rule.max_consecutive
                ));
            }
            if let Some(path) = save_aligned {
                write_poses(&path, &aligned, paired.estimate_format)?;
                emit(&format!("aligned estimate written to {}\n", path.display()));
            }
            write_json(out.json.as_deref(), || {
                let mut v = errors_json("ape", &pair, &paired, &alignment, &errors, None);
                v["horizontal"] = serde_json::json!(horizontal);
                v["completed"] = serde_json::json!(completed.flatten());
                v["completion_rule"] = serde_json::json!(CompletionRule::default());
                v
            })
        }
        EvalCommand::Rpe {
            pair,
            delta,
            delta_unit,
            all_pairs,
            pairs_from_reference,
            align,
            relation,
            horizontal,
            out,
        } => {
            ensure!(
                !horizontal || relation == RelationArg::Trans,
                "--horizontal measures translation: it takes --relation trans"
            );
            let delta = match delta_unit {
                DeltaUnitArg::F if delta >= 1.0 && delta.fract() == 0.0 => {
                    Delta::Frames(delta as usize)
                }
                DeltaUnitArg::F => {
                    bail!("--delta {delta}: a frame delta must be a whole number >= 1")
                }
                DeltaUnitArg::M if delta > 0.0 && delta.is_finite() => Delta::Meters(delta),
                DeltaUnitArg::M => bail!("--delta {delta}: a metric delta must be positive"),
            };
            pair.refuse_overlaps(&out.outputs(), out.force)?;
            let paired = load_pair(&pair)?;
            let (aligned, alignment) =
                align_trajectory(&paired.estimate, &paired.reference, align.into(), None)
                    .with_context(|| pair.aligning())?;
            warn_line_alignment(&paired.reference, &alignment);
            let options = RpeOptions {
                relation: relation.into(),
                delta,
                all_pairs,
                pairs_from_reference,
            };
            let errors = match horizontal {
                true => rpe(
                    &paired.reference.horizontal(),
                    &aligned.horizontal(),
                    &options,
                )?,
                false => rpe(&paired.reference, &aligned, &options)?,
            };
            let label = if horizontal {
                "RPE (horizontal)"
            } else {
                "RPE"
            };
            print_errors(label, &pair, &paired, &alignment, &errors, Some(&options));
            write_json(out.json.as_deref(), || {
                let mut v = errors_json("rpe", &pair, &paired, &alignment, &errors, Some(&options));
                v["horizontal"] = serde_json::json!(horizontal);
                v
            })
        }
        EvalCommand::Kitti { pair, step, out } => {
            pair.refuse_overlaps(&out.outputs(), out.force)?;
            let paired = load_pair(&pair)?;
            let metric =
                kitti_metric_with(&paired.reference, &paired.estimate, &KITTI_LENGTHS, step)?;
            print_kitti(&pair, &paired, &metric);
            write_json(out.json.as_deref(), || {
                serde_json::json!({
                    "metric": "kitti_odometry",
                    "reference": pair.reference,
                    "estimate": pair.estimate,
                    "pairs": paired.reference.len(),
                    "step_frames": step,
                    "result": metric,
                })
            })
        }
    }
}

/// Two trajectories of equal length, paired by index.
struct Paired {
    reference: Trajectory,
    estimate: Trajectory,
    estimate_format: PoseFormat,
    /// Whether the pairs come from time-stamp association.
    associated: bool,
    /// Poses in the files before pairing.
    reference_poses: usize,
    estimate_poses: usize,
}

fn load_one(path: &Path, times: Option<&Path>) -> anyhow::Result<(PoseFile, bool)> {
    let mut file = read_poses(path)?;
    let mut stamped = file.format.has_stamps();
    if let Some(times) = times {
        ensure!(
            !stamped,
            "{}: a {} file carries its own time stamps; --ref-times / --est-times are for \
             KITTI files (which have none), {} would replace them",
            path.display(),
            file.format,
            times.display()
        );
        let stamps = read_times(times)?;
        file.trajectory = file
            .trajectory
            .with_stamps(stamps)
            .with_context(|| format!("{} with times from {}", path.display(), times.display()))?;
        stamped = true;
    }
    Ok((file, stamped))
}

/// Reads both files and pairs their poses: by time-stamp association when
/// both carry stamps, otherwise by index (lengths must then agree).
fn load_pair(args: &PairArgs) -> anyhow::Result<Paired> {
    let (reference, ref_stamped) = load_one(&args.reference, args.ref_times.as_deref())?;
    let (estimate, est_stamped) = load_one(&args.estimate, args.est_times.as_deref())?;
    let (reference_poses, estimate_poses) = (reference.trajectory.len(), estimate.trajectory.len());
    let estimate_format = estimate.format;
    if ref_stamped && est_stamped {
        // Repeated stamps pair with the last of each group, as in evo 1.38.1:
        // said, since many of them mean a file written with too few digits.
        for (file, path) in [(&reference, &args.reference), (&estimate, &args.estimate)] {
            if let Some((n, first, stamp)) = repeated_stamps(&file.trajectory) {
                eprintln!(
                    "note: {}: {} the time stamp of the pose before (the first: the file's \
                     pose {first}, counting from 0, at {stamp} s); time pairing takes the last \
                     pose of a stamp, as evo 1.38.1 does{}",
                    path.display(),
                    if n == 1 {
                        "1 pose repeats".to_string()
                    } else {
                        format!("{n} poses repeat")
                    },
                    if n * 10 > file.trajectory.len() {
                        " (so many: stamps written with too few digits?)"
                    } else {
                        ""
                    }
                );
            }
        }
        let (r, e) = associate(
            &reference.trajectory,
            &estimate.trajectory,
            args.t_max_diff,
            args.t_offset,
        )?;
        return Ok(Paired {
            reference: r,
            estimate: e,
            estimate_format,
            associated: true,
            reference_poses,
            estimate_poses,
        });
    }
    if ref_stamped != est_stamped {
        let (stamped, other) = match ref_stamped {
            true => (&args.reference, &args.estimate),
            false => (&args.estimate, &args.reference),
        };
        eprintln!(
            "note: {} carries time stamps and {} none (a KITTI file: --ref-times / \
             --est-times give it some), so the poses are paired by index, not by time",
            stamped.display(),
            other.display()
        );
    }
    if reference_poses != estimate_poses {
        // A run over a sequence's first frames (a folder with the first
        // scans and the whole drive's poses) is the usual case.
        let first = if estimate_poses < reference_poses {
            // Never the reference's own name: `head F > F` empties F.
            let r = &args.reference;
            let stem = r.file_stem().unwrap_or_default().to_string_lossy();
            let name = format!("{stem}_first{estimate_poses}.txt");
            // Beside the reference, but not into a dataset's folder (a
            // new file among a dataset's): there, in the current folder.
            // (KITTI's poses/ beside sequences/ is a dataset's folder too.)
            let parent = r.parent().unwrap_or(Path::new(""));
            let folder = match parent.as_os_str().is_empty() {
                true => Path::new("."),
                false => parent,
            };
            let kitti_poses = folder.canonicalize().ok().is_some_and(|d| {
                d.file_name().is_some_and(|n| n == "poses")
                    && d.parent().is_some_and(|p| p.join("sequences").is_dir())
            });
            let in_dataset = super::outputs::is_sequence_folder(folder) || kitti_poses;
            let mut first = match (in_dataset, parent.as_os_str().is_empty()) {
                (false, _) => r.with_file_name(&name),
                // Run inside the dataset's folder: one up.
                (true, true) => Path::new("..").join(&name),
                (true, false) => PathBuf::from(&name),
            };
            if first == *r {
                first = r.with_file_name(format!("{stem}_first{estimate_poses}_.txt"));
            }
            format!(
                " (for a run over the sequence's first {estimate_poses} frames, compare with \
                 those: head -n {estimate_poses} {} > {})",
                r.display(),
                first.display()
            )
        } else {
            String::new()
        };
        bail!(
            "{} has {reference_poses} poses and {} has {estimate_poses}; without time stamps on \
             both (TUM files, or --ref-times/--est-times for KITTI files) poses are paired by \
             index and the counts must agree{first}",
            args.reference.display(),
            args.estimate.display()
        );
    }
    Ok(Paired {
        reference: reference.trajectory,
        estimate: estimate.trajectory,
        estimate_format,
        associated: false,
        reference_poses,
        estimate_poses,
    })
}

fn pairing_line(args: &PairArgs, p: &Paired) -> String {
    if p.associated {
        format!(
            "{} of {} / {} poses matched by time (max diff {} s, offset {} s)",
            p.reference.len(),
            p.reference_poses,
            p.estimate_poses,
            args.t_max_diff,
            args.t_offset
        )
    } else {
        format!("{} poses paired by index", p.reference.len())
    }
}

fn print_errors(
    metric: &str,
    args: &PairArgs,
    p: &Paired,
    alignment: &AlignmentResult,
    errors: &PoseErrors,
    rpe: Option<&RpeOptions>,
) {
    let mut out = String::new();
    let what = match errors.relation {
        PoseRelation::Translation => "translation",
        PoseRelation::RotationAngleDeg => "rotation angle",
    };
    outln!(out, "{metric} w.r.t. {what} ({})", errors.relation.unit());
    if let Some(o) = rpe {
        let kind = if o.all_pairs { "all" } else { "consecutive" };
        outln!(out, "  delta      {}, {kind} pairs", o.delta);
    }
    outln!(out, "  reference  {}", args.reference.display());
    outln!(out, "  estimate   {}", args.estimate.display());
    outln!(out, "  pairing    {}", pairing_line(args, p));
    let sim = &alignment.reference_from_estimate;
    match alignment.alignment {
        Alignment::None => outln!(out, "  alignment  none"),
        a => outln!(
            out,
            "  alignment  {a:?} on {} poses: scale {:.6}, translation [{:.4}, {:.4}, {:.4}] m, rotation {:.4} deg",
            alignment.poses_used,
            sim.scale,
            sim.translation.x,
            sim.translation.y,
            sim.translation.z,
            sim.rotation_angle().to_degrees()
        ),
    }
    let s = &errors.stats;
    outln!(out, "");
    for (name, v) in [
        ("rmse", s.rmse),
        ("mean", s.mean),
        ("median", s.median),
        ("std", s.std),
        ("min", s.min),
        ("max", s.max),
        ("sse", s.sse),
    ] {
        outln!(out, "  {name:>8}  {v:>14.6}");
    }
    outln!(out, "  {:>8}  {:>14}", "count", s.count);
    emit(&out);
}

fn errors_json(
    metric: &str,
    args: &PairArgs,
    p: &Paired,
    alignment: &AlignmentResult,
    errors: &PoseErrors,
    rpe: Option<&RpeOptions>,
) -> serde_json::Value {
    serde_json::json!({
        "metric": metric,
        "relation": errors.relation,
        "unit": errors.relation.unit(),
        "reference": args.reference,
        "estimate": args.estimate,
        "pairs": p.reference.len(),
        "associated": p.associated,
        "t_max_diff": args.t_max_diff,
        "t_offset": args.t_offset,
        "rpe": rpe,
        "alignment": alignment,
        "stats": errors.stats,
        "errors": errors.errors,
    })
}

fn print_kitti(args: &PairArgs, p: &Paired, m: &KittiMetric) {
    let mut out = String::new();
    outln!(out, "KITTI odometry metric");
    outln!(out, "  reference  {}", args.reference.display());
    outln!(out, "  estimate   {}", args.estimate.display());
    outln!(out, "  pairing    {}", pairing_line(args, p));
    outln!(out, "");
    outln!(
        out,
        "  {:>8}  {:>8}  {:>14}  {:>14}",
        "length",
        "segments",
        "trans (%)",
        "rot (deg/m)"
    );
    for l in &m.per_length {
        outln!(
            out,
            "  {:>6} m  {:>8}  {:>14.6}  {:>14.6}",
            l.length,
            l.segments,
            l.translation_percent,
            l.rotation_deg_per_m
        );
    }
    outln!(
        out,
        "  {:>8}  {:>8}  {:>14.6}  {:>14.6}",
        "all",
        m.segments,
        m.translation_percent,
        m.rotation_deg_per_m
    );
    emit(&out);
}

/// Prints a report; a closed stdout (`omcl eval ... | head`) is not an error.
fn emit(text: &str) {
    let mut stdout = std::io::stdout().lock();
    let _ = stdout
        .write_all(text.as_bytes())
        .and_then(|_| stdout.flush());
}

/// Writes JSON through a temporary file renamed into place.
fn write_json(
    path: Option<&Path>,
    value: impl FnOnce() -> serde_json::Value,
) -> anyhow::Result<()> {
    let Some(path) = path else { return Ok(()) };
    let text = serde_json::to_string_pretty(&value())?;
    omcl::io::atomic::write(path, format!("{text}\n").as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    emit(&format!("JSON written to {}\n", path.display()));
    Ok(())
}

/// A rotation fitted to positions that lie almost on a line (a few poses
/// of a straight drive) is noise about that line: said, with the spread.
fn warn_line_alignment(reference: &Trajectory, alignment: &AlignmentResult) {
    if !matches!(alignment.alignment, Alignment::Se3 | Alignment::Sim3) {
        return;
    }
    let used: Vec<_> = reference
        .poses()
        .iter()
        .take(alignment.poses_used)
        .map(|p| p.translation.vector)
        .collect();
    let r = omcl::eval::align::off_line(&used);
    if r < 0.01 {
        eprintln!(
            "warning: the {} reference positions the alignment is fitted to lie almost on a \
             line (their spread across it is {:.2} % of that along it): the rotation about \
             that line is left to noise; use more poses, or --align origin or none",
            used.len(),
            100.0 * r
        );
    }
}
