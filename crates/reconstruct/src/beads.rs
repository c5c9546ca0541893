//! Finding beads in an attenuation-mode image, sharp or blurred, over soft tissue, bone edges and
//! plates, and never in the metal shadow.
//!
//! The detector works on the attenuation image ([`super::density`]), where a bead's attenuation
//! adds to whatever lies behind it, so its contrast does not depend on the background.
//!
//! 1. **Noise** per 32 × 32 tile: the median absolute difference of horizontal neighbours,
//!    scaled to a standard deviation (robust to the few edges and beads in a tile).
//! 2. **Matched filter** at the bead's expected scale (radius `r` pixels, from the known bead
//!    diameter, nominal magnification and pitch): the mean of a box inside the bead's disc
//!    (half-size `⌊r/√2⌋`, at least 1) minus the mean of a square ring around it (between
//!    half-sizes `⌈r⌉ + 2` and `⌈r⌉ + 4`, clear of the bead and of its blur), by integral images.
//! 3. **Candidates**: local maxima of the response within the bead's radius, at least
//!    [`MIN_SNR`] times the response's noise (two beads whose images do not overlap are two
//!    candidates, even inside each other's window): tile noise × √(1/N_box + 1/N_ring) for white
//!    noise, times the image's correlation factor (the median over tiles of the response's own
//!    robust spread against that prediction, at least 1), which a detector PSF raises. The
//!    maximum is taken of the response itself, not of the signal-to-noise ratio: the tile noise
//!    steps at tile borders (a tile across an oblique plate's gradient reads the gradient as
//!    noise, ten times a flat tile's), and the ratio's maximum would then sit on the quiet side
//!    of the border, pixels off the bead.
//! 4. **Shape**: the pixels above half the candidate's peak absorbed fraction
//!    (`1 − S/S_background`, in which blur is linear) connected to it must stay inside the
//!    window (a plate's edge or a bone ridge runs out of it) and must not run side by side into
//!    the pixels nearer another candidate (a ridge is a row of candidates whose regions join) —
//!    their count is the blob's area, which the matching then compares with a bead's.
//! 5. **Metal**: a candidate whose window touches the metal shadow (a large clipped component,
//!    [`metal_mask`], and in an image of a metal implant its dense shadow, clipped or not,
//!    [`implant_metal_mask`]) is not a bead: its centre cannot be measured. It is dropped, so the bead
//!    behind it is reported occluded (by the caller) instead of being matched to a wrong blob.
//! 6. **Sub-pixel centre**: the background is a plane fitted to the ring (refitted once without
//!    pixels off by more than 3 noise SDs: a bone edge or a neighbour), without the pixels
//!    within `⌈r⌉ + 2` of another candidate; the intensity centroid of the background-subtracted
//!    attenuation over a disc of radius `⌈r⌉ + 2` and the pixels nearer this candidate than any
//!    other, recentred three times, starts a least-squares fit of a circular Gaussian to the
//!    window, whose centre is the bead's (fitted together with the Gaussians of the candidates
//!    whose bead and blur reach into the window, [`gaussians_fit`]); on an image of one ray per pixel centre from a point source without blur, a
//!    sphere's chord profile is then fitted from there, and its centre is the bead's ([`Centre`],
//!    [`super::bead_profile`]; each fit more accurate than the step before on the images it is
//!    used for, as `tests/reconstruct_realistic.rs` measures).

use glam::DVec2;

use super::bead_profile::{Sample, gaussian_fit, gaussians_fit, sphere_fit};
use super::density::Density;
use super::detect::Blob;
use super::shadow::{Shadow, dense_shadow};

/// Candidates must exceed the matched filter's noise this many times.
pub const MIN_SNR: f64 = 6.0;
/// Side of the noise tiles, pixels.
const TILE: usize = 32;
/// Centroid iterations (recentring the window).
const CENTROID_ITERATIONS: usize = 3;

/// The geometry of the filter and windows for a bead of radius `r` pixels.
#[derive(Debug, Clone, Copy)]
struct Scale {
    /// The bead's expected radius, pixels.
    radius_px: f64,
    /// Inner box half-size.
    inner: usize,
    /// Half-size of the box a candidate's response must be the largest in: the bead's radius,
    /// so the images of two beads that do not overlap are two candidates.
    peak: usize,
    /// Excluded box half-size (the bead and its blur).
    clear: usize,
    /// Outer ring half-size.
    outer: usize,
}

impl Scale {
    fn of(radius_px: f64) -> Scale {
        let r = if radius_px.is_finite() {
            radius_px.clamp(0.5, 50.0)
        } else {
            2.0
        };
        let inner = ((r / std::f64::consts::SQRT_2).floor() as usize).max(1);
        let clear = r.ceil() as usize + 2;
        Scale {
            radius_px: r,
            inner,
            peak: r.ceil() as usize,
            clear,
            outer: clear + 2,
        }
    }
}

/// Summed-area table of a `width × height` image.
struct Integral {
    width: usize,
    sums: Vec<f64>,
}

impl Integral {
    fn new(values: &[f64], width: usize, height: usize) -> Integral {
        let stride = width + 1;
        let mut sums = vec![0.0; stride * (height + 1)];
        for j in 0..height {
            let mut row = 0.0;
            for i in 0..width {
                row += values[j * width + i];
                sums[(j + 1) * stride + i + 1] = sums[j * stride + i + 1] + row;
            }
        }
        Integral { width, sums }
    }

