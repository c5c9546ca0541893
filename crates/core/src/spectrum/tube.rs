//! Unfiltered tungsten-anode tube spectra from the shipped SpekPy table
//! (`data/spectra/tungsten.tsv`, made by `data/spectra/regen.py`).

use super::Spectrum;

/// The shipped table: `anode_angle_deg kvp photons…` per line (tab-separated), `#` comments;
/// photons per mm² per mAs at 1000 mm in the 1 keV bins [1, 2), …, [kvp − 1, kvp) keV.
const TABLE: &str = include_str!("../../../../data/spectra/tungsten.tsv");

/// The lowest tabulated tube voltage, kV.
pub const TUBE_KVP_MIN: u32 = 40;
/// The highest tabulated tube voltage, kV.
pub const TUBE_KVP_MAX: u32 = 150;
/// The smallest tabulated anode angle, degrees.
pub const TUBE_ANGLE_MIN_DEG: u32 = 6;
/// The largest tabulated anode angle, degrees.
pub const TUBE_ANGLE_MAX_DEG: u32 = 22;
/// The step between tabulated anode angles, degrees.
pub const TUBE_ANGLE_STEP_DEG: u32 = 2;
/// Width of a tube spectrum's bins, keV.
pub const TUBE_BIN_WIDTH_KEV: f64 = 1.0;

/// The unfiltered tungsten spectrum at `kvp` and `anode_angle_deg`, linear in the angle between
/// the two tabulated angles around it (see [`Spectrum::tube`]).
pub(super) fn tungsten(kvp: f64, anode_angle_deg: f64) -> Result<Spectrum, String> {
    if !(kvp >= f64::from(TUBE_KVP_MIN) && kvp <= f64::from(TUBE_KVP_MAX) && kvp.fract() == 0.0) {
        return Err(format!(
            "tube voltage {kvp} kVp is not available: the tungsten tube spectra cover whole kVp \
             from {TUBE_KVP_MIN} to {TUBE_KVP_MAX}"
        ));
    }
    let (lo, hi) = (f64::from(TUBE_ANGLE_MIN_DEG), f64::from(TUBE_ANGLE_MAX_DEG));
    if !(anode_angle_deg >= lo && anode_angle_deg <= hi) {
        return Err(format!(
            "anode angle {anode_angle_deg}° is not available: the tungsten tube spectra cover \
             {TUBE_ANGLE_MIN_DEG}° to {TUBE_ANGLE_MAX_DEG}°"
        ));
    }
    let kvp = kvp as u32;
    let step = f64::from(TUBE_ANGLE_STEP_DEG);
    // The tabulated angle at or below, and the fraction of the way to the next one.
    let cell = libm::floor((anode_angle_deg - lo) / step).min((hi - lo) / step - 1.0);
    let below = lo + cell * step;
    let t = (anode_angle_deg - below) / step;
    let below = below as u32;
    let photons = if t == 0.0 {
        row(below, kvp)?
    } else if t == 1.0 {
        row(below + TUBE_ANGLE_STEP_DEG, kvp)?
    } else {
        let high_row = row(below + TUBE_ANGLE_STEP_DEG, kvp)?;
        row(below, kvp)?
            .iter()
            .zip(&high_row)
            .map(|(&a, &b)| a + t * (b - a))
            .collect()
    };
    let energies_kev = (0..photons.len())
        .map(|i| 1.0 + (i as f64 + 0.5) * TUBE_BIN_WIDTH_KEV)
        .collect();
    Ok(Spectrum {
        energies_kev,
        photons,
        absolute: true,
    })
}

