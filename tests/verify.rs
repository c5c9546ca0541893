//! `rsasim verify` and the truth check of `rsasim evaluate`: every file against the manifest,
//! the manifest's own hash, files added, and the build recorded in the manifest and `--version`.

use crate::common;

use std::path::{Path, PathBuf};

use common::{rsasim, run_scenario};

/// A fresh output of the small biplanar golden scenario.
fn output() -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    run_scenario("scenarios/golden/small_biplanar.toml", &out, &[]);
    (tmp, out)
}

/// `rsasim verify OUT`: exit code and stdout.
fn verify(out: &Path) -> (i32, String) {
    let o = rsasim(&["verify", out.to_str().unwrap()], &[]);
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
    )
}

/// `rsasim evaluate OUT`: exit code and stderr.
fn evaluate(out: &Path) -> (i32, String) {
    let o = rsasim(&["evaluate", out.to_str().unwrap()], &[]);
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Asserts that verify fails with exit 2 and a line naming `file` and saying `what`.
fn assert_problem(out: &Path, file: &str, what: &str) {
    let (code, text) = verify(out);
    assert_eq!(code, 2, "{text}");
    let named = out.join(file).display().to_string();
    assert!(
        text.lines()
            .any(|l| l.starts_with(&format!("{named}: ")) && l.contains(what)),
        "no line names {named} with {what:?}:\n{text}"
    );
    assert!(text.contains("NOT VERIFIED"), "{text}");
}

#[test]
fn a_clean_output_verifies_and_results_and_reports_are_not_covered() {
    let (_tmp, out) = output();
    let (code, text) = verify(&out);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("0 problem(s)") && text.contains("VERIFIED"),
        "{text}"
    );
    // What a software under test and the report add is reported, not a problem.
    std::fs::write(out.join("runs/n0-r00/measured.json"), "{}").unwrap();
    std::fs::create_dir(out.join("report")).unwrap();
    std::fs::write(out.join("report/report.md"), "x").unwrap();
    let (code, text) = verify(&out);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("runs/n0-r00/measured.json: not covered by the manifest"),
        "{text}"
    );
    assert!(
        text.contains("report/: not covered by the manifest"),
        "{text}"
    );
}

#[test]
fn a_flipped_byte_in_an_image_is_found() {
    let (_tmp, out) = output();
    let file = out.join("runs/n1-r01/model-det2.tiff");
    let mut bytes = std::fs::read(&file).unwrap();
    let k = bytes.len() / 2;
    bytes[k] ^= 0x01;
    std::fs::write(&file, bytes).unwrap();
    assert_problem(&out, "runs/n1-r01/model-det2.tiff", "content differs");
}

#[test]
fn a_truncated_file_is_found() {
    let (_tmp, out) = output();
    let file = out.join("runs/n0-r00/calibration-det1.exr");
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() - 100]).unwrap();
    assert_problem(&out, "runs/n0-r00/calibration-det1.exr", "truncated");
}

#[test]
fn a_missing_file_is_found() {
    let (_tmp, out) = output();
    std::fs::remove_file(out.join("phantoms/box.csv")).unwrap();
    assert_problem(&out, "phantoms/box.csv", "missing");
}

#[test]
fn an_extra_file_in_rsasims_places_is_found() {
    let (_tmp, out) = output();
    std::fs::write(out.join("runs/n0-r01/extra-det1.tiff"), "not ours").unwrap();
    assert_problem(&out, "runs/n0-r01/extra-det1.tiff", "not listed");
    let (_tmp2, out2) = output();
    std::fs::write(out2.join("phantoms/other.csv"), "id\n").unwrap();
    assert_problem(&out2, "phantoms/other.csv", "not listed");
}

#[test]
fn an_edited_manifest_is_found() {
    let (_tmp, out) = output();
    let file = out.join("manifest.json");
    let text = std::fs::read_to_string(&file).unwrap();
    // A changed size that matches an edited file would hide the edit: the manifest's own hash
    // catches it.
    let edited = text.replacen("\"runs\": 4", "\"runs\": 5", 1);
    assert_ne!(text, edited);
    std::fs::write(&file, edited).unwrap();
    assert_problem(&out, "manifest.json", "modified or corrupted");
    std::fs::write(&file, "{ not json").unwrap();
    assert_problem(&out, "manifest.json", "not a valid manifest");
}

#[test]
fn evaluate_refuses_a_truth_edited_by_half_a_millimetre() {
    let (_tmp, out) = output();
    // With results present, so that only the truth check can refuse.
    let o = rsasim(&["reconstruct", out.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let file = out.join("runs/n1-r00/truth.json");
    let mut truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
    let x = &mut truth["phantoms"][1]["position_mm"][0];
    *x = (x.as_f64().unwrap() + 0.5).into();
    std::fs::write(&file, serde_json::to_vec_pretty(&truth).unwrap()).unwrap();
    let (code, err) = evaluate(&out);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains(&format!("{}: ", file.display())) && err.contains("the manifest"),
        "{err}"
    );
}

#[test]
fn evaluate_refuses_a_missing_truth_and_an_edited_scenario() {
    let (_tmp, out) = output();
    let truth = out.join("runs/n0-r01/truth.json");
    std::fs::remove_file(&truth).unwrap();
    let (code, err) = evaluate(&out);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains(&format!("{}: missing", truth.display())),
        "{err}"
    );

    let (_tmp2, out2) = output();
    let scenario = out2.join("scenario.toml");
    let text = std::fs::read_to_string(&scenario).unwrap();
    std::fs::write(&scenario, text + "\n").unwrap();
    let (code, err) = evaluate(&out2);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains(&scenario.display().to_string()), "{err}");
}

#[test]
fn evaluate_states_that_the_truth_was_verified() {
    let (_tmp, out) = output();
    let o = rsasim(&["reconstruct", out.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (code, err) = evaluate(&out);
    assert_eq!(code, 0, "{err}");
    // The report folder is named after the results file reconstruct wrote.
    let report = common::report_dir(&out);
    let md = std::fs::read_to_string(report.join("report.md")).unwrap();
    assert!(md.contains("verified against it"), "{md}");
}

#[test]
fn the_manifest_and_version_name_the_build() {
    let build = rsasim::build_info::build();
    let (_tmp, out) = output();
    let manifest: rsasim::output::Manifest =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest.build.as_ref(), Some(&build));
    assert_eq!(manifest.output_format, rsasim::output::OUTPUT_FORMAT);
    assert_eq!(build.version, env!("CARGO_PKG_VERSION"));
    let o = rsasim(&["--version"], &[]);
    let line = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        line.starts_with(&format!("rsasim {} (", env!("CARGO_PKG_VERSION"))),
        "{line}"
    );
    let in_git = std::process::Command::new("git")
        .args(["rev-parse", "HEAD"])
        .current_dir(common::root())
        .output()
        .is_ok_and(|o| o.status.success());
    if in_git {
        // Built from a checkout: the commit is recorded and shown.
        assert_eq!(build.commit.len(), 40, "{build:?}");
        assert!(build.commit.bytes().all(|b| b.is_ascii_hexdigit()));
        assert!(line.contains(&build.commit[..7]), "{line}");
    }
    // Images and truth carry only the version, so their bytes do not change with the commit.
    let truth = std::fs::read_to_string(out.join("runs/n0-r00/truth.json")).unwrap();
    assert!(!truth.contains(&build.commit));
}
