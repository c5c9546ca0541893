//! The scenario as the user writes it: plain serde records, one per TOML table.
//!
//! Every field's doc comment becomes its description in `schemas/scenario.schema.json`, which
//! editors with Taplo / Even Better TOML use to complete and check keys. Every default is stated
//! in the doc comment and in docs/src/reference/scenario.md. Coordinates are in the scanner (lab) frame, mm; angles
//! are X-Y-Z Euler angles in degrees (`R = Rx(α)·Ry(β)·Rz(γ)`, the paper's decomposition).

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub use super::dicom::*;
pub use super::imaging::*;
pub use super::sequence::*;
pub use super::study::*;

/// A whole simulation: the radiological set-up, the phantoms, the protocol and the outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Name of the scenario (letters, digits, `-`, `_`, `.`); the default output folder is
    /// `out/<name>`.
    pub name: String,
    /// Free text describing the scenario; copied into reports.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// Master seed of every random draw (geometry and noise). The same scenario, seed and
    /// program version give byte-identical outputs. Default 0.
    #[serde(default)]
    pub seed: u64,
    /// Noise levels and runs per level. Default: the paper's 5 levels × 20 runs.
    #[serde(default)]
    pub protocol: Protocol,
    /// A clinical RSA study instead of the protocol: segments, exams with the implant's
    /// prescribed migration, patients. Each exam of each patient is one run. Default: none (the
    /// protocol's runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub study: Option<StudyDesign>,
    /// A dynamic exam: every run becomes a sequence of frames in which the phantoms with a
    /// `motion` move. Default: none (one image set per run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sequence: Option<Sequence>,
    /// Image formats and compression. Default: 16-bit TIFF (Deflate) and 32-bit float EXR.
    #[serde(default)]
    pub output: OutputOptions,
    /// How images are formed: the paper's binary mode (the default) or attenuation mode.
    #[serde(default, skip_serializing_if = "Imaging::is_default")]
    pub imaging: Imaging,
    /// Materials of your own, by name, for `material` keys (beside the shipped library).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub materials: BTreeMap<String, UserMaterial>,
    /// Point X-ray sources (tube foci).
    pub sources: Vec<Source>,
    /// Flat detectors; each pairs with one source to form a beamline.
    pub detectors: Vec<Detector>,
    /// Objects in the beam: bead sets, calibration boxes, meshes.
    pub phantoms: Vec<Phantom>,
    /// Image sets: which phantoms appear together in one image per detector.
    pub exposures: Vec<Exposure>,
}

/// The validation protocol: a set of noise levels, each simulated `runs_per_level` times with
/// fresh random poses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Protocol {
    /// Mean background noise as fractions of I_max = 2^bpp − 1, each in [0, 1].
    /// Default `[0.0, 0.225, 0.45, 0.675, 0.9]` (the paper's 0 % to 90 % in steps of 22.5 %).
    #[serde(default = "Protocol::paper_noise_levels")]
    pub noise_levels: Vec<f64>,
    /// Runs per noise level, at least 1. Default 20 (the paper).
    #[serde(default = "Protocol::paper_runs_per_level")]
    pub runs_per_level: u32,
    /// Attenuation mode only, instead of `noise_levels`: exposure levels as factors on the
    /// imaging exposure (`photons_per_pixel` or `mas`), each > 0; image quality follows from the
    /// photons. Default `[1.0]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposure_levels: Option<Vec<f64>>,
}

impl Protocol {
    fn paper_noise_levels() -> Vec<f64> {
        vec![0.0, 0.225, 0.45, 0.675, 0.9]
    }

    fn paper_runs_per_level() -> u32 {
        20
    }
}

impl Default for Protocol {
    fn default() -> Self {
        Protocol {
            noise_levels: Self::paper_noise_levels(),
            runs_per_level: Self::paper_runs_per_level(),
            exposure_levels: None,
        }
    }
}

/// An image file format.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize, JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum ImageFormat {
    /// 16-bit grayscale TIFF (`.tiff`), detector counts 0..=I_max.
    Tiff,
    /// OpenEXR (`.exr`), one 32-bit float channel `Y` with the same counts.
    Exr,
    /// DICOM Digital X-Ray images (`.dcm`), 16-bit containers with the same counts; which ones
    /// (for presentation, for processing) is set in `[output.dicom]`.
    Dicom,
}

