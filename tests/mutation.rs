//! Seeded mutation tests: hundreds of broken variants of every input a lab hands rsasim (the
//! scenario, its mesh files in STL, GLB and glTF, a software's `measured.json` and CSV results),
//! each run through the real binary. Whatever the mutant, rsasim must end in one of two ways:
//!
//! - exit 0, with an output folder that `rsasim verify` accepts (or a report with no NaN or
//!   infinite cell), or
//! - exit 2, with an error that names the file it read, and nothing written.
//!
//! Never a panic (exit 101), an abort, a hang, exit 1 after `validate` said valid, or a leftover.
//!
//! The same contract holds for the folders a lab *receives* (`received_folders` below): every byte
//! of a received output, sweep or shard folder is the sender's, its manifests too (half the mutants
//! are rehashed into their manifest, as a hostile sender would, so that they reach the parsers).
//! Each reading command (`export`, `evaluate`, `reconstruct`, `verify`, `merge`, `sweep --merge`)
//! runs on a copy of a folder made once, with one file mutated (its values replaced by hostile
//! numbers and strings, paths out of the folder among them; entries duplicated, up to many
//! thousand times; its structure or bytes broken; or the file replaced by a FIFO, a link out of
//! the folder or to a device, a folder, a sparse file past the caps, nothing) or one folder
//! replaced (by a link out or to a sibling, a file, a FIFO, nothing) or given unlisted entries.
//! It must exit 0 having written only into the output the user named (which then verifies, with
//! no NaN or infinite report cell or camera number), or exit 2 naming a file and having written
//! nothing at all, not even a lock file (`reconstruct` may also exit 1, writing only its results);
//! never panic, abort or hang (killed after `RSASIM_MUTATION_LIMIT_S`, default 20 s). Run as
//! root, the mutants run as `nobody` on a copy they own, so that no mutant can touch system files.
//! A failing mutant's whole folder is kept in `$TMPDIR/rsasim-mutant-<command>-<seed>`; replay one
//! with `RSASIM_MUTATION_SEED=<seed> RSASIM_MUTATION_CASES=1 cargo test --test integration
//! mutation::received_folders::<test>`. The folders are built with the binary under test, their manifests
//! then given one fixed build (commit zero) and resealed, so a seed names the same mutant whichever
//! commit built the binary, as long as the bytes rsasim writes do not change. The long run (20,000
//! mutants per command) is `examples/fuzz_inputs.rs`.
//!
//! The budget is small for CI. For longer runs (fuzzing as a habit, see docs/src/development/testing.md):
//! `RSASIM_MUTATION_CASES=5000 RSASIM_MUTATION_SEED=$RANDOM cargo test --release --test integration mutation::`.
//! A failure prints the seed of its mutant and keeps the mutant file so it can be replayed.

use crate::common;
use crate::common::mutate;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use mutate::{Rng, mutate_bytes, mutate_text};

