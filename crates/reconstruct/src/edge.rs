//! The model's outline in an attenuation-mode image, where its edge is graded: partial pixels,
//! focal-spot penumbra, detector blur and the scatter veil spread it over a few pixels.
//!
//! 1. **Segmentation**: the implant's shadow is the densest large component of the image,
//!    separated from its own neighbourhood by a two-class split ([`super::shadow`]); clipping is
//!    not needed. The component only seeds the edge search and the coarse pose search; the edge's
//!    position comes from step 2.
//! 2. **Edge points**: for every pair of horizontally or vertically neighbouring pixels of which
//!    exactly one is in the shadow, and whose row or column crosses the edge within 45° of its
//!    normal (the transmission's Sobel gradient), the profile along that row or column is read in
//!    *transmission* `S/S_open` (where blur, and the scatter veil, are linear): the local plateau
//!    is the median of the inside pixels [`EdgeWindows::near_px`]..=[`EdgeWindows::far_px`] from
//!    the pair, the local background the median of the outside ones, and the edge is where the
//!    profile crosses the level half-way between them, by linear interpolation between pixel
//!    centres, searched within [`EdgeWindows::search_px`] of the pair; the levels are then read
//!    again from that crossing and the crossing found again (the segmentation's level may lie a
//!    few pixels inside a blurred edge). A symmetric blur of a straight edge crosses that level
//!    exactly at the edge, and a smooth additive veil (scatter) moves both levels alike, so the
//!    points are unbiased under both; on a sharp image the crossing is the pair's midpoint, as
//!    in binary mode. A pair whose local levels do not straddle the segmentation's level (the
//!    plateau denser than it, the background less dense), or whose local step is less than
//!    [`MAX_INSIDE_FRACTION`] in transmission, gives no point: a bead or bone touching the
//!    shadow, a hole of noise in it, or a threshold inside the shadow's gentle dome is not its
//!    edge.

use glam::DVec2;

use super::contour::Outline;
use super::density::Density;
use super::model_outline::OutlineSegment;
use super::shadow::{Shadow, dense_shadow};
use crate::scenario::{Imaging, SpotProfile};

/// The implant's local plateau transmits at most this fraction of its local background (a step
/// of at least 0.3 in attenuation): a threshold lying inside the gently graded shadow of a
/// scatter-lifted implant gives no edge points there.
pub const MAX_INSIDE_FRACTION: f64 = 0.74;

/// Where the local levels of an edge profile are read and how far its crossing is searched,
/// pixels from the current edge estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EdgeWindows {
    /// Profile samples nearer than this lie in the graded edge.
    pub near_px: usize,
    /// Profile samples from `near_px` up to this far give the local levels.
    pub far_px: usize,
    /// The crossing is searched this far on both sides of the pair.
    pub search_px: usize,
}

impl EdgeWindows {
    /// The windows for edges of sharp images and blurs up to σ ≈ 1.5 px: levels 3–6 px from the
    /// edge, crossing within 5 px.
    pub const SHARP: EdgeWindows = EdgeWindows {
        near_px: 3,
        far_px: 6,
        search_px: 5,
    };

    /// The windows for a model's edges under the nominal `imaging` settings, on pixels of
    /// `pitch_mm`, for an object whose distance from the detector is `magnified_fraction` times
    /// its distance from the source (object-to-detector over source-to-object): those of its
    /// [`nominal_blur_px`].
    pub fn for_imaging(imaging: &Imaging, pitch_mm: f64, magnified_fraction: f64) -> EdgeWindows {
        EdgeWindows::for_blur(nominal_blur_px(imaging, pitch_mm, magnified_fraction))
    }

    /// The windows for an edge blurred by a total standard deviation of `sigma_px` pixels: the
    /// levels are read from 2σ beyond the edge (at least 3 px, where a Gaussian edge has
    /// reached 98 % of its step) over 4 px, the crossing searched as far as the levels start
    /// plus 2 px. Sharp or mildly blurred images (σ ≤ 1.5 px) get [`EdgeWindows::SHARP`].
    pub fn for_blur(sigma_px: f64) -> EdgeWindows {
        let near = if sigma_px.is_finite() {
            (2.0 * sigma_px).ceil().clamp(3.0, 30.0) as usize
        } else {
            3
        };
        EdgeWindows {
            near_px: near,
            far_px: near + 3,
            search_px: near + 2,
        }
    }
}

