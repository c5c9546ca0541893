//! A bead's centre in a binary-mode image from the covered fraction of its pixels.
//!
//! A binary-mode pixel is `c · I_max + (1 − c) · n`: `c` the fraction of the pixel the objects
//! cover (0 or 1 with one ray per pixel from a point source; in between with area sampling, a
//! focal spot or motion during the pulse) and `n` the background noise, whose mean and spread the
//! image itself shows ([`Levels::of`]). Taking only the pixels at `I_max` throws the partly
//! covered edge away: the centre of a bead 3.3 pixels wide then moves in steps as the bead moves
//! across the pixel grid (pixel locking, up to 0.4 px), and a focal spot's penumbra can leave a
//! bead with too few pixels at `I_max` to pass for one. So:
//!
//! 1. a bead's **core** is its pixels covered at least half ([`Levels::core`]): the pixels whose
//!    centres the bead's outline encloses, as many as its area in pixels, however wide the
//!    penumbra;
//! 2. its **centre** is the mean of the pixel centres around the core weighted by their covered
//!    fraction ([`Levels::covered`], 0 below the noise floor), within `r + 2` pixels of the centre
//!    ([`refine`]). Summed over the pixels, the covered fraction is exactly the bead shadow's
//!    area moment, so the centre is the shadow's centroid but for the sampling of the coverage
//!    (`pixel_samples²` levels) and the noise. A pixel another bead's centre is nearer to, or
//!    that touches the core of an object that is not a bead (a mesh's shadow), is left out, so a
//!    neighbour's edge cannot pull a centre.
//!
//! When the noise is too strong for a covered fraction to be read (the span from background to
//! `I_max` below [`MIN_SPAN_SDS`] noise standard deviations, e.g. 8-bit images at 90 % noise), a
//! core is the pixels at `I_max` and the centre their mean, as in the paper's binary images.

use glam::DVec2;

use super::detect::{Blob, bead_area_px, fits_one_bead};

/// Below this many noise standard deviations between the background and `I_max`, only pixels at
/// `I_max` count as covered.
pub const MIN_SPAN_SDS: f64 = 10.0;
/// A pixel counts as partly covered from this many noise standard deviations above the
/// background ...
pub const FLOOR_SDS: f64 = 5.0;
/// ... and at least this fraction of the span (images without noise).
pub const FLOOR_FRACTION: f64 = 0.02;
/// How far beyond a bead's radius (pixels) its partly covered pixels are looked for.
pub const WINDOW_MARGIN_PX: f64 = 2.0;

/// The grey levels of one binary-mode image: its background and noise, read from the pixels
/// below `I_max` (the covered pixels of a binary image are `I_max`; the background is most of
/// the rest).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Levels {
    /// The median of the pixels below `I_max`.
    pub background: f64,
    /// The noise's standard deviation, 1.4826 × the median absolute deviation of those pixels.
    pub noise_sd: f64,
    /// The image's `I_max`.
    pub i_max: u16,
}

