//! `rsasim merge`: the shard folders of one scenario ([`crate::shard`]) joined into the output
//! folder a single run writes, byte for byte, `manifest.json` included.
//!
//! 1. [`check`] reads every shard's manifest without reading the images: its own hash, every
//!    listed file present with its size, nothing added in rsasim's places; the same program,
//!    build, scenario (SHA-256), seed, output format and number of shards N in all; every index
//!    0 … N − 1 exactly once, each holding exactly the runs the split gives it; the shared files
//!    (`README.md`, `scenario.toml`, `phantoms/`) identical in all. Any problem: errors (exit 2),
//!    nothing written; a missing shard is named with the ids of the runs it holds.
//! 2. [`claim`] claims the merged folder like a run's output (lock, `--force` rules); a shard
//!    folder is never replaced and never written into.
//! 3. [`assemble`] places every file into the staging folder, hard-linked (or copied where a link
//!    is impossible, or with `copy`), then hashes the placed file: a file whose SHA-256 differs
//!    from its shard's manifest stops the merge (exit 2) before anything is swapped in. Each file
//!    is read once. Then the merged manifest: the shards' program and build, every file sorted
//!    by path, the protocol's run count, no shard record — the manifest a single run writes.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::atomic::write_staged;
use super::commit::{FolderKind, OutputTarget};
use super::manifest::{Manifest, ManifestFile, ShardRecord};
use super::verify::{sha256_file, verify_folder};
use crate::diagnostic::Diagnostic;
use crate::shard::{ShardSpec, runs_of_shard};

/// The checked shards of one scenario, ready to be assembled.
#[derive(Debug)]
pub struct Shards {
    /// The merged folder's manifest (its self-hash is filled in when written).
    manifest: Manifest,
    /// Every file of the merged folder with the shard file it comes from.
    sources: Vec<(ManifestFile, PathBuf)>,
    /// The shard folders as given, in shard order.
    dirs: Vec<PathBuf>,
    /// Files in the shards that no manifest lists and that are not merged (a software's
    /// results, report folders), for the user.
    pub not_merged: Vec<String>,
}

impl Shards {
    /// Number of shards N.
    pub fn count(&self) -> usize {
        self.dirs.len()
    }

    /// The shard folders as given, in shard order.
    pub fn dirs(&self) -> &[PathBuf] {
        &self.dirs
    }

    /// The SHA-256 of the scenario the shards were written from.
    pub fn scenario_sha256(&self) -> Option<&str> {
        self.manifest.scenario_sha256.as_deref()
    }

    /// Number of runs of the merged folder.
    pub fn runs(&self) -> usize {
        self.manifest.runs
    }
}

/// Why a merge stopped.
#[derive(Debug)]
pub enum Error {
    /// A shard is wrong (changed since written): exit 2; nothing was replaced.
    Input(Vec<Diagnostic>),
    /// Writing the merged folder failed: exit 1; nothing was replaced.
    Write(std::io::Error),
}

/// What a merge did.
#[derive(Debug)]
pub struct Summary {
    /// The merged folder.
    pub out_dir: PathBuf,
    /// Files hard-linked from the shards.
    pub linked: usize,
    /// Files copied.
    pub copied: usize,
    /// Their total size, bytes.
    pub bytes: u64,
    /// What the commit wants the user to know.
    pub notes: Vec<String>,
}

/// One read shard folder.
struct Shard {
    dir: PathBuf,
    manifest: Manifest,
    record: ShardRecord,
}

fn error(path: &Path, message: impl Into<String>, help: impl Into<String>) -> Diagnostic {
    Diagnostic::file_error(path, message).with_help(help)
}

/// At most `limit` items joined by ", ", then "… and N more".
fn listed(items: &[String], limit: usize) -> String {
    let mut text = items
        .iter()
        .take(limit)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    if items.len() > limit {
        text += &format!(" … and {} more", items.len() - limit);
    }
    text
}

/// Reads one shard folder: its manifest and every file it lists verified, and its shard record.
fn read_shard(dir: &Path, not_merged: &mut Vec<String>) -> Result<Shard, Vec<Diagnostic>> {
    // Every file hashed here, before the merged folder is claimed, so that a changed file is an
    // error (exit 2) with nothing written, not even a lock; assembling hashes each placed file
    // again, which catches a file changed in between.
    let v = verify_folder(dir);
    if !v.ok() {
        return Err(v
            .problems
            .iter()
            .map(|f| {
                error(
                    &dir.join(&f.path),
                    f.problem.clone(),
                    "a shard must be exactly as rsasim wrote it: rerun that shard (--shard K/N --force) and merge again",
                )
            })
            .collect());
    }
    not_merged.extend(
        v.not_covered
            .iter()
            .map(|p| dir.join(p).display().to_string()),
    );
    let Some(manifest) = v.manifest else {
        return Err(vec![error(
            &dir.join("manifest.json"),
            "not an rsasim output folder: it has no readable manifest.json",
            "give the shard folders rsasim SCENARIO --shard K/N wrote (e.g. OUT/shard-0-of-4)",
        )]);
    };
    let Some(record) = manifest.shard.clone() else {
        return Err(vec![error(
            &dir.join("manifest.json"),
            "not a shard folder: its manifest has no `shard` record",
            "give the folders `rsasim SCENARIO --shard K/N` wrote (OUT/shard-K-of-N)",
        )]);
    };
    Ok(Shard {
        dir: dir.to_path_buf(),
        manifest,
        record,
    })
}

