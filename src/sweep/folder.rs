//! The sweep folder: its index (`sweep.json`), the point scenarios and the files they read, and
//! the claim that keeps a second writer out and resumes a sweep that stopped.
//!
//! ```text
//! DIR/
//!   sweep.toml          the sweep file as given
//!   sweep.json          the index: program, parameters, every point with its values and hash
//!   points/<id>.toml    each point's scenario, standalone
//!   points/inputs/      the meshes (and spectra) the points read
//!   <id>/               each point's output folder (the main command's layout)
//!   shards/<id>/        a sharded sweep's shards of each point (shard-K-of-N/), until merged
//!   sweep-report/       the summary (`rsasim evaluate DIR`, `rsasim sweep … --evaluate`)
//! ```

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::prepare::{INPUTS_DIR, POINTS_DIR, Sweep};
use crate::diagnostic::Diagnostic;
use crate::output::atomic::{Once, is_partial, write_once};
use crate::output::commit::guard::{self, Existing};
use crate::output::commit::lock::{LockError, OutputLock};
use crate::output::received::{MAX_JSON_BYTES, ReceivedFolder, check_name};
use crate::scenario::hex;

/// The index file of a sweep folder.
pub const INDEX: &str = "sweep.json";
/// The index's format tag.
pub const FORMAT: &str = "rsasim-sweep/1";
/// The copy of the sweep file in the sweep folder.
pub const SWEEP_COPY: &str = "sweep.toml";
/// The summary folder's default name.
pub const REPORT_DIR: &str = "sweep-report";
/// The folder of a sharded sweep's shards: `shards/<point id>/shard-K-of-N/`.
pub const SHARDS_DIR: &str = "shards";

/// `sweep.json`: what the sweep folder holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Index {
    /// Always [`FORMAT`].
    pub format: String,
    /// `rsasim <version>` that wrote the folder.
    pub program: String,
    /// The sweep's name.
    pub name: String,
    /// SHA-256 of the sweep file (`sweep.toml`).
    pub sweep_sha256: String,
    /// The base scenario's name.
    pub scenario: String,
    /// SHA-256 of the base scenario file.
    pub scenario_sha256: String,
    /// `grid` or `zip`.
    pub combine: String,
    /// The parameters, in the sweep file's order.
    pub parameters: Vec<IndexParameter>,
    /// The points, in sweep order.
    pub points: Vec<IndexPoint>,
}

/// A parameter in `sweep.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IndexParameter {
    /// Key path into the scenario.
    pub key: String,
    /// Display name (the key unless the sweep names it).
    pub name: String,
}

/// A point in `sweep.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IndexPoint {
    /// `p00`, `p01`, …: also the output folder's name.
    pub id: String,
    /// The point's scenario, relative to the sweep folder.
    pub scenario: String,
    /// SHA-256 of that scenario file (the `scenario_sha256` of the point's manifest).
    pub scenario_sha256: String,
    /// Every parameter's value as TOML text.
    pub values: Vec<String>,
    /// Every parameter's number for plots (the sweep's `axis`, or the value when it is a
    /// number; null otherwise).
    pub axis: Vec<Option<f64>>,
}

impl Index {
    /// The index of a prepared sweep.
    pub fn of(sweep: &Sweep) -> Index {
        Index {
            format: FORMAT.into(),
            program: crate::output::program(),
            name: sweep.file.name.clone(),
            sweep_sha256: hex(&<sha2::Sha256 as sha2::Digest>::digest(&sweep.file.bytes)),
            scenario: sweep.base_name.clone(),
            scenario_sha256: sweep.base_sha256.clone(),
            combine: match sweep.file.record.combine {
                super::file::Combine::Grid => "grid".into(),
                super::file::Combine::Zip => "zip".into(),
            },
            parameters: sweep
                .parameters
                .iter()
                .map(|p| IndexParameter {
                    key: p.key.clone(),
                    name: p.name.clone(),
                })
                .collect(),
            points: sweep
                .points
                .iter()
                .map(|pt| IndexPoint {
                    id: pt.id.clone(),
                    scenario: format!("{POINTS_DIR}/{}.toml", pt.id),
                    scenario_sha256: pt.sha256.clone(),
                    values: sweep
                        .parameters
                        .iter()
                        .zip(&pt.choice)
                        .map(|(p, &c)| p.values[c].clone())
                        .collect(),
                    axis: sweep
                        .parameters
                        .iter()
                        .zip(&pt.choice)
                        .map(|(p, &c)| p.axis[c])
                        .collect(),
                })
                .collect(),
        }
    }

