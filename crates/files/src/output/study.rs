//! `study.json`: the design and the migration truth of a clinical RSA study, at the top of the
//! output folder beside `manifest.json`. It is the contract between the study's simulation (which
//! writes it) and the migration analysis of `rsasim reconstruct` and `rsasim evaluate` (which read
//! it). Each exam of each patient is one run with its own `truth.json`; this file says which run is
//! which exam and what the implant's true motion relative to the bone was.
//!
//! Conventions (docs/src/guide/clinical-study.md states them for users):
//! - **Anatomical frame.** Migration is expressed in the anatomical frame of the reference segment
//!   (the bone): x medial–lateral, y proximal–distal (+y proximal), z anterior–posterior
//!   (+z anterior), given as a pose in the reference segment's local frame.
//! - **Relative motion.** With `B` the reference segment's pose, `A` the anatomical frame's pose in
//!   it and `I` the implant's pose (all rigid transforms, box frame), the implant's pose in the
//!   anatomical frame is `P = (B·A)⁻¹·I`. The migration at exam `e` is the rigid motion
//!   `M = P_e · P_ref⁻¹` (it carries a point of the implant, expressed in the anatomical frame at
//!   the reference exam, to where it is at exam `e`).
//! - **Reported numbers.** `translation_mm` is the motion `M·c − c` of the implant's centre `c`
//!   (the centroid of its `mtpm_points_mm`, in the anatomical frame at the reference exam);
//!   `rotation_deg` are the X-Y-Z Euler angles of `M`'s rotation, `R = Rx·Ry·Rz` (the scenario's
//!   convention); `mtpm_mm` is the largest `|M·p − p|` over the implant's `mtpm_points_mm`.

use std::collections::BTreeMap;
use std::path::Path;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use glam::DVec3;

use sha2::{Digest, Sha256};

use crate::diagnostic::Diagnostic;
use crate::expand::study;
use crate::geometry::{Pose, euler_xyz_deg};
use crate::output::received::{MAX_JSON_BYTES, ReceivedFolder, check_name};
use crate::output::verify::{check_manifest, read_manifest};
use crate::scenario::{Scenario, StudyDesign, hex};

/// The format tag of study files written by this version.
pub const STUDY_FORMAT: &str = "rsasim-study/1";

/// The study file's name, at the top of an output folder (or of its truth folder).
pub const STUDY_FILE: &str = "study.json";

/// Reads [`STUDY_FILE`] from `dir`: `None` when there is none (not a study); a byte-order mark
/// is skipped. Errors name the file (and the line of a parse error).
///
/// The file must be the one the folder's `manifest.json` lists, byte for byte (its SHA-256):
/// an edited `study.json`, or one copied from another study, would pair runs with the wrong
/// exams or patients, so it is refused, as is a folder whose manifest is missing or modified.
pub fn read_study(dir: &Path) -> Result<Option<Study>, Vec<Diagnostic>> {
    let file = dir.join(STUDY_FILE);
    let folder = ReceivedFolder::unlisted(dir);
    if !folder.exists(STUDY_FILE) {
        // A folder whose manifest lists a study.json is a study, with or without the file.
        if let Ok((listing, _)) = read_manifest(dir)
            && listing.files.iter().any(|f| f.path == STUDY_FILE)
        {
            return Err(vec![Diagnostic::file_error(
                &file,
                "is missing, but manifest.json lists it: this folder holds a clinical study",
            )
            .with_help("restore study.json (or ask the sender for the folder as rsasim wrote it); `rsasim verify` lists every missing file")]);
        }
        return Ok(None);
    }
    let bytes = folder
        .read(STUDY_FILE, MAX_JSON_BYTES)
        .map_err(|d| vec![d])?;
    check_listed(dir, &bytes).map_err(|e| {
        vec![Diagnostic::file_error(&file, e).with_help(
            "study.json must be the file the simulator wrote into this folder: restore it, or re-run the scenario",
        )]
    })?;
    let text = String::from_utf8(bytes)
        .map_err(|e| vec![Diagnostic::file_error(&file, format!("not UTF-8: {e}"))])?;
    let study: Study = serde_json::from_str(text.strip_prefix('\u{feff}').unwrap_or(&text))
        .map_err(|e| {
            vec![
                Diagnostic::file_error(
                    &file,
                    format!(
                        "line {}: {}",
                        e.line(),
                        crate::diagnostic::cut(&e.to_string())
                    ),
                )
                .with_help("study.json is written by the simulator: re-run the scenario"),
            ]
        })?;
    let runs = folder.sub_folders("runs").map_err(|d| vec![d])?;
    check_study(&file, &study, &runs).map_err(|d| vec![d])?;
    Ok(Some(study))
}

