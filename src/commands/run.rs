//! The default command, `rsasim SCENARIO`: run a scenario (or one shard of it).

use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use rsasim::shard::ShardSpec;
use rsasim::simulate::{self, Allowances, Plan};

use super::Outcome;
use super::shared::{check_shard_count, prepare, report_errors, resolve_shard};
use crate::cli::RunArgs;

/// The shard (if any) decided first, then the scenario checked and run.
pub fn execute(args: RunArgs) -> Outcome {
    let scenario = args.scenario.expect("clap requires a scenario");
    let shard = args
        .shard
        .map(|request| resolve_shard(request, args.shard_count))
        .transpose()?;
    let allow: Allowances = args.allow.into();
    let mut plan = prepare(&scenario, &allow)?;
    if let Some((spec, from)) = &shard {
        check_shard_count(*spec, from, plan.runs.len(), allow.large)?;
    }
    plan.previews = args.preview.is_some();
    match shard {
        None => write(&plan, args.out, args.truth_dir.as_deref(), args.force),
        Some((spec, from)) => {
            let base = args.out.unwrap_or_else(|| {
                Path::new("out").join(format!("{}-shards", plan.loaded.scenario.name))
            });
            write_shard(&mut plan, spec, &from, &base, args.force)
        }
    }
}

/// Writes shard `spec` of `plan` into `base/shard-K-of-N/`, unless that folder already holds it
/// complete (a requeued task, a replaced pod): then nothing is written.
pub fn write_shard(
    plan: &mut Plan,
    spec: ShardSpec,
    from: &str,
    base: &Path,
    force: bool,
) -> Outcome {
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
    write(plan, Some(out), None, force)
}

/// Simulates `plan` into `out` (default `out/<scenario name>`), with the truth into `truth_dir`
/// for the blind layout: every refusal (exit 2) before any simulation work, a failure while
/// writing exit 1.
pub fn write(plan: &Plan, out: Option<PathBuf>, truth_dir: Option<&Path>, force: bool) -> Outcome {
    let out = out.unwrap_or_else(|| Path::new("out").join(&plan.loaded.scenario.name));
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
