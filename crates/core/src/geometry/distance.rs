//! Distances between points and triangles.

use glam::DVec3;

/// Distance from `p` to triangle `abc` (closest point by Voronoi regions, Ericson §5.1.5).
pub fn point_triangle_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return (p - (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))))).length();
    }
    let denom = 1.0 / (va + vb + vc);
    (p - (a + ab * (vb * denom) + ac * (vc * denom))).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_triangle_distance_covers_face_edge_and_vertex_regions() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        assert!((point_triangle_distance(DVec3::new(0.2, 0.2, 3.0), a, b, c) - 3.0).abs() < 1e-15);
        assert!(
            (point_triangle_distance(DVec3::new(-1.0, -1.0, 0.0), a, b, c) - 2f64.sqrt()).abs()
                < 1e-15
        );
        assert!((point_triangle_distance(DVec3::new(0.5, -2.0, 0.0), a, b, c) - 2.0).abs() < 1e-15);
        assert!(
            (point_triangle_distance(DVec3::new(1.0, 1.0, 0.0), a, b, c) - 0.5f64.sqrt()).abs()
                < 1e-15
        );
    }
}
