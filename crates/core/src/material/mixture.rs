//! A material: density and elemental mass fractions, attenuating by the mixture rule.

use super::element::{element, element_by_z, elements};
use crate::diagnostic::cut;

/// The largest density a material may have, g/cm³ (osmium, the densest element, is 22.59).
const DENSITY_MAX_G_CM3: f64 = 30.0;
/// How far the given mass fractions may sum from 1 before they are refused.
const FRACTION_SUM_TOLERANCE: f64 = 1e-3;

/// A homogeneous material: a density and its composition by element mass fraction.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// The material's name (a library name such as `cocr_f75`, or the user's).
    pub name: String,
    /// Density, g/cm³.
    pub density_g_cm3: f64,
    /// (Z, mass fraction), in increasing Z, each fraction > 0, summing to 1.
    pub mass_fractions: Vec<(u8, f64)>,
}

impl Material {
    /// μ/ρ in cm²/g at `e_kev` by the mixture rule Σ wᵢ·(μ/ρ)ᵢ over the elements, summed in
    /// increasing Z. The energy range rule of [`Element::mass_attenuation_cm2_g`]
    /// (super::Element::mass_attenuation_cm2_g) applies: callers validate energies.
    pub fn mass_attenuation_cm2_g(&self, e_kev: f64) -> f64 {
        self.mass_fractions
            .iter()
            .map(|&(z, w)| {
                // A Material made by `mixture` or the library only holds Z in 1..=92; a hand-built
                // one with another Z contributes nothing rather than panic.
                debug_assert!(element_by_z(z).is_some(), "Z {z} has no table");
                element_by_z(z).map_or(0.0, |el| w * el.mass_attenuation_cm2_g(e_kev))
            })
            .sum()
    }

    /// The linear attenuation coefficient μ in 1/mm at `e_kev`: (μ/ρ)·ρ / 10 (cm²/g · g/cm³ =
    /// 1/cm, and 1/cm = 0.1/mm).
    pub fn linear_attenuation_per_mm(&self, e_kev: f64) -> f64 {
        self.mass_attenuation_cm2_g(e_kev) * self.density_g_cm3 / 10.0
    }

    /// The absorption edges of every element of the material (see [`Element::edges`]
    /// (super::Element::edges)), increasing in energy.
    pub fn edges(&self) -> Vec<super::Edge> {
        let mut edges: Vec<super::Edge> = self
            .mass_fractions
            .iter()
            .filter_map(|&(z, _)| element_by_z(z))
            .flat_map(|el| el.edges())
            .collect();
        edges.sort_by(|a, b| a.energy_kev.total_cmp(&b.energy_kev).then(a.z.cmp(&b.z)));
        edges
    }

    /// A user material from element symbols and mass fractions. The error is a sentence naming
    /// the material and the bad symbol, fraction or density, and saying what is valid. Refused:
    /// no elements; an unknown symbol (symbols are case-sensitive, `H` to `U`); a fraction ≤ 0 or
    /// not finite; an element listed twice; fractions summing to more than 1e-3 away from 1; a
    /// density ≤ 0, above 30 g/cm³ or not finite. Accepted fractions are divided by their sum,
    /// so they sum to 1, and sorted by Z.
    pub fn mixture(
        name: &str,
        density_g_cm3: f64,
        fractions: &[(&str, f64)],
    ) -> Result<Material, String> {
        let who = format!("material `{}`", cut(name));
        if !(density_g_cm3.is_finite() && density_g_cm3 > 0.0 && density_g_cm3 <= DENSITY_MAX_G_CM3)
        {
            return Err(format!(
                "{who}: density_g_cm3 = {density_g_cm3} is not valid; give a density above 0 and \
                 at most {DENSITY_MAX_G_CM3} g/cm³ (water is 1, tantalum 16.65)"
            ));
        }
        if fractions.is_empty() {
            return Err(format!(
                "{who} has no elements; give its composition as element symbols with mass \
                 fractions, e.g. {{ H = 0.111898, O = 0.888102 }}"
            ));
        }
        let mut out: Vec<(u8, f64)> = Vec::with_capacity(fractions.len());
        for &(symbol, w) in fractions {
            let Some(el) = element(symbol) else {
                return Err(unknown_symbol(&who, symbol));
            };
            if !(w.is_finite() && w > 0.0) {
                return Err(format!(
                    "{who}: the mass fraction of {symbol} is {w}; each fraction must be a number \
                     above 0 (leave out an element that is not there)"
                ));
            }
            if out.iter().any(|&(z, _)| z == el.z) {
                return Err(format!(
                    "{who}: element {symbol} is listed twice; give each element once"
                ));
            }
            out.push((el.z, w));
        }
        let sum: f64 = out.iter().map(|&(_, w)| w).sum();
        if (sum - 1.0).abs() > FRACTION_SUM_TOLERANCE {
            return Err(format!(
                "{who}: the mass fractions sum to {}; they must sum to 1 (within \
                 {FRACTION_SUM_TOLERANCE})",
                // Six decimals say how far off the sum is without float noise (0.8999999999999999).
                (sum * 1e6).round() / 1e6
            ));
        }
        for entry in &mut out {
            entry.1 /= sum;
        }
        out.sort_by_key(|&(z, _)| z);
        Ok(Material {
            name: name.to_string(),
            density_g_cm3,
            mass_fractions: out,
        })
    }
}

