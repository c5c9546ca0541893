//! Binary mode with area sampling or a focal spot: the covered fraction of every pixel.
//!
//! A pixel's covered fraction c is the weighted mean over sub-sources and pixel samples of the
//! binary ray test (crosses any object: 1, else 0). How it becomes a pixel value with the paper's
//! noise is [`crate::binary`]'s.

use glam::DVec3;
use rayon::prelude::*;

use super::Sampling;
use super::strip::{STRIP_SAMPLES, strips};
use crate::geometry::DetectorFrame;
use crate::trace::{self, Object};

/// The covered fraction of every pixel of `frame` (W×H, row-major, in [0, 1]): per pixel
/// `Σ_k w_k · (covered samples of sub-source k) / s²`, sub-sources in order.
pub fn coverage(
    frame: &DetectorFrame,
    source_mm: DVec3,
    objects: &[Object],
    sampling: &Sampling,
) -> Vec<f64> {
    let [w, h] = frame.pixels.map(|n| n as usize);
    let s = sampling.samples_per_side.max(1) as usize;
    let sources = sampling.sources(frame, source_mm);
    let strips = strips(frame, s as u32, STRIP_SAMPLES);
    let mut out = vec![0.0; w * h];
    // Strips in parallel (disjoint rows); within a strip the sub-sources in order.
    let mut chunks: Vec<&mut [f64]> = Vec::with_capacity(strips.len());
    let mut rest = &mut out[..];
    for st in &strips {
        let (a, b) = rest.split_at_mut(st.rows as usize * w);
        chunks.push(a);
        rest = b;
    }
    let per_sample = 1.0 / (s * s) as f64;
    strips
        .par_iter()
        .zip(chunks.into_par_iter())
        .for_each(|(st, chunk)| {
            let mut counts = vec![0u32; chunk.len()];
            for &(src, weight) in &sources {
                // Hits are 0 or 1: each pixel's count of covered samples is exact in integers.
                let hits = trace::render_binary(&st.frame, src, objects, 1);
                counts.fill(0);
                for (b, row) in hits.chunks_exact(w * s).enumerate() {
                    let counts_row = &mut counts[(b / s) * w..(b / s + 1) * w];
                    for (c, block) in counts_row.iter_mut().zip(row.chunks_exact(s)) {
                        *c += block.iter().map(|&v| u32::from(v)).sum::<u32>();
                    }
                }
                let k = weight * per_sample;
                for (o, &c) in chunk.iter_mut().zip(&counts) {
                    *o += k * f64::from(c);
                }
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use crate::sampling::focal_spot::sub_sources;
    use crate::scenario::SpotProfile;

    fn frame(pixels: u32, pitch: f64) -> DetectorFrame {
        DetectorFrame {
            pose: Pose::from_position_euler_deg([0.0, 0.0, -500.0], [0.0, 0.0, 0.0]),
            pixels: [pixels, pixels],
            pixel_pitch_mm: [pitch, pitch],
        }
    }

    fn point(s: u32) -> Sampling {
        Sampling {
            samples_per_side: s,
            sub_sources: vec![super::super::SubSource {
                offset_mm: [0.0, 0.0],
                weight: 1.0,
            }],
            heel: None,
            adaptive: false,
        }
    }

    #[test]
    fn one_sample_is_the_binary_image() {
        let f = frame(64, 0.5);
        let src = DVec3::new(0.3, -0.2, 1300.0);
        let objects = [Object::Sphere {
            centre_mm: DVec3::new(1.1, 2.3, 0.0),
            radius_mm: 3.0,
        }];
        let c = coverage(&f, src, &objects, &point(1));
        let b = trace::render_binary(&f, src, &objects, 1);
        assert_eq!(c, b.iter().map(|&v| f64::from(v)).collect::<Vec<_>>());
    }

    #[test]
    fn area_sampling_gives_a_disc_its_area_and_centroid() {
        // A 1 mm bead 1300 mm from the source, 500 mm in front of a detector of 0.3 mm pitch:
        // its shadow is a disc of radius 0.5·1800/1300 mm; the summed coverage is its area in
        // pixels, the coverage-weighted centroid its centre.
        let f = frame(40, 0.3);
        let centre = DVec3::new(0.437, -0.215, 0.0);
        let src = DVec3::new(0.0, 0.0, 1300.0);
        let objects = [Object::Sphere {
            centre_mm: centre,
            radius_mm: 0.5,
        }];
        let c = coverage(&f, src, &objects, &point(8));
        let radius_px = 0.5 * 1800.0 / 1300.0 / 0.3;
        let area: f64 = c.iter().sum();
        let want = std::f64::consts::PI * radius_px * radius_px;
        assert!((area - want).abs() / want < 0.01, "{area} vs {want}");
        let (mut cu, mut cv) = (0.0, 0.0);
        for (k, &v) in c.iter().enumerate() {
            cu += v * ((k % 40) as f64 + 0.5);
            cv += v * ((k / 40) as f64 + 0.5);
        }
        let truth = f.project(src, centre).unwrap();
        assert!(
            (cu / area - truth.x).abs() < 0.01,
            "u {} vs {}",
            cu / area,
            truth.x
        );
        assert!(
            (cv / area - truth.y).abs() < 0.01,
            "v {} vs {}",
            cv / area,
            truth.y
        );
        assert!(c.iter().any(|&v| v > 0.0 && v < 1.0), "partial pixels");
    }

    #[test]
    fn a_focal_spot_gives_an_edge_its_geometric_penumbra() {
        // A large cuboid whose edge x = 0 lies 600 mm from the source, 1200 mm in front of the
        // detector: a 2 mm uniform spot gives a penumbra U = 2 · 1200/600 = 4 mm = 40 px of
        // 0.1 mm, linear from 0 to 1, centred on the edge's projection from the spot centre.
        let f = DetectorFrame {
            pose: Pose::from_position_euler_deg([0.0, 0.0, -600.0], [0.0, 0.0, 0.0]),
            pixels: [120, 4],
            pixel_pitch_mm: [0.1, 0.1],
        };
        let src = DVec3::new(0.0, 0.0, 1200.0);
        let objects = [Object::Cuboid {
            pose: Pose::from_position_euler_deg([-50.0, 0.0, 600.0], [0.0, 0.0, 0.0]),
            half_size_mm: DVec3::new(50.0, 50.0, 0.001),
        }];
        let k = 16;
        let sampling = Sampling {
            samples_per_side: 4,
            sub_sources: sub_sources(SpotProfile::Uniform, 2.0, k),
            heel: None,
            adaptive: false,
        };
        let c = coverage(&f, src, &objects, &sampling);
        let row = &c[120..240];
        // The edge projects from the spot centre to x = 0 mm × 1800/1200 → u = 60 px.
        let half = row.iter().position(|&v| v < 0.5).unwrap();
        assert!((half as f64 - 60.0).abs() <= 1.0, "50 % at column {half}");
        // Penumbra: the outermost sub-sources are ±(a/2)(k − 1)/k apart; the partial pixels
        // span U·(k − 1)/k plus the pixel and sample widths.
        let partial = row.iter().filter(|&&v| v > 1e-9 && v < 1.0 - 1e-9).count() as f64;
        let u_px = 40.0 * (k - 1) as f64 / k as f64;
        assert!(
            (partial - u_px).abs() <= 2.0,
            "{partial} partial pixels, U = {u_px} px"
        );
        // Linear ramp: the value 10 px inside the penumbra from its start is ≈ 0.75.
        assert!((row[50] - 0.75).abs() < 0.04, "{}", row[50]);
        // Symmetric about the edge: c(60 − d) + c(60 + d) = 1 (u = 60 is a pixel boundary).
        for d in 0..25 {
            let sum = row[59 - d] + row[60 + d];
            assert!((sum - 1.0).abs() < 0.01, "d = {d}: {sum}");
        }
    }
}
