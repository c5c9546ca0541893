//! A rigid fit between two exams' triangulated markers, weighted by how well each marker's
//! position is known in each direction.
//!
//! A marker triangulated from two views is known least well along the depth both beams share:
//! its error is a fraction of a pixel across each ray, and the rays of a uniplanar room cross at
//! about 40°. With lateral error σ across every ray, the least-squares intersection of rays from
//! sources `s_i` has the information matrix `Σ (I − d_i·d_iᵀ) / σ²`, `d_i` the unit direction
//! from `s_i` to the marker. For rays at ±20° from the vertical its covariance is
//! `σ²·diag(0.57, 0.50, 4.3)`: the depth error is 2.8 times the others (the shipped study's
//! measured bead errors: 0.057 mm along z, 0.020 mm along x).
//!
//! The fit of follow-up markers `y_k` to reference markers `x_k` minimises
//! `Σ r_kᵀ·W_k·r_k` with `r_k = R·x_k + t − y_k` and `W_k = (R·C_x,k·Rᵀ + C_y,k)⁻¹`, the inverse
//! covariance of the residual (both exams' errors, the reference's turned by `R`), by
//! Gauss–Newton from the unweighted (Kabsch) fit. Equal covariances give the Kabsch fit.

use glam::{DMat3, DVec3};
use nalgebra::{Matrix6, Vector6};

use crate::geometry::{Pose, RigidFit, condition_number, fit_rigid};

/// Gauss–Newton stops when the update is below this (radians and mm).
const CONVERGED: f64 = 1e-12;

/// Gauss–Newton iterations at most (it converges in three or four).
const MAX_ITERATIONS: usize = 20;

/// The covariance, up to the common factor σ², of a point at `point_mm` triangulated from rays
/// from `sources_mm` with the same lateral error σ across each: `(Σ (I − d·dᵀ))⁻¹`. `None` for
/// fewer than two sources, or rays too close to parallel to place the point.
pub fn triangulation_covariance(point_mm: DVec3, sources_mm: &[DVec3]) -> Option<DMat3> {
    if sources_mm.len() < 2 {
        return None;
    }
    let information = sources_mm
        .iter()
        .filter_map(|s| (point_mm - *s).try_normalize())
        .map(|d| DMat3::IDENTITY - DMat3::from_cols(d * d.x, d * d.y, d * d.z))
        .fold(DMat3::ZERO, |a, b| a + b);
    // Rays within about half a degree of each other leave the depth undetermined.
    (information.determinant() > 1e-12).then(|| information.inverse())
}

