//! How images are formed, as the user writes it: the `[imaging]` table and the user's
//! `[materials.<name>]` tables. Plain records; the physics lives in `crate::material`,
//! `crate::spectrum` and `crate::response`, which later stages feed from these records.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Which image model a scenario uses.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ImagingMode {
    /// The paper's model (the default): a pixel whose ray crosses any object is I_max, the
    /// background carries Poisson noise of `noise_level · I_max`.
    #[default]
    Binary,
    /// A radiograph by physics: per pixel the exact path length in every material, Beer–Lambert
    /// attenuation of the source spectrum, the detector's absorption and quantum noise on every
    /// pixel. Every volume needs a `material`.
    Attenuation,
}

/// How images are formed. Default: the paper's binary mode; everything else here applies to
/// `mode = "attenuation"` only, except `pixel_samples` and `focal_spot` (both modes).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Imaging {
    /// `"binary"` (the paper, the default) or `"attenuation"`.
    #[serde(default)]
    pub mode: ImagingMode,
    /// A monochromatic source of this energy, keV (within 1–200). Give exactly one of
    /// `energy_kev`, `tube` and `spectrum_file` in attenuation mode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy_kev: Option<f64>,
    /// An X-ray tube: tungsten anode, kVp, anode angle and filtration (SpekPy spectra).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tube: Option<Tube>,
    /// A spectrum of your own: a text file next to the scenario, one `energy_kev photons` pair
    /// per line (relative photon numbers; `#` starts a comment).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spectrum_file: Option<String>,
    /// Most energy bins traced per image: the spectrum's bins are grouped into at most this
    /// many (never across an absorption edge of a material in the beam; the tube's lines on
    /// their own). Default 40, or 1000 when `spectral_tolerance` is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_energy_bins: Option<u32>,
    /// The relative error of a layer's transmission that grouping the spectrum's bins may add,
    /// for every material in the beam at every thickness down to 0.1 % transmission: the bins
    /// are as many as it needs (at most `max_energy_bins`; when that is too few, a warning says
    /// what they hold). Default: the finest that `max_energy_bins` allows. `rsasim validate` and
    /// `rsasim spectrum` show the bins and the tolerance they hold.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spectral_tolerance: Option<f64>,
    /// Expected photons reaching one pixel with no object in the beam, at the detector point
    /// nearest the source (elsewhere scaled by inverse square and obliquity). Give exactly one
    /// of `photons_per_pixel` and `mas` in attenuation mode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub photons_per_pixel: Option<f64>,
    /// Tube current-time product, mAs (needs `tube`): photons per pixel follow from the tube's
    /// output per mAs at 1 m, the source–detector distance and the pixel area.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mas: Option<f64>,
    /// The detector's response (shared by every detector).
    #[serde(default, skip_serializing_if = "ResponseOptions::is_default")]
    pub detector: ResponseOptions,
    /// Also write, per image, an EXR with one layer per material: the path length (mm) of each
    /// pixel's ray in it (truth for image-processing research). Default false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub path_length_layers: bool,
    /// Area sampling (both modes): s×s rays per pixel on a regular grid over its area (at
    /// `(i + (a + ½)/s, j + (b + ½)/s)`), averaged, so a pixel an edge crosses gets a partial
    /// value. Default 1: one ray to the pixel centre (the paper). At most 16.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixel_samples: Option<u32>,
    /// A finite focal spot (both modes), sampled by k×k sub-sources. Default: a point source.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub focal_spot: Option<FocalSpot>,
    /// Attenuation mode with `pixel_samples` or `focal_spot`: `"adaptive"` (the default) traces
    /// every ray only for pixels near an edge or a kink, where the one ray to the pixel centre
    /// would differ from the mean of all rays by more than 0.01 of the pixel's quantum-noise SD
    /// (estimated); `"full"` traces every ray of every pixel. Binary mode always traces every ray.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ray_sampling: Option<RaySampling>,
}

/// Which pixels get all their rays (attenuation mode).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum RaySampling {
    /// Only pixels near an edge or a kink; the others take the ray to their centre from the
    /// spot's centre (`crate::sampling::adaptive`).
    #[default]
    Adaptive,
    /// Every pixel.
    Full,
}

/// The intensity profile of a focal spot.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SpotProfile {
    /// Uniform over a square of side `size_mm` (the default).
    #[default]
    Uniform,
    /// A round Gaussian whose full width at half maximum is `size_mm`.
    Gaussian,
}

