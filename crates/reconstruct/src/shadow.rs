//! The implant's shadow in an attenuation-mode image, found from the image's own levels, with or
//! without clipping.
//!
//! On a sharp image a metal component clips: its shadow is a flat plateau at the top of the
//! range. With scatter it does not. The scattered photons reach the detector behind the metal, so
//! its shadow reads only the scatter veil (`ln(S_open/S)` of about 3–4.5 in the project's knee
//! exams). That veil is lowest in the middle of the shadow and highest at its rim, so the shadow is
//! a dome, not a plateau, and its rim may lie only 0.6–1 above the tissue around it. A level
//! half-way between the image's median and its densest pixels then merges the shadow with the
//! thigh, and one half-way between the surroundings and the dome's top lies inside the shadow.
//!
//! The segmentation therefore looks for the level at which the shadow's boundary is steepest,
//! as an operator moving a threshold would see the mask snap to the implant's edge:
//!
//! 1. **Core**: the largest 8-connected component of pixels at or above the image's
//!    [`CORE_QUANTILE`] (the densest part of the implant; it must cover at least 0.5 % of the
//!    image).
//! 2. **Levels**: [`LEVELS`] levels evenly spaced from the image's median up to the core's
//!    level. At each, the region is the 8-connected set of pixels at or above it that holds the
//!    core (grown from the core), as long as it covers at most [`MAX_AREA_FRACTION`] of the image.
//! 3. **Steepness**: the mean Sobel gradient magnitude of the attenuation over the region's
//!    boundary pixels. A level inside the dome gives a gentle boundary, one below the implant's
//!    rim a boundary over bone and soft tissue; the implant's edge, a jump of about one unit of
//!    attenuation within two pixels, is the steepest. The shadow is the region at the steepest
//!    level.
//!
//! In a lateral knee view bone can read as dense as the metal's scatter veil, so that no level
//! separates them. When the expected area of the implant's shadow is known (from the model mesh
//! at its nominal pose), only levels whose region covers [`AREA_RANGE`] times that area are
//! considered, and if none does, the one whose area comes closest to it.
//!
//! On a clipped implant every level between its surroundings and the top crosses the same
//! jump, and the shadow is the clipped component with the partial pixels above that level. The
//! level only seeds the outline: where the edge lies is measured on the local profiles
//! ([`super::edge`]).

use super::density::Density;
use super::detect::{Blob, components};

/// The core is the largest component at or above this quantile of the image.
pub const CORE_QUANTILE: f64 = 0.995;
/// Levels tried between the image's median and the core's level.
pub const LEVELS: usize = 32;
/// A region larger than this fraction of the image is not an implant's shadow.
pub const MAX_AREA_FRACTION: f64 = 0.25;
/// With an expected area, a level's region must cover between these multiples of it.
pub const AREA_RANGE: [f64; 2] = [0.6, 1.6];

/// The implant's shadow in one image.
#[derive(Debug, Clone)]
pub struct Shadow {
    /// The shadow mask, row-major, like the image.
    pub mask: Vec<bool>,
    /// The shadow's component (area, centroid, bounding box).
    pub blob: Blob,
    /// The attenuation level that separates the shadow from its surroundings.
    pub level: f64,
}