/// Checks what a sender could have forged in a study file before anything relies on it: the
/// format; segment, exam and patient ids plain names, each once; every exam a patient lists, and
/// every exam and segment a migration or loose marker names, in the design; every run id a plain
/// name, one of the folder's `runs` and used by one patient's exam only (so the patients are at
/// most as many as the runs, and no run is scored twice).
pub fn check_study(file: &Path, study: &Study, runs: &[String]) -> Result<(), Diagnostic> {
    use crate::diagnostic::cut;
    use std::collections::{HashMap, HashSet};
    let bad = |message: String| {
        Diagnostic::file_error(file, message)
            .with_help("study.json is written by the simulator with the runs of its folder: ask the sender for the folder as rsasim wrote it")
    };
    if study.format != STUDY_FORMAT {
        return Err(bad(format!(
            "`format` is {:?}; this rsasim reads {STUDY_FORMAT:?}",
            cut(&study.format)
        )));
    }
    let unique = |field: &str, ids: Vec<&str>| -> Result<HashSet<String>, Diagnostic> {
        let mut seen = HashSet::with_capacity(ids.len());
        for id in ids {
            check_name(file, field, id)?;
            if !seen.insert(id.to_string()) {
                return Err(bad(format!("`{field}` {:?} appears twice", cut(id))));
            }
        }
        Ok(seen)
    };
    let segments = unique(
        "segments[].id",
        study.segments.iter().map(|s| s.id.as_str()).collect(),
    )?;
    let exams = unique(
        "exams[].id",
        study.exams.iter().map(|e| e.id.as_str()).collect(),
    )?;
    unique(
        "patients[].id",
        study.patients.iter().map(|p| p.id.as_str()).collect(),
    )?;
    for exam in &study.exams {
        if let Some(of) = &exam.double_of
            && !exams.contains(of)
        {
            return Err(bad(format!(
                "exam {:?}: `double_of` names {:?}, which is not an exam of the study",
                cut(&exam.id),
                cut(of)
            )));
        }
    }
    let known_runs: HashSet<&str> = runs.iter().map(String::as_str).collect();
    let mut used: HashMap<&str, (&str, &str)> = HashMap::new();
    for p in &study.patients {
        if p.runs.is_empty() {
            return Err(bad(format!("patient {:?}: `runs` is empty", cut(&p.id))));
        }
        for (exam, run) in &p.runs {
            if !exams.contains(exam) {
                return Err(bad(format!(
                    "patient {:?}: `runs` names the exam {:?}, which is not an exam of the study",
                    cut(&p.id),
                    cut(exam)
                )));
            }
            check_name(file, "patients[].runs", run)?;
            if !known_runs.contains(run.as_str()) {
                return Err(bad(format!(
                    "patient {:?}, exam {:?}: `runs` names the run {:?}, which has no folder under runs/",
                    cut(&p.id),
                    cut(exam),
                    cut(run)
                )));
            }
            if let Some((other, other_exam)) =
                used.insert(run.as_str(), (p.id.as_str(), exam.as_str()))
            {
                return Err(bad(format!(
                    "the run {:?} is given to patient {:?} exam {:?} and to patient {:?} exam {:?}: every run is one exam of one patient",
                    cut(run),
                    cut(other),
                    cut(other_exam),
                    cut(&p.id),
                    cut(exam)
                )));
            }
        }
        let named = p
            .migration
            .iter()
            .map(|m| (&m.exam, &m.segment, "migration"))
            .chain(
                p.loose_markers
                    .iter()
                    .map(|m| (&m.exam, &m.segment, "loose_markers")),
            );
        for (exam, segment, field) in named {
            if !exams.contains(exam) || !segments.contains(segment) {
                return Err(bad(format!(
                    "patient {:?}: `{field}` names exam {:?} and segment {:?}, not both of the study",
                    cut(&p.id),
                    cut(exam),
                    cut(segment)
                )));
            }
        }
    }
    Ok(())
}

