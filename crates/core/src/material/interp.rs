//! One μ/ρ(E) table and its log-log interpolation.

use super::{ENERGY_MAX_KEV, ENERGY_MIN_KEV};

/// Rows of (energy, μ/ρ) in non-decreasing energy; an absorption edge is two rows with the same
/// energy, the value below the edge first. Logarithms are kept so a lookup costs one `log` and
/// one `exp`.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Table {
    energy_kev: Vec<f64>,
    mu_rho_cm2_g: Vec<f64>,
    ln_energy: Vec<f64>,
    ln_mu_rho: Vec<f64>,
}

impl Table {
    /// A table from its rows. The rows must start at [`ENERGY_MIN_KEV`], end at
    /// [`ENERGY_MAX_KEV`], never decrease in energy, repeat an energy at most twice and hold
    /// positive finite values; the error says which rule a row breaks.
    pub(super) fn new(rows: Vec<(f64, f64)>) -> Result<Table, String> {
        let (first, last) = match (rows.first(), rows.last()) {
            (Some(f), Some(l)) => (f.0, l.0),
            _ => return Err("the table has no rows".to_string()),
        };
        if first != ENERGY_MIN_KEV || last != ENERGY_MAX_KEV {
            return Err(format!(
                "the table runs from {first} to {last} keV, not {ENERGY_MIN_KEV} to {ENERGY_MAX_KEV}"
            ));
        }
        for (i, w) in rows.windows(2).enumerate() {
            if w[1].0 < w[0].0 {
                return Err(format!("row {} goes down in energy", i + 1));
            }
            if i >= 1 && rows[i - 1].0 == w[0].0 && w[0].0 == w[1].0 {
                return Err(format!("energy {} keV appears three times", w[0].0));
            }
        }
        if let Some((e, v)) = rows.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return Err(format!(
                "the value {v} at {e} keV is not positive and finite"
            ));
        }
        Ok(Table {
            ln_energy: rows.iter().map(|r| libm::log(r.0)).collect(),
            ln_mu_rho: rows.iter().map(|r| libm::log(r.1)).collect(),
            energy_kev: rows.iter().map(|r| r.0).collect(),
            mu_rho_cm2_g: rows.iter().map(|r| r.1).collect(),
        })
    }

    /// μ/ρ at `e_kev`: the stored value on a row (the above-edge value at an edge), log-log
    /// linear between rows. An energy outside the table (or NaN) is clamped to its range.
    pub(super) fn at(&self, e_kev: f64) -> f64 {
        let e = if e_kev.is_nan() || e_kev < ENERGY_MIN_KEV {
            ENERGY_MIN_KEV
        } else if e_kev > ENERGY_MAX_KEV {
            ENERGY_MAX_KEV
        } else {
            e_kev
        };
        // The last row with energy ≤ e: at an edge, the above-edge row. The first row is
        // ENERGY_MIN_KEV ≤ e, so the count is at least 1.
        let i = self.energy_kev.partition_point(|&x| x <= e).max(1) - 1;
        if self.energy_kev[i] == e || i + 1 == self.energy_kev.len() {
            return self.mu_rho_cm2_g[i];
        }
        let t = (libm::log(e) - self.ln_energy[i]) / (self.ln_energy[i + 1] - self.ln_energy[i]);
        libm::exp(self.ln_mu_rho[i] + t * (self.ln_mu_rho[i + 1] - self.ln_mu_rho[i]))
    }

    /// The absorption edges of the table: the energies that appear on two rows, increasing.
    pub(super) fn edges_kev(&self) -> impl Iterator<Item = f64> + '_ {
        self.energy_kev
            .windows(2)
            .filter(|w| w[0] == w[1])
            .map(|w| w[0])
    }

    /// The rows (energy, value), for tests.
    #[cfg(test)]
    pub(super) fn rows(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.energy_kev
            .iter()
            .copied()
            .zip(self.mu_rho_cm2_g.iter().copied())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> Table {
        Table::new(vec![
            (1.0, 1000.0),
            (10.0, 10.0),
            (20.0, 2.0),
            (20.0, 16.0),
            (200.0, 0.1),
        ])
        .unwrap()
    }

    #[test]
    fn exact_on_rows_and_above_edge_at_the_edge() {
        let t = table();
        assert_eq!(t.at(1.0), 1000.0);
        assert_eq!(t.at(10.0), 10.0);
        assert_eq!(
            t.at(20.0),
            16.0,
            "at the edge energy the above-edge value applies"
        );
        assert_eq!(t.at(200.0), 0.1);
    }

    #[test]
    fn log_log_linear_between_rows() {
        let t = table();
        // A power law through (1, 1000) and (10, 10): μ = 1000·E^-2, so √10 keV gives 100.
        let got = t.at(libm::sqrt(10.0));
        assert!((got / 100.0 - 1.0).abs() < 1e-14, "{got}");
        // Just below the edge the lower branch, just above it the upper one.
        assert!((t.at(19.999_999) / 2.0 - 1.0).abs() < 1e-6);
        assert!((t.at(20.000_001) / 16.0 - 1.0).abs() < 1e-6);
    }

    #[test]
    fn edges_are_the_energies_on_two_rows() {
        assert_eq!(table().edges_kev().collect::<Vec<_>>(), vec![20.0]);
    }

    #[test]
    fn out_of_range_and_nan_are_clamped_not_panicking() {
        let t = table();
        assert_eq!(t.at(0.5), 1000.0);
        assert_eq!(t.at(f64::NAN), 1000.0);
        assert_eq!(t.at(1e9), 0.1);
        assert_eq!(t.at(f64::INFINITY), 0.1);
    }

    #[test]
    fn malformed_tables_are_refused_with_the_rule_they_break() {
        let err = |rows: Vec<(f64, f64)>| Table::new(rows).unwrap_err();
        assert!(err(vec![]).contains("no rows"));
        assert!(err(vec![(2.0, 1.0), (200.0, 1.0)]).contains("runs from 2"));
        assert!(
            err(vec![(1.0, 1.0), (50.0, 1.0), (40.0, 1.0), (200.0, 1.0)]).contains("goes down")
        );
        assert!(
            err(vec![
                (1.0, 1.0),
                (5.0, 1.0),
                (5.0, 2.0),
                (5.0, 3.0),
                (200.0, 1.0)
            ])
            .contains("three times")
        );
        assert!(err(vec![(1.0, 1.0), (5.0, 0.0), (200.0, 1.0)]).contains("not positive"));
    }
}
