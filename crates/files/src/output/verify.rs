//! `rsasim verify`: checks an output folder against its `manifest.json`.
//!
//! Every file the manifest lists must exist as a regular file with the recorded size and SHA-256;
//! the manifest's own hash ([`super::manifest`]) must match; files present but not listed are
//! reported: results of a software under test (`runs/<id>/measured*.json`) and anything outside
//! rsasim's own places (report folders, a user's notes) as "not covered by the manifest", while an
//! unlisted file inside rsasim's places (`runs/`, `phantoms/`, `scenario.toml`) is a problem.
//! A truth folder of the blind layout also binds its images folder by the SHA-256 of that
//! folder's `manifest.json`; [`verify`] checks the binding and then the images folder too.
//!
//! Files are hashed streaming (64 KiB at a time) and in parallel on the rayon pool.

use std::collections::BTreeSet;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

use rayon::prelude::*;
use sha2::{Digest, Sha256};

use super::manifest::{self, Layout, MANIFEST_FORMAT, Manifest, ManifestFile, OUTPUT_FORMAT};
use super::received::{MAX_MANIFEST_BYTES, ReceivedFolder};
use crate::scenario::hex;

/// One thing wrong with a folder: the file (relative to the folder, `/` separators) and what.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Finding {
    /// The file, relative to the folder checked.
    pub path: String,
    /// What is wrong with it.
    pub problem: String,
}

impl Finding {
    fn new(path: impl Into<String>, problem: impl Into<String>) -> Finding {
        Finding {
            path: path.into(),
            problem: problem.into(),
        }
    }
}

/// The result of checking one folder.
#[derive(Debug, Clone)]
pub struct Verification {
    /// The folder checked.
    pub folder: PathBuf,
    /// Its manifest, when it could be read.
    pub manifest: Option<Manifest>,
    /// Everything that does not verify; empty when the folder verifies.
    pub problems: Vec<Finding>,
    /// Files present but not listed, where that is expected (results of a software under test,
    /// report folders, files of others): reported, not problems.
    pub not_covered: Vec<String>,
    /// Remarks that are not problems (e.g. the images folder of a truth folder was not found).
    pub notes: Vec<String>,
    /// Number of listed files that verified.
    pub files_verified: usize,
    /// Their total size, bytes.
    pub bytes_verified: u64,
}

impl Verification {
    /// True when nothing is wrong.
    pub fn ok(&self) -> bool {
        self.problems.is_empty()
    }
}

/// Reads and parses `dir/manifest.json`, returning it with its bytes.
pub fn read_manifest(dir: &Path) -> Result<(Manifest, Vec<u8>), Finding> {
    let bytes = ReceivedFolder::unlisted(dir)
        .read("manifest.json", MAX_MANIFEST_BYTES)
        .map_err(|d| Finding::new("manifest.json", d.message))?;
    let manifest: Manifest = serde_json::from_slice(&bytes).map_err(|e| {
        Finding::new(
            "manifest.json",
            format!(
                "not a valid manifest (line {}, column {}): {e}",
                e.line(),
                e.column()
            ),
        )
    })?;
    Ok((manifest, bytes))
}

