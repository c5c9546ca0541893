//! The phantom stage: each phantom of the scenario turned into what the tracer and the truth
//! files need, in the phantom's own local frame (mm): its beads and its mesh.
//!
//! Mesh files are opened here (not in the scenario stage), and their problems are reported at
//! the scenario key that named them.

pub mod calibration_box;
pub mod confine;
pub mod femoral;
pub mod femur;
pub(crate) mod implicit;
pub mod isosurface;
pub mod mesh;
pub mod mesh_io;
#[cfg(test)]
pub(crate) mod test_support;
pub mod tibia;
pub mod tibial;
pub mod volume;

use std::path::PathBuf;
use std::sync::Arc;

use glam::DVec3;

pub use mesh::TriMesh;
pub use volume::{Volume, VolumeShape};

use crate::diagnostic::{Diagnostic, KeyPath};
use crate::scenario::{Bead, LoadedScenario, PhantomShape, PlateRole};

/// A bead of a phantom, in the phantom's local frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// Id, unique within the phantom.
    pub id: String,
    /// Centre, mm, local frame.
    pub position_mm: DVec3,
    /// Diameter, mm.
    pub diameter_mm: f64,
    /// For calibration box beads: the plate it sits on.
    pub plate: Option<String>,
    /// For calibration box beads: the plate's role.
    pub role: Option<PlateRole>,
}

impl Marker {
    fn from_bead(b: &Bead) -> Marker {
        Marker {
            id: b.id.clone(),
            position_mm: DVec3::from_array(b.position_mm),
            diameter_mm: b.diameter_mm,
            plate: None,
            role: None,
        }
    }
}

/// A phantom ready to be posed and traced.
#[derive(Debug, Clone)]
pub struct PhantomModel {
    /// The scenario's id.
    pub id: String,
    /// `beads`, `calibration_box` or `mesh`.
    pub kind: &'static str,
    /// Beads in the local frame.
    pub markers: Vec<Marker>,
    /// The closed mesh in the local frame (mm), for mesh phantoms.
    pub mesh: Option<Arc<TriMesh>>,
    /// The mesh file as resolved on disk, for mesh phantoms.
    pub mesh_file: Option<PathBuf>,
    /// The self-contained copy of the mesh file for an output's `phantoms/` (the bytes that
    /// were read and checked), for mesh phantoms.
    pub mesh_package: Option<mesh_io::MeshPackage>,
    /// The solids of the phantom (its mesh, a cylinder, box plates with a thickness), local frame.
    pub volumes: Vec<Volume>,
    /// Material of the phantom's beads (attenuation mode). Default `tantalum`.
    pub bead_material: String,
}

impl PhantomModel {
    /// Every point that bounds the phantom's shape in its local frame, each with a radius:
    /// bead centres with their radii, and mesh vertices with radius 0.
    pub fn extent_points(&self) -> impl Iterator<Item = (DVec3, f64)> + '_ {
        let beads = self
            .markers
            .iter()
            .map(|m| (m.position_mm, m.diameter_mm / 2.0));
        let verts = self.mesh.iter().flat_map(|m| {
            m.vertices
                .iter()
                .map(|v| (DVec3::from_array(v.map(f64::from)), 0.0))
        });
        let corners = self
            .volumes
            .iter()
            .flat_map(Volume::corners)
            .map(|c| (c, 0.0));
        beads.chain(verts).chain(corners)
    }
}

/// Builds every phantom of the scenario, opening and checking mesh files. Errors name the
/// scenario key of the offending phantom; warnings (see [`build_with_warnings`]) are dropped.
pub fn build(loaded: &LoadedScenario) -> Result<Vec<PhantomModel>, Vec<Diagnostic>> {
    build_with_warnings(loaded).map(|(models, _)| models)
}

