//! Mesh decimation for the scene page by vertex clustering (Rossignac and Borrel 1993): the
//! vertices are snapped to a grid of cubic cells, each occupied cell becomes one vertex (the mean
//! of its vertices), triangles whose corners fall into fewer than three cells vanish and repeated
//! triangles are kept once. The grid is refined from coarse to fine and the finest grid that stays
//! within the triangle budget wins. Only the picture uses it: the simulation traces the full mesh.

use std::collections::{BTreeMap, BTreeSet};

use crate::phantom::mesh::TriMesh;

/// Cells along the longest side of the mesh's bounding box, tried from finest to coarsest.
const GRID_CELLS: [u32; 10] = [256, 192, 128, 96, 64, 48, 32, 24, 16, 8];

/// A mesh for drawing: vertices (mm, phantom frame) and triangles.
#[derive(Debug, Clone, PartialEq)]
pub struct Decimated {
    /// Vertex positions, mm.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as indices into `vertices`.
    pub triangles: Vec<[u32; 3]>,
}

/// `mesh` with at most `max_triangles` triangles: unchanged when it has no more, else clustered
/// on the finest grid of [`GRID_CELLS`] that meets the budget (the coarsest one when none does).
pub fn decimate(mesh: &TriMesh, max_triangles: usize) -> Decimated {
    let vertices: Vec<[f64; 3]> = mesh.vertices.iter().map(|v| v.map(f64::from)).collect();
    if mesh.triangles.len() <= max_triangles {
        return Decimated {
            vertices,
            triangles: mesh.triangles.clone(),
        };
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for v in &vertices {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    let longest = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f64, f64::max);
    let mut best = None;
    for cells in GRID_CELLS {
        let size = if longest > 0.0 {
            longest / f64::from(cells)
        } else {
            1.0
        };
        let d = cluster(&vertices, &mesh.triangles, lo, size);
        let fits = d.triangles.len() <= max_triangles;
        best = Some(d);
        if fits {
            break;
        }
    }
    best.unwrap_or(Decimated {
        vertices: Vec::new(),
        triangles: Vec::new(),
    })
}

/// One clustering pass with cubic cells of `size` mm anchored at `origin`.
fn cluster(
    vertices: &[[f64; 3]],
    triangles: &[[u32; 3]],
    origin: [f64; 3],
    size: f64,
) -> Decimated {
    let cell_of = |v: &[f64; 3]| -> [i64; 3] {
        [0, 1, 2].map(|k| ((v[k] - origin[k]) / size).floor() as i64)
    };
    // Cells numbered in order of first appearance (deterministic).
    let mut index: BTreeMap<[i64; 3], u32> = BTreeMap::new();
    let mut sums: Vec<([f64; 3], u32)> = Vec::new();
    let mut map = Vec::with_capacity(vertices.len());
    for v in vertices {
        let next = sums.len() as u32;
        let i = *index.entry(cell_of(v)).or_insert(next);
        if i == next {
            sums.push(([0.0; 3], 0));
        }
        let (sum, n) = &mut sums[i as usize];
        for k in 0..3 {
            sum[k] += v[k];
        }
        *n += 1;
        map.push(i);
    }
    let mut seen = BTreeSet::new();
    let mut out = Vec::new();
    for t in triangles {
        let c = t.map(|i| map.get(i as usize).copied().unwrap_or(0));
        if c[0] == c[1] || c[1] == c[2] || c[0] == c[2] {
            continue;
        }
        let mut key = c;
        key.sort_unstable();
        if seen.insert(key) {
            out.push(c);
        }
    }
    Decimated {
        vertices: sums
            .into_iter()
            .map(|(s, n)| s.map(|x| x / f64::from(n)))
            .collect(),
        triangles: out,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_mesh_is_kept_and_a_large_one_meets_the_budget() {
        let sphere = TriMesh::uv_sphere(10.0, 64, 64);
        let n = sphere.triangles.len();
        assert!(n > 4000, "{n}");
        let kept = decimate(&sphere, n);
        assert_eq!(kept.triangles, sphere.triangles);
        let small = decimate(&sphere, 1000);
        assert!(small.triangles.len() <= 1000 && small.triangles.len() > 100);
        // Every vertex kept is a mean of sphere vertices within one cell: near the surface.
        for v in &small.vertices {
            let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            assert!((r - 10.0).abs() < 1.0, "{r}");
        }
        // Every index points at a vertex, and no triangle is degenerate.
        for t in &small.triangles {
            assert!(t.iter().all(|&i| (i as usize) < small.vertices.len()));
            assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
        }
        assert_eq!(small, decimate(&sphere, 1000));
    }
}
