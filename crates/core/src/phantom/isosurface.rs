//! Closed triangle surfaces of implicit solids by marching tetrahedra on a regular grid.
//!
//! The grid's cubes are split into six tetrahedra along their main diagonal (the Kuhn /
//! Freudenthal triangulation), which matches across neighbouring cubes. In each tetrahedron the
//! surface is one triangle or one quad (two triangles) with its vertices on the tetrahedron's
//! edges. A surface vertex is shared by every tetrahedron around its grid edge, so the result is
//! closed and 2-manifold by construction; since each piece lies inside its own tetrahedron and
//! meets its neighbours only on shared faces, it does not intersect itself either. Orientation is
//! decided from integer corner offsets (exact), never from rounded coordinates.

use glam::DVec3;

/// Smallest fraction of an edge between a surface vertex and a grid node, so that no triangle
/// degenerates when a node value is (nearly) zero.
const EDGE_CLAMP: f64 = 0.02;

/// A regular grid of `n[0] × n[1] × n[2]` nodes, `step.x`, `step.y`, `step.z` apart along the
/// axes, whose first node is at `origin`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Position of node (0, 0, 0).
    pub origin: DVec3,
    /// Spacing between neighbouring nodes along each axis (positive).
    pub step: DVec3,
    /// Number of nodes along x, y and z (each at least 2).
    pub n: [usize; 3],
}

impl Grid {
    /// Position of node (i, j, k).
    pub fn node(&self, i: usize, j: usize, k: usize) -> DVec3 {
        self.origin + DVec3::new(i as f64, j as f64, k as f64) * self.step
    }

    fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.n[0] * (j + self.n[1] * k)
    }
}

/// A polygonised surface: vertices (same units as the grid) and outward-wound triangles.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface {
    /// Vertex positions.
    pub vertices: Vec<DVec3>,
    /// Triangles as indices into `vertices`, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

/// Polygonises the solid `{p : value(p) < 0}` sampled at the nodes of `grid` (`values` in node
/// order x fastest, then y, then z; see [`sample`]). A node with value exactly 0 counts as outside.
/// Every boundary node must be outside, so that the surface closes; the error says otherwise.
pub fn marching_tetrahedra(grid: &Grid, values: &[f64]) -> Result<Surface, String> {
    let [nx, ny, nz] = grid.n;
    if grid.step.is_nan() || grid.step.min_element() <= 0.0 {
        return Err(format!("grid steps {} must be positive", grid.step));
    }
    if nx < 2 || ny < 2 || nz < 2 || values.len() != nx * ny * nz {
        return Err(format!(
            "grid of {:?} nodes does not match {} values",
            grid.n,
            values.len()
        ));
    }
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let boundary =
                    i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1;
                if boundary && values[grid.index(i, j, k)] < 0.0 {
                    return Err(format!(
                        "the solid reaches the grid boundary at node ({i}, {j}, {k}): enlarge the grid"
                    ));
                }
            }
        }
    }
    let mut mc = March {
        grid,
        values,
        edge_vertex: vec![u32::MAX; values.len() * 7],
        vertices: Vec::new(),
        triangles: Vec::new(),
    };
    for k in 0..nz - 1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                mc.cube(i, j, k);
            }
        }
    }
    Ok(Surface {
        vertices: mc.vertices,
        triangles: mc.triangles,
    })
}

/// Samples `f` at every node of `grid`, in the order [`marching_tetrahedra`] expects.
pub fn sample(grid: &Grid, mut f: impl FnMut(DVec3) -> f64) -> Vec<f64> {
    let mut values = Vec::with_capacity(grid.n.iter().product());
    for k in 0..grid.n[2] {
        for j in 0..grid.n[1] {
            for i in 0..grid.n[0] {
                values.push(f(grid.node(i, j, k)));
            }
        }
    }
    values
}

