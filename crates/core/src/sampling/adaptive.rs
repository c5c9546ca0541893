//! Adaptive sampling (attenuation mode): which pixels need all their rays.
//!
//! A pixel's value is the mean of what its rays see (`s × s` pixel samples from each of `k × k`
//! focal-spot sub-sources). Where the path lengths vary smoothly over the pixel and its penumbra,
//! that mean equals the value of the one ray to the pixel centre from the spot's centre up to a
//! second-order term: the sample points are placed symmetrically about that ray, so the
//! first-order terms cancel, and what is left is `½ (∂²V/∂u²·σ_u² + ∂²V/∂v²·σ_v²)`, with σ² the
//! variance of where the rays cross the scene, in pixels ([`Footprint`]). Only pixels near an
//! edge or a kink need every ray.
//!
//! [`refine_mask`] marks those pixels from the sharp image (one ray per pixel centre from the
//! spot's centre, which the image needs anyway for the truth):
//!
//! 1. **Edges**: pixels where some solid's shadow starts or ends (given by the caller), and every
//!    pixel of a small solid's shadow rectangle (beads: a bead narrower than the pixel spacing could
//!    fall between pixel centres).
//! 2. **Curvature**: pixels whose second-order estimate
//!    `e = ½ (|V(u+1) − 2V(u) + V(u−1)|·σ_u² + |V(v+1) − 2V(v) + V(v−1)|·σ_v²)` (at the border,
//!    the second difference of the inner neighbour) exceeds
//!    [`TOLERANCE_NOISE_SD`] times the pixel's quantum-noise standard deviation: `√Q` for the
//!    quanta `Q`, `E/√Q` for the energy `E`. A kink shows up in the second difference as well.
//! 3. Both grown by the footprint's reach, rounded down, plus one pixel ([`Footprint::grow_px`]):
//!    a pixel is refined when an edge or a curved pixel lies within the reach of its rays.
//!
//! Every other pixel keeps its sharp value. The bound is tested against full sampling on the
//! realistic knee (`tests/sampling.rs`): the largest difference over every pixel is stated there
//! and in docs/src/physics/unsharpness.md.

/// The error a pixel left to one ray may have, estimated, as a fraction of its quantum-noise
/// standard deviation.
pub const TOLERANCE_NOISE_SD: f64 = 0.01;

/// Detector pixels per side of the tiles the refined pixels are traced in.
pub const TILE_PX: u32 = 16;

/// Where the rays of a pixel cross the scene, relative to the ray to its centre from the spot's
/// centre, in pixels of the detector (at the projection of the scene onto the detector from the
/// spot's centre): per axis (r, c) its reach (largest offset) and its variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Largest offset along r and c, px.
    pub reach_px: [f64; 2],
    /// Variance of the offsets along r and c, px².
    pub variance_px2: [f64; 2],
}

impl Footprint {
    /// The footprint of `s × s` pixel samples and sub-sources at `offsets_mm` (along the
    /// detector's r and c, mm) with `weights` (summing to 1), for pixels of `pitch_mm` and a scene
    /// whose points lie at most `depth_ratio` = (D − z)/z from the spot (z the distance of a point
    /// from the spot's plane, D the detector's): a sub-source offset o moves the ray's crossing of
    /// depth z, projected onto the detector, by `o·(D − z)/z`.
    pub fn new(
        samples_per_side: u32,
        offsets_mm: &[[f64; 2]],
        weights: &[f64],
        pitch_mm: [f64; 2],
        depth_ratio: f64,
    ) -> Footprint {
        let s = f64::from(samples_per_side.max(1));
        let ratio = depth_ratio.max(0.0);
        let pixel_reach = (s - 1.0) / (2.0 * s);
        let pixel_variance = (s * s - 1.0) / (12.0 * s * s);
        let mut out = Footprint {
            reach_px: [pixel_reach; 2],
            variance_px2: [pixel_variance; 2],
        };
        for axis in 0..2 {
            let scale = ratio / pitch_mm[axis];
            let mean: f64 = offsets_mm
                .iter()
                .zip(weights)
                .map(|(o, w)| w * o[axis])
                .sum();
            let reach = offsets_mm
                .iter()
                .map(|o| (o[axis] * scale).abs())
                .fold(0.0, f64::max);
            let variance: f64 = offsets_mm
                .iter()
                .zip(weights)
                .map(|(o, w)| w * ((o[axis] - mean) * scale).powi(2))
                .sum();
            out.reach_px[axis] += reach;
            out.variance_px2[axis] += variance;
        }
        out
    }

