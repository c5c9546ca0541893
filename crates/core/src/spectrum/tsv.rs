//! A user's spectrum as text: `energy_kev photons` per line.

use super::Spectrum;
use crate::diagnostic::cut;

/// The most rows a user spectrum may have (a spectrum with 0.02 keV bins over 1–200 keV).
pub const TSV_MAX_ROWS: usize = 10_000;
/// The lowest energy a user spectrum may hold, keV.
pub const TSV_MIN_ENERGY_KEV: f64 = 1.0;
/// The highest energy a user spectrum may hold, keV.
pub const TSV_MAX_ENERGY_KEV: f64 = 200.0;

/// The largest sum of a user spectrum's photon numbers (and of photons × keV): far above any
/// physical count, far below where the arithmetic on spectra (normalising, weighting, summing
/// per pixel) would overflow.
pub const MAX_TOTAL: f64 = 1e200;

/// Parses the TSV text of a user spectrum (see [`Spectrum::from_tsv`]); errors carry the 1-based
/// line they are about.
pub(super) fn parse(text: &str) -> Result<Spectrum, (usize, String)> {
    let mut energies_kev: Vec<f64> = Vec::new();
    let mut photons: Vec<f64> = Vec::new();
    let mut first_row_line = None;
    let mut header_allowed = true;
    let mut last_line = 0;
    let (mut total_photons, mut total_energy) = (0.0f64, 0.0f64);
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        last_line = line;
        let content = raw.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let fields: Vec<&str> = content.split_whitespace().collect();
        let may_be_header = header_allowed && fields[0].parse::<f64>().is_err();
        header_allowed = false;
        if may_be_header {
            continue;
        }
        if fields.len() != 2 {
            return Err((
                line,
                format!(
                    "expected two columns, energy_kev and photons (separated by a tab or spaces), found {}",
                    fields.len()
                ),
            ));
        }
        let energy = number(fields[0], "energy", line)?;
        let count = number(fields[1], "photon number", line)?;
        if !(TSV_MIN_ENERGY_KEV..=TSV_MAX_ENERGY_KEV).contains(&energy) {
            return Err((
                line,
                format!(
                    "energy {energy} keV is outside {TSV_MIN_ENERGY_KEV}–{TSV_MAX_ENERGY_KEV} keV, the range a spectrum may cover"
                ),
            ));
        }
        if let Some(&previous) = energies_kev.last()
            && energy <= previous
        {
            return Err((
                line,
                format!(
                    "energy {energy} keV is not above the previous row's {previous} keV; energies must increase"
                ),
            ));
        }
        if count < 0.0 {
            return Err((
                line,
                format!("photon number {count} is negative; it must be 0 or more"),
            ));
        }
        if energies_kev.len() == TSV_MAX_ROWS {
            return Err((
                line,
                format!(
                    "more than {TSV_MAX_ROWS} rows; a spectrum may have at most {TSV_MAX_ROWS} bins"
                ),
            ));
        }
        // Each number is finite, but their sums must be too: the spectrum is normalised by its
        // total and weighted by energy, and an overflowing sum would make every image zero.
        total_photons += count;
        total_energy += count * energy;
        if !(total_photons <= MAX_TOTAL && total_energy <= MAX_TOTAL) {
            return Err((
                line,
                format!(
                    "the photon numbers up to this row add up to more than {MAX_TOTAL:e} (or their energy-weighted sum does): only their ratios matter, so scale them down (e.g. to photons per keV per mAs, or to a fraction of the total)"
                ),
            ));
        }
        first_row_line.get_or_insert(line);
        energies_kev.push(energy);
        photons.push(count);
    }
    let Some(first_row_line) = first_row_line else {
        return Err((
            last_line.max(1),
            "no spectrum rows: expected lines of `energy_kev photons`".to_string(),
        ));
    };
    if !photons.iter().any(|&n| n > 0.0) {
        return Err((
            first_row_line,
            "every photon number is 0; at least one must be positive".to_string(),
        ));
    }
    Ok(Spectrum {
        energies_kev,
        photons,
        absolute: false,
    })
}

