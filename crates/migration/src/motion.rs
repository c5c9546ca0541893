//! The implant's motion relative to the reference segment, in its anatomical frame.
//!
//! With `B` the reference segment's pose, `A` the anatomical frame's pose in it and `I` the
//! implant's pose (box frame), the implant's pose in the anatomical frame is `P = (B·A)⁻¹·I`; the
//! migration from the reference exam to exam `e` is `M = P_e·P_ref⁻¹`. Its numbers: the motion
//! `M·c − c` of the implant's centre `c` (the centroid of its MTPM points in the anatomical frame
//! at the reference exam), the X-Y-Z Euler angles of `M`'s rotation (`R = Rx·Ry·Rz`) and the
//! largest `|M·p − p|` over the MTPM points (MTPM).

use glam::DVec3;

use crate::geometry::{Pose, euler_xyz_deg};

/// The migration of an implant segment at one exam, relative to the reference exam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Migration {
    /// Motion of the implant's centre along the anatomical x, y, z axes, mm.
    pub translation_mm: [f64; 3],
    /// X-Y-Z Euler angles of the relative rotation about the anatomical axes, degrees.
    pub rotation_deg: [f64; 3],
    /// Maximum total point motion over the MTPM points, mm.
    pub mtpm_mm: f64,
}

/// `P = (B·A)⁻¹·I`: the implant's pose in the anatomical frame, from the reference segment's
/// pose `reference_segment` (B), the anatomical frame's pose in that segment's local frame
/// `anatomical_frame` (A) and the implant's pose `implant` (I), both segment poses in one frame.
pub fn pose_in_anatomical_frame(
    reference_segment: &Pose,
    anatomical_frame: &Pose,
    implant: &Pose,
) -> Pose {
    reference_segment
        .compose(anatomical_frame)
        .inverse()
        .compose(implant)
}

/// `M = P_e·P_ref⁻¹`: the rigid motion that carries a point of the implant, expressed in the
/// anatomical frame at the reference exam, to where it is at the exam.
pub fn relative_motion(at_reference: &Pose, at_exam: &Pose) -> Pose {
    at_exam.compose(&at_reference.inverse())
}

