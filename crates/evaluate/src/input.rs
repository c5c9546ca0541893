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
//!
//! # What is accepted
//!
//! - Every position must be finite and within ±[`MAX_ABS_MM`] mm of the box origin.
//! - Rotations within [`REPAIR_TOLERANCE`](super::rotation::REPAIR_TOLERANCE) of orthonormal (quaternions: of unit length) are
//!   re-orthonormalised and counted ([`RunMeasurement::repaired_rotations`]); larger deviations
//!   are errors naming the deviation.
//! - One result per run and entity: a repeated (run, kind, id) row, or a repeated id in a
//!   `measured.json` array, is an error naming both lines.
//! - A UTF-8 byte-order mark at the start of a file is ignored.
//! - Values echoed in errors are cut to [`crate::diagnostic::ECHO_MAX_CHARS`] characters.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3};

use super::rotation::{CheckedRotation, checked_rotation, rotation_from_quaternion};
use crate::diagnostic::{Diagnostic, KeyPath};
use crate::interop::xmalab_points2d::PixelOptions;
use crate::output::received::{MAX_JSON_BYTES, ReceivedFolder};
use crate::output::{MEASURED_FORMAT, Measured, Truth};

/// One run's truth and where it came from.
pub struct TruthRun {
    /// The run folder.
    pub dir: PathBuf,
    /// Its `truth.json`.
    pub truth: Truth,
}

/// The models of `run`, the phantoms scored (every one but the calibration box), in order.
pub fn model_ids(run: &rsasim_core::expand::Run) -> Vec<&str> {
    run.phantoms
        .iter()
        .filter(|p| p.kind != "calibration_box")
        .map(|p| p.id.as_str())
        .collect()
}

/// Inputs of the scoring (`assemble`, `sequence`): truth runs with their measurement (None = not measured).
pub struct Scored<'a> {
    /// The run's truth.
    pub truth: &'a TruthRun,
    /// What the software reported, if anything.
    pub measured: Option<&'a RunMeasurement>,
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
    /// Measured bead centres by phantom id, then bead id (a study's marker-based migration).
    pub markers: BTreeMap<String, BTreeMap<String, DVec3>>,
    /// Rotations that were re-orthonormalised (rounded, within [`REPAIR_TOLERANCE`](super::rotation::REPAIR_TOLERANCE)).
    pub repaired_rotations: usize,
}

/// Largest plausible |coordinate| of a measured position, mm (1 km): anything beyond is a unit
/// or format error, and would overflow the statistics. The scenario's own bound on lengths
/// ([`rsasim_core::scenario::MAX_ABS`]), which also bounds mesh vertices.
pub const MAX_ABS_MM: f64 = rsasim_core::scenario::MAX_ABS;

/// `value` cut for a message, by the one rule of [`crate::diagnostic::cut`].
fn cut(value: &str) -> String {
    crate::diagnostic::cut(value).into_owned()
}

/// The text without a leading UTF-8 byte-order mark.
fn strip_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

