//! The projected outline of a model's mesh as a calibrated beamline sees it at a given pose.
//!
//! The shadow of a closed mesh from a point source is bounded by the images of its *contour
//! generator*: the edges between a face that faces the source and one that faces away. Some of
//! those edges lie inside the shadow (a fold, or an edge hidden behind another part of the
//! model); an edge is kept when a ray passing just outside its projected midpoint, on the side
//! away from its faces, misses the mesh, which is where the shadow's winding number
//! (`super::winding`) is zero. What is left are the segments of the outer outline, in
//! continuous pixel coordinates, with the 3-D points they come from so that a fit can move them.

use glam::{DMat3, DVec2, DVec3};

use super::winding::Winding;
use crate::geometry::{DetectorFrame, Pose};
use crate::phantom::TriMesh;
use crate::trace::MeshBvh;

/// How far outside an edge's projected midpoint the visibility ray passes, pixels.
const VISIBILITY_OFFSET_PX: f64 = 0.25;

/// A model mesh prepared for outline projection: face normals, edge adjacency and a BVH.
pub struct OutlineModel {
    pub(crate) vertices: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    /// Unnormalised outward face normals, local frame.
    pub(crate) normals: Vec<DVec3>,
    /// Each face's normal times its first vertex: the face faces a point p where
    /// `normal · p > offset` (up to rounding, `normal · (p − vertex) > 0`).
    pub(crate) offsets: Vec<f64>,
    /// Every undirected edge once: its two vertices and its two faces.
    pub(crate) edges: Vec<MeshEdge>,
    /// `edges[k].faces`, packed: the scan for the contour generator reads only these.
    edge_faces: Vec<[u32; 2]>,
    bvh: MeshBvh,
    /// Centre of the local bounding box, mm.
    pub centre_mm: DVec3,
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct MeshEdge {
    pub(crate) a: u32,
    pub(crate) b: u32,
    pub(crate) faces: [u32; 2],
    /// Whether `faces[0]` runs the edge from `a` to `b` (`faces[1]` then runs it back).
    pub(crate) forward: bool,
}

impl MeshEdge {
    /// Whether the face of this contour edge that faces the source (`facing`:
    /// [`OutlineModel::facing`]) runs it from `a` to `b`. Projected in that order, the contour
    /// edges all turn the same way about the shadow they bound (`super::model_shadow`).
    pub(crate) fn runs_forward(&self, facing: &[bool]) -> bool {
        facing[self.faces[0] as usize] == self.forward
    }
}

/// One segment of the outer outline in one image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutlineSegment {
    /// Projected end points, continuous pixel coordinates.
    pub uv: [DVec2; 2],
    /// The 3-D end points (world frame, mm) that project there.
    pub world_mm: [DVec3; 2],
}

