//! Writing files so that no reader ever sees a truncated file under its final name.
//!
//! Test-only fault injection: with `RSASIM_FAULT_AFTER_FILES=N` in the environment, the N-th file
//! written by this process (counting from 1, across threads) fails with an I/O error, as a full
//! disk would. The integration tests use it to check that a failed rerun keeps the old output.

use std::io::Write;
use std::path::Path;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

use sha2::{Digest, Sha256};

use crate::scenario::hex;

/// The environment variable of the test-only write fault (see the module documentation).
pub const FAULT_ENV: &str = "RSASIM_FAULT_AFTER_FILES";

/// Fails the N-th call when [`FAULT_ENV`] is N.
fn injected_fault(path: &Path) -> std::io::Result<()> {
    static AFTER: OnceLock<Option<usize>> = OnceLock::new();
    static WRITTEN: AtomicUsize = AtomicUsize::new(0);
    let Some(n) = *AFTER.get_or_init(|| std::env::var(FAULT_ENV).ok()?.trim().parse().ok()) else {
        return Ok(());
    };
    if WRITTEN.fetch_add(1, Ordering::SeqCst) + 1 == n {
        return Err(std::io::Error::other(format!(
            "injected write fault ({FAULT_ENV}={n}) at {}",
            path.display()
        )));
    }
    Ok(())
}

/// Writes `bytes` to a temporary file beside `path`, syncs it, renames it over `path` and syncs
/// the folder, so the file survives a power cut once this returns. Returns the SHA-256 of the
/// bytes, lowercase hex.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<String> {
    let sha = write_staged(path, bytes)?;
    crate::output::commit::durable::sync_dir(folder_of(path))?;
    Ok(sha)
}

/// [`write_atomic`] without syncing the folder: for files inside a staging folder, whose
/// folders are all synced once at the commit.
pub fn write_staged(path: &Path, bytes: &[u8]) -> std::io::Result<String> {
    synced_temporary(path, bytes)?
        .persist(path)
        .map_err(|e| e.error)?;
    Ok(hex(&Sha256::digest(bytes)))
}

/// The start and end of the names of this module's temporary files.
const PARTIAL: (&str, &str) = (".rsasim-", ".partial");

/// Whether a file name is one of this module's temporary files (a writer still at work, or one
/// killed before it could remove its file).
pub fn is_partial(name: &str) -> bool {
    name.starts_with(PARTIAL.0) && name.ends_with(PARTIAL.1)
}

/// A temporary file `.rsasim-*.partial` beside `path` holding `bytes`, synced, removed when
/// dropped unless moved into place.
fn synced_temporary(path: &Path, bytes: &[u8]) -> std::io::Result<tempfile::NamedTempFile> {
    injected_fault(path)?;
    let mut builder = tempfile::Builder::new();
    builder.prefix(PARTIAL.0).suffix(PARTIAL.1);
    // Temporary files are created 0600; outputs are ordinary files for every reader (0644).
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o644));
    let mut tmp = builder.tempfile_in(folder_of(path))?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_data()?;
    Ok(tmp)
}

/// What [`write_once`] found at its path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Once {
    /// Nothing was there: the file is now written (synced, folder synced).
    Written,
    /// A file with exactly these bytes was there (written before, or meanwhile by another
    /// process): left as it is.
    Identical,
    /// Something else is there (other bytes, a folder, a link): left as it is, nothing written.
    Different,
}

/// Writes `bytes` to `path` once: through a synced temporary file beside it, moved into place
/// only if nothing is there (never replacing: a file another process puts there meanwhile is
/// kept), then compared. For files that several processes write with the same bytes at the same
/// time (the tasks of an array job on a shared file system): none overwrites another's file, and
/// a reader never sees a partial one.
pub fn write_once(path: &Path, bytes: &[u8]) -> std::io::Result<Once> {
    let compare = || -> std::io::Result<Once> {
        let meta = std::fs::symlink_metadata(path)?;
        if !meta.is_file() || meta.len() != bytes.len() as u64 {
            return Ok(Once::Different);
        }
        // Opened without blocking or following a link: a FIFO put there cannot hang the task.
        let Ok(file) = crate::input_file::open_regular(path, bytes.len() as u64, true) else {
            return Ok(Once::Different);
        };
        let mut found = Vec::with_capacity(bytes.len());
        std::io::Read::read_to_end(
            &mut std::io::Read::take(file, bytes.len() as u64 + 1),
            &mut found,
        )?;
        Ok(if found == bytes {
            Once::Identical
        } else {
            Once::Different
        })
    };
    if std::fs::symlink_metadata(path).is_ok() {
        return compare();
    }
    match synced_temporary(path, bytes)?
        .into_temp_path()
        .persist_noclobber(path)
    {
        Ok(()) => {
            crate::output::commit::durable::sync_dir(folder_of(path))?;
            Ok(Once::Written)
        }
        // Another process was quicker (its temporary file is removed on drop).
        Err(e) if e.error.kind() == std::io::ErrorKind::AlreadyExists => compare(),
        Err(e) => Err(e.error),
    }
}

fn folder_of(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_are_written_whole_with_their_hash_and_readable_mode() {
        let root = tempfile::tempdir().unwrap();
        let path = root.path().join("a.txt");
        let sha = write_atomic(&path, b"abc").unwrap();
        assert_eq!(
            sha,
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        assert_eq!(std::fs::read(&path).unwrap(), b"abc");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o644);
        }
        // No temporary files are left behind.
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_file_is_written_once_and_never_replaced() {
        let root = tempfile::tempdir().unwrap();
        let path = root.path().join("p.toml");
        assert_eq!(write_once(&path, b"abc").unwrap(), Once::Written);
        assert_eq!(write_once(&path, b"abc").unwrap(), Once::Identical);
        assert_eq!(write_once(&path, b"abd").unwrap(), Once::Different);
        assert_eq!(write_once(&path, b"abcd").unwrap(), Once::Different);
        assert_eq!(std::fs::read(&path).unwrap(), b"abc");
        // A folder or a link in its place is left alone.
        std::fs::create_dir(root.path().join("dir")).unwrap();
        assert_eq!(
            write_once(&root.path().join("dir"), b"abc").unwrap(),
            Once::Different
        );
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(&path, root.path().join("link")).unwrap();
            assert_eq!(
                write_once(&root.path().join("link"), b"abc").unwrap(),
                Once::Different
            );
        }
        // Many writers at once: one writes, the others find the same bytes; nothing is left over.
        let racing = root.path().join("racing.json");
        let found: Vec<Once> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..8)
                .map(|_| s.spawn(|| write_once(&racing, b"same bytes").unwrap()))
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert_eq!(found.iter().filter(|&&o| o == Once::Written).count(), 1);
        assert!(found.iter().all(|&o| o != Once::Different));
        let names: Vec<String> = std::fs::read_dir(root.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(names.iter().all(|n| !is_partial(n)), "{names:?}");
    }
}
