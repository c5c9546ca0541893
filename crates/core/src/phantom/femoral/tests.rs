//! Tests of the femoral component: closedness, size, beads, determinism, the shipped model.

use std::sync::OnceLock;

use glam::DVec3;

use super::*;
use crate::geometry::{DetectorFrame, Pose, rotation_xyz_deg};
use crate::trace::{MeshBvh, Object, render_binary};

/// The component, built once for all tests.
fn component() -> &'static FemoralComponent {
    static C: OnceLock<FemoralComponent> = OnceLock::new();
    C.get_or_init(femoral_component)
}

fn vertex(m: &TriMesh, i: u32) -> DVec3 {
    DVec3::from_array(m.vertices[i as usize].map(f64::from))
}

/// Number of triangles a ray from `origin` along `dir` crosses (Möller–Trumbore, f64).
fn crossings(m: &TriMesh, origin: DVec3, dir: DVec3) -> usize {
    m.triangles
        .iter()
        .filter(|t| {
            let [a, b, c] = t.map(|i| vertex(m, i));
            let (e1, e2) = (b - a, c - a);
            let pv = dir.cross(e2);
            let det = e1.dot(pv);
            if det.abs() < 1e-12 {
                return false;
            }
            let tv = origin - a;
            let u = tv.dot(pv) / det;
            let qv = tv.cross(e1);
            let v = dir.dot(qv) / det;
            let t = e2.dot(qv) / det;
            (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0 && t > 0.0
        })
        .count()
}

/// Eigenvalues of a symmetric 3×3 matrix by cyclic Jacobi rotations, ascending.
fn symmetric_eigenvalues(mut a: [[f64; 3]; 3]) -> [f64; 3] {
    for _ in 0..50 {
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() < 1e-15 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let (c, s) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
            a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
        }
    }
    let mut e = [a[0][0], a[1][1], a[2][2]];
    e.sort_by(f64::total_cmp);
    e
}

#[test]
fn mesh_is_closed_outward_genus_zero_and_connected() {
    let m = &component().mesh;
    m.check_closed().unwrap();
    let volume = m.signed_volume_mm3();
    assert!(
        (25_000.0..60_000.0).contains(&volume),
        "volume {volume} mm³"
    );
    // Euler characteristic V − E + F = 2 for one closed genus-0 surface (E = 3F/2).
    let chi =
        m.vertices.len() as i64 - (3 * m.triangles.len() / 2) as i64 + m.triangles.len() as i64;
    assert_eq!(chi, 2, "Euler characteristic");
    // One connected piece (union-find over triangle vertices).
    let mut parent: Vec<u32> = (0..m.vertices.len() as u32).collect();
    fn find(p: &mut [u32], mut i: u32) -> u32 {
        while p[i as usize] != i {
            p[i as usize] = p[p[i as usize] as usize];
            i = p[i as usize];
        }
        i
    }
    for t in &m.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2])] {
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            parent[ra as usize] = rb;
        }
    }
    let roots = (0..m.vertices.len() as u32)
        .filter(|&i| find(&mut parent, i) == i)
        .count();
    assert_eq!(roots, 1, "connected components");
}

#[test]
fn size_frame_and_triangle_count_are_in_range() {
    let m = &component().mesh;
    let (lo, hi) = m.bounds_mm();
    let size = hi - lo;
    assert!(
        (60.0..=75.0).contains(&size.x) && (size.x - 68.0).abs() < 2.0,
        "ML {size}"
    );
    assert!((55.0..=65.0).contains(&size.z), "AP {size}");
    assert!((50.0..=60.0).contains(&size.y), "PD {size}");
    assert!(
        ((lo + hi) * 0.5).length() < 1e-4,
        "origin must be the bounding-box centre: {lo} {hi}"
    );
    assert!(
        (5_000..=100_000).contains(&m.triangles.len()),
        "{} triangles",
        m.triangles.len()
    );
    // The anterior flange is at +z and reaches highest (+y); the notch leaves x = 0 open at the back.
    let top: Vec<DVec3> = (0..m.vertices.len() as u32)
        .map(|i| vertex(m, i))
        .filter(|p| p.y > hi.y - 1.0)
        .collect();
    assert!(
        top.iter().all(|p| p.z > 0.0),
        "the flange top must be anterior"
    );
    let dir = DVec3::new(0.3, 0.8, 0.52);
    for x in [-20.0, 20.0] {
        assert_eq!(
            crossings(m, DVec3::new(x, lo.y + 25.0, lo.z + 4.0), dir) % 2,
            1,
            "posterior condyle at x = {x}"
        );
    }
    assert_eq!(
        crossings(m, DVec3::new(0.0, lo.y + 25.0, lo.z + 4.0), dir) % 2,
        0,
        "the notch must separate the condyles"
    );
}

