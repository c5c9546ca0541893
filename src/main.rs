//! The `rsasim` command: parse the arguments, call the library, map failures to exit codes
//! (2: bad input, nothing written; 1: a failure while writing).

mod cli;

use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use indicatif::{ProgressBar, ProgressStyle};
use rsasim::diagnostic::Diagnostic;
use rsasim::simulate::{self, Plan};

use cli::{Cli, Command};

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Validate { scenario, allow }) => {
            check(&scenario, &allow.into()).map(|checked| {
                eprintln!("{}: valid: {}", scenario.display(), checked.cost.summary());
            })
        }
        Some(Command::Expand { scenario, allow }) => {
            check(&scenario, &allow.into()).and_then(|checked| expand(&checked))
        }
        Some(Command::Scene {
            scenario,
            out,
            no_images,
            allow,
        }) => scene(&scenario, out, !no_images, &allow.into()),
        Some(Command::Schema { name, write_dir }) => schema(&name, write_dir.as_deref()),
        Some(Command::Reconstruct {
            out,
            method,
            model_method,
            measured,
            overwrite,
            stability_threshold_mm,
        }) => reconstruct_any(
            &out,
            &rsasim::reconstruct::Options {
                method,
                model_method,
                measured,
                overwrite,
                stability_threshold_mm: Some(stability_threshold_mm),
            },
        ),
        Some(Command::Sweep {
            file,
            out,
            evaluate,
            no_run,
            shard,
            shard_count,
            merge,
            allow,
        }) => {
            let allow = allow.into();
            match (shard, merge) {
                (Some(request), _) => sweep_shard(&file, &out, request, shard_count, &allow),
                (None, true) => sweep_merge(&file, &out, shard_count, evaluate, &allow),
                (None, false) if shard_count.is_some() => {
                    eprintln!(
                        "error: --shard-count is for a sharded sweep's tasks (--shard) and its --merge\n  = help: add --shard auto (or K/N), or --merge, or drop --shard-count"
                    );
                    Err(2)
                }
                (None, false) => sweep(&file, &out, evaluate, no_run, &allow),
            }
        }
        Some(Command::Export {
            out,
            truth,
            to,
            dir,
            runs,
            invert,
            calibration_from,
        }) => export(
            &out,
            truth.as_deref(),
            &dir,
            &rsasim::interop::export::Options {
                target: if to == "autoscoper" {
                    rsasim::interop::export::Target::Autoscoper
                } else {
                    rsasim::interop::export::Target::Xmalab
                },
                runs,
                invert,
                calibration_from,
            },
        ),
        Some(Command::Evaluate {
            out,
            measured,
            results_in,
            csv,
            confidence,
            sided,
            format,
            mtpm_threshold_mm,
            report,
            truth,
            migration_csv,
            stability_threshold_mm,
            limits_99,
        }) => evaluate(
            &out,
            truth.as_deref(),
            measured,
            results_in,
            csv,
            confidence,
            &sided,
            mtpm_threshold_mm,
            &format,
            report,
            rsasim::evaluate::study::StudyOptions {
                migration_csv,
                stability_threshold_mm,
                limits_99,
            },
        ),
        Some(Command::Verify { out, images }) => verify(&out, images.as_deref()),
        Some(Command::Merge {
            shards,
            out,
            force,
            copy,
        }) => merge(&shards, &out, force, copy),
        None => run_scenario(cli.run),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(code) => ExitCode::from(code),
    }
}

/// Loads and checks a scenario (run by run, without keeping the runs), printing warnings;
/// errors are printed and give exit code 2.
fn check(path: &std::path::Path, allow: &simulate::Allowances) -> Result<simulate::Checked, u8> {
    match simulate::check(path, allow) {
        Ok(checked) => {
            checked.warnings.iter().for_each(|w| eprintln!("{w}"));
            Ok(checked)
        }
        Err(errors) => Err(report_errors(&errors)),
    }
}

/// [`check`], then every run expanded for the simulation.
fn prepare(path: &std::path::Path, allow: &simulate::Allowances) -> Result<Plan, u8> {
    check(path, allow).map(Plan::from)
}