/// A detector axis, with its sign: where the anode lies, seen from the detector.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
pub enum AxisDirection {
    /// Along +r (increasing column index).
    #[serde(rename = "+r")]
    PlusR,
    /// Along −r.
    #[serde(rename = "-r")]
    MinusR,
    /// Along +c (increasing row index).
    #[serde(rename = "+c")]
    PlusC,
    /// Along −c.
    #[serde(rename = "-c")]
    MinusC,
}

/// The X-ray tube's focal spot: a finite source instead of a point, the same for every source.
/// Its centre is the source position (the truth's source position is the focal-spot centre).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FocalSpot {
    /// The spot's width, mm, in the plane through the source parallel to the detector (the
    /// effective spot seen from the detector): the side of a uniform square or the FWHM of a
    /// Gaussian. IEC 60336 nominal sizes: 0.3, 0.6, 1.0, 1.2 mm.
    pub size_mm: f64,
    /// `"uniform"` (default) or `"gaussian"`.
    #[serde(default)]
    pub profile: SpotProfile,
    /// Sub-sources per axis, k (k×k in all), 1 to 16. Default 3. Uniform: the centres of a
    /// k×k grid of equal cells; Gaussian: the k-point Gauss–Hermite nodes and weights.
    #[serde(default = "FocalSpot::default_samples")]
    pub samples: u32,
    /// Anode heel effect (attenuation mode): the fluence falls linearly towards the anode side by
    /// this many percent per 100 mm along the detector axis `anode_direction`, zero at the
    /// detector centre. Default 0 (none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heel_percent_per_100_mm: Option<f64>,
    /// The spot's emission across its width (both modes): it falls linearly along
    /// `anode_direction` by this many percent from the spot's cathode-side edge to its
    /// anode-side edge (a uniform spot's side, a Gaussian's FWHM; clamped at zero beyond), so
    /// the spot's intensity-weighted centre — the effective source a calibration of the images
    /// finds — lies off its geometric centre towards the cathode (truth:
    /// `sources[].effective_position_mm`). From 0 to below 100; default 0 (a symmetric spot).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intensity_fall_percent: Option<f64>,
    /// The detector axis pointing towards the anode side: `"+r"`, `"-r"`, `"+c"` or `"-c"`.
    /// Default `"-c"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub anode_direction: Option<AxisDirection>,
}

impl FocalSpot {
    fn default_samples() -> u32 {
        3
    }
}

impl Imaging {
    /// Whether this is the default (binary mode with no options): then it is not written back.
    pub fn is_default(&self) -> bool {
        *self == Imaging::default()
    }

    /// Whether images are formed by attenuation.
    pub fn is_attenuation(&self) -> bool {
        self.mode == ImagingMode::Attenuation
    }

    /// The bin limit: `max_energy_bins`, else 1000 with a `spectral_tolerance`, else 40.
    pub fn max_bins(&self) -> usize {
        let default = if self.spectral_tolerance.is_some() {
            1000
        } else {
            40
        };
        self.max_energy_bins.unwrap_or(default) as usize
    }

    /// Rays per pixel side, s (default 1).
    pub fn samples_per_side(&self) -> u32 {
        self.pixel_samples.unwrap_or(1)
    }

    /// Whether a pixel is one ray from a point source to its centre (the paper): no area
    /// sampling and no focal spot.
    pub fn is_point_sampled(&self) -> bool {
        self.samples_per_side() == 1 && self.focal_spot.is_none()
    }
}

/// An X-ray tube with a tungsten anode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Tube {
    /// Peak tube voltage, kV (an integer from 40 to 150).
    pub kvp: f64,
    /// Anode (target) angle, degrees. Default 12.
    #[serde(default = "Tube::default_anode_angle_deg")]
    pub anode_angle_deg: f64,
    /// Filters in the beam, inherent and added (e.g. 2.5 mm aluminium). Default none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub filtration: Vec<Filter>,
}

impl Tube {
    fn default_anode_angle_deg() -> f64 {
        12.0
    }
}

/// A filter of uniform thickness across the beam.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Filter {
    /// A material name (library or `[materials]`), e.g. `"aluminium"`, `"copper"`.
    pub material: String,
    /// Thickness along the central ray, mm.
    pub thickness_mm: f64,
}

