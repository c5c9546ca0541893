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
//!   sweep-report/       the summary (`rsasim evaluate DIR`, `rsasim sweep … --evaluate`)
//! ```

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::prepare::{INPUTS_DIR, POINTS_DIR, Sweep};
use crate::diagnostic::Diagnostic;
use crate::output::atomic::write_atomic;
use crate::output::commit::guard::{self, Existing};
use crate::output::commit::lock::{LockError, OutputLock};
use crate::scenario::hex;

/// The index file of a sweep folder.
pub const INDEX: &str = "sweep.json";
/// The index's format tag.
pub const FORMAT: &str = "rsasim-sweep/1";
/// The copy of the sweep file in the sweep folder.
pub const SWEEP_COPY: &str = "sweep.toml";
/// The summary folder's default name.
pub const REPORT_DIR: &str = "sweep-report";

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
    dir.join(INDEX).is_file()
}

/// Reads the index of the sweep folder `dir`; errors name the file.
pub fn read_index(dir: &Path) -> Result<Index, Vec<Diagnostic>> {
    let path = dir.join(INDEX);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        vec![Diagnostic::file_error(
            &path,
            format!("cannot read it: {e}"),
        )]
    })?;
    let index: Index = serde_json::from_str(&text).map_err(|e| {
        vec![
            Diagnostic::file_error(&path, format!("not a sweep index: {e}"))
                .with_help("a sweep folder is written by `rsasim sweep FILE --out DIR`"),
        ]
    })?;
    if index.format != FORMAT {
        return Err(vec![Diagnostic::file_error(
            &path,
            format!("format `{}`, not `{FORMAT}`", index.format),
        )]);
    }
    Ok(index)
}

/// A sweep folder claimed by this process (its lock is held until dropped).
pub struct SweepFolder {
    _lock: OutputLock,
    /// The folder.
    pub dir: PathBuf,
    /// Per point: its output is already there, complete, from an earlier run of the same sweep.
    pub done: Vec<bool>,
    index: Index,
}

/// Claims `dir` for `sweep`: a new or empty folder, or the folder of an earlier run of the same
/// sweep by the same program (its `sweep.json` identical), whose complete point outputs are kept
/// and whose missing ones are run (a stopped sweep resumes). Anything else is refused: a file, a
/// link, another folder, a point folder that is not the complete output of its point. The lock
/// `.<name>.rsasim-lock` beside it keeps a second sweep out.
pub fn claim(sweep: &Sweep, dir: &Path) -> Result<SweepFolder, Vec<Diagnostic>> {
    let resolved = guard::resolve(dir).map_err(|d| vec![*d])?;
    let refuse =
        |message: String, help: &str| vec![Diagnostic::file_error(dir, message).with_help(help)];
    let index = Index::of(sweep);
    let new_help =
        "give a new folder with --out (rsasim never writes into a folder it did not make)";
    let existing = guard::existing(&resolved.path)
        .map_err(|e| refuse(format!("cannot look at the sweep folder: {e}"), new_help))?;
    let resume = match existing {
        Existing::Absent => false,
        Existing::Symlink => {
            return Err(refuse(
                "the sweep folder is a symbolic link; rsasim never writes through a link".into(),
                new_help,
            ));
        }
        Existing::NotFolder => {
            return Err(refuse("the sweep folder names a file".into(), new_help));
        }
        Existing::Folder => {
            let empty = std::fs::read_dir(&resolved.path).is_ok_and(|mut d| d.next().is_none());
            if !empty {
                match std::fs::read(resolved.path.join(INDEX)) {
                    Ok(bytes) if bytes == index.to_bytes() => {}
                    Ok(_) => {
                        return Err(refuse(
                            format!(
                                "the folder holds another sweep (its {INDEX} differs: another sweep file, base scenario or program version)"
                            ),
                            new_help,
                        ));
                    }
                    Err(_) => {
                        return Err(refuse(
                            format!("the folder exists and is not a sweep folder (no {INDEX})"),
                            new_help,
                        ));
                    }
                }
            }
            !empty
        }
    };
    std::fs::create_dir_all(&resolved.parent).map_err(|e| {
        refuse(
            format!("cannot create {}: {e}", resolved.parent.display()),
            "check that the folder of --out can be written to",
        )
    })?;
    let lock = OutputLock::acquire(&resolved.parent, &resolved.name).map_err(|e| match e {
        LockError::Busy(pid) => refuse(
            format!(
                "another rsasim process ({}) is writing this sweep folder",
                pid.map_or("pid unknown".to_string(), |p| format!("pid {p}"))
            ),
            "wait for it to finish, or give another folder with --out",
        ),
        LockError::Io(e) => refuse(
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
                return Err(refuse(
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
        _lock: lock,
        dir: dir.to_path_buf(),
        done,
        index,
    })
}

/// `Ok` when `out` is a complete simulation output of the scenario with hash `sha256`.
fn point_output_matches(out: &Path, sha256: &str) -> Result<(), String> {
    guard::complete_output(out)?;
    let manifest: serde_json::Value = std::fs::read(out.join("manifest.json"))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok())
        .ok_or("its manifest.json cannot be read")?;
    match manifest.get("scenario_sha256").and_then(|s| s.as_str()) {
        Some(s) if s == sha256 => Ok(()),
        _ => Err("its manifest names another scenario".into()),
    }
}

impl SweepFolder {
    /// Writes the sweep file's copy, the point scenarios, the files they read and the index,
    /// each atomically (identical bytes when the sweep resumes).
    pub fn write_points(&self, sweep: &Sweep) -> std::io::Result<()> {
        let inputs = self.dir.join(POINTS_DIR).join(INPUTS_DIR);
        std::fs::create_dir_all(&inputs)?;
        write_atomic(&self.dir.join(SWEEP_COPY), &sweep.file.bytes)?;
        for (name, bytes) in &sweep.inputs {
            write_atomic(&inputs.join(name), bytes)?;
        }
        for p in &sweep.points {
            write_atomic(&self.point_scenario(&p.id), p.text.as_bytes())?;
        }
        write_atomic(&self.dir.join(INDEX), &self.index.to_bytes())?;
        Ok(())
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
