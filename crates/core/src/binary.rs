//! Binary-mode image formation, the paper's images: every object is opaque, a pixel whose ray
//! crosses one is `I_max`, every other pixel carries the paper's background noise. This is the one
//! home of how a binary image forms:
//!
//! - one ray per pixel centre from a point source: the binary projection
//!   ([`crate::trace::render_binary`]) with the noise field overlaid ([`sharp_noisy_image`]);
//! - with area sampling or a focal spot: the covered fraction c of every pixel
//!   ([`crate::sampling::coverage`]) blended with the pixel's noise sample n ([`blend`]):
//!   `round(c · I_max + (1 − c) · n)`, half up. With one ray per pixel and a point source c is 0
//!   or 1 and this is the sharp image, byte for byte;
//! - a frame of a sequence whose objects move during its pulse: c is the mean of the covered
//!   fractions at the pulse's poses ([`noisy_image_in_motion`]), blended the same way.

use glam::DVec3;

use crate::geometry::DetectorFrame;
use crate::noise::{self, NoiseKey};
use crate::sampling::strip::window;
use crate::sampling::{Sampling, coverage};
use crate::trace::{self, Object};

/// One noisy binary-mode image of `objects` on `frame` from the spot centred at `source_mm`, as
/// `sampling` says: [`sharp_noisy_image`] for a point source and one ray per pixel, else the
/// covered fractions blended with the noise ([`blend`]).
pub fn noisy_image(
    frame: &DetectorFrame,
    source_mm: DVec3,
    objects: &[Object],
    sampling: &Sampling,
    noise_level: f64,
    i_max: u16,
    key: &NoiseKey,
) -> Vec<u16> {
    if sampling.is_point() {
        return sharp_noisy_image(frame, source_mm, objects, noise_level, i_max, key);
    }
    let [w, h] = frame.pixels.map(|n| n as usize);
    let (covered, field) = rayon::join(
        || coverage::coverage(frame, source_mm, objects, sampling),
        || noise::noise_field(w, h, noise_level, i_max, key),
    );
    blended(&covered, &field, i_max)
}

/// The objects of a frame whose objects move during its pulse ([`noisy_image_in_motion`]).
#[derive(Clone, Copy)]
pub struct Pulse<'p, 'a> {
    /// The objects that stand still.
    pub still: &'p [Object<'a>],
    /// The others at each of the pulse's poses, in time order.
    pub moving: &'p [Vec<Object<'a>>],
}

/// One noisy binary-mode image of a frame whose objects move during its pulse: `still` are the
/// objects that stand still, `moving[k]` the others at the pulse's pose k (in time order, equal
/// weights). A pixel's covered fraction is the mean of its covered fractions at those poses
/// ([`coverage::coverage`], each as `sampling` says, summed in pose order and divided by their
/// number), blended with the noise ([`blend`]) as in [`noisy_image`].
///
/// Only the pixels that some moving object can reach at some pose (the union of their shadows'
/// bounding rectangles from every sub-source, grown by a pixel) are traced at every pose; the
/// others see the still objects alone, the same at every pose, and are traced once.
pub fn noisy_image_in_motion(
    frame: &DetectorFrame,
    source_mm: DVec3,
    pulse: Pulse,
    sampling: &Sampling,
    noise_level: f64,
    i_max: u16,
    key: &NoiseKey,
) -> Vec<u16> {
    let Pulse { still, moving } = pulse;
    let [w, h] = frame.pixels.map(|n| n as usize);
    let (covered, field) = rayon::join(
        || {
            let mut covered = coverage::coverage(frame, source_mm, still, sampling);
            let Some((i0, i1, j0, j1)) = reach(frame, source_mm, moving, sampling) else {
                return covered;
            };
            let (ww, wh) = (i1 - i0, j1 - j0);
            let part = window(frame, i0, j0, ww, wh, 1);
            let mut sum = vec![0.0; (ww * wh) as usize];
            for pose in moving {
                let objects: Vec<Object> = still.iter().chain(pose).cloned().collect();
                let c = coverage::coverage(&part, source_mm, &objects, sampling);
                sum.iter_mut().zip(&c).for_each(|(s, c)| *s += c);
            }
            let k = moving.len().max(1) as f64;
            for (row, sums) in sum.chunks_exact(ww as usize).enumerate() {
                let start = (j0 as usize + row) * w + i0 as usize;
                for (c, s) in covered[start..start + ww as usize].iter_mut().zip(sums) {
                    *c = s / k;
                }
            }
            covered
        },
        || noise::noise_field(w, h, noise_level, i_max, key),
    );
    blended(&covered, &field, i_max)
}

