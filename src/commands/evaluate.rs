//! `rsasim evaluate`: score a software's results and write the reports (on a sweep folder: every
//! point's, then the summary, by [`evaluate_sweep`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use rsasim::evaluate::report::{self, Format, pdf::Browser};
use rsasim::evaluate::study::StudyOptions;
use rsasim::evaluate::table::Report;
use rsasim::evaluate::{MeasuredSource, Options, stats};
use rsasim::output::commit::OutputTarget;

use super::Outcome;
use super::shared::{report_errors, shown};
use crate::cli::EvaluateArgs;

/// The reports asked for: their formats, the browser a PDF needs, and the folder given with
/// `--report` (if any).
pub struct Reports {
    /// The formats, in the order given.
    pub formats: Vec<Format>,
    /// The headless browser, when a PDF is asked for.
    pub browser: Option<Browser>,
    /// `--report`: the reports' folder (on a sweep folder: the summary's).
    pub dir: Option<PathBuf>,
}

/// Checks the numbers and finds a browser for a PDF (exit 2 before anything is read), scores
/// (exit 2, nothing written), claims the report folder, then writes the reports (exit 1).
pub fn execute(args: EvaluateArgs) -> Outcome {
    let study = StudyOptions {
        migration_csv: args.migration_csv,
        stability_threshold_mm: args.stability_threshold_mm,
        limits_99: args.limits_99,
    };
    if !(study.stability_threshold_mm.is_finite() && study.stability_threshold_mm > 0.0) {
        eprintln!(
            "error: --stability-threshold-mm {} is not a positive length in mm\n  = help: e.g. --stability-threshold-mm 0.3",
            study.stability_threshold_mm
        );
        return Err(2);
    }
    let (confidence, mtpm_threshold_mm) = (args.confidence, args.mtpm_threshold_mm);
    if !(confidence > 0.0 && confidence < 1.0) {
        eprintln!(
            "error: --confidence {confidence} is outside (0, 1)\n  = help: e.g. --confidence 0.95"
        );
        return Err(2);
    }
    if !(mtpm_threshold_mm.is_finite() && mtpm_threshold_mm > 0.0) {
        eprintln!(
            "error: --mtpm-threshold-mm {mtpm_threshold_mm} is not a positive length in mm\n  = help: e.g. --mtpm-threshold-mm 0.2"
        );
        return Err(2);
    }
    let formats: Vec<Format> = args.format.into_iter().map(Format::from).collect();
    // A PDF needs a browser: found before any work, so a missing one writes nothing.
    let browser = if formats.contains(&Format::Pdf) {
        Some(report::pdf::find_browser().map_err(|e| {
            eprintln!("error: {}\n  = help: {}", e.message, e.help);
            2
        })?)
    } else {
        None
    };
    let options = Options {
        measured: match (args.csv, args.measured) {
            (Some(file), _) => MeasuredSource::Csv(file),
            (None, Some(name)) => match args.results_in {
                Some(dir) => MeasuredSource::PerRunIn { name, dir },
                None => MeasuredSource::PerRun(name),
            },
            (None, None) => MeasuredSource::Auto,
        },
        confidence: stats::Confidence {
            level: confidence,
            sided: args.sided.into(),
        },
        mtpm_threshold_mm,
        study,
        xmalab_2d: rsasim::interop::xmalab_points2d::PixelOptions {
            y_axis: args.xmalab_2d_y_axis.into(),
            first_pixel: args.xmalab_2d_start_at.into(),
        },
        source_truth: args.source_truth.into(),
    };
    let reports = Reports {
        formats,
        browser,
        dir: args.report,
    };
    let (out, truth) = (args.out.as_path(), args.truth.as_deref());
    if rsasim::sweep::is_sweep_folder(out) {
        return evaluate_sweep(out, truth, &options, &reports);
    }
    let start = Instant::now();
    let result = score(out, truth, &options)?;
    // The default folder is named after the results file, known once they are read. Scoring
    // writes nothing, so the claim (refused with exit 2) still comes before any file is written.
    let dir = reports
        .dir
        .clone()
        .unwrap_or_else(|| out.join(report::default_folder_name(&result)));
    let target = report::claim_report_dir(&dir).map_err(|d| report_errors(&[*d]))?;
    write_report(&result, target, &reports, start)
}