impl ImageFormat {
    /// The file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            ImageFormat::Tiff => "tiff",
            ImageFormat::Exr => "exr",
            ImageFormat::Dicom => "dcm",
        }
    }
}

/// One image file written per exposure and detector: a format, and for DICOM its intent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFile {
    /// `<exposure>-<detector>.tiff`.
    Tiff,
    /// `<exposure>-<detector>.exr`.
    Exr,
    /// `<exposure>-<detector>.dcm` (for presentation) or `…-processing.dcm`.
    Dicom(DicomIntent),
}

impl ImageFile {
    /// The file's name for an image whose stem is `<exposure>-<detector>`.
    pub fn name(self, stem: &str) -> String {
        match self {
            ImageFile::Tiff => format!("{stem}.tiff"),
            ImageFile::Exr => format!("{stem}.exr"),
            ImageFile::Dicom(intent) => format!("{stem}{}", intent.file_suffix()),
        }
    }

    /// Its format.
    pub fn format(self) -> ImageFormat {
        match self {
            ImageFile::Tiff => ImageFormat::Tiff,
            ImageFile::Exr => ImageFormat::Exr,
            ImageFile::Dicom(_) => ImageFormat::Dicom,
        }
    }
}

/// Compression of the TIFF files.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum TiffCompression {
    /// No compression: fastest, largest.
    None,
    /// LZW with the horizontal predictor.
    Lzw,
    /// Deflate (zlib, fast level) with the horizontal predictor: small files, read by every TIFF
    /// reader.
    #[default]
    Deflate,
    /// PackBits run-length coding.
    Packbits,
}

/// How EXR scanline blocks are compressed. All options are lossless.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ExrCompression {
    /// No compression (`NO_COMPRESSION`), one scanline per block: fastest, 4 bytes per pixel.
    None,
    /// Run-length coding (`RLE_COMPRESSION`), one scanline per block: fast, but gains little on
    /// noisy images.
    Rle,
    /// zlib over blocks of 16 scanlines (`ZIP_COMPRESSION`, the `exr` crate's `ZIP16`), with
    /// OpenEXR's byte reordering and delta predictor. The default: the smallest files.
    #[default]
    Zip,
    /// zlib over single scanlines (`ZIPS_COMPRESSION`, the `exr` crate's `ZIP1`).
    Zips,
}

/// What files a run writes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputOptions {
    /// Image formats to write for every exposure and detector: `"tiff"`, `"exr"`, `"dicom"`.
    /// Default `["tiff", "exr"]`.
    #[serde(default = "OutputOptions::default_formats")]
    pub formats: Vec<ImageFormat>,
    /// TIFF compression. Default `"deflate"`.
    #[serde(default)]
    pub tiff_compression: TiffCompression,
    /// EXR compression. Default `"zip"`.
    #[serde(default)]
    pub exr_compression: ExrCompression,
    /// DICOM images: which intents, and their date. Default: for presentation, dated
    /// 2000-01-01.
    #[serde(default, skip_serializing_if = "DicomOptions::is_default")]
    pub dicom: DicomOptions,
}

impl OutputOptions {
    fn default_formats() -> Vec<ImageFormat> {
        vec![ImageFormat::Tiff, ImageFormat::Exr]
    }

    /// Every image file written per exposure and detector, in the order of `formats` (DICOM:
    /// in the order of `intents`).
    pub fn image_files(&self) -> Vec<ImageFile> {
        self.formats
            .iter()
            .flat_map(|f| match f {
                ImageFormat::Tiff => vec![ImageFile::Tiff],
                ImageFormat::Exr => vec![ImageFile::Exr],
                ImageFormat::Dicom => self
                    .dicom
                    .intents
                    .iter()
                    .map(|&i| ImageFile::Dicom(i))
                    .collect(),
            })
            .collect()
    }
}

impl Default for OutputOptions {
    fn default() -> Self {
        OutputOptions {
            formats: Self::default_formats(),
            tiff_compression: TiffCompression::default(),
            exr_compression: ExrCompression::default(),
            dicom: DicomOptions::default(),
        }
    }
}

/// ± half-widths of the uniform random draw applied to a position each run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PositionRange {
    /// Each run adds a uniform draw in [−r, +r] mm along each scanner axis x, y, z.
    /// Default `[0, 0, 0]` (no randomisation).
    #[serde(default)]
    pub position_mm: [f64; 3],
}

