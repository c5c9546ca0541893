//! Tests of the distal femur: closedness, size, fit on the component, nesting, beads, the
//! shipped models.

use std::sync::OnceLock;

use glam::DVec3;

use super::*;
use crate::phantom::femoral::{FemoralComponent, femoral_component};
use crate::phantom::test_support::{
    Nearby, assert_closed_genus_zero, assert_shipped, closest_approach, cortex_mm, inside,
    slab_extent, thinnest_wall,
};
use crate::trace::MeshBvh;

fn femur() -> &'static DistalFemur {
    static F: OnceLock<DistalFemur> = OnceLock::new();
    F.get_or_init(distal_femur)
}

fn component() -> &'static FemoralComponent {
    static C: OnceLock<FemoralComponent> = OnceLock::new();
    C.get_or_init(femoral_component)
}

#[test]
fn both_surfaces_are_closed_outward_genus_zero_and_within_the_triangle_budget() {
    let f = femur();
    assert_closed_genus_zero("cortical", &f.cortical, 50_000.0, 80_000);
    assert_closed_genus_zero("cancellous", &f.cancellous, 50_000.0, 80_000);
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
    for cortex in cortex_mm(&f.cortical, &f.cancellous, y) {
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
    for cortex in cortex_mm(&f.cortical, &f.cancellous, y).into_iter().take(2) {
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
    let closest = closest_approach(&femur().cortical, &component().mesh, 1.0);
    eprintln!(
        "closest bone point to the metal: {:.4} mm at {}",
        closest.0, closest.1
    );
    // 0.1 mm on the flat cuts; at the edges between cuts the metal's chords (its 1 mm fillets
    // polygonised on a 0.9 mm grid) come a little closer.
    assert!(
        closest.0 >= 0.05,
        "bone point {} is {} mm from the metal",
        closest.1,
        closest.0
    );
}

#[test]
fn the_cancellous_region_is_inside_with_a_wall_of_at_least_0_8_mm() {
    let (wall, at) = thinnest_wall(&femur().cortical, &femur().cancellous);
    assert!(wall >= 0.8, "wall of {wall} mm at {at}");
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

#[test]
fn the_femur_is_deterministic_and_the_shipped_models_match_the_code() {
    assert_eq!(&distal_femur(), femur());
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
        assert_shipped(file, mesh, "distal_femur");
    }
}
