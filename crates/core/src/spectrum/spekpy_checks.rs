//! The shipped tube spectra and this module's arithmetic against SpekPy itself
//! (`data/spectra/checks.tsv`, written by `data/spectra/regen.py`): mean energy, first HVL and
//! photon fluence of filtered clinical settings, and spectra between the tabulated anode angles.
//!
//! The Al and Cu attenuation here is SpekPy's own (a test-only table); the simulator takes its
//! attenuation from the material library.

use super::Spectrum;

const CHECKS: &str = include_str!("../../../../data/spectra/checks.tsv");

/// Worst per-bin relative error of linear interpolation between tabulated angles, for bins holding
/// at least [`BIN_FLOOR`] of the peak bin, as measured by `regen.py` (README: 0.66 %).
const INTERPOLATION_MAX_BIN_ERROR: f64 = 0.007;
/// Worst relative error of the photon total between tabulated angles (README: 0.50 %).
const INTERPOLATION_MAX_TOTAL_ERROR: f64 = 0.0051;
/// Bins below this fraction of the peak are left out of the per-bin interpolation error.
const BIN_FLOOR: f64 = 1e-3;

/// One filtered setting SpekPy evaluated.
struct Setting {
    kvp: f64,
    angle_deg: f64,
    al_mm: f64,
    cu_mm: f64,
    mean_energy_kev: f64,
    hvl1_mm_al: f64,
    fluence: f64,
    fluence_unfiltered: f64,
}

/// The parsed checks file.
struct Checks {
    settings: Vec<Setting>,
    /// (energy keV, Al μ per mm, Cu μ per mm) at the bin centres 1.5, 2.5, … keV.
    mu: Vec<(f64, f64, f64)>,
    /// (kVp, angle, photons per bin) computed by SpekPy between the tabulated angles.
    spectra: Vec<(f64, f64, Vec<f64>)>,
}

fn checks() -> Checks {
    let mut settings = Vec::new();
    let mut mu_over_rho = Vec::new();
    let (mut rho_al, mut rho_cu) = (0.0, 0.0);
    let mut spectra = Vec::new();
    for line in CHECKS.lines().filter(|l| !l.starts_with('#')) {
        let fields: Vec<&str> = line.split('\t').collect();
        let num = |i: usize| fields[i].parse::<f64>().unwrap();
        match fields[0] {
            "setting" => settings.push(Setting {
                kvp: num(1),
                angle_deg: num(2),
                al_mm: num(3),
                cu_mm: num(4),
                mean_energy_kev: num(5),
                hvl1_mm_al: num(6),
                fluence: num(7),
                fluence_unfiltered: num(8),
            }),
            "density" if fields[1] == "Al" => rho_al = num(2),
            "density" if fields[1] == "Cu" => rho_cu = num(2),
            "mu" => mu_over_rho.push((num(1), num(2), num(3))),
            "spectrum" => spectra.push((num(1), num(2), (3..fields.len()).map(num).collect())),
            other => panic!("unknown row kind {other}"),
        }
    }
    // μ/ρ in cm²/g times ρ in g/cm³ is μ per cm; per mm is a tenth of that.
    let mu = mu_over_rho
        .into_iter()
        .map(|(e, al, cu)| (e, al * rho_al / 10.0, cu * rho_cu / 10.0))
        .collect();
    Checks {
        settings,
        mu,
        spectra,
    }
}

/// SpekPy's μ per mm at a bin centre (column 1 Al, 2 Cu).
fn mu_at(mu: &[(f64, f64, f64)], e: f64, cu: bool) -> f64 {
    let row = mu[(e - 1.5) as usize];
    assert_eq!(row.0, e, "no attenuation row for {e} keV");
    if cu { row.2 } else { row.1 }
}