    /// Sum over columns `i0..i1`, rows `j0..j1` (half-open).
    fn sum(&self, i0: usize, j0: usize, i1: usize, j1: usize) -> f64 {
        let s = self.width + 1;
        self.sums[j1 * s + i1] - self.sums[j0 * s + i1] - self.sums[j1 * s + i0]
            + self.sums[j0 * s + i0]
    }
}

/// The noise standard deviation of every 32 × 32 tile (tiles in row-major order, `tiles_x` wide).
fn tile_noise(img: &Density) -> (Vec<f64>, usize) {
    let (w, h) = (img.width, img.height);
    let tiles_x = w.div_ceil(TILE);
    let tiles_y = h.div_ceil(TILE);
    let mut out = Vec::with_capacity(tiles_x * tiles_y);
    let mut diffs = Vec::with_capacity(TILE * TILE);
    for ty in 0..tiles_y {
        for tx in 0..tiles_x {
            diffs.clear();
            for j in ty * TILE..((ty + 1) * TILE).min(h) {
                for i in tx * TILE..((tx + 1) * TILE).min(w.saturating_sub(1)) {
                    let k = j * w + i;
                    if !img.clipped[k] && !img.clipped[k + 1] {
                        diffs.push((img.values[k + 1] - img.values[k]).abs());
                    }
                }
            }
            let sd = if diffs.is_empty() {
                f64::INFINITY
            } else {
                let mid = diffs.len() / 2;
                let (_, m, _) = diffs.select_nth_unstable_by(mid, f64::total_cmp);
                // MAD of a difference of two N(0, σ²): 0.6745·√2·σ.
                *m / (0.674_489_75 * std::f64::consts::SQRT_2)
            };
            out.push(sd);
        }
    }
    // Quantised or noise-free tiles have a median difference of 0: floor at a tiny value so the
    // threshold still means something, and let tiles with no usable pixel take the image median.
    let mut finite: Vec<f64> = out.iter().copied().filter(|s| s.is_finite()).collect();
    let fallback = if finite.is_empty() {
        1e-3
    } else {
        let mid = finite.len() / 2;
        *finite.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    for s in &mut out {
        if !s.is_finite() {
            *s = fallback;
        }
        *s = s.max(1e-4);
    }
    (out, tiles_x)
}

/// The metal shadow: the clipped pixels of 8-connected clipped components of at least
/// `min_area` pixels (a bead's own clipped core is far smaller). Row-major, like the image.
pub fn metal_mask(img: &Density, min_area: usize) -> Vec<bool> {
    let as_u16: Vec<u16> = img.clipped.iter().map(|&c| u16::from(c)).collect();
    let (labels, blobs) = super::detect::components(&as_u16, img.width.max(1), 1);
    let big: Vec<bool> = blobs.iter().map(|b| b.area >= min_area).collect();
    labels
        .iter()
        .map(|&l| l > 0 && big[l as usize - 1])
        .collect()
}

/// The metal shadow of an image known to show a metal implant: [`metal_mask`]'s clipped
/// components, and the implant's dense shadow ([`dense_shadow`], with the implant's
/// `expected_area_px` if known) when it covers at least `min_area` pixels. Unlike clipping, this
/// also finds an implant whose shadow the scatter veil lifts below the top of the range.
pub fn implant_metal_mask(
    img: &Density,
    min_area: usize,
    expected_area_px: Option<f64>,
) -> Vec<bool> {
    implant_metal_mask_with(img, min_area, dense_shadow(img, expected_area_px).as_ref())
}

/// [`implant_metal_mask`] with the implant's dense shadow already segmented (`shadow`, as
/// [`dense_shadow`] gives it for the image).
pub fn implant_metal_mask_with(
    img: &Density,
    min_area: usize,
    shadow: Option<&Shadow>,
) -> Vec<bool> {
    let mut mask = metal_mask(img, min_area);
    if let Some(shadow) = shadow.filter(|s| s.blob.area >= min_area) {
        for (m, s) in mask.iter_mut().zip(&shadow.mask) {
            *m |= *s;
        }
    }
    mask
}

/// Whether any pixel of `mask` (row-major, `width` wide) lies within `radius_px` of `uv`
/// (continuous pixel coordinates).
pub fn touches(mask: &[bool], width: usize, uv: DVec2, radius_px: f64) -> bool {
    if width == 0 || !uv.is_finite() {
        return false;
    }
    let height = mask.len() / width;
    let lo = |c: f64| (c - radius_px - 0.5).floor().max(0.0) as usize;
    let (i0, j0) = (lo(uv.x), lo(uv.y));
    let i1 = ((uv.x + radius_px).ceil().max(0.0) as usize).min(width);
    let j1 = ((uv.y + radius_px).ceil().max(0.0) as usize).min(height);
    (j0..j1).any(|j| {
        (i0..i1).any(|i| {
            mask[j * width + i]
                && (DVec2::new(i as f64 + 0.5, j as f64 + 0.5) - uv).length() <= radius_px
        })
    })
}

/// How a bead's sub-pixel centre is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Centre {
    /// The background-subtracted intensity centroid over a disc, recentred.
    Centroid,
    /// A least-squares fit of a circular Gaussian (amplitude, centre, width) to the
    /// background-subtracted window, started at the centroid (the default: more accurate than
    /// the centroid on the project's images, sharp or blurred; see
    /// docs/src/guide/reference-program.md).
    #[default]
    GaussianFit,
    /// The Gaussian's fit, then a fit of a sphere's chord profile sampled at the pixel centres
    /// from the Gaussian's centre ([`super::bead_profile`]): for images of one ray per pixel
    /// centre from a point source without blur, where the Gaussian pixel-locks.
    SphereFit,
}

