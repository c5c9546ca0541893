//! `study.json`: the design and the migration truth of a clinical RSA study, at the top of the
//! output folder beside `manifest.json`. It is the contract between the study's simulation (which
//! writes it) and the migration analysis of `rsasim reconstruct` and `rsasim evaluate` (which read
//! it). Each exam of each patient is one run with its own `truth.json`; this file says which run is
//! which exam and what the implant's true motion relative to the bone was.
//!
//! Conventions (the README's "Clinical studies" section states them for users):
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

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::geometry::Pose;

/// The format tag of study files written by this version.
pub const STUDY_FORMAT: &str = "rsasim-study/1";

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