/// How many mutants of each kind: `RSASIM_MUTATION_CASES`, or `default` (sized for CI).
fn cases(default: usize) -> usize {
    std::env::var("RSASIM_MUTATION_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The first seed: `RSASIM_MUTATION_SEED`, or 0.
fn first_seed() -> u64 {
    std::env::var("RSASIM_MUTATION_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

/// What one rsasim process did.
struct Ran {
    code: Option<i32>,
    stderr: String,
    timed_out: bool,
}

/// Runs the binary in `cwd`, killing it after `limit`.
fn rsasim_in(cwd: &Path, args: &[&str], limit: Duration) -> Ran {
    let mut child = Command::new(env!("CARGO_BIN_EXE_rsasim"))
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("rsasim starts");
    let mut stderr_pipe = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = Vec::new();
        std::io::Read::read_to_end(&mut stderr_pipe, &mut s).ok();
        s
    });
    let start = Instant::now();
    let (status, timed_out) = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break (status, false);
        }
        if start.elapsed() > limit {
            child.kill().ok();
            break (child.wait().unwrap(), true);
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let stderr = String::from_utf8_lossy(&reader.join().unwrap()).into_owned();
    Ran {
        code: status.code(),
        stderr,
        timed_out,
    }
}

/// The names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A failure, with what is needed to replay it.
fn failed(kind: &str, seed: u64, mutant: &Path, why: &str, ran: &Ran) -> String {
    let keep = std::env::temp_dir().join(format!("rsasim-mutant-{kind}-{seed}"));
    let _ = std::fs::create_dir_all(&keep);
    if let Some(name) = mutant.file_name() {
        let _ = std::fs::copy(mutant, keep.join(name));
    }
    format!(
        "{kind} mutant seed {seed} (kept in {}): {why}; exit {:?}{}\n{}",
        keep.display(),
        ran.code,
        if ran.timed_out { " (timed out)" } else { "" },
        cut(&ran.stderr, 1500)
    )
}

fn cut(s: &str, n: usize) -> &str {
    let mut i = n.min(s.len());
    while !s.is_char_boundary(i) {
        i -= 1;
    }
    &s[..i]
}

/// The base inputs in a fresh folder: the scenario, its STL, and the same mesh as GLB and as a
/// self-contained glTF (base64 buffer).
fn base_folder() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let root = common::root();
    std::fs::copy(
        root.join("tests/mutation/base.toml"),
        dir.path().join("base.toml"),
    )
    .unwrap();
    std::fs::copy(
        root.join("scenarios/golden/models/ball.stl"),
        dir.path().join("ball.stl"),
    )
    .unwrap();
    let ball =
        rsasim::phantom::mesh_io::load_mesh(&root.join("scenarios/golden/models/ball.stl"), 1.0)
            .unwrap();
    let glb = rsasim::phantom::mesh_io::glb_bytes(&ball).unwrap();
    std::fs::write(dir.path().join("ball.glb"), &glb).unwrap();
    std::fs::write(dir.path().join("ball.gltf"), gltf_from_glb(&glb)).unwrap();
    dir
}

/// A `.gltf` whose one buffer is the GLB's binary chunk as a base64 `data:` URI.
fn gltf_from_glb(glb: &[u8]) -> String {
    use base64::Engine;
    let word = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
    let json_len = word(12);
    let json = &glb[20..20 + json_len];
    let bin_at = 20 + json_len;
    let bin = &glb[bin_at + 8..bin_at + 8 + word(bin_at)];
    let mut doc: serde_json::Value = serde_json::from_slice(json).unwrap();
    doc["buffers"][0]["uri"] = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bin)
    )
    .into();
    serde_json::to_string_pretty(&doc).unwrap()
}

/// Runs `scenario` (in `dir`) through `validate` and a full run, and checks the contract.
fn check_scenario_run(kind: &str, seed: u64, dir: &Path, scenario: &Path) -> Result<(), String> {
    let before = listing(dir);
    let name = scenario.file_name().unwrap().to_str().unwrap();
    let limit = Duration::from_secs(60);
    let validate = rsasim_in(dir, &["validate", name], limit);
    let run = rsasim_in(dir, &[name, "--out", "out"], limit);
    for (what, ran) in [("validate", &validate), ("run", &run)] {
        match ran.code {
            Some(0) | Some(2) if !ran.timed_out => {}
            _ => {
                return Err(failed(
                    kind,
                    seed,
                    scenario,
                    &format!("{what} did not exit 0 or 2"),
                    ran,
                ));
            }
        }
        if ran.stderr.contains("panicked") {
            return Err(failed(
                kind,
                seed,
                scenario,
                &format!("{what} panicked"),
                ran,
            ));
        }
    }
    if validate.code == Some(0) && run.code != Some(0) {
        return Err(failed(
            kind,
            seed,
            scenario,
            "validate said valid but the run failed",
            &run,
        ));
    }
    if run.code == Some(2) {
        if !(run.stderr.contains(name) || run.stderr.contains("ball.")) {
            return Err(failed(
                kind,
                seed,
                scenario,
                "the error names no input file",
                &run,
            ));
        }
        if listing(dir) != before {
            return Err(failed(
                kind,
                seed,
                scenario,
                &format!("exit 2 left files behind: {:?}", listing(dir)),
                &run,
            ));
        }
    } else {
        let verify = rsasim_in(dir, &["verify", "out"], limit);
        if verify.code != Some(0) {
            return Err(failed(
                kind,
                seed,
                scenario,
                "the output does not verify",
                &verify,
            ));
        }
        std::fs::remove_dir_all(dir.join("out")).unwrap();
        let leftovers: Vec<String> = listing(dir)
            .into_iter()
            .filter(|n| !before.contains(n))
            .filter(|n| !n.ends_with(".rsasim-lock"))
            .collect();
        if !leftovers.is_empty() {
            return Err(failed(
                kind,
                seed,
                scenario,
                &format!("leftovers {leftovers:?}"),
                &run,
            ));
        }
    }
    Ok(())
}