/// The six Kuhn tetrahedra of a cube as corner bit masks (bit 0 = +x, bit 1 = +y, bit 2 = +z):
/// each walks from corner 0 to corner 7 adding one axis at a time, so every edge joins a corner to
/// a superset corner.
const TETS: [[u8; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

struct March<'a> {
    grid: &'a Grid,
    values: &'a [f64],
    /// Surface vertex on the grid edge (node, direction 1..=7), or u32::MAX.
    edge_vertex: Vec<u32>,
    vertices: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
}

fn offset(corner: u8) -> [i64; 3] {
    [
        i64::from(corner & 1),
        i64::from((corner >> 1) & 1),
        i64::from((corner >> 2) & 1),
    ]
}

/// Sign of det(b − a, c − a, d − a) for cube corners (exact, integer).
fn orientation(a: u8, b: u8, c: u8, d: u8) -> i64 {
    let [a, b, c, d] = [a, b, c, d].map(offset);
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
    let det = u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
        + u[2] * (v[0] * w[1] - v[1] * w[0]);
    det.signum()
}

impl March<'_> {
    fn cube(&mut self, i: usize, j: usize, k: usize) {
        let nodes: [usize; 8] = std::array::from_fn(|c| {
            let [dx, dy, dz] = offset(c as u8).map(|o| o as usize);
            self.grid.index(i + dx, j + dy, k + dz)
        });
        let inside: [bool; 8] = nodes.map(|n| self.values[n] < 0.0);
        if inside.iter().all(|&b| b) || inside.iter().all(|&b| !b) {
            return;
        }
        let base = [i, j, k];
        for tet in TETS {
            let ins: Vec<u8> = tet
                .iter()
                .copied()
                .filter(|&c| inside[c as usize])
                .collect();
            let outs: Vec<u8> = tet
                .iter()
                .copied()
                .filter(|&c| !inside[c as usize])
                .collect();
            let mut e = |a: u8, b: u8| self.edge(base, &nodes, a, b);
            match (ins.as_slice(), outs.as_slice()) {
                (&[a], &[o1, o2, o3]) => {
                    let tri = [e(a, o1), e(a, o2), e(a, o3)];
                    // Points on rays from `a`: outward (away from `a`) iff det(o − a) > 0.
                    let flip = orientation(a, o1, o2, o3) < 0;
                    self.push(tri, flip);
                }
                (&[i1, i2, i3], &[o]) => {
                    let tri = [e(o, i1), e(o, i2), e(o, i3)];
                    // Outward means towards `o`: det(i − o) < 0.
                    let flip = orientation(o, i1, i2, i3) > 0;
                    self.push(tri, flip);
                }
                (&[a, b], &[c, d]) => {
                    let quad = [e(a, c), e(a, d), e(b, d), e(b, c)];
                    // det(P0 − a, P1 − a, P2 − a) has the sign of det(c − a, d − a, b − a).
                    let flip = orientation(a, c, d, b) < 0;
                    self.push([quad[0], quad[1], quad[2]], flip);
                    self.push([quad[0], quad[2], quad[3]], flip);
                }
                _ => {}
            }
        }
    }

    fn push(&mut self, tri: [u32; 3], flip: bool) {
        self.triangles
            .push(if flip { [tri[0], tri[2], tri[1]] } else { tri });
    }

    /// The surface vertex on the edge between cube corners `a` and `b` (one inside, one outside).
    fn edge(&mut self, base: [usize; 3], nodes: &[usize; 8], a: u8, b: u8) -> u32 {
        let (lo, hi) = if a & b == a { (a, b) } else { (b, a) };
        let key = nodes[lo as usize] * 7 + usize::from(hi ^ lo) - 1;
        if self.edge_vertex[key] != u32::MAX {
            return self.edge_vertex[key];
        }
        let (f0, f1) = (
            self.values[nodes[lo as usize]],
            self.values[nodes[hi as usize]],
        );
        let t = (f0 / (f0 - f1)).clamp(EDGE_CLAMP, 1.0 - EDGE_CLAMP);
        let corner = |c: u8| {
            let [dx, dy, dz] = offset(c).map(|o| o as usize);
            self.grid.node(base[0] + dx, base[1] + dy, base[2] + dz)
        };
        let (p0, p1) = (corner(lo), corner(hi));
        self.vertices.push(p0 + (p1 - p0) * t);
        let id = (self.vertices.len() - 1) as u32;
        self.edge_vertex[key] = id;
        id
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phantom::TriMesh;

    fn to_mesh(s: &Surface) -> TriMesh {
        TriMesh {
            vertices: s
                .vertices
                .iter()
                .map(|v| [v.x as f32, v.y as f32, v.z as f32])
                .collect(),
            triangles: s.triangles.clone(),
        }
    }

    #[test]
    fn a_sphere_is_closed_outward_and_close_to_its_volume() {
        let grid = Grid {
            origin: DVec3::splat(-6.0),
            step: DVec3::splat(0.5),
            n: [25, 25, 25],
        };
        let values = sample(&grid, |p| p.length() - 5.0);
        let mesh = to_mesh(&marching_tetrahedra(&grid, &values).unwrap());
        mesh.check_closed().unwrap();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 125.0;
        let v = mesh.signed_volume_mm3();
        assert!((v / exact - 1.0).abs() < 0.02, "volume {v} vs {exact}");
    }

    #[test]
    fn zero_node_values_and_two_touching_boxes_stay_manifold() {
        // Node values exactly zero on the faces, and two boxes meeting along an edge line.
        let grid = Grid {
            origin: DVec3::splat(-4.0),
            step: DVec3::new(1.0, 0.9, 1.1),
            n: [9, 9, 9],
        };
        let values = sample(&grid, |p| {
            let a = (p - DVec3::splat(-1.0)).abs().max_element() - 1.0;
            let b = (p - DVec3::splat(1.0)).abs().max_element() - 1.0;
            a.min(b)
        });
        let mesh = to_mesh(&marching_tetrahedra(&grid, &values).unwrap());
        mesh.check_closed().unwrap();
        assert!(mesh.signed_volume_mm3() > 0.0);
    }

    #[test]
    fn a_solid_touching_the_boundary_is_refused() {
        let grid = Grid {
            origin: DVec3::ZERO,
            step: DVec3::ONE,
            n: [3, 3, 3],
        };
        let values = sample(&grid, |p| p.length() - 1.5);
        assert!(
            marching_tetrahedra(&grid, &values)
                .unwrap_err()
                .contains("boundary")
        );
    }
}
