//! A sweep on a cluster: `rsasim sweep FILE --shard K/N` for every task K (one after another, or
//! all at once into one folder), then `--merge`, gives the unsharded sweep's folder byte for byte
//! (N = 1, 2, 3), and `--merge --evaluate` its summary; a missing or duplicated shard is an error
//! naming the point and its runs (exit 2, nothing written); a finished task rerun writes nothing;
//! the sweep's own files are never replaced; `--shard auto` reads SLURM's and Kubernetes'
//! variables.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::OnceLock;

use common::{hashes, rsasim};

/// The small zipped sweep: 3 points (angles of beamline 2) of 3 runs each.
const SMALL: &str = "tests/scenarios/sweeps/small_angle.toml";

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn sweep(out: &Path, extra: &[&str], env: &[(&str, &str)]) -> Output {
    let mut args = vec!["sweep", SMALL, "--out", s(out)];
    args.extend(extra);
    rsasim(&args, env)
}

fn ok(o: Output) -> Output {
    assert!(o.status.success(), "{}", stderr(&o));
    o
}

/// Every task of a sweep into `out` with N tasks, one after another.
fn tasks(out: &Path, n: usize) {
    for k in 0..n {
        ok(sweep(out, &["--shard", &format!("{k}/{n}")], &[]));
    }
}

/// Every file of a sweep folder but its shards (and the lock files, which hold process ids).
fn sweep_files(out: &Path) -> Vec<(String, String)> {
    hashes(out)
        .into_iter()
        .filter(|(p, _)| !p.starts_with("shards/") && !p.ends_with(".rsasim-lock"))
        .collect()
}

/// The unsharded sweep, reconstructed and evaluated (once for the tests below).
fn unsharded() -> &'static Path {
    static DIR: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    let (_, out) = DIR.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("single");
        ok(sweep(&out, &["--evaluate"], &[]));
        (tmp, out)
    });
    out
}

/// The unsharded sweep's files before scoring: the sweep's own and every point's output.
fn unsharded_outputs() -> Vec<(String, String)> {
    sweep_files(unsharded())
        .into_iter()
        .filter(|(p, _)| {
            !p.starts_with("sweep-report/")
                && !p.contains("/report-")
                && !p.contains("/measured-rsasim-")
        })
        .collect()
}

#[test]
fn n_tasks_merged_equal_the_unsharded_sweep_byte_for_byte() {
    let expected = unsharded_outputs();
    assert!(expected.iter().any(|(p, _)| p == "p02/manifest.json"));
    assert!(expected.iter().any(|(p, _)| p == "points/p01.toml"));
    let tmp = tempfile::tempdir().unwrap();
    for n in [1, 2, 3] {
        let out = tmp.path().join(format!("n{n}"));
        tasks(&out, n);
        // Every task wrote one shard of every point: N folders per point.
        for p in ["p00", "p01", "p02"] {
            let shards = std::fs::read_dir(out.join("shards").join(p))
                .unwrap()
                .filter(|e| {
                    !e.as_ref()
                        .unwrap()
                        .file_name()
                        .to_string_lossy()
                        .starts_with('.')
                })
                .count();
            assert_eq!(shards, n, "{p}");
        }
        // Nothing merged yet: no point folder.
        assert!(!out.join("p00").exists());
        let o = ok(sweep(&out, &["--merge"], &[]));
        assert!(
            stderr(&o).contains(&format!("point p01: {n} shard(s), 3 run(s)")),
            "{}",
            stderr(&o)
        );
        assert_eq!(sweep_files(&out), expected, "N = {n}");
        let v = rsasim(&["verify", s(&out.join("p01"))], &[]);
        assert!(v.status.success(), "{}", String::from_utf8_lossy(&v.stdout));
    }
}

#[test]
fn the_tasks_deal_the_sweeps_runs_round_robin() {
    // 9 runs (3 points × 3) in 2 tasks: task 0 takes the sweep's runs 0, 2, 4, 6, 8: runs 0 and 2
    // of p00 (its shard 0/2), run 1 of p01 (whose runs are the sweep's 3, 4, 5: its shard 1/2)
    // and runs 0 and 2 of p02 (the sweep's 6, 7, 8: its shard 0/2).
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    let o = ok(sweep(&out, &["--shard", "0/2"], &[]));
    assert!(
        stderr(&o).contains("task 0/2 (--shard): 5 of the sweep's 9 run(s)"),
        "{}",
        stderr(&o)
    );
    let names = |p: &str| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(out.join("shards").join(p))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| !n.starts_with('.'))
            .collect();
        v.sort();
        v
    };
    assert_eq!(names("p00"), ["shard-0-of-2"]);
    assert_eq!(names("p01"), ["shard-1-of-2"]);
    assert_eq!(names("p02"), ["shard-0-of-2"]);
    let runs = |p: &str, shard: &str| -> Vec<String> {
        let m: rsasim::output::Manifest = serde_json::from_slice(
            &std::fs::read(out.join("shards").join(p).join(shard).join("manifest.json")).unwrap(),
        )
        .unwrap();
        m.shard.unwrap().runs
    };
    assert_eq!(runs("p00", "shard-0-of-2"), ["n0-r00", "n0-r02"]);
    assert_eq!(runs("p01", "shard-1-of-2"), ["n0-r01"]);
    assert_eq!(runs("p02", "shard-0-of-2"), ["n0-r00", "n0-r02"]);
    // A shard of a point is the point scenario's own shard, byte for byte.
    let alone = tmp.path().join("alone");
    ok(rsasim(
        &[
            s(&out.join("points/p01.toml")),
            "--shard",
            "1/2",
            "--out",
            s(&alone),
        ],
        &[],
    ));
    assert_eq!(
        hashes(&alone.join("shard-1-of-2")),
        hashes(&out.join("shards/p01/shard-1-of-2"))
    );
}