/// The photons of the tabulated row for `angle_deg` and `kvp`.
fn row(angle_deg: u32, kvp: u32) -> Result<Vec<f64>, String> {
    let damaged = |why: &str| {
        format!(
            "the shipped tube spectrum table is damaged ({why} for {angle_deg}° and {kvp} kVp); \
             regenerate it with data/spectra/regen.py"
        )
    };
    let key = format!("{angle_deg}\t{kvp}\t");
    let line = TABLE
        .lines()
        .find(|l| l.starts_with(&key))
        .ok_or_else(|| damaged("no row"))?;
    let photons = line[key.len()..]
        .split('\t')
        .map(|f| f.parse::<f64>().ok().filter(|v| v.is_finite() && *v >= 0.0))
        .collect::<Option<Vec<f64>>>()
        .ok_or_else(|| damaged("a value is not a finite number ≥ 0"))?;
    if photons.len() != (kvp - 1) as usize {
        return Err(damaged("wrong number of bins"));
    }
    Ok(photons)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_tabulated_row_is_present_and_whole() {
        let mut rows = 0;
        for angle in (TUBE_ANGLE_MIN_DEG..=TUBE_ANGLE_MAX_DEG).step_by(TUBE_ANGLE_STEP_DEG as usize)
        {
            for kvp in TUBE_KVP_MIN..=TUBE_KVP_MAX {
                let r = row(angle, kvp).unwrap();
                assert!(r.iter().any(|&n| n > 0.0), "{angle}° {kvp} kVp");
                rows += 1;
            }
        }
        let data_lines = TABLE.lines().filter(|l| !l.starts_with('#')).count();
        assert_eq!(rows, data_lines);
    }

    #[test]
    fn bins_are_1_kev_wide_from_1_kev_to_the_kvp() {
        let s = tungsten(80.0, 12.0).unwrap();
        assert_eq!(s.energies_kev.len(), 79);
        assert_eq!(s.energies_kev[0], 1.5);
        assert_eq!(*s.energies_kev.last().unwrap(), 79.5);
        assert!(s.absolute);
    }

    #[test]
    fn grid_angles_are_the_table_and_between_is_linear() {
        let a = tungsten(90.0, 10.0).unwrap();
        let b = tungsten(90.0, 12.0).unwrap();
        assert_eq!(a.photons, row(10, 90).unwrap());
        let m = tungsten(90.0, 10.5).unwrap();
        for i in 0..a.photons.len() {
            let expect = 0.75 * a.photons[i] + 0.25 * b.photons[i];
            assert!((m.photons[i] - expect).abs() <= 1e-12 * expect, "bin {i}");
        }
        assert_eq!(tungsten(90.0, 22.0).unwrap().photons, row(22, 90).unwrap());
    }

    #[test]
    fn out_of_range_settings_name_the_valid_range() {
        for kvp in [39.0, 151.0, 80.5, f64::NAN, f64::INFINITY, -80.0] {
            let e = tungsten(kvp, 12.0).unwrap_err();
            assert!(e.contains("40 to 150"), "{e}");
        }
        for angle in [5.9, 22.1, f64::NAN, f64::NEG_INFINITY] {
            let e = tungsten(80.0, angle).unwrap_err();
            assert!(e.contains("6° to 22°"), "{e}");
        }
    }

    #[test]
    fn kramers_like_shape() {
        for kvp in [40.0, 70.0, 100.0, 150.0] {
            let s = tungsten(kvp, 12.0).unwrap();
            // No photon at or above the kVp: the last bin ends at the kVp.
            assert!(*s.energies_kev.last().unwrap() < kvp);
            // Above the low-energy self-absorption, the continuum falls towards the kVp.
            let n = |e: f64| s.photons[(e - 1.5) as usize];
            assert!(n(kvp - 0.5) < n(kvp * 0.5 - 0.5), "{kvp}");
            assert!(s.photons.iter().all(|&p| p >= 0.0));
        }
    }

    #[test]
    fn tungsten_k_lines_above_70_kvp() {
        // W K edge 69.5 keV; Kα2 57.98 keV in bin [57, 58), Kα1 59.32 in [59, 60), Kβ1 67.24 in
        // [67, 68); bins [58, 59) and [65, 66) hold no line (the continuum beside them).
        for angle in [6.0, 12.0, 22.0] {
            for kvp in 60..=150 {
                let s = tungsten(f64::from(kvp), angle).unwrap();
                let n = |bin_start: usize| s.photons[bin_start - 1];
                let alpha = n(59) / n(58);
                let what = format!("{kvp} kVp {angle}°: Kα1 bin / neighbour {alpha}");
                if kvp < 70 {
                    assert!(alpha < 0.95, "{what}: a line below the K edge");
                } else if kvp >= 75 {
                    assert!(alpha > 1.1 && n(57) / n(58) > 1.15, "{what}");
                }
                if kvp >= 80 {
                    assert!(alpha > 1.4, "{what}");
                    assert!(n(67) > n(65), "{kvp} kVp {angle}°: no Kβ line");
                }
            }
        }
    }
}
