//! Checks of the image model's keys: `[imaging]`, `[materials]`, the phantoms' `material`,
//! `bead_material`, plate `thickness_mm`, and the `fixed_to` / `inside` relations. Every
//! finding is located at its key path; a key that only attenuation mode reads, given in binary
//! mode, is a warning (it is ignored there).

use super::*;
use crate::diagnostic::{Diagnostic, KeyPath, Locator, cut};
use crate::material;

/// Most photons per pixel: beyond this a 16-bit detector saturates by orders of magnitude and
/// the Poisson sampler's counts leave the exactly representable range of its arithmetic.
const MAX_PHOTONS_PER_PIXEL: f64 = 1e12;

/// Rays per pixel (pixel samples × focal-spot sub-sources) above which `validate` warns about
/// the cost.
const RAYS_PER_PIXEL_WARNING: u64 = 256;

/// Most rays per pixel side (`pixel_samples`) and sub-sources per focal-spot axis (`samples`).
pub const MAX_SAMPLES_PER_SIDE: u32 = 16;

/// All findings on the image model of `s`.
pub fn check(s: &Scenario, loc: &Locator) -> Vec<Diagnostic> {
    let mut c = Check {
        s,
        loc,
        out: Vec::new(),
    };
    c.user_materials();
    c.relations();
    c.sampling();
    if s.imaging.is_attenuation() {
        c.attenuation();
    } else {
        c.binary();
    }
    c.out
}

struct Check<'a> {
    s: &'a Scenario,
    loc: &'a Locator,
    out: Vec<Diagnostic>,
}

fn root() -> KeyPath {
    KeyPath::root()
}