#[test]
fn tasks_running_at_once_into_one_folder_do_not_race() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    let n = 3;
    let children: Vec<_> = (0..n)
        .map(|k| {
            std::process::Command::new(env!("CARGO_BIN_EXE_rsasim"))
                .args(["sweep", SMALL, "--out", s(&out), "--shard"])
                .arg(format!("{k}/{n}"))
                .current_dir(common::root())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // No temporary file left over, and the merge gives the unsharded sweep.
    let leftovers: Vec<String> = hashes(&out)
        .into_iter()
        .map(|(p, _)| p)
        .filter(|p| p.ends_with(".partial"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    ok(sweep(&out, &["--merge"], &[]));
    assert_eq!(sweep_files(&out), unsharded_outputs());
}

#[test]
fn merge_and_evaluate_give_the_unsharded_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    tasks(&out, 2);
    ok(sweep(&out, &["--merge", "--evaluate"], &[]));
    let summary = "sweep-report/sweep_summary.csv";
    assert_eq!(
        std::fs::read(out.join(summary)).unwrap(),
        std::fs::read(unsharded().join(summary)).unwrap()
    );
    // Every point's results and report too.
    let scored = |dir: &Path| -> Vec<(String, String)> {
        sweep_files(dir)
            .into_iter()
            .filter(|(p, _)| p.contains("/measured-rsasim-") || p.ends_with("/report.csv"))
            .collect()
    };
    let expected = scored(unsharded());
    assert_eq!(expected.len(), 3 * 3 + 3);
    assert_eq!(scored(&out), expected);
}

#[test]
fn a_missing_or_duplicated_shard_is_an_error_naming_the_point_and_its_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    tasks(&out, 3);
    // Shard 1/3 of p01 (offset 3: task 1 writes shard (1 − 3) mod 3 = 1) missing: its run n0-r01.
    let aside = tmp.path().join("aside");
    std::fs::rename(out.join("shards/p01/shard-1-of-3"), &aside).unwrap();
    let o = sweep(&out, &["--merge"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("point p01 (sources.tube2.position_mm = [1255.704, 0.0, 336.465]")
            && e.contains("1 of 3 shard(s) missing (1/3): run(s) n0-r01 are in no folder given"),
        "{e}"
    );
    assert!(e.contains("1 error(s); nothing was written"), "{e}");
    for p in ["p00", "p01", "p02"] {
        assert!(!out.join(p).exists(), "{p} written");
    }
    // A shard copied under another shard's name: shard 0/3 given twice.
    std::fs::create_dir(out.join("shards/p01/shard-1-of-3")).unwrap();
    for f in hashes(&out.join("shards/p01/shard-0-of-3")) {
        let to = out.join("shards/p01/shard-1-of-3").join(&f.0);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(out.join("shards/p01/shard-0-of-3").join(&f.0), to).unwrap();
    }
    let o = sweep(&out, &["--merge"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("point p01 (") && e.contains("shard 0/3 is given twice"),
        "{e}"
    );
    assert!(!out.join("p00").exists());
    // The right shard back: merged.
    std::fs::remove_dir_all(out.join("shards/p01/shard-1-of-3")).unwrap();
    std::fs::rename(&aside, out.join("shards/p01/shard-1-of-3")).unwrap();
    ok(sweep(&out, &["--merge"], &[]));
    assert_eq!(sweep_files(&out), unsharded_outputs());
}

#[test]
fn two_splits_need_a_shard_count_and_a_point_without_shards_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    // No task has run: no shards at all.
    ok(sweep(&out, &["--no-run"], &[]));
    let o = sweep(&out, &["--merge"], &[]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(e.contains("3 error(s)"), "{e}");
    assert!(
        e.contains("point p02 (") && e.contains("no shards to merge"),
        "{e}"
    );
    // Two splits of every point: the merge must be told which.
    tasks(&out, 1);
    tasks(&out, 2);
    let o = sweep(&out, &["--merge"], &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("holds the shards of 2 splits (N = 1, N = 2)")
            && stderr(&o).contains("--shard-count N"),
        "{}",
        stderr(&o)
    );
    let o = sweep(&out, &["--merge", "--shard-count", "3"], &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("no shard folder shard-K-of-3"),
        "{}",
        stderr(&o)
    );
    ok(sweep(&out, &["--merge", "--shard-count", "2"], &[]));
    assert_eq!(sweep_files(&out), unsharded_outputs());
    // Merged points are complete: a second merge keeps them, a task rerun writes no shard.
    let o = ok(sweep(&out, &["--merge"], &[]));
    assert!(
        stderr(&o).contains("3 point(s) complete from an earlier run or merge, kept"),
        "{}",
        stderr(&o)
    );
    let o = ok(sweep(&out, &["--shard", "0/5"], &[]));
    assert!(stderr(&o).contains("needs no shard"), "{}", stderr(&o));
    assert!(!out.join("shards/p00/shard-0-of-5").exists());
    // --shard-count alone is for the tasks and the merge.
    let o = sweep(&out, &["--shard-count", "2"], &[]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn a_finished_task_rerun_writes_nothing_and_the_sweeps_files_are_never_replaced() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    tasks(&out, 2);
    let before = hashes(&out);
    let time = |p: &str| std::fs::metadata(out.join(p)).unwrap().modified().unwrap();
    let manifest = "shards/p01/shard-1-of-2/manifest.json";
    let (m0, p0) = (time(manifest), time("points/p01.toml"));
    let o = ok(sweep(&out, &["--shard", "1/2"], &[]));
    assert_eq!(
        stderr(&o).matches("complete and verified").count(),
        3,
        "{}",
        stderr(&o)
    );
    assert_eq!(hashes(&out), before);
    assert_eq!((time(manifest), time("points/p01.toml")), (m0, p0));
    // A point scenario changed by hand: a task refuses (exit 2) and leaves it as it is.
    let point = out.join("points/p01.toml");
    let edited = std::fs::read_to_string(&point).unwrap() + "\n# mine\n";
    std::fs::write(&point, &edited).unwrap();
    let o = sweep(&out, &["--shard", "0/2"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("p01.toml") && stderr(&o).contains("holds other bytes"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read_to_string(&point).unwrap(), edited);
    // Another sweep into the folder is refused before anything is written.
    let other = tmp.path().join("other.toml");
    std::fs::write(
        &other,
        std::fs::read_to_string(common::root().join(SMALL))
            .unwrap()
            .replace(
                "../../../scenarios",
                &common::root().join("scenarios").display().to_string(),
            )
            .replace("values = [3]", "values = [2]"),
    )
    .unwrap();
    let o = rsasim(
        &["sweep", s(&other), "--out", s(&out), "--shard", "0/2"],
        &[],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("holds another sweep"), "{}", stderr(&o));
    // And a folder rsasim did not write.
    let foreign = tmp.path().join("foreign");
    std::fs::create_dir(&foreign).unwrap();
    std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
    let o = sweep(&foreign, &["--shard", "0/2"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("not a sweep folder"), "{}", stderr(&o));
    assert_eq!(std::fs::read_dir(&foreign).unwrap().count(), 1);
}

#[test]
fn shard_auto_takes_the_task_from_slurm_or_kubernetes() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    // SLURM array 1-2: task ID 2 is K = 1 of N = 2.
    let slurm = [
        ("SLURM_ARRAY_TASK_ID", "2"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
        ("SLURM_ARRAY_TASK_MAX", "2"),
        ("SLURM_ARRAY_TASK_COUNT", "2"),
    ];
    let o = ok(sweep(&out, &["--shard", "auto"], &slurm));
    assert!(
        stderr(&o).contains("task 1/2 (SLURM_ARRAY_TASK_ID=2 of 2 task(s) from 1)"),
        "{}",
        stderr(&o)
    );
    // Kubernetes: index 0 with the count from the command line.
    let o = ok(sweep(
        &out,
        &["--shard", "auto", "--shard-count", "2"],
        &[("JOB_COMPLETION_INDEX", "0")],
    ));
    assert!(
        stderr(&o).contains("task 0/2 (JOB_COMPLETION_INDEX=0 and --shard-count 2)"),
        "{}",
        stderr(&o)
    );
    ok(sweep(&out, &["--merge"], &[]));
    assert_eq!(sweep_files(&out), unsharded_outputs());
    // Without the count, or without any variable: exit 2, nothing written.
    let fresh = tmp.path().join("fresh");
    let o = sweep(
        &fresh,
        &["--shard", "auto"],
        &[("JOB_COMPLETION_INDEX", "0")],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--shard-count"), "{}", stderr(&o));
    assert!(!fresh.exists());
}
