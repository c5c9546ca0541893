//! Writing scenes for the peers of `bench/peers.py`: shared by `examples/bench_scene.rs` and
//! `examples/attenuation_bench.rs` (included with `#[path]`; this folder is no example of its
//! own).

#![allow(dead_code)]

use std::fs;
use std::path::{Path, PathBuf};

use rsasim::geometry::{DVec3, DetectorFrame, Pose, rotation_rows};
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

/// A surface in world coordinates with the largest gap between it and the exact solid it stands
/// for (0 for a mesh, which is exact as it is).
pub struct Tessellation {
    /// The triangles, world frame, mm, outward-wound.
    pub mesh: TriMesh,
    /// Largest distance between the exact surface and the triangles, mm.
    pub chord_error_mm: f64,
}

/// Sectors of an elliptic cylinder's tessellation: 4096 around the perimeter keeps the chord
/// error of the 65 × 58 mm soft-tissue envelope at 2·10⁻⁵ mm.
pub const CYLINDER_SECTORS: usize = 4096;

/// Subdivision level of a sphere's geodesic tessellation: level 6 (81 920 triangles) keeps the
/// chord error of a 1 mm bead at 3.6·10⁻⁵ mm (gVXR's time does not change from level 5 to 6).
pub const SPHERE_LEVEL: u32 = 6;

fn mesh_from(vertices: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> TriMesh {
    TriMesh {
        vertices: vertices
            .iter()
            .map(|v| [v.x as f32, v.y as f32, v.z as f32])
            .collect(),
        triangles,
    }
}

/// A sphere as a geodesic (subdivided icosahedron) surface of `20·4^level` triangles with its
/// vertices on the exact sphere. Unlike a UV sphere its triangles are all about the same size,
/// so the peer is not given 3× the triangles for the same chord error.
pub fn sphere_tessellation(centre_mm: DVec3, radius_mm: f64, level: u32) -> Tessellation {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut unit: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|v| DVec3::from_array(*v).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut midpoints = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, unit: &mut Vec<DVec3>| -> u32 {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                unit.push((unit[a as usize] + unit[b as usize]).normalize());
                unit.len() as u32 - 1
            })
        };
        let mut finer = Vec::with_capacity(triangles.len() * 4);
        for [a, b, c] in triangles {
            let (ab, bc, ca) = (
                mid(a, b, &mut unit),
                mid(b, c, &mut unit),
                mid(c, a, &mut unit),
            );
            finer.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = finer;
    }
    // The gap is largest where a facet's plane is closest to the centre (its foot lies inside
    // these near-equilateral facets).
    let closest = triangles
        .iter()
        .map(|&[a, b, c]| {
            let [a, b, c] = [a, b, c].map(|i| unit[i as usize]);
            (b - a).cross(c - a).normalize().dot(a)
        })
        .fold(1.0, f64::min);
    let world = unit.iter().map(|u| centre_mm + *u * radius_mm).collect();
    Tessellation {
        mesh: mesh_from(world, triangles),
        chord_error_mm: radius_mm * (1.0 - closest),
    }
}

/// A solid elliptic cylinder (axis along local z, semi-axes `radii_mm` along local x and y,
/// caps at z = ±`half_length_mm`) as `4·sectors` triangles, vertices on the exact surface at
/// equal steps of the ellipse's parameter.
pub fn elliptic_cylinder_tessellation(
    pose: &Pose,
    radii_mm: [f64; 2],
    half_length_mm: f64,
    sectors: usize,
) -> Tessellation {
    let n = sectors as u32;
    let [a, b] = radii_mm;
    let point = |t: f64, z: f64| DVec3::new(a * libm::cos(t), b * libm::sin(t), z);
    let step = 2.0 * std::f64::consts::PI / sectors as f64;
    let mut local = Vec::with_capacity(2 * sectors + 2);
    for z in [-half_length_mm, half_length_mm] {
        local.extend((0..sectors).map(|k| point(k as f64 * step, z)));
    }
    local.push(DVec3::new(0.0, 0.0, -half_length_mm));
    local.push(DVec3::new(0.0, 0.0, half_length_mm));
    let (bottom, top) = (2 * n, 2 * n + 1);
    let mut triangles = Vec::with_capacity(4 * sectors);
    for k in 0..n {
        let k1 = (k + 1) % n;
        triangles.push([k, k1, n + k1]);
        triangles.push([k, n + k1, n + k]);
        triangles.push([top, n + k, n + k1]);
        triangles.push([bottom, k1, k]);
    }
    // The gap between each chord and its arc, sampled along the arc.
    let mut chord_error_mm: f64 = 0.0;
    for k in 0..sectors {
        let (p, q) = (
            point(k as f64 * step, 0.0),
            point((k + 1) as f64 * step, 0.0),
        );
        let dir = (q - p).normalize();
        for s in 1..16 {
            let r = point((k as f64 + s as f64 / 16.0) * step, 0.0) - p;
            chord_error_mm = chord_error_mm.max((r - dir * r.dot(dir)).length());
        }
    }
    let world = local.iter().map(|v| pose.to_world(*v)).collect();
    Tessellation {
        mesh: mesh_from(world, triangles),
        chord_error_mm,
    }
}

