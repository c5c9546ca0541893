//! Helpers of several commands: printing errors, checking and preparing a scenario, resolving
//! and bounding a shard.

use std::path::{Path, PathBuf};

use rsasim::diagnostic::Diagnostic;
use rsasim::shard::{ShardRequest, ShardSpec};
use rsasim::simulate::{self, Allowances, Checked, Plan};

/// Most errors printed in full; the rest are counted (a hostile file can hold millions).
pub const MAX_ERRORS_SHOWN: usize = 20;

/// Prints `errors` (the first [`MAX_ERRORS_SHOWN`] in full) and that nothing was written;
/// returns exit code 2.
pub fn report_errors(errors: &[Diagnostic]) -> u8 {
    errors
        .iter()
        .take(MAX_ERRORS_SHOWN)
        .for_each(|e| eprintln!("{e}\n"));
    if errors.len() > MAX_ERRORS_SHOWN {
        eprintln!(
            "rsasim: {} more error(s) not shown",
            errors.len() - MAX_ERRORS_SHOWN
        );
    }
    eprintln!("rsasim: {} error(s); nothing was written", errors.len());
    2
}

/// Reports why a new folder (`export`, `camera --dir`) was not written: bad input (exit 2) or a
/// failure while writing `dir` (exit 1); nothing was written either way.
pub fn report_folder_error(e: rsasim::interop::export::Error, dir: &Path) -> u8 {
    match e {
        rsasim::interop::export::Error::Input(errors) => report_errors(&errors),
        rsasim::interop::export::Error::Write(why) => {
            eprintln!(
                "error: writing {} failed: {why}\n  = note: nothing was written there",
                dir.display()
            );
            1
        }
    }
}

/// Loads and checks a scenario (run by run, without keeping the runs), printing warnings;
/// errors are printed and give exit code 2.
pub fn check(path: &Path, allow: &Allowances) -> Result<Checked, u8> {
    match simulate::check(path, allow) {
        Ok(checked) => {
            checked.warnings.iter().for_each(|w| eprintln!("{w}"));
            Ok(checked)
        }
        Err(errors) => Err(report_errors(&errors)),
    }
}

/// [`check`], then every run expanded for the simulation.
pub fn prepare(path: &Path, allow: &Allowances) -> Result<Plan, u8> {
    check(path, allow).map(Plan::from)
}

/// The shard of `--shard` (`auto`: from the environment), or exit 2 with the reason.
pub fn resolve_shard(
    request: ShardRequest,
    shard_count: Option<usize>,
) -> Result<(ShardSpec, String), u8> {
    let vars: std::collections::HashMap<String, String> = std::env::vars().collect();
    rsasim::shard::env::resolve(request, shard_count, &vars).map_err(|e| {
        eprintln!(
            "error: {}\n  = help: {}\n\nrsasim: 1 error(s); nothing was written",
            e.message, e.help
        );
        2
    })
}

/// Refuses (exit 2) more shards `spec` (decided `from`) than `runs` can fill, unless `large`.
pub fn check_shard_count(spec: ShardSpec, from: &str, runs: usize, large: bool) -> Result<(), u8> {
    rsasim::shard::check_count(spec.count, runs, large).map_err(|why| {
        eprintln!(
            "error: --shard {spec} ({from}): {why}\n  = help: use fewer shards (--shard K/N with a smaller N)\n\nrsasim: 1 error(s); nothing was written"
        );
        2
    })
}

/// Writes `text` to standard output; exit 1 naming the failure (a reader that closed the pipe
/// early, as `| head` does, is no failure: the rest is not wanted).
pub fn print_stdout(text: &str) -> Result<(), u8> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => {
            eprintln!("error: writing to standard output failed: {e}");
            Err(1)
        }
    }
}

/// Paths for a message, joined by `, `.
pub fn shown(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}
