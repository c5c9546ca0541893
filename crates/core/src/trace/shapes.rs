//! Analytic solids: the parameter interval of a line inside a sphere, a cuboid or an elliptic
//! cylinder, and its length on a segment.
//!
//! Every function takes the line `s + t·d` (t real, `d` not normalised) and returns the interval
//! `(t_in, t_out)` with `t_in < t_out` over which the line is inside the closed solid, or `None`
//! when the line misses it or only touches it. The surface belongs to the solid: a line along a
//! face of a cuboid, or along the side of a cylinder, runs inside. No transcendental functions:
//! only IEEE operations and `sqrt`, which are correctly rounded on every platform.

use glam::{DVec2, DVec3};

/// The interval of the line `s + t·d` inside the sphere of radius `radius_mm` at `centre_mm`.
/// The half-chord comes from the distance to the centre through a cross product (no cancellation
/// between the two roots of the quadratic).
pub(super) fn sphere_interval(
    centre_mm: DVec3,
    radius_mm: f64,
    s: DVec3,
    d: DVec3,
) -> Option<(f64, f64)> {
    let w = centre_mm - s;
    let dd = d.length_squared();
    // r²|d|² − |w × d|² = |d|²·(r² − b²), with b the line's distance from the centre.
    let h2 = radius_mm * radius_mm * dd - w.cross(d).length_squared();
    if !(h2 > 0.0 && dd > 0.0) {
        return None;
    }
    let mid = w.dot(d) / dd;
    let half = h2.sqrt() / dd;
    Some((mid - half, mid + half))
}

/// The interval of the line `s + t·d` (local frame) inside the box `|x| ≤ half.x`, `|y| ≤ half.y`,
/// `|z| ≤ half.z` (slabs).
pub(super) fn cuboid_interval(half_mm: DVec3, s: DVec3, d: DVec3) -> Option<(f64, f64)> {
    let mut t = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        t = slab(t, half_mm[k], s[k], d[k])?;
    }
    (t.0 < t.1).then_some(t)
}

/// The interval of the line `s + t·d` (local frame) inside the elliptic cylinder
/// `(x/a)² + (y/b)² ≤ 1`, `|z| ≤ half_length_mm`, with `[a, b] = radii_mm`. The cross-section is
/// scaled to the unit circle, where the half-chord again comes from a cross product.
pub(super) fn cylinder_interval(
    radii_mm: [f64; 2],
    half_length_mm: f64,
    s: DVec3,
    d: DVec3,
) -> Option<(f64, f64)> {
    let scale = DVec2::new(1.0 / radii_mm[0], 1.0 / radii_mm[1]);
    let p = s.truncate() * scale;
    let q = d.truncate() * scale;
    let qq = q.length_squared();
    let side = if qq == 0.0 {
        // Parallel to the axis: inside for every t or for none.
        if !(p.length_squared() <= 1.0) {
            return None;
        }
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        // |p + t·q|² = 1: t = (−p·q ± √(|q|² − (p × q)²)) / |q|².
        let cross = p.perp_dot(q);
        let disc = qq - cross * cross;
        if !(disc >= 0.0) {
            return None;
        }
        let mid = -p.dot(q) / qq;
        let half = disc.sqrt() / qq;
        (mid - half, mid + half)
    };
    let t = slab(side, half_length_mm, s.z, d.z)?;
    (t.0 < t.1).then_some(t)
}

/// Narrows the interval `t` to where `|s + t·d| ≤ half` along one axis; `None` when nothing is left
/// (a NaN, from a non-finite input, also gives `None`).
fn slab(t: (f64, f64), half: f64, s: f64, d: f64) -> Option<(f64, f64)> {
    let t = if d == 0.0 {
        if !(s.abs() <= half) {
            return None;
        }
        t
    } else {
        let (a, b) = ((-half - s) / d, (half - s) / d);
        if a.is_nan() || b.is_nan() {
            return None;
        }
        (t.0.max(a.min(b)), t.1.min(a.max(b)))
    };
    (t.0 <= t.1).then_some(t)
}

