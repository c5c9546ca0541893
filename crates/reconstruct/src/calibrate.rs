//! Calibration of one beamline (source + detector) from the calibration box's beads, and the
//! ray through a pixel of a calibrated beamline ([`ray_through_pixel`]).
//!
//! The pipeline is the one of `rsa-methods.md` §4.1: a Hartley-normalised DLT gives the 3×4
//! projection matrix P; P is decomposed with the known pixel pitch into the physical model
//! (source position, detector pose); Levenberg–Marquardt then refines the 9 physical parameters on
//! the pixel reprojection error, and one outlier pass drops grossly wrong correspondences.
//!
//! Conventions (docs/src/reference/conventions.md, "Units" and "Frames"): world = calibration box frame, mm. Continuous pixel
//! (u, v) lies at detector-frame x = (u − W/2)·pitch_x, y = (v − H/2)·pitch_y; the detector frame's
//! axes are r (increasing column), c (increasing row) and s = r × c, pointing towards the source.

use glam::{DMat3, DVec2, DVec3};
use nalgebra::{DMatrix, SMatrix, SVector};

use crate::geometry::{DetectorFrame, Pose};

/// One source and its detector, as a calibration recovers them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beamline {
    /// Position of the X-ray source (focus) in the box frame, mm.
    pub source_mm: DVec3,
    /// Pose of the detector frame (r, c, s axes; origin at the centre of the active area).
    pub detector: Pose,
}

impl Beamline {
    /// The detector frame with the given pixel counts `[W, H]` and pitch `[x, y]` (mm).
    pub fn frame(&self, pixels: [u32; 2], pitch: [f64; 2]) -> DetectorFrame {
        DetectorFrame {
            pose: self.detector,
            pixels,
            pixel_pitch_mm: pitch,
        }
    }

    /// Continuous pixel coordinates of the central projection of `p`
    /// (see [`DetectorFrame::project`]); `None` when `p` does not project onto the detector plane.
    pub fn project(&self, pixels: [u32; 2], pitch: [f64; 2], p: DVec3) -> Option<DVec2> {
        self.frame(pixels, pitch).project(self.source_mm, p)
    }
}

/// The ray from the beamline's source through continuous pixel `uv`: (origin = source, unit
/// direction towards the pixel's world position on the detector plane).
pub fn ray_through_pixel(
    beamline: &Beamline,
    pixels: [u32; 2],
    pitch: [f64; 2],
    uv: DVec2,
) -> (DVec3, DVec3) {
    let frame = beamline.frame(pixels, pitch);
    let on_detector = frame.pose.to_world(frame.pixel_local(uv.x, uv.y));
    (
        beamline.source_mm,
        (on_detector - beamline.source_mm).normalize(),
    )
}

/// The result of a refinement or a full calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Refined {
    /// The refined beamline.
    pub beamline: Beamline,
    /// Root mean square of the per-point reprojection distances |projected − measured| in pixels,
    /// over the points used in the fit (a per-coordinate RMS is this value divided by √2).
    pub rms_px: f64,
    /// Reprojection distance of every input point in pixels, in input order (dropped points
    /// included, measured against the final beamline).
    pub residuals_px: Vec<f64>,
    /// Levenberg–Marquardt iterations of the last refinement.
    pub iterations: usize,
    /// Indices (into the input) of the points the outlier pass dropped; empty from [`refine`].
    pub dropped: Vec<usize>,
}

/// Similarity transform (as a matrix acting on homogeneous coordinates) that moves the centroid
/// of `pts` (given as coordinate slices) to the origin and scales the mean distance to `√dim`.
fn normalisation(pts: &[Vec<f64>], dim: usize) -> Result<DMatrix<f64>, String> {
    let n = pts.len() as f64;
    let mut c = vec![0.0; dim];
    for p in pts {
        for k in 0..dim {
            c[k] += p[k] / n;
        }
    }
    let mean_dist = pts
        .iter()
        .map(|p| (0..dim).map(|k| (p[k] - c[k]).powi(2)).sum::<f64>().sqrt())
        .sum::<f64>()
        / n;
    if !(mean_dist > 0.0 && mean_dist.is_finite()) {
        return Err("calibration points are all at one place".into());
    }
    let s = (dim as f64).sqrt() / mean_dist;
    let mut t = DMatrix::<f64>::identity(dim + 1, dim + 1);
    for k in 0..dim {
        t[(k, k)] = s;
        t[(k, dim)] = -s * c[k];
    }
    Ok(t)
}

