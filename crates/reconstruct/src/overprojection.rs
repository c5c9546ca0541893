//! Model beads overprojected by box beads.
//!
//! The box sits between the patient and the detectors, so a box bead's image may fall on a
//! model bead's image. The two then merge into one blob, or touch, and the blob's centre lies
//! between the two beads: a model bead measured there is off by a fraction of a pixel in that
//! view. Across the two views of a uniplanar or biplanar room such an offset along the epipolar
//! line moves the triangulated bead along the depth both beams share, where a fraction of a
//! pixel is a few tenths of a millimetre (the shipped clinical study's largest bead errors,
//! 0.3–0.5 mm, were all of this kind). RSA programs leave such markers out of the view: the
//! calibration predicts every box bead's image, so the overlap is known without looking at
//! the blob.

use glam::DVec2;

use super::correspond::Prediction;

/// Margin (pixels) beyond touching discs: blobs are made of whole pixels, so two discs whose
/// rims are up to a pixel apart can still share a pixel (as [`super::beads::touches`] allows).
pub const MARGIN_PX: f64 = 1.0;

/// Whether a model bead imaged at `uv` with radius `radius_px` shares pixels with the image of
/// any box bead in `box_images` (their predicted centres and areas in the same view): centres
/// closer than the sum of the radii plus [`MARGIN_PX`].
pub fn overprojected(uv: DVec2, radius_px: f64, box_images: &[Prediction]) -> bool {
    box_images.iter().any(|b| {
        let box_radius_px = (b.expected_area / std::f64::consts::PI).sqrt();
        (b.uv - uv).length() < radius_px + box_radius_px + MARGIN_PX
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn box_bead(u: f64, v: f64, radius_px: f64) -> Prediction {
        Prediction {
            index: 0,
            uv: DVec2::new(u, v),
            expected_area: crate::detect::bead_area_px(radius_px),
            group: 0,
        }
    }

    #[test]
    fn a_bead_is_overprojected_within_the_sum_of_the_radii_plus_a_pixel() {
        // A 2.5 px model bead and a 1.7 px box bead: overlap below 2.5 + 1.7 + 1 = 5.2 px.
        let boxes = [box_bead(100.0, 100.0, 1.7), box_bead(300.0, 40.0, 1.9)];
        assert!(overprojected(DVec2::new(103.0, 104.0), 2.5, &boxes)); // 5.0 px
        assert!(!overprojected(DVec2::new(100.0, 105.3), 2.5, &boxes)); // 5.3 px
        assert!(overprojected(DVec2::new(300.0, 45.3), 2.5, &boxes)); // 5.3 < 5.4 px
        assert!(!overprojected(DVec2::new(200.0, 70.0), 2.5, &boxes));
        assert!(!overprojected(DVec2::new(103.0, 104.0), 2.5, &[]));
    }
}
