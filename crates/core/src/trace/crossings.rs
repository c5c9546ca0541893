//! Every crossing of a line with a mesh surface, in f64: the reference for path lengths
//! (`path_length.rs`) and their fallback for a mesh that cannot be projected.
//!
//! Candidates come from the mesh's BVH, walked in f64 with every box widened by a margin far
//! above f64 rounding (`MeshBvh::walk_faces`), so no triangle the line crosses is culled. Each candidate is tested
//! with the watertight test of Woop, Benthin and Wald (as `watertight.rs`) in f64: the line is
//! sheared onto an axis, and the three edge functions are evaluated at the line's point in the
//! sheared plane. An edge function depends only on the edge's two (sheared) endpoints and is
//! exactly negated for the triangle across the edge. Where it is exactly zero (the line passes
//! through an edge or a vertex), the crossing goes to the triangle that would contain the line's
//! point moved by an infinitesimal step along the sheared plane's first axis, then its second
//! (the tie rule of `raster.rs`), so a crossing through a shared edge or vertex is counted once.

use glam::{DVec2, DVec3};

use super::MeshBvh;
use super::watertight::dominant_axis;

/// A line `origin + t·direction` prepared for the watertight test: the shear that maps its
/// direction onto the axis `kz`.
struct ShearedLine {
    origin: DVec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f64,
    sy: f64,
    sz: f64,
}

impl ShearedLine {
    fn new(origin: DVec3, direction: DVec3) -> ShearedLine {
        let kz = dominant_axis(direction.abs());
        let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
        ShearedLine {
            origin,
            kx,
            ky,
            kz,
            sx: direction[kx] / direction[kz],
            sy: direction[ky] / direction[kz],
            sz: 1.0 / direction[kz],
        }
    }

    /// A vertex in the sheared frame: its (x, y) relative to the line, and its `t` along it.
    fn shear(&self, v: DVec3) -> (DVec2, f64) {
        let a = v - self.origin;
        (
            DVec2::new(
                a[self.kx] - self.sx * a[self.kz],
                a[self.ky] - self.sy * a[self.kz],
            ),
            a[self.kz] * self.sz,
        )
    }

    /// The line parameter of its crossing with the triangle, or `None` (ties by the module's rule;
    /// a triangle seen edge-on is never crossed).
    fn crossing(&self, v: [DVec3; 3]) -> Option<f64> {
        let [(a, za), (b, zb), (c, zc)] = v.map(|v| self.shear(v));
        // Edge p → q at the line's point (the sheared origin): p × q. Weight of the opposite vertex.
        let e_bc = edge(b, c);
        let e_ca = edge(c, a);
        let e_ab = edge(a, b);
        let det = e_bc + e_ca + e_ab;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let sign = det.signum();
        let inside = |e: f64, p: DVec2, q: DVec2| {
            let e = sign * e;
            // The gradient of the edge function with respect to the line's point, (p.y − q.y,
            // q.x − p.x), oriented to the triangle's inside, decides a tie.
            let (gx, gy) = (sign * (p.y - q.y), sign * (q.x - p.x));
            e > 0.0 || (e == 0.0 && (gx > 0.0 || (gx == 0.0 && gy > 0.0)))
        };
        if !(inside(e_bc, b, c) && inside(e_ca, c, a) && inside(e_ab, a, b)) {
            return None;
        }
        Some((e_bc * za + e_ca * zb + e_ab * zc) / det)
    }
}

/// The edge function of edge `p → q` at the sheared origin: `p × q`, exactly negated for `q → p`.
fn edge(p: DVec2, q: DVec2) -> f64 {
    p.x * q.y - p.y * q.x
}

/// Whether the line `o + t·d` passes through the box `lo..hi` (closed).
fn line_meets_box(o: DVec3, d: DVec3, lo: DVec3, hi: DVec3) -> bool {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        if d[k] == 0.0 {
            if !(o[k] >= lo[k] && o[k] <= hi[k]) {
                return false;
            }
        } else {
            let (a, b) = ((lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    t0 <= t1
}

impl MeshBvh {
    /// Every parameter `t` (any real, not only the segment's) at which the line
    /// `origin + t·direction` (mesh frame, mm) crosses the surface, sorted: the f64 reference
    /// (see the module docs). Empty for a zero direction.
    pub fn line_crossings(&self, origin: DVec3, direction: DVec3) -> Vec<f64> {
        let mut ts = Vec::new();
        if direction == DVec3::ZERO {
            return ts;
        }
        let line = ShearedLine::new(origin, direction);
        self.walk_faces(
            |lo, hi| line_meets_box(origin, direction, lo, hi),
            |_, v| {
                if let Some(t) = line.crossing(v) {
                    ts.push(t);
                }
            },
        );
        ts.sort_by(f64::total_cmp);
        ts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_through_a_shared_edge_or_vertex_crosses_once() {
        // The unit square at z = 1 as two triangles, and as a fan of four around its centre;
        // lines along z exactly through the diagonal, the centre and the grid's corners.
        let (a, b, c, d, m) = (
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(0.0, 1.0, 1.0),
            DVec3::new(0.5, 0.5, 1.0),
        );
        let split = [[a, b, c], [a, c, d]];
        let fan = [[a, b, m], [b, c, m], [c, d, m], [d, a, m]];
        for dir in [DVec3::new(0.0, 0.0, 2.0), DVec3::new(0.0, 0.0, -2.0)] {
            for k in 1..16 {
                let x = k as f64 / 16.0;
                for (x, y) in [(x, x), (0.5, 0.5), (x, 0.5), (0.5, x), (x, 1.0 - x)] {
                    let line = ShearedLine::new(DVec3::new(x, y, 0.0), dir);
                    for tris in [&split[..], &fan[..]] {
                        let hits: Vec<f64> =
                            tris.iter().filter_map(|&t| line.crossing(t)).collect();
                        assert_eq!(hits.len(), 1, "({x}, {y}) along {dir}: {hits:?}");
                        assert!((hits[0] - 1.0 / dir.z).abs() < 1e-15);
                    }
                }
            }
        }
    }
}