/// The normalised DLT for a projective map from points of any dimension d to the image plane:
/// the 3 × (d+1) matrix M with (x', y', 1)ᵀ ∝ M·(x, 1)ᵀ, from Hartley-normalised point sets and the
/// SVD null vector, denormalised (`T_to⁻¹ · M_n · T_from`). The camera DLT (d = 3) and the
/// homography of Selvik's method (d = 2) are both this. `degenerate` is the error when the null
/// space is not one-dimensional.
pub(crate) fn projective_dlt(
    from: &[Vec<f64>],
    to: &[DVec2],
    degenerate: &str,
) -> Result<DMatrix<f64>, String> {
    let (n, d) = (from.len(), from.first().map_or(0, Vec::len));
    let t_from = normalisation(from, d)?;
    let t_to = normalisation(
        &to.iter().map(|p| p.to_array().to_vec()).collect::<Vec<_>>(),
        2,
    )?;
    let cols = d + 1;
    // At least 3·cols rows, so that the thin SVD holds the null vector (zero rows change nothing).
    let mut a = DMatrix::<f64>::zeros((2 * n).max(3 * cols), 3 * cols);
    for (i, (f, t)) in from.iter().zip(to).enumerate() {
        let mut h = f.clone();
        h.push(1.0);
        let x = &t_from * DMatrix::from_column_slice(cols, 1, &h);
        let m = &t_to * DMatrix::from_column_slice(3, 1, &[t.x, t.y, 1.0]);
        let (u, v) = (m[0] / m[2], m[1] / m[2]);
        for k in 0..cols {
            a[(2 * i, k)] = x[k];
            a[(2 * i, 2 * cols + k)] = -u * x[k];
            a[(2 * i + 1, cols + k)] = x[k];
            a[(2 * i + 1, 2 * cols + k)] = -v * x[k];
        }
    }
    let svd = a.svd(false, true);
    let v_t = svd.v_t.ok_or("SVD failed")?;
    let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
    order.sort_by(|&i, &j| svd.singular_values[i].total_cmp(&svd.singular_values[j]));
    if svd.singular_values[order[1]] <= 1e-10 * svd.singular_values.max() {
        return Err(degenerate.into());
    }
    let h = v_t.row(order[0]);
    let normalised = DMatrix::from_row_slice(3, cols, &h.iter().copied().collect::<Vec<_>>());
    let t_to_inv = t_to.try_inverse().ok_or("singular 2-D normalisation")?;
    Ok(t_to_inv * normalised * t_from)
}

/// Direct linear transform: the 3×4 projection matrix P with (u, v, 1)ᵀ ∝ P·(X, 1)ᵀ.
///
/// Hartley normalisation of both point sets (centroid at the origin, mean distance √3 in 3-D and
/// √2 in 2-D), the 11-DOF homogeneous system solved by SVD (right singular vector of the smallest
/// singular value), then denormalised. P is returned with unit Frobenius norm and an arbitrary
/// sign ([`decompose`] fixes it). Needs ≥ 6 non-coplanar points; errors when there are fewer,
/// when the lengths differ, or when the solution is not unique (degenerate configuration).
pub fn dlt(points: &[DVec3], pixels_uv: &[DVec2]) -> Result<[[f64; 4]; 3], String> {
    let n = points.len();
    if n != pixels_uv.len() {
        return Err(format!(
            "{n} points but {} pixel positions",
            pixels_uv.len()
        ));
    }
    if n < 6 {
        return Err(format!("the DLT needs at least 6 points, got {n}"));
    }
    // Coplanarity: the centred 3-D scatter must have a third direction.
    let c = points.iter().copied().sum::<DVec3>() / n as f64;
    let mut scatter = SMatrix::<f64, 3, 3>::zeros();
    for p in points {
        let d = SVector::<f64, 3>::new(p.x - c.x, p.y - c.y, p.z - c.z);
        scatter += d * d.transpose();
    }
    let sv = scatter.symmetric_eigenvalues();
    let (lo, hi) = (sv.min(), sv.max());
    if hi.is_nan() || hi <= 0.0 || lo <= 1e-12 * hi {
        return Err("calibration points are coplanar (or collinear): the DLT is degenerate".into());
    }

    let from: Vec<Vec<f64>> = points.iter().map(|p| p.to_array().to_vec()).collect();
    let p = projective_dlt(
        &from,
        pixels_uv,
        "degenerate calibration configuration: the DLT solution is not unique",
    )?;
    let norm = p.norm();
    let mut out = [[0.0; 4]; 3];
    for (r, row) in out.iter_mut().enumerate() {
        for (k, v) in row.iter_mut().enumerate() {
            *v = p[(r, k)] / norm;
        }
    }
    Ok(out)
}

