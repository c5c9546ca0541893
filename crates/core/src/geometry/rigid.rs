//! Triangulation of points from rays and rigid-body fits of marker sets (`rsa-methods.md`
//! §4.1, items 5 and 6): what the reference program, the migration analysis and the XMALab
//! import all fit with.

use glam::{DMat3, DVec3};
use nalgebra::{Matrix3, Vector3};

use super::Pose;

/// Least-squares intersection of rays given as (origin, direction); directions need not be unit.
///
/// Returns the point minimising the sum of squared distances to the rays' lines and the
/// crossing-line error: for two rays the shortest distance between the two lines (the point is
/// then the midpoint of their common perpendicular); for more rays the RMS distance of the point
/// to the lines. Parallel (or fewer than two) rays have no intersection: the point is NaN and the
/// error infinite.
pub fn triangulate(rays: &[(DVec3, DVec3)]) -> (DVec3, f64) {
    let nan = (DVec3::splat(f64::NAN), f64::INFINITY);
    if rays.len() < 2 {
        return nan;
    }
    let mut m = DMat3::ZERO;
    let mut rhs = DVec3::ZERO;
    for &(o, d) in rays {
        let d = d.normalize();
        let proj = DMat3::IDENTITY - DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        m += proj;
        rhs += proj * o;
    }
    let scale = rays.len() as f64;
    if m.determinant().abs() <= 1e-12 * scale * scale * scale {
        return nan;
    }
    let x = m.inverse() * rhs;
    let dist = |&(o, d): &(DVec3, DVec3)| (x - o).cross(d.normalize()).length();
    let error = if rays.len() == 2 {
        let ((o1, d1), (o2, d2)) = (rays[0], rays[1]);
        let n = d1.normalize().cross(d2.normalize());
        ((o2 - o1).dot(n) / n.length()).abs()
    } else {
        (rays.iter().map(|r| dist(r).powi(2)).sum::<f64>() / scale).sqrt()
    };
    (x, error)
}

/// A rigid-body fit of a marker model to measured marker positions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidFit {
    /// Maps model (local) coordinates to measured (world) coordinates: y ≈ R·x + t.
    pub pose: Pose,
    /// Mean error ME of the fit, mm: the mean over markers of |R·x + t − y|.
    pub mean_error_mm: f64,
    /// Condition number of the model's marker configuration, see [`condition_number`].
    pub condition_number: f64,
}

/// Centred 3×n coordinates' scatter matrix Σ (xᵢ − x̄)(yᵢ − ȳ)ᵀ and the centroids.
fn cross_scatter(x: &[DVec3], y: &[DVec3]) -> (Matrix3<f64>, DVec3, DVec3) {
    let n = x.len() as f64;
    let (cx, cy) = (
        x.iter().copied().sum::<DVec3>() / n,
        y.iter().copied().sum::<DVec3>() / n,
    );
    let mut h = Matrix3::zeros();
    for (a, b) in x.iter().zip(y) {
        let (a, b) = (*a - cx, *b - cy);
        h += Vector3::new(a.x, a.y, a.z) * Vector3::new(b.x, b.y, b.z).transpose();
    }
    (h, cx, cy)
}

/// Singular values σ1 ≥ σ2 ≥ σ3 (mm) of the centred marker coordinate matrix A = [x1 − x̄, …].
fn configuration_singular_values(markers: &[DVec3]) -> [f64; 3] {
    let (h, _, _) = cross_scatter(markers, markers);
    // AAᵀ = h; its eigenvalues are σ².
    let mut ev: Vec<f64> = h
        .symmetric_eigenvalues()
        .iter()
        .map(|e| e.max(0.0).sqrt())
        .collect();
    ev.sort_by(|a, b| b.total_cmp(a));
    [ev[0], ev[1], ev[2]]
}

