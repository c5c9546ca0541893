//! A bead's sub-pixel centre in an attenuation-mode image from a model of its profile, fitted by
//! least squares to the background-subtracted attenuation of the pixels around it
//! ([`super::beads`] measures that excess and starts the fits at its intensity centroid).
//!
//! Two models, because a bead's profile has one of two shapes:
//!
//! - a **Gaussian** `A·exp(−|p − m|²/(2σ²))`: a bead seen through blur (area sampling, a focal
//!   spot, a detector PSF), whose profile is the sphere's smoothed by the blur's kernel;
//! - a **sphere** `a₁·h + a₂·h²`, `h = √(1 − |p − m|²/R²)` within `R` of the centre `m` and 0
//!   outside: the attenuation along the ray through a pixel's centre, which crosses the bead on
//!   a chord `2R·h` long, as an image of one ray per pixel from a point source samples it. The
//!   attenuation of a polychromatic beam grows more slowly than the chord (beam hardening); the
//!   quadratic term (0 for a monochromatic beam) takes that up.
//!
//! A bead beside another, whose image reaches into its window, is fitted together with it
//! ([`gaussians_fit`]: Gaussians of one shared width).
//!
//! A model that does not match the profile moves its centre with the bead's place against the
//! pixel grid (pixel locking): fitted to a sharp image, the Gaussian's centre follows the grid
//! (the guide's table of bead-centre methods measures by how much), and a sphere fitted to the
//! same pixels much less. On a blurred image the sphere's hard edge is the wrong shape, and it
//! can still fit the pixels more closely than the Gaussian with its centre further off (an
//! area-sampled bead does), so the residual cannot choose between them: the caller chooses the
//! model from what the imaging chain is declared to be ([`super::beads::Centre`]).

use glam::DVec2;
use nalgebra::{DMatrix, DVector, SMatrix, SVector};

/// One pixel of a bead's window: its centre (pixel coordinates) and its excess attenuation over
/// the background.
pub type Sample = (DVec2, f64);

/// A fitted profile: its centre and the sum of squared residuals over the window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fit {
    /// The bead's centre, pixels.
    pub centre: DVec2,
    /// Sum of squared residuals over the window.
    pub ssr: f64,
}

/// How far a fitted centre may move from its start, pixels: further, and the fit followed
/// something else (a neighbour, an edge).
pub const MAX_SHIFT_PX: f64 = 1.0;

/// The centre of a circular Gaussian fitted by Gauss–Newton to `pts` from `start` (σ starts at
/// `sigma_start_px`); `None` when the fit fails or moves more than [`MAX_SHIFT_PX`].
pub fn gaussian_fit(pts: &[Sample], start: DVec2, sigma_start_px: f64) -> Option<Fit> {
    let peak = pts.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    // Parameters: amplitude, centre u, v, ln σ.
    let mut q = [peak, start.x, start.y, libm::log(sigma_start_px)];
    for _ in 0..20 {
        let mut h = nalgebra::Matrix4::<f64>::zeros();
        let mut g = nalgebra::Vector4::<f64>::zeros();
        let sigma = libm::exp(q[3]);
        for &(p, v) in pts {
            let d = p - DVec2::new(q[1], q[2]);
            let r2 = d.length_squared();
            let e = libm::exp(-r2 / (2.0 * sigma * sigma));
            let model = q[0] * e;
            let jac = nalgebra::Vector4::new(
                e,
                model * d.x / (sigma * sigma),
                model * d.y / (sigma * sigma),
                model * r2 / (sigma * sigma),
            );
            h += jac * jac.transpose();
            g += jac * (v - model);
        }
        let step = h.lu().solve(&g)?;
        for k in 0..4 {
            q[k] += step[k].clamp(-1.0, 1.0);
        }
        if step.iter().all(|x| x.abs() < 1e-7) {
            break;
        }
    }
    let centre = DVec2::new(q[1], q[2]);
    let sigma = libm::exp(q[3]);
    let ssr: f64 = pts
        .iter()
        .map(|&(p, v)| {
            let r2 = (p - centre).length_squared();
            let r = v - q[0] * libm::exp(-r2 / (2.0 * sigma * sigma));
            r * r
        })
        .sum();
    ((centre - start).length() <= MAX_SHIFT_PX && q[0] > 0.0 && ssr.is_finite())
        .then_some(Fit { centre, ssr })
}

