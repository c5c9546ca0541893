//! `rsasim spectrum`: the beam of an attenuation-mode scenario as numbers (text or JSON on
//! standard output) and, on request, as a TSV table and an SVG plot.

use std::path::Path;

use rsasim::attenuation::beamline::{Beamline, material_named};
use rsasim::attenuation::setup::beam_spectrum;
use rsasim::scenario::ResponseKind;

use super::Outcome;
use super::shared::{check, print_stdout, report_errors};
use crate::cli::SpectrumArgs;
use crate::spectrum_plot;

/// The first line of every TSV this command writes: how an earlier one is recognised before it
/// is replaced.
const TSV_MARK: &str = "# rsasim spectrum";

/// The largest thickness accepted, mm.
const MAX_THICKNESS_MM: f64 = 10_000.0;

/// Checks the scenario and the options (exit 2, nothing written), prints the beam, then writes
/// the files asked for.
pub fn execute(args: SpectrumArgs) -> Outcome {
    let checked = check(&args.scenario, &args.allow.clone().into())?;
    let loaded = &checked.loaded;
    let Some(setup) = &checked.setup else {
        eprintln!(
            "error: {}: the scenario forms binary images; `rsasim spectrum` shows the beam of an attenuation-mode scenario\n  = help: set [imaging] mode = \"attenuation\" with a tube (the manual, docs/src/physics/attenuation.md)\n\nrsasim: 1 error(s); nothing was written",
            args.scenario.display()
        );
        return Err(2);
    };
    let spectrum = beam_spectrum(loaded).map_err(|e| report_errors(&e))?;
    let mut beam = Beamline::new(loaded, setup, spectrum);
    for (name, mm) in thicknesses(&args.thickness_mm, &setup.names)? {
        let Some(m) = material_named(loaded, &name) else {
            eprintln!(
                "error: --thickness-mm {}: material `{}` is not known\n  = help: name a material of the scene, a shipped one (`rsasim material` lists what a name gives) or a chemical symbol (e.g. W)\n\nrsasim: 1 error(s); nothing was written",
                rsasim::diagnostic::cut(&format!("{name}={mm}")),
                rsasim::diagnostic::cut(&name)
            );
            return Err(2);
        };
        beam.add_transmission(&m, mm);
    }
    for (path, mark) in [(&args.tsv, TSV_MARK), (&args.svg, spectrum_plot::MARK)] {
        if let Some(path) = path {
            check_target(path, mark)?;
        }
    }
    if args.json {
        let json = serde_json::to_string_pretty(&beam).expect("plain numbers and strings");
        print_stdout(&(json + "\n"))?;
    } else {
        print_stdout(&text(&args.scenario, &beam))?;
    }
    let title = format!("{}: {}", args.scenario.display(), beam.source);
    if let Some(path) = &args.tsv {
        write(path, tsv(&title, &beam).as_bytes())?;
    }
    if let Some(path) = &args.svg {
        write(path, spectrum_plot::svg(&title, &beam).as_bytes())?;
    }
    Ok(())
}

/// The `--thickness-mm` entries as (material, mm): a bare number for every scene material not
/// named (default 1 mm), then the named ones in the order given (a material may be named with
/// several thicknesses; the same pair twice counts once).
fn thicknesses(entries: &[String], scene: &[String]) -> Result<Vec<(String, f64)>, u8> {
    let mut all_mm = 1.0;
    let mut named: Vec<(String, f64)> = Vec::new();
    for entry in entries {
        let (name, value) = match entry.split_once('=') {
            Some((n, v)) => (Some(n.trim()), v.trim()),
            None => (None, entry.trim()),
        };
        let mm = value
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && (0.0..=MAX_THICKNESS_MM).contains(v));
        let Some(mm) = mm else {
            eprintln!(
                "error: --thickness-mm {}: `{}` is not a thickness\n  = help: give MATERIAL=MM or MM with MM from 0 to {MAX_THICKNESS_MM}, e.g. --thickness-mm tantalum=1,soft_tissue=100\n\nrsasim: 1 error(s); nothing was written",
                rsasim::diagnostic::cut(entry),
                rsasim::diagnostic::cut(value)
            );
            return Err(2);
        };
        match name {
            Some(n) => {
                if !named.iter().any(|(x, t)| x == n && *t == mm) {
                    named.push((n.to_string(), mm));
                }
            }
            None => all_mm = mm,
        }
    }
    let mut out: Vec<(String, f64)> = scene
        .iter()
        .filter(|n| !named.iter().any(|(x, _)| x == *n))
        .map(|n| (n.clone(), all_mm))
        .collect();
    out.extend(named);
    Ok(out)
}

