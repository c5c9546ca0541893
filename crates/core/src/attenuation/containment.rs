//! Where a bead sits among the volumes: wholly inside, wholly outside, or across a surface.
//! A bead's tantalum replaces the material of the innermost volume it lies in, so this decides
//! which path length its chord is taken from.

use glam::DVec3;

use crate::geometry::point_triangle_distance;
use crate::trace::{MeshBvh, columns};

/// A sphere against a solid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Placement {
    /// The whole sphere lies inside.
    Inside,
    /// The sphere and the solid do not meet.
    Outside,
    /// The sphere crosses the solid's surface.
    Across,
}

fn place(centre_inside: bool, distance_to_surface_mm: f64, radius_mm: f64) -> Placement {
    if distance_to_surface_mm < radius_mm {
        Placement::Across
    } else if centre_inside {
        Placement::Inside
    } else {
        Placement::Outside
    }
}

/// A sphere (centre in the box's frame) against a box of half-sizes `h`, exactly.
pub fn in_cuboid(centre: DVec3, radius_mm: f64, h: DVec3) -> Placement {
    let a = centre.abs();
    let inside = a.x <= h.x && a.y <= h.y && a.z <= h.z;
    let distance = if inside {
        (h - a).min_element()
    } else {
        (a - h).max(DVec3::ZERO).length()
    };
    place(inside, distance, radius_mm)
}

/// A sphere (centre in the cylinder's frame) against an elliptic cylinder on z with semi-axes
/// `radii` and half-length `half_length`. Radially it compares the centre with the ellipses of
/// semi-axes `radii ∓ r` (exact for a circle; for an ellipse whose curvature radius b²/a exceeds
/// r, as any body envelope with a 1 mm bead, the shrunk ellipse lies within the inner parallel
/// curve, so "inside" is never claimed wrongly).
pub fn in_cylinder(centre: DVec3, radius_mm: f64, radii: [f64; 2], half_length: f64) -> Placement {
    let e = |da: f64| {
        let (a, b) = (radii[0] + da, radii[1] + da);
        if a <= 0.0 || b <= 0.0 {
            return f64::INFINITY;
        }
        (centre.x / a) * (centre.x / a) + (centre.y / b) * (centre.y / b)
    };
    let z = centre.z.abs();
    if e(-radius_mm) <= 1.0 && z <= half_length - radius_mm {
        Placement::Inside
    } else if e(radius_mm) >= 1.0 || z >= half_length + radius_mm {
        Placement::Outside
    } else {
        Placement::Across
    }
}

/// A sphere (centre in the mesh's frame, mm) against a closed mesh: the centre's side by the
/// parity of crossings of a ray (along [`columns::DIRECTION`], fixed and irrational, so it misses
/// edges and vertices of any practical mesh), the distance to the surface as the least distance to
/// a triangle (only triangles whose bounding box comes within the radius are measured: only a
/// distance below the radius decides anything). The mesh's column index ([`columns`]) lists the
/// triangles either test can accept; the others are not looked at, which changes no answer.
pub fn in_mesh(centre: DVec3, radius_mm: f64, mesh: &MeshBvh) -> Placement {
    let dir = columns::DIRECTION.normalize();
    let v = |i: u32| mesh.vertices_mm[i as usize];
    let corners = |t: u32| mesh.faces[t as usize].map(v);
    let crossings = mesh
        .columns
        .along(centre)
        .iter()
        .filter(|&&t| {
            let [a, b, c] = corners(t);
            ray_hits(centre, dir, a, b, c)
        })
        .count();
    let mut distance = f64::INFINITY;
    // Only `distance < radius` matters: a triangle whose bounding box lies farther than the
    // radius (with a relative margin far above the distance's rounding) cannot change it, so its
    // exact distance is not computed.
    let reach2 = radius_mm * radius_mm * (1.0 + 1e-9);
    mesh.columns.near(centre, radius_mm, |t| {
        let [a, b, c] = corners(t);
        let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
        let gap = (lo - centre).max(centre - hi).max(DVec3::ZERO);
        if gap.length_squared() <= reach2 {
            distance = distance.min(point_triangle_distance(centre, a, b, c));
        }
    });
    place(crossings % 2 == 1, distance, radius_mm)
}

