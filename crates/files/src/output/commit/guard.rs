//! What an output folder may replace: the checks made before any work starts.
//!
//! `--force` (and `evaluate`'s report folder) replace only a folder rsasim wrote, and never the
//! current folder, one of its ancestors, a folder holding a file the run reads, a symbolic link or
//! something that is not a folder.

use std::ffi::OsString;
use std::path::{Component, Path, PathBuf};

use crate::diagnostic::Diagnostic;

/// The name of the file that marks a report folder as written by `rsasim evaluate`.
pub const REPORT_MARKER: &str = ".rsasim-report";

/// The files an `rsasim evaluate` of an earlier version wrote into a report folder (before the
/// marker existed); a folder holding only these is recognised as a report folder too.
const LEGACY_REPORT_FILES: [&str; 5] = [
    "report.md",
    "report.csv",
    "report.tex",
    "report.html",
    "iso5725.csv",
];

/// What kind of folder an output target is, which decides what it may replace.
#[derive(Debug, Clone)]
pub enum FolderKind {
    /// The output folder of a simulation: replaced only with `force`, only when its
    /// `manifest.json` carries an `rsasim-manifest/N` tag, and never when it holds one of `inputs`
    /// (the scenario file and every file it reads).
    Simulation {
        /// Replace an existing rsasim output (the `--force` flag).
        force: bool,
        /// Files the run reads; a folder holding one is never replaced.
        inputs: Vec<PathBuf>,
    },
    /// The report folder of `rsasim evaluate`: replaced when it holds the report marker (or only
    /// files an earlier evaluate wrote).
    Report,
    /// The folder `rsasim export` writes for another program: always a new folder; anything
    /// already there (even an earlier export, which XMALab or the user may have added to) is
    /// refused.
    Export,
    /// The folder `rsasim camera --dir` writes: always a new folder, as [`FolderKind::Export`].
    Camera,
}

/// An output path resolved to an absolute folder and a name, links in the folder resolved (the
/// last component is never followed).
#[derive(Debug, Clone)]
pub struct Resolved {
    /// The folder the target lives in (canonical, or canonical prefix plus folders to create).
    pub parent: PathBuf,
    /// The target's name in `parent`.
    pub name: String,
    /// `parent/name`.
    pub path: PathBuf,
    /// The path as the user gave it, for messages.
    pub shown: PathBuf,
}

/// What is at a target path now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Existing {
    /// Nothing.
    Absent,
    /// A folder.
    Folder,
    /// A symbolic link (maybe dangling).
    Symlink,
    /// A regular file, a device, a FIFO or a socket.
    NotFolder,
}

/// Looks at `path` without following a final link.
pub fn existing(path: &Path) -> std::io::Result<Existing> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => Ok(Existing::Symlink),
        Ok(m) if m.is_dir() => Ok(Existing::Folder),
        Ok(_) => Ok(Existing::NotFolder),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Existing::Absent),
        Err(e) => Err(e),
    }
}

fn refuse(shown: &Path, message: impl Into<String>, help: impl Into<String>) -> Box<Diagnostic> {
    Box::new(Diagnostic::file_error(shown, message).with_help(help))
}

/// Resolves `out` against the current folder: the folder part is made canonical (links
/// followed) as far as it exists; the last component is kept as given.
pub fn resolve(out: &Path) -> Result<Resolved, Box<Diagnostic>> {
    let io_refusal = |e: std::io::Error| {
        refuse(
            out,
            format!("cannot resolve the output path: {e}"),
            "give a folder path you can write to with --out",
        )
    };
    let cwd = std::env::current_dir().map_err(io_refusal)?;
    let absolute = cwd.join(out);
    let (parent, name): (PathBuf, OsString) = match absolute.file_name() {
        Some(name)
            if !matches!(
                absolute.components().next_back(),
                Some(Component::ParentDir)
            ) =>
        {
            let parent = absolute.parent().unwrap_or(Path::new("/"));
            (canonical_prefix(parent).map_err(io_refusal)?, name.into())
        }
        // `.`, `..`, `/`: the folder itself, which exists.
        _ => {
            let canonical = absolute.canonicalize().map_err(io_refusal)?;
            match (canonical.parent(), canonical.file_name()) {
                (Some(p), Some(n)) => (p.to_path_buf(), n.into()),
                _ => {
                    return Err(refuse(
                        out,
                        "the output folder is the root of the file system",
                        "give a new folder with --out, e.g. --out out/my-run",
                    ));
                }
            }
        }
    };
    let name = name.into_string().map_err(|n| {
        refuse(
            out,
            format!("the output folder name {n:?} is not valid UTF-8"),
            "give a folder name in UTF-8 with --out",
        )
    })?;
    Ok(Resolved {
        path: parent.join(&name),
        parent,
        name,
        shown: out.to_path_buf(),
    })
}

