//! The staging folder of one process beside its target, the swap that commits it, and the
//! recovery of what a killed run left: staging folders (removed) and an old output renamed aside
//! (restored when the target is missing, removed otherwise).

use std::path::{Path, PathBuf};

use super::durable::{human_bytes, sync_dir, sync_tree, tree_bytes};
use super::guard::{self, FolderKind, REPORT_MARKER};

/// The marker file inside a staging folder naming it as rsasim's; removed just before the commit.
pub const STAGING_MARKER: &str = ".rsasim-staging";
/// The marker file put into an old output renamed aside once the new one is in place: it may be
/// removed (even half removed).
pub const DISCARD_MARKER: &str = ".rsasim-discard";

/// `.<name>.rsasim-staging-`: the prefix of staging folders of the output `name`.
pub fn staging_prefix(name: &str) -> String {
    format!(".{name}.rsasim-staging-")
}

/// `.<name>.rsasim-old-`: the prefix of old outputs renamed aside during a swap.
pub fn aside_prefix(name: &str) -> String {
    format!(".{name}.rsasim-old-")
}

/// A fresh name `<prefix><pid>-<random>` not used in `parent`, created as a folder.
pub fn create_unique_dir(parent: &Path, prefix: &str) -> std::io::Result<PathBuf> {
    for _ in 0..100 {
        let path = parent.join(unique_name(prefix));
        match std::fs::create_dir(&path) {
            Ok(()) => return Ok(path),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other(format!(
        "no free name {prefix}* in {}",
        parent.display()
    )))
}

fn unique_name(prefix: &str) -> String {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u32(std::process::id());
    format!("{prefix}{}-{:016x}", std::process::id(), h.finish())
}

/// Removes `dir` with everything in it, the file `marker` at its top last, so that a removal
/// cut short leaves a folder that still carries the marker.
pub fn remove_marked(dir: &Path, marker: &str) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        if entry.file_name() == marker {
            continue;
        }
        if entry.file_type()?.is_dir() {
            std::fs::remove_dir_all(entry.path())?;
        } else {
            std::fs::remove_file(entry.path())?;
        }
    }
    match std::fs::remove_file(dir.join(marker)) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
        _ => {}
    }
    std::fs::remove_dir(dir)
}

/// Whether `dir` is a complete output of `kind` (what a swap renamed aside).
fn complete(dir: &Path, kind: &FolderKind) -> bool {
    !dir.join(DISCARD_MARKER).exists()
        && match kind {
            FolderKind::Simulation { .. } => guard::complete_output(dir).is_ok(),
            FolderKind::Report => dir.join(REPORT_MARKER).is_file(),
            // An export (or camera folder) never replaces a folder, so none is ever renamed
            // aside to restore.
            FolderKind::Export | FolderKind::Camera => false,
        }
}

/// Cleans what killed runs into `target` left in `parent`. Call only while holding the output
/// lock (so no live process owns those folders). Returns one message per action.
pub fn recover(
    parent: &Path,
    name: &str,
    target: &Path,
    shown: &Path,
    kind: &FolderKind,
) -> std::io::Result<Vec<String>> {
    let mut notes = Vec::new();
    let (staging_p, aside_p) = (staging_prefix(name), aside_prefix(name));
    let mut leftovers: Vec<(PathBuf, bool)> = Vec::new();
    for entry in std::fs::read_dir(parent)? {
        let entry = entry?;
        let file_name = entry.file_name();
        let Some(n) = file_name.to_str() else {
            continue;
        };
        let is_aside = n.starts_with(&aside_p);
        if (is_aside || n.starts_with(&staging_p)) && entry.file_type()?.is_dir() {
            leftovers.push((entry.path(), is_aside));
        }
    }
    leftovers.sort();
    // A killed swap may have left the target missing and the old output aside: restore it.
    for (dir, _) in leftovers.iter().filter(|(_, aside)| *aside) {
        if guard::existing(target)? == guard::Existing::Absent && complete(dir, kind) {
            std::fs::rename(dir, target)?;
            sync_dir(parent)?;
            notes.push(format!(
                "restored {} from {} (a run into it was stopped while swapping outputs)",
                shown.display(),
                dir.display()
            ));
        }
    }
    for (dir, aside) in &leftovers {
        if !dir.exists() {
            continue;
        }
        let bytes = tree_bytes(dir);
        let (marker, what) = if *aside {
            (DISCARD_MARKER, "old output set aside by")
        } else {
            (STAGING_MARKER, "unfinished staging folder of")
        };
        let removable = dir.join(marker).exists()
            || (*aside && complete(dir, kind))
            // A staging folder whose marker was removed just before its commit was cut short.
            || (!*aside && complete(dir, kind));
        if removable {
            remove_marked(dir, marker)?;
            notes.push(format!(
                "removed {} ({}), the {what} an interrupted run",
                dir.display(),
                human_bytes(bytes)
            ));
        } else {
            notes.push(format!(
                "left {} alone: its name is rsasim's but it lacks rsasim's marker; remove it yourself if it is not yours",
                dir.display()
            ));
        }
    }
    Ok(notes)
}

