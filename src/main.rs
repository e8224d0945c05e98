//! The `omcl` command.
mod cli;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "omcl",
    version,
    about = "Open-vocabulary Monte Carlo Localization"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Trajectory metrics (APE, RPE, KITTI odometry metric).
    #[command(subcommand)]
    Eval(cli::eval::EvalCommand),
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Eval(cmd) => cli::eval::run(cmd),
    }
}
