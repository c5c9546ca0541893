//! TEMPORARY: replaced by the full glTF/STL reader on the `knee` branch.
use std::path::Path;

use super::TriMesh;

/// Millimetres per file unit by default.
pub fn default_unit_mm(path: &Path) -> f64 {
    match path.extension().and_then(|e| e.to_str()) {
        Some("stl") => 1.0,
        _ => 1000.0,
    }
}

/// Loads a mesh.
pub fn load_mesh(path: &Path, unit_mm: f64) -> Result<TriMesh, String> {
    let mut f = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let m = stl_io::read_stl(&mut f).map_err(|e| e.to_string())?;
    let mut mesh = TriMesh {
        vertices: m.vertices.iter().map(|v| [v[0] * unit_mm as f32, v[1] * unit_mm as f32, v[2] * unit_mm as f32]).collect(),
        triangles: m.faces.iter().map(|f| f.vertices.map(|i| i as u32)).collect(),
    };
    mesh.weld();
    Ok(mesh)
}
