//! Geometric checks over every run, run by run (memory stays flat with the run count; runs are
//! checked in parallel): each phantom of an exposure must lie between every source and its
//! detector, must show in some image of every run, and should project inside the detectors;
//! every bead should be visible in at least one image.
//!
//! A bead counts as visible in an image when its centre projects inside the detector and the ray
//! from the source through its centre to the detector crosses no mesh of that exposure. In the
//! paper's binary images a bead whose ray crosses a mesh — in front of it or behind it — lies
//! inside the mesh's shadow and cannot be told apart from it (in attenuation mode only a metal
//! mesh hides it: beads show through bone). The ray test uses the tracer's BVH
//! ([`MeshBvh::segment_hits`]).

use std::sync::Arc;

use glam::DVec3;
use rayon::prelude::*;

use crate::diagnostic::{Diagnostic, KeyPath, cut};
use crate::phantom::PhantomModel;
use crate::scenario::{LoadedScenario, PhantomShape};
use crate::trace::MeshBvh;

use super::{Run, run_at};

/// The first run (in protocol order) where something happened, and how often it happened.
#[derive(Debug, Clone, Default)]
struct Tally {
    count: u64,
    first: Option<(u64, String)>,
}

impl Tally {
    fn note(&mut self, index: u64, run_id: &str) {
        self.count += 1;
        if self.first.is_none() {
            self.first = Some((index, run_id.to_string()));
        }
    }

    fn merge(mut self, other: Tally) -> Tally {
        self.count += other.count;
        self.first = match (self.first, other.first) {
            (Some(a), Some(b)) => Some(if a.0 <= b.0 { a } else { b }),
            (a, b) => a.or(b),
        };
        self
    }
}

/// Findings of a range of runs; merged in protocol order.
#[derive(Debug, Clone)]
struct Findings {
    /// Per (phantom, detector): first run where the phantom is not between source and detector.
    misplaced: Vec<Option<(u64, String, String)>>,
    /// Per (phantom, detector): runs where the phantom falls partly outside the field.
    partly_outside: Vec<Tally>,
    /// Per phantom: runs where it lies outside the field of every detector.
    unseen: Vec<Tally>,
    /// Per phantom, per bead: images checked, images where it is outside, hidden by a mesh.
    beads: Vec<Vec<[u64; 3]>>,
}

impl Findings {
    fn new(models: &[PhantomModel], detectors: usize) -> Findings {
        Findings {
            misplaced: vec![None; models.len() * detectors],
            partly_outside: vec![Tally::default(); models.len() * detectors],
            unseen: vec![Tally::default(); models.len()],
            beads: models
                .iter()
                .map(|m| vec![[0; 3]; m.markers.len()])
                .collect(),
        }
    }

    fn merge(mut self, other: Findings) -> Findings {
        for (a, b) in self.misplaced.iter_mut().zip(other.misplaced) {
            *a = match (a.take(), b) {
                (Some(x), Some(y)) => Some(if x.0 <= y.0 { x } else { y }),
                (x, y) => x.or(y),
            };
        }
        self.partly_outside = std::mem::take(&mut self.partly_outside)
            .into_iter()
            .zip(other.partly_outside)
            .map(|(a, b)| a.merge(b))
            .collect();
        self.unseen = std::mem::take(&mut self.unseen)
            .into_iter()
            .zip(other.unseen)
            .map(|(a, b)| a.merge(b))
            .collect();
        for (a, b) in self.beads.iter_mut().zip(other.beads) {
            for (x, y) in a.iter_mut().zip(b) {
                for k in 0..3 {
                    x[k] += y[k];
                }
            }
        }
        self
    }
}

/// Errors for phantoms that are not strictly between a source and its detector in some run, or
/// that lie outside the field of every detector in some run (no image of that run shows them);
/// warnings for phantoms partly outside a detector's field in some runs, and for beads that are
/// visible in no image at all. Every run is expanded, checked and dropped in turn. `bvhs` holds
/// each model's mesh in a BVH (`None` for a model without a mesh), built once by the caller.
pub fn check_geometry(
    loaded: &LoadedScenario,
    models: &[PhantomModel],
    bvhs: &[Option<Arc<MeshBvh>>],
) -> Vec<Diagnostic> {
    let s = &loaded.scenario;
    let total = s.run_count();
    let detectors = s.detectors.len();
    let findings = (0..total)
        .into_par_iter()
        .map(|i| {
            let run = run_at(s, models, i);
            check_run(loaded, models, bvhs, &run, i)
        })
        .reduce(|| Findings::new(models, detectors), Findings::merge);
    report(loaded, models, &findings, total)
}

