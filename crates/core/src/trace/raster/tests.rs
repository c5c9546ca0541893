use std::path::Path;

use glam::{DVec2, DVec3};

use super::*;
use crate::geometry::rotation_xyz_deg;
use crate::phantom::{TriMesh, mesh_io};
use crate::random::{stream, symmetric, uniform01};
use crate::trace::{Object, render_binary, render_binary_traced};

/// Pixel centres that the two projectors may decide differently lie this close to a projected
/// triangle edge, px. The scan conversion is exact to ~1e-12 px; the tracer is not: it rounds its
/// ray to f32 in the mesh frame, origin ~1300 mm and direction ~1800 mm long, so ~6e-5 mm each,
/// ~1e-4 mm at the object, up to ~5e-4 px on a 0.3 mm detector after magnification. The worst
/// seen over 75 random poses is 2.3e-4 px (most poses differ on no pixel at all).
const EDGE_TOLERANCE_PX: f64 = 1e-3;

/// Coverage count per pixel of triangles given in pixel coordinates (either winding).
fn coverage(w: u32, h: u32, triangles: &[[DVec2; 3]]) -> Vec<u32> {
    let mut counts = vec![0u32; (w * h) as usize];
    for &[a, b, c] in triangles {
        let (b, c) = if (b - a).perp_dot(c - a) > 0.0 {
            (b, c)
        } else {
            (c, b)
        };
        scan_triangle(w, h, a, b, c, |row, first, end| {
            for k in first..end {
                counts[row * w as usize + k] += 1;
            }
        });
    }
    counts
}

/// Whether `p` is strictly inside the counter-clockwise convex polygon `poly`, by more than `margin`.
fn strictly_inside(poly: &[DVec2], p: DVec2, margin: f64) -> bool {
    (0..poly.len()).all(|k| {
        let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
        (b - a).perp_dot(p - a) > margin * (b - a).length()
    })
}

/// Convex hull, counter-clockwise (Andrew's monotone chain), without collinear points.
fn hull(mut pts: Vec<DVec2>) -> Vec<DVec2> {
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup();
    let mut out: Vec<DVec2> = Vec::new();
    for pass in 0..2 {
        let start = out.len();
        for &p in &pts {
            while out.len() >= start + 2 {
                let (a, b) = (out[out.len() - 2], out[out.len() - 1]);
                if (b - a).perp_dot(p - a) <= 0.0 {
                    out.pop();
                } else {
                    break;
                }
            }
            out.push(p);
        }
        out.pop();
        if pass == 0 {
            pts.reverse();
        }
    }
    out
}

/// Convex polygons with vertices on the half-pixel grid (so edges run through many pixel centres
/// and vertices sit on centres), and polygons with arbitrary vertices: two different
/// triangulations fill the same pixels, every pixel at most once, and every centre inside.
#[test]
fn shared_edges_and_vertices_are_filled_exactly_once() {
    let (w, h) = (48u32, 40u32);
    let mut rng = stream("raster shared edges");
    for trial in 0..300 {
        let snap = trial % 2 == 0;
        let centre = DVec2::new(24.0, 20.0) + DVec2::new(symmetric(&mut rng, 6.0), 0.0);
        let pts: Vec<DVec2> = (0..3 + trial % 9)
            .map(|_| {
                let angle = uniform01(&mut rng) * std::f64::consts::TAU;
                let r = 4.0 + 20.0 * uniform01(&mut rng);
                let p = centre + r * DVec2::new(libm::cos(angle), libm::sin(angle));
                if snap { (p * 2.0).round() / 2.0 } else { p }
            })
            .collect();
        let poly = hull(pts);
        if poly.len() < 3 {
            continue;
        }
        // Triangulation 1: a fan from the first vertex. Triangulation 2: a fan from an inner point
        // (a pixel centre on the snapped trials).
        let fan_vertex: Vec<[DVec2; 3]> = (1..poly.len() - 1)
            .map(|k| [poly[0], poly[k], poly[k + 1]])
            .collect();
        let mut inner = poly.iter().copied().sum::<DVec2>() / poly.len() as f64;
        if snap {
            inner = inner.floor() + 0.5;
        }
        if !strictly_inside(&poly, inner, 1e-6) {
            continue;
        }
        let fan_inner: Vec<[DVec2; 3]> = (0..poly.len())
            .map(|k| [inner, poly[k], poly[(k + 1) % poly.len()]])
            .collect();
        let (one, two) = (coverage(w, h, &fan_vertex), coverage(w, h, &fan_inner));
        assert_eq!(one, two, "trial {trial}: triangulations disagree");
        for j in 0..h {
            for i in 0..w {
                let n = one[(j * w + i) as usize];
                let p = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
                assert!(n <= 1, "trial {trial}: pixel ({i}, {j}) filled {n} times");
                if strictly_inside(&poly, p, 1e-9) {
                    assert_eq!(n, 1, "trial {trial}: gap at ({i}, {j})");
                }
                if !strictly_inside(&poly, p, -1e-9) {
                    assert_eq!(n, 0, "trial {trial}: ({i}, {j}) outside but filled");
                }
            }
        }
    }
}