#[test]
fn beads_are_outside_clear_of_the_metal_and_well_spread() {
    let c = component();
    let m = &c.mesh;
    assert!((4..=6).contains(&c.beads.len()));
    for (i, bead) in c.beads.iter().enumerate() {
        assert_eq!(bead.id, format!("K{}", i + 1));
        assert_eq!(bead.diameter_mm, 1.0);
        let p = DVec3::from_array(bead.position_mm);
        let d = m
            .triangles
            .iter()
            .map(|t| {
                crate::geometry::point_triangle_distance(
                    p,
                    vertex(m, t[0]),
                    vertex(m, t[1]),
                    vertex(m, t[2]),
                )
            })
            .fold(f64::INFINITY, f64::min);
        let gap = d - bead.diameter_mm / 2.0;
        eprintln!(
            "{} at {:?}: surface {gap:.3} mm from the metal",
            bead.id, bead.position_mm
        );
        // In the bone bed proximal to the component: clear of the metal, but not far from it.
        assert!(
            (1.5..=40.0).contains(&gap),
            "{}: bead surface {gap} mm from the metal",
            bead.id
        );
        for dir in [DVec3::new(0.3, 0.8, 0.52), DVec3::new(-0.61, -0.2, 0.77)] {
            assert_eq!(
                crossings(m, p, dir) % 2,
                0,
                "{} is inside the metal",
                bead.id
            );
        }
    }
    let n = c.beads.len() as f64;
    let centroid = c
        .beads
        .iter()
        .map(|b| DVec3::from_array(b.position_mm))
        .sum::<DVec3>()
        / n;
    let mut cov = [[0.0; 3]; 3];
    for b in &c.beads {
        let d = (DVec3::from_array(b.position_mm) - centroid).to_array();
        for r in 0..3 {
            for s in 0..3 {
                cov[r][s] += d[r] * d[s] / n;
            }
        }
    }
    let e = symmetric_eigenvalues(cov);
    eprintln!(
        "bead covariance eigenvalues {e:?} mm², smallest/largest {:.3}",
        e[0] / e[2]
    );
    assert!(e[0] / e[2] > 0.15, "bead spread eigenvalues {e:?}");
    assert!(
        e[0] > 25.0,
        "beads must spread at least 5 mm (RMS) in every direction: {e:?} mm²"
    );
}