/// A bead and the neighbours whose images reach into its window, fitted together: circular
/// Gaussians `Σ Aₖ·exp(−|p − mₖ|²/(2σ²))` of one shared width (the beads of one image have one
/// diameter and one blur), by Levenberg–Marquardt from `beads` (each one's start centre and
/// amplitude; the first is the bead measured) and `sigma_start_px`. Returns the first bead's
/// centre and the window's residual; `None` when the fit fails, the first's amplitude is not
/// positive or its centre moves more than [`MAX_SHIFT_PX`]. A neighbour's tail in the window
/// is then modelled instead of pulling the centre towards it, as it pulls a lone Gaussian.
pub fn gaussians_fit(pts: &[Sample], beads: &[(DVec2, f64)], sigma_start_px: f64) -> Option<Fit> {
    let (first, _) = *beads.first()?;
    let n = 1 + 3 * beads.len();
    // Parameters: ln σ, then per bead its amplitude and centre u, v.
    let mut q = Vec::with_capacity(n);
    q.push(libm::log(sigma_start_px));
    for &(m, a) in beads {
        q.extend([a, m.x, m.y]);
    }
    // The model at `p` and, when `jac` is given, its gradient in the parameters.
    let model = |q: &[f64], p: DVec2, mut jac: Option<&mut [f64]>| -> f64 {
        let sigma = libm::exp(q[0]);
        let s2 = sigma * sigma;
        let mut total = 0.0;
        let mut d_ln_sigma = 0.0;
        for k in 0..beads.len() {
            let [a, u, v] = [q[1 + 3 * k], q[2 + 3 * k], q[3 + 3 * k]];
            let d = p - DVec2::new(u, v);
            let r2 = d.length_squared();
            let e = libm::exp(-r2 / (2.0 * s2));
            total += a * e;
            d_ln_sigma += a * e * r2 / s2;
            if let Some(j) = jac.as_deref_mut() {
                j[1 + 3 * k] = e;
                j[2 + 3 * k] = a * e * d.x / s2;
                j[3 + 3 * k] = a * e * d.y / s2;
            }
        }
        if let Some(j) = jac {
            j[0] = d_ln_sigma;
        }
        total
    };
    let cost = |q: &[f64]| -> f64 {
        pts.iter()
            .map(|&(p, v)| {
                let r = v - model(q, p, None);
                r * r
            })
            .sum()
    };
    let mut ssr = cost(&q);
    let mut lambda = 1e-4;
    let mut jac = vec![0.0; n];
    let mut h = DMatrix::<f64>::zeros(n, n);
    let mut g = DVector::<f64>::zeros(n);
    for _ in 0..100 {
        h.fill(0.0);
        g.fill(0.0);
        for &(p, v) in pts {
            let r = v - model(&q, p, Some(&mut jac));
            for a in 0..n {
                g[a] += jac[a] * r;
                for b in 0..=a {
                    h[(a, b)] += jac[a] * jac[b];
                }
            }
        }
        for a in 0..n {
            for b in 0..a {
                h[(b, a)] = h[(a, b)];
            }
        }
        let Some((next, c, step)) = marquardt_step(&h, &g, &q, ssr, &mut lambda, &cost) else {
            break;
        };
        // The bead's centre is what is wanted: once it settles (a step below 10⁻⁵ px, far below
        // the centre's noise), the neighbours' parameters need not.
        let converged = ssr - c <= 1e-10 * ssr
            || step.iter().all(|x| x.abs() < 1e-9)
            || (step[2].abs() < 1e-5 && step[3].abs() < 1e-5);
        q = next;
        ssr = c;
        if converged {
            break;
        }
    }
    let centre = DVec2::new(q[2], q[3]);
    ((centre - first).length() <= MAX_SHIFT_PX && q[1] > 0.0 && ssr.is_finite() && q[0].is_finite())
        .then_some(Fit { centre, ssr })
}

