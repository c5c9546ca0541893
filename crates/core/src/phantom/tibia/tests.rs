//! Tests of the proximal tibia: closedness, size against the cited ranges, fit on the tray,
//! nesting, markers, the shipped models.

use std::sync::OnceLock;

use glam::DVec3;

use super::*;
use crate::phantom::test_support::{
    Nearby, assert_closed_genus_zero, assert_shipped, closest_approach, cortex_mm, inside,
    slab_extent, thinnest_wall,
};
use crate::phantom::tibial::tibial_tray;
use crate::trace::MeshBvh;

fn tibia() -> &'static ProximalTibia {
    static T: OnceLock<ProximalTibia> = OnceLock::new();
    T.get_or_init(proximal_tibia)
}

fn tray() -> &'static TriMesh {
    static T: OnceLock<TriMesh> = OnceLock::new();
    T.get_or_init(tibial_tray)
}

fn markers() -> impl Iterator<Item = (&'static str, DVec3)> {
    TIBIAL_MARKERS_MM
        .iter()
        .map(|(id, p)| (*id, DVec3::from_array(*p)))
}

#[test]
fn both_surfaces_are_closed_outward_genus_zero_and_within_the_triangle_budget() {
    let t = tibia();
    assert_closed_genus_zero("cortical", &t.cortical, 50_000.0, 75_000);
    assert_closed_genus_zero("cancellous", &t.cancellous, 50_000.0, 75_000);
}

#[test]
fn dimensions_follow_the_cited_anatomy() {
    let t = tibia();
    let (lo, hi) = t.cortical.bounds_mm();
    eprintln!("cortical bounds {lo} … {hi}");
    // The cut face 0.1 mm below the baseplate's distal face, the bottom 130 mm below it.
    assert!((hi.y + GAP_MM).abs() < 1e-5, "cut face at {hi}");
    assert!((lo.y + SHAFT_LENGTH_MM).abs() < 0.01, "bottom at {lo}");
    // Just under the cut: a plateau 67–83 mm medio-lateral and 43–54 mm antero-posterior (Cheng
    // et al. 2009, Hitt et al. 2003).
    let (o_lo, o_hi) = slab_extent(&t.cortical, -3.0);
    let size = o_hi - o_lo;
    eprintln!("plateau 3 mm below the cut: {size}");
    assert!((67.0..=83.0).contains(&size.x), "medio-lateral {size}");
    assert!((43.0..=54.0).contains(&size.z), "antero-posterior {size}");
    // And the baseplate rests on it without overhanging: wider than the 70 × 46 mm plate.
    assert!(size.x > 70.0 && size.z > 46.0, "{size}");
    // Metaphysis, 20 mm below the cut: a thin cortex (about 1 mm, Capozza et al. 2010).
    for cortex in cortex_mm(&t.cortical, &t.cancellous, -20.0) {
        assert!(
            (1.0..=1.5).contains(&cortex),
            "metaphyseal cortex {cortex} mm"
        );
    }
    // Diaphysis, 15 mm above the bottom: the 25 × 30 mm ellipse with a cortex of several mm
    // (4.5 mm by design).
    let y = lo.y + 15.0;
    let (o_lo, o_hi) = slab_extent(&t.cortical, y);
    let outer = o_hi - o_lo;
    eprintln!("diaphysis at y = {y:.1}: outer {outer}");
    assert!(
        (outer.x - 25.0).abs() < 0.5 && (outer.z - 30.0).abs() < 0.5,
        "{outer}"
    );
    for cortex in cortex_mm(&t.cortical, &t.cancellous, y) {
        assert!(
            (4.0..=5.0).contains(&cortex),
            "diaphyseal cortex {cortex} mm"
        );
    }
}

