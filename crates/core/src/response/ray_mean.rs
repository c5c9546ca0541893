//! The expected quanta and energy of one pixel from all its rays (area sampling and focal-spot
//! sub-sources): `Q = Σ_i v_i · Σ_b w_b · exp(−μ_b·L_i)` and `E` likewise with `w_b · e_b`, ray
//! i with weight `v_i` (its sub-source's weight over the samples per pixel, times its relative
//! fluence) and path lengths `L_i` per material.
//!
//! **Expansion.** With `V = Σ_i v_i`, the weighted mean `L̄ = Σ_i v_i L_i / V` and
//! `δ_{b,i} = μ_b·(L_i − L̄)` (so `Σ_i v_i δ_{b,i} = 0`),
//! `Σ_i v_i exp(−μ_b·L_i) = exp(−μ_b·L̄) · (V + ½ Σ_i v_i δ_{b,i}² − ⅙ Σ_i v_i δ_{b,i}³ + R_b)`.
//! The second and third terms come from the rays' weighted central moments per material
//! (`Σ_i v_i ΔL_a ΔL_b` and `Σ_i v_i ΔL_a ΔL_b ΔL_c` over the materials crossed, computed once per
//! pixel), contracted with `μ_b` per bin. The remainder is a sum of
//! `v_i·(e^{−δ} − 1 + δ − δ²/2 + δ³/6)`, each at most `v_i·δ⁴/24·e^{|δ|}` in size. With `D_m` the
//! largest `|L_{m,i} − L̄_m|`, `|δ_{b,i}| ≤ d_b = Σ_m μ_{m,b}·D_m`; for `d_b ≤ 1`, and with
//! `(Σ_m x_m)⁴ ≤ k³ Σ_m x_m⁴` over the `k` materials crossed,
//! `|R_b| ≤ e/24 · k³ · Σ_m μ_{m,b}⁴ · Σ_i v_i ΔL_{m,i}⁴`. So the expansion costs one exponential
//! per bin instead of one per bin and ray, and its error is bounded: summed over the bins with
//! the weights `w_b·exp(−μ_b·L̄)` (and `w_b·e_b·exp(−μ_b·L̄)` for E), the bound must stay within
//! `τ` quantum-noise standard deviations of the pixel (`τ·√Q` for Q, `τ·E/√Q` for E), `τ` the
//! caller's tolerance (adaptive sampling's [`crate::sampling::adaptive::TOLERANCE_NOISE_SD`]).
//!
//! Where the lengths vary little in μ's terms over the rays (the smooth side of a kink, a bone's
//! gentle curvature) the expansion holds; across an edge (a bead's rim, where some rays meet
//! tantalum and some do not) `d_b` is large, and the pixel takes the exact sum over its rays
//! (`super::expected::ray_sums`: the per-pixel sums of a sharp image, ray by ray, in ray order).
//! Every sum runs in a fixed order (rays in the caller's order, materials ascending, bins
//! ascending), so a value does not depend on threads.

use super::bins::Bins;
use super::exp::exp;
use super::expected::{LANES, ray_sums};
use super::{Beam, DetectorModel, Scene, net_material_row};

/// The beam, the detector and the materials' attenuation, prepared once for many pixels.
#[derive(Debug, Clone)]
pub struct RayMean {
    bins: Bins,
    /// μ by bin then material: `[b][m]`, per mm (the exact sums' layout).
    mu: Vec<f64>,
    /// μ by material then bin: `[m][b]` (the expansion runs over the bins innermost).
    mu_by_material: Vec<f64>,
    materials: usize,
}

/// One pixel's expected quanta and energy, and how they were found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelMean {
    /// Expected detected quanta Q.
    pub quanta: f64,
    /// Expected detected energy E, keV.
    pub energy_kev: f64,
    /// The sum of the rays' weights `V` (what the open field scales by).
    pub weight: f64,
    /// Whether the expansion gave them (else the sum over every ray).
    pub expanded: bool,
}