/// Runs `check` on `n` seeds and fails with every failure (at most 10 shown).
fn over_seeds(n: usize, mut check: impl FnMut(u64) -> Result<(), String>) {
    let failures: Vec<String> = (0..n as u64)
        .map(|k| first_seed().wrapping_add(k))
        .filter_map(|seed| check(seed).err())
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {n} mutants broke the contract:\n\n{}",
        failures.len(),
        failures
            .iter()
            .take(10)
            .cloned()
            .collect::<Vec<_>>()
            .join("\n\n")
    );
}

#[test]
fn the_unmutated_inputs_run_and_verify() {
    let dir = base_folder();
    let base = std::fs::read_to_string(dir.path().join("base.toml")).unwrap();
    for mesh in ["ball.stl", "ball.glb", "ball.gltf"] {
        let text = base.replace("\"ball.stl\"", &format!("\"{mesh}\""));
        std::fs::write(dir.path().join("plain.toml"), text).unwrap();
        let limit = Duration::from_secs(60);
        let run = rsasim_in(dir.path(), &["plain.toml", "--out", "out"], limit);
        assert_eq!(run.code, Some(0), "{mesh}: {}", run.stderr);
        let verify = rsasim_in(dir.path(), &["verify", "out"], limit);
        assert_eq!(verify.code, Some(0), "{mesh}: {}", verify.stderr);
        std::fs::remove_dir_all(dir.path().join("out")).unwrap();
    }
}

#[test]
fn mutated_scenarios_exit_0_with_a_verified_output_or_2_with_nothing_written() {
    let base = std::fs::read_to_string(common::root().join("tests/mutation/base.toml")).unwrap();
    over_seeds(cases(120), |seed| {
        let dir = base_folder();
        let scenario = dir.path().join("mutant.toml");
        std::fs::write(&scenario, mutate_text(&base, &mut Rng::new(seed))).unwrap();
        check_scenario_run("scenario", seed, dir.path(), &scenario)
    });
}

#[test]
fn mutated_meshes_exit_0_with_a_verified_output_or_2_with_nothing_written() {
    let base = std::fs::read_to_string(common::root().join("tests/mutation/base.toml")).unwrap();
    over_seeds(cases(120), |seed| {
        let dir = base_folder();
        let mut rng = Rng::new(seed);
        let mesh = *rng.pick(&["ball.stl", "ball.glb", "ball.gltf"]);
        let path = dir.path().join(mesh);
        let bytes = std::fs::read(&path).unwrap();
        let mutant = if mesh.ends_with(".gltf") {
            mutate_text(&String::from_utf8(bytes).unwrap(), &mut rng).into_bytes()
        } else {
            mutate_bytes(&bytes, &mut rng)
        };
        std::fs::write(&path, mutant).unwrap();
        let scenario = dir.path().join("mesh.toml");
        std::fs::write(
            &scenario,
            base.replace("\"ball.stl\"", &format!("\"{mesh}\"")),
        )
        .unwrap();
        check_scenario_run("mesh", seed, dir.path(), &scenario).map_err(|e| format!("{mesh}: {e}"))
    });
}

/// A simulated output folder with a perfect `measured.json` in every run (the truth, as a
/// software would write it) and the same results as one CSV long table.
struct Scored {
    dir: tempfile::TempDir,
    out: PathBuf,
    runs: Vec<PathBuf>,
    csv: String,
}

