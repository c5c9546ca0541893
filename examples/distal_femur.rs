//! Regenerates the shipped distal femur models.
//!
//! ```text
//! cargo run --release --example distal_femur -- scenarios/models
//! ```
//!
//! Writes `distal_femur_cortical.glb` (the outer bone surface) and
//! `distal_femur_cancellous.glb` (the cancellous region inside it) into the given folder, as
//! binary glTF (metres, as glTF requires; load them with `unit_mm = 1000`), both in the femoral
//! component's local frame. A summary (triangles, bounding box, file size) goes to stderr.

use std::path::PathBuf;
use std::process::ExitCode;

use rsasim::phantom::femur::distal_femur;
use rsasim::phantom::mesh_io::glb_bytes;

fn main() -> ExitCode {
    let Some(dir) = std::env::args_os().nth(1).map(PathBuf::from) else {
        eprintln!("usage: distal_femur <output folder>");
        return ExitCode::from(2);
    };
    let femur = distal_femur();
    for (name, mesh) in [
        ("distal_femur_cortical.glb", &femur.cortical),
        ("distal_femur_cancellous.glb", &femur.cancellous),
    ] {
        let path = dir.join(name);
        let bytes = match glb_bytes(mesh) {
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
    }
    ExitCode::SUCCESS
}