/// One Levenberg–Marquardt step from `q` (cost `ssr`) with Marquardt's scaling by the diagonal
/// of the normal matrix `h`: the damping `lambda` grows tenfold until a step lowers `cost`, then
/// shrinks tenfold for the next step. The new parameters, their cost and the step; `None` when
/// no damping up to 10¹² lowers the cost.
fn marquardt_step(
    h: &DMatrix<f64>,
    g: &DVector<f64>,
    q: &[f64],
    ssr: f64,
    lambda: &mut f64,
    cost: impl Fn(&[f64]) -> f64,
) -> Option<(Vec<f64>, f64, DVector<f64>)> {
    while *lambda < 1e12 {
        let mut damped = h.clone();
        for k in 0..q.len() {
            damped[(k, k)] += *lambda * h[(k, k)].max(1e-12);
        }
        let Some(step) = damped.lu().solve(g) else {
            *lambda *= 10.0;
            continue;
        };
        let next: Vec<f64> = q.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
        let c = cost(&next);
        if c < ssr {
            *lambda = (*lambda / 10.0).max(1e-9);
            return Some((next, c, step));
        }
        *lambda *= 10.0;
    }
    None
}

/// The sphere model `a₁·h + a₂·h²` at `p` for parameters `q = [a₁, a₂, u, v, R]`, with its
/// gradient in the parameters (zero outside the disc).
fn sphere(q: &[f64; 5], p: DVec2) -> (f64, [f64; 5]) {
    let [a1, a2, u, v, r] = *q;
    let d = p - DVec2::new(u, v);
    let h2 = 1.0 - d.length_squared() / (r * r);
    // Within a millionth of the rim the model and its gradient are 0 (the gradient's 1/h would
    // overflow the normal equations; such a pixel carries no signal anyway).
    if !(h2 > 1e-12) {
        return (0.0, [0.0; 5]);
    }
    let h = h2.sqrt();
    let model = a1 * h + a2 * h2;
    // ∂h/∂m = d/(R²h), ∂h/∂R = |d|²/(R³h).
    let dh = (a1 + 2.0 * a2 * h) / h;
    (
        model,
        [
            h,
            h2,
            dh * d.x / (r * r),
            dh * d.y / (r * r),
            dh * d.length_squared() / (r * r * r),
        ],
    )
}

/// The sphere model fitted by Levenberg–Marquardt to `pts` from centre `start` and radius
/// `radius_px`: its parameters and sum of squared residuals, or `None`.
fn sphere_from(pts: &[Sample], start: DVec2, radius_px: f64, peak: f64) -> Option<([f64; 5], f64)> {
    let cost = |q: &[f64; 5]| -> f64 {
        pts.iter()
            .map(|&(p, v)| {
                let r = v - sphere(q, p).0;
                r * r
            })
            .sum()
    };
    let mut q = [peak, 0.0, start.x, start.y, radius_px];
    let mut ssr = cost(&q);
    let mut lambda = 1e-3;
    for _ in 0..100 {
        let mut h = SMatrix::<f64, 5, 5>::zeros();
        let mut g = SVector::<f64, 5>::zeros();
        for &(p, v) in pts {
            let (model, grad) = sphere(&q, p);
            let jac = SVector::<f64, 5>::from(grad);
            h += jac * jac.transpose();
            g += jac * (v - model);
        }
        // A radius below a quarter pixel is no sphere.
        let bounded = |q: &[f64]| {
            let q: [f64; 5] = q.try_into().expect("5 parameters");
            if q[4] > 0.25 { cost(&q) } else { f64::INFINITY }
        };
        let h = DMatrix::from_column_slice(5, 5, h.as_slice());
        let g = DVector::from_column_slice(g.as_slice());
        let Some((next, c, step)) = marquardt_step(&h, &g, &q, ssr, &mut lambda, &bounded) else {
            break;
        };
        let next: [f64; 5] = next.try_into().expect("5 parameters");
        let converged = ssr - c <= 1e-12 * ssr || step.iter().all(|x| x.abs() < 1e-9);
        q = next;
        ssr = c;
        if converged {
            break;
        }
    }
    ssr.is_finite().then_some((q, ssr))
}