/// Checks that every run's truth has the same sources, detectors and phantoms as the first:
/// a folder mixing runs of different scenarios cannot be scored together.
pub fn check_same_entities(truths: &[TruthRun]) -> Result<(), Vec<Diagnostic>> {
    let ids = |t: &Truth| {
        let r = &t.run;
        (
            r.sources.iter().map(|x| x.id.clone()).collect::<Vec<_>>(),
            r.detectors.iter().map(|x| x.id.clone()).collect::<Vec<_>>(),
            r.phantoms.iter().map(|x| x.id.clone()).collect::<Vec<_>>(),
        )
    };
    let Some(first) = truths.first() else {
        return Ok(());
    };
    let reference = ids(&first.truth);
    let errors: Vec<Diagnostic> = truths
        .iter()
        .filter_map(|t| {
            let own = ids(&t.truth);
            let differs = |what: &str, a: &[String], b: &[String]| {
                (a != b).then(|| {
                    format!(
                        "{what} [{}] instead of [{}]",
                        cut(&b.join(", ")),
                        cut(&a.join(", "))
                    )
                })
            };
            let diffs: Vec<String> = [
                differs("sources", &reference.0, &own.0),
                differs("detectors", &reference.1, &own.1),
                differs("phantoms", &reference.2, &own.2),
            ]
            .into_iter()
            .flatten()
            .collect();
            (!diffs.is_empty()).then(|| {
                Diagnostic::file_error(
                    &t.dir.join("truth.json"),
                    format!(
                        "run `{}` has {} (run `{}` has the latter): the output folder mixes runs of different scenarios",
                        cut(&t.truth.run.id),
                        diffs.join("; "),
                        cut(&first.truth.run.id)
                    ),
                )
                .with_help("score each scenario's output folder on its own; remove run folders copied from another output")
            })
        })
        .collect();
    if errors.is_empty() {
        Ok(())
    } else {
        Err(errors)
    }
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
    let folder = ReceivedFolder::unlisted(truth_root);
    let names = folder.sub_folders("runs").map_err(|d| {
        vec![d.with_help(
            "give the output folder of `rsasim SCENARIO.toml` (it holds manifest.json and runs/)",
        )]
    })?;
    let mut out_runs = Vec::new();
    let mut errors = Vec::new();
    for name in names {
        let dir = results_root.join("runs").join(&name);
        match crate::output::truth::read_run_truth(&folder, &name) {
            Ok(truth) => out_runs.push(TruthRun { dir, truth }),
            Err(d) => errors.push(d),
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
    // Level, run, then frame (a sequence's frames are runs of their own).
    out_runs.sort_by_key(|r| {
        let run = &r.truth.run;
        let frame = run.frame.as_ref().map_or(0, |f| f.index);
        (run.noise_level_index, run.run_index, frame)
    });
    Ok(out_runs)
}

fn json_error(file: &Path, e: &serde_json::Error) -> Diagnostic {
    let mut d = Diagnostic::file_error(
        file,
        format!("invalid JSON: {}", cut_message(&e.to_string())),
    );
    if e.line() > 0 {
        d.line_col = Some((e.line(), e.column()));
    }
    d.with_help("the file must follow schemas/measured.schema.json (truth files: schemas/truth.schema.json)")
}

/// A parser's message with every quoted value in it cut (serde echoes offending strings whole).
fn cut_message(message: &str) -> String {
    cut_quoted(&cut_quoted(message, '`'), '"')
}

/// `message` with every part between two `quote`s cut.
fn cut_quoted(message: &str, quote: char) -> String {
    let parts: Vec<String> = message
        .split(quote)
        .enumerate()
        .map(|(i, part)| {
            if i % 2 == 1 {
                cut(part)
            } else {
                part.to_string()
            }
        })
        .collect();
    parts.join(&quote.to_string())
}

/// The 1-based line and column of the `nth` (0-based) `"value"` string after the first
/// `"section"` key.
fn json_line_nth(text: &str, section: &str, value: &str, nth: usize) -> Option<(usize, usize)> {
    let start = text.find(&format!("\"{section}\""))?;
    let needle = format!("\"{value}\"");
    let at = start + text[start..].match_indices(&needle).nth(nth)?.0;
    let line = text[..at].matches('\n').count() + 1;
    let col = at - text[..at].rfind('\n').map_or(0, |i| i + 1) + 1;
    Some((line, col))
}

/// Reads a results file in a run folder through the gate for received folders: a regular file
/// (not a link, not a FIFO) within the size cap.
pub fn read_results(file: &Path) -> Result<Vec<u8>, Vec<Diagnostic>> {
    crate::output::received::read_in_folder(file, MAX_JSON_BYTES).map_err(|d| vec![d])
}

/// A results file of this name in every run folder (or, with `results_in`, in
/// `results_in/<run id>/`), read and checked, by run id. A name ending in `.csv` is XMALab's
/// export of a trial, one ending in `.tra` Autoscoper's tracking of it, any other a
/// `measured.json`. With `results_in`, XMALab's and Autoscoper's file of a sequence is
/// `results_in/<sequence id>/<name>`, one for the sequence's trial as `rsasim export` wrote it:
/// line (or data row) k is the k-th frame of the sequence in the output
/// ([`crate::interop::trials`]). Run folders without the file are left out (their runs are
/// then excluded); every problem of the files read is an error.
pub fn load_per_run(
    name: &str,
    results_in: Option<&Path>,
    truths: &[TruthRun],
    truth_root: &Path,
    xmalab_2d: PixelOptions,
) -> Result<BTreeMap<String, RunMeasurement>, Vec<Diagnostic>> {
    let lower = name.to_ascii_lowercase();
    let client = if lower.ends_with(".csv") {
        Client::Xmalab(xmalab_2d)
    } else if lower.ends_with(".tra") {
        // Autoscoper's poses are of its volumes: the volume frame's offset in each mesh
        // phantom's frame comes from the meshes of the output (phantoms/).
        Client::Autoscoper(
            crate::output::exam::load_setup(truth_root)?
                .meshes
                .iter()
                .map(|(id, m)| (id.clone(), crate::interop::volume::frame_offset_mm(m)))
                .collect(),
        )
    } else {
        return load_json_per_run(name, truths);
    };
    let trials = crate::interop::trials::group(
        truths.iter().collect(),
        |t| &t.truth.run,
        |t| {
            truth_root
                .join("runs")
                .join(&t.truth.run.id)
                .join("truth.json")
        },
    )?;
    let mut found = BTreeMap::new();
    let mut errors = Vec::new();
    for (id, frames) in &trials {
        // A sequence's file is its trial's; a run's (or a frame's, in the run folders) its own.
        let files: Vec<(PathBuf, Vec<&TruthRun>)> = match results_in {
            Some(dir) if frames[0].truth.run.frame.is_some() => {
                vec![(dir.join(id).join(name), frames.clone())]
            }
            _ => frames
                .iter()
                .map(|t| (t.dir.join(name), vec![*t]))
                .collect(),
        };
        for (file, runs) in files {
            if !file.exists() {
                continue;
            }
            match client.read(&file, &runs) {
                Ok(results) => found.extend(results),
                Err(e) => errors.extend(e),
            }
        }
    }
    if errors.is_empty() {
        Ok(found)
    } else {
        Err(errors)
    }
}

/// `measured.json` files named `name`, one in every run folder that has one.
fn load_json_per_run(
    name: &str,
    truths: &[TruthRun],
) -> Result<BTreeMap<String, RunMeasurement>, Vec<Diagnostic>> {
    let mut found = BTreeMap::new();
    let mut errors = Vec::new();
    for t in truths {
        let file = t.dir.join(name);
        if !file.exists() {
            continue;
        }
        match load_measured_json(&file, &t.truth) {
            Ok(m) => drop(found.insert(t.truth.run.id.clone(), m)),
            Err(e) => errors.extend(e),
        }
    }
    if errors.is_empty() {
        Ok(found)
    } else {
        Err(errors)
    }
}

/// The program whose files are read, with what reading them needs.
enum Client {
    /// XMALab's CSV exports, with how its 2-D points were exported.
    Xmalab(PixelOptions),
    /// Autoscoper's `.tra`, with each mesh phantom's volume frame offset, mm.
    Autoscoper(BTreeMap<String, glam::DVec3>),
}

impl Client {
    /// The results of the frames `runs` (one trial's, in frame order) in `file`, checked, by
    /// run id.
    fn read(
        &self,
        file: &Path,
        runs: &[&TruthRun],
    ) -> Result<Vec<(String, RunMeasurement)>, Vec<Diagnostic>> {
        let truths: Vec<&Truth> = runs.iter().map(|t| &t.truth).collect();
        let measured = match self {
            Client::Xmalab(pixels) => {
                crate::interop::xmalab::read_export_frames(file, &truths, *pixels)?
            }
            Client::Autoscoper(offsets) => {
                crate::interop::autoscoper_tracking::read_tracking_frames(file, &truths, &|p| {
                    offsets.get(p).copied()
                })?
            }
        };
        measured
            .into_iter()
            .zip(truths)
            .map(|(m, truth)| check_measured(file, "", m, truth).map(|r| (truth.run.id.clone(), r)))
            .collect()
    }
}

/// Reads one run's `measured.json`, checking the run id, every entity id against `truth` (each
/// at most once), every position (finite, within [`MAX_ABS_MM`]) and every rotation.
pub fn load_measured_json(file: &Path, truth: &Truth) -> Result<RunMeasurement, Vec<Diagnostic>> {
    let bytes = read_results(file)?;
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        vec![
            Diagnostic::file_error(file, format!("not UTF-8 text: {e}"))
                .with_help("write the file as UTF-8 JSON (schemas/measured.schema.json)"),
        ]
    })?;
    let text = strip_bom(text);
    let m: Measured = serde_json::from_str(text).map_err(|e| vec![json_error(file, &e)])?;
    check_measured(file, text, m, truth)
}

