//! Relative fluence of a point source over a flat detector: inverse square and obliquity.
//!
//! A pixel of area `A` at distance `r` from the source, seen at angle θ from the detector normal,
//! receives a share of the source's photons proportional to `A·cos θ / r²`. With `D` the source's
//! distance to the detector plane, `cos θ = D/r`, so relative to the foot of the perpendicular
//! (where `r = D`, θ = 0) the fluence is `f = (D/r)³`. It is evaluated as `c·√c` with
//! `c = D²/r²` (IEEE `sqrt` is correctly rounded, so the values are the same everywhere).

use glam::DVec3;

use crate::geometry::DetectorFrame;

/// `(D/r)³` for every pixel centre, row-major (`W·H` values, row 0 first): `D` the distance of
/// `source_mm` (world, mm) to the detector plane, `r` its distance to the pixel centre.
///
/// A source on the plane or behind the detector (on the side away from its normal `s`) gives
/// no photons: every value is 0.
pub fn point_source_fluence(frame: &DetectorFrame, source_mm: DVec3) -> Vec<f64> {
    let f = PointSourceFluence::new(frame, source_mm);
    let w = f.columns_mm.len();
    let mut out = vec![0.0; w * f.rows_mm.len()];
    if w > 0 {
        for (j, row) in out.chunks_exact_mut(w).enumerate() {
            f.row(j, row);
        }
    }
    out
}

/// The fluence `(D/r)³` of [`point_source_fluence`], one row at a time (the same values, bit
/// for bit): what an image renderer needs without holding a W×H map.
#[derive(Debug, Clone, PartialEq)]
pub struct PointSourceFluence {
    /// `D²`, mm² (0 when the source is on or behind the detector plane: no photons).
    d2_mm2: f64,
    /// Per column, the pixel centre's in-plane x offset from the source's foot, mm.
    columns_mm: Vec<f64>,
    /// Per row, the pixel centre's in-plane y offset from the source's foot, mm.
    rows_mm: Vec<f64>,
}

impl PointSourceFluence {
    /// The fluence of `source_mm` (world, mm) over `frame`'s pixel centres.
    pub fn new(frame: &DetectorFrame, source_mm: DVec3) -> PointSourceFluence {
        let [w, h] = frame.pixels;
        let s = frame.pose.to_local(source_mm);
        let d = s.z;
        let d2_mm2 = if d > 0.0 && d.is_finite() { d * d } else { 0.0 };
        PointSourceFluence {
            d2_mm2,
            columns_mm: (0..w)
                .map(|i| frame.pixel_local(i as f64 + 0.5, 0.5).x - s.x)
                .collect(),
            rows_mm: (0..h)
                .map(|j| frame.pixel_local(0.5, j as f64 + 0.5).y - s.y)
                .collect(),
        }
    }

    /// Writes row `j`'s `W` values into `out`.
    ///
    /// # Panics
    /// When `j` is not a row or `out` is not `W` long.
    pub fn row(&self, j: usize, out: &mut [f64]) {
        assert_eq!(out.len(), self.columns_mm.len(), "one value per column");
        let d2 = self.d2_mm2;
        if d2 == 0.0 {
            out.fill(0.0);
            return;
        }
        let y = self.rows_mm[j];
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            unsafe { row_avx2(&self.columns_mm, y, d2, out) };
            return;
        }
        row_portable(&self.columns_mm, y, d2, out);
    }

    /// Pixels per row (W).
    pub fn width(&self) -> usize {
        self.columns_mm.len()
    }

    /// Rows (H).
    pub fn height(&self) -> usize {
        self.rows_mm.len()
    }
}

/// `(D/r)³ = c·√c` with `c = D²/(x² + y² + D²)` for each column `x` of a row at `y`.
#[inline(always)]
fn row_portable(columns_mm: &[f64], y: f64, d2: f64, out: &mut [f64]) {
    for (o, &x) in out.iter_mut().zip(columns_mm) {
        let c = d2 / (x * x + y * y + d2);
        *o = c * c.sqrt();
    }
}

