//! Writing scenes for the peers of `bench/peers.py`: shared by `examples/bench_scene.rs` and
//! `examples/attenuation_bench.rs` (included with `#[path]`; this folder is no example of its
//! own).

#![allow(dead_code)]

use std::fs;
use std::path::{Path, PathBuf};

use rsasim::geometry::{DVec3, DetectorFrame, rotation_rows};
use rsasim::phantom::TriMesh;
use rsasim::phantom::mesh_io::write_stl;
use serde_json::{Value, json};

/// A vector as a JSON-ready array.
pub fn arr(v: DVec3) -> [f64; 3] {
    v.to_array()
}

/// Writes `bytes` to `path`; a benchmark tool, so a failure ends it with the path named.
pub fn write(path: PathBuf, bytes: &[u8]) {
    fs::write(&path, bytes).unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
}

/// Writes a world-space mesh as `NAME.tris.f32` (little-endian f32 `[N][3][3]`, mm) and
/// `NAME.stl` (binary STL, mm).
pub fn write_triangles(dir: &Path, name: &str, world: &TriMesh) {
    let mut tris = Vec::with_capacity(world.triangles.len() * 36);
    for t in &world.triangles {
        for &i in t {
            for x in world.vertices[i as usize] {
                tris.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    write(dir.join(format!("{name}.tris.f32")), &tris);
    let mut stl = Vec::new();
    write_stl(world, &mut stl).expect("STL encoding");
    write(dir.join(format!("{name}.stl")), &stl);
}

/// The detector as the peers read it: pixel (i, j)'s centre is
/// `pixel00_centre_mm + i·step_u_mm + j·step_v_mm`; `rotation` has the r, c, s axes as columns.
pub fn detector_json(frame: &DetectorFrame) -> Value {
    let r = frame.pose.rotation;
    let [px, py] = frame.pixel_pitch_mm;
    json!({
        "pixels": frame.pixels,
        "pixel_pitch_mm": frame.pixel_pitch_mm,
        "position_mm": arr(frame.pose.position_mm),
        "rotation": rotation_rows(&r),
        "normal_towards_source": arr(r.col(2)),
        "pixel00_centre_mm": arr(frame.pixel_centre_world(0, 0)),
        "step_u_mm": arr(r.col(0) * px),
        "step_v_mm": arr(r.col(1) * py),
    })
}