    /// The file's bytes: pretty JSON with a final newline.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut v = serde_json::to_vec_pretty(self).unwrap_or_default();
        v.push(b'\n');
        v
    }
}

/// Whether `dir` holds a sweep index.
pub fn is_sweep_folder(dir: &Path) -> bool {
    // Anything named sweep.json makes a sweep folder, so that a FIFO or a link there is refused
    // by name when the index is read, not taken for an ordinary output.
    std::fs::symlink_metadata(dir.join(INDEX)).is_ok()
}

/// Reads the index of the sweep folder `dir`; errors name the file. The index is the sender's
/// (a received sweep folder): it is read through the gate for received folders, its point ids
/// must be plain names, each once, and its scenario paths the ones rsasim writes, so that no
/// point leads out of the folder.
pub fn read_index(dir: &Path) -> Result<Index, Vec<Diagnostic>> {
    let path = dir.join(INDEX);
    let bytes = ReceivedFolder::unlisted(dir)
        .read(INDEX, MAX_JSON_BYTES)
        .map_err(|d| vec![d])?;
    let index: Index = serde_json::from_slice(&bytes).map_err(|e| {
        vec![
            Diagnostic::file_error(
                &path,
                format!(
                    "not a sweep index: {}",
                    crate::diagnostic::cut(&e.to_string())
                ),
            )
            .with_help("a sweep folder is written by `rsasim sweep FILE --out DIR`"),
        ]
    })?;
    if index.format != FORMAT {
        return Err(vec![Diagnostic::file_error(
            &path,
            format!(
                "`format` is {:?}, not `{FORMAT}`",
                crate::diagnostic::cut(&index.format)
            ),
        )]);
    }
    let mut seen = std::collections::HashSet::with_capacity(index.points.len());
    for point in &index.points {
        check_name(&path, "points[].id", &point.id).map_err(|d| vec![d])?;
        if !seen.insert(point.id.as_str()) {
            return Err(vec![Diagnostic::file_error(
                &path,
                format!("`points[].id` {:?} appears twice", point.id),
            )
            .with_help("a sweep folder is written by `rsasim sweep FILE --out DIR`: ask the sender for the folder as rsasim wrote it")]);
        }
        if point.values.len() != index.parameters.len()
            || point.axis.len() != index.parameters.len()
        {
            return Err(vec![Diagnostic::file_error(
                &path,
                format!(
                    "point {}: `values` has {} and `axis` {} entries for the {} parameters",
                    point.id,
                    point.values.len(),
                    point.axis.len(),
                    index.parameters.len()
                ),
            )
            .with_help("a sweep folder is written by `rsasim sweep FILE --out DIR`: ask the sender for the folder as rsasim wrote it")]);
        }
        if point.scenario != format!("{POINTS_DIR}/{}.toml", point.id) {
            return Err(vec![Diagnostic::file_error(
                &path,
                format!(
                    "point {}: `scenario` is {:?}, not {POINTS_DIR}/{}.toml as rsasim writes it",
                    point.id,
                    crate::diagnostic::cut(&point.scenario),
                    point.id
                ),
            )]);
        }
    }
    Ok(index)
}

