//! Reading an output folder's truth files and a software's results: one `measured.json` per run
//! folder, or one CSV long table for the whole protocol. Every problem is a diagnostic that names
//! the file, the line and the field.
//!
//! # CSV long table
//!
//! One row per (run, entity); header names the columns, in any order:
//!
//! | column | meaning |
//! |---|---|
//! | `run` | run id, e.g. `n2-r07` |
//! | `kind` | `source`, `detector` or `phantom` |
//! | `id` | the entity's id, as in `truth.json` |
//! | `x_mm`, `y_mm`, `z_mm` | position in the box frame, mm |
//! | `r11` … `r33` (optional) | rotation matrix, row-major (`r12` = row 1, column 2); columns are the local axes |
//! | `qw`, `qx`, `qy`, `qz` (optional) | or the rotation as a unit quaternion (scalar first) |
//!
//! Give either the nine `r` columns or the four `q` columns (or neither, for positions only); a
//! row may leave the rotation cells empty (sources always do).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3};

use super::rotation::{checked_rotation, rotation_from_quaternion};
use crate::diagnostic::{Diagnostic, KeyPath};
use crate::output::{MEASURED_FORMAT, Measured, Truth};

/// One run's truth and where it came from.
pub struct TruthRun {
    /// The run folder.
    pub dir: PathBuf,
    /// Its `truth.json`.
    pub truth: Truth,
}

/// What a software reported for one run, parsed and checked.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunMeasurement {
    /// The software's name and version.
    pub software: String,
    /// Source positions by id.
    pub sources: BTreeMap<String, DVec3>,
    /// Detector poses by id (rotation optional).
    pub detectors: BTreeMap<String, (DVec3, Option<DMat3>)>,
    /// Phantom poses by id (rotation optional).
    pub phantoms: BTreeMap<String, (DVec3, Option<DMat3>)>,
}

/// Every run folder's `truth.json` under `out/runs`, in protocol order.
pub fn load_truths(out: &Path) -> Result<Vec<TruthRun>, Vec<Diagnostic>> {
    load_truths_from(out, out)
}

