//! `rsasim merge`: join the shard folders of one scenario into one output folder.

use std::time::Instant;

use rsasim::output::merge::{self, Error};

use super::Outcome;
use super::shared::report_errors;
use crate::cli::MergeArgs;

/// Checks the shards (exit 2, nothing written), claims the merged folder, then assembles it.
pub fn execute(args: MergeArgs) -> Outcome {
    let out = &args.out;
    let start = Instant::now();
    let checked = merge::check(&args.shards).map_err(|e| report_errors(&e))?;
    for path in &checked.not_merged {
        eprintln!("rsasim: not merged (no manifest lists it): {path}");
    }
    let target = merge::claim(&checked, out, args.force).map_err(|e| report_errors(&e))?;
    target.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    let (count, runs) = (checked.count(), checked.runs());
    let summary = merge::assemble(checked, target, args.copy).map_err(|e| match e {
        Error::Input(errors) => report_errors(&errors),
        Error::Write(why) => {
            eprintln!(
                "error: writing {} failed: {why}\n  = note: nothing was replaced; a previous output there is unchanged",
                out.display()
            );
            1
        }
    })?;
    summary.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    eprintln!(
        "rsasim merge: {count} shard(s), {runs} run(s), {} file(s) ({} hard-linked, {} copied), {:.1} MB verified in {:.1} s -> {}",
        summary.linked + summary.copied,
        summary.linked,
        summary.copied,
        summary.bytes as f64 / 1e6,
        start.elapsed().as_secs_f64(),
        summary.out_dir.display()
    );
    Ok(())
}
