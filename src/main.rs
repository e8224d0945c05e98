//! The `omcl` command-line tool.
mod cli;

use clap::Parser;

#[derive(Debug, Parser)]
#[command(
    name = "omcl",
    version,
    about = "Open-vocabulary Monte Carlo Localization"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    /// Synthetic worlds and sensor data.
    #[command(subcommand)]
    Sim(cli::sim::SimCommand),
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Sim(cmd) => cli::sim::run(cmd),
    }
}
