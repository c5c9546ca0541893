//! Where the measured edge of a metal model's shadow lies, as its mesh and material predict it.
//!
//! The edge points of [`super::edge`] lie where the transmission crosses half-way between the
//! local plateau and background. For an opaque object that is its geometric outline (after a
//! symmetric blur, up to the curvature term). A metal implant is not opaque near its outline:
//! a ray grazing a rounded rim or a thin flange crosses only a short chord of metal, so the
//! transmission falls over a few tenths of a millimetre inside the outline, and the half-way
//! crossing lies inside it by an amount that depends on the local shape: 0.03–0.08 px on
//! average per view on the CoCr component of `biplanar_realistic` at 85 kVp, more where the
//! rim is thin. Because the
//! shift differs around the outline, it turns the fitted pose (+0.05° about x on
//! `biplanar_realistic_blurred`), where a uniform shift would only shrink it.
//!
//! [`EdgeModel::crossing_px`] predicts that shift at a point of the projected outline: it
//! takes the chords through the metal of the rays to points every [`STEP_PX`] along the
//! outline's normal, at the current pose (one cut of the mesh by the plane of those rays,
//! `MeshBvh::fan_chords_mm`), turns the chords into transmission with the nominal beam's spectrum
//! and the model's material ([`MetalTransmission`]), blurs the profile with the nominal blur
//! (as [`super::edge::EdgeWindows::for_imaging`] adds it up) and finds its half-way crossing
//! with the same level windows as the measurement. Subtracting it from a measured point puts
//! the point on the geometric outline, which is what the fit compares it with.

use std::sync::OnceLock;

use glam::{DVec2, DVec3};

use super::edge::EdgeWindows;
use super::model_outline::OutlineModel;
use crate::attenuation::Setup;
use crate::geometry::{DetectorFrame, Pose};
use crate::scenario::ResponseKind;

/// Spacing of the predicted profile's samples along the normal, pixels.
pub const STEP_PX: f64 = 0.2;

/// The transmission of the model's material for the nominal beam as the detector weighs it:
/// `T(ℓ) = Σ_b w_b·exp(−μ_b·ℓ)` over the spectrum's bins, `w_b` the detected signal of bin b
/// in the open field (photons × absorption, × energy for an energy-integrating detector),
/// normalised.
#[derive(Debug, Clone, PartialEq)]
pub struct MetalTransmission {
    weights: Vec<f64>,
    mu_per_mm: Vec<f64>,
    /// `T` and `T′` on a grid of chords, for [`MetalTransmission::at_tabulated`]; built on
    /// first use.
    table: OnceLock<Table>,
}

/// Chords up to this length (mm) are read from the table; longer ones are summed.
const TABLE_MAX_MM: f64 = 200.0;

/// The largest error of a tabulated transmission, absolute (the transmission is at most 1).
pub const TABLE_TOLERANCE: f64 = 1e-7;

/// `T(ℓ)` and `T′(ℓ)` at `ℓ = i·step_mm`, i = 0, 1, …
#[derive(Debug, Clone, PartialEq)]
struct Table {
    step_mm: f64,
    nodes: Vec<(f64, f64)>,
}

impl Table {
    /// The grid's step is the largest (at most 0.01 mm) for which cubic Hermite interpolation
    /// errs by at most [`TABLE_TOLERANCE`]: its error is at most `h⁴/384·max|T⁗|`, and
    /// `|T⁗(ℓ)| = Σ w_b·μ_b⁴·exp(−μ_b·ℓ) ≤ Σ w_b·μ_b⁴`. The exponentials of each bin follow
    /// the grid by repeated multiplication with `exp(−μ_b·h)`; after the at most 2²⁰ steps
    /// that adds a relative error of at most 2²¹ ulp, below 10⁻⁹.
    fn new(weights: &[f64], mu_per_mm: &[f64]) -> Table {
        let fourth: f64 = (weights.iter().zip(mu_per_mm))
            .map(|(w, mu)| w * mu.powi(4))
            .sum();
        let step_mm = (384.0 * TABLE_TOLERANCE / fourth)
            .powf(0.25)
            .clamp(TABLE_MAX_MM / (1 << 20) as f64, 0.01);
        let count = (TABLE_MAX_MM / step_mm).ceil() as usize + 1;
        let ratios: Vec<f64> = (mu_per_mm.iter())
            .map(|mu| libm::exp(-mu * step_mm))
            .collect();
        let mut powers = vec![1.0; weights.len()];
        let mut nodes = Vec::with_capacity(count);
        for _ in 0..count {
            let (mut t, mut dt) = (0.0, 0.0);
            for ((p, w), mu) in powers.iter().zip(weights).zip(mu_per_mm) {
                t += w * p;
                dt -= w * mu * p;
            }
            nodes.push((t, dt));
            for (p, r) in powers.iter_mut().zip(&ratios) {
                *p *= r;
            }
        }
        Table { step_mm, nodes }
    }

