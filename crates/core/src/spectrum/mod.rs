//! X-ray spectra: binned photon spectra of a tungsten tube, a single energy or a user's table,
//! filtered by Beer–Lambert, with the photon-weighted mean energy, air-kerma weights and the first
//! half-value layer.
//!
//! A [`Spectrum`] is a list of energy bins (bin centres in keV, increasing) with a photon number
//! per bin. Tube spectra ([`Spectrum::tube`]) are SpekPy's unfiltered tungsten-anode spectra in
//! absolute units (photons per bin per mm² per mAs at 1000 mm from the focus), shipped as
//! `data/spectra/tungsten.tsv` with the script that made them. Filtration (inherent or added,
//! any material) is applied by [`Spectrum::filtered`] with a caller-supplied linear attenuation
//! coefficient μ(E), so this module needs no material library.
//!
//! Everything here that decides a pixel value uses the `libm` crate, never the platform's maths
//! library, and sums bins in index order, so results are the same bytes on every machine.

mod air;
mod tsv;
mod tube;

pub use tsv::{TSV_MAX_ENERGY_KEV, TSV_MAX_ROWS, TSV_MIN_ENERGY_KEV};
pub use tube::{
    TUBE_ANGLE_MAX_DEG, TUBE_ANGLE_MIN_DEG, TUBE_ANGLE_STEP_DEG, TUBE_BIN_WIDTH_KEV, TUBE_KVP_MAX,
    TUBE_KVP_MIN,
};

#[cfg(test)]
mod spekpy_checks;

/// Air kerma in Gy of one unit of [`Spectrum::air_kerma_weights`] for photons per mm²:
/// 1 keV = 1.602176634e-16 J, 1 mm⁻² = 1e6 m⁻², 1 cm²/g = 0.1 m²/kg.
pub const GY_PER_KERMA_WEIGHT: f64 = 1.602176634e-16 * 1e6 * 0.1;

/// A binned X-ray photon spectrum.
#[derive(Debug, Clone, PartialEq)]
pub struct Spectrum {
    /// Bin centres in keV, strictly increasing.
    pub energies_kev: Vec<f64>,
    /// Photons in each bin (same length as `energies_kev`), finite and ≥ 0.
    pub photons: Vec<f64>,
    /// `true`: photons per bin per mm² per mAs at 1000 mm from the focus (a tube spectrum);
    /// `false`: relative numbers (a monochromatic or user spectrum), to be scaled by the caller.
    pub absolute: bool,
}

impl Spectrum {
    /// The unfiltered spectrum of a tungsten-anode tube at `kvp` (an integer from 40 to 150) and
    /// anode angle `anode_angle_deg` (6° to 22°), in 0.05 keV bins from 1 keV to the kVp, in
    /// photons per bin per mm² per mAs at 1000 mm on the central axis (SpekPy 2.5.4, see
    /// `data/spectra/README.md`): the bremsstrahlung continuum interpolated from its 0.5 keV
    /// table, the characteristic lines in their own bins. Between the tabulated angles (every
    /// 2°) the photon numbers are interpolated linearly. The error names the valid range.
    pub fn tube(kvp: f64, anode_angle_deg: f64) -> Result<Spectrum, String> {
        tube::tungsten(kvp, anode_angle_deg)
    }

    /// The centres (keV) of the bins of [`Spectrum::tube`] spectra that can hold one of the
    /// anode's characteristic lines (whether they do depends on the kVp).
    pub fn tube_line_bins_kev() -> Vec<f64> {
        tube::line_centres_kev()
    }

    /// One bin at `energy_kev` holding 1 photon (relative units).
    pub fn monochromatic(energy_kev: f64) -> Spectrum {
        Spectrum {
            energies_kev: vec![energy_kev],
            photons: vec![1.0],
            absolute: false,
        }
    }

    /// A user spectrum from TSV text: one `energy_kev photons` pair per line (tab or spaces
    /// between), `#` starts a comment, an optional header line first. Energies must increase and
    /// lie within 1–200 keV; photons must be finite and ≥ 0, at least one > 0; at most
    /// [`TSV_MAX_ROWS`] rows. An error gives the 1-based line and what would be valid.
    pub fn from_tsv(text: &str) -> Result<Spectrum, (usize, String)> {
        tsv::parse(text)
    }

