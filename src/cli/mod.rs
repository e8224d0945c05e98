//! Command-line interface: argument parsing and the glue between files and
//! the library. Errors are `anyhow` here, `thiserror` in the library.

pub mod bench;
pub mod bench_args;
pub mod bench_sevenscenes;
pub mod bench_table1;
pub mod demo;
pub mod encode;
pub mod encoders;
pub mod eval;
pub mod localize;
pub mod map;
pub mod map_build;
pub mod map_floorplan;
pub mod outputs;
pub mod progress;
pub mod serve;
pub mod sim;
pub mod sweep;

use clap::{Parser, Subcommand};

/// The command line as parsed: [`Cli`]'s, with every option and argument
/// that takes a value allowed to take a negative number, so `--delta -1`
/// reaches the option's own check ("out of range") instead of clap's
/// "unexpected argument '-1'" and its tip to write `-- -1`.
pub fn command() -> clap::Command {
    fn negatives(c: clap::Command) -> clap::Command {
        c.mut_args(|a| {
            if a.get_action().takes_values() {
                a.allow_negative_numbers(true)
            } else {
                a
            }
        })
        .mut_subcommands(negatives)
    }
    use clap::CommandFactory;
    negatives(Cli::command())
}

/// Parses the process's arguments with [`command`]; on an error prints
/// clap's message and exits as clap does (2).
pub fn parse() -> Cli {
    use clap::FromArgMatches;
    let mut matches = command().get_matches();
    Cli::from_arg_matches_mut(&mut matches).unwrap_or_else(|e| e.format(&mut command()).exit())
}

/// Open-vocabulary Monte Carlo Localization: build language maps from RGB-D
/// frames or point clouds, localize cameras in them, and evaluate.
#[derive(Debug, Parser)]
#[command(name = "omcl", version, about, long_about = None, propagate_version = true)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Build, inspect, ground and query Octree Language Maps.
    #[command(subcommand)]
    Map(map::MapCommand),
    /// The paper's experiments on the synthetic benchmark: tables and plots.
    Bench(bench_args::BenchArgs),
    /// Run the pipeline end to end on the built-in synthetic world.
    Demo(demo::DemoArgs),
    /// Run ONNX encoders: words, images and point clouds to features.
    #[command(subcommand)]
    Encode(encode::EncodeCommand),
    /// Trajectory metrics: APE, RPE (as evo) and the KITTI odometry metric.
    #[command(subcommand)]
    Eval(eval::EvalCommand),
    /// Localize a camera sequence in a map with the particle filter.
    Localize(Box<localize::LocalizeArgs>),
    /// Serve localization to many cameras at once over gRPC (+ HTTP control
    /// plane), maps loaded once.
    Serve(Box<serve::ServeArgs>),
    /// Synthetic worlds and sensor data in real datasets' layouts.
    #[command(subcommand)]
    Sim(sim::SimCommand),
    /// Experiment sweeps as independent runs: plan, run, collect, Slurm.
    #[command(subcommand)]
    Sweep(sweep::SweepCommand),
}

/// Runs a parsed command line.
/// A whole number in `LO..=HI`: clap's parser for the counts that size
/// allocations (`--particles 100000000000` asked for 6.4 TB and aborted).
pub fn count_in<const LO: usize, const HI: usize>(s: &str) -> Result<usize, String> {
    let n: usize = s.trim().parse().map_err(|e| format!("{e}"))?;
    if (LO..=HI).contains(&n) {
        Ok(n)
    } else if HI == usize::MAX {
        Err(format!("{n} is less than {LO}: give at least {LO}"))
    } else {
        Err(format!("{n} is not in {LO}..={HI}"))
    }
}

/// A finite number of metres in `0..=10000`: clap's parser for spreads
/// and noise (`--odom-noise-m inf` ran and wrote infinite poses).
pub fn metres(s: &str) -> Result<f64, String> {
    finite_in(s, 0.0, 10_000.0)
}

/// A finite number of degrees in `0..=360` (spreads and noise).
pub fn degrees(s: &str) -> Result<f64, String> {
    finite_in(s, 0.0, 360.0)
}

/// A finite number (a height, say: `--max-height nan` ran).
pub fn finite(s: &str) -> Result<f64, String> {
    finite_in(s, f64::MIN, f64::MAX)
}

