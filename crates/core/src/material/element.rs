//! The elements Z = 1..92: symbol, name, atomic mass, density and the μ/ρ(E) table of each,
//! parsed once from the shipped TSV files.

use std::fmt;
use std::sync::OnceLock;

use super::interp::Table;

/// `z, symbol, name, atomic_mass, density_g_cm3`, one element a line, Z = 1..92 in order.
const ELEMENTS_TSV: &str = include_str!("../../../../data/attenuation/elements.tsv");
/// `z, energy_kev, mu_rho_cm2_g`: the μ/ρ tables of all elements, each in non-decreasing energy.
const MU_RHO_TSV: &str = include_str!("../../../../data/attenuation/mu_rho.tsv");

/// The highest atomic number in the tables (uranium).
const Z_MAX: u8 = 92;

/// A chemical element with its total mass attenuation coefficient (coherent + incoherent +
/// photoelectric scattering and absorption, as NIST XCOM's "total with coherent scattering").
#[derive(Clone, PartialEq)]
pub struct Element {
    /// Atomic number, 1..=92.
    pub z: u8,
    /// Chemical symbol with its case, e.g. `"Ta"`.
    pub symbol: &'static str,
    /// English name, e.g. `"Tantalum"`.
    pub name: &'static str,
    /// Standard atomic weight, g/mol.
    pub atomic_mass: f64,
    /// Density of the pure element at room temperature (gases at 20 °C, 1 atm), g/cm³.
    pub density_g_cm3: f64,
    table: Table,
}

impl fmt::Debug for Element {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Element")
            .field("z", &self.z)
            .field("symbol", &self.symbol)
            .field("name", &self.name)
            .field("atomic_mass", &self.atomic_mass)
            .field("density_g_cm3", &self.density_g_cm3)
            .finish_non_exhaustive()
    }
}

impl Element {
    /// μ/ρ in cm²/g at photon energy `e_kev`: log-log interpolation between table rows; exactly
    /// at an absorption edge, the value above the edge.
    ///
    /// `e_kev` must lie in [`ENERGY_MIN_KEV`](super::ENERGY_MIN_KEV)..=
    /// [`ENERGY_MAX_KEV`](super::ENERGY_MAX_KEV): callers validate energies (a scenario's
    /// spectrum) before they get here. Debug builds assert it; release builds clamp to the range.
    pub fn mass_attenuation_cm2_g(&self, e_kev: f64) -> f64 {
        debug_assert!(
            (super::ENERGY_MIN_KEV..=super::ENERGY_MAX_KEV).contains(&e_kev),
            "energy {e_kev} keV outside the attenuation tables"
        );
        self.table.at(e_kev)
    }

    /// The absorption edges of this element between [`ENERGY_MIN_KEV`](super::ENERGY_MIN_KEV)
    /// and [`ENERGY_MAX_KEV`](super::ENERGY_MAX_KEV), highest first, each with its shell: the
    /// highest is the K edge, then L1, L2, L3, M1 … M5 (each shell's edge lies below the one
    /// before it, so the edges in a range from the top down are those shells in that order).
    pub fn edges(&self) -> Vec<Edge> {
        const SHELLS: [&str; 9] = ["K", "L1", "L2", "L3", "M1", "M2", "M3", "M4", "M5"];
        let mut energies: Vec<f64> = self.table.edges_kev().collect();
        energies.reverse();
        energies
            .into_iter()
            .zip(SHELLS)
            .map(|(energy_kev, shell)| Edge {
                z: self.z,
                shell,
                energy_kev,
            })
            .collect()
    }

    /// The table rows (energy in keV, μ/ρ in cm²/g), edges as two rows with the same energy.
    #[cfg(test)]
    pub(super) fn rows(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.table.rows()
    }
}

/// An absorption edge: the energy at which μ/ρ of an element jumps, as a photon can free an
/// electron of one more shell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// The element's atomic number.
    pub z: u8,
    /// The shell: `K`, `L1`, `L2`, `L3`, `M1` … `M5`.
    pub shell: &'static str,
    /// The edge energy, keV (above it the higher value applies).
    pub energy_kev: f64,
}