/// Builds every phantom of the scenario, opening and checking mesh files under the confinement
/// rule ([`confine`]: the scenario's folder and `loaded.allowed_dirs`). Errors name the
/// scenario key of the offending phantom; warnings name a mesh whose size is implausible for
/// its unit.
pub fn build_with_warnings(
    loaded: &LoadedScenario,
) -> Result<(Vec<PhantomModel>, Vec<Diagnostic>), Vec<Diagnostic>> {
    let confinement =
        confine::Confinement::new(&loaded.base_dir, &loaded.allowed_dirs).map_err(|e| {
            vec![
                Diagnostic::file_error(&loaded.path, e)
                    .with_help("--allow-dir takes an existing folder"),
            ]
        })?;
    let mut errors = Vec::new();
    let mut warnings = Vec::new();
    let mut models = Vec::new();
    for (i, ph) in loaded.scenario.phantoms.iter().enumerate() {
        let path = KeyPath::root().key("phantoms").index(i);
        let (markers, mesh, mesh_file, mesh_package) = match ph.shape() {
            PhantomShape::Beads(beads) => (
                beads.iter().map(Marker::from_bead).collect(),
                None,
                None,
                None,
            ),
            PhantomShape::CalibrationBox(b) => (calibration_box::box_markers(b), None, None, None),
            PhantomShape::EllipticCylinder(_) => (Vec::new(), None, None, None),
            PhantomShape::Mesh(m) => {
                let file = loaded.base_dir.join(&m.file);
                let unit = m.unit_mm.unwrap_or_else(|| mesh_io::default_unit_mm(&file));
                match load_closed_mesh(&file, unit, &confinement) {
                    Ok(read) => {
                        let key = if m.unit_mm.is_some() {
                            "unit_mm"
                        } else {
                            "file"
                        };
                        warnings.extend(
                            read.warnings.iter().map(|w| {
                                loaded.locator.warning(path.key("mesh").key(key), w.clone())
                            }),
                        );
                        (
                            m.beads.iter().map(Marker::from_bead).collect(),
                            Some(Arc::new(read.mesh)),
                            Some(file),
                            Some(read.package),
                        )
                    }
                    Err((message, help)) => {
                        errors.push(
                            loaded
                                .locator
                                .error(path.key("mesh").key("file"), message)
                                .with_help(help),
                        );
                        continue;
                    }
                }
            }
        };
        let volumes = match ph.shape() {
            PhantomShape::Mesh(_) => vec![Volume {
                label: ph.id.clone(),
                shape: VolumeShape::Mesh,
                material: ph.material.clone(),
            }],
            PhantomShape::EllipticCylinder(c) => {
                vec![volume::cylinder(&ph.id, c, ph.material.as_ref())]
            }
            PhantomShape::CalibrationBox(b) if loaded.scenario.imaging.is_attenuation() => {
                volume::plates(&ph.id, b)
            }
            _ => Vec::new(),
        };
        models.push(PhantomModel {
            id: ph.id.clone(),
            kind: ph.kind(),
            markers,
            mesh,
            mesh_file,
            mesh_package,
            volumes,
            bead_material: ph
                .bead_material
                .clone()
                .unwrap_or_else(|| "tantalum".into()),
        });
    }
    if errors.is_empty() {
        Ok((models, warnings))
    } else {
        Err(errors)
    }
}

/// Loads a mesh under the confinement rule and insists that it is closed and outward-wound
/// (inward winding is fixed).
fn load_closed_mesh(
    file: &std::path::Path,
    unit_mm: f64,
    confinement: &confine::Confinement,
) -> Result<mesh_io::LoadedMesh, (String, String)> {
    let mut read = mesh_io::load_mesh_in(file, unit_mm, confinement).map_err(|e| {
        let help = if e.contains("outside the folders") {
            "mesh files, buffers and images must lie in the scenario file's folder: copy them there, or allow their folder with --allow-dir DIR"
        } else if e.contains("does not exist") {
            "mesh paths are relative to the scenario file; check the spelling and the folder"
        } else {
            "use a closed triangle mesh as .glb, .gltf or .stl (a regular file)"
        };
        (format!("cannot read mesh: {e}"), help.to_string())
    })?;
    let shown = confine::shown_path(file);
    read.mesh.check_closed().map_err(|e| {
        (
            format!("mesh {shown} is not a closed surface: {e}"),
            "the tracer needs a watertight solid; repair the mesh (e.g. fill holes, unify normals) and export again".into(),
        )
    })?;
    if read.mesh.signed_volume_mm3() < 0.0 {
        read.mesh.flip_winding();
    }
    Ok(read)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extent_points_cover_beads_and_vertices() {
        let model = PhantomModel {
            id: "m".into(),
            kind: "mesh",
            markers: vec![Marker {
                id: "b".into(),
                position_mm: DVec3::new(50.0, 0.0, 0.0),
                diameter_mm: 2.0,
                plate: None,
                role: None,
            }],
            mesh: Some(Arc::new(TriMesh::uv_sphere(10.0, 4, 4))),
            mesh_file: None,
            mesh_package: None,
            volumes: Vec::new(),
            bead_material: "tantalum".into(),
        };
        let pts: Vec<_> = model.extent_points().collect();
        assert_eq!(pts.len(), 1 + model.mesh.as_ref().unwrap().vertices.len());
        assert_eq!(pts[0], (DVec3::new(50.0, 0.0, 0.0), 1.0));
    }
}
