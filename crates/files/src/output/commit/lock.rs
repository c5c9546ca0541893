//! One writer per output: an exclusive lock on a file beside the target, held for the whole run.

use std::fs::{File, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

/// An exclusive lock on `.<name>.rsasim-lock` beside an output folder; released when dropped or
/// when the process ends in any way (the operating system drops it, even after kill -9).
///
/// The holder removes the lock file before it lets go of the lock, so a command leaves no file
/// beside the output it named (an exit 2 leaves nothing at all); only a killed process leaves one,
/// unlocked, which the next writer takes over. Removing a lock file could let two processes lock
/// two different files (one locks the removed file it had opened just before, the other a new
/// one), so [`OutputLock::acquire`] checks, after locking, that the path still names the file it
/// locked, and otherwise starts again.
#[derive(Debug)]
pub struct OutputLock {
    _file: File,
    /// The lock file.
    pub path: PathBuf,
}

/// Why the lock was not taken.
#[derive(Debug)]
pub enum LockError {
    /// Another process holds it; its pid when it wrote one.
    Busy(Option<u32>),
    /// The lock file could not be created or locked.
    Io(std::io::Error),
}

impl OutputLock {
    /// Takes the lock of the output `name` in `parent`, at once or not at all.
    pub fn acquire(parent: &Path, name: &str) -> Result<OutputLock, LockError> {
        let path = parent.join(format!(".{name}.rsasim-lock"));
        // Each round loses only to a holder that released and removed the file between our open
        // and our lock; a bounded number of rounds keeps a pathological race from spinning.
        for _ in 0..MAX_ROUNDS {
            let mut file = open_lock_file(&path).map_err(LockError::Io)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    let mut text = String::new();
                    let _ = file.read_to_string(&mut text);
                    return Err(LockError::Busy(text.trim().parse().ok()));
                }
                Err(TryLockError::Error(e)) => return Err(LockError::Io(e)),
            }
            if !still_named(&file, &path) {
                continue;
            }
            // The pid, for the message another process prints; best effort.
            let _ = file
                .set_len(0)
                .and_then(|()| file.rewind())
                .and_then(|()| write!(file, "{}", std::process::id()))
                .and_then(|()| file.flush());
            return Ok(OutputLock { _file: file, path });
        }
        Err(LockError::Busy(None))
    }
}

impl Drop for OutputLock {
    /// Removes the lock file while the lock is still held (the file is closed, and the lock let
    /// go, only after this runs), and only if the path still names the file this lock opened: a
    /// file someone else put there meanwhile is not rsasim's to remove.
    fn drop(&mut self) {
        if still_named(&self._file, &self.path) {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Rounds of open-lock-check before [`OutputLock::acquire`] gives up as if busy.
const MAX_ROUNDS: usize = 64;

/// Opens (creating) the lock file, never through a symbolic link.
fn open_lock_file(path: &Path) -> std::io::Result<File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true).write(true).create(true).truncate(false);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NOFOLLOW);
    }
    options.open(path)
}

/// Whether `path` still names the file `file` has open (not removed, not replaced).
fn still_named(file: &File, path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (file.metadata(), std::fs::symlink_metadata(path)) {
            (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = (file, path);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_writer_is_refused_with_the_first_ones_pid() {
        let root = tempfile::tempdir().unwrap();
        let first = OutputLock::acquire(root.path(), "out").unwrap();
        match OutputLock::acquire(root.path(), "out") {
            Err(LockError::Busy(pid)) => assert_eq!(pid, Some(std::process::id())),
            other => panic!("expected Busy, got {other:?}"),
        }
        drop(first);
        assert!(
            !root.path().join(".out.rsasim-lock").exists(),
            "the holder removes its lock file"
        );
        assert!(OutputLock::acquire(root.path(), "out").is_ok());
    }

    #[test]
    fn a_lock_file_removed_after_opening_is_not_held() {
        // What a second writer sees when the first removes the file between the second's open
        // and lock: the open file is no longer the one the path names.
        let root = tempfile::tempdir().unwrap();
        let path = root.path().join(".out.rsasim-lock");
        let stale = open_lock_file(&path).unwrap();
        assert!(still_named(&stale, &path));
        std::fs::remove_file(&path).unwrap();
        assert!(!still_named(&stale, &path));
        std::fs::write(&path, "").unwrap();
        assert!(
            !still_named(&stale, &path),
            "a new file at the path is another file"
        );
    }

    #[test]
    fn a_file_put_in_place_of_the_lock_file_is_not_removed() {
        let root = tempfile::tempdir().unwrap();
        let lock = OutputLock::acquire(root.path(), "out").unwrap();
        let path = root.path().join(".out.rsasim-lock");
        std::fs::remove_file(&path).unwrap();
        std::fs::write(&path, "someone else's").unwrap();
        drop(lock);
        assert_eq!(std::fs::read(&path).unwrap(), b"someone else's");
    }

    #[cfg(unix)]
    #[test]
    fn a_symbolic_link_as_lock_file_is_refused() {
        let root = tempfile::tempdir().unwrap();
        std::fs::write(root.path().join("victim"), "keep").unwrap();
        std::os::unix::fs::symlink("victim", root.path().join(".out.rsasim-lock")).unwrap();
        assert!(matches!(
            OutputLock::acquire(root.path(), "out"),
            Err(LockError::Io(_))
        ));
        assert_eq!(std::fs::read(root.path().join("victim")).unwrap(), b"keep");
    }
}