/// The canonical form of the longest existing prefix of `path` plus the rest as given (which
/// must be plain names, since a `..` below a missing folder cannot be resolved).
fn canonical_prefix(path: &Path) -> std::io::Result<PathBuf> {
    let mut rest = Vec::new();
    let mut cur = path;
    loop {
        if let Ok(c) = cur.canonicalize() {
            let mut out = c;
            for part in rest.iter().rev() {
                out.push(part);
            }
            return Ok(out);
        }
        match (cur.parent(), cur.components().next_back()) {
            (Some(p), Some(Component::Normal(n))) => {
                rest.push(n.to_os_string());
                cur = p;
            }
            (Some(p), Some(Component::CurDir)) => cur = p,
            _ => {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    format!("{} does not exist", path.display()),
                ));
            }
        }
    }
}

/// Checks that writing `target` may proceed given what is there now; `Ok` with what exists.
pub fn check(target: &Resolved, kind: &FolderKind) -> Result<Existing, Box<Diagnostic>> {
    let shown = &target.shown;
    let what = || format!("output folder {}", shown.display());
    // The deepest existing ancestor must be a folder (a file there would fail only at the end).
    let mut ancestor = target.parent.as_path();
    while existing(ancestor).map_err(|e| refuse(shown, e.to_string(), "check --out"))?
        == Existing::Absent
    {
        ancestor = ancestor.parent().unwrap_or(Path::new("/"));
    }
    if !ancestor.is_dir() {
        return Err(refuse(
            shown,
            format!(
                "cannot create the {}: {} is not a folder",
                what(),
                ancestor.display()
            ),
            "give an --out path whose parents are folders",
        ));
    }
    let now = existing(&target.path).map_err(|e| refuse(shown, e.to_string(), "check --out"))?;
    match now {
        Existing::Absent => return Ok(now),
        Existing::Symlink => {
            let to = std::fs::read_link(&target.path)
                .map(|p| p.display().to_string())
                .unwrap_or_default();
            return Err(refuse(
                shown,
                format!(
                    "the {} is a symbolic link (to {to}); rsasim never writes through or replaces a link",
                    what()
                ),
                "give the real folder or a new one with --out",
            ));
        }
        Existing::NotFolder => {
            return Err(refuse(
                shown,
                format!("the {} names a file, not a folder", what()),
                "give a new folder with --out; rsasim never replaces a file",
            ));
        }
        Existing::Folder => {}
    }
    let force = match kind {
        FolderKind::Simulation { force, .. } => *force,
        FolderKind::Report => true,
        FolderKind::Export => {
            return Err(refuse(
                shown,
                format!(
                    "the export folder {} already exists; rsasim export writes only new folders",
                    shown.display()
                ),
                "give a new folder with --dir (results saved there by XMALab are never overwritten)",
            ));
        }
        FolderKind::Camera => {
            return Err(refuse(
                shown,
                format!(
                    "the camera folder {} already exists; rsasim camera writes only new folders",
                    shown.display()
                ),
                "give a new folder with --dir, or print the cameras without --dir",
            ));
        }
    };
    if !force {
        return Err(refuse(
            shown,
            format!("{} already exists", what()),
            "pass --force to replace it (only a folder rsasim wrote is replaced), or --out DIR to write elsewhere",
        ));
    }
    if let Ok(cwd) = std::env::current_dir().and_then(|c| c.canonicalize())
        && cwd.starts_with(&target.path)
    {
        return Err(refuse(
            shown,
            format!(
                "the {} is the current folder or one of its parents; rsasim never replaces it",
                what()
            ),
            "give a new folder with --out, e.g. --out out/my-run",
        ));
    }
    if let FolderKind::Simulation { inputs, .. } = kind {
        for input in inputs {
            let input = input.canonicalize().unwrap_or_else(|_| input.clone());
            if input.starts_with(&target.path) {
                return Err(refuse(
                    shown,
                    format!(
                        "the {} holds {}, which this run reads; rsasim never replaces it",
                        what(),
                        input.display()
                    ),
                    "write the output elsewhere with --out, e.g. --out out/my-run",
                ));
            }
        }
    }
    if is_empty_folder(&target.path) {
        return Ok(now);
    }
    let recognised = match kind {
        FolderKind::Simulation { .. } => simulation_output(&target.path),
        FolderKind::Report => report_folder(&target.path),
        FolderKind::Export | FolderKind::Camera => Err("an existing folder".to_string()),
    };
    if let (FolderKind::Simulation { .. }, Ok(())) = (kind, &recognised) {
        let foreign = foreign_files(&target.path);
        if let Some(first) = foreign.first() {
            return Err(refuse(
                shown,
                format!(
                    "the {} holds {} file(s) that rsasim did not write (first: {first}); rsasim \
                     never deletes another program's files",
                    what(),
                    foreign.len()
                ),
                "move them out of the folder first (e.g. a software's measured.json), or write \
                 the new output elsewhere with --out",
            ));
        }
    }
    recognised.map(|()| now).map_err(|why| {
        refuse(
            shown,
            format!(
                "the {} was not written by rsasim ({why}); rsasim replaces only its own outputs",
                what()
            ),
            match kind {
                FolderKind::Simulation { .. } => {
                    "give a new folder with --out, or move that folder away first"
                }
                FolderKind::Report => {
                    "give a new report folder with --report, or move that folder away first"
                }
                FolderKind::Export | FolderKind::Camera => "give a new folder with --dir",
            },
        )
    })
}

