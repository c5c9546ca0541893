//! The sub-sources of a focal spot: a k×k product of one-dimensional nodes and weights along
//! the detector's r and c axes.
//!
//! * **Uniform** square of side a: nodes at the centres of k equal cells,
//!   `x_n = ((n + ½)/k − ½)·a`, weights 1/k.
//! * **Gaussian** of FWHM a (σ = a / (2·√(2 ln 2))): the k-point Gauss–Hermite rule for the
//!   normal distribution, nodes `σ·x_n` with x_n the roots of the probabilists' Hermite
//!   polynomial He_k, weights `k! / (k² · He_{k−1}(x_n)²)`. It integrates polynomials up to
//!   degree 2k − 1 exactly, so its mean is 0 and its variance σ² for every k ≥ 2.
//!
//! Roots are found by scanning for sign changes and bisecting in plain IEEE arithmetic (the
//! three-term recurrence `He_{n+1} = x·He_n − n·He_{n−1}`, no transcendental function), the
//! positive half mirrored so nodes and weights are symmetric bit for bit.

use crate::scenario::{AxisDirection, FocalSpot, SpotProfile};

/// One sub-source: its offset from the spot's centre and its share of the photons.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubSource {
    /// Offset along the detector's r and c axes, mm.
    pub offset_mm: [f64; 2],
    /// Weight (the weights of a spot sum to 1).
    pub weight: f64,
}

/// FWHM of a Gaussian over its σ: 2·√(2 ln 2).
pub const FWHM_PER_SIGMA: f64 = 2.354_820_045_030_949_3;

/// The k nodes (mm, ascending) and weights (summing to 1) along one axis of a spot of width
/// `size_mm` (square side or FWHM).
pub fn spot_nodes(profile: SpotProfile, size_mm: f64, k: u32) -> Vec<(f64, f64)> {
    let k = k.max(1);
    match profile {
        SpotProfile::Uniform => (0..k)
            .map(|n| {
                (
                    ((n as f64 + 0.5) / k as f64 - 0.5) * size_mm,
                    1.0 / k as f64,
                )
            })
            .collect(),
        SpotProfile::Gaussian => {
            let sigma = size_mm / FWHM_PER_SIGMA;
            hermite_rule(k)
                .into_iter()
                .map(|(x, w)| (sigma * x, w))
                .collect()
        }
    }
}

/// The k×k sub-sources of a spot, row by row (c outer, r inner), weights the products.
pub fn sub_sources(profile: SpotProfile, size_mm: f64, k: u32) -> Vec<SubSource> {
    let nodes = spot_nodes(profile, size_mm, k);
    let mut out = Vec::with_capacity(nodes.len() * nodes.len());
    for &(y, wy) in &nodes {
        for &(x, wx) in &nodes {
            out.push(SubSource {
                offset_mm: [x, y],
                weight: wx * wy,
            });
        }
    }
    out
}

/// The sub-sources of `spot` as the scenario gives it: [`sub_sources`], with the weights
/// tilted by its `intensity_fall_percent` along its anode direction ([`tilted`]). The one place
/// both the images and the truth's effective source take the spot from.
pub fn spot_sub_sources(spot: &FocalSpot) -> Vec<SubSource> {
    let subs = sub_sources(spot.profile, spot.size_mm, spot.samples.max(1));
    match spot.intensity_fall_percent {
        Some(p) if p != 0.0 => tilted(
            subs,
            spot.size_mm,
            p,
            spot.anode_direction.unwrap_or(AxisDirection::MinusC),
        ),
        _ => subs,
    }
}

