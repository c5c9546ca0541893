//! Tests of the distal femur: closedness, size, fit on the component, nesting, beads, the
//! shipped models.

use std::sync::OnceLock;

use glam::DVec3;
use sha2::{Digest, Sha256};

use super::*;
use crate::geometry::point_triangle_distance;
use crate::phantom::femoral::{FemoralComponent, femoral_component};
use crate::trace::MeshBvh;

fn femur() -> &'static DistalFemur {
    static F: OnceLock<DistalFemur> = OnceLock::new();
    F.get_or_init(distal_femur)
}

fn component() -> &'static FemoralComponent {
    static C: OnceLock<FemoralComponent> = OnceLock::new();
    C.get_or_init(femoral_component)
}

fn vertices(m: &TriMesh) -> impl Iterator<Item = DVec3> + '_ {
    m.vertices
        .iter()
        .map(|v| DVec3::from_array(v.map(f64::from)))
}

/// Whether `p` is inside the closed mesh of `bvh` (parity of crossings along a long segment in
/// a direction no grid axis or diagonal shares).
fn inside(bvh: &MeshBvh, p: DVec3) -> bool {
    let dir = DVec3::new(0.3127, 0.8311, 0.4597) * 1000.0;
    bvh.segment_crossings(p, dir).len() % 2 == 1
}

/// Triangles bucketed in a uniform grid, for distances up to a small radius.
struct Nearby {
    corners: Vec<[DVec3; 3]>,
    lo: DVec3,
    cell_mm: f64,
    dims: [usize; 3],
    buckets: Vec<Vec<u32>>,
}

impl Nearby {
    fn new(m: &TriMesh, cell_mm: f64) -> Nearby {
        let (lo, hi) = m.bounds_mm();
        let lo = lo - DVec3::splat(cell_mm);
        let dims = ((hi - lo) / cell_mm)
            .ceil()
            .as_uvec3()
            .to_array()
            .map(|d| d as usize + 2);
        let mut buckets = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        let corners: Vec<[DVec3; 3]> = m
            .triangles
            .iter()
            .map(|t| t.map(|i| DVec3::from_array(m.vertices[i as usize].map(f64::from))))
            .collect();
        let cell = |p: DVec3| {
            ((p - lo) / cell_mm)
                .floor()
                .as_uvec3()
                .to_array()
                .map(|c| c as usize)
        };
        for (t, c) in corners.iter().enumerate() {
            let (a, b) = (
                cell(c[0].min(c[1]).min(c[2])),
                cell(c[0].max(c[1]).max(c[2])),
            );
            for k in a[2]..=b[2] {
                for j in a[1]..=b[1] {
                    for i in a[0]..=b[0] {
                        buckets[i + dims[0] * (j + dims[1] * k)].push(t as u32);
                    }
                }
            }
        }
        Nearby {
            corners,
            lo,
            cell_mm,
            dims,
            buckets,
        }
    }

    /// Distance from `p` to the nearest triangle, or `radius` if none is closer.
    fn distance_within(&self, p: DVec3, radius: f64) -> f64 {
        let cell = |p: DVec3, d: usize| {
            let c = ((p - self.lo) / self.cell_mm).floor();
            (c.to_array()[d].max(0.0) as usize).min(self.dims[d] - 1)
        };
        let (a, b) = (p - DVec3::splat(radius), p + DVec3::splat(radius));
        let mut best = radius;
        for k in cell(a, 2)..=cell(b, 2) {
            for j in cell(a, 1)..=cell(b, 1) {
                for i in cell(a, 0)..=cell(b, 0) {
                    for &t in &self.buckets[i + self.dims[0] * (j + self.dims[1] * k)] {
                        let [u, v, w] = self.corners[t as usize];
                        best = best.min(point_triangle_distance(p, u, v, w));
                    }
                }
            }
        }
        best
    }
}

/// Genus-0 connected closed surface check shared by both meshes.
fn euler_characteristic(m: &TriMesh) -> i64 {
    m.vertices.len() as i64 - (3 * m.triangles.len() / 2) as i64 + m.triangles.len() as i64
}

#[test]
fn both_surfaces_are_closed_outward_genus_zero_and_within_the_triangle_budget() {
    let f = femur();
    for (name, m) in [("cortical", &f.cortical), ("cancellous", &f.cancellous)] {
        m.check_closed().unwrap_or_else(|e| panic!("{name}: {e}"));
        let volume = m.signed_volume_mm3();
        eprintln!(
            "{name}: {} triangles, {} vertices, volume {volume:.0} mm³",
            m.triangles.len(),
            m.vertices.len()
        );
        assert!(volume > 50_000.0, "{name}: volume {volume} mm³");
        assert_eq!(
            euler_characteristic(m),
            2,
            "{name}: one closed genus-0 surface"
        );
        assert!(
            m.triangles.len() <= 80_000,
            "{name}: {} triangles",
            m.triangles.len()
        );
    }
}

