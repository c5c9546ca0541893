//! Shards end to end: `rsasim SCENARIO --shard K/N` for every K, then `rsasim merge`, give the
//! single run's folder byte for byte (N = 1, 2, 3, 7 and more shards than runs); a missing,
//! tampered, foreign or mixed shard is refused with exit 2 and nothing written; a rerun of a
//! finished shard writes nothing; `--shard auto` reads SLURM's and Kubernetes' variables.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{ALLOW_MODELS, hashes, rsasim, truths};
use rsasim::output::Manifest;
use rsasim::output::measured::{Measured, MeasuredPoint, MeasuredPose};

const SCENARIO: &str = "tests/scenarios/shards.toml";

/// The protocol's run ids in order, by hand: 2 levels × 5 runs.
fn protocol_ids() -> Vec<String> {
    (0..2)
        .flat_map(|n| (0..5).map(move |r| format!("n{n}-r{r:02}")))
        .collect()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `rsasim SHARDS --out OUT --shard SPEC` with extra arguments and environment.
fn run_shard(out: &Path, spec: &str, extra: &[&str], env: &[(&str, &str)]) -> Output {
    let mut args = vec![SCENARIO, "--out", s(out), "--shard", spec];
    args.extend(ALLOW_MODELS);
    args.extend(extra);
    rsasim(&args, env)
}

fn ok(o: Output) -> Output {
    assert!(o.status.success(), "{}", stderr(&o));
    o
}

fn single(root: &Path) -> PathBuf {
    let out = root.join("single");
    let mut args = vec![SCENARIO, "--out", s(&out)];
    args.extend(ALLOW_MODELS);
    ok(rsasim(&args, &[]));
    out
}

/// Writes all N shards into `root/name` and returns their folders.
fn all_shards(root: &Path, name: &str, n: usize) -> Vec<PathBuf> {
    let base = root.join(name);
    (0..n)
        .map(|k| {
            ok(run_shard(&base, &format!("{k}/{n}"), &[], &[]));
            let width = (n - 1).to_string().len();
            base.join(format!("shard-{k:0width$}-of-{n}"))
        })
        .collect()
}

fn merge(shards: &[PathBuf], out: &Path) -> Output {
    let mut args = vec!["merge"];
    args.extend(shards.iter().map(|p| s(p)));
    args.extend(["--out", s(out)]);
    rsasim(&args, &[])
}

fn manifest(dir: &Path) -> Manifest {
    serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap()
}

/// Exact results but the phantoms moved by a run-dependent offset along x, so the tables are not
/// all zero.
fn measured(truth: &rsasim::output::Truth, k: usize) -> Measured {
    let run = &truth.run;
    let rows = |m: rsasim::geometry::DMat3| rsasim::geometry::rotation_rows(&m);
    Measured {
        format: "rsasim-measured/1".into(),
        run: run.id.clone(),
        software: "test 1.0".into(),
        methods: None,
        sources: run
            .sources
            .iter()
            .map(|s| MeasuredPoint {
                id: s.id.clone(),
                position_mm: s.position_mm.to_array(),
                quality: None,
            })
            .collect(),
        detectors: run
            .detectors
            .iter()
            .map(|d| MeasuredPose {
                id: d.id.clone(),
                position_mm: d.position_mm.to_array(),
                rotation: Some(rows(d.rotation)),
                markers: vec![],
                quality: None,
            })
            .collect(),
        phantoms: run
            .phantoms
            .iter()
            .filter(|p| p.kind != "calibration_box")
            .map(|p| MeasuredPose {
                id: p.id.clone(),
                position_mm: (p.position_mm + glam::DVec3::X * (0.01 * k as f64)).to_array(),
                rotation: Some(rows(p.rotation)),
                markers: vec![],
                quality: None,
            })
            .collect(),
    }
}

/// Writes the same results into every run of `out` and evaluates them; the CSV report's text.
fn evaluated(out: &Path) -> String {
    for (k, (dir, truth)) in truths(out).iter().enumerate() {
        let bytes = serde_json::to_vec_pretty(&measured(truth, k)).unwrap();
        std::fs::write(dir.join("measured.json"), bytes).unwrap();
    }
    let report = out.join("report");
    let o = rsasim(
        &[
            "evaluate",
            s(out),
            "--format",
            "csv",
            "--report",
            s(&report),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::read_to_string(report.join("report.csv")).unwrap()
}

#[test]
fn n_shards_merged_equal_the_single_run_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let single = single(tmp.path());
    let expected = hashes(&single);
    let ids = protocol_ids();
    assert_eq!(manifest(&single).runs, ids.len());
    for n in [1usize, 2, 3, 7, 12] {
        let shards = all_shards(tmp.path(), &format!("shards-{n}"), n);
        let single_files: std::collections::BTreeMap<_, _> = expected.iter().cloned().collect();
        for (k, dir) in shards.iter().enumerate() {
            // The documented split, by hand: run p goes to shard p mod N.
            let held: Vec<String> = (0..ids.len())
                .filter(|p| p % n == k)
                .map(|p| ids[p].clone())
                .collect();
            let m = manifest(dir);
            let record = m
                .shard
                .as_ref()
                .expect("a shard manifest records its shard");
            assert_eq!((record.index, record.count), (k, n));
            assert_eq!(record.runs, held, "N = {n}, K = {k}");
            assert_eq!(record.protocol_runs, ids);
            assert_eq!(m.runs, held.len());
            assert_eq!(m.scenario_sha256, manifest(&single).scenario_sha256);
            // Every file a shard writes but its manifest is the single run's file, byte for byte.
            for (path, sha) in hashes(dir) {
                if path != "manifest.json" {
                    assert_eq!(single_files.get(&path), Some(&sha), "N = {n}: {path}");
                }
            }
        }
        let merged = tmp.path().join(format!("merged-{n}"));
        let o = ok(merge(&shards, &merged));
        assert!(stderr(&o).contains("hard-linked"), "{}", stderr(&o));
        assert_eq!(hashes(&merged), expected, "N = {n}");
        let v = rsasim(&["verify", s(&merged)], &[]);
        assert!(v.status.success(), "{}", String::from_utf8_lossy(&v.stdout));
    }
    // Copies instead of links: the same bytes.
    let shards = all_shards(tmp.path(), "shards-2", 2);
    let copied = tmp.path().join("copied");
    let mut args = vec!["merge", s(&shards[0]), s(&shards[1]), "--out", s(&copied)];
    args.push("--copy");
    let o = ok(rsasim(&args, &[]));
    assert!(
        stderr(&o).contains("0 hard-linked, 95 copied"),
        "{}",
        stderr(&o)
    );
    assert_eq!(hashes(&copied), expected);
    // evaluate reads the merged folder as it reads the single run's.
    assert_eq!(evaluated(&tmp.path().join("merged-3")), evaluated(&single));
}

#[test]
fn a_missing_or_duplicated_shard_is_an_error_naming_its_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let shards = all_shards(tmp.path(), "shards", 3);
    let out = tmp.path().join("merged");
    let o = merge(&[shards[0].clone(), shards[2].clone()], &out);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    // Shard 1 of 3 holds positions 1, 4, 7.
    assert!(
        stderr(&o).contains("1 of 3 shard(s) missing (1/3): run(s) n0-r01, n0-r04, n1-r02"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
    let o = merge(
        &[shards[0].clone(), shards[1].clone(), shards[0].clone()],
        &out,
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("shard 0/3 is given twice"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
    // Never into a shard folder.
    let inside = shards[0].join("merged");
    let o = merge(&shards, &inside);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("inside the shard folder"),
        "{}",
        stderr(&o)
    );
    assert!(!inside.exists());
}

#[test]
fn a_tampered_shard_is_refused_and_nothing_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let shards = all_shards(tmp.path(), "shards", 2);
    let out = tmp.path().join("merged");
    // One byte of an image changed, its size kept.
    let tiff = shards[1].join("runs/n0-r01/model-det2.tiff");
    let mut bytes = std::fs::read(&tiff).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&tiff, &bytes).unwrap();
    let o = merge(&shards, &out);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("model-det2.tiff: content differs from the manifest"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
    // Every file is hashed before the output is claimed: exit 2 leaves nothing, not even a lock.
    assert_eq!(
        std::fs::read_dir(tmp.path()).unwrap().count(),
        1,
        "no staging folder, partial output or lock is left (only shards/)"
    );
    // A file added among the runs, and an edited manifest.
    let shards = all_shards(tmp.path(), "more", 2);
    std::fs::write(shards[0].join("runs/n0-r00/extra.tiff"), b"x").unwrap();
    let o = merge(&shards, &out);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("extra.tiff: not listed"),
        "{}",
        stderr(&o)
    );
    std::fs::remove_file(shards[0].join("runs/n0-r00/extra.tiff")).unwrap();
    let text = std::fs::read_to_string(shards[1].join("manifest.json")).unwrap();
    std::fs::write(
        shards[1].join("manifest.json"),
        text.replacen("\"runs\": 5", "\"runs\": 4", 1),
    )
    .unwrap();
    let o = merge(&shards, &out);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("modified or corrupted"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
}

#[test]
fn shards_of_other_versions_scenarios_or_splits_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let shards = all_shards(tmp.path(), "shards", 2);
    let out = tmp.path().join("merged");
    // Another split: shard 1 of 3 with shard 0 of 2.
    let three = all_shards(tmp.path(), "three", 3);
    let o = merge(&[shards[0].clone(), three[1].clone()], &out);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("its number of shards differs"),
        "{}",
        stderr(&o)
    );
    // Another scenario (another seed): its hash and seed differ.
    let other = tmp.path().join("other.toml");
    let text = std::fs::read_to_string(common::root().join(SCENARIO)).unwrap();
    std::fs::write(
        &other,
        text.replace("seed = 11", "seed = 12").replace(
            "../../scenarios/models/",
            &format!("{}/scenarios/models/", common::root().display()),
        ),
    )
    .unwrap();
    let base = tmp.path().join("seed12");
    let mut args = vec![s(&other), "--out", s(&base), "--shard", "1/2"];
    args.extend(ALLOW_MODELS);
    ok(rsasim(&args, &[]));
    let o = merge(&[shards[0].clone(), base.join("shard-1-of-2")], &out);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("its scenario SHA-256 differs"),
        "{}",
        stderr(&o)
    );
    // Another version: a shard whose manifest names another program (re-sealed, so only the
    // version is wrong).
    let mut m = manifest(&shards[1]);
    m.program = "rsasim 0.0.1".into();
    std::fs::write(shards[1].join("manifest.json"), m.to_bytes()).unwrap();
    let o = merge(&shards, &out);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("its program differs"), "{}", stderr(&o));
    let o = merge(&[shards[1].clone(), shards[0].clone()], &out);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("written by rsasim 0.0.1"),
        "{}",
        stderr(&o)
    );
    // A folder that is no shard.
    let single = single(tmp.path());
    let o = merge(&[single], &out);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("not a shard folder"), "{}", stderr(&o));
    assert!(!out.exists());
}

