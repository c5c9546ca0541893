//! Writing the shipped procedural models: shared by `examples/distal_femur.rs`,
//! `examples/femoral_component.rs` and `examples/proximal_tibia.rs` (included with `#[path]`;
//! this folder is no example of its own).

use std::path::Path;

use rsasim::phantom::TriMesh;
use rsasim::phantom::mesh_io::glb_bytes;

/// Writes `mesh` (mm) to `path` as binary glTF (metres, as glTF requires) and prints a summary
/// (triangles, vertices, file size, bounding box, volume) to stderr; the error names the path.
pub fn write_model(path: &Path, mesh: &TriMesh) -> Result<(), String> {
    let bytes = glb_bytes(mesh)?;
    std::fs::write(path, &bytes).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    let (lo, hi) = mesh.bounds_mm();
    let size = hi - lo;
    eprintln!(
        "{}: {} triangles, {} vertices, {} bytes; bounding box {:.2} × {:.2} × {:.2} mm (x × y × z), volume {:.0} mm³",
        path.display(),
        mesh.triangles.len(),
        mesh.vertices.len(),
        bytes.len(),
        size.x,
        size.y,
        size.z,
        mesh.signed_volume_mm3()
    );
    Ok(())
}