/// The two halves of a square split along a diagonal through a row of pixel centres: each centre
/// on the diagonal is filled once, whichever way round the square is split.
#[test]
fn a_diagonal_through_pixel_centres_is_filled_once() {
    let (a, b, c, d) = (
        DVec2::new(2.5, 2.5),
        DVec2::new(12.5, 2.5),
        DVec2::new(12.5, 12.5),
        DVec2::new(2.5, 12.5),
    );
    let split_ac = coverage(16, 16, &[[a, b, c], [a, c, d]]);
    let split_bd = coverage(16, 16, &[[a, b, d], [b, c, d]]);
    assert_eq!(split_ac, split_bd);
    assert!(split_ac.iter().all(|&n| n <= 1));
    // Interior centres 3..=12 along both axes, plus the owned half of the border.
    for k in 3..12 {
        assert_eq!(split_ac[k * 16 + k], 1, "diagonal centre ({k}, {k})");
    }
}

/// The shipped femoral component (`scenarios/models/femoral_component.glb`), closed, wound outward.
pub(in crate::trace) fn femoral_mesh() -> TriMesh {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .join("scenarios/models/femoral_component.glb");
    let mut mesh = mesh_io::load_mesh(&path, 1000.0).expect("the femoral component loads");
    mesh.check_closed()
        .expect("the femoral component is closed");
    if mesh.signed_volume_mm3() < 0.0 {
        mesh.flip_winding();
    }
    mesh
}

/// A detector `n × n` of 0.3 mm pixels 500 mm below the origin (s = +z, turned a little),
/// shifted by `offset_mm` along its plane, and a source about 1300 mm above the origin.
pub(in crate::trace) fn beamline(
    rng: &mut rand_chacha::ChaCha8Rng,
    n: u32,
    offset_mm: [f64; 2],
) -> (DetectorFrame, DVec3) {
    let rotation = rotation_xyz_deg([
        symmetric(rng, 5.0),
        symmetric(rng, 5.0),
        symmetric(rng, 180.0),
    ]);
    let frame = DetectorFrame {
        pose: Pose {
            position_mm: DVec3::new(0.0, 0.0, -500.0)
                + rotation * DVec3::new(offset_mm[0], offset_mm[1], 0.0),
            rotation,
        },
        pixels: [n, n],
        pixel_pitch_mm: [0.3, 0.3],
    };
    let source = DVec3::new(
        symmetric(rng, 20.0),
        symmetric(rng, 20.0),
        1300.0 + symmetric(rng, 20.0),
    );
    (frame, source)
}

/// Distance from `p` to the segment `a b`.
pub(in crate::trace) fn segment_distance(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    (a + t * ab - p).length()
}

