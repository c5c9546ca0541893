//! Checking and repairing reconstructed rotation matrices.

use glam::{DMat3, DQuat};

use crate::geometry::rotation_from_rows;

/// Largest deviation from orthonormality that is silently repaired: `max |RᵀR − I|`.
pub const REPAIR_TOLERANCE: f64 = 1e-6;

/// A rotation as a software wrote it: checked to be a proper rotation, re-orthonormalised when
/// within [`REPAIR_TOLERANCE`]; otherwise an error naming the deviation.
pub fn checked_rotation(rows: [[f64; 3]; 3]) -> Result<DMat3, String> {
    if rows.iter().flatten().any(|x| !x.is_finite()) {
        return Err("the rotation has a NaN or infinite entry".into());
    }
    let m = rotation_from_rows(rows);
    let deviation = orthonormality_deviation(&m);
    if deviation > REPAIR_TOLERANCE {
        return Err(format!(
            "the rotation is not orthonormal: max |RᵀR − I| = {deviation:.3e} (at most {REPAIR_TOLERANCE:e} is repaired)"
        ));
    }
    if m.determinant() < 0.0 {
        return Err("the rotation has determinant −1 (a reflection, not a rotation)".into());
    }
    Ok(orthonormalise(m))
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

/// The rotation of a unit quaternion (w, x, y, z), normalised; an error if it is far from unit
/// length (|‖q‖ − 1| > 1e-6) or not finite.
pub fn rotation_from_quaternion(w: f64, x: f64, y: f64, z: f64) -> Result<DMat3, String> {
    let q = DQuat::from_xyzw(x, y, z, w);
    if !q.is_finite() {
        return Err("the quaternion has a NaN or infinite component".into());
    }
    let norm = q.length();
    if (norm - 1.0).abs() > REPAIR_TOLERANCE {
        return Err(format!(
            "the quaternion is not a unit quaternion: ‖q‖ = {norm:.9} (within 1e-6 of 1 is repaired)"
        ));
    }
    Ok(DMat3::from_quat(q / norm))
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
        bent[0][1] += 4e-7;
        let fixed = checked_rotation(bent).unwrap();
        assert!(orthonormality_deviation(&fixed) < 1e-14);
        assert!((fixed - r).abs_diff_eq(DMat3::ZERO, 1e-6));
        bent[0][1] += 1e-3;
        let e = checked_rotation(bent).unwrap_err();
        assert!(
            e.contains("not orthonormal: max |RᵀR − I| = 9.391e-4"),
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
        let m = rotation_from_quaternion(h, 0.0, 0.0, h).unwrap();
        assert!((m - rotation_xyz_deg([0.0, 0.0, 90.0])).abs_diff_eq(DMat3::ZERO, 1e-12));
        assert!(rotation_from_quaternion(1.0, 0.1, 0.0, 0.0).is_err());
    }
}
