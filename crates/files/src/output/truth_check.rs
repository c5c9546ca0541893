//! Before scoring, `evaluate` checks that the truth it reads is the truth rsasim wrote: every
//! `runs/<id>/truth.json` and the `scenario.toml` it relies on must be listed in the folder's
//! `manifest.json` with the same size and SHA-256, no listed truth may be missing, and the
//! manifest's own hash must match. In the blind layout the truth folder must also be bound to the
//! images folder holding the results (the SHA-256 of that folder's manifest file), and that
//! manifest must be intact too. Images are not hashed here (`rsasim verify` does that).

use std::path::Path;

use crate::diagnostic::Diagnostic;
use crate::output::verify::{self, Finding};
use crate::output::{Layout, Manifest};

/// True for the files the truth consists of: `scenario.toml` and `runs/<id>/truth.json`.
fn is_truth_file(path: &str) -> bool {
    let parts: Vec<&str> = path.split('/').collect();
    matches!(
        parts.as_slice(),
        ["scenario.toml"] | ["runs", _, "truth.json"]
    )
}

fn diagnostic(dir: &Path, f: Finding) -> Diagnostic {
    Diagnostic::file_error(&dir.join(&f.path), f.problem).with_help(
        "the truth no longer matches the manifest rsasim wrote: regenerate the output (`rsasim SCENARIO.toml --force`), or restore the file; `rsasim verify` checks the whole folder",
    )
}

/// Reads `dir/manifest.json` and checks its own integrity.
fn intact_manifest(dir: &Path) -> Result<(Manifest, Vec<u8>), Vec<Diagnostic>> {
    let (manifest, bytes) = verify::read_manifest(dir).map_err(|f| vec![diagnostic(dir, f)])?;
    let problems = verify::check_manifest(&manifest, &bytes);
    if !problems.is_empty() {
        return Err(problems.into_iter().map(|f| diagnostic(dir, f)).collect());
    }
    Ok((manifest, bytes))
}

/// Checks the truth of `truth_dir` against its manifest (see the module documentation). With
/// `images_dir` (blind layout) `truth_dir` must be a truth folder bound to `images_dir`; without,
/// `truth_dir` must be an ordinary output folder (not a blind one). Returns the manifest.
pub fn verify_truth(
    truth_dir: &Path,
    images_dir: Option<&Path>,
) -> Result<Manifest, Vec<Diagnostic>> {
    let (manifest, _) = intact_manifest(truth_dir)?;
    match (images_dir, manifest.layout) {
        (None, Some(Layout::Images)) => {
            return Err(vec![Diagnostic::file_error(
                truth_dir,
                "this is the images folder of a blind layout: its truth is kept in a separate folder",
            )
            .with_help("pass the truth folder: rsasim evaluate OUT --truth TRUTH_DIR")]);
        }
        (None, Some(Layout::Truth)) => {
            return Err(vec![Diagnostic::file_error(
                truth_dir,
                "this is the truth folder of a blind layout, not the folder holding the results",
            )
            .with_help("rsasim evaluate IMAGES_DIR --truth TRUTH_DIR")]);
        }
        (Some(_), layout) if layout != Some(Layout::Truth) => {
            return Err(vec![
                Diagnostic::file_error(
                    &truth_dir.join("manifest.json"),
                    "--truth names a folder that is not the truth folder of a blind layout",
                )
                .with_help("give the folder written by `rsasim SCENARIO.toml --truth-dir DIR`"),
            ]);
        }
        _ => {}
    }
    if let Some(images) = images_dir {
        let (images_manifest, _) = intact_manifest(images)?;
        if images_manifest.layout != Some(Layout::Images) {
            return Err(vec![Diagnostic::file_error(
                &images.join("manifest.json"),
                "not the images folder of a blind layout",
            )]);
        }
        let binding = verify::check_binding(&manifest, images);
        if !binding.is_empty() {
            return Err(binding
                .into_iter()
                .map(|f| {
                    Diagnostic::file_error(&images.join(&f.path), f.problem).with_help(
                        "evaluate the images folder together with the truth folder written in the same run",
                    )
                })
                .collect());
        }
    }
    let (mut problems, _, _) = verify::check_files(truth_dir, &manifest, is_truth_file);
    if !manifest.files.iter().any(|f| f.path == "scenario.toml") {
        problems.push(Finding {
            path: "scenario.toml".into(),
            problem: "not listed in the manifest".into(),
        });
    }
    if let Ok(entries) = std::fs::read_dir(truth_dir.join("runs")) {
        for entry in entries.flatten() {
            let rel = format!("runs/{}/truth.json", entry.file_name().to_string_lossy());
            let listed = manifest.files.iter().any(|f| f.path == rel);
            if !listed && truth_dir.join(&rel).exists() {
                problems.push(Finding {
                    path: rel,
                    problem: "not listed in the manifest (a truth rsasim did not write)".into(),
                });
            }
        }
    }
    if problems.is_empty() {
        Ok(manifest)
    } else {
        problems.sort_by(|a, b| a.path.cmp(&b.path));
        Err(problems
            .into_iter()
            .map(|f| diagnostic(truth_dir, f))
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_truth_is_the_scenario_and_every_truth_json() {
        assert!(is_truth_file("scenario.toml"));
        assert!(is_truth_file("runs/n0-r00/truth.json"));
        assert!(!is_truth_file("runs/n0-r00/det1.tiff"));
        assert!(!is_truth_file("runs/truth.json"));
        assert!(!is_truth_file("phantoms/box.csv"));
    }
}
