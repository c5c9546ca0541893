//! Closed triangle meshes in a phantom's local frame, in millimetres.

use std::collections::HashMap;

use glam::DVec3;

/// An indexed triangle mesh; vertices in mm in the phantom's local frame, triangles wound
/// counter-clockwise seen from outside (outward normals).
#[derive(Debug, Clone, PartialEq)]
pub struct TriMesh {
    /// Vertex positions, mm.
    pub vertices: Vec<[f32; 3]>,
    /// Triangles as indices into `vertices`.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Checks that the mesh is closed and consistently oriented: every edge is shared by exactly
    /// two triangles that traverse it in opposite directions, and no triangle has zero area.
    /// The error says which edge or triangle is at fault.
    pub fn check_closed(&self) -> Result<(), String> {
        if self.triangles.is_empty() {
            return Err("the mesh has no triangles".into());
        }
        let n = self.vertices.len() as u32;
        // Every directed edge (u, v) as the number u·2³² + v, sorted: equal neighbours are an
        // edge used twice in one direction, and the reverse of each is found by binary search.
        let mut directed: Vec<u64> = Vec::with_capacity(self.triangles.len() * 3);
        for (t, tri) in self.triangles.iter().enumerate() {
            if tri.iter().any(|&i| i >= n) {
                return Err(format!(
                    "triangle {t} refers to a vertex index beyond the {n} vertices"
                ));
            }
            let [a, b, c] =
                tri.map(|i| DVec3::from_array(self.vertices[i as usize].map(f64::from)));
            if (b - a).cross(c - a).length_squared() == 0.0 {
                return Err(format!("triangle {t} has zero area (degenerate)"));
            }
            for (u, v) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
                directed.push(edge_key(u, v));
            }
        }
        directed.sort_unstable();
        for run in directed.chunk_by(|a, b| a == b) {
            let (u, v) = ((run[0] >> 32) as u32, run[0] as u32);
            if run.len() > 1 {
                return Err(format!(
                    "edge {u}-{v} is traversed {} times in the same direction: triangles are inconsistently oriented or the mesh is not manifold",
                    run.len()
                ));
            }
            if directed.binary_search(&edge_key(v, u)).is_err() {
                return Err(format!(
                    "edge {u}-{v} belongs to one triangle only: the mesh has a hole (it is not closed)"
                ));
            }
        }
        Ok(())
    }

    /// Enclosed volume in mm³ by the divergence theorem; positive when normals point outward.
    pub fn signed_volume_mm3(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] =
                    t.map(|i| DVec3::from_array(self.vertices[i as usize].map(f64::from)));
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// Axis-aligned bounds `(min, max)` of the vertices, mm.
    pub fn bounds_mm(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for v in &self.vertices {
            let p = DVec3::from_array(v.map(f64::from));
            lo = lo.min(p);
            hi = hi.max(p);
        }
        (lo, hi)
    }

    /// Flips every triangle's winding (turns inward normals outward).
    pub fn flip_winding(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// Welds vertices with bit-identical positions, so meshes stored as triangle soups (STL,
    /// glTF with split normals) become indexed and their edges can be matched.
    pub fn weld(&mut self) {
        let mut index: HashMap<[u32; 3], u32> = HashMap::with_capacity(self.vertices.len());
        let mut vertices = Vec::with_capacity(self.vertices.len());
        let remap: Vec<u32> = self
            .vertices
            .iter()
            .map(|v| {
                let key = v.map(|x| if x == 0.0 { 0 } else { x.to_bits() });
                *index.entry(key).or_insert_with(|| {
                    vertices.push(*v);
                    (vertices.len() - 1) as u32
                })
            })
            .collect();
        for t in &mut self.triangles {
            *t = t.map(|i| remap[i as usize]);
        }
        self.vertices = vertices;
    }

    /// A UV sphere of radius `radius_mm` centred at the origin with `rings` × `segments`
    /// facets, closed and outward-wound. Its facets' vertices lie on the exact sphere.
    pub fn uv_sphere(radius_mm: f64, rings: u32, segments: u32) -> TriMesh {
        let mut vertices = vec![[0.0, 0.0, radius_mm as f32]];
        for r in 1..rings {
            let theta = std::f64::consts::PI * r as f64 / rings as f64;
            for s in 0..segments {
                let phi = 2.0 * std::f64::consts::PI * s as f64 / segments as f64;
                let (st, ct) = (libm::sin(theta), libm::cos(theta));
                let (sp, cp) = (libm::sin(phi), libm::cos(phi));
                vertices.push([
                    (radius_mm * st * cp) as f32,
                    (radius_mm * st * sp) as f32,
                    (radius_mm * ct) as f32,
                ]);
            }
        }
        vertices.push([0.0, 0.0, -radius_mm as f32]);
        let south = vertices.len() as u32 - 1;
        let ring = |r: u32, s: u32| 1 + (r - 1) * segments + (s % segments);
        let mut triangles = Vec::new();
        for s in 0..segments {
            triangles.push([0, ring(1, s), ring(1, s + 1)]);
            triangles.push([south, ring(rings - 1, s + 1), ring(rings - 1, s)]);
        }
        for r in 1..rings - 1 {
            for s in 0..segments {
                let (a, b, c, d) = (
                    ring(r, s),
                    ring(r, s + 1),
                    ring(r + 1, s),
                    ring(r + 1, s + 1),
                );
                triangles.push([a, c, d]);
                triangles.push([a, d, b]);
            }
        }
        TriMesh {
            vertices,
            triangles,
        }
    }
}

/// The directed edge `u → v` as one sortable number, `u·2³² + v`.
fn edge_key(u: u32, v: u32) -> u64 {
    (u64::from(u) << 32) | u64::from(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_is_closed_outward_and_has_the_right_volume() {
        let m = TriMesh::uv_sphere(10.0, 64, 128);
        m.check_closed().unwrap();
        let v = m.signed_volume_mm3();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 1000.0;
        assert!(
            v > 0.0 && (v / exact - 1.0).abs() < 2e-3,
            "volume {v} vs {exact}"
        );
    }

    #[test]
    fn a_hole_and_a_flipped_triangle_are_named() {
        let mut m = TriMesh::uv_sphere(10.0, 8, 8);
        m.triangles.pop();
        assert!(m.check_closed().unwrap_err().contains("hole"));
        let mut m = TriMesh::uv_sphere(10.0, 8, 8);
        m.triangles[3].swap(1, 2);
        assert!(
            m.check_closed()
                .unwrap_err()
                .contains("inconsistently oriented")
        );
    }

    #[test]
    fn welding_a_triangle_soup_closes_it() {
        let m = TriMesh::uv_sphere(5.0, 6, 6);
        let mut soup = TriMesh {
            vertices: Vec::new(),
            triangles: Vec::new(),
        };
        for t in &m.triangles {
            let base = soup.vertices.len() as u32;
            soup.vertices.extend(t.map(|i| m.vertices[i as usize]));
            soup.triangles.push([base, base + 1, base + 2]);
        }
        assert!(soup.check_closed().is_err());
        soup.weld();
        soup.check_closed().unwrap();
        assert_eq!(soup.vertices.len(), m.vertices.len());
    }
}