/// The nominal blur of a model's edge, SD in pixels of `pitch_mm`, for an object whose
/// distance from the detector is `magnified_fraction` times its distance from the source: the
/// standard deviations of the detector's Gaussian PSF, of the focal spot's projected penumbra
/// (a uniform spot of side a: a/√12; a Gaussian of FWHM a: a/2.3548; times
/// `magnified_fraction`) and of the pixel's sampling added in quadrature. An MTF table is not
/// read (its blur is taken as none). A pixel of `pixel_samples` s is the mean of s × s rays on a
/// regular grid over its area: along each axis a uniform distribution over s points one s-th of
/// a pixel apart, of variance (1 − 1/s²)/12 px², which is 0 for one ray to the pixel centre
/// (such an image samples the edge; it does not average it). The pixel used to count 1/12 px²
/// whatever its sampling: on sharp images the predicted edge profile was then blurred where the
/// image is not, which held the silhouette fit of runs n3-r06 and n4-r17 of
/// `biplanar_realistic` just beyond 0.1°.
pub fn nominal_blur_px(imaging: &Imaging, pitch_mm: f64, magnified_fraction: f64) -> f64 {
    let psf_mm = imaging.detector.psf.as_ref().map_or(0.0, |p| p.sigma_mm);
    let spot_mm = imaging
        .focal_spot
        .as_ref()
        .map_or(0.0, |f| match f.profile {
            SpotProfile::Uniform => f.size_mm / 12f64.sqrt(),
            SpotProfile::Gaussian => f.size_mm / 2.3548,
        })
        * magnified_fraction.max(0.0);
    let s = f64::from(imaging.pixel_samples.unwrap_or(1).max(1));
    let sampling = (1.0 - 1.0 / (s * s)) / 12.0;
    ((psf_mm * psf_mm + spot_mm * spot_mm) / (pitch_mm * pitch_mm) + sampling).sqrt()
}

/// The implant's dense shadow in `img` (module docs; `expected_area_px`: see
/// [`dense_shadow`]), with its sub-pixel edge points measured with `windows`. `None` when the
/// image has no dense component.
pub fn graded_outline(
    img: &Density,
    windows: EdgeWindows,
    expected_area_px: Option<f64>,
) -> Option<Outline> {
    if img.width < 2 || img.height < 2 {
        return None;
    }
    graded_outline_of(img, windows, &dense_shadow(img, expected_area_px)?)
}

/// [`graded_outline`] of the implant's dense shadow already segmented (`shadow`, as
/// [`dense_shadow`] gives it for `img`).
pub fn graded_outline_of(img: &Density, windows: EdgeWindows, shadow: &Shadow) -> Option<Outline> {
    let (w, h) = (img.width, img.height);
    if w < 2 || h < 2 {
        return None;
    }
    let (mask, largest, level) = (&shadow.mask, &shadow.blob, shadow.level);
    let [i0, j0, i1, j1] = largest.bbox.map(|v| v as usize);
    let mut edge_points = Vec::new();
    for j in j0.saturating_sub(1)..=(j1 + 1).min(h - 1) {
        for i in i0.saturating_sub(1)..=(i1 + 1).min(w - 1) {
            let here = mask[j * w + i];
            if i + 1 < w && here != mask[j * w + i + 1] && along_normal(img, i, j, i + 1, j) {
                let profile = |k: i64| {
                    let x = i as i64 + k;
                    (x >= 0 && (x as usize) < w)
                        .then(|| (img.transmission(x as usize, j), mask[j * w + x as usize]))
                };
                if let Some(u) = crossing(profile, here, Some(level), windows) {
                    edge_points.push(DVec2::new(i as f64 + 0.5 + u, j as f64 + 0.5));
                }
            }
            if j + 1 < h && here != mask[(j + 1) * w + i] && along_normal(img, i, j, i, j + 1) {
                let profile = |k: i64| {
                    let y = j as i64 + k;
                    (y >= 0 && (y as usize) < h)
                        .then(|| (img.transmission(i, y as usize), mask[y as usize * w + i]))
                };
                if let Some(v) = crossing(profile, here, Some(level), windows) {
                    edge_points.push(DVec2::new(i as f64 + 0.5, j as f64 + 0.5 + v));
                }
            }
        }
    }
    Some(Outline {
        width: w,
        height: h,
        mask: mask.clone(),
        area: largest.area,
        centroid: largest.centroid,
        edge_points,
    })
}