    /// This spectrum after `thickness_mm` of a material whose linear attenuation coefficient at
    /// energy E (keV) is `mu_per_mm(E)` (1/mm): each bin's photons times exp(−μ(E)·t)
    /// (Beer–Lambert at the bin centre). Filtering never adds photons: a μ·t that is negative or
    /// not a number counts as 0 (no attenuation), an infinite one removes the bin's photons.
    pub fn filtered(&self, mu_per_mm: impl Fn(f64) -> f64, thickness_mm: f64) -> Spectrum {
        let photons = self
            .energies_kev
            .iter()
            .zip(&self.photons)
            .map(|(&e, &n)| n * transmission(mu_per_mm(e) * thickness_mm))
            .collect();
        Spectrum {
            energies_kev: self.energies_kev.clone(),
            photons,
            absolute: self.absolute,
        }
    }

    /// The sum of the photons of all bins (in index order).
    pub fn total_photons(&self) -> f64 {
        self.photons.iter().sum()
    }

    /// The photon-weighted mean energy in keV, Σ N·E / Σ N; 0 for a spectrum without photons.
    pub fn mean_energy_kev(&self) -> f64 {
        let total = self.total_photons();
        if total > 0.0 {
            self.pairs().map(|(e, n)| n * e).sum::<f64>() / total
        } else {
            0.0
        }
    }

    /// Each bin's contribution to the air kerma, N·E·(μ_en/ρ)_air(E), in keV·cm²/g times the
    /// spectrum's photon unit. For a tube spectrum (photons per mm² per mAs) their sum times
    /// [`GY_PER_KERMA_WEIGHT`] is the air kerma in Gy per mAs at 1000 mm. μ_en/ρ of dry air is
    /// NIST's table (`data/spectra/air_muen.tsv`), interpolated log-log; outside its 1–200 keV
    /// the nearest end value is used.
    pub fn air_kerma_weights(&self) -> Vec<f64> {
        self.pairs()
            .map(|(e, n)| n * e * air::muen_over_rho_cm2_per_g(e))
            .collect()
    }

    /// The first half-value layer in mm of the material with linear attenuation `mu_per_mm(E)`:
    /// the thickness that halves the air kerma of this spectrum (bisection to 1e-12 relative).
    /// `f64::INFINITY` when the material never halves it (μ = 0 wherever there is kerma),
    /// `f64::NAN` when the spectrum has no air kerma at all.
    pub fn hvl_mm(&self, mu_per_mm: impl Fn(f64) -> f64) -> f64 {
        self.kerma_layer_mm(mu_per_mm, 0.5)
    }

    /// The second half-value layer in mm: the thickness that halves the air kerma again after
    /// the first (the quarter-value layer minus the first HVL). `INFINITY` and `NAN` as
    /// [`Spectrum::hvl_mm`].
    pub fn hvl2_mm(&self, mu_per_mm: impl Fn(f64) -> f64) -> f64 {
        let mu = &mu_per_mm;
        self.kerma_layer_mm(mu, 0.25) - self.kerma_layer_mm(mu, 0.5)
    }

    /// The thickness in mm of the material with linear attenuation `mu_per_mm(E)` that leaves
    /// `fraction` (in (0, 1)) of this spectrum's air kerma (bisection to 1e-12 relative).
    fn kerma_layer_mm(&self, mu_per_mm: impl Fn(f64) -> f64, fraction: f64) -> f64 {
        let weights = self.air_kerma_weights();
        let mus: Vec<f64> = self.energies_kev.iter().map(|&e| mu_per_mm(e)).collect();
        let kerma = |t: f64| -> f64 {
            weights
                .iter()
                .zip(&mus)
                .map(|(&w, &mu)| w * transmission(mu * t))
                .sum()
        };
        let target = fraction * kerma(0.0);
        if target.is_nan() || target <= 0.0 {
            return f64::NAN;
        }
        let mut hi = 1.0;
        while kerma(hi) > target {
            hi *= 2.0;
            if hi > 1e12 {
                return f64::INFINITY;
            }
        }
        let mut lo = 0.0;
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if kerma(mid) > target {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi - lo <= 1e-12 * hi {
                break;
            }
        }
        0.5 * (lo + hi)
    }

    /// (energy, photons) of every bin.
    fn pairs(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.energies_kev
            .iter()
            .copied()
            .zip(self.photons.iter().copied())
    }
}