    /// How far (whole pixels) a marked pixel's influence reaches: the reach rounded down, plus
    /// one. A pixel's rays meet the scene within `reach` of its centre (per axis); an edge point
    /// there lies in a cell of four pixel centres whose boundary the edge crosses, so a corner of
    /// that cell is marked, within one pixel per axis of the point.
    pub fn grow_px(&self) -> [usize; 2] {
        self.reach_px.map(|r| r.floor() as usize + 1)
    }
}

/// The pixels (W×H, row-major) that need all their rays: see the module docs. `edges` marks the
/// pixels where a shadow starts or ends; `quanta` and `energy_kev` are the sharp expected image
/// at the exposure being rendered.
pub fn refine_mask(
    width: usize,
    height: usize,
    edges: &[bool],
    quanta: &[f64],
    energy_kev: &[f64],
    footprint: &Footprint,
    tolerance_noise_sd: f64,
) -> Vec<bool> {
    let mut seed = edges.to_vec();
    let [vu, vv] = footprint.variance_px2;
    for j in 0..height {
        for i in 0..width {
            let p = j * width + i;
            if seed[p] {
                continue;
            }
            let q = quanta[p];
            let curvature = |image: &[f64]| {
                let at = |ii: usize, jj: usize| image[jj * width + ii];
                // The second difference centred on the pixel, or on its inner neighbour at the
                // image's border; none along an axis shorter than 3 pixels.
                let second = |n: usize, k: usize, f: &dyn Fn(usize) -> f64| {
                    if n < 3 {
                        return 0.0;
                    }
                    let c = k.clamp(1, n - 2);
                    (f(c - 1) - 2.0 * f(c) + f(c + 1)).abs()
                };
                0.5 * (second(width, i, &|ii| at(ii, j)) * vu
                    + second(height, j, &|jj| at(i, jj)) * vv)
            };
            let noise_sd = q.max(0.0).sqrt();
            let energy_sd = if q > 0.0 {
                energy_kev[p] / noise_sd
            } else {
                0.0
            };
            seed[p] = curvature(quanta) > tolerance_noise_sd * noise_sd
                || curvature(energy_kev) > tolerance_noise_sd * energy_sd;
        }
    }
    grow(&seed, width, height, footprint.grow_px())
}

/// `mask` grown by `by` pixels along each axis (a box of half-sizes `by`), W×H row-major.
fn grow(mask: &[bool], width: usize, height: usize, by: [usize; 2]) -> Vec<bool> {
    // Along rows, then along columns: a pixel is set when a set pixel lies within the half-size.
    let along = |src: &[bool], n: usize, stride: usize, lines: usize, step: usize, reach: usize| {
        let mut out = vec![false; src.len()];
        for line in 0..lines {
            let base = line * step;
            // Distance to the last set pixel seen, forwards then backwards.
            let mut since = usize::MAX;
            for k in 0..n {
                let p = base + k * stride;
                since = if src[p] { 0 } else { since.saturating_add(1) };
                out[p] = since <= reach;
            }
            since = usize::MAX;
            for k in (0..n).rev() {
                let p = base + k * stride;
                since = if src[p] { 0 } else { since.saturating_add(1) };
                out[p] |= since <= reach;
            }
        }
        out
    };
    let rows = along(mask, width, 1, height, width, by[0]);
    along(&rows, height, width, width, 1, by[1])
}