#[test]
fn a_finished_shard_is_not_rewritten_and_a_changed_one_needs_force() {
    let tmp = tempfile::tempdir().unwrap();
    let base = tmp.path().join("shards");
    ok(run_shard(&base, "1/2", &[], &[]));
    let dir = base.join("shard-1-of-2");
    let before = hashes(&dir);
    let inode = |p: &Path| {
        use std::os::unix::fs::MetadataExt;
        std::fs::metadata(p).unwrap().ino()
    };
    let manifest_inode = inode(&dir.join("manifest.json"));
    // A replaced pod or requeued task: the same shard again.
    let o = ok(run_shard(&base, "1/2", &[], &[]));
    assert!(stderr(&o).contains("nothing to do"), "{}", stderr(&o));
    assert_eq!(inode(&dir.join("manifest.json")), manifest_inode);
    // A damaged shard is not taken as finished: refused without --force, rewritten with it.
    std::fs::write(dir.join("runs/n0-r01/truth.json"), b"{}").unwrap();
    let o = run_shard(&base, "1/2", &[], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("already exists"), "{}", stderr(&o));
    ok(run_shard(&base, "1/2", &["--force"], &[]));
    assert_eq!(hashes(&dir), before);
}

#[test]
fn shard_auto_takes_the_shard_from_slurm_or_kubernetes() {
    let tmp = tempfile::tempdir().unwrap();
    let fixed = tmp.path().join("fixed");
    ok(run_shard(&fixed, "2/4", &[], &[]));
    let want = hashes(&fixed.join("shard-2-of-4"));
    // Kubernetes: the index, the count from the command line.
    let k8s = tmp.path().join("k8s");
    ok(run_shard(
        &k8s,
        "auto",
        &["--shard-count", "4"],
        &[("JOB_COMPLETION_INDEX", "2")],
    ));
    assert_eq!(hashes(&k8s.join("shard-2-of-4")), want);
    // SLURM, an array numbered from 1 (--array=1-4): task 3 is shard 2.
    let slurm = tmp.path().join("slurm");
    let env = [
        ("SLURM_ARRAY_TASK_ID", "3"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
        ("SLURM_ARRAY_TASK_MAX", "4"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ];
    ok(run_shard(&slurm, "auto", &[], &env));
    assert_eq!(hashes(&slurm.join("shard-2-of-4")), want);
    // Errors before anything is written: no engine, no count, gaps.
    let none = tmp.path().join("none");
    for (extra, env, expect) in [
        (vec![], vec![], "neither SLURM_ARRAY_TASK_ID"),
        (
            vec![],
            vec![("JOB_COMPLETION_INDEX", "1")],
            "pass --shard-count N",
        ),
        (
            vec![],
            vec![
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_MIN", "0"),
                ("SLURM_ARRAY_TASK_MAX", "6"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ],
            "gaps",
        ),
        (
            vec!["--shard-count", "4"],
            vec![("JOB_COMPLETION_INDEX", "4")],
            "not below --shard-count 4",
        ),
    ] {
        let o = run_shard(&none, "auto", &extra, &env);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(expect), "{expect}: {}", stderr(&o));
        assert!(!none.exists());
    }
    // --shard with --truth-dir (the blind layout) is refused by the command line.
    let o = run_shard(
        &none,
        "0/2",
        &["--truth-dir", s(&tmp.path().join("t"))],
        &[],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(!none.exists());
}

#[test]
fn a_clinical_study_in_shards_merges_into_the_single_run() {
    // A study's runs (patients × exams) and its study.json shard and merge like a protocol's.
    let tmp = tempfile::tempdir().unwrap();
    let study = "tests/scenarios/study.toml";
    let single = tmp.path().join("single");
    let mut args = vec![study, "--out", s(&single)];
    args.extend(ALLOW_MODELS);
    ok(rsasim(&args, &[]));
    let base = tmp.path().join("shards");
    let shards: Vec<PathBuf> = (0..3)
        .map(|k| {
            let spec = format!("{k}/3");
            let mut args = vec![study, "--out", s(&base), "--shard", &spec];
            args.extend(ALLOW_MODELS);
            ok(rsasim(&args, &[]));
            base.join(format!("shard-{k}-of-3"))
        })
        .collect();
    assert!(shards.iter().all(|d| d.join("study.json").is_file()));
    let merged = tmp.path().join("merged");
    ok(merge(&shards, &merged));
    assert_eq!(hashes(&merged), hashes(&single));
    assert!(single.join("study.json").is_file());
}