    /// Cubic Hermite interpolation between the nodes around `length_mm`; `None` beyond them.
    fn at(&self, length_mm: f64) -> Option<f64> {
        let x = length_mm / self.step_mm;
        let i = x.floor();
        if !(i >= 0.0) {
            return None;
        }
        let (&(t0, d0), &(t1, d1)) = (self.nodes.get(i as usize)?, self.nodes.get(i as usize + 1)?);
        let s = x - i;
        let (s2, s3) = (s * s, s * s * s);
        let h = self.step_mm;
        Some(
            (2.0 * s3 - 3.0 * s2 + 1.0) * t0
                + (s3 - 2.0 * s2 + s) * h * d0
                + (-2.0 * s3 + 3.0 * s2) * t1
                + (s3 - s2) * h * d1,
        )
    }
}

impl MetalTransmission {
    /// From per-bin signal weights (any scale) and the material's attenuation per bin, 1/mm.
    /// `None` when the weights do not add up to a positive number or the lengths differ.
    pub fn new(weights: &[f64], mu_per_mm: &[f64]) -> Option<MetalTransmission> {
        let total: f64 = weights.iter().sum();
        (weights.len() == mu_per_mm.len() && total > 0.0 && total.is_finite()).then(|| {
            MetalTransmission {
                weights: weights.iter().map(|w| w / total).collect(),
                mu_per_mm: mu_per_mm.to_vec(),
                table: OnceLock::new(),
            }
        })
    }

    /// The transmission of the material `name` for the nominal beam of `physics` (its bins after
    /// filtration and the detector's absorption), hardened on its way by the material `around`
    /// (the tissue the implant lies in, when the scenario says so) to an attenuation of
    /// `background` (the image's level beside the implant): the thickness of `around` that
    /// attenuates the beam that much filters every bin. `None` when a material is not in use.
    pub fn of_material(
        physics: &Setup,
        name: &str,
        around: Option<&str>,
        background: f64,
    ) -> Option<MetalTransmission> {
        let index = |name: &str| physics.names.iter().position(|n| n == name);
        let m = index(name)?;
        let weights: Vec<f64> = (physics.spectrum_photons.iter())
            .zip(&physics.efficiency)
            .zip(&physics.energies_kev)
            .map(|((n, eta), e)| match physics.response {
                ResponseKind::EnergyIntegrating => n * eta * e,
                ResponseKind::PhotonCounting => n * eta,
            })
            .collect();
        let weights = match around {
            Some(t) => {
                let tissue = MetalTransmission::new(&weights, physics.mu_per_mm.get(index(t)?)?)?;
                let length_mm = tissue.length_for(background);
                (weights.iter().zip(&tissue.mu_per_mm))
                    .map(|(w, mu)| w * libm::exp(-mu * length_mm))
                    .collect()
            }
            None => weights,
        };
        MetalTransmission::new(&weights, physics.mu_per_mm.get(m)?)
    }

    /// The chord (mm, at most 1 m) whose attenuation `−ln T` is `attenuation`, by bisection.
    pub fn length_for(&self, attenuation: f64) -> f64 {
        let target = libm::exp(-attenuation.max(0.0));
        let (mut lo, mut hi) = (0.0, 1000.0);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if self.at(mid) > target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// [`MetalTransmission::at`] within [`TABLE_TOLERANCE`], read from a table (built on the
    /// first call) for chords up to 200 mm: the edge model reads it for some hundred chords
    /// per outline point, where summing the bins' exponentials took most of its time.
    pub fn at_tabulated(&self, length_mm: f64) -> f64 {
        let table = self
            .table
            .get_or_init(|| Table::new(&self.weights, &self.mu_per_mm));
        table.at(length_mm).unwrap_or_else(|| self.at(length_mm))
    }

    /// The transmission through a chord of `length_mm` of the material.
    pub fn at(&self, length_mm: f64) -> f64 {
        self.weights
            .iter()
            .zip(&self.mu_per_mm)
            .map(|(w, mu)| w * libm::exp(-mu * length_mm))
            .sum()
    }
}

/// A model's predicted edge profile (module docs).
pub struct EdgeModel<'a> {
    /// The model's mesh.
    pub model: &'a OutlineModel,
    /// Its material's transmission for the nominal beam.
    pub metal: &'a MetalTransmission,
    /// The nominal blur, SD in pixels (detector PSF, focal-spot penumbra and pixel area).
    pub sigma_px: f64,
    /// The level windows of the measurement.
    pub windows: EdgeWindows,
}

