//! The scenario's `[imaging]` resolved once into plain numbers: the materials in use (indexed),
//! the spectrum after filtration grouped into the bins the images are traced with (at most
//! `max_energy_bins`, see [`spectral`]), the linear attenuation of every material over every
//! traced bin, and the detector's absorption per bin.

use glam::DVec3;

use crate::diagnostic::{Diagnostic, KeyPath};
use crate::geometry::DetectorFrame;
use crate::material::{self, Material};
use crate::phantom::{PhantomModel, confine};
use crate::response::{
    Beam, DetectorModel, Polarity, Psf, PsfShape, Response, Scatter, Unsharpness,
};
use crate::scenario::{LoadedScenario, PolarityOption, ResponseKind, Scenario};
use crate::spectrum::Spectrum;

use super::spectral;

/// Largest spectrum file read, bytes.
const MAX_SPECTRUM_FILE_BYTES: u64 = 4 * 1024 * 1024;

/// Default `radiograph_range`: ln(S_open/S) shown white (about 0.1 % transmission).
pub const DEFAULT_RADIOGRAPH_RANGE: f64 = 7.0;

/// Default `white_level`: the open field reads this fraction of I_max.
pub const DEFAULT_WHITE_LEVEL: f64 = 0.8;

/// The detector's unsharpness and extra noise, as plain numbers from the scenario.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DetectorBlur {
    /// A Gaussian PSF's SD, mm.
    pub psf_sigma_mm: Option<f64>,
    /// An MTF table: rows (cycles per mm, value).
    pub mtf: Option<Vec<[f64; 2]>>,
    /// Scatter: (scatter-to-primary ratio, kernel SD in mm).
    pub scatter: Option<(f64, f64)>,
    /// Electronic noise SD, DN.
    pub electronic_noise_dn: f64,
}

impl DetectorBlur {
    /// The detector's [`Unsharpness`] for pixels of `pitch_mm`; the error names the scenario
    /// key (`psf`, `mtf` or `scatter`) and what is wrong.
    pub fn build(&self, pitch_mm: [f64; 2]) -> Result<Unsharpness, (&'static str, String)> {
        let psf = match (self.psf_sigma_mm, &self.mtf) {
            (Some(sigma_mm), _) => {
                Some(Psf::new(PsfShape::Gaussian { sigma_mm }, pitch_mm).map_err(|e| ("psf", e))?)
            }
            (None, Some(table)) => Some(
                Psf::new(
                    PsfShape::Mtf {
                        table: table.clone(),
                    },
                    pitch_mm,
                )
                .map_err(|e| ("mtf", e))?,
            ),
            (None, None) => None,
        };
        let scatter = match self.scatter {
            Some((ratio, sigma_mm)) => {
                Some(Scatter::new(ratio, sigma_mm, pitch_mm).map_err(|e| ("scatter", e))?)
            }
            None => None,
        };
        Ok(Unsharpness {
            scatter,
            psf,
            electronic_noise_dn: self.electronic_noise_dn,
        })
    }
}

