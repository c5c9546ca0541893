use std::collections::HashMap;

use glam::{DMat3, DVec2, DVec3};

use super::*;
use crate::geometry::rotation_xyz_deg;
use crate::phantom::TriMesh;
use crate::random::{stream, symmetric};
use crate::trace::raster::tests::{beamline, femoral_mesh, segment_distance};
use crate::trace::{render_binary, render_binary_traced};

/// Pixel centres this close to a projected silhouette edge (px) are not compared: there the length
/// goes to zero and a rounding residue is all that is left of it.
const SILHOUETTE_PX: f64 = 1e-6;

/// Agreement required between scan conversion and the f64 tracer, relative.
const RELATIVE: f64 = 1e-6;

fn frame(n: u32, pitch_mm: f64) -> DetectorFrame {
    DetectorFrame {
        pose: Pose::IDENTITY,
        pixels: [n, n],
        pixel_pitch_mm: [pitch_mm, pitch_mm],
    }
}

/// A closed mesh of a convex polyhedron around the origin from its faces (vertex loops), each
/// triangle turned to face outward.
fn convex(vertices: Vec<[f32; 3]>, loops: &[&[u32]]) -> TriMesh {
    let v = |k: u32| DVec3::from_array(vertices[k as usize].map(f64::from));
    let mut triangles = Vec::new();
    for face in loops {
        for k in 1..face.len() - 1 {
            let (a, b, c) = (face[0], face[k], face[k + 1]);
            let outward = (v(b) - v(a)).cross(v(c) - v(a)).dot(v(a) + v(b) + v(c)) > 0.0;
            triangles.push(if outward { [a, b, c] } else { [a, c, b] });
        }
    }
    TriMesh {
        vertices,
        triangles,
    }
}

/// A cube of half-size `half_mm`: 8 vertices, 12 triangles.
fn cube(half_mm: f32) -> TriMesh {
    let vertices = (0..8)
        .map(|k| [1, 2, 4].map(|bit| if k & bit == 0 { -half_mm } else { half_mm }))
        .collect();
    let loops: [&[u32]; 6] = [
        &[0, 2, 6, 4],
        &[1, 3, 7, 5],
        &[0, 1, 5, 4],
        &[2, 3, 7, 6],
        &[0, 1, 3, 2],
        &[4, 5, 7, 6],
    ];
    convex(vertices, &loops)
}