impl EdgeModel<'_> {
    /// The predicted half-way crossing of the edge profile along `normal` (unit, pixels) through
    /// the outline point `q`, in pixels along `normal` from `q`, for the model at `pose` seen
    /// from `source_mm` on `frame`. `None` when the predicted profile has no clean step there
    /// (another part of the model within the windows, or no metal at all).
    pub fn crossing_px(
        &self,
        pose: &Pose,
        source_mm: DVec3,
        frame: &DetectorFrame,
        q: DVec2,
        normal: DVec2,
    ) -> Option<f64> {
        let w = self.windows;
        let blur = (3.0 * self.sigma_px / STEP_PX).ceil() as i64;
        let reach_px = (w.far_px + w.search_px) as f64 + 1.0;
        let n = (reach_px / STEP_PX).ceil() as i64 + blur;
        let to_local = pose.rotation.transpose();
        let origin = to_local * (source_mm - pose.position_mm);
        // The samples' targets lie on one line of the detector: the chords are a fan's.
        let local = |p: DVec2| {
            to_local * (frame.pose.to_world(frame.pixel_local(p.x, p.y)) - pose.position_mm)
        };
        let first = local(q - normal * (n as f64 * STEP_PX));
        let step = local(q + normal * STEP_PX) - local(q);
        let chords = (self.model.bvh()).fan_chords_mm(origin, first, step, (2 * n + 1) as usize);
        let sharp: Vec<f64> = chords.iter().map(|&l| self.metal.at_tabulated(l)).collect();
        let profile = gaussian_blurred(&sharp, self.sigma_px / STEP_PX);
        half_way_crossing(&profile, n, w)
    }
}

/// `v` convolved with a normalised Gaussian of `sigma` samples (truncated at 3σ, the ends
/// held); `v` itself when σ is below a tenth of a sample.
fn gaussian_blurred(v: &[f64], sigma: f64) -> Vec<f64> {
    if !(sigma >= 0.1) {
        return v.to_vec();
    }
    let half = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f64> = (-half..=half)
        .map(|k| libm::exp(-0.5 * (k as f64 / sigma).powi(2)))
        .collect();
    let total: f64 = kernel.iter().sum();
    let last = v.len() as i64 - 1;
    (0..v.len() as i64)
        .map(|i| {
            kernel
                .iter()
                .enumerate()
                .map(|(m, k)| k * v[(i + m as i64 - half).clamp(0, last) as usize])
                .sum::<f64>()
                / total
        })
        .collect()
}