/// Everything attenuation mode needs besides the geometry of a run.
#[derive(Debug, Clone)]
pub struct Setup {
    /// The materials in use, in first-use order (volumes, beads, then plates); indices below.
    pub materials: Vec<Material>,
    /// The traced bins' energies, keV ([`spectral`]).
    pub energies_kev: Vec<f64>,
    /// Photons per bin after filtration: absolute (per mm² per mAs at 1000 mm) for a tube with
    /// `mas`, otherwise normalised to a total of 1.
    pub spectrum_photons: Vec<f64>,
    /// Whether `spectrum_photons` is per mm² per mAs at 1000 mm (exposure given as `mas`).
    pub per_mas: bool,
    /// `photons_per_pixel` or `mas`, before the level's exposure factor.
    pub exposure: f64,
    /// `mu_per_mm[m][b]`: linear attenuation of material m over traced bin b, 1/mm.
    pub mu_per_mm: Vec<Vec<f64>>,
    /// The relative error the traced bins hold (`spectral_tolerance`; larger when
    /// `max_energy_bins` forced it; without `spectral_tolerance`, the smallest that
    /// `max_energy_bins` allows; see [`spectral`]).
    pub spectral_tolerance: f64,
    /// Per traced bin: the centres of the first and last bin of the spectrum it groups, keV.
    pub traced_bounds_kev: Vec<[f64; 2]>,
    /// Detector absorption per bin (1 for an ideal absorber).
    pub efficiency: Vec<f64>,
    /// Energy integrating or photon counting.
    pub response: ResponseKind,
    /// Digital units per keV or per photon; `None` = automatic (white level).
    pub gain: Option<f64>,
    /// Open-field fraction of I_max for the automatic gain.
    pub white_level: f64,
    /// Dark offset, digital units.
    pub offset: f64,
    /// Raw or radiograph, with its range.
    pub polarity: Polarity,
    /// Whether each pixel's count is drawn (Poisson) or is its expected value
    /// (`quantum_noise = false`).
    pub quantum_noise: bool,
    /// Spectrum summary for reports and file headers: mean energy after filtration, keV.
    pub mean_energy_kev: f64,
    /// Material names by index (for messages and EXR layers).
    pub names: Vec<String>,
    /// The detector's blur, scatter and electronic noise as the scenario gives them
    /// (`[imaging.detector]` psf, mtf, scatter, electronic_noise_dn).
    pub blur: DetectorBlur,
    /// Per detector id, the blur, scatter and electronic noise built for its pixel pitch.
    pub unsharp: Vec<(String, Unsharpness)>,
    /// The bytes of `spectrum_file` as read, for the output's `phantoms/` (so the output's own
    /// `scenario.toml` stands alone).
    pub spectrum_file_bytes: Option<Vec<u8>>,
}

impl Setup {
    /// Resolves the imaging of `loaded` (attenuation mode) with its phantoms. Errors name the
    /// scenario key.
    pub fn build(
        loaded: &LoadedScenario,
        models: &[PhantomModel],
    ) -> Result<Setup, Vec<Diagnostic>> {
        let s = &loaded.scenario;
        let im = &s.imaging;
        let key = KeyPath::root().key("imaging");
        let err = |path: KeyPath, message: String, help: &str| {
            vec![loaded.locator.error(path, message).with_help(help)]
        };
        let BeamSpectrum {
            filtered: spectrum,
            file_bytes: spectrum_file_bytes,
            lines_kev,
            ..
        } = beam_spectrum(loaded)?;
        let (names, materials) = materials_in_use(s, models);
        let d = &im.detector;
        let scintillator = d.scintillator.as_ref().map(|sc| {
            (
                resolve(s, &sc.material).expect("validated material"),
                sc.thickness_mm,
            )
        });
        let traced = spectral::traced(&spectral::Request {
            spectrum: &spectrum,
            lines_kev: &lines_kev,
            materials: &materials,
            scintillator: scintillator.as_ref().map(|(m, t)| (m, *t)),
            response: d.response,
            tolerance: im.spectral_tolerance,
            max_bins: im.max_bins(),
        });
        let total = traced.photons.iter().sum::<f64>();
        if !(total > 0.0) {
            return Err(err(
                key.clone(),
                "no photon of the spectrum passes the filtration".into(),
                "reduce the filtration",
            ));
        }
        let per_mas = im.mas.is_some();
        let spectrum_photons: Vec<f64> = if per_mas {
            traced.photons.clone()
        } else {
            traced.photons.iter().map(|n| n / total).collect()
        };
        let blur = DetectorBlur {
            psf_sigma_mm: d.psf.as_ref().map(|p| p.sigma_mm),
            mtf: d.mtf.clone(),
            scatter: d.scatter.as_ref().map(|sc| (sc.ratio, sc.sigma_mm)),
            electronic_noise_dn: d.electronic_noise_dn.unwrap_or(0.0),
        };
        let mut unsharp = Vec::with_capacity(s.detectors.len());
        for det in &s.detectors {
            let built = blur
                .build(det.resolved_pixel_pitch_mm())
                .map_err(|(field, message)| {
                    err(
                        key.key("detector").key(field),
                        format!("detector `{}`: {message}", det.id),
                        "see the manual, docs/src/physics/unsharpness.md, for valid values",
                    )
                })?;
            unsharp.push((det.id.clone(), built));
        }
        Ok(Setup {
            materials,
            mean_energy_kev: spectrum.mean_energy_kev(),
            energies_kev: traced.energies_kev,
            spectrum_photons,
            per_mas,
            exposure: im.photons_per_pixel.or(im.mas).expect("validated exposure"),
            mu_per_mm: traced.mu_per_mm,
            efficiency: traced.efficiency,
            spectral_tolerance: traced.tolerance,
            traced_bounds_kev: traced.bounds_kev,
            response: d.response,
            gain: d.gain,
            white_level: d.white_level.unwrap_or(DEFAULT_WHITE_LEVEL),
            offset: d.offset.unwrap_or(0.0),
            polarity: match d.polarity {
                PolarityOption::Raw => Polarity::Raw,
                PolarityOption::Radiograph => Polarity::Radiograph {
                    range: d.radiograph_range.unwrap_or(DEFAULT_RADIOGRAPH_RANGE),
                },
            },
            quantum_noise: d.quantum_noise.unwrap_or(true),
            names,
            blur,
            unsharp,
            spectrum_file_bytes,
        })
    }