/// The beads of radius `radius_px` (pixels) in `img`, as blobs: sub-pixel centre, and as area the
/// number of pixels above half the bead's peak contrast. Candidates touching `metal` (see
/// [`metal_mask`]) are left out.
pub fn find_beads(img: &Density, radius_px: f64, metal: &[bool]) -> Vec<Blob> {
    find_beads_by(img, radius_px, metal, Centre::default())
}

/// [`find_beads`] with the centre measured by `centre`.
pub fn find_beads_by(img: &Density, radius_px: f64, metal: &[bool], how: Centre) -> Vec<Blob> {
    let Some(filter) = Filtered::of(img, radius_px, metal) else {
        return Vec::new();
    };
    let candidates = filter.candidates(img);
    let mut found = Vec::new();
    for &[i, j] in &candidates {
        let others = filter.neighbours(&candidates, [i, j]);
        if let Ok(blob) = filter.judge(img, metal, i, j, &others, how) {
            found.push((filter.response[j * img.width + i], blob));
        }
    }
    distinct(found, filter.scale.radius_px)
}

/// The blobs of `found` (each with its candidate's response, in the candidates' order) less
/// those whose centre lies within `radius_px` of a blob of larger response: one bead measured
/// from two candidates is reported once.
fn distinct(found: Vec<(f64, Blob)>, radius_px: f64) -> Vec<Blob> {
    let mut order: Vec<usize> = (0..found.len()).collect();
    order.sort_by(|&a, &b| found[b].0.total_cmp(&found[a].0).then(a.cmp(&b)));
    let mut keep = vec![false; found.len()];
    let mut kept: Vec<DVec2> = Vec::new();
    for k in order {
        let c = found[k].1.centroid;
        if kept.iter().all(|o| (*o - c).length() >= radius_px) {
            keep[k] = true;
            kept.push(c);
        }
    }
    found
        .into_iter()
        .zip(keep)
        .filter_map(|((_, blob), k)| k.then_some(blob))
        .collect()
}

/// Why the detector does not report a bead at a pixel: the first of its tests the pixel fails,
/// in the order [`find_beads`] applies them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejection {
    /// The matched filter's response is below [`MIN_SNR`] times its noise.
    Threshold,
    /// A stronger response lies within the excluded box (the bead and its blur).
    NotLocalMax,
    /// The window touches the metal shadow.
    Metal,
    /// No background plane could be fitted to the ring.
    Background,
    /// The absorbed fraction at the peak is not above the ring's background.
    NoPeak,
    /// The half-maximum region runs out of the window (an edge or a ridge, not a bead).
    Shape,
    /// The intensity centroid has no positive weight, or drifts more than 1.5 px.
    Centroid,
    /// The Gaussian fit fails or moves more than 1 px from the centroid.
    GaussianFit,
    /// The sphere's fit ([`Centre::SphereFit`]) fails, or its centre moves more than 1 px from
    /// the Gaussian's.
    SphereFit,
}

/// What the detector sees at one place of an image ([`probe`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    /// The pixel (column, row) of the largest signal-to-noise within the search radius: the
    /// candidate the detector judges there.
    pub pixel: [usize; 2],
    /// Its matched filter's signal-to-noise ratio (the threshold is [`MIN_SNR`]).
    pub snr: f64,
    /// Its matched filter's response: the inner box's mean attenuation minus the ring's.
    pub contrast: f64,
    /// The ring's mean attenuation (the background the bead lies on).
    pub background: f64,
    /// The noise standard deviation of one pixel's attenuation in its tile.
    pub noise_sd: f64,
    /// The blob reported, or the first test the candidate fails.
    pub verdict: Result<Blob, Rejection>,
}

/// What [`find_beads`] (Gaussian-fit centres) sees within `search_px` of `uv` (continuous
/// pixel coordinates): the pixel of the largest signal-to-noise there, and the blob it reports
/// or the test that rejects it. `None` when no pixel's ring fits in the image within the search
/// radius.
pub fn probe(
    img: &Density,
    radius_px: f64,
    metal: &[bool],
    uv: DVec2,
    search_px: f64,
) -> Option<Probe> {
    let filter = Filtered::of(img, radius_px, metal)?;
    let [i, j] = filter.strongest_near(img, uv, search_px)?;
    let k = j * img.width + i;
    let verdict = if filter.snr[k] >= MIN_SNR {
        let others = filter.neighbours(&filter.candidates(img), [i, j]);
        filter.judge(img, metal, i, j, &others, Centre::default())
    } else {
        Err(Rejection::Threshold)
    };
    Some(Probe {
        pixel: [i, j],
        snr: filter.snr[k],
        contrast: filter.response[k],
        background: filter.ring_mean(img, i, j),
        noise_sd: filter.tile_sd(i, j),
        verdict,
    })
}

/// An image's matched filter at a bead's scale ([`find_beads`], steps 1–3): its response and
/// signal-to-noise ratio on every pixel whose ring fits (0 elsewhere), and the tile noise.
struct Filtered {
    scale: Scale,
    integral: Integral,
    response: Vec<f64>,
    snr: Vec<f64>,
    noise: Vec<f64>,
    tiles_x: usize,
}