/// Whether the line through the neighbouring pixels (i0, j0) and (i1, j1) runs within 45° of
/// the edge's normal there (the transmission's Sobel gradient averaged over both pixels): a
/// profile nearly along the edge crosses its half-way level far from where the pair lies, and
/// imprecisely. Every edge point is then measured along the row or the column that crosses the
/// edge more steeply.
fn along_normal(img: &Density, i0: usize, j0: usize, i1: usize, j1: usize) -> bool {
    let g = sobel(img, i0, j0) + sobel(img, i1, j1);
    if i1 != i0 {
        g.x.abs() >= g.y.abs()
    } else {
        g.y.abs() > g.x.abs()
    }
}

/// The Sobel gradient of the transmission at pixel (i, j), the image clamped at its borders.
fn sobel(img: &Density, i: usize, j: usize) -> DVec2 {
    let t = |di: i64, dj: i64| {
        let x = (i as i64 + di).clamp(0, img.width as i64 - 1) as usize;
        let y = (j as i64 + dj).clamp(0, img.height as i64 - 1) as usize;
        img.transmission(x, y)
    };
    let gx = (t(1, -1) + 2.0 * t(1, 0) + t(1, 1)) - (t(-1, -1) + 2.0 * t(-1, 0) + t(-1, 1));
    let gy = (t(-1, 1) + 2.0 * t(0, 1) + t(1, 1)) - (t(-1, -1) + 2.0 * t(0, -1) + t(1, -1));
    DVec2::new(gx, gy)
}

/// The sub-pixel offset from pixel 0's centre (towards pixel 1) where the transmission profile
/// crosses the local half-way level, for a pair (0, 1) of which pixel 0 is inside iff
/// `first_inside`. `profile(k)` is pixel k's transmission and whether it is in the shadow, or
/// `None` off the image. `level` is the segmentation's attenuation level: the local plateau must
/// lie above it and the local background below it (with `None`, only the step is checked).
///
/// The levels are read `windows.near_px..=windows.far_px` from the current edge estimate (first
/// the pair's boundary, then the crossing found), so a shadow mask that sits a few pixels inside
/// a blurred edge still yields the edge's half-way crossing.
fn crossing(
    profile: impl Fn(i64) -> Option<(f64, bool)>,
    first_inside: bool,
    level: Option<f64>,
    windows: EdgeWindows,
) -> Option<f64> {
    let outward = if first_inside { 1.0 } else { -1.0 };
    let reach = (windows.search_px + windows.far_px + 1) as i64;
    let (near, far) = (windows.near_px as f64, windows.far_px as f64);
    let t_level = level.map(|l| libm::exp(-l));
    let median = |mut v: Vec<f64>| -> Option<f64> {
        if v.len() < 2 {
            return None;
        }
        let mid = v.len() / 2;
        Some(*v.select_nth_unstable_by(mid, f64::total_cmp).1)
    };
    let mut centre = 0.5;
    let mut found = None;
    for _ in 0..2 {
        // (distance from the current estimate, transmission) of the level samples on each side.
        let (mut inside, mut outside, mut between) = (Vec::new(), Vec::new(), Vec::new());
        for k in -reach..=reach {
            let Some((t, in_shadow)) = profile(k) else {
                continue;
            };
            let d = (k as f64 - centre) * outward;
            if in_shadow && (near..=far).contains(&-d) {
                inside.push((-d, t));
            } else if !in_shadow && (near..=far).contains(&d) {
                outside.push((d, t));
            } else if d.abs() < near {
                between.push(t);
            }
        }
        let levels = |side: &[(f64, f64)]| median(side.iter().map(|&(_, t)| t).collect());
        let (t_in, t_out) = (levels(&inside)?, levels(&outside)?);
        if level.is_none() && !clean(&inside, &outside, &between, 0.5 * (near + far), t_in, t_out) {
            return None;
        }
        let straddles = t_level.is_none_or(|t| t_in <= t && t <= t_out);
        if !(straddles && t_in <= MAX_INSIDE_FRACTION * t_out) {
            return None;
        }
        let half = 0.5 * (t_in + t_out);
        // Crossings of `half` between consecutive pixels k, k+1 within the search span of the
        // pair; the one nearest the current estimate wins.
        let span = windows.search_px as i64;
        let mut best: Option<(f64, f64)> = None;
        for k in -span..=span {
            let (Some((a, _)), Some((b, _))) = (profile(k), profile(k + 1)) else {
                continue;
            };
            if (a - half) * (b - half) > 0.0 || a == b {
                continue;
            }
            let u = k as f64 + (half - a) / (b - a);
            let d = (u - centre).abs();
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, u));
            }
        }
        let (_, u) = best?;
        centre = u;
        found = Some(u);
    }
    found
}