    /// What the detector of id `detector` adds beyond quantum noise (its kernels built for its
    /// pitch when the setup was built); nothing for an unknown id.
    pub fn unsharpness(&self, detector: &str) -> Unsharpness {
        self.unsharp
            .iter()
            .find(|(id, _)| id == detector)
            .map(|(_, u)| u.clone())
            .unwrap_or_default()
    }

    /// Index of a material in use.
    pub fn index(&self, name: &str) -> usize {
        self.names
            .iter()
            .position(|n| n == name)
            .expect("every material in use was collected")
    }

    /// The beam reaching one pixel at the detector point nearest the source (no object), at
    /// exposure factor `factor`: photons per bin.
    pub fn beam(&self, frame: &DetectorFrame, source_mm: DVec3, factor: f64) -> Beam {
        let scale = if self.per_mas {
            // Fluence per mm² per mAs at 1000 mm → at the detector plane (distance D), per pixel.
            let d_mm = frame.pose.to_local(source_mm).z.abs();
            let [px, py] = frame.pixel_pitch_mm;
            self.exposure * factor * (1000.0 / d_mm) * (1000.0 / d_mm) * px * py
        } else {
            self.exposure * factor
        };
        Beam {
            energies_kev: self.energies_kev.clone(),
            photons_per_pixel: self.spectrum_photons.iter().map(|n| n * scale).collect(),
        }
    }

    /// The detector model for an image of `i_max`; the automatic gain is set on `nominal`, the
    /// beam at exposure factor 1 (so a lower exposure level reads darker, a higher one may
    /// saturate, as on a real detector of fixed gain).
    pub fn detector(&self, nominal: &Beam, i_max: u16) -> DetectorModel {
        let response = match self.response {
            ResponseKind::EnergyIntegrating => Response::EnergyIntegrating,
            ResponseKind::PhotonCounting => Response::PhotonCounting,
        };
        let gain = self.gain.unwrap_or_else(|| {
            DetectorModel::auto_gain(
                &response,
                nominal,
                &self.efficiency,
                self.offset,
                self.white_level,
                i_max,
            )
        });
        DetectorModel {
            response,
            efficiency: self.efficiency.clone(),
            gain,
            offset: self.offset,
            i_max,
            polarity: self.polarity.clone(),
            quantum_noise: self.quantum_noise,
        }
    }

    /// Whether a material counts as metal for bead visibility: density at least 4 g/cm³.
    pub fn is_metal(&self, m: usize) -> bool {
        self.materials[m].density_g_cm3 >= METAL_DENSITY_G_CM3
    }
}

pub use crate::material::METAL_DENSITY_G_CM3;

/// The spectrum of an attenuation-mode scenario's `[imaging]`, before the bins are merged for
/// tracing (`max_energy_bins`).
#[derive(Debug, Clone)]
pub struct BeamSpectrum {
    /// The tube's spectrum before its filtration (a monochromatic or user spectrum as given).
    pub unfiltered: Spectrum,
    /// After the tube's filtration: what reaches the patient.
    pub filtered: Spectrum,
    /// The bytes of `spectrum_file` as read.
    pub file_bytes: Option<Vec<u8>>,
    /// The energies of the bins that hold the tube's characteristic lines (none for a
    /// monochromatic or user spectrum).
    pub lines_kev: Vec<f64>,
}

