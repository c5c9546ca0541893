//! Command-line arguments. `main` only parses these and dispatches to the library.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// rsasim: simulate Radio Stereometric Analysis X-ray scenes with known ground truth.
///
/// Run a scenario: `rsasim scenarios/biplanar.toml` writes images, truth.json and manifest.json
/// for every run of its protocol into out/<scenario name>/.
#[derive(Debug, Parser)]
#[command(name = "rsasim", version, args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct Cli {
    /// A subcommand; without one, rsasim runs the scenario given.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Running a scenario (the default command).
    #[command(flatten)]
    pub run: RunArgs,
}

/// Arguments of the default command: run a scenario.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The scenario file to run (TOML), e.g. scenarios/biplanar.toml.
    #[arg(required = true)]
    pub scenario: Option<PathBuf>,
    /// Output folder. Default: out/<scenario name>.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Replace the output folder if it already exists (it is swapped in only once complete).
    #[arg(long)]
    pub force: bool,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Check a scenario (syntax, values, mesh files, geometry of every run) and write nothing.
    Validate {
        /// The scenario file to check.
        scenario: PathBuf,
    },
    /// Print every concrete run (poses, seeds, noise level) as JSON, in the box frame.
    Expand {
        /// The scenario file to expand.
        scenario: PathBuf,
    },
    /// Print a JSON Schema: scenario (default), truth, measured or manifest.
    Schema {
        /// Which schema to print.
        #[arg(default_value = "scenario", value_parser = ["scenario", "truth", "measured", "manifest"])]
        name: String,
        /// Instead of printing, write every schema as <DIR>/<name>.schema.json.
        #[arg(long, value_name = "DIR")]
        write_dir: Option<PathBuf>,
    },
}