/// Whether an edge profile is a clean step between the local levels `t_in` and `t_out`: each
/// side's level samples `(distance, transmission)` are flat ([`flat`]) and the samples
/// `between` the two level windows stay within the levels, give or take [`MAX_LEVEL_DRIFT`] of
/// the step. Where another structure (bone beside the implant, a bead, a gap of tissue between
/// implant and bone) lies within the windows, the levels read there are not the edge's own and
/// the half-way crossing would be pulled off the edge: such a profile gives no point.
fn clean(
    inside: &[(f64, f64)],
    outside: &[(f64, f64)],
    between: &[f64],
    mid: f64,
    t_in: f64,
    t_out: f64,
) -> bool {
    let step = t_out - t_in;
    let slack = MAX_LEVEL_DRIFT * step.abs();
    let (lo, hi) = (t_in.min(t_out) - slack, t_in.max(t_out) + slack);
    flat(inside, mid, step)
        && flat(outside, mid, step)
        && between.iter().all(|t| (lo..=hi).contains(t))
}

/// Whether the level samples `(distance, transmission)` of one side of an edge are flat: the
/// mean of those nearer than `mid` differs from the mean of the others by at most
/// [`MAX_LEVEL_DRIFT`] of the edge's `step`. A side with samples on only one side of `mid`
/// counts as flat.
fn flat(side: &[(f64, f64)], mid: f64, step: f64) -> bool {
    let mean = |near: bool| {
        let (sum, n) = side
            .iter()
            .filter(|&&(d, _)| (d < mid) == near)
            .fold((0.0, 0usize), |(s, n), &(_, t)| (s + t, n + 1));
        (n > 0).then(|| sum / n as f64)
    };
    match (mean(true), mean(false)) {
        (Some(a), Some(b)) => (a - b).abs() <= MAX_LEVEL_DRIFT * step,
        _ => true,
    }
}

/// How far the two halves of a side's level window may differ, and the samples between the
/// windows may stray beyond the levels, as a fraction of the edge's step in transmission (see
/// [`clean`]): a Gaussian edge blurred as the windows expect is within 2 % of its levels there,
/// and quantum noise at the lowest exposures moves a sample by a few per cent of a metal edge's
/// step.
pub const MAX_LEVEL_DRIFT: f64 = 0.15;