/// Offsets (px) of the sphere fit's starts from the given one: the cost has a kink wherever the
/// rim crosses a pixel centre, so a single descent can stop at one.
const STARTS_PX: [[f64; 2]; 5] = [[0.0, 0.0], [0.3, 0.0], [-0.3, 0.0], [0.0, 0.3], [0.0, -0.3]];

/// The centre of the sphere model fitted by Levenberg–Marquardt to `pts` (the best of starts
/// around `start`, radius `radius_start_px`); `None` when every fit fails, or the best one's
/// radius leaves half to twice its start, its peak is not positive or its centre moves more than
/// [`MAX_SHIFT_PX`].
pub fn sphere_fit(pts: &[Sample], start: DVec2, radius_start_px: f64) -> Option<Fit> {
    let peak = pts.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    if !(peak > 0.0 && radius_start_px > 0.0) {
        return None;
    }
    let (q, ssr) = STARTS_PX
        .iter()
        .filter_map(|o| sphere_from(pts, start + DVec2::from(*o), radius_start_px, peak))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let centre = DVec2::new(q[2], q[3]);
    ((centre - start).length() <= MAX_SHIFT_PX
        && (0.5 * radius_start_px..=2.0 * radius_start_px).contains(&q[4])
        && q[0] + q[1] > 0.0)
        .then_some(Fit { centre, ssr })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The window of a bead of radius `r` px at `c`: attenuation `(1 − exp(−k·chord))/k`
    /// (beam hardening of strength `k`) at each pixel centre (`samples = 1`) or averaged over
    /// `samples²` points per pixel.
    fn window(c: DVec2, r: f64, k: f64, samples: usize) -> Vec<Sample> {
        let (i0, j0) = (c.x.floor() as i64 - 5, c.y.floor() as i64 - 5);
        let mut pts = Vec::new();
        for j in j0..=j0 + 10 {
            for i in i0..=i0 + 10 {
                let mut acc = 0.0;
                for sy in 0..samples {
                    for sx in 0..samples {
                        let p = DVec2::new(
                            i as f64 + (sx as f64 + 0.5) / samples as f64,
                            j as f64 + (sy as f64 + 0.5) / samples as f64,
                        );
                        let d2 = (p - c).length_squared();
                        if d2 < r * r {
                            let chord = 2.0 * (r * r - d2).sqrt();
                            acc += (1.0 - (-k * chord).exp()) / k;
                        }
                    }
                }
                pts.push((
                    DVec2::new(i as f64 + 0.5, j as f64 + 0.5),
                    acc / (samples * samples) as f64,
                ));
            }
        }
        pts
    }

    /// Worst centre error (px) of `fit` over a 7 × 7 grid of sub-pixel positions.
    fn worst(fit: impl Fn(&[Sample], DVec2) -> Option<Fit>, r: f64, k: f64, samples: usize) -> f64 {
        let mut worst: f64 = 0.0;
        for a in 0..7 {
            for b in 0..7 {
                let c = DVec2::new(20.0 + a as f64 / 7.0, 30.0 + b as f64 / 7.0);
                let pts = window(c, r, k, samples);
                // Start where an intensity centroid would: a little off.
                let found = fit(&pts, c + DVec2::new(0.15, -0.1)).expect("a fit");
                worst = worst.max((found.centre - c).length());
            }
        }
        worst
    }

    #[test]
    fn a_point_sampled_bead_is_pixel_locked_by_the_gaussian_and_much_less_by_the_sphere() {
        // Radius 2.26 px (a 1 mm bead at magnification 1.35 on 0.2986 mm pixels). With a
        // monochromatic beam the sphere is the exact profile; with strong beam hardening
        // (attenuation 1 − e^(−0.8·chord), the chord up to 4.5 px) its quadratic term only
        // approximates it.
        let gaussian = worst(|p, s| gaussian_fit(p, s, 1.5), 2.26, 0.8, 1);
        let exact = worst(|p, s| sphere_fit(p, s, 3.0), 2.26, 1e-6, 1);
        let hardened = worst(|p, s| sphere_fit(p, s, 3.0), 2.26, 0.8, 1);
        assert!(
            gaussian > 0.1,
            "the Gaussian's pixel locking: {gaussian} px"
        );
        assert!(exact < 1e-6, "sphere, monochromatic: {exact} px");
        assert!(
            hardened < gaussian / 2.0,
            "sphere {hardened} px, Gaussian {gaussian} px"
        );
    }

    #[test]
    fn an_area_sampled_bead_fits_the_gaussian_better_than_the_sphere() {
        // 8 × 8 rays per pixel: the profile is smooth, the Gaussian's centre close; the sphere's
        // is further off (which is why the caller does not choose by the residual).
        let gaussian = worst(|p, s| gaussian_fit(p, s, 1.5), 2.26, 0.8, 8);
        let sphere = worst(|p, s| sphere_fit(p, s, 3.0), 2.26, 0.8, 8);
        assert!(gaussian < 0.02, "Gaussian {gaussian} px");
        assert!(
            sphere > gaussian,
            "sphere {sphere} px, Gaussian {gaussian} px"
        );
    }

    #[test]
    fn a_bead_fitted_with_its_neighbour_gets_its_centre_and_alone_it_leans() {
        // The exact model: two Gaussians of σ 1.1 px, 5.5 px apart, amplitudes 1 and 0.7, seen
        // in the first one's 11 × 11 window, which holds the near half of the second.
        let (a, b) = (DVec2::new(20.3, 30.6), DVec2::new(25.4, 32.7));
        let g = |p: DVec2, m: DVec2, amp: f64| amp * (-(p - m).length_squared() / 2.42).exp();
        let pts: Vec<Sample> = (25..36)
            .flat_map(|j| (15..26).map(move |i| DVec2::new(i as f64 + 0.5, j as f64 + 0.5)))
            .map(|p| (p, g(p, a, 1.0) + g(p, b, 0.7)))
            .collect();
        let start = a + DVec2::new(0.2, -0.15);
        let together = gaussians_fit(&pts, &[(start, 0.9), (DVec2::new(25.5, 32.5), 0.6)], 1.6)
            .expect("a fit");
        assert!((together.centre - a).length() < 1e-6, "{together:?}");
        let alone = gaussian_fit(&pts, start, 1.6).expect("a fit");
        assert!((alone.centre - a).length() > 0.005, "{alone:?}");
        // Without the neighbour in the window the joint fit is the lone one.
        let single: Vec<Sample> = pts.iter().map(|&(p, _)| (p, g(p, a, 1.0))).collect();
        let one = gaussians_fit(&single, &[(start, 0.9)], 1.6).expect("a fit");
        assert!((one.centre - a).length() < 1e-6, "{one:?}");
    }

    #[test]
    fn no_signal_gives_no_sphere() {
        let pts: Vec<Sample> = (0..25)
            .map(|k| (DVec2::new((k % 5) as f64 + 0.5, (k / 5) as f64 + 0.5), 0.0))
            .collect();
        assert_eq!(sphere_fit(&pts, DVec2::new(2.5, 2.5), 2.0), None);
    }
}
