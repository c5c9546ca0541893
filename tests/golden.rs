//! Golden outputs: the small golden scenarios regenerate byte for byte, on any thread count.
//!
//! Every file is compared byte for byte, except `manifest.json`, whose build fields (`commit`,
//! `dirty`) and self-hash change with every commit: it is compared with those normalised.
//!
//! The rule "output bytes changed ⇒ crate version bumped": `golden/VERSION` records the crate
//! version the hashes were blessed at. Hashes that differ at the same version fail the test, and
//! blessing them is refused until `version` in Cargo.toml is raised.
//!
//! To bless new hashes after a deliberate change (and a version bump):
//! `RSASIM_BLESS=1 cargo test --test integration golden::`, and say why in the commit message.

use crate::common;

use std::path::Path;

use common::{hashes, root, run_scenario};

const GOLDEN: &[&str] = &[
    "small_biplanar",
    "small_uniplanar",
    "small_attenuation",
    "small_sampled",
    "small_unsharp",
    "small_sequence",
];

/// The crate version the golden hashes were blessed at.
const VERSION_FILE: &str = "VERSION";

/// SHA-256 of a manifest with `build.commit`, `build.dirty` and `manifest_sha256` normalised.
fn normalised_manifest_sha256(file: &Path) -> String {
    use sha2::{Digest, Sha256};
    let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(file).unwrap()).unwrap();
    v["manifest_sha256"] = "".into();
    let build = v.get_mut("build").expect("the manifest records the build");
    build["commit"] = "(normalised)".into();
    build["dirty"] = "(normalised)".into();
    let mut bytes = serde_json::to_vec_pretty(&v).unwrap();
    bytes.push(b'\n');
    Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The golden lines of an output folder: `<sha256>  <path>`, the manifest normalised.
fn golden_lines(out: &Path) -> String {
    hashes(out)
        .into_iter()
        .map(|(p, h)| {
            let h = if p == "manifest.json" {
                normalised_manifest_sha256(&out.join(&p))
            } else {
                h
            };
            format!("{h}  {p}\n")
        })
        .collect()
}

/// Which lines of `got` are not in `want`, and whether the line counts match.
fn differing<'a>(want: &str, got: &'a str) -> (Vec<&'a str>, bool) {
    let want_lines: Vec<&str> = want.lines().collect();
    let got_lines: Vec<&str> = got.lines().collect();
    let diff: Vec<&str> = got_lines
        .iter()
        .filter(|l| !want_lines.contains(l))
        .copied()
        .collect();
    (diff, want_lines.len() == got_lines.len())
}

#[test]
fn golden_scenarios_reproduce_their_hashes() {
    let version = env!("CARGO_PKG_VERSION");
    let dir = root().join("golden");
    let blessed_at = std::fs::read_to_string(dir.join(VERSION_FILE))
        .ok()
        .map(|v| v.trim().to_string());
    let bless = std::env::var_os("RSASIM_BLESS").is_some();
    let mut changed = Vec::new();
    let mut got_all = Vec::new();
    for name in GOLDEN {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join(name);
        run_scenario(&format!("scenarios/golden/{name}.toml"), &out, &[]);
        let got = golden_lines(&out);
        let file = dir.join(format!("{name}.sha256"));
        match std::fs::read_to_string(&file) {
            Ok(want) => {
                let (diff, same_count) = differing(&want, &got);
                if !diff.is_empty() || !same_count {
                    changed.push(format!(
                        "{name}: {} of {} lines differ from golden/{name}.sha256 (first: {:?})",
                        diff.len(),
                        got.lines().count(),
                        diff.first()
                    ));
                }
            }
            Err(_) if !bless => panic!(
                "{} is missing: bless it with RSASIM_BLESS=1",
                file.display()
            ),
            Err(_) => {}
        }
        got_all.push((file, got));
    }
    let same_version = blessed_at.as_deref() == Some(version);
    if bless {
        assert!(
            changed.is_empty() || !same_version,
            "refusing to bless: output bytes changed but the crate version is still {version}, \
             the version the golden hashes were blessed at. Raise `version` in Cargo.toml \
             (output bytes changed ⇒ version bumped), then bless again.\n{}",
            changed.join("\n")
        );
        for (file, got) in got_all {
            std::fs::write(file, got).unwrap();
        }
        std::fs::write(dir.join(VERSION_FILE), format!("{version}\n")).unwrap();
        return;
    }
    assert!(
        changed.is_empty() || !same_version,
        "output bytes changed at the same crate version {version}: a change of output bytes needs \
         a version bump (Cargo.toml), then `RSASIM_BLESS=1 cargo test --test integration golden::`.\n{}",
        changed.join("\n")
    );
    assert!(
        same_version && changed.is_empty(),
        "the golden hashes were blessed at version {}, the crate is {version}: re-bless with \
         `RSASIM_BLESS=1 cargo test --test integration golden::` and say why in the commit message.\n{}",
        blessed_at
            .as_deref()
            .unwrap_or("(none: golden/VERSION is missing)"),
        changed.join("\n")
    );
}

#[test]
fn outputs_are_identical_on_one_and_two_threads() {
    for name in [
        "small_biplanar",
        "small_attenuation",
        "small_sampled",
        "small_unsharp",
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let (a, b) = (tmp.path().join("t1"), tmp.path().join("t2"));
        let scenario = format!("scenarios/golden/{name}.toml");
        run_scenario(&scenario, &a, &[("RAYON_NUM_THREADS", "1")]);
        run_scenario(&scenario, &b, &[("RAYON_NUM_THREADS", "2")]);
        let (ha, hb) = (hashes(&a), hashes(&b));
        assert!(ha.len() > 20, "{name}");
        assert_eq!(ha, hb, "{name}");
    }
}

#[test]
fn shipped_scenarios_carry_the_generated_knee_beads() {
    let beads = rsasim::phantom::femoral::femoral_component().beads;
    for file in ["scenarios/biplanar.toml", "scenarios/uniplanar.toml"] {
        let loaded =
            rsasim::scenario::load(&root().join(file)).unwrap_or_else(|e| panic!("{file}: {e:?}"));
        let femur = loaded
            .scenario
            .phantoms
            .iter()
            .find(|p| p.id == "femur")
            .unwrap();
        let listed = &femur.mesh.as_ref().unwrap().beads;
        assert_eq!(listed.len(), beads.len(), "{file}");
        for (a, b) in listed.iter().zip(&beads) {
            assert_eq!(
                (a.id.as_str(), a.position_mm, a.diameter_mm),
                (b.id.as_str(), b.position_mm, b.diameter_mm),
                "{file}"
            );
        }
    }
}
