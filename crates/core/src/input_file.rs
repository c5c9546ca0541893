//! Opening an input file safely: the one place where rsasim opens a file it did not write for
//! reading. A file is opened without blocking (a FIFO cannot hang the program) and, inside a
//! received folder, without following a final symbolic link; the opened file must be a regular
//! file within a size cap, and it is never read beyond the cap. Received folders add their own
//! rules on top (`rsasim::output::received`, in the crate above); scenario files and the files they pull in add the
//! confinement of [`crate::phantom::confine`].

use std::fs::{File, Metadata};
use std::io::Read;
use std::path::Path;

use crate::diagnostic::Diagnostic;

/// Longest text from a file system error shown in a message, in characters.
const SHOWN: usize = 120;

/// Reads a file the user named on the command line (symbolic links followed): a regular file of
/// at most `cap` bytes, opened without blocking.
pub fn read_named(path: &Path, cap: u64) -> Result<Vec<u8>, Diagnostic> {
    let file = open_regular(path, cap, false)?;
    read_capped(path, file, cap)
}

/// Reads a file the user named as UTF-8 text (a byte-order mark is kept; callers strip it).
pub fn read_named_text(path: &Path, cap: u64) -> Result<String, Diagnostic> {
    let bytes = read_named(path, cap)?;
    String::from_utf8(bytes).map_err(|e| {
        Diagnostic::file_error(path, format!("not UTF-8 text: {}", e.utf8_error()))
            .with_help("save the file as UTF-8")
    })
}

/// Opens `path` for reading without blocking (and, with `no_follow`, without following a final
/// symbolic link), then requires a regular file of at most `cap` bytes.
pub fn open_regular(path: &Path, cap: u64, no_follow: bool) -> Result<File, Diagnostic> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        let follow = if no_follow { libc::O_NOFOLLOW } else { 0 };
        options.custom_flags(follow | libc::O_NONBLOCK | libc::O_NOCTTY);
    }
    #[cfg(not(unix))]
    let _ = no_follow;
    let file = options.open(path).map_err(|e| {
        let link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
        if link && no_follow {
            Diagnostic::file_error(
                path,
                "is a symbolic link: files inside a received folder are never followed out of it",
            )
            .with_help("replace the link by the file it points to (a copy)")
        } else {
            Diagnostic::file_error(path, format!("cannot be read: {}", reason(&e)))
        }
    })?;
    let meta = file.metadata().map_err(|e| {
        Diagnostic::file_error(path, format!("cannot be inspected: {}", reason(&e)))
    })?;
    if !meta.is_file() {
        return Err(Diagnostic::file_error(
            path,
            format!(
                "is a {}, not a regular file: only regular files are read",
                kind(&meta)
            ),
        ));
    }
    if meta.len() > cap {
        return Err(Diagnostic::file_error(
            path,
            format!(
                "holds {} bytes, more than the limit of {cap} bytes ({} MiB) for this kind of file",
                meta.len(),
                cap / (1024 * 1024)
            ),
        ));
    }
    Ok(file)
}

/// Reads an opened file, never more than `cap` bytes.
pub fn read_capped(path: &Path, file: File, cap: u64) -> Result<Vec<u8>, Diagnostic> {
    let expected = file.metadata().map(|m| m.len()).unwrap_or(0).min(cap);
    let mut bytes = Vec::with_capacity(expected as usize);
    file.take(cap.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| Diagnostic::file_error(path, format!("cannot be read: {}", reason(&e))))?;
    if bytes.len() as u64 > cap {
        return Err(Diagnostic::file_error(
            path,
            format!("grew beyond the limit of {cap} bytes while it was read"),
        ));
    }
    Ok(bytes)
}

/// An I/O error's reason without the path and OS error number.
pub fn reason(e: &std::io::Error) -> String {
    let text = e.to_string();
    let text = text.split(" (os error").next().unwrap_or(&text);
    text.chars().take(SHOWN).collect()
}

/// What a file system entry is, in words.
pub fn kind(meta: &Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_file() {
        return "regular file";
    }
    if t.is_dir() {
        return "folder";
    }
    if t.is_symlink() {
        return "symbolic link";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "FIFO (named pipe)";
        }
        if t.is_socket() {
            return "socket";
        }
        if t.is_char_device() {
            return "character device";
        }
        if t.is_block_device() {
            return "block device";
        }
    }
    "special file"
}