/// Buffers of one worker, reused from pixel to pixel.
#[derive(Debug, Default)]
pub struct RayScratch {
    active: Vec<usize>,
    mean: Vec<f64>,
    spread: Vec<f64>,
    dev: Vec<f64>,
    weighted: Vec<f64>,
    fourth: Vec<f64>,
    scatter: Vec<f64>,
    cubic: Vec<f64>,
    pair: Vec<f64>,
    exponent: Vec<f64>,
    reach: Vec<f64>,
    quartic: Vec<f64>,
    quad: Vec<f64>,
    cube: Vec<f64>,
    blocks: Vec<f64>,
    mu: Vec<f64>,
    quanta: Vec<f64>,
    energy: Vec<f64>,
}

/// `e`, the bound of `e^{|δ|}` for `|δ| ≤ 1` in the remainder.
const E: f64 = std::f64::consts::E;

impl RayMean {
    /// The bins of `beam` on `det` and `mu_per_mm[m][b]` (one row per material).
    ///
    /// # Panics
    /// When a material's row does not have one value per bin.
    pub fn new(beam: &Beam, det: &DetectorModel, mu_per_mm: &[Vec<f64>]) -> RayMean {
        let bins = Bins::new(beam, &det.efficiency);
        let n = bins.quanta.len();
        for (m, row) in mu_per_mm.iter().enumerate() {
            assert_eq!(row.len(), n, "mu_per_mm[{m}]: one value per bin");
        }
        let mu = (0..n)
            .flat_map(|b| mu_per_mm.iter().map(move |row| row[b]))
            .collect();
        RayMean {
            bins,
            mu,
            mu_by_material: mu_per_mm.iter().flatten().copied().collect(),
            materials: mu_per_mm.len(),
        }
    }

    /// Materials per ray in the `lengths` that [`RayMean::pixel`] takes.
    pub fn materials(&self) -> usize {
        self.materials
    }

    /// The pixel whose rays have weights `weights` (≥ 0) and path lengths `lengths`
    /// (`[ray][material]`, mm, ≥ 0): by the expansion where its bound is within
    /// `tolerance_noise_sd` noise standard deviations, else by the sum over every ray. Rays whose
    /// weights sum to 0 take the sum over every ray (0).
    pub fn pixel(
        &self,
        lengths: &[f64],
        weights: &[f64],
        tolerance_noise_sd: f64,
        s: &mut RayScratch,
    ) -> PixelMean {
        let m_all = self.materials;
        let n = weights.len();
        debug_assert_eq!(lengths.len(), n * m_all);
        let at = |i: usize, m: usize| lengths[i * m_all + m];
        let v = weights.iter().fold(0.0, |a, &w| a + w);
        s.active.clear();
        s.active
            .extend((0..m_all).filter(|&m| (0..n).any(|i| at(i, m) != 0.0)));
        let k = s.active.len();
        if let Some(p) = self.expand(lengths, weights, v, tolerance_noise_sd, s) {
            return p;
        }
        // Every ray: lengths gathered by block of LANES rays, [block][slot][lane].
        s.blocks.clear();
        for first in (0..n).step_by(LANES) {
            let rays = first..(first + LANES).min(n);
            for &m in &s.active {
                s.blocks.extend(rays.clone().map(|i| at(i, m)));
                s.blocks
                    .extend(std::iter::repeat_n(0.0, LANES - rays.len()));
            }
        }
        s.mu.clear();
        for b in 0..self.bins.quanta.len() {
            let row = &self.mu[b * m_all..(b + 1) * m_all];
            s.mu.extend(s.active.iter().map(|&m| row[m]));
        }
        s.quanta.resize(n, 0.0);
        s.energy.resize(n, 0.0);
        ray_sums(
            &self.bins,
            &s.mu,
            k,
            &s.blocks,
            weights,
            &mut s.quanta,
            &mut s.energy,
        );
        PixelMean {
            quanta: s.quanta.iter().fold(0.0, |a, &x| a + x),
            energy_kev: s.energy.iter().fold(0.0, |a, &x| a + x),
            weight: v,
            expanded: false,
        }
    }