/// Condition number of a marker configuration (mm coordinates), in m⁻¹:
/// CN = 1 / √(σ2² + σ3²) with σ1 ≥ σ2 ≥ σ3 the singular values, in metres, of the centred marker
/// matrix A = [x1 − x̄, …, xn − x̄].
///
/// Source: Söderkvist I, Wedin P-Å, "Determining the movements of the skeleton using
/// well-configured markers", J Biomech 1993;26:1473–1477, and "On condition numbers and
/// algorithms for determining a rigid body movement", BIT 1994;34:424–436: the sensitivity of the
/// least-squares rotation to marker perturbations is governed by the two smallest singular values
/// of the centred configuration; σ2² + σ3² is the sum of squared distances of the markers from
/// their best-fitting line, so CN grows without bound as the markers approach collinearity (the
/// behaviour the RSA guideline, Valstar et al. 2005, Acta Orthop 76:563, limits to CN ≤ 150).
///
/// Caveat: the papers' text was not available to this implementation; the form above is the
/// geometric statement quoted from them, and the scale (metres, no extra constant) is an
/// assumption. The "8 markers in 40 × 40 mm → CN 9.8" example could not be reproduced with it (8
/// markers on the corners of a 40 mm cube give 12.5, the maximum for markers inside a 40 mm cube).
/// Returns infinity for collinear or coincident markers.
pub fn condition_number(markers: &[DVec3]) -> f64 {
    if markers.len() < 3 {
        return f64::INFINITY;
    }
    let [s1, s2, s3] = configuration_singular_values(markers);
    let spread_m = (s2 * s2 + s3 * s3).sqrt() / 1000.0;
    if spread_m <= 1e-12 * s1.max(1e-300) / 1000.0 {
        f64::INFINITY
    } else {
        1.0 / spread_m
    }
}