/// Checks `bytes` (the content of `dir`'s [`STUDY_FILE`]) against the SHA-256 that
/// `dir/manifest.json` lists for it, after checking the manifest's own integrity.
fn check_listed(dir: &Path, bytes: &[u8]) -> Result<(), String> {
    let manifest = dir.join("manifest.json");
    let (listing, manifest_bytes) = read_manifest(dir).map_err(|f| {
        format!(
            "cannot be checked against {}: {}",
            manifest.display(),
            f.problem
        )
    })?;
    if let Some(f) = check_manifest(&listing, &manifest_bytes).first() {
        return Err(format!(
            "cannot be checked against {}: {}",
            manifest.display(),
            f.problem
        ));
    }
    let entry = listing
        .files
        .iter()
        .find(|f| f.path == STUDY_FILE)
        .ok_or_else(|| {
            format!(
                "is not listed in {}: it was not written with this folder's runs",
                manifest.display()
            )
        })?;
    let sha256 = hex(&Sha256::digest(bytes));
    if sha256 != entry.sha256 {
        return Err(format!(
            "differs from the study.json {} lists (SHA-256 {sha256}, listed {}): it was edited, or comes from another study (this folder holds scenario {:?})",
            manifest.display(),
            entry.sha256,
            listing.scenario,
        ));
    }
    Ok(())
}

/// The design of a clinical RSA study and its migration truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Study {
    /// Always `rsasim-study/1` for this layout.
    pub format: String,
    /// The program that wrote the file, `rsasim <version>`.
    pub program: String,
    /// The scenario's name.
    pub scenario: String,
    /// The segments: one with role `reference` (the bone), one or more with role `implant`.
    pub segments: Vec<StudySegment>,
    /// The anatomical frame as a pose in the reference segment's local frame: its axes are
    /// x medial–lateral, y proximal–distal (+y proximal), z anterior–posterior (+z anterior).
    pub anatomical_frame: Pose,
    /// The order of the reported rotations: always `"xyz"`, meaning `R = Rx·Ry·Rz`.
    pub rotation_order: String,
    /// The exams in time order; exactly one is the reference (`postop`).
    pub exams: Vec<StudyExam>,
    /// One entry per simulated patient, in order.
    pub patients: Vec<StudyPatient>,
}

/// A rigid segment of the study: a phantom of the scenario (its mesh and/or its beads).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StudySegment {
    /// The phantom id (as in every run's `truth.json`).
    pub id: String,
    /// `reference` (the bone migration is measured against) or `implant`.
    pub role: String,
    /// The bead ids that are this segment's markers (may be empty for a model-only implant).
    pub markers: Vec<String>,
    /// Points whose motion gives the MTPM, in the segment's local frame, mm: the markers' centres,
    /// or for a model-only implant fictive points at its extremities.
    pub mtpm_points_mm: Vec<[f64; 3]>,
}

/// One exam of the design.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StudyExam {
    /// Exam id, e.g. `postop`, `double`, `3m`, `1y`.
    pub id: String,
    /// Days from surgery (the reporting item of the RSA guidelines).
    pub days: u32,
    /// Whether this exam is the reference every migration is measured from.
    pub reference: bool,
    /// For a double examination: the exam it repeats (the patient repositioned in between; the
    /// true migration between the two is zero).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub double_of: Option<String>,
}

/// One simulated patient.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StudyPatient {
    /// Patient id, e.g. `p01`.
    pub id: String,
    /// Exam id → run id (the run folder holding that exam's images and truth).
    pub runs: BTreeMap<String, String>,
    /// The true migration of every implant segment at every exam except the reference.
    pub migration: Vec<MigrationTruth>,
    /// Markers that moved relative to their segment (a loose marker), per exam.
    pub loose_markers: Vec<LooseMarker>,
}

/// The true motion of an implant segment relative to the reference segment, from the reference
/// exam to `exam` (see the module's conventions).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MigrationTruth {
    /// Exam id.
    pub exam: String,
    /// Implant segment id.
    pub segment: String,
    /// Motion of the segment's centre along the anatomical x, y, z axes, mm.
    pub translation_mm: [f64; 3],
    /// Rotation about the anatomical axes, X-Y-Z Euler angles, degrees.
    pub rotation_deg: [f64; 3],
    /// Maximum total point motion over the segment's `mtpm_points_mm`, mm.
    pub mtpm_mm: f64,
}