/// Checks the manifest's own integrity (its format tags and its `manifest_sha256`).
pub fn check_manifest(manifest: &Manifest, bytes: &[u8]) -> Vec<Finding> {
    let mut out = Vec::new();
    // A path listed twice would be placed twice by `merge`: the second placement over a hard
    // link to the first would truncate the shard's own file.
    let mut seen = std::collections::HashSet::with_capacity(manifest.files.len());
    if let Some(twice) = manifest
        .files
        .iter()
        .find(|f| !seen.insert(f.path.as_str()))
    {
        out.push(Finding::new(
            "manifest.json",
            format!(
                "lists {} twice: a manifest rsasim writes lists every file once",
                crate::diagnostic::cut(&twice.path)
            ),
        ));
    }
    if manifest.format != MANIFEST_FORMAT {
        out.push(Finding::new(
            "manifest.json",
            format!(
                "format is {:?}; this rsasim reads {MANIFEST_FORMAT:?}",
                manifest.format
            ),
        ));
    }
    if manifest.output_format > OUTPUT_FORMAT {
        out.push(Finding::new(
            "manifest.json",
            format!(
                "output_format {} was written by a newer rsasim (this one knows up to {OUTPUT_FORMAT})",
                manifest.output_format
            ),
        ));
    }
    match manifest::self_hash(bytes) {
        None => out.push(Finding::new(
            "manifest.json",
            "has no manifest_sha256 (written by rsasim 0.1?): its own integrity cannot be checked; regenerate the output",
        )),
        Some((recorded, recomputed)) if recorded != recomputed => out.push(Finding::new(
            "manifest.json",
            format!(
                "modified or corrupted: manifest_sha256 records {recorded}, its content hashes to {recomputed}"
            ),
        )),
        Some(_) => {}
    }
    out
}

/// A manifest path as a safe relative path (no root, no `..`), or `None`.
fn relative(path: &str) -> Option<PathBuf> {
    let p = Path::new(path);
    let ok = !path.is_empty() && p.components().all(|c| matches!(c, Component::Normal(_)));
    ok.then(|| p.to_path_buf())
}

/// SHA-256 (lowercase hex) and length of a file, read 64 KiB at a time.
pub fn sha256_file(path: &Path) -> std::io::Result<(String, u64)> {
    sha256_reader(std::fs::File::open(path)?)
}

/// SHA-256 (lowercase hex) and length of everything `file` yields, read 64 KiB at a time.
fn sha256_reader(mut file: impl Read) -> std::io::Result<(String, u64)> {
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 64 * 1024];
    let mut total = 0u64;
    loop {
        let n = file.read(&mut buf)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        total += n as u64;
    }
    Ok((hex(&hasher.finalize()), total))
}

/// Checks one listed file: present, a regular file (not a link), its size, its SHA-256.
pub fn check_file(root: &Path, entry: &ManifestFile) -> Option<Finding> {
    check_entry(root, entry, true)
}

/// [`check_file`], reading the content (the SHA-256) only when `content`.
fn check_entry(root: &Path, entry: &ManifestFile, content: bool) -> Option<Finding> {
    let bad = |what: String| Some(Finding::new(entry.path.clone(), what));
    // A path that cannot name a file of the folder is the manifest's fault, so the finding names
    // the manifest: a received manifest listing `/etc/passwd` must not make rsasim print
    // `/etc/passwd` as the file in error.
    let Some(rel) = relative(&entry.path) else {
        return Some(Finding::new(
            "manifest.json",
            format!(
                "`files[].path` {:?} is not a path inside the folder: a listed path is relative, \
                 without `.`, `..` or a leading `/`",
                crate::diagnostic::cut(&entry.path)
            ),
        ));
    };
    let Some(rel) = rel.to_str() else {
        return Some(Finding::new(
            "manifest.json",
            format!(
                "`files[].path` {:?} is not UTF-8",
                crate::diagnostic::cut(&entry.path)
            ),
        ));
    };
    let folder = ReceivedFolder::unlisted(root);
    if !folder.exists(rel) {
        return bad("missing".into());
    }
    // Opened through the gate: no link anywhere below the folder, a regular file, no blocking.
    let file = match folder.open(rel, u64::MAX) {
        Ok(f) => f,
        Err(d) => {
            return bad(format!(
                "not a regular file inside the folder: {}",
                d.message
            ));
        }
    };
    let len = file.metadata().map(|m| m.len()).unwrap_or(u64::MAX);
    if len != entry.bytes {
        return bad(format!(
            "size {len} bytes, the manifest says {} (truncated or extended)",
            entry.bytes
        ));
    }
    if !content {
        return None;
    }
    match sha256_reader(file) {
        Err(e) => bad(format!("cannot read: {e}")),
        Ok((sha, _)) if sha != entry.sha256 => bad(format!(
            "content differs from the manifest (SHA-256 {sha}, the manifest says {})",
            crate::diagnostic::cut(&entry.sha256)
        )),
        Ok(_) => None,
    }
}