/// A finite number, or an error naming `what` and echoing the field.
fn number(field: &str, what: &str, line: usize) -> Result<f64, (usize, String)> {
    match field.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err((
            line,
            format!("{what} '{}' is not a finite number", cut(field)),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> (usize, String) {
        match parse(text) {
            Ok(s) => panic!("accepted {s:?}"),
            Err(e) => e,
        }
    }

    #[test]
    fn reads_tabs_spaces_comments_and_a_header() {
        let text = "# measured 2026\nenergy_kev\tphotons\n20\t1.5\n  30   2  # peak\n\n40\t0\n";
        let s = parse(text).unwrap();
        assert_eq!(s.energies_kev, vec![20.0, 30.0, 40.0]);
        assert_eq!(s.photons, vec![1.5, 2.0, 0.0]);
        assert!(!s.absolute);
        assert_eq!(parse("1 1\n200 1e3").unwrap().photons, vec![1.0, 1000.0]);
    }

    #[test]
    fn finite_rows_whose_sum_overflows_are_refused_at_the_row() {
        let (line, msg) = err("20 1e308\n30 1e308\n");
        assert_eq!(line, 1, "{msg}");
        assert!(msg.contains("add up to more than"), "{msg}");
        let (line, _) = err("1 1\n100 5e197\n200 5e197\n");
        assert_eq!(line, 3);
        assert!(parse("20 1e150\n30 1e150\n").is_ok());
    }

    #[test]
    fn errors_name_the_right_line() {
        assert_eq!(err("20 1\n30 1\n25 1\n").0, 3);
        assert!(err("20 1\n30 1\n25 1\n").1.contains("must increase"));
        assert_eq!(err("20 1\n30 1\n30 1\n").0, 3);
        let (line, msg) = err("# c\nE N\n20 1\n30 -1\n");
        assert_eq!(line, 4);
        assert!(msg.contains("negative"), "{msg}");
        let (line, msg) = err("20 1\n\n250 1\n");
        assert_eq!(line, 3);
        assert!(msg.contains("1–200 keV"), "{msg}");
        assert_eq!(err("20 1\n0.5 1\n").0, 2);
        let (line, msg) = err("20 1\n30 1 7\n");
        assert_eq!(line, 2);
        assert!(msg.contains("two columns"), "{msg}");
        assert_eq!(err("20\n").0, 1);
        let (line, msg) = err("20 1\n30 NaN\n");
        assert_eq!(line, 2);
        assert!(msg.contains("'NaN' is not a finite number"), "{msg}");
        assert_eq!(err("20 1\n30 inf\n").0, 2);
        assert_eq!(err("20 1\nx 1\n").0, 2);
    }

    #[test]
    fn only_the_first_line_may_be_a_header() {
        assert_eq!(err("energy photons\nE N\n20 1\n").0, 2);
    }

    #[test]
    fn needs_rows_and_a_positive_photon_number() {
        let (line, msg) = err("# nothing\n\nenergy photons\n");
        assert_eq!(line, 3);
        assert!(msg.contains("no spectrum rows"), "{msg}");
        assert_eq!(err("").0, 1);
        let (line, msg) = err("# c\n20 0\n30 0\n");
        assert_eq!(line, 2);
        assert!(msg.contains("at least one must be positive"), "{msg}");
    }

    #[test]
    fn long_values_are_cut_and_rows_are_capped() {
        let long = "9".repeat(5000) + "x";
        let (_, msg) = err(&format!("20 1\n30 {long}\n"));
        assert!(
            msg.len() < 400 && msg.contains("more bytes"),
            "{}",
            msg.len()
        );
        let mut text = String::new();
        for i in 0..=TSV_MAX_ROWS {
            text.push_str(&format!("{} 1\n", 1.0 + i as f64 * 0.019));
        }
        let (line, msg) = err(&text);
        assert_eq!(line, TSV_MAX_ROWS + 1);
        assert!(msg.contains("at most"), "{msg}");
    }
}
