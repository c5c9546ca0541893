//! Regenerates the shipped femoral component model and prints its beads.
//!
//! ```text
//! cargo run --release --example femoral_component -- scenarios/models/femoral_component.glb
//! ```
//!
//! Writes the mesh as binary glTF (metres, as glTF requires; load it with `unit_mm = 1000`) and
//! prints the beads as `[[phantoms.mesh.beads]]` TOML tables (local frame, mm) on stdout. A
//! summary (triangles, bounding box, file size) goes to stderr.

#[path = "common/model_files.rs"]
mod model_files;

use std::path::PathBuf;
use std::process::ExitCode;

use rsasim::phantom::femoral::femoral_component;

fn main() -> ExitCode {
    let Some(path) = std::env::args_os().nth(1).map(PathBuf::from) else {
        eprintln!("usage: femoral_component <output.glb>");
        return ExitCode::from(2);
    };
    let component = femoral_component();
    if let Err(e) = model_files::write_model(&path, &component.mesh) {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    for bead in &component.beads {
        let [x, y, z] = bead.position_mm;
        println!(
            "[[phantoms.mesh.beads]]\nid = \"{}\"\nposition_mm = [{x:?}, {y:?}, {z:?}]\ndiameter_mm = {:?}\n",
            bead.id, bead.diameter_mm
        );
    }
    ExitCode::SUCCESS
}