/// The output folder of `point` in the received sweep folder `dir`, checked before anything reads
/// or writes it: a real folder (not a symbolic link) whose manifest names the scenario SHA-256
/// that `sweep.json` lists for the point.
pub fn point_folder(dir: &Path, point: &IndexPoint) -> Result<PathBuf, Vec<Diagnostic>> {
    let out = dir.join(&point.id);
    let meta = std::fs::symlink_metadata(&out).map_err(|e| {
        vec![
            Diagnostic::file_error(
                &out,
                format!(
                    "point {}: its output folder cannot be read: {}",
                    point.id,
                    crate::input_file::reason(&e)
                ),
            )
            .with_help("run the sweep first: rsasim sweep FILE --out DIR"),
        ]
    })?;
    if !meta.is_dir() {
        return Err(vec![Diagnostic::file_error(
            &out,
            format!(
                "point {}: its output is a {}, not a folder: a sweep folder's points are never followed out of it",
                point.id,
                crate::input_file::kind(&meta)
            ),
        )
        .with_help("ask the sender for the sweep folder as rsasim wrote it")]);
    }
    let manifest_file = out.join("manifest.json");
    let (manifest, _) = crate::output::verify::read_manifest(&out)
        .map_err(|f| vec![Diagnostic::file_error(&manifest_file, f.problem)])?;
    if manifest.scenario_sha256.as_deref() != Some(point.scenario_sha256.as_str()) {
        return Err(vec![Diagnostic::file_error(
            &manifest_file,
            format!(
                "`scenario_sha256` is {:?}, but sweep.json lists point {} with {}",
                manifest
                    .scenario_sha256
                    .as_deref()
                    .map(crate::diagnostic::cut),
                point.id,
                crate::diagnostic::cut(&point.scenario_sha256)
            ),
        )
        .with_help("the point's folder holds the output of another scenario: ask the sender for the sweep folder as rsasim wrote it")]);
    }
    Ok(out)
}

/// A sweep folder claimed by this process (with the lock on it, held until dropped), or joined
/// by one task of a sharded sweep (without).
pub struct SweepFolder {
    _lock: Option<OutputLock>,
    /// The folder.
    pub dir: PathBuf,
    /// Per point: its output is already there, complete, from an earlier run of the same sweep.
    pub done: Vec<bool>,
    index: Index,
}

/// Why the sweep folder's own files were not written.
#[derive(Debug)]
pub enum WriteError {
    /// A file there holds other bytes than this sweep writes (exit 2).
    Input(Vec<Diagnostic>),
    /// The file system failed (exit 1).
    Io(std::io::Error),
}

fn refusal(dir: &Path, message: String, help: &str) -> Vec<Diagnostic> {
    vec![Diagnostic::file_error(dir, message).with_help(help)]
}

const NEW_HELP: &str =
    "give a new folder with --out (rsasim never writes into a folder it did not make)";

/// Whether the existing sweep folder `path` holds the sweep of `index` (`Ok(true)`), is absent or
/// empty (`Ok(false)`), or is something else (refused). Temporary files of a writer that is
/// still placing its files ([`write_once`]) do not count.
fn existing_sweep(dir: &Path, path: &Path, index: &Index) -> Result<bool, Vec<Diagnostic>> {
    let existing = guard::existing(path).map_err(|e| {
        refusal(
            dir,
            format!("cannot look at the sweep folder: {e}"),
            NEW_HELP,
        )
    })?;
    match existing {
        Existing::Absent => Ok(false),
        Existing::Symlink => Err(refusal(
            dir,
            "the sweep folder is a symbolic link; rsasim never writes through a link".into(),
            NEW_HELP,
        )),
        Existing::NotFolder => Err(refusal(
            dir,
            "the sweep folder names a file".into(),
            NEW_HELP,
        )),
        Existing::Folder => {
            let empty = std::fs::read_dir(path).is_ok_and(|mut d| {
                d.all(|e| e.is_ok_and(|e| is_partial(&e.file_name().to_string_lossy())))
            });
            if empty {
                return Ok(false);
            }
            match ReceivedFolder::unlisted(path).read(INDEX, MAX_JSON_BYTES) {
                Ok(bytes) if bytes == index.to_bytes() => Ok(true),
                Ok(_) => Err(refusal(
                    dir,
                    format!(
                        "the folder holds another sweep (its {INDEX} differs: another sweep file, base scenario or program version)"
                    ),
                    NEW_HELP,
                )),
                Err(_) => Err(refusal(
                    dir,
                    format!("the folder exists and is not a sweep folder (no {INDEX})"),
                    NEW_HELP,
                )),
            }
        }
    }
}

