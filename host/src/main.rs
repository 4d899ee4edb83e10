//! The `riseg` command line.

use clap::{Parser, Subcommand};

/// RISeg: robot interactive object segmentation via body frame-invariant features.
///
/// A robot looks at touching objects on a table with an RGB-D camera; a static segmenter
/// merges them; riseg makes a few 2 cm pushes, samples small body frames on the objects,
/// groups them by their spatial twists and splits what moved differently.
#[derive(Debug, Parser)]
#[command(name = "riseg", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the whole loop on a simulated scene and write a report (the default command).
    ///
    /// Needs the simulator, built-in segmenter and flow, which later releases add; until
    /// then this command says so and exits with an error.
    Demo,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command.unwrap_or(Command::Demo) {
        Command::Demo => anyhow::bail!(
            "the demo is not built yet: it needs the simulator, the built-in segmenter and \
             flow (see README.md, 'State of each part'); riseg-core's algorithm is usable as a \
             library today"
        ),
    }
}