/// The tiles of [`TILE_PX`] pixels that hold a refined pixel, as (first column, first row),
/// rows then columns ascending.
pub fn tiles(mask: &[bool], width: usize, height: usize) -> Vec<(u32, u32)> {
    let t = TILE_PX as usize;
    let mut out = Vec::new();
    for j0 in (0..height).step_by(t) {
        for i0 in (0..width).step_by(t) {
            let any = (j0..(j0 + t).min(height))
                .any(|j| mask[j * width + i0..j * width + (i0 + t).min(width)].contains(&true));
            if any {
                out.push((i0 as u32, j0 as u32));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn footprint_of_pixel_samples_and_a_uniform_spot() {
        // 2 × 2 samples: offsets ±¼ px, variance 1/16; a 3-point uniform spot of 1.2 mm has
        // offsets −0.4, 0, 0.4 mm, variance 0.32/3 mm²; at a depth ratio 0.5 and pitch 0.2 mm
        // that is ±1 px and variance (2/3) px².
        let offsets: Vec<[f64; 2]> = (0..9)
            .map(|k| [0.4 * (k % 3) as f64 - 0.4, 0.4 * (k / 3) as f64 - 0.4])
            .collect();
        let f = Footprint::new(2, &offsets, &[1.0 / 9.0; 9], [0.2, 0.2], 0.5);
        for axis in 0..2 {
            assert!((f.reach_px[axis] - 1.25).abs() < 1e-12);
            assert!((f.variance_px2[axis] - (1.0 / 16.0 + 2.0 / 3.0)).abs() < 1e-12);
        }
        assert_eq!(f.grow_px(), [2, 2]);
        // A point source, one ray: nothing to reach.
        let point = Footprint::new(1, &[[0.0, 0.0]], &[1.0], [0.2, 0.2], 0.5);
        assert_eq!(point.reach_px, [0.0, 0.0]);
        assert_eq!(point.variance_px2, [0.0, 0.0]);
    }

    #[test]
    fn growing_a_mask_sets_the_box_around_each_pixel() {
        let (w, h) = (9, 7);
        let mut mask = vec![false; w * h];
        mask[3 * w + 4] = true;
        let grown = grow(&mask, w, h, [2, 1]);
        for j in 0..h {
            for i in 0..w {
                let want = (2..=6).contains(&i) && (2..=4).contains(&j);
                assert_eq!(grown[j * w + i], want, "({i}, {j})");
            }
        }
    }

    /// An image linear in u and v needs no refinement, a gentle curvature neither; a kink does,
    /// and so do its neighbours within the footprint's reach.
    #[test]
    fn linear_and_gently_curved_images_stay_sharp_a_kink_does_not() {
        let (w, h) = (40, 30);
        let f = Footprint {
            reach_px: [1.2, 1.2],
            variance_px2: [0.5, 0.5],
        };
        let edges = vec![false; w * h];
        let image = |v: &dyn Fn(f64, f64) -> f64| -> Vec<f64> {
            (0..w * h)
                .map(|p| v((p % w) as f64, (p / w) as f64))
                .collect()
        };
        let linear = image(&|u, v| 10_000.0 + 50.0 * u - 30.0 * v);
        assert!(
            !refine_mask(w, h, &edges, &linear, &linear, &f, TOLERANCE_NOISE_SD).contains(&true)
        );
        // Curvature 0.1 count/px² gives an estimate of 0.05, far below 0.01 × √10⁴ = 1.
        let curved = image(&|u, v| 10_000.0 + 0.05 * (u - 20.0).powi(2) + 0.0 * v);
        assert!(
            !refine_mask(w, h, &edges, &curved, &curved, &f, TOLERANCE_NOISE_SD).contains(&true)
        );
        // A kink of slope 40 counts/px at u = 20.5: second differences of 20 at columns 20, 21.
        let kink = image(&|u, _| 10_000.0 + 40.0 * (u - 20.5).max(0.0));
        let mask = refine_mask(w, h, &edges, &kink, &kink, &f, TOLERANCE_NOISE_SD);
        for i in 0..w {
            // Columns 20 and 21 curve; grown by ⌊1.2⌋ + 1 = 2: columns 18 to 23.
            assert_eq!(mask[5 * w + i], (18..=23).contains(&i), "column {i}");
        }
    }

    #[test]
    fn tiles_hold_the_refined_pixels() {
        let (w, h) = (40, 20);
        let mut mask = vec![false; w * h];
        mask[3 * w + 35] = true;
        mask[17 * w + 2] = true;
        assert_eq!(tiles(&mask, w, h), vec![(32, 0), (0, 16)]);
    }
}