fn scored_output() -> Scored {
    let dir = base_folder();
    let run = rsasim_in(
        dir.path(),
        &["base.toml", "--out", "out"],
        Duration::from_secs(60),
    );
    assert_eq!(run.code, Some(0), "{}", run.stderr);
    let out = dir.path().join("out");
    let mut csv = String::from("run,kind,id,x_mm,y_mm,z_mm,r11,r12,r13,r21,r22,r23,r31,r32,r33\n");
    let mut runs = Vec::new();
    for (run_dir, truth) in common::truths(&out) {
        let t = serde_json::to_value(&truth).unwrap();
        let r = &t;
        let pose = |v: &serde_json::Value| serde_json::json!({"id": v["id"], "position_mm": v["position_mm"], "rotation": v["rotation"]});
        let measured = serde_json::json!({
            "format": "rsasim-measured/1",
            "run": r["id"],
            "software": "Perfect 1.0",
            "sources": r["sources"].as_array().unwrap().iter()
                .map(|s| serde_json::json!({"id": s["id"], "position_mm": s["position_mm"]}))
                .collect::<Vec<_>>(),
            "detectors": r["detectors"].as_array().unwrap().iter().map(pose).collect::<Vec<_>>(),
            "phantoms": r["phantoms"].as_array().unwrap().iter().map(pose).collect::<Vec<_>>(),
        });
        std::fs::write(
            run_dir.join("measured.json"),
            serde_json::to_string_pretty(&measured).unwrap(),
        )
        .unwrap();
        let id = r["id"].as_str().unwrap();
        for s in r["sources"].as_array().unwrap() {
            let p = &s["position_mm"];
            csv += &format!(
                "{id},source,{},{},{},{},,,,,,,,,\n",
                s["id"].as_str().unwrap(),
                p[0],
                p[1],
                p[2]
            );
        }
        for (kind, key) in [("detector", "detectors"), ("phantom", "phantoms")] {
            for e in r[key].as_array().unwrap() {
                let p = &e["position_mm"];
                let rot: Vec<String> = e["rotation"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .flat_map(|row| row.as_array().unwrap().iter().map(|x| x.to_string()))
                    .collect();
                csv += &format!(
                    "{id},{kind},{},{},{},{},{}\n",
                    e["id"].as_str().unwrap(),
                    p[0],
                    p[1],
                    p[2],
                    rot.join(",")
                );
            }
        }
        runs.push(run_dir);
    }
    Scored {
        dir,
        out,
        runs,
        csv,
    }
}

/// The first cell of `report.csv` that is infinite, or NaN in a row with N ≥ 2 (NaN is the
/// documented value of the precision and SD of a cell with a single residual).
fn non_finite_cell(csv: &str) -> Option<String> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next()?.split(',').collect();
    let n_col = header.iter().position(|h| *h == "n")?;
    lines.enumerate().find_map(|(k, line)| {
        let cells: Vec<&str> = line
            .split(',')
            .map(|c| c.trim().trim_matches('"'))
            .collect();
        let single = cells.get(n_col).and_then(|n| n.parse::<u64>().ok()) < Some(2);
        cells
            .iter()
            .filter_map(|c| c.parse::<f64>().ok())
            .find(|x| x.is_infinite() || (x.is_nan() && !single))
            .map(|x| format!("line {}: {x} in `{line}`", k + 2))
    })
}