/// Scores the output folder `out` (with the truth folder of a blind layout), printing notes.
pub fn score(out: &Path, truth: Option<&Path>, options: &Options) -> Result<Report, u8> {
    let result = rsasim::evaluate::evaluate_with_truth(out, truth, options)
        .map_err(|errors| report_errors(&errors))?;
    for note in &result.notes {
        eprintln!("note: {note}");
    }
    Ok(result)
}

/// Writes a scored report into its claimed folder and says what was written.
pub fn write_report(
    result: &Report,
    target: OutputTarget,
    reports: &Reports,
    start: Instant,
) -> Outcome {
    target.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    let dir = target.shown().to_path_buf();
    let written =
        report::write_reports_into(result, target, &reports.formats, reports.browser.as_ref())
            .map_err(|e| {
                eprintln!(
                    "error: writing the reports into {} failed: {e}",
                    dir.display()
                );
                1
            })?;
    for e in &result.excluded {
        eprintln!("excluded: {}: {}", e.run, e.reason);
    }
    eprintln!(
        "rsasim evaluate: {} runs scored, {} exclusion(s), in {:.2} s -> {}",
        result.runs_scored,
        result.excluded.len(),
        start.elapsed().as_secs_f64(),
        shown(&written)
    );
    Ok(())
}

/// `rsasim evaluate` on a sweep folder: scores every point (nothing written), claims every
/// point's report folder and the summary's, then writes the point reports and the summary.
pub fn evaluate_sweep(
    dir: &Path,
    truth: Option<&Path>,
    options: &Options,
    reports: &Reports,
) -> Outcome {
    use rsasim::evaluate::{MeasuredSource, report};
    use rsasim::sweep::{folder, summary};
    if truth.is_some()
        || matches!(
            options.measured,
            MeasuredSource::Csv(_) | MeasuredSource::PerRunIn { .. }
        )
    {
        eprintln!(
            "error: {}: a sweep folder is evaluated point by point from the results in its run folders; --truth, --csv and --results-in are for one output folder\n  = help: evaluate a point's folder ({}/<point id>) with them, or drop them",
            dir.display(),
            dir.display()
        );
        return Err(2);
    }
    let index = rsasim::sweep::read_index(dir).map_err(|e| report_errors(&e))?;
    let start = Instant::now();
    let mut point_dirs = Vec::with_capacity(index.points.len());
    for p in &index.points {
        point_dirs
            .push(rsasim::sweep::folder::point_folder(dir, p).map_err(|e| report_errors(&e))?);
    }
    let mut scored = Vec::with_capacity(index.points.len());
    for (p, point_dir) in index.points.iter().zip(&point_dirs) {
        eprintln!("rsasim evaluate: point {}", p.id);
        scored.push(score(point_dir, None, options)?);
    }
    let mut targets = Vec::with_capacity(scored.len());
    for (point_dir, r) in point_dirs.iter().zip(&scored) {
        let point_dir = point_dir.join(report::default_folder_name(r));
        targets.push(report::claim_report_dir(&point_dir).map_err(|d| report_errors(&[*d]))?);
    }
    let summary_dir = reports
        .dir
        .clone()
        .unwrap_or_else(|| dir.join(folder::REPORT_DIR));
    let summary_target =
        report::claim_report_dir(&summary_dir).map_err(|d| report_errors(&[*d]))?;
    for (r, target) in scored.iter().zip(targets) {
        write_report(r, target, reports, start)?;
    }
    summary_target
        .notes
        .iter()
        .for_each(|n| eprintln!("rsasim: {n}"));
    let written =
        summary::write(summary_target, &summary::summary(&index, &scored)).map_err(|e| {
            eprintln!(
                "error: writing the summary into {} failed: {e}",
                summary_dir.display()
            );
            1
        })?;
    eprintln!(
        "rsasim evaluate: sweep {} ({} points) in {:.2} s -> {}",
        index.name,
        index.points.len(),
        start.elapsed().as_secs_f64(),
        shown(&written)
    );
    Ok(())
}
