//! Semantic checks on the scenario records: everything that can be judged without opening a
//! mesh file or tracing a ray. Every finding is located at its key path.

use std::collections::HashSet;

use super::*;
use crate::diagnostic::{Diagnostic, KeyPath, Locator, cut};

/// Largest pixel count per axis (16-bit TIFF dimensions stay well within this).
const MAX_PIXELS_PER_AXIS: u32 = 65_535;

/// The finest pixel pitch a detector may have, mm (1 µm: the finest X-ray detectors have
/// pixels of a few µm).
pub const MIN_PIXEL_PITCH_MM: f64 = 1e-3;

/// Longest id, in bytes. Ids name files and folders: `<exposure>-<detector>.tiff` is at most
/// 2 × 100 + 6 = 206 bytes, and a scenario name leaves room for staging suffixes, within the
/// 255 bytes per name component that Linux, macOS and Windows file systems allow.
pub const MAX_ID_BYTES: usize = 100;

/// Names Windows reserves for devices, with or without an extension (`CON`, `nul.csv`, `COM1`).
const WINDOWS_RESERVED: &[&str] = &[
    "CON", "PRN", "AUX", "NUL", "COM0", "COM1", "COM2", "COM3", "COM4", "COM5", "COM6", "COM7",
    "COM8", "COM9", "LPT0", "LPT1", "LPT2", "LPT3", "LPT4", "LPT5", "LPT6", "LPT7", "LPT8", "LPT9",
];

/// Why `id` cannot name a file on every common file system, if it cannot.
pub fn id_problem(id: &str) -> Option<String> {
    if id.is_empty() {
        return Some("it is empty".into());
    }
    if let Some(c) = id
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.')))
    {
        return Some(format!("it contains {c:?}"));
    }
    if id.starts_with('.') || id.ends_with('.') {
        return Some("it starts or ends with `.`".into());
    }
    if id.len() > MAX_ID_BYTES {
        return Some(format!(
            "it is {} bytes long, more than {MAX_ID_BYTES}",
            id.len()
        ));
    }
    let stem = id.split('.').next().unwrap_or(id);
    if WINDOWS_RESERVED
        .iter()
        .any(|r| r.eq_ignore_ascii_case(stem))
    {
        return Some(format!("`{stem}` is a device name Windows reserves"));
    }
    None
}

/// All findings on `s`, errors and warnings, in file order of the sections.
pub fn validate(s: &Scenario, loc: &Locator) -> Vec<Diagnostic> {
    let mut v = Checker {
        loc,
        out: Vec::new(),
    };
    let root = KeyPath::root();
    v.id(&root.key("name"), &s.name, "the scenario name");
    v.protocol(&s.protocol);
    if let Some(study) = &s.study {
        v.study(s, study);
    }
    v.sequence(s);
    if s.output.formats.is_empty() {
        v.err(
            root.key("output").key("formats"),
            "no image format is selected",
            "list at least one of \"tiff\", \"exr\", \"dicom\"",
        );
    }
    for (i, f) in s.output.formats.iter().enumerate() {
        if s.output.formats[..i].contains(f) {
            v.err(
                root.key("output").key("formats").index(i),
                format!("\"{}\" is listed twice", f.extension()),
                "list each format once",
            );
        }
    }
    v.unique_ids(
        &root.key("sources"),
        s.sources.iter().map(|x| x.id.as_str()),
        "source",
    );
    v.unique_ids(
        &root.key("detectors"),
        s.detectors.iter().map(|x| x.id.as_str()),
        "detector",
    );
    v.unique_ids(
        &root.key("phantoms"),
        s.phantoms.iter().map(|x| x.id.as_str()),
        "phantom",
    );
    v.unique_ids(
        &root.key("exposures"),
        s.exposures.iter().map(|x| x.id.as_str()),
        "exposure",
    );
    if !v.out.iter().any(Diagnostic::is_error) {
        // Bad or duplicate ids are reported above; only names built from valid ids can collide.
        v.file_names(s);
    }
    v.nonempty(&root.key("sources"), s.sources.len(), "[[sources]]");
    v.nonempty(&root.key("detectors"), s.detectors.len(), "[[detectors]]");
    v.nonempty(&root.key("phantoms"), s.phantoms.len(), "[[phantoms]]");
    v.nonempty(&root.key("exposures"), s.exposures.len(), "[[exposures]]");
    for (i, src) in s.sources.iter().enumerate() {
        let p = root.key("sources").index(i);
        v.finite3(&p.key("position_mm"), src.position_mm);
        v.range3(
            &p.key("randomize").key("position_mm"),
            src.randomize.position_mm,
        );
    }
    let source_ids: Vec<&str> = s.sources.iter().map(|x| x.id.as_str()).collect();
    for (i, d) in s.detectors.iter().enumerate() {
        v.detector(&root.key("detectors").index(i), d, &source_ids);
    }
    for (i, ph) in s.phantoms.iter().enumerate() {
        v.phantom(&root.key("phantoms").index(i), ph);
    }
    let phantom_ids: Vec<&str> = s.phantoms.iter().map(|x| x.id.as_str()).collect();
    let mut used = HashSet::new();
    for (i, e) in s.exposures.iter().enumerate() {
        let p = root.key("exposures").index(i);
        if e.phantoms.is_empty() {
            v.err(
                p.key("phantoms"),
                "the exposure has no phantoms",
                "list the ids of the phantoms in the beam",
            );
        }
        for (k, id) in e.phantoms.iter().enumerate() {
            used.insert(id.as_str());
            if !phantom_ids.contains(&id.as_str()) {
                v.err(
                    p.key("phantoms").index(k),
                    format!("no phantom has the id `{}`", cut(id)),
                    format!("valid phantom ids: {}", quoted(&phantom_ids)),
                );
            }
        }
    }
    for (i, ph) in s.phantoms.iter().enumerate() {
        if !used.contains(ph.id.as_str()) {
            v.warn(
                root.key("phantoms").index(i).key("id"),
                format!(
                    "phantom `{}` appears in no exposure, so no image shows it",
                    ph.id
                ),
            );
        }
    }
    v.out
}

