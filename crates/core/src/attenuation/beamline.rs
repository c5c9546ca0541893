//! The beam of an attenuation-mode scenario as numbers a user can check against other tools
//! (`rsasim spectrum`): the spectrum before and after the tube's filtration, its mean energy,
//! first and second half-value layers in aluminium, fluence and air kerma per mAs at 1000 mm,
//! the bins traced for the images (after `max_energy_bins` merges them), the absorption edges of
//! the materials in the beam, and materials' transmissions at stated thicknesses as the detector
//! weighs them, over the traced bins (what the images use) and over every bin of the spectrum.
//!
//! Nothing here forms an image: it reads the same [`Setup`] the images are made from.

use serde::Serialize;

use super::setup::{BeamSpectrum, Setup, resolve};
use crate::material::{self, Material};
use crate::scenario::{LoadedScenario, ResponseKind};
use crate::spectrum::{GY_PER_KERMA_WEIGHT, Spectrum};

/// A material's transmission at one thickness, as the detector weighs it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Transmission {
    /// The material's name.
    pub material: String,
    /// The thickness crossed, mm.
    pub thickness_mm: f64,
    /// Over the bins traced for the images: what a pixel behind this thickness reads, as a
    /// fraction of the open field (before noise, blur and scatter).
    pub traced: f64,
    /// Over every bin of the filtered spectrum, before the bins are merged for tracing.
    pub all_bins: f64,
}

/// An absorption edge of a material in the beam.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EdgeInBeam {
    /// The material.
    pub material: String,
    /// The element's symbol.
    pub element: &'static str,
    /// `K`, `L1` … `M5`.
    pub shell: &'static str,
    /// keV.
    pub energy_kev: f64,
}

/// The beam of a scenario, summed up.
#[derive(Debug, Clone, Serialize)]
pub struct Beamline {
    /// Where the spectrum comes from, in words.
    pub source: String,
    /// Whether photon numbers are absolute (photons per bin per mm² per mAs at 1000 mm, a tube
    /// spectrum) or relative (a monochromatic or user spectrum).
    pub absolute: bool,
    /// The spectrum before the tube's filtration.
    #[serde(skip)]
    pub unfiltered: Spectrum,
    /// After the tube's filtration.
    #[serde(skip)]
    pub filtered: Spectrum,
    /// Photon-weighted mean energy after filtration, keV.
    pub mean_energy_kev: f64,
    /// First half-value layer in aluminium (air kerma), mm.
    pub hvl1_mm_al: f64,
    /// Second half-value layer in aluminium, mm.
    pub hvl2_mm_al: f64,
    /// Photons per mm² per mAs at 1000 mm after filtration (tube spectra only).
    pub fluence_per_mm2_per_mas: Option<f64>,
    /// Air kerma per mAs at 1000 mm after filtration, µGy (tube spectra only).
    pub air_kerma_ugy_per_mas: Option<f64>,
    /// The bins the images are traced with: (energy keV, photons as in `filtered`).
    pub traced_bins: Vec<[f64; 2]>,
    /// The detector's response.
    pub response: ResponseKind,
    /// The scintillator, `(material, thickness mm)`, if any (else an ideal absorber).
    pub scintillator: Option<(String, f64)>,
    /// Absorption edges of the scene's materials and the scintillator between the lowest and the
    /// highest energy where the filtered beam holds at least 10⁻⁶ of its largest bin.
    pub edges: Vec<EdgeInBeam>,
    /// The materials the transmissions were asked for.
    pub transmissions: Vec<Transmission>,
    /// For each bin of `filtered`: the detector's absorption.
    #[serde(skip)]
    efficiency: Vec<f64>,
    /// For each traced bin: the detector's absorption.
    #[serde(skip)]
    traced_efficiency: Vec<f64>,
    /// For each traced bin: the first and last energy it groups.
    #[serde(skip)]
    traced_bounds_kev: Vec<[f64; 2]>,
    /// The materials the images trace, and their attenuation over each traced bin.
    #[serde(skip)]
    scene: Vec<Material>,
    #[serde(skip)]
    scene_mu: Vec<Vec<f64>>,
    /// The relative error the traced bins hold ([`Setup::spectral_tolerance`]).
    pub spectral_tolerance: f64,
}

/// A material by name: the scenario's own (`[materials]`), the library's, or a chemical symbol
/// for the pure element at its density (e.g. `W`, `Pb`).
pub fn material_named(loaded: &LoadedScenario, name: &str) -> Option<Material> {
    resolve(&loaded.scenario, name).or_else(|| pure_element(name))
}

/// The pure element with chemical symbol `symbol` at its density, named by its symbol.
pub fn pure_element(symbol: &str) -> Option<Material> {
    let el = material::element(symbol)?;
    Material::mixture(symbol, el.density_g_cm3, &[(symbol, 1.0)]).ok()
}