/// The pixel rectangle the `moving` objects can reach at any pose from any sub-source, grown by
/// one pixel and clipped to the detector; `None` when they miss it.
fn reach(
    frame: &DetectorFrame,
    source_mm: DVec3,
    moving: &[Vec<Object>],
    sampling: &Sampling,
) -> Option<(u32, u32, u32, u32)> {
    let [w, h] = frame.pixels;
    let mut out: Option<(u32, u32, u32, u32)> = None;
    for (src, _) in sampling.sources(frame, source_mm) {
        for object in moving.iter().flatten() {
            if let Some((i0, i1, j0, j1)) = trace::shadow_bounds(frame, src, object) {
                out = Some(match out {
                    None => (i0, i1, j0, j1),
                    Some((a0, a1, b0, b1)) => (a0.min(i0), a1.max(i1), b0.min(j0), b1.max(j1)),
                });
            }
        }
    }
    out.map(|(i0, i1, j0, j1)| {
        (
            i0.saturating_sub(1),
            (i1 + 1).min(w),
            j0.saturating_sub(1),
            (j1 + 1).min(h),
        )
    })
    .filter(|&(i0, i1, j0, j1)| i1 > i0 && j1 > j0)
}

/// One noisy binary-mode image from one ray per pixel centre: the clean projection
/// ([`trace::render_binary`]) and the noise field ([`noise::noise_field`]) computed at the same
/// time on the rayon pool, then overlaid. Byte for byte the image of `render_binary` followed by
/// [`noise::add_noise`], in less wall time when cores are free (the projection is
/// single-threaded, the noise row-parallel).
pub fn sharp_noisy_image(
    frame: &DetectorFrame,
    source_mm: DVec3,
    objects: &[Object],
    noise_level: f64,
    i_max: u16,
    key: &NoiseKey,
) -> Vec<u16> {
    let [w, h] = frame.pixels.map(|n| n as usize);
    let (clean, mut field) = rayon::join(
        || trace::render_binary(frame, source_mm, objects, i_max),
        || noise::noise_field(w, h, noise_level, i_max, key),
    );
    noise::overlay(&clean, &mut field);
    field
}

/// Every pixel's covered fraction blended with its noise sample ([`blend`]).
fn blended(covered: &[f64], field: &[u16], i_max: u16) -> Vec<u16> {
    covered
        .iter()
        .zip(field)
        .map(|(&c, &n)| blend(c, n, i_max))
        .collect()
}

/// A pixel value from its covered fraction `c` and its background noise sample `n`:
/// `round(c · i_max + (1 − c) · n)`, half up, within `0..=i_max`.
pub fn blend(c: f64, n: u16, i_max: u16) -> u16 {
    let v = c * f64::from(i_max) + (1.0 - c) * f64::from(n);
    if !(v > 0.0) {
        0
    } else if v >= f64::from(i_max) {
        i_max
    } else {
        (v + 0.5) as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use crate::sampling::SubSource;

    #[test]
    fn one_sample_from_a_point_is_the_papers_image() {
        let frame = DetectorFrame {
            pose: Pose::from_position_euler_deg([0.0, 0.0, -500.0], [0.0, 0.0, 0.0]),
            pixels: [64, 64],
            pixel_pitch_mm: [0.5, 0.5],
        };
        let src = DVec3::new(0.3, -0.2, 1300.0);
        let objects = [Object::Sphere {
            centre_mm: DVec3::new(1.1, 2.3, 0.0),
            radius_mm: 3.0,
        }];
        let key = NoiseKey::derive(1, 0, 0, "e", "d");
        // The paper's image: the binary projection with the noise added on its background.
        let mut paper = trace::render_binary(&frame, src, &objects, 4095);
        noise::add_noise(&mut paper, 64, 0.3, 4095, &key);
        assert_eq!(
            sharp_noisy_image(&frame, src, &objects, 0.3, 4095, &key),
            paper
        );
        // The blended path with one sample from a point gives the same bytes.
        let point = Sampling {
            samples_per_side: 1,
            sub_sources: vec![SubSource {
                offset_mm: [0.0, 0.0],
                weight: 1.0,
            }],
            heel: None,
            adaptive: false,
        };
        let [w, h] = [64, 64];
        let covered = coverage::coverage(&frame, src, &objects, &point);
        let field = noise::noise_field(w, h, 0.3, 4095, &key);
        let blended: Vec<u16> = covered
            .iter()
            .zip(&field)
            .map(|(&c, &n)| blend(c, n, 4095))
            .collect();
        assert_eq!(blended, paper);
    }

    #[test]
    fn blend_mixes_cover_and_noise() {
        assert_eq!(blend(0.0, 17, 4095), 17);
        assert_eq!(blend(1.0, 17, 4095), 4095);
        assert_eq!(blend(0.5, 1, 4095), 2048);
        assert_eq!(blend(0.25, 0, 100), 25);
    }
}
