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
//! A model that does not match the profile moves its centre with the bead's place against the
//! pixel grid (pixel locking): fitted to a sharp image, the Gaussian's centre follows the grid
//! (the guide's table of bead-centre methods measures by how much), and a sphere fitted to the
//! same pixels much less. On a blurred image the sphere's hard edge is the wrong shape, and it
//! can still fit the pixels more closely than the Gaussian with its centre further off (an
//! area-sampled bead does), so the residual cannot choose between them: the caller chooses the
//! model from what the imaging chain is declared to be ([`super::beads::Centre`]).

use glam::DVec2;
use nalgebra::{SMatrix, SVector};

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
        // Damped steps until one lowers the cost (Marquardt's scaling by the diagonal).
        let mut improved = None;
        while lambda < 1e12 {
            let mut damped = h;
            for k in 0..5 {
                damped[(k, k)] += lambda * h[(k, k)].max(1e-12);
            }
            let Some(step) = damped.lu().solve(&g) else {
                lambda *= 10.0;
                continue;
            };
            let next: [f64; 5] = std::array::from_fn(|k| q[k] + step[k]);
            let c = if next[4] > 0.25 {
                cost(&next)
            } else {
                f64::INFINITY
            };
            if c < ssr {
                improved = Some((next, c, step));
                lambda = (lambda / 10.0).max(1e-9);
                break;
            }
            lambda *= 10.0;
        }
        let Some((next, c, step)) = improved else {
            break;
        };
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
    fn no_signal_gives_no_sphere() {
        let pts: Vec<Sample> = (0..25)
            .map(|k| (DVec2::new((k % 5) as f64 + 0.5, (k / 5) as f64 + 0.5), 0.0))
            .collect();
        assert_eq!(sphere_fit(&pts, DVec2::new(2.5, 2.5), 2.0), None);
    }
}