/// Checks the listed files for which `wanted(path)` holds, in parallel.
pub fn check_files(
    root: &Path,
    manifest: &Manifest,
    wanted: impl Fn(&str) -> bool + Sync,
) -> (Vec<Finding>, usize, u64) {
    check_files_as(root, manifest, wanted, true)
}

/// [`check_files`], reading the contents only when `content`.
fn check_files_as(
    root: &Path,
    manifest: &Manifest,
    wanted: impl Fn(&str) -> bool + Sync,
    content: bool,
) -> (Vec<Finding>, usize, u64) {
    // What is there, seen in one walk (links not followed): a listed path that is not there, and
    // none of whose parents is a link or a file, is missing without a look-up of its own (a
    // received manifest listing 400,000 absent files cost 400,000 failing look-ups).
    let present: Option<std::collections::HashSet<String>> =
        walk(root).ok().map(|v| v.into_iter().collect());
    let missing = |path: &str| {
        present.as_ref().is_some_and(|present| {
            !present.contains(path)
                && !path
                    .match_indices('/')
                    .any(|(i, _)| present.contains(&path[..i]))
        })
    };
    let results: Vec<(Option<Finding>, u64)> = manifest
        .files
        .par_iter()
        .filter(|f| wanted(&f.path))
        .map(|f| {
            let finding = if relative(&f.path).is_some() && missing(&f.path) {
                Some(Finding::new(f.path.clone(), "missing"))
            } else {
                check_entry(root, f, content)
            };
            (finding, f.bytes)
        })
        .collect();
    let mut problems = Vec::new();
    let (mut n, mut bytes) = (0, 0);
    for (finding, b) in results {
        match finding {
            Some(f) => problems.push(f),
            None => {
                n += 1;
                bytes += b;
            }
        }
    }
    (problems, n, bytes)
}

/// Every entry under `root` that is not a folder (links are not followed), relative with `/`.
fn walk(root: &Path) -> std::io::Result<Vec<String>> {
    let mut out = Vec::new();
    let mut stack = vec![(root.to_path_buf(), String::new())];
    while let Some((dir, prefix)) = stack.pop() {
        for entry in std::fs::read_dir(&dir)? {
            let entry = entry?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let rel = if prefix.is_empty() {
                name
            } else {
                format!("{prefix}/{name}")
            };
            if entry.file_type()?.is_dir() {
                stack.push((entry.path(), rel));
            } else {
                out.push(rel);
            }
        }
    }
    out.sort();
    Ok(out)
}

/// Where an unlisted file lies: in rsasim's own places (a problem) or not (not covered).
fn expected_unlisted(rel: &str) -> bool {
    let parts: Vec<&str> = rel.split('/').collect();
    match parts.as_slice() {
        ["runs", _, name] => name.starts_with("measured") && name.ends_with(".json"),
        ["runs", ..] | ["phantoms", ..] | ["scenario.toml"] => false,
        _ => true,
    }
}

/// Checks one folder against its manifest (not following a truth folder's binding).
pub fn verify_folder(dir: &Path) -> Verification {
    verify_folder_as(dir, true)
}