/// [`row_portable`] compiled for AVX2 (4 lanes; the same IEEE operations, so the same bits).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn row_avx2(columns_mm: &[f64], y: f64, d2: f64, out: &mut [f64]) {
    row_portable(columns_mm, y, d2, out);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;

    fn frame(euler_deg: [f64; 3]) -> DetectorFrame {
        DetectorFrame {
            pose: Pose::from_position_euler_deg([10.0, -5.0, -300.0], euler_deg),
            pixels: [40, 30],
            pixel_pitch_mm: [0.5, 0.25],
        }
    }

    #[test]
    fn every_path_of_a_row_gives_the_scalar_bits() {
        // The AVX2 build (where the CPU has it) against the scalar expression, value for value.
        let f = frame([3.0, -4.0, 25.0]);
        let fl = PointSourceFluence::new(&f, DVec3::new(13.0, -7.0, 700.0));
        let mut out = vec![0.0; 40];
        for j in 0..30 {
            fl.row(j, &mut out);
            let y = fl.rows_mm[j];
            for (i, &x) in fl.columns_mm.iter().enumerate() {
                let c = fl.d2_mm2 / (x * x + y * y + fl.d2_mm2);
                assert_eq!(out[i].to_bits(), (c * c.sqrt()).to_bits(), "({i}, {j})");
            }
        }
    }

    #[test]
    fn corner_pixel_by_hand() {
        // Detector frame = world axes shifted to (10, −5, −300); source 1000 mm above the
        // detector centre, offset by (3, −2) mm in the plane: D = 1000.
        let f = frame([0.0, 0.0, 0.0]);
        let source = DVec3::new(13.0, -7.0, 700.0);
        let fl = point_source_fluence(&f, source);
        assert_eq!(fl.len(), 40 * 30);
        // Pixel (0, 0) centre: x = (0.5 − 20)·0.5 = −9.75, y = (0.5 − 15)·0.25 = −3.625.
        // In-plane offset to the source's foot: (−12.75, −1.625); r² = 12.75² + 1.625² + 1000².
        let r2 = 12.75f64 * 12.75 + 1.625 * 1.625 + 1e6;
        let expected = (1000.0 / r2.sqrt()).powi(3);
        assert!((fl[0] - expected).abs() < 1e-15, "{} vs {expected}", fl[0]);
        // Last pixel (39, 29): x = 9.75, y = 3.625 → offset (6.75, 5.625).
        let r2 = 6.75f64 * 6.75 + 5.625 * 5.625 + 1e6;
        let expected = (1000.0 / r2.sqrt()).powi(3);
        assert!((fl[40 * 30 - 1] - expected).abs() < 1e-15);
        // The largest value is at the pixel nearest the foot of the perpendicular, and < 1.
        assert!(fl.iter().all(|&v| v > 0.99 && v <= 1.0));
    }

    #[test]
    fn one_at_the_foot_and_invariant_under_detector_rotation() {
        // Pixel centre (20, 15) is the detector origin only for even W, H: here it is at
        // (0.25, 0.125) mm; put the source right above that centre.
        let f = frame([20.0, -35.0, 110.0]);
        let centre = f.pixel_centre_world(20, 15);
        let normal = f.pose.rotation.col(2);
        let fl = point_source_fluence(&f, centre + normal * 800.0);
        assert!((fl[15 * 40 + 20] - 1.0).abs() < 1e-15);
        // A pixel 3 columns and 4 rows away: offset (1.5, 1.0) mm, whatever the pose.
        let r2 = 1.5f64 * 1.5 + 1.0 + 800.0 * 800.0;
        let expected = (800.0 / r2.sqrt()).powi(3);
        assert!((fl[19 * 40 + 23] - expected).abs() < 1e-14);
    }

    #[test]
    fn source_behind_or_on_the_detector_gives_zero() {
        let f = frame([0.0, 0.0, 0.0]);
        for z in [-300.0, -1000.0, f64::NAN] {
            let fl = point_source_fluence(&f, DVec3::new(0.0, 0.0, z));
            assert!(fl.iter().all(|&v| v == 0.0), "z = {z}");
        }
    }
}