/// Checks one run's results (read from `file`, whose JSON `text` locates entities for messages;
/// empty when the results were not JSON): the run id, every entity id against `truth` (each at
/// most once), every position (finite, within [`MAX_ABS_MM`]) and every rotation.
pub fn check_measured(
    file: &Path,
    text: &str,
    m: Measured,
    truth: &Truth,
) -> Result<RunMeasurement, Vec<Diagnostic>> {
    // Only the first MAX_ERRORS_PER_FILE problems are described, located (which scans the text)
    // and kept; the rest are counted without building a message, so a file of 400,000 bad
    // entries costs little more than its parse.
    let kept: std::cell::RefCell<Vec<Diagnostic>> = std::cell::RefCell::new(Vec::new());
    let more = std::cell::Cell::new(0usize);
    let report = |section: &str,
                  index: Option<usize>,
                  field: &str,
                  value: &str,
                  nth: usize,
                  describe: &dyn Fn() -> (String, String)| {
        if kept.borrow().len() >= MAX_ERRORS_PER_FILE {
            more.set(more.get() + 1);
            return;
        }
        let (message, help) = describe();
        let mut path = KeyPath::root().key(section);
        if let Some(i) = index {
            path = path.index(i);
        }
        if !field.is_empty() {
            path = path.key(field);
        }
        let mut d = Diagnostic::file_error(file, message).with_help(help);
        d.key_path = Some(path);
        d.line_col = json_line_nth(text, section, value, nth);
        kept.borrow_mut().push(d);
    };
    if m.format != MEASURED_FORMAT {
        report("format", None, "", &m.format, 0, &|| {
            (
                format!("unknown format `{}`", cut(&m.format)),
                "use \"rsasim-measured/1\"".into(),
            )
        });
    }
    if m.run != truth.run.id {
        report("run", None, "", &m.run, 0, &|| {
            (
                format!(
                    "the file says run `{}` but lies in the folder of run `{}` ({})",
                    cut(&m.run),
                    truth.run.id,
                    file.parent().unwrap_or(file).display()
                ),
                "write each run's result into that run's folder".into(),
            )
        });
    }
    let mut out = RunMeasurement {
        software: m.software.clone(),
        ..Default::default()
    };
    // Every entity id at most once per section: the error names both lines.
    for (section, ids) in [
        (
            "sources",
            m.sources.iter().map(|x| x.id.as_str()).collect::<Vec<_>>(),
        ),
        (
            "detectors",
            m.detectors.iter().map(|x| x.id.as_str()).collect(),
        ),
        (
            "phantoms",
            m.phantoms.iter().map(|x| x.id.as_str()).collect(),
        ),
    ] {
        // First index and count so far of every id: one pass, not a search per entity.
        let mut seen: std::collections::HashMap<&str, (usize, usize)> =
            std::collections::HashMap::with_capacity(ids.len());
        for (i, id) in ids.iter().enumerate() {
            let entry = seen.entry(id).or_insert((i, 0));
            let (first, nth) = (entry.0, entry.1);
            entry.1 += 1;
            if nth > 0 {
                report(section, Some(i), "id", id, nth, &|| {
                    let line_of = |k: usize| {
                        json_line_nth(text, section, id, k)
                            .map_or("an unknown line".to_string(), |(l, _)| format!("line {l}"))
                    };
                    (
                        format!(
                            "{section}[{i}] repeats the id `{}` of {section}[{first}] ({} and {})",
                            cut(id),
                            line_of(0),
                            line_of(nth)
                        ),
                        "give each entity once per run".into(),
                    )
                });
            }
        }
    }
    let source_ids: Vec<String> = truth.run.sources.iter().map(|x| x.id.clone()).collect();
    let known_sources = KnownIds::new(&source_ids);
    for (i, s) in m.sources.iter().enumerate() {
        match entity_position(&s.id, s.position_mm, &known_sources) {
            Ok(p) => {
                out.sources.insert(s.id.clone(), p);
            }
            Err(field) => report("sources", Some(i), field, &s.id, 0, &|| {
                describe_entity(field, &s.id, s.position_mm, &known_sources, "source")
            }),
        }
    }
    let detector_ids: Vec<String> = truth.run.detectors.iter().map(|x| x.id.clone()).collect();
    let phantom_ids: Vec<String> = truth.run.phantoms.iter().map(|x| x.id.clone()).collect();
    for (section, list, known) in [
        ("detectors", &m.detectors, KnownIds::new(&detector_ids)),
        ("phantoms", &m.phantoms, KnownIds::new(&phantom_ids)),
    ] {
        let what = &section[..section.len() - 1];
        for (i, e) in list.iter().enumerate() {
            let pos = entity_position(&e.id, e.position_mm, &known);
            let rot = e.rotation.map(checked_rotation).transpose();
            let bad_marker = e
                .markers
                .iter()
                .enumerate()
                .find(|(_, b)| !is_plausible(b.position_mm));
            match (pos, rot, bad_marker) {
                (Ok(p), Ok(r), None) => {
                    out.repaired_rotations += usize::from(r.is_some_and(|r| r.repaired));
                    let target = if section == "detectors" {
                        &mut out.detectors
                    } else {
                        &mut out.phantoms
                    };
                    target.insert(e.id.clone(), (p, r.map(|r: CheckedRotation| r.rotation)));
                    if section == "phantoms" && !e.markers.is_empty() {
                        out.markers.insert(
                            e.id.clone(),
                            e.markers
                                .iter()
                                .map(|b| (b.id.clone(), DVec3::from_array(b.position_mm)))
                                .collect(),
                        );
                    }
                }
                (Err(field), _, _) => report(section, Some(i), field, &e.id, 0, &|| {
                    describe_entity(field, &e.id, e.position_mm, &known, what)
                }),
                (_, Err(msg), _) => report(section, Some(i), "rotation", &e.id, 0, &|| {
                    (
                        format!("{what} `{}`: {msg}", cut(&e.id)),
                        "write the rotation as three rows of an orthonormal matrix with determinant +1".into(),
                    )
                }),
                (_, _, Some((k, b))) => report(section, Some(i), "markers", &b.id, 0, &|| {
                    let msg = plausible_position(b.position_mm).err().unwrap_or_default();
                    (
                        format!(
                            "{what} `{}`: marker {k} (`{}`): {msg}",
                            cut(&e.id),
                            cut(&b.id)
                        ),
                        "give three finite numbers in mm, box frame".into(),
                    )
                }),
            }
        }
    }
    let mut errors = kept.into_inner();
    if errors.is_empty() {
        return Ok(out);
    }
    if more.get() > 0 {
        errors.push(
            Diagnostic::file_error(
                file,
                format!(
                    "{} more problem(s) of the same kinds in this file, not listed",
                    more.get()
                ),
            )
            .with_help("fix the ones above and run again"),
        );
    }
    Err(errors)
}