fn verify_folder_as(dir: &Path, content: bool) -> Verification {
    let mut v = Verification {
        folder: dir.to_path_buf(),
        manifest: None,
        problems: Vec::new(),
        not_covered: Vec::new(),
        notes: Vec::new(),
        files_verified: 0,
        bytes_verified: 0,
    };
    if !dir.is_dir() {
        v.problems.push(Finding::new(
            "",
            "not a folder (give an rsasim output folder)",
        ));
        return v;
    }
    let (manifest, bytes) = match read_manifest(dir) {
        Ok(m) => m,
        Err(f) => {
            v.problems.push(f);
            return v;
        }
    };
    v.problems.extend(check_manifest(&manifest, &bytes));
    let (problems, n, total) = check_files_as(dir, &manifest, |_| true, content);
    v.problems.extend(problems);
    v.files_verified = n;
    v.bytes_verified = total;
    let listed: BTreeSet<&str> = manifest.files.iter().map(|f| f.path.as_str()).collect();
    match walk(dir) {
        Err(e) => v
            .problems
            .push(Finding::new("", format!("cannot list the folder: {e}"))),
        Ok(present) => {
            let mut report_dirs = BTreeSet::new();
            for rel in present {
                if rel == "manifest.json" || listed.contains(rel.as_str()) {
                    continue;
                }
                if !expected_unlisted(&rel) {
                    v.problems.push(Finding::new(
                        rel,
                        "not listed in the manifest (added to a folder rsasim wrote)",
                    ));
                } else if let Some((top, _)) = rel.split_once('/')
                    && top.starts_with("report")
                {
                    report_dirs.insert(format!("{top}/"));
                } else {
                    v.not_covered.push(rel);
                }
            }
            v.not_covered.extend(report_dirs);
            v.not_covered.sort();
        }
    }
    v.problems.sort_by(|a, b| a.path.cmp(&b.path));
    v.manifest = Some(manifest);
    v
}

/// SHA-256 of a folder's `manifest.json` file, lowercase hex.
pub fn manifest_file_sha256(dir: &Path) -> std::io::Result<String> {
    sha256_file(&dir.join("manifest.json")).map(|(sha, _)| sha)
}

/// Where a truth folder's images folder is: `images` if given, else the recorded folder name
/// beside the truth folder.
pub fn bound_images_folder(
    truth_dir: &Path,
    manifest: &Manifest,
    images: Option<&Path>,
) -> Option<PathBuf> {
    if let Some(p) = images {
        return Some(p.to_path_buf());
    }
    let binding = manifest.images.as_ref()?;
    let name = relative(&binding.folder)?;
    let parent = truth_dir
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    Some(parent.join(name))
}

/// Checks that `images` is the folder a truth manifest was written for (by the SHA-256 of its
/// manifest file). Findings name `manifest.json` of the images folder (relative to it).
pub fn check_binding(truth: &Manifest, images: &Path) -> Vec<Finding> {
    let Some(binding) = &truth.images else {
        return vec![Finding::new(
            "manifest.json",
            "a truth folder's manifest must name its images folder (the `images` field)",
        )];
    };
    match manifest_file_sha256(images) {
        Err(e) => vec![Finding::new("manifest.json", format!("cannot read: {e}"))],
        Ok(sha) if sha != binding.manifest_sha256 => vec![Finding::new(
            "manifest.json",
            format!(
                "is not the images folder this truth was written for (its SHA-256 is {sha}, the truth folder binds {})",
                binding.manifest_sha256
            ),
        )],
        Ok(_) => Vec::new(),
    }
}

/// `rsasim verify DIR [--images IMAGES]`: checks `dir`; for a truth folder also the binding to
/// its images folder (given, or found beside it) and that folder itself.
pub fn verify(dir: &Path, images: Option<&Path>) -> Vec<Verification> {
    let mut first = verify_folder(dir);
    let is_truth = first
        .manifest
        .as_ref()
        .is_some_and(|m| m.layout == Some(Layout::Truth));
    if !is_truth {
        if images.is_some() {
            first
                .notes
                .push("--images applies to a truth folder only; this folder is not one".into());
        }
        return vec![first];
    }
    let manifest = first.manifest.clone().expect("checked above");
    let Some(images_dir) = bound_images_folder(dir, &manifest, images) else {
        first.problems.push(Finding::new(
            "manifest.json",
            "a truth folder's manifest must name its images folder (field `images`, a plain folder name)",
        ));
        return vec![first];
    };
    if images.is_none() && !images_dir.join("manifest.json").exists() {
        first.notes.push(format!(
            "its images folder {} was not found: the binding was not checked (pass --images DIR)",
            images_dir.display()
        ));
        return vec![first];
    }
    let mut second = verify_folder(&images_dir);
    second
        .problems
        .extend(check_binding(&manifest, &images_dir));
    vec![first, second]
}