/// The densest large component of `img` at the level of its steepest boundary (module docs),
/// among the levels whose region fits `expected_area_px` if given; `None` when the image has no
/// pixel above its median.
pub fn dense_shadow(img: &Density, expected_area_px: Option<f64>) -> Option<Shadow> {
    let (w, h) = (img.width, img.height);
    if w < 3 || h < 3 || img.values.len() != w * h {
        return None;
    }
    // The median and the core's quantile by selection, not a full sort: the same order
    // statistics, and the sort of a whole image showed in `reconstruct`'s profile.
    let mut values = img.values.clone();
    let n = values.len();
    let (_, &mut median, above) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    let q = ((n as f64 * CORE_QUANTILE) as usize).min(n - 1);
    let core_level = if q > n / 2 {
        *above
            .select_nth_unstable_by(q - n / 2 - 1, f64::total_cmp)
            .1
    } else {
        median
    };
    if !(core_level > median) {
        return None;
    }
    let core = core_pixels(img, core_level)?;
    let max_area = ((w * h) as f64 * MAX_AREA_FRACTION) as usize;
    let mut region = Region::new(w * h, &core);
    // (fits the expected area, steepness, level) of the best level so far, and (area misfit,
    // level) of the level closest to the expected area.
    let mut best: Option<(f64, f64)> = None;
    let mut closest: Option<(f64, f64)> = None;
    for k in (1..=LEVELS).rev() {
        let level = median + (core_level - median) * k as f64 / LEVELS as f64;
        if !region.grow(img, level, max_area) {
            break;
        }
        if let Some(expected) = expected_area_px {
            let ratio = region.pixels.len() as f64 / expected.max(1.0);
            let misfit = ratio.max(1.0 / ratio.max(f64::MIN_POSITIVE));
            if closest.is_none_or(|(m, _)| misfit < m) {
                closest = Some((misfit, level));
            }
            if !(AREA_RANGE[0]..=AREA_RANGE[1]).contains(&ratio) {
                continue;
            }
        }
        let steepness = region.boundary_mean(img);
        if best.is_none_or(|(b, _)| steepness > b) {
            best = Some((steepness, level));
        }
    }
    let (_, level) = best.or(closest)?;
    let mut region = Region::new(w * h, &core);
    region.grow(img, level, usize::MAX);
    let mask = region.mask();
    let blob = blob_of(&mask, w);
    Some(Shadow { mask, blob, level })
}

/// The pixels of the largest 8-connected component at or above `level`.
fn core_pixels(img: &Density, level: f64) -> Option<Vec<usize>> {
    let dense: Vec<u16> = img.values.iter().map(|&v| u16::from(v >= level)).collect();
    let (labels, blobs) = components(&dense, img.width, 1);
    let (index, _) = blobs.iter().enumerate().max_by_key(|(_, b)| b.area)?;
    let id = index as u32 + 1;
    Some((0..labels.len()).filter(|&k| labels[k] == id).collect())
}

/// The 8-connected region at or above a level that holds the core, grown by a depth-first fill.
/// Lowering the level only adds pixels, so each level grows the region from the last one's
/// border instead of refilling it from the core (refilling it for every level was the largest
/// cost of segmenting a shadow in `reconstruct`'s profile).
struct Region {
    /// `inside[k]`: pixel k is in the region.
    inside: Vec<bool>,
    /// The region's pixels, in the order they joined it.
    pixels: Vec<usize>,
    /// Pixels beside the region that were below the level when they were reached (a pixel may
    /// be listed more than once); the next, lower level starts from them.
    border: Vec<usize>,
    /// The region's boundary pixels (a 4-neighbour outside it) as of the last
    /// [`Region::boundary_mean`], in the order they joined: a pixel whose 4-neighbours are all
    /// inside stays so as the region grows, so only these and the pixels joined since can be
    /// on the boundary.
    boundary: Vec<usize>,
    /// How many of `pixels` `boundary` has looked at.
    looked: usize,
}

impl Region {
    /// An empty region that will grow from `core` (pixels at or above every level).
    fn new(n: usize, core: &[usize]) -> Region {
        Region {
            inside: vec![false; n],
            pixels: Vec::new(),
            border: core.to_vec(),
            boundary: Vec::new(),
            looked: 0,
        }
    }