/// The message for a symbol that names no element, with the right spelling when only the case
/// is wrong.
fn unknown_symbol(who: &str, symbol: &str) -> String {
    let hint = elements()
        .iter()
        .find(|e| e.symbol.eq_ignore_ascii_case(symbol))
        .map(|e| format!(" (did you mean `{}`?)", e.symbol))
        .unwrap_or_default();
    format!(
        "{who}: `{}` is not an element symbol{hint}; use chemical symbols with their case, \
         H to U (Z 1 to 92), e.g. Co, Cr, Mo",
        cut(symbol)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(density: f64, fractions: &[(&str, f64)]) -> String {
        Material::mixture("alloy_x", density, fractions).unwrap_err()
    }

    #[test]
    fn mixture_rule_equals_the_hand_sum() {
        let water = Material::mixture("w", 1.0, &[("O", 0.888102), ("H", 0.111898)]).unwrap();
        assert_eq!(water.mass_fractions[0].0, 1, "sorted by Z");
        let (h, o) = (element("H").unwrap(), element("O").unwrap());
        for e in [1.0, 17.3, 60.0, 67.4164, 123.4, 200.0] {
            let hand =
                0.111898 * h.mass_attenuation_cm2_g(e) + 0.888102 * o.mass_attenuation_cm2_g(e);
            let got = water.mass_attenuation_cm2_g(e);
            assert!((got / hand - 1.0).abs() < 1e-14, "{e} keV: {got} vs {hand}");
            assert_eq!(water.linear_attenuation_per_mm(e), got * 1.0 / 10.0);
        }
        let ta = Material::mixture("ta", 16.65, &[("Ta", 1.0)]).unwrap();
        let mu = element("Ta").unwrap().mass_attenuation_cm2_g(80.0);
        assert_eq!(ta.mass_attenuation_cm2_g(80.0), mu);
        assert!((ta.linear_attenuation_per_mm(80.0) - mu * 1.665).abs() < 1e-12);
    }

    #[test]
    fn fractions_within_tolerance_are_normalised_to_one() {
        let m = Material::mixture("m", 2.0, &[("Al", 0.5004), ("Cu", 0.5)]).unwrap();
        let sum: f64 = m.mass_fractions.iter().map(|f| f.1).sum();
        assert!((sum - 1.0).abs() < 1e-15, "{sum}");
        assert!((m.mass_fractions[0].1 - 0.5004 / 1.0004).abs() < 1e-15);
    }

    #[test]
    fn bad_symbols_are_named_with_what_is_valid() {
        let e = err(8.3, &[("Co", 0.7), ("Xx", 0.3)]);
        assert!(e.contains("material `alloy_x`") && e.contains("`Xx` is not an element symbol"));
        assert!(e.contains("H to U"), "{e}");
        let e = err(8.3, &[("co", 1.0)]);
        assert!(e.contains("did you mean `Co`?"), "{e}");
        let e = err(8.3, &[("Uuo", 1.0)]);
        assert!(e.contains("`Uuo`") && !e.contains("did you mean"), "{e}");
    }

    #[test]
    fn bad_fractions_are_named_with_what_is_valid() {
        for w in [0.0, -0.1, f64::NAN, f64::INFINITY] {
            let e = err(8.3, &[("Co", 1.0), ("Cr", w)]);
            assert!(
                e.contains("mass fraction of Cr is") && e.contains("above 0"),
                "{e}"
            );
        }
        let e = err(8.3, &[("Co", 0.5), ("Cr", 0.2), ("Co", 0.3)]);
        assert!(e.contains("element Co is listed twice"), "{e}");
        let e = err(8.3, &[("Co", 0.6), ("Cr", 0.3)]);
        assert!(
            e.contains("sum to 0.9;") && e.contains("must sum to 1"),
            "{e}"
        );
        let e = err(8.3, &[("Co", 0.6), ("Cr", 0.4011)]);
        assert!(e.contains("must sum to 1 (within 0.001)"), "{e}");
        let e = err(8.3, &[]);
        assert!(e.contains("has no elements"), "{e}");
    }

    #[test]
    fn bad_densities_are_named_with_what_is_valid() {
        for d in [0.0, -1.0, 30.000_001, f64::NAN, f64::INFINITY] {
            let e = err(d, &[("Co", 1.0)]);
            assert!(
                e.contains("density_g_cm3 = ") && e.contains("above 0 and at most 30 g/cm³"),
                "{e}"
            );
        }
        assert!(Material::mixture("m", 30.0, &[("Os", 1.0)]).is_ok());
    }

    #[test]
    fn a_long_name_is_cut_in_the_message() {
        let name = "n".repeat(10_000);
        let e = Material::mixture(&name, -1.0, &[("H", 1.0)]).unwrap_err();
        assert!(e.len() < 1_000, "{}", e.len());
    }
}
