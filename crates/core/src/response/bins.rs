//! The beam's energy bins as a detector sees them: per bin the expected detected photons and
//! energy of an open-field pixel, and their sums. What the per-pixel sums ([`super::expected`])
//! and the transmission tables ([`super::transmission`]) weigh each bin by.

use super::Beam;

/// The per-bin weights of a beam on a detector, and their open-field sums.
#[derive(Debug, Clone)]
pub(crate) struct Bins {
    /// `w_b = N_b · η_b`: expected detected photons per pixel in bin b, open field, `f = 1`.
    pub quanta: Vec<f64>,
    /// `w_b · e_b`: expected detected energy (keV) per pixel in bin b, open field, `f = 1`.
    pub energy_kev: Vec<f64>,
    /// `Σ_b w_b` (bins ascending, from 0).
    pub open_quanta: f64,
    /// `Σ_b w_b · e_b` (bins ascending, from 0).
    pub open_energy_kev: f64,
}

impl Bins {
    /// The weights of `beam` on a detector of absorption efficiency `efficiency` (per bin).
    ///
    /// # Panics
    /// When `beam.energies_kev`, `beam.photons_per_pixel` and `efficiency` differ in length.
    pub fn new(beam: &Beam, efficiency: &[f64]) -> Bins {
        let n = beam.energies_kev.len();
        assert!(
            beam.photons_per_pixel.len() == n && efficiency.len() == n,
            "beam and efficiency differ in bin count: {} energies, {} photon counts, {} efficiencies",
            n,
            beam.photons_per_pixel.len(),
            efficiency.len()
        );
        let quanta: Vec<f64> = beam
            .photons_per_pixel
            .iter()
            .zip(efficiency)
            .map(|(&n, &eta)| n * eta)
            .collect();
        let energy_kev: Vec<f64> = quanta
            .iter()
            .zip(&beam.energies_kev)
            .map(|(&w, &e)| w * e)
            .collect();
        Bins {
            open_quanta: quanta.iter().fold(0.0, |s, &w| s + w),
            open_energy_kev: energy_kev.iter().fold(0.0, |s, &w| s + w),
            quanta,
            energy_kev,
        }
    }
}
