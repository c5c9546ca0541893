//! `truth.json`: the exact ground truth of one run, in the calibration box frame.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::expand::Run;

/// The format tag of truth files written by this version.
pub const TRUTH_FORMAT: &str = "rsasim-truth/1";

/// Ground truth of one run: every pose drawn (the fields of [`Run`] at top level), and for each
/// image the files and the projected centre of every bead.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Truth {
    /// Always `rsasim-truth/1` for this layout.
    pub format: String,
    /// The program that wrote the file, `rsasim <version>`.
    pub program: String,
    /// The scenario's name.
    pub scenario: String,
    /// The run: id, noise level, sources, detectors, phantoms with their beads, exposures.
    #[serde(flatten)]
    pub run: Run,
    /// One entry per exposure and detector.
    pub images: Vec<ImageTruth>,
}

/// One image (an exposure seen by a detector) and where each bead of its phantoms lands.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ImageTruth {
    /// Exposure id.
    pub exposure: String,
    /// Detector id.
    pub detector: String,
    /// The image files, one per format, relative to the run folder.
    pub files: Vec<FileRef>,
    /// Every bead of the exposure's phantoms, projected.
    pub markers: Vec<ProjectedMarker>,
    /// Attenuation mode: pixels clamped at I_max (over-exposure).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub saturated_pixels: Option<u64>,
    /// Attenuation mode with `path_length_layers`: the EXR holding, per material, the path
    /// length (mm) of every pixel's ray (channels `pathlength_mm.<material>`), beside truth.json.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path_lengths: Option<FileRef>,
}

/// A file and its SHA-256.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FileRef {
    /// Path relative to the folder of the JSON file that lists it, with `/` separators.
    pub path: String,
    /// SHA-256 of the file's bytes, lowercase hex.
    pub sha256: String,
}

/// The central projection of a bead's centre onto a detector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProjectedMarker {
    /// Id of the phantom the bead belongs to.
    pub phantom: String,
    /// Bead id within its phantom.
    pub id: String,
    /// Continuous pixel coordinates `[u, v]` of the projected centre: pixel (column i, row j)
    /// spans [i, i+1) × [j, j+1), its centre is (i + 0.5, j + 0.5).
    pub pixel: [f64; 2],
    /// Whether the projected centre falls on the active area.
    pub inside: bool,
    /// Whether the bead is hidden by an implant. Attenuation mode: the ray to the pixel under the
    /// projected centre crosses metal (a volume of density ≥ 4 g/cm³, beads aside), i.e. the bead
    /// is seen over the implant. Binary mode: the bead's disc shares a pixel with the shadow of a
    /// solid of the exposure (a mesh or cylinder): some pixel centre whose ray crosses the bead
    /// also crosses that solid, so the bead merges with its shadow.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occluded: Option<bool>,
    /// Attenuation mode: the fraction of the bead's shadow pixels whose ray also crosses metal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metal_fraction: Option<f64>,
}