/// `subs` with each weight times `max(0, 1 − (p/100)·(t/a + ½))`, t the offset along
/// `anode` and a the spot's width, renormalised to sum 1: the emission falls linearly by `p`
/// percent from the cathode-side edge (t = −a/2) to the anode-side edge (t = a/2).
pub fn tilted(
    subs: Vec<SubSource>,
    size_mm: f64,
    percent: f64,
    anode: AxisDirection,
) -> Vec<SubSource> {
    let along = |o: [f64; 2]| match anode {
        AxisDirection::PlusR => o[0],
        AxisDirection::MinusR => -o[0],
        AxisDirection::PlusC => o[1],
        AxisDirection::MinusC => -o[1],
    };
    let raw: Vec<f64> = subs
        .iter()
        .map(|s| s.weight * (1.0 - percent / 100.0 * (along(s.offset_mm) / size_mm + 0.5)).max(0.0))
        .collect();
    let total: f64 = raw.iter().sum();
    subs.iter()
        .zip(raw)
        .map(|(s, w)| SubSource {
            offset_mm: s.offset_mm,
            weight: w / total,
        })
        .collect()
}

/// The intensity-weighted centre of `subs`: `Σ w·offset` along r and c, mm.
pub fn centroid_mm(subs: &[SubSource]) -> [f64; 2] {
    subs.iter().fold([0.0, 0.0], |c, s| {
        [
            c[0] + s.weight * s.offset_mm[0],
            c[1] + s.weight * s.offset_mm[1],
        ]
    })
}

/// `(He_k(x), He_{k−1}(x))` by the three-term recurrence.
fn hermite(k: u32, x: f64) -> (f64, f64) {
    let (mut prev, mut cur) = (0.0, 1.0); // He_{−1} (unused) and He_0
    for n in 0..k {
        let next = x * cur - n as f64 * prev;
        prev = cur;
        cur = next;
    }
    (cur, prev)
}