/// Edge points measured along the normals of a predicted outline (`segments`, the model's
/// projected outline at a pose close to the truth): every [`ALONG_OUTLINE_SPACING_PX`] of outline
/// length, the transmission is read along the segment's normal through that point (bilinear
/// between pixel centres, one sample per pixel of distance) and the edge found there as for a
/// pixel pair ([`crossing`]: half-way between the local plateau and background, read
/// `windows.near_px..=windows.far_px` from the edge, twice), the denser side being the implant's.
/// Unlike the points of [`graded_outline`], these do not depend on the segmentation: where the
/// implant's thin rim reads less dense than bone beside it (a lateral view under scatter), the
/// shadow found may leave the rim out, but its edge is still a step along the outline's normal.
/// With `predicted`, each point is moved back along the normal by the crossing the model
/// predicts there (the implant's own graded edge, [`super::edge_model`]), and left out where
/// the prediction has none.
pub fn edge_points_along_outline(
    img: &Density,
    segments: &[OutlineSegment],
    windows: EdgeWindows,
    predicted: Option<PredictedCrossing>,
) -> Vec<DVec2> {
    let (w, h) = (img.width, img.height);
    let sample = |p: DVec2| -> Option<f64> {
        // Bilinear in transmission between the four pixel centres around p.
        let (x, y) = (p.x - 0.5, p.y - 0.5);
        if !(x >= 0.0 && y >= 0.0 && x < (w - 1) as f64 && y < (h - 1) as f64) {
            return None;
        }
        let (i, j) = (x.floor() as usize, y.floor() as usize);
        let (fx, fy) = (x - i as f64, y - j as f64);
        let t = |di: usize, dj: usize| img.transmission(i + di, j + dj);
        Some(
            (1.0 - fy) * ((1.0 - fx) * t(0, 0) + fx * t(1, 0))
                + fy * ((1.0 - fx) * t(0, 1) + fx * t(1, 1)),
        )
    };
    let reach = (windows.search_px + windows.far_px + 2) as i64;
    let mut points = Vec::new();
    let mut carried = 0.0;
    for s in segments {
        let d = s.uv[1] - s.uv[0];
        let length = d.length();
        if !(length > 0.0) {
            continue;
        }
        let normal = DVec2::new(-d.y, d.x) / length;
        let mut at = ALONG_OUTLINE_SPACING_PX - carried;
        while at <= length {
            let q = s.uv[0] + d * (at / length);
            at += ALONG_OUTLINE_SPACING_PX;
            // Samples k = −reach..=reach at q + (k − ½)·n: the pair (0, 1) straddles q.
            let t: Vec<Option<f64>> = (-reach..=reach)
                .map(|k| sample(q + normal * (k as f64 - 0.5)))
                .collect();
            let at_k = |k: i64| t.get((k + reach) as usize).copied().flatten();
            let side_mean = |sign: i64| {
                let v: Vec<f64> = (windows.near_px as i64..=windows.far_px as i64)
                    .filter_map(|m| at_k(if sign < 0 { 1 - m } else { m }))
                    .collect();
                (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
            };
            let (Some(before), Some(after)) = (side_mean(-1), side_mean(1)) else {
                continue;
            };
            // The implant lies on the side that transmits less.
            let first_inside = before < after;
            let profile = |k: i64| at_k(k).map(|v| (v, (k <= 0) == first_inside));
            let Some(u) = crossing(profile, first_inside, None, windows) else {
                continue;
            };
            let shift = match predicted {
                Some(predict) => match predict(q, normal) {
                    Some(c) => c,
                    None => continue,
                },
                None => 0.0,
            };
            points.push(q + normal * (u - 0.5 - shift));
        }
        carried = length - (at - ALONG_OUTLINE_SPACING_PX);
    }
    points
}

/// Where the edge profile along `normal` (unit) through the outline point `q` is predicted to
/// cross its half-way level, pixels along `normal` from `q` (see [`super::edge_model`]); `None`
/// where it predicts no clean step.
pub type PredictedCrossing<'p> = &'p dyn Fn(DVec2, DVec2) -> Option<f64>;

/// The spacing of the points [`edge_points_along_outline`] measures, pixels of outline length.
pub const ALONG_OUTLINE_SPACING_PX: f64 = 1.0;

#[cfg(test)]
mod tests {
    use super::*;

    /// An attenuation image of an opaque disc of radius `r` at `c` over a background of
    /// attenuation 2, area-sampled, optionally blurred by a Gaussian of `sigma` px (in
    /// transmission, where blur acts).
    pub(crate) fn disc(w: usize, h: usize, c: DVec2, r: f64, sigma: f64) -> Density {
        let mut values = vec![0.0; w * h];
        for j in 0..h {
            for i in 0..w {
                let mut inside = 0;
                for sy in 0..6 {
                    for sx in 0..6 {
                        let p = DVec2::new(
                            i as f64 + (sx as f64 + 0.5) / 6.0,
                            j as f64 + (sy as f64 + 0.5) / 6.0,
                        );
                        if (p - c).length() <= r {
                            inside += 1;
                        }
                    }
                }
                let f = f64::from(inside) / 36.0;
                values[j * w + i] = -libm::log(libm::exp(-2.0) * (1.0 - f) + libm::exp(-9.0) * f);
            }
        }
        let sharp = Density {
            width: w,
            height: h,
            values,
            clipped: vec![false; w * h],
        };
        if sigma > 0.0 {
            sharp.blurred(sigma)
        } else {
            sharp
        }
    }

    fn mean_radius(o: &Outline, c: DVec2) -> f64 {
        o.edge_points.iter().map(|p| (*p - c).length()).sum::<f64>() / o.edge_points.len() as f64
    }

    #[test]
    fn a_sharp_disc_outline_is_unbiased() {
        let c = DVec2::new(60.3, 55.8);
        let o = graded_outline(&disc(120, 110, c, 30.2, 0.0), EdgeWindows::SHARP, None).unwrap();
        let r = mean_radius(&o, c);
        assert!((r - 30.2).abs() < 0.03, "{r}");
    }

    #[test]
    fn a_blurred_disc_outline_stays_on_the_edge() {
        // A Gaussian blur of σ moves a disc's half-level contour inwards only by the curvature
        // term σ²/(2R) (0.04 px at σ = 1.5 px, R = 30.2 px); the outline follows it to 0.03 px
        // on average, each point within 0.05 px (SD), for σ up to 1.5 px. (A fixed threshold
        // at the segmentation's level would sit 2.8σ inside the edge.)
        let c = DVec2::new(60.3, 55.8);
        for sigma in [0.5, 0.8, 1.0, 1.5] {
            let o =
                graded_outline(&disc(120, 110, c, 30.2, sigma), EdgeWindows::SHARP, None).unwrap();
            let r = mean_radius(&o, c);
            let n = o.edge_points.len() as f64;
            let sd = (o
                .edge_points
                .iter()
                .map(|p| ((*p - c).length() - r).powi(2))
                .sum::<f64>()
                / n)
                .sqrt();
            let expected = 30.2 - sigma * sigma / (2.0 * 30.2);
            assert!((r - expected).abs() < 0.03, "σ {sigma}: {r} vs {expected}");
            assert!(sd < 0.05 && n > 140.0, "σ {sigma}: SD {sd} over {n} points");
        }
    }

    /// `img` with an additive scatter veil of `veil` (a fraction of the open field) in
    /// transmission: the metal then reads `−ln(veil)` instead of clipping.
    fn with_veil(img: &Density, veil: f64) -> Density {
        Density {
            values: img
                .values
                .iter()
                .map(|v| -libm::log(libm::exp(-v) + veil))
                .collect(),
            ..img.clone()
        }
    }

    #[test]
    fn a_scatter_veil_leaves_the_outline_on_the_edge() {
        // A veil of 3 % of the open field lifts the disc from 9 to 3.5 and the background from
        // 2 to 1.8; the half-way crossing in transmission does not move.
        let c = DVec2::new(60.3, 55.8);
        for sigma in [0.0, 1.0] {
            let sharp = disc(120, 110, c, 30.2, 0.0);
            let veiled = with_veil(&sharp, 0.03);
            let img = if sigma > 0.0 {
                veiled.blurred(sigma)
            } else {
                veiled
            };
            let o = graded_outline(&img, EdgeWindows::SHARP, None).unwrap();
            let r = mean_radius(&o, c);
            let expected = 30.2 - sigma * sigma / (2.0 * 30.2);
            assert!(
                (r - expected).abs() < 0.03 && o.edge_points.len() > 140,
                "σ {sigma}: {r} vs {expected} over {} points",
                o.edge_points.len()
            );
        }
    }

    #[test]
    fn windows_widened_for_the_blur_keep_a_blurred_outline_unbiased() {
        // σ = 2.5 px: levels read 3–6 px from the edge still lie in its graded part; the
        // windows for that blur (5–8 px) lie beyond it.
        let c = DVec2::new(60.3, 55.8);
        let sigma = 2.5;
        let img = disc(120, 110, c, 30.2, sigma);
        let expected = 30.2 - sigma * sigma / (2.0 * 30.2);
        let wide = EdgeWindows::for_blur(sigma);
        assert_eq!((wide.near_px, wide.far_px, wide.search_px), (5, 8, 7));
        let r_wide = mean_radius(&graded_outline(&img, wide, None).unwrap(), c);
        let r_sharp = mean_radius(&graded_outline(&img, EdgeWindows::SHARP, None).unwrap(), c);
        // Measured: 0.11 px inside with the wide windows, 0.93 px with the sharp ones.
        assert!((r_wide - expected).abs() < 0.15, "{r_wide} vs {expected}");
        assert!(
            (r_sharp - expected).abs() > 5.0 * (r_wide - expected).abs(),
            "{r_sharp}"
        );
    }

    #[test]
    fn the_windows_follow_the_nominal_blur() {
        // biplanar_realistic_blurred's PSF and spot, one ray per pixel: σ 0.15 mm PSF, 1.2 mm
        // uniform spot, 0.2986 mm pixels, model 500 mm from the detector and 1300 mm from the
        // source: σ ≈ 0.67 px, the sharp windows; a 1 mm PSF asks for wider ones.
        let mut imaging: Imaging = toml::from_str(
            "mode = \"attenuation\"\nfocal_spot = { size_mm = 1.2 }\n[detector]\npsf = { sigma_mm = 0.15 }\n",
        )
        .unwrap();
        assert_eq!(
            EdgeWindows::for_imaging(&imaging, 0.2986, 500.0 / 1300.0),
            EdgeWindows::SHARP
        );
        imaging.detector.psf = Some(crate::scenario::PsfOption { sigma_mm: 1.0 });
        // σ = √((1.0² + (0.346·0.385)²)/0.2986²) = 3.38 px → levels from 7 px.
        assert_eq!(
            EdgeWindows::for_imaging(&imaging, 0.2986, 500.0 / 1300.0).near_px,
            7
        );
    }

    #[test]
    fn a_pixel_blurs_by_its_sampling_not_by_its_area() {
        // s × s rays per pixel: along each axis s points 1/s px apart, a discrete uniform
        // distribution of variance (s² − 1)/(12 s²) px² (by hand: s = 2, offsets ±1/4, variance
        // 1/16). One ray to the centre samples the edge and does not blur it.
        let sigma = |samples: &str| {
            let imaging: Imaging =
                toml::from_str(&format!("mode = \"attenuation\"\n{samples}")).unwrap();
            nominal_blur_px(&imaging, 0.3, 0.4)
        };
        assert_eq!(sigma(""), 0.0);
        assert_eq!(sigma("pixel_samples = 1"), 0.0);
        assert!((sigma("pixel_samples = 2") - 0.25).abs() < 1e-12);
        let by_hand_4 = [-0.375f64, -0.125, 0.125, 0.375]
            .iter()
            .map(|x| x * x / 4.0)
            .sum::<f64>()
            .sqrt();
        assert!((sigma("pixel_samples = 4") - by_hand_4).abs() < 1e-12);
        assert!((sigma("pixel_samples = 16") - (1.0f64 / 12.0).sqrt()).abs() < 0.01);
    }

    #[test]
    fn bone_touching_the_implant_is_not_its_shadow() {
        // Mostly air (the image's median 0), a leg of attenuation 2.5, a bone of 4.0 ending on
        // the implant (a clipped disc of attenuation 7, radius 20 px): a level half-way between
        // the median and the plateau would merge the bone; the surroundings' level does not.
        let (w, h) = (160, 150);
        let c = DVec2::new(80.4, 60.7);
        let values: Vec<f64> = (0..w * h)
            .map(|k| {
                let p = DVec2::new((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
                if (p - c).length() <= 20.0 {
                    7.0
                } else if (p.x - 80.0).abs() < 12.0 && p.y > 60.0 && p.y < 140.0 {
                    4.0
                } else if (p.x - 80.0).abs() < 30.0 {
                    2.5
                } else {
                    0.0
                }
            })
            .collect();
        let img = Density {
            width: w,
            height: h,
            clipped: values.iter().map(|&v| v >= 7.0).collect(),
            values,
        };
        let o = graded_outline(&img, EdgeWindows::SHARP, None).unwrap();
        let disc_area = std::f64::consts::PI * 400.0;
        assert!(
            (o.area as f64 - disc_area).abs() < 0.03 * disc_area,
            "{}",
            o.area
        );
        let r = mean_radius(&o, c);
        assert!((r - 20.0).abs() < 0.1, "{r}");
    }

    /// A circle of `n` segments (continuous pixel coordinates), as a projected outline.
    fn circle_segments(c: DVec2, r: f64, n: usize) -> Vec<OutlineSegment> {
        let at = |k: usize| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            c + DVec2::new(a.cos(), a.sin()) * r
        };
        (0..n)
            .map(|k| OutlineSegment {
                uv: [at(k), at(k + 1)],
                world_mm: [glam::DVec3::ZERO; 2],
            })
            .collect()
    }

    #[test]
    fn points_along_a_predicted_outline_find_the_blurred_edge_under_a_veil() {
        // A disc of radius 20 px blurred by σ = 2 px under a veil, and an outline predicted
        // 1.5 px off-centre and 0.8 px too large: every point lies on the true edge.
        let c = DVec2::new(60.3, 59.6);
        let img = with_veil(&disc(120, 120, c, 20.0, 2.0), 0.05);
        let windows = EdgeWindows::for_blur(2.0);
        let predicted = circle_segments(c + DVec2::new(1.5, 0.0), 20.8, 720);
        let points = edge_points_along_outline(&img, &predicted, windows, None);
        // About one point per pixel of outline length (2π·20.8 ≈ 131).
        assert!(points.len() > 120 && points.len() < 140, "{}", points.len());
        // The half-level contour of a blurred disc lies σ²/(2R) = 0.1 px inside its edge
        // (as for the pixel-pair points above).
        let radii: Vec<f64> = points.iter().map(|p| (*p - c).length()).collect();
        let r = radii.iter().sum::<f64>() / radii.len() as f64;
        let sd = (radii.iter().map(|x| (x - r).powi(2)).sum::<f64>() / radii.len() as f64).sqrt();
        let expected = 20.0 - 2.0 * 2.0 / (2.0 * 20.0);
        assert!(
            (r - expected).abs() < 0.03 && sd < 0.05,
            "{r} vs {expected}, SD {sd}"
        );
    }

    #[test]
    fn bone_beside_the_implant_gives_no_points_along_the_outline() {
        // The disc touched by a bar of bone (attenuation 3, 6 px wide) ending 2 px from its rim:
        // the profiles whose background window holds the bone's edge give no point, and every
        // point given lies on the disc's edge.
        let c = DVec2::new(60.3, 59.6);
        let mut img = disc(120, 120, c, 20.0, 0.0);
        for j in 0..120 {
            for i in 0..120 {
                let p = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
                if (p.x - c.x).abs() < 3.0 && p.y > c.y + 22.0 {
                    img.values[j * 120 + i] = 3.0;
                }
            }
        }
        let points = edge_points_along_outline(
            &img.blurred(1.0),
            &circle_segments(c, 20.0, 720),
            EdgeWindows::SHARP,
            None,
        );
        // Without the checks, the profiles through the gap would put their points 0.9 px inside
        // (half-way between metal and bone is crossed on the metal's edge to tissue). Only
        // profiles grazing the bar's corners may still give a point a little off.
        // The blur (σ = 1 px) puts the half-level contour σ²/(2R) = 0.025 px inside the edge.
        let errors: Vec<f64> = points
            .iter()
            .map(|p| (*p - c).length() - (20.0 - 0.025))
            .collect();
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        assert!(mean.abs() < 0.015, "{mean}");
        let off = errors.iter().filter(|e| e.abs() >= 0.08).count();
        assert!(off <= 3 && points.len() > 100, "{off} of {}", points.len());
        let below = points
            .iter()
            .filter(|p| (p.x - c.x).abs() < 2.0 && p.y > c.y)
            .count();
        assert_eq!(below, 0);
    }
}