#[test]
fn the_bone_sits_on_the_cut_with_the_gap_and_never_overlaps_the_tray() {
    let (metal, bone) = (MeshBvh::new(tray()), MeshBvh::new(&tibia().cortical));
    // From 2 mm inside the plate straight down: the plate's face, then 0.1 mm below it the bone.
    for (x, z) in [(-25.0, -10.0), (-15.0, 15.0), (15.0, -15.0), (28.0, 8.0)] {
        let start = DVec3::new(x, 2.0, z);
        let first =
            |bvh: &MeshBvh| f64::from(bvh.segment_crossings(start, DVec3::NEG_Y * 5.0)[0]) * 5.0;
        let (to_metal_face, to_bone) = (first(&metal), first(&bone));
        assert!(
            (to_metal_face - 2.0).abs() < 1e-5 && (to_bone - to_metal_face - GAP_MM).abs() < 1e-5,
            "at ({x}, {z}): metal face {to_metal_face} mm, bone {to_bone} mm"
        );
    }
    let closest = closest_approach(&tibia().cortical, tray(), 1.0);
    eprintln!(
        "closest bone point to the tray: {:.6} mm at {}",
        closest.0, closest.1
    );
    assert!(
        closest.0 >= GAP_MM - 1e-5,
        "bone point {} is {} mm from the tray",
        closest.1,
        closest.0
    );
}

#[test]
fn the_cancellous_region_is_inside_with_a_wall_of_at_least_0_8_mm() {
    let (wall, at) = thinnest_wall(&tibia().cortical, &tibia().cancellous);
    assert!(wall >= 0.8, "wall of {wall} mm at {at}");
}

#[test]
fn the_markers_lie_in_the_cancellous_bone_away_from_the_keel_and_apart() {
    let cancellous = MeshBvh::new(&tibia().cancellous);
    let near_bone = Nearby::new(&tibia().cancellous, 2.0);
    let near_metal = Nearby::new(tray(), 2.0);
    let radius = 0.5 * MARKER_DIAMETER_MM;
    for (id, p) in markers() {
        assert!(
            inside(&cancellous, p),
            "{id} at {p} is outside the cancellous bone"
        );
        let to_bone = near_bone.distance_within(p, 20.0) - radius;
        let to_metal = near_metal.distance_within(p, 20.0) - radius;
        eprintln!(
            "{id}: {to_bone:.2} mm from the cancellous surface, {to_metal:.2} mm from the tray"
        );
        assert!(
            to_bone >= 3.0,
            "{id}: {to_bone} mm from the cancellous surface"
        );
        assert!(to_metal >= 3.0, "{id}: {to_metal} mm from the tray");
    }
    for (i, (a, p)) in markers().enumerate() {
        for (b, q) in markers().skip(i + 1) {
            assert!(
                p.distance(q) >= 10.0,
                "{a} and {b} are {} mm apart",
                p.distance(q)
            );
        }
    }
    // Spread through the metaphysis: on both sides, in front and behind, over 40 mm of height.
    let (lo, hi) = markers().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), (_, p)| (lo.min(p), hi.max(p)),
    );
    assert!(lo.x < -15.0 && hi.x > 15.0 && lo.z < -10.0 && hi.z > 10.0 && hi.y - lo.y >= 40.0);
}

#[test]
fn every_marker_shows_beside_the_metal_and_the_other_markers_in_both_views() {
    let metal = MeshBvh::new(tray());
    let radius = 0.5 * MARKER_DIAMETER_MM;
    // Antero-posterior view: the beam along z, the image in (x, y); lateral view: along x,
    // the image in (z, y).
    for (view, beam, across) in [("AP", DVec3::Z, DVec3::X), ("lateral", DVec3::X, DVec3::Z)] {
        for (id, p) in markers() {
            // The bead's outline and 1 mm beyond it, seen along the beam, misses the metal.
            for offset in [DVec3::ZERO, across, -across, DVec3::Y, DVec3::NEG_Y] {
                let q = p + offset * (radius + 1.0) - beam * 200.0;
                assert!(
                    metal.segment_crossings(q, beam * 400.0).is_empty(),
                    "{view}: {id} is behind the metal"
                );
            }
        }
        for (i, (a, p)) in markers().enumerate() {
            for (b, q) in markers().skip(i + 1) {
                let d = p - q;
                let apart = (d - beam * d.dot(beam)).length();
                assert!(
                    apart >= MARKER_DIAMETER_MM + 1.0,
                    "{view}: {a} and {b} are {apart} mm apart"
                );
            }
        }
    }
}

#[test]
fn the_tibia_is_deterministic_and_the_shipped_models_match_the_code() {
    assert_eq!(&proximal_tibia(), tibia());
    for (file, mesh) in [
        (
            "scenarios/models/proximal_tibia_cortical.glb",
            &tibia().cortical,
        ),
        (
            "scenarios/models/proximal_tibia_cancellous.glb",
            &tibia().cancellous,
        ),
    ] {
        assert_shipped(file, mesh, "proximal_tibia");
    }
}
