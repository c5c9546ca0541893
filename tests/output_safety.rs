//! Output safety (issues 10 and 17): `--force` replaces only rsasim's own outputs, refusals come
//! before any work, a failed, killed or concurrent run never leaves a mix or a corrupt output.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

use common::{hashes, root};

/// A lab folder with a scenario (small, 40 runs of 16×16 pixels) and its mesh, both the user's.
fn lab(tmp: &Path) -> (PathBuf, PathBuf) {
    let lab = tmp.join("lab");
    let meshes = lab.join("meshes");
    std::fs::create_dir_all(&meshes).unwrap();
    std::fs::copy(
        root().join("scenarios/models/femoral_component.glb"),
        meshes.join("femur.glb"),
    )
    .unwrap();
    let text = std::fs::read_to_string(root().join("tests/scenarios/evaluate.toml"))
        .unwrap()
        .replace(
            "../../scenarios/models/femoral_component.glb",
            "meshes/femur.glb",
        );
    let scenario = lab.join("knee.toml");
    std::fs::write(&scenario, text).unwrap();
    (lab, scenario)
}

fn cmd(cwd: &Path, args: &[&str], env: &[(&str, &str)]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rsasim"));
    c.args(args).current_dir(cwd);
    for (k, v) in env {
        c.env(k, v);
    }
    c
}

fn run_in(cwd: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    cmd(cwd, args, env).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Every file the manifest lists matches its hash, and nothing else is there but the manifest.
fn verifies(out: &Path) -> bool {
    let Ok(bytes) = std::fs::read(out.join("manifest.json")) else {
        return false;
    };
    let Ok(m) = serde_json::from_slice::<rsasim::output::Manifest>(&bytes) else {
        return false;
    };
    let mut listed: Vec<(String, String)> =
        m.files.into_iter().map(|f| (f.path, f.sha256)).collect();
    listed.sort();
    let mut got = hashes(out);
    got.retain(|(p, _)| p != "manifest.json");
    listed == got
}

/// Names in `dir` other than `keep` and lock files.
fn others(dir: &Path, keep: &str) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != keep && !n.ends_with(".rsasim-lock"))
        .collect()
}

#[test]
fn force_refuses_every_forbidden_folder_and_leaves_the_users_files_intact() {
    let tmp = tempfile::tempdir().unwrap();
    let (lab, scenario) = lab(tmp.path());
    let sc = scenario.to_str().unwrap();
    let mine = tmp.path().join("thesis");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("chapter1.tex"), "mine").unwrap();
    let afile = tmp.path().join("afile");
    std::fs::write(&afile, "mine too").unwrap();
    std::os::unix::fs::symlink(tmp.path().join("nowhere"), tmp.path().join("dangling")).unwrap();
    std::os::unix::fs::symlink(&mine, tmp.path().join("link")).unwrap();
    let before = (hashes(&lab), hashes(&mine));
    let cases: [(&Path, &str, &str); 8] = [
        (tmp.path(), "lab", "which this run reads"),
        (tmp.path(), "lab/meshes", "which this run reads"),
        (&lab, ".", "current folder"),
        (&lab.join("meshes"), "..", "current folder"),
        (tmp.path(), "thesis", "not written by rsasim"),
        (tmp.path(), "link", "symbolic link"),
        (tmp.path(), "dangling", "symbolic link"),
        (tmp.path(), "afile", "names a file"),
    ];
    for (cwd, out, why) in cases {
        for force in [true, false] {
            let mut args = vec![sc, "--out", out];
            if force {
                args.push("--force");
            }
            let o = run_in(cwd, &args, &[]);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "--out {out}: {err}");
            if force || matches!(out, "dangling" | "afile" | "link") {
                assert!(err.contains(why), "--out {out} --force={force}: {err}");
            }
            assert!(err.contains("help:"), "{err}");
        }
    }
    assert_eq!((hashes(&lab), hashes(&mine)), before);
    assert_eq!(std::fs::read(&afile).unwrap(), b"mine too");
    assert_eq!(
        others(tmp.path(), "lab").len(),
        4,
        "nothing staged: {:?}",
        others(tmp.path(), "lab")
    );
}