/// The migration's numbers from the implant's pose in the anatomical frame at the reference exam
/// (`at_reference`) and at the exam (`at_exam`), with `mtpm_points_mm` given in the implant's
/// local frame. With no points, the implant's local origin stands for them (its centre and its
/// only MTPM point).
pub fn migration(at_reference: &Pose, at_exam: &Pose, mtpm_points_mm: &[DVec3]) -> Migration {
    let m = relative_motion(at_reference, at_exam);
    let points: Vec<DVec3> = if mtpm_points_mm.is_empty() {
        vec![at_reference.position_mm]
    } else {
        mtpm_points_mm
            .iter()
            .map(|p| at_reference.to_world(*p))
            .collect()
    };
    let centre = points.iter().copied().sum::<DVec3>() / points.len() as f64;
    let mtpm_mm = points
        .iter()
        .map(|p| (m.to_world(*p) - *p).length())
        .fold(0.0, f64::max);
    Migration {
        translation_mm: (m.to_world(centre) - centre).to_array(),
        rotation_deg: euler_xyz_deg(&m.rotation),
        mtpm_mm,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::rotation_xyz_deg;

    fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
    }

    /// A bone placed anywhere in the box, an anatomical frame turned in it, and an implant
    /// translated by `t` (anatomical axes) about its centre and turned by `r` at the exam, while
    /// the whole limb was repositioned: the migration gives exactly `t` and `r`.
    #[test]
    fn a_known_motion_gives_exactly_its_numbers() {
        let anatomical = Pose::from_position_euler_deg([3.0, -40.0, 2.0], [0.0, 90.0, 0.0]);
        let bone_ref = Pose::from_position_euler_deg([10.0, 20.0, -5.0], [5.0, -12.0, 30.0]);
        let implant_ref = Pose::from_position_euler_deg([14.0, -2.0, 1.0], [-3.0, 8.0, 25.0]);
        // Fictive points: a 60 × 20 × 40 mm box's corners in the implant's frame.
        let points: Vec<DVec3> = (0..8)
            .map(|k| {
                DVec3::new(
                    if k & 1 == 0 { -30.0 } else { 30.0 },
                    if k & 2 == 0 { 0.0 } else { 20.0 },
                    if k & 4 == 0 { -20.0 } else { 20.0 },
                )
            })
            .collect();
        let p_ref = pose_in_anatomical_frame(&bone_ref, &anatomical, &implant_ref);
        let centre = points.iter().map(|p| p_ref.to_world(*p)).sum::<DVec3>() / 8.0;
        // Subsidence 0.2 mm (−y), 0.05 mm medial, 0.3° tilt about x then 0.1° about z.
        let (t, r) = ([0.05, -0.2, 0.0], [0.3, 0.0, 0.1]);
        let rot = rotation_xyz_deg(r);
        // M about the centre: p ↦ R·(p − c) + c + t.
        let m = Pose {
            rotation: rot,
            position_mm: centre + DVec3::from_array(t) - rot * centre,
        };
        let p_exam = m.compose(&p_ref);
        // The patient repositioned: bone and implant both moved by one rigid pose.
        let limb = Pose::from_position_euler_deg([-25.0, 7.0, 12.0], [8.0, 3.0, -15.0]);
        let bone_exam = limb.compose(&bone_ref);
        let implant_exam = limb.compose(&bone_ref.compose(&anatomical).compose(&p_exam));
        let got = migration(
            &p_ref,
            &pose_in_anatomical_frame(&bone_exam, &anatomical, &implant_exam),
            &points,
        );
        assert!(close(got.translation_mm, t, 1e-10), "{got:?}");
        assert!(close(got.rotation_deg, r, 1e-10), "{got:?}");
        // MTPM of a pure translation is its length; here the hand value is the largest motion of
        // a corner: |R·(p − c) − (p − c) + t| over the 8 corners.
        let want = points
            .iter()
            .map(|p| {
                let q = p_ref.to_world(*p) - centre;
                (rot * q - q + DVec3::from_array(t)).length()
            })
            .fold(0.0, f64::max);
        assert!(
            (got.mtpm_mm - want).abs() < 1e-10,
            "{} vs {want}",
            got.mtpm_mm
        );
        assert!(got.mtpm_mm > (0.05f64.powi(2) + 0.2f64.powi(2)).sqrt());
    }

    #[test]
    fn a_pure_translation_has_its_length_as_mtpm_and_no_rotation() {
        let anatomical = Pose::IDENTITY;
        let bone = Pose::from_position_euler_deg([1.0, 2.0, 3.0], [0.0, 0.0, 90.0]);
        let implant_ref = Pose::from_position_euler_deg([0.0, 10.0, 0.0], [0.0, 0.0, 0.0]);
        // In the box frame the implant moves −x, which is the bone's +y (the bone is turned 90°
        // about z, so its local y axis points along box −x): 0.3 mm proximal.
        let implant_exam = Pose::from_position_euler_deg([-0.3, 10.0, 0.0], [0.0, 0.0, 0.0]);
        let g = migration(
            &pose_in_anatomical_frame(&bone, &anatomical, &implant_ref),
            &pose_in_anatomical_frame(&bone, &anatomical, &implant_exam),
            &[DVec3::new(5.0, 0.0, 0.0), DVec3::new(-5.0, 1.0, 2.0)],
        );
        assert!(close(g.translation_mm, [0.0, 0.3, 0.0], 1e-12), "{g:?}");
        assert!(close(g.rotation_deg, [0.0, 0.0, 0.0], 1e-12));
        assert!((g.mtpm_mm - 0.3).abs() < 1e-12);
        // No points: the origin stands for them.
        let g = migration(
            &pose_in_anatomical_frame(&bone, &anatomical, &implant_ref),
            &pose_in_anatomical_frame(&bone, &anatomical, &implant_exam),
            &[],
        );
        assert!((g.mtpm_mm - 0.3).abs() < 1e-12);
    }

    #[test]
    fn the_reference_exam_has_no_migration() {
        let p = Pose::from_position_euler_deg([4.0, 5.0, 6.0], [10.0, 20.0, 30.0]);
        let g = migration(&p, &p, &[DVec3::new(1.0, 2.0, 3.0)]);
        assert!(close(g.translation_mm, [0.0; 3], 1e-12));
        assert!(close(g.rotation_deg, [0.0; 3], 1e-12));
        assert!(g.mtpm_mm < 1e-12);
    }
}
