//! Which blob is which bead: predict every bead's pixel position from the nominal set-up, align
//! the predictions to the blobs, and match, dropping anything ambiguous rather than guessing.
//!
//! 1. A global offset by voting: every (prediction, candidate blob) pair within `search_px`
//!    votes for its offset in a 2-D histogram; the densest bin wins. This absorbs the shift a
//!    displaced source or detector causes.
//! 2. Per group (a calibration plate), nearest-neighbour pairs that pass a ratio test fit a 2-D
//!    affine map from predictions to blobs, trimmed of outliers. This absorbs the detector's
//!    in-plane rotation and the magnification change.
//! 3. Final matching within a tight radius. A blob is a candidate for a bead only if its area is
//!    a bead's (not a merged pair, not a noise speck, not a mesh shadow); a blob claimed by two
//!    predictions is dropped with both.

use glam::DVec2;

use super::detect::{Blob, fits_one_bead};

/// A bead's predicted image position.
#[derive(Debug, Clone, PartialEq)]
pub struct Prediction {
    /// The bead's index in the caller's list.
    pub index: usize,
    /// Predicted continuous pixel coordinates.
    pub uv: DVec2,
    /// Expected blob area in pixels (π·(r·magnification/pitch)²).
    pub expected_area: f64,
    /// Alignment group (e.g. the plate); predictions of one group share an affine map.
    pub group: usize,
}

/// A bead matched to a blob.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    /// The bead's index (from [`Prediction::index`]).
    pub index: usize,
    /// The blob's index in the blob list.
    pub blob: usize,
    /// The blob's centroid.
    pub uv: DVec2,
}

/// Whether a blob's area fits a single bead of `expected` pixels.
fn bead_sized(blob: &Blob, expected: f64) -> bool {
    fits_one_bead(blob.area, expected)
}

/// A 2-D affine map `x ↦ A·x + t`.
#[derive(Debug, Clone, Copy)]
struct Affine {
    a: [[f64; 2]; 2],
    t: DVec2,
}

impl Affine {
    fn translation(t: DVec2) -> Affine {
        Affine {
            a: [[1.0, 0.0], [0.0, 1.0]],
            t,
        }
    }

    fn apply(&self, x: DVec2) -> DVec2 {
        DVec2::new(
            self.a[0][0] * x.x + self.a[0][1] * x.y,
            self.a[1][0] * x.x + self.a[1][1] * x.y,
        ) + self.t
    }

    /// Least-squares fit of `to ≈ A·from + t` (needs ≥ 3 non-collinear pairs).
    fn fit(from: &[DVec2], to: &[DVec2]) -> Option<Affine> {
        let n = from.len();
        if n < 3 {
            return None;
        }
        let cf = from.iter().copied().sum::<DVec2>() / n as f64;
        let ct = to.iter().copied().sum::<DVec2>() / n as f64;
        let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
        let (mut bx, mut by) = ([0.0; 2], [0.0; 2]);
        for (f, t) in from.iter().zip(to) {
            let (p, q) = (*f - cf, *t - ct);
            sxx += p.x * p.x;
            sxy += p.x * p.y;
            syy += p.y * p.y;
            bx = [bx[0] + p.x * q.x, bx[1] + p.y * q.x];
            by = [by[0] + p.x * q.y, by[1] + p.y * q.y];
        }
        let det = sxx * syy - sxy * sxy;
        if det.abs() < 1e-9 * (sxx * syy).max(1e-300) {
            return None;
        }
        let solve = |b: [f64; 2]| {
            [
                (syy * b[0] - sxy * b[1]) / det,
                (sxx * b[1] - sxy * b[0]) / det,
            ]
        };
        let (r0, r1) = (solve(bx), solve(by));
        let a = [r0, r1];
        let aff = Affine { a, t: DVec2::ZERO };
        Some(Affine {
            a,
            t: ct - aff.apply(cf),
        })
    }
}

