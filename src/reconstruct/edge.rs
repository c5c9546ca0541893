//! The model's outline in an attenuation-mode image, where its edge is graded: partial pixels,
//! focal-spot penumbra and detector blur spread it over a few pixels.
//!
//! 1. **Segmentation**: the implant is far denser than anything around it. Its shadow is the
//!    largest 8-connected component of pixels whose attenuation is at least half-way between its
//!    surroundings and the implant's plateau (the image's 99.5th percentile). The surroundings
//!    are first the image's median, then twice the median of the pixels within [`RING_PX`] of
//!    the component found (bone next to the implant merges with it at the first level, never at
//!    the second). The component only seeds the edge search and the coarse pose search; the
//!    edge's position comes from step 2.
//! 2. **Edge points**: for every pair of horizontally or vertically neighbouring pixels of which
//!    exactly one is in the shadow, and whose row or column crosses the edge within 45° of its
//!    normal (the transmission's Sobel gradient), the profile along that row or column is read in
//!    *transmission* `S/S_open` (where blur is linear): the local plateau is the median of the
//!    inside pixels [`NEAR_PX`]..=[`FAR_PX`] from the pair, the local background the median of
//!    the outside ones, and the edge is where the profile crosses the level half-way between
//!    them, by linear interpolation between pixel centres, searched within [`SEARCH_PX`] of the
//!    pair; the levels are then read again from that crossing and the crossing found again
//!    (the segmentation's level may lie a few pixels inside a blurred edge). A symmetric blur of a straight edge crosses that level exactly at the edge, so the
//!    points are unbiased under it; on a sharp image the crossing is the pair's midpoint, as in
//!    binary mode. A pair whose local step is not an implant's (inside transmission above
//!    [`MAX_INSIDE_FRACTION`] of the outside) gives no point: a bead or bone touching the
//!    shadow is not its edge.

use glam::DVec2;

use super::contour::Outline;
use super::density::Density;
use super::detect::{Blob, components};

/// Profile samples nearer than this to the pair (pixels) are in the graded edge.
pub const NEAR_PX: usize = 3;
/// Profile samples up to this far from the pair (pixels) give the local levels.
pub const FAR_PX: usize = 6;
/// The crossing is searched this far (pixels) on both sides of the pair.
pub const SEARCH_PX: usize = 5;
/// The implant's local plateau transmits at most this fraction of its local background.
pub const MAX_INSIDE_FRACTION: f64 = 0.5;

/// The largest dense component of `img` (module docs), with its sub-pixel edge points. `None`
/// when the image has no dense component.
pub fn graded_outline(img: &Density) -> Option<Outline> {
    let (w, h) = (img.width, img.height);
    if w < 2 || h < 2 {
        return None;
    }
    let (mask, largest) = segment(img)?;
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
                if let Some(u) = crossing(profile, here) {
                    edge_points.push(DVec2::new(i as f64 + 0.5 + u, j as f64 + 0.5));
                }
            }
            if j + 1 < h && here != mask[(j + 1) * w + i] && along_normal(img, i, j, i, j + 1) {
                let profile = |k: i64| {
                    let y = j as i64 + k;
                    (y >= 0 && (y as usize) < h)
                        .then(|| (img.transmission(i, y as usize), mask[y as usize * w + i]))
                };
                if let Some(v) = crossing(profile, here) {
                    edge_points.push(DVec2::new(i as f64 + 0.5, j as f64 + 0.5 + v));
                }
            }
        }
    }
    Some(Outline {
        width: w,
        height: h,
        mask,
        area: largest.area,
        centroid: largest.centroid,
        edge_points,
    })
}

/// Pixels within this many pixels of the shadow (outside it) give its surroundings' level.
const RING_PX: usize = 8;

