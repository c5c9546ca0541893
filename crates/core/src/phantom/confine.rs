//! Confinement: the one rule for every file a scenario pulls in (mesh files, glTF buffers and
//! images). Such a file is read only if it is a regular file inside the scenario file's folder or
//! inside a folder allowed explicitly (`--allow-dir`), after `..`, percent-encoding (decoded by
//! the caller) and symbolic links are resolved: the path is canonicalised and its canonical form
//! must start with one of the canonical allowed roots. Devices, FIFOs, sockets, folders and
//! anything under `/proc`, `/sys` or `/dev` (but `/dev/shm`, a tmpfs for data) are refused before they are opened; the file is then
//! opened without following a last symbolic link and without blocking, and the opened file is
//! checked again (same file, still regular, still within the size limit) before it is read.
//!
//! Messages name the path (cut to [`MAX_SHOWN_CHARS`]) and never a byte of a file's contents.

use std::fs::{File, Metadata};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Largest file that is read (a mesh file, a glTF buffer or image), in bytes: 512 MiB.
pub const MAX_INPUT_BYTES: u64 = 512 * 1024 * 1024;

/// Longest path, URI or name shown in a message, in characters; longer ones are cut with `…`.
pub const MAX_SHOWN_CHARS: usize = 120;

/// System folders whose "files" are not data, refused whatever the allowed roots are.
const SYSTEM_ROOTS: [&str; 3] = ["/proc", "/sys", "/dev"];

/// Folders under the system folders that hold ordinary files: `/dev/shm` is a tmpfs, a usual
/// scratch place for data (its devices, if any, are refused as not regular files all the same).
const DATA_UNDER_SYSTEM: [&str; 1] = ["/dev/shm"];

/// Whether `canonical` lies in a system folder whose files are not data.
fn is_system(canonical: &Path) -> bool {
    SYSTEM_ROOTS.iter().any(|r| canonical.starts_with(r))
        && !DATA_UNDER_SYSTEM.iter().any(|r| canonical.starts_with(r))
}

/// The folders files may be read from, canonicalised.
#[derive(Debug, Clone)]
pub struct Confinement {
    roots: Vec<PathBuf>,
}

impl Confinement {
    /// Files may be read from `base_dir` (the scenario file's folder; "" means the current
    /// folder) and from every folder of `allowed`. The error names a folder that does not exist
    /// or is not a folder.
    pub fn new(base_dir: &Path, allowed: &[PathBuf]) -> Result<Self, String> {
        let mut roots = Vec::with_capacity(1 + allowed.len());
        for dir in std::iter::once(base_dir).chain(allowed.iter().map(PathBuf::as_path)) {
            roots.push(canonical_dir(dir)?);
        }
        Ok(Confinement { roots })
    }

    /// The canonical allowed folders, the scenario's folder first.
    pub fn roots(&self) -> &[PathBuf] {
        &self.roots
    }

    /// Checks, without opening it, that the rule allows reading `path` and that it holds at
    /// most `limit` bytes; the error is the one [`Confinement::read`] would give.
    pub fn check(&self, path: &Path, limit: u64) -> Result<(), String> {
        self.resolve(path, limit).map(|_| ())
    }

