//! Writes the benchmark scenes of `benches/projector.rs` for the peers of `bench/peers.py`, so
//! that another ray caster can cast exactly the same rays against exactly the same triangles.
//!
//! ```sh
//! cargo run --release --example bench_scene -- DIR
//! ```
//!
//! DIR receives:
//! - `scene.json`: the source, the detector frame (world position of pixel (0, 0)'s centre and
//!   the world step per pixel along u (columns) and v (rows): pixel (i, j)'s centre is
//!   `pixel00_centre_mm + i·step_u_mm + j·step_v_mm`), the pixel counts, I_max, the noise level,
//!   and per scene its file names, triangle count and covered pixel count. Ray = from the source
//!   to a pixel centre (the segment, 0 < t < 1 with direction = centre − source).
//! - per scene (`femur`: the femoral component alone; `sphere`: the 79 600-triangle sphere):
//!   `NAME.tris.f32`, the triangles in world coordinates, mm, little-endian f32, `[N][3][3]`
//!   (triangle, vertex, xyz); `NAME.stl`, the same as binary STL in mm; `NAME.binary.u8` and
//!   `NAME.traced.u8`, rsasim's hit masks (row-major `H × W`, 1 = covered) from
//!   `trace::render_binary` and `trace::render_binary_traced`.
//! - `model.u16`: the protocol's model image (component + 6 beads) with noise, row-major
//!   little-endian u16 counts, as rsasim writes into its TIFF.

#[path = "common/export.rs"]
mod export;
#[path = "../benches/common/scenes.rs"]
mod scenes;

use std::fs;
use std::path::{Path, PathBuf};

use export::{arr, detector_json, write, write_triangles};
use rsasim::geometry::rotation_rows;
use rsasim::noise;
use rsasim::trace::{Object, render_binary, render_binary_traced};
use scenes::{PlacedMesh, Scenes};
use serde_json::{Value, json};

fn mask(image: &[u16]) -> Vec<u8> {
    image.iter().map(|&p| u8::from(p != 0)).collect()
}

fn export_mesh(dir: &Path, s: &Scenes, name: &str, placed: &PlacedMesh) -> Value {
    let world = placed.world_mesh();
    write_triangles(dir, name, &world);
    let objects: Vec<Object> = vec![placed.object()];
    let binary = render_binary(&s.frame, s.source, &objects, s.i_max);
    let traced = render_binary_traced(&s.frame, s.source, &objects, s.i_max);
    write(dir.join(format!("{name}.binary.u8")), &mask(&binary));
    write(dir.join(format!("{name}.traced.u8")), &mask(&traced));
    let covered = |img: &[u16]| img.iter().filter(|&&p| p != 0).count();
    let (lo, hi) = world.bounds_mm();
    println!(
        "{name}: {} triangles, {} px covered ({:.2} % of the image)",
        world.triangles.len(),
        covered(&binary),
        100.0 * scenes::covered_fraction(&binary)
    );
    json!({
        "triangles": world.triangles.len(),
        "tris_f32": format!("{name}.tris.f32"),
        "stl": format!("{name}.stl"),
        "mask_binary": format!("{name}.binary.u8"),
        "mask_traced": format!("{name}.traced.u8"),
        "covered_px_binary": covered(&binary),
        "covered_px_traced": covered(&traced),
        "covered_fraction": scenes::covered_fraction(&binary),
        "bounds_mm": [arr(lo), arr(hi)],
        "pose": {
            "position_mm": arr(placed.pose.position_mm),
            "rotation": rotation_rows(&placed.pose.rotation),
        },
    })
}

fn main() {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .expect("usage: cargo run --release --example bench_scene -- DIR"),
    );
    fs::create_dir_all(&dir).expect("create the output folder");
    let s = Scenes::load();
    let f = &s.frame;

    let femur = export_mesh(&dir, &s, "femur", &s.femur);
    let mut sphere = export_mesh(&dir, &s, "sphere", &s.sphere);
    sphere["radius_mm"] = json!(s.sphere_radius_mm);
    sphere["rings_segments"] = json!([scenes::SPHERE_RINGS, scenes::SPHERE_SEGMENTS]);

    let mut model = render_binary(f, s.source, &s.model(), s.i_max);
    noise::add_noise(
        &mut model,
        s.width(),
        s.noise_level,
        s.i_max,
        &s.noise_key("model"),
    );
    let bytes: Vec<u8> = model.iter().flat_map(|p| p.to_le_bytes()).collect();
    write(dir.join("model.u16"), &bytes);

    let scene = json!({
        "format": "rsasim-bench-scene/1",
        "rsasim_version": env!("CARGO_PKG_VERSION"),
        "scenario": "scenarios/biplanar.toml",
        "run": "n2-r07",
        "detector_id": "det1",
        "source_mm": arr(s.source),
        "detector": detector_json(f),
        "i_max": s.i_max,
        "noise_level": s.noise_level,
        "scenes": { "femur": femur, "sphere": sphere },
        "model_image": {
            "file": "model.u16",
            "what": "femoral component + 6 beads, binary + noise, row-major LE u16",
        },
    });
    write(
        dir.join("scene.json"),
        serde_json::to_string_pretty(&scene).unwrap().as_bytes(),
    );
    println!("wrote {}", dir.display());
}