/// Extents (x, z) of the vertices of `m` within 1 mm of height `y` (local frame).
fn slab_extent(m: &TriMesh, y: f64) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in vertices(m).filter(|p| (p.y - y).abs() < 1.0) {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    (lo, hi)
}

#[test]
fn dimensions_follow_the_anatomy() {
    let f = femur();
    let flange_top = component().mesh.bounds_mm().1.y;
    let (lo, hi) = f.cortical.bounds_mm();
    let size = hi - lo;
    eprintln!("cortical bounds {lo} … {hi}, size {size}");
    assert!((size.x - 66.0).abs() < 1.0, "medio-lateral {size}");
    assert!(
        (hi.y - flange_top - SHAFT_LENGTH_MM).abs() < 0.5,
        "the shaft must end {SHAFT_LENGTH_MM} mm above the flange top ({flange_top}): {hi}"
    );
    // The distal end rests on the distal cut, 9 mm + gap above the lowest point of the metal.
    let metal_lo = component().mesh.bounds_mm().0.y;
    assert!(
        (lo.y - metal_lo - 9.0 - GAP_MM).abs() < 0.01,
        "distal end {lo} vs metal {metal_lo}"
    );
    // Diaphysis, 30 mm below the top: 26–30 mm outer diameter, 4–6 mm cortex.
    let y = hi.y - 30.0;
    let (o_lo, o_hi) = slab_extent(&f.cortical, y);
    let (i_lo, i_hi) = slab_extent(&f.cancellous, y);
    let (outer, inner) = (o_hi - o_lo, i_hi - i_lo);
    eprintln!("diaphysis at y = {y:.1}: outer {outer}, inner {inner}");
    for d in [outer.x, outer.z] {
        assert!((26.0..=30.0).contains(&d), "diaphysis diameter {outer}");
    }
    for cortex in [
        i_lo.x - o_lo.x,
        o_hi.x - i_hi.x,
        i_lo.z - o_lo.z,
        o_hi.z - i_hi.z,
    ] {
        assert!(
            (4.0..=6.0).contains(&cortex),
            "diaphyseal cortex {cortex} mm"
        );
    }
    // Metaphysis, 6 mm above the flange top: a thin cortex medially and laterally, the bone much
    // wider than the shaft.
    let y = flange_top + 6.0;
    let (o_lo, o_hi) = slab_extent(&f.cortical, y);
    let (i_lo, i_hi) = slab_extent(&f.cancellous, y);
    eprintln!("metaphysis at y = {y:.1}: outer {o_lo} … {o_hi}, inner {i_lo} … {i_hi}");
    assert!(
        o_hi.x - o_lo.x > 50.0,
        "metaphysis width {}",
        o_hi.x - o_lo.x
    );
    for cortex in [i_lo.x - o_lo.x, o_hi.x - i_hi.x] {
        assert!(
            (1.0..=1.5).contains(&cortex),
            "metaphyseal cortex {cortex} mm"
        );
    }
}

