//! Sagittal (y–z plane) geometry of the femoral component: the J-curved outer contour and the
//! five-cut bone box, as polygons with exact signed distances.
//!
//! 2D points are `[z, y]` (anterior, proximal). The outer contour is convex: from the posterior
//! face (leaning forward by [`POST_LEAN_DEG`]) it runs around the posterior-condyle arc (radius [`R_POST`]), the distal arc
//! ([`R_DIST`]) and the anterior arc ([`R_ANT`]), each tangent to the next (the "J-curve"), and up
//! the anterior flange, which leans back by [`FLANGE_TILT_DEG`]. Each bone cut is a line at a set
//! metal thickness inside the outer contour's support line with the same normal.

use std::f64::consts::FRAC_1_SQRT_2;

/// Distal arc radius, mm.
pub const R_DIST: f64 = 38.0;
/// Distal arc centre `[z, y]`: the lowest point of the component is at y = 0.
pub const C_DIST: [f64; 2] = [-1.0, 38.0];
/// Posterior-condyle arc radius, mm.
pub const R_POST: f64 = 19.0;
/// Angle (degrees, from straight down towards posterior) where the distal arc hands over to the
/// posterior arc.
pub const POST_HANDOVER_DEG: f64 = 30.0;
/// Forward lean of the posterior condyles' back face above the posterior-condyle arc, degrees.
pub const POST_LEAN_DEG: f64 = 8.0;
/// Anterior (trochlear) arc radius, mm.
pub const R_ANT: f64 = 20.0;
/// Angle (degrees, from straight down towards anterior) where the distal arc hands over to the
/// anterior arc.
pub const ANT_HANDOVER_DEG: f64 = 35.0;
/// Backward lean of the anterior flange from the femoral axis, degrees.
pub const FLANGE_TILT_DEG: f64 = 5.0;
/// How far up the open contours run before they are closed (beyond any cap), mm.
const Y_FAR: f64 = 120.0;
/// Arc sampling step, degrees (sagitta below 0.002 mm at these radii).
const ARC_STEP_DEG: f64 = 0.5;

/// Metal thickness under each bone cut, mm, in the order of [`cut_normals`].
pub const CUT_THICKNESS: [f64; 5] = [7.5, 8.0, 9.0, 8.0, 8.5];
/// Fillet radius of the bone box's corners, mm.
pub const BOX_FILLET: f64 = 1.0;

/// A closed polygon in the sagittal plane with its signed distance.
#[derive(Debug, Clone, PartialEq)]
pub struct Polygon(pub Vec<[f64; 2]>);

impl Polygon {
    /// Signed distance from `p` to the polygon's boundary: negative inside (even-odd rule).
    pub fn sdf(&self, p: [f64; 2]) -> f64 {
        let v = &self.0;
        let mut d2 = f64::INFINITY;
        let mut inside = false;
        let mut j = v.len() - 1;
        for i in 0..v.len() {
            let (a, b) = (v[j], v[i]);
            let e = [b[0] - a[0], b[1] - a[1]];
            let w = [p[0] - a[0], p[1] - a[1]];
            let t = ((w[0] * e[0] + w[1] * e[1]) / (e[0] * e[0] + e[1] * e[1])).clamp(0.0, 1.0);
            let q = [w[0] - e[0] * t, w[1] - e[1] * t];
            d2 = d2.min(q[0] * q[0] + q[1] * q[1]);
            if (a[1] > p[1]) != (b[1] > p[1]) && p[0] < a[0] + (p[1] - a[1]) * e[0] / e[1] {
                inside = !inside;
            }
            j = i;
        }
        let d = d2.sqrt();
        if inside { -d } else { d }
    }

