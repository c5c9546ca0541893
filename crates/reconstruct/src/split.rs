//! Touching bead images in a binary-mode image: one 8-connected blob, two beads.
//!
//! Two beads whose images lie about a bead's width apart (3.7 px for 1 mm beads 3.3 px wide, say)
//! touch, and [`super::detect::components`] makes one blob of them. Its centroid lies between the
//! two beads, and if its area still passes for one bead's, that wrong centre is used. The bead
//! radius `r` is known (bead diameter, magnification and pitch), so the blob's shape tells one
//! bead from two:
//!
//! 1. **One bead** is round: the difference of the blob's principal second moments, `λ₁ − λ₂`, is
//!    at most [`ROUND_ELONGATION`]` · r²` (pixel-centre sampling of a disc of 1.4 px radius or more
//!    gives at most 0.22 r², of one 15 % smaller than expected 0.29 r²), or its area is below
//!    [`PAIR_MIN_AREAS`] bead areas (a disc blurred by motion is elongated but smaller than one
//!    bead). Such a blob is left as it is.
//! 2. **Two beads**: the pixels are split in two by exact 2-means ([`two_means`]: of all splits
//!    by a line, the one whose parts' pixels lie closest to the parts' centroids; two discs at ±h
//!    that do not overlap have `λ₁ − λ₂ = h²`). The split is taken when each part is round and one
//!    bead's size, and the parts' centroids are at least [`MIN_SEPARATION_RADII`]` · r` apart.
//!    Discs that do not overlap then give each part its own bead's pixels (but for a pixel at the
//!    seam in about 1 % of pairs), so each part's centroid is the one its bead's blob would have
//!    alone: within 0.4 px of the bead's centre for 1.4–2.5 px radii, as for a lone bead. Discs
//!    that overlap by a sliver (1.75–2 radii apart) leave their shared lens to the split, which
//!    pushes both centres apart, by at most 0.67 px (the unit tests sweep both cases).
//! 3. **Unresolved**: any other elongated blob of more than [`PAIR_MIN_AREAS`] bead areas (two
//!    beads overlapping more, a bead on the end of another's) is dropped: a bead missing from one
//!    view costs the fit one bead, a wrong centre biases it.
//!
//! Below [`MIN_RADIUS_PX`] the pixel pattern of one bead is too coarse to tell from two, and every
//! blob is left as it is. Attenuation-mode images have their own detector ([`super::beads`]).

use glam::DVec2;

use super::bead_centre::{Levels, refine};
use super::detect::{
    Blob, bead_area_px, components_at_least, fits_one_bead, one_bead_area_range_px,
};

/// Bead images of a smaller radius (pixels) are never split.
pub const MIN_RADIUS_PX: f64 = 1.3;
/// The largest `(λ₁ − λ₂) / r²` of one bead's blob.
pub const ROUND_ELONGATION: f64 = 0.3;
/// A blob of fewer bead areas than this is taken as one bead, elongated or not.
pub const PAIR_MIN_AREAS: f64 = 1.2;
/// The smallest distance between two split beads' centres, in bead radii (2: the discs touch).
pub const MIN_SEPARATION_RADII: f64 = 1.75;
/// Directions of the dividing lines [`two_means`] tries over a half turn (0.5° apart).
const SPLIT_DIRECTIONS: usize = 360;

/// The bead images of a `width`-wide row-major binary-mode image whose covered pixels are
/// `i_max`: every 8-connected component of pixels covered at least half ([`Levels::core`]),
/// each blob of two touching beads of `radius_px` split into the two beads' blobs, each blob
/// that is neither one bead nor two separable ones dropped (see the module's documentation), and
/// every one bead's centre taken from its pixels' covered fractions ([`refine`]).
pub fn bead_blobs(pixels: &[u16], width: usize, i_max: u16, radius_px: f64) -> Vec<Blob> {
    let levels = Levels::of(pixels, i_max);
    let (labels, blobs) = components_at_least(pixels, width, levels.core());
    let mut out = Vec::with_capacity(blobs.len());
    for (k, blob) in blobs.into_iter().enumerate() {
        let label = k as u32 + 1;
        if !radius_px.is_finite()
            || radius_px < MIN_RADIUS_PX
            || (blob.area as f64) < PAIR_MIN_AREAS * bead_area_px(radius_px)
        {
            out.push((label, blob));
            continue;
        }
        let points = pixel_centres(&labels, width, label, blob.bbox);
        match judge(&points, radius_px) {
            Judgement::One => out.push((label, blob)),
            Judgement::Two(pair) => out.extend(pair.map(|b| (label, b))),
            Judgement::Unresolved => {}
        }
    }
    refine(&mut out, &labels, pixels, width, &levels, radius_px);
    out.into_iter().map(|(_, b)| b).collect()
}

