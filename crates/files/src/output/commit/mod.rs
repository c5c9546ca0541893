//! Safe output commits: claim an output folder (checks, one-writer lock, recovery of what killed
//! runs left), stage the new folder beside it in a folder private to this process, and swap it in
//! only when complete, durably.
//!
//! The life of an output, for `rsasim SCENARIO --out OUT` and for `evaluate`'s report folder:
//! 1. [`OutputTarget::claim`] resolves OUT and refuses (exit 2, before any work) what must not be
//!    replaced ([`guard::check`]); takes the lock `.<name>.rsasim-lock` beside OUT (a second
//!    process is refused at once); restores an old output a killed swap left aside and removes
//!    marked staging folders of killed runs, saying so.
//! 2. [`OutputTarget::stage`] creates `.<name>.rsasim-staging-<pid>-<random>/` beside OUT with a
//!    marker file; everything is written there.
//! 3. [`Staged::commit`] checks OUT did not change since the claim, renames the old OUT aside,
//!    the staging folder to OUT, then removes the old one; every folder and rename is synced.
//!    Dropping a [`Staged`] without committing removes the staging folder (a failed run leaves
//!    the previous output as it was).

pub mod durable;
pub mod guard;
pub mod interrupt;
pub mod lock;
pub mod staging;

use std::path::{Path, PathBuf};

use crate::diagnostic::Diagnostic;
pub use guard::FolderKind;
use guard::Resolved;
use lock::{LockError, OutputLock};

/// The identity of what is at the target, to notice a change under us.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Identity(Option<(u64, u64, Option<std::time::SystemTime>)>);

impl Identity {
    fn of(path: &Path) -> Identity {
        Identity(std::fs::symlink_metadata(path).ok().map(|m| {
            #[cfg(unix)]
            let (dev, ino) = {
                use std::os::unix::fs::MetadataExt;
                (m.dev(), m.ino())
            };
            #[cfg(not(unix))]
            let (dev, ino) = (0, 0);
            (dev, ino, m.modified().ok())
        }))
    }
}

/// An output folder claimed by this process: checked, locked, cleaned of leftovers.
#[derive(Debug)]
pub struct OutputTarget {
    resolved: Resolved,
    kind: FolderKind,
    _lock: OutputLock,
    identity: Identity,
    /// What the claim did (leftovers removed, an old output restored), for the user.
    pub notes: Vec<String>,
}

impl OutputTarget {
    /// Claims `out` for writing a folder of `kind`; every refusal is an error for the user
    /// (exit 2) and leaves everything as it was.
    pub fn claim(out: &Path, kind: FolderKind) -> Result<OutputTarget, Box<Diagnostic>> {
        let resolved = guard::resolve(out)?;
        guard::check(&resolved, &kind)?;
        let io_error = |what: &str, e: std::io::Error| {
            Box::new(
                Diagnostic::file_error(out, format!("cannot {what}: {e}"))
                    .with_help("check that the folder of --out exists and can be written to"),
            )
        };
        std::fs::create_dir_all(&resolved.parent)
            .map_err(|e| io_error(&format!("create {}", resolved.parent.display()), e))?;
        let lock = match OutputLock::acquire(&resolved.parent, &resolved.name) {
            Ok(lock) => lock,
            Err(LockError::Busy(pid)) => {
                let pid = pid.map_or("pid unknown".to_string(), |p| format!("pid {p}"));
                return Err(Box::new(
                    Diagnostic::file_error(
                        out,
                        format!(
                            "another rsasim process ({pid}) is writing {}",
                            out.display()
                        ),
                    )
                    .with_help("wait for it to finish, or write elsewhere with --out"),
                ));
            }
            Err(LockError::Io(e)) => return Err(io_error("lock the output folder", e)),
        };
        let notes = staging::recover(&resolved.parent, &resolved.name, &resolved.path, out, &kind)
            .map_err(|e| io_error("clean up after an interrupted run", e))?;
        // Recovery may have restored the target: check again, now under the lock.
        guard::check(&resolved, &kind)?;
        Ok(OutputTarget {
            identity: Identity::of(&resolved.path),
            resolved,
            kind,
            _lock: lock,
            notes,
        })
    }

    /// The output folder as the user named it.
    pub fn shown(&self) -> &Path {
        &self.resolved.shown
    }

    /// The output folder's own name (resolved: `--out .` gives the current folder's name).
    pub fn name(&self) -> &str {
        &self.resolved.name
    }

    /// Creates this process's staging folder beside the target.
    pub fn stage(self) -> std::io::Result<Staged> {
        let prefix = staging::staging_prefix(&self.resolved.name);
        let path = staging::create_unique_dir(&self.resolved.parent, &prefix)?;
        interrupt::register(&path, &self.resolved.shown);
        let staged = Staged {
            path,
            target: self,
            committed: false,
        };
        std::fs::write(
            staged.path.join(staging::STAGING_MARKER),
            b"rsasim staging folder: an unfinished output; the next run into the same output removes it\n",
        )?;
        Ok(staged)
    }
}

/// A staging folder being written; becomes the output on [`Staged::commit`], is removed when
/// dropped uncommitted.
#[derive(Debug)]
pub struct Staged {
    path: PathBuf,
    target: OutputTarget,
    committed: bool,
}

/// What a commit did.
#[derive(Debug)]
pub struct Committed {
    /// The output folder as the user named it.
    pub path: PathBuf,
    /// Anything the user should know (an old output that could not be removed).
    pub notes: Vec<String>,
}

impl Staged {
    /// The folder files are written into now.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Swaps the finished folder in (see the module documentation).
    pub fn commit(mut self) -> std::io::Result<Committed> {
        let t = &self.target;
        if Identity::of(&t.resolved.path) != t.identity {
            return Err(std::io::Error::other(format!(
                "{} changed while rsasim was writing (another program wrote or removed it); nothing was replaced",
                t.resolved.shown.display()
            )));
        }
        if matches!(t.kind, FolderKind::Report) {
            std::fs::write(
                self.path.join(guard::REPORT_MARKER),
                b"written by rsasim evaluate, which replaces this folder on its next run\n",
            )?;
        }
        let notes = staging::swap(
            &t.resolved.parent,
            &t.resolved.name,
            &self.path,
            &t.resolved.path,
        )?;
        self.committed = true;
        interrupt::unregister(&self.path);
        Ok(Committed {
            path: self.target.resolved.shown.clone(),
            notes,
        })
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.committed {
            let _ = staging::remove_marked(&self.path, staging::STAGING_MARKER);
            interrupt::unregister(&self.path);
        }
    }
}