/// The k-point Gauss–Hermite rule of the standard normal: nodes ascending, weights summing
/// to 1 (normalised by their sum).
fn hermite_rule(k: u32) -> Vec<(f64, f64)> {
    if k == 1 {
        return vec![(0.0, 1.0)];
    }
    // Positive roots: every root of He_k lies below √(4k + 2); scan steps of 1/1024 (far below
    // the smallest gap between roots for k ≤ 16), then bisect to the last bit.
    let limit = (4.0 * k as f64 + 2.0).sqrt();
    let step = 1.0 / 1024.0;
    let mut positive = Vec::new();
    let mut a = if k % 2 == 1 { step } else { 0.0 };
    let mut fa = hermite(k, a).0;
    while a < limit {
        let b = a + step;
        let fb = hermite(k, b).0;
        if fa == 0.0 {
            positive.push(a);
        } else if fb != 0.0 && fa.signum() != fb.signum() {
            let (mut lo, mut hi, mut flo) = (a, b, fa);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                let fm = hermite(k, mid).0;
                if fm == 0.0 {
                    lo = mid;
                    hi = mid;
                    break;
                }
                if fm.signum() == flo.signum() {
                    lo = mid;
                    flo = fm;
                } else {
                    hi = mid;
                }
            }
            positive.push(0.5 * (lo + hi));
        }
        a = b;
        fa = fb;
    }
    let factorial: f64 = (1..=k).map(f64::from).product();
    let weight = |x: f64| {
        let d = hermite(k - 1, x).0;
        factorial / ((k * k) as f64 * d * d)
    };
    let mut rule: Vec<(f64, f64)> = positive.iter().rev().map(|&x| (-x, weight(x))).collect();
    if k % 2 == 1 {
        rule.push((0.0, weight(0.0)));
    }
    rule.extend(positive.iter().map(|&x| (x, weight(x))));
    let total: f64 = rule.iter().map(|r| r.1).sum();
    rule.iter().map(|&(x, w)| (x, w / total)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spot_falling_towards_the_anode_has_its_centre_towards_the_cathode_by_hand() {
        // Uniform 1.2 mm, 3×3, falling 60 % towards −c: rows at c = −0.4, 0, 0.4 mm (t = 0.4,
        // 0, −0.4 along the anode) get 1 − 0.6·(t/1.2 + ½) = 0.5, 0.7, 0.9; their shares
        // 0.5/2.1, 0.7/2.1, 0.9/2.1; the centre c = 0.4·(0.9 − 0.5)/2.1 = 0.16/2.1 mm.
        let subs = tilted(
            sub_sources(SpotProfile::Uniform, 1.2, 3),
            1.2,
            60.0,
            AxisDirection::MinusC,
        );
        let [r, c] = centroid_mm(&subs);
        assert!(r.abs() < 1e-15, "{r}");
        assert!((c - 0.16 / 2.1).abs() < 1e-15, "{c}");
        assert!((subs.iter().map(|s| s.weight).sum::<f64>() - 1.0).abs() < 1e-15);
        assert!((subs[0].weight - 0.5 / 2.1 / 3.0).abs() < 1e-15);
        // No fall: the plain spot, centre 0.
        let [r0, c0] = centroid_mm(&sub_sources(SpotProfile::Uniform, 1.2, 3));
        assert!(r0.abs() < 1e-15 && c0.abs() < 1e-15, "{r0} {c0}");
    }

    fn moments(nodes: &[(f64, f64)]) -> [f64; 3] {
        let m0: f64 = nodes.iter().map(|n| n.1).sum();
        let m1: f64 = nodes.iter().map(|n| n.1 * n.0).sum();
        let m2: f64 = nodes.iter().map(|n| n.1 * n.0 * n.0).sum();
        [m0, m1, m2]
    }

    #[test]
    fn gauss_hermite_rules_have_the_normal_moments() {
        for k in 2..=16 {
            let rule = hermite_rule(k);
            assert_eq!(rule.len(), k as usize, "k = {k}");
            let [m0, m1, m2] = moments(&rule);
            assert!((m0 - 1.0).abs() < 1e-14, "k = {k}: Σw = {m0}");
            assert!(m1.abs() < 1e-14, "k = {k}: mean {m1}");
            assert!((m2 - 1.0).abs() < 1e-12, "k = {k}: variance {m2}");
            // Fourth moment 3 (exact for 2k − 1 ≥ 4).
            if k >= 3 {
                let m4: f64 = rule.iter().map(|n| n.1 * n.0.powi(4)).sum();
                assert!((m4 - 3.0).abs() < 1e-11, "k = {k}: m4 {m4}");
            }
            for (a, b) in rule.iter().zip(rule.iter().rev()) {
                assert_eq!(a.0, -b.0, "symmetric nodes");
                assert_eq!(a.1, b.1, "symmetric weights");
            }
        }
        // The 3-point rule: 0, ±√3 with weights 2/3, 1/6.
        let r3 = hermite_rule(3);
        assert!((r3[2].0 - 3f64.sqrt()).abs() < 1e-15);
        assert!((r3[1].1 - 2.0 / 3.0).abs() < 1e-15);
    }

    #[test]
    fn gaussian_spot_has_the_fwhm_variance() {
        let nodes = spot_nodes(SpotProfile::Gaussian, 1.2, 5);
        let sigma = 1.2 / FWHM_PER_SIGMA;
        let [_, _, m2] = moments(&nodes);
        assert!((m2 - sigma * sigma).abs() < 1e-14);
    }

    #[test]
    fn uniform_spot_nodes_are_cell_centres() {
        let nodes = spot_nodes(SpotProfile::Uniform, 1.2, 3);
        assert_eq!(nodes.len(), 3);
        assert!((nodes[0].0 + 0.4).abs() < 1e-15);
        assert_eq!(nodes[1].0, 0.0);
        assert!((nodes[2].0 - 0.4).abs() < 1e-15);
        // Variance a²(k² − 1)/(12 k²), the continuous a²/12 as k grows.
        let [m0, m1, m2] = moments(&nodes);
        assert!((m0 - 1.0).abs() < 1e-15 && m1.abs() < 1e-15);
        assert!((m2 - 1.44 * 8.0 / 108.0).abs() < 1e-15);
        let grid = sub_sources(SpotProfile::Uniform, 1.2, 3);
        assert_eq!(grid.len(), 9);
        assert!((grid.iter().map(|s| s.weight).sum::<f64>() - 1.0).abs() < 1e-15);
        assert_eq!(grid[0].offset_mm, [nodes[0].0, nodes[0].0]);
    }
}
