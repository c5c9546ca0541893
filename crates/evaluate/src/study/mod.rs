//! `rsasim evaluate` on a clinical RSA study (an output folder with `study.json`): migration
//! accuracy per axis and time point (ISO 5725 trueness and precision, the paper's style),
//! clinical precision from the double exams, loose-marker detection, and each patient's
//! migration over time for the plots.
//!
//! The measured migration comes from, in this order: a relative-motion CSV
//! (`--migration-csv`); the folder's `migration_measured.json` when the software that wrote it
//! is the one whose per-exam results are scored; else it is computed here from the per-exam
//! results (each segment's pose and markers) by [`crate::migration::analysis`], as the
//! reference program does.

pub mod csv_input;
pub mod limits;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::DVec3;
use serde::Serialize;

use super::input::RunMeasurement;
use super::stats::{Cell, Confidence};
use crate::diagnostic::Diagnostic;
use crate::geometry::Pose;
use crate::migration::analysis::{
    ExamSeen, SegmentSeen, design_roles, measure_study, seen_by_patient,
};
use crate::output::migration_measured::{
    MIGRATION_MEASURED_FILE, MeasuredMigration, MigrationMeasured, SegmentExam,
};
use crate::output::study::{STUDY_FILE, Study, read_study};
use limits::{DoubleLimits, double_limits};

/// The file name of a study's design and truth at the top of the output folder.

/// The seven reported parameters: label and unit.
pub const PARAMETERS: [(&str, &str); 7] = [
    ("x", "mm"),
    ("y", "mm"),
    ("z", "mm"),
    ("Rx", "deg"),
    ("Ry", "deg"),
    ("Rz", "deg"),
    ("MTPM", "mm"),
];

/// Options of the study evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyOptions {
    /// A relative-motion CSV to score instead of the per-exam results.
    pub migration_csv: Option<PathBuf>,
    /// Marker-stability threshold when the migration is computed here, mm.
    pub stability_threshold_mm: f64,
    /// Also report the 99 % double-exam limits.
    pub limits_99: bool,
}

impl Default for StudyOptions {
    fn default() -> Self {
        StudyOptions {
            migration_csv: None,
            stability_threshold_mm: crate::migration::DEFAULT_STABILITY_THRESHOLD_MM,
            limits_99: false,
        }
    }
}

/// Migration accuracy of one implant segment: one row per follow-up exam.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AccuracyTable {
    /// Implant segment id.
    pub segment: String,
    /// One row per non-reference exam, in time order.
    pub rows: Vec<AccuracyRow>,
}

/// The cells of one exam: measured − true per parameter over the patients.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AccuracyRow {
    /// Exam id.
    pub exam: String,
    /// Days from surgery.
    pub days: u32,
    /// One cell per [`PARAMETERS`] entry; `None` where no patient was measured.
    pub cells: Vec<Option<Cell>>,
}

/// The double-exam precision of one implant segment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DoubleExamTable {
    /// Implant segment id.
    pub segment: String,
    /// The double exam's id.
    pub exam: String,
    /// The exam it repeats.
    pub repeats: String,
    /// One entry per [`PARAMETERS`] entry (MTPM only when the double exam repeats the reference
    /// exam: then its MTPM is the motion between the two).
    pub limits: Vec<DoubleLimits>,
}

/// A marker that truly moved by more than the stability threshold, and what the program did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LooseMarkerRow {
    /// Patient id.
    pub patient: String,
    /// Exam id.
    pub exam: String,
    /// Segment id.
    pub segment: String,
    /// Bead id.
    pub bead: String,
    /// Its true displacement relative to its segment since the reference exam, mm.
    pub displacement_mm: f64,
    /// Whether the program excluded it; `None` when its results do not say.
    pub excluded: Option<bool>,
}

/// One patient's migration of one implant over time (the plots).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PatientSeries {
    /// Patient id.
    pub patient: String,
    /// Implant segment id.
    pub segment: String,
    /// One point per exam (the reference exam at zero), in time order.
    pub points: Vec<SeriesPoint>,
}

/// One exam of a [`PatientSeries`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SeriesPoint {
    /// Exam id.
    pub exam: String,
    /// Days from surgery.
    pub days: u32,
    /// True values per [`PARAMETERS`] entry.
    pub truth: [f64; 7],
    /// Measured values, when measured.
    pub measured: Option<[f64; 7]>,
}

