//! Durability helpers: syncing folders after writes and renames, as databases do, and folder sizes
//! for messages.

use std::path::Path;

/// Syncs the folder `dir` itself (its list of entries), so that files created or renamed in it
/// survive a power cut. A no-op where folders cannot be opened for syncing (not unix).
pub fn sync_dir(dir: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::fs::File::open(dir)?.sync_all()
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        Ok(())
    }
}

/// Syncs `root` and every folder below it (files are synced when written).
pub fn sync_tree(root: &Path) -> std::io::Result<()> {
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir)? {
            let entry = entry?;
            if entry.file_type()?.is_dir() {
                stack.push(entry.path());
            }
        }
        sync_dir(&dir)?;
    }
    Ok(())
}

/// Total size in bytes of the regular files under `root` (links are not followed; unreadable
/// entries count as 0).
pub fn tree_bytes(root: &Path) -> u64 {
    let mut total = 0;
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            match entry.file_type() {
                Ok(t) if t.is_dir() => stack.push(entry.path()),
                Ok(t) if t.is_file() => total += entry.metadata().map_or(0, |m| m.len()),
                _ => {}
            }
        }
    }
    total
}

/// `bytes` for people, in decimal units: one rule for every message ([`crate::cost::human_bytes`]).
pub use crate::cost::human_bytes;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_for_people() {
        assert_eq!(human_bytes(999), "999 B");
        assert_eq!(human_bytes(3_400_000), "3.4 MB");
        assert_eq!(human_bytes(1_200_000_000), "1.2 GB");
    }

    #[test]
    fn tree_is_synced_and_measured() {
        let root = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(root.path().join("a/b")).unwrap();
        std::fs::write(root.path().join("a/b/f"), [0u8; 10]).unwrap();
        std::fs::write(root.path().join("g"), [0u8; 5]).unwrap();
        sync_tree(root.path()).unwrap();
        assert_eq!(tree_bytes(root.path()), 15);
    }
}