#[test]
fn force_replaces_an_earlier_output_and_a_failed_rerun_keeps_it() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, scenario) = lab(tmp.path());
    let sc = scenario.to_str().unwrap();
    let out = tmp.path().join("out");
    let o = run_in(tmp.path(), &[sc, "--out", "out"], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(verifies(&out) && out.join("README.md").exists());
    let first = hashes(&out);
    let o = run_in(tmp.path(), &[sc, "--out", "out"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    // The 60th file write fails (as a full disk would): the old output stays, whole.
    let o = run_in(
        tmp.path(),
        &[sc, "--out", "out", "--force"],
        &[("RSASIM_FAULT_AFTER_FILES", "60")],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("injected write fault"),
        "{}",
        stderr(&o)
    );
    assert_eq!(hashes(&out), first);
    assert_eq!(others(tmp.path(), "out"), ["lab"], "no staging left");
    let o = run_in(tmp.path(), &[sc, "--out", "out", "--force"], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(hashes(&out), first, "same scenario, same bytes");
    assert_eq!(others(tmp.path(), "out"), ["lab"]);
}

#[test]
fn two_runs_into_one_output_give_one_verified_output_and_one_clear_refusal() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, scenario) = lab(tmp.path());
    let sc = scenario.to_str().unwrap();
    let spawn = || {
        cmd(tmp.path(), &[sc, "--out", "out"], &[])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (a, b) = (spawn(), spawn());
    let (a, b) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
    let codes = [a.status.code(), b.status.code()];
    assert!(
        codes.contains(&Some(0)) && codes.contains(&Some(2)),
        "{codes:?}"
    );
    let loser = if a.status.success() { &b } else { &a };
    assert!(
        stderr(loser).contains("another rsasim process (pid "),
        "{}",
        stderr(loser)
    );
    assert!(verifies(&tmp.path().join("out")));
}

#[test]
fn kill_9_at_any_moment_leaves_the_old_or_the_new_output_never_a_mix() {
    let tmp = tempfile::tempdir().unwrap();
    let (lab, scenario) = lab(tmp.path());
    let sc = scenario.to_str().unwrap();
    let out = tmp.path().join("out");
    // The previous output is of another seed, so old and new differ in every image.
    let other = lab.join("other.toml");
    let text = std::fs::read_to_string(&scenario).unwrap();
    std::fs::write(
        &other,
        format!("seed = 99\n{text}").replace("\nseed = ", "\n# seed = "),
    )
    .unwrap();
    let o = run_in(tmp.path(), &[other.to_str().unwrap(), "--out", "out"], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let old = hashes(&out);
    // Seeded moments spread over a run (~1-2 s here).
    let mut state: u64 = 0x5eed;
    for _ in 0..8 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let delay_ms = 50 + (state >> 33) % 1600;
        let mut child = cmd(tmp.path(), &[sc, "--out", "out", "--force"], &[])
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(delay_ms));
        let _ = child.kill();
        let _ = child.wait();
        if out.exists() {
            assert!(verifies(&out), "a mix after kill at {delay_ms} ms");
        }
        // The next run recovers, cleans up and succeeds.
        let o = run_in(tmp.path(), &[sc, "--out", "out", "--force"], &[]);
        assert!(
            o.status.success(),
            "after kill at {delay_ms} ms: {}",
            stderr(&o)
        );
        assert!(verifies(&out));
        assert_ne!(hashes(&out), old);
        assert_eq!(
            others(tmp.path(), "out"),
            ["lab"],
            "after kill at {delay_ms} ms"
        );
        // Back to the old output for the next moment.
        let o = run_in(
            tmp.path(),
            &[other.to_str().unwrap(), "--out", "out", "--force"],
            &[],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
}

#[test]
fn ctrl_c_says_what_it_left_and_the_next_run_removes_it_saying_so() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, scenario) = lab(tmp.path());
    let sc = scenario.to_str().unwrap();
    let child = cmd(tmp.path(), &[sc, "--out", "out"], &[])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Signal once the run is writing (its staging folder exists).
    for _ in 0..400 {
        if others(tmp.path(), "lab")
            .iter()
            .any(|n| n.contains("rsasim-staging-"))
        {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    if o.status.success() {
        // The run beat the signal on a fast machine; nothing to check.
        return;
    }
    assert_eq!(o.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    assert!(
        err.contains("rsasim-staging-") && err.contains("the next run into out removes it"),
        "{err}"
    );
    assert!(!tmp.path().join("out").exists());
    let o = run_in(tmp.path(), &[sc, "--out", "out"], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("removed ") && stderr(&o).contains("unfinished staging folder"),
        "{}",
        stderr(&o)
    );
    assert_eq!(others(tmp.path(), "out"), ["lab"]);
}
