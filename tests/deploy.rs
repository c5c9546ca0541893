//! The cluster files in `deploy/`: the Kubernetes manifests pass a schema check of the Kubernetes
//! API (`kubernetes-validate` from PyPI, which ships the schemas: no cluster needed), and they
//! agree with themselves and with rsasim (the shard count is the Job's completions; the merge
//! takes that split's shards; the sweep's merge names the same sweep, folder and split). The SLURM scripts parse; `deploy/slurm/selftest.sh` runs them on a
//! real single-node SLURM cluster (`.ci/run` calls it).
//!
//! A tool that is missing fails the test when `CI` is set; otherwise the test prints a loud
//! `SKIPPED` line and returns.

use crate::common;

use std::path::PathBuf;
use std::process::Command;

const MANIFESTS: [&str; 4] = [
    "deploy/k8s/rsasim-shards.yaml",
    "deploy/k8s/rsasim-merge.yaml",
    "deploy/k8s/rsasim-sweep-shards.yaml",
    "deploy/k8s/rsasim-sweep-merge.yaml",
];

/// The `kubernetes-validate` command, or `None` (fails under CI, SKIPPED otherwise).
fn kubernetes_validate() -> Option<PathBuf> {
    let tool = std::env::var_os("RSASIM_KUBERNETES_VALIDATE")
        .map_or_else(|| PathBuf::from("kubernetes-validate"), PathBuf::from);
    let ok = Command::new(&tool)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        common::skip(
            "(needs kubernetes-validate: python3 -m venv V && V/bin/pip install kubernetes-validate==1.37.0, then put V/bin on PATH)",
        );
        return None;
    }
    Some(tool)
}

fn text(path: &str) -> String {
    std::fs::read_to_string(common::root().join(path)).unwrap()
}

#[test]
fn kubernetes_manifests_pass_the_api_schema() {
    let Some(tool) = kubernetes_validate() else {
        return;
    };
    // Strict: unknown keys are errors. The newest API the tool knows and an older one (1.27,
    // where Indexed Jobs had long been stable).
    for version in ["1.37.0", "1.27.0"] {
        let mut cmd = Command::new(&tool);
        cmd.args(["--strict", "-k", version])
            .args(MANIFESTS)
            .current_dir(common::root());
        let o = cmd.output().unwrap();
        let out =
            String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{version}: {out}");
        for m in MANIFESTS {
            assert!(out.contains(&format!("{m} passed")), "{version}: {out}");
        }
    }
    // The checker does reject a mistake: a misspelt key in the Job spec.
    let tmp = tempfile::tempdir().unwrap();
    let bad = tmp.path().join("bad.yaml");
    std::fs::write(
        &bad,
        text(MANIFESTS[0]).replace("  backoffLimit:", "  backofLimit:"),
    )
    .unwrap();
    let o = Command::new(&tool)
        .arg("--strict")
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("'backofLimit' was unexpected"));
}

/// The value of the first line `key: value` (trimmed, quotes removed).
fn value_of(yaml: &str, key: &str) -> String {
    yaml.lines()
        .find_map(|l| l.trim().strip_prefix(&format!("{key}:")))
        .unwrap_or_else(|| panic!("no {key}"))
        .trim()
        .trim_matches('"')
        .to_string()
}

/// The container's `args:` list (quotes removed).
fn args_of(yaml: &str) -> Vec<String> {
    yaml.lines()
        .map(str::trim)
        .skip_while(|l| *l != "args:")
        .skip(1)
        .take_while(|l| l.starts_with("- "))
        .map(|l| l[2..].trim_matches('"').to_string())
        .collect()
}

/// The value after `flag` in `args`.
fn after(args: &[String], flag: &str) -> String {
    let i = args
        .iter()
        .position(|a| a == flag)
        .unwrap_or_else(|| panic!("no {flag} in {args:?}"));
    args[i + 1].clone()
}

