//! The material library: elements Z = 1..92 with their mass attenuation coefficients μ/ρ(E), the
//! shipped materials (tantalum, CoCr, Ti-6Al-4V, 316L, UHMWPE, PMMA, bone, soft tissue, water, air,
//! aluminium, copper, CsI) and user materials made of elements by mass fraction.
//!
//! The numbers come from `data/attenuation/` (read at compile time with `include_str!`), which
//! `data/attenuation/regen.py` writes from xraylib; its README says the source, the tool versions,
//! the units and how closely the tables match NIST's published values.
//!
//! μ/ρ is interpolated linearly in log E – log μ/ρ between table rows (with `libm`, so the result
//! is the same on every platform). Absorption edges are kept as two rows with the same energy:
//! exactly at an edge energy the value above the edge applies.
//!
//! Energies are in keV, μ/ρ in cm²/g, densities in g/cm³, linear attenuation in 1/mm. The tables
//! cover [`ENERGY_MIN_KEV`]..=[`ENERGY_MAX_KEV`]; callers validate energies against that range
//! before they ask (debug builds assert it; release builds clamp to the range).

mod element;
mod interp;
mod library;
mod mixture;
#[cfg(test)]
mod nist_tests;

pub use element::{Edge, Element, element, element_by_z};
pub use library::{by_name, library, library_source};
pub use mixture::Material;

/// The lowest photon energy of the attenuation tables, in keV.
pub const ENERGY_MIN_KEV: f64 = 1.0;
/// The highest photon energy of the attenuation tables, in keV.
pub const ENERGY_MAX_KEV: f64 = 200.0;

/// Density from which a material counts as metal where bead visibility is judged, g/cm³
/// (titanium alloys 4.4, CoCr 8.3, steel 8.0, tantalum 16.7; cortical bone 1.9).
pub const METAL_DENSITY_G_CM3: f64 = 4.0;
