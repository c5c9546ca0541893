//! Tests of the tibial component: closedness, the plate's volume and the frame against hand
//! values, the insert's dishes, the insert on the plate, the knee at full extension, the
//! shipped models.

use std::sync::OnceLock;

use glam::DVec3;

use super::*;
use crate::phantom::femoral::{FemoralComponent, femoral_component};
use crate::phantom::femur::{DistalFemur, distal_femur};
use crate::phantom::test_support::{
    Nearby, assert_closed_genus_zero, assert_shipped, closest_approach, inside, vertices,
};
use crate::phantom::tibia::{ProximalTibia, proximal_tibia};
use crate::trace::MeshBvh;

fn tray_mesh() -> &'static TriMesh {
    static T: OnceLock<TriMesh> = OnceLock::new();
    T.get_or_init(tibial_tray)
}

fn insert_mesh() -> &'static TriMesh {
    static I: OnceLock<TriMesh> = OnceLock::new();
    I.get_or_init(tibial_insert)
}

#[test]
fn tray_and_insert_are_closed_outward_genus_zero_and_small() {
    assert_closed_genus_zero("tray", tray_mesh(), 10_000.0, 60_000);
    assert_closed_genus_zero("insert", insert_mesh(), 10_000.0, 60_000);
}

/// Volume of the part of the closed, outward-wound mesh `m` above the plane y = 0, mm³. By the
/// divergence theorem with the field (0, y, 0), whose divergence is 1, it is the integral of
/// y·n_y over the surface above the plane (the cut face at y = 0 adds nothing): each triangle is
/// clipped to y ≥ 0, and over a flat piece the integral is its area's y component times the
/// mean of y.
fn volume_above_y0(m: &TriMesh) -> f64 {
    let mut volume = 0.0;
    for t in &m.triangles {
        let p = t.map(|i| DVec3::from_array(m.vertices[i as usize].map(f64::from)));
        let mut clipped = Vec::with_capacity(4);
        for k in 0..3 {
            let (a, b) = (p[k], p[(k + 1) % 3]);
            if a.y >= 0.0 {
                clipped.push(a);
            }
            if (a.y >= 0.0) != (b.y >= 0.0) {
                clipped.push(a + (b - a) * (a.y / (a.y - b.y)));
            }
        }
        for k in 1..clipped.len().saturating_sub(1) {
            let (a, b, c) = (clipped[0], clipped[k], clipped[k + 1]);
            volume += 0.5 * (b - a).cross(c - a).y * (a.y + b.y + c.y) / 3.0;
        }
    }
    volume
}

#[test]
fn the_plate_has_the_volume_of_a_rounded_rectangle_4_mm_thick() {
    // The plate is everything of the tray above its distal face (the keel meets it in a sharp
    // edge at y = 0): a 70 × 46 mm rectangle less the four corners a 16 mm radius cuts off
    // ((4 − π)·16² mm² together), 4 mm thick.
    let area = 70.0 * 46.0 - (4.0 - std::f64::consts::PI) * 16.0 * 16.0;
    let expected = area * 4.0;
    let measured = volume_above_y0(tray_mesh());
    eprintln!("plate: {measured:.1} mm³, analytic {expected:.1} mm³");
    // The polygonisation bevels the plate's sharp edges (only removing metal): about a right
    // triangle of an eighth of a grid cell (1.2 × 1.0 mm) along each of its two 205 mm edges,
    // some 60 mm³ or 0.5 %. Allowed: up to 1 % less, nothing more.
    let relative = measured / expected - 1.0;
    assert!(
        (-0.01..=0.0).contains(&relative),
        "plate volume {measured} mm³ vs {expected} mm³"
    );
    // The control: the whole tray is larger by the keel (a 14 mm stem 40 mm long alone is about
    // 5600 mm³).
    let whole = tray_mesh().signed_volume_mm3();
    assert!(whole > expected + 5_000.0, "tray {whole} mm³");
}

#[test]
fn the_tray_spans_the_frame_as_documented() {
    let (lo, hi) = tray_mesh().bounds_mm();
    eprintln!("tray bounds {lo} … {hi}");
    // Plate 70 × 46 mm centred on the axis, its distal face at y = 0 and its top at y = 4; the
    // stem's tip 40 mm below the distal face.
    for (got, want) in [
        (lo.x, -35.0),
        (hi.x, 35.0),
        (lo.z, -23.0),
        (hi.z, 23.0),
        (hi.y, 4.0),
        (lo.y, -40.0),
    ] {
        assert!((got - want).abs() < 0.1, "bound {got} vs {want}");
    }
    let (ilo, ihi) = insert_mesh().bounds_mm();
    eprintln!("insert bounds {ilo} … {ihi}");
    assert!((ilo.y - 4.1).abs() < 1e-5, "insert underside {ilo}");
    assert!((ihi.x - 35.0).abs() < 0.1 && (ihi.z - 23.0).abs() < 0.1);
}