/// Claims `dir` for `sweep`: a new or empty folder, or the folder of an earlier run of the same
/// sweep by the same program (its `sweep.json` identical), whose complete point outputs are kept
/// and whose missing ones are run (a stopped sweep resumes). Anything else is refused: a file, a
/// link, another folder, a point folder that is not the complete output of its point. The lock
/// `.<name>.rsasim-lock` beside it keeps a second sweep out.
pub fn claim(sweep: &Sweep, dir: &Path) -> Result<SweepFolder, Vec<Diagnostic>> {
    let resolved = guard::resolve(dir).map_err(|d| vec![*d])?;
    let index = Index::of(sweep);
    let resume = existing_sweep(dir, &resolved.path, &index)?;
    std::fs::create_dir_all(&resolved.parent).map_err(|e| {
        refusal(
            dir,
            format!("cannot create {}: {e}", resolved.parent.display()),
            "check that the folder of --out can be written to",
        )
    })?;
    let lock = OutputLock::acquire(&resolved.parent, &resolved.name).map_err(|e| match e {
        LockError::Busy(pid) => refusal(
            dir,
            format!(
                "another rsasim process ({}) is writing this sweep folder",
                pid.map_or("pid unknown".to_string(), |p| format!("pid {p}"))
            ),
            "wait for it to finish, or give another folder with --out",
        ),
        LockError::Io(e) => refusal(
            dir,
            format!("cannot take the lock beside the sweep folder: {e}"),
            "check that the folder of --out can be written to",
        ),
    })?;
    let mut done = Vec::with_capacity(index.points.len());
    for p in &index.points {
        let out = resolved.path.join(&p.id);
        let present = resume && std::fs::symlink_metadata(&out).is_ok();
        if present {
            if let Err(why) = point_output_matches(&out, &p.scenario_sha256) {
                return Err(refusal(
                    dir,
                    format!(
                        "{} is not the complete output of point {}: {why}",
                        out.display(),
                        p.id
                    ),
                    "move that folder away and run the sweep again (its other points are kept)",
                ));
            }
        }
        done.push(present);
    }
    Ok(SweepFolder {
        _lock: Some(lock),
        dir: dir.to_path_buf(),
        done,
        index,
    })
}

/// Joins `dir` as one task of a sharded sweep (`rsasim sweep FILE --shard K/N`). The tasks of an
/// array job write the folder at the same time, so no task locks it (each shard folder has its
/// own lock); otherwise the rules of [`claim`] hold: a new or empty folder, or the folder of the
/// same sweep by the same program. The sweep's own files are then written once, by whichever
/// task comes first, and checked by the others ([`SweepFolder::write_points`]). A point whose
/// output is already complete in `dir` (run whole, or merged) is done and needs no shard.
pub fn join(sweep: &Sweep, dir: &Path) -> Result<SweepFolder, Vec<Diagnostic>> {
    let resolved = guard::resolve(dir).map_err(|d| vec![*d])?;
    let index = Index::of(sweep);
    let resume = existing_sweep(dir, &resolved.path, &index)?;
    let done = index
        .points
        .iter()
        .map(|p| {
            resume && point_output_matches(&resolved.path.join(&p.id), &p.scenario_sha256).is_ok()
        })
        .collect();
    Ok(SweepFolder {
        _lock: None,
        dir: dir.to_path_buf(),
        done,
        index,
    })
}