/// The offset (blob − prediction) that brings the most predictions within 30 px of a bead-sized
/// blob. Candidates are the peaks of a vote over all (prediction, blob) pairs within
/// `search_px`. On a regular grid a shift by one grid period also collects votes; scoring by
/// coverage rejects it, because a shifted grid loses a whole border row or column.
fn voted_offset(preds: &[Prediction], blobs: &[Blob], search_px: f64) -> DVec2 {
    const BIN_PX: f64 = 6.0;
    const COVER_PX: f64 = 30.0;
    let bins = (2.0 * search_px / BIN_PX).ceil() as usize + 1;
    let mut votes = vec![0u32; bins * bins];
    let candidates: Vec<Vec<usize>> = preds
        .iter()
        .map(|p| {
            (0..blobs.len())
                .filter(|&b| bead_sized(&blobs[b], p.expected_area))
                .collect()
        })
        .collect();
    for (p, cands) in preds.iter().zip(&candidates) {
        for &b in cands {
            let d = blobs[b].centroid - p.uv;
            let (x, y) = (
                ((d.x + search_px) / BIN_PX) as i64,
                ((d.y + search_px) / BIN_PX) as i64,
            );
            if d.length() <= search_px
                && x >= 0
                && y >= 0
                && (x as usize) < bins
                && (y as usize) < bins
            {
                votes[y as usize * bins + x as usize] += 1;
            }
        }
    }
    // The 24 strongest bins are the candidate offsets (ties broken by bin order: deterministic).
    let mut order: Vec<usize> = (0..votes.len()).filter(|&k| votes[k] > 0).collect();
    order.sort_by(|&a, &b| votes[b].cmp(&votes[a]).then(a.cmp(&b)));
    order.truncate(24);
    let coverage = |offset: DVec2| -> usize {
        preds
            .iter()
            .zip(&candidates)
            .filter(|(p, cands)| {
                cands
                    .iter()
                    .any(|&b| (blobs[b].centroid - p.uv - offset).length() <= COVER_PX)
            })
            .count()
    };
    let mut best = (0usize, f64::INFINITY, DVec2::ZERO);
    for k in order {
        let offset = DVec2::new((k % bins) as f64 + 0.5, (k / bins) as f64 + 0.5) * BIN_PX
            - DVec2::splat(search_px);
        let score = coverage(offset);
        if score > best.0 || (score == best.0 && offset.length() < best.1) {
            best = (score, offset.length(), offset);
        }
    }
    best.2
}

/// For each prediction (through `map`), the nearest bead-sized blob within `radius_px`, if it is
/// unambiguous: the second-nearest candidate must be at least `ratio` times farther.
fn nearest_pairs(
    preds: &[Prediction],
    blobs: &[Blob],
    map: impl Fn(&Prediction) -> DVec2,
    radius_px: f64,
    ratio: f64,
) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for (k, p) in preds.iter().enumerate() {
        let at = map(p);
        let mut best = (f64::INFINITY, usize::MAX);
        let mut second = f64::INFINITY;
        for (bi, b) in blobs.iter().enumerate() {
            if !bead_sized(b, p.expected_area) {
                continue;
            }
            let d = (b.centroid - at).length();
            if d < best.0 {
                second = best.0;
                best = (d, bi);
            } else if d < second {
                second = d;
            }
        }
        if best.0 <= radius_px && second >= ratio * best.0.max(0.5) {
            out.push((k, best.1));
        }
    }
    out
}

/// Unique matches within `radius_px` of the mapped predictions; a blob wanted by two beads, or a
/// bead with two blobs in reach, is dropped.
fn unique_matches(
    preds: &[Prediction],
    blobs: &[Blob],
    map: impl Fn(&Prediction) -> DVec2,
    radius_px: f64,
) -> Vec<Match> {
    let pairs = nearest_pairs(preds, blobs, map, radius_px, 2.0);
    let mut claims = vec![0u32; blobs.len()];
    for &(_, b) in &pairs {
        claims[b] += 1;
    }
    pairs
        .into_iter()
        .filter(|&(_, b)| claims[b] == 1)
        .map(|(k, b)| Match {
            index: preds[k].index,
            blob: b,
            uv: blobs[b].centroid,
        })
        .collect()
}

/// Matches beads to blobs starting from nominal predictions that may be off by up to
/// `search_px` (a global shift plus a smaller per-group distortion).
pub fn match_beads(preds: &[Prediction], blobs: &[Blob], search_px: f64) -> Vec<Match> {
    let offset = voted_offset(preds, blobs, search_px);
    let shifted = Affine::translation(offset);
    let groups: Vec<usize> = {
        let mut g: Vec<usize> = preds.iter().map(|p| p.group).collect();
        g.sort_unstable();
        g.dedup();
        g
    };
    let mut maps: Vec<(usize, Affine)> = Vec::new();
    for &g in &groups {
        let members: Vec<Prediction> = preds.iter().filter(|p| p.group == g).cloned().collect();
        // Residual distortion after the global shift: rotation of a few degrees and scale.
        let mut map = shifted;
        for radius in [search_px / 3.0, 12.0, 6.0] {
            let pairs = nearest_pairs(&members, blobs, |p| map.apply(p.uv), radius, 1.8);
            let from: Vec<DVec2> = pairs.iter().map(|&(k, _)| members[k].uv).collect();
            let to: Vec<DVec2> = pairs.iter().map(|&(_, b)| blobs[b].centroid).collect();
            if let Some(fitted) = trimmed_affine(&from, &to) {
                map = fitted;
            }
        }
        maps.push((g, map));
    }
    let map_of = |p: &Prediction| {
        maps.iter()
            .find(|(g, _)| *g == p.group)
            .map_or(shifted, |(_, m)| *m)
            .apply(p.uv)
    };
    unique_matches(preds, blobs, map_of, 4.0)
}

