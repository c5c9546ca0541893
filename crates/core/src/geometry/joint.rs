//! A joint's kinematics in the joint coordinate system of Grood and Suntay (E.S. Grood, W.J.
//! Suntay, *A joint coordinate system for the clinical description of three-dimensional motions:
//! application to the knee*, J Biomech Eng 1983;105:136–144), as the ISB recommends it.
//!
//! Given the proximal anatomical frame `P` (axes `x_p` medio-lateral, `y_p` proximal, `z_p`
//! anterior; origin `o_p`) and the distal one `D` (`x_d`, `y_d`, `z_d`, origin `o_d`), both in one
//! world frame:
//!
//! * `e1 = x_p`, the fixed flexion axis of the proximal segment;
//! * `e3 = y_d`, the fixed long axis of the distal segment;
//! * `e2 = (e1 × e3)/|e1 × e3|`, the floating axis (anterior when the frames are aligned).
//!
//! Angles, in degrees, each by the right-hand rule about its axis:
//!
//! * flexion `α` about `e1`: `α = atan2(−e2·y_p, e2·z_p)`;
//! * ab/adduction `β` about `e2`: `β = asin(−e1·e3)` (so `β = 0` when `e1 ⟂ e3`);
//! * internal/external rotation `γ` about `e3`: `γ = atan2(−e2·x_d, e2·z_d)`.
//!
//! These are the Cardan angles of `R = Pᵀ·D = Rx(α)·Rz(β)·Ry(γ)`. Translations, in mm, are the
//! components of `H = o_d − o_p` along the three axes: `q = (H·e1, H·e2, H·e3)`. With the distal
//! frame's x to the left of a right knee, positive `α` is flexion (the distal segment's anterior
//! axis turning down); what positive `β` and `γ` mean clinically (valgus or varus, internal or
//! external rotation) depends on the side and is the reader's to name.

use glam::{DMat3, DVec3};

use super::Pose;

/// The kinematics of a joint at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointAngles {
    /// Flexion α, ab/adduction β and axial rotation γ, degrees.
    pub angles_deg: [f64; 3],
    /// Translations along e1, e2, e3, mm.
    pub translation_mm: [f64; 3],
}

/// The joint coordinate system's angles and translations between the proximal anatomical frame
/// `proximal` and the distal one `distal` (both poses in one world frame; module documentation).
/// At `β = ±90°` (e1 parallel to e3) the floating axis is undefined: the angles are then NaN.
pub fn grood_suntay(proximal: &Pose, distal: &Pose) -> JointAngles {
    let (p, d): (&DMat3, &DMat3) = (&proximal.rotation, &distal.rotation);
    let (e1, e3) = (p.x_axis, d.y_axis);
    let e2 = e1.cross(e3).normalize();
    let flexion = libm::atan2(-e2.dot(p.y_axis), e2.dot(p.z_axis));
    let adduction = libm::asin((-e1.dot(e3)).clamp(-1.0, 1.0));
    let rotation = libm::atan2(-e2.dot(d.x_axis), e2.dot(d.z_axis));
    let h: DVec3 = distal.position_mm - proximal.position_mm;
    JointAngles {
        angles_deg: [flexion, adduction, rotation].map(f64::to_degrees),
        translation_mm: [h.dot(e1), h.dot(e2), h.dot(e3)],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rx(a: f64) -> DMat3 {
        DMat3::from_rotation_x(a.to_radians())
    }
    fn ry(a: f64) -> DMat3 {
        DMat3::from_rotation_y(a.to_radians())
    }
    fn rz(a: f64) -> DMat3 {
        DMat3::from_rotation_z(a.to_radians())
    }

    #[test]
    fn the_angles_are_the_cardan_angles_x_z_y_of_the_relative_rotation() {
        // A proximal frame at an arbitrary pose, the distal one turned by Rx(α)·Rz(β)·Ry(γ)
        // relative to it: the joint gives back (α, β, γ).
        let base = Pose {
            position_mm: DVec3::new(3.0, -7.0, 11.0),
            rotation: rz(25.0) * ry(-40.0) * rx(12.0),
        };
        for (a, b, g) in [
            (0.0, 0.0, 0.0),
            (60.0, 4.0, -9.0),
            (-10.0, -7.5, 20.0),
            (120.0, 30.0, 45.0),
        ] {
            let distal = Pose {
                position_mm: base.to_world(DVec3::new(1.0, -40.0, 2.0)),
                rotation: base.rotation * rx(a) * rz(b) * ry(g),
            };
            let j = grood_suntay(&base, &distal);
            for (got, want) in j.angles_deg.iter().zip([a, b, g]) {
                assert!((got - want).abs() < 1e-10, "{j:?} vs {a} {b} {g}");
            }
        }
    }

    #[test]
    fn translations_are_measured_along_e1_e2_e3_by_hand() {
        // Aligned frames: e1 = x, e2 = z (anterior), e3 = y; the distal origin 40 mm below and
        // 2 mm medial (−x), 3 mm anterior: q = (−2, 3, −40).
        let p = Pose::IDENTITY;
        let d = Pose {
            position_mm: DVec3::new(-2.0, -40.0, 3.0),
            rotation: DMat3::IDENTITY,
        };
        let j = grood_suntay(&p, &d);
        assert_eq!(j.angles_deg, [0.0, 0.0, 0.0]);
        assert_eq!(j.translation_mm, [-2.0, 3.0, -40.0]);
        // Flexed 90° about x: e3 = y_d = Rx(90°)·y = z, e2 = x × z = −y: the same origin offset
        // reads q = (−2, 40, 3).
        let d = Pose {
            position_mm: DVec3::new(-2.0, -40.0, 3.0),
            rotation: rx(90.0),
        };
        let j = grood_suntay(&p, &d);
        assert!((j.angles_deg[0] - 90.0).abs() < 1e-12, "{j:?}");
        let want = [-2.0, 40.0, 3.0];
        for (got, want) in j.translation_mm.iter().zip(want) {
            assert!((got - want).abs() < 1e-12, "{j:?}");
        }
    }
}
