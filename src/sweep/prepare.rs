//! A sweep made ready to write: every point's scenario text built from the base scenario and
//! checked as the main command checks a scenario (values, meshes, cost, geometry of every run),
//! before anything is written. A point's problem is reported at the sweep file's value that made
//! it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use sha2::{Digest, Sha256};

use super::file::{MAX_POINTS, MAX_POINTS_LARGE, SweepFile};
use super::points::{choices, point_id, set_at, value_text};
use crate::diagnostic::{Diagnostic, KeyPath, Severity};
use crate::scenario::{self, hex};
use crate::simulate::{self, Allowances};

/// Folder of the point scenarios inside a sweep folder.
pub const POINTS_DIR: &str = "points";
/// Folder of the files the point scenarios read (meshes, spectra), inside [`POINTS_DIR`].
pub const INPUTS_DIR: &str = "inputs";

/// One parameter of a sweep, resolved.
#[derive(Debug, Clone)]
pub struct Parameter {
    /// Key path as written, e.g. `sources.tube2.position_mm`.
    pub key: String,
    /// What it is (`name`, or the key).
    pub name: String,
    /// The values as compact TOML text.
    pub values: Vec<String>,
    /// A number per value for summaries and plots: the `axis` given, else the value when it is a
    /// number.
    pub axis: Vec<Option<f64>>,
}

/// One point: a standalone scenario.
#[derive(Debug, Clone)]
pub struct Point {
    /// `p00`, `p01`, …
    pub id: String,
    /// The index of the value each parameter takes.
    pub choice: Vec<usize>,
    /// The scenario file's text.
    pub text: String,
    /// SHA-256 of `text`.
    pub sha256: String,
    /// Number of runs of its protocol (or study).
    pub runs: usize,
}

/// A sweep expanded and checked, nothing written yet.
pub struct Sweep {
    /// The sweep file.
    pub file: SweepFile,
    /// The base scenario's name.
    pub base_name: String,
    /// SHA-256 of the base scenario file.
    pub base_sha256: String,
    /// The parameters.
    pub parameters: Vec<Parameter>,
    /// The points, in sweep order.
    pub points: Vec<Point>,
    /// Files the points read, by name in `points/inputs/`.
    pub inputs: BTreeMap<String, Arc<Vec<u8>>>,
}

impl Sweep {
    /// `key = value` of every parameter at `point`, joined by `, `.
    pub fn assignments(&self, point: &Point) -> String {
        assignments(&self.parameters, &point.choice)
    }
}