/// A solid box centred on its local origin as 12 triangles (exact).
pub fn cuboid_tessellation(pose: &Pose, half_size_mm: DVec3) -> Tessellation {
    let corner = |i: u32| {
        let s = |bit: u32| if i & bit == 0 { -1.0 } else { 1.0 };
        pose.to_world(half_size_mm * DVec3::new(s(1), s(2), s(4)))
    };
    // Faces as corner-index quads, counter-clockwise seen from outside.
    let quads = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    let triangles = quads
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
        .collect();
    Tessellation {
        mesh: mesh_from((0..8).map(corner).collect(), triangles),
        chord_error_mm: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rsasim::geometry::rotation_xyz_deg;

    fn pose() -> Pose {
        Pose {
            position_mm: DVec3::new(10.0, -20.0, 30.0),
            rotation: rotation_xyz_deg([-90.0, 5.0, 12.0]),
        }
    }

    /// Closed, outward-wound, and the volume of the exact solid to within what the chord error
    /// allows.
    fn check(t: &Tessellation, exact_mm3: f64, area_mm2: f64) {
        t.mesh.check_closed().unwrap();
        let v = t.mesh.signed_volume_mm3();
        assert!(v > 0.0, "wound inwards: {v}");
        let slack = area_mm2 * t.chord_error_mm + 1e-5 * exact_mm3;
        assert!(
            v <= exact_mm3 * (1.0 + 1e-6) && exact_mm3 - v <= slack,
            "volume {v} vs {exact_mm3} (chord error {})",
            t.chord_error_mm
        );
    }

    #[test]
    fn bead_sphere_is_closed_outward_and_within_its_chord_error() {
        let r = 0.5;
        let t = sphere_tessellation(DVec3::new(1.0, 2.0, 3.0), r, SPHERE_LEVEL);
        assert_eq!(t.mesh.triangles.len(), 20 * 4usize.pow(SPHERE_LEVEL));
        assert!(t.chord_error_mm > 0.0 && t.chord_error_mm < 4e-5);
        let pi = std::f64::consts::PI;
        check(&t, 4.0 / 3.0 * pi * r * r * r, 4.0 * pi * r * r);
    }

    #[test]
    fn leg_cylinder_is_closed_outward_and_within_its_chord_error() {
        let (a, b, h) = (65.0, 58.0, 120.0);
        let t = elliptic_cylinder_tessellation(&pose(), [a, b], h, CYLINDER_SECTORS);
        assert_eq!(t.mesh.triangles.len(), 4 * CYLINDER_SECTORS);
        assert!(t.chord_error_mm > 0.0 && t.chord_error_mm < 2e-5);
        let pi = std::f64::consts::PI;
        // Perimeter (Ramanujan) times the length.
        let perimeter = pi * (3.0 * (a + b) - ((3.0 * a + b) * (a + 3.0 * b)).sqrt());
        check(&t, pi * a * b * 2.0 * h, perimeter * 2.0 * h);
    }

    #[test]
    fn cuboid_is_closed_outward_and_exact() {
        let t = cuboid_tessellation(&pose(), DVec3::new(1.0, 2.0, 3.0));
        check(&t, 48.0, 0.0);
    }
}
