//! Unfiltered tungsten-anode tube spectra from the shipped SpekPy tables
//! (`data/spectra/tungsten.tsv` for the bremsstrahlung continuum, `tungsten_lines.tsv` for the
//! characteristic lines, both made by `data/spectra/regen.py`), on a grid of 0.05 keV bins.
//!
//! The continuum is tabulated every 0.5 keV (SpekPy's density at each bin centre); a 0.05 keV
//! bin takes the density interpolated linearly between those centres (falling linearly to zero
//! at the kVp) times its width. The lines are tabulated in SpekPy's own 0.05 keV bins and added
//! to the same bins, so a line stays at its energy: tungsten's Kβ1 line at 67.24 keV lies below
//! tantalum's K edge at 67.42 keV, as it does in SpekPy.

use super::Spectrum;

/// The continuum: `anode_angle_deg kvp photons…` per line (tab-separated), `#` comments;
/// photons per mm² per mAs at 1000 mm in the 0.5 keV bins [1, 1.5), …, [kvp − 0.5, kvp) keV.
const CONTINUUM: &str = include_str!("../../../../data/spectra/tungsten.tsv");
/// The lines: a row `energy_kev - E…` naming the 0.05 keV bins (by centre) that hold a line,
/// then `anode_angle_deg kvp photons…` per line, photons per mm² per mAs at 1000 mm per bin.
const LINES: &str = include_str!("../../../../data/spectra/tungsten_lines.tsv");

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
pub const TUBE_BIN_WIDTH_KEV: f64 = 0.05;
/// Bins of [`TUBE_BIN_WIDTH_KEV`] per keV.
const BINS_PER_KEV: u32 = 20;
/// Width of the continuum table's bins, keV.
const CONTINUUM_WIDTH_KEV: f64 = 0.5;
/// Fine bins per continuum bin.
const FINE_PER_CONTINUUM: u32 = 10;

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
    let at_angle = |table: &str, count: usize| -> Result<Vec<f64>, String> {
        if t == 0.0 {
            return row(table, below, kvp, count);
        }
        let high = row(table, below + TUBE_ANGLE_STEP_DEG, kvp, count)?;
        if t == 1.0 {
            return Ok(high);
        }
        Ok(row(table, below, kvp, count)?
            .iter()
            .zip(&high)
            .map(|(&a, &b)| a + t * (b - a))
            .collect())
    };
    let continuum = at_angle(CONTINUUM, (2 * (kvp - 1)) as usize)?;
    let line_bins = line_bins()?;
    let lines = at_angle(LINES, line_bins.len())?;
    let bins = (BINS_PER_KEV * (kvp - 1)) as usize;
    let mut photons: Vec<f64> = (0..bins)
        .map(|j| continuum_density(&continuum, j) * TUBE_BIN_WIDTH_KEV)
        .collect();
    for (&j, &n) in line_bins.iter().zip(&lines) {
        match photons.get_mut(j) {
            Some(p) => *p += n,
            None if n == 0.0 => {}
            None => return Err(damaged("a line above the kVp", 0, kvp)),
        }
    }
    let energies_kev = (0..bins).map(bin_centre_kev).collect();
    Ok(Spectrum {
        energies_kev,
        photons,
        absolute: true,
    })
}

/// The centres (keV) of the bins of a tube spectrum that can hold a characteristic line.
pub(super) fn line_centres_kev() -> Vec<f64> {
    line_bins()
        .map(|bins| bins.into_iter().map(bin_centre_kev).collect())
        .unwrap_or_default()
}

/// The centre of fine bin `j`, keV: 1.025, 1.075, …
fn bin_centre_kev(j: usize) -> f64 {
    1.0 + (j as f64 + 0.5) * TUBE_BIN_WIDTH_KEV
}