/// What a blob of at least [`PAIR_MIN_AREAS`] bead areas is.
#[derive(Debug, Clone, PartialEq)]
enum Judgement {
    /// One bead, or not a bead at all (too large to be two: left to the callers' size checks).
    One,
    /// Two beads, each with its own blob.
    Two([Blob; 2]),
    /// Beads whose centres cannot be told apart well enough: no blob.
    Unresolved,
}

/// Judges the blob made of `points` (pixel centres) against beads of `radius_px`.
fn judge(points: &[DVec2], radius_px: f64) -> Judgement {
    let area = bead_area_px(radius_px);
    if points.len() as f64 > 2.0 * one_bead_area_range_px(area).1 {
        return Judgement::One;
    }
    let Some(m) = Moments::of(points) else {
        return Judgement::One;
    };
    if m.elongation_px2() <= ROUND_ELONGATION * radius_px * radius_px {
        return Judgement::One;
    }
    match two_means(points) {
        Some(parts) if separable(&parts, radius_px) => Judgement::Two(parts.map(|p| blob_of(&p))),
        _ => Judgement::Unresolved,
    }
}

/// Whether two parts of a blob are two whole beads of `radius_px`: each round and one bead's
/// size, their centres at least [`MIN_SEPARATION_RADII`] radii apart.
fn separable(parts: &[Vec<DVec2>; 2], radius_px: f64) -> bool {
    let area = bead_area_px(radius_px);
    let mut centres = [DVec2::ZERO; 2];
    for (part, centre) in parts.iter().zip(&mut centres) {
        let Some(m) = Moments::of(part) else {
            return false;
        };
        if !fits_one_bead(part.len(), area)
            || m.elongation_px2() > ROUND_ELONGATION * radius_px * radius_px
        {
            return false;
        }
        *centre = m.centroid;
    }
    (centres[0] - centres[1]).length() >= MIN_SEPARATION_RADII * radius_px
}

/// The pixel centres of blob `label` within its bounding box `bbox` (`[i_min, j_min, i_max,
/// j_max]`, inclusive) of the label image.
fn pixel_centres(labels: &[u32], width: usize, label: u32, bbox: [u32; 4]) -> Vec<DVec2> {
    let mut out = Vec::new();
    for j in bbox[1] as usize..=bbox[3] as usize {
        for i in bbox[0] as usize..=bbox[2] as usize {
            if labels.get(j * width + i) == Some(&label) {
                out.push(DVec2::new(i as f64 + 0.5, j as f64 + 0.5));
            }
        }
    }
    out
}

/// The centroid and principal second moments (variances along the principal axes) of a set of
/// pixel centres.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Moments {
    centroid: DVec2,
    /// Variance along the major axis, px².
    major_px2: f64,
    /// Variance along the minor axis, px².
    minor_px2: f64,
}

impl Moments {
    /// `None` for no points.
    fn of(points: &[DVec2]) -> Option<Moments> {
        if points.is_empty() {
            return None;
        }
        let n = points.len() as f64;
        let centroid = points.iter().copied().sum::<DVec2>() / n;
        let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
        for p in points {
            let d = *p - centroid;
            sxx += d.x * d.x;
            syy += d.y * d.y;
            sxy += d.x * d.y;
        }
        let (sxx, syy, sxy) = (sxx / n, syy / n, sxy / n);
        let mean = (sxx + syy) / 2.0;
        let spread = (((sxx - syy) / 2.0).powi(2) + sxy * sxy).sqrt();
        Some(Moments {
            centroid,
            major_px2: mean + spread,
            minor_px2: mean - spread,
        })
    }