impl Levels {
    /// The levels of `pixels`, an image whose covered pixels are `i_max`.
    pub fn of(pixels: &[u16], i_max: u16) -> Levels {
        // Counting sort: the median and the MAD of up to 65 536 levels in one pass over the
        // pixels and two over the levels.
        let mut counts = vec![0u64; usize::from(i_max) + 1];
        for &v in pixels {
            if v < i_max {
                counts[usize::from(v)] += 1;
            }
        }
        let n: u64 = counts.iter().sum();
        if n == 0 {
            return Levels {
                background: 0.0,
                noise_sd: 0.0,
                i_max,
            };
        }
        let half = n.div_ceil(2);
        let mut below = vec![0u64; counts.len() + 1];
        for (k, c) in counts.iter().enumerate() {
            below[k + 1] = below[k] + c;
        }
        let median = below.iter().position(|&b| b >= half).map_or(0, |k| k - 1);
        // The number of pixels within `d` of the median, for the smallest d that holds half.
        let within = |d: usize| {
            let hi = (median + d).min(counts.len() - 1);
            let lo = median.saturating_sub(d);
            below[hi + 1] - below[lo]
        };
        let (mut lo, mut hi) = (0usize, counts.len());
        while lo < hi {
            let mid = (lo + hi) / 2;
            if within(mid) >= half {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        Levels {
            background: median as f64,
            noise_sd: 1.4826 * lo as f64,
            i_max,
        }
    }

    /// `I_max` less the background.
    fn span(&self) -> f64 {
        f64::from(self.i_max) - self.background
    }

    /// Whether the noise leaves only the pixels at `I_max` to be read as covered.
    pub fn only_full_pixels(&self) -> bool {
        !(self.span() > 0.0 && self.span() >= MIN_SPAN_SDS * self.noise_sd)
    }

    /// The smallest value of a pixel covered at least half (`I_max` when
    /// [`Levels::only_full_pixels`]).
    pub fn core(&self) -> u16 {
        if self.only_full_pixels() {
            return self.i_max;
        }
        (self.background + 0.5 * self.span())
            .ceil()
            .min(f64::from(self.i_max)) as u16
    }

    /// The covered fraction a pixel of value `v` shows: 0 up to the noise floor (the larger of
    /// [`FLOOR_SDS`] standard deviations and [`FLOOR_FRACTION`] of the span above the
    /// background), then `(v − background) / span` up to 1. With [`Levels::only_full_pixels`],
    /// 1 at `I_max` and 0 below.
    pub fn covered(&self, v: u16) -> f64 {
        if self.only_full_pixels() {
            return if v >= self.i_max { 1.0 } else { 0.0 };
        }
        let above = f64::from(v) - self.background;
        if above < (FLOOR_SDS * self.noise_sd).max(FLOOR_FRACTION * self.span()) {
            return 0.0;
        }
        (above / self.span()).min(1.0)
    }
}

/// Moves the centre of every blob of one bead (`blobs[k].1`, of label `blobs[k].0` in `labels`,
/// [`super::detect::components_at_least`] at [`Levels::core`]) to the mean of the pixel centres
/// within `radius_px + `[`WINDOW_MARGIN_PX`] of it weighted by [`Levels::covered`], twice (the
/// second time around the first's centre). A pixel counts for the blob whose centre is nearest
/// (ties: the earlier blob) if it is one of the blob's own label's pixels, or unlabelled and not
/// touching the pixels of an object that is not a bead (a mesh's shadow, an unresolved blob).
/// Blobs that do not fit one bead ([`fits_one_bead`]) are left as they are, as is everything
/// when [`Levels::only_full_pixels`].
pub fn refine(
    blobs: &mut [(u32, Blob)],
    labels: &[u32],
    pixels: &[u16],
    width: usize,
    levels: &Levels,
    radius_px: f64,
) {
    if levels.only_full_pixels() || width == 0 || !(radius_px > 0.0 && radius_px.is_finite()) {
        return;
    }
    let height = pixels.len() / width;
    let reach = radius_px + WINDOW_MARGIN_PX;
    let area = bead_area_px(radius_px);
    let beads: Vec<usize> = (0..blobs.len())
        .filter(|&k| fits_one_bead(blobs[k].1.area, area))
        .collect();
    let max_label = labels.iter().copied().max().unwrap_or(0) as usize;
    let mut is_bead = vec![false; max_label + 1];
    for &k in &beads {
        if let Some(b) = is_bead.get_mut(blobs[k].0 as usize) {
            *b = true;
        }
    }
    let admitted = |p: usize, own: u32| {
        if labels[p] == own {
            return true;
        }
        if labels[p] != 0 {
            return false;
        }
        let (i, j) = ((p % width) as i64, (p / width) as i64);
        for dj in -1..=1 {
            for di in -1..=1 {
                let (x, y) = (i + di, j + dj);
                if x < 0 || y < 0 || x >= width as i64 || y >= height as i64 {
                    continue;
                }
                let l = labels[y as usize * width + x as usize];
                if l != 0 && l != own && !is_bead[l as usize] {
                    return false;
                }
            }
        }
        true
    };
    for _ in 0..2 {
        // (pixel, squared distance, blob) for every pixel within reach of a bead's centre.
        let mut near: Vec<(usize, f64, usize)> = Vec::new();
        for &k in &beads {
            let (own, blob) = &blobs[k];
            let c = blob.centroid;
            let j0 = (c.y - reach).floor().max(0.0) as usize;
            let j1 = ((c.y + reach).ceil().max(0.0) as usize).min(height);
            let i0 = (c.x - reach).floor().max(0.0) as usize;
            let i1 = ((c.x + reach).ceil().max(0.0) as usize).min(width);
            for j in j0..j1 {
                for i in i0..i1 {
                    let d2 = (DVec2::new(i as f64 + 0.5, j as f64 + 0.5) - c).length_squared();
                    let p = j * width + i;
                    if d2 <= reach * reach && admitted(p, *own) {
                        near.push((p, d2, k));
                    }
                }
            }
        }
        near.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
        near.dedup_by_key(|e| e.0);
        let mut sums = vec![(0.0f64, DVec2::ZERO); blobs.len()];
        for &(p, _, k) in &near {
            let w = levels.covered(pixels[p]);
            if w > 0.0 {
                let q = DVec2::new((p % width) as f64 + 0.5, (p / width) as f64 + 0.5);
                sums[k].0 += w;
                sums[k].1 += w * q;
            }
        }
        for &k in &beads {
            let (w, m) = sums[k];
            if w > 0.0 {
                blobs[k].1.centroid = m / w;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::components_at_least;

    /// A disc of `radius_px` at `centre` on a `side`² image, each pixel's covered fraction from
    /// `n × n` samples blended with a background of `background` (no noise), `i_max` 65535.
    fn disc(side: usize, centre: DVec2, radius_px: f64, n: usize, background: u16) -> Vec<u16> {
        let mut img = vec![background; side * side];
        for j in 0..side {
            for i in 0..side {
                let mut inside = 0;
                for b in 0..n {
                    for a in 0..n {
                        let q = DVec2::new(
                            i as f64 + (a as f64 + 0.5) / n as f64,
                            j as f64 + (b as f64 + 0.5) / n as f64,
                        );
                        if (q - centre).length() <= radius_px {
                            inside += 1;
                        }
                    }
                }
                let c = inside as f64 / (n * n) as f64;
                let v = c * 65535.0 + (1.0 - c) * f64::from(background);
                img[j * side + i] = (v + 0.5).min(65535.0) as u16;
            }
        }
        img
    }

    fn centre(img: &[u16], side: usize, radius_px: f64) -> DVec2 {
        let levels = Levels::of(img, 65535);
        let (labels, blobs) = components_at_least(img, side, levels.core());
        let mut blobs: Vec<(u32, Blob)> = blobs
            .into_iter()
            .enumerate()
            .map(|(k, b)| (k as u32 + 1, b))
            .collect();
        assert_eq!(blobs.len(), 1);
        refine(&mut blobs, &labels, img, side, &levels, radius_px);
        blobs[0].1.centroid
    }

    #[test]
    fn levels_are_the_median_and_the_spread_of_the_background() {
        // 90 pixels at 100 and 101 alternately, 10 at I_max: median 100, MAD 0 or 1.
        let mut img: Vec<u16> = (0..90).map(|k| 100 + (k % 2) as u16).collect();
        img.extend([4095; 10]);
        let l = Levels::of(&img, 4095);
        assert_eq!(l.background, 100.0);
        assert!(l.noise_sd <= 1.4826 + 1e-12);
        assert_eq!(l.core(), 2098);
        assert_eq!(l.covered(4095), 1.0);
        assert_eq!(l.covered(101), 0.0);
        // Background 3686 ± 60 under I_max 4095 (12 bits at 90 % noise): too noisy to read a
        // fraction, only I_max counts.
        let noisy: Vec<u16> = (0..1000).map(|k| 3600 + (k % 173) as u16).collect();
        let l = Levels::of(&noisy, 4095);
        assert!(l.only_full_pixels(), "{l:?}");
        assert_eq!(l.core(), 4095);
    }

    #[test]
    fn area_sampled_discs_are_centred_within_a_twentieth_of_a_pixel_where_full_pixels_lock() {
        // Bead images 3.3 px wide (radius 1.65 px) at 40 sub-pixel offsets, 4 × 4 samples per
        // pixel: the covered-fraction centre stays within 0.05 px; the I_max pixels alone (what
        // the paper's binary images give) are off by more than 0.15 px somewhere.
        let (side, r) = (16, 1.65);
        let (mut worst, mut worst_full) = (0.0f64, 0.0f64);
        for k in 0..40 {
            let c = DVec2::new(8.0 + 0.025 * k as f64, 7.7 + 0.0193 * k as f64);
            let img = disc(side, c, r, 4, 0);
            worst = worst.max((centre(&img, side, r) - c).length());
            let full = crate::detect::blobs(&img, side, 65535);
            if let Some(b) = full.first() {
                worst_full = worst_full.max((b.centroid - c).length());
            }
        }
        assert!(worst < 0.05, "covered-fraction centre off by {worst} px");
        assert!(
            worst_full > 0.15,
            "I_max pixels alone off by only {worst_full} px"
        );
    }

    #[test]
    fn a_neighbours_edge_does_not_pull_a_centre() {
        // Two beads 4.2 px apart, each with its own core: each centre within 0.06 px.
        let (side, r) = (20, 1.65);
        let (a, b) = (DVec2::new(7.8, 10.3), DVec2::new(12.0, 10.3));
        let (ia, ib) = (disc(side, a, r, 4, 0), disc(side, b, r, 4, 0));
        let img: Vec<u16> = ia.iter().zip(&ib).map(|(x, y)| (*x).max(*y)).collect();
        let levels = Levels::of(&img, 65535);
        let (labels, blobs) = components_at_least(&img, side, levels.core());
        assert_eq!(blobs.len(), 2);
        let mut blobs: Vec<(u32, Blob)> = blobs
            .into_iter()
            .enumerate()
            .map(|(k, b)| (k as u32 + 1, b))
            .collect();
        refine(&mut blobs, &labels, &img, side, &levels, r);
        assert!(
            (blobs[0].1.centroid - a).length() < 0.06,
            "{:?}",
            blobs[0].1.centroid
        );
        assert!(
            (blobs[1].1.centroid - b).length() < 0.06,
            "{:?}",
            blobs[1].1.centroid
        );
    }

    #[test]
    fn sharp_images_keep_the_centres_of_their_full_pixels() {
        let (side, r) = (16, 1.65);
        let c = DVec2::new(8.13, 7.91);
        let img = disc(side, c, r, 1, 0);
        let before = crate::detect::blobs(&img, side, 65535)[0].centroid;
        assert_eq!(centre(&img, side, r), before);
    }
}