/// The continuum's photons per keV at the centre of fine bin `j`: linear between the centres of
/// the continuum's bins (1.25, 1.75, … keV, the density there being the bin's photons over its
/// width), constant below the first centre, falling linearly to zero at the kVp above the last.
fn continuum_density(continuum: &[f64], j: usize) -> f64 {
    let density = |i: usize| continuum.get(i).map_or(0.0, |n| n / CONTINUUM_WIDTH_KEV);
    // Fine centre j sits at (j + 0.5)/10 continuum bins from 1 keV; centre i of the continuum
    // at i + 0.5: the position in continuum centres is (j − 4.5)/10.
    let half = f64::from(FINE_PER_CONTINUUM / 2) - 0.5;
    let x = (j as f64 - half) / f64::from(FINE_PER_CONTINUUM);
    if x <= 0.0 {
        return density(0);
    }
    let i = libm::floor(x) as usize;
    let f = x - i as f64;
    if i + 1 >= continuum.len() {
        // Past the last centre (a quarter keV below the kVp): down to zero at the kVp, half a
        // continuum centre spacing further.
        return density(i) * (1.0 - 2.0 * f).max(0.0);
    }
    density(i) + f * (density(i + 1) - density(i))
}

/// The fine bins (indices) of the line table's columns, from its `energy_kev` row.
fn line_bins() -> Result<Vec<usize>, String> {
    let header = LINES
        .lines()
        .find(|l| l.starts_with("energy_kev\t"))
        .ok_or_else(|| damaged("no energy_kev row", 0, 0))?;
    header
        .split('\t')
        .skip(2)
        .map(|e| {
            e.parse::<f64>()
                .ok()
                .filter(|e| (1.0..=f64::from(TUBE_KVP_MAX)).contains(e))
                .map(|e| libm::floor((e - 1.0) * f64::from(BINS_PER_KEV)) as usize)
                .ok_or_else(|| damaged("a line energy is not a number in range", 0, 0))
        })
        .collect()
}

/// The message for a damaged shipped table (a build defect, reported rather than panicking).
fn damaged(why: &str, angle_deg: u32, kvp: u32) -> String {
    format!(
        "the shipped tube spectrum tables are damaged ({why} for {angle_deg}° and {kvp} kVp); \
         regenerate them with data/spectra/regen.py"
    )
}