/// The half-way crossing (in pixels from sample `centre`) of a profile sampled every
/// [`STEP_PX`], found as the measurement finds it: levels are the medians of the samples
/// `windows.near_px..=windows.far_px` pixels on each side of the current estimate (the side
/// that transmits less being the metal's), the crossing the one nearest the estimate within
/// `windows.search_px`, twice. `None` without a clean step (the metal's level must transmit at
/// most [`super::edge::MAX_INSIDE_FRACTION`] of the other).
fn half_way_crossing(profile: &[f64], centre: i64, windows: EdgeWindows) -> Option<f64> {
    let at = |x_px: f64| -> Option<f64> {
        let k = (x_px / STEP_PX).round() as i64 + centre;
        (k >= 0).then(|| profile.get(k as usize).copied()).flatten()
    };
    let (near, far) = (windows.near_px as f64, windows.far_px as f64);
    let level = |c: f64, sign: f64| -> Option<f64> {
        let mut v: Vec<f64> = (0..)
            .map(|m| near + m as f64 * STEP_PX)
            .take_while(|d| *d <= far + 1e-9)
            .filter_map(|d| at(c + sign * d))
            .collect();
        if v.is_empty() {
            return None;
        }
        let mid = v.len() / 2;
        Some(*v.select_nth_unstable_by(mid, f64::total_cmp).1)
    };
    let mut c = 0.0;
    for _ in 0..2 {
        let (minus, plus) = (level(c, -1.0)?, level(c, 1.0)?);
        let (t_in, t_out) = (minus.min(plus), minus.max(plus));
        if !(t_in <= super::edge::MAX_INSIDE_FRACTION * t_out) {
            return None;
        }
        let half = 0.5 * (minus + plus);
        let span = (windows.search_px as f64 / STEP_PX).round() as i64;
        let k0 = (c / STEP_PX).round() as i64 + centre;
        let mut best: Option<(f64, f64)> = None;
        for k in (k0 - span).max(0)..(k0 + span).min(profile.len() as i64 - 1) {
            let (a, b) = (profile[k as usize], profile[k as usize + 1]);
            if (a - half) * (b - half) > 0.0 || a == b {
                continue;
            }
            let x = ((k - centre) as f64 + (half - a) / (b - a)) * STEP_PX;
            if best.is_none_or(|(d, _)| (x - c).abs() < d) {
                best = Some(((x - c).abs(), x));
            }
        }
        c = best?.1;
    }
    Some(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tabulated_transmission_is_the_sum_within_its_tolerance() {
        // 40 bins from 20 to 85 keV with a cobalt-like μ (41/mm at 20 keV falling as E⁻³,
        // plus a floor) and weights of a filtered beam (none below 25 keV would make it
        // easier): the direct sum against the table at chords off the grid, up to and beyond
        // its end.
        let energies: Vec<f64> = (0..40).map(|b| 20.0 + 65.0 * b as f64 / 39.0).collect();
        let mu: Vec<f64> = energies
            .iter()
            .map(|e| 41.0 * (20.0 / e).powi(3) + 0.3)
            .collect();
        let weights: Vec<f64> = energies.iter().map(|e| (e - 18.0) * (90.0 - e)).collect();
        let metal = MetalTransmission::new(&weights, &mu).unwrap();
        let mut worst: f64 = 0.0;
        for k in 0..200_000 {
            let length_mm = 210.0 * (k as f64 * 0.618_033_988_749_895).fract().powi(3);
            let error = (metal.at_tabulated(length_mm) - metal.at(length_mm)).abs();
            worst = worst.max(error);
        }
        assert!(worst <= TABLE_TOLERANCE, "{worst}");
        assert_eq!(metal.at_tabulated(0.0), metal.at(0.0));
        assert_eq!(metal.at_tabulated(250.0), metal.at(250.0));
    }
    use crate::edge::edge_points_along_outline;
    use crate::phantom::TriMesh;

    #[test]
    fn an_opaque_straight_edge_crosses_on_the_outline() {
        // A step from 1 to 0 at sample `centre` (between two samples), blurred symmetrically:
        // the crossing is the step's position.
        let n = 100;
        let profile: Vec<f64> = (0..=2 * n)
            .map(|k| {
                if k < n {
                    1.0
                } else if k > n {
                    0.0
                } else {
                    0.5
                }
            })
            .collect();
        let blurred = gaussian_blurred(&profile, 3.7);
        let c = half_way_crossing(&blurred, n as i64, EdgeWindows::SHARP).unwrap();
        assert!(c.abs() < 1e-9, "{c}");
    }

    #[test]
    fn points_on_a_blurred_translucent_sphere_lie_on_its_outline_once_corrected() {
        // A sphere of radius 2 mm and μ = 1/mm, 900 mm from the source and 100 mm from the
        // detector (0.05 mm pixels), over a background of attenuation 2, area-sampled (4 × 4)
        // and blurred by σ = 0.7 px. The chord through it at distance r from its centre is
        // 2·√(R² − r²): half transmission lies some 0.8 px inside the outline. Measured along
        // the outline's normals, the points lie that far inside; corrected by the predicted
        // crossing, on the outline.
        let (radius_mm, mu) = (2.0, 1.0);
        let frame = DetectorFrame {
            pose: Pose::IDENTITY,
            pixels: [140, 140],
            pixel_pitch_mm: [0.05, 0.05],
        };
        let source = DVec3::new(0.3, -0.2, 1000.0);
        let pose = Pose {
            position_mm: DVec3::new(0.1, -0.2, 100.0),
            rotation: crate::geometry::rotation_xyz_deg([10.0, 20.0, 30.0]),
        };
        let mut values = vec![0.0; 140 * 140];
        for j in 0..140 {
            for i in 0..140 {
                let mut t = 0.0;
                for s in 0..16 {
                    let uv = DVec2::new(
                        i as f64 + (f64::from(s % 4) + 0.5) / 4.0,
                        j as f64 + (f64::from(s / 4) + 0.5) / 4.0,
                    );
                    let target = frame.pose.to_world(frame.pixel_local(uv.x, uv.y));
                    let d = (target - source).normalize();
                    let off = pose.position_mm - source;
                    let r2 = (off - d * off.dot(d)).length_squared();
                    let chord = 2.0 * (radius_mm * radius_mm - r2).max(0.0).sqrt();
                    t += libm::exp(-mu * chord) / 16.0;
                }
                values[j * 140 + i] = 2.0 - libm::log(t);
            }
        }
        let img = crate::density::Density {
            width: 140,
            height: 140,
            clipped: vec![false; values.len()],
            values,
        }
        .blurred(0.7);
        let model = OutlineModel::new(&TriMesh::uv_sphere(radius_mm, 128, 256)).unwrap();
        let metal = MetalTransmission::new(&[1.0], &[mu]).unwrap();
        let segments = model.outline(&pose, source, &frame);
        let windows = EdgeWindows::SHARP;
        let edge = EdgeModel {
            model: &model,
            metal: &metal,
            sigma_px: (0.7f64 * 0.7 + 1.0 / 12.0).sqrt(),
            windows,
        };
        let predict = |q: DVec2, n: DVec2| edge.crossing_px(&pose, source, &frame, q, n);
        let centre = frame.project(source, pose.position_mm).unwrap();
        let outline_px = 1000.0
            * (radius_mm / (pose.position_mm - source).length())
                .asin()
                .tan()
            / 0.05;
        let mean_offset = |points: &[DVec2]| {
            assert!(points.len() > 250, "{} points", points.len());
            points
                .iter()
                .map(|p| (*p - centre).length() - outline_px)
                .sum::<f64>()
                / points.len() as f64
        };
        let measured = mean_offset(&edge_points_along_outline(&img, &segments, windows, None));
        let corrected = mean_offset(&edge_points_along_outline(
            &img,
            &segments,
            windows,
            Some(&predict),
        ));
        // Measured: −0.77 px uncorrected, −0.075 px corrected (what is left is the pixel
        // sampling the prediction does not model: area sampling and bilinear reading of a
        // steep graded profile).
        assert!(measured < -0.4, "uncorrected {measured} px");
        assert!(
            corrected.abs() < 0.1 && corrected.abs() < 0.15 * measured.abs(),
            "corrected {corrected} px"
        );
    }

    #[test]
    fn a_sphere_of_finite_attenuation_crosses_inside_its_outline_by_the_chord_prediction() {
        // A sphere of radius 10 mm (metal, μ = 2/mm), 100 mm from the detector at 1 mm pixels
        // seen from 1000 mm: near the outline a ray at depth d inside it (object scale) crosses a
        // chord of 2·√(2·R·d); half transmission (the plateau being 0) is a chord of ln 2 / μ,
        // at d = (ln 2/μ)²/(8R) = 0.0015 mm at the object, times the magnification 1000/900.
        let model = OutlineModel::new(&TriMesh::uv_sphere(10.0, 256, 512)).unwrap();
        let metal = MetalTransmission::new(&[1.0], &[2.0]).unwrap();
        let frame = DetectorFrame {
            pose: Pose::IDENTITY,
            pixels: [200, 200],
            pixel_pitch_mm: [0.01, 0.01],
        };
        let source = DVec3::new(1.0, 1.0, 1000.0);
        let pose = Pose {
            position_mm: DVec3::new(1.0, 1.0, 100.0),
            rotation: glam::DMat3::IDENTITY,
        };
        // The outline's point on the +u side, its outward normal +u; pixels of 0.01 mm.
        let magnification = 1000.0 / 900.0;
        let radius_px = 1000.0 * (10.0f64 / 900.0).asin().tan() / 0.01;
        let centre = frame.project(source, pose.position_mm).unwrap();
        let q = centre + DVec2::new(radius_px, 0.0);
        let edge = EdgeModel {
            model: &model,
            metal: &metal,
            sigma_px: 0.0,
            windows: EdgeWindows::SHARP,
        };
        let c = edge
            .crossing_px(&pose, source, &frame, q, DVec2::X)
            .unwrap();
        let depth_mm = (2f64.ln() / 2.0).powi(2) / (8.0 * 10.0) * magnification;
        // The mesh's facets (256 around) lie up to 10·(1 − cos(π/256)) = 0.0008 mm inside.
        assert!(
            (c + depth_mm / 0.01).abs() < 0.1,
            "{c} px vs −{} px",
            depth_mm / 0.01
        );
    }
}