/// `key = value` of every parameter for the value indices `choice`, joined by `, `.
fn assignments(parameters: &[Parameter], choice: &[usize]) -> String {
    parameters
        .iter()
        .zip(choice)
        .map(|(p, &c)| format!("{} = {}", p.key, p.values[c]))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The base scenario's errors, each also naming the sweep file's `scenario` value that chose the
/// file (`sweep.toml:3:12`): a path that leads to the wrong file (a typo, `/etc/hosts`) is then
/// corrected where it was written, not searched for in the file it reached.
fn named_by_sweep(file: &SweepFile, errors: Vec<Diagnostic>) -> Vec<Diagnostic> {
    let at = KeyPath::root().key("scenario");
    let (line, col) = file
        .locator
        .span_of(&at)
        .map(|span| file.locator.line_col(span.start).0)
        .unwrap_or((1, 1));
    let origin = format!(
        "{} is the base scenario named by `scenario` at {}:{line}:{col}; if it is not the file you meant, correct the path there",
        file.scenario_path.display(),
        file.locator.file().display()
    );
    errors
        .into_iter()
        .map(|d| {
            if d.file != file.scenario_path {
                return d;
            }
            let help = match &d.help {
                Some(h) => format!("{h}\n  = note: {origin}"),
                None => origin.clone(),
            };
            d.with_help(help)
        })
        .collect()
}

/// Reads the sweep file and its base scenario, builds every point's scenario and checks it like
/// the main command (warnings are left to the run of each point, which names its file; with `allow`: `--allow-dir`, `--allow-large`, which also raises the cap of
/// [`MAX_POINTS`] points to [`MAX_POINTS_LARGE`]). Every point shares the base scenario's seed unless the sweep varies
/// `seed` itself.
pub fn prepare(path: &Path, allow: &Allowances) -> Result<Sweep, Vec<Diagnostic>> {
    let file = SweepFile::read(path)?;
    file.point_count(if allow.large {
        MAX_POINTS_LARGE
    } else {
        MAX_POINTS
    })?;
    let scenario_at = KeyPath::root().key("scenario");
    if !file.scenario_path.is_file() {
        return Err(vec![
            file.locator
                .error(
                    scenario_at,
                    format!(
                        "the base scenario {} is not a file",
                        file.scenario_path.display()
                    ),
                )
                .with_help("give the scenario's path relative to the sweep file, e.g. scenario = \"../biplanar.toml\""),
        ]);
    }
    let named_by = |errors: Vec<Diagnostic>| named_by_sweep(&file, errors);
    let base = scenario::load(&file.scenario_path).map_err(named_by)?;
    let base_text = crate::input_file::read_named_text(
        &file.scenario_path,
        crate::scenario::MAX_SCENARIO_BYTES,
    )
    .map_err(|d| named_by(vec![d]))?;
    let base_doc: toml::Table = base_text.parse().map_err(|e: toml::de::Error| {
        named_by(vec![Diagnostic::file_error(
            &file.scenario_path,
            e.message().to_string(),
        )])
    })?;
    let parameters = resolve_parameters(&file);
    let all = choices(&file.record);
    let mut points = Vec::with_capacity(all.len());
    let mut inputs = BTreeMap::new();
    let mut errors = Vec::new();
    for (index, choice) in all.iter().enumerate() {
        let id = point_id(index, all.len());
        let mut doc = base_doc.clone();
        let mut paths = Vec::new();
        for (i, (p, &c)) in file.record.parameters.iter().zip(choice).enumerate() {
            match set_at(&mut doc, &p.key, p.values[c].clone()) {
                Ok(path) => paths.push(path),
                Err(why) => {
                    // The same for every point: reported once, at the key.
                    return Err(vec![
                        file.locator
                            .error(SweepFile::parameter_path(i, "key"), why)
                            .with_help("a key path names tables by key and arrays of tables by the `id` of a table, e.g. \"detectors.det2.position_mm\" (see schemas/scenario.schema.json)"),
                    ]);
                }
            }
        }
        if !file.record.parameters.iter().any(|p| p.key == "name") {
            doc.insert(
                "name".into(),
                toml::Value::String(format!("{}-{id}", base.scenario.name)),
            );
        }
        let shown = PathBuf::from(POINTS_DIR).join(format!("{id}.toml"));
        let header = header(&file, &parameters, &id, choice, &base.sha256);
        let point_errors = |ds: Vec<Diagnostic>| -> Vec<Diagnostic> {
            ds.into_iter()
                .map(|d| at_sweep_value(&file, &parameters, &paths, &id, choice, d))
                .collect()
        };
        let draft = format!("{header}{}", toml_text(&doc));
        let checked = scenario::from_text(&draft, &shown, &base.base_dir)
            .and_then(|mut loaded| {
                loaded.allowed_dirs = allow.dirs.clone();
                simulate::check_loaded(loaded, allow.large)
            })
            .map_err(point_errors);
        let checked = match checked {
            Ok(c) => c,
            Err(e) => {
                errors.extend(e);
                continue;
            }
        };
        // The files the point reads, copied beside it: the point stands alone.
        for (i, model) in checked.models.iter().enumerate() {
            let (Some(file_path), Some(pkg)) = (&model.mesh_file, &model.mesh_package) else {
                continue;
            };
            let sha = hex(&Sha256::digest(pkg.bytes.as_slice()));
            let name = format!("{}-{}.{}", model.id, &sha[..16], pkg.extension);
            let unit_mm = checked
                .loaded
                .scenario
                .phantoms
                .get(i)
                .and_then(|p| p.mesh.as_ref())
                .and_then(|m| m.unit_mm)
                .unwrap_or_else(|| crate::phantom::mesh_io::default_unit_mm(file_path));
            if let Some(toml::Value::Table(mesh)) = doc
                .get_mut("phantoms")
                .and_then(|p| p.get_mut(i))
                .and_then(|p| p.get_mut("mesh"))
            {
                mesh.insert(
                    "file".into(),
                    toml::Value::String(format!("{INPUTS_DIR}/{name}")),
                );
                mesh.insert("unit_mm".into(), toml::Value::Float(unit_mm));
            }
            inputs.insert(name, pkg.bytes.clone());
        }
        if let Some(bytes) = checked
            .setup
            .as_ref()
            .and_then(|s| s.spectrum_file_bytes.as_ref())
        {
            let sha = hex(&Sha256::digest(bytes));
            let name = format!("spectrum-{}.tsv", &sha[..16]);
            if let Some(toml::Value::Table(imaging)) = doc.get_mut("imaging") {
                imaging.insert(
                    "spectrum_file".into(),
                    toml::Value::String(format!("{INPUTS_DIR}/{name}")),
                );
            }
            inputs.insert(name, Arc::new(bytes.clone()));
        }
        let text = format!("{header}{}", toml_text(&doc));
        // The final text parses as the draft did (only file paths changed).
        scenario::from_text(&text, &shown, &base.base_dir).map_err(point_errors)?;
        points.push(Point {
            sha256: hex(&Sha256::digest(text.as_bytes())),
            runs: usize::try_from(checked.loaded.scenario.run_count()).unwrap_or(usize::MAX),
            id,
            choice: choice.clone(),
            text,
        });
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    Ok(Sweep {
        base_name: base.scenario.name.clone(),
        base_sha256: base.sha256.clone(),
        file,
        parameters,
        points,
        inputs,
    })
}

/// The parameters with their display names, values as text and axis numbers.
fn resolve_parameters(file: &SweepFile) -> Vec<Parameter> {
    file.record
        .parameters
        .iter()
        .map(|p| Parameter {
            key: p.key.clone(),
            name: p.name.clone().unwrap_or_else(|| p.key.clone()),
            values: p.values.iter().map(value_text).collect(),
            axis: match &p.axis {
                Some(axis) => axis.iter().map(|&a| Some(a)).collect(),
                None => p
                    .values
                    .iter()
                    .map(|v| match v {
                        toml::Value::Integer(i) => Some(*i as f64),
                        toml::Value::Float(f) => Some(*f),
                        _ => None,
                    })
                    .collect(),
            },
        })
        .collect()
}

/// The comment block at the top of a point's scenario: what it is and how to run it alone.
fn header(
    file: &SweepFile,
    parameters: &[Parameter],
    id: &str,
    choice: &[usize],
    base_sha256: &str,
) -> String {
    let mut s = format!(
        "# Point {id} of the sweep `{}` (written by `rsasim sweep`): the base scenario (SHA-256\n# {base_sha256}) with\n",
        file.name
    );
    for (p, &c) in parameters.iter().zip(choice) {
        s += &format!("#   {} = {}\n", p.key, p.values[c]);
    }
    s += &format!(
        "# and mesh and spectrum paths pointing at copies in {INPUTS_DIR}/. It stands alone:\n# `rsasim {id}.toml --out DIR` writes the same bytes as the sweep's {id}/.\n\n"
    );
    s
}

/// A scenario table as TOML text (arrays of numbers on one line).
fn toml_text(doc: &toml::Table) -> String {
    toml::to_string(doc).unwrap_or_else(|e| format!("# not serialisable: {e}\n"))
}

/// A point's diagnostic restated at the sweep file's value that made the point: the parameter
/// whose key path leads to (or lies under) the diagnostic's, else the first varied one.
fn at_sweep_value(
    file: &SweepFile,
    parameters: &[Parameter],
    paths: &[KeyPath],
    id: &str,
    choice: &[usize],
    d: Diagnostic,
) -> Diagnostic {
    let related = |p: &KeyPath| {
        d.key_path.as_ref().is_some_and(|k| {
            let n = p.0.len().min(k.0.len());
            n > 0 && p.0[..n] == k.0[..n]
        })
    };
    let j = paths
        .iter()
        .position(related)
        .or_else(|| parameters.iter().position(|p| p.values.len() > 1))
        .unwrap_or(0);
    let mut message = format!("point {id} ({}): ", assignments(parameters, choice));
    if let Some(k) = d.key_path.as_ref().filter(|k| !k.0.is_empty()) {
        message += &format!("the scenario's `{k}`: ");
    }
    message += &d.message;
    let sweep_path =
        SweepFile::parameter_path(j, "values").index(choice.get(j).copied().unwrap_or(0));
    let mut out = file.locator.at(d.severity, sweep_path, message);
    out.help = d.help.or_else(|| {
        (d.severity == Severity::Error)
            .then(|| "change or remove this value; the scenario's rules are in the manual, docs/src/reference/scenario.md".into())
    });
    out
}