/// Runs `rsasim ARGS --shard auto --shard-count COMPLETIONS --out OUT` as the pod of index
/// completions − 1 would, asserts it succeeds, and returns that index.
fn in_last_pod(completions: &str, args: &[&str], out: &std::path::Path) -> String {
    let last = (completions.parse::<usize>().unwrap() - 1).to_string();
    let mut all = args.to_vec();
    all.extend(["--shard", "auto", "--shard-count", completions]);
    all.extend(["--out", out.to_str().unwrap()]);
    let o = common::rsasim(&all, &[("JOB_COMPLETION_INDEX", &last)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    last
}

#[test]
fn the_indexed_job_and_the_merge_agree_on_the_number_of_shards() {
    let job = text(MANIFESTS[0]);
    assert_eq!(value_of(&job, "completionMode"), "Indexed");
    let completions = value_of(&job, "completions");
    let args = args_of(&job);
    let after = |flag: &str| after(&args, flag);
    assert_eq!(after("--shard"), "auto");
    assert_eq!(after("--shard-count"), completions);
    let merge = text(MANIFESTS[1]);
    assert!(
        merge.contains(&format!("{}/shard-*-of-{completions} ", after("--out"))),
        "the merge must glob the shards of this split"
    );
    // The same arguments in a pod of index completions − 1 are accepted and write that shard.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("shards");
    let last = in_last_pod(
        &completions,
        &[
            "tests/scenarios/shards.toml",
            common::ALLOW_MODELS[0],
            common::ALLOW_MODELS[1],
        ],
        &out,
    );
    assert!(
        out.join(format!("shard-{last}-of-{completions}/manifest.json"))
            .is_file()
    );
}

#[test]
fn the_sweeps_indexed_job_and_its_merge_agree() {
    let job = text(MANIFESTS[2]);
    assert_eq!(value_of(&job, "completionMode"), "Indexed");
    let completions = value_of(&job, "completions");
    assert_eq!(value_of(&job, "parallelism"), completions);
    let args = args_of(&job);
    assert_eq!(args[0], "sweep");
    assert_eq!(after(&args, "--shard"), "auto");
    assert_eq!(after(&args, "--shard-count"), completions);
    // The sweep file is the repository's, copied to the volume's root.
    let file = args[1].strip_prefix("/data/").unwrap();
    assert!(common::root().join(file).is_file(), "{file}");
    // The merge: the same sweep and folder, this split, then the evaluation.
    let merge = args_of(&text(MANIFESTS[3]));
    assert_eq!(merge[..2], args[..2]);
    assert_eq!(after(&merge, "--out"), after(&args, "--out"));
    assert_eq!(after(&merge, "--shard-count"), completions);
    assert!(merge.iter().any(|a| a == "--merge") && merge.iter().any(|a| a == "--evaluate"));
    // The task arguments in the pod of index completions − 1, on the small test sweep: one
    // shard of every point, of this split.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sweep");
    in_last_pod(
        &completions,
        &["sweep", "tests/scenarios/sweeps/small_angle.toml"],
        &out,
    );
    for point in ["p00", "p01", "p02"] {
        let shards: Vec<String> = std::fs::read_dir(out.join("shards").join(point))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("shard-"))
            .collect();
        assert_eq!(shards.len(), 1, "{point}: {shards:?}");
        assert!(
            shards[0].ends_with(&format!("-of-{completions}")),
            "{shards:?}"
        );
    }
}

#[test]
fn the_slurm_scripts_parse() {
    for script in [
        "deploy/slurm/rsasim-shard.sbatch",
        "deploy/slurm/rsasim-merge.sbatch",
        "deploy/slurm/submit.sh",
        "deploy/slurm/rsasim-sweep-shard.sbatch",
        "deploy/slurm/rsasim-sweep-merge.sbatch",
        "deploy/slurm/submit-sweep.sh",
        "deploy/slurm/selftest.sh",
    ] {
        let o = Command::new("bash")
            .args(["-n", script])
            .current_dir(common::root())
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{script}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(text(script).contains("set -euo pipefail"), "{script}");
    }
    // The array task takes its shard from SLURM, the merge only this split's shards.
    assert!(text("deploy/slurm/rsasim-shard.sbatch").contains("--shard auto --out \"$shards\""));
    assert!(text("deploy/slurm/rsasim-merge.sbatch").contains("shard-*-of-\"$count\""));
    // A sweep's task takes its task from SLURM, its merge only this split, then evaluates.
    assert!(
        text("deploy/slurm/rsasim-sweep-shard.sbatch")
            .contains("sweep \"$sweep\" --out \"$dir\" --shard auto")
    );
    assert!(
        text("deploy/slurm/rsasim-sweep-merge.sbatch")
            .contains("--merge --shard-count \"$count\" --evaluate")
    );
}

/// Every manifest, and the manual's Kubernetes steps (`docs/src/guide/cluster.md`), name the
/// image of this version, so a version bump cannot leave a manifest running an older rsasim
/// (whose bytes differ).
#[test]
fn the_manifests_name_the_image_of_this_version() {
    let image = format!("rsasim:{}", env!("CARGO_PKG_VERSION"));
    for m in MANIFESTS {
        assert_eq!(value_of(&text(m), "image"), image, "{m}");
    }
    assert!(text("docs/src/guide/cluster.md").contains(&format!("`{image}`")));
}