/// Everything the study evaluation reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyReport {
    /// Where the measured migration came from.
    pub source: String,
    /// The reference exam.
    pub reference_exam: String,
    /// The marker-stability threshold the loose-marker table judges by, mm.
    pub stability_threshold_mm: f64,
    /// Migration accuracy per implant segment.
    pub accuracy: Vec<AccuracyTable>,
    /// Double-exam precision per implant segment and double exam.
    pub double_exams: Vec<DoubleExamTable>,
    /// Whether the 99 % limits were asked for.
    pub limits_99: bool,
    /// Markers that truly moved by more than the threshold.
    pub loose_markers: Vec<LooseMarkerRow>,
    /// Exclusions of markers that did not move by more than the threshold.
    pub false_exclusions: Vec<String>,
    /// Segment-exams whose fit between exams exceeded a guideline limit, e.g.
    /// `p03 1y femur: ME > 0.35 mm`.
    pub quality_flags: Vec<String>,
    /// Segment-exams measured.
    pub segment_exams: usize,
    /// Per patient and implant: the migration over time.
    pub series: Vec<PatientSeries>,
    /// Follow-ups that could not be scored, and other remarks.
    pub notes: Vec<String>,
}

fn values(t: [f64; 3], r: [f64; 3], mtpm: f64) -> [f64; 7] {
    [t[0], t[1], t[2], r[0], r[1], r[2], mtpm]
}

/// Reads `study.json` from `truth_root` ([`read_study`]) and checks its design's roles; `None`
/// when there is none (not a study).
pub fn load_study(truth_root: &Path) -> Result<Option<Study>, Vec<Diagnostic>> {
    let Some(study) = read_study(truth_root)? else {
        return Ok(None);
    };
    design_roles(&study)
        .map_err(|e| vec![Diagnostic::file_error(&truth_root.join(STUDY_FILE), e)])?;
    Ok(Some(study))
}

/// What was measured per patient and exam, from the per-run results.
fn seen_from_runs(
    study: &Study,
    measurements: &BTreeMap<String, RunMeasurement>,
) -> BTreeMap<String, BTreeMap<String, ExamSeen>> {
    seen_by_patient(study, |run| {
        let m = measurements.get(run)?;
        Some(
            m.phantoms
                .iter()
                .map(|(id, (position_mm, rotation))| {
                    (
                        id.clone(),
                        SegmentSeen {
                            pose: rotation.map(|rotation| Pose {
                                position_mm: *position_mm,
                                rotation,
                            }),
                            markers: m.markers.get(id).cloned().unwrap_or_default(),
                            mean_error_mm: None,
                            condition_number: None,
                            sources_mm: m.sources.values().copied().collect(),
                        },
                    )
                })
                .collect(),
        )
    })
}

/// The measured migration and where it came from (see the module doc).
fn measured_migration(
    out: &Path,
    study: &Study,
    measurements: &BTreeMap<String, RunMeasurement>,
    options: &StudyOptions,
) -> Result<(MigrationMeasured, String), Vec<Diagnostic>> {
    if let Some(csv) = &options.migration_csv {
        let migrations = csv_input::read_migration_csv(csv, Some(study))?;
        let (reference_exam, _, _) =
            design_roles(study).map_err(|e| vec![Diagnostic::file_error(out, e)])?;
        return Ok((
            MigrationMeasured {
                format: crate::output::migration_measured::MIGRATION_MEASURED_FORMAT.into(),
                software: String::new(),
                scenario: study.scenario.clone(),
                reference_exam,
                stability_threshold_mm: options.stability_threshold_mm,
                segments: Vec::new(),
                migrations,
                failures: Vec::new(),
            },
            csv.display().to_string(),
        ));
    }
    let mut softwares: Vec<&str> = measurements.values().map(|m| m.software.as_str()).collect();
    softwares.sort_unstable();
    softwares.dedup();
    let file = out.join(MIGRATION_MEASURED_FILE);
    let folder = crate::output::received::ReceivedFolder::unlisted(out);
    if folder.exists(MIGRATION_MEASURED_FILE) {
        let bytes = folder
            .read(
                MIGRATION_MEASURED_FILE,
                crate::output::received::MAX_JSON_BYTES,
            )
            .map_err(|d| vec![d])?;
        let text = String::from_utf8_lossy(&bytes);
        let written: MigrationMeasured = serde_json::from_str(&text).map_err(|e| {
            vec![
                Diagnostic::file_error(&file, format!("line {}: {e}", e.line()))
                    .with_help("the schema is schemas/migration_measured.schema.json"),
            ]
        })?;
        if softwares == [written.software.as_str()] {
            return Ok((written, MIGRATION_MEASURED_FILE.into()));
        }
    }
    let software = softwares.join(", ");
    let seen = seen_from_runs(study, measurements);
    let computed = measure_study(study, &seen, options.stability_threshold_mm, &software)
        .map_err(|e| vec![Diagnostic::file_error(&out.join(STUDY_FILE), e)])?;
    Ok((
        computed,
        format!(
            "computed from the per-exam results (segment poses and markers; marker stability {} mm)",
            options.stability_threshold_mm
        ),
    ))
}