/// The implant's shadow (module docs, step 1) and its component.
fn segment(img: &Density) -> Option<(Vec<bool>, Blob)> {
    let (w, h) = (img.width, img.height);
    let mut sorted = img.values.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let plateau = sorted[(sorted.len() * 995) / 1000];
    if !(plateau > median) {
        return None;
    }
    let largest = |level: f64| -> Option<(Vec<bool>, Blob)> {
        let dense: Vec<u16> = img.values.iter().map(|&v| u16::from(v >= level)).collect();
        let (labels, blobs) = components(&dense, w, 1);
        let (index, blob) = blobs.iter().enumerate().max_by_key(|(_, b)| b.area)?;
        let id = index as u32 + 1;
        Some((labels.iter().map(|&l| l == id).collect(), blob.clone()))
    };
    let mut found = largest(0.5 * (median + plateau))?;
    for _ in 0..2 {
        let near = dilate(&found.0, w, h, RING_PX);
        let mut ring: Vec<f64> = (0..w * h)
            .filter(|&k| near[k] && !found.0[k])
            .map(|k| img.values[k])
            .collect();
        if ring.is_empty() {
            break;
        }
        let mid = ring.len() / 2;
        let surroundings = *ring.select_nth_unstable_by(mid, f64::total_cmp).1;
        if !(plateau > surroundings) {
            break;
        }
        found = largest(0.5 * (surroundings + plateau))?;
    }
    Some(found)
}

/// `mask` dilated by a square of half-size `r` (separable running counts).
fn dilate(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let pass = |src: &[bool], horizontal: bool| -> Vec<bool> {
        let (n, lines) = if horizontal { (w, h) } else { (h, w) };
        let at = |line: usize, k: usize| {
            if horizontal {
                line * w + k
            } else {
                k * w + line
            }
        };
        let mut out = vec![false; w * h];
        for line in 0..lines {
            let mut count = 0usize;
            for k in 0..(r).min(n) {
                count += usize::from(src[at(line, k)]);
            }
            for k in 0..n {
                if k + r < n {
                    count += usize::from(src[at(line, k + r)]);
                }
                if k > r {
                    count -= usize::from(src[at(line, k - r - 1)]);
                }
                out[at(line, k)] = count > 0;
            }
        }
        out
    };
    pass(&pass(mask, true), false)
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
/// `None` off the image.
///
/// The levels are read [`NEAR_PX`]..=[`FAR_PX`] from the current edge estimate (first the pair's
/// boundary, then the crossing found), so a shadow mask that sits a few pixels inside a blurred
/// edge still yields the edge's half-way crossing.
fn crossing(profile: impl Fn(i64) -> Option<(f64, bool)>, first_inside: bool) -> Option<f64> {
    let outward = if first_inside { 1.0 } else { -1.0 };
    let reach = (SEARCH_PX + FAR_PX + 1) as i64;
    let (near, far) = (NEAR_PX as f64, FAR_PX as f64);
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
        let (mut inside, mut outside) = (Vec::new(), Vec::new());
        for k in -reach..=reach {
            let Some((t, in_shadow)) = profile(k) else {
                continue;
            };
            let d = (k as f64 - centre) * outward;
            if in_shadow && (near..=far).contains(&-d) {
                inside.push(t);
            } else if !in_shadow && (near..=far).contains(&d) {
                outside.push(t);
            }
        }
        let (t_in, t_out) = (median(inside)?, median(outside)?);
        if !(t_in <= MAX_INSIDE_FRACTION * t_out) {
            return None;
        }
        let half = 0.5 * (t_in + t_out);
        // Crossings of `half` between consecutive pixels k, k+1 within the search span of the
        // pair; the one nearest the current estimate wins.
        let span = SEARCH_PX as i64;
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
        let o = graded_outline(&disc(120, 110, c, 30.2, 0.0)).unwrap();
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
            let o = graded_outline(&disc(120, 110, c, 30.2, sigma)).unwrap();
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
        let o = graded_outline(&img).unwrap();
        let disc_area = std::f64::consts::PI * 400.0;
        assert!(
            (o.area as f64 - disc_area).abs() < 0.03 * disc_area,
            "{}",
            o.area
        );
        let r = mean_radius(&o, c);
        assert!((r - 20.0).abs() < 0.1, "{r}");
    }
}
