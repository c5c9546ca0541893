//! `rsasim material`: what rsasim knows of materials' attenuation — density, composition,
//! absorption edges and μ/ρ, μ at chosen energies — as a table or JSON on standard output.

use rsasim::attenuation::beamline::pure_element;
use rsasim::attenuation::setup::resolve;
use rsasim::material::{self, ENERGY_MAX_KEV, ENERGY_MIN_KEV, Material};
use serde::Serialize;

use super::Outcome;
use super::shared::{print_stdout, report_errors};
use crate::cli::MaterialArgs;

/// One material as printed.
#[derive(Serialize)]
struct Shown {
    name: String,
    density_g_cm3: f64,
    /// Element symbol → mass fraction.
    composition: Vec<(&'static str, f64)>,
    /// Where the numbers come from (shipped materials).
    source: Option<&'static str>,
    /// Edges in 1–200 keV, increasing: (element, shell, keV).
    edges: Vec<(&'static str, &'static str, f64)>,
    /// (energy keV, μ/ρ cm²/g, μ 1/mm).
    attenuation: Vec<[f64; 3]>,
}

/// Prints every material named (exit 2 naming the first unknown name or bad energy).
pub fn execute(args: MaterialArgs) -> Outcome {
    if let Some(&e) = args
        .energies_kev
        .iter()
        .find(|e| !(ENERGY_MIN_KEV..=ENERGY_MAX_KEV).contains(*e))
    {
        eprintln!(
            "error: --energies-kev {e}: outside the attenuation tables\n  = help: give energies from {ENERGY_MIN_KEV} to {ENERGY_MAX_KEV} keV, e.g. --energies-kev 20,40,60\n\nrsasim: 1 error(s); nothing was written"
        );
        return Err(2);
    }
    let loaded = match &args.scenario {
        Some(path) => Some(rsasim::scenario::load(path).map_err(|e| report_errors(&e))?),
        None => None,
    };
    let mut shown = Vec::with_capacity(args.names.len());
    for name in &args.names {
        let found = loaded
            .as_ref()
            .and_then(|l| resolve(&l.scenario, name))
            .or_else(|| material::by_name(name).cloned())
            .or_else(|| pure_element(name));
        let Some(m) = found else {
            let library: Vec<&str> = material::library()
                .iter()
                .map(|m| m.name.as_str())
                .collect();
            eprintln!(
                "error: material `{}` is not known\n  = help: name a shipped material ({}), a chemical symbol (e.g. W, Pb), or a material of the scenario given with --scenario\n\nrsasim: 1 error(s); nothing was written",
                rsasim::diagnostic::cut(name),
                library.join(", ")
            );
            return Err(2);
        };
        shown.push(show(&m, &args.energies_kev));
    }
    if args.json {
        let json = serde_json::to_string_pretty(&shown).expect("plain numbers and strings");
        print_stdout(&(json + "\n"))?;
    } else {
        print_stdout(&table(&shown))?;
    }
    Ok(())
}

fn show(m: &Material, energies_kev: &[f64]) -> Shown {
    let symbol = |z: u8| material::element_by_z(z).map_or("?", |e| e.symbol);
    Shown {
        name: m.name.clone(),
        density_g_cm3: m.density_g_cm3,
        composition: m
            .mass_fractions
            .iter()
            .map(|&(z, w)| (symbol(z), w))
            .collect(),
        source: material::library_source(&m.name),
        edges: m
            .edges()
            .iter()
            .map(|e| (symbol(e.z), e.shell, e.energy_kev))
            .collect(),
        attenuation: energies_kev
            .iter()
            .map(|&e| {
                [
                    e,
                    m.mass_attenuation_cm2_g(e),
                    m.linear_attenuation_per_mm(e),
                ]
            })
            .collect(),
    }
}

/// `#` lines per material (density, composition, source, edges), then one tab-separated table.
fn table(shown: &[Shown]) -> String {
    let mut out = String::new();
    for m in shown {
        let composition: Vec<String> = m
            .composition
            .iter()
            .map(|(s, w)| format!("{s} {w:.6}"))
            .collect();
        out += &format!(
            "# {}: density {} g/cm³; by mass {}\n",
            m.name,
            m.density_g_cm3,
            composition.join(", ")
        );
        if let Some(source) = m.source {
            out += &format!("# {}: {source}\n", m.name);
        }
        let edges: Vec<String> = m
            .edges
            .iter()
            .map(|(el, shell, e)| format!("{el} {shell} {e}"))
            .collect();
        out += &format!(
            "# {}: edges (keV): {}\n",
            m.name,
            if edges.is_empty() {
                "none in 1–200 keV".to_string()
            } else {
                edges.join(", ")
            }
        );
    }
    out += "material\tenergy_kev\tmu_rho_cm2_g\tmu_per_mm\n";
    for m in shown {
        for [e, mu_rho, mu] in &m.attenuation {
            out += &format!("{}\t{e}\t{mu_rho:.6e}\t{mu:.6e}\n", m.name);
        }
    }
    out
}