/// Decomposes a projection matrix into the physical beamline, using the known pixel counts
/// `[W, H]` and pitch `[x, y]` (mm) (`rsa-methods.md` §4.1, item 3).
///
/// With P = [A | b]: source S = −A⁻¹b. P's sign is chosen so that the homogeneous scale w of the
/// `points` (the calibration beads) is positive, i.e. they lie between source and detector. With
/// A⁻¹ = [a1 a2 a3] the detector axes are e_u ∝ a1, e_v ∝ a2 (symmetrically orthonormalised: the
/// DLT has 11 DOF, the physical model 9), the scale is the mean of |a1|/p_x and |a2|/p_y, the
/// world position of continuous pixel (0, 0) is S + a3/scale, and the detector origin (centre of
/// the active area) is that point + (W/2)·p_x·e_u + (H/2)·p_y·e_v. The normal e_u × e_v must point
/// towards the source (r × c = s); an error is returned otherwise (a mirrored image).
pub fn decompose(
    p: &[[f64; 4]; 3],
    pixels: [u32; 2],
    pitch: [f64; 2],
    points: &[DVec3],
) -> Result<Beamline, String> {
    let mut a = DMat3::from_cols(
        DVec3::new(p[0][0], p[1][0], p[2][0]),
        DVec3::new(p[0][1], p[1][1], p[2][1]),
        DVec3::new(p[0][2], p[1][2], p[2][2]),
    );
    let mut b = DVec3::new(p[0][3], p[1][3], p[2][3]);
    if a.determinant().abs() < 1e-300 {
        return Err("projection matrix has a singular 3×3 part".into());
    }
    // Sign: w = third row · (X, 1) must be positive for the beads (in front of the source).
    let w_sum: f64 = points
        .iter()
        .map(|x| a.row(2).dot(*x) + b.z)
        .map(f64::signum)
        .sum();
    if w_sum < 0.0 {
        a = -a;
        b = -b;
    }
    let a_inv = a.inverse();
    let source = -(a_inv * b);
    let (a1, a2, a3) = (a_inv.x_axis, a_inv.y_axis, a_inv.z_axis);
    let scale = 0.5 * (a1.length() / pitch[0] + a2.length() / pitch[1]);
    let (eu, ev) = orthonormal_pair(a1.normalize(), a2.normalize());
    let n = eu.cross(ev);
    let pixel0 = source + a3 / scale;
    let origin = pixel0
        + eu * (pixels[0] as f64 / 2.0 * pitch[0])
        + ev * (pixels[1] as f64 / 2.0 * pitch[1]);
    if (source - origin).dot(n) <= 0.0 {
        return Err(
            "the detector normal r × c points away from the source: is the image mirrored?".into(),
        );
    }
    Ok(Beamline {
        source_mm: source,
        detector: Pose {
            position_mm: origin,
            rotation: DMat3::from_cols(eu, ev, n),
        },
    })
}

/// The orthonormal pair closest to unit vectors `a`, `b`, symmetric in both (the bisector frame).
fn orthonormal_pair(a: DVec3, b: DVec3) -> (DVec3, DVec3) {
    let x = (a + b).normalize();
    let y = (a - b).normalize();
    let s = std::f64::consts::FRAC_1_SQRT_2;
    ((x + y) * s, (x - y) * s)
}

