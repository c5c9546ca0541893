//! Where the rays of one pixel go (beyond the paper): area sampling over the pixel and a finite
//! focal spot. Both modes average what these rays see, so a pixel an edge crosses gets a partial
//! value and a shadow gets the penumbra of the spot (docs/src/reference/conventions.md, "Image formation (sampling and unsharpness)").
//!
//! * **Pixel samples**: s×s rays per pixel, to the points `(i + (a + ½)/s, j + (b + ½)/s)`
//!   (a, b = 0 … s−1) in continuous pixel coordinates, equal weights. They are traced as a
//!   detector of s× the resolution, one horizontal strip of pixel rows at a time
//!   ([`strip::strips`]), so the memory stays bounded.
//! * **Focal spot**: k×k sub-sources in the plane through the source parallel to the detector,
//!   offset along the detector's r and c axes ([`focal_spot::sub_sources`]). The spot's centre is
//!   the source position: truth keeps it, and a marker's projected centre stays the projection of
//!   its centre from there.
//! * **Heel effect** (attenuation mode): a linear fall of the fluence towards the anode
//!   ([`Heel`]).
//!
//! A pixel's value is the weighted mean over sub-sources (weights w_k, summing to 1) and pixel
//! samples (1/s² each) of what each ray gives: the covered fraction in binary mode
//! ([`coverage`]), the expected quanta and energy in attenuation mode
//! (`crate::attenuation::sampled`). Sums run in a fixed order (sub-sources in order, then the
//! samples row by row), so values do not depend on the thread count.

pub mod adaptive;
pub mod coverage;
pub mod focal_spot;
pub mod strip;

use glam::DVec3;

use crate::geometry::DetectorFrame;
use crate::scenario::{AxisDirection, Imaging, RaySampling};

pub use focal_spot::{SubSource, spot_nodes};

/// How the rays of one image are sampled: plain numbers from `[imaging]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Sampling {
    /// Rays per pixel side, s ≥ 1.
    pub samples_per_side: u32,
    /// The focal spot's sub-sources (offsets along the detector's r and c, mm; weights summing
    /// to 1). One sub-source at offset 0 for a point source.
    pub sub_sources: Vec<SubSource>,
    /// The heel effect, if any.
    pub heel: Option<Heel>,
    /// Attenuation mode: trace every ray only where the pixel needs it ([`adaptive`]).
    pub adaptive: bool,
}

impl Sampling {
    /// The sampling `[imaging]` asks for.
    pub fn from_imaging(imaging: &Imaging) -> Sampling {
        let spot = imaging.focal_spot.as_ref();
        Sampling {
            samples_per_side: imaging.samples_per_side().max(1),
            sub_sources: match spot {
                Some(f) => focal_spot::spot_sub_sources(f),
                None => vec![SubSource {
                    offset_mm: [0.0, 0.0],
                    weight: 1.0,
                }],
            },
            adaptive: imaging.ray_sampling.unwrap_or_default() == RaySampling::Adaptive,
            heel: spot.and_then(|f| {
                f.heel_percent_per_100_mm
                    .filter(|&h| h != 0.0)
                    .map(|h| Heel {
                        percent_per_100_mm: h,
                        anode_direction: f.anode_direction.unwrap_or(AxisDirection::MinusC),
                    })
            }),
        }
    }

    /// One ray to each pixel centre from the source: the paper's sampling.
    pub fn is_point(&self) -> bool {
        self.samples_per_side == 1
            && self.heel.is_none()
            && self.sub_sources.len() == 1
            && self.sub_sources[0].offset_mm == [0.0, 0.0]
    }

    /// World positions and weights of the sub-sources of `source_mm` for a detector `frame`.
    pub fn sources(&self, frame: &DetectorFrame, source_mm: DVec3) -> Vec<(DVec3, f64)> {
        let r = frame.pose.rotation.x_axis;
        let c = frame.pose.rotation.y_axis;
        self.sub_sources
            .iter()
            .map(|s| {
                (
                    source_mm + r * s.offset_mm[0] + c * s.offset_mm[1],
                    s.weight,
                )
            })
            .collect()
    }
}