/// `Ok` when `out` is a complete simulation output of the scenario with hash `sha256`.
fn point_output_matches(out: &Path, sha256: &str) -> Result<(), String> {
    guard::complete_output(out)?;
    let (manifest, _) = crate::output::verify::read_manifest(out)
        .map_err(|_| "its manifest.json cannot be read".to_string())?;
    match manifest.scenario_sha256.as_deref() {
        Some(s) if s == sha256 => Ok(()),
        _ => Err("its manifest names another scenario".into()),
    }
}

/// Makes the folder `path` if it is absent; a real folder there is used as it is. Anything else
/// (a file, a FIFO, a symbolic link, which could lead the writes elsewhere) is an input error
/// naming it: rsasim writes only into folders, never through a link.
fn real_folder(path: &Path) -> Result<(), WriteError> {
    match std::fs::symlink_metadata(path) {
        Ok(meta) if meta.is_dir() => Ok(()),
        Ok(meta) => Err(WriteError::Input(vec![
            Diagnostic::file_error(
                path,
                format!(
                    "is a {}, where the sweep keeps a folder",
                    crate::input_file::kind(&meta)
                ),
            )
            .with_help("move it away and run again; rsasim writes only into folders it made"),
        ])),
        // create_dir_all: the sweep folder's own parents may be new too; a folder another task
        // of a sharded sweep made meanwhile is fine, and one that is not a folder fails.
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            std::fs::create_dir_all(path).map_err(WriteError::Io)
        }
        Err(e) => Err(WriteError::Io(e)),
    }
}

impl SweepFolder {
    /// Writes the sweep's own files, each once ([`write_once`]): the index first (so a folder
    /// rsasim is filling is either empty or names its sweep), then the sweep file's copy, the
    /// files the points read and the point scenarios. A file already there with the same bytes
    /// (a resumed sweep, another task of a sharded one) is left as it is; one with other bytes
    /// is an input error naming it, and nothing there is replaced.
    pub fn write_points(&self, sweep: &Sweep) -> Result<(), WriteError> {
        let once = |path: PathBuf, bytes: &[u8]| -> Result<Option<Diagnostic>, WriteError> {
            Ok((write_once(&path, bytes).map_err(WriteError::Io)? == Once::Different).then(|| {
                Diagnostic::file_error(
                    &path,
                    "holds other bytes than this sweep writes there (changed after rsasim wrote it?)",
                )
                .with_help("move it away and run again; rsasim never replaces a file in a sweep folder")
            }))
        };
        real_folder(&self.dir)?;
        if let Some(d) = once(self.dir.join(INDEX), &self.index.to_bytes())? {
            // Another sweep was quicker into this folder: nothing of this one is written.
            return Err(WriteError::Input(vec![d]));
        }
        let points = self.dir.join(POINTS_DIR);
        let inputs = points.join(INPUTS_DIR);
        real_folder(&points)?;
        real_folder(&inputs)?;
        let mut differing = Vec::new();
        differing.extend(once(self.dir.join(SWEEP_COPY), &sweep.file.bytes)?);
        for (name, bytes) in &sweep.inputs {
            differing.extend(once(inputs.join(name), bytes)?);
        }
        for p in &sweep.points {
            differing.extend(once(self.point_scenario(&p.id), p.text.as_bytes())?);
        }
        if differing.is_empty() {
            Ok(())
        } else {
            Err(WriteError::Input(differing))
        }
    }

    /// The folder of point `id`'s shards: `DIR/shards/<id>/` (holding `shard-K-of-N/`).
    pub fn point_shards(&self, id: &str) -> PathBuf {
        self.dir.join(SHARDS_DIR).join(id)
    }

    /// The scenario file of point `id`.
    pub fn point_scenario(&self, id: &str) -> PathBuf {
        self.dir.join(POINTS_DIR).join(format!("{id}.toml"))
    }

    /// The output folder of point `id`.
    pub fn point_out(&self, id: &str) -> PathBuf {
        self.dir.join(id)
    }
}