    /// The expansion (module docs), or `None` where its bound is beyond the tolerance. The
    /// moments are dot products over the rays and the contractions run over the bins innermost,
    /// both in a fixed order (four partial sums for the dot products), so the compiler can
    /// vectorise them.
    fn expand(
        &self,
        lengths: &[f64],
        weights: &[f64],
        v: f64,
        tolerance_noise_sd: f64,
        s: &mut RayScratch,
    ) -> Option<PixelMean> {
        if !(v > 0.0) {
            return None;
        }
        let m_all = self.materials;
        let n = weights.len();
        let nb = self.bins.quanta.len();
        let k = s.active.len();
        // Deviations from the weighted mean, [active material][ray], and the same times the
        // weights.
        s.mean.clear();
        s.dev.clear();
        s.weighted.clear();
        for &m in &s.active {
            let mean = (0..n).fold(0.0, |a, i| a + weights[i] * lengths[i * m_all + m]) / v;
            s.mean.push(mean);
            s.dev.extend((0..n).map(|i| lengths[i * m_all + m] - mean));
        }
        for a in 0..k {
            let dev = &s.dev[a * n..(a + 1) * n];
            s.weighted
                .extend(dev.iter().zip(weights).map(|(d, w)| d * w));
        }
        s.spread.clear();
        s.fourth.clear();
        for a in 0..k {
            let dev = &s.dev[a * n..(a + 1) * n];
            let wd = &s.weighted[a * n..(a + 1) * n];
            s.spread
                .push(dev.iter().fold(0.0f64, |x, d| x.max(d.abs())));
            s.fourth.push(dot4(wd, dev, |d| d * d * d));
        }
        // Second and third moments over the pairs a ≤ b and triples a ≤ b ≤ c.
        s.scatter.clear();
        s.cubic.clear();
        s.pair.resize(n, 0.0);
        for a in 0..k {
            let wd = &s.weighted[a * n..(a + 1) * n];
            for b in a..k {
                let db = &s.dev[b * n..(b + 1) * n];
                s.scatter.push(dot4(wd, db, |d| d));
                for c in b..k {
                    let dc = &s.dev[c * n..(c + 1) * n];
                    for ((p, x), y) in s.pair.iter_mut().zip(db).zip(dc) {
                        *p = x * y;
                    }
                    s.cubic.push(dot4(wd, &s.pair, |d| d));
                }
            }
        }
        // Per bin: the exponent at the mean, the largest deviation, the fourth-moment bound, and
        // the second and third terms.
        for buf in [
            &mut s.exponent,
            &mut s.reach,
            &mut s.quartic,
            &mut s.quad,
            &mut s.cube,
        ] {
            buf.clear();
            buf.resize(nb, 0.0);
        }
        let mu = |m: usize| &self.mu_by_material[m * nb..(m + 1) * nb];
        for (a, &m) in s.active.iter().enumerate() {
            let (mean, spread, fourth) = (s.mean[a], s.spread[a], s.fourth[a]);
            for (b, &x) in mu(m).iter().enumerate() {
                s.exponent[b] += x * mean;
                s.reach[b] += x * spread;
                s.quartic[b] += (x * x) * (x * x) * fourth;
            }
        }
        if s.reach.iter().any(|&d| d > 1.0) {
            return None;
        }
        let (mut c2, mut c3) = (0, 0);
        for a in 0..k {
            let ma = mu(s.active[a]);
            for bb in a..k {
                let mb = mu(s.active[bb]);
                let coef = if a == bb { 0.5 } else { 1.0 } * s.scatter[c2];
                c2 += 1;
                for ((q, x), y) in s.quad.iter_mut().zip(ma).zip(mb) {
                    *q += coef * x * y;
                }
                for c in bb..k {
                    let mc = mu(s.active[c]);
                    // Permutations of (a, b, c): 1, 3 or 6; over 6 for the third term.
                    let times = match (a == bb, bb == c) {
                        (true, true) => 1.0,
                        (true, false) | (false, true) => 3.0,
                        (false, false) => 6.0,
                    };
                    let coef = times / 6.0 * s.cubic[c3];
                    c3 += 1;
                    for (((q, x), y), z) in s.cube.iter_mut().zip(ma).zip(mb).zip(mc) {
                        *q += coef * x * y * z;
                    }
                }
            }
        }
        // (Σ_m x_m)⁴ ≤ k³ Σ_m x_m⁴ for k terms (power means).
        let k3 = (k * k * k) as f64;
        let (mut q, mut e, mut bound_q, mut bound_e) = (0.0, 0.0, 0.0, 0.0);
        for b in 0..nb {
            let t = exp(-s.exponent[b]);
            let sum = t * (v + s.quad[b] - s.cube[b]);
            let r = t * k3 * s.quartic[b] * E / 24.0;
            let (wq, we) = (self.bins.quanta[b], self.bins.energy_kev[b]);
            q += wq * sum;
            e += we * sum;
            bound_q += wq * r;
            bound_e += we * r;
        }
        let ok = q > 0.0
            && bound_q <= tolerance_noise_sd * q.sqrt()
            && bound_e <= tolerance_noise_sd * e / q.sqrt();
        ok.then_some(PixelMean {
            quanta: q,
            energy_kev: e,
            weight: v,
            expanded: true,
        })
    }
}