impl Beamline {
    /// The beam of `loaded` as `setup` (built from it) traces it.
    pub fn new(loaded: &LoadedScenario, setup: &Setup, spectrum: BeamSpectrum) -> Beamline {
        let im = &loaded.scenario.imaging;
        let source = if let Some(e) = im.energy_kev {
            format!("monochromatic {e} keV")
        } else if let Some(t) = &im.tube {
            let filters: Vec<String> = t
                .filtration
                .iter()
                .map(|f| format!("{} mm {}", f.thickness_mm, f.material))
                .collect();
            format!(
                "tungsten tube {} kVp, anode {}°, filtration {}",
                t.kvp,
                t.anode_angle_deg,
                if filters.is_empty() {
                    "none".to_string()
                } else {
                    filters.join(" + ")
                }
            )
        } else {
            format!(
                "spectrum file {}",
                im.spectrum_file.as_deref().unwrap_or("")
            )
        };
        let scintillator = im.detector.scintillator.as_ref().map(|sc| {
            (
                resolve(&loaded.scenario, &sc.material).expect("validated material"),
                sc.thickness_mm,
            )
        });
        let efficiency_at = |e: f64| {
            super::spectral::detector_absorption(scintillator.as_ref().map(|(m, t)| (m, *t)), e)
        };
        let filtered = spectrum.filtered;
        let efficiency = filtered
            .energies_kev
            .iter()
            .map(|&e| efficiency_at(e))
            .collect();
        let aluminium = material::by_name("aluminium").expect("shipped material");
        let mu_al = |e: f64| aluminium.linear_attenuation_per_mm(e);
        let kerma: f64 = filtered.air_kerma_weights().iter().sum();
        // The energies where the filtered beam has photons (at least 1e-6 of its largest bin).
        let peak = filtered.photons.iter().copied().fold(0.0, f64::max);
        let present: Vec<f64> = filtered
            .energies_kev
            .iter()
            .zip(&filtered.photons)
            .filter(|&(_, &n)| n > 0.0 && n >= 1e-6 * peak)
            .map(|(&e, _)| e)
            .collect();
        let lo = present.first().copied().unwrap_or(0.0);
        let hi = present.last().copied().unwrap_or(0.0);
        let mut edges = Vec::new();
        let mut in_beam: Vec<(String, Material)> = setup
            .names
            .iter()
            .cloned()
            .zip(setup.materials.iter().cloned())
            .collect();
        if let Some((m, _)) = &scintillator {
            in_beam.push((m.name.clone(), m.clone()));
        }
        for (name, m) in &in_beam {
            for edge in m.edges() {
                if edge.energy_kev >= lo && edge.energy_kev <= hi {
                    edges.push(EdgeInBeam {
                        material: name.clone(),
                        element: material::element_by_z(edge.z).map_or("?", |e| e.symbol),
                        shell: edge.shell,
                        energy_kev: edge.energy_kev,
                    });
                }
            }
        }
        Beamline {
            source,
            absolute: filtered.absolute,
            mean_energy_kev: filtered.mean_energy_kev(),
            hvl1_mm_al: filtered.hvl_mm(mu_al),
            hvl2_mm_al: filtered.hvl2_mm(mu_al),
            fluence_per_mm2_per_mas: filtered.absolute.then(|| filtered.total_photons()),
            air_kerma_ugy_per_mas: filtered
                .absolute
                .then_some(kerma * GY_PER_KERMA_WEIGHT * 1e6),
            traced_bins: traced_bins(setup, &filtered),
            response: setup.response,
            scintillator: scintillator.map(|(m, t)| (m.name, t)),
            edges,
            transmissions: Vec::new(),
            unfiltered: spectrum.unfiltered,
            filtered,
            efficiency,
            traced_efficiency: setup.efficiency.clone(),
            traced_bounds_kev: setup.traced_bounds_kev.clone(),
            scene: setup.materials.clone(),
            scene_mu: setup.mu_per_mm.clone(),
            spectral_tolerance: setup.spectral_tolerance,
        }
    }

    /// Adds the transmission of `material` at `thickness_mm`, over the traced bins (with each
    /// bin's attenuation as the images take it: the signal-weighted mean over the bins it
    /// groups) and over every bin.
    pub fn add_transmission(&mut self, material: &Material, thickness_mm: f64) {
        let (energies, photons): (Vec<f64>, Vec<f64>) =
            self.traced_bins.iter().map(|b| (b[0], b[1])).unzip();
        let traced = detected_transmission(
            self.response,
            &energies,
            &photons,
            &self.traced_efficiency,
            &self.traced_mu(material),
            thickness_mm,
        );
        let mu: Vec<f64> = self
            .filtered
            .energies_kev
            .iter()
            .map(|&e| material.linear_attenuation_per_mm(e))
            .collect();
        let all_bins = detected_transmission(
            self.response,
            &self.filtered.energies_kev,
            &self.filtered.photons,
            &self.efficiency,
            &mu,
            thickness_mm,
        );
        self.transmissions.push(Transmission {
            material: material.name.clone(),
            thickness_mm,
            traced,
            all_bins,
        });
    }

