//! `rsasim reconstruct`: the reference RSA program on an output folder (on a sweep folder: on
//! every point, by [`reconstruct_any`]).

use std::path::Path;
use std::time::Instant;

use rsasim::reconstruct::Options;

use super::Outcome;
use super::shared::report_errors;
use crate::cli::ReconstructArgs;

/// Reconstructs the output folder, or every point of the sweep folder, given.
pub fn execute(args: ReconstructArgs) -> Outcome {
    let options = Options {
        method: args.method.into(),
        model_method: args.model_method.map(Into::into),
        measured: args.measured,
        overwrite: args.overwrite,
        stability_threshold_mm: Some(args.stability_threshold_mm),
        bead_centre: args.bead_centre.into(),
        edge_on_plates: args.edge_on_plates.into(),
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

/// `rsasim reconstruct` on an output folder, or on every point of a sweep folder (all points
/// are tried; the worst exit code is returned).
pub fn reconstruct_any(out: &Path, options: &rsasim::reconstruct::Options) -> Outcome {
    if !rsasim::sweep::is_sweep_folder(out) {
        return one(out, options);
    }
    let index = rsasim::sweep::read_index(out).map_err(|e| report_errors(&e))?;
    let mut point_dirs = Vec::with_capacity(index.points.len());
    for p in &index.points {
        point_dirs
            .push(rsasim::sweep::folder::point_folder(out, p).map_err(|e| report_errors(&e))?);
    }
    let mut worst = Ok(());
    let mut written: Vec<&str> = Vec::new();
    for (p, point_dir) in index.points.iter().zip(&point_dirs) {
        eprintln!("rsasim reconstruct: point {}", p.id);
        match one(point_dir, options) {
            Ok(()) => written.push(&p.id),
            Err(code) => worst = Err(worst.err().map_or(code, |w: u8| w.max(code))),
        }
    }
    // Exit 2 says nothing was written: once a point's results are written, a later point's bad
    // input is exit 1, with the points that were reconstructed named.
    if worst == Err(2) && !written.is_empty() {
        eprintln!(
            "rsasim reconstruct: the results of point(s) {} were written before a later point was refused",
            written.join(", ")
        );
        return Err(1);
    }
    worst
}