/// How the detector turns absorbed photons into a signal.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ResponseKind {
    /// The signal is the absorbed energy (flat-panel and CR detectors). The default.
    #[default]
    EnergyIntegrating,
    /// The signal is the number of absorbed photons.
    PhotonCounting,
}

/// Which way the stored values run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PolarityOption {
    /// Detector values: bright where many photons arrive, metal dark. The default.
    #[default]
    Raw,
    /// Flat-field corrected and log-transformed, dense matter bright, as a clinician views a
    /// radiograph: `I_max · ln(S_open / S) / radiograph_range`, clamped.
    Radiograph,
}

/// A scintillator layer in front of the photodiodes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Scintillator {
    /// Its material. Default `"csi"` (caesium iodide).
    #[serde(default = "Scintillator::default_material")]
    pub material: String,
    /// Thickness, mm (e.g. 0.6 for a CsI flat panel).
    pub thickness_mm: f64,
}

impl Scintillator {
    fn default_material() -> String {
        "csi".into()
    }
}

/// The detector response in attenuation mode.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ResponseOptions {
    /// `"energy_integrating"` (default) or `"photon_counting"`.
    #[serde(default)]
    pub response: ResponseKind,
    /// A scintillator whose absorption `1 − exp(−μ(E)·t)` weights each energy. Default: an
    /// ideal absorber (every photon counted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scintillator: Option<Scintillator>,
    /// Digital units per keV (energy integrating) or per photon (photon counting). Default:
    /// chosen so that the open field at the detector point nearest the source reads
    /// `white_level · I_max`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain: Option<f64>,
    /// The fraction of I_max the open field reads when `gain` is not given. Default 0.8.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub white_level: Option<f64>,
    /// Digital value added to every pixel before clamping (dark offset). Default 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset: Option<f64>,
    /// `"raw"` (default) or `"radiograph"`.
    #[serde(default)]
    pub polarity: PolarityOption,
    /// For `polarity = "radiograph"`: the attenuation ln(S_open/S) shown as I_max. Default 7.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radiograph_range: Option<f64>,
    /// Detector blur (the scintillator's light spread) as a Gaussian point-spread function,
    /// e.g. `{ sigma_mm = 0.15 }`. Give at most one of `psf` and `mtf`. Default: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub psf: Option<PsfOption>,
    /// Detector blur given by its modulation transfer function (without the pixel aperture,
    /// which `pixel_samples` provides): rows `[cycles_per_mm, value]`, frequencies ascending
    /// from `[0.0, 1.0]`, values in [0, 1]; zero beyond the last row. Default: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mtf: Option<Vec<[f64; 2]>>,
    /// Scattered radiation, approximated as the primary image blurred by a broad Gaussian
    /// times a constant scatter-to-primary ratio: `{ ratio = 0.3, sigma_mm = 40 }`. Default:
    /// none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scatter: Option<ScatterOption>,
    /// Electronic (read-out) noise: the SD of a Gaussian added to every raw value, digital
    /// units. Default 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub electronic_noise_dn: Option<f64>,
    /// Quantum noise: each pixel's count drawn from the Poisson law of its expected count.
    /// `false` writes the expected (noise-free) image instead: every pixel's signal is its mean
    /// (the expected photons counted, or the expected energy absorbed), then scatter, PSF,
    /// electronic noise and digitisation as usual. For checking the physics against a
    /// reference, and for noise-free reference images. Default true.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quantum_noise: Option<bool>,
}

/// A Gaussian point-spread function.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PsfOption {
    /// Its standard deviation on the detector, mm (typ. 0.1–0.2 for a CsI flat panel).
    pub sigma_mm: f64,
}

/// The scatter approximation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ScatterOption {
    /// Scatter-to-primary ratio (≥ 0; typ. 0.1–0.5 for a knee without a grid, less with one).
    pub ratio: f64,
    /// Standard deviation of the scatter kernel on the detector, mm (typ. 20–60).
    pub sigma_mm: f64,
}

impl ResponseOptions {
    /// Whether nothing was set.
    pub fn is_default(&self) -> bool {
        *self == ResponseOptions::default()
    }
}

/// A material of the user's: density and mass fractions of elements.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct UserMaterial {
    /// Density, g/cm³.
    pub density_g_cm3: f64,
    /// Mass fraction per chemical symbol, e.g. `{ Co = 0.635, Cr = 0.285, Mo = 0.06, Ni = 0.02 }`;
    /// the fractions add up to 1.
    pub composition: BTreeMap<String, f64>,
}