/// A marker displaced relative to its own segment at an exam, compared with the reference exam.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LooseMarker {
    /// Exam id.
    pub exam: String,
    /// Segment id (a phantom id).
    pub segment: String,
    /// Bead id.
    pub bead: String,
    /// Its displacement in the segment's local frame, mm.
    pub displacement_mm: [f64; 3],
}

impl MigrationTruth {
    /// The migration numbers of the rigid motion `motion` (`M`, in the anatomical frame) of an
    /// implant whose MTPM points are `points` (anatomical frame at the reference exam): the
    /// motion of their centroid, the X-Y-Z Euler angles of the rotation, the largest point motion.
    pub fn from_motion(exam: &str, segment: &str, motion: &Pose, points: &[DVec3]) -> Self {
        let sum: DVec3 = points.iter().copied().sum();
        let centre = sum / points.len().max(1) as f64;
        let mtpm_mm = points
            .iter()
            .map(|&p| (motion.to_world(p) - p).length())
            .fold(0.0, f64::max);
        MigrationTruth {
            exam: exam.to_string(),
            segment: segment.to_string(),
            // `+ 0.0` writes a zero as 0.0, never -0.0.
            translation_mm: (motion.to_world(centre) - centre)
                .to_array()
                .map(|x| x + 0.0),
            rotation_deg: euler_xyz_deg(&motion.rotation).map(|x| x + 0.0),
            mtpm_mm,
        }
    }
}

/// The design and migration truth of the study of scenario `s` (which must have one).
pub fn study_truth(s: &Scenario, d: &StudyDesign) -> Study {
    let frames = study::frames(s, d);
    let segments = d
        .segments
        .iter()
        .map(|g| {
            let implant = frames
                .implants
                .iter()
                .find(|f| s.phantoms[f.phantom].id == g.phantom);
            StudySegment {
                id: g.phantom.clone(),
                role: g.role.name().to_string(),
                markers: study::segment_markers(s, g),
                mtpm_points_mm: implant.map_or_else(Vec::new, |f| {
                    f.mtpm_points_local.iter().map(|p| p.to_array()).collect()
                }),
            }
        })
        .collect();
    let exams = d
        .exams
        .iter()
        .map(|e| StudyExam {
            id: e.id.clone(),
            days: e.days,
            reference: e.reference,
            double_of: e.double_of.clone(),
        })
        .collect();
    let patients = (0..d.patients)
        .map(|p| {
            let factor = study::migration_factor(s, d, p);
            let runs = d
                .exams
                .iter()
                .enumerate()
                .map(|(i, e)| (e.id.clone(), study::exam_run_id(d, p, i)))
                .collect();
            let mut migration = Vec::new();
            for (i, e) in d.exams.iter().enumerate().filter(|(_, e)| !e.reference) {
                for f in &frames.implants {
                    let motion = study::prescribed_motion(d, i, factor, f.centre);
                    let points: Vec<DVec3> = f
                        .mtpm_points_local
                        .iter()
                        .map(|&q| f.in_anatomical.to_world(q))
                        .collect();
                    migration.push(MigrationTruth::from_motion(
                        &e.id,
                        &s.phantoms[f.phantom].id,
                        &motion,
                        &points,
                    ));
                }
            }
            let loose_markers = d
                .exams
                .iter()
                .enumerate()
                .flat_map(|(i, e)| {
                    d.loose_markers.iter().filter_map(move |l| {
                        study::loose_displacement(d, p, i, &l.phantom, &l.bead).map(|v| {
                            LooseMarker {
                                exam: e.id.clone(),
                                segment: l.phantom.clone(),
                                bead: l.bead.clone(),
                                displacement_mm: v.to_array(),
                            }
                        })
                    })
                })
                .collect();
            StudyPatient {
                id: study::patient_id(p),
                runs,
                migration,
                loose_markers,
            }
        })
        .collect();
    Study {
        format: STUDY_FORMAT.into(),
        program: super::program(),
        scenario: s.name.clone(),
        segments,
        anatomical_frame: frames.anatomical,
        rotation_order: "xyz".into(),
        exams,
        patients,
    }
}
