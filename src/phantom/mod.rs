//! The phantom stage: each phantom of the scenario turned into what the tracer and the truth
//! files need, in the phantom's own local frame (mm): its beads and its mesh.
//!
//! Mesh files are opened here (not in the scenario stage), and their problems are reported at
//! the scenario key that named them.

pub mod calibration_box;
pub mod femoral;
pub mod isosurface;
pub mod mesh;
pub mod mesh_io;

use std::path::PathBuf;
use std::sync::Arc;

use glam::DVec3;

pub use mesh::TriMesh;

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
        beads.chain(verts)
    }
}

/// Builds every phantom of the scenario, opening and checking mesh files. Errors name the
/// scenario key of the offending phantom.
pub fn build(loaded: &LoadedScenario) -> Result<Vec<PhantomModel>, Vec<Diagnostic>> {
    let mut errors = Vec::new();
    let mut models = Vec::new();
    for (i, ph) in loaded.scenario.phantoms.iter().enumerate() {
        let path = KeyPath::root().key("phantoms").index(i);
        let (markers, mesh, mesh_file) = match ph.shape() {
            PhantomShape::Beads(beads) => {
                (beads.iter().map(Marker::from_bead).collect(), None, None)
            }
            PhantomShape::CalibrationBox(b) => (calibration_box::box_markers(b), None, None),
            PhantomShape::Mesh(m) => {
                let file = loaded.base_dir.join(&m.file);
                let unit = m.unit_mm.unwrap_or_else(|| mesh_io::default_unit_mm(&file));
                match load_closed_mesh(&file, unit) {
                    Ok(mesh) => (
                        m.beads.iter().map(Marker::from_bead).collect(),
                        Some(Arc::new(mesh)),
                        Some(file),
                    ),
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
        models.push(PhantomModel {
            id: ph.id.clone(),
            kind: ph.kind(),
            markers,
            mesh,
            mesh_file,
        });
    }
    if errors.is_empty() {
        Ok(models)
    } else {
        Err(errors)
    }
}

/// Loads a mesh and insists that it is closed and outward-wound (inward winding is fixed).
fn load_closed_mesh(file: &std::path::Path, unit_mm: f64) -> Result<TriMesh, (String, String)> {
    if !file.is_file() {
        return Err((
            format!("mesh file {} does not exist", file.display()),
            "mesh paths are relative to the scenario file; check the spelling and the folder"
                .into(),
        ));
    }
    let mut mesh = mesh_io::load_mesh(file, unit_mm).map_err(|e| {
        (
            format!("cannot read mesh {}: {e}", file.display()),
            "use a closed triangle mesh as .glb, .gltf or .stl".into(),
        )
    })?;
    mesh.check_closed().map_err(|e| {
        (
            format!("mesh {} is not a closed surface: {e}", file.display()),
            "the tracer needs a watertight solid; repair the mesh (e.g. fill holes, unify normals) and export again".into(),
        )
    })?;
    if mesh.signed_volume_mm3() < 0.0 {
        mesh.flip_winding();
    }
    Ok(mesh)
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
        };
        let pts: Vec<_> = model.extent_points().collect();
        assert_eq!(pts.len(), 1 + model.mesh.as_ref().unwrap().vertices.len());
        assert_eq!(pts[0], (DVec3::new(50.0, 0.0, 0.0), 1.0));
    }
}