#[test]
fn filtered_settings_match_spekpy() {
    let c = checks();
    assert!(c.settings.len() >= 6);
    for s in &c.settings {
        let what = format!(
            "{} kVp {}° {} mm Al {} mm Cu",
            s.kvp, s.angle_deg, s.al_mm, s.cu_mm
        );
        let raw = Spectrum::tube(s.kvp, s.angle_deg).unwrap();
        let rel = raw.total_photons() / s.fluence_unfiltered - 1.0;
        assert!(
            rel.abs() < 0.01,
            "{what}: unfiltered photons off by {rel:e}"
        );
        let beam = raw
            .filtered(|e| mu_at(&c.mu, e, false), s.al_mm)
            .filtered(|e| mu_at(&c.mu, e, true), s.cu_mm);
        let rel = beam.total_photons() / s.fluence - 1.0;
        assert!(rel.abs() < 0.01, "{what}: filtered photons off by {rel:e}");
        let de = beam.mean_energy_kev() - s.mean_energy_kev;
        assert!(de.abs() < 0.2, "{what}: mean energy off by {de} keV");
        let hvl = beam.hvl_mm(|e| mu_at(&c.mu, e, false));
        let rel = hvl / s.hvl1_mm_al - 1.0;
        assert!(
            rel.abs() < 0.01,
            "{what}: HVL {hvl} mm Al vs {}",
            s.hvl1_mm_al
        );
    }
}

/// What a scenario runs: the filtration and the HVL with the shipped material library's
/// aluminium and copper (`crate::material`, xraylib/NIST), not SpekPy's own attenuation table.
#[test]
fn filtered_settings_match_spekpy_with_the_material_library() {
    let al = crate::material::by_name("aluminium").unwrap();
    let cu = crate::material::by_name("copper").unwrap();
    for s in &checks().settings {
        let what = format!(
            "{} kVp {}° {} mm Al {} mm Cu",
            s.kvp, s.angle_deg, s.al_mm, s.cu_mm
        );
        let beam = Spectrum::tube(s.kvp, s.angle_deg)
            .unwrap()
            .filtered(|e| al.linear_attenuation_per_mm(e), s.al_mm)
            .filtered(|e| cu.linear_attenuation_per_mm(e), s.cu_mm);
        let rel = beam.total_photons() / s.fluence - 1.0;
        assert!(rel.abs() < 0.01, "{what}: filtered photons off by {rel:e}");
        let de = beam.mean_energy_kev() - s.mean_energy_kev;
        assert!(de.abs() < 0.2, "{what}: mean energy off by {de} keV");
        if s.al_mm + s.cu_mm == 0.0 {
            // An unfiltered beam's HVL (0.02 mm Al) is set by 1–5 keV photons, where the two
            // attenuation tables differ by a few per cent around the Al K edge; no clinical beam.
            continue;
        }
        let hvl = beam.hvl_mm(|e| al.linear_attenuation_per_mm(e));
        let rel = hvl / s.hvl1_mm_al - 1.0;
        assert!(
            rel.abs() < 0.015,
            "{what}: HVL {hvl} mm Al vs {}",
            s.hvl1_mm_al
        );
    }
}

#[test]
fn interpolation_between_angles_stays_within_the_documented_error() {
    let c = checks();
    assert!(!c.spectra.is_empty());
    for (kvp, angle, exact) in &c.spectra {
        assert!(angle % 2.0 == 1.0, "{angle}° is a tabulated angle");
        let ours = Spectrum::tube(*kvp, *angle).unwrap();
        assert_eq!(ours.photons.len(), exact.len());
        let peak = exact.iter().cloned().fold(0.0, f64::max);
        for (i, (&n, &x)) in ours.photons.iter().zip(exact).enumerate() {
            if x >= BIN_FLOOR * peak {
                let rel = n / x - 1.0;
                assert!(
                    rel.abs() <= INTERPOLATION_MAX_BIN_ERROR,
                    "{kvp} kVp {angle}°: bin {i} off by {rel:e}"
                );
            }
        }
        let rel = ours.total_photons() / exact.iter().sum::<f64>() - 1.0;
        assert!(
            rel.abs() <= INTERPOLATION_MAX_TOTAL_ERROR,
            "{kvp} kVp {angle}°: total {rel:e}"
        );
    }
}