/// Prints every run as one pretty JSON array, run by run (the same bytes as printing the whole
/// array at once, without holding it): memory stays flat with the run count.
fn expand(checked: &simulate::Checked) -> Result<(), u8> {
    use std::io::Write;
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let mut write = || -> std::io::Result<()> {
        let mut first = true;
        out.write_all(b"[")?;
        for run in rsasim::expand::runs(&checked.loaded.scenario, &checked.models) {
            let text = serde_json::to_string_pretty(&run).map_err(std::io::Error::other)?;
            out.write_all(if first { b"\n" } else { b",\n" })?;
            first = false;
            for (i, line) in text.lines().enumerate() {
                if i > 0 {
                    out.write_all(b"\n")?;
                }
                out.write_all(b"  ")?;
                out.write_all(line.as_bytes())?;
            }
        }
        out.write_all(if first { b"]\n" } else { b"\n]\n" })?;
        out.flush()
    };
    write().map_err(|e| {
        eprintln!("error: writing the runs to standard output failed: {e}");
        1
    })
}

/// `rsasim scene`: checks the scenario (errors: exit 2, nothing written), then writes its page.
fn scene(
    path: &std::path::Path,
    out: Option<std::path::PathBuf>,
    images: bool,
    allow: &simulate::Allowances,
) -> Result<(), u8> {
    use rsasim::scene_view;
    let checked = check(path, allow)?;
    let out = out.unwrap_or_else(|| {
        std::path::Path::new("out").join(format!("{}-scene.html", checked.loaded.scenario.name))
    });
    scene_view::check_page_target(&out).map_err(|d| report_errors(&[*d]))?;
    let scene = scene_view::scene_of(checked, images).map_err(|e| {
        eprintln!("error: making the thumbnails of the first run failed: {e}");
        1
    })?;
    let page = scene_view::page(&scene);
    let written = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or(Ok(()), std::fs::create_dir_all)
        .and_then(|()| rsasim::output::atomic::write_atomic(&out, page.as_bytes()));
    written.map_err(|e| {
        eprintln!("error: writing {} failed: {e}", out.display());
        1
    })?;
    eprintln!(
        "rsasim scene: {} warning(s), {} KiB -> {}",
        scene.warnings.len(),
        page.len().div_ceil(1024),
        out.display()
    );
    Ok(())
}

/// Most errors printed in full; the rest are counted (a hostile file can hold millions).
const MAX_ERRORS_SHOWN: usize = 20;