pub(super) fn quoted(ids: &[&str]) -> String {
    ids.iter()
        .map(|s| format!("`{s}`"))
        .collect::<Vec<_>>()
        .join(", ")
}

pub(super) struct Checker<'a> {
    pub(super) loc: &'a Locator,
    pub(super) out: Vec<Diagnostic>,
}

impl Checker<'_> {
    pub(super) fn err(
        &mut self,
        path: KeyPath,
        message: impl Into<String>,
        help: impl Into<String>,
    ) {
        self.out.push(self.loc.error(path, message).with_help(help));
    }

    pub(super) fn warn(&mut self, path: KeyPath, message: impl Into<String>) {
        self.out.push(self.loc.warning(path, message));
    }

    fn nonempty(&mut self, path: &KeyPath, n: usize, what: &str) {
        if n == 0 {
            self.err(
                path.clone(),
                format!("the scenario has no {what}"),
                format!("add at least one {what} table"),
            );
        }
    }

    pub(super) fn id(&mut self, path: &KeyPath, id: &str, what: &str) {
        if let Some(why) = id_problem(id) {
            self.err(
                path.clone(),
                format!("`{}` is not a valid id for {what}: {why}", cut(id)),
                format!(
                    "ids name files: use 1 to {MAX_ID_BYTES} letters, digits, `-`, `_` and `.` \
                     (not first or last), and no Windows device name (CON, NUL, COM1, …)"
                ),
            );
        }
    }

    /// Two files of one folder whose names differ only in letter case collide on macOS and
    /// Windows (and equal names collide everywhere): the image files of each run folder
    /// ([`OutputOptions::image_files`]), and the bead tables and mesh copies in `phantoms/`.
    fn file_names(&mut self, s: &Scenario) {
        let root = KeyPath::root();
        let mut images: Vec<(String, KeyPath)> = Vec::new();
        // A format or intent listed twice is reported at its own key.
        let mut files = Vec::new();
        for f in s.output.image_files() {
            if !files.contains(&f) {
                files.push(f);
            }
        }
        for (ei, e) in s.exposures.iter().enumerate() {
            for d in &s.detectors {
                for f in &files {
                    images.push((
                        f.name(&format!("{}-{}", e.id, d.id)),
                        root.key("exposures").index(ei).key("id"),
                    ));
                }
            }
        }
        self.collisions(
            images,
            "a run folder",
            "images are named `<exposure>-<detector>.<ext>` (DICOM for processing: `<exposure>-<detector>-processing.dcm`)",
        );
        let mut phantom_files: Vec<(String, KeyPath)> = Vec::new();
        for (pi, ph) in s.phantoms.iter().enumerate() {
            let key = root.key("phantoms").index(pi).key("id");
            match (&ph.mesh, &ph.beads, &ph.calibration_box) {
                (Some(m), _, _) => {
                    let ext = std::path::Path::new(&m.file)
                        .extension()
                        .and_then(|e| e.to_str())
                        .unwrap_or("mesh")
                        .to_ascii_lowercase();
                    phantom_files.push((format!("{}.{ext}", ph.id), key.clone()));
                    if !m.beads.is_empty() {
                        phantom_files.push((format!("{}-beads.csv", ph.id), key));
                    }
                }
                (None, Some(_), _) | (None, None, Some(_)) => {
                    phantom_files.push((format!("{}.csv", ph.id), key));
                }
                (None, None, None) => {}
            }
        }
        self.collisions(
            phantom_files,
            "`phantoms/`",
            "bead tables are `<phantom>.csv` (`<phantom>-beads.csv` for a mesh's beads) and meshes `<phantom>.<ext>`",
        );
    }

    fn collisions(&mut self, names: Vec<(String, KeyPath)>, folder: &str, rule: &str) {
        let mut seen: std::collections::HashMap<String, &str> = std::collections::HashMap::new();
        for (name, key) in &names {
            match seen.get(&name.to_ascii_lowercase()) {
                Some(first) => self.err(
                    key.clone(),
                    format!(
                        "two files in {folder} would be named `{}` and `{}`, which are the same \
                         name on case-insensitive file systems (macOS, Windows)",
                        cut(first),
                        cut(name)
                    ),
                    format!("{rule}; rename one of the ids"),
                ),
                None => {
                    seen.insert(name.to_ascii_lowercase(), name);
                }
            }
        }
    }

    pub(super) fn unique_ids<'s>(
        &mut self,
        path: &KeyPath,
        ids: impl Iterator<Item = &'s str>,
        what: &str,
    ) {
        let mut seen = HashSet::new();
        for (i, id) in ids.enumerate() {
            self.id(&path.index(i).key("id"), id, &format!("a {what}"));
            if !seen.insert(id) {
                self.err(
                    path.index(i).key("id"),
                    format!("two {what}s have the id `{}`", cut(id)),
                    format!("give every {what} its own id"),
                );
            }
        }
    }

    pub(super) fn finite3(&mut self, path: &KeyPath, v: [f64; 3]) {
        if v.iter().any(|x| !x.is_finite()) {
            self.err(
                path.clone(),
                format!("{v:?} is not a finite vector"),
                "use three finite numbers [x, y, z]",
            );
        }
    }

    pub(super) fn positive(&mut self, path: &KeyPath, v: &[f64], what: &str) {
        if v.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            self.err(
                path.clone(),
                format!("{what} must be positive, got {v:?}"),
                format!("give a positive {what}"),
            );
        }
    }

    fn range3(&mut self, path: &KeyPath, v: [f64; 3]) {
        if v.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
            self.err(
                path.clone(),
                format!("randomisation half-widths must be finite and ≥ 0, got {v:?}"),
                "each run draws uniformly in [−r, +r]; use 0 for no randomisation",
            );
        }
    }

    fn protocol(&mut self, p: &Protocol) {
        let path = KeyPath::root().key("protocol");
        if p.noise_levels.is_empty() {
            self.err(
                path.key("noise_levels"),
                "no noise levels",
                "the paper uses [0.0, 0.225, 0.45, 0.675, 0.9]",
            );
        }
        for (i, l) in p.noise_levels.iter().enumerate() {
            if !(0.0..=1.0).contains(l) {
                self.err(
                    path.key("noise_levels").index(i),
                    format!("noise level {l} is outside [0, 1]"),
                    "levels are fractions of I_max: 0.45 means a mean background of 45 % of I_max",
                );
            }
        }
        if p.runs_per_level == 0 {
            self.err(
                path.key("runs_per_level"),
                "runs_per_level is 0",
                "use at least 1 (the paper uses 20)",
            );
        }
    }

    fn detector(&mut self, p: &KeyPath, d: &Detector, sources: &[&str]) {
        if !sources.contains(&d.source.as_str()) {
            self.err(
                p.key("source"),
                format!("no source has the id `{}`", d.source),
                format!("valid source ids: {}", quoted(sources)),
            );
        }
        if d.pixels.iter().any(|&n| n == 0 || n > MAX_PIXELS_PER_AXIS) {
            self.err(
                p.key("pixels"),
                format!("pixel counts {:?} are out of range", d.pixels),
                format!("give [columns, rows], each 1..={MAX_PIXELS_PER_AXIS}"),
            );
        }
        // The pitch is a physical size: below MIN_PIXEL_PITCH_MM it is a typo or a hostile file,
        // and would only overflow later (a pixel 1e-300 mm wide has no finite resolution).
        let pitch_problem = |pitch: [f64; 2]| {
            pitch
                .iter()
                .any(|&x| x.is_finite() && x > 0.0 && x < MIN_PIXEL_PITCH_MM)
                .then(|| format!("{:?} mm", pitch))
        };
        match (d.size_mm, d.pixel_pitch_mm) {
            (Some(s), None) => {
                self.positive(&p.key("size_mm"), &s, "detector size");
                let pitch = [
                    s[0] / f64::from(d.pixels[0].max(1)),
                    s[1] / f64::from(d.pixels[1].max(1)),
                ];
                if let Some(shown) = pitch_problem(pitch) {
                    self.err(
                        p.key("size_mm"),
                        format!("size_mm {s:?} over pixels {:?} gives a pixel pitch of {shown}, finer than {MIN_PIXEL_PITCH_MM} mm", d.pixels),
                        format!("X-ray detectors have pixels of about 0.05–1 mm: give size_mm in mm (each side at least {MIN_PIXEL_PITCH_MM} mm per pixel)"),
                    );
                }
            }
            (None, Some(s)) => {
                self.positive(&p.key("pixel_pitch_mm"), &s, "pixel pitch");
                if let Some(shown) = pitch_problem(s) {
                    self.err(
                        p.key("pixel_pitch_mm"),
                        format!("pixel pitch {shown} is finer than {MIN_PIXEL_PITCH_MM} mm"),
                        "X-ray detectors have pixels of about 0.05–1 mm: give the pitch in mm",
                    );
                }
            }
            (Some(_), Some(_)) => self.err(
                p.key("pixel_pitch_mm"),
                "both size_mm and pixel_pitch_mm are given",
                "give only one: the other follows from the pixel counts",
            ),
            (None, None) => self.err(
                p.clone(),
                format!("detector `{}` has neither size_mm nor pixel_pitch_mm", d.id),
                "add size_mm = [width, height] or pixel_pitch_mm = [x, y]",
            ),
        }
        if !(1..=16).contains(&d.bpp) {
            self.err(
                p.key("bpp"),
                format!("bpp {} is out of range", d.bpp),
                "bpp must be 1..=16 (images are stored in 16 bits)",
            );
        }
        self.finite3(&p.key("position_mm"), d.position_mm);
        self.finite3(&p.key("rotation_deg"), d.rotation_deg);
        self.range3(
            &p.key("randomize").key("position_mm"),
            d.randomize.position_mm,
        );
        self.range3(
            &p.key("randomize").key("rotation_deg"),
            d.randomize.rotation_deg,
        );
    }

    fn beads(&mut self, p: &KeyPath, beads: &[Bead]) {
        self.unique_ids(p, beads.iter().map(|b| b.id.as_str()), "bead");
        for (i, b) in beads.iter().enumerate() {
            self.finite3(&p.index(i).key("position_mm"), b.position_mm);
            self.positive(
                &p.index(i).key("diameter_mm"),
                &[b.diameter_mm],
                "bead diameter",
            );
        }
    }

    fn phantom(&mut self, p: &KeyPath, ph: &Phantom) {
        self.finite3(&p.key("position_mm"), ph.position_mm);
        self.finite3(&p.key("rotation_deg"), ph.rotation_deg);
        self.range3(
            &p.key("randomize").key("position_mm"),
            ph.randomize.position_mm,
        );
        self.range3(
            &p.key("randomize").key("rotation_deg"),
            ph.randomize.rotation_deg,
        );
        let shapes = [
            ph.beads.is_some(),
            ph.calibration_box.is_some(),
            ph.mesh.is_some(),
            ph.elliptic_cylinder.is_some(),
        ];
        if shapes.iter().filter(|x| **x).count() != 1 {
            self.err(
                p.clone(),
                format!("phantom `{}` must have exactly one of `beads`, `calibration_box`, `mesh`, `elliptic_cylinder`", ph.id),
                "add [[phantoms.beads]], [phantoms.calibration_box], [phantoms.mesh] or [phantoms.elliptic_cylinder] under this phantom",
            );
            return;
        }
        match ph.shape() {
            PhantomShape::Beads(beads) => {
                if beads.is_empty() {
                    self.err(
                        p.key("beads"),
                        "the bead set is empty",
                        "add [[phantoms.beads]] tables",
                    );
                }
                self.beads(&p.key("beads"), beads);
            }
            PhantomShape::CalibrationBox(b) => self.calibration_box(&p.key("calibration_box"), b),
            PhantomShape::Mesh(m) => {
                if let Some(u) = m.unit_mm {
                    self.positive(&p.key("mesh").key("unit_mm"), &[u], "unit_mm");
                }
                self.beads(&p.key("mesh").key("beads"), &m.beads);
            }
            PhantomShape::EllipticCylinder(e) => {
                let path = p.key("elliptic_cylinder");
                self.positive(&path.key("radii_mm"), &e.radii_mm, "cylinder semi-axis");
                self.positive(&path.key("length_mm"), &[e.length_mm], "cylinder length");
            }
        }
    }

    fn calibration_box(&mut self, p: &KeyPath, b: &CalibrationBox) {
        if b.plates.is_empty() {
            self.err(
                p.key("plates"),
                "the calibration box has no plates",
                "add [[phantoms.calibration_box.plates]] tables",
            );
        }
        self.unique_ids(
            &p.key("plates"),
            b.plates.iter().map(|x| x.id.as_str()),
            "plate",
        );
        for (i, plate) in b.plates.iter().enumerate() {
            let pp = p.key("plates").index(i);
            self.finite3(&pp.key("center_mm"), plate.center_mm);
            self.finite3(&pp.key("rotation_deg"), plate.rotation_deg);
            self.positive(&pp.key("size_mm"), &plate.size_mm, "plate size");
            self.positive(&pp.key("spacing_mm"), &plate.spacing_mm, "bead spacing");
            self.positive(
                &pp.key("bead_diameter_mm"),
                &[plate.bead_diameter_mm],
                "bead diameter",
            );
            if plate.grid.iter().any(|&n| n == 0 || n > 1000) {
                self.err(
                    pp.key("grid"),
                    format!("grid {:?} is out of range", plate.grid),
                    "give [columns, rows], each 1..=1000",
                );
                continue;
            }
            for k in 0..2 {
                let extent =
                    (plate.grid[k] - 1) as f64 * plate.spacing_mm[k] + plate.bead_diameter_mm;
                if extent > plate.size_mm[k] {
                    self.err(
                        pp.key("size_mm"),
                        format!(
                            "the bead grid spans {extent} mm along {} but the plate is {} mm",
                            ["x", "y"][k],
                            plate.size_mm[k]
                        ),
                        "enlarge size_mm, or reduce grid or spacing_mm",
                    );
                }
            }
            if plate.spacing_mm.iter().any(|&s| s < plate.bead_diameter_mm) {
                self.err(
                    pp.key("spacing_mm"),
                    "beads would touch or overlap",
                    "make spacing_mm larger than bead_diameter_mm",
                );
            }
            for (k, o) in plate.omit.iter().enumerate() {
                if o[0] >= plate.grid[0] || o[1] >= plate.grid[1] {
                    self.err(
                        pp.key("omit").index(k),
                        format!("grid position {o:?} is outside the {:?} grid", plate.grid),
                        "omit lists [column, row] pairs, counted from 0",
                    );
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_that_cannot_name_a_file_everywhere_are_refused() {
        for bad in [
            "",
            "a/b",
            "a\\b",
            "a:b",
            "a*b",
            "a?b",
            "a\"b",
            "a<b",
            "a|b",
            "a\tb",
            ".a",
            "a.",
            "a b",
            "CON",
            "con.x",
            "Com1",
            "lpt9.tiff",
            "NUL",
        ] {
            assert!(id_problem(bad).is_some(), "{bad:?} accepted");
        }
        assert!(id_problem(&"a".repeat(MAX_ID_BYTES)).is_none());
        assert!(
            id_problem(&"a".repeat(MAX_ID_BYTES + 1))
                .unwrap()
                .contains("bytes long")
        );
        for good in ["knee", "B1", "det-1_a.b", "CONE", "console", "COM10"] {
            assert_eq!(id_problem(good), None, "{good}");
        }
    }
}
