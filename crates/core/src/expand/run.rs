//! The plain records of one concrete run: every pose drawn, in the calibration box frame.
//! These are what `rsasim expand` prints and what `truth.json` is built from.

use glam::{DMat3, DVec3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::geometry::{DetectorFrame, Pose};
use crate::geometry::{mat3_rows_serde, vec3_serde};

/// One run of the protocol: noise level `n`, run `r`, with its drawn geometry.
///
/// `truth.json` flattens these fields into its top level, so this record does not reject
/// unknown keys itself; `Truth` does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Run {
    /// `n<level>-r<run>`, e.g. `n2-r07` (both 0-based; the run number has at least two digits).
    pub id: String,
    /// Index of the noise level in the protocol, 0-based.
    pub noise_level_index: u32,
    /// Mean background noise as a fraction of I_max (binary mode; 0 in attenuation mode).
    pub noise_level: f64,
    /// Attenuation mode: the factor on the imaging exposure of this run's level.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposure_factor: Option<f64>,
    /// Index of the run within its noise level, 0-based.
    pub run_index: u32,
    /// The label whose SHA-256 keys this run's geometry stream (see docs/src/reference/conventions.md, "Determinism and seeds").
    pub geometry_stream: String,
    /// Pose of the calibration box (the world frame of this file) in the scanner frame.
    pub box_pose_in_scanner: Pose,
    /// Sources, in the box frame.
    pub sources: Vec<SourceState>,
    /// Detectors, in the box frame.
    pub detectors: Vec<DetectorState>,
    /// Phantoms with their beads, in the box frame.
    pub phantoms: Vec<PhantomState>,
    /// Image sets of this run.
    pub exposures: Vec<ExposureState>,
    /// With `[sequence]`: which frame of which sequence this run is. Absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<FrameState>,
}

/// A run's place in a sequence (module [`super::sequence`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FrameState {
    /// The sequence's id, `n<level>-r<run>`: the run id without the frame.
    pub sequence: String,
    /// The frame's number, 0-based.
    pub index: u32,
    /// Frames in the sequence.
    pub count: u32,
    /// The frame's time from the first frame, s: `index / frame_rate_hz` (the middle of its
    /// pulse).
    pub time_s: f64,
    /// The kinematics of each joint of `[sequence]` at `time_s`, in the joint coordinate system
    /// of Grood and Suntay (`crate::geometry::joint`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub joints: Vec<JointState>,
}

/// One joint's kinematics in one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JointState {
    /// The joint's id.
    pub id: String,
    /// Flexion α (about e1, the proximal frame's x), ab/adduction β (about the floating axis
    /// e2) and axial rotation γ (about e3, the distal frame's y), degrees.
    pub angles_deg: [f64; 3],
    /// The distal frame's origin from the proximal one's along e1, e2, e3, mm.
    pub translation_mm: [f64; 3],
}

impl Run {
    /// The exposure's name in the labels of this run's noise streams (`crate::noise::NoiseKey`):
    /// its id, followed by `/f<k>` in frame `k` of a sequence (module [`super::sequence`]), so
    /// that every frame has its own noise.
    pub fn noise_exposure(&self, exposure_id: &str) -> String {
        match &self.frame {
            Some(f) => format!("{exposure_id}/f{}", f.index),
            None => exposure_id.to_string(),
        }
    }

    /// The focus position of the source a detector pairs with, mm, box frame.
    pub fn source_of(&self, detector: &DetectorState) -> DVec3 {
        self.sources
            .iter()
            .find(|s| s.id == detector.source)
            .expect("validated: every detector names a source")
            .position_mm
    }
}

/// A source's drawn position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SourceState {
    /// The scenario's id.
    pub id: String,
    /// Focus position, mm, box frame: the focal spot's geometric centre.
    #[serde(with = "vec3_serde")]
    #[schemars(with = "[f64; 3]")]
    pub position_mm: DVec3,
    /// The effective source, mm, box frame: the focal spot's intensity-weighted centre as its
    /// beamline's detector sees it, which is what a calibration of the images finds. Present
    /// only where it differs from `position_mm`: a spot whose emission falls across it
    /// (`imaging.focal_spot.intensity_fall_percent`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub effective_position_mm: Option<[f64; 3]>,
}

/// A detector's drawn pose and its pixel grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DetectorState {
    /// The scenario's id.
    pub id: String,
    /// Id of its source.
    pub source: String,
    /// Centre of the active area, mm, box frame.
    #[serde(with = "vec3_serde")]
    #[schemars(with = "[f64; 3]")]
    pub position_mm: DVec3,
    /// Rotation (rows); columns are the r, c, s axes in the box frame.
    #[serde(with = "mat3_rows_serde")]
    #[schemars(with = "[[f64; 3]; 3]")]
    pub rotation: DMat3,
    /// `[columns, rows]`.
    pub pixels: [u32; 2],
    /// Pixel pitch `[x, y]`, mm.
    pub pixel_pitch_mm: [f64; 2],
    /// Bits per pixel; I_max = 2^bpp − 1.
    pub bpp: u8,
}

impl DetectorState {
    /// The detector's pose in the box frame.
    pub fn pose(&self) -> Pose {
        Pose {
            position_mm: self.position_mm,
            rotation: self.rotation,
        }
    }

    /// The detector's pixel frame, for projection and tracing.
    pub fn frame(&self) -> DetectorFrame {
        DetectorFrame {
            pose: self.pose(),
            pixels: self.pixels,
            pixel_pitch_mm: self.pixel_pitch_mm,
        }
    }

    /// I_max = 2^bpp − 1.
    pub fn i_max(&self) -> u16 {
        ((1u32 << self.bpp) - 1) as u16
    }
}

/// A phantom's drawn pose and its beads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PhantomState {
    /// The scenario's id.
    pub id: String,
    /// `beads`, `calibration_box` or `mesh`.
    pub kind: String,
    /// Origin of the phantom's local frame, mm, box frame.
    #[serde(with = "vec3_serde")]
    #[schemars(with = "[f64; 3]")]
    pub position_mm: DVec3,
    /// Rotation (rows); columns are the local axes in the box frame.
    #[serde(with = "mat3_rows_serde")]
    #[schemars(with = "[[f64; 3]; 3]")]
    pub rotation: DMat3,
    /// The phantom's beads.
    pub markers: Vec<MarkerState>,
}

impl PhantomState {
    /// The phantom's pose in the box frame.
    pub fn pose(&self) -> Pose {
        Pose {
            position_mm: self.position_mm,
            rotation: self.rotation,
        }
    }
}

/// A bead's centre in the box frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MarkerState {
    /// Id, unique within its phantom.
    pub id: String,
    /// Centre, mm, box frame.
    #[serde(with = "vec3_serde")]
    #[schemars(with = "[f64; 3]")]
    pub position_mm: DVec3,
    /// Diameter, mm.
    pub diameter_mm: f64,
}

impl ExposureState {
    /// Indices into `models` (the run's phantoms, in scenario order) of the phantoms in the beam.
    pub fn phantom_indices(&self, models: &[crate::phantom::PhantomModel]) -> Vec<usize> {
        self.phantoms
            .iter()
            .map(|id| {
                models
                    .iter()
                    .position(|m| &m.id == id)
                    .expect("validated phantom id")
            })
            .collect()
    }
}

/// An image set of the run: one image per detector of these phantoms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExposureState {
    /// The scenario's id.
    pub id: String,
    /// Ids of the phantoms in the beam.
    pub phantoms: Vec<String>,
}