/// The length (mm) of the part of the interval `t` that lies on the segment `0 ≤ t ≤ 1` of the
/// line `s + t·d`.
pub(super) fn segment_length_mm((t_in, t_out): (f64, f64), d: DVec3) -> f64 {
    let span = t_out.min(1.0) - t_in.max(0.0);
    if span > 0.0 { span * d.length() } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1.0)
    }

    #[test]
    fn a_sphere_chord_is_twice_the_half_chord_from_the_line_distance() {
        let centre = DVec3::new(1.0, -2.0, 500.0);
        let r = 6.0;
        let s = DVec3::new(3.0, 1.0, 1000.0);
        for k in 0..50 {
            let target = DVec3::new(-8.0 + 0.33 * k as f64, 0.7 * k as f64 - 20.0, 0.0);
            let d = target - s;
            // b: distance from the centre to the closest point of the line.
            let closest = s + d * ((centre - s).dot(d) / d.length_squared());
            let b = (closest - centre).length();
            let length = sphere_interval(centre, r, s, d).map_or(0.0, |t| segment_length_mm(t, d));
            let expected = if b < r {
                2.0 * (r * r - b * b).sqrt()
            } else {
                0.0
            };
            assert!(
                (length - expected).abs() < 1e-9,
                "{k}: {length} vs {expected}"
            );
        }
    }

    #[test]
    fn a_chord_is_clipped_to_the_segment() {
        // The segment ends inside the sphere (at its centre): half the chord; starts inside: too.
        let d = DVec3::new(0.0, 0.0, -10.0);
        let t = sphere_interval(DVec3::ZERO, 2.0, DVec3::new(0.0, 0.0, 10.0), d).unwrap();
        assert!(close(segment_length_mm(t, d), 10.0 - 8.0));
        let t = sphere_interval(DVec3::ZERO, 2.0, DVec3::new(0.0, 0.0, 1.0), d).unwrap();
        assert!(close(segment_length_mm(t, d), 3.0));
        // Entirely behind the segment's end: nothing.
        let t = sphere_interval(DVec3::new(0.0, 0.0, -20.0), 2.0, DVec3::ZERO, d).unwrap();
        assert_eq!(segment_length_mm(t, d), 0.0);
    }

    #[test]
    fn cuboid_chords_along_an_axis_and_obliquely() {
        let half = DVec3::new(5.0, 10.0, 2.0);
        let s = DVec3::new(1.0, 2.0, 100.0);
        // Along −z through the plate: its thickness, 4 mm.
        let d = DVec3::new(0.0, 0.0, -200.0);
        let t = cuboid_interval(half, s, d).unwrap();
        assert!(close(segment_length_mm(t, d), 4.0));
        // Oblique, through both z faces: 4 mm / cos θ, with tan θ = 3/100 in x.
        let d = DVec3::new(3.0, 0.0, -100.0) * 2.0;
        let t = cuboid_interval(half, s, d).unwrap();
        assert!(close(
            segment_length_mm(t, d),
            4.0 * (1.0f64 + 0.0009).sqrt()
        ));
        // Enters through the top face (z = 2 at x = 4.9) and leaves through the side x = 5.
        let s2 = DVec3::new(4.9, 0.0, 2.0);
        let d2 = DVec3::new(1.0, 0.0, -10.0); // x = 5 at t = 0.1: z = 1.
        let t = cuboid_interval(half, s2, d2).unwrap();
        assert!(close(segment_length_mm(t, d2), 0.1 * d2.length()));
        let miss = cuboid_interval(half, s, DVec3::new(6.0, 0.0, -100.0));
        assert_eq!(miss, None);
        // Parallel to a face, outside it and on it.
        assert_eq!(
            cuboid_interval(
                half,
                DVec3::new(5.5, 0.0, 10.0),
                DVec3::new(0.0, 0.0, -20.0)
            ),
            None
        );
        let t = cuboid_interval(
            half,
            DVec3::new(5.0, 0.0, 10.0),
            DVec3::new(0.0, 0.0, -20.0),
        );
        assert_eq!(t, Some((0.4, 0.6)));
    }

    #[test]
    fn elliptic_cylinder_chords_along_an_axis_and_obliquely() {
        let radii = [40.0, 25.0];
        let half_length = 100.0;
        // Along −y through the axis: the full minor diameter, 50 mm.
        let s = DVec3::new(0.0, 300.0, 10.0);
        let d = DVec3::new(0.0, -600.0, 0.0);
        let t = cylinder_interval(radii, half_length, s, d).unwrap();
        assert!(close(segment_length_mm(t, d), 50.0));
        // Along −y at x = 20: y = ±25·√(1 − 1/4) = ±21.65: chord 25·√3.
        let t = cylinder_interval(radii, half_length, DVec3::new(20.0, 300.0, 0.0), d).unwrap();
        assert!(close(segment_length_mm(t, d), 25.0 * 3f64.sqrt()));
        // Along the axis (−z): the full length, 200 mm; outside the ellipse: nothing.
        let dz = DVec3::new(0.0, 0.0, -1000.0);
        let t = cylinder_interval(radii, half_length, DVec3::new(30.0, 10.0, 500.0), dz).unwrap();
        assert!(close(segment_length_mm(t, dz), 200.0));
        assert_eq!(
            cylinder_interval(radii, half_length, DVec3::new(30.0, 20.0, 500.0), dz),
            None
        );
        // Oblique in the x–z plane through the axis: the line x = 0.5·z enters the side at
        // x = ±40 (z = ±80, inside the caps): chord √(80² + 160²) = 80·√5.
        let s = DVec3::new(250.0, 0.0, 500.0);
        let d = DVec3::new(-500.0, 0.0, -1000.0);
        let t = cylinder_interval(radii, half_length, s, d).unwrap();
        assert!(close(segment_length_mm(t, d), 80.0 * 5f64.sqrt()));
        // Steeper, x = 0.2·z: the caps cut it at z = ±100 (x = ±20): chord √(40² + 200²).
        let d = DVec3::new(-200.0, 0.0, -1000.0);
        let s = DVec3::new(100.0, 0.0, 500.0);
        let t = cylinder_interval(radii, half_length, s, d).unwrap();
        assert!(close(
            segment_length_mm(t, d),
            (40f64 * 40.0 + 200.0 * 200.0).sqrt()
        ));
    }

    #[test]
    fn non_finite_input_gives_no_interval() {
        let d = DVec3::new(0.0, 0.0, -1.0);
        assert_eq!(
            cuboid_interval(DVec3::splat(1.0), DVec3::splat(f64::NAN), d),
            None
        );
        assert_eq!(
            cylinder_interval([1.0, 1.0], 1.0, DVec3::splat(f64::NAN), d),
            None
        );
        assert_eq!(sphere_interval(DVec3::ZERO, 1.0, DVec3::NAN, d), None);
    }
}
