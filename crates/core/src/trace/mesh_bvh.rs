//! A closed mesh in a BVH (obvhs), queried with the watertight triangle test; it also keeps the
//! indexed mesh for scan conversion (`raster.rs`).

use std::time::Duration;

use glam::{DVec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::builder::build_bvh2_from_tris;
use obvhs::ray::Ray;
use obvhs::triangle::Triangle;

use super::columns::Columns;
use super::raster::Faces;
use super::watertight::ShearedRay;
use crate::phantom::TriMesh;

/// A mesh in its local frame with a BVH over its triangles. Built once per phantom; each run
/// moves the rays into the local frame instead of rebuilding.
pub struct MeshBvh {
    pub(super) bvh: Bvh2,
    /// Triangles in BVH primitive order.
    triangles: Vec<Triangle>,
    /// Local bounds (min, max), mm.
    pub bounds_mm: (DVec3, DVec3),
    /// The mesh's vertices in its local frame, mm (for scan conversion and containment).
    pub(crate) vertices_mm: Vec<DVec3>,
    /// The mesh's triangles as indices into `vertices_mm`, in the mesh's order and winding.
    pub(crate) faces: Vec<[u32; 3]>,
    /// The triangles binned along [`super::columns::DIRECTION`] (for containment).
    pub(crate) columns: Columns,
    /// Which projected triangles scan conversion must fill (see [`Faces`]).
    pub(super) facing: Faces,
}

impl MeshBvh {
    /// Builds the BVH (obvhs `medium_build`, single-threaded: the layout is deterministic), and
    /// checks whether the mesh is closed (scan conversion then fills front faces only).
    pub fn new(mesh: &TriMesh) -> MeshBvh {
        let v = |i: u32| Vec3A::from_array(mesh.vertices[i as usize]);
        let tris: Vec<Triangle> = mesh
            .triangles
            .iter()
            .map(|t| Triangle {
                v0: v(t[0]),
                v1: v(t[1]),
                v2: v(t[2]),
            })
            .collect();
        let bvh = build_bvh2_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let triangles = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize])
            .collect();
        // Front faces alone cover a closed mesh's shadow (raster.rs); any other mesh needs all.
        let facing = match mesh.check_closed() {
            Ok(()) if mesh.signed_volume_mm3() >= 0.0 => Faces::Outward,
            Ok(()) => Faces::Inward,
            Err(_) => Faces::All,
        };
        let vertices_mm: Vec<DVec3> = mesh
            .vertices
            .iter()
            .map(|v| DVec3::from_array(v.map(f64::from)))
            .collect();
        MeshBvh {
            bvh,
            triangles,
            bounds_mm: mesh.bounds_mm(),
            columns: Columns::new(&vertices_mm, &mesh.triangles),
            vertices_mm,
            faces: mesh.triangles.clone(),
            facing,
        }
    }

    /// Whether the mesh is closed and consistently wound (every edge shared by exactly two
    /// triangles that run it in opposite directions, no degenerate triangle;
    /// [`TriMesh::check_closed`]). Path lengths ([`super::path_lengths`]) need a closed mesh.
    pub fn is_closed(&self) -> bool {
        self.facing != Faces::All
    }

    /// Whether the segment `origin + t·direction`, 0 < t < 1, crosses the mesh surface.
    pub fn segment_hits(&self, origin: DVec3, direction: DVec3) -> bool {
        let (o, d) = (origin.as_vec3a(), direction.as_vec3a());
        let sheared = ShearedRay::new(o, d);
        let tris = &self.triangles;
        !self
            .bvh
            .ray_traverse_miss(Ray::new(o, d, 0.0, 1.0), |_, id| {
                let t = &tris[id];
                sheared.intersect(t.v0, t.v1, t.v2, 0.0, 1.0)
            })
    }

    /// Calls `visit` with every triangle (its indices and its vertices in the local frame, f64)
    /// of every leaf whose box `meets` accepts, walking down only through boxes it accepts. The
    /// boxes are f32; each is widened by a margin far above f64 rounding
    /// (`BOX_MARGIN` of the root box's size plus its distance from the origin) before `meets`
    /// sees it, so a test in f64 culls no triangle it should keep.
    pub(super) fn walk_faces(
        &self,
        meets: impl Fn(DVec3, DVec3) -> bool,
        mut visit: impl FnMut([u32; 3], [DVec3; 3]),
    ) {
        /// The margin, relative.
        const BOX_MARGIN: f64 = 1e-9;
        let nodes = &self.bvh.nodes;
        let Some(root) = nodes.first() else {
            return;
        };
        let (root_lo, root_hi) = (root.aabb.min.as_dvec3(), root.aabb.max.as_dvec3());
        let margin = BOX_MARGIN
            * ((root_hi - root_lo).max_element() + root_lo.abs().max(root_hi.abs()).max_element());
        let mut stack = vec![0usize];
        while let Some(k) = stack.pop() {
            let Some(node) = nodes.get(k) else {
                continue;
            };
            let lo = node.aabb.min.as_dvec3() - DVec3::splat(margin);
            let hi = node.aabb.max.as_dvec3() + DVec3::splat(margin);
            if !meets(lo, hi) {
                continue;
            }
            let first = node.first_index as usize;
            if node.prim_count == 0 {
                stack.extend([first, first + 1]);
                continue;
            }
            for slot in first..first + node.prim_count as usize {
                let Some(&face) = (self.bvh.primitive_indices.get(slot))
                    .and_then(|&f| self.faces.get(f as usize))
                else {
                    continue;
                };
                visit(face, face.map(|i| self.vertices_mm[i as usize]));
            }
        }
    }

    /// Every crossing parameter `t` (0 < t < 1) of the segment with the surface, sorted.
    pub fn segment_crossings(&self, origin: DVec3, direction: DVec3) -> Vec<f32> {
        let (o, d) = (origin.as_vec3a(), direction.as_vec3a());
        let sheared = ShearedRay::new(o, d);
        let mut ts = Vec::new();
        self.bvh
            .ray_traverse_anyhit(Ray::new(o, d, 0.0, 1.0), |_, id| {
                let t = &self.triangles[id];
                let hit = sheared.intersect(t.v0, t.v1, t.v2, 0.0, 1.0);
                if hit.is_finite() {
                    ts.push(hit);
                }
            });
        ts.sort_by(f32::total_cmp);
        ts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_ray_leaks_through_a_closed_sphere() {
        // Every segment from outside through the sphere must cross an even, non-zero number of times.
        let bvh = MeshBvh::new(&TriMesh::uv_sphere(10.0, 24, 48));
        let origin = DVec3::new(0.0, 0.0, 100.0);
        let mut hits = 0;
        for i in 0..120 {
            for j in 0..120 {
                let target = DVec3::new(-12.0 + 0.2 * i as f64, -12.0 + 0.2 * j as f64, -100.0);
                let crossings = bvh.segment_crossings(origin, target - origin);
                assert_eq!(crossings.len() % 2, 0, "odd crossing count at ({i}, {j})");
                // The f64 caster of path lengths crosses each surface exactly once, wherever the
                // tracer finds a crossing (the tracer may count a crossing through the pole's
                // vertex more than once) and on the rays in the plane y = 0, which obvhs' f32 box
                // test drops (0 · ∞ = NaN where a box face lies in that plane).
                let exact = bvh.line_crossings(origin, target - origin);
                assert!(
                    exact.len() == 2 || exact.is_empty(),
                    "({i}, {j}): {exact:?}"
                );
                assert!(crossings.is_empty() || exact.len() == 2, "({i}, {j})");
                assert_eq!(
                    bvh.segment_hits(origin, target - origin),
                    !crossings.is_empty()
                );
                hits += usize::from(!crossings.is_empty());
            }
        }
        assert!(hits > 5000);
    }
}