/// The findings of one run.
fn check_run(
    loaded: &LoadedScenario,
    models: &[PhantomModel],
    bvhs: &[Option<Arc<MeshBvh>>],
    run: &Run,
    index: u64,
) -> Findings {
    let s = &loaded.scenario;
    let mut f = Findings::new(models, s.detectors.len());
    let hides: Vec<bool> = models.iter().map(|m| hides_beads(s, m)).collect();
    for (pi, model) in models.iter().enumerate() {
        if !s.exposures.iter().any(|e| e.phantoms.contains(&model.id)) {
            continue;
        }
        let pose = run.phantoms[pi].pose();
        let points: Vec<(DVec3, f64)> = model
            .extent_points()
            .map(|(p, radius)| (pose.to_world(p), radius))
            .collect();
        // Leaving the field is worth a warning for every bead, and for the outline of a phantom
        // an RSA program fits, not for a background solid cut by the image's edge in every real
        // radiograph (a soft-tissue envelope, or a solid fixed to another phantom, such as a
        // bone carried by its implant).
        let beads = model.markers.len();
        let outline_matters = outline_matters(s, pi);
        let mut in_some_field = false;
        let mut misplaced_here = false;
        for (di, dstate) in run.detectors.iter().enumerate() {
            let frame = dstate.frame();
            let source = run.source_of(dstate);
            let s_local = frame.pose.to_local(source);
            let [w, h] = frame.pixels.map(f64::from);
            let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            let mut outside = false;
            let mut misplaced = None;
            for (k, &(world, radius)) in points.iter().enumerate() {
                let z = frame.pose.to_local(world).z;
                if z - radius <= 0.0 {
                    misplaced = Some(format!(
                        "reaches {:.1} mm behind the detector plane",
                        radius - z
                    ));
                    break;
                }
                if z + radius >= s_local.z {
                    misplaced = Some("reaches the source or beyond it".into());
                    break;
                }
                let Some(uv) = frame.project(source, world) else {
                    continue;
                };
                let magnification = s_local.z / (s_local.z - z);
                let r_px =
                    radius * magnification / frame.pixel_pitch_mm[0].min(frame.pixel_pitch_mm[1]);
                lo = lo.min(DVec3::new(uv.x - r_px, uv.y - r_px, 0.0));
                hi = hi.max(DVec3::new(uv.x + r_px, uv.y + r_px, 0.0));
                if (k < beads || outline_matters)
                    && (uv.x - r_px < 0.0
                        || uv.y - r_px < 0.0
                        || uv.x + r_px > w
                        || uv.y + r_px > h)
                {
                    outside = true;
                }
            }
            let slot = pi * s.detectors.len() + di;
            if let Some(what) = misplaced {
                f.misplaced[slot] = Some((index, run.id.clone(), what));
                misplaced_here = true;
                continue;
            }
            if outside && !is_box(s, pi) {
                f.partly_outside[slot].note(index, &run.id);
            }
            // The projected bounding box of the phantom meets the active area.
            if hi.x > 0.0 && hi.y > 0.0 && lo.x < w && lo.y < h {
                in_some_field = true;
            }
        }
        if !in_some_field && !misplaced_here {
            f.unseen[pi].note(index, &run.id);
        }
    }
    for exposure in &run.exposures {
        let in_beam: Vec<usize> = exposure
            .phantoms
            .iter()
            .filter_map(|id| models.iter().position(|m| &m.id == id))
            .collect();
        for dstate in &run.detectors {
            let frame = dstate.frame();
            let source = run.source_of(dstate);
            for &pi in &in_beam {
                for bead in &run.phantoms[pi].markers {
                    // A study run may leave a patient's missing beads out: tally by id.
                    let Some(k) = models[pi].markers.iter().position(|m| m.id == bead.id) else {
                        continue;
                    };
                    let tally = &mut f.beads[pi][k];
                    tally[0] += 1;
                    let Some(uv) = frame
                        .project(source, bead.position_mm)
                        .filter(|uv| frame.contains_pixel(*uv))
                    else {
                        tally[1] += 1;
                        continue;
                    };
                    let end = frame.pose.to_world(frame.pixel_local(uv.x, uv.y));
                    let hidden = in_beam.iter().filter(|&&pj| hides[pj]).any(|&pj| {
                        bvhs[pj].as_ref().is_some_and(|bvh| {
                            let pose = run.phantoms[pj].pose();
                            let origin = pose.to_local(source);
                            bvh.segment_hits(origin, pose.to_local(end) - origin)
                        })
                    });
                    if hidden {
                        tally[2] += 1;
                    }
                }
            }
        }
    }
    f
}

/// Whether phantom `pi`'s outline leaving a detector's field is worth a warning: not for a
/// soft-tissue envelope (an elliptic cylinder) or a solid fixed to another phantom (a bone
/// carried by its implant), which real radiographs cut at their edges; only their beads count.
fn outline_matters(s: &crate::scenario::Scenario, pi: usize) -> bool {
    let p = &s.phantoms[pi];
    !matches!(p.shape(), PhantomShape::EllipticCylinder(_)) && p.fixed_to.is_none()
}

