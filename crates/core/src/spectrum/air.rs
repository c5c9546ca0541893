//! Mass energy-absorption coefficient of dry air, from NIST's table shipped in
//! `data/spectra/air_muen.tsv` (made by `data/spectra/regen.py`).

use std::sync::OnceLock;

/// The shipped table: `energy_kev muen_over_rho_cm2_per_g` per line, `#` comments; an absorption
/// edge is two rows at the same energy (below, then above).
const TABLE: &str = include_str!("../../../../data/spectra/air_muen.tsv");

/// (energy keV, μ_en/ρ cm²/g) rows of [`TABLE`], parsed once.
fn rows() -> &'static [(f64, f64)] {
    static ROWS: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    // The shipped table always parses (pinned by a test); a damaged one gives no kerma at all.
    ROWS.get_or_init(|| parse(TABLE).unwrap_or_default())
}

/// Parses the table text; an error names the line.
fn parse(text: &str) -> Result<Vec<(f64, f64)>, String> {
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let mut fields = line.split('\t').map(str::parse::<f64>);
        match (fields.next(), fields.next(), fields.next()) {
            (Some(Ok(e)), Some(Ok(m)), None) if e > 0.0 && m > 0.0 => rows.push((e, m)),
            _ => return Err(format!("air_muen.tsv line {}: not `energy muen`", i + 1)),
        }
    }
    if rows.len() < 2 || rows.windows(2).any(|w| w[1].0 < w[0].0) {
        return Err("air_muen.tsv: energies must increase".to_string());
    }
    Ok(rows)
}

/// (μ_en/ρ)_air at `energy_kev` in cm²/g: linear in log(E)–log(μ_en/ρ) between the table rows
/// around it (above an edge at the edge energy itself); the end value outside the table.
pub(super) fn muen_over_rho_cm2_per_g(energy_kev: f64) -> f64 {
    interpolate_log_log(rows(), energy_kev)
}

/// Log-log interpolation in `rows` (energies non-decreasing), clamped at both ends; 0 if empty.
fn interpolate_log_log(rows: &[(f64, f64)], energy_kev: f64) -> f64 {
    let (Some(&first), Some(&last)) = (rows.first(), rows.last()) else {
        return 0.0;
    };
    if energy_kev.is_nan() || energy_kev <= first.0 {
        return first.1;
    }
    if energy_kev >= last.0 {
        return last.1;
    }
    // The first row above the energy; the row before it is at or below it.
    let j = rows.partition_point(|&(e, _)| e <= energy_kev);
    let ((e0, m0), (e1, m1)) = (rows[j - 1], rows[j]);
    if energy_kev == e0 {
        return m0;
    }
    let t = (libm::log(energy_kev) - libm::log(e0)) / (libm::log(e1) - libm::log(e0));
    libm::exp(libm::log(m0) + t * (libm::log(m1) - libm::log(m0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_table_parses_and_covers_1_to_200_kev() {
        let parsed = parse(TABLE).unwrap();
        assert_eq!(parsed.len(), rows().len());
        assert_eq!(parsed.first().unwrap().0, 1.0);
        assert_eq!(parsed.last().unwrap().0, 200.0);
    }

    #[test]
    fn nist_values_at_table_energies() {
        // NIST (Hubbell & Seltzer, Table 4, air, dry): 1, 20, 60, 100, 150 keV.
        for (e, m) in [
            (1.0, 3599.0),
            (20.0, 0.5389),
            (60.0, 0.03041),
            (100.0, 0.02325),
            (150.0, 0.02496),
        ] {
            assert_eq!(muen_over_rho_cm2_per_g(e), m, "{e} keV");
        }
    }

    #[test]
    fn log_log_between_rows_and_edges_kept() {
        // A power law is exact under log-log interpolation.
        let rows = [(10.0, 1000.0), (20.0, 125.0)];
        let m = interpolate_log_log(&rows, 15.0);
        assert!(
            (m / (1000.0 * (10.0f64 / 15.0).powi(3)) - 1.0).abs() < 1e-12,
            "{m}"
        );
        // The argon K edge at 3.2029 keV: below 133, at and above it 146.
        assert!((muen_over_rho_cm2_per_g(3.2028) - 133.0).abs() < 0.05);
        assert_eq!(muen_over_rho_cm2_per_g(3.2029), 146.0);
        assert_eq!(muen_over_rho_cm2_per_g(0.5), 3599.0);
        assert_eq!(muen_over_rho_cm2_per_g(500.0), 0.02672);
        assert_eq!(muen_over_rho_cm2_per_g(f64::NAN), 3599.0);
        assert_eq!(interpolate_log_log(&[], 10.0), 0.0);
    }

    #[test]
    fn damaged_tables_are_refused() {
        assert!(parse("1\t2\n3\tx\n").unwrap_err().contains("line 2"));
        assert!(parse("5\t2\n3\t1\n").is_err());
        assert!(parse("5\t2\n").is_err());
    }
}