/// ± half-widths of the uniform random draws applied to a pose each run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PoseRange {
    /// Each run adds a uniform draw in [−r, +r] mm along each scanner axis x, y, z.
    /// Default `[0, 0, 0]`.
    #[serde(default)]
    pub position_mm: [f64; 3],
    /// Each run turns the object by X-Y-Z Euler angles drawn uniformly in [−r, +r] degrees about
    /// its own (nominal) local axes: `R = R_nominal · Rx(δα)·Ry(δβ)·Rz(δγ)`. Default `[0, 0, 0]`.
    #[serde(default)]
    pub rotation_deg: [f64; 3],
}

/// A point X-ray source (the tube focus), ideal and monochromatic as in the paper.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Source {
    /// Unique id (letters, digits, `-`, `_`, `.`), used in file names and reports.
    pub id: String,
    /// Nominal focus position in the scanner frame, mm.
    pub position_mm: [f64; 3],
    /// Random displacement per run. Default: none.
    #[serde(default)]
    pub randomize: PositionRange,
}

/// A flat detector. Its local frame: x = r along a row (increasing column), y = c along a column
/// (increasing row), z = s the normal towards its source; origin at the centre of the active area.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Detector {
    /// Unique id (letters, digits, `-`, `_`, `.`), used in file names and reports.
    pub id: String,
    /// Id of the source this detector pairs with (one beamline).
    pub source: String,
    /// Pixel counts `[columns, rows]`, each 1..=65535.
    pub pixels: [u32; 2],
    /// Active area `[width, height]` in mm. Give exactly one of `size_mm` and `pixel_pitch_mm`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size_mm: Option<[f64; 2]>,
    /// Pixel pitch `[x, y]` in mm. Give exactly one of `size_mm` and `pixel_pitch_mm`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixel_pitch_mm: Option<[f64; 2]>,
    /// Bits per pixel, 1..=16; I_max = 2^bpp − 1. Default 16.
    #[serde(default = "Detector::default_bpp")]
    pub bpp: u8,
    /// Nominal position of the centre of the active area in the scanner frame, mm.
    pub position_mm: [f64; 3],
    /// Nominal orientation, X-Y-Z Euler angles in degrees; `[0, 0, 0]` puts r, c, s along the
    /// scanner x, y, z (a detector facing a source on its +z side). Default `[0, 0, 0]`.
    #[serde(default)]
    pub rotation_deg: [f64; 3],
    /// Random displacement and tilt per run. Default: none.
    #[serde(default)]
    pub randomize: PoseRange,
}

impl Detector {
    fn default_bpp() -> u8 {
        16
    }
}

/// A tantalum bead (an exact sphere).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Bead {
    /// Id, unique within its phantom.
    pub id: String,
    /// Centre in the phantom's local frame, mm.
    pub position_mm: [f64; 3],
    /// Diameter in mm. Default 1.0 (the usual RSA tantalum bead).
    #[serde(default = "default_bead_diameter_mm")]
    pub diameter_mm: f64,
}

fn default_bead_diameter_mm() -> f64 {
    1.0
}

/// The role of a calibration plate, as in Selvik's calibration cages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PlateRole {
    /// The plate near the detector; its beads define the image plane mapping.
    Fiducial,
    /// The plate near the source; its beads fix the focus position.
    Control,
}

/// One plate of a calibration box: a rectangular grid of beads in the plate's local x-y plane.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Plate {
    /// Id, unique within the box; bead ids are `<plate>-<row>-<column>` (two digits each).
    pub id: String,
    /// Fiducial (near a detector) or control (near a source).
    pub role: PlateRole,
    /// Centre of the grid in the box frame, mm.
    pub center_mm: [f64; 3],
    /// Orientation of the plate in the box frame, X-Y-Z Euler angles in degrees; the grid lies in
    /// the plate's local x-y plane. Default `[0, 0, 0]` (a plate normal to z).
    #[serde(default)]
    pub rotation_deg: [f64; 3],
    /// Outer size of the (radiolucent) plate `[x, y]` in mm; the bead grid must fit inside it.
    pub size_mm: [f64; 2],
    /// Number of beads `[columns along x, rows along y]`, each at least 1.
    pub grid: [u32; 2],
    /// Bead spacing `[x, y]` in mm.
    pub spacing_mm: [f64; 2],
    /// Bead diameter in mm. Default 1.0.
    #[serde(default = "default_bead_diameter_mm")]
    pub bead_diameter_mm: f64,
    /// Grid positions `[column, row]` left empty, as real cages do to mark their orientation.
    /// Default: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub omit: Vec<[u32; 2]>,
    /// Attenuation mode: thickness of the plate itself (a slab of `size_mm`, centred on the bead
    /// plane, the beads embedded in it), mm. Default: no plate material, beads only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thickness_mm: Option<f64>,
    /// Attenuation mode: the plate's material. Default `"pmma"` (acrylic).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<String>,
}