    /// `λ₁ − λ₂`, px²: 0 for a disc, `h²` for two equal discs at ±h that do not overlap.
    fn elongation_px2(&self) -> f64 {
        self.major_px2 - self.minor_px2
    }
}

/// The split of `points` into two parts with the least sum of squared distances to the parts'
/// centroids (2-means), searched over every split by a line: the best 2-means split is always
/// one, as the parts' Voronoi cells are half-planes. Lloyd's iteration from a guess stops at a
/// split that moves a pixel of one touching bead to the other in a few per cent of pairs; this
/// search does not. Lines are tried at [`SPLIT_DIRECTIONS`] directions over a half turn, each at
/// every offset. `None` for fewer than two points.
fn two_means(points: &[DVec2]) -> Option<[Vec<DVec2>; 2]> {
    if points.len() < 2 {
        return None;
    }
    let mut best: Option<(f64, DVec2, usize)> = None;
    let mut order: Vec<usize> = (0..points.len()).collect();
    for k in 0..SPLIT_DIRECTIONS {
        let angle = std::f64::consts::PI * k as f64 / SPLIT_DIRECTIONS as f64;
        let normal = DVec2::new(angle.cos(), angle.sin());
        order.sort_by(|&a, &b| points[a].dot(normal).total_cmp(&points[b].dot(normal)));
        let (count, sse) = best_cut(points, &order);
        if best.is_none_or(|(least, _, _)| sse < least) {
            best = Some((sse, normal, count));
        }
    }
    let (_, normal, count) = best?;
    order.sort_by(|&a, &b| points[a].dot(normal).total_cmp(&points[b].dot(normal)));
    let first = order[..count].iter().map(|&i| points[i]).collect();
    let second = order[count..].iter().map(|&i| points[i]).collect();
    Some([first, second])
}

/// The cut of `points` taken in `order` into its first `count` points and the rest (both
/// non-empty) with the least sum of squared distances to the two parts' centroids: `(count,
/// that sum)`.
fn best_cut(points: &[DVec2], order: &[usize]) -> (usize, f64) {
    let total = Sums::of(order.iter().map(|&i| points[i]));
    let mut head = Sums::default();
    let mut best = (1, f64::INFINITY);
    for (count, &i) in order.iter().enumerate().take(order.len() - 1) {
        head.add(points[i]);
        let sse = head.squared_spread() + total.minus(&head).squared_spread();
        if sse < best.1 {
            best = (count + 1, sse);
        }
    }
    best
}

/// Running sums of points: their number, sum and sum of squared lengths.
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    n: f64,
    sum: DVec2,
    squares: f64,
}

impl Sums {
    fn of(points: impl Iterator<Item = DVec2>) -> Sums {
        let mut s = Sums::default();
        points.for_each(|p| s.add(p));
        s
    }

    fn add(&mut self, p: DVec2) {
        self.n += 1.0;
        self.sum += p;
        self.squares += p.length_squared();
    }

    fn minus(&self, other: &Sums) -> Sums {
        Sums {
            n: self.n - other.n,
            sum: self.sum - other.sum,
            squares: self.squares - other.squares,
        }
    }

    /// The sum of squared distances of the points to their centroid (0 for none).
    fn squared_spread(&self) -> f64 {
        if self.n <= 0.0 {
            return 0.0;
        }
        self.squares - self.sum.length_squared() / self.n
    }
}

/// The mean of `points`; `None` for none.
fn centroid(points: &[DVec2]) -> Option<DVec2> {
    (!points.is_empty()).then(|| points.iter().copied().sum::<DVec2>() / points.len() as f64)
}