    /// The canonical path and metadata of `path` if the rule allows it.
    fn resolve(&self, path: &Path, limit: u64) -> Result<(PathBuf, Metadata), String> {
        let shown = shown_path(path);
        let canonical = std::fs::canonicalize(non_empty(path)).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => format!("{shown} does not exist"),
            _ => format!("{shown} cannot be resolved: {}", io_reason(&e)),
        })?;
        if is_system(&canonical) {
            return Err(format!(
                "{shown} resolves to {}, a system file: only regular files inside the scenario's folder (or a folder given with --allow-dir) are read",
                shown_path(&canonical)
            ));
        }
        if !self.roots.iter().any(|r| canonical.starts_with(r)) {
            return Err(format!(
                "{shown} resolves to {}, outside the folders files may be read from ({})",
                shown_path(&canonical),
                self.roots
                    .iter()
                    .map(|r| shown_path(r))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        let meta = std::fs::symlink_metadata(&canonical)
            .map_err(|e| format!("{shown} cannot be inspected: {}", io_reason(&e)))?;
        check_regular(&shown, &meta, limit)?;
        Ok((canonical, meta))
    }

    /// Reads `path` if the rule allows it and it holds at most `limit` bytes. The error says
    /// why the file is refused (outside the allowed folders, not a regular file, too large,
    /// missing) without any of its contents.
    pub fn read(&self, path: &Path, limit: u64) -> Result<Vec<u8>, String> {
        let shown = shown_path(path);
        let (canonical, before) = self.resolve(path, limit)?;
        let file = open_no_follow(&canonical)
            .map_err(|e| format!("{shown} cannot be opened: {}", io_reason(&e)))?;
        let after = file
            .metadata()
            .map_err(|e| format!("{shown} cannot be inspected: {}", io_reason(&e)))?;
        check_regular(&shown, &after, limit)?;
        if !same_file(&before, &after) {
            return Err(format!(
                "{shown} was replaced while it was being opened: run again on a folder nobody is changing"
            ));
        }
        let mut bytes = Vec::with_capacity(after.len() as usize);
        file.take(limit.saturating_add(1))
            .read_to_end(&mut bytes)
            .map_err(|e| format!("{shown} cannot be read: {}", io_reason(&e)))?;
        if bytes.len() as u64 > limit {
            return Err(format!(
                "{shown} grew beyond the limit of {limit} bytes while it was read"
            ));
        }
        Ok(bytes)
    }
}

/// Canonical form of an allowed folder; the error says it does not exist or is not a folder.
pub fn canonical_dir(dir: &Path) -> Result<PathBuf, String> {
    let canonical = std::fs::canonicalize(non_empty(dir)).map_err(|e| {
        format!(
            "folder {} cannot be used: {}",
            shown_path(dir),
            io_reason(&e)
        )
    })?;
    if !canonical.is_dir() {
        return Err(format!("{} is not a folder", shown_path(dir)));
    }
    Ok(canonical)
}

/// `path` for display: control characters replaced by `?`, cut to [`MAX_SHOWN_CHARS`].
pub fn shown_path(path: &Path) -> String {
    shorten(&path.to_string_lossy())
}

/// `text` for display: control characters replaced by `?`, cut to [`MAX_SHOWN_CHARS`]
/// characters with a final `…` when longer.
pub fn shorten(text: &str) -> String {
    let mut out: String = text
        .chars()
        .take(MAX_SHOWN_CHARS)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    if text.chars().nth(MAX_SHOWN_CHARS).is_some() {
        out.push('…');
    }
    out
}

/// "" (the parent of a bare file name) is the current folder.
fn non_empty(path: &Path) -> &Path {
    if path.as_os_str().is_empty() {
        Path::new(".")
    } else {
        path
    }
}

/// The reason of an I/O error without the path (the caller names it).
fn io_reason(e: &std::io::Error) -> String {
    let text = e.to_string();
    shorten(text.split(" (os error").next().unwrap_or(&text))
}

/// Refuses anything but a regular file of at most `limit` bytes, naming what it is instead.
fn check_regular(shown: &str, meta: &Metadata, limit: u64) -> Result<(), String> {
    let kind = crate::input_file::kind(meta);
    if kind != "regular file" {
        return Err(format!(
            "{shown} is a {kind}, not a regular file: only regular files are read"
        ));
    }
    if meta.len() > limit {
        return Err(format!(
            "{shown} holds {} bytes, more than the limit of {limit} bytes ({} MiB) for one input file",
            meta.len(),
            limit / (1024 * 1024)
        ));
    }
    Ok(())
}

/// Opens for reading without following a final symbolic link and without blocking (a FIFO
/// swapped in after the check cannot hang the program).
fn open_no_follow(path: &Path) -> std::io::Result<File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK | libc::O_NOCTTY);
    }
    options.open(path)
}

/// Whether two metadata records describe the same file.
fn same_file(a: &Metadata, b: &Metadata) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        a.dev() == b.dev() && a.ino() == b.ino()
    }
    #[cfg(not(unix))]
    {
        a.len() == b.len()
    }
}

#[cfg(test)]
mod tests;