/// Most problems reported for one results file; the rest are counted.
pub const MAX_ERRORS_PER_FILE: usize = 20;

/// The first [`MAX_ERRORS_PER_FILE`] of `errors`, and one more saying how many were left out.
fn summarised(file: &Path, mut errors: Vec<Diagnostic>) -> Vec<Diagnostic> {
    if errors.len() > MAX_ERRORS_PER_FILE {
        let more = errors.len() - MAX_ERRORS_PER_FILE;
        errors.truncate(MAX_ERRORS_PER_FILE);
        errors.push(
            Diagnostic::file_error(
                file,
                format!("{more} more problem(s) of the same kinds in this file, not listed"),
            )
            .with_help("fix the ones above and run again"),
        );
    }
    errors
}

/// A position that is finite and within ±[`MAX_ABS_MM`], or why not.
fn plausible_position(p: [f64; 3]) -> Result<DVec3, String> {
    if p.iter().any(|x| !x.is_finite()) {
        return Err(format!("position {p:?} is not finite"));
    }
    if let Some(x) = p.iter().find(|x| x.abs() > MAX_ABS_MM) {
        return Err(format!(
            "position coordinate {x:e} mm is implausible (beyond ±{MAX_ABS_MM:e} mm)"
        ));
    }
    Ok(DVec3::from_array(p))
}