fn is_empty_folder(path: &Path) -> bool {
    std::fs::read_dir(path).is_ok_and(|mut d| d.next().is_none())
}

/// Whether `tag` is `rsasim-manifest/N` for the current or a later version N.
pub fn is_manifest_tag(tag: &str) -> bool {
    let current: u32 = crate::output::MANIFEST_FORMAT
        .rsplit('/')
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or(1);
    tag.strip_prefix("rsasim-manifest/")
        .and_then(|n| n.parse::<u32>().ok())
        .is_some_and(|n| n >= current)
}

/// `Ok` when `dir/manifest.json` parses and carries an `rsasim-manifest/N` tag; otherwise why not.
pub fn simulation_output(dir: &Path) -> Result<(), String> {
    let manifest = read_manifest(dir)?;
    let tag = manifest.get("format").and_then(|f| f.as_str());
    match tag {
        Some(t) if is_manifest_tag(t) => Ok(()),
        Some(t) => Err(format!(
            "its manifest.json has format {t:?}, not rsasim-manifest/N"
        )),
        None => Err("its manifest.json has no format tag".into()),
    }
}

fn read_manifest(dir: &Path) -> Result<serde_json::Value, String> {
    let path = dir.join("manifest.json");
    let file = std::fs::File::open(&path).map_err(|_| "it holds no manifest.json".to_string())?;
    // A manifest is small; a huge file named manifest.json is not one of ours.
    let mut text = Vec::new();
    std::io::Read::read_to_end(&mut std::io::Read::take(file, 64 * 1024 * 1024), &mut text)
        .map_err(|e| format!("its manifest.json cannot be read: {e}"))?;
    serde_json::from_slice(&text).map_err(|_| "its manifest.json is not JSON".to_string())
}

/// `Ok` when `dir` is a complete simulation output: its manifest is rsasim's and every file it
/// lists is there with the listed size.
pub fn complete_output(dir: &Path) -> Result<(), String> {
    simulation_output(dir)?;
    let manifest = read_manifest(dir)?;
    let files = manifest
        .get("files")
        .and_then(|f| f.as_array())
        .ok_or("its manifest.json lists no files")?;
    for f in files {
        let (Some(path), Some(bytes)) = (
            f.get("path").and_then(|p| p.as_str()),
            f.get("bytes").and_then(|b| b.as_u64()),
        ) else {
            return Err("its manifest.json has an entry without path or size".into());
        };
        let len = std::fs::symlink_metadata(dir.join(path)).map(|m| m.len());
        if len.ok() != Some(bytes) {
            return Err(format!("{path} is missing or has the wrong size"));
        }
    }
    Ok(())
}