/// Renders `mesh` with both projectors at random poses and checks that every pixel they decide
/// differently has its centre within [`EDGE_TOLERANCE_PX`] of a projected triangle edge, and that
/// such pixels are rare (at most 1 in 2000 covered). With `offset_mm` non-zero, also that the
/// shadow reaches the detector's border.
fn cross_check(label: &str, mesh: &TriMesh, n: u32, offset_mm: [f64; 2], poses: usize) {
    let poses = std::env::var("RSASIM_RASTER_POSES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(poses);
    let bvh = MeshBvh::new(mesh);
    assert_eq!(bvh.facing, Faces::Outward);
    let mut rng = stream(label);
    for k in 0..poses {
        let (frame, source) = beamline(&mut rng, n, offset_mm);
        let pose = Pose {
            position_mm: DVec3::new(
                symmetric(&mut rng, 10.0),
                symmetric(&mut rng, 10.0),
                symmetric(&mut rng, 10.0),
            ),
            rotation: rotation_xyz_deg([
                symmetric(&mut rng, 180.0),
                symmetric(&mut rng, 180.0),
                symmetric(&mut rng, 180.0),
            ]),
        };
        let objects = [Object::Mesh { bvh: &bvh, pose }];
        let fast = render_binary(&frame, source, &objects, 1);
        let slow = render_binary_traced(&frame, source, &objects, 1);
        let uv = project_vertices(&frame, source, &bvh.vertices_mm, pose).expect("projects");
        let covered = slow.iter().filter(|&&p| p == 1).count();
        let mut worst_px: f64 = 0.0;
        let mut differ = 0;
        for (idx, _) in fast
            .iter()
            .zip(&slow)
            .enumerate()
            .filter(|(_, (a, b))| a != b)
        {
            differ += 1;
            let p = DVec2::new(
                (idx % n as usize) as f64 + 0.5,
                (idx / n as usize) as f64 + 0.5,
            );
            let nearest = bvh
                .faces
                .iter()
                .flat_map(|t| {
                    let [a, b, c] = t.map(|v| uv[v as usize]);
                    [(a, b), (b, c), (c, a)]
                })
                .map(|(a, b)| segment_distance(p, a, b))
                .fold(f64::INFINITY, f64::min);
            worst_px = worst_px.max(nearest);
        }
        eprintln!(
            "{label} pose {k}: {covered} covered px, {differ} differ, worst edge distance {worst_px:.2e} px"
        );
        assert!(
            covered > 1000,
            "{label} pose {k}: only {covered} px covered"
        );
        if offset_mm != [0.0, 0.0] {
            let n = n as usize;
            let on_border = (0..n).any(|k| {
                [k, (n - 1) * n + k, k * n, k * n + n - 1]
                    .iter()
                    .any(|&idx| slow[idx] == 1)
            });
            assert!(
                on_border,
                "{label} pose {k}: the shadow stays inside the detector"
            );
        }
        assert!(
            worst_px < EDGE_TOLERANCE_PX,
            "{label} pose {k}: a differing pixel lies {worst_px:.2e} px from every edge"
        );
        assert!(
            differ * 2000 <= covered,
            "{label} pose {k}: {differ} of {covered} px differ"
        );
    }
}

#[test]
fn scan_conversion_matches_the_tracer_on_the_femoral_component() {
    cross_check("raster femoral", &femoral_mesh(), 400, [0.0, 0.0], 4);
}

#[test]
fn scan_conversion_matches_the_tracer_on_a_fine_sphere_mesh() {
    // 2·200 + 2·198·200 = 79 600 triangles.
    let mesh = TriMesh::uv_sphere(30.0, 200, 200);
    assert!(mesh.triangles.len() > 79_000);
    cross_check("raster sphere", &mesh, 320, [0.0, 0.0], 3);
}

#[test]
fn scan_conversion_matches_the_tracer_when_the_shadow_leaves_the_detector() {
    // The detector is shifted by 40 mm (133 px) along r and c: the shadow crosses two borders.
    cross_check("raster clipped", &femoral_mesh(), 300, [40.0, 40.0], 3);
}

#[test]
fn front_faces_project_with_positive_area() {
    let mesh = TriMesh::uv_sphere(10.0, 12, 24);
    let frame = DetectorFrame {
        pose: Pose::from_position_euler_deg([5.0, -3.0, -400.0], [4.0, -3.0, 30.0]),
        pixels: [200, 200],
        pixel_pitch_mm: [0.2, 0.25],
    };
    let source = DVec3::new(20.0, 10.0, 900.0);
    let pose = Pose::from_position_euler_deg([2.0, 1.0, 30.0], [10.0, 20.0, 30.0]);
    let vertices: Vec<DVec3> = mesh
        .vertices
        .iter()
        .map(|v| DVec3::from_array(v.map(f64::from)))
        .collect();
    let uv = project_vertices(&frame, source, &vertices, pose).unwrap();
    let mut front = 0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|k| pose.to_world(vertices[k as usize]));
        let towards_source = (b - a)
            .cross(c - a)
            .normalize()
            .dot((source - a).normalize());
        let [pa, pb, pc] = t.map(|k| uv[k as usize]);
        let area = (pb - pa).perp_dot(pc - pa);
        if towards_source.abs() > 1e-6 {
            assert_eq!(
                towards_source > 0.0,
                area > 0.0,
                "{towards_source} vs {area}"
            );
        }
        front += usize::from(area > 0.0);
    }
    assert!(front > 100 && front < mesh.triangles.len() - 100);
}