impl Filtered {
    /// The filter of `img` for beads of radius `radius_px`; `None` when the image is smaller
    /// than the filter or `metal` is not the image's size.
    fn of(img: &Density, radius_px: f64, metal: &[bool]) -> Option<Filtered> {
        let (w, h) = (img.width, img.height);
        let s = Scale::of(radius_px);
        if w < 2 * s.outer + 3 || h < 2 * s.outer + 3 || metal.len() != w * h {
            return None;
        }
        let integral = Integral::new(&img.values, w, h);
        let (noise, tiles_x) = tile_noise(img);
        let n_in = ((2 * s.inner + 1) * (2 * s.inner + 1)) as f64;
        let n_ring = ((2 * s.outer + 1).pow(2) - (2 * s.clear + 1).pow(2)) as f64;
        let noise_factor = (1.0 / n_in + 1.0 / n_ring).sqrt();
        // Matched filter response on every pixel whose ring fits.
        let mut response = vec![0.0f64; w * h];
        let (b, a, c) = (s.outer, s.inner, s.clear);
        for j in b..h - b {
            for i in b..w - b {
                let inner = integral.sum(i - a, j - a, i + a + 1, j + a + 1) / n_in;
                let outer = integral.sum(i - b, j - b, i + b + 1, j + b + 1);
                let clear = integral.sum(i - c, j - c, i + c + 1, j + c + 1);
                let ring = (outer - clear) / n_ring;
                response[j * w + i] = inner - ring;
            }
        }
        // The response's noise per tile: what white pixel noise would give, times the image's
        // correlation factor. A detector PSF correlates neighbouring pixels: their differences
        // then understate the noise, while box means average it away less than 1/√N, so
        // white-noise arithmetic alone lets noise peaks through by the thousand. The factor is
        // the median over tiles of the response's own robust spread against the white-noise
        // prediction (at least 1): one number for the image, as the blur is, so a tile crowded
        // with beads or plate edges does not raise its own threshold.
        let spread = response_spread(&response, w, h, b, tiles_x);
        let mut ratios: Vec<f64> = spread
            .iter()
            .zip(&noise)
            .filter(|(s, _)| **s > 0.0)
            .map(|(s, n)| s / (n * noise_factor))
            .filter(|r| r.is_finite())
            .collect();
        let correlation = if ratios.is_empty() {
            1.0
        } else {
            let mid = ratios.len() / 2;
            ratios
                .select_nth_unstable_by(mid, f64::total_cmp)
                .1
                .max(1.0)
        };
        let mut snr = vec![0.0f64; w * h];
        for j in b..h - b {
            for i in b..w - b {
                let sd = noise[(j / TILE) * tiles_x + i / TILE] * noise_factor * correlation;
                snr[j * w + i] = response[j * w + i] / sd;
            }
        }
        Some(Filtered {
            scale: s,
            integral,
            response,
            snr,
            noise,
            tiles_x,
        })
    }

    /// The noise standard deviation of one pixel's attenuation in the tile of pixel (i, j).
    fn tile_sd(&self, i: usize, j: usize) -> f64 {
        self.noise[(j / TILE) * self.tiles_x + i / TILE]
    }

    /// The mean attenuation of the filter's ring around pixel (i, j), whose ring must fit.
    fn ring_mean(&self, img: &Density, i: usize, j: usize) -> f64 {
        let (b, c) = (self.scale.outer, self.scale.clear);
        if i < b || j < b || i + b >= img.width || j + b >= img.height {
            return f64::NAN;
        }
        let outer = self.integral.sum(i - b, j - b, i + b + 1, j + b + 1);
        let clear = self.integral.sum(i - c, j - c, i + c + 1, j + c + 1);
        let n_ring = ((2 * b + 1).pow(2) - (2 * c + 1).pow(2)) as f64;
        (outer - clear) / n_ring
    }

    /// The pixel of the largest signal-to-noise ratio whose centre lies within `search_px` of
    /// `uv`, among those whose ring fits.
    fn strongest_near(&self, img: &Density, uv: DVec2, search_px: f64) -> Option<[usize; 2]> {
        let b = self.scale.outer;
        let lo = |c: f64, n: usize| ((c - search_px).floor().max(b as f64) as usize).min(n - b);
        let hi = |c: f64, n: usize| ((c + search_px).ceil().max(0.0) as usize).min(n - b);
        let (w, h) = (img.width, img.height);
        (lo(uv.y, h)..hi(uv.y, h))
            .flat_map(|j| (lo(uv.x, w)..hi(uv.x, w)).map(move |i| [i, j]))
            .filter(|&[i, j]| {
                (DVec2::new(i as f64 + 0.5, j as f64 + 0.5) - uv).length() <= search_px
            })
            .max_by(|&[a, b], &[c, d]| self.snr[b * w + a].total_cmp(&self.snr[d * w + c]))
    }

    /// The pixels whose response passes the threshold and is the largest within the bead's
    /// radius ([`Scale::peak`]), in row-major order.
    fn candidates(&self, img: &Density) -> Vec<[usize; 2]> {
        let (w, h, b) = (img.width, img.height, self.scale.outer);
        let mut out = Vec::new();
        for j in b..h - b {
            for i in b..w - b {
                // The threshold first: it rejects nearly every pixel at no cost.
                if self.snr[j * w + i] >= MIN_SNR
                    && is_local_max(&self.response, w, h, i, j, self.scale.peak)
                {
                    out.push([i, j]);
                }
            }
        }
        out
    }

    /// The candidates (row-major, as [`Filtered::candidates`] lists them) other than `at` whose
    /// bead and blur (radius [`Scale::clear`]) can reach into the window around `at` (its
    /// ring, half-size [`Scale::outer`]).
    fn neighbours(&self, candidates: &[[usize; 2]], at: [usize; 2]) -> Vec<[usize; 2]> {
        let reach = self.scale.outer + self.scale.clear;
        let first = candidates.partition_point(|c| c[1] + reach < at[1]);
        candidates[first..]
            .iter()
            .take_while(|c| c[1] <= at[1] + reach)
            .filter(|&&c| c != at && c[0].abs_diff(at[0]) <= reach)
            .filter(|c| squared_distance(**c, at) <= (reach * reach) as i64)
            .copied()
            .collect()
    }