/// The files in the rsasim output `dir` that rsasim did not write, as paths relative to `dir`
/// (at most 20): anything not listed in its manifest, except rsasim's own later additions — its
/// reference program's results (`runs/<id>/measured-rsasim-*.json` whose `software` is rsasim's),
/// `rsasim evaluate`'s report folders ([`report_folder`]) and lock files. `--force` replaces an
/// output only when this is empty, so a vendor's results inside it are never deleted.
pub fn foreign_files(dir: &Path) -> Vec<String> {
    let listed: std::collections::HashSet<String> = read_manifest(dir)
        .ok()
        .and_then(|m| {
            m.get("files").and_then(|f| f.as_array()).map(|files| {
                files
                    .iter()
                    .filter_map(|f| f.get("path").and_then(|p| p.as_str()).map(String::from))
                    .collect()
            })
        })
        .unwrap_or_default();
    let mut foreign = Vec::new();
    let mut stack = vec![(dir.to_path_buf(), String::new())];
    while let Some((folder, rel)) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&folder) else {
            foreign.push(format!("{rel}(unreadable)"));
            continue;
        };
        for entry in entries.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let path = format!("{rel}{name}");
            let is_dir = entry.file_type().is_ok_and(|t| t.is_dir());
            let ours = if is_dir {
                (rel.is_empty() && report_folder(&entry.path()).is_ok())
                    || listed.iter().any(|l| l.starts_with(&format!("{path}/")))
            } else {
                listed.contains(&path)
                    || (rel.is_empty() && name == "manifest.json")
                    || name.ends_with(".rsasim-lock")
                    || (rel.starts_with("runs/") && own_results(&entry.path(), &name))
            };
            if !ours {
                foreign.push(if is_dir { format!("{path}/") } else { path });
            } else if is_dir && !(rel.is_empty() && report_folder(&entry.path()).is_ok()) {
                stack.push((entry.path(), format!("{path}/")));
            }
            if foreign.len() >= 20 {
                return foreign;
            }
        }
    }
    foreign.sort();
    foreign
}

/// Whether `file` (named `name`) is results written by rsasim's reference program.
fn own_results(file: &Path, name: &str) -> bool {
    name.starts_with("measured-rsasim")
        && name.ends_with(".json")
        && crate::output::measured::written_by_reference_program(file)
}