/// The two views of the biplanar scenario: source, and detector pose (1800 mm source-to-image).
fn views() -> [(&'static str, DVec3, Pose); 2] {
    [
        (
            "AP",
            DVec3::new(0.0, 0.0, 1300.0),
            Pose {
                position_mm: DVec3::new(0.0, 0.0, -500.0),
                rotation: rotation_xyz_deg([0.0; 3]),
            },
        ),
        (
            "lateral",
            DVec3::new(1300.0, 0.0, 0.0),
            Pose {
                position_mm: DVec3::new(-500.0, 0.0, 0.0),
                rotation: rotation_xyz_deg([0.0, 90.0, 0.0]),
            },
        ),
    ]
}

/// Each bead's projected centre (continuous pixel coordinates of `frame`) and disc radius (px).
fn bead_discs(frame: &DetectorFrame, source: DVec3, pose: &Pose) -> Vec<(glam::DVec2, f64)> {
    let s = frame.pose.to_local(source).z;
    component()
        .beads
        .iter()
        .map(|b| {
            let world = pose.to_world(DVec3::from_array(b.position_mm));
            let uv = frame
                .project(source, world)
                .expect("bead between source and detector");
            let magnification = s / (s - frame.pose.to_local(world).z);
            (
                uv,
                b.diameter_mm / 2.0 * magnification / frame.pixel_pitch_mm[0],
            )
        })
        .collect()
}

/// Marker-based RSA needs every bead as a separate blob in both views, for every pose the
/// scenarios draw (±10° about each axis): render the metal alone with the project's tracer at
/// 0.1 mm pixels, over rotations of −12°, 0 and +12° about each local axis (27 poses), and check
/// each bead's projected disc against the metal's shadow and against the other beads' discs.
#[test]
fn beads_show_as_separate_blobs_in_both_views_at_any_pose() {
    const PITCH: f64 = 0.1;
    /// Half-size of the window rendered around each bead, px (the gap is measured up to this).
    const HALF: i64 = 40;
    let bvh = MeshBvh::new(&component().mesh);
    let angles = [-12.0, 0.0, 12.0];
    let (mut mesh_gap, mut bead_gap) = (
        (f64::INFINITY, String::new()),
        (f64::INFINITY, String::new()),
    );
    for (view, source, detector) in views() {
        // The 600² detector of 0.1 mm covers only 60 mm, less than the component's shadow: render
        // a window of the same pixel grid (extended across the detector plane) around each bead.
        let frame = DetectorFrame {
            pose: detector,
            pixels: [600, 600],
            pixel_pitch_mm: [PITCH, PITCH],
        };
        for a in angles {
            for b in angles {
                for g in angles {
                    let pose = Pose {
                        position_mm: DVec3::ZERO,
                        rotation: rotation_xyz_deg([a, b, g]),
                    };
                    let discs = bead_discs(&frame, source, &pose);
                    for (k, &(c, r)) in discs.iter().enumerate() {
                        let (i0, j0) = (c.x.floor() as i64 - HALF, c.y.floor() as i64 - HALF);
                        let n = 2 * HALF as u32;
                        let centre = frame.pixel_local((i0 + HALF) as f64, (j0 + HALF) as f64);
                        let window = DetectorFrame {
                            pose: Pose {
                                position_mm: detector.to_world(centre),
                                rotation: detector.rotation,
                            },
                            pixels: [n, n],
                            pixel_pitch_mm: [PITCH, PITCH],
                        };
                        let image =
                            render_binary(&window, source, &[Object::Mesh { bvh: &bvh, pose }], 1);
                        // Distance from the disc's edge to the nearest metal pixel centre, px.
                        let gap = image
                            .iter()
                            .enumerate()
                            .filter(|(_, p)| **p != 0)
                            .map(|(idx, _)| {
                                let (i, j) = (
                                    (idx % n as usize) as i64 + i0,
                                    (idx / n as usize) as i64 + j0,
                                );
                                (glam::DVec2::new(i as f64 + 0.5, j as f64 + 0.5) - c).length() - r
                            })
                            .fold(HALF as f64 - r, f64::min);
                        let id = &component().beads[k].id;
                        // Dilated by one pixel, the disc must still touch no metal pixel.
                        assert!(
                            gap > 1.0,
                            "{view} view, rotation [{a}, {b}, {g}]°: {id} touches the metal ({gap:.1} px)"
                        );
                        if gap < mesh_gap.0 {
                            mesh_gap =
                                (gap, format!("{id}, {view} view, rotation [{a}, {b}, {g}]°"));
                        }
                    }
                }
            }
        }
        // Bead against bead is exact geometry: check a finer grid of rotations (every 3°).
        let fine: Vec<f64> = (0..9).map(|k| -12.0 + 3.0 * k as f64).collect();
        for &a in &fine {
            for &b in &fine {
                for &g in &fine {
                    let pose = Pose {
                        position_mm: DVec3::ZERO,
                        rotation: rotation_xyz_deg([a, b, g]),
                    };
                    let discs = bead_discs(&frame, source, &pose);
                    for (k, &(ck, rk)) in discs.iter().enumerate() {
                        for (l, &(cl, rl)) in discs.iter().enumerate().skip(k + 1) {
                            let gap = (ck - cl).length() - rk - rl;
                            let ids = (&component().beads[k].id, &component().beads[l].id);
                            // Blob surfaces at least 2 mm apart on the detector.
                            assert!(
                                gap * PITCH >= 2.0,
                                "{view} view, rotation [{a}, {b}, {g}]°: {} and {} are {gap:.1} px apart",
                                ids.0,
                                ids.1
                            );
                            if gap < bead_gap.0 {
                                bead_gap = (
                                    gap,
                                    format!(
                                        "{} and {}, {view} view, rotation [{a}, {b}, {g}]°",
                                        ids.0, ids.1
                                    ),
                                );
                            }
                        }
                    }
                }
            }
        }
    }
    eprintln!(
        "smallest gap bead disc to metal: {:.1} px = {:.2} mm on the detector ({})",
        mesh_gap.0,
        mesh_gap.0 * PITCH,
        mesh_gap.1
    );
    eprintln!(
        "smallest gap between bead discs: {:.1} px = {:.2} mm on the detector ({})",
        bead_gap.0,
        bead_gap.0 * PITCH,
        bead_gap.1
    );
    // A margin for the scenarios' position randomisation (±10 mm) and detector jitter.
    assert!(
        mesh_gap.0 >= 10.0,
        "smallest bead-to-metal gap {:.1} px ({})",
        mesh_gap.0,
        mesh_gap.1
    );
}

#[test]
fn the_component_is_deterministic() {
    assert_eq!(&femoral_component(), component());
}

#[test]
fn the_shipped_model_matches_the_code() {
    let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let path = root.join("scenarios/models/femoral_component.glb");
    let expected = crate::phantom::mesh_io::glb_bytes(&component().mesh).unwrap();
    // The golden scenarios keep their own copy, inside their folder (meshes are read only from a
    // scenario's own folder unless --allow-dir says otherwise).
    for file in [
        "scenarios/models/femoral_component.glb",
        "scenarios/golden/models/femoral_component.glb",
    ] {
        let p = root.join(file);
        let shipped = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert!(
            shipped == expected,
            "{} is out of date: run `cargo run --release --example femoral_component -- {file}`",
            p.display()
        );
    }
    // And it loads back (glTF metres → mm) as the same closed surface.
    let loaded = crate::phantom::mesh_io::load_mesh(&path, 1000.0).unwrap();
    loaded.check_closed().unwrap();
    assert_eq!(loaded.triangles, component().mesh.triangles);
}