#[test]
fn a_mesh_that_does_not_project_is_traced() {
    // A sphere mesh straddling the detector plane, and one straddling the source's plane: both
    // fall back to the tracer, so the images are the tracer's exactly.
    let frame = DetectorFrame {
        pose: Pose::IDENTITY,
        pixels: [120, 120],
        pixel_pitch_mm: [0.5, 0.5],
    };
    let source = DVec3::new(0.0, 0.0, 200.0);
    let bvh = MeshBvh::new(&TriMesh::uv_sphere(8.0, 16, 32));
    for z in [2.0, 198.0] {
        let pose = Pose::from_position_euler_deg([3.0, 4.0, z], [0.0, 0.0, 0.0]);
        assert!(project_vertices(&frame, source, &bvh.vertices_mm, pose).is_none());
        let objects = [Object::Mesh { bvh: &bvh, pose }];
        assert_eq!(
            render_binary(&frame, source, &objects, 7),
            render_binary_traced(&frame, source, &objects, 7)
        );
    }
}

#[test]
fn an_open_mesh_fills_every_face() {
    // Half a sphere (an open bowl), seen from inside and from outside.
    let mut bowl = TriMesh::uv_sphere(10.0, 16, 32);
    bowl.triangles
        .retain(|t| t.iter().map(|&k| bowl.vertices[k as usize][2]).sum::<f32>() > 0.0);
    let bvh = MeshBvh::new(&bowl);
    assert_eq!(bvh.facing, Faces::All);
    let frame = DetectorFrame {
        pose: Pose::IDENTITY,
        pixels: [160, 160],
        pixel_pitch_mm: [0.25, 0.25],
    };
    let source = DVec3::new(1.0, 2.0, 600.0);
    for angle in [0.0, 80.0, 180.0] {
        let pose = Pose::from_position_euler_deg([0.0, 0.0, 200.0], [angle, 0.0, 0.0]);
        let objects = [Object::Mesh { bvh: &bvh, pose }];
        let fast = render_binary(&frame, source, &objects, 1);
        let slow = render_binary_traced(&frame, source, &objects, 1);
        let differ = fast.iter().zip(&slow).filter(|(a, b)| a != b).count();
        let covered = slow.iter().filter(|&&p| p == 1).count();
        assert!(
            covered > 1000 && differ * 500 <= covered,
            "{angle}°: {differ} of {covered}"
        );
    }
}

#[test]
fn bead_pixels_are_the_tracers_byte_for_byte() {
    // Beads anywhere in the beam, some partly off the detector, some seen at a steep angle.
    let mut rng = stream("raster beads");
    for _ in 0..20 {
        let shift_mm = symmetric(&mut rng, 60.0);
        let (frame, source) = beamline(&mut rng, 300, [shift_mm, 0.0]);
        let objects: Vec<Object> = (0..40)
            .map(|_| Object::Sphere {
                centre_mm: DVec3::new(
                    symmetric(&mut rng, 70.0),
                    symmetric(&mut rng, 70.0),
                    symmetric(&mut rng, 400.0),
                ),
                radius_mm: 0.2 + 8.0 * uniform01(&mut rng),
            })
            .collect();
        let fast = render_binary(&frame, source, &objects, 65535);
        let slow = render_binary_traced(&frame, source, &objects, 65535);
        assert!(slow.iter().filter(|&&p| p != 0).count() > 100);
        assert_eq!(fast, slow);
    }
}

#[test]
fn centre_range_keeps_the_centres_between_its_bounds() {
    let reference = |lo: f64, hi: f64, n: u32| {
        let first = (lo - 0.5).ceil().clamp(0.0, n as f64) as i64;
        let end = ((hi - 0.5).floor() + 1.0).clamp(0.0, n as f64) as i64;
        (first < end).then_some((first, end))
    };
    let values = [
        -3.0, -0.5, -1e-300, 0.0, 0.25, 0.5, 0.5000001, 1.0, 1.5, 2.49999, 2.5, 9.5, 9.75, 10.0,
        10.5, 11.0, 1e12,
    ];
    for &lo in &values {
        for &hi in &values {
            if lo <= hi {
                assert_eq!(
                    centre_range(lo, hi, 10),
                    reference(lo, hi, 10),
                    "{lo}..{hi}"
                );
            }
        }
    }
}
