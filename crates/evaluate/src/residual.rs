//! Residuals exactly as docs/src/reference/conventions.md ("Accuracy") defines them.
//!
//! - Position: Δ = x_measured − x_true.
//! - Orientation: M = R_measured · R_trueᵀ = Mx(α)·My(β)·Mz(γ), angles in degrees.
//! - Sources and detectors are reported along their beamline axes (r, c, s) of the TRUE detector:
//!   positions R_detᵀ·Δ, orientations R_detᵀ·M·R_det. Phantoms along the box axes x, y, z.

use glam::{DMat3, DVec3};

use crate::geometry::euler_xyz_deg;

/// Numerical resolution of residuals, in mm or degrees: 1e-12, far below anything physical.
/// Residuals are rounded to it before any statistic, so an exact reconstruction scores exactly
/// zero instead of double-precision round-off (≈1e-16) that a significance test would flag.
pub const RESOLUTION: f64 = 1e-12;

/// `x` rounded to a multiple of [`RESOLUTION`].
pub fn quantise(x: f64) -> f64 {
    (x / RESOLUTION).round() * RESOLUTION
}

/// A position residual along the axes of `frame` (columns = axes): `frameᵀ·(measured − true)`.
pub fn position_along(frame: &DMat3, measured: DVec3, truth: DVec3) -> [f64; 3] {
    (frame.transpose() * (measured - truth)).to_array()
}

/// An orientation residual `[α, β, γ]` in degrees about the axes of `frame`:
/// the X-Y-Z decomposition of `frameᵀ · (R_measured·R_trueᵀ) · frame`.
pub fn orientation_about(frame: &DMat3, measured: &DMat3, truth: &DMat3) -> [f64; 3] {
    let m = *measured * truth.transpose();
    euler_xyz_deg(&(frame.transpose() * m * *frame))
}

/// Maximum total point motion: the largest distance between a point of the object carried by
/// the true pose and by the measured pose. `points_local` are in the object's frame.
pub fn mtpm(points_local: &[DVec3], measured: (DVec3, DMat3), truth: (DVec3, DMat3)) -> f64 {
    points_local
        .iter()
        .map(|p| ((measured.1 * *p + measured.0) - (truth.1 * *p + truth.0)).length())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::rotation_xyz_deg;

    #[test]
    fn round_off_is_quantised_away_but_real_residuals_are_kept() {
        assert_eq!(quantise(-3.3e-16), 0.0);
        assert_eq!(quantise(0.1 + 1e-17), quantise(0.1));
        assert!((quantise(0.123456789) - 0.123456789).abs() < 1e-12);
        assert!((quantise(-2.5e-9) + 2.5e-9).abs() < 1e-15);
    }

    #[test]
    fn a_reconstruction_turned_plus_one_degree_about_x_reports_alpha_plus_one() {
        let truth = rotation_xyz_deg([3.0, -7.0, 20.0]);
        let measured = rotation_xyz_deg([1.0, 0.0, 0.0]) * truth;
        let [a, b, c] = orientation_about(&DMat3::IDENTITY, &measured, &truth);
        assert!((a - 1.0).abs() < 1e-12 && b.abs() < 1e-12 && c.abs() < 1e-12);
    }

    #[test]
    fn detector_residuals_are_along_its_own_axes() {
        // A detector of beamline 2 (s = +x): r = −z, c = +y, s = +x.
        let det = rotation_xyz_deg([0.0, 90.0, 0.0]);
        // A source moved 2 mm towards the detector (along −s = −x) reports s = −2.
        let [r, c, s] = position_along(
            &det,
            DVec3::new(1298.0, 0.0, 0.0),
            DVec3::new(1300.0, 0.0, 0.0),
        );
        assert!(r.abs() < 1e-12 && c.abs() < 1e-12 && (s + 2.0).abs() < 1e-12);
        // A detector turned 0.5° about its own s axis (world x) reports γ_s = 0.5.
        let measured = rotation_xyz_deg([0.5, 0.0, 0.0]) * det;
        let [a, b, g] = orientation_about(&det, &measured, &det);
        assert!(
            a.abs() < 1e-12 && b.abs() < 1e-12 && (g - 0.5).abs() < 1e-12,
            "{a} {b} {g}"
        );
    }

    #[test]
    fn mtpm_is_the_largest_point_displacement() {
        let pts = [DVec3::new(10.0, 0.0, 0.0), DVec3::new(0.0, 0.0, 0.0)];
        let truth = (DVec3::ZERO, DMat3::IDENTITY);
        // Turn 90° about z: the point at (10, 0, 0) moves to (0, 10, 0): √200.
        let measured = (DVec3::ZERO, rotation_xyz_deg([0.0, 0.0, 90.0]));
        assert!((mtpm(&pts, measured, truth) - 200f64.sqrt()).abs() < 1e-12);
    }
}