/// The facts every shard of one scenario shares, by name: (what, value).
fn identity(m: &Manifest, r: &ShardRecord) -> Vec<(&'static str, String)> {
    vec![
        ("format", m.format.clone()),
        ("program", m.program.clone()),
        ("build", format!("{:?}", m.build)),
        ("output format", m.output_format.to_string()),
        ("layout", format!("{:?}", m.layout)),
        ("scenario", m.scenario.clone()),
        (
            "scenario SHA-256",
            m.scenario_sha256.clone().unwrap_or_default(),
        ),
        ("seed", format!("{:?}", m.seed)),
        ("number of shards", r.count.to_string()),
        ("protocol's runs", r.protocol_runs.join(",")),
    ]
}

/// The run a file belongs to (`runs/<id>/…`), or `None` for a shared file.
fn run_of(path: &str) -> Option<&str> {
    let rest = path.strip_prefix("runs/")?;
    rest.split_once('/').map(|(id, _)| id)
}

/// Checks a shard against its own record: the runs the split gives its index, and files only of
/// those runs, each with its `truth.json`.
fn check_record(s: &Shard) -> Vec<Diagnostic> {
    let at = s.dir.join("manifest.json");
    let r = &s.record;
    let Some(spec) = ShardSpec::new(r.index, r.count) else {
        return vec![error(
            &at,
            format!("shard index {} is not below its count {}", r.index, r.count),
            "the manifest is not one rsasim wrote",
        )];
    };
    // The count is the sender's: bounded before anything proportional to it is made. rsasim
    // writes at most MAX_SHARDS shards, or one per run beyond it (with --allow-large).
    if r.count > crate::shard::MAX_SHARDS.max(r.protocol_runs.len()) {
        return vec![error(
            &at,
            format!(
                "`shard.count` is {}: rsasim splits a protocol of {} run(s) into at most {} shards",
                r.count,
                r.protocol_runs.len(),
                crate::shard::MAX_SHARDS.max(r.protocol_runs.len())
            ),
            "the manifest is not one rsasim wrote",
        )];
    }
    let expected: Vec<String> = runs_of_shard(r.protocol_runs.len(), spec)
        .into_iter()
        .map(|p| r.protocol_runs[p].clone())
        .collect();
    if r.runs != expected || s.manifest.runs != r.runs.len() {
        return vec![error(
            &at,
            format!(
                "shard {spec} lists runs {} but the split gives it {}",
                listed(&r.runs, 10),
                listed(&expected, 10)
            ),
            "the manifest is not one rsasim wrote",
        )];
    }
    let held: BTreeSet<&str> = r.runs.iter().map(String::as_str).collect();
    let mut problems = Vec::new();
    for f in &s.manifest.files {
        if let Some(id) = run_of(&f.path)
            && !held.contains(id)
        {
            problems.push(error(
                &s.dir.join(&f.path),
                format!("belongs to run {id}, which shard {spec} does not hold"),
                "the manifest is not one rsasim wrote",
            ));
        }
    }
    let listed_paths: BTreeSet<&str> = s.manifest.files.iter().map(|f| f.path.as_str()).collect();
    for id in &held {
        let truth = format!("runs/{id}/truth.json");
        if !listed_paths.contains(truth.as_str()) {
            problems.push(error(
                &s.dir.join(&truth),
                format!("shard {spec} holds run {id} but lists no {truth}"),
                "the manifest is not one rsasim wrote",
            ));
        }
    }
    problems
}