/// Runs `evaluate` with `extra` arguments into a fresh report folder and checks the contract.
fn check_evaluate(
    kind: &str,
    seed: u64,
    s: &Scored,
    mutant: &Path,
    extra: &[&str],
) -> Result<(), String> {
    let report = s.dir.path().join(format!("report-{seed}"));
    let mut args = vec![
        "evaluate",
        s.out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let ran = rsasim_in(s.dir.path(), &args, Duration::from_secs(60));
    match ran.code {
        Some(0) => {
            let csv = std::fs::read_to_string(report.join("report.csv"))
                .map_err(|e| failed(kind, seed, mutant, &format!("no report.csv: {e}"), &ran))?;
            if let Some(cell) = non_finite_cell(&csv) {
                let why = format!("exit 0 with a non-finite cell: {cell}");
                return Err(failed(kind, seed, mutant, &why, &ran));
            }
            std::fs::remove_dir_all(&report).unwrap();
        }
        Some(2) if !ran.timed_out => {
            let name = mutant.file_name().unwrap().to_str().unwrap();
            if !ran.stderr.contains(name) {
                return Err(failed(
                    kind,
                    seed,
                    mutant,
                    "the error names no input file",
                    &ran,
                ));
            }
            if report.exists() {
                return Err(failed(kind, seed, mutant, "exit 2 wrote a report", &ran));
            }
        }
        _ => {
            return Err(failed(
                kind,
                seed,
                mutant,
                "evaluate did not exit 0 or 2",
                &ran,
            ));
        }
    }
    if ran.stderr.contains("panicked") {
        return Err(failed(kind, seed, mutant, "evaluate panicked", &ran));
    }
    Ok(())
}

#[test]
fn mutated_measured_results_are_scored_or_refused_with_their_location() {
    let s = scored_output();
    let clean = check_evaluate(
        "measured",
        0,
        &s,
        &s.runs[0].join("measured.json"),
        &["--measured", "measured.json"],
    );
    assert!(clean.is_ok(), "the perfect results must score: {clean:?}");
    over_seeds(cases(150), |seed| {
        let mut rng = Rng::new(seed);
        let file = s.runs[rng.below(s.runs.len())].join("measured.json");
        let original = std::fs::read_to_string(&file).unwrap();
        std::fs::write(&file, mutate_text(&original, &mut rng)).unwrap();
        let r = check_evaluate(
            "measured",
            seed,
            &s,
            &file,
            &["--measured", "measured.json"],
        );
        std::fs::write(&file, original).unwrap();
        r
    });
}

#[test]
fn mutated_csv_results_are_scored_or_refused_with_their_location() {
    let s = scored_output();
    let file = s.dir.path().join("results.csv");
    std::fs::write(&file, &s.csv).unwrap();
    let clean = check_evaluate("csv", 0, &s, &file, &["--csv", file.to_str().unwrap()]);
    assert!(clean.is_ok(), "the perfect results must score: {clean:?}");
    over_seeds(cases(150), |seed| {
        std::fs::write(&file, mutate_text(&s.csv, &mut Rng::new(seed))).unwrap();
        check_evaluate("csv", seed, &s, &file, &["--csv", file.to_str().unwrap()])
    });
}

#[test]
fn a_mutated_truth_is_never_scored() {
    let s = scored_output();
    over_seeds(cases(20), |seed| {
        let mut rng = Rng::new(seed);
        let file = s.runs[rng.below(s.runs.len())].join("truth.json");
        let original = std::fs::read_to_string(&file).unwrap();
        let mutant = mutate_text(&original, &mut rng);
        if mutant == original {
            return Ok(());
        }
        std::fs::write(&file, mutant).unwrap();
        let report = s.dir.path().join("report-truth");
        let ran = rsasim_in(
            s.dir.path(),
            &[
                "evaluate",
                s.out.to_str().unwrap(),
                "--measured",
                "measured.json",
                "--report",
                report.to_str().unwrap(),
            ],
            Duration::from_secs(60),
        );
        std::fs::write(&file, original).unwrap();
        if ran.code != Some(2) || !ran.stderr.contains("truth.json") || report.exists() {
            return Err(failed(
                "truth",
                seed,
                &file,
                "a modified truth was not refused by name",
                &ran,
            ));
        }
        Ok(())
    });
}

/// Received folders: one test per reading command, each on its own folder built once.
#[cfg(unix)]
mod received_folders {
    use super::{cases, over_seeds};
    use crate::common::mutate::received::{Harness, Kind};
    use std::path::PathBuf;
    use std::time::Duration;

    /// How long one command may take before it counts as a hang: `RSASIM_MUTATION_LIMIT_S`, or
    /// 20 s (every command here takes well under 2 s on its small folder).
    fn limit() -> Duration {
        let s = std::env::var("RSASIM_MUTATION_LIMIT_S")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(20);
        Duration::from_secs(s)
    }

    /// Builds `kind`'s folder, checks that the unmutated copy is read (exit 0, the contract's
    /// checks pass), then runs `cases(default)` mutants.
    fn received(kind: Kind, default: usize) {
        let h = Harness::new(PathBuf::from(env!("CARGO_BIN_EXE_rsasim")), limit());
        let fixture = h.fixture(kind.fixture());
        match h.check(kind, &fixture, None) {
            Ok(0) => {}
            Ok(code) => panic!("{}: the unmutated folder gave exit {code}", kind.name()),
            Err(f) => panic!("the unmutated folder must be read:\n{f}"),
        }
        over_seeds(cases(default), |seed| {
            h.check(kind, &fixture, Some(seed))
                .map(|_| ())
                .map_err(|f| f.to_string())
        });
    }

    #[test]
    fn export_to_xmalab() {
        received(Kind::ExportXmalab, 100);
    }

    #[test]
    fn export_to_autoscoper() {
        received(Kind::ExportAutoscoper, 100);
    }

    #[test]
    fn evaluate() {
        received(Kind::Evaluate, 100);
    }

    #[test]
    fn evaluate_a_study() {
        received(Kind::EvaluateStudy, 80);
    }

    #[test]
    fn reconstruct() {
        received(Kind::Reconstruct, 80);
    }

    #[test]
    fn verify() {
        received(Kind::Verify, 120);
    }

    #[test]
    fn merge() {
        received(Kind::Merge, 100);
    }

    #[test]
    fn sweep_merge() {
        received(Kind::SweepMerge, 100);
    }

    #[test]
    fn evaluate_a_sweep() {
        received(Kind::EvaluateSweep, 80);
    }

    #[test]
    fn reconstruct_a_sweep() {
        received(Kind::ReconstructSweep, 80);
    }
}