/// The anode heel effect as a linear gradient of the fluence across the detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Heel {
    /// Fall of the fluence towards the anode, percent per 100 mm.
    pub percent_per_100_mm: f64,
    /// The detector axis pointing towards the anode side.
    pub anode_direction: AxisDirection,
}

impl Heel {
    /// The fluence factor at detector-frame point (`x_mm`, `y_mm`):
    /// `max(0, 1 − (percent/100) · t/100 mm)`, t the coordinate along the anode direction
    /// (0 at the detector centre).
    pub fn factor(&self, x_mm: f64, y_mm: f64) -> f64 {
        let t = match self.anode_direction {
            AxisDirection::PlusR => x_mm,
            AxisDirection::MinusR => -x_mm,
            AxisDirection::PlusC => y_mm,
            AxisDirection::MinusC => -y_mm,
        };
        (1.0 - self.percent_per_100_mm / 100.0 * (t / 100.0)).max(0.0)
    }

    /// The factor of every pixel centre of `frame` (W×H, row-major).
    pub fn image(&self, frame: &DetectorFrame) -> Vec<f64> {
        let [w, h] = frame.pixels;
        let mut out = Vec::with_capacity(w as usize * h as usize);
        for j in 0..h {
            for i in 0..w {
                let p = frame.pixel_local(i as f64 + 0.5, j as f64 + 0.5);
                out.push(self.factor(p.x, p.y));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{FocalSpot, SpotProfile};

    #[test]
    fn default_imaging_is_the_paper_point_source() {
        let s = Sampling::from_imaging(&Imaging::default());
        assert!(s.is_point());
        assert_eq!(s.sub_sources.len(), 1);
    }

    #[test]
    fn sub_sources_lie_in_the_detector_plane_directions() {
        let imaging = Imaging {
            focal_spot: Some(FocalSpot {
                size_mm: 1.2,
                profile: SpotProfile::Uniform,
                samples: 2,
                heel_percent_per_100_mm: None,
                intensity_fall_percent: None,
                anode_direction: None,
            }),
            ..Imaging::default()
        };
        let s = Sampling::from_imaging(&imaging);
        assert!(!s.is_point());
        // A detector turned 90° about y: r = −z, c = +y, s = +x.
        let frame = DetectorFrame {
            pose: crate::geometry::Pose::from_position_euler_deg(
                [-500.0, 0.0, 0.0],
                [0.0, 90.0, 0.0],
            ),
            pixels: [10, 10],
            pixel_pitch_mm: [1.0, 1.0],
        };
        let src = DVec3::new(1300.0, 0.0, 0.0);
        for (p, w) in s.sources(&frame, src) {
            assert!(
                (p.x - 1300.0).abs() < 1e-12,
                "stays in the plane x = 1300: {p}"
            );
            assert!(((p - src).length() - 0.3 * 2f64.sqrt()).abs() < 1e-12);
            assert_eq!(w, 0.25);
        }
    }

    #[test]
    fn heel_falls_towards_the_anode() {
        let heel = Heel {
            percent_per_100_mm: 10.0,
            anode_direction: AxisDirection::MinusC,
        };
        assert_eq!(heel.factor(0.0, 0.0), 1.0);
        assert!((heel.factor(50.0, -100.0) - 0.9).abs() < 1e-15);
        assert!((heel.factor(0.0, 100.0) - 1.1).abs() < 1e-15);
        let steep = Heel {
            percent_per_100_mm: 50.0,
            anode_direction: AxisDirection::PlusR,
        };
        assert_eq!(steep.factor(300.0, 0.0), 0.0, "clamped at 0");
    }
}