/// The swap: `staging` (complete) becomes `target`; an old `target` is renamed aside first and
/// removed only once the new one is in place. Every step is synced. Returns notes (an old output
/// that could not be removed).
pub fn swap(
    parent: &Path,
    name: &str,
    staging: &Path,
    target: &Path,
) -> std::io::Result<Vec<String>> {
    let mut notes = Vec::new();
    std::fs::remove_file(staging.join(STAGING_MARKER))?;
    sync_tree(staging)?;
    let aside = match guard::existing(target)? {
        guard::Existing::Absent => None,
        _ => {
            // A unique name: the folder is created, then replaced by the rename (an empty
            // folder may be renamed over on unix; elsewhere remove it first).
            let aside = create_unique_dir(parent, &aside_prefix(name))?;
            std::fs::remove_dir(&aside)?;
            std::fs::rename(target, &aside)?;
            sync_dir(parent)?;
            Some(aside)
        }
    };
    if let Err(e) = std::fs::rename(staging, target) {
        if let Some(aside) = &aside {
            let _ = std::fs::rename(aside, target);
            let _ = sync_dir(parent);
        }
        return Err(e);
    }
    sync_dir(parent)?;
    if let Some(aside) = aside {
        let removed = std::fs::write(
            aside.join(DISCARD_MARKER),
            b"rsasim: old output, to be removed\n",
        )
        .and_then(|()| sync_dir(&aside))
        .and_then(|()| remove_marked(&aside, DISCARD_MARKER));
        if let Err(e) = removed {
            notes.push(format!(
                "could not remove the previous output {} ({e}); the next run into it removes it",
                aside.display()
            ));
        }
    }
    Ok(notes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn output(dir: &Path) {
        std::fs::create_dir_all(dir).unwrap();
        std::fs::write(dir.join("a.txt"), b"abc").unwrap();
        std::fs::write(
            dir.join("manifest.json"),
            r#"{"format": "rsasim-manifest/1", "files": [{"path": "a.txt", "bytes": 3}]}"#,
        )
        .unwrap();
    }

    fn sim() -> FolderKind {
        FolderKind::Simulation {
            force: true,
            inputs: vec![],
        }
    }

    #[test]
    fn an_old_output_left_aside_is_restored_and_leftovers_are_removed() {
        let root = tempfile::tempdir().unwrap();
        let target = root.path().join("out");
        let aside = root.path().join(format!("{}1-0", aside_prefix("out")));
        output(&aside);
        let staging = root.path().join(format!("{}1-1", staging_prefix("out")));
        std::fs::create_dir_all(staging.join("runs")).unwrap();
        std::fs::write(staging.join(STAGING_MARKER), "").unwrap();
        let foreign = root.path().join(format!("{}2-2", staging_prefix("out")));
        std::fs::create_dir_all(&foreign).unwrap();
        std::fs::write(foreign.join("mine.txt"), "x").unwrap();
        let notes = recover(root.path(), "out", &target, &target, &sim()).unwrap();
        assert_eq!(std::fs::read(target.join("a.txt")).unwrap(), b"abc");
        assert!(!aside.exists() && !staging.exists());
        assert!(foreign.join("mine.txt").exists(), "no marker: left alone");
        assert_eq!(notes.len(), 3, "{notes:?}");
    }

    #[test]
    fn swap_replaces_the_old_output_and_leaves_nothing_else() {
        let root = tempfile::tempdir().unwrap();
        let target = root.path().join("out");
        output(&target);
        let staging = create_unique_dir(root.path(), &staging_prefix("out")).unwrap();
        std::fs::write(staging.join(STAGING_MARKER), "").unwrap();
        std::fs::write(staging.join("b.txt"), "new").unwrap();
        swap(root.path(), "out", &staging, &target).unwrap();
        assert!(target.join("b.txt").exists() && !target.join("a.txt").exists());
        assert!(!target.join(STAGING_MARKER).exists());
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1);
    }
}