/// Matches predictions that are already accurate (from a calibrated beamline) within `radius_px`.
pub fn match_near(preds: &[Prediction], blobs: &[Blob], radius_px: f64) -> Vec<Match> {
    unique_matches(preds, blobs, |p| p.uv, radius_px)
}

/// An affine fit that drops pairs off by more than max(3 px, 3 × median) and refits.
fn trimmed_affine(from: &[DVec2], to: &[DVec2]) -> Option<Affine> {
    let mut keep: Vec<usize> = (0..from.len()).collect();
    let mut fit = None;
    for _ in 0..4 {
        let f: Vec<DVec2> = keep.iter().map(|&k| from[k]).collect();
        let t: Vec<DVec2> = keep.iter().map(|&k| to[k]).collect();
        let a = Affine::fit(&f, &t)?;
        let mut res: Vec<f64> = keep
            .iter()
            .map(|&k| (a.apply(from[k]) - to[k]).length())
            .collect();
        fit = Some(a);
        let mut sorted = res.clone();
        sorted.sort_by(f64::total_cmp);
        let limit = (3.0 * sorted[sorted.len() / 2]).max(3.0);
        let before = keep.len();
        let mut k = 0;
        keep.retain(|_| {
            let ok = res[k] <= limit;
            k += 1;
            ok
        });
        res.clear();
        if keep.len() == before || keep.len() < 3 {
            break;
        }
    }
    fit
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blob(u: f64, v: f64, area: usize) -> Blob {
        Blob {
            centroid: DVec2::new(u, v),
            area,
            bbox: [0; 4],
        }
    }

    #[test]
    fn a_shifted_rotated_grid_is_matched_and_merged_blobs_are_dropped() {
        // A 9×9 grid at 86 px spacing, seen shifted by (70, −55) px and turned 2°.
        let mut preds = Vec::new();
        let mut blobs = Vec::new();
        let (s, c) = (2f64.to_radians().sin(), 2f64.to_radians().cos());
        for j in 0..9 {
            for i in 0..9 {
                let p = DVec2::new(300.0 + 86.0 * i as f64, 300.0 + 86.0 * j as f64);
                preds.push(Prediction {
                    index: preds.len(),
                    uv: p,
                    expected_area: 15.0,
                    group: 0,
                });
                let q = p - DVec2::splat(644.0);
                let turned = DVec2::new(c * q.x - s * q.y, s * q.x + c * q.y)
                    + DVec2::splat(644.0)
                    + DVec2::new(70.0, -55.0);
                blobs.push(blob(turned.x, turned.y, 15));
            }
        }
        // Bead 40's blob merged with a neighbour (twice the area): it must not be matched.
        blobs[40].area = 31;
        // Noise specks and a large mesh shadow are never candidates.
        blobs.push(blob(500.0, 500.0, 1));
        blobs.push(blob(700.0, 700.0, 5000));
        let m = match_beads(&preds, &blobs, 120.0);
        assert_eq!(m.len(), 80, "{} matches", m.len());
        assert!(m.iter().all(|m| m.blob == m.index && m.index != 40));
    }

    #[test]
    fn two_predictions_in_one_blob_drop_both() {
        let preds = [
            Prediction {
                index: 0,
                uv: DVec2::new(10.0, 10.0),
                expected_area: 15.0,
                group: 0,
            },
            Prediction {
                index: 1,
                uv: DVec2::new(11.0, 10.0),
                expected_area: 15.0,
                group: 0,
            },
            Prediction {
                index: 2,
                uv: DVec2::new(50.0, 50.0),
                expected_area: 15.0,
                group: 0,
            },
        ];
        let blobs = [blob(10.5, 10.0, 15), blob(50.2, 49.9, 14)];
        let m = match_near(&preds, &blobs, 3.0);
        assert_eq!(m.len(), 1);
        assert_eq!(m[0].index, 2);
    }
}
