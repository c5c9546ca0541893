//! Command-line arguments. `main` only parses these and dispatches to the library.

use std::path::PathBuf;

use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand};
use rsasim::reconstruct::{Method, ModelMethod};

/// rsasim: simulate Radio Stereometric Analysis X-ray scenes with known ground truth.
///
/// Run a scenario: `rsasim scenarios/biplanar.toml` writes images, truth.json and manifest.json
/// for every run of its protocol into out/<scenario name>/.
#[derive(Debug, Parser)]
#[command(
    name = "rsasim",
    version,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
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
    /// Output folder. Default: out/<scenario name>. It is written in a private staging folder
    /// beside it and swapped in only once complete; a lock file `.<name>.rsasim-lock` beside it
    /// keeps a second rsasim process out. A file or a symbolic link there is refused.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Replace the output folder if it is an earlier rsasim output (its manifest.json says so) or
    /// empty; never the current folder or a parent of it, a folder holding the scenario or a mesh
    /// it reads, a link or a file. The old output is removed only after the new one is in place.
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
    /// Score a software's results against the truth by ISO 5725 (trueness ± precision) and write
    /// the paper's tables as Markdown, CSV, LaTeX and a self-contained HTML report.
    Evaluate {
        /// The output folder of a simulation (it holds manifest.json, scenario.toml and runs/).
        out: PathBuf,
        /// File name of the results in every run folder (schemas/measured.schema.json).
        #[arg(
            long,
            default_value = "measured.json",
            value_name = "FILE_NAME",
            conflicts_with = "csv"
        )]
        measured: String,
        /// Read every run's results from one CSV long table instead (columns in the README).
        #[arg(long, value_name = "FILE")]
        csv: Option<PathBuf>,
        /// Confidence level of τ, in (0, 1).
        #[arg(long, default_value_t = 0.95, value_name = "LEVEL")]
        confidence: f64,
        /// One- or two-sided τ; the paper's τ = 1.73 at N = 20 is one-sided 95 %.
        #[arg(long, default_value = "one", value_parser = ["one", "two"])]
        sided: String,
        /// Report formats, comma-separated: md, csv, tex, html.
        #[arg(
            long,
            default_value = "md,csv,tex,html",
            value_delimiter = ',',
            value_name = "LIST"
        )]
        format: Vec<String>,
        /// Folder the reports are written to. Default: OUT/report.
        #[arg(long, value_name = "DIR")]
        report: Option<PathBuf>,
    },
    /// Run rsasim's reference RSA program on an output folder: calibrate every beamline from the
    /// box beads, find each model from its beads, and write measured.json into every run folder.
    /// It reads only what a real RSA program has: images, nominal set-up, phantoms/ (never truth.json).
    Reconstruct {
        /// The output folder of a simulation.
        out: PathBuf,
        /// How each beamline is calibrated from the box beads. dlt: normalised DLT on both facing
        /// plates, decomposition with the known pixel pitch, joint Levenberg–Marquardt fit of
        /// source and detector. selvik: the classic cage method (homography from the fiducial
        /// plate, focus from the control plate; not statistically optimal), for comparison.
        #[arg(long, default_value = "dlt", value_parser = method_parser())]
        method: Method,
        /// How each model's pose is found. markers: marker-based RSA (triangulate the model's
        /// beads in two views, fit its bead table). silhouette: model-based RSA (fit the model
        /// mesh's projected outline to the edges of its shadow in every view; no beads needed).
        /// Default: markers for a model with beads, silhouette for a model without.
        #[arg(long, value_name = "METHOD", value_parser = model_method_parser())]
        model_method: Option<ModelMethod>,
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

/// `markers` | `silhouette` → [`ModelMethod`], listing both in `--help`.
fn model_method_parser() -> impl TypedValueParser<Value = ModelMethod> {
    PossibleValuesParser::new(["markers", "silhouette"]).map(|s| {
        if s == "silhouette" {
            ModelMethod::Silhouette
        } else {
            ModelMethod::Markers
        }
    })
}

/// `dlt` | `selvik` → [`Method`], listing both in `--help`.
fn method_parser() -> impl TypedValueParser<Value = Method> {
    PossibleValuesParser::new(["dlt", "selvik"]).map(|s| {
        if s == "selvik" {
            Method::Selvik
        } else {
            Method::Dlt
        }
    })
}