/// The blob of a part: its centroid, pixel count and bounding box.
fn blob_of(points: &[DVec2]) -> Blob {
    let mut bbox = [u32::MAX, u32::MAX, 0, 0];
    for p in points {
        let (i, j) = (p.x.floor() as u32, p.y.floor() as u32);
        bbox = [
            bbox[0].min(i),
            bbox[1].min(j),
            bbox[2].max(i),
            bbox[3].max(j),
        ];
    }
    Blob {
        centroid: centroid(points).unwrap_or(DVec2::ZERO),
        area: points.len(),
        bbox,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::components;

    /// A noise-free binary image of discs (`centre`, `radius_px`) sampled at pixel centres, as
    /// one ray per pixel from a point source images a bead: `on` inside any disc, 0 elsewhere.
    fn image_of(discs: &[(DVec2, f64)], side: usize, on: u16) -> Vec<u16> {
        let mut img = vec![0u16; side * side];
        for j in 0..side {
            for i in 0..side {
                let p = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
                if discs.iter().any(|(c, r)| p.distance(*c) < *r) {
                    img[j * side + i] = on;
                }
            }
        }
        img
    }

    /// The centroid of the pixel centres inside one disc: what its blob gives when alone.
    fn alone(centre: DVec2, radius_px: f64) -> DVec2 {
        let side = (centre.x.max(centre.y) + radius_px + 2.0).ceil() as usize;
        components(&image_of(&[(centre, radius_px)], side, 1), side, 1).1[0].centroid
    }

    /// A deterministic spread of sub-pixel offsets in [0, 1)².
    fn offsets(n: usize) -> impl Iterator<Item = DVec2> {
        (0..n).map(move |k| {
            let k = k as f64;
            DVec2::new((k * 0.618_034).fract(), (k * 0.754_877_7 + 0.25).fract())
        })
    }

    #[test]
    fn a_single_bead_is_never_split_or_dropped() {
        // Beads of 1.3–4 px radius at 200 sub-pixel positions each, judged with a radius up to
        // 15 % off either way (a model bead's depth, the box plates' magnifications).
        for radius_px in [1.3, 1.5, 1.65, 2.0, 2.5, 3.0, 4.0] {
            for scale in [0.87, 1.0, 1.15] {
                for offset in offsets(200) {
                    let centre = DVec2::new(10.0, 10.0) + offset;
                    let img = image_of(&[(centre, radius_px)], 24, 9);
                    let plain = components(&img, 24, 9).1;
                    let judged = bead_blobs(&img, 24, 9, radius_px * scale);
                    assert_eq!(
                        judged, plain,
                        "r {radius_px}, judged with {scale} r, at {centre}"
                    );
                }
            }
        }
    }

    /// Side of the images of [`pairs`], pixels.
    const PAIR_SIDE: usize = 28;

    /// `n` pairs of discs of `radius_px` whose centres lie `from` to `from + span` radii apart,
    /// at changing directions and sub-pixel positions: the two centres and the pair's image.
    fn pairs(
        radius_px: f64,
        n: usize,
        from: f64,
        span: f64,
    ) -> impl Iterator<Item = (DVec2, DVec2, Vec<u16>)> {
        offsets(n).enumerate().map(move |(k, offset)| {
            let k = k as f64;
            let separation_px = radius_px * (from + span * (k * 0.381_966).fract());
            let angle = k * 0.9;
            let half = 0.5 * separation_px * DVec2::new(angle.cos(), angle.sin());
            let mid = DVec2::new(12.0, 12.0) + offset;
            let (a, b) = (mid - half, mid + half);
            (
                a,
                b,
                image_of(&[(a, radius_px), (b, radius_px)], PAIR_SIDE, 9),
            )
        })
    }

    /// The distance from `p` to the nearest centroid of `blobs` (infinite for none).
    fn nearest_px(blobs: &[Blob], p: DVec2) -> f64 {
        blobs
            .iter()
            .map(|b| b.centroid.distance(p))
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn touching_beads_get_the_centroids_they_would_have_alone() {
        // Two beads whose discs do not overlap (2.0–2.6 radii apart) at every direction: the
        // split gives each its own pixels, so its centroid is the one the bead's blob has alone,
        // but for a pixel at the seam now and then.
        let (mut touching, mut own, mut worst_px) = (0, 0, 0.0f64);
        for radius_px in [1.4, 1.65, 2.0, 2.5] {
            for (a, b, img) in pairs(radius_px, 150, 2.0, 0.6) {
                if components(&img, PAIR_SIDE, 9).1.len() != 1 {
                    continue; // not touching: nothing to split
                }
                touching += 1;
                let found = bead_blobs(&img, PAIR_SIDE, 9, radius_px);
                assert_eq!(found.len(), 2, "r {radius_px}: {a}, {b}");
                if nearest_px(&found, alone(a, radius_px)) < 1e-9
                    && nearest_px(&found, alone(b, radius_px)) < 1e-9
                {
                    own += 1;
                }
                worst_px = worst_px
                    .max(nearest_px(&found, a))
                    .max(nearest_px(&found, b));
            }
        }
        eprintln!("{own} of {touching} touching pairs split as alone; worst {worst_px:.3} px");
        assert!(touching > 300, "{touching} touching pairs");
        // One bead alone is off by up to 0.39 px (pixel-centre sampling at r = 1.65 px); a pixel
        // at the seam given to the wrong bead moves a centre by a few hundredths more.
        assert!(
            own * 50 >= touching * 49,
            "{own} of {touching} split as alone"
        );
        assert!(worst_px < 0.45, "worst centre {worst_px} px");
    }

    #[test]
    fn slightly_overlapping_beads_are_split_within_two_thirds_of_a_pixel() {
        // Discs 1.8–2.0 radii apart share a sliver: split, or dropped, never merged.
        for radius_px in [1.4, 1.65, 2.0, 2.5] {
            for (a, b, img) in pairs(radius_px, 120, 1.8, 0.2) {
                for found in bead_blobs(&img, PAIR_SIDE, 9, radius_px) {
                    let error = found.centroid.distance(a).min(found.centroid.distance(b));
                    assert!(error < 0.67, "r {radius_px}: {a}, {b}: {error} px");
                }
            }
        }
    }

    #[test]
    fn beads_overlapping_much_are_dropped_not_merged() {
        // 1.1–1.6 radii apart: no bead-sized blob comes out but one on a bead's centre (a
        // merged blob's centroid lies half the separation, 0.9–1.3 radii, from both).
        let mut dropped = 0;
        for radius_px in [1.65, 2.0, 2.5, 3.0] {
            let area = bead_area_px(radius_px);
            for (a, b, img) in pairs(radius_px, 60, 1.1, 0.5) {
                let found = bead_blobs(&img, PAIR_SIDE, 9, radius_px);
                let beads: Vec<Blob> = found
                    .into_iter()
                    .filter(|f| fits_one_bead(f.area, area))
                    .collect();
                dropped += usize::from(beads.is_empty());
                for f in &beads {
                    let error = f.centroid.distance(a).min(f.centroid.distance(b));
                    assert!(error < 0.67, "r {radius_px}: {a}, {b}: {f:?}");
                }
            }
        }
        assert!(dropped > 200, "{dropped} of 240 pairs dropped");
    }

    #[test]
    fn small_beads_large_blobs_and_odd_radii_are_left_alone() {
        // Below MIN_RADIUS_PX, a blob many beads large (a mesh's shadow), a radius that is no
        // number: the components, unchanged.
        let pair = image_of(
            &[
                (DVec2::new(8.3, 8.6), 1.2),
                (DVec2::new(10.6, 8.5), 1.2),
                (DVec2::new(20.0, 20.0), 6.0),
            ],
            32,
            5,
        );
        let plain = components(&pair, 32, 5).1;
        for radius_px in [1.2, f64::NAN, f64::INFINITY, -1.0, 0.0] {
            assert_eq!(bead_blobs(&pair, 32, 5, radius_px), plain, "{radius_px}");
        }
        assert_eq!(bead_blobs(&pair, 32, 5, 1.65).last(), plain.last());
        assert!(bead_blobs(&[], 0, 5, 1.65).is_empty());
    }

    #[test]
    fn moments_of_two_discs_give_their_half_separation() {
        // λ₁ − λ₂ = h² for two equal discs at ±h that do not overlap (continuous discs: the
        // pixel sampling of large discs comes close); along y here, so λ₁ is the y variance.
        let (r, h) = (6.0, 7.0);
        let discs = [
            (DVec2::new(20.3, 20.0 - h), r),
            (DVec2::new(20.3, 20.0 + h), r),
        ];
        let img = image_of(&discs, 40, 1);
        let points: Vec<DVec2> = (0..img.len())
            .filter(|&k| img[k] == 1)
            .map(|k| DVec2::new((k % 40) as f64 + 0.5, (k / 40) as f64 + 0.5))
            .collect();
        let m = Moments::of(&points).unwrap();
        assert!((m.elongation_px2().sqrt() - h).abs() < 0.1, "{m:?}");
        assert_eq!(Moments::of(&[]), None);
    }
}