/// A calibration box (cage) built like real RSA cages: plates of bead grids.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CalibrationBox {
    /// The plates, at least one.
    pub plates: Vec<Plate>,
}

/// A closed triangle mesh loaded from a file, optionally carrying beads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MeshPhantom {
    /// Path of a `.glb`, `.gltf` or `.stl` file, relative to the scenario file.
    pub file: String,
    /// Millimetres per file unit. Default 1000 for glTF (the glTF spec's metre) and 1 for STL
    /// (customary millimetres).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unit_mm: Option<f64>,
    /// Beads fixed to the mesh, in the mesh's local frame (mm, after `unit_mm`). Default: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub beads: Vec<Bead>,
}

/// An object in the beam. Give exactly one of `beads`, `calibration_box`, `mesh` or
/// `elliptic_cylinder`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Phantom {
    /// Unique id (letters, digits, `-`, `_`, `.`), used in file names and reports.
    pub id: String,
    /// Nominal position of the phantom's local origin in the scanner frame, mm. Default origin.
    #[serde(default)]
    pub position_mm: [f64; 3],
    /// Nominal orientation, X-Y-Z Euler angles in degrees. Default `[0, 0, 0]`.
    #[serde(default)]
    pub rotation_deg: [f64; 3],
    /// Random displacement and rotation per run. Default: none.
    #[serde(default)]
    pub randomize: PoseRange,
    /// A free set of beads.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beads: Option<Vec<Bead>>,
    /// A calibration box. The first calibration box defines the world (box) frame in which all
    /// ground truth is written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration_box: Option<CalibrationBox>,
    /// A mesh (a prosthesis or bone model), optionally with beads.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<MeshPhantom>,
    /// An elliptic cylinder along the local z axis, e.g. a soft-tissue envelope of the thigh
    /// (attenuation mode; binary mode renders it as any object).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elliptic_cylinder: Option<EllipticCylinder>,
    /// Attenuation mode: the material filling the mesh or cylinder (library name or a
    /// `[materials]` name, e.g. `"cocr_f75"`, `"bone_cortical"`, `"soft_tissue"`). Required there
    /// for meshes and cylinders.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<String>,
    /// Attenuation mode: the material of this phantom's beads. Default `"tantalum"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bead_material: Option<String>,
    /// Id of another phantom this one is rigidly fixed to: `position_mm` and `rotation_deg` are
    /// then in that phantom's local frame, and it moves with it each run (it has no `randomize`
    /// of its own). E.g. a bone model fixed to the implant it carries.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixed_to: Option<String>,
    /// Attenuation mode: id of the phantom whose volume wholly contains this one's (a bone
    /// inside the soft-tissue envelope, the cancellous core inside the cortex): where a ray
    /// crosses both, this phantom's material replaces that one's. Checked on every pixel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inside: Option<String>,
    /// With `[sequence]`: how this phantom moves from frame to frame (keyframes relative to its
    /// pose without motion). Phantoms `fixed_to` it move with it. Default: it stands still.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<Motion>,
}

/// An elliptic cylinder centred on the phantom's local origin, its axis along local z, with
/// flat end caps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct EllipticCylinder {
    /// Semi-axes along local x and y, mm.
    pub radii_mm: [f64; 2],
    /// Length along local z, mm (from −length/2 to +length/2).
    pub length_mm: f64,
}

/// One image set: every detector takes one image of these phantoms together.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Exposure {
    /// Unique id (letters, digits, `-`, `_`, `.`); images are `<exposure>-<detector>.<ext>`.
    pub id: String,
    /// Ids of the phantoms in the beam, at least one.
    pub phantoms: Vec<String>,
}
