//! A detector traced at s× its resolution, one strip of pixel rows at a time: the fine frame of
//! each strip has s×s pixels per pixel of the detector, so its pixel centres are the pixel
//! samples `(i + (a + ½)/s, j + (b + ½)/s)`.

use std::ops::Range;

use glam::DVec3;

use crate::geometry::{DetectorFrame, Pose};

/// Fine samples per strip the tracing holds at a time (about 4 million: 8 bytes each for a
/// path-length or expected-value buffer, 32 MB).
pub const STRIP_SAMPLES: usize = 1 << 22;

/// One strip: rows of the detector and the fine frame that samples them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Strip {
    /// First row of the detector in this strip.
    pub first_row: u32,
    /// Number of detector rows.
    pub rows: u32,
    /// The strip's fine frame: `[W·s, rows·s]` pixels of pitch `pitch / s`, same axes.
    pub frame: DetectorFrame,
}

impl Strip {
    /// The detector rows of the strip.
    pub fn row_range(&self) -> Range<u32> {
        self.first_row..self.first_row + self.rows
    }
}

/// The strips covering `frame` at `s` rays per pixel side, each holding at most
/// `max_samples` fine samples (at least one detector row).
pub fn strips(frame: &DetectorFrame, s: u32, max_samples: usize) -> Vec<Strip> {
    let [w, h] = frame.pixels;
    let s = s.max(1);
    let per_row = (w as usize) * (s as usize) * (s as usize);
    let rows = (max_samples / per_row.max(1)).clamp(1, h.max(1) as usize) as u32;
    let mut out = Vec::new();
    let mut first = 0;
    while first < h {
        let n = rows.min(h - first);
        out.push(Strip {
            first_row: first,
            rows: n,
            frame: window(frame, 0, first, w, n, s),
        });
        first += n;
    }
    out
}

/// The fine frame of a window of `frame`: columns `i0 … i0 + w`, rows `j0 … j0 + h`, at `s`
/// rays per pixel side (`[w·s, h·s]` pixels of pitch `pitch / s`, the same axes): its pixel
/// centres are the pixel samples of those pixels.
pub fn window(frame: &DetectorFrame, i0: u32, j0: u32, w: u32, h: u32, s: u32) -> DetectorFrame {
    let [fw, fh] = frame.pixels;
    let [px, py] = frame.pixel_pitch_mm;
    let centre = DVec3::new(
        (i0 as f64 + w as f64 / 2.0 - fw as f64 / 2.0) * px,
        (j0 as f64 + h as f64 / 2.0 - fh as f64 / 2.0) * py,
        0.0,
    );
    DetectorFrame {
        pose: Pose {
            position_mm: frame.pose.to_world(centre),
            rotation: frame.pose.rotation,
        },
        pixels: [w * s, h * s],
        pixel_pitch_mm: [px / s as f64, py / s as f64],
    }
}

/// Sums each s×s block of a fine strip image (`[W·s, rows·s]`, row-major) into `out` (`[W,
/// rows]`) times `weight`, adding to what is there: per pixel `out += weight · Σ_b Σ_a fine`,
/// the samples summed row by row from 0 (a fixed order).
pub fn add_blocks(fine: &[f64], w: usize, s: usize, weight: f64, out: &mut [f64]) {
    let fine_w = w * s;
    for (j, row) in out.chunks_mut(w).enumerate() {
        for (i, o) in row.iter_mut().enumerate() {
            let mut sum = 0.0;
            for b in 0..s {
                let start = (j * s + b) * fine_w + i * s;
                for &v in &fine[start..start + s] {
                    sum += v;
                }
            }
            *o += weight * sum;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strip_pixel_centres_are_the_pixel_samples() {
        let frame = DetectorFrame {
            pose: Pose::from_position_euler_deg([3.0, -2.0, -500.0], [4.0, -7.0, 30.0]),
            pixels: [13, 11],
            pixel_pitch_mm: [0.3, 0.25],
        };
        let s = 3;
        let strips = strips(&frame, s, 13 * 9 * 4);
        assert_eq!(strips.len(), 3, "4 + 4 + 3 rows");
        assert_eq!(strips[2].rows, 3);
        for st in &strips {
            for jj in 0..st.rows * s {
                for ii in 0..13 * s {
                    let fine = st.frame.pixel_centre_world(ii, jj);
                    let u = (ii as f64 + 0.5) / s as f64;
                    let v = st.first_row as f64 + (jj as f64 + 0.5) / s as f64;
                    let want = frame.pose.to_world(frame.pixel_local(u, v));
                    assert!((fine - want).length() < 1e-12, "{fine} vs {want}");
                }
            }
        }
    }

    #[test]
    fn blocks_sum_in_order() {
        // 2×1 detector pixels, s = 2: fine 4×2.
        let fine = [1.0, 2.0, 10.0, 20.0, 3.0, 4.0, 30.0, 40.0];
        let mut out = vec![1.0, 1.0];
        add_blocks(&fine, 2, 2, 0.25, &mut out);
        assert_eq!(out, vec![1.0 + 2.5, 1.0 + 25.0]);
    }
}
