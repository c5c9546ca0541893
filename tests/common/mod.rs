//! Helpers shared by the whole-program tests.
#![allow(dead_code)]

pub mod browser;
pub mod mutate;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A test that cannot run on this machine for want of what `line` names. Under CI (`CI` set:
/// `.ci/run` installs every tool) it fails. Elsewhere it writes `SKIPPED <line>` to the real
/// standard error, past the test harness's capture, so that the skip shows in `cargo test`'s
/// output even though the test passes.
pub fn skip(line: &str) {
    assert!(
        std::env::var_os("CI").is_none(),
        "{line}; CI must run this test"
    );
    use std::io::Write;
    let _ = writeln!(
        std::io::stderr().lock(),
        "\n********** SKIPPED {line} **********"
    );
}

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs the `rsasim` binary with `args` in the repository root, with extra environment.
pub fn rsasim(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_rsasim"));
    cmd.args(args).current_dir(root());
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("rsasim runs")
}

/// Runs the `rsasim` binary with `args` and panics with its stderr unless it succeeds.
pub fn rsasim_ok(args: &[&str]) -> Output {
    let o = rsasim(args, &[]);
    assert!(
        o.status.success(),
        "rsasim {args:?} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// The test scenarios (`tests/scenarios/`, `scenarios/golden/small_biplanar.toml`) use the
/// shipped model in `scenarios/models/`, outside their folder: runs allow it with `--allow-dir`.
pub const ALLOW_MODELS: [&str; 2] = ["--allow-dir", "scenarios/models"];

/// Runs a scenario into `out` (allowing [`ALLOW_MODELS`]) and panics with its stderr on failure.
pub fn run_scenario(scenario: &str, out: &Path, env: &[(&str, &str)]) {
    let o = rsasim(
        &[
            scenario,
            "--out",
            out.to_str().unwrap(),
            ALLOW_MODELS[0],
            ALLOW_MODELS[1],
        ],
        env,
    );
    assert!(
        o.status.success(),
        "rsasim {scenario} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Writes scenario `text` to `dir/<name>.toml` and runs it into `dir/out`, allowing the shipped
/// models' folders `scenarios/models` and `scenarios/golden/models` (the text names them by
/// absolute path, e.g. through `root().join("scenarios/models")`); panics with stderr on
/// failure. Returns the output folder.
pub fn run_scenario_text(dir: &Path, name: &str, text: &str) -> PathBuf {
    let scenario = dir.join(format!("{name}.toml"));
    std::fs::write(&scenario, text).unwrap();
    let out = dir.join("out");
    let (models, golden) = (
        root().join("scenarios/models"),
        root().join("scenarios/golden/models"),
    );
    rsasim_ok(&[
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--allow-dir",
        models.to_str().unwrap(),
        "--allow-dir",
        golden.to_str().unwrap(),
    ]);
    out
}

/// Every file under `dir` as (relative path with `/`, SHA-256), sorted.
pub fn hashes(dir: &Path) -> Vec<(String, String)> {
    use sha2::{Digest, Sha256};
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p
                    .strip_prefix(dir)
                    .unwrap()
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned());
                let rel = rel.collect::<Vec<_>>().join("/");
                let sha = Sha256::digest(std::fs::read(&p).unwrap());
                out.push((rel, sha.iter().map(|b| format!("{b:02x}")).collect()));
            }
        }
    }
    out.sort();
    out
}

/// Decodes a 16-bit TIFF into (width, height, pixels).
pub fn read_tiff(path: &Path) -> (u32, u32, Vec<u16>) {
    let mut dec =
        tiff::decoder::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()))
            .unwrap();
    let (w, h) = dec.dimensions().unwrap();
    match dec.read_image().unwrap() {
        tiff::decoder::DecodingResult::U16(v) => (w, h, v),
        _ => panic!("{} is not 16-bit", path.display()),
    }
}

/// Every run folder of an output folder with its `truth.json`, sorted by run id.
pub fn truths(out: &Path) -> Vec<(PathBuf, rsasim::output::Truth)> {
    let mut v: Vec<_> = std::fs::read_dir(out.join("runs"))
        .unwrap()
        .map(|e| {
            let dir = e.unwrap().path();
            let truth =
                serde_json::from_slice(&std::fs::read(dir.join("truth.json")).unwrap()).unwrap();
            (dir, truth)
        })
        .collect();
    v.sort_by(|a: &(PathBuf, rsasim::output::Truth), b| a.1.run.id.cmp(&b.1.run.id));
    v
}

/// The one report folder `rsasim evaluate` wrote into `out` by default (`report-<results>`).
pub fn report_dir(out: &Path) -> PathBuf {
    let found: Vec<PathBuf> = std::fs::read_dir(out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.is_dir()
                && p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("report-"))
        })
        .collect();
    assert_eq!(
        found.len(),
        1,
        "report folders in {}: {found:?}",
        out.display()
    );
    found.into_iter().next().unwrap()
}