/// The rigid fit `y ≈ R·x + t` minimising the covariance-weighted residuals (see the module
/// doc); `cov_from[k]` and `cov_to[k]` are the covariances of `from[k]` and `to[k]`. The mean
/// error (ME) is the plain mean of `|R·x + t − y|`, the condition number that of `from`.
pub fn fit_rigid_weighted(
    from: &[DVec3],
    to: &[DVec3],
    cov_from: &[DMat3],
    cov_to: &[DMat3],
) -> Result<RigidFit, String> {
    let start = fit_rigid(from, to)?;
    if cov_from.len() != from.len() || cov_to.len() != to.len() {
        return Err(format!(
            "{} markers but {} and {} covariances",
            from.len(),
            cov_from.len(),
            cov_to.len()
        ));
    }
    let mut pose = start.pose;
    for _ in 0..MAX_ITERATIONS {
        let mut normal = Matrix6::<f64>::zeros();
        let mut gradient = Vector6::<f64>::zeros();
        for k in 0..from.len() {
            let turned = pose.rotation * from[k];
            let residual = turned + pose.position_mm - to[k];
            let combined = pose.rotation * cov_from[k] * pose.rotation.transpose() + cov_to[k];
            if combined.determinant() <= 0.0 {
                return Err(format!(
                    "marker {k}: its covariance is not positive definite"
                ));
            }
            let weight = combined.inverse();
            // r(ω, δ) = Exp(ω)·R·x + t + δ − y: ∂r/∂ω = −[R·x]×, ∂r/∂δ = I.
            let skew = DMat3::from_cols(
                DVec3::new(0.0, turned.z, -turned.y),
                DVec3::new(-turned.z, 0.0, turned.x),
                DVec3::new(turned.y, -turned.x, 0.0),
            );
            let jacobian = [-skew, DMat3::IDENTITY];
            for (a, ja) in jacobian.iter().enumerate() {
                let wj = weight * *ja;
                let g = ja.transpose() * (weight * residual);
                for i in 0..3 {
                    gradient[3 * a + i] += g[i];
                }
                for (b, jb) in jacobian.iter().enumerate() {
                    let block = jb.transpose() * wj;
                    for i in 0..3 {
                        for j in 0..3 {
                            normal[(3 * b + i, 3 * a + j)] += block.col(j)[i];
                        }
                    }
                }
            }
        }
        let step = normal
            .cholesky()
            .ok_or("the weighted fit's normal equations are singular")?
            .solve(&(-gradient));
        let omega = DVec3::new(step[0], step[1], step[2]);
        let delta = DVec3::new(step[3], step[4], step[5]);
        let turn =
            DMat3::from_axis_angle(omega.try_normalize().unwrap_or(DVec3::X), omega.length());
        pose = Pose {
            rotation: turn * pose.rotation,
            position_mm: turn * pose.position_mm + delta,
        };
        if omega.length() < CONVERGED && delta.length() < CONVERGED {
            break;
        }
    }
    let mean_error_mm = from
        .iter()
        .zip(to)
        .map(|(x, y)| (pose.to_world(*x) - *y).length())
        .sum::<f64>()
        / from.len() as f64;
    Ok(RigidFit {
        pose,
        mean_error_mm,
        condition_number: condition_number(from),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The uniplanar room's sources (scanner frame, the knee at the origin).
    const SOURCES: [DVec3; 2] = [
        DVec3::new(-342.0, 0.0, 939.7),
        DVec3::new(342.0, 0.0, 939.7),
    ];

    fn markers() -> Vec<DVec3> {
        [
            [6.0, 34.0, 12.0],
            [0.0, 36.0, 2.0],
            [-14.0, 40.0, -12.0],
            [-10.0, 52.0, 12.0],
            [-4.0, 52.0, 6.0],
            [14.0, 52.0, -6.0],
            [18.0, 42.0, 8.0],
            [-16.0, 66.0, -2.0],
        ]
        .iter()
        .map(|p| DVec3::from_array(*p))
        .collect()
    }

    #[test]
    fn rays_at_plus_minus_20_degrees_leave_the_depth_worst_known() {
        // At the crossing point: the information is diag(2·cos²20°, 2, 2·sin²20°).
        let c = triangulation_covariance(DVec3::ZERO, &SOURCES).unwrap();
        let a = 20f64.to_radians();
        let expected = [
            1.0 / (2.0 * a.cos().powi(2)),
            0.5,
            1.0 / (2.0 * a.sin().powi(2)),
        ];
        for (i, e) in expected.iter().enumerate() {
            assert!((c.col(i)[i] - e).abs() < 1e-3 * e, "{c:?}");
        }
        assert!((c.col(2)[2] / c.col(0)[0]).sqrt() > 2.7);
        assert!(triangulation_covariance(DVec3::ZERO, &SOURCES[..1]).is_none());
        assert!(triangulation_covariance(DVec3::ZERO, &[SOURCES[0], SOURCES[0] * 2.0]).is_none());
    }

    #[test]
    fn exact_markers_give_the_exact_motion_and_equal_weights_the_kabsch_fit() {
        let x = markers();
        let t = Pose::from_position_euler_deg([3.0, -7.0, 5.0], [4.0, -2.0, 9.0]);
        let y: Vec<DVec3> = x.iter().map(|p| t.to_world(*p)).collect();
        let cov: Vec<DMat3> = x
            .iter()
            .map(|p| triangulation_covariance(*p, &SOURCES).unwrap())
            .collect();
        let fit = fit_rigid_weighted(&x, &y, &cov, &cov).unwrap();
        assert!((fit.pose.position_mm - t.position_mm).length() < 1e-9);
        assert!(fit.pose.rotation.abs_diff_eq(t.rotation, 1e-12));
        // Noisy markers, isotropic covariances: the Kabsch fit.
        let noisy: Vec<DVec3> = y
            .iter()
            .enumerate()
            .map(|(k, p)| *p + DVec3::new(0.03, -0.02, 0.05) * ((k % 3) as f64 - 1.0))
            .collect();
        let iso = vec![DMat3::IDENTITY; x.len()];
        let weighted = fit_rigid_weighted(&x, &noisy, &iso, &iso).unwrap();
        let kabsch = fit_rigid(&x, &noisy).unwrap();
        assert!((weighted.pose.position_mm - kabsch.pose.position_mm).length() < 1e-9);
        assert!(
            weighted
                .pose
                .rotation
                .abs_diff_eq(kabsch.pose.rotation, 1e-12)
        );
        assert!((weighted.mean_error_mm - kabsch.mean_error_mm).abs() < 1e-12);
    }

    #[test]
    fn depth_errors_move_the_weighted_fit_far_less_than_the_kabsch_fit() {
        // Every follow-up marker off by ±0.1 mm in depth (z), alternating with its height along
        // the bone: the Kabsch fit tilts the bone; the weighted one, which knows depth is four
        // times less certain than the other directions, tilts it much less.
        let x = markers();
        let y: Vec<DVec3> = x
            .iter()
            .map(|p| *p + DVec3::new(0.0, 0.0, if p.y > 45.0 { 0.1 } else { -0.1 }))
            .collect();
        let cov: Vec<DMat3> = x
            .iter()
            .map(|p| triangulation_covariance(*p, &SOURCES).unwrap())
            .collect();
        // Error at a point of the implant, 50 mm below the markers.
        let implant = DVec3::new(0.0, -7.0, -9.0);
        let off = |fit: &RigidFit| (fit.pose.to_world(implant) - implant).length();
        let kabsch = off(&fit_rigid(&x, &y).unwrap());
        let weighted = off(&fit_rigid_weighted(&x, &y, &cov, &cov).unwrap());
        assert!(kabsch > 0.2, "{kabsch}");
        assert!(weighted < 0.5 * kabsch, "{weighted} vs {kabsch}");
    }
}