/// Rotation by the vector `w` (axis · angle in radians).
fn exp_rotation(w: DVec3) -> DMat3 {
    let angle = w.length();
    if angle == 0.0 {
        DMat3::IDENTITY
    } else {
        DMat3::from_axis_angle(w / angle, angle)
    }
}

/// The beamline moved by the 9 parameters: source += q[0..3], detector position += q[3..6],
/// detector rotation = exp(q[6..9]) · rotation (a world-frame increment).
fn apply(b: &Beamline, q: &[f64; 9]) -> Beamline {
    Beamline {
        source_mm: b.source_mm + DVec3::new(q[0], q[1], q[2]),
        detector: Pose {
            position_mm: b.detector.position_mm + DVec3::new(q[3], q[4], q[5]),
            rotation: exp_rotation(DVec3::new(q[6], q[7], q[8])) * b.detector.rotation,
        },
    }
}

/// Stacked residuals (projected − measured), 2 per point; `None` when a point does not project.
fn residuals(
    b: &Beamline,
    pixels: [u32; 2],
    pitch: [f64; 2],
    pts: &[DVec3],
    uv: &[DVec2],
) -> Option<Vec<f64>> {
    let frame = b.frame(pixels, pitch);
    let mut r = Vec::with_capacity(2 * pts.len());
    for (p, m) in pts.iter().zip(uv) {
        let d = frame.project(b.source_mm, *p)? - *m;
        r.push(d.x);
        r.push(d.y);
    }
    Some(r)
}

/// Per-point reprojection distances in pixels (infinite where a point does not project).
pub(crate) fn point_residuals(
    b: &Beamline,
    pixels: [u32; 2],
    pitch: [f64; 2],
    pts: &[DVec3],
    uv: &[DVec2],
) -> Vec<f64> {
    pts.iter()
        .zip(uv)
        .map(|(p, m)| {
            b.project(pixels, pitch, *p)
                .map_or(f64::INFINITY, |q| (q - *m).length())
        })
        .collect()
}

