//! The gate for every file rsasim reads from a folder somebody else may have written: an output
//! folder, a truth folder, a sweep folder, shard folders, a software's results. Every byte of such
//! a folder is the sender's, its manifest too (anyone can recompute a manifest's own hash), so
//! every command that reads one goes through this module:
//!
//! - **Regular files only.** A file is opened without blocking and without following a final
//!   symbolic link, and the opened file is inspected before a byte is read: a FIFO, a device, a
//!   socket or a folder is refused, so nothing hangs on a pipe or reads a disk. Inside a received
//!   folder no part of the path below the folder may be a symbolic link either (a point folder
//!   linked to another output is refused, not followed).
//! - **A size cap** per kind of file ([`MAX_JSON_BYTES`], [`MAX_TABLE_BYTES`], [`MAX_IMAGE_BYTES`]),
//!   checked before the read and enforced during it.
//! - **The manifest's hash first.** Where the folder's `manifest.json` lists the file, its size
//!   and SHA-256 must match before it is parsed.
//! - **Names from the file are not paths.** Every string that becomes part of a path to write or
//!   read (a run id, a phantom id, an exposure name, a sweep point id) must pass [`name_problem`],
//!   the same rule as scenario ids: 1 to 100 letters, digits, `-`, `_` and `.`, not starting or
//!   ending with `.` (so never `..`, never a separator, never absolute, no control character).
//!
//! Files the user names on the command line (a results CSV, a scenario, a sweep file) follow
//! their symbolic links, as the user wrote them, but are otherwise held to the same rules
//! ([`read_named`]).

