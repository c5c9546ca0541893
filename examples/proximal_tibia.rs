//! Regenerates the shipped proximal tibia and tibial component models and prints the tibial
//! markers and the full-extension pose.
//!
//! ```text
//! cargo run --release --example proximal_tibia -- scenarios/models
//! ```
//!
//! Writes `proximal_tibia_cortical.glb` (the outer bone surface),
//! `proximal_tibia_cancellous.glb` (the cancellous region inside it), `tibial_tray.glb` (the
//! Ti-6Al-4V baseplate with its keel) and `tibial_insert.glb` (the polyethylene insert) into the
//! given folder, as binary glTF (metres, as glTF requires; load them with `unit_mm = 1000`), all
//! in the tibial frame. A summary (triangles, bounding box, file size) goes to stderr; the markers
//! as `[[phantoms.mesh.beads]]` TOML tables (tibial frame, mm) and the position of the tibial
//! frame in the femoral component's frame at full extension go to stdout.

#[path = "common/model_files.rs"]
mod model_files;

use std::path::PathBuf;
use std::process::ExitCode;

use rsasim::phantom::tibia::{MARKER_DIAMETER_MM, TIBIAL_MARKERS_MM, proximal_tibia};
use rsasim::phantom::tibial::{full_extension_position_mm, tibial_insert, tibial_tray};

fn main() -> ExitCode {
    let Some(dir) = std::env::args_os().nth(1).map(PathBuf::from) else {
        eprintln!("usage: proximal_tibia <output folder>");
        return ExitCode::from(2);
    };
    let tibia = proximal_tibia();
    let (tray, insert) = (tibial_tray(), tibial_insert());
    for (name, mesh) in [
        ("proximal_tibia_cortical.glb", &tibia.cortical),
        ("proximal_tibia_cancellous.glb", &tibia.cancellous),
        ("tibial_tray.glb", &tray),
        ("tibial_insert.glb", &insert),
    ] {
        if let Err(e) = model_files::write_model(&dir.join(name), mesh) {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    }
    for (id, [x, y, z]) in TIBIAL_MARKERS_MM {
        println!(
            "[[phantoms.mesh.beads]]\nid = \"{id}\"\nposition_mm = [{x:?}, {y:?}, {z:?}]\ndiameter_mm = {MARKER_DIAMETER_MM:?}\n"
        );
    }
    let [x, y, z] = full_extension_position_mm();
    println!(
        "# full extension: the tibial frame's origin in the femoral component's frame, no rotation\nposition_mm = [{x:?}, {y:?}, {z:?}]"
    );
    ExitCode::SUCCESS
}