/// Rewrites `out/manifest.json` as a hostile sender would: `edit` changes the manifest, then its
/// `manifest_sha256` is recomputed (the SHA-256 of the bytes with that field's value emptied, as
/// `Manifest::to_bytes` writes it), so the manifest's own check passes.
pub fn reseal_manifest(out: &Path, edit: impl FnOnce(&mut rsasim::output::Manifest)) {
    let file = out.join("manifest.json");
    let mut m: rsasim::output::Manifest =
        serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
    edit(&mut m);
    std::fs::write(&file, m.to_bytes()).unwrap();
}

/// Rehashes the files `rels` (relative to `out`, `/` separators) into `out/manifest.json` as a
/// hostile sender would after rewriting them: their SHA-256 and size, then the manifest's own
/// hash. A file the manifest does not list is added; a file that no longer exists is dropped.
pub fn rehash(out: &Path, rels: &[&str]) {
    use sha2::{Digest, Sha256};
    reseal_manifest(out, |m| {
        for rel in rels {
            let path = out.join(rel);
            m.files.retain(|f| f.path != *rel);
            if let Ok(bytes) = std::fs::read(&path) {
                let sha = Sha256::digest(&bytes);
                m.files.push(rsasim::output::ManifestFile {
                    path: rel.to_string(),
                    sha256: sha.iter().map(|b| format!("{b:02x}")).collect(),
                    bytes: bytes.len() as u64,
                });
            }
        }
        m.files.sort_by(|a, b| a.path.cmp(&b.path));
    });
}

/// Runs `scenario` into `<tmp>/out` and exports it with `rsasim export --to <to> --dir <tmp>/<to>`
/// and the `extra` options: (the temporary folder, the output, the export).
pub fn exported(scenario: &str, to: &str, extra: &[&str]) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    run_scenario(scenario, &out, &[]);
    let dest = tmp.path().join(to);
    export_ok(&out, to, &dest, extra);
    (tmp, out, dest)
}

/// `rsasim export <out> --to <to> --dir <dest>` with the `extra` options.
pub fn export(out: &Path, to: &str, dest: &Path, extra: &[&str]) -> Output {
    let args = [
        &[
            "export",
            out.to_str().unwrap(),
            "--to",
            to,
            "--dir",
            dest.to_str().unwrap(),
        ],
        extra,
    ]
    .concat();
    rsasim(&args, &[])
}

/// [`export`], which must succeed; returns its stderr (the notes).
pub fn export_ok(out: &Path, to: &str, dest: &Path, extra: &[&str]) -> String {
    let o = export(out, to, dest, extra);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    err
}

/// The detector `id` of `truth`'s run.
pub fn detector<'a>(
    truth: &'a rsasim::output::Truth,
    id: &str,
) -> &'a rsasim::expand::DetectorState {
    truth.run.detectors.iter().find(|d| d.id == id).unwrap()
}

/// Numbers of a comma-separated line.
pub fn numbers(line: &str) -> Vec<f64> {
    line.split(',').map(|v| v.trim().parse().unwrap()).collect()
}

/// A MayaCam 2.0 camera: image size (width, height), K, R, t.
pub type MayaCam = ([f64; 2], [[f64; 3]; 3], [[f64; 3]; 3], [f64; 3]);

/// MayaCam 2.0 text read as Autoscoper reads it (libautoscoper/src/Camera.cpp,
/// `Camera::loadMayaCam2`: 0-based line 1 the size, 4–6 K, 9–11 R, 14–16 t, comma-separated),
/// with the section names XMALab writes checked.
pub fn read_mayacam(text: &str) -> MayaCam {
    let l: Vec<&str> = text.lines().collect();
    assert_eq!(
        (l[0], l[3], l[8], l[13]),
        ("image size", "camera matrix", "rotation", "translation")
    );
    let m3 = |a: usize| [0, 1, 2].map(|i| <[f64; 3]>::try_from(numbers(l[a + i])).unwrap());
    let s = numbers(l[1]);
    (
        [s[0], s[1]],
        m3(4),
        m3(9),
        [0, 1, 2].map(|i| numbers(l[14 + i])[0]),
    )
}

/// Every bead of every image of `truth` with its box-frame centre and truth pixel, for the
/// beads whose centre falls on the detector.
pub fn beads(truth: &rsasim::output::Truth) -> Vec<(String, [f64; 3], [f64; 2])> {
    let mut out = Vec::new();
    for image in &truth.images {
        for m in image.markers.iter().filter(|m| m.inside) {
            let p = truth
                .run
                .phantoms
                .iter()
                .find(|p| p.id == m.phantom)
                .unwrap()
                .markers
                .iter()
                .find(|b| b.id == m.id)
                .unwrap()
                .position_mm;
            out.push((image.detector.clone(), p.to_array(), m.pixel));
        }
    }
    out
}