fn report_errors(errors: &[Diagnostic]) -> u8 {
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

/// The shard of `--shard` (`auto`: from the environment), or exit 2 with the reason.
fn resolve_shard(
    request: rsasim::shard::ShardRequest,
    shard_count: Option<usize>,
) -> Result<(rsasim::shard::ShardSpec, String), u8> {
    let vars: std::collections::HashMap<String, String> = std::env::vars().collect();
    rsasim::shard::env::resolve(request, shard_count, &vars).map_err(|e| {
        eprintln!(
            "error: {}\n  = help: {}\n\nrsasim: 1 error(s); nothing was written",
            e.message, e.help
        );
        2
    })
}

/// The default command: the shard (if any) decided first, then the scenario checked and run.
fn run_scenario(args: cli::RunArgs) -> Result<(), u8> {
    let scenario = args.scenario.expect("clap requires a scenario");
    let shard = args
        .shard
        .map(|request| resolve_shard(request, args.shard_count))
        .transpose()?;
    let allow: simulate::Allowances = args.allow.into();
    let mut plan = prepare(&scenario, &allow)?;
    if let Some((spec, from)) = &shard {
        rsasim::shard::check_count(spec.count, plan.runs.len(), allow.large).map_err(|why| {
            eprintln!(
                "error: --shard {spec} ({from}): {why}\n  = help: use fewer shards (--shard K/N with a smaller N)\n\nrsasim: 1 error(s); nothing was written"
            );
            2u8
        })?;
    }
    plan.previews = args.preview.is_some();
    match shard {
        None => run(&plan, args.out, args.truth_dir.as_deref(), args.force),
        Some((spec, from)) => {
            let base = args.out.unwrap_or_else(|| {
                std::path::Path::new("out").join(format!("{}-shards", plan.loaded.scenario.name))
            });
            write_shard(&mut plan, spec, &from, &base, args.force)
        }
    }
}

/// Writes shard `spec` of `plan` into `base/shard-K-of-N/`, unless that folder already holds it
/// complete (a requeued task, a replaced pod): then nothing is written.
fn write_shard(
    plan: &mut Plan,
    spec: rsasim::shard::ShardSpec,
    from: &str,
    base: &std::path::Path,
    force: bool,
) -> Result<(), u8> {
    plan.shard = Some(spec);
    let out = base.join(spec.folder_name());
    let held = plan.written_runs().len();
    eprintln!(
        "rsasim: shard {spec} ({from}): {held} of {} run(s){}",
        plan.runs.len(),
        if held == 0 {
            "; this shard holds no run (more shards than runs): its folder gets the shared files and a manifest only"
        } else {
            ""
        }
    );
    if simulate::finished_shard(plan, &out) {
        eprintln!(
            "rsasim: {} already holds this shard, complete and verified (same scenario, build and shard): nothing to do",
            out.display()
        );
        return Ok(());
    }
    run(plan, Some(out), None, force)
}

fn run(
    plan: &Plan,
    out: Option<std::path::PathBuf>,
    truth_dir: Option<&std::path::Path>,
    force: bool,
) -> Result<(), u8> {
    let out = out.unwrap_or_else(|| std::path::Path::new("out").join(&plan.loaded.scenario.name));
    if let Some(truth) = truth_dir {
        simulate::check_truth_dir(&out, truth).map_err(|e| report_errors(&e))?;
        simulate::blind_warnings(plan)
            .iter()
            .for_each(|w| eprintln!("{w}"));
    }
    // Every refusal (exit 2) comes here, before any simulation work.
    let target =
        simulate::claim_output(plan, &out, force).map_err(|errors| report_errors(&errors))?;
    let truth_target = truth_dir
        .map(|t| simulate::claim_output(plan, t, force))
        .transpose()
        .map_err(|errors| report_errors(&errors))?;
    for t in std::iter::once(&target).chain(&truth_target) {
        t.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    }
    if let Err(e) = rsasim::output::commit::interrupt::install() {
        eprintln!("warning: Ctrl-C will not report what it leaves: {e}");
    }
    let bar = ProgressBar::new(plan.image_count() as u64);
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} {bar:40} {pos}/{len} images ({eta} left)")
            .expect("valid template"),
    );
    let start = Instant::now();
    let summary = simulate::simulate(plan, target, truth_target, &|| bar.inc(1)).map_err(|e| {
        bar.abandon();
        if e.kind() == std::io::ErrorKind::InvalidData {
            // Found while rendering (the scene cannot be simulated as written): an input error.
            eprintln!(
                "error: {}: {e}\n  = help: fix the scenario; the check needs the path lengths, so only a run finds it\n\nrsasim: 1 error(s); nothing was written",
                plan.loaded.path.display()
            );
            return 2;
        }
        eprintln!(
            "error: writing {} failed: {e}\n  = note: nothing was replaced; a previous output there is unchanged",
            out.display()
        );
        1
    })?;
    bar.finish_and_clear();
    summary.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    eprintln!(
        "rsasim: {} runs, {} image files in {:.1} s -> {}",
        summary.runs,
        summary.image_files,
        start.elapsed().as_secs_f64(),
        summary.out_dir.display()
    );
    Ok(())
}

