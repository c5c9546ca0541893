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

#[path = "common/model_files.rs"]
mod model_files;

use std::path::PathBuf;
use std::process::ExitCode;

use rsasim::phantom::femur::distal_femur;

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
        if let Err(e) = model_files::write_model(&dir.join(name), mesh) {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    }
    ExitCode::SUCCESS
}