    /// Largest `n · p` over the vertices (the support function of the polygon).
    pub fn support(&self, n: [f64; 2]) -> f64 {
        self.0
            .iter()
            .map(|p| n[0] * p[0] + n[1] * p[1])
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

fn deg(d: f64) -> f64 {
    d.to_radians()
}

fn dir(angle_deg: f64) -> [f64; 2] {
    [libm::cos(deg(angle_deg)), libm::sin(deg(angle_deg))]
}

fn add(a: [f64; 2], s: f64, d: [f64; 2]) -> [f64; 2] {
    [a[0] + s * d[0], a[1] + s * d[1]]
}

/// Appends the arc of radius `r` about `c` from angle `from` to `to` (degrees from +z towards +y),
/// excluding its start point.
fn arc(out: &mut Vec<[f64; 2]>, c: [f64; 2], r: f64, from: f64, to: f64) {
    let steps = ((to - from) / ARC_STEP_DEG).ceil().max(1.0) as usize;
    for s in 1..=steps {
        out.push(add(c, r, dir(from + (to - from) * s as f64 / steps as f64)));
    }
}

/// Centres of the posterior and anterior arcs, `[z, y]`: each is internally tangent to the distal
/// arc at its hand-over angle.
pub fn arc_centres() -> ([f64; 2], [f64; 2]) {
    let post = add(C_DIST, R_DIST - R_POST, dir(270.0 - POST_HANDOVER_DEG));
    let ant = add(C_DIST, R_DIST - R_ANT, dir(270.0 + ANT_HANDOVER_DEG));
    (post, ant)
}

/// The outer J-contour, closed far above the component (caps are applied separately).
pub fn outer_contour() -> Polygon {
    let (c_post, c_ant) = arc_centres();
    let top_of_arc = add(c_post, R_POST, dir(180.0 - POST_LEAN_DEG));
    let lean = dir(90.0 - POST_LEAN_DEG);
    let mut v = vec![
        add(top_of_arc, (Y_FAR - top_of_arc[1]) / lean[1], lean),
        top_of_arc,
    ];
    arc(
        &mut v,
        c_post,
        R_POST,
        180.0 - POST_LEAN_DEG,
        270.0 - POST_HANDOVER_DEG,
    );
    arc(
        &mut v,
        C_DIST,
        R_DIST,
        270.0 - POST_HANDOVER_DEG,
        270.0 + ANT_HANDOVER_DEG,
    );
    arc(
        &mut v,
        c_ant,
        R_ANT,
        270.0 + ANT_HANDOVER_DEG,
        360.0 + FLANGE_TILT_DEG,
    );
    let tangent = *v.last().unwrap_or(&c_ant);
    let up = dir(90.0 + FLANGE_TILT_DEG);
    v.push(add(tangent, (Y_FAR - tangent[1]) / up[1], up));
    Polygon(v)
}

/// Outward normals (from the bone into the metal) of the five cuts: anterior, anterior chamfer,
/// distal, posterior chamfer, posterior.
pub fn cut_normals() -> [[f64; 2]; 5] {
    [
        dir(FLANGE_TILT_DEG),
        [FRAC_1_SQRT_2, -FRAC_1_SQRT_2],
        [0.0, -1.0],
        [-FRAC_1_SQRT_2, -FRAC_1_SQRT_2],
        [-1.0, 0.0],
    ]
}

/// The bone cuts as lines `n · p = c` (normal, offset), with the metal on the side `n · p > c`.
pub fn cut_planes(outer: &Polygon) -> [([f64; 2], f64); 5] {
    let normals = cut_normals();
    std::array::from_fn(|i| (normals[i], outer.support(normals[i]) - CUT_THICKNESS[i]))
}

/// The resected bone (the inside of the box cuts), closed far above, shrunk by `inset` mm: the
/// corners of the convex polygon `n_i · p ≤ c_i − inset`, counter-clockwise.
pub fn bone_box(outer: &Polygon, inset: f64) -> Polygon {
    let cuts = cut_planes(outer);
    // Counter-clockwise by normal angle: anterior, top, posterior, posterior chamfer, distal,
    // anterior chamfer.
    let lines = [
        cuts[0],
        ([0.0, 1.0], Y_FAR),
        cuts[4],
        cuts[3],
        cuts[2],
        cuts[1],
    ];
    let corners = (0..lines.len())
        .map(|i| {
            let ((n1, c1), (n2, c2)) = (lines[i], lines[(i + 1) % lines.len()]);
            let (c1, c2) = (c1 - inset, c2 - inset);
            let det = n1[0] * n2[1] - n1[1] * n2[0];
            [
                (c1 * n2[1] - c2 * n1[1]) / det,
                (n1[0] * c2 - n2[0] * c1) / det,
            ]
        })
        .collect();
    Polygon(corners)
}

/// Signed distance to the filleted bone box (negative in the bone).
pub struct BoneBox(Polygon);

impl BoneBox {
    /// The bone box of `outer` with corners rounded by [`BOX_FILLET`].
    pub fn new(outer: &Polygon) -> Self {
        BoneBox(bone_box(outer, BOX_FILLET))
    }

    /// Signed distance, mm; negative inside the bone.
    pub fn sdf(&self, p: [f64; 2]) -> f64 {
        self.0.sdf(p) - BOX_FILLET
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contour_is_tangent_continuous_and_spans_about_60_mm() {
        let outer = outer_contour();
        let z_min = -outer.support([-1.0, 0.0]);
        let z_max = outer.support([1.0, 0.0]);
        assert!(
            (55.0..=62.0).contains(&(z_max - z_min)),
            "AP {z_min}..{z_max}"
        );
        assert!(
            outer.support([0.0, -1.0]).abs() < 1e-9,
            "lowest point must be at y = 0"
        );
        // No kinks: consecutive edge directions turn by less than 2° everywhere but the top.
        let v = &outer.0;
        for w in v[1..v.len() - 1].windows(3) {
            let (a, b) = (
                [w[1][0] - w[0][0], w[1][1] - w[0][1]],
                [w[2][0] - w[1][0], w[2][1] - w[1][1]],
            );
            let cross = a[0] * b[1] - a[1] * b[0];
            let dot = a[0] * b[0] + a[1] * b[1];
            let turn = libm::atan2(cross, dot).to_degrees();
            assert!((-0.01..2.0).contains(&turn), "turn {turn}° at {:?}", w[1]);
        }
    }

    #[test]
    fn bone_box_has_five_real_cuts_and_metal_everywhere_under_it() {
        let outer = outer_contour();
        let bone = bone_box(&outer, 0.0);
        let v = &bone.0;
        for i in 0..v.len() {
            let j = (i + 1) % v.len();
            let len = ((v[j][0] - v[i][0]).powi(2) + (v[j][1] - v[i][1]).powi(2)).sqrt();
            assert!(len > 5.0, "cut {i} is only {len} mm long");
        }
        // Every bone corner below the caps is at least 6 mm inside the outer contour.
        for p in v.iter().filter(|p| p[1] < 60.0) {
            assert!(
                outer.sdf(*p) < -6.0,
                "corner {p:?} has {} mm of metal",
                -outer.sdf(*p)
            );
        }
    }

    #[test]
    fn polygon_sdf_of_a_square() {
        let sq = Polygon(vec![[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]);
        assert_eq!(sq.sdf([1.0, 1.0]), -1.0);
        assert_eq!(sq.sdf([3.0, 1.0]), 1.0);
        assert!((sq.sdf([3.0, 3.0]) - 2f64.sqrt()).abs() < 1e-12);
    }
}