/// Refuses (exit 2) a target that exists and is not a regular file starting with `mark` (an
/// earlier file of this command, which is replaced).
fn check_target(path: &Path, mark: &str) -> Result<(), u8> {
    let refuse = |why: String| {
        eprintln!(
            "error: {}: {why}; it is left as it is\n  = help: give a new file\n\nrsasim: 1 error(s); nothing was written",
            path.display()
        );
        2
    };
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(refuse(format!("cannot check it: {e}"))),
        Ok(meta) if !meta.is_file() => {
            Err(refuse("is not a regular file (a folder or a link)".into()))
        }
        Ok(_) => {
            let mut head = vec![0u8; 256];
            let n = std::fs::File::open(path)
                .and_then(|mut f| std::io::Read::read(&mut f, &mut head))
                .unwrap_or(0);
            if head[..n].starts_with(mark.as_bytes()) {
                Ok(())
            } else {
                Err(refuse(
                    "exists and is not a file rsasim spectrum wrote".into(),
                ))
            }
        }
    }
}

/// Writes `bytes` into `path` atomically (its folder made if missing); exit 1 on failure.
fn write(path: &Path, bytes: &[u8]) -> Outcome {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or(Ok(()), std::fs::create_dir_all)
        .and_then(|()| rsasim::output::atomic::write_atomic(path, bytes))
        .map_err(|e| {
            eprintln!("error: writing {} failed: {e}", path.display());
            1
        })?;
    eprintln!("rsasim spectrum: -> {}", path.display());
    Ok(())
}

/// Photons in words: per mm² per mAs at 1000 mm for a tube, else relative.
fn photon_unit(beam: &Beamline) -> &'static str {
    if beam.absolute {
        "photons per bin per mm² per mAs at 1000 mm"
    } else {
        "relative photons per bin"
    }
}

fn text(scenario: &Path, beam: &Beamline) -> String {
    let mut out = format!("rsasim spectrum: {}\n", scenario.display());
    out += &format!("source: {}\n", beam.source);
    out += &format!(
        "bins: {} in the spectrum, {} traced for the images, within {:.3} % for a layer of one material down to 0.1 % transmission\n",
        beam.filtered.energies_kev.len(),
        beam.traced_bins.len(),
        beam.spectral_tolerance * 100.0
    );
    out += &format!("mean energy: {:.3} keV\n", beam.mean_energy_kev);
    out += &format!(
        "half-value layers: HVL1 {:.4} mm Al, HVL2 {:.4} mm Al\n",
        beam.hvl1_mm_al, beam.hvl2_mm_al
    );
    if let (Some(f), Some(k)) = (beam.fluence_per_mm2_per_mas, beam.air_kerma_ugy_per_mas) {
        out += &format!("fluence: {f:.6e} photons per mm² per mAs at 1000 mm\n");
        out += &format!("air kerma: {k:.4} µGy per mAs at 1000 mm\n");
    }
    out += &format!(
        "detector: {}, {}\n",
        match beam.response {
            ResponseKind::EnergyIntegrating => "energy integrating",
            ResponseKind::PhotonCounting => "photon counting",
        },
        match &beam.scintillator {
            Some((m, t)) => format!("{t} mm {m}"),
            None => "ideal absorber".into(),
        }
    );
    let edges: Vec<String> = beam
        .edges
        .iter()
        .map(|e| {
            format!(
                "{} {} {} keV ({})",
                e.element, e.shell, e.energy_kev, e.material
            )
        })
        .collect();
    out += &format!(
        "edges in the spectrum: {}\n",
        if edges.is_empty() {
            "none".into()
        } else {
            edges.join(", ")
        }
    );
    out += "\ntransmission as the detector weighs it:\n";
    out += "material\tthickness_mm\ttraced\tall_bins\ttraced_vs_all_percent\n";
    for t in &beam.transmissions {
        let diff = if t.all_bins > 0.0 {
            format!("{:+.3}", (t.traced / t.all_bins - 1.0) * 100.0)
        } else {
            "-".into()
        };
        out += &format!(
            "{}\t{}\t{:.6e}\t{:.6e}\t{diff}\n",
            t.material, t.thickness_mm, t.traced, t.all_bins
        );
    }
    out += &format!(
        "\ntraced bins ({}):\nenergy_kev\tphotons\n",
        photon_unit(beam)
    );
    for [e, n] in &beam.traced_bins {
        out += &format!("{e:.4}\t{n:.6e}\n");
    }
    out
}

fn tsv(title: &str, beam: &Beamline) -> String {
    let mut out = format!(
        "{TSV_MARK}: {title}; rsasim {}\n",
        rsasim::build_info::VERSION_LINE
    );
    out += &format!(
        "# {}; detector_absorption: the scintillator's absorbed fraction (1: an ideal absorber)\n",
        photon_unit(beam)
    );
    out += "energy_kev\tphotons_unfiltered\tphotons_filtered\tdetector_absorption\n";
    let rows = beam
        .filtered
        .energies_kev
        .iter()
        .zip(&beam.unfiltered.photons)
        .zip(&beam.filtered.photons)
        .zip(beam.efficiency());
    for (((e, n0), n), eta) in rows {
        out += &format!("{e}\t{n0:.7e}\t{n:.7e}\t{eta:.7e}\n");
    }
    out
}