    /// The attenuation of `material` over each traced bin: the setup's own for a material the
    /// images trace, else the signal-weighted mean over the spectrum's bins the traced bin groups.
    fn traced_mu(&self, material: &Material) -> Vec<f64> {
        if let Some(m) = self.scene.iter().position(|x| x == material) {
            return self.scene_mu[m].clone();
        }
        self.traced_bounds_kev
            .iter()
            .map(|&[lo, hi]| {
                let (mut w, mut wmu) = (0.0, 0.0);
                let bins = self
                    .filtered
                    .energies_kev
                    .iter()
                    .zip(&self.filtered.photons)
                    .zip(&self.efficiency);
                for ((&e, &n), &eta) in bins {
                    if e >= lo && e <= hi {
                        let x = match self.response {
                            ResponseKind::PhotonCounting => n * eta,
                            ResponseKind::EnergyIntegrating => n * eta * e,
                        };
                        w += x;
                        wmu += x * material.linear_attenuation_per_mm(e);
                    }
                }
                if w > 0.0 { wmu / w } else { 0.0 }
            })
            .collect()
    }

    /// The detector's absorption at each bin of the filtered spectrum.
    pub fn efficiency(&self) -> &[f64] {
        &self.efficiency
    }
}

/// The traced bins in the units of `filtered` (the setup keeps relative spectra normalised).
fn traced_bins(setup: &Setup, filtered: &Spectrum) -> Vec<[f64; 2]> {
    let scale = if setup.per_mas {
        1.0
    } else {
        filtered.total_photons()
    };
    setup
        .energies_kev
        .iter()
        .zip(&setup.spectrum_photons)
        .map(|(&e, &n)| [e, n * scale])
        .collect()
}

/// `Σ w_b·exp(−μ_b·t) / Σ w_b` with the detector's weights `w_b = N_b·η_b` (photon counting)
/// or `N_b·η_b·E_b` (energy integrating), as the images weigh the bins
/// (`crate::response::bins`); 0 for a beam the detector does not see.
pub fn detected_transmission(
    response: ResponseKind,
    energies_kev: &[f64],
    photons: &[f64],
    efficiency: &[f64],
    mu_per_mm: &[f64],
    thickness_mm: f64,
) -> f64 {
    let (mut open, mut behind) = (0.0, 0.0);
    let bins = energies_kev
        .iter()
        .zip(photons)
        .zip(efficiency)
        .zip(mu_per_mm);
    for (((&e, &n), &eta), &mu) in bins {
        let w = match response {
            ResponseKind::PhotonCounting => n * eta,
            ResponseKind::EnergyIntegrating => n * eta * e,
        };
        open += w;
        behind += w * libm::exp(-mu * thickness_mm);
    }
    if open > 0.0 { behind / open } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_energy_is_beer_lambert() {
        // Hand computation: μ = 0.5/mm over 2 mm leaves e^−1 whatever the weights.
        for response in [
            ResponseKind::PhotonCounting,
            ResponseKind::EnergyIntegrating,
        ] {
            let t = detected_transmission(response, &[60.0], &[7.0], &[0.3], &[0.5], 2.0);
            assert!((t - libm::exp(-1.0)).abs() < 1e-15, "{t}");
        }
    }

    #[test]
    fn the_weights_are_photons_or_energy_times_absorption() {
        // Two bins, μ = 1 and 0 per mm over 1 mm: T = w₁e⁻¹ + w₂ over w₁ + w₂.
        let (e, n, eta) = ([20.0, 60.0], [3.0, 1.0], [1.0, 0.5]);
        let mu = [1.0, 0.0];
        let counting = detected_transmission(ResponseKind::PhotonCounting, &e, &n, &eta, &mu, 1.0);
        let want = (3.0 * libm::exp(-1.0) + 0.5) / 3.5;
        assert!((counting - want).abs() < 1e-15, "{counting} {want}");
        let integrating =
            detected_transmission(ResponseKind::EnergyIntegrating, &e, &n, &eta, &mu, 1.0);
        let want = (60.0 * libm::exp(-1.0) + 30.0) / 90.0;
        assert!((integrating - want).abs() < 1e-15, "{integrating} {want}");
        let dark =
            detected_transmission(ResponseKind::PhotonCounting, &e, &[0.0; 2], &eta, &mu, 1.0);
        assert_eq!(dark, 0.0);
    }

    #[test]
    fn pure_elements_by_symbol_at_their_density() {
        let w = pure_element("W").unwrap();
        assert_eq!(w.name, "W");
        assert_eq!(
            w.density_g_cm3,
            material::element("W").unwrap().density_g_cm3
        );
        assert_eq!(w.mass_fractions, vec![(74, 1.0)]);
        assert!(pure_element("w").is_none());
    }
}