/// Whether the ray `o + t·d`, t > 0, crosses triangle abc (Möller–Trumbore, f64).
fn ray_hits(o: DVec3, d: DVec3, a: DVec3, b: DVec3, c: DVec3) -> bool {
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-300 {
        return false;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let q = s.cross(e1);
    let w = d.dot(q) * inv;
    if w < 0.0 || u + w > 1.0 {
        return false;
    }
    e2.dot(q) * inv > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phantom::TriMesh;

    #[test]
    fn cuboid_placement_is_exact() {
        let h = DVec3::new(10.0, 5.0, 4.0);
        assert_eq!(in_cuboid(DVec3::ZERO, 0.5, h), Placement::Inside);
        assert_eq!(
            in_cuboid(DVec3::new(0.0, 0.0, 3.5), 0.5, h),
            Placement::Inside
        );
        assert_eq!(
            in_cuboid(DVec3::new(0.0, 0.0, 3.6), 0.5, h),
            Placement::Across
        );
        assert_eq!(
            in_cuboid(DVec3::new(0.0, 0.0, 4.5), 0.5, h),
            Placement::Outside
        );
        // Off a corner: distance √(0.3²·3) ≈ 0.52 > 0.5.
        assert_eq!(in_cuboid(h + DVec3::splat(0.3), 0.5, h), Placement::Outside);
        assert_eq!(in_cuboid(h + DVec3::splat(0.2), 0.5, h), Placement::Across);
    }

    #[test]
    fn cylinder_placement_for_a_circle_is_exact() {
        let r = [20.0, 20.0];
        assert_eq!(
            in_cylinder(DVec3::new(19.4, 0.0, 0.0), 0.5, r, 50.0),
            Placement::Inside
        );
        assert_eq!(
            in_cylinder(DVec3::new(19.6, 0.0, 0.0), 0.5, r, 50.0),
            Placement::Across
        );
        assert_eq!(
            in_cylinder(DVec3::new(20.6, 0.0, 0.0), 0.5, r, 50.0),
            Placement::Outside
        );
        assert_eq!(
            in_cylinder(DVec3::new(0.0, 0.0, 49.6), 0.5, r, 50.0),
            Placement::Across
        );
    }

    /// Measuring only the triangles whose box comes within the radius gives the placement of
    /// measuring every triangle, for centres all around a coarse sphere's surface (where the
    /// nearest triangle decides between inside, across and outside).
    /// The placement from every triangle: parity of all crossings, least of all distances.
    fn every_triangle(m: &TriMesh, centre: DVec3, r: f64) -> Placement {
        let v = |i: u32| DVec3::from_array(m.vertices[i as usize].map(f64::from));
        let dir = columns::DIRECTION.normalize();
        let mut crossings = 0;
        let mut distance = f64::INFINITY;
        for t in &m.triangles {
            let [a, b, c] = t.map(v);
            crossings += usize::from(ray_hits(centre, dir, a, b, c));
            distance = distance.min(point_triangle_distance(centre, a, b, c));
        }
        place(crossings % 2 == 1, distance, r)
    }

    #[test]
    fn indexed_placement_is_that_of_every_triangle() {
        // A coarse and a fine sphere, and the shipped femoral component (its mesh is what beads
        // are placed against in the realistic scenarios), at points inside, across and outside.
        let knee = crate::phantom::mesh_io::load_mesh(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../scenarios/models/distal_femur_cortical.glb")
                .as_path(),
            1000.0,
        )
        .expect("shipped model");
        let (lo, hi) = knee.bounds_mm();
        let ball = (DVec3::splat(-12.0), DVec3::splat(12.0));
        for (m, span, points) in [
            (TriMesh::uv_sphere(10.0, 12, 24), ball, 3000),
            (TriMesh::uv_sphere(10.0, 64, 128), ball, 1000),
            (knee, (lo, hi), 400),
        ] {
            let bvh = MeshBvh::new(&m);
            let mut seen = [0usize; 3];
            for i in 0..points {
                let f = |k: u32| f64::from((i * k) % 1009) / 1009.0;
                let t = DVec3::new(f(7), f(13), f(29));
                let centre = span.0 + (span.1 - span.0) * t;
                for r in [0.0, 0.5, 3.0] {
                    let p = in_mesh(centre, r, &bvh);
                    assert_eq!(p, every_triangle(&m, centre, r), "centre {centre}, r {r}");
                    seen[p as usize] += 1;
                }
            }
            assert!(seen.iter().all(|&n| n > 30), "{seen:?}");
        }
    }

    #[test]
    fn pruned_distances_give_the_placement_of_all_distances() {
        let m = TriMesh::uv_sphere(10.0, 12, 24);
        let bvh = MeshBvh::new(&m);
        let all = |centre: DVec3, r: f64| every_triangle(&m, centre, r);
        let mut seen = [0usize; 3];
        for i in 0..4000u32 {
            let (theta, phi) = (0.7853 * f64::from(i % 97), 0.0311 * f64::from(i % 101));
            let dir = DVec3::new(phi.sin() * theta.cos(), phi.sin() * theta.sin(), phi.cos());
            let centre = dir * (8.8 + 2.4 * f64::from(i) / 4000.0);
            let p = in_mesh(centre, 0.5, &bvh);
            assert_eq!(p, all(centre, 0.5), "centre {centre}");
            seen[p as usize] += 1;
        }
        assert!(seen.iter().all(|&n| n > 100), "{seen:?}");
    }

    #[test]
    fn mesh_placement_matches_the_sphere_it_approximates() {
        // A fine UV sphere of radius 10: its surface lies within 0.02 mm of the true sphere.
        let m = MeshBvh::new(&TriMesh::uv_sphere(10.0, 64, 128));
        assert_eq!(
            in_mesh(DVec3::new(0.0, 0.0, 0.0), 0.5, &m),
            Placement::Inside
        );
        assert_eq!(
            in_mesh(DVec3::new(9.3, 0.0, 0.0), 0.5, &m),
            Placement::Inside
        );
        assert_eq!(
            in_mesh(DVec3::new(9.8, 0.0, 0.0), 0.5, &m),
            Placement::Across
        );
        assert_eq!(
            in_mesh(DVec3::new(0.0, 10.2, 0.0), 0.5, &m),
            Placement::Across
        );
        assert_eq!(
            in_mesh(DVec3::new(0.0, 0.0, -11.0), 0.5, &m),
            Placement::Outside
        );
        assert_eq!(
            in_mesh(DVec3::new(30.0, 0.0, 0.0), 0.5, &m),
            Placement::Outside
        );
    }
}