/// `Σ_i x_i · f(y_i)` in four interleaved partial sums (lane `i mod 4`), added in lane order at
/// the end: a fixed order the compiler can vectorise.
#[inline(always)]
fn dot4(x: &[f64], y: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    let mut acc = [0.0f64; 4];
    let (xc, yc) = (x.chunks_exact(4), y.chunks_exact(4));
    let (xr, yr) = (xc.remainder(), yc.remainder());
    for (a, b) in xc.zip(yc) {
        for l in 0..4 {
            acc[l] += a[l] * f(b[l]);
        }
    }
    for (l, (a, b)) in xr.iter().zip(yr).enumerate() {
        acc[l] += a * f(*b);
    }
    ((acc[0] + acc[1]) + acc[2]) + acc[3]
}

/// Every pixel's net path length per material (`[pixel][material]`, W×H pixels row-major, the
/// scene's materials; as the per-pixel sums take them: a material's layers summed, a negative sum
/// 0) into `lengths`, and every pixel's relative fluence into `fluence`: the rays of `scene`, for
/// [`RayMean::pixel`].
pub fn rays_of(scene: &Scene, lengths: &mut Vec<f64>, fluence: &mut Vec<f64>) {
    let (w, h) = (scene.width, scene.height);
    let m_all = scene.mu_per_mm.len();
    lengths.clear();
    lengths.resize(w * h * m_all, 0.0);
    fluence.clear();
    fluence.resize(w * h, 0.0);
    let mut row = vec![0.0; w];
    let mut materials: Vec<usize> = scene.layers.iter().map(|l| l.material).collect();
    materials.sort_unstable();
    materials.dedup();
    for j in 0..h {
        scene.fluence.row(j, &mut fluence[j * w..(j + 1) * w]);
        for &m in &materials {
            let span = net_material_row(scene.layers, m, j, &mut row);
            for i in span {
                lengths[(j * w + i) * m_all + m] = row[i];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::response::{Polarity, Response};

    fn setup() -> (Beam, DetectorModel, Vec<Vec<f64>>) {
        // 30 bins from 20 to 78 keV; soft tissue, bone and tantalum-like attenuation (tantalum
        // with its K edge at 67.4 keV).
        let energies: Vec<f64> = (0..30).map(|b| 20.0 + 2.0 * b as f64).collect();
        let beam = Beam {
            energies_kev: energies.clone(),
            photons_per_pixel: energies
                .iter()
                .map(|e| 1e3 * (e - 15.0) * (90.0 - e) / 1e3)
                .collect(),
        };
        let det = DetectorModel {
            efficiency: vec![0.8; 30],
            response: Response::EnergyIntegrating,
            gain: 1.0,
            offset: 0.0,
            i_max: u16::MAX,
            polarity: Polarity::Raw,
            quantum_noise: true,
        };
        let soft: Vec<f64> = energies
            .iter()
            .map(|e| 0.02 * (60.0 / e).powf(1.5) + 0.015)
            .collect();
        let bone: Vec<f64> = energies
            .iter()
            .map(|e| 0.1 * (60.0 / e).powi(3) + 0.02)
            .collect();
        let ta: Vec<f64> = energies
            .iter()
            .map(|&e| if e < 67.4 { 2.0 } else { 8.0 } * (60.0 / e).powi(3))
            .collect();
        (beam, det, vec![soft, bone, ta])
    }

    /// The exact sum over rays, scalar, from the definition.
    fn direct(rm: &RayMean, lengths: &[f64], weights: &[f64]) -> (f64, f64) {
        let m_all = rm.materials;
        let (mut q, mut e) = (0.0, 0.0);
        for (i, &w) in weights.iter().enumerate() {
            for (b, (&wq, &we)) in rm.bins.quanta.iter().zip(&rm.bins.energy_kev).enumerate() {
                let a: f64 = (0..m_all)
                    .map(|m| rm.mu[b * m_all + m] * lengths[i * m_all + m])
                    .sum();
                q += w * wq * (-a).exp();
                e += w * we * (-a).exp();
            }
        }
        (q, e)
    }

    #[test]
    fn expanded_and_exact_pixels_are_within_the_tolerance_of_the_direct_sum() {
        let (beam, det, mu) = setup();
        let rm = RayMean::new(&beam, &det, &mu);
        let mut s = RayScratch::default();
        let rays = 36;
        let weights: Vec<f64> = (0..rays).map(|i| (1.0 + 0.01 * i as f64) / 36.0).collect();
        let mut expanded = 0;
        let mut exact = 0;
        let mut second_order = 0;
        for case in 0..400 {
            let c = case as f64;
            // Soft tissue ~100 mm and bone ~20 mm varying smoothly over the rays; every fourth
            // case a bead's rim (tantalum on some rays only), every fifth a bone edge.
            let lengths: Vec<f64> = (0..rays)
                .flat_map(|i| {
                    let x = i as f64 / rays as f64 - 0.5;
                    let soft = 80.0 + 0.1 * c + (2.0 + 0.02 * c) * x;
                    let mut bone = 15.0 + 0.02 * c + (0.05 + 0.002 * c) * x * x;
                    if case % 5 == 0 && x < 0.0 {
                        bone = 0.0;
                    }
                    let ta = if case % 4 == 0 && x > 0.1 {
                        0.8 * x
                    } else {
                        0.0
                    };
                    [soft, bone, ta]
                })
                .collect();
            let got = rm.pixel(&lengths, &weights, 0.01, &mut s);
            let (q, e) = direct(&rm, &lengths, &weights);
            let sd = q.sqrt();
            assert!(
                (got.quanta - q).abs() <= 0.01 * sd + 1e-9 * q,
                "case {case}: Q {} vs {q} (σ {sd}, expanded {})",
                got.quanta,
                got.expanded
            );
            assert!(
                (got.energy_kev - e).abs() <= 0.01 * e / sd + 1e-9 * e,
                "case {case}: E {} vs {e}",
                got.energy_kev
            );
            if got.expanded {
                expanded += 1;
                // The mean's own transmission (no second-order term) misses by more than the
                // tolerance: the expansion's second term is doing work.
                let v: f64 = weights.iter().sum();
                let mean: Vec<f64> = (0..3)
                    .map(|m| {
                        (0..rays)
                            .map(|i| weights[i] * lengths[i * 3 + m])
                            .sum::<f64>()
                            / v
                    })
                    .collect();
                let (q0, _) = direct(&rm, &mean, &[v]);
                if (q0 - q).abs() > 0.01 * sd {
                    second_order += 1;
                }
            } else {
                exact += 1;
            }
        }
        // Both routes are taken: smooth pixels expand, rims and edges do not.
        assert!(
            expanded > 100 && exact > 100 && second_order > 50,
            "{expanded} expanded ({second_order} needing the second order), {exact} exact"
        );
    }

    #[test]
    fn a_bead_rim_is_summed_ray_by_ray() {
        let (beam, det, mu) = setup();
        let rm = RayMean::new(&beam, &det, &mu);
        let mut s = RayScratch::default();
        let weights = vec![0.25; 4];
        // Two rays through 1 mm of tantalum, two beside it.
        let lengths = [
            50.0, 0.0, 1.0, 50.0, 0.0, 1.0, 50.0, 0.0, 0.0, 50.0, 0.0, 0.0,
        ];
        let got = rm.pixel(&lengths, &weights, 0.01, &mut s);
        assert!(!got.expanded);
        let (q, e) = direct(&rm, &lengths, &weights);
        assert!(
            (got.quanta / q - 1.0).abs() < 1e-12,
            "{} vs {q}",
            got.quanta
        );
        assert!((got.energy_kev / e - 1.0).abs() < 1e-12);
    }
}
