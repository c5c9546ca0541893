//! `migration_measured.json`: a program's measured migration of every implant of a clinical RSA
//! study, at the top of the study's output folder beside `study.json` (the reference program
//! writes it with `rsasim reconstruct`; `rsasim evaluate` scores it against the study's truth).
//! Numbers follow the conventions of [`super::study`]: translations of the implant's centre along,
//! and X-Y-Z Euler rotations about, the reference segment's anatomical axes, from the reference
//! exam to each exam.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The format tag of measured-migration files.
pub const MIGRATION_MEASURED_FORMAT: &str = "rsasim-migration-measured/1";

/// The file's name at the top of a study's output folder.
pub const MIGRATION_MEASURED_FILE: &str = "migration_measured.json";

/// The same migrations as a CSV table (one row per patient, exam and implant segment).
pub const MIGRATION_MEASURED_CSV: &str = "migration_measured.csv";

/// The header of the migration CSV: rsasim writes it, and `rsasim evaluate --migration-csv`
/// reads it from any program.
pub const MIGRATION_CSV_HEADER: &str =
    "patient,exam,segment,tx_mm,ty_mm,tz_mm,rx_deg,ry_deg,rz_deg,mtpm_mm";

/// A program's measured migrations of one study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MigrationMeasured {
    /// Always `rsasim-migration-measured/1`.
    pub format: String,
    /// Name and version of the software, e.g. `rsasim reconstruct 0.5.0 (dlt, auto)`.
    pub software: String,
    /// The study's scenario name.
    pub scenario: String,
    /// The exam every migration is measured from.
    pub reference_exam: String,
    /// Residual above which a marker was treated as loose and excluded, mm.
    pub stability_threshold_mm: f64,
    /// Per patient, exam and segment: how its motion since the reference exam was found.
    pub segments: Vec<SegmentExam>,
    /// Per patient, exam and implant segment: the migration.
    pub migrations: Vec<MeasuredMigration>,
    /// Patients, exams or segments that could not be measured, each with the reason.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub failures: Vec<String>,
}

/// How one segment's motion from the reference exam to an exam was measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SegmentExam {
    /// Patient id.
    pub patient: String,
    /// Exam id.
    pub exam: String,
    /// Segment id (a phantom id).
    pub segment: String,
    /// `markers` (rigid fit of the exam's markers to the reference exam's, marker stability
    /// checked) or `model` (the segment's pose at both exams, e.g. model-based RSA).
    pub method: String,
    /// Markers the fit kept.
    #[serde(default)]
    pub markers_used: Vec<String>,
    /// Markers excluded as unstable.
    #[serde(default)]
    pub excluded: Vec<ExcludedMarker>,
    /// Mean error of rigid-body fitting (ME) of the kept markers between the two exams, mm (for
    /// `model`: the exam's own fit figure, when the results give one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_error_mm: Option<f64>,
    /// Condition number (CN) of the kept markers' configuration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub condition_number: Option<f64>,
    /// Guideline limits exceeded, e.g. `"ME > 0.35 mm"`, `"CN > 150"`.
    #[serde(default)]
    pub flags: Vec<String>,
}

/// A marker excluded from a segment's fit between exams.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExcludedMarker {
    /// Bead id.
    pub bead: String,
    /// Its leave-one-out residual when it was excluded: its distance at the exam from where the
    /// fit of the other kept markers puts it, mm.
    pub residual_mm: f64,
}

/// The measured migration of an implant segment from the reference exam to `exam`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MeasuredMigration {
    /// Patient id.
    pub patient: String,
    /// Exam id.
    pub exam: String,
    /// Implant segment id.
    pub segment: String,
    /// Motion of the implant's centre along the anatomical x, y, z axes, mm.
    pub translation_mm: [f64; 3],
    /// Rotation about the anatomical axes, X-Y-Z Euler angles, degrees.
    pub rotation_deg: [f64; 3],
    /// Maximum total point motion over the implant's MTPM points, mm.
    pub mtpm_mm: f64,
    /// The segments' flags at this exam, each prefixed by the segment id, e.g.
    /// `"femur: ME > 0.35 mm"`.
    #[serde(default)]
    pub flags: Vec<String>,
}
