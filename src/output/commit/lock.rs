//! One writer per output: an exclusive lock on a file beside the target, held for the whole run.

use std::fs::{File, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

/// An exclusive lock on `.<name>.rsasim-lock` beside an output folder; released when dropped or
/// when the process ends in any way (the operating system drops it, even after kill -9). The lock
/// file itself stays: removing it would let two processes lock two different files.
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
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(LockError::Io)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let mut text = String::new();
                let _ = file.read_to_string(&mut text);
                return Err(LockError::Busy(text.trim().parse().ok()));
            }
            Err(TryLockError::Error(e)) => return Err(LockError::Io(e)),
        }
        // The pid, for the message another process prints; best effort.
        let _ = file
            .set_len(0)
            .and_then(|()| file.rewind())
            .and_then(|()| write!(file, "{}", std::process::id()))
            .and_then(|()| file.flush());
        Ok(OutputLock { _file: file, path })
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
        assert!(OutputLock::acquire(root.path(), "out").is_ok());
    }
}
