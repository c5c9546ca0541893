//! Checks on the `[study]` table: segments, exams, loose and missing markers. Every finding is
//! located at its key path, like the rest of [`super::validate`].

use std::collections::HashSet;

use super::validate::{Checker, quoted};
use super::*;
use crate::diagnostic::{KeyPath, cut};

/// The bead ids of a phantom (its free beads or its mesh's beads; a calibration box has none
/// that can be a segment's markers).
pub fn bead_ids(ph: &Phantom) -> Vec<&str> {
    let beads = match (&ph.beads, &ph.mesh) {
        (Some(b), _) => b.as_slice(),
        (None, Some(m)) => m.beads.as_slice(),
        (None, None) => &[],
    };
    beads.iter().map(|b| b.id.as_str()).collect()
}

fn is_zero_range(r: &PoseRange) -> bool {
    r.position_mm
        .iter()
        .chain(&r.rotation_deg)
        .all(|&x| x == 0.0)
}

impl Checker<'_> {
    /// Every finding on the study design `d` of scenario `s`.
    pub(super) fn study(&mut self, s: &Scenario, d: &StudyDesign) {
        let path = KeyPath::root().key("study");
        if self.loc.has(&KeyPath::root().key("protocol")) {
            self.err(
                KeyPath::root().key("protocol"),
                "a scenario with [study] has no [protocol]: every exam of every patient is one run",
                "remove [protocol]; set the noise of every exam with study.noise_level (binary mode) or study.exposure_factor (attenuation mode)",
            );
        }
        if d.patients == 0 {
            self.err(
                path.key("patients"),
                "the study has no patients",
                "give the number of simulated patients, e.g. patients = 20",
            );
        }
        let attenuation = s.imaging.is_attenuation();
        if !(d.noise_level.is_finite() && (0.0..=1.0).contains(&d.noise_level)) {
            self.err(
                path.key("noise_level"),
                format!("noise_level must lie in [0, 1], got {}", d.noise_level),
                "a fraction of I_max, e.g. 0.1",
            );
        } else if attenuation && d.noise_level != 0.0 {
            self.err(
                path.key("noise_level"),
                "noise_level is binary mode's: in attenuation mode noise follows from the photons",
                "remove noise_level; scale the exposure with study.exposure_factor",
            );
        }
        if let Some(f) = d.exposure_factor {
            if !attenuation {
                self.err(
                    path.key("exposure_factor"),
                    "exposure_factor needs attenuation mode",
                    "set [imaging] mode = \"attenuation\", or use study.noise_level",
                );
            } else {
                self.positive(&path.key("exposure_factor"), &[f], "exposure_factor");
            }
        }
        if !(d.migration_spread.is_finite() && (0.0..=1.0).contains(&d.migration_spread)) {
            self.err(
                path.key("migration_spread"),
                format!(
                    "migration_spread must lie in [0, 1], got {}",
                    d.migration_spread
                ),
                "each patient's migration is scaled by 1 + u, u uniform in [−spread, +spread); 0 for none",
            );
        }
        self.segments(s, d, &path.key("segments"));
        self.exams(d, &path.key("exams"));
        self.clinical_failures(s, d, &path);
    }

    fn segments(&mut self, s: &Scenario, d: &StudyDesign, path: &KeyPath) {
        let phantom_ids: Vec<&str> = s.phantoms.iter().map(|p| p.id.as_str()).collect();
        let mut seen = HashSet::new();
        let mut reference: Option<usize> = None;
        let mut implants = 0;
        for (i, g) in d.segments.iter().enumerate() {
            let p = path.index(i);
            if !seen.insert(g.phantom.as_str()) {
                self.err(
                    p.key("phantom"),
                    format!("phantom `{}` is named by two segments", cut(&g.phantom)),
                    "each segment is its own phantom",
                );
            }
            let Some(pi) = s.phantoms.iter().position(|q| q.id == g.phantom) else {
                self.err(
                    p.key("phantom"),
                    format!("no phantom has the id `{}`", cut(&g.phantom)),
                    format!("valid phantom ids: {}", quoted(&phantom_ids)),
                );
                continue;
            };
            let ph = &s.phantoms[pi];
            if ph.calibration_box.is_some() {
                self.err(
                    p.key("phantom"),
                    format!("`{}` is the calibration box, not a segment", ph.id),
                    "name the bone (reference) and implant phantoms",
                );
                continue;
            }
            let beads = bead_ids(ph);
            if let Some(markers) = &g.markers {
                let mut once = HashSet::new();
                for (k, m) in markers.iter().enumerate() {
                    if !beads.contains(&m.as_str()) {
                        self.err(
                            p.key("markers").index(k),
                            format!("phantom `{}` has no bead `{}`", ph.id, cut(m)),
                            format!("its beads: {}", quoted(&beads)),
                        );
                    } else if !once.insert(m.as_str()) {
                        self.err(
                            p.key("markers").index(k),
                            format!("bead `{}` is listed twice", cut(m)),
                            "list each marker once",
                        );
                    }
                }
            }
            let markers = g.markers.as_ref().map_or(beads.len(), Vec::len);
            match g.role {
                SegmentRole::Reference => {
                    if reference.is_some() {
                        self.err(
                            p.key("role"),
                            "a second reference segment",
                            "a study has exactly one reference segment (the bone); the others are implants",
                        );
                    }
                    reference = Some(pi);
                    if g.mtpm_points_mm.is_some() {
                        self.err(
                            p.key("mtpm_points_mm"),
                            "mtpm_points_mm belongs to an implant segment",
                            "remove it here; the MTPM is the implant's",
                        );
                    }
                    if let Some(f) = &g.anatomical_frame {
                        self.finite3(&p.key("anatomical_frame").key("position_mm"), f.position_mm);
                        self.finite3(
                            &p.key("anatomical_frame").key("rotation_deg"),
                            f.rotation_deg,
                        );
                    }
                }
                SegmentRole::Implant => {
                    implants += 1;
                    if g.anatomical_frame.is_some() {
                        self.err(
                            p.key("anatomical_frame"),
                            "the anatomical frame belongs to the reference segment",
                            "move anatomical_frame to the segment with role = \"reference\"",
                        );
                    }
                    if ph.fixed_to.is_some() {
                        self.err(
                            KeyPath::root().key("phantoms").index(pi).key("fixed_to"),
                            format!(
                                "implant segment `{}` is fixed_to another phantom",
                                ph.id
                            ),
                            "remove fixed_to: an implant rides on the reference segment by itself (its position_mm/rotation_deg place it at the reference's nominal pose) and migrates relative to it",
                        );
                    }
                    if !is_zero_range(&ph.randomize) {
                        self.err(
                            KeyPath::root().key("phantoms").index(pi).key("randomize"),
                            format!("implant segment `{}` has random ranges of its own", ph.id),
                            "remove them: the implant moves with the reference segment, whose randomize is the patient's repositioning",
                        );
                    }
                    match &g.mtpm_points_mm {
                        Some(points) if points.is_empty() => self.err(
                            p.key("mtpm_points_mm"),
                            "no MTPM points",
                            "give points at the implant's extremities, or leave the key out to use its markers",
                        ),
                        Some(points) => {
                            for (k, q) in points.iter().enumerate() {
                                self.finite3(&p.key("mtpm_points_mm").index(k), *q);
                            }
                        }
                        None if markers == 0 => self.err(
                            p.key("phantom"),
                            format!(
                                "implant segment `{}` has no markers, so its MTPM has no points",
                                ph.id
                            ),
                            "give mtpm_points_mm: fictive points at the implant's extremities, in its local frame",
                        ),
                        None => {}
                    }
                }
            }
        }
        let Some(reference) = reference else {
            self.err(
                path.clone(),
                "the study has no reference segment",
                "give one segment role = \"reference\" (the bone migration is measured against)",
            );
            return;
        };
        if implants == 0 {
            self.err(
                path.clone(),
                "the study has no implant segment",
                "give at least one segment role = \"implant\"",
            );
        }
        // The reference segment must not hang on an implant: an implant's migration would move
        // the bone it is measured against.
        let mut k = reference;
        for _ in 0..s.phantoms.len() {
            let Some(parent) = s.phantoms[k]
                .fixed_to
                .as_ref()
                .and_then(|id| s.phantoms.iter().position(|q| &q.id == id))
            else {
                break;
            };
            if d.implants().any(|g| g.phantom == s.phantoms[parent].id) {
                self.err(
                    KeyPath::root().key("phantoms").index(k).key("fixed_to"),
                    format!(
                        "the reference segment `{}` is fixed to implant `{}`",
                        s.phantoms[reference].id, s.phantoms[parent].id
                    ),
                    "fix the bone's meshes and markers to the bone (or the limb), never to the implant",
                );
                break;
            }
            k = parent;
        }
    }

    fn exams(&mut self, d: &StudyDesign, path: &KeyPath) {
        if d.exams.is_empty() {
            self.err(
                path.clone(),
                "the study has no exams",
                "list the exams in time order, e.g. postop (reference = true), double, 3m, 1y, 2y",
            );
            return;
        }
        self.unique_ids(path, d.exams.iter().map(|e| e.id.as_str()), "exam");
        let references = d.exams.iter().filter(|e| e.reference).count();
        if references != 1 {
            self.err(
                path.clone(),
                format!("{references} exams are marked reference = true"),
                "mark exactly one exam (the postoperative one) reference = true",
            );
        }
        for (i, e) in d.exams.iter().enumerate() {
            let p = path.index(i);
            if i > 0 && e.days < d.exams[i - 1].days {
                self.err(
                    p.key("days"),
                    format!(
                        "exam `{}` is on day {}, before the exam listed above it (day {})",
                        e.id,
                        e.days,
                        d.exams[i - 1].days
                    ),
                    "list the exams in time order",
                );
            }
            for (key, v) in [
                ("translation_mm", e.translation_mm),
                ("rotation_deg", e.rotation_deg),
            ] {
                let Some(v) = v else { continue };
                self.finite3(&p.key(key), v);
                if e.reference {
                    self.err(
                        p.key(key),
                        "the reference exam has no migration",
                        "migration is measured from the reference exam: remove the key",
                    );
                } else if e.double_of.is_some() {
                    self.err(
                        p.key(key),
                        "a double examination has the migration of the exam it repeats",
                        "remove the key",
                    );
                }
            }
            if let Some(of) = &e.double_of {
                match d.exam_index(of) {
                    Some(j) if j < i => {
                        if d.exams[j].days != e.days {
                            self.warn(
                                p.key("days"),
                                format!(
                                    "double examination `{}` is on day {}, exam `{}` on day {}: a double is taken at the same visit",
                                    e.id, e.days, d.exams[j].id, d.exams[j].days
                                ),
                            );
                        }
                    }
                    _ => self.err(
                        p.key("double_of"),
                        format!("no exam listed before `{}` has the id `{}`", e.id, cut(of)),
                        "a double examination repeats an earlier exam of the list",
                    ),
                }
                if e.reference {
                    self.err(
                        p.key("reference"),
                        "a double examination cannot be the reference exam",
                        "mark the exam it repeats reference = true",
                    );
                }
            }
        }
    }

    fn clinical_failures(&mut self, s: &Scenario, d: &StudyDesign, path: &KeyPath) {
        let exam_ids: Vec<&str> = d.exams.iter().map(|e| e.id.as_str()).collect();
        let segment_ids: Vec<&str> = d.segments.iter().map(|g| g.phantom.as_str()).collect();
        for (i, l) in d.loose_markers.iter().enumerate() {
            let p = path.key("loose_markers").index(i);
            self.patient(&p.key("patient"), l.patient, d.patients);
            if !segment_ids.contains(&l.phantom.as_str()) {
                self.err(
                    p.key("phantom"),
                    format!("`{}` is not a segment of the study", cut(&l.phantom)),
                    format!(
                        "a loose marker moves relative to its segment: {}",
                        quoted(&segment_ids)
                    ),
                );
            } else {
                self.bead_of(s, &p.key("bead"), &l.phantom, &l.bead);
            }
            if !exam_ids.contains(&l.from_exam.as_str()) {
                self.err(
                    p.key("from_exam"),
                    format!("no exam has the id `{}`", cut(&l.from_exam)),
                    format!("valid exam ids: {}", quoted(&exam_ids)),
                );
            }
            self.finite3(&p.key("displacement_mm"), l.displacement_mm);
            if d.loose_markers[..i]
                .iter()
                .any(|o| o.patient == l.patient && o.phantom == l.phantom && o.bead == l.bead)
            {
                self.err(
                    p.key("bead"),
                    format!(
                        "bead `{}` of patient {} is loose twice",
                        cut(&l.bead),
                        l.patient
                    ),
                    "give one loose_markers entry per bead and patient",
                );
            }
        }
        for (i, m) in d.missing_markers.iter().enumerate() {
            let p = path.key("missing_markers").index(i);
            self.patient(&p.key("patient"), m.patient, d.patients);
            if !s.phantoms.iter().any(|q| q.id == m.phantom) {
                let ids: Vec<&str> = s.phantoms.iter().map(|q| q.id.as_str()).collect();
                self.err(
                    p.key("phantom"),
                    format!("no phantom has the id `{}`", cut(&m.phantom)),
                    format!("valid phantom ids: {}", quoted(&ids)),
                );
                continue;
            }
            for (k, b) in m.beads.iter().enumerate() {
                self.bead_of(s, &p.key("beads").index(k), &m.phantom, b);
                let loose = d
                    .loose_markers
                    .iter()
                    .any(|l| l.patient == m.patient && l.phantom == m.phantom && &l.bead == b);
                if loose {
                    self.err(
                        p.key("beads").index(k),
                        format!(
                            "bead `{}` of patient {} is both missing and loose",
                            cut(b),
                            m.patient
                        ),
                        "remove it from one of the two lists",
                    );
                }
            }
        }
    }

    fn patient(&mut self, path: &KeyPath, patient: u32, patients: u32) {
        if patient == 0 {
            self.err(
                path.clone(),
                "there is no patient 0",
                format!("patients are numbered from 1 (p01, p02, …) to {patients}"),
            );
        } else if patient > patients {
            // Not an error: a study run with fewer patients keeps its design (prefix-stable).
            self.warn(
                path.clone(),
                format!("there is no patient {patient} (the study has {patients}): this entry changes nothing"),
            );
        }
    }

    fn bead_of(&mut self, s: &Scenario, path: &KeyPath, phantom: &str, bead: &str) {
        let Some(ph) = s.phantoms.iter().find(|q| q.id == phantom) else {
            return;
        };
        let beads = bead_ids(ph);
        if !beads.contains(&bead) {
            self.err(
                path.clone(),
                format!("phantom `{phantom}` has no bead `{}`", cut(bead)),
                format!("its beads: {}", quoted(&beads)),
            );
        }
    }
}