/// The ids of one kind of entity of a truth: looked up in a set (a results file may hold
/// thousands of entries), and named in messages (the first [`SHOWN_IDS`], sorted).
struct KnownIds<'a> {
    set: std::collections::HashSet<&'a str>,
    shown: String,
}

/// Most valid ids a message lists.
const SHOWN_IDS: usize = 10;

impl<'a> KnownIds<'a> {
    fn new(ids: &'a [String]) -> Self {
        Self::of(ids.iter().map(String::as_str))
    }

    fn of(ids: impl Iterator<Item = &'a str>) -> Self {
        let set: std::collections::HashSet<&str> = ids.collect();
        let mut sorted: Vec<&str> = set.iter().copied().collect();
        sorted.sort_unstable();
        let mut shown = sorted
            .iter()
            .take(SHOWN_IDS)
            .map(|id| cut(id))
            .collect::<Vec<_>>()
            .join(", ");
        if sorted.len() > SHOWN_IDS {
            shown += &format!(" … and {} more", sorted.len() - SHOWN_IDS);
        }
        KnownIds { set, shown }
    }
}

/// An entity's position if its id is one of `known` and the position is plausible; otherwise the
/// field at fault (`id` or `position_mm`), found without building a message.
fn entity_position(id: &str, p: [f64; 3], known: &KnownIds<'_>) -> Result<DVec3, &'static str> {
    if !known.set.contains(id) {
        return Err("id");
    }
    if !is_plausible(p) {
        return Err("position_mm");
    }
    Ok(DVec3::from_array(p))
}

/// The message and help of [`entity_position`]'s error on `field`.
fn describe_entity(
    field: &str,
    id: &str,
    p: [f64; 3],
    known: &KnownIds<'_>,
    what: &str,
) -> (String, String) {
    if field == "id" {
        return (
            format!("no {what} has the id `{}` in truth.json", cut(id)),
            format!("valid {what} ids: {}", known.shown),
        );
    }
    (
        format!(
            "{what} `{}`: {}",
            cut(id),
            plausible_position(p).err().unwrap_or_default()
        ),
        format!("give three finite numbers in mm, box frame, within ±{MAX_ABS_MM:e} mm"),
    )
}

/// Whether [`plausible_position`] accepts `p`, without building its message.
fn is_plausible(p: [f64; 3]) -> bool {
    p.iter().all(|x| x.is_finite() && x.abs() <= MAX_ABS_MM)
}

/// Reads a CSV long table (see the module doc) holding every run's results. Errors name the
/// line and the column.
pub fn load_measured_csv(
    file: &Path,
    truths: &[TruthRun],
) -> Result<BTreeMap<String, RunMeasurement>, Vec<Diagnostic>> {
    let bytes = crate::input_file::read_named(file, crate::output::received::MAX_TABLE_BYTES)
        .map_err(|d| vec![d])?;
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(bytes.as_slice());
    let known_by_run: std::collections::HashMap<&str, [KnownIds<'_>; 3]> = truths
        .iter()
        .map(|t| {
            let run = &t.truth.run;
            (
                run.id.as_str(),
                [
                    KnownIds::of(run.sources.iter().map(|x| x.id.as_str())),
                    KnownIds::of(run.detectors.iter().map(|x| x.id.as_str())),
                    KnownIds::of(run.phantoms.iter().map(|x| x.id.as_str())),
                ],
            )
        })
        .collect();
    let headers = reader
        .headers()
        .map_err(|e| {
            vec![Diagnostic::file_error(
                file,
                format!("cannot read the header: {e}"),
            )]
        })?
        .clone();
    // A byte-order mark sticks to the first header name.
    let col = |name: &str| headers.iter().position(|h| strip_bom(h).trim() == name);
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
    let mut seen: BTreeMap<(String, String, String), usize> = BTreeMap::new();
    let mut errors = Vec::new();
    for (k, record) in reader.records().enumerate() {
        let mut line = k + 2;
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                errors.push(at(
                    line,
                    "row",
                    format!("malformed row: {}", cut_message(&e.to_string())),
                    "every row needs as many fields as the header",
                ));
                continue;
            }
        };
        if let Some(p) = record.position() {
            line = usize::try_from(p.line()).unwrap_or(line);
        }
        let get = |name: &str| col(name).and_then(|c| record.get(c)).unwrap_or("");
        let number = |name: &str| -> Result<f64, Box<Diagnostic>> {
            let v = get(name);
            let Some(x) = v.parse::<f64>().ok().filter(|x| x.is_finite()) else {
                return Err(Box::new(at(
                    line,
                    name,
                    format!("`{name}` = `{}` is not a finite number", cut(v)),
                    "use a decimal number such as 12.5 or -0.003",
                )));
            };
            if x.abs() > MAX_ABS_MM {
                return Err(Box::new(at(
                    line,
                    name,
                    format!("`{name}` = {x:e} mm is implausible (beyond ±{MAX_ABS_MM:e} mm)"),
                    "give the position in mm, box frame",
                )));
            }
            Ok(x)
        };
        let run_id = get("run").to_string();
        let Some(known_of_run) = known_by_run.get(run_id.as_str()) else {
            errors.push(at(
                line,
                "run",
                format!("no run `{}` in the output folder", cut(&run_id)),
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
            Ok(r) => r.map(|r| (r.rotation, r.repaired)),
            Err((field, msg)) => {
                errors.push(at(line, &field, msg, "give an orthonormal rotation (r11..r33, row-major) or a unit quaternion (qw,qx,qy,qz), or leave all empty"));
                continue;
            }
        };
        let entry = out.entry(run_id.clone()).or_insert_with(|| RunMeasurement {
            software: software.clone(),
            ..Default::default()
        });
        let known = match kind.as_str() {
            "source" => &known_of_run[0],
            "detector" => &known_of_run[1],
            "phantom" => &known_of_run[2],
            _ => {
                errors.push(at(
                    line,
                    "kind",
                    format!("unknown kind `{}`", cut(&kind)),
                    "kind is source, detector or phantom",
                ));
                continue;
            }
        };
        if !known.set.contains(id.as_str()) {
            errors.push(at(
                line,
                "id",
                format!(
                    "no {kind} has the id `{}` in run {}",
                    cut(&id),
                    cut(&run_id)
                ),
                &format!("valid {kind} ids: {}", known.shown),
            ));
            continue;
        }
        if let Some(first) = seen.insert((run_id.clone(), kind.clone(), id.clone()), line) {
            seen.insert((run_id.clone(), kind.clone(), id.clone()), first);
            errors.push(at(
                line,
                "id",
                format!(
                    "line {line} repeats run {run_id}, {kind} `{}` of line {first}",
                    cut(&id)
                ),
                "give one row per run and entity",
            ));
            continue;
        }
        entry.repaired_rotations += usize::from(rotation.is_some_and(|r| r.1));
        let rotation = rotation.map(|r| r.0);
        match kind.as_str() {
            "source" => drop(entry.sources.insert(id, position)),
            "detector" => drop(entry.detectors.insert(id, (position, rotation))),
            _ => drop(entry.phantoms.insert(id, (position, rotation))),
        }
    }
    if errors.is_empty() {
        Ok(out)
    } else {
        Err(summarised(file, errors))
    }
}

fn parse_rotation(
    record: &csv::StringRecord,
    matrix: Option<&[usize]>,
    quat: Option<&[usize]>,
) -> Result<Option<CheckedRotation>, (String, String)> {
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
                            format!("`{}` = `{}` is not a finite number", names(i), cut(v)),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn echoed_values_are_cut_at_the_documented_length() {
        assert_eq!(cut("det1"), "det1");
        let long = "é".repeat(10_000);
        let c = cut(&long);
        assert_eq!(
            c.chars().filter(|&ch| ch == 'é').count(),
            crate::diagnostic::ECHO_MAX_CHARS
        );
        assert!(c.ends_with("… (19600 more bytes)"), "{c}");
        let message = format!("invalid type: string \"{long}\", expected f64");
        let m = cut_message(&message);
        assert!(m.len() < 700 && m.ends_with("expected f64"), "{m}");
    }

    #[test]
    fn a_byte_order_mark_is_ignored() {
        assert_eq!(strip_bom("\u{feff}{}"), "{}");
        assert_eq!(strip_bom("{}"), "{}");
    }

    #[test]
    fn the_nth_occurrence_of_an_id_is_located() {
        let text = "{\n \"phantoms\": [\n  {\"id\": \"a\"},\n  {\"id\": \"a\"}\n ]\n}";
        assert_eq!(json_line_nth(text, "phantoms", "a", 0), Some((3, 10)));
        assert_eq!(json_line_nth(text, "phantoms", "a", 1), Some((4, 10)));
        assert_eq!(json_line_nth(text, "phantoms", "a", 2), None);
    }

    #[test]
    fn implausible_positions_are_refused() {
        assert!(plausible_position([1.0, 2.0, 3.0]).is_ok());
        assert!(plausible_position([0.0, 0.0, MAX_ABS_MM]).is_ok());
        let e = plausible_position([0.0, 1e308, 0.0]).unwrap_err();
        assert!(e.contains("1e308") && e.contains("implausible"), "{e}");
        assert!(plausible_position([f64::NAN, 0.0, 0.0]).is_err());
    }
}
