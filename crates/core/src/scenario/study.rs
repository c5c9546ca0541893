//! The `[study]` table: a clinical RSA study instead of the paper's protocol.
//!
//! A study names rigid segments (a reference bone and one or more implants, each a phantom),
//! a list of exams with the implant's prescribed migration relative to the bone, and a number of
//! simulated patients. Every exam of every patient is one run: the whole limb is repositioned by
//! the reference phantom's own `randomize` ranges (tubes and detectors by theirs), and every
//! implant segment rides on the reference segment, displaced by the exam's migration. docs/src/guide/clinical-study.md
//! states every convention; `crates/core/src/expand/study.rs` turns this into runs.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A clinical RSA study: segments, exams, patients and what goes wrong clinically.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StudyDesign {
    /// Number of simulated patients, at least 1. Patient `k` (1-based, id `p<k:02>`) draws from
    /// its own streams, so patients 1..k are the same whatever the count.
    pub patients: u32,
    /// Binary mode: the mean background noise of every exam, as a fraction of I_max, in [0, 1].
    /// Default 0.
    #[serde(default)]
    pub noise_level: f64,
    /// Attenuation mode: the factor on the imaging exposure of every exam, > 0. Default 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposure_factor: Option<f64>,
    /// Per-patient variation of the true migration: patient `k`'s prescribed translations and
    /// rotations are all multiplied by `1 + u`, `u` drawn uniformly in [−spread, +spread) from
    /// the patient's stream. In [0, 1]. Default 0 (every patient migrates as prescribed).
    #[serde(default)]
    pub migration_spread: f64,
    /// The rigid segments: exactly one with role `reference` (the bone), at least one `implant`.
    pub segments: Vec<SegmentSpec>,
    /// The exams in time order; exactly one is the reference (`reference = true`).
    pub exams: Vec<ExamSpec>,
    /// Markers that come loose: from an exam on, a bead of one patient sits displaced relative to
    /// its segment. Default: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub loose_markers: Vec<LooseMarkerSpec>,
    /// Fewer markers than planned: beads that one patient does not have (never placed, or lost).
    /// Default: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub missing_markers: Vec<MissingMarkersSpec>,
}

/// The role of a segment in the study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SegmentRole {
    /// The bone every migration is measured against.
    Reference,
    /// An implant whose migration relative to the reference is measured.
    Implant,
}

impl SegmentRole {
    /// The role as written in `study.json`: `reference` or `implant`.
    pub fn name(self) -> &'static str {
        match self {
            SegmentRole::Reference => "reference",
            SegmentRole::Implant => "implant",
        }
    }
}

/// A rigid segment: a phantom of the scenario (its mesh and/or its beads).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SegmentSpec {
    /// Id of the phantom. The reference is the limb: it carries the `randomize` ranges of the
    /// patient's repositioning, and whatever is `fixed_to` it moves with it. An implant has no
    /// `randomize` and no `fixed_to`: its `position_mm`/`rotation_deg` place it at the reference
    /// segment's nominal pose, and it rides on the reference segment, displaced by the exam's
    /// migration.
    pub phantom: String,
    /// `reference` or `implant`.
    pub role: SegmentRole,
    /// Ids of the phantom's beads that are this segment's markers. Default: all its beads.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub markers: Option<Vec<String>>,
    /// Reference segment only: the anatomical frame as a pose in the segment's local frame; its
    /// axes are x medial–lateral, y proximal–distal (+y proximal), z anterior–posterior
    /// (+z anterior). Default: the segment's own frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub anatomical_frame: Option<FrameSpec>,
    /// Implant segment only: points whose motion gives the MTPM, in the segment's local frame,
    /// mm (e.g. fictive points at a model-only implant's extremities). Default: its markers'
    /// centres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mtpm_points_mm: Option<Vec<[f64; 3]>>,
}

/// A frame given as a pose in a segment's local frame.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FrameSpec {
    /// Origin of the frame in the segment's local frame, mm. Default origin.
    #[serde(default)]
    pub position_mm: [f64; 3],
    /// Orientation, X-Y-Z Euler angles in degrees. Default `[0, 0, 0]`.
    #[serde(default)]
    pub rotation_deg: [f64; 3],
}

/// One exam of the study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExamSpec {
    /// Exam id (letters, digits, `-`, `_`, `.`), e.g. `postop`, `double`, `3m`, `1y`.
    pub id: String,
    /// Days from surgery (a reporting item). Not decreasing along the list. Default 0.
    #[serde(default)]
    pub days: u32,
    /// Whether this is the reference exam every migration is measured from. Exactly one exam is.
    /// It has no migration of its own. Default false.
    #[serde(default)]
    pub reference: bool,
    /// A double examination: the id of an earlier exam it repeats at the same visit (the patient
    /// repositioned in between). It has that exam's migration and no `translation_mm` or
    /// `rotation_deg` of its own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub double_of: Option<String>,
    /// The implants' prescribed migration at this exam: the motion of the implant's centre
    /// along the anatomical x, y, z axes, mm (subsidence of a femoral component is +y, of a
    /// tibial component −y: see docs/src/guide/clinical-study.md). Default `[0, 0, 0]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation_mm: Option<[f64; 3]>,
    /// The implants' prescribed rotation at this exam about their centre, X-Y-Z Euler angles
    /// about the anatomical axes, degrees (`R = Rx·Ry·Rz`). Default `[0, 0, 0]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation_deg: Option<[f64; 3]>,
}

/// A loose marker: one patient's bead displaced relative to its segment from an exam on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LooseMarkerSpec {
    /// The patient, 1-based (`3` is `p03`).
    pub patient: u32,
    /// The segment's phantom id.
    pub phantom: String,
    /// The bead id.
    pub bead: String,
    /// The first exam at which the bead sits displaced; it stays displaced in every later exam.
    pub from_exam: String,
    /// The displacement in the segment's local frame, mm.
    pub displacement_mm: [f64; 3],
}

/// Beads one patient does not have.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MissingMarkersSpec {
    /// The patient, 1-based.
    pub patient: u32,
    /// The phantom id.
    pub phantom: String,
    /// The ids of its beads this patient lacks in every exam.
    pub beads: Vec<String>,
}

impl StudyDesign {
    /// Index of the reference segment (validation guarantees exactly one).
    pub fn reference_segment(&self) -> Option<&SegmentSpec> {
        self.segments
            .iter()
            .find(|g| g.role == SegmentRole::Reference)
    }

    /// The implant segments, in order.
    pub fn implants(&self) -> impl Iterator<Item = &SegmentSpec> {
        self.segments
            .iter()
            .filter(|g| g.role == SegmentRole::Implant)
    }

    /// Index of the exam with id `id`.
    pub fn exam_index(&self, id: &str) -> Option<usize> {
        self.exams.iter().position(|e| e.id == id)
    }

    /// The exam whose migration exam `i` has: itself, or for a double the exam it repeats
    /// (followed through doubles of doubles).
    pub fn migration_exam(&self, i: usize) -> usize {
        let mut k = i;
        for _ in 0..self.exams.len() {
            match self.exams[k]
                .double_of
                .as_deref()
                .and_then(|id| self.exam_index(id))
            {
                Some(j) if j < k => k = j,
                _ => break,
            }
        }
        k
    }
}