/// Points in the middle of the five bone cuts where the metal covers them, each with its cut's
/// normal (towards the metal), in the local frame; four per cut, clear of the notch and sides.
fn cut_probes() -> Vec<(&'static str, DVec3, DVec3)> {
    let (_, origin) = femoral_component_and_origin();
    let outer = profile::outer_contour();
    let cuts = profile::cut_planes(&outer);
    let c = profile::bone_box(&outer, 0.0).0;
    let mid = |a: [f64; 2], b: [f64; 2]| [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
    let on_anterior_at = |y: f64| [(cuts[0].1 - y * cuts[0].0[1]) / cuts[0].0[0], y];
    // Corners (profile::bone_box): 2 posterior/posterior chamfer, 3 posterior chamfer/distal,
    // 4 distal/anterior chamfer, 5 anterior chamfer/anterior.
    let points = [
        ("anterior", on_anterior_at(36.0), cuts[0].0),
        ("anterior chamfer", mid(c[4], c[5]), cuts[1].0),
        ("distal", mid(c[3], c[4]), cuts[2].0),
        ("posterior chamfer", mid(c[2], c[3]), cuts[3].0),
        ("posterior", [-cuts[4].1, 28.0], cuts[4].0),
    ];
    let mut probes = Vec::new();
    for (name, [z, y], [nz, ny]) in points {
        for x in [-25.0, -15.0, 15.0, 25.0] {
            probes.push((name, DVec3::new(x, y, z) - origin, DVec3::new(0.0, ny, nz)));
        }
    }
    probes
}

#[test]
fn the_bone_sits_on_the_five_cuts_with_the_gap() {
    let metal = MeshBvh::new(&component().mesh);
    let bone = MeshBvh::new(&femur().cortical);
    for (name, p, n) in cut_probes() {
        // From 2 mm inside the metal, 5 mm straight into the bone.
        let start = p + n * 2.0;
        let first = |bvh: &MeshBvh| {
            bvh.segment_crossings(start, -n * 5.0)
                .first()
                .map(|&t| f64::from(t) * 5.0)
                .unwrap_or(f64::NAN)
        };
        let (to_metal_face, to_bone) = (first(&metal), first(&bone));
        let gap = to_bone - to_metal_face;
        assert!(
            (to_metal_face - 2.0).abs() < 1e-3 && (gap - GAP_MM).abs() < 2e-3,
            "{name} cut at {p}: metal face {to_metal_face} mm, gap {gap} mm"
        );
    }
}

#[test]
fn the_bone_never_overlaps_the_metal() {
    let metal_mesh = &component().mesh;
    let bone_mesh = &femur().cortical;
    let (metal, bone) = (MeshBvh::new(metal_mesh), MeshBvh::new(bone_mesh));
    let near_metal = Nearby::new(metal_mesh, 2.0);
    let mut closest = (f64::INFINITY, DVec3::ZERO);
    for p in vertices(bone_mesh) {
        assert!(!inside(&metal, p), "bone vertex {p} is inside the metal");
        let d = near_metal.distance_within(p, 1.0);
        if d < closest.0 {
            closest = (d, p);
        }
    }
    eprintln!(
        "closest bone vertex to the metal: {:.4} mm at {}",
        closest.0, closest.1
    );
    // 0.1 mm on the flat cuts; at the edges between cuts the metal's chords (its 1 mm fillets
    // polygonised on a 0.9 mm grid) come a little closer.
    assert!(
        closest.0 >= 0.05,
        "bone vertex {} is {} mm from the metal",
        closest.1,
        closest.0
    );
    // And no point of the metal (vertices, triangle centroids) lies in the bone.
    for t in &metal_mesh.triangles {
        let [a, b, c] =
            t.map(|i| DVec3::from_array(metal_mesh.vertices[i as usize].map(f64::from)));
        for p in [a, (a + b + c) / 3.0] {
            assert!(!inside(&bone, p), "metal point {p} is inside the bone");
        }
    }
}

#[test]
fn the_cancellous_region_is_inside_with_a_wall_of_at_least_0_8_mm() {
    let f = femur();
    let cortical = MeshBvh::new(&f.cortical);
    let (near_outer, near_inner) = (
        Nearby::new(&f.cortical, 2.0),
        Nearby::new(&f.cancellous, 2.0),
    );
    let mut thinnest = (f64::INFINITY, DVec3::ZERO);
    for p in vertices(&f.cancellous) {
        assert!(
            inside(&cortical, p),
            "cancellous vertex {p} is outside the cortical surface"
        );
        let d = near_outer.distance_within(p, 1.0);
        if d < thinnest.0 {
            thinnest = (d, p);
        }
    }
    for p in vertices(&f.cortical) {
        let d = near_inner.distance_within(p, 1.0);
        if d < thinnest.0 {
            thinnest = (d, p);
        }
    }
    eprintln!("thinnest wall: {:.3} mm at {}", thinnest.0, thinnest.1);
    assert!(
        thinnest.0 >= 0.8,
        "wall of {} mm at {}",
        thinnest.0,
        thinnest.1
    );
}

#[test]
fn the_beads_lie_in_the_cancellous_bone_with_clearance() {
    let f = femur();
    let cancellous = MeshBvh::new(&f.cancellous);
    let near = Nearby::new(&f.cancellous, 2.0);
    for bead in &component().beads {
        let p = DVec3::from_array(bead.position_mm);
        assert!(
            inside(&cancellous, p),
            "{} at {p} is outside the cancellous bone",
            bead.id
        );
        let clearance = near.distance_within(p, 20.0) - bead.diameter_mm / 2.0;
        eprintln!("{}: {clearance:.2} mm from the cancellous surface", bead.id);
        assert!(
            clearance >= 0.3,
            "{}: bead surface {clearance} mm from the cancellous surface",
            bead.id
        );
    }
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[test]
fn the_femur_is_deterministic_and_the_shipped_models_match_the_code() {
    assert_eq!(&distal_femur(), femur());
    let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    for (file, mesh) in [
        (
            "scenarios/models/distal_femur_cortical.glb",
            &femur().cortical,
        ),
        (
            "scenarios/models/distal_femur_cancellous.glb",
            &femur().cancellous,
        ),
    ] {
        let path = root.join(file);
        let expected = crate::phantom::mesh_io::glb_bytes(mesh).unwrap();
        let shipped = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(
            sha256_hex(&shipped),
            sha256_hex(&expected),
            "{file} is out of date: run `cargo run --release --example distal_femur -- scenarios/models`"
        );
        let loaded = crate::phantom::mesh_io::load_mesh(&path, 1000.0).unwrap();
        loaded.check_closed().unwrap();
        assert_eq!(&loaded.triangles, &mesh.triangles);
    }
}