/// Scores the study's measured migration against its truth.
pub fn evaluate_study(
    out: &Path,
    study: &Study,
    measurements: &BTreeMap<String, RunMeasurement>,
    confidence: &Confidence,
    options: &StudyOptions,
) -> Result<StudyReport, Vec<Diagnostic>> {
    let (measured, source) = measured_migration(out, study, measurements, options)?;
    Ok(score(study, &measured, source, confidence, options))
}

/// The report from the study and a measured migration (no I/O).
pub fn score(
    study: &Study,
    measured: &MigrationMeasured,
    source: String,
    confidence: &Confidence,
    options: &StudyOptions,
) -> StudyReport {
    let reference_exam = study
        .exams
        .iter()
        .find(|e| e.reference)
        .map(|e| e.id.clone())
        .unwrap_or_default();
    let implants: Vec<&str> = study
        .segments
        .iter()
        .filter(|s| s.role == "implant")
        .map(|s| s.id.as_str())
        .collect();
    let mut by_key: BTreeMap<(&str, &str, &str), &MeasuredMigration> = BTreeMap::new();
    for m in &measured.migrations {
        by_key.insert((&m.patient, &m.exam, &m.segment), m);
    }
    let patients_by_id: std::collections::HashMap<&str, &crate::output::study::StudyPatient> =
        study.patients.iter().map(|p| (p.id.as_str(), p)).collect();
    let truth_of = |patient: &str, exam: &str, segment: &str| -> Option<[f64; 7]> {
        if exam == reference_exam {
            return Some([0.0; 7]);
        }
        let p = patients_by_id.get(patient)?;
        let t = p
            .migration
            .iter()
            .find(|t| t.exam == exam && t.segment == segment)?;
        Some(values(t.translation_mm, t.rotation_deg, t.mtpm_mm))
    };
    let measured_of = |patient: &str, exam: &str, segment: &str| -> Option<[f64; 7]> {
        if exam == reference_exam {
            return Some([0.0; 7]);
        }
        by_key
            .get(&(patient, exam, segment))
            .map(|m| values(m.translation_mm, m.rotation_deg, m.mtpm_mm))
    };
    let mut notes: Vec<String> = measured.failures.clone();
    let follow_ups: Vec<_> = study.exams.iter().filter(|e| !e.reference).collect();
    let mut accuracy = Vec::new();
    let mut series = Vec::new();
    let mut double_exams = Vec::new();
    for &segment in &implants {
        let mut rows = Vec::new();
        for exam in &follow_ups {
            let mut residuals: Vec<Vec<f64>> = vec![Vec::new(); 7];
            for p in &study.patients {
                let (Some(t), Some(m)) = (
                    truth_of(&p.id, &exam.id, segment),
                    measured_of(&p.id, &exam.id, segment),
                ) else {
                    continue;
                };
                for k in 0..7 {
                    residuals[k].push(m[k] - t[k]);
                }
            }
            let cells = residuals
                .iter()
                .map(|r| (!r.is_empty()).then(|| Cell::from_residuals(r, confidence)))
                .collect();
            rows.push(AccuracyRow {
                exam: exam.id.clone(),
                days: exam.days,
                cells,
            });
        }
        accuracy.push(AccuracyTable {
            segment: segment.into(),
            rows,
        });
        for exam in follow_ups.iter().filter(|e| e.double_of.is_some()) {
            let repeats = exam.double_of.clone().unwrap_or_default();
            let mut diffs: Vec<Vec<f64>> = vec![Vec::new(); 7];
            for p in &study.patients {
                let (Some(second), Some(first)) = (
                    measured_of(&p.id, &exam.id, segment),
                    measured_of(&p.id, &repeats, segment),
                ) else {
                    continue;
                };
                for k in 0..6 {
                    diffs[k].push(second[k] - first[k]);
                }
                if repeats == reference_exam {
                    diffs[6].push(second[6]);
                }
            }
            if diffs[0].is_empty() {
                notes.push(format!(
                    "double exam {} of {segment}: no patient has both {} and {repeats} measured",
                    exam.id, exam.id
                ));
                continue;
            }
            let limits = PARAMETERS
                .iter()
                .zip(&diffs)
                .filter(|(_, d)| !d.is_empty())
                .map(|(&(label, unit), d)| {
                    double_limits(label, unit, d, options.limits_99, label == "MTPM")
                })
                .collect();
            double_exams.push(DoubleExamTable {
                segment: segment.into(),
                exam: exam.id.clone(),
                repeats,
                limits,
            });
        }
        for p in &study.patients {
            let points = study
                .exams
                .iter()
                .filter(|e| e.double_of.is_none())
                .filter_map(|e| {
                    Some(SeriesPoint {
                        exam: e.id.clone(),
                        days: e.days,
                        truth: truth_of(&p.id, &e.id, segment)?,
                        measured: measured_of(&p.id, &e.id, segment),
                    })
                })
                .collect();
            series.push(PatientSeries {
                patient: p.id.clone(),
                segment: segment.into(),
                points,
            });
        }
    }
    let segment_exam: BTreeMap<(&str, &str, &str), &SegmentExam> = measured
        .segments
        .iter()
        .map(|s| ((s.patient.as_str(), s.exam.as_str(), s.segment.as_str()), s))
        .collect();
    let threshold = options.stability_threshold_mm;
    let mut loose_markers = Vec::new();
    let mut truly_loose = std::collections::BTreeSet::new();
    for p in &study.patients {
        for l in &p.loose_markers {
            let displacement_mm = DVec3::from_array(l.displacement_mm).length();
            if displacement_mm <= threshold {
                continue;
            }
            truly_loose.insert((
                p.id.as_str(),
                l.exam.as_str(),
                l.segment.as_str(),
                l.bead.as_str(),
            ));
            let excluded = segment_exam
                .get(&(p.id.as_str(), l.exam.as_str(), l.segment.as_str()))
                .filter(|s| s.method == "markers")
                .map(|s| s.excluded.iter().any(|x| x.bead == l.bead));
            loose_markers.push(LooseMarkerRow {
                patient: p.id.clone(),
                exam: l.exam.clone(),
                segment: l.segment.clone(),
                bead: l.bead.clone(),
                displacement_mm,
                excluded,
            });
        }
    }
    let mut false_exclusions = Vec::new();
    let mut quality_flags = Vec::new();
    for s in &measured.segments {
        for x in &s.excluded {
            if !truly_loose.contains(&(
                s.patient.as_str(),
                s.exam.as_str(),
                s.segment.as_str(),
                x.bead.as_str(),
            )) {
                false_exclusions.push(format!(
                    "{} {} {}: {} (residual {:.3} mm)",
                    s.patient, s.exam, s.segment, x.bead, x.residual_mm
                ));
            }
        }
        for f in &s.flags {
            quality_flags.push(format!("{} {} {}: {f}", s.patient, s.exam, s.segment));
        }
    }
    if measured.segments.is_empty() {
        notes.push("the migration results say nothing of markers: loose-marker detection and ME/CN are not scored".into());
    }
    StudyReport {
        source,
        reference_exam,
        stability_threshold_mm: threshold,
        accuracy,
        double_exams,
        limits_99: options.limits_99,
        loose_markers,
        false_exclusions,
        quality_flags,
        segment_exams: measured.segments.len(),
        series,
        notes,
    }
}