impl Check<'_> {
    fn err(&mut self, path: KeyPath, message: impl Into<String>, help: impl Into<String>) {
        self.out.push(self.loc.error(path, message).with_help(help));
    }

    fn warn(&mut self, path: KeyPath, message: impl Into<String>) {
        self.out.push(self.loc.warning(path, message));
    }

    /// Whether the user wrote the key (not only got its default).
    fn written(&self, path: &KeyPath) -> bool {
        self.loc.has(path)
    }

    fn positive(&mut self, path: KeyPath, v: f64, what: &str, help: &str) {
        if !(v.is_finite() && v > 0.0) {
            self.err(
                path,
                format!("{what} must be a positive number, got {v}"),
                help,
            );
        }
    }

    /// Whether `name` is a library or user material.
    fn known(&self, name: &str) -> bool {
        self.s.materials.contains_key(name) || material::by_name(name).is_some()
    }

    fn material_name(&mut self, path: KeyPath, name: &str) {
        if !self.known(name) {
            let mut names: Vec<String> =
                material::library().iter().map(|m| m.name.clone()).collect();
            names.extend(self.s.materials.keys().cloned());
            self.err(
                path,
                format!("no material is named `{}`", cut(name)),
                format!(
                    "use one of {}, or define it under [materials.{}]",
                    names.join(", "),
                    if super::validate::id_problem(name).is_none() {
                        name
                    } else {
                        "<name>"
                    }
                ),
            );
        }
    }

    fn user_materials(&mut self) {
        for (name, m) in &self.s.materials {
            let path = root().key("materials").key(name);
            if material::by_name(name).is_some() {
                self.err(
                    path.clone(),
                    format!("`{name}` is already a material of the shipped library"),
                    "give your material another name (the library's cannot be redefined)",
                );
            }
            if let Some(why) = super::validate::id_problem(name) {
                self.err(
                    path.clone(),
                    format!("`{}` is not a valid material name: {why}", cut(name)),
                    "use letters, digits, `-`, `_` and `.`",
                );
            }
            let fractions: Vec<(&str, f64)> = m
                .composition
                .iter()
                .map(|(k, v)| (k.as_str(), *v))
                .collect();
            if let Err(why) = material::Material::mixture(name, m.density_g_cm3, &fractions) {
                self.err(
                    path.key("composition"),
                    why,
                    "give the density in g/cm³ and mass fractions by chemical symbol that add up to 1, e.g. composition = { Ti = 0.90, Al = 0.06, V = 0.04 }",
                );
            }
        }
    }

    /// `fixed_to` and `inside` name another phantom and form no cycle.
    fn relations(&mut self) {
        let ids: Vec<&str> = self.s.phantoms.iter().map(|p| p.id.as_str()).collect();
        let index = |id: &str| ids.iter().position(|x| *x == id);
        for (i, ph) in self.s.phantoms.iter().enumerate() {
            let p = root().key("phantoms").index(i);
            for (key, target) in [("fixed_to", &ph.fixed_to), ("inside", &ph.inside)] {
                let Some(target) = target else { continue };
                match index(target) {
                    None => self.err(
                        p.key(key),
                        format!("no phantom has the id `{}`", cut(target)),
                        format!("valid phantom ids: {}", ids.join(", ")),
                    ),
                    Some(k) if k == i => self.err(
                        p.key(key),
                        format!("phantom `{}` names itself", ph.id),
                        "name another phantom",
                    ),
                    Some(k) => {
                        let follow = |q: &Phantom| -> Option<String> {
                            if key == "fixed_to" {
                                q.fixed_to.clone()
                            } else {
                                q.inside.clone()
                            }
                        };
                        // Walk the chain from the target; coming back to `i` is a cycle.
                        let mut at = k;
                        for _ in 0..ids.len() {
                            match follow(&self.s.phantoms[at]).and_then(|t| index(&t)) {
                                Some(next) if next == i => {
                                    self.err(
                                        p.key(key),
                                        format!(
                                            "`{key}` forms a cycle through phantom `{}`",
                                            ids[k]
                                        ),
                                        "a chain of `{key}` must end at a phantom that names none",
                                    );
                                    break;
                                }
                                Some(next) => at = next,
                                None => break,
                            }
                        }
                        if key == "inside" {
                            let t = &self.s.phantoms[k];
                            if t.mesh.is_none() && t.elliptic_cylinder.is_none() {
                                self.err(
                                    p.key(key),
                                    format!("phantom `{}` has no volume to be inside of", ids[k]),
                                    "`inside` names a mesh or elliptic_cylinder phantom",
                                );
                            }
                        }
                    }
                }
            }
            if ph.fixed_to.is_some() {
                let r = &ph.randomize;
                if r.position_mm
                    .iter()
                    .chain(&r.rotation_deg)
                    .any(|&x| x != 0.0)
                {
                    self.err(
                        p.key("randomize"),
                        format!(
                            "phantom `{}` is fixed to another and cannot be randomised itself",
                            ph.id
                        ),
                        "remove its [randomize] table: it moves with the phantom named in fixed_to",
                    );
                }
            }
        }
    }

    /// `pixel_samples` and `focal_spot` (both modes).
    fn sampling(&mut self) {
        let im = &self.s.imaging;
        let ip = root().key("imaging");
        if let Some(n) = im.pixel_samples {
            if !(1..=MAX_SAMPLES_PER_SIDE).contains(&n) {
                self.err(
                    ip.key("pixel_samples"),
                    format!("pixel_samples = {n} is out of range"),
                    format!("give 1 (one ray to the pixel centre) to {MAX_SAMPLES_PER_SIDE} rays per pixel side; 8 puts 95 % of 1 mm bead centroids within 0.02 px of truth"),
                );
            }
        }
        let Some(f) = &im.focal_spot else { return };
        let fp = ip.key("focal_spot");
        let s = u64::from(im.samples_per_side());
        let k = u64::from(f.samples);
        let rays = s * s * k * k;
        if rays > RAYS_PER_PIXEL_WARNING && k <= u64::from(MAX_SAMPLES_PER_SIDE) {
            self.warn(
                fp.key("samples"),
                format!("{rays} rays per pixel ({s}×{s} pixel samples × {k}×{k} sub-sources): each image costs about {rays} times one ray per pixel"),
            );
        }
        if !(f.size_mm.is_finite() && f.size_mm > 0.0 && f.size_mm <= 10.0) {
            self.err(
                fp.key("size_mm"),
                format!("focal spot size {} mm is out of range", f.size_mm),
                "give the spot's width in mm, above 0 and at most 10 (IEC 60336 nominal sizes: 0.3, 0.6, 1.0, 1.2)",
            );
        }
        if !(1..=MAX_SAMPLES_PER_SIDE).contains(&f.samples) {
            self.err(
                fp.key("samples"),
                format!("samples = {} is out of range", f.samples),
                format!(
                    "give 1 to {MAX_SAMPLES_PER_SIDE} sub-sources per axis (k×k in all), e.g. 3"
                ),
            );
        }
        if let Some(h) = f.heel_percent_per_100_mm {
            if !(h.is_finite() && (-50.0..=50.0).contains(&h)) {
                self.err(
                    fp.key("heel_percent_per_100_mm"),
                    format!("heel gradient {h} % per 100 mm is out of range"),
                    "give the fall of the fluence towards the anode in percent per 100 mm, from −50 to 50 (clinical tubes: about 5–15)",
                );
            }
        }
        if let Some(p) = f.intensity_fall_percent {
            if !(p.is_finite() && (0.0..100.0).contains(&p)) {
                self.err(
                    fp.key("intensity_fall_percent"),
                    format!("a fall of the spot's emission of {p} % is out of range"),
                    "give how many percent the emission falls from the spot's cathode-side edge to its anode-side edge, from 0 (a symmetric spot) to below 100",
                );
            }
        }
        if !im.is_attenuation() {
            // The spot's fall is imaged in both modes, and takes its direction from
            // anode_direction.
            let direction_used = f.intensity_fall_percent.is_some_and(|p| p != 0.0);
            for (key, given) in [
                (
                    "heel_percent_per_100_mm",
                    f.heel_percent_per_100_mm.is_some(),
                ),
                (
                    "anode_direction",
                    f.anode_direction.is_some() && !direction_used,
                ),
            ] {
                if given {
                    self.warn(
                        fp.key(key),
                        format!("imaging.focal_spot.{key} applies to mode = \"attenuation\" only and is ignored in binary mode"),
                    );
                }
            }
        }
    }

    /// Binary mode: keys only attenuation mode reads are ignored (a warning each).
    fn binary(&mut self) {
        let im = &self.s.imaging;
        let imaging_keys = [
            ("energy_kev", im.energy_kev.is_some()),
            ("tube", im.tube.is_some()),
            ("spectrum_file", im.spectrum_file.is_some()),
            ("max_energy_bins", im.max_energy_bins.is_some()),
            ("spectral_tolerance", im.spectral_tolerance.is_some()),
            ("photons_per_pixel", im.photons_per_pixel.is_some()),
            ("mas", im.mas.is_some()),
            ("detector", !im.detector.is_default()),
            ("path_length_layers", im.path_length_layers),
            ("ray_sampling", im.ray_sampling.is_some()),
        ];
        for (key, given) in imaging_keys {
            if given {
                self.warn(
                    root().key("imaging").key(key),
                    format!("imaging.{key} applies to mode = \"attenuation\" only and is ignored in binary mode"),
                );
            }
        }
        if self.s.protocol.exposure_levels.is_some() {
            self.err(
                root().key("protocol").key("exposure_levels"),
                "exposure_levels apply to attenuation mode; binary mode has noise_levels",
                "set [imaging] mode = \"attenuation\", or use protocol.noise_levels",
            );
        }
        for (i, ph) in self.s.phantoms.iter().enumerate() {
            let p = root().key("phantoms").index(i);
            for (key, given) in [
                ("material", ph.material.is_some()),
                ("bead_material", ph.bead_material.is_some()),
                ("inside", ph.inside.is_some()),
            ] {
                if given {
                    self.warn(
                        p.key(key),
                        format!("phantoms.{key} applies to [imaging] mode = \"attenuation\" only and is ignored in binary mode"),
                    );
                }
            }
        }
    }

    fn attenuation(&mut self) {
        let im = &self.s.imaging;
        let ip = root().key("imaging");
        let sources = [
            im.energy_kev.is_some(),
            im.tube.is_some(),
            im.spectrum_file.is_some(),
        ];
        if sources.iter().filter(|x| **x).count() != 1 {
            self.err(
                ip.clone(),
                "attenuation mode needs exactly one of imaging.energy_kev, imaging.tube and imaging.spectrum_file",
                "e.g. [imaging.tube] kvp = 90, filtration = [{ material = \"aluminium\", thickness_mm = 2.5 }]",
            );
        }
        if let Some(e) = im.energy_kev {
            if !(e.is_finite()
                && (material::ENERGY_MIN_KEV..=material::ENERGY_MAX_KEV).contains(&e))
            {
                self.err(
                    ip.key("energy_kev"),
                    format!("energy {e} keV is outside the attenuation tables"),
                    format!(
                        "give an energy from {} to {} keV",
                        material::ENERGY_MIN_KEV,
                        material::ENERGY_MAX_KEV
                    ),
                );
            }
        }
        if let Some(t) = &im.tube {
            let tp = ip.key("tube");
            if !(t.kvp.is_finite() && t.kvp.fract() == 0.0 && (40.0..=150.0).contains(&t.kvp)) {
                self.err(
                    tp.key("kvp"),
                    format!("{} kVp is not a tube voltage of the shipped spectra", t.kvp),
                    "give a whole number of kV from 40 to 150",
                );
            }
            self.positive(
                tp.key("anode_angle_deg"),
                t.anode_angle_deg,
                "the anode angle",
                "anode angles of X-ray tubes are about 6–22°",
            );
            for (k, f) in t.filtration.iter().enumerate() {
                let fp = tp.key("filtration").index(k);
                self.material_name(fp.key("material"), &f.material);
                if !(f.thickness_mm.is_finite() && f.thickness_mm >= 0.0) {
                    self.err(
                        fp.key("thickness_mm"),
                        format!("filter thickness {} mm is not a length", f.thickness_mm),
                        "give a thickness ≥ 0 mm",
                    );
                }
            }
        }
        match (im.photons_per_pixel, im.mas) {
            (Some(n), None) => {
                if !(n.is_finite() && n > 0.0 && n <= MAX_PHOTONS_PER_PIXEL) {
                    self.err(
                        ip.key("photons_per_pixel"),
                        format!("{n} photons per pixel is out of range"),
                        format!("give a number above 0 and at most {MAX_PHOTONS_PER_PIXEL:e} (clinical flat panels get about 10³–10⁴)"),
                    );
                }
            }
            (None, Some(m)) => {
                self.positive(
                    ip.key("mas"),
                    m,
                    "mas",
                    "give the tube current-time product in mAs, e.g. 5",
                );
                if im.tube.is_none() {
                    self.err(
                        ip.key("mas"),
                        "mas needs a tube spectrum (its output per mAs)",
                        "add [imaging.tube], or give photons_per_pixel instead",
                    );
                }
            }
            _ => self.err(
                ip.clone(),
                "attenuation mode needs exactly one of imaging.photons_per_pixel and imaging.mas",
                "e.g. photons_per_pixel = 5000 (expected photons per pixel with no object)",
            ),
        }
        if let Some(b) = im.max_energy_bins {
            if !(1..=1000).contains(&b) {
                self.err(
                    ip.key("max_energy_bins"),
                    format!("max_energy_bins {b} is out of range"),
                    "give 1 to 1000 (the default 40 keeps a tube spectrum's mean energy and HVL)",
                );
            }
        }
        if let Some(t) = im.spectral_tolerance {
            if !(t.is_finite() && t > 0.0 && t < 1.0) {
                self.err(
                    ip.key("spectral_tolerance"),
                    format!("spectral_tolerance {t} is out of range"),
                    "give a relative error above 0 and below 1, e.g. 0.001 (the default)",
                );
            }
        }
        let d = &im.detector;
        let dp = ip.key("detector");
        if let Some(sc) = &d.scintillator {
            self.material_name(dp.key("scintillator").key("material"), &sc.material);
            self.positive(
                dp.key("scintillator").key("thickness_mm"),
                sc.thickness_mm,
                "the scintillator thickness",
                "e.g. 0.6 mm of CsI",
            );
        }
        if let Some(g) = d.gain {
            self.positive(
                dp.key("gain"),
                g,
                "the gain",
                "digital units per keV (energy integrating) or per photon (photon counting)",
            );
        }
        if let Some(w) = d.white_level {
            if !(w > 0.0 && w <= 1.0) {
                self.err(
                    dp.key("white_level"),
                    format!("white_level {w} is outside (0, 1]"),
                    "the open field reads white_level · I_max, e.g. 0.8",
                );
            }
        }
        if let Some(o) = d.offset {
            if !(o.is_finite() && o >= 0.0 && o < 65535.0) {
                self.err(
                    dp.key("offset"),
                    format!("offset {o} is out of range"),
                    "give a dark offset in digital units, 0 or more and below I_max",
                );
            }
        }
        if let Some(r) = d.radiograph_range {
            self.positive(
                dp.key("radiograph_range"),
                r,
                "radiograph_range",
                "the attenuation ln(S_open/S) shown white, e.g. 7",
            );
        }
        self.detector_blur();
        let pp = root().key("protocol");
        if self.written(&pp.key("noise_levels")) {
            self.err(
                pp.key("noise_levels"),
                "noise_levels are the binary mode's; in attenuation mode the noise follows from the photons",
                "use protocol.exposure_levels = [factors on the exposure], e.g. [4.0, 1.0, 0.25]",
            );
        }
        if let Some(levels) = &self.s.protocol.exposure_levels {
            if levels.is_empty() {
                self.err(
                    pp.key("exposure_levels"),
                    "no exposure levels",
                    "give at least one factor, e.g. [1.0]",
                );
            }
            for (k, &f) in levels.iter().enumerate() {
                if !(f.is_finite() && f > 0.0 && f <= 1e6) {
                    self.err(
                        pp.key("exposure_levels").index(k),
                        format!("exposure factor {f} is out of range"),
                        "each factor multiplies the exposure: give a number above 0 (at most 10⁶)",
                    );
                }
            }
        }
        for (i, ph) in self.s.phantoms.iter().enumerate() {
            self.phantom(root().key("phantoms").index(i), ph);
        }
    }

    /// `[imaging.detector]`: psf, mtf, scatter, electronic noise.
    fn detector_blur(&mut self) {
        let d = &self.s.imaging.detector;
        let dp = root().key("imaging").key("detector");
        if d.psf.is_some() && d.mtf.is_some() {
            self.err(
                dp.key("mtf"),
                "give the detector blur once: psf or mtf, not both",
                "keep psf = { sigma_mm = … } for a Gaussian, or mtf = [[0.0, 1.0], …] for a measured MTF",
            );
        }
        if let Some(p) = &d.psf {
            if !(p.sigma_mm.is_finite() && p.sigma_mm > 0.0 && p.sigma_mm <= 10.0) {
                self.err(
                    dp.key("psf").key("sigma_mm"),
                    format!("PSF sigma {} mm is out of range", p.sigma_mm),
                    "give the Gaussian's SD on the detector in mm, above 0 and at most 10 (CsI flat panels: about 0.1–0.2)",
                );
            }
        }
        if let Some(rows) = &d.mtf {
            let mp = dp.key("mtf");
            let help = "rows [cycles_per_mm, value]: the first [0.0, 1.0], frequencies ascending, values from 0 to 1, e.g. [[0.0, 1.0], [1.0, 0.7], [2.0, 0.35], [3.0, 0.15]]";
            if rows.len() < 2 {
                self.err(
                    mp.clone(),
                    format!("the MTF has {} row(s)", rows.len()),
                    help,
                );
            } else if rows[0] != [0.0, 1.0] {
                self.err(
                    mp.index(0),
                    format!("the MTF starts at [{}, {}]", rows[0][0], rows[0][1]),
                    help,
                );
            }
            for (k, r) in rows.iter().enumerate() {
                let bad = !(r[0].is_finite()
                    && r[0] <= crate::response::psf::MAX_MTF_FREQUENCY
                    && (0.0..=1.0).contains(&r[1]))
                    || (k > 0 && !(r[0] > rows[k - 1][0]));
                if bad {
                    self.err(
                        mp.index(k),
                        format!("MTF row {k} [{}, {}] is not valid", r[0], r[1]),
                        help,
                    );
                    break;
                }
            }
        }
        if let Some(sc) = &d.scatter {
            let sp = dp.key("scatter");
            if !(sc.ratio.is_finite() && (0.0..=10.0).contains(&sc.ratio)) {
                self.err(
                    sp.key("ratio"),
                    format!("scatter-to-primary ratio {} is out of range", sc.ratio),
                    "give a ratio from 0 to 10 (a knee without a grid: about 0.2–0.5)",
                );
            }
            if !(sc.sigma_mm.is_finite() && sc.sigma_mm > 0.0 && sc.sigma_mm <= 1000.0) {
                self.err(
                    sp.key("sigma_mm"),
                    format!("scatter kernel sigma {} mm is out of range", sc.sigma_mm),
                    "give the kernel's SD on the detector in mm, above 0 and at most 1000 (typ. 20–60)",
                );
            }
        }
        if let Some(e) = d.electronic_noise_dn {
            if !(e.is_finite() && (0.0..=65535.0).contains(&e)) {
                self.err(
                    dp.key("electronic_noise_dn"),
                    format!("electronic noise {e} DN is out of range"),
                    "give the read-out noise SD in digital units, from 0 to 65535 (flat panels: a few DN)",
                );
            }
        }
    }

    fn phantom(&mut self, p: KeyPath, ph: &Phantom) {
        let volume = ph.mesh.is_some() || ph.elliptic_cylinder.is_some();
        match (&ph.material, volume) {
            (Some(m), true) => self.material_name(p.key("material"), m),
            (None, true) => self.err(
                p.clone(),
                format!("phantom `{}` needs a material in attenuation mode", ph.id),
                "add e.g. material = \"cocr_f75\" (an implant), \"bone_cortical\" or \"soft_tissue\"",
            ),
            (Some(_), false) => self.warn(
                p.key("material"),
                format!("phantom `{}` has no mesh or cylinder: its material is not used (its beads take bead_material)", ph.id),
            ),
            (None, false) => {}
        }
        if let Some(b) = &ph.bead_material {
            self.material_name(p.key("bead_material"), b);
        }
        if let Some(cb) = &ph.calibration_box {
            for (k, plate) in cb.plates.iter().enumerate() {
                let pp = p.key("calibration_box").key("plates").index(k);
                if let Some(m) = &plate.material {
                    self.material_name(pp.key("material"), m);
                    if plate.thickness_mm.is_none() {
                        self.warn(
                            pp.key("material"),
                            "the plate has no thickness_mm, so no plate material is simulated",
                        );
                    }
                }
                if let Some(t) = plate.thickness_mm {
                    if !(t.is_finite() && t >= plate.bead_diameter_mm) {
                        self.err(
                            pp.key("thickness_mm"),
                            format!("plate thickness {t} mm cannot hold its {} mm beads", plate.bead_diameter_mm),
                            "the beads are embedded in the plate: give a thickness at least the bead diameter (real cages use 5–10 mm of acrylic)",
                        );
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {

    const BASE: &str = r#"
name = "t"
[[sources]]
id = "a"
position_mm = [0, 0, 1000]
[[detectors]]
id = "d"
source = "a"
pixels = [10, 10]
pixel_pitch_mm = [1, 1]
position_mm = [0, 0, -100]
[[exposures]]
id = "e"
phantoms = ["c"]
"#;

    fn messages(extra: &str) -> Vec<String> {
        crate::scenario::messages_of(&format!("{BASE}{extra}"))
    }

    const CYL: &str =
        "[[phantoms]]\nid = \"c\"\nelliptic_cylinder = { radii_mm = [60, 50], length_mm = 200 }\n";

    #[test]
    fn attenuation_needs_a_source_spectrum_an_exposure_and_materials() {
        let m = messages(&format!("[imaging]\nmode = \"attenuation\"\n{CYL}"));
        assert!(
            m.iter()
                .any(|x| x.contains("exactly one of imaging.energy_kev")),
            "{m:?}"
        );
        assert!(
            m.iter()
                .any(|x| x.contains("photons_per_pixel and imaging.mas")),
            "{m:?}"
        );
        assert!(m.iter().any(|x| x.contains("needs a material")), "{m:?}");
    }

    #[test]
    fn a_complete_attenuation_scenario_loads() {
        let m = messages(&format!(
            "[imaging]\nmode = \"attenuation\"\nenergy_kev = 60\nphotons_per_pixel = 1000\n{CYL}material = \"soft_tissue\"\n"
        ));
        assert!(m.is_empty(), "{m:?}");
    }

    #[test]
    fn unknown_materials_are_named_with_the_valid_ones() {
        let m = messages(&format!(
            "[imaging]\nmode = \"attenuation\"\nenergy_kev = 60\nphotons_per_pixel = 1000\n{CYL}material = \"unobtainium\"\n"
        ));
        assert!(
            m.iter()
                .any(|x| x.contains("no material is named `unobtainium`")
                    && x.contains("soft_tissue")
                    && x.contains("s.toml:22:12")),
            "{m:?}"
        );
    }

    #[test]
    fn noise_levels_are_refused_in_attenuation_mode_and_exposure_levels_in_binary_mode() {
        let m = messages(&format!(
            "[protocol]\nnoise_levels = [0.1]\n[imaging]\nmode = \"attenuation\"\nenergy_kev = 60\nphotons_per_pixel = 1000\n{CYL}material = \"water\"\n"
        ));
        assert!(m.iter().any(|x| x.contains("exposure_levels")), "{m:?}");
        // Another [protocol] key alone is not a noise level.
        let m = messages(&format!(
            "[protocol]\nruns_per_level = 2\n[imaging]\nmode = \"attenuation\"\nenergy_kev = 60\nphotons_per_pixel = 1000\n{CYL}material = \"water\"\n"
        ));
        assert!(m.is_empty(), "{m:?}");
        let m = messages(&format!("[protocol]\nexposure_levels = [1.0]\n{CYL}"));
        assert!(
            m.iter().any(|x| x.contains("binary mode has noise_levels")),
            "{m:?}"
        );
    }

    #[test]
    fn attenuation_keys_in_binary_mode_are_warned_about() {
        let m = messages(&format!(
            "[imaging]\nenergy_kev = 60\n{CYL}material = \"water\"\n"
        ));
        assert!(
            m.iter()
                .any(|x| x.starts_with("warning") && x.contains("imaging.energy_kev applies")),
            "{m:?}"
        );
        assert!(
            m.iter()
                .any(|x| x.starts_with("warning") && x.contains("phantoms.material applies")),
            "{m:?}"
        );
    }

    #[test]
    fn fixed_to_and_inside_cycles_and_randomised_fixed_phantoms_are_refused() {
        let two = "[[phantoms]]\nid = \"c\"\nelliptic_cylinder = { radii_mm = [60, 50], length_mm = 200 }\nfixed_to = \"b\"\n[[phantoms]]\nid = \"b\"\nelliptic_cylinder = { radii_mm = [6, 5], length_mm = 20 }\nfixed_to = \"c\"\n[phantoms.randomize]\nposition_mm = [1, 0, 0]\n";
        let m = messages(two);
        assert!(m.iter().any(|x| x.contains("forms a cycle")), "{m:?}");
        assert!(
            m.iter().any(|x| x.contains("cannot be randomised")),
            "{m:?}"
        );
        let m = messages(&format!("{CYL}inside = \"nobody\"\n"));
        assert!(
            m.iter()
                .any(|x| x.contains("no phantom has the id `nobody`")),
            "{m:?}"
        );
    }

    #[test]
    fn user_materials_are_checked_and_cannot_shadow_the_library() {
        let m = messages(&format!(
            "[materials.water]\ndensity_g_cm3 = 1\ncomposition = {{ H = 0.5, O = 0.4 }}\n{CYL}"
        ));
        assert!(
            m.iter()
                .any(|x| x.contains("already a material of the shipped library")),
            "{m:?}"
        );
        assert!(
            m.iter()
                .any(|x| x.contains("materials.water.composition") || x.contains("composition")),
            "{m:?}"
        );
    }

    #[test]
    fn plates_must_be_thick_enough_for_their_beads() {
        let m = messages(
            "[imaging]\nmode = \"attenuation\"\nenergy_kev = 60\nphotons_per_pixel = 1000\n[[phantoms]]\nid = \"c\"\n[[phantoms.calibration_box.plates]]\nid = \"F\"\nrole = \"fiducial\"\ncenter_mm = [0, 0, 0]\nsize_mm = [50, 50]\ngrid = [2, 2]\nspacing_mm = [10, 10]\nthickness_mm = 0.5\n",
        );
        assert!(
            m.iter().any(|x| x.contains("cannot hold its 1 mm beads")),
            "{m:?}"
        );
    }
}
