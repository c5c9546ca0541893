//! Checking and repairing reconstructed rotation matrices.

use glam::{DMat3, DQuat};

use crate::geometry::rotation_from_rows;

/// Largest deviation from orthonormality that is repaired: `max |RᵀR − I|` and `|det R − 1|` of a
/// matrix, `|‖q‖ − 1|` of a quaternion. Rotations printed to 6 decimals deviate by about 1e-6;
/// anything beyond 1e-3 is not a rounded rotation and is rejected.
pub const REPAIR_TOLERANCE: f64 = 1e-3;

/// Deviations at or below this are double-precision round-off, not a repair worth counting.
pub const ROUND_OFF: f64 = 1e-12;

/// A rotation as a software wrote it, checked to be a proper rotation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckedRotation {
    /// The nearest proper rotation.
    pub rotation: DMat3,
    /// Whether it had to be re-orthonormalised (deviation above [`ROUND_OFF`]).
    pub repaired: bool,
}

/// A rotation as a software wrote it: checked to be a proper rotation, re-orthonormalised (the
/// nearest rotation, by polar decomposition) when within [`REPAIR_TOLERANCE`]; otherwise an
/// error naming the deviation.
pub fn checked_rotation(rows: [[f64; 3]; 3]) -> Result<CheckedRotation, String> {
    if rows.iter().flatten().any(|x| !x.is_finite()) {
        return Err("the rotation has a NaN or infinite entry".into());
    }
    let m = rotation_from_rows(rows);
    let deviation = orthonormality_deviation(&m);
    if !(deviation <= REPAIR_TOLERANCE) {
        return Err(format!(
            "the rotation is not orthonormal: max |RᵀR − I| = {deviation:.3e} (at most {REPAIR_TOLERANCE:e} is repaired)"
        ));
    }
    let det = m.determinant();
    if det < 0.0 {
        return Err("the rotation has determinant −1 (a reflection, not a rotation)".into());
    }
    let det_deviation = (det - 1.0).abs();
    if !(det_deviation <= REPAIR_TOLERANCE) {
        return Err(format!(
            "the rotation's determinant is {det:.6} (|det − 1| = {det_deviation:.3e}; at most {REPAIR_TOLERANCE:e} is repaired)"
        ));
    }
    Ok(CheckedRotation {
        rotation: orthonormalise(m),
        repaired: deviation.max(det_deviation) > ROUND_OFF,
    })
}

/// `max |RᵀR − I|` over the nine entries.
pub fn orthonormality_deviation(m: &DMat3) -> f64 {
    let e = m.transpose() * *m - DMat3::IDENTITY;
    e.to_cols_array().iter().fold(0.0, |a, x| a.max(x.abs()))
}

/// The nearest rotation to an almost-orthonormal matrix (Newton iteration of the polar
/// decomposition, R ← (R + R⁻ᵀ)/2, quadratically convergent).
pub fn orthonormalise(mut m: DMat3) -> DMat3 {
    for _ in 0..8 {
        m = (m + m.inverse().transpose()) * 0.5;
    }
    m
}

/// The rotation of a unit quaternion (w, x, y, z), normalised when |‖q‖ − 1| ≤
/// [`REPAIR_TOLERANCE`]; an error if it is farther from unit length or not finite.
pub fn rotation_from_quaternion(w: f64, x: f64, y: f64, z: f64) -> Result<CheckedRotation, String> {
    let q = DQuat::from_xyzw(x, y, z, w);
    if !q.is_finite() {
        return Err("the quaternion has a NaN or infinite component".into());
    }
    let norm = q.length();
    let deviation = (norm - 1.0).abs();
    if !(deviation <= REPAIR_TOLERANCE) {
        return Err(format!(
            "the quaternion is not a unit quaternion: ‖q‖ = {norm:.9} (within {REPAIR_TOLERANCE:e} of 1 is repaired)"
        ));
    }
    Ok(CheckedRotation {
        rotation: DMat3::from_quat(q / norm),
        repaired: deviation > ROUND_OFF,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{rotation_rows, rotation_xyz_deg};

    fn rows(m: DMat3) -> [[f64; 3]; 3] {
        rotation_rows(&m)
    }

    #[test]
    fn small_deviations_are_repaired_large_ones_named() {
        let r = rotation_xyz_deg([10.0, 20.0, 30.0]);
        let mut bent = rows(r);
        assert!(!checked_rotation(bent).unwrap().repaired);
        bent[0][1] += 4e-7;
        let fixed = checked_rotation(bent).unwrap();
        assert!(fixed.repaired);
        assert!(orthonormality_deviation(&fixed.rotation) < 1e-14);
        assert!((fixed.rotation - r).abs_diff_eq(DMat3::ZERO, 1e-6));
        bent[0][1] += 1e-2;
        let e = checked_rotation(bent).unwrap_err();
        assert!(
            e.contains("not orthonormal: max |RᵀR − I| = 9.297e-3"),
            "{e}"
        );
        let mut mirror = rows(DMat3::IDENTITY);
        mirror[2][2] = -1.0;
        assert!(checked_rotation(mirror).unwrap_err().contains("reflection"));
    }

    #[test]
    fn quaternions_match_matrices() {
        // 90° about z: q = (cos 45°, 0, 0, sin 45°).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let m = rotation_from_quaternion(h, 0.0, 0.0, h).unwrap().rotation;
        assert!((m - rotation_xyz_deg([0.0, 0.0, 90.0])).abs_diff_eq(DMat3::ZERO, 1e-12));
        assert!(rotation_from_quaternion(1.0, 0.1, 0.0, 0.0).is_err());
        // 1/√2 rounded to 6 digits on purpose: a quaternion as a file would hold it.
        #[allow(clippy::approx_constant)]
        let rounded = rotation_from_quaternion(0.707107, 0.0, 0.0, 0.707107).unwrap();
        assert!(rounded.repaired);
        assert!((rounded.rotation - m).abs_diff_eq(DMat3::ZERO, 1e-6));
    }

    #[test]
    fn rotations_rounded_to_six_decimals_are_repaired_and_counted() {
        let r = rotation_xyz_deg([12.3, -45.6, 78.9]);
        let rounded = rows(r).map(|row| row.map(|x| (x * 1e6).round() / 1e6));
        let fixed = checked_rotation(rounded).unwrap();
        assert!(fixed.repaired);
        assert!((fixed.rotation - r).abs_diff_eq(DMat3::ZERO, 2e-6));
        let mut far = rows(r);
        far[1][1] += 1e-2;
        assert!(
            checked_rotation(far)
                .unwrap_err()
                .contains("not orthonormal")
        );
    }
}
