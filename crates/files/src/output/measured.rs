//! `measured.json`: what a software under test reconstructed for one run. It mirrors the ids
//! and fields of `truth.json`; everything a software does not measure is simply left out.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The format tag of measured files.
pub const MEASURED_FORMAT: &str = "rsasim-measured/1";

/// How rsasim's reference program (`rsasim reconstruct`) signs its results: their `software`
/// starts with this.
pub const REFERENCE_SOFTWARE_PREFIX: &str = "rsasim reconstruct ";

/// Whether `file` holds results written by rsasim's reference program: a regular file of at
/// most 64 MiB (anything larger is not ours and is not read) that parses as [`Measured`], a
/// UTF-8 BOM allowed, and whose `software` starts with [`REFERENCE_SOFTWARE_PREFIX`]. One rule for
/// `reconstruct` (which never replaces another software's results) and `--force` (which never
/// deletes them).
pub fn written_by_reference_program(file: &std::path::Path) -> bool {
    // Through the gate: a FIFO swapped in after a check cannot hang the program.
    let Ok(bytes) = super::received::read_in_folder(file, 64 << 20) else {
        return false;
    };
    let text = String::from_utf8_lossy(&bytes);
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    serde_json::from_str::<Measured>(text)
        .is_ok_and(|m| m.software.starts_with(REFERENCE_SOFTWARE_PREFIX))
}

/// One run's reconstruction by a software under test, in the calibration box frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Measured {
    /// Always `rsasim-measured/1`.
    pub format: String,
    /// Run id, as in `truth.json`.
    pub run: String,
    /// Name and version of the software that measured, e.g. `"MyRSA 3.1"` or
    /// `"rsasim reconstruct 0.1.0 (dlt, markers)"`.
    pub software: String,
    /// The methods the software used, if it says (rsasim's reference program always does).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub methods: Option<MeasuredMethods>,
    /// Reconstructed source (focus) positions.
    #[serde(default)]
    pub sources: Vec<MeasuredPoint>,
    /// Reconstructed detector poses.
    #[serde(default)]
    pub detectors: Vec<MeasuredPose>,
    /// Reconstructed phantom poses.
    #[serde(default)]
    pub phantoms: Vec<MeasuredPose>,
}

/// The methods a reconstruction used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MeasuredMethods {
    /// How the scene was calibrated, e.g. `dlt` or `selvik`.
    pub calibration: String,
    /// How each model was found, by phantom id, e.g. `{"femur": "markers"}`.
    #[serde(default)]
    pub models: std::collections::BTreeMap<String, String>,
}

/// A reconstructed position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MeasuredPoint {
    /// Id, as in `truth.json`.
    pub id: String,
    /// Position, mm, box frame.
    pub position_mm: [f64; 3],
    /// How well the software's fit went, if it says.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<FitQuality>,
}

/// Quality figures of a reconstruction, as RSA guidelines ask them to be reported. Every field
/// is optional; a software reports what it has.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FitQuality {
    /// Number of beads the fit used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beads_used: Option<usize>,
    /// Root-mean-square reprojection error of a scene calibration, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reprojection_rms_px: Option<f64>,
    /// Mean crossing-line error of triangulated beads (the distance between the two views'
    /// rays), mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crossing_line_error_mm: Option<f64>,
    /// Mean error of rigid-body fitting (ME), mm; the guideline limit is 0.35 mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_error_mm: Option<f64>,
    /// Condition number of the bead configuration (CN); the guideline limit is 150.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub condition_number: Option<f64>,
    /// Model-based RSA: the mean distance between the detected edge points of the model's shadow
    /// and its fitted projected outline, pixels (over every view).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contour_distance_px: Option<f64>,
    /// Model-based RSA: the number of detected edge points the fit used (over every view).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contour_points: Option<usize>,
    /// Guideline limits exceeded, e.g. `"ME > 0.35 mm"`, `"CN > 150"`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub flags: Vec<String>,
    /// Beads the software did not measure on an image because their image falls on the metal
    /// shadow of an implant (attenuation-mode images), each with the detector it is hidden on.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub occluded: Vec<OccludedBead>,
    /// Beads the software left out of an image because a calibration-box bead's image overlaps
    /// theirs there (their blob's centre would be pulled towards the box bead), each with the
    /// detector of that image.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub overprojected: Vec<OccludedBead>,
}

/// A bead hidden on one image.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OccludedBead {
    /// Bead id, as in the phantom's bead table.
    pub bead: String,
    /// Id of the detector whose image hides it.
    pub detector: String,
}

/// A reconstructed pose; `rotation` (three rows, columns = local axes in the box frame) may be
/// left out by software that measures positions only.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MeasuredPose {
    /// Id, as in `truth.json`.
    pub id: String,
    /// Position of the local origin, mm, box frame.
    pub position_mm: [f64; 3],
    /// Rotation matrix rows, if measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation: Option<[[f64; 3]; 3]>,
    /// Reconstructed bead centres, if measured.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub markers: Vec<MeasuredPoint>,
    /// How well the software's fit went, if it says.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<FitQuality>,
}
