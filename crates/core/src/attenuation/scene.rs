//! The solids of one exposure of a run in the world (box) frame, each with its material and the
//! solid it displaces: volumes named by `inside` displace the volume of that phantom, and a bead
//! displaces the innermost volume it lies in.

use std::sync::Arc;

use glam::DVec3;

use crate::expand::{ExposureState, Run};
use crate::geometry::DetectorFrame;
use crate::phantom::{PhantomModel, VolumeShape};
use crate::scenario::Scenario;
use crate::trace::{MeshBvh, Object};

use super::containment::{self, Placement};
use super::setup::Setup;

/// One exposure on one detector, ready to form: the resolved set-up, the solids in the beam (in
/// order, [`parts`]), the detector's frame and the focal spot's centre.
#[derive(Clone, Copy)]
pub struct Exposure<'a> {
    pub setup: &'a Setup,
    pub parts: &'a [Part<'a>],
    pub frame: &'a DetectorFrame,
    pub source_mm: DVec3,
}

/// One solid in the beam.
pub struct Part<'a> {
    /// Its shape, placed.
    pub object: Object<'a>,
    /// Index of its material in [`Setup::materials`].
    pub material: usize,
    /// Index (into the parts) of the solid whose material it replaces where both are crossed.
    pub parent: Option<usize>,
    /// For messages: the phantom id (and plate), or `<phantom>/<bead>`.
    pub label: String,
    /// Index of its phantom in the run.
    pub phantom: usize,
    /// For a bead: its index among its phantom's markers.
    pub bead: Option<usize>,
}

/// The parts of `exposure` in `run`: every volume of its phantoms, then every bead. Errors (a
/// bead across a surface, or inside two volumes that do not nest) are sentences for the user,
/// with the index of the bead's phantom.
pub fn parts<'a>(
    s: &Scenario,
    setup: &Setup,
    models: &'a [PhantomModel],
    bvhs: &'a [Option<Arc<MeshBvh>>],
    run: &Run,
    exposure: &ExposureState,
) -> Result<Vec<Part<'a>>, (usize, String)> {
    let in_beam = exposure.phantom_indices(models);
    let mut parts: Vec<Part<'a>> = Vec::new();
    // First volume part of each phantom, for `inside`.
    let mut first_volume: Vec<Option<usize>> = vec![None; models.len()];
    for &pi in &in_beam {
        let pose = run.phantoms[pi].pose();
        for v in &models[pi].volumes {
            let object = match &v.shape {
                VolumeShape::Mesh => Object::Mesh {
                    bvh: bvhs[pi].as_deref().expect("mesh phantoms have a BVH"),
                    pose,
                },
                VolumeShape::Cuboid {
                    pose: local,
                    half_size_mm,
                } => Object::Cuboid {
                    pose: pose.compose(local),
                    half_size_mm: *half_size_mm,
                },
                VolumeShape::EllipticCylinder {
                    radii_mm,
                    half_length_mm,
                } => Object::EllipticCylinder {
                    pose,
                    radii_mm: *radii_mm,
                    half_length_mm: *half_length_mm,
                },
            };
            first_volume[pi].get_or_insert(parts.len());
            parts.push(Part {
                object,
                material: setup.index(
                    v.material
                        .as_deref()
                        .expect("validated: volumes have a material"),
                ),
                parent: None,
                label: v.label.clone(),
                phantom: pi,
                bead: None,
            });
        }
    }
    // `inside`: every volume of the phantom displaces the named phantom's volume.
    let mut k = 0;
    for &pi in &in_beam {
        let outer = s.phantoms[pi]
            .inside
            .as_ref()
            .and_then(|id| models.iter().position(|m| &m.id == id))
            .and_then(|t| first_volume[t]);
        for _ in &models[pi].volumes {
            parts[k].parent = outer;
            k += 1;
        }
    }
    let volumes = parts.len();
    let depth = |parts: &[Part], mut i: usize| {
        let mut d = 0;
        while let Some(p) = parts[i].parent {
            d += 1;
            i = p;
            if d > parts.len() {
                break;
            }
        }
        d
    };
    for &pi in &in_beam {
        let state = &run.phantoms[pi];
        for (bi, m) in state.markers.iter().enumerate() {
            let r = m.diameter_mm / 2.0;
            let label = format!("{}/{}", state.id, m.id);
            let mut host: Option<usize> = None;
            for vi in 0..volumes {
                let placement = match &parts[vi].object {
                    Object::Mesh { bvh, pose } => {
                        let local = pose.to_local(m.position_mm);
                        let (lo, hi) = bvh.bounds_mm;
                        if local.cmplt(lo - r).any() || local.cmpgt(hi + r).any() {
                            // Clear of the mesh's bounding box: outside, no triangle to test.
                            Placement::Outside
                        } else {
                            containment::in_mesh(local, r, bvh)
                        }
                    }
                    Object::Cuboid { pose, half_size_mm } => {
                        containment::in_cuboid(pose.to_local(m.position_mm), r, *half_size_mm)
                    }
                    Object::EllipticCylinder {
                        pose,
                        radii_mm,
                        half_length_mm,
                    } => containment::in_cylinder(
                        pose.to_local(m.position_mm),
                        r,
                        *radii_mm,
                        *half_length_mm,
                    ),
                    Object::Sphere { .. } => Placement::Outside,
                };
                match placement {
                    Placement::Outside => {}
                    Placement::Across => {
                        return Err((
                            pi,
                            format!(
                                "bead {label} crosses the surface of {} in run {} (exposure {}): a bead must lie wholly inside or wholly outside every volume",
                                parts[vi].label, run.id, exposure.id
                            ),
                        ));
                    }
                    Placement::Inside => {
                        host = match host {
                            None => Some(vi),
                            Some(h) if depth(&parts, vi) > depth(&parts, h) => Some(vi),
                            Some(h) if depth(&parts, vi) < depth(&parts, h) => Some(h),
                            Some(h) => {
                                return Err((
                                    pi,
                                    format!(
                                        "bead {label} lies inside both {} and {} in run {}, which do not nest: declare one `inside` the other, or keep the volumes apart",
                                        parts[h].label, parts[vi].label, run.id
                                    ),
                                ));
                            }
                        };
                    }
                }
            }
            parts.push(Part {
                object: Object::Sphere {
                    centre_mm: m.position_mm,
                    radius_mm: r,
                },
                material: setup.index(&models[pi].bead_material),
                parent: host,
                label,
                phantom: pi,
                bead: Some(bi),
            });
        }
    }
    Ok(parts)
}
