//! `rsasim export`: an output folder as the files XMALab or Autoscoper open.

use std::time::Instant;

use rsasim::interop::export::{self, Options};

use super::Outcome;
use super::shared::report_folder_error;
use crate::cli::ExportArgs;

/// Exports (errors in the input: exit 2, nothing written; a failure while writing: exit 1).
pub fn execute(args: ExportArgs) -> Outcome {
    let options = Options {
        target: args.to.into(),
        runs: args.runs,
        dense_matter: args.dense_matter.into(),
        calibration_from: args.calibration_from,
        calibration_object: args.calibration_object.into(),
        voxel_mm: args.voxel_mm,
    };
    let dir = &args.dir;
    let start = Instant::now();
    let summary = export::export(&args.out, args.truth.as_deref(), dir, &options)
        .map_err(|e| report_folder_error(e, dir))?;
    summary.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    let what = if summary.sequences == 0 {
        format!("{} run(s)", summary.runs)
    } else {
        format!(
            "{} trial(s) ({} sequence(s), {} frame(s) in all)",
            summary.runs, summary.sequences, summary.frames
        )
    };
    eprintln!(
        "rsasim export: {what}, {} files for {} in {:.1} s -> {}",
        summary.files,
        options.target.name(),
        start.elapsed().as_secs_f64(),
        summary.dir.display()
    );
    Ok(())
}