/// Reads and checks the shard folders `dirs` (step 1 of the module documentation).
pub fn check(dirs: &[PathBuf]) -> Result<Shards, Vec<Diagnostic>> {
    let mut errors = Vec::new();
    let mut not_merged = Vec::new();
    let mut shards = Vec::new();
    for dir in dirs {
        match read_shard(dir, &mut not_merged) {
            Ok(s) => shards.push(s),
            Err(e) => errors.extend(e),
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    let Some(first) = shards.first() else {
        return Err(vec![error(
            Path::new("."),
            "no shard folder given",
            "give every shard folder, e.g. rsasim merge out/knee-shards/shard-* --out out/knee",
        )]);
    };
    let ours = super::program();
    if first.manifest.program != ours {
        errors.push(error(
            &first.dir.join("manifest.json"),
            format!("written by {}; this is {ours}", first.manifest.program),
            "merge with the rsasim version that wrote the shards",
        ));
    }
    let reference = identity(&first.manifest, &first.record);
    for s in &shards[1..] {
        for ((what, want), (_, got)) in reference.iter().zip(identity(&s.manifest, &s.record)) {
            if *want != got {
                errors.push(error(
                    &s.dir.join("manifest.json"),
                    format!(
                        "its {what} differs from that of {} ({got:?} against {want:?})",
                        first.dir.display()
                    ),
                    "merge only shards of one scenario, seed and split written by one build",
                ));
            }
        }
    }
    for s in &shards {
        errors.extend(check_record(s));
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    let count = first.record.count;
    let mut by_index: BTreeMap<usize, &Shard> = BTreeMap::new();
    for s in &shards {
        if let Some(other) = by_index.insert(s.record.index, s) {
            errors.push(error(
                &s.dir,
                format!(
                    "shard {}/{count} is given twice (also as {})",
                    s.record.index,
                    other.dir.display()
                ),
                "give each shard folder once",
            ));
        }
    }
    // Counted, and only the first few named: the count is bounded, but the message need not be.
    let missing_count = count - by_index.len().min(count);
    let missing: Vec<usize> = (0..count)
        .filter(|k| !by_index.contains_key(k))
        .take(20)
        .collect();
    if missing_count > 0 {
        let protocol = &first.record.protocol_runs;
        let runs: Vec<String> = missing
            .iter()
            .flat_map(|&k| runs_of_shard(protocol.len(), ShardSpec { index: k, count }))
            .take(51)
            .map(|p| protocol[p].clone())
            .collect();
        let mut shards_text = missing
            .iter()
            .map(|k| format!("{k}/{count}"))
            .collect::<Vec<_>>();
        if missing_count > shards_text.len() {
            shards_text.push(format!("and {} more", missing_count - shards_text.len()));
        }
        // Named after the folder that holds the shards (OUT of `--shard`), when there is one.
        let holder = first
            .dir
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(&first.dir);
        errors.push(error(
            holder,
            format!(
                "{} of {count} shard(s) missing ({}): run(s) {} are in no folder given",
                missing_count,
                listed(&shards_text, 20),
                listed(&runs, 50)
            ),
            "give every shard folder; write a missing one with `rsasim SCENARIO --shard K/N` (the same --out), or rerun its array task",
        ));
    }
    let shared = |s: &Shard| -> Vec<ManifestFile> {
        s.manifest
            .files
            .iter()
            .filter(|f| run_of(&f.path).is_none())
            .cloned()
            .collect()
    };
    let reference = shared(first);
    for s in &shards[1..] {
        let theirs = shared(s);
        if theirs != reference {
            let differing = theirs
                .iter()
                .filter(|f| !reference.contains(f))
                .chain(reference.iter().filter(|f| !theirs.contains(f)))
                .map(|f| f.path.clone())
                .collect::<BTreeSet<_>>();
            errors.push(error(
                &s.dir,
                format!(
                    "its shared files differ from those of {}: {}",
                    first.dir.display(),
                    listed(&differing.into_iter().collect::<Vec<_>>(), 10)
                ),
                "merge only shards written from one scenario by one build",
            ));
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    let mut sources: Vec<(ManifestFile, PathBuf)> = reference
        .into_iter()
        .map(|f| {
            let src = first.dir.join(&f.path);
            (f, src)
        })
        .collect();
    for s in by_index.values() {
        sources.extend(
            s.manifest
                .files
                .iter()
                .filter(|f| run_of(&f.path).is_some())
                .map(|f| (f.clone(), s.dir.join(&f.path))),
        );
    }
    sources.sort_by(|a, b| a.0.path.cmp(&b.0.path));
    let manifest = Manifest {
        manifest_sha256: String::new(),
        runs: first.record.protocol_runs.len(),
        shard: None,
        files: sources.iter().map(|(f, _)| f.clone()).collect(),
        ..first.manifest.clone()
    };
    Ok(Shards {
        manifest,
        sources,
        dirs: by_index.values().map(|s| s.dir.clone()).collect(),
        not_merged,
    })
}

/// Claims `out` for the merged folder (step 2): refused when it is, holds or lies inside a shard
/// folder, and otherwise by the rules of a run's output (`force`).
pub fn claim(shards: &Shards, out: &Path, force: bool) -> Result<OutputTarget, Vec<Diagnostic>> {
    let out_abs = super::commit::guard::resolve(out)
        .map(|r| r.path)
        .map_err(|d| vec![*d])?;
    for dir in &shards.dirs {
        let dir_abs = dir.canonicalize().unwrap_or_else(|_| dir.clone());
        if out_abs.starts_with(dir_abs) {
            return Err(vec![error(
                out,
                format!(
                    "the merged folder would lie inside the shard folder {}",
                    dir.display()
                ),
                "give --out a new folder outside every shard folder, e.g. --out out/knee",
            )]);
        }
    }
    let inputs = shards
        .dirs
        .iter()
        .map(|d| d.join("manifest.json"))
        .collect();
    OutputTarget::claim(out, FolderKind::Simulation { force, inputs }).map_err(|d| vec![*d])
}

/// Places one file: a hard link to `src`, or a copy (synced) when `copy` or when linking fails.
/// Returns whether it was linked.
fn place(src: &Path, dest: &Path, copy: bool) -> std::io::Result<bool> {
    if !copy && std::fs::hard_link(src, dest).is_ok() {
        return Ok(true);
    }
    std::fs::copy(src, dest)?;
    std::fs::File::open(dest)?.sync_data()?;
    Ok(false)
}

/// Writes the merged folder into the claimed `target` (step 3).
pub fn assemble(shards: Shards, target: OutputTarget, copy: bool) -> Result<Summary, Error> {
    let staged = target.stage().map_err(Error::Write)?;
    let root = staged.path().to_path_buf();
    let folders: BTreeSet<PathBuf> = shards
        .sources
        .iter()
        .filter_map(|(f, _)| root.join(&f.path).parent().map(Path::to_path_buf))
        .collect();
    for folder in &folders {
        std::fs::create_dir_all(folder).map_err(Error::Write)?;
    }
    let placed: Vec<std::io::Result<(bool, Option<Diagnostic>)>> = shards
        .sources
        .par_iter()
        .map(|(entry, src)| {
            let dest = root.join(&entry.path);
            let linked = place(src, &dest, copy)?;
            let (sha, bytes) = sha256_file(&dest)?;
            let changed = (sha != entry.sha256 || bytes != entry.bytes).then(|| {
                error(
                    src,
                    format!(
                        "content differs from its shard's manifest (SHA-256 {sha}, {bytes} bytes; the manifest says {}, {} bytes): the file was changed after rsasim wrote it",
                        entry.sha256, entry.bytes
                    ),
                    "rerun that shard (rsasim SCENARIO --shard K/N --force) and merge again",
                )
            });
            Ok((linked, changed))
        })
        .collect();
    let (mut linked, mut copied, mut changed) = (0, 0, Vec::new());
    for p in placed {
        let (was_linked, problem) = p.map_err(Error::Write)?;
        if was_linked {
            linked += 1;
        } else {
            copied += 1;
        }
        changed.extend(problem);
    }
    if !changed.is_empty() {
        return Err(Error::Input(changed));
    }
    write_staged(&root.join("manifest.json"), &shards.manifest.to_bytes()).map_err(Error::Write)?;
    let committed = staged.commit().map_err(Error::Write)?;
    Ok(Summary {
        out_dir: committed.path,
        linked,
        copied,
        bytes: shards.manifest.files.iter().map(|f| f.bytes).sum(),
        notes: committed.notes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_belong_to_their_run_or_are_shared() {
        assert_eq!(run_of("runs/n0-r01/truth.json"), Some("n0-r01"));
        assert_eq!(run_of("runs/n1-r00/calibration-det1.tiff"), Some("n1-r00"));
        assert_eq!(run_of("phantoms/box.csv"), None);
        assert_eq!(run_of("README.md"), None);
        assert_eq!(run_of("runs/x"), None);
    }

    #[test]
    fn long_lists_are_cut_with_a_count() {
        let ids: Vec<String> = (0..5).map(|i| format!("r{i}")).collect();
        assert_eq!(listed(&ids, 10), "r0, r1, r2, r3, r4");
        assert_eq!(listed(&ids, 2), "r0, r1 … and 3 more");
    }

    #[test]
    fn a_placed_file_is_a_link_unless_a_copy_is_asked_for() {
        let dir = tempfile::tempdir().unwrap();
        let src = dir.path().join("a");
        std::fs::write(&src, b"bytes").unwrap();
        assert!(place(&src, &dir.path().join("b"), false).unwrap());
        assert!(!place(&src, &dir.path().join("c"), true).unwrap());
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let ino = |p: &str| std::fs::metadata(dir.path().join(p)).unwrap().ino();
            assert_eq!(ino("a"), ino("b"));
            assert_ne!(ino("a"), ino("c"));
        }
        assert_eq!(std::fs::read(dir.path().join("c")).unwrap(), b"bytes");
    }
}