/// Whether phantom `pi` is a calibration box: one that spans several detectors (a uniplanar
/// cage over two side-by-side panels) is partly outside each by design, so leaving a field is
/// no warning for it; a bead of it that no image shows still is.
fn is_box(s: &crate::scenario::Scenario, pi: usize) -> bool {
    matches!(s.phantoms[pi].shape(), PhantomShape::CalibrationBox(_))
}

/// Whether a phantom's mesh hides the beads in its shadow: always in binary mode (its shadow is
/// I_max like a bead's); in attenuation mode only a metal one (density ≥
/// [`crate::material::METAL_DENSITY_G_CM3`]), since beads show through bone and soft tissue.
fn hides_beads(s: &crate::scenario::Scenario, model: &PhantomModel) -> bool {
    if !s.imaging.is_attenuation() {
        return true;
    }
    model
        .volumes
        .first()
        .and_then(|v| v.material.as_deref())
        .is_some_and(|name| s.is_metal(name))
}

/// The key of a phantom's `k`-th bead, for beads the user listed; the phantom's id otherwise.
fn bead_key(loaded: &LoadedScenario, pi: usize, k: usize) -> KeyPath {
    let p = KeyPath::root().key("phantoms").index(pi);
    match loaded.scenario.phantoms[pi].shape() {
        PhantomShape::Beads(_) => p.key("beads").index(k).key("id"),
        PhantomShape::Mesh(_) => p.key("mesh").key("beads").index(k).key("id"),
        PhantomShape::CalibrationBox(_) | PhantomShape::EllipticCylinder(_) => p.key("id"),
    }
}

/// Most never-visible beads named one by one per phantom; the rest are counted.
const MAX_BEAD_WARNINGS: usize = 10;

fn report(
    loaded: &LoadedScenario,
    models: &[PhantomModel],
    f: &Findings,
    total: u64,
) -> Vec<Diagnostic> {
    let s = &loaded.scenario;
    let mut out = Vec::new();
    for (pi, model) in models.iter().enumerate() {
        let key = KeyPath::root().key("phantoms").index(pi).key("position_mm");
        let id = cut(&model.id);
        let mut misplaced_any = false;
        for (di, det) in s.detectors.iter().enumerate() {
            let slot = pi * s.detectors.len() + di;
            if let Some((_, run_id, what)) = &f.misplaced[slot] {
                misplaced_any = true;
                out.push(
                    loaded
                        .locator
                        .error(
                            key.clone(),
                            format!(
                                "phantom `{id}` is not between source `{}` and detector `{}` in run {run_id}: it {what}",
                                cut(&det.source), cut(&det.id)
                            ),
                        )
                        .with_help("move the phantom, the source or the detector, or narrow the `randomize` ranges"),
                );
            } else if let Some((_, first)) = &f.partly_outside[slot].first {
                out.push(loaded.locator.warning(
                    key.clone(),
                    format!(
                        "{} `{id}` falls partly outside the field of detector `{}` in {} of {total} runs (first: {first})",
                        if outline_matters(s, pi) { "phantom" } else { "a bead of phantom" },
                        cut(&det.id),
                        f.partly_outside[slot].count,
                    ),
                ));
            }
        }
        if misplaced_any {
            continue;
        }
        if let Some((_, first)) = &f.unseen[pi].first {
            out.push(
                loaded
                    .locator
                    .error(
                        key.clone(),
                        format!(
                            "phantom `{id}` lies outside the field of every detector in run {first} \
                             ({} of {total} runs), so no image of that run shows it",
                            f.unseen[pi].count
                        ),
                    )
                    .with_help(
                        "move the phantom or the detectors so it projects onto a detector, or narrow the `randomize` ranges",
                    ),
            );
            continue;
        }
        // A calibration box's bead that an implant hides in some views is a cage exam's
        // everyday lot: only one that falls off every detector in every image is worth a word.
        let boxed = is_box(s, pi);
        let never: Vec<usize> = f.beads[pi]
            .iter()
            .enumerate()
            .filter(|(_, t)| {
                t[0] > 0
                    && if boxed {
                        t[1] >= t[0]
                    } else {
                        t[1] + t[2] >= t[0]
                    }
            })
            .map(|(k, _)| k)
            .collect();
        for &k in never.iter().take(MAX_BEAD_WARNINGS) {
            let [checked, outside, hidden] = f.beads[pi][k];
            out.push(loaded.locator.warning(
                bead_key(loaded, pi, k),
                format!(
                    "bead `{}` of phantom `{id}` is visible in none of the {checked} images it was checked in \
                     (outside the detector in {outside}, in a mesh's shadow in {hidden})",
                    cut(&model.markers[k].id)
                ),
            ));
        }
        if never.len() > MAX_BEAD_WARNINGS {
            out.push(loaded.locator.warning(
                KeyPath::root().key("phantoms").index(pi).key("id"),
                format!(
                    "{} more beads of phantom `{id}` are visible in no image",
                    never.len() - MAX_BEAD_WARNINGS
                ),
            ));
        }
    }
    out
}