/// Least-squares rigid fit y ≈ R·x + t (Söderkvist & Wedin 1993; Kabsch), with det R = +1.
///
/// With centred coordinates, C = Σ (xᵢ − x̄)(yᵢ − ȳ)ᵀ = U Σ Vᵀ, R = V·diag(1, 1, det(V Uᵀ))·Uᵀ (the
/// guard against a reflection), t = ȳ − R x̄. Needs ≥ 3 corresponding, non-collinear markers.
pub fn fit_rigid(model: &[DVec3], measured: &[DVec3]) -> Result<RigidFit, String> {
    if model.len() != measured.len() {
        return Err(format!(
            "{} model markers but {} measured",
            model.len(),
            measured.len()
        ));
    }
    if model.len() < 3 {
        return Err(format!(
            "a rigid fit needs at least 3 markers, got {}",
            model.len()
        ));
    }
    let [s1, s2, _] = configuration_singular_values(model);
    if s2.is_nan() || s2 <= 1e-9 * s1 {
        return Err("model markers are collinear: the rotation is undetermined".into());
    }
    let (c, cx, cy) = cross_scatter(model, measured);
    let svd = c.svd(true, true);
    let (u, v_t) = (svd.u.ok_or("SVD failed")?, svd.v_t.ok_or("SVD failed")?);
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let rotation = DMat3::from_cols(
        DVec3::new(r[(0, 0)], r[(1, 0)], r[(2, 0)]),
        DVec3::new(r[(0, 1)], r[(1, 1)], r[(2, 1)]),
        DVec3::new(r[(0, 2)], r[(1, 2)], r[(2, 2)]),
    );
    let pose = Pose {
        position_mm: cy - rotation * cx,
        rotation,
    };
    let mean_error_mm = model
        .iter()
        .zip(measured)
        .map(|(x, y)| (pose.to_world(*x) - *y).length())
        .sum::<f64>()
        / model.len() as f64;
    Ok(RigidFit {
        pose,
        mean_error_mm,
        condition_number: condition_number(model),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::gaussians;

    fn markers() -> Vec<DVec3> {
        vec![
            DVec3::new(12.0, -5.0, 3.0),
            DVec3::new(-8.0, 14.0, -6.0),
            DVec3::new(3.0, 9.0, 15.0),
            DVec3::new(-15.0, -11.0, 4.0),
            DVec3::new(7.0, 2.0, -13.0),
            DVec3::new(-2.0, -16.0, -9.0),
        ]
    }

    #[test]
    fn triangulation_of_exact_and_skew_rays() {
        let p = DVec3::new(10.0, -20.0, 30.0);
        let (o1, o2, o3) = (
            DVec3::new(0.0, 0.0, 1300.0),
            DVec3::new(1300.0, 0.0, 0.0),
            DVec3::new(0.0, 900.0, 900.0),
        );
        let (x, e) = triangulate(&[(o1, p - o1), (o2, (p - o2) * 3.0)]);
        assert!((x - p).length() < 1e-9 && e < 1e-9);
        let (x, e) = triangulate(&[(o1, p - o1), (o2, p - o2), (o3, p - o3)]);
        assert!((x - p).length() < 1e-9 && e < 1e-9);
        // Skew lines: x axis and the line z = 2 along y. Shortest distance 2, midpoint (0, 0, 1).
        let (x, e) = triangulate(&[
            (DVec3::new(5.0, 0.0, 0.0), DVec3::X),
            (DVec3::new(0.0, -3.0, 2.0), DVec3::Y),
        ]);
        assert!((x - DVec3::new(0.0, 0.0, 1.0)).length() < 1e-12 && (e - 2.0).abs() < 1e-12);
        // Parallel rays: no point.
        let (x, e) = triangulate(&[(DVec3::ZERO, DVec3::X), (DVec3::Y, DVec3::X)]);
        assert!(x.x.is_nan() && e.is_infinite());
    }

    #[test]
    fn known_pose_is_recovered_from_exact_points() {
        let truth = Pose::from_position_euler_deg([12.0, -7.5, 40.0], [17.0, -33.0, 71.0]);
        let model = markers();
        let measured: Vec<DVec3> = model.iter().map(|x| truth.to_world(*x)).collect();
        let fit = fit_rigid(&model, &measured).unwrap();
        assert!((fit.pose.rotation - truth.rotation).abs_diff_eq(DMat3::ZERO, 1e-12));
        assert!((fit.pose.position_mm - truth.position_mm).length() < 1e-12);
        assert!(fit.mean_error_mm < 1e-12);
        assert!(fit.condition_number.is_finite() && fit.condition_number > 0.0);
    }

    #[test]
    fn mean_error_follows_the_noise() {
        let truth = Pose::from_position_euler_deg([-3.0, 5.0, 1.0], [-4.0, 8.0, 2.0]);
        // 8 markers spread over ±40 mm, noise σ = 0.05 mm per coordinate.
        let extra = [DVec3::new(40.0, 0.0, 0.0), DVec3::new(0.0, -40.0, 30.0)];
        let model: Vec<DVec3> = markers().iter().chain(&extra).map(|x| 2.0 * *x).collect();
        let g = gaussians("rigid noise", 3 * model.len());
        let measured: Vec<DVec3> = model
            .iter()
            .enumerate()
            .map(|(i, x)| {
                truth.to_world(*x) + 0.05 * DVec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2])
            })
            .collect();
        let fit = fit_rigid(&model, &measured).unwrap();
        // E|N(0, σ²I₃)| ≈ 1.6σ, shrunk by the 6 fitted DOF out of 24 coordinates.
        assert!(
            fit.mean_error_mm > 0.02 && fit.mean_error_mm < 0.12,
            "{}",
            fit.mean_error_mm
        );
        assert!((fit.pose.position_mm - truth.position_mm).length() < 0.1);
    }

    #[test]
    fn reflections_are_refused_and_the_rotation_stays_proper() {
        let model = markers();
        let mirrored: Vec<DVec3> = model
            .iter()
            .map(|x| DVec3::new(x.x, x.y, -x.z) + DVec3::new(1.0, 2.0, 3.0))
            .collect();
        let fit = fit_rigid(&model, &mirrored).unwrap();
        assert!((fit.pose.rotation.determinant() - 1.0).abs() < 1e-12);
        let r = fit.pose.rotation;
        assert!((r.transpose() * r).abs_diff_eq(DMat3::IDENTITY, 1e-12));
        assert!(fit.mean_error_mm > 1.0);
    }

    #[test]
    fn condition_number_tracks_collinearity() {
        let line: Vec<DVec3> = (0..5)
            .map(|k| DVec3::new(10.0 * k as f64, 5.0 * k as f64, -2.0 * k as f64))
            .collect();
        assert!(condition_number(&line).is_infinite());
        assert!(fit_rigid(&line, &line).is_err());
        // Nearly collinear (0.1 mm off the line): far beyond the 150 limit.
        let mut near = line.clone();
        near[2] += DVec3::new(0.0, 0.0, 0.1);
        assert!(condition_number(&near) > 1000.0);
        // A regular tetrahedron with 40 mm edges: well below the limit.
        let a = 40.0 / (2.0 * 2f64.sqrt());
        let tetra = [
            DVec3::new(a, a, a),
            DVec3::new(a, -a, -a),
            DVec3::new(-a, a, -a),
            DVec3::new(-a, -a, a),
        ];
        let cn = condition_number(&tetra);
        // σ² = 4a² for each axis, so CN = 1 / √(8a²) in m.
        assert!(
            (cn - 1000.0 / (8.0 * a * a).sqrt()).abs() < 1e-9 && cn < 50.0,
            "{cn}"
        );
        // Leiden-style check, unverified: 8 markers on a 40 mm cube's corners give 12.5 m⁻¹, not 9.8.
        let cube: Vec<DVec3> = (0..8)
            .map(|k| {
                let c = |bit: u32| if k & bit == 0 { -20.0 } else { 20.0 };
                DVec3::new(c(1), c(2), c(4))
            })
            .collect();
        assert!((condition_number(&cube) - 12.5).abs() < 1e-9);
        // Scale invariance of the definition's geometry: doubling the spread halves CN.
        let doubled: Vec<DVec3> = tetra.iter().map(|x| 2.0 * *x).collect();
        assert!((condition_number(&doubled) - cn / 2.0).abs() < 1e-9);
    }
}
