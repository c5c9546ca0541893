//! Regenerates the shipped femoral component model and prints its beads.
//!
//! ```text
//! cargo run --release --example femoral_component -- scenarios/models/femoral_component.glb
//! ```
//!
//! Writes the mesh as binary glTF (metres, as glTF requires; load it with `unit_mm = 1000`) and
//! prints the beads as `[[phantoms.mesh.beads]]` TOML tables (local frame, mm) on stdout. A
//! summary (triangles, bounding box, file size) goes to stderr.

use std::path::PathBuf;
use std::process::ExitCode;

use rsasim::phantom::femoral::femoral_component;
use rsasim::phantom::mesh_io::glb_bytes;

fn main() -> ExitCode {
    let Some(path) = std::env::args_os().nth(1).map(PathBuf::from) else {
        eprintln!("usage: femoral_component <output.glb>");
        return ExitCode::from(2);
    };
    let component = femoral_component();
    let bytes = match glb_bytes(&component.mesh) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    if let Err(e) = std::fs::write(&path, &bytes) {
        eprintln!("error: cannot write {}: {e}", path.display());
        return ExitCode::FAILURE;
    }
    let (lo, hi) = component.mesh.bounds_mm();
    let size = hi - lo;
    eprintln!(
        "{}: {} triangles, {} vertices, {} bytes; bounding box {:.2} × {:.2} × {:.2} mm (x × y × z), volume {:.0} mm³",
        path.display(),
        component.mesh.triangles.len(),
        component.mesh.vertices.len(),
        bytes.len(),
        size.x,
        size.y,
        size.z,
        component.mesh.signed_volume_mm3()
    );
    for bead in &component.beads {
        let [x, y, z] = bead.position_mm;
        println!(
            "[[phantoms.mesh.beads]]\nid = \"{}\"\nposition_mm = [{x:?}, {y:?}, {z:?}]\ndiameter_mm = {:?}\n",
            bead.id, bead.diameter_mm
        );
    }
    ExitCode::SUCCESS
}