impl OutlineModel {
    /// Prepares a closed, consistently oriented mesh (as `phantom::build` gives): every edge is
    /// shared by exactly two faces.
    pub fn new(mesh: &TriMesh) -> Result<OutlineModel, String> {
        let vertices: Vec<DVec3> = mesh
            .vertices
            .iter()
            .map(|v| DVec3::from_array(v.map(f64::from)))
            .collect();
        let normals: Vec<DVec3> = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| vertices[i as usize]);
                (b - a).cross(c - a)
            })
            .collect();
        // Directed edges sorted by their undirected key pair up with their twins.
        let mut directed: Vec<(u32, u32, u32)> = Vec::with_capacity(mesh.triangles.len() * 3);
        for (f, t) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                directed.push((a.min(b), a.max(b), f as u32));
            }
        }
        directed.sort_unstable();
        let mut edges = Vec::with_capacity(directed.len() / 2);
        for pair in directed.chunks(2) {
            match pair {
                [x, y] if (x.0, x.1) == (y.0, y.1) => edges.push(MeshEdge {
                    a: x.0,
                    b: x.1,
                    faces: [x.2, y.2],
                    forward: {
                        let t = mesh.triangles[x.2 as usize];
                        (0..3).any(|k| t[k] == x.0 && t[(k + 1) % 3] == x.1)
                    },
                }),
                _ => {
                    return Err(
                        "the model mesh is not closed: an edge is not shared by exactly two faces"
                            .into(),
                    );
                }
            }
        }
        let (lo, hi) = mesh.bounds_mm();
        let offsets = (normals.iter().zip(&mesh.triangles))
            .map(|(n, t)| n.dot(vertices[t[0] as usize]))
            .collect();
        Ok(OutlineModel {
            vertices,
            triangles: mesh.triangles.clone(),
            normals,
            offsets,
            edge_faces: edges.iter().map(|e| e.faces).collect(),
            edges,
            bvh: MeshBvh::new(mesh),
            centre_mm: (lo + hi) / 2.0,
        })
    }

    /// Whether each face faces the point `source_local` (model frame): `normal · p > offset`.
    pub(crate) fn facing(&self, source_local: DVec3) -> Vec<bool> {
        (self.normals.iter().zip(&self.offsets))
            .map(|(n, d)| n.dot(source_local) > *d)
            .collect()
    }

    /// The contour generator for `facing` ([`OutlineModel::facing`]): the edges between a face
    /// that faces the source and one that does not, in mesh order.
    pub(crate) fn contour<'m>(&'m self, facing: &'m [bool]) -> impl Iterator<Item = &'m MeshEdge> {
        (self.edge_faces.iter().zip(&self.edges))
            .filter(|([f0, f1], _)| facing[*f0 as usize] != facing[*f1 as usize])
            .map(|(_, e)| e)
    }

    /// The mesh's BVH (for rendering a predicted shadow).
    pub fn bvh(&self) -> &MeshBvh {
        &self.bvh
    }

    /// The outer outline of the model at `pose` (local → world) seen from `source_mm` on
    /// `frame`. Edges with an end point that does not project are skipped.
    pub fn outline(
        &self,
        pose: &Pose,
        source_mm: DVec3,
        frame: &DetectorFrame,
    ) -> Vec<OutlineSegment> {
        self.outline_by(pose, source_mm, frame, false)
    }

    /// [`OutlineModel::outline`], its visibility rays traced through the BVH in f64
    /// (`MeshBvh::line_crossings`) when `by_rays`, else, as `outline` does, read from the
    /// shadow's winding number where the whole contour projects.
    fn outline_by(
        &self,
        pose: &Pose,
        source_mm: DVec3,
        frame: &DetectorFrame,
        by_rays: bool,
    ) -> Vec<OutlineSegment> {
        let to_local: DMat3 = pose.rotation.transpose();
        let source_local = to_local * (source_mm - pose.position_mm);
        let facing = self.facing(source_local);
        // The contour generator, projected.
        let mut contour = Vec::new();
        let mut all_projected = true;
        for e in self.contour(&facing) {
            let world = [e.a, e.b].map(|v| pose.to_world(self.vertices[v as usize]));
            match (
                frame.project(source_mm, world[0]),
                frame.project(source_mm, world[1]),
            ) {
                (Some(ua), Some(ub)) => contour.push((e, world, ua, ub)),
                _ => all_projected = false,
            }
        }
        // Whether a ray misses the mesh: it does where the shadow does not cover its point on
        // the detector, the winding number of the contour (`super::winding`); by a ray through
        // the BVH, in f64, when part of the contour does not project. (The f32 ray test used
        // before found a sliver of two crossings 4·10⁻⁷ apart on 2 of 35 000 probes of the
        // femoral component, where the f64 caster and the winding number find none.)
        let winding = (all_projected && !by_rays).then(|| {
            Winding::new(
                (contour.iter())
                    .map(|(e, _, ua, ub)| {
                        if e.runs_forward(&facing) {
                            [*ua, *ub]
                        } else {
                            [*ub, *ua]
                        }
                    })
                    .collect(),
            )
        });
        let mut out = Vec::new();
        for (e, world, ua, ub) in contour {
            let f0 = e.faces[0] as usize;
            // The third vertex of a face on this edge lies on the shadow's side of the edge.
            let t = self.triangles[f0];
            let third = t
                .into_iter()
                .find(|&v| v != e.a && v != e.b)
                .unwrap_or(t[0]);
            let Some(uc) = frame.project(source_mm, pose.to_world(self.vertices[third as usize]))
            else {
                continue;
            };
            let along = ub - ua;
            if along.length_squared() == 0.0 {
                continue;
            }
            let mut outward = DVec2::new(along.y, -along.x).normalize();
            if outward.dot(uc - ua) > 0.0 {
                outward = -outward;
            }
            let probe = (ua + ub) / 2.0 + outward * VISIBILITY_OFFSET_PX;
            let hidden = match &winding {
                Some(w) => w.covers(probe),
                None => {
                    let target = frame.pose.to_world(frame.pixel_local(probe.x, probe.y));
                    (self
                        .bvh
                        .line_crossings(source_local, to_local * (target - source_mm)))
                    .iter()
                    .any(|t| *t > 0.0 && *t < 1.0)
                }
            };
            if hidden {
                continue;
            }
            out.push(OutlineSegment {
                uv: [ua, ub],
                world_mm: world,
            });
        }
        out
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The shipped femoral component (87 000 faces; folds, a box and pegs), wound outward.
    pub(crate) fn femoral_component() -> OutlineModel {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../scenarios/models/femoral_component.glb");
        let mut mesh = crate::phantom::mesh_io::load_mesh(&file, 1000.0).unwrap();
        if mesh.signed_volume_mm3() < 0.0 {
            mesh.flip_winding();
        }
        OutlineModel::new(&mesh).unwrap()
    }

    /// Pose `k` of a set that turns a model through many orientations about the origin.
    pub(crate) fn turned(k: u32) -> Pose {
        let f = f64::from(k);
        Pose {
            position_mm: DVec3::new(0.3 * f - 6.0, 4.0 - 0.2 * f, 0.5 * f - 10.0),
            rotation: crate::geometry::rotation_xyz_deg([
                9.0 * f,
                37.0 * f % 360.0 - 180.0,
                23.0 * f % 90.0,
            ]),
        }
    }

    #[test]
    fn visibility_from_the_shadow_is_visibility_by_rays() {
        // The shipped femoral component in 40 poses, at full resolution: the outline whose
        // visibility probes read the shadow's winding number is the one whose probes trace
        // rays through the BVH, segment for segment.
        let model = femoral_component();
        let source = DVec3::new(3.0, -5.0, 1300.0);
        let frame = DetectorFrame {
            pose: Pose {
                position_mm: DVec3::new(1.0, -2.0, -500.0),
                rotation: crate::geometry::rotation_xyz_deg([1.0, -2.0, 3.0]),
            },
            pixels: [1440, 1440],
            pixel_pitch_mm: [0.3, 0.3],
        };
        let mut kept = 0;
        for k in 0..40 {
            let pose = turned(k);
            let by_rays = model.outline_by(&pose, source, &frame, true);
            let by_shadow = model.outline(&pose, source, &frame);
            let only = |a: &[OutlineSegment], b: &[OutlineSegment]| -> Vec<OutlineSegment> {
                a.iter().filter(|s| !b.contains(s)).copied().collect()
            };
            assert_eq!(
                (only(&by_shadow, &by_rays), only(&by_rays, &by_shadow)),
                (vec![], vec![]),
                "pose {k}"
            );
            kept += by_rays.len();
        }
        assert!(kept > 30_000, "{kept} segments kept");
    }

    #[test]
    fn a_sphere_outlines_as_its_exact_shadow_circle() {
        // Source on the z axis 1000 mm above a detector at z = 0; a sphere of radius 20 mm at
        // z = 400: its shadow is a circle of radius 1000·tan(asin(20/600)) about the foot point.
        let frame = DetectorFrame {
            pose: Pose::IDENTITY,
            pixels: [400, 400],
            pixel_pitch_mm: [0.25, 0.25],
        };
        let model = OutlineModel::new(&TriMesh::uv_sphere(20.0, 96, 192)).unwrap();
        let source = DVec3::new(0.0, 0.0, 1000.0);
        let pose = Pose {
            position_mm: DVec3::new(0.0, 0.0, 400.0),
            rotation: crate::geometry::rotation_xyz_deg([20.0, -10.0, 5.0]),
        };
        let segments = model.outline(&pose, source, &frame);
        let radius_px = 1000.0 * (20.0f64 / 600.0).asin().tan() / 0.25;
        let centre = DVec2::new(200.0, 200.0);
        assert!(segments.len() > 150, "{}", segments.len());
        let mut around = 0.0;
        for s in &segments {
            for uv in s.uv {
                // Facet vertices lie on the sphere (to f32 precision), so the outline is within the
                // facet sag.
                let r = (uv - centre).length();
                assert!(
                    r <= radius_px * 1.000_01 && r > radius_px * 0.999,
                    "{r} vs {radius_px}"
                );
            }
            around += (s.uv[1] - s.uv[0]).length();
            // Each segment's end points come from its 3-D points.
            for k in 0..2 {
                let p = frame.project(source, s.world_mm[k]).unwrap();
                assert!((p - s.uv[k]).length() < 1e-9);
            }
        }
        // The outline closes once around the circle (a zig-zag would make it longer).
        let circumference = 2.0 * std::f64::consts::PI * radius_px;
        assert!(
            (around / circumference - 1.0).abs() < 0.02,
            "{around} vs {circumference}"
        );
    }

    #[test]
    fn edges_hidden_behind_the_model_are_left_out() {
        // Two spheres, one in front of the other along the ray: only the larger shadow's outline
        // remains where the smaller one lies inside it.
        let mut mesh = TriMesh::uv_sphere(10.0, 48, 96);
        let small = TriMesh::uv_sphere(4.0, 24, 48);
        let offset = mesh.vertices.len() as u32;
        mesh.vertices
            .extend(small.vertices.iter().map(|v| [v[0], v[1], v[2] + 40.0]));
        mesh.triangles
            .extend(small.triangles.iter().map(|t| t.map(|i| i + offset)));
        let model = OutlineModel::new(&mesh).unwrap();
        let frame = DetectorFrame {
            pose: Pose::IDENTITY,
            pixels: [200, 200],
            pixel_pitch_mm: [0.25, 0.25],
        };
        let source = DVec3::new(0.0, 0.0, 1000.0);
        let pose = Pose {
            position_mm: DVec3::new(0.0, 0.0, 300.0),
            rotation: DMat3::IDENTITY,
        };
        let segments = model.outline(&pose, source, &frame);
        let big_radius_px = 1000.0 * (10.0f64 / 700.0).asin().tan() / 0.25;
        for s in &segments {
            let r = (s.uv[0] - DVec2::new(100.0, 100.0)).length();
            assert!(r > big_radius_px * 0.99, "an inner edge at {r} px was kept");
        }
        assert!(segments.len() > 80);
    }
}