/// The element with chemical symbol `symbol`, case-sensitive (`"Ta"`, not `"ta"`).
pub fn element(symbol: &str) -> Option<&'static Element> {
    elements().iter().find(|e| e.symbol == symbol)
}

/// The element with atomic number `z` (1..=92).
pub fn element_by_z(z: u8) -> Option<&'static Element> {
    elements().get(usize::from(z).checked_sub(1)?)
}

/// All elements, Z = 1..92 in order, parsed on first use.
pub(super) fn elements() -> &'static [Element] {
    static ELEMENTS: OnceLock<Vec<Element>> = OnceLock::new();
    // The tables are compiled in and checked by the unit tests: a failure here is a build defect,
    // never something a user's input can cause.
    ELEMENTS.get_or_init(|| parse(ELEMENTS_TSV, MU_RHO_TSV).unwrap_or_else(|e| panic!("{e}")))
}

/// The elements from the two TSV texts; the error names the file and line that is wrong.
fn parse(elements_tsv: &'static str, mu_rho_tsv: &'static str) -> Result<Vec<Element>, String> {
    let mut rows: Vec<Vec<(f64, f64)>> = vec![Vec::new(); usize::from(Z_MAX)];
    for (n, line) in mu_rho_tsv.lines().enumerate().skip(1) {
        let at = || format!("data/attenuation/mu_rho.tsv line {}", n + 1);
        let f: Vec<&str> = line.split('\t').collect();
        let [z, e, v] = f[..] else {
            return Err(format!("{}: expected 3 tab-separated fields", at()));
        };
        let z: usize = z.parse().map_err(|_| format!("{}: bad Z `{z}`", at()))?;
        let e: f64 = e
            .parse()
            .map_err(|_| format!("{}: bad energy `{e}`", at()))?;
        let v: f64 = v
            .parse()
            .map_err(|_| format!("{}: bad value `{v}`", at()))?;
        match rows.get_mut(z.wrapping_sub(1)) {
            Some(r) => r.push((e, v)),
            None => return Err(format!("{}: Z {z} outside 1..={Z_MAX}", at())),
        }
    }
    let mut out = Vec::with_capacity(usize::from(Z_MAX));
    for (n, line) in elements_tsv.lines().enumerate().skip(1) {
        let at = || format!("data/attenuation/elements.tsv line {}", n + 1);
        let f: Vec<&'static str> = line.split('\t').collect();
        let [z, symbol, name, mass, density] = f[..] else {
            return Err(format!("{}: expected 5 tab-separated fields", at()));
        };
        let z: u8 = z.parse().map_err(|_| format!("{}: bad Z `{z}`", at()))?;
        if usize::from(z) != out.len() + 1 {
            return Err(format!("{}: Z {z} out of order", at()));
        }
        let atomic_mass: f64 = mass.parse().map_err(|_| format!("{}: bad mass", at()))?;
        let density_g_cm3: f64 = density
            .parse()
            .map_err(|_| format!("{}: bad density", at()))?;
        let table_rows = std::mem::take(&mut rows[usize::from(z) - 1]);
        let table = Table::new(table_rows)
            .map_err(|e| format!("data/attenuation/mu_rho.tsv, Z {z}: {e}"))?;
        out.push(Element {
            z,
            symbol,
            name,
            atomic_mass,
            density_g_cm3,
            table,
        });
    }
    if out.len() != usize::from(Z_MAX) {
        return Err(format!(
            "data/attenuation/elements.tsv has {} elements, not {Z_MAX}",
            out.len()
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{ENERGY_MAX_KEV, ENERGY_MIN_KEV};

    #[test]
    fn the_shipped_tables_parse_and_hold_all_92_elements_in_order() {
        let all = parse(ELEMENTS_TSV, MU_RHO_TSV).unwrap();
        assert_eq!(all.len(), 92);
        for (i, el) in all.iter().enumerate() {
            assert_eq!(usize::from(el.z), i + 1);
            assert!(el.atomic_mass > 0.9 && el.atomic_mass < 240.0, "{el:?}");
            assert!(el.density_g_cm3 > 0.0 && el.density_g_cm3 < 23.0, "{el:?}");
            let rows: Vec<_> = el.rows().collect();
            assert_eq!(rows[0].0, ENERGY_MIN_KEV);
            assert_eq!(rows[rows.len() - 1].0, ENERGY_MAX_KEV);
            // About 50 points per decade or finer over 1–200 keV (2.3 decades).
            assert!(rows.len() >= 115, "Z {}: {} rows", el.z, rows.len());
        }
    }

    #[test]
    fn lookups_by_symbol_and_atomic_number() {
        let ta = element("Ta").unwrap();
        assert_eq!((ta.z, ta.name), (73, "Tantalum"));
        assert_eq!(ta.density_g_cm3, 16.654);
        assert!((ta.atomic_mass - 180.948).abs() < 1e-3);
        assert_eq!(element_by_z(73), Some(ta));
        assert_eq!(element("H").map(|e| e.z), Some(1));
        assert_eq!(element("U").map(|e| e.z), Some(92));
        assert_eq!(element("ta"), None, "symbols are case-sensitive");
        assert_eq!(element("Xx"), None);
        assert_eq!(element(""), None);
        assert_eq!(element_by_z(0), None);
        assert_eq!(element_by_z(93), None);
    }

    #[test]
    fn every_table_row_is_returned_exactly_and_edges_give_the_value_above() {
        for el in elements() {
            let rows: Vec<_> = el.rows().collect();
            for (i, &(e, v)) in rows.iter().enumerate() {
                let edge_below = rows.get(i + 1).is_some_and(|n| n.0 == e);
                let want = if edge_below { rows[i + 1].1 } else { v };
                assert_eq!(el.mass_attenuation_cm2_g(e), want, "Z {} at {e} keV", el.z);
            }
        }
    }

    /// Edge energies of tantalum and aluminium as NIST tabulates them (Hubbell & Seltzer, NISTIR
    /// 5632, Table 3: Ta K 67.4164, L1 11.6815, L2 11.1361, L3 9.8811, M1 2.708, M2 2.4687, M3
    /// 2.1943, M4 1.7932, M5 1.7351 keV; Al K 1.5596 keV); the shipped edges are xraylib's,
    /// snapped to those energies when within 0.3 % (data/attenuation/README.md).
    #[test]
    fn edges_are_the_shells_from_the_top_down() {
        let ta: Vec<(&str, f64)> = element("Ta")
            .unwrap()
            .edges()
            .iter()
            .map(|e| (e.shell, e.energy_kev))
            .collect();
        let nist = [
            ("K", 67.4164),
            ("L1", 11.6815),
            ("L2", 11.1361),
            ("L3", 9.8811),
            ("M1", 2.708),
            ("M2", 2.4687),
            ("M3", 2.1943),
            ("M4", 1.7932),
            ("M5", 1.7351),
        ];
        assert_eq!(ta.len(), nist.len(), "{ta:?}");
        for ((shell, got), (want_shell, want)) in ta.iter().zip(nist) {
            assert_eq!(*shell, want_shell);
            assert!(
                (got / want - 1.0).abs() < 3e-3,
                "{shell}: {got} keV, NIST {want}"
            );
        }
        let al = element("Al").unwrap().edges();
        assert_eq!(al.len(), 1);
        assert_eq!(al[0].shell, "K");
        assert!((al[0].energy_kev / 1.5596 - 1.0).abs() < 3e-3);
        assert!(element("H").unwrap().edges().is_empty());
    }

    #[test]
    fn malformed_data_is_reported_with_file_and_line() {
        let e = parse("z\n", "z\tenergy_kev\tmu\n1\t1.0\n").unwrap_err();
        assert!(e.contains("mu_rho.tsv line 2"), "{e}");
        let e = parse("z\n", "z\tenergy_kev\tmu\n99\t1.0\t2.0\n").unwrap_err();
        assert!(e.contains("Z 99 outside"), "{e}");
        let e = parse("z\n2\tHe\tHelium\t4\t0.1\n", "z\n").unwrap_err();
        assert!(e.contains("elements.tsv line 2: Z 2 out of order"), "{e}");
    }
}