/// exp(−a) for an attenuation exponent a = μ·t; a negative or NaN exponent counts as 0.
fn transmission(a: f64) -> f64 {
    if a > 0.0 { libm::exp(-a) } else { 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn three_bins() -> Spectrum {
        Spectrum {
            energies_kev: vec![20.0, 40.0, 60.0],
            photons: vec![1.0, 2.0, 1.0],
            absolute: false,
        }
    }

    #[test]
    fn monochromatic_is_one_photon_at_its_energy() {
        let s = Spectrum::monochromatic(60.0);
        assert_eq!(s.energies_kev, vec![60.0]);
        assert_eq!(s.total_photons(), 1.0);
        assert_eq!(s.mean_energy_kev(), 60.0);
        assert!(!s.absolute);
    }

    #[test]
    fn filtered_is_beer_lambert_per_bin() {
        let s = three_bins().filtered(|e| 0.01 * e, 2.0);
        for (i, (&e, &n0)) in [20.0, 40.0, 60.0].iter().zip(&[1.0, 2.0, 1.0]).enumerate() {
            let expect = n0 * libm::exp(-0.01 * e * 2.0);
            assert!((s.photons[i] - expect).abs() < 1e-15, "bin {i}");
        }
        assert_eq!(s.energies_kev, three_bins().energies_kev);
    }

    #[test]
    fn filtered_never_adds_photons() {
        let s = three_bins();
        assert_eq!(s.filtered(|_| -1.0, 5.0), s);
        assert_eq!(s.filtered(|_| f64::NAN, 5.0), s);
        assert_eq!(s.filtered(|_| 1.0, -5.0), s);
        assert_eq!(s.filtered(|_| f64::INFINITY, 1.0).total_photons(), 0.0);
    }

    #[test]
    fn mean_energy_is_photon_weighted() {
        assert_eq!(three_bins().mean_energy_kev(), 40.0);
        let empty = three_bins().filtered(|_| f64::INFINITY, 1.0);
        assert_eq!(empty.mean_energy_kev(), 0.0);
    }

    #[test]
    fn hvl_of_a_single_energy_is_ln2_over_mu() {
        let s = Spectrum::monochromatic(60.0);
        let hvl = s.hvl_mm(|_| 0.25);
        assert!(
            (hvl - core::f64::consts::LN_2 / 0.25).abs() < 1e-10,
            "{hvl}"
        );
    }

    #[test]
    fn hvl_halves_the_kerma_of_a_polychromatic_spectrum() {
        let s = three_bins();
        let mu = |e: f64| 5.0 / e;
        let hvl = s.hvl_mm(mu);
        let k0: f64 = s.air_kerma_weights().iter().sum();
        let k1: f64 = s.filtered(mu, hvl).air_kerma_weights().iter().sum();
        assert!((k1 / k0 - 0.5).abs() < 1e-10, "{}", k1 / k0);
    }

    #[test]
    fn hvl2_of_a_single_energy_equals_hvl1() {
        // One energy: every half-value layer is ln 2 / μ.
        let s = Spectrum::monochromatic(60.0);
        let (h1, h2) = (s.hvl_mm(|_| 0.25), s.hvl2_mm(|_| 0.25));
        assert!((h2 - h1).abs() < 1e-9 * h1, "{h1} {h2}");
    }

    #[test]
    fn hvl2_exceeds_hvl1_in_a_hardening_beam() {
        let s = three_bins();
        let mu = |e: f64| 5.0 / e;
        let (h1, h2) = (s.hvl_mm(mu), s.hvl2_mm(mu));
        let k0: f64 = s.air_kerma_weights().iter().sum();
        let k2: f64 = s.filtered(mu, h1 + h2).air_kerma_weights().iter().sum();
        assert!((k2 / k0 - 0.25).abs() < 1e-10, "{}", k2 / k0);
        assert!(h2 > h1, "{h1} {h2}");
    }

    #[test]
    fn hvl_without_attenuation_or_kerma() {
        assert_eq!(three_bins().hvl_mm(|_| 0.0), f64::INFINITY);
        let empty = three_bins().filtered(|_| f64::INFINITY, 1.0);
        assert!(empty.hvl_mm(|_| 1.0).is_nan());
    }

    #[test]
    fn mismatched_fields_do_not_panic() {
        let s = Spectrum {
            energies_kev: vec![10.0, 20.0],
            photons: vec![1.0],
            absolute: false,
        };
        assert_eq!(s.air_kerma_weights().len(), 1);
        let _ = (s.hvl_mm(|_| 1.0), s.filtered(|_| 1.0, 1.0));
        assert_eq!(s.mean_energy_kev(), 10.0);
    }
}