    /// The candidate at pixel (i, j), whose response passed the threshold, beside the other
    /// candidates `others` near it: the blob, or the first test (local maximum, metal, shape,
    /// centre) it fails.
    fn judge(
        &self,
        img: &Density,
        metal: &[bool],
        i: usize,
        j: usize,
        others: &[[usize; 2]],
        how: Centre,
    ) -> Result<Blob, Rejection> {
        let (w, h, c) = (img.width, img.height, self.scale.clear);
        if !is_local_max(&self.response, w, h, i, j, self.scale.peak) {
            return Err(Rejection::NotLocalMax);
        }
        let at = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
        if touches(metal, w, at, c as f64 + 1.0) {
            return Err(Rejection::Metal);
        }
        measure(img, [i, j], self.scale, self.tile_sd(i, j), others, how)
    }
}

/// The robust standard deviation (1.4826 × the median absolute deviation from the median) of the
/// matched filter's response over each tile's pixels whose ring fits (`margin` from the border);
/// 0 for a tile without such pixels. Beads and edges are a minority of a tile's pixels, so they
/// do not move it.
fn response_spread(
    response: &[f64],
    w: usize,
    h: usize,
    margin: usize,
    tiles_x: usize,
) -> Vec<f64> {
    let tiles_y = h.div_ceil(TILE);
    let mut out = Vec::with_capacity(tiles_x * tiles_y);
    let mut values = Vec::with_capacity(TILE * TILE);
    for ty in 0..tiles_y {
        for tx in 0..tiles_x {
            values.clear();
            for j in (ty * TILE).max(margin)..((ty + 1) * TILE).min(h - margin) {
                for i in (tx * TILE).max(margin)..((tx + 1) * TILE).min(w - margin) {
                    values.push(response[j * w + i]);
                }
            }
            if values.is_empty() {
                out.push(0.0);
                continue;
            }
            let mid = values.len() / 2;
            let median = *values.select_nth_unstable_by(mid, f64::total_cmp).1;
            for v in &mut values {
                *v = (*v - median).abs();
            }
            let mad = *values.select_nth_unstable_by(mid, f64::total_cmp).1;
            out.push(1.482_602_2 * mad);
        }
    }
    out
}

/// Whether `values[j·w + i]` is the largest within the box of half-size `half` (ties go to the
/// first pixel in row-major order).
fn is_local_max(values: &[f64], w: usize, h: usize, i: usize, j: usize, half: usize) -> bool {
    let v = values[j * w + i];
    for y in j.saturating_sub(half)..(j + half + 1).min(h) {
        for x in i.saturating_sub(half)..(i + half + 1).min(w) {
            let u = values[y * w + x];
            if u > v || (u == v && (y, x) < (j, i)) {
                return false;
            }
        }
    }
    true
}

/// The squared distance between two pixels.
fn squared_distance(a: [usize; 2], b: [usize; 2]) -> i64 {
    let dx = a[0] as i64 - b[0] as i64;
    let dy = a[1] as i64 - b[1] as i64;
    dx * dx + dy * dy
}

/// Ring pixels a plane needs beside a neighbour's bead (a sixth of the ring's at the
/// smallest scale).
const MIN_RING_PIXELS: usize = 12;

/// A background plane `p[0] + p[1]·(x − i) + p[2]·(y − j)` fitted to the ring of the window
/// around pixel (i, j), without the pixels within [`Scale::clear`] of a neighbouring candidate
/// in `others` (its bead and blur), refitted once without outliers beyond 3 `sd`.
fn ring_plane(
    img: &Density,
    [i, j]: [usize; 2],
    s: Scale,
    sd: f64,
    others: &[[usize; 2]],
) -> Option<[f64; 3]> {
    let (c, b) = (s.clear as i64, s.outer as i64);
    let mut pts: Vec<(f64, f64, f64)> = Vec::new();
    for dy in -b..=b {
        for dx in -b..=b {
            if dx.abs() <= c && dy.abs() <= c {
                continue;
            }
            let (x, y) = ((i as i64 + dx) as usize, (j as i64 + dy) as usize);
            if img.clipped[y * img.width + x]
                || others.iter().any(|&o| squared_distance(o, [x, y]) <= c * c)
            {
                continue;
            }
            pts.push((dx as f64, dy as f64, img.at(x, y)));
        }
    }
    if !others.is_empty() && pts.len() < MIN_RING_PIXELS {
        return None;
    }
    let mut plane = fit_plane(&pts)?;
    let eval = |p: &[f64; 3], x: f64, y: f64| p[0] + p[1] * x + p[2] * y;
    let kept: Vec<(f64, f64, f64)> = pts
        .iter()
        .copied()
        .filter(|&(x, y, v)| (v - eval(&plane, x, y)).abs() <= 3.0 * sd)
        .collect();
    if kept.len() >= pts.len() / 2 {
        plane = fit_plane(&kept).unwrap_or(plane);
    }
    Some(plane)
}