/// The spectrum `[imaging]` gives (`energy_kev`, `tube` with its filtration, or
/// `spectrum_file`); errors name the key.
pub fn beam_spectrum(loaded: &LoadedScenario) -> Result<BeamSpectrum, Vec<Diagnostic>> {
    let s = &loaded.scenario;
    let im = &s.imaging;
    let key = KeyPath::root().key("imaging");
    let err = |path: KeyPath, message: String, help: &str| {
        vec![loaded.locator.error(path, message).with_help(help)]
    };
    if let Some(e) = im.energy_kev {
        let sp = Spectrum::monochromatic(e);
        return Ok(BeamSpectrum {
            unfiltered: sp.clone(),
            filtered: sp,
            file_bytes: None,
            lines_kev: Vec::new(),
        });
    }
    if let Some(t) = &im.tube {
        let unfiltered = Spectrum::tube(t.kvp, t.anode_angle_deg).map_err(|e| {
            err(
                key.key("tube"),
                e,
                "kVp 40–150 (whole numbers), anode angles 6–22° (docs/src/physics/attenuation.md)",
            )
        })?;
        let mut filtered = unfiltered.clone();
        for f in &t.filtration {
            let m = resolve(s, &f.material).expect("validated material");
            filtered = filtered.filtered(|e| m.linear_attenuation_per_mm(e), f.thickness_mm);
        }
        return Ok(BeamSpectrum {
            unfiltered,
            filtered,
            file_bytes: None,
            lines_kev: Spectrum::tube_line_bins_kev(),
        });
    }
    let Some(file) = &im.spectrum_file else {
        unreachable!("validated: one spectrum source");
    };
    let (sp, bytes) = read_spectrum(loaded, file)
        .map_err(|(m, h): (String, String)| err(key.key("spectrum_file"), m, &h))?;
    Ok(BeamSpectrum {
        unfiltered: sp.clone(),
        filtered: sp,
        file_bytes: Some(bytes),
        lines_kev: Vec::new(),
    })
}

/// A library or user material by name.
pub fn resolve(s: &Scenario, name: &str) -> Option<Material> {
    if let Some(u) = s.materials.get(name) {
        let fractions: Vec<(&str, f64)> = u
            .composition
            .iter()
            .map(|(k, v)| (k.as_str(), *v))
            .collect();
        return Material::mixture(name, u.density_g_cm3, &fractions).ok();
    }
    material::by_name(name).cloned()
}

/// The materials the phantoms use, in first-use order.
fn materials_in_use(s: &Scenario, models: &[PhantomModel]) -> (Vec<String>, Vec<Material>) {
    let mut names: Vec<String> = Vec::new();
    let mut add = |n: &str| {
        if !names.iter().any(|x| x == n) {
            names.push(n.to_string());
        }
    };
    for m in models {
        for v in &m.volumes {
            if let Some(mat) = &v.material {
                add(mat);
            }
        }
        if !m.markers.is_empty() {
            add(&m.bead_material);
        }
    }
    let materials = names
        .iter()
        .map(|n| resolve(s, n).expect("validated material"))
        .collect();
    (names, materials)
}

/// Reads a user spectrum under the confinement rule.
fn read_spectrum(
    loaded: &LoadedScenario,
    file: &str,
) -> Result<(Spectrum, Vec<u8>), (String, String)> {
    let path = loaded.base_dir.join(file);
    let c = confine::Confinement::new(&loaded.base_dir, &loaded.allowed_dirs)
        .map_err(|e| (e, "--allow-dir takes an existing folder".to_string()))?;
    let bytes = c.read(&path, MAX_SPECTRUM_FILE_BYTES).map_err(|e| {
        (
            format!("cannot read the spectrum: {e}"),
            "the spectrum file lies in the scenario's folder (or one allowed with --allow-dir)"
                .to_string(),
        )
    })?;
    let shown = confine::shown_path(&path);
    let text = String::from_utf8(bytes.clone()).map_err(|_| {
        (
            format!("spectrum {shown} is not UTF-8 text"),
            "write one `energy_kev photons` pair per line".to_string(),
        )
    })?;
    let spectrum = Spectrum::from_tsv(&text).map_err(|(line, why)| {
        (
            format!("spectrum {shown}, line {line}: {why}"),
            "write one `energy_kev photons` pair per line (keV 1–200, increasing; photons ≥ 0)"
                .to_string(),
        )
    })?;
    Ok((spectrum, bytes))
}
