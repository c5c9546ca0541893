//! The `rsasim` command: parse the arguments ([`cli`]), hand each subcommand to its module under
//! [`commands`], and map a failure to the exit code (2: bad input, nothing written; 1: a failure
//! while writing). Every message is printed by the command itself.

mod cli;
mod commands;
mod spectrum_plot;

use std::process::ExitCode;

use clap::Parser;

use cli::{Cli, Command};
use commands::{
    camera, evaluate, expand, export, material, merge, reconstruct, run, scene, schema, spectrum,
    sweep, validate, verify,
};

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Validate(args)) => validate::execute(args),
        Some(Command::Expand(args)) => expand::execute(args),
        Some(Command::Scene(args)) => scene::execute(args),
        Some(Command::Schema(args)) => schema::execute(args),
        Some(Command::Reconstruct(args)) => reconstruct::execute(args),
        Some(Command::Sweep(args)) => sweep::execute(args),
        Some(Command::Export(args)) => export::execute(args),
        Some(Command::Camera(args)) => camera::execute(args),
        Some(Command::Evaluate(args)) => evaluate::execute(args),
        Some(Command::Verify(args)) => verify::execute(args),
        Some(Command::Merge(args)) => merge::execute(args),
        Some(Command::Material(args)) => material::execute(args),
        Some(Command::Spectrum(args)) => spectrum::execute(args),
        None => run::execute(cli.run),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(code) => ExitCode::from(code),
    }
}