    /// Grows the region to every pixel at or above `level` connected to it (or, the first time,
    /// to the core); `false` (and a partial region) once it exceeds `max_area` pixels. Levels
    /// must not rise from one call to the next.
    fn grow(&mut self, img: &Density, level: f64, max_area: usize) -> bool {
        let (w, h) = (img.width as i64, img.height as i64);
        let mut stack: Vec<usize> = Vec::new();
        let mut below = Vec::new();
        for k in std::mem::take(&mut self.border) {
            if self.inside[k] {
                continue;
            }
            if img.values[k] >= level {
                self.inside[k] = true;
                stack.push(k);
            } else {
                below.push(k);
            }
        }
        while let Some(k) = stack.pop() {
            self.pixels.push(k);
            if self.pixels.len() > max_area {
                return false;
            }
            let (i, j) = ((k as i64) % w, (k as i64) / w);
            for dj in -1..=1 {
                for di in -1..=1 {
                    let (x, y) = (i + di, j + dj);
                    if x < 0 || y < 0 || x >= w || y >= h {
                        continue;
                    }
                    let n = (y * w + x) as usize;
                    if self.inside[n] {
                        continue;
                    }
                    if img.values[n] >= level {
                        self.inside[n] = true;
                        stack.push(n);
                    } else {
                        below.push(n);
                    }
                }
            }
        }
        self.border = below;
        true
    }

    /// The mean Sobel gradient magnitude ([`sobel_at`]) over the region's boundary pixels:
    /// those with a 4-neighbour outside it (or off the image), summed in the order they joined
    /// the region. Only the last call's boundary and the pixels joined since are looked at
    /// (see `boundary`), and the gradient is computed at those pixels only.
    fn boundary_mean(&mut self, img: &Density) -> f64 {
        let (w, h) = (img.width, img.height);
        let inside = &self.inside;
        let on_boundary = |k: usize| {
            let (i, j) = (k % w, k / w);
            let outside = |x: Option<usize>, y: Option<usize>| match (x, y) {
                (Some(x), Some(y)) if x < w && y < h => !inside[y * w + x],
                _ => true,
            };
            outside(i.checked_sub(1), Some(j))
                || outside(Some(i + 1), Some(j))
                || outside(Some(i), j.checked_sub(1))
                || outside(Some(i), Some(j + 1))
        };
        let joined = &self.pixels[self.looked..];
        let boundary: Vec<usize> = (self.boundary.iter().chain(joined))
            .copied()
            .filter(|&k| on_boundary(k))
            .collect();
        self.looked = self.pixels.len();
        let (mut sum, n) = (0.0, boundary.len());
        for &k in &boundary {
            sum += sobel_at(img, k);
        }
        self.boundary = boundary;
        if n == 0 { 0.0 } else { sum / n as f64 }
    }

    fn mask(self) -> Vec<bool> {
        self.inside
    }
}

/// Area, centroid and bounding box of the pixels of `mask` (`width` wide).
fn blob_of(mask: &[bool], width: usize) -> Blob {
    let (mut area, mut sx, mut sy) = (0usize, 0.0, 0.0);
    let mut bbox = [u32::MAX, u32::MAX, 0, 0];
    for (k, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        let (i, j) = ((k % width) as u32, (k / width) as u32);
        area += 1;
        sx += f64::from(i) + 0.5;
        sy += f64::from(j) + 0.5;
        bbox = [
            bbox[0].min(i),
            bbox[1].min(j),
            bbox[2].max(i),
            bbox[3].max(j),
        ];
    }
    let n = area.max(1) as f64;
    Blob {
        centroid: glam::DVec2::new(sx / n, sy / n),
        area,
        bbox,
    }
}

