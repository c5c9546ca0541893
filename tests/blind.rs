//! The blind layout: `rsasim SCENARIO --out IMAGES --truth-dir TRUTH` gives the software under
//! test a folder without truth or seed; `reconstruct` works on it and `evaluate --truth` scores
//! across both folders exactly as the ordinary layout does.

use crate::common;

use std::path::{Path, PathBuf};

use common::{hashes, rsasim};
use rsasim::evaluate::stats::{Confidence, Sided};
use rsasim::evaluate::{MeasuredSource, Options, evaluate, evaluate_with_truth};

const SCENARIO: &str = "scenarios/golden/small_biplanar.toml";

fn ok(args: &[&str]) {
    let o = rsasim(args, &[]);
    assert!(
        o.status.success(),
        "rsasim {args:?} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Writes the blind layout into `tmp/images` + `tmp/truth`.
fn blind(tmp: &Path) -> (PathBuf, PathBuf) {
    let (images, truth) = (tmp.join("images"), tmp.join("truth"));
    ok(&[SCENARIO, "--out", s(&images), "--truth-dir", s(&truth)]);
    (images, truth)
}

fn options() -> Options {
    Options {
        measured: MeasuredSource::Auto,
        confidence: Confidence {
            level: 0.95,
            sided: Sided::One,
        },
        mtpm_threshold_mm: rsasim::evaluate::DEFAULT_MTPM_THRESHOLD_MM,
        study: Default::default(),
        xmalab_2d: Default::default(),
        source_truth: Default::default(),
    }
}

#[test]
fn the_images_folder_holds_no_truth_and_no_seed() {
    let tmp = tempfile::tempdir().unwrap();
    let (images, truth) = blind(tmp.path());
    let ordinary = tmp.path().join("ordinary");
    ok(&[SCENARIO, "--out", s(&ordinary)]);
    let files = hashes(&images);
    assert!(files.iter().any(|(p, _)| p.ends_with(".tiff")));
    for (path, _) in &files {
        assert!(!path.ends_with("truth.json"), "{path}");
        let bytes = std::fs::read(images.join(path)).unwrap();
        let text = String::from_utf8_lossy(&bytes).to_lowercase();
        assert!(!text.contains("seed"), "{path} names the seed");
        assert!(!text.contains("randomize"), "{path} holds random ranges");
    }
    // The images are the very bytes of the ordinary layout (their metadata holds no truth).
    let ordinary_files = hashes(&ordinary);
    for (path, sha) in files.iter().filter(|(p, _)| p.starts_with("runs/")) {
        assert!(
            ordinary_files.contains(&(path.clone(), sha.clone())),
            "{path}"
        );
    }
    // The truth folder holds every truth.json and the scenario with its seed.
    let truth_files = hashes(&truth);
    let n_truth = truth_files
        .iter()
        .filter(|(p, _)| p.ends_with("/truth.json"))
        .count();
    assert_eq!(n_truth, 4);
    let scenario = std::fs::read_to_string(truth.join("scenario.toml")).unwrap();
    assert!(scenario.contains("seed = 42"), "{scenario}");
    // Both verify, the images folder through the truth folder's binding.
    let o = rsasim(&["verify", s(&truth)], &[]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains("blind images folder") && text.contains("truth folder"),
        "{text}"
    );
}

#[test]
fn reconstruct_and_evaluate_across_the_two_folders_give_the_ordinary_report() {
    let tmp = tempfile::tempdir().unwrap();
    let (images, truth) = blind(tmp.path());
    let ordinary = tmp.path().join("ordinary");
    ok(&[SCENARIO, "--out", s(&ordinary)]);
    ok(&["reconstruct", s(&images)]);
    ok(&["reconstruct", s(&ordinary)]);
    let a = evaluate(&ordinary, &options()).unwrap();
    let b = evaluate_with_truth(&images, Some(&truth), &options()).unwrap();
    assert!(b.runs_scored > 0);
    assert_eq!(a.tables, b.tables);
    assert_eq!(a.mtpm, b.mtpm);
    assert_eq!(a.group_analyses, b.group_analyses);
    assert_eq!((a.runs_scored, &a.excluded), (b.runs_scored, &b.excluded));
    // The command too.
    ok(&["evaluate", s(&images), "--truth", s(&truth)]);
    // Without the truth folder the images folder cannot be scored, and says why.
    let o = rsasim(&["evaluate", s(&images)], &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--truth"));
}

#[test]
fn an_edited_images_manifest_breaks_the_binding() {
    let tmp = tempfile::tempdir().unwrap();
    let (images, truth) = blind(tmp.path());
    ok(&["reconstruct", s(&images)]);
    ok(&["evaluate", s(&images), "--truth", s(&truth)]);
    let file = images.join("manifest.json");
    let original = std::fs::read(&file).unwrap();
    // An accidental edit: the manifest's own hash no longer matches.
    let text = String::from_utf8(original.clone()).unwrap();
    std::fs::write(&file, text.replacen("\"runs\": 4", "\"runs\": 3", 1)).unwrap();
    let o = rsasim(&["evaluate", s(&images), "--truth", s(&truth)], &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains(&file.display().to_string()));
    // A deliberate edit with the manifest's own hash recomputed: the binding still catches it.
    let mut m: rsasim::output::Manifest = serde_json::from_slice(&original).unwrap();
    m.files.pop();
    std::fs::write(&file, m.to_bytes()).unwrap();
    let o = rsasim(&["evaluate", s(&images), "--truth", s(&truth)], &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("is not the images folder this truth was written for"),
        "{err}"
    );
    let o = rsasim(&["verify", s(&truth)], &[]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(2), "{text}");
    assert!(
        text.contains(&format!(
            "{}: is not the images folder this truth was written for",
            file.display()
        )),
        "{text}"
    );
}

#[test]
fn a_moved_images_folder_is_given_with_images_and_a_truth_inside_it_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let (images, truth) = blind(tmp.path());
    let moved = tmp.path().join("elsewhere");
    std::fs::rename(&images, &moved).unwrap();
    let o = rsasim(&["verify", s(&truth)], &[]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && text.contains("--images"), "{text}");
    let o = rsasim(&["verify", s(&truth), "--images", s(&moved)], &[]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && text.contains("blind images folder"),
        "{text}"
    );

    let out = tmp.path().join("again");
    let inside = out.join("truth");
    let o = rsasim(
        &[SCENARIO, "--out", s(&out), "--truth-dir", s(&inside)],
        &[],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("outside the images folder"));
    assert!(!out.exists() && !inside.exists());
}

/// `export IMAGES --truth TRUTH` writes, file for file, the export of the ordinary layout of the
/// same scenario (cameras from the truth folder, images from the images folder); the images
/// folder alone is refused with exit 2, nothing written, pointing at --truth.
#[test]
fn a_blind_layout_exports_as_the_ordinary_one() {
    let tmp = tempfile::tempdir().unwrap();
    let (images, truth) = blind(tmp.path());
    let ordinary = tmp.path().join("ordinary");
    ok(&[SCENARIO, "--out", s(&ordinary)]);
    for to in ["xmalab", "autoscoper"] {
        let (from_blind, from_ordinary) = (
            tmp.path().join(format!("{to}-blind")),
            tmp.path().join(format!("{to}-ordinary")),
        );
        ok(&[
            "export",
            s(&images),
            "--truth",
            s(&truth),
            "--to",
            to,
            "--dir",
            s(&from_blind),
        ]);
        ok(&[
            "export",
            s(&ordinary),
            "--to",
            to,
            "--dir",
            s(&from_ordinary),
        ]);
        let (a, b) = (hashes(&from_blind), hashes(&from_ordinary));
        // Everything but the README (which names the folder it was exported from).
        let strip = |h: Vec<(String, String)>| -> Vec<(String, String)> {
            h.into_iter().filter(|(p, _)| p != "README.md").collect()
        };
        assert_eq!(strip(a), strip(b), "{to}");
    }
    let refused = tmp.path().join("refused");
    let o = rsasim(
        &["export", s(&images), "--to", "xmalab", "--dir", s(&refused)],
        &[],
    );
    assert_eq!(o.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("--truth"), "{stderr}");
    assert!(!refused.exists());
}