/// A torus around local z (a non-convex solid: a line through the ring's plane crosses the
/// surface four times), wound outward.
fn torus(major_mm: f64, minor_mm: f64, around: u32, tube: u32) -> TriMesh {
    let mut vertices = Vec::new();
    for i in 0..around {
        let u = std::f64::consts::TAU * i as f64 / around as f64;
        for j in 0..tube {
            let v = std::f64::consts::TAU * j as f64 / tube as f64;
            let rho = major_mm + minor_mm * v.cos();
            vertices.push([
                (rho * u.cos()) as f32,
                (rho * u.sin()) as f32,
                (minor_mm * v.sin()) as f32,
            ]);
        }
    }
    let k = |i: u32, j: u32| (i % around) * tube + j % tube;
    let mut triangles = Vec::new();
    for i in 0..around {
        for j in 0..tube {
            let (a, b, c, d) = (k(i, j), k(i + 1, j), k(i + 1, j + 1), k(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    let mut mesh = TriMesh {
        vertices,
        triangles,
    };
    if mesh.signed_volume_mm3() < 0.0 {
        mesh.flip_winding();
    }
    mesh
}

fn random_pose(rng: &mut rand_chacha::ChaCha8Rng) -> Pose {
    Pose {
        position_mm: DVec3::new(
            symmetric(rng, 10.0),
            symmetric(rng, 10.0),
            symmetric(rng, 10.0),
        ),
        rotation: rotation_xyz_deg([
            symmetric(rng, 180.0),
            symmetric(rng, 180.0),
            symmetric(rng, 180.0),
        ]),
    }
}

/// Marks the pixels whose centre lies within [`SILHOUETTE_PX`] of a projected silhouette edge:
/// an edge whose two triangles do not both face the source or both face away.
fn near_silhouette(frame: &DetectorFrame, source: DVec3, mesh: &MeshBvh, pose: Pose) -> Vec<bool> {
    let uv = raster::project_vertices(frame, source, &mesh.vertices_mm, pose).expect("projects");
    let mut facing: HashMap<(u32, u32), Vec<i8>> = HashMap::new();
    for t in &mesh.faces {
        let [a, b, c] = t.map(|k| uv[k as usize]);
        let area = (b - a).perp_dot(c - a);
        let side = i8::from(area > 0.0) - i8::from(area < 0.0);
        for (p, q) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            facing.entry((p.min(q), p.max(q))).or_default().push(side);
        }
    }
    let [w, h] = frame.pixels;
    let mut mask = vec![false; (w * h) as usize];
    for ((p, q), sides) in facing {
        if sides.len() == 2 && sides[0] == sides[1] && sides[0] != 0 {
            continue;
        }
        let (a, b) = (uv[p as usize], uv[q as usize]);
        let (lo, hi) = (a.min(b) - SILHOUETTE_PX, a.max(b) + SILHOUETTE_PX);
        let Some((i0, i1)) = centre_range(lo.x, hi.x, w) else {
            continue;
        };
        let Some((j0, j1)) = centre_range(lo.y, hi.y, h) else {
            continue;
        };
        for j in j0..j1 {
            for i in i0..i1 {
                let centre = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
                if segment_distance(centre, a, b) <= SILHOUETTE_PX {
                    mask[(j * w as i64 + i) as usize] = true;
                }
            }
        }
    }
    mask
}

/// Scan conversion against the f64 tracer (to [`RELATIVE`]) and against binary mode (a positive
/// length exactly where binary mode fills) over the whole detector, except the pixel centres
/// next to a silhouette. Returns the number of pixels with a positive length and the number
/// skipped.
fn compare(
    label: &str,
    mesh: &MeshBvh,
    frame: &DetectorFrame,
    source: DVec3,
    pose: Pose,
) -> (usize, usize) {
    let object = Object::Mesh { bvh: mesh, pose };
    let fast = path_lengths(frame, source, &object).expect("the shadow is on the detector");
    let slow = path_lengths_traced(frame, source, &object).expect("the shadow is on the detector");
    let binary = render_binary(frame, source, std::slice::from_ref(&object), 1);
    let near = near_silhouette(frame, source, mesh, pose);
    let [w, h] = frame.pixels;
    let (mut covered, mut skipped, mut worst) = (0, 0, 0.0f64);
    for j in 0..h {
        for i in 0..w {
            let k = (j * w + i) as usize;
            if near[k] {
                skipped += 1;
                continue;
            }
            let (a, b) = (fast.at(i, j), slow.at(i, j));
            let error = (a - b).abs();
            assert!(
                error <= RELATIVE * a.max(b),
                "{label}: pixel ({i}, {j}): scan {a} mm, traced {b} mm"
            );
            if a > 0.0 {
                worst = worst.max(error / a);
            }
            assert_eq!(
                binary[k] > 0,
                a > 0.0,
                "{label}: pixel ({i}, {j}): binary {} but length {a} mm",
                binary[k]
            );
            covered += usize::from(a > 0.0);
        }
    }
    eprintln!(
        "{label}: {covered} px with a path length, {skipped} px skipped next to a silhouette, worst relative difference {worst:.1e}"
    );
    (covered, skipped)
}

#[test]
fn sphere_lengths_are_twice_the_half_chord() {
    let f = frame(120, 0.25);
    let source = DVec3::new(3.0, -2.0, 1000.0);
    let (centre, r) = (DVec3::new(1.0, 2.0, 400.0), 6.0);
    let object = Object::Sphere {
        centre_mm: centre,
        radius_mm: r,
    };
    let lengths = path_lengths(&f, source, &object).unwrap();
    let mut inside = 0;
    for j in 0..120 {
        for i in 0..120 {
            let d = f.pixel_centre_world(i, j) - source;
            let closest = source + d * ((centre - source).dot(d) / d.length_squared());
            let b = (closest - centre).length();
            let expected = if b < r {
                2.0 * (r * r - b * b).sqrt()
            } else {
                0.0
            };
            assert!(
                (lengths.at(i, j) - expected).abs() < 1e-9,
                "({i}, {j}): {} vs {expected}",
                lengths.at(i, j)
            );
            inside += usize::from(expected > 0.0);
        }
    }
    assert!(inside > 5000);
    assert_eq!(Some(lengths), path_lengths_traced(&f, source, &object));
}

#[test]
fn a_plate_is_its_thickness_over_the_cosine() {
    // A 60 × 40 × 6 mm plate at z = 300 under a source at z = 1000: a ray through both large
    // faces runs 6·|d|/|d_z| inside it; one passing beside it, nothing.
    let f = frame(101, 1.0);
    let source = DVec3::new(5.0, -3.0, 1000.0);
    let plate = Object::Cuboid {
        pose: Pose::from_position_euler_deg([0.0, 0.0, 300.0], [0.0, 0.0, 0.0]),
        half_size_mm: DVec3::new(30.0, 20.0, 3.0),
    };
    let lengths = path_lengths(&f, source, &plate).unwrap();
    let (mut through, mut beside) = (0, 0);
    for j in 0..101 {
        for i in 0..101 {
            let d = f.pixel_centre_world(i, j) - source;
            let at = |z: f64| source + d * ((z - source.z) / d.z);
            let inside = |p: DVec3| p.x.abs() < 30.0 && p.y.abs() < 20.0;
            let outside = |p: DVec3| p.x.abs() > 30.0 || p.y.abs() > 20.0;
            let (top, bottom) = (at(303.0), at(297.0));
            if inside(top) && inside(bottom) {
                let expected = 6.0 * d.length() / d.z.abs();
                assert!((lengths.at(i, j) - expected).abs() < 1e-9);
                through += 1;
            } else if outside(top) && outside(bottom) && (top.x - bottom.x).abs() < 1.0 {
                // Both beside the plate on the same side (the ray moves < 1 mm across it).
                if (top.x.abs() > 30.0 && top.x.signum() == bottom.x.signum())
                    || (top.y.abs() > 20.0 && top.y.signum() == bottom.y.signum())
                {
                    assert_eq!(lengths.at(i, j), 0.0);
                    beside += 1;
                }
            }
        }
    }
    assert!(through > 1000 && beside > 1000, "{through} {beside}");
}

#[test]
fn a_cylinder_across_the_beam_is_its_diameter_over_the_cosine() {
    // Axis along world x (local z), local x along world z: the rays of the middle row (y = 0)
    // pass through the axis and run 2a·|d|/|d_z| inside, a = radii_mm[0].
    let f = frame(101, 0.5);
    let source = DVec3::new(0.0, 0.0, 1000.0);
    let (a, b) = (12.0, 7.0);
    let cylinder = Object::EllipticCylinder {
        pose: Pose {
            position_mm: DVec3::new(0.0, 0.0, 300.0),
            rotation: DMat3::from_cols(DVec3::Z, -DVec3::Y, DVec3::X),
        },
        radii_mm: [a, b],
        half_length_mm: 100.0,
    };
    let lengths = path_lengths(&f, source, &cylinder).unwrap();
    for i in 0..101 {
        let d = f.pixel_centre_world(i, 50) - source;
        let expected = 2.0 * a * d.length() / d.z.abs();
        assert!((lengths.at(i, 50) - expected).abs() < 1e-9, "{i}");
    }
    // The middle column (x = 0) sees the ellipse's other semi-axis: the vertical ray 2a, the rays
    // beyond the shadow of b, nothing.
    assert!((lengths.at(50, 50) - 2.0 * a).abs() < 1e-12);
    assert_eq!(lengths.at(50, 0), 0.0);
}

#[test]
fn analytic_solids_fill_the_same_pixels_in_binary_mode_and_both_projectors_agree() {
    let f = frame(160, 0.5);
    let source = DVec3::new(4.0, 7.0, 1100.0);
    let objects = [
        Object::Cuboid {
            pose: Pose::from_position_euler_deg([-5.0, 3.0, 350.0], [25.0, -40.0, 70.0]),
            half_size_mm: DVec3::new(15.0, 8.0, 2.5),
        },
        Object::EllipticCylinder {
            pose: Pose::from_position_euler_deg([6.0, -4.0, 420.0], [60.0, 10.0, -20.0]),
            radii_mm: [14.0, 9.0],
            half_length_mm: 22.0,
        },
    ];
    for object in &objects {
        let single = std::slice::from_ref(object);
        let binary = render_binary(&f, source, single, 1);
        assert_eq!(binary, render_binary_traced(&f, source, single, 1));
        let lengths = path_lengths(&f, source, object).unwrap();
        assert_eq!(
            Some(&lengths),
            path_lengths_traced(&f, source, object).as_ref()
        );
        let mut covered = 0;
        for j in 0..160 {
            for i in 0..160 {
                let l = lengths.at(i, j);
                assert_eq!(binary[(j * 160 + i) as usize] == 1, l > 0.0, "({i}, {j})");
                covered += usize::from(l > 0.0);
            }
        }
        assert!(covered > 2000, "{covered}");
    }
}

/// [`compare`] at `poses` random beamlines (an `n × n` detector) and mesh poses.
fn compare_at_random_poses(label: &str, mesh: &MeshBvh, n: u32, poses: usize) {
    let mut rng = stream(&format!("path length {label}"));
    for k in 0..poses {
        let (f, source) = beamline(&mut rng, n, [0.0, 0.0]);
        let pose = random_pose(&mut rng);
        let (covered, skipped) = compare(&format!("{label} {k}"), mesh, &f, source, pose);
        assert!(covered > 10_000 && skipped < covered / 1000);
    }
}

#[test]
fn a_cube_mesh_matches_the_tracer() {
    let bvh = MeshBvh::new(&cube(20.0));
    assert!(bvh.is_closed());
    compare_at_random_poses("cube", &bvh, 300, 4);
    // Axis-aligned, the source on the cube's axis: edges project through rows of pixel centres.
    let (f, source) = (frame(200, 0.5), DVec3::new(0.0, 0.0, 1000.0));
    let pose = Pose::from_position_euler_deg([0.0, 0.0, 400.0], [0.0, 0.0, 0.0]);
    let (covered, _) = compare("cube aligned", &bvh, &f, source, pose);
    assert!(covered > 10_000);
    // The vertical central ray: 40 mm.
    let l = path_lengths(&f, source, &Object::Mesh { bvh: &bvh, pose }).unwrap();
    assert!((l.at(100, 100) - 40.0 * (1.0 + (0.25f64 / 1000.0).powi(2) * 2.0).sqrt()).abs() < 1e-9);
}

#[test]
fn a_torus_with_two_entries_and_exits_matches_the_tracer() {
    let bvh = MeshBvh::new(&torus(30.0, 8.0, 64, 24));
    assert!(bvh.is_closed());
    let mut rng = stream("path length torus");
    for k in 0..3 {
        let (f, source) = beamline(&mut rng, 320, [0.0, 0.0]);
        // The ring's plane within 20° of the beam: many rays cross both arms.
        let pose = Pose {
            position_mm: DVec3::new(symmetric(&mut rng, 5.0), symmetric(&mut rng, 5.0), 0.0),
            rotation: rotation_xyz_deg([
                90.0 + symmetric(&mut rng, 20.0),
                0.0,
                symmetric(&mut rng, 180.0),
            ]),
        };
        let (covered, skipped) = compare(&format!("torus {k}"), &bvh, &f, source, pose);
        assert!(covered > 10_000 && skipped < covered / 1000);
        let four = (0..320 * 320)
            .step_by(7)
            .filter(|&k| {
                let d = f.pixel_centre_world(k % 320, k / 320) - source;
                let ts = bvh.line_crossings(pose.to_local(source), pose.rotation.transpose() * d);
                ts.len() == 4
            })
            .count();
        assert!(
            four > 10,
            "torus {k}: {four} rays with two entries and two exits"
        );
    }
}

#[test]
fn the_femoral_component_matches_the_tracer() {
    let bvh = MeshBvh::new(&femoral_mesh());
    compare_at_random_poses("femoral", &bvh, 400, 3);
    let mut rng = stream("path length femoral clipped");
    // The shadow crossing the detector's borders.
    let (f, source) = beamline(&mut rng, 300, [40.0, 40.0]);
    compare("femoral clipped", &bvh, &f, source, random_pose(&mut rng));
}

#[test]
fn an_inward_wound_mesh_gives_the_same_lengths() {
    let mut inward = torus(30.0, 8.0, 32, 12);
    let outward = MeshBvh::new(&inward);
    inward.flip_winding();
    let inward = MeshBvh::new(&inward);
    assert_eq!(inward.facing, raster::Faces::Inward);
    let (f, source) = (frame(200, 0.5), DVec3::new(2.0, 1.0, 1000.0));
    let pose = Pose::from_position_euler_deg([1.0, -2.0, 300.0], [80.0, 10.0, 5.0]);
    let a = path_lengths(
        &f,
        source,
        &Object::Mesh {
            bvh: &outward,
            pose,
        },
    );
    let b = path_lengths(&f, source, &Object::Mesh { bvh: &inward, pose });
    assert!(
        a.as_ref()
            .is_some_and(|l| l.length_mm.iter().any(|&x| x > 10.0))
    );
    assert_eq!(a, b);
}

#[test]
fn a_mesh_that_does_not_project_or_is_open_is_traced() {
    let f = frame(120, 0.5);
    let source = DVec3::new(0.0, 0.0, 200.0);
    let sphere = MeshBvh::new(&TriMesh::uv_sphere(8.0, 32, 64));
    // Straddling the source's plane (the source inside the sphere), and the detector plane.
    for z in [198.0, 2.0] {
        let pose = Pose::from_position_euler_deg([3.0, 4.0, z], [0.0, 0.0, 0.0]);
        assert!(raster::project_vertices(&f, source, &sphere.vertices_mm, pose).is_none());
        let object = Object::Mesh { bvh: &sphere, pose };
        let lengths = path_lengths(&f, source, &object).unwrap();
        assert_eq!(
            Some(&lengths),
            path_lengths_traced(&f, source, &object).as_ref()
        );
        // Close to the exact sphere's chords, clipped to the segment (facets: < 0.1 mm).
        let exact = path_lengths(
            &f,
            source,
            &Object::Sphere {
                centre_mm: DVec3::new(3.0, 4.0, z),
                radius_mm: 8.0,
            },
        )
        .unwrap();
        // Away from the rim (line distance b < 0.8 r), where a facet moves the surface by more.
        let centre = DVec3::new(3.0, 4.0, z);
        let mut compared = 0;
        for j in 0..120 {
            for i in 0..120 {
                let (a, b) = (lengths.at(i, j), exact.at(i, j));
                let d = f.pixel_centre_world(i, j) - source;
                let distance = (centre - source).cross(d).length() / d.length();
                if b > 1.0 && distance < 6.4 {
                    assert!((a - b).abs() < 0.1, "z {z} ({i}, {j}): {a} vs {b}");
                    compared += 1;
                }
            }
        }
        assert!(compared > 100, "{compared}");
    }
    // An open bowl: not closed, so traced.
    let mut bowl = TriMesh::uv_sphere(10.0, 16, 32);
    bowl.triangles
        .retain(|t| t.iter().map(|&k| bowl.vertices[k as usize][2]).sum::<f32>() > 0.0);
    let bowl = MeshBvh::new(&bowl);
    assert!(!bowl.is_closed());
    let object = Object::Mesh {
        bvh: &bowl,
        pose: Pose::from_position_euler_deg([0.0, 0.0, 100.0], [0.0, 0.0, 0.0]),
    };
    assert_eq!(
        path_lengths(&f, source, &object),
        path_lengths_traced(&f, source, &object)
    );
}

#[test]
fn a_shadow_off_the_detector_gives_none_and_at_is_zero_outside() {
    let f = frame(50, 0.5);
    let source = DVec3::new(0.0, 0.0, 1000.0);
    let far = Object::Sphere {
        centre_mm: DVec3::new(500.0, 0.0, 500.0),
        radius_mm: 5.0,
    };
    assert_eq!(path_lengths(&f, source, &far), None);
    let bvh = MeshBvh::new(&cube(5.0));
    let far = Object::Mesh {
        bvh: &bvh,
        pose: Pose::from_position_euler_deg([500.0, 0.0, 500.0], [0.0, 0.0, 0.0]),
    };
    assert_eq!(path_lengths(&f, source, &far), None);
    let l = PathLengths {
        columns: 2..4,
        rows: 3..4,
        length_mm: vec![1.0, 2.0],
    };
    assert_eq!(
        (l.at(3, 3), l.at(1, 3), l.at(2, 4), l.at(4, 3)),
        (2.0, 0.0, 0.0, 0.0)
    );
}