/// The Sobel gradient magnitude of the attenuation at pixel `k`, the image clamped at its
/// borders.
fn sobel_at(img: &Density, k: usize) -> f64 {
    let (w, h) = (img.width as i64, img.height as i64);
    let (i, j) = (k as i64 % w, k as i64 / w);
    let at = |x: i64, y: i64| img.values[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize];
    let gx = (at(i + 1, j - 1) + 2.0 * at(i + 1, j) + at(i + 1, j + 1))
        - (at(i - 1, j - 1) + 2.0 * at(i - 1, j) + at(i - 1, j + 1));
    let gy = (at(i - 1, j + 1) + 2.0 * at(i, j + 1) + at(i + 1, j + 1))
        - (at(i - 1, j - 1) + 2.0 * at(i, j - 1) + at(i + 1, j - 1));
    (gx * gx + gy * gy).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec2;

    /// A knee-like attenuation image, `w × h`: air (0) around a leg (2.0) that holds the
    /// implant's shadow, a disc of radius `r` at `c` that reads as a scatter dome (`rim` at its
    /// edge, `rim + 1` in the middle), and a bone bar of `bone` running from the disc to the
    /// image's bottom; then blurred by σ = 0.8 px.
    fn knee(rim: f64, bone: f64) -> (Density, Vec<bool>) {
        let (w, h) = (200, 180);
        let (c, r) = (DVec2::new(100.3, 70.6), 30.0);
        let mut disc = vec![false; w * h];
        let values: Vec<f64> = (0..w * h)
            .map(|k| {
                let p = DVec2::new((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
                let d = (p - c).length();
                if d <= r {
                    disc[k] = true;
                    rim + (1.0 - (d / r).powi(2))
                } else if (p.x - 100.0).abs() < 14.0 && p.y > 70.0 {
                    bone
                } else if (p.x - 100.0).abs() < 70.0 {
                    2.0
                } else {
                    0.0
                }
            })
            .collect();
        let img = Density {
            width: w,
            height: h,
            clipped: vec![false; w * h],
            values,
        };
        (img.blurred(0.8), disc)
    }

    fn iou(a: &[bool], b: &[bool]) -> f64 {
        let both = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
        let either = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
        both as f64 / either as f64
    }

    #[test]
    fn a_scatter_lifted_implant_is_found_without_clipping() {
        // The rim reads 3.0 against the leg's 2.0 and a bone of 2.5; nothing clips. A level
        // half-way between the image's median (0) and its top (4.0) would take the whole leg.
        let (img, disc) = knee(3.0, 2.5);
        let s = dense_shadow(&img, None).unwrap();
        assert!(iou(&s.mask, &disc) > 0.95, "IoU {}", iou(&s.mask, &disc));
        assert!(s.level > 2.5 && s.level < 3.0, "{}", s.level);
    }

    #[test]
    fn a_clipped_implant_is_its_clipped_shadow() {
        // Sharp, clipped at 7 over a leg of 2 and a bone of 4: the level lies in the jump.
        let (w, h) = (160, 150);
        let c = DVec2::new(80.4, 60.7);
        let values: Vec<f64> = (0..w * h)
            .map(|k| {
                let p = DVec2::new((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
                if (p - c).length() <= 20.0 {
                    7.0
                } else if (p.x - 80.0).abs() < 12.0 && p.y > 60.0 {
                    4.0
                } else if (p.x - 80.0).abs() < 60.0 {
                    2.0
                } else {
                    0.0
                }
            })
            .collect();
        let clipped: Vec<bool> = values.iter().map(|&v| v >= 7.0).collect();
        let img = Density {
            width: w,
            height: h,
            clipped: clipped.clone(),
            values,
        };
        let s = dense_shadow(&img, None).unwrap();
        assert_eq!(s.mask, clipped);
        assert!(s.level > 4.0 && s.level <= 7.0, "{}", s.level);
    }

    #[test]
    fn the_expected_area_keeps_bone_as_dense_as_the_rim_out() {
        // A lateral view: the bone reads 3.1, above the implant's rim (3.0), so every level that
        // takes the whole disc takes the bone too; the steepest boundary is then the bone's and
        // the disc's together. With the disc's expected area only the dense core that fits it
        // is taken.
        let (img, disc) = knee(3.0, 3.1);
        let area = disc.iter().filter(|d| **d).count() as f64;
        let merged = dense_shadow(&img, None).unwrap();
        assert!(merged.blob.area as f64 > 1.7 * area, "{}", merged.blob.area);
        let s = dense_shadow(&img, Some(area)).unwrap();
        let ratio = s.blob.area as f64 / area;
        assert!((AREA_RANGE[0]..=AREA_RANGE[1]).contains(&ratio), "{ratio}");
        let outside = s
            .mask
            .iter()
            .zip(&disc)
            .filter(|(m, d)| **m && !**d)
            .count();
        assert!(
            outside as f64 <= 0.02 * area,
            "{outside} pixels outside the disc"
        );
    }
}