/// `Ok` when `dir` holds the report marker, or only files an earlier `rsasim evaluate` wrote.
pub fn report_folder(dir: &Path) -> Result<(), String> {
    if dir.join(REPORT_MARKER).is_file() {
        return Ok(());
    }
    let entries = std::fs::read_dir(dir).map_err(|e| format!("it cannot be read: {e}"))?;
    for entry in entries {
        let entry = entry.map_err(|e| format!("it cannot be read: {e}"))?;
        let name = entry.file_name();
        let ours = name
            .to_str()
            .is_some_and(|n| LEGACY_REPORT_FILES.contains(&n))
            && entry.file_type().is_ok_and(|t| t.is_file());
        if !ours {
            return Err(format!(
                "it holds {} and no {REPORT_MARKER} marker",
                name.to_string_lossy()
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sim(force: bool, inputs: Vec<PathBuf>) -> FolderKind {
        FolderKind::Simulation { force, inputs }
    }

    #[test]
    fn manifest_tags_of_this_and_later_versions_are_recognised() {
        assert!(is_manifest_tag("rsasim-manifest/1"));
        assert!(is_manifest_tag("rsasim-manifest/7"));
        assert!(!is_manifest_tag("rsasim-manifest/x"));
        assert!(!is_manifest_tag("other/1"));
    }

    #[test]
    fn force_replaces_only_rsasim_outputs_and_never_folders_holding_inputs() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        std::fs::create_dir(&dir).unwrap();
        let r = resolve(&dir).unwrap();
        assert_eq!(check(&r, &sim(true, vec![])).unwrap(), Existing::Folder);
        std::fs::write(dir.join("notes.txt"), "mine").unwrap();
        let e = check(&r, &sim(true, vec![])).unwrap_err();
        assert!(e.message.contains("not written by rsasim"), "{}", e.message);
        std::fs::write(
            dir.join("manifest.json"),
            r#"{"format": "rsasim-manifest/1"}"#,
        )
        .unwrap();
        // notes.txt is not in that manifest: another program's file, never deleted.
        let e = check(&r, &sim(true, vec![])).unwrap_err();
        assert!(
            e.message.contains("did not write (first: notes.txt)"),
            "{}",
            e.message
        );
        std::fs::write(
            dir.join("manifest.json"),
            r#"{"format": "rsasim-manifest/1", "files": [{"path": "notes.txt"}]}"#,
        )
        .unwrap();
        assert!(check(&r, &sim(true, vec![])).is_ok());
        assert!(check(&r, &sim(false, vec![])).is_err());
        let e = check(&r, &sim(true, vec![dir.join("notes.txt")])).unwrap_err();
        assert!(e.message.contains("which this run reads"), "{}", e.message);
    }

    #[test]
    fn results_of_other_software_block_force_and_rsasims_own_do_not() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        std::fs::create_dir_all(dir.join("runs/n0-r00")).unwrap();
        std::fs::write(dir.join("runs/n0-r00/a.tiff"), "x").unwrap();
        std::fs::write(
            dir.join("manifest.json"),
            r#"{"format": "rsasim-manifest/1", "files": [{"path": "runs/n0-r00/a.tiff"}]}"#,
        )
        .unwrap();
        assert!(foreign_files(&dir).is_empty());
        // rsasim's own later additions: reference results, a report folder, a lock file.
        std::fs::write(
            dir.join("runs/n0-r00/measured-rsasim-dlt-markers.json"),
            r#"{"format": "rsasim-measured/1", "run": "n0-r00", "software": "rsasim reconstruct 0.2.0 (dlt, markers)"}"#,
        )
        .unwrap();
        std::fs::create_dir(dir.join("report-x")).unwrap();
        std::fs::write(dir.join("report-x").join(REPORT_MARKER), "").unwrap();
        std::fs::write(dir.join("report-x/thesis.tex"), "x").unwrap();
        std::fs::write(dir.join(".report-x.rsasim-lock"), "").unwrap();
        assert!(foreign_files(&dir).is_empty(), "{:?}", foreign_files(&dir));
        // A vendor's results, or one posing under rsasim's name, are another program's.
        std::fs::write(dir.join("runs/n0-r00/measured.json"), "{}").unwrap();
        std::fs::write(
            dir.join("runs/n0-r00/measured-rsasim-x.json"),
            r#"{"format": "rsasim-measured/1", "run": "n0-r00", "software": "MyRSA"}"#,
        )
        .unwrap();
        assert_eq!(
            foreign_files(&dir),
            [
                "runs/n0-r00/measured-rsasim-x.json",
                "runs/n0-r00/measured.json"
            ]
        );
        let r = resolve(&dir).unwrap();
        assert!(check(&r, &sim(true, vec![])).is_err());
    }

    #[test]
    fn files_and_links_are_refused_even_when_dangling() {
        let root = tempfile::tempdir().unwrap();
        let file = root.path().join("afile");
        std::fs::write(&file, "x").unwrap();
        let e = check(&resolve(&file).unwrap(), &sim(true, vec![])).unwrap_err();
        assert!(e.message.contains("names a file"), "{}", e.message);
        #[cfg(unix)]
        {
            let link = root.path().join("link");
            std::os::unix::fs::symlink(root.path().join("nowhere"), &link).unwrap();
            let e = check(&resolve(&link).unwrap(), &sim(false, vec![])).unwrap_err();
            assert!(e.message.contains("symbolic link"), "{}", e.message);
        }
    }

    #[test]
    fn report_folders_are_recognised_by_marker_or_legacy_files() {
        let root = tempfile::tempdir().unwrap();
        std::fs::write(root.path().join("report.md"), "x").unwrap();
        assert!(report_folder(root.path()).is_ok());
        std::fs::write(root.path().join("thesis.tex"), "x").unwrap();
        assert!(report_folder(root.path()).is_err());
        std::fs::write(root.path().join(REPORT_MARKER), "x").unwrap();
        assert!(report_folder(root.path()).is_ok());
    }
}
