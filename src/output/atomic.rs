//! Writing files so that no reader ever sees a truncated file under its final name.

use std::io::Write;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::scenario::hex;

/// Writes `bytes` to a temporary file beside `path`, syncs it, then renames it over `path`.
/// Returns the SHA-256 of the bytes, lowercase hex.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<String> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut builder = tempfile::Builder::new();
    builder.prefix(".rsasim-").suffix(".partial");
    // Temporary files are created 0600; outputs are ordinary files for every reader (0644).
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o644));
    let mut tmp = builder.tempfile_in(dir)?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_data()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(hex(&Sha256::digest(bytes)))
}

/// An output folder under construction: files go to `<final>.partial/`, which is renamed to its
/// final name only when everything is written. An interrupted run leaves only the `.partial`
/// folder, which the next run removes.
pub struct StagedDir {
    staging: PathBuf,
    target: PathBuf,
}

impl StagedDir {
    /// Prepares to write `target`. Fails if `target` exists and `force` is false.
    pub fn create(target: &Path, force: bool) -> std::io::Result<StagedDir> {
        if target.exists() && !force {
            return Err(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                format!(
                    "output folder {} already exists; pass --force to replace it, or --out to choose another",
                    target.display()
                ),
            ));
        }
        let mut name = target.file_name().unwrap_or_default().to_os_string();
        name.push(".partial");
        let staging = target.with_file_name(name);
        if staging.exists() {
            std::fs::remove_dir_all(&staging)?;
        }
        std::fs::create_dir_all(&staging)?;
        Ok(StagedDir {
            staging,
            target: target.to_path_buf(),
        })
    }

    /// The folder files are written into now.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Moves the finished folder to its final name, replacing an old one.
    pub fn commit(self) -> std::io::Result<PathBuf> {
        if self.target.exists() {
            std::fs::remove_dir_all(&self.target)?;
        }
        std::fs::rename(&self.staging, &self.target)?;
        Ok(self.target)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn staged_folder_appears_only_on_commit_and_refuses_to_overwrite() {
        let root = tempfile::tempdir().unwrap();
        let target = root.path().join("out");
        let staged = StagedDir::create(&target, false).unwrap();
        let sha = write_atomic(&staged.path().join("a.txt"), b"abc").unwrap();
        assert_eq!(
            sha,
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        assert!(!target.exists());
        staged.commit().unwrap();
        assert_eq!(std::fs::read(target.join("a.txt")).unwrap(), b"abc");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(target.join("a.txt"))
                .unwrap()
                .permissions()
                .mode();
            assert_eq!(mode & 0o777, 0o644);
        }
        assert!(StagedDir::create(&target, false).is_err());
        let again = StagedDir::create(&target, true).unwrap();
        again.commit().unwrap();
        assert!(!target.join("a.txt").exists());
        // No temporary files are left behind.
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1);
    }
}