/// Most problems listed per folder (a forged manifest can list millions of missing files); the
/// rest are counted.
pub const MAX_PROBLEMS_SHOWN: usize = 100;

/// The text `rsasim verify` prints: one line per problem (`<folder>/<file>: <what>`; at most
/// [`MAX_PROBLEMS_SHOWN`] per folder, the rest counted), one per file not covered, the notes, and
/// a summary line per folder.
pub fn render(results: &[Verification]) -> String {
    let mut out = String::new();
    for v in results {
        let name = |path: &str| {
            if path.is_empty() {
                v.folder.display().to_string()
            } else {
                v.folder.join(path).display().to_string()
            }
        };
        for f in v.problems.iter().take(MAX_PROBLEMS_SHOWN) {
            out += &format!("{}: {}\n", name(&f.path), f.problem);
        }
        if v.problems.len() > MAX_PROBLEMS_SHOWN {
            out += &format!(
                "{}: {} more problem(s) not shown\n",
                v.folder.display(),
                v.problems.len() - MAX_PROBLEMS_SHOWN
            );
        }
        for path in &v.not_covered {
            out += &format!("{}: not covered by the manifest\n", name(path));
        }
        for note in &v.notes {
            out += &format!("{}: note: {note}\n", v.folder.display());
        }
        let what = match v.manifest.as_ref().and_then(|m| m.layout) {
            Some(Layout::Images) => "blind images folder",
            Some(Layout::Truth) => "truth folder",
            None => "output folder",
        };
        out += &format!(
            "rsasim verify: {} ({what}): {} file(s), {:.1} MB verified; {} problem(s); {} not covered by the manifest -> {}\n",
            v.folder.display(),
            v.files_verified,
            v.bytes_verified as f64 / 1e6,
            v.problems.len(),
            v.not_covered.len(),
            if v.ok() { "VERIFIED" } else { "NOT VERIFIED" }
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manifest_paths_must_stay_inside_the_folder() {
        assert!(relative("runs/a/truth.json").is_some());
        for bad in ["", "/etc/passwd", "../x", "runs/../../x", "./x"] {
            assert!(relative(bad).is_none(), "{bad}");
        }
    }

    #[test]
    fn a_listed_path_outside_the_folder_is_the_manifests_fault() {
        let dir = tempfile::tempdir().unwrap();
        for path in ["/etc/passwd", "../victim", "runs/../../x"] {
            let entry = ManifestFile {
                path: path.into(),
                bytes: 0,
                sha256: String::new(),
            };
            let finding = check_file(dir.path(), &entry).expect("a finding");
            assert_eq!(finding.path, "manifest.json", "{path}");
            assert!(
                finding.problem.contains("`files[].path`") && finding.problem.contains(path),
                "{}",
                finding.problem
            );
        }
    }

    #[test]
    fn unlisted_files_are_problems_only_in_rsasims_places() {
        assert!(expected_unlisted("runs/n0-r00/measured.json"));
        assert!(expected_unlisted("runs/n0-r00/measured-rsasim-dlt.json"));
        assert!(expected_unlisted("report/report.md"));
        assert!(expected_unlisted("notes.txt"));
        assert!(!expected_unlisted("runs/n0-r00/extra.tiff"));
        assert!(!expected_unlisted("runs/n0-r00/sub/measured.json"));
        assert!(!expected_unlisted("phantoms/x.csv"));
        assert!(!expected_unlisted("scenario.toml"));
    }

    #[test]
    fn streamed_hash_matches_the_one_shot_hash() {
        let dir = tempfile::tempdir().unwrap();
        let bytes: Vec<u8> = (0..200_000u32).map(|i| (i * 7) as u8).collect();
        let file = dir.path().join("f");
        std::fs::write(&file, &bytes).unwrap();
        assert_eq!(
            sha256_file(&file).unwrap(),
            (hex(&Sha256::digest(&bytes)), bytes.len() as u64)
        );
    }
}
