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
        Some(Command::Validate { scenario }) => prepare(&scenario).map(|plan| {
            eprintln!(
                "{}: valid ({} runs, {} images per format)",
                scenario.display(),
                plan.runs.len(),
                plan.image_count()
            );
        }),
        Some(Command::Expand { scenario }) => prepare(&scenario).map(|plan| {
            println!(
                "{}",
                serde_json::to_string_pretty(&plan.runs).expect("runs serialise")
            );
        }),
        Some(Command::Schema { name, write_dir }) => schema(&name, write_dir.as_deref()),
        Some(Command::Reconstruct {
            out,
            method,
            model_method,
        }) => reconstruct(&out, method, model_method),
        Some(Command::Evaluate {
            out,
            measured,
            csv,
            confidence,
            sided,
            format,
            report,
        }) => evaluate(&out, measured, csv, confidence, &sided, &format, report),
        None => {
            let scenario = cli.run.scenario.expect("clap requires a scenario");
            prepare(&scenario).and_then(|plan| run(&plan, cli.run.out, cli.run.force))
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(code) => ExitCode::from(code),
    }
}

/// Loads and checks a scenario, printing warnings; errors are printed and give exit code 2.
fn prepare(path: &std::path::Path) -> Result<Plan, u8> {
    match simulate::prepare(path) {
        Ok(plan) => {
            plan.warnings.iter().for_each(|w| eprintln!("{w}"));
            Ok(plan)
        }
        Err(errors) => Err(report_errors(&errors)),
    }
}

fn report_errors(errors: &[Diagnostic]) -> u8 {
    errors.iter().for_each(|e| eprintln!("{e}\n"));
    eprintln!("rsasim: {} error(s); nothing was written", errors.len());
    2
}

fn run(plan: &Plan, out: Option<std::path::PathBuf>, force: bool) -> Result<(), u8> {
    let out = out.unwrap_or_else(|| std::path::Path::new("out").join(&plan.loaded.scenario.name));
    // Every refusal (exit 2) comes here, before any simulation work.
    let target =
        simulate::claim_output(plan, &out, force).map_err(|errors| report_errors(&errors))?;
    target.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    if let Err(e) = rsasim::output::commit::interrupt::install() {
        eprintln!("warning: Ctrl-C will not report what it leaves: {e}");
    }
    let bar = ProgressBar::new(plan.image_count() as u64);
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} {bar:40} {pos}/{len} images ({eta} left)")
            .expect("valid template"),
    );
    let start = Instant::now();
    let summary = simulate::simulate(plan, target, &|| bar.inc(1)).map_err(|e| {
        bar.abandon();
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

fn reconstruct(
    out: &std::path::Path,
    method: rsasim::reconstruct::Method,
    model_method: Option<rsasim::reconstruct::ModelMethod>,
) -> Result<(), u8> {
    let start = Instant::now();
    let summary = rsasim::reconstruct::reconstruct(out, method, model_method)
        .map_err(|errors| report_errors(&errors))?;
    for (run, why) in &summary.failed {
        eprintln!("error: run {run}: {why}");
    }
    eprintln!(
        "rsasim reconstruct: {} run(s) reconstructed, {} failed, in {:.1} s; score them with `rsasim evaluate {}`",
        summary.runs,
        summary.failed.len(),
        start.elapsed().as_secs_f64(),
        out.display()
    );
    if summary.failed.is_empty() {
        Ok(())
    } else {
        Err(1)
    }
}

fn evaluate(
    out: &std::path::Path,
    measured: String,
    csv: Option<std::path::PathBuf>,
    confidence: f64,
    sided: &str,
    formats: &[String],
    report_dir: Option<std::path::PathBuf>,
) -> Result<(), u8> {
    use rsasim::evaluate::{self, MeasuredSource, Options, report, stats};
    if !(confidence > 0.0 && confidence < 1.0) {
        eprintln!(
            "error: --confidence {confidence} is outside (0, 1)\n  = help: e.g. --confidence 0.95"
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
    let sided = if sided == "two" {
        stats::Sided::Two
    } else {
        stats::Sided::One
    };
    let options = Options {
        measured: csv.map_or(MeasuredSource::PerRun(measured), MeasuredSource::Csv),
        confidence: stats::Confidence {
            level: confidence,
            sided,
        },
    };
    let start = Instant::now();
    let dir = report_dir.unwrap_or_else(|| out.join("report"));
    // The report folder is claimed (and refused, exit 2) before any work, once OUT is known to
    // be an output folder (the claim creates the lock file beside the report folder).
    rsasim::output::check_output_folder(out).map_err(|errors| report_errors(&errors))?;
    let target = report::claim_report_dir(&dir).map_err(|d| report_errors(&[*d]))?;
    target.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    let result = evaluate::evaluate(out, &options).map_err(|errors| report_errors(&errors))?;
    let written = report::write_reports_into(&result, target, &formats).map_err(|e| {
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
        written
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
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