#[test]
fn the_insert_dishes_have_the_documented_heights() {
    let bvh = MeshBvh::new(insert_mesh());
    // (x, z, hand-computed height): 4 mm plate + 0.1 mm gap + 8 mm polyethylene = 12.1 mm at
    // the dishes' lowest points; + z²/160 sagittally (80 mm radius); + u²/80 coronally (40 mm
    // radius, u the distance from x = 21.75 clamped to the condyle's 9.5..34 mm) where the
    // condyles are domed (z more than 5 mm behind the dish bottom).
    let probes = [
        (21.75, 0.0, 12.1),
        (-21.75, 0.0, 12.1),
        (21.75, 20.0, 12.1 + 400.0 / 160.0),
        (-21.75, -20.0, 12.1 + 400.0 / 160.0),
        (28.0, -15.0, 12.1 + 6.25 * 6.25 / 80.0 + 225.0 / 160.0),
        (0.0, -10.0, 12.1 + 12.25 * 12.25 / 80.0 + 100.0 / 160.0),
    ];
    for (x, z, want) in probes {
        let top = DVec3::new(x, 40.0, z);
        let hits = bvh.segment_crossings(top, DVec3::new(0.0, -40.0, 0.0));
        let got = 40.0 - 40.0 * f64::from(hits[0]);
        eprintln!("articular surface at ({x}, {z}): {got:.4} mm, hand value {want:.4} mm");
        assert!((got - want).abs() < 0.01, "({x}, {z}): {got} vs {want}");
    }
}

#[test]
fn the_insert_sits_on_the_plate_with_the_gap() {
    let tray = MeshBvh::new(tray_mesh());
    let insert = MeshBvh::new(insert_mesh());
    let near_tray = Nearby::new(tray_mesh(), 2.0);
    let mut closest = f64::INFINITY;
    for p in vertices(insert_mesh()) {
        assert!(!inside(&tray, p), "insert vertex {p} is inside the tray");
        closest = closest.min(near_tray.distance_within(p, 1.0));
    }
    for p in vertices(tray_mesh()) {
        assert!(!inside(&insert, p), "tray vertex {p} is inside the insert");
    }
    eprintln!("closest insert vertex to the tray: {closest:.6} mm");
    assert!(
        (closest - GAP_MM).abs() < 1e-5,
        "the insert is {closest} mm from the plate"
    );
}

/// Every vertex of `m` moved by `t`.
fn moved(m: &TriMesh, t: DVec3) -> TriMesh {
    TriMesh {
        vertices: vertices(m).map(|v| (v + t).as_vec3().to_array()).collect(),
        triangles: m.triangles.clone(),
    }
}

#[test]
fn at_full_extension_the_condyles_rest_in_the_dishes_and_nothing_overlaps() {
    let component: FemoralComponent = femoral_component();
    let femur: DistalFemur = distal_femur();
    let tibia: ProximalTibia = proximal_tibia();
    let t = DVec3::from_array(full_extension_position_mm());
    eprintln!("tibial origin in the femoral component's frame: {t}");
    let (tray, insert, bone) = (
        moved(tray_mesh(), t),
        moved(insert_mesh(), t),
        moved(&tibia.cortical, t),
    );
    // The insert comes closest to the metal where the condyles are lowest, 0.1 mm apart. The
    // meshes' chords move that by hundredths: the dish's (concave, radius ≥ 40 mm, chords up to
    // 1.7 mm on the 1.2 mm grid) rise above it by at most 1.7² / (8 · 40) = 0.009 mm, the
    // condyles' (convex) lie inside them.
    let (gap, at) = closest_approach(&insert, &component.mesh, 2.0);
    eprintln!("insert to component: {gap:.4} mm at {at}");
    assert!(
        (CONTACT_GAP_MM - 0.01..CONTACT_GAP_MM + 0.05).contains(&gap),
        "the condyles are {gap} mm from the insert"
    );
    let at_tibial = at - t;
    assert!(
        (at_tibial.x.abs() - DISH_CENTRE_X_MM).abs() < 3.0 && at_tibial.z.abs() < 3.0,
        "closest at {at_tibial} (tibial frame), not under a condyle"
    );
    // Both compartments are loaded: the medial and the lateral dish each come as close.
    let near = Nearby::new(&component.mesh, 2.0);
    for side in [-1.0, 1.0] {
        let d = vertices(&insert)
            .filter(|p| p.x * side > 0.0)
            .map(|p| near.distance_within(p, 2.0))
            .fold(f64::INFINITY, f64::min);
        assert!(d < CONTACT_GAP_MM + 0.05, "side {side}: {d} mm");
    }
    // Nothing else of the tibial side comes near the femoral side.
    for (name, a, b, least) in [
        ("insert/femur", &insert, &femur.cortical, 2.0),
        ("tray/component", &tray, &component.mesh, 2.0),
        ("tray/femur", &tray, &femur.cortical, 2.0),
        ("tibia/component", &bone, &component.mesh, 2.0),
        ("tibia/femur", &bone, &femur.cortical, 2.0),
    ] {
        let (d, at) = closest_approach(a, b, least);
        assert!(d >= least, "{name}: {d} mm at {at}");
    }
}

#[test]
fn the_parts_are_deterministic_and_the_shipped_models_match_the_code() {
    assert_eq!(&tibial_tray(), tray_mesh());
    assert_eq!(&tibial_insert(), insert_mesh());
    assert_shipped(
        "scenarios/models/tibial_tray.glb",
        tray_mesh(),
        "proximal_tibia",
    );
    assert_shipped(
        "scenarios/models/tibial_insert.glb",
        insert_mesh(),
        "proximal_tibia",
    );
}