/// Every `truth_root/runs/<id>/truth.json`, in protocol order, each with its run folder under
/// `results_root/runs/<id>` (where the software under test wrote its results). The two roots
/// differ in the blind layout (truth folder, images folder).
pub fn load_truths_from(
    truth_root: &Path,
    results_root: &Path,
) -> Result<Vec<TruthRun>, Vec<Diagnostic>> {
    let runs = truth_root.join("runs");
    let entries = std::fs::read_dir(&runs).map_err(|e| {
        vec![Diagnostic::file_error(&runs, format!("cannot list the run folders: {e}"))
            .with_help("give the output folder of `rsasim SCENARIO.toml` (it holds manifest.json and runs/)")]
    })?;
    let mut out_runs = Vec::new();
    let mut errors = Vec::new();
    for entry in entries.flatten() {
        let dir = entry.path();
        if !dir.is_dir() {
            continue;
        }
        let file = dir.join("truth.json");
        let dir = results_root.join("runs").join(entry.file_name());
        match std::fs::read(&file) {
            Ok(bytes) => match serde_json::from_slice::<Truth>(&bytes) {
                Ok(truth) => out_runs.push(TruthRun { dir, truth }),
                Err(e) => errors.push(json_error(&file, &e)),
            },
            Err(e) => errors.push(Diagnostic::file_error(
                &file,
                format!("cannot read truth: {e}"),
            )),
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    if out_runs.is_empty() {
        return Err(vec![
            Diagnostic::file_error(&runs, "no run folder with a truth.json")
                .with_help("run the scenario first: rsasim SCENARIO.toml --out DIR"),
        ]);
    }
    out_runs.sort_by_key(|r| (r.truth.run.noise_level_index, r.truth.run.run_index));
    Ok(out_runs)
}

fn json_error(file: &Path, e: &serde_json::Error) -> Diagnostic {
    let mut d = Diagnostic::file_error(file, format!("invalid JSON: {e}"));
    if e.line() > 0 {
        d.line_col = Some((e.line(), e.column()));
    }
    d.with_help("the file must follow schemas/measured.schema.json (truth files: schemas/truth.schema.json)")
}

/// The 1-based line of the first `"value"` string after the first `"section"` key, to point at
/// an entity inside a JSON file (serde_json keeps no spans).
fn json_line(text: &str, section: &str, value: &str) -> Option<(usize, usize)> {
    let start = text.find(&format!("\"{section}\""))?;
    let at = start + text[start..].find(&format!("\"{value}\""))?;
    let line = text[..at].matches('\n').count() + 1;
    let col = at - text[..at].rfind('\n').map_or(0, |i| i + 1) + 1;
    Some((line, col))
}

/// Reads one run's `measured.json`, checking the run id, every entity id against `truth`, and
/// every rotation.
pub fn load_measured_json(file: &Path, truth: &Truth) -> Result<RunMeasurement, Vec<Diagnostic>> {
    let text = std::fs::read_to_string(file)
        .map_err(|e| vec![Diagnostic::file_error(file, format!("cannot read: {e}"))])?;
    let m: Measured = serde_json::from_str(&text).map_err(|e| vec![json_error(file, &e)])?;
    let mut errors = Vec::new();
    let err = |section: &str,
               index: Option<usize>,
               field: &str,
               value: &str,
               message: String,
               help: &str| {
        let mut path = KeyPath::root().key(section);
        if let Some(i) = index {
            path = path.index(i);
        }
        if !field.is_empty() {
            path = path.key(field);
        }
        let mut d = Diagnostic::file_error(file, message).with_help(help);
        d.key_path = Some(path);
        d.line_col = json_line(&text, section, value);
        d
    };
    if m.format != MEASURED_FORMAT {
        errors.push(err(
            "format",
            None,
            "",
            &m.format,
            format!("unknown format `{}`", m.format),
            "use \"rsasim-measured/1\"",
        ));
    }
    if m.run != truth.run.id {
        errors.push(err(
            "run",
            None,
            "",
            &m.run,
            format!(
                "the file says run `{}` but lies in the folder of run `{}`",
                m.run, truth.run.id
            ),
            "write each run's result into that run's folder",
        ));
    }
    let mut out = RunMeasurement {
        software: m.software.clone(),
        ..Default::default()
    };
    for (i, s) in m.sources.iter().enumerate() {
        match entity_position(
            &s.id,
            s.position_mm,
            truth.run.sources.iter().map(|x| x.id.as_str()),
            "source",
        ) {
            Ok(p) => {
                out.sources.insert(s.id.clone(), p);
            }
            Err((field, msg, help)) => {
                errors.push(err("sources", Some(i), field, &s.id, msg, &help))
            }
        }
    }
    for (section, list, known, target) in [
        (
            "detectors",
            &m.detectors,
            truth
                .run
                .detectors
                .iter()
                .map(|x| x.id.clone())
                .collect::<Vec<_>>(),
            &mut out.detectors,
        ),
        (
            "phantoms",
            &m.phantoms,
            truth
                .run
                .phantoms
                .iter()
                .map(|x| x.id.clone())
                .collect::<Vec<_>>(),
            &mut out.phantoms,
        ),
    ] {
        for (i, e) in list.iter().enumerate() {
            let what = &section[..section.len() - 1];
            let pos = entity_position(&e.id, e.position_mm, known.iter().map(String::as_str), what);
            let rot = e.rotation.map(checked_rotation).transpose();
            match (pos, rot) {
                (Ok(p), Ok(r)) => {
                    target.insert(e.id.clone(), (p, r));
                }
                (Err((field, msg, help)), _) => {
                    errors.push(err(section, Some(i), field, &e.id, msg, &help))
                }
                (_, Err(msg)) => errors.push(err(
                    section,
                    Some(i),
                    "rotation",
                    &e.id,
                    format!("{what} `{}`: {msg}", e.id),
                    "write the rotation as three rows of an orthonormal matrix with determinant +1",
                )),
            }
        }
    }
    if errors.is_empty() {
        Ok(out)
    } else {
        Err(errors)
    }
}

type EntityError = (&'static str, String, String);

fn entity_position<'a>(
    id: &str,
    p: [f64; 3],
    mut known: impl Iterator<Item = &'a str>,
    what: &str,
) -> Result<DVec3, EntityError> {
    let known_list: Vec<&str> = known.by_ref().collect();
    if !known_list.contains(&id) {
        return Err((
            "id",
            format!("no {what} has the id `{id}` in truth.json"),
            format!("valid {what} ids: {}", known_list.join(", ")),
        ));
    }
    if p.iter().any(|x| !x.is_finite()) {
        return Err((
            "position_mm",
            format!("{what} `{id}`: position {p:?} is not finite"),
            "give three finite numbers in mm".into(),
        ));
    }
    Ok(DVec3::from_array(p))
}

/// Reads a CSV long table (see the module doc) holding every run's results. Errors name the
/// line and the column.
pub fn load_measured_csv(
    file: &Path,
    truths: &[TruthRun],
) -> Result<BTreeMap<String, RunMeasurement>, Vec<Diagnostic>> {
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(file)
        .map_err(|e| vec![Diagnostic::file_error(file, format!("cannot read: {e}"))])?;
    let headers = reader
        .headers()
        .map_err(|e| {
            vec![Diagnostic::file_error(
                file,
                format!("cannot read the header: {e}"),
            )]
        })?
        .clone();
    let col = |name: &str| headers.iter().position(|h| h == name);
    let at = |line: usize, field: &str, message: String, help: &str| {
        let mut d = Diagnostic::file_error(file, message).with_help(help);
        d.line_col = Some((line, 1));
        d.key_path = Some(KeyPath::root().key(field));
        d
    };
    let required = ["run", "kind", "id", "x_mm", "y_mm", "z_mm"];
    let missing: Vec<&str> = required
        .iter()
        .copied()
        .filter(|c| col(c).is_none())
        .collect();
    if !missing.is_empty() {
        return Err(vec![at(
            1,
            missing[0],
            format!("the header lacks the column(s) {}", missing.join(", ")),
            "the header needs run,kind,id,x_mm,y_mm,z_mm and optionally r11..r33 or qw,qx,qy,qz",
        )]);
    }
    let matrix: Option<Vec<usize>> = (1..=3)
        .flat_map(|r| (1..=3).map(move |c| format!("r{r}{c}")))
        .map(|n| col(&n))
        .collect();
    let quat: Option<Vec<usize>> = ["qw", "qx", "qy", "qz"].iter().map(|n| col(n)).collect();
    let software = format!(
        "{} (CSV)",
        file.file_name().unwrap_or_default().to_string_lossy()
    );
    let mut out: BTreeMap<String, RunMeasurement> = BTreeMap::new();
    let mut errors = Vec::new();
    for (k, record) in reader.records().enumerate() {
        let line = k + 2;
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                errors.push(at(
                    line,
                    "row",
                    format!("malformed row: {e}"),
                    "every row needs as many fields as the header",
                ));
                continue;
            }
        };
        let get = |name: &str| record.get(col(name).expect("checked column")).unwrap_or("");
        let number = |name: &str| -> Result<f64, Box<Diagnostic>> {
            let v = get(name);
            v.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    Box::new(at(
                        line,
                        name,
                        format!("`{name}` = `{v}` is not a finite number"),
                        "use a decimal number such as 12.5 or -0.003",
                    ))
                })
        };
        let run_id = get("run").to_string();
        let Some(truth) = truths.iter().find(|t| t.truth.run.id == run_id) else {
            errors.push(at(
                line,
                "run",
                format!("no run `{run_id}` in the output folder"),
                "use the run ids of the runs/ folders, e.g. n0-r00",
            ));
            continue;
        };
        let (kind, id) = (get("kind").to_string(), get("id").to_string());
        let position = match (number("x_mm"), number("y_mm"), number("z_mm")) {
            (Ok(x), Ok(y), Ok(z)) => DVec3::new(x, y, z),
            (a, b, c) => {
                errors.extend(
                    [a.err(), b.err(), c.err()]
                        .into_iter()
                        .flatten()
                        .map(|d| *d),
                );
                continue;
            }
        };
        let rotation = match parse_rotation(&record, matrix.as_deref(), quat.as_deref()) {
            Ok(r) => r,
            Err((field, msg)) => {
                errors.push(at(line, &field, msg, "give an orthonormal rotation (r11..r33, row-major) or a unit quaternion (qw,qx,qy,qz), or leave all empty"));
                continue;
            }
        };
        let entry = out.entry(run_id.clone()).or_insert_with(|| RunMeasurement {
            software: software.clone(),
            ..Default::default()
        });
        let run = &truth.truth.run;
        let known: Vec<&str> = match kind.as_str() {
            "source" => run.sources.iter().map(|x| x.id.as_str()).collect(),
            "detector" => run.detectors.iter().map(|x| x.id.as_str()).collect(),
            "phantom" => run.phantoms.iter().map(|x| x.id.as_str()).collect(),
            _ => {
                errors.push(at(
                    line,
                    "kind",
                    format!("unknown kind `{kind}`"),
                    "kind is source, detector or phantom",
                ));
                continue;
            }
        };
        if !known.contains(&id.as_str()) {
            errors.push(at(
                line,
                "id",
                format!("no {kind} has the id `{id}` in run {run_id}"),
                &format!("valid {kind} ids: {}", known.join(", ")),
            ));
            continue;
        }
        match kind.as_str() {
            "source" => drop(entry.sources.insert(id, position)),
            "detector" => drop(entry.detectors.insert(id, (position, rotation))),
            _ => drop(entry.phantoms.insert(id, (position, rotation))),
        }
    }
    if errors.is_empty() {
        Ok(out)
    } else {
        Err(errors)
    }
}