use std::collections::HashMap;
use std::fs::File;
use std::path::{Component, Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::diagnostic::Diagnostic;
use crate::input_file::{kind, open_regular, read_capped, reason};
pub use crate::input_file::{read_named, read_named_text};
use crate::scenario::hex;

/// Largest JSON file read from a received folder (`truth.json`, results, `study.json`,
/// `sweep.json`): 32 MiB, far above what rsasim writes (a truth of the paper's protocol is
/// 40 kB, a results file a few kB), and small enough that a file at the cap is parsed and
/// refused in well under a second.
pub const MAX_JSON_BYTES: u64 = 32 * 1024 * 1024;

/// Largest `manifest.json` read: 64 MiB. A manifest lists every file of a folder in about 150
/// bytes, so this is about 400,000 files (40,000 runs of a biplanar protocol in two formats); a
/// forged manifest at the cap is parsed and refused in about a second.
pub const MAX_MANIFEST_BYTES: u64 = 64 * 1024 * 1024;

/// Largest table read (bead tables, results and migration CSV files): 256 MiB.
pub const MAX_TABLE_BYTES: u64 = 256 * 1024 * 1024;

/// Largest image file read: 8 GiB (a 65,535² 16-bit image is 8.6 GB; rsasim's own are far
/// smaller).
pub const MAX_IMAGE_BYTES: u64 = 8 * 1024 * 1024 * 1024;

/// Why `name`, read from a file, cannot be used as one part of a path (the scenario id rule of
/// [`crate::scenario::id_problem`]), if it cannot.
pub fn name_problem(name: &str) -> Option<String> {
    crate::scenario::id_problem(name)
}

/// A name read from `file` at `field`, checked by [`name_problem`]; the error names the file, the
/// field and what would be valid.
pub fn check_name(file: &Path, field: &str, name: &str) -> Result<(), Diagnostic> {
    match name_problem(name) {
        None => Ok(()),
        Some(why) => Err(Diagnostic::file_error(
            file,
            format!(
                "`{field}` is {:?}, which cannot name a file or folder: {why}",
                crate::phantom::confine::shorten(name)
            ),
        )
        .with_help(
            "names in rsasim's files are 1 to 100 letters, digits, `-`, `_` and `.` (not starting or ending with `.`): this folder was not written by rsasim as it is",
        )),
    }
}

/// Reads the file `file` of a received folder (a results file in a run folder): the rules of
/// [`ReceivedFolder::read`] for its last part, without a manifest.
pub fn read_in_folder(file: &Path, cap: u64) -> Result<Vec<u8>, Diagnostic> {
    let (Some(dir), Some(name)) = (file.parent(), file.file_name().and_then(|n| n.to_str())) else {
        return Err(Diagnostic::file_error(file, "is not a file name"));
    };
    ReceivedFolder::unlisted(dir).read(name, cap)
}

/// What the manifest of a received folder says of one file.
#[derive(Debug, Clone)]
struct Listed {
    bytes: u64,
    sha256: String,
}

/// A folder received from someone else, with what its manifest lists (when it has one and it was
/// given).
#[derive(Debug, Clone)]
pub struct ReceivedFolder {
    root: PathBuf,
    listed: Option<HashMap<String, Listed>>,
}

impl ReceivedFolder {
    /// The folder `root` as the user named it, without a manifest to check files against.
    pub fn unlisted(root: &Path) -> ReceivedFolder {
        ReceivedFolder {
            root: root.to_path_buf(),
            listed: None,
        }
    }

    /// The folder `root`, whose files listed in `manifest` are checked against it when read.
    pub fn listed(root: &Path, manifest: &crate::output::Manifest) -> ReceivedFolder {
        let listed = manifest
            .files
            .iter()
            .map(|f| {
                (
                    f.path.clone(),
                    Listed {
                        bytes: f.bytes,
                        sha256: f.sha256.to_ascii_lowercase(),
                    },
                )
            })
            .collect();
        ReceivedFolder {
            root: root.to_path_buf(),
            listed: Some(listed),
        }
    }

    /// The folder as the user named it.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// `root/rel`, for messages and for commands that go on with a checked path.
    pub fn path(&self, rel: &str) -> PathBuf {
        self.root.join(rel)
    }

    /// Whether the manifest lists `rel` (`/` separators).
    pub fn lists(&self, rel: &str) -> bool {
        self.listed.as_ref().is_some_and(|l| l.contains_key(rel))
    }

    /// Whether `rel` exists below the folder (as anything, a link included).
    pub fn exists(&self, rel: &str) -> bool {
        std::fs::symlink_metadata(self.path(rel)).is_ok()
    }

    /// Reads `rel` (`/` separators): a relative path of plain names, no part of it a symbolic
    /// link, a regular file of at most `cap` bytes, with the size and SHA-256 the manifest lists
    /// for it (when it lists it).
    pub fn read(&self, rel: &str, cap: u64) -> Result<Vec<u8>, Diagnostic> {
        let path = self.checked_path(rel)?;
        let file = open_regular(&path, cap, true)?;
        let bytes = read_capped(&path, file, cap)?;
        self.check_listed(rel, &path, &bytes)?;
        Ok(bytes)
    }

    /// Opens `rel` for streaming (images, hashing): the same rules as [`ReceivedFolder::read`]
    /// except the hash, which the caller checks where it needs to (`verify` hashes every file).
    pub fn open(&self, rel: &str, cap: u64) -> Result<File, Diagnostic> {
        let path = self.checked_path(rel)?;
        open_regular(&path, cap, true)
    }

    /// The sub-folders of `rel` that are real folders (not links), sorted by name, each name
    /// checked by [`name_problem`]. Anything else in `rel` is ignored; a link to a folder is an
    /// error (it would lead out of the folder).
    pub fn sub_folders(&self, rel: &str) -> Result<Vec<String>, Diagnostic> {
        let dir = self.checked_path(rel)?;
        let meta = std::fs::symlink_metadata(&dir)
            .map_err(|e| Diagnostic::file_error(&dir, format!("cannot be read: {}", reason(&e))))?;
        if !meta.is_dir() {
            return Err(Diagnostic::file_error(
                &dir,
                format!("is a {}, not a folder", kind(&meta)),
            ));
        }
        let entries = std::fs::read_dir(&dir).map_err(|e| {
            Diagnostic::file_error(&dir, format!("cannot be listed: {}", reason(&e)))
        })?;
        let mut names = Vec::new();
        for entry in entries {
            let entry = entry.map_err(|e| {
                Diagnostic::file_error(&dir, format!("cannot be listed: {}", reason(&e)))
            })?;
            let path = entry.path();
            let meta = std::fs::symlink_metadata(&path).map_err(|e| {
                Diagnostic::file_error(&path, format!("cannot be inspected: {}", reason(&e)))
            })?;
            if meta.file_type().is_symlink() {
                if std::fs::metadata(&path).is_ok_and(|m| m.is_dir()) {
                    return Err(Diagnostic::file_error(
                        &path,
                        "is a symbolic link to a folder: folders inside a received folder are never followed out of it",
                    )
                    .with_help("replace the link by the folder it points to (a copy), or ask the sender for the folder as rsasim wrote it"));
                }
                continue;
            }
            if !meta.is_dir() {
                continue;
            }
            let name = entry.file_name();
            let Some(name) = name.to_str() else {
                return Err(Diagnostic::file_error(
                    &path,
                    "has a name that is not UTF-8: rsasim names its folders with letters, digits, `-`, `_` and `.`",
                ));
            };
            check_name(&dir, "folder name", name)?;
            names.push(name.to_string());
        }
        names.sort();
        Ok(names)
    }

    /// `root/rel` once it is known to be a real folder below the folder: a relative path of plain
    /// names, no part of it (the last included) a symbolic link.
    pub fn sub_folder(&self, rel: &str) -> Result<PathBuf, Diagnostic> {
        let path = self.checked_path(rel)?;
        match std::fs::symlink_metadata(&path) {
            Ok(meta) if meta.file_type().is_symlink() => Err(Diagnostic::file_error(
                &path,
                "is a symbolic link: folders inside a received folder are never followed out of it",
            )
            .with_help("replace the link by the folder it points to (a copy), or ask the sender for the folder as rsasim wrote it")),
            Ok(meta) if meta.is_dir() => Ok(path),
            Ok(meta) => Err(Diagnostic::file_error(
                &path,
                format!("is a {}, not a folder", kind(&meta)),
            )),
            Err(e) => Err(Diagnostic::file_error(
                &path,
                format!("cannot be read: {}", reason(&e)),
            )),
        }
    }

    /// `root/rel` once `rel` is known to be a relative path of plain names below the folder with
    /// no part a symbolic link.
    fn checked_path(&self, rel: &str) -> Result<PathBuf, Diagnostic> {
        let rel_path = Path::new(rel);
        let plain = !rel.is_empty()
            && rel_path
                .components()
                .all(|c| matches!(c, Component::Normal(_)));
        if !plain {
            return Err(Diagnostic::file_error(
                &self.root,
                format!(
                    "the path {:?} leaves the folder or is not a plain relative path",
                    crate::phantom::confine::shorten(rel)
                ),
            ));
        }
        let mut path = self.root.clone();
        let parts: Vec<Component> = rel_path.components().collect();
        for part in &parts[..parts.len() - 1] {
            path.push(part);
            match std::fs::symlink_metadata(&path) {
                Ok(meta) if meta.file_type().is_symlink() => {
                    return Err(Diagnostic::file_error(
                        &path,
                        "is a symbolic link: folders inside a received folder are never followed out of it",
                    )
                    .with_help("replace the link by the folder it points to (a copy), or ask the sender for the folder as rsasim wrote it"));
                }
                Ok(meta) if !meta.is_dir() => {
                    return Err(Diagnostic::file_error(
                        &path,
                        format!("is a {}, not a folder", kind(&meta)),
                    ));
                }
                Ok(_) => {}
                Err(e) => {
                    return Err(Diagnostic::file_error(
                        &path,
                        format!("cannot be read: {}", reason(&e)),
                    ));
                }
            }
        }
        Ok(self.root.join(rel_path))
    }

    /// Checks `bytes` against the manifest's record of `rel`, when it has one.
    fn check_listed(&self, rel: &str, path: &Path, bytes: &[u8]) -> Result<(), Diagnostic> {
        let Some(listed) = self.listed.as_ref().and_then(|l| l.get(rel)) else {
            return Ok(());
        };
        let help = "the file is not the one rsasim wrote: ask the sender for the folder as written (`rsasim verify` checks every file)";
        if bytes.len() as u64 != listed.bytes {
            return Err(Diagnostic::file_error(
                path,
                format!(
                    "holds {} bytes, but manifest.json lists {rel} with {} bytes",
                    bytes.len(),
                    listed.bytes
                ),
            )
            .with_help(help));
        }
        let sha = hex(&Sha256::digest(bytes));
        if sha != listed.sha256 {
            return Err(Diagnostic::file_error(
                path,
                format!(
                    "its SHA-256 is {sha}, but manifest.json lists {rel} with {}",
                    crate::phantom::confine::shorten(&listed.sha256)
                ),
            )
            .with_help(help));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("runs/n0-r00")).unwrap();
        std::fs::write(dir.path().join("runs/n0-r00/truth.json"), b"{}").unwrap();
        dir
    }

    #[test]
    fn reads_a_regular_file_below_the_folder() {
        let dir = folder();
        let f = ReceivedFolder::unlisted(dir.path());
        assert_eq!(f.read("runs/n0-r00/truth.json", 10).unwrap(), b"{}");
    }

    #[test]
    fn refuses_paths_that_leave_the_folder() {
        let dir = folder();
        let f = ReceivedFolder::unlisted(&dir.path().join("runs"));
        for bad in [
            "../runs/n0-r00/truth.json",
            "/etc/passwd",
            "",
            "n0-r00/../x",
        ] {
            assert!(f.read(bad, 100).is_err(), "{bad}");
        }
    }

    #[test]
    fn refuses_a_size_above_the_cap_before_reading() {
        let dir = folder();
        let f = ReceivedFolder::unlisted(dir.path());
        let e = f.read("runs/n0-r00/truth.json", 1).unwrap_err();
        assert!(e.message.contains("more than the limit of 1 bytes"), "{e}");
    }

    #[cfg(unix)]
    #[test]
    fn refuses_a_fifo_without_blocking_and_links_out_of_the_folder() {
        let dir = folder();
        let fifo = dir.path().join("runs/n0-r00/fifo");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let f = ReceivedFolder::unlisted(dir.path());
        let e = f.read("runs/n0-r00/fifo", 100).unwrap_err();
        assert!(e.message.contains("FIFO"), "{e}");
        let e = read_named(&fifo, 100).unwrap_err();
        assert!(e.message.contains("FIFO"), "{e}");

        let other = tempfile::tempdir().unwrap();
        std::fs::write(other.path().join("truth.json"), b"x").unwrap();
        std::os::unix::fs::symlink(other.path(), dir.path().join("runs/n0-r01")).unwrap();
        let e = f.read("runs/n0-r01/truth.json", 100).unwrap_err();
        assert!(e.message.contains("symbolic link"), "{e}");
        let e = f.sub_folders("runs").unwrap_err();
        assert!(e.message.contains("symbolic link"), "{e}");
        std::os::unix::fs::symlink(
            other.path().join("truth.json"),
            dir.path().join("runs/n0-r00/link.json"),
        )
        .unwrap();
        let e = f.read("runs/n0-r00/link.json", 100).unwrap_err();
        assert!(e.message.contains("symbolic link"), "{e}");
    }

    #[test]
    fn a_listed_file_must_match_the_manifest() {
        let dir = folder();
        let manifest = crate::output::Manifest {
            format: crate::output::MANIFEST_FORMAT.into(),
            manifest_sha256: String::new(),
            program: String::new(),
            build: None,
            output_format: crate::output::OUTPUT_FORMAT,
            layout: None,
            scenario: "s".into(),
            scenario_sha256: None,
            seed: None,
            runs: 1,
            images: None,
            shard: None,
            files: vec![crate::output::ManifestFile {
                path: "runs/n0-r00/truth.json".into(),
                bytes: 2,
                // SHA-256 of "{}" (sha256sum).
                sha256: "44136fa355b3678a1146ad16f7e8649e94fb4fc21fe77e8310c060f61caaff8a".into(),
            }],
        };
        let f = ReceivedFolder::listed(dir.path(), &manifest);
        assert!(f.read("runs/n0-r00/truth.json", 10).is_ok());
        std::fs::write(dir.path().join("runs/n0-r00/truth.json"), b"[]").unwrap();
        let e = f.read("runs/n0-r00/truth.json", 10).unwrap_err();
        assert!(e.message.contains("manifest.json lists"), "{e}");
    }

    #[test]
    fn names_follow_the_scenario_id_rule() {
        for bad in [
            "..", "../x", "/abs", "a/b", "a\\b", "", "a\u{7}", ".hidden", "CON",
        ] {
            assert!(name_problem(bad).is_some(), "{bad:?}");
        }
        for good in ["n0-r00", "det1", "femur_component", "p01.e3m"] {
            assert!(name_problem(good).is_none(), "{good}");
        }
    }
}