/// A finite number of seconds above 0 (`serve --deadline-s 0` was taken).
pub fn positive_seconds(s: &str) -> Result<f64, String> {
    let v = finite_in(s, 0.0, 1e9)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err("must be above 0 seconds".into())
    }
}

/// `n` and the noun, plural but for one: `count(1, "row")` is "1 row".
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// A finite score in `0..=1` (`--miss-score 5` was taken).
pub fn unit_score(s: &str) -> Result<f32, String> {
    finite_in(s, 0.0, 1.0).map(|v| v as f32)
}

/// A finite cosine similarity in `-1..=1` (`--min-similarity nan` was
/// taken).
pub fn cosine(s: &str) -> Result<f32, String> {
    finite_in(s, -1.0, 1.0).map(|v| v as f32)
}

/// A name stored in a file and printed back (`--encoder`): 1 to 200
/// characters, none of them a control character (a newline or a terminal
/// escape had been stored and printed as it was).
pub fn name(s: &str) -> Result<String, String> {
    if s.trim().is_empty() {
        return Err("a name cannot be empty".into());
    }
    if s.chars().count() > 200 {
        return Err(format!("{} characters: at most 200", s.chars().count()));
    }
    if s.chars().any(char::is_control) {
        return Err("a name cannot hold control characters (newlines, escapes)".into());
    }
    Ok(s.to_string())
}

/// A finite number above 0 (`--depth-scale 0` was refused by the first
/// frame, named as if the file were at fault).
pub fn positive(s: &str) -> Result<f64, String> {
    let v = finite(s)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not above 0"))
    }
}

/// A finite number, 0 or more (a count of voxels, say).
pub fn non_negative(s: &str) -> Result<f64, String> {
    finite_in(s, 0.0, f64::MAX)
}

/// A finite number of seconds, 0 or more.
pub fn seconds(s: &str) -> Result<f64, String> {
    finite_in(s, 0.0, 1e12)
}

fn finite_in(s: &str, lo: f64, hi: f64) -> Result<f64, String> {
    let v: f64 = s.trim().parse().map_err(|e| format!("{e}"))?;
    if !v.is_finite() {
        return Err(format!("{} is not a finite number", s.trim()));
    }
    if (lo..=hi).contains(&v) {
        return Ok(v);
    }
    // f64::MIN and f64::MAX print as 309 digits: no bound at all.
    Err(match (lo > f64::MIN, hi < f64::MAX) {
        (true, true) => format!("{v} is out of range: {lo}..={hi} is accepted"),
        (true, false) => format!("{v} is out of range: {lo} or more is accepted"),
        (false, true) => format!("{v} is out of range: {hi} or less is accepted"),
        (false, false) => unreachable!("every finite number is in range"),
    })
}

/// Most frames a simulated sequence or path may have (`omcl sim`, `omcl
/// bench`): `bench --frames 1000000000` asked for 56 GB and aborted.
pub const MAX_FRAMES: usize = 100_000;

/// Most particles and most rays a filter takes from the command line, as
/// from `omcl serve`'s clients.
pub use omcl::mcl::MAX_COUNT;

/// An error with an exit code of its own, for scripts and batch systems
/// to tell apart from a failure (1) and a usage error (2, clap's).
#[derive(Debug)]
pub struct Exit {
    pub code: u8,
    pub message: String,
}

impl Exit {
    /// No retry can mend it (a sweep run's manifest line is unusable):
    /// exit 3, which a Slurm task does not requeue.
    pub fn cannot_succeed(message: String) -> Self {
        Exit { code: 3, message }
    }

    /// Work not finished yet (`omcl sweep status --complete` with runs
    /// missing): exit 4.
    pub fn not_yet(message: String) -> Self {
        Exit { code: 4, message }
    }
}

impl std::fmt::Display for Exit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Exit {}

impl Cli {
    /// The command handles SIGINT and SIGTERM itself (`omcl serve`: a
    /// graceful shutdown).
    pub fn handles_signals(&self) -> bool {
        matches!(self.command, Command::Serve(_))
    }
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Map(cmd) => map::run(cmd),
        Command::Bench(args) => bench::run(args),
        Command::Demo(args) => demo::run(args),
        Command::Encode(cmd) => encode::run(cmd),
        Command::Eval(cmd) => eval::run(cmd),
        Command::Localize(a) => localize::run(*a),
        Command::Serve(a) => serve::run(*a),
        Command::Sim(cmd) => sim::run(cmd),
        Command::Sweep(cmd) => sweep::run(cmd),
    }
}
