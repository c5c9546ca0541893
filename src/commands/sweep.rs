//! `rsasim sweep`: a parameter sweep run point by point (or as one task of a sharded sweep, or
//! the merge of its shards), then optionally reconstructed and evaluated (`reconstruct` and
//! `evaluate` on a sweep folder live with those commands).

use std::path::Path;
use std::time::Instant;

use rsasim::shard::ShardRequest;
use rsasim::simulate::Allowances;
use rsasim::sweep::{Sweep, SweepFolder};

use super::evaluate;
use super::shared::{MAX_ERRORS_SHOWN, check_shard_count, prepare, report_errors, resolve_shard};
use super::{Outcome, reconstruct, run};
use crate::cli::{EvaluateArgs, SweepArgs};

/// A sweep, one task of a sharded sweep (`--shard`) or the merge of its shards (`--merge`).
pub fn execute(args: SweepArgs) -> Outcome {
    let allow: Allowances = args.allow.clone().into();
    match (args.shard, args.merge) {
        (Some(request), _) => sweep_shard(&args, request, &allow),
        (None, true) => sweep_merge(&args, &allow),
        (None, false) if args.shard_count.is_some() => {
            eprintln!(
                "error: --shard-count is for a sharded sweep's tasks (--shard) and its --merge\n  = help: add --shard auto (or K/N), or --merge, or drop --shard-count"
            );
            Err(2)
        }
        (None, false) => sweep(&args, &allow),
    }
}

/// Writes the sweep folder's own files (sweep.json, the sweep file's copy, the point scenarios
/// and their inputs), each once; a file there with other bytes is an input error (exit 2).
fn write_points(folder: &SweepFolder, sweep: &Sweep, out: &Path) -> Outcome {
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
    file: &Path,
    out: &Path,
    allow: &Allowances,
    as_task: bool,
) -> Result<(Sweep, SweepFolder), u8> {
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
fn point_allowances(allow: &Allowances) -> Allowances {
    Allowances {
        dirs: Vec::new(),
        large: allow.large,
    }
}

/// `rsasim sweep`: prepares every point (errors: exit 2, nothing written), claims the sweep
/// folder, writes the point scenarios, then runs every pending point with the main command's own
/// `prepare` and `run::write`, exactly as `rsasim DIR/points/<id>.toml --out DIR/<id>`; with
/// `--evaluate`, reconstructs every point and evaluates the sweep.
fn sweep(args: &SweepArgs, allow: &Allowances) -> Outcome {
    let (file, out) = (args.file.as_path(), args.out.as_path());
    let start = Instant::now();
    let (sweep, folder) = open_sweep(file, out, allow, false)?;
    if args.no_run {
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
        run::write(&plan, Some(folder.point_out(&point.id)), None, false)?;
    }
    eprintln!(
        "rsasim sweep: {n} point(s) in {:.1} s -> {}",
        start.elapsed().as_secs_f64(),
        out.display()
    );
    finish_sweep(out, args.evaluate)
}

/// The end of a sweep whose every point is complete: with `evaluate_too`, `rsasim reconstruct`
/// (default methods) on every point and `rsasim evaluate` on the sweep; otherwise how to.
fn finish_sweep(out: &Path, evaluate_too: bool) -> Outcome {
    if !evaluate_too {
        eprintln!(
            "reconstruct and score them with `rsasim reconstruct {0}` and `rsasim evaluate {0}`",
            out.display()
        );
        return Ok(());
    }
    let reconstructed = reconstruct::reconstruct_any(out, &rsasim::reconstruct::Options::default());
    evaluate::execute(EvaluateArgs::defaults(out.to_path_buf()))?;
    reconstructed
}

/// `rsasim sweep --shard K/N|auto`: one task of a sharded sweep. The shard is decided and every
/// point prepared first (errors: exit 2, nothing written); the task then joins the sweep folder
/// (which other tasks may be writing at the same time), writes or checks the sweep's own files,
/// and writes its shard of every point not already complete ([`rsasim::sweep::split`]), each as
/// `rsasim DIR/points/<id>.toml --shard j/N --out DIR/shards/<id>` would.
fn sweep_shard(args: &SweepArgs, request: ShardRequest, allow: &Allowances) -> Outcome {
    let (file, out) = (args.file.as_path(), args.out.as_path());
    let start = Instant::now();
    let (task, from) = resolve_shard(request, args.shard_count)?;
    let sweep = rsasim::sweep::prepare(file, allow).map_err(|e| report_errors(&e))?;
    let most_runs = sweep.points.iter().map(|p| p.runs).max().unwrap_or(0);
    check_shard_count(task, &from, most_runs, allow.large)?;
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
        run::write_shard(
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
/// point's shards checked (every problem of every point reported; exit 2, nothing written), the
/// sweep's own files written or checked, every point's output folder claimed, then each point
/// merged; with `--evaluate`,
/// reconstructed and evaluated as an unsharded sweep.
fn sweep_merge(args: &SweepArgs, allow: &Allowances) -> Outcome {
    use rsasim::output::merge;
    let (file, out) = (args.file.as_path(), args.out.as_path());
    let start = Instant::now();
    let sweep = rsasim::sweep::prepare(file, allow).map_err(|e| report_errors(&e))?;
    let folder = rsasim::sweep::claim(&sweep, out).map_err(|e| report_errors(&e))?;
    // `check` hashes every file of every point's shards (rsasim::output::merge::check) before the
    // sweep's own files are written or checked, so its exit 2 means nothing was written.
    let points = rsasim::sweep::merge::check(&sweep, &folder, args.shard_count)
        .map_err(|e| report_errors(&e))?;
    write_points(&folder, &sweep, out)?;
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
    finish_sweep(out, args.evaluate)
}