fn parse_rotation(
    record: &csv::StringRecord,
    matrix: Option<&[usize]>,
    quat: Option<&[usize]>,
) -> Result<Option<DMat3>, (String, String)> {
    let cells = |cols: &[usize]| -> Vec<String> {
        cols.iter()
            .map(|&c| record.get(c).unwrap_or("").to_string())
            .collect()
    };
    let numbers = |cols: &[usize],
                   names: &dyn Fn(usize) -> String|
     -> Result<Option<Vec<f64>>, (String, String)> {
        let values = cells(cols);
        if values.iter().all(String::is_empty) {
            return Ok(None);
        }
        values
            .iter()
            .enumerate()
            .map(|(i, v)| {
                v.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| {
                        (
                            names(i),
                            format!("`{}` = `{v}` is not a finite number", names(i)),
                        )
                    })
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
    };
    if let Some(cols) = matrix
        && let Some(v) = numbers(cols, &|i| format!("r{}{}", i / 3 + 1, i % 3 + 1))?
    {
        let rows = [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]];
        return checked_rotation(rows)
            .map(Some)
            .map_err(|m| ("r11".into(), m));
    }
    if let Some(cols) = quat
        && let Some(v) = numbers(cols, &|i| ["qw", "qx", "qy", "qz"][i].to_string())?
    {
        return rotation_from_quaternion(v[0], v[1], v[2], v[3])
            .map(Some)
            .map_err(|m| ("qw".into(), m));
    }
    Ok(None)
}