fn reconstruct(out: &std::path::Path, options: &rsasim::reconstruct::Options) -> Result<(), u8> {
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

/// `rsasim merge`: shards checked (exit 2, nothing written), the merged folder claimed, then
/// assembled.
fn merge(
    shards: &[std::path::PathBuf],
    out: &std::path::Path,
    force: bool,
    copy: bool,
) -> Result<(), u8> {
    use rsasim::output::merge::{self, Error};
    let start = Instant::now();
    let checked = merge::check(shards).map_err(|e| report_errors(&e))?;
    for path in &checked.not_merged {
        eprintln!("rsasim: not merged (no manifest lists it): {path}");
    }
    let target = merge::claim(&checked, out, force).map_err(|e| report_errors(&e))?;
    target.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    let (count, runs) = (checked.count(), checked.runs());
    let summary = merge::assemble(checked, target, copy).map_err(|e| match e {
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

fn verify(out: &std::path::Path, images: Option<&std::path::Path>) -> Result<(), u8> {
    let results = rsasim::output::verify::verify(out, images);
    print!("{}", rsasim::output::verify::render(&results));
    if results.iter().all(|v| v.ok()) {
        Ok(())
    } else {
        Err(2)
    }
}

fn export(
    out: &std::path::Path,
    truth: Option<&std::path::Path>,
    dir: &std::path::Path,
    options: &rsasim::interop::export::Options,
) -> Result<(), u8> {
    use rsasim::interop::export::{self, Error};
    let start = Instant::now();
    let summary = export::export(out, truth, dir, options).map_err(|e| match e {
        Error::Input(errors) => report_errors(&errors),
        Error::Write(why) => {
            eprintln!(
                "error: writing {} failed: {why}\n  = note: nothing was written there",
                dir.display()
            );
            1
        }
    })?;
    summary.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    eprintln!(
        "rsasim export: {} run(s), {} files for {} in {:.1} s -> {}",
        summary.runs,
        summary.files,
        options.target.name(),
        start.elapsed().as_secs_f64(),
        summary.dir.display()
    );
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn evaluate(
    out: &std::path::Path,
    truth: Option<&std::path::Path>,
    measured: Option<String>,
    results_in: Option<std::path::PathBuf>,
    csv: Option<std::path::PathBuf>,
    confidence: f64,
    sided: &str,
    mtpm_threshold_mm: f64,
    formats: &[String],
    report_dir: Option<std::path::PathBuf>,
    study: rsasim::evaluate::study::StudyOptions,
) -> Result<(), u8> {
    use rsasim::evaluate::{MeasuredSource, Options, report, stats};
    if !(study.stability_threshold_mm.is_finite() && study.stability_threshold_mm > 0.0) {
        eprintln!(
            "error: --stability-threshold-mm {} is not a positive length in mm\n  = help: e.g. --stability-threshold-mm 0.3",
            study.stability_threshold_mm
        );
        return Err(2);
    }
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
    let formats: Vec<report::Format> = formats
        .iter()
        .map(|f| f.parse())
        .collect::<Result<_, report::ParseFormatError>>()
        .map_err(|e| {
            eprintln!("error: --format: {e}");
            2
        })?;
    // A PDF needs a browser: found before any work, so a missing one writes nothing.
    let browser = if formats.contains(&report::Format::Pdf) {
        Some(report::pdf::find_browser().map_err(|e| {
            eprintln!("error: {}\n  = help: {}", e.message, e.help);
            2
        })?)
    } else {
        None
    };
    let sided = if sided == "two" {
        stats::Sided::Two
    } else {
        stats::Sided::One
    };
    let options = Options {
        measured: match (csv, measured) {
            (Some(file), _) => MeasuredSource::Csv(file),
            (None, Some(name)) => match results_in {
                Some(dir) => MeasuredSource::PerRunIn { name, dir },
                None => MeasuredSource::PerRun(name),
            },
            (None, None) => MeasuredSource::Auto,
        },
        confidence: stats::Confidence {
            level: confidence,
            sided,
        },
        mtpm_threshold_mm,
        study,
    };
    if rsasim::sweep::is_sweep_folder(out) {
        return evaluate_sweep(out, truth, &options, &formats, browser.as_ref(), report_dir);
    }
    let start = Instant::now();
    let result = score(out, truth, &options)?;
    // The default folder is named after the results file, known once they are read. Scoring
    // writes nothing, so the claim (refused with exit 2) still comes before any file is written.
    let dir = report_dir.unwrap_or_else(|| out.join(report::default_folder_name(&result)));
    let target = report::claim_report_dir(&dir).map_err(|d| report_errors(&[*d]))?;
    write_report(&result, target, &formats, browser.as_ref(), start)
}

/// Scores the output folder `out` (with the truth folder of a blind layout), printing notes.
fn score(
    out: &std::path::Path,
    truth: Option<&std::path::Path>,
    options: &rsasim::evaluate::Options,
) -> Result<rsasim::evaluate::table::Report, u8> {
    let result = rsasim::evaluate::evaluate_with_truth(out, truth, options)
        .map_err(|errors| report_errors(&errors))?;
    for note in &result.notes {
        eprintln!("note: {note}");
    }
    Ok(result)
}

/// Writes a scored report into its claimed folder and says what was written.
fn write_report(
    result: &rsasim::evaluate::table::Report,
    target: rsasim::output::commit::OutputTarget,
    formats: &[rsasim::evaluate::report::Format],
    browser: Option<&rsasim::evaluate::report::pdf::Browser>,
    start: Instant,
) -> Result<(), u8> {
    use rsasim::evaluate::report;
    target.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    let dir = target.shown().to_path_buf();
    let written = report::write_reports_into(result, target, formats, browser).map_err(|e| {
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

/// Paths for a message, joined by `, `.
fn shown(paths: &[std::path::PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// `rsasim evaluate` on a sweep folder: scores every point (nothing written), claims every
/// point's report folder and the summary's, then writes the point reports and the summary.
fn evaluate_sweep(
    dir: &std::path::Path,
    truth: Option<&std::path::Path>,
    options: &rsasim::evaluate::Options,
    formats: &[rsasim::evaluate::report::Format],
    browser: Option<&rsasim::evaluate::report::pdf::Browser>,
    report_dir: Option<std::path::PathBuf>,
) -> Result<(), u8> {
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
    let mut reports = Vec::with_capacity(index.points.len());
    for (p, point_dir) in index.points.iter().zip(&point_dirs) {
        eprintln!("rsasim evaluate: point {}", p.id);
        reports.push(score(point_dir, None, options)?);
    }
    let mut targets = Vec::with_capacity(reports.len());
    for (point_dir, r) in point_dirs.iter().zip(&reports) {
        let point_dir = point_dir.join(report::default_folder_name(r));
        targets.push(report::claim_report_dir(&point_dir).map_err(|d| report_errors(&[*d]))?);
    }
    let summary_dir = report_dir.unwrap_or_else(|| dir.join(folder::REPORT_DIR));
    let summary_target =
        report::claim_report_dir(&summary_dir).map_err(|d| report_errors(&[*d]))?;
    for (r, target) in reports.iter().zip(targets) {
        write_report(r, target, formats, browser, start)?;
    }
    summary_target
        .notes
        .iter()
        .for_each(|n| eprintln!("rsasim: {n}"));
    let written =
        summary::write(summary_target, &summary::summary(&index, &reports)).map_err(|e| {
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

/// `rsasim reconstruct` on an output folder, or on every point of a sweep folder (all points
/// are tried; the worst exit code is returned).
fn reconstruct_any(
    out: &std::path::Path,
    options: &rsasim::reconstruct::Options,
) -> Result<(), u8> {
    if !rsasim::sweep::is_sweep_folder(out) {
        return reconstruct(out, options);
    }
    let index = rsasim::sweep::read_index(out).map_err(|e| report_errors(&e))?;
    let mut point_dirs = Vec::with_capacity(index.points.len());
    for p in &index.points {
        point_dirs
            .push(rsasim::sweep::folder::point_folder(out, p).map_err(|e| report_errors(&e))?);
    }
    let mut worst = Ok(());
    for (p, point_dir) in index.points.iter().zip(&point_dirs) {
        eprintln!("rsasim reconstruct: point {}", p.id);
        if let Err(code) = reconstruct(point_dir, options) {
            worst = Err(worst.err().map_or(code, |w: u8| w.max(code)));
        }
    }
    worst
}

/// Writes the sweep folder's own files (sweep.json, the sweep file's copy, the point scenarios
/// and their inputs), each once; a file there with other bytes is an input error (exit 2).
fn write_points(
    folder: &rsasim::sweep::SweepFolder,
    sweep: &rsasim::sweep::Sweep,
    out: &std::path::Path,
) -> Result<(), u8> {
    folder.write_points(sweep).map_err(|e| match e {
        rsasim::sweep::WriteError::Input(errors) => report_errors(&errors),
        rsasim::sweep::WriteError::Io(e) => {
            eprintln!(
                "error: writing the point scenarios into {} failed: {e}",
                out.display()
            );
            1
        }
    })
}

/// Prepares the sweep of `file` (errors: exit 2, nothing written), takes its folder `out`
/// (claimed with its lock, or joined as one task of a sharded sweep) and writes the sweep's own
/// files.
fn open_sweep(
    file: &std::path::Path,
    out: &std::path::Path,
    allow: &simulate::Allowances,
    as_task: bool,
) -> Result<(rsasim::sweep::Sweep, rsasim::sweep::SweepFolder), u8> {
    let sweep = rsasim::sweep::prepare(file, allow).map_err(|e| report_errors(&e))?;
    let folder = if as_task {
        rsasim::sweep::join(&sweep, out)
    } else {
        rsasim::sweep::claim(&sweep, out)
    }
    .map_err(|e| report_errors(&e))?;
    write_points(&folder, &sweep, out)?;
    Ok((sweep, folder))
}

/// What the point scenarios may read: only their own folder's copies of the base scenario's
/// files.
fn point_allowances(allow: &simulate::Allowances) -> simulate::Allowances {
    simulate::Allowances {
        dirs: Vec::new(),
        large: allow.large,
    }
}

/// `rsasim sweep`: prepares every point (errors: exit 2, nothing written), claims the sweep
/// folder, writes the point scenarios, then runs every pending point with the main command's own
/// `prepare` and `run`, exactly as `rsasim DIR/points/<id>.toml --out DIR/<id>`; with
/// `evaluate`, reconstructs every point and evaluates the sweep.
fn sweep(
    file: &std::path::Path,
    out: &std::path::Path,
    evaluate_too: bool,
    no_run: bool,
    allow: &simulate::Allowances,
) -> Result<(), u8> {
    let start = Instant::now();
    let (sweep, folder) = open_sweep(file, out, allow, false)?;
    if no_run {
        eprintln!(
            "rsasim sweep: {} point scenario(s) written to {}; run each with `rsasim {}/<id>.toml --out {}/<id>`",
            sweep.points.len(),
            out.join(rsasim::sweep::prepare::POINTS_DIR).display(),
            out.join(rsasim::sweep::prepare::POINTS_DIR).display(),
            out.display()
        );
        return Ok(());
    }
    let point_allow = point_allowances(allow);
    let n = sweep.points.len();
    for (k, (point, done)) in sweep.points.iter().zip(&folder.done).enumerate() {
        let what = sweep.assignments(point);
        if *done {
            eprintln!(
                "rsasim sweep: point {} ({}/{n}) is complete from an earlier run, kept: {what}",
                point.id,
                k + 1
            );
            continue;
        }
        eprintln!("rsasim sweep: point {} ({}/{n}): {what}", point.id, k + 1);
        let plan = prepare(&folder.point_scenario(&point.id), &point_allow)?;
        run(&plan, Some(folder.point_out(&point.id)), None, false)?;
    }
    eprintln!(
        "rsasim sweep: {n} point(s) in {:.1} s -> {}",
        start.elapsed().as_secs_f64(),
        out.display()
    );
    finish_sweep(out, evaluate_too)
}

/// The end of a sweep whose every point is complete: with `evaluate_too`, `rsasim reconstruct`
/// (default methods) on every point and `rsasim evaluate` on the sweep; otherwise how to.
fn finish_sweep(out: &std::path::Path, evaluate_too: bool) -> Result<(), u8> {
    if !evaluate_too {
        eprintln!(
            "reconstruct and score them with `rsasim reconstruct {0}` and `rsasim evaluate {0}`",
            out.display()
        );
        return Ok(());
    }
    let reconstructed = reconstruct_any(out, &rsasim::reconstruct::Options::default());
    evaluate(
        out,
        None,
        None,
        None,
        None,
        cli::DEFAULT_CONFIDENCE,
        "one",
        rsasim::evaluate::DEFAULT_MTPM_THRESHOLD_MM,
        &cli::DEFAULT_FORMATS
            .split(',')
            .map(String::from)
            .collect::<Vec<_>>(),
        None,
        rsasim::evaluate::study::StudyOptions::default(),
    )?;
    reconstructed
}

/// `rsasim sweep --shard K/N|auto`: one task of a sharded sweep. The shard is decided and every
/// point prepared first (errors: exit 2, nothing written); the task then joins the sweep folder
/// (which other tasks may be writing at the same time), writes or checks the sweep's own files,
/// and writes its shard of every point not already complete ([`rsasim::sweep::split`]), each as
/// `rsasim DIR/points/<id>.toml --shard j/N --out DIR/shards/<id>` would.
fn sweep_shard(
    file: &std::path::Path,
    out: &std::path::Path,
    request: rsasim::shard::ShardRequest,
    shard_count: Option<usize>,
    allow: &simulate::Allowances,
) -> Result<(), u8> {
    let start = Instant::now();
    let (task, from) = resolve_shard(request, shard_count)?;
    let sweep = rsasim::sweep::prepare(file, allow).map_err(|e| report_errors(&e))?;
    let most_runs = sweep.points.iter().map(|p| p.runs).max().unwrap_or(0);
    rsasim::shard::check_count(task.count, most_runs, allow.large).map_err(|why| {
        eprintln!(
            "error: --shard {task} ({from}): {why}\n  = help: use fewer shards (--shard K/N with a smaller N)\n\nrsasim: 1 error(s); nothing was written"
        );
        2u8
    })?;
    let folder = rsasim::sweep::join(&sweep, out).map_err(|e| report_errors(&e))?;
    write_points(&folder, &sweep, out)?;
    let counts: Vec<usize> = sweep.points.iter().map(|p| p.runs).collect();
    let shards = rsasim::sweep::split::point_shards(&counts, task);
    let total: usize = counts.iter().sum();
    let held: usize = counts
        .iter()
        .zip(&shards)
        .zip(&folder.done)
        .filter(|(_, done)| !**done)
        .map(|((&runs, spec), _)| spec.runs(runs).len())
        .sum();
    eprintln!(
        "rsasim sweep: task {task} ({from}): {held} of the sweep's {total} run(s), one shard of each of {} point(s)",
        sweep.points.len()
    );
    let point_allow = point_allowances(allow);
    let n = sweep.points.len();
    for (k, ((point, done), spec)) in sweep
        .points
        .iter()
        .zip(&folder.done)
        .zip(&shards)
        .enumerate()
    {
        let what = sweep.assignments(point);
        if *done {
            eprintln!(
                "rsasim sweep: point {} ({}/{n}) is complete in {}, needs no shard: {what}",
                point.id,
                k + 1,
                folder.point_out(&point.id).display()
            );
            continue;
        }
        eprintln!("rsasim sweep: point {} ({}/{n}): {what}", point.id, k + 1);
        let mut plan = prepare(&folder.point_scenario(&point.id), &point_allow)?;
        if plan.runs.len() != point.runs {
            eprintln!(
                "error: point {} expands to {} run(s), not the {} the sweep counted: a bug in rsasim; nothing of this point was written",
                point.id,
                plan.runs.len(),
                point.runs
            );
            return Err(1);
        }
        write_shard(
            &mut plan,
            *spec,
            &format!("task {task} of the sweep"),
            &folder.point_shards(&point.id),
            false,
        )?;
    }
    eprintln!(
        "rsasim sweep: task {task}: {n} point(s) in {:.1} s -> {}; when every task is done, `rsasim sweep {} --out {} --merge`",
        start.elapsed().as_secs_f64(),
        out.join(rsasim::sweep::folder::SHARDS_DIR).display(),
        file.display(),
        out.display()
    );
    Ok(())
}

/// `rsasim sweep --merge`: the sweep prepared and its folder claimed (the lock held), every
/// point's shards checked (every problem of every point reported; exit 2, nothing written),
/// every point's output folder claimed, then each point merged; with `evaluate_too`,
/// reconstructed and evaluated as an unsharded sweep.
fn sweep_merge(
    file: &std::path::Path,
    out: &std::path::Path,
    shard_count: Option<usize>,
    evaluate_too: bool,
    allow: &simulate::Allowances,
) -> Result<(), u8> {
    use rsasim::output::merge;
    let start = Instant::now();
    let (sweep, folder) = open_sweep(file, out, allow, false)?;
    let points =
        rsasim::sweep::merge::check(&sweep, &folder, shard_count).map_err(|e| report_errors(&e))?;
    // Every file of every point's shards hashed before any point is written, so that exit 2
    // (a shard changed after its task wrote it) means nothing was written.
    let mut changed = Vec::new();
    for p in &points {
        for shard_dir in p.shards.dirs() {
            let v = rsasim::output::verify::verify_folder(shard_dir);
            changed.extend(v.problems.into_iter().map(|f| {
                rsasim::diagnostic::Diagnostic::file_error(
                    &shard_dir.join(&f.path),
                    format!("point {}: {}", p.id, f.problem),
                )
                .with_help("a shard must be exactly as rsasim wrote it: rerun that task of the sweep (a finished one writes nothing) and merge again")
            }));
        }
    }
    if !changed.is_empty() {
        return Err(report_errors(&changed));
    }
    let mut targets = Vec::with_capacity(points.len());
    for p in &points {
        for path in &p.shards.not_merged {
            eprintln!("rsasim: not merged (no manifest lists it): {path}");
        }
        targets.push(merge::claim(&p.shards, &p.out, false).map_err(|e| report_errors(&e))?);
    }
    let kept = sweep.points.len() - points.len();
    if kept > 0 {
        eprintln!("rsasim sweep: {kept} point(s) complete from an earlier run or merge, kept");
    }
    let mut merged: Vec<String> = Vec::new();
    for (p, target) in points.into_iter().zip(targets) {
        target.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
        let (count, runs) = (p.shards.count(), p.shards.runs());
        let merged_before = if merged.is_empty() {
            "no point was merged before it".to_string()
        } else {
            format!(
                "the points merged before it are complete: {}",
                merged.join(", ")
            )
        };
        let summary = merge::assemble(p.shards, target, false).map_err(|e| {
            let input = matches!(e, merge::Error::Input(_));
            match e {
                // A shard changed between the check and the merge: not "nothing was written"
                // when earlier points were merged, so exit 1 and say which.
                merge::Error::Input(errors) => {
                    errors
                        .iter()
                        .take(MAX_ERRORS_SHOWN)
                        .for_each(|e| eprintln!("{e}\n"));
                    eprintln!(
                        "error: point {} was not merged ({} error(s)); {merged_before}",
                        p.id,
                        errors.len()
                    );
                }
                merge::Error::Write(why) => eprintln!(
                    "error: writing {} failed: {why}\n  = note: point {} was not merged; {merged_before}",
                    p.out.display(),
                    p.id
                ),
            }
            if input && merged.is_empty() { 2 } else { 1 }
        })?;
        merged.push(p.id.clone());
        summary.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
        eprintln!(
            "rsasim sweep: point {}: {count} shard(s), {runs} run(s), {} file(s) merged -> {}",
            p.id,
            summary.linked + summary.copied,
            summary.out_dir.display()
        );
    }
    eprintln!(
        "rsasim sweep: {} point(s) complete in {:.1} s -> {} (the shards in {} may be deleted)",
        sweep.points.len(),
        start.elapsed().as_secs_f64(),
        out.display(),
        out.join(rsasim::sweep::folder::SHARDS_DIR).display()
    );
    finish_sweep(out, evaluate_too)
}

fn schema(name: &str, write_dir: Option<&std::path::Path>) -> Result<(), u8> {
    let schemas = rsasim::output::schemas();
    match write_dir {
        Some(dir) => {
            for (n, s) in &schemas {
                let path = dir.join(format!("{n}.schema.json"));
                let text = serde_json::to_string_pretty(s).expect("schema serialises") + "\n";
                rsasim::output::atomic::write_atomic(&path, text.as_bytes()).map_err(|e| {
                    eprintln!("error: cannot write {}: {e}", path.display());
                    1
                })?;
                eprintln!("wrote {}", path.display());
            }
        }
        None => {
            let (_, s) = schemas
                .iter()
                .find(|(n, _)| *n == name)
                .expect("clap restricts the names");
            println!(
                "{}",
                serde_json::to_string_pretty(s).expect("schema serialises")
            );
        }
    }
    Ok(())
}