/// Levenberg–Marquardt refinement of the 9 physical parameters (source xyz, detector position
/// xyz, detector rotation as an axis-angle increment composed onto the current rotation),
/// minimising the pixel reprojection error of `points` against `pixels_uv`.
///
/// Central-difference Jacobian (steps 1e-5 mm and 1e-8 rad), Marquardt damping λ·diag(JᵀJ).
/// Stops when the step changes no parameter by more than 1e-12 (mm or rad, relative to the
/// scene), when the gradient vanishes, or after 50 iterations. Points that do not project make a
/// step unacceptable. `dropped` is empty.
pub fn refine(
    initial: &Beamline,
    pixels: [u32; 2],
    pitch: [f64; 2],
    points: &[DVec3],
    pixels_uv: &[DVec2],
) -> Refined {
    const STEPS: [f64; 9] = [1e-5, 1e-5, 1e-5, 1e-5, 1e-5, 1e-5, 1e-8, 1e-8, 1e-8];
    let cost = |b: &Beamline| {
        residuals(b, pixels, pitch, points, pixels_uv).map(|r| r.iter().map(|x| x * x).sum::<f64>())
    };
    let mut current = *initial;
    let mut f = cost(&current).unwrap_or(f64::INFINITY);
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let m = 2 * points.len();
    while iterations < 50 && f.is_finite() {
        iterations += 1;
        let Some(r0) = residuals(&current, pixels, pitch, points, pixels_uv) else {
            break;
        };
        let mut jac = DMatrix::<f64>::zeros(m, 9);
        let mut ok = true;
        for k in 0..9 {
            let mut q = [0.0; 9];
            q[k] = STEPS[k];
            let plus = residuals(&apply(&current, &q), pixels, pitch, points, pixels_uv);
            q[k] = -STEPS[k];
            let minus = residuals(&apply(&current, &q), pixels, pitch, points, pixels_uv);
            let (Some(plus), Some(minus)) = (plus, minus) else {
                ok = false;
                break;
            };
            for i in 0..m {
                jac[(i, k)] = (plus[i] - minus[i]) / (2.0 * STEPS[k]);
            }
        }
        if !ok {
            break;
        }
        let r = DMatrix::from_column_slice(m, 1, &r0);
        let jtj = jac.transpose() * &jac;
        let g = jac.transpose() * r;
        if g.amax() < 1e-15 * (1.0 + f) {
            break;
        }
        // Try increasing damping until the cost goes down.
        let mut accepted = false;
        let mut converged = false;
        for _ in 0..20 {
            let mut h = jtj.clone();
            for k in 0..9 {
                h[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            let Some(step) = h.lu().solve(&(-&g)) else {
                lambda *= 10.0;
                continue;
            };
            let q: [f64; 9] = std::array::from_fn(|k| step[k]);
            let candidate = apply(&current, &q);
            let fc = cost(&candidate).unwrap_or(f64::INFINITY);
            if fc <= f {
                converged = step.amax() < 1e-12 || (f - fc) <= 1e-16 * f;
                current = candidate;
                f = fc;
                lambda = (lambda / 10.0).max(1e-12);
                accepted = true;
                break;
            }
            lambda *= 10.0;
        }
        if !accepted || converged {
            break;
        }
    }
    let residuals_px = point_residuals(&current, pixels, pitch, points, pixels_uv);
    let rms_px =
        (residuals_px.iter().map(|d| d * d).sum::<f64>() / residuals_px.len().max(1) as f64).sqrt();
    Refined {
        beamline: current,
        rms_px,
        residuals_px,
        iterations,
        dropped: Vec::new(),
    }
}

/// Full calibration of one beamline: [`dlt`] → [`decompose`] → [`refine`], then one outlier pass.
///
/// The outlier pass drops every point whose reprojection distance exceeds
/// max(1.0 px, 5 × median distance) and refines again on the rest (starting from the first
/// refinement). `dropped` lists the dropped indices; `residuals_px` covers every input point
/// against the final beamline; `rms_px` is over the kept points.
pub fn calibrate(
    points: &[DVec3],
    pixels_uv: &[DVec2],
    pixels: [u32; 2],
    pitch: [f64; 2],
) -> Result<Refined, String> {
    let p = dlt(points, pixels_uv)?;
    let initial = decompose(&p, pixels, pitch, points)?;
    let first = refine(&initial, pixels, pitch, points, pixels_uv);
    let mut sorted = first.residuals_px.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let limit = (5.0 * median).max(1.0);
    let is_outlier = |&i: &usize| first.residuals_px[i] > limit || first.residuals_px[i].is_nan();
    let dropped: Vec<usize> = (0..points.len()).filter(is_outlier).collect();
    if dropped.is_empty() {
        return Ok(first);
    }
    let keep: Vec<usize> = (0..points.len()).filter(|i| !dropped.contains(i)).collect();
    if keep.len() < 6 {
        return Err(format!(
            "only {} calibration points left after the outlier pass",
            keep.len()
        ));
    }
    let kp: Vec<DVec3> = keep.iter().map(|&i| points[i]).collect();
    let ku: Vec<DVec2> = keep.iter().map(|&i| pixels_uv[i]).collect();
    let second = refine(&first.beamline, pixels, pitch, &kp, &ku);
    Ok(Refined {
        residuals_px: point_residuals(&second.beamline, pixels, pitch, points, pixels_uv),
        dropped,
        ..second
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geometry::{rotation_xyz_deg, triangulate};
    use crate::random::gaussians;

    pub(crate) const PIXELS: [u32; 2] = [1440, 1440];
    pub(crate) const PITCH: [f64; 2] = [430.0 / 1440.0, 430.0 / 1440.0];

    /// The calibration box: z = −100 plate, 9×9 grid at 20 mm; z = +100 plate, 7×7 grid at 25 mm.
    pub(crate) fn box_points() -> Vec<DVec3> {
        let mut pts = Vec::new();
        for i in -4..=4 {
            for j in -4..=4 {
                pts.push(DVec3::new(20.0 * i as f64, 20.0 * j as f64, -100.0));
            }
        }
        for i in -3..=3 {
            for j in -3..=3 {
                pts.push(DVec3::new(25.0 * i as f64, 25.0 * j as f64, 100.0));
            }
        }
        pts
    }

    /// Beamline 1: source near (0, 0, 1300), detector near (0, 0, −500), tilted by ≤ 2°.
    pub(crate) fn beamline_1() -> Beamline {
        Beamline {
            source_mm: DVec3::new(14.0, -18.0, 1312.0),
            detector: Pose::from_position_euler_deg([6.0, -9.0, -492.0], [1.5, -2.0, 1.2]),
        }
    }

    /// Beamline 2: source near (1300, 0, 0), detector rotated [0, 90, 0] near (−500, 0, 0).
    pub(crate) fn beamline_2() -> Beamline {
        Beamline {
            source_mm: DVec3::new(1288.0, 17.0, -11.0),
            detector: Pose::from_position_euler_deg([-507.0, 4.0, 8.0], [-1.7, 91.8, 0.9]),
        }
    }

    fn project_all(b: &Beamline, pts: &[DVec3]) -> Vec<DVec2> {
        pts.iter()
            .map(|p| b.project(PIXELS, PITCH, *p).expect("bead projects"))
            .collect()
    }

    fn angle_deg(a: DMat3, b: DMat3) -> f64 {
        let r = a.transpose() * b;
        let c = ((r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) / 2.0).clamp(-1.0, 1.0);
        c.acos().to_degrees()
    }

    #[test]
    fn exact_projections_recover_both_beamlines() {
        let pts = box_points();
        for truth in [beamline_1(), beamline_2()] {
            let uv = project_all(&truth, &pts);
            // The DLT alone already reproduces the projections.
            let p = dlt(&pts, &uv).unwrap();
            let b0 = decompose(&p, PIXELS, PITCH, &pts).unwrap();
            assert!((b0.source_mm - truth.source_mm).length() < 1e-6);
            let fit = calibrate(&pts, &uv, PIXELS, PITCH).unwrap();
            let b = fit.beamline;
            assert!(
                (b.source_mm - truth.source_mm).length() < 1e-6,
                "{:?}",
                b.source_mm - truth.source_mm
            );
            assert!((b.detector.position_mm - truth.detector.position_mm).length() < 1e-6);
            assert!(angle_deg(b.detector.rotation, truth.detector.rotation) < 1e-6);
            assert!(fit.rms_px < 1e-8 && fit.dropped.is_empty());
        }
    }

    #[test]
    fn detector_normal_points_to_the_source() {
        // r × c = s and s towards the source, for both geometries.
        let pts = box_points();
        for truth in [beamline_1(), beamline_2()] {
            let b = decompose(
                &dlt(&pts, &project_all(&truth, &pts)).unwrap(),
                PIXELS,
                PITCH,
                &pts,
            )
            .unwrap();
            let r = b.detector.rotation;
            assert!((r.x_axis.cross(r.y_axis) - r.z_axis).length() < 1e-12);
            assert!((b.source_mm - b.detector.position_mm).dot(r.z_axis) > 1000.0);
            assert!((r.z_axis - truth.detector.rotation.z_axis).length() < 1e-9);
        }
        // A mirrored image (u → W − u) cannot come from a right-handed detector: refused.
        let truth = beamline_1();
        let mirrored: Vec<DVec2> = project_all(&truth, &pts)
            .iter()
            .map(|q| DVec2::new(1440.0 - q.x, q.y))
            .collect();
        let p = dlt(&pts, &mirrored).unwrap();
        assert!(decompose(&p, PIXELS, PITCH, &pts).is_err());
    }

    #[test]
    fn dlt_refuses_too_few_or_coplanar_points() {
        let pts = box_points();
        let uv = project_all(&beamline_1(), &pts);
        assert!(dlt(&pts[..5], &uv[..5]).is_err());
        assert!(dlt(&pts[..81], &uv[..81]).is_err()); // one plate only
        assert!(dlt(&pts, &uv[..10]).is_err());
    }

    #[test]
    fn noisy_projections_give_sub_millimetre_source_across_the_beam() {
        let pts = box_points();
        for (name, truth) in [("beamline 1", beamline_1()), ("beamline 2", beamline_2())] {
            let g = gaussians(&format!("calibrate noise {name}"), 2 * pts.len());
            let uv: Vec<DVec2> = project_all(&truth, &pts)
                .iter()
                .enumerate()
                .map(|(i, q)| *q + 0.1 * DVec2::new(g[2 * i], g[2 * i + 1]))
                .collect();
            let fit = calibrate(&pts, &uv, PIXELS, PITCH).unwrap();
            let rot = truth.detector.rotation;
            let e = rot.transpose() * (fit.beamline.source_mm - truth.source_mm);
            let ed =
                rot.transpose() * (fit.beamline.detector.position_mm - truth.detector.position_mm);
            let tilt = angle_deg(fit.beamline.detector.rotation, rot);
            eprintln!(
                "{name}: rms {:.4} px (per coordinate {:.4}), source error r {:+.4} c {:+.4} s {:+.4} mm, \
                 detector error r {:+.4} c {:+.4} s {:+.4} mm, tilt {:.4}°, {} iterations, dropped {:?}",
                fit.rms_px,
                fit.rms_px / 2f64.sqrt(),
                e.x,
                e.y,
                e.z,
                ed.x,
                ed.y,
                ed.z,
                tilt,
                fit.iterations,
                fit.dropped
            );
            assert!(fit.dropped.is_empty());
            assert!(
                (fit.rms_px / 2f64.sqrt() - 0.1).abs() < 0.02,
                "rms {}",
                fit.rms_px
            );
            assert!(e.x.abs() < 0.1 && e.y.abs() < 0.1, "{e:?}");
            assert!(e.z.abs() < 5.0, "{e:?}");
        }
    }

    #[test]
    fn gross_correspondence_errors_are_dropped() {
        let pts = box_points();
        let truth = beamline_1();
        let g = gaussians("calibrate outliers", 2 * pts.len());
        let mut uv: Vec<DVec2> = project_all(&truth, &pts)
            .iter()
            .enumerate()
            .map(|(i, q)| *q + 0.1 * DVec2::new(g[2 * i], g[2 * i + 1]))
            .collect();
        let bad = [3, 40, 77, 90, 121];
        for (k, &i) in bad.iter().enumerate() {
            let dir = rotation_xyz_deg([0.0, 0.0, 70.0 * k as f64]) * DVec3::X;
            uv[i] += 30.0 * DVec2::new(dir.x, dir.y);
        }
        let fit = calibrate(&pts, &uv, PIXELS, PITCH).unwrap();
        assert_eq!(fit.dropped, bad.to_vec());
        assert!(fit.rms_px < 0.2);
        assert!(bad.iter().all(|&i| fit.residuals_px[i] > 25.0));
        let e = truth.detector.rotation.transpose() * (fit.beamline.source_mm - truth.source_mm);
        assert!(
            e.x.abs() < 0.1 && e.y.abs() < 0.1 && e.z.abs() < 5.0,
            "{e:?}"
        );
    }

    #[test]
    fn rays_through_projected_pixels_meet_at_the_bead() {
        let (b1, b2) = (beamline_1(), beamline_2());
        let p = DVec3::new(23.0, -41.0, 17.0);
        let r1 = ray_through_pixel(&b1, PIXELS, PITCH, b1.project(PIXELS, PITCH, p).unwrap());
        let r2 = ray_through_pixel(&b2, PIXELS, PITCH, b2.project(PIXELS, PITCH, p).unwrap());
        assert!((r1.1.length() - 1.0).abs() < 1e-12);
        let (x, e) = triangulate(&[r1, r2]);
        assert!((x - p).length() < 1e-9 && e < 1e-9);
        // One pixel off in one view gives a crossing-line error of about a pixel pitch × (source-
        // to-bead / source-to-detector) ≈ 0.2 mm.
        let uv = b2.project(PIXELS, PITCH, p).unwrap() + DVec2::new(0.0, 1.0);
        let (_, e) = triangulate(&[r1, ray_through_pixel(&b2, PIXELS, PITCH, uv)]);
        assert!(e > 0.1 && e < 0.3, "{e}");
    }
}
