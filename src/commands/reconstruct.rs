//! `rsasim reconstruct`: the reference RSA program on an output folder (on a sweep folder: on
//! every point, by [`super::sweep::reconstruct_any`]).

use std::path::Path;
use std::time::Instant;

use rsasim::reconstruct::Options;

use super::Outcome;
use super::shared::report_errors;
use super::sweep::reconstruct_any;
use crate::cli::ReconstructArgs;

/// Reconstructs the output folder, or every point of the sweep folder, given.
pub fn execute(args: ReconstructArgs) -> Outcome {
    let options = Options {
        method: args.method.into(),
        model_method: args.model_method.map(Into::into),
        measured: args.measured,
        overwrite: args.overwrite,
        stability_threshold_mm: Some(args.stability_threshold_mm),
    };
    reconstruct_any(&args.out, &options)
}

/// Reconstructs one output folder: errors in the input exit 2; a run that failed, or nothing
/// reconstructed, exits 1.
pub fn one(out: &Path, options: &Options) -> Outcome {
    let start = Instant::now();
    let summary =
        rsasim::reconstruct::reconstruct(out, options).map_err(|errors| report_errors(&errors))?;
    for f in &summary.failures {
        eprintln!("warning: run {}: {}", f.run, f.reason);
    }
    for (run, why) in &summary.failed {
        eprintln!("error: run {run}: {why}");
    }
    eprintln!(
        "rsasim reconstruct: {} run(s) reconstructed, {} run(s) failed; {} of {} model fit(s) failed; in {:.1} s -> runs/*/{}",
        summary.runs,
        summary.failed.len(),
        summary.models_tried - summary.models_found,
        summary.models_tried,
        start.elapsed().as_secs_f64(),
        summary.measured
    );
    if let Some(m) = &summary.migration {
        for f in &m.failures {
            eprintln!("warning: migration: {f}");
        }
        eprintln!(
            "rsasim reconstruct: study migration: {} migration(s), {} loose marker(s) excluded -> migration_measured.json, migration_measured.csv",
            m.migrations, m.excluded_markers
        );
    }
    if summary.nothing_reconstructed() {
        eprintln!("error: nothing could be reconstructed");
        return Err(1);
    }
    eprintln!(
        "score them with `rsasim evaluate {} --measured {}`",
        out.display(),
        summary.measured
    );
    if summary.failed.is_empty() {
        Ok(())
    } else {
        Err(1)
    }
}