/// Least-squares plane `v ≈ p0 + p1·x + p2·y`.
fn fit_plane(pts: &[(f64, f64, f64)]) -> Option<[f64; 3]> {
    if pts.len() < 3 {
        return None;
    }
    let m = nalgebra::Matrix3::from_fn(|r, c| {
        pts.iter()
            .map(|&(x, y, _)| {
                let f = [1.0, x, y];
                f[r] * f[c]
            })
            .sum::<f64>()
    });
    let rhs = nalgebra::Vector3::from_fn(|r, _| {
        pts.iter().map(|&(x, y, v)| [1.0, x, y][r] * v).sum::<f64>()
    });
    let p = m.lu().solve(&rhs)?;
    Some([p[0], p[1], p[2]])
}

/// The blob of the candidate at pixel (i, j): shape check, area and sub-pixel centre. Beside
/// neighbouring candidates (`others`), the background leaves out their beads, the half-maximum
/// region and the centroid take only the pixels nearer this candidate than any of them, and
/// the Gaussian is fitted together with theirs ([`gaussians_fit`]).
fn measure(
    img: &Density,
    [i, j]: [usize; 2],
    s: Scale,
    sd: f64,
    others: &[[usize; 2]],
    how: Centre,
) -> Result<Blob, Rejection> {
    let plane = ring_plane(img, [i, j], s, sd, others).ok_or(Rejection::Background)?;
    // Pixels nearer this candidate than any other (all of them when it has none).
    let own = |x: usize, y: usize| {
        let d = squared_distance([i, j], [x, y]);
        others.iter().all(|&o| d < squared_distance(o, [x, y]))
    };
    let (ci, cj) = (i as f64 + 0.5, j as f64 + 0.5);
    let excess = |x: usize, y: usize| {
        img.at(x, y)
            - (plane[0] + plane[1] * (x as f64 - i as f64) + plane[2] * (y as f64 - j as f64))
    };
    // The fraction of the background's photons the bead absorbs, `1 − S/S_background`: blur is
    // linear in it, so its half-maximum region keeps a bead's area under a detector PSF. (The
    // attenuation's own half maximum shrinks: blurring transmission and then taking the
    // logarithm sharpens the peak; a 1 mm tantalum bead under a 0.5 px PSF keeps 6 of its
    // 15 pixels.)
    let absorbed = |x: usize, y: usize| 1.0 - (-excess(x, y)).exp();
    let c = s.clear;
    // Half-maximum region connected to the peak, inside the cleared box.
    let (x0, y0) = (i - c, j - c);
    let side = 2 * c + 1;
    let mut peak = f64::NEG_INFINITY;
    for y in y0..y0 + side {
        for x in x0..x0 + side {
            if (x as i64 - i as i64).abs() <= 1 && (y as i64 - j as i64).abs() <= 1 {
                peak = peak.max(absorbed(x, y));
            }
        }
    }
    if !(peak > 0.0) {
        return Err(Rejection::NoPeak);
    }
    let half = 0.5 * peak;
    let mut inside = vec![false; side * side];
    let mut stack = vec![(i, j)];
    inside[c * side + c] = true;
    let mut area = 0usize;
    let mut bbox = [u32::MAX, u32::MAX, 0, 0];
    while let Some((x, y)) = stack.pop() {
        area += 1;
        bbox = [
            bbox[0].min(x as u32),
            bbox[1].min(y as u32),
            bbox[2].max(x as u32),
            bbox[3].max(y as u32),
        ];
        for (dx, dy) in [
            (-1i64, 0i64),
            (1, 0),
            (0, -1),
            (0, 1),
            (-1, -1),
            (1, 1),
            (-1, 1),
            (1, -1),
        ] {
            let (nx, ny) = (x as i64 + dx, y as i64 + dy);
            let (lx, ly) = (nx - x0 as i64, ny - y0 as i64);
            if !own(nx as usize, ny as usize) {
                // The region runs on into a neighbouring candidate's pixels (side by side, not
                // only corner to corner): one object seen as several candidates (a ridge), or
                // beads too close to be told apart.
                if (dx == 0 || dy == 0) && absorbed(nx as usize, ny as usize) >= half {
                    return Err(Rejection::Shape);
                }
                continue;
            }
            if lx < 0 || ly < 0 || lx >= side as i64 || ly >= side as i64 {
                // The region reaches the window's edge: a ridge or an edge, not a bead.
                if absorbed(nx as usize, ny as usize) >= half {
                    return Err(Rejection::Shape);
                }
                continue;
            }
            let k = ly as usize * side + lx as usize;
            if !inside[k] && absorbed(nx as usize, ny as usize) >= half {
                inside[k] = true;
                stack.push((nx as usize, ny as usize));
            }
        }
    }
    // Intensity centroid over a disc, recentred.
    let radius = c as f64;
    let mut centre = DVec2::new(ci, cj);
    for _ in 0..CENTROID_ITERATIONS {
        let (mut sw, mut su, mut sv) = (0.0, 0.0, 0.0);
        for y in j - c..=j + c {
            for x in i - c..=i + c {
                let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                if (p - centre).length() > radius || !own(x, y) {
                    continue;
                }
                let e = excess(x, y);
                sw += e;
                su += e * p.x;
                sv += e * p.y;
            }
        }
        if !(sw > 0.0) {
            return Err(Rejection::Centroid);
        }
        let next = DVec2::new(su / sw, sv / sw);
        if (next - DVec2::new(ci, cj)).length() > 1.5 {
            return Err(Rejection::Centroid);
        }
        centre = next;
    }
    if how != Centre::Centroid {
        let pts: Vec<Sample> = (j - c..=j + c)
            .flat_map(|y| (i - c..=i + c).map(move |x| (x, y)))
            .map(|(x, y)| (DVec2::new(x as f64 + 0.5, y as f64 + 0.5), excess(x, y)))
            .collect();
        // σ starts at a third of the window.
        let sigma_start_px = c as f64 / 3.0;
        // The neighbours whose bead and blur (radius `c`) reach into the window.
        let reaching: Vec<[usize; 2]> = others
            .iter()
            .copied()
            .filter(|&o| squared_distance(o, [i, j]) <= (4 * c * c) as i64)
            .collect();
        let fit = if reaching.is_empty() {
            gaussian_fit(&pts, centre, sigma_start_px)
        } else {
            // Each bead starts at its candidate with the largest excess around it.
            let peak_near = |[x, y]: [usize; 2]| {
                (y - 1..=y + 1)
                    .flat_map(|y| (x - 1..=x + 1).map(move |x| (x, y)))
                    .map(|(x, y)| excess(x, y))
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            let beads: Vec<(DVec2, f64)> = std::iter::once((centre, peak_near([i, j])))
                .chain(reaching.iter().map(|&[x, y]| {
                    (
                        DVec2::new(x as f64 + 0.5, y as f64 + 0.5),
                        peak_near([x, y]),
                    )
                }))
                .collect();
            gaussians_fit(&pts, &beads, sigma_start_px)
        };
        centre = fit.ok_or(Rejection::GaussianFit)?.centre;
        if how == Centre::SphereFit {
            // A sharp bead's profile ends at its rim: its own pixels hold all of it.
            let mine: Vec<Sample> = pts
                .iter()
                .copied()
                .filter(|&(p, _)| own(p.x as usize, p.y as usize))
                .collect();
            centre = sphere_fit(&mine, centre, s.radius_px)
                .ok_or(Rejection::SphereFit)?
                .centre;
        }
    }
    Ok(Blob {
        centroid: centre,
        area,
        bbox,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic attenuation image: a sloped background plus beads of radius `r` px (area
    /// sampled 8×8 per pixel, attenuation ∝ chord length) and Gaussian-free deterministic noise.
    fn scene(w: usize, h: usize, beads: &[DVec2], r: f64, mu: f64) -> Density {
        let mut values = vec![0.0; w * h];
        for j in 0..h {
            for i in 0..w {
                let mut v = 0.5 + 0.001 * i as f64 + 0.0005 * j as f64;
                for c in beads {
                    let mut acc = 0.0;
                    for sy in 0..8 {
                        for sx in 0..8 {
                            let p = DVec2::new(
                                i as f64 + (sx as f64 + 0.5) / 8.0,
                                j as f64 + (sy as f64 + 0.5) / 8.0,
                            );
                            let d2 = (p - *c).length_squared();
                            if d2 < r * r {
                                acc += 2.0 * (r * r - d2).sqrt();
                            }
                        }
                    }
                    v += mu * acc / 64.0;
                }
                values[j * w + i] = v;
            }
        }
        Density {
            width: w,
            height: h,
            clipped: vec![false; w * h],
            values,
        }
    }

    #[test]
    fn area_sampled_beads_on_a_slope_are_found_at_their_centres() {
        let beads = [
            DVec2::new(20.3, 22.7),
            DVec2::new(51.55, 18.2),
            DVec2::new(40.9, 49.05),
        ];
        let img = scene(72, 70, &beads, 2.3, 1.0);
        let metal = vec![false; 72 * 70];
        let found = find_beads(&img, 2.3, &metal);
        assert_eq!(found.len(), 3, "{found:?}");
        for b in &beads {
            let nearest = found
                .iter()
                .map(|f| (f.centroid - *b).length())
                .fold(f64::INFINITY, f64::min);
            assert!(nearest < 0.01, "{b}: {nearest} px");
        }
        // A bead's half-maximum area is about its disc's (π·2.3² ≈ 16.6 px).
        assert!(
            found.iter().all(|f| (8..=25).contains(&f.area)),
            "{found:?}"
        );
    }

    #[test]
    fn a_bead_touching_metal_is_not_reported_and_a_step_edge_is_not_a_bead() {
        let beads = [DVec2::new(20.5, 20.5), DVec2::new(45.5, 20.5)];
        let mut img = scene(72, 44, &beads, 2.3, 1.0);
        // Metal: a clipped block whose edge is 4 px from the second bead's centre.
        let mut clipped = vec![false; 72 * 44];
        for j in 0..44 {
            for i in 50..72 {
                clipped[j * 72 + i] = true;
                img.values[j * 72 + i] = 7.0;
            }
        }
        img.clipped = clipped;
        let metal = metal_mask(&img, 100);
        let found = find_beads(&img, 2.3, &metal);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!((found[0].centroid - beads[0]).length() < 0.05);
        // Without the metal mask the second bead is still never a blob of the step's corner rows.
        let none = vec![false; 72 * 44];
        for f in find_beads(&img, 2.3, &none) {
            assert!(
                beads.iter().any(|b| (f.centroid - *b).length() < 1.5),
                "a blob off every bead: {f:?}"
            );
        }
    }

    /// Deterministic noise of about `amplitude` (uniform in ±amplitude/2) at pixel (i, j).
    fn pseudo_noise(i: usize, j: usize, amplitude: f64) -> f64 {
        let h = (i as u64 * 73_856_093) ^ (j as u64 * 19_349_663);
        let u = (h.wrapping_mul(2_654_435_761) % 10_007) as f64 / 10_007.0;
        amplitude * (u - 0.5)
    }

    #[test]
    fn a_bead_at_the_end_of_a_ramp_beside_a_quiet_tile_is_found_at_its_centre() {
        // An oblique plate's image: the background climbs 0.03 per pixel up to column 28, then
        // stays flat. The ramp's tile (columns 0–31) reads the climb as noise, ten times the
        // flat tile's: the signal-to-noise ratio jumps at column 32, two pixels from the bead.
        let bead = DVec2::new(30.3, 48.4);
        let mut img = scene(96, 96, &[bead], 2.3, 0.3);
        for j in 0..96 {
            for i in 0..96 {
                let ramp = 0.03 * (i.min(28) as f64);
                img.values[j * 96 + i] += ramp + pseudo_noise(i, j, 0.01);
            }
        }
        let metal = vec![false; 96 * 96];
        let found = find_beads(&img, 2.3, &metal);
        let nearest = found
            .iter()
            .map(|f| (f.centroid - bead).length())
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 0.25, "nearest blob {nearest} px off: {found:?}");
        let seen = probe(&img, 2.3, &metal, bead, 1.5).expect("inside the image");
        assert_eq!(seen.pixel, [30, 48], "{seen:?}");
        assert!(seen.verdict.is_ok(), "{seen:?}");
    }

    /// `img` convolved with a normalised Gaussian of `sigma` px (separable, truncated at 4σ,
    /// the border pixels repeated): a detector PSF.
    fn blurred(img: &Density, sigma: f64) -> Density {
        let half = (4.0 * sigma).ceil() as i64;
        let kernel: Vec<f64> = (-half..=half)
            .map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp())
            .collect();
        let total: f64 = kernel.iter().sum();
        let (w, h) = (img.width as i64, img.height as i64);
        let pass = |src: &[f64], along_x: bool| -> Vec<f64> {
            let mut out = vec![0.0; src.len()];
            for j in 0..h {
                for i in 0..w {
                    out[(j * w + i) as usize] = (-half..=half)
                        .map(|d| {
                            let (x, y) = if along_x {
                                ((i + d).clamp(0, w - 1), j)
                            } else {
                                (i, (j + d).clamp(0, h - 1))
                            };
                            kernel[(d + half) as usize] * src[(y * w + x) as usize]
                        })
                        .sum::<f64>()
                        / total;
                }
            }
            out
        };
        let values = pass(&pass(&img.values, true), false);
        Density {
            values,
            ..img.clone()
        }
    }

    #[test]
    fn beads_whose_images_do_not_overlap_are_each_found_beside_the_other() {
        // Pairs of beads of radius 2.3 px, 2.6 to 4 radii apart in four directions, under a
        // PSF of σ 0.6 px: each pair lies within the box a candidate had to be the largest in
        // before (the bead and its blur, half-size 5 px), so one bead of every pair was missed,
        // and a lone Gaussian fitted to either leaned towards the other.
        let r = 2.3;
        let mut beads = Vec::new();
        let mut pairs = Vec::new();
        for (k, times_r) in [2.6, 3.0, 3.5, 4.0].into_iter().enumerate() {
            for (l, angle_deg) in [0.0f64, 30.0, 45.0, 90.0].into_iter().enumerate() {
                let a = DVec2::new(20.37 + 30.0 * l as f64, 20.61 + 30.0 * k as f64);
                let d = times_r
                    * r
                    * DVec2::new(angle_deg.to_radians().cos(), angle_deg.to_radians().sin());
                pairs.push((a, a + d));
                beads.extend([a, a + d]);
            }
        }
        let img = blurred(&scene(130, 130, &beads, r, 1.0), 0.6);
        let metal = vec![false; 130 * 130];
        let found = find_beads(&img, r, &metal);
        let mut worst: f64 = 0.0;
        for b in &beads {
            let nearest = found
                .iter()
                .map(|f| (f.centroid - *b).length())
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(nearest);
        }
        assert_eq!(found.len(), beads.len(), "{found:?}");
        // A lone Gaussian per bead, pulled by its neighbour, is 0.04 px off at worst here.
        assert!(worst < 0.025, "worst centre {worst} px off");
        // Their half-maximum areas are a bead's, as for lone beads.
        assert!(
            found.iter().all(|f| (8..=25).contains(&f.area)),
            "{found:?}"
        );
    }

    #[test]
    fn a_thin_ridge_is_not_a_row_of_beads() {
        // A plate seen edge-on, as a line 2 px wide across the image, under the same PSF and
        // a little noise: its candidates line up every few pixels along it, and their
        // half-maximum regions run into each other, so none is a bead. A bead 6 px from the
        // ridge is still found, at its centre.
        let (w, h) = (160, 128);
        let bead = DVec2::new(80.4, 54.3);
        let mut img = scene(w, h, &[bead], 2.3, 1.0);
        for j in 0..h {
            for i in 0..w {
                if (60..62).contains(&j) {
                    img.values[j * w + i] += 1.5;
                }
            }
        }
        let mut img = blurred(&img, 0.6);
        for j in 0..h {
            for i in 0..w {
                img.values[j * w + i] += pseudo_noise(i, j, 0.01);
            }
        }
        let found = find_beads(&img, 2.3, &vec![false; w * h]);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!((found[0].centroid - bead).length() < 0.05, "{found:?}");
    }

    #[test]
    fn touches_measures_from_pixel_centres() {
        let mut mask = vec![false; 100];
        mask[5 * 10 + 7] = true; // centre (7.5, 5.5)
        assert!(touches(&mask, 10, DVec2::new(5.5, 5.5), 2.0));
        assert!(!touches(&mask, 10, DVec2::new(5.4, 5.5), 2.0));
        assert!(!touches(&mask, 10, DVec2::new(f64::NAN, 1.0), 2.0));
    }
}