/// The values of the row for `angle_deg` and `kvp` of `table`, which must hold `count` of them.
fn row(table: &str, angle_deg: u32, kvp: u32, count: usize) -> Result<Vec<f64>, String> {
    let key = format!("{angle_deg}\t{kvp}\t");
    let line = table
        .lines()
        .find(|l| l.starts_with(&key))
        .ok_or_else(|| damaged("no row", angle_deg, kvp))?;
    let values = line[key.len()..]
        .split('\t')
        .map(|f| f.parse::<f64>().ok().filter(|v| v.is_finite() && *v >= 0.0))
        .collect::<Option<Vec<f64>>>()
        .ok_or_else(|| damaged("a value is not a finite number ≥ 0", angle_deg, kvp))?;
    if values.len() != count {
        return Err(damaged("wrong number of values", angle_deg, kvp));
    }
    Ok(values)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_tabulated_row_is_present_and_whole() {
        let lines = line_bins().unwrap();
        let mut rows = 0;
        for angle in (TUBE_ANGLE_MIN_DEG..=TUBE_ANGLE_MAX_DEG).step_by(TUBE_ANGLE_STEP_DEG as usize)
        {
            for kvp in TUBE_KVP_MIN..=TUBE_KVP_MAX {
                let c = row(CONTINUUM, angle, kvp, (2 * (kvp - 1)) as usize).unwrap();
                assert!(c.iter().any(|&n| n > 0.0), "{angle}° {kvp} kVp");
                let l = row(LINES, angle, kvp, lines.len()).unwrap();
                assert!(l.iter().any(|&n| n > 0.0), "{angle}° {kvp} kVp: no line");
                rows += 1;
            }
        }
        let data = |t: &str| {
            t.lines()
                .filter(|l| l.starts_with(char::is_numeric))
                .count()
        };
        assert_eq!(rows, data(CONTINUUM));
        assert_eq!(rows, data(LINES));
    }

    #[test]
    fn bins_are_a_twentieth_of_a_kev_from_1_kev_to_the_kvp() {
        let s = tungsten(80.0, 12.0).unwrap();
        assert_eq!(s.energies_kev.len(), 79 * 20);
        assert!((s.energies_kev[0] - 1.025).abs() < 1e-12);
        assert!((s.energies_kev.last().unwrap() - 79.975).abs() < 1e-12);
        assert!(s.absolute);
    }

    #[test]
    fn the_continuum_is_the_table_at_its_bin_centres_and_zero_at_the_kvp() {
        // Between two fine bins either side of a continuum centre the interpolated density is
        // the tabulated one (a straight line through both); the last fine bin is nearly empty.
        let kvp = 90;
        let c = row(CONTINUUM, 12, kvp, 2 * 89).unwrap();
        let d = |j: usize| continuum_density(&c, j);
        for i in 1..c.len() - 1 {
            // Centre i is at 1.25 + 0.5·i keV, between fine bins 10·i + 4 and 10·i + 5.
            let (a, b) = (d(10 * i + 4), d(10 * i + 5));
            let on_line = |x: f64, y: f64| (x + y) / 2.0;
            let want = c[i] / CONTINUUM_WIDTH_KEV;
            let slope_change = (c[i + 1] - 2.0 * c[i] + c[i - 1]).abs() / CONTINUUM_WIDTH_KEV;
            assert!(
                (on_line(a, b) - want).abs() <= 0.05 * slope_change + 1e-9 * want,
                "{i}"
            );
        }
        let last = d(20 * (kvp as usize - 1) - 1);
        assert!(last < 0.11 * c[c.len() - 1] / CONTINUUM_WIDTH_KEV, "{last}");
        assert_eq!(continuum_density(&c, 0), c[0] / CONTINUUM_WIDTH_KEV);
    }

    #[test]
    fn grid_angles_are_the_tables_and_between_is_linear() {
        let a = tungsten(90.0, 10.0).unwrap();
        let b = tungsten(90.0, 12.0).unwrap();
        let m = tungsten(90.0, 10.5).unwrap();
        for i in 0..a.photons.len() {
            let expect = 0.75 * a.photons[i] + 0.25 * b.photons[i];
            assert!((m.photons[i] - expect).abs() <= 1e-12 * expect, "bin {i}");
        }
        assert_eq!(tungsten(90.0, 22.0).unwrap().photons.len(), a.photons.len());
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
            assert!(*s.energies_kev.last().unwrap() < kvp);
            let n = |e: f64| s.photons[((e - 1.0) * 20.0) as usize];
            // Above the low-energy self-absorption, the continuum falls towards the kVp.
            assert!(n(kvp - 0.5) < n(kvp * 0.5 - 0.5), "{kvp}");
            assert!(s.photons.iter().all(|&p| p >= 0.0));
        }
    }

    /// Tungsten's K lines (Kα2 57.98, Kα1 59.32, Kβ1 67.24 keV; NIST X-ray transition energies)
    /// appear in their own 0.05 keV bins above the K edge (69.5 keV), on both sides of nothing
    /// else: the bins beside a line hold the continuum only; below the K edge there is no line.
    #[test]
    fn tungsten_k_lines_sit_in_their_own_bins_above_the_k_edge() {
        let bin = |e: f64| ((e - 1.0) * 20.0) as usize;
        for angle in [6.0, 12.0, 22.0] {
            // (Just above the edge, at 70 kVp, the K lines are barely excited.)
            for kvp in [60, 69, 80, 120, 150] {
                let s = tungsten(f64::from(kvp), angle).unwrap();
                // The bin against the mean of its neighbours two bins away (1 for a straight
                // continuum, even where it falls to zero at the kVp).
                let peak = |e: f64| {
                    let b = bin(e);
                    2.0 * s.photons[b] / (s.photons[b - 2] + s.photons[b + 2])
                };
                let what = format!("{kvp} kVp {angle}°");
                for line in [57.98, 59.32, 67.24] {
                    if line > f64::from(kvp) - 1.0 {
                        continue;
                    }
                    if kvp < 70 {
                        assert!(
                            peak(line) < 1.1,
                            "{what}: a line at {line} below the K edge"
                        );
                    } else {
                        assert!(
                            peak(line) > 2.0,
                            "{what}: no line at {line} ({})",
                            peak(line)
                        );
                    }
                }
            }
        }
    }
}
