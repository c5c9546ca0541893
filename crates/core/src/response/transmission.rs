//! The spectral transmission of one material as a table of its path length: for a pixel whose
//! ray crosses a single material m (length `L`), `Q/f = T_Q(L) = Σ_b w_b · exp(−μ_{m,b} · L)` and
//! `E/f = T_E(L) = Σ_b w_b · e_b · exp(−μ_{m,b} · L)` depend on `L` alone, so instead of one
//! exponential per energy bin the pixel takes a cubic from a table built once per image.
//!
//! **Table.** Nodes `x_i = i·h` from 0, `h` a power of two (so `L/h` and its fraction are
//! exact), up to `L_max`: an upper bound of the material's net length on the image, cut where
//! the largest `μ_{m,b}·L` would reach `−X_MIN − 1` ([`super::exp::X_MIN`]; longer paths take the
//! sums). At each node `T` and `T′ = −Σ_b w_b μ_b exp(−μ_b x)` are computed as the per-pixel
//! sums are (bins ascending, the module's own [`super::exp::exp`]); each interval holds the cubic
//! Hermite interpolant of `T` (values and slopes at both ends), evaluated in Horner form. The
//! node values depend only on the beam, the detector and μ, not on `L_max`.
//!
//! **Error bound.** On `[x_i, x_i + h]` the Hermite remainder is
//! `|T(x) − p(x)| ≤ h⁴/384 · max |T⁗|`. `T⁗ = Σ_b w_b μ_b⁴ exp(−μ_b x)` is positive and falling
//! and `T` is falling, so the relative error there is at most
//! `B_i = h⁴/384 · T⁗(x_i)/T(x_i + h) = h⁴/384 · [T⁗(x_i)/T(x_i)] · [T(x_i)/T(x_i + h)]`. Both
//! brackets fall with `x_i`: the first is the mean of `μ⁴`, the second the inverse of the mean of
//! `exp(−μh)`, under the weights `w_b exp(−μ_b x_i)`, which move towards small μ as `x_i`
//! grows. So `B_0` bounds every interval, and `h` is the largest power of two with
//! `B_0 ≤` [`REL_ERROR_BOUND`] = 10⁻¹⁰ for `T_Q` and for `T_E`; rounding adds a few units of
//! 10⁻¹⁶. That is far below the quantum noise (a pixel of 10⁴ quanta has a relative noise of
//! 10⁻²): a Poisson mean moves by at most 10⁻¹⁰ of itself. The test
//! `table_is_within_its_bound_of_the_sums` compares the table with the per-bin sums over the
//! whole range.
//!
//! No table (every pixel takes the per-bin sums) when it would need more than [`MAX_NODES`]
//! intervals, or more than one per [`PIXELS_PER_NODE`] pixels of the image (building it would
//! cost more than it saves, e.g. in the 16 × 16-pixel tiles of adaptive sampling), or when the
//! beam gives no photons.

use super::bins::Bins;
use super::exp::{X_MIN, exp};

/// The largest relative error of a table value against the per-bin sum (Hermite remainder).
pub(crate) const REL_ERROR_BOUND: f64 = 1e-10;

/// At most this many nodes per table.
pub(crate) const MAX_NODES: usize = 1 << 16;

/// A table is built only when the material's layers cover at least this many pixels per node.
pub(crate) const PIXELS_PER_NODE: usize = 16;

/// `T_Q` (and `T_E`) of one material as cubics over a uniform grid of path lengths.
#[derive(Debug, Clone)]
pub(crate) struct Transmission {
    /// `1/h`, per mm.
    inv_h: f64,
    /// Lengths up to this (mm) are in the table: `n·h`.
    max_mm: f64,
    /// Per interval the cubic of `T_Q` in `s = x/h − i ∈ [0, 1]`: `[c0, c1, c2, c3]`.
    quanta: Vec<[f64; 4]>,
    /// The same for `T_E`.
    energy: Vec<[f64; 4]>,
}

/// `T`, `T′` and `T⁗` at `x` for weights `w` and attenuations `mu` (bins ascending, from 0).
fn sums(w: &[f64], mu: &[f64], x: f64) -> [f64; 3] {
    let (mut t, mut d1, mut d4) = (0.0, 0.0, 0.0);
    for (&w, &mu) in w.iter().zip(mu) {
        let e = w * exp(-(mu * x));
        t += e;
        d1 -= mu * e;
        let mu2 = mu * mu;
        d4 += mu2 * mu2 * e;
    }
    [t, d1, d4]
}

/// The cubic Hermite interpolants of one weight set on `n` intervals of width `h` from 0.
fn cubics(w: &[f64], mu: &[f64], h: f64, n: usize) -> Vec<[f64; 4]> {
    let mut out = Vec::with_capacity(n);
    let mut left = sums(w, mu, 0.0);
    for i in 0..n {
        let right = sums(w, mu, (i + 1) as f64 * h);
        let (y0, y1, d0, d1) = (left[0], right[0], h * left[1], h * right[1]);
        out.push([
            y0,
            d0,
            3.0 * (y1 - y0) - 2.0 * d0 - d1,
            2.0 * (y0 - y1) + d0 + d1,
        ]);
        left = right;
    }
    out
}

/// The remainder bound `h⁴/384 · T⁗(0)/T(h)` of the first interval, the larger of the weight
/// sets'; NaN counts as unbounded.
fn first_interval_bound(weights: [&[f64]; 2], mu: &[f64], h: f64) -> f64 {
    let k = h * h * h * h / 384.0;
    weights
        .iter()
        .map(|w| {
            let b = k * sums(w, mu, 0.0)[2] / sums(w, mu, h)[0];
            if b.is_nan() { f64::INFINITY } else { b }
        })
        .fold(0.0, f64::max)
}

/// The largest power of two at most `x` (> 0, finite, normal), `None` otherwise.
fn power_of_two_at_most(x: f64) -> Option<f64> {
    (x >= f64::MIN_POSITIVE && x.is_finite())
        .then(|| f64::from_bits(x.to_bits() & !((1u64 << 52) - 1)))
}

impl Transmission {
    /// The table of one material of attenuation `mu` (per mm, per bin) for lengths up to
    /// `max_mm` on an image of `image_pixels` pixels, or `None` (module documentation). `T_Q`
    /// and `T_E` are both built and both bound whatever the detector, so the quanta do not
    /// depend on whether the energy is wanted.
    pub(crate) fn new(
        bins: &Bins,
        mu: &[f64],
        max_mm: f64,
        image_pixels: usize,
    ) -> Option<Transmission> {
        if !(max_mm > 0.0 && max_mm.is_finite()) {
            return None;
        }
        let mu_max = mu.iter().fold(0.0f64, |m, &v| m.max(v));
        // Beyond this no bin's exponent reaches X_MIN + 1: longer paths take the sums.
        let reach_mm = if mu_max > 0.0 {
            max_mm.min(-(X_MIN + 1.0) / mu_max)
        } else {
            max_mm
        };
        let weights = [&bins.quanta[..], &bins.energy_kev[..]];
        // The step: the bound is largest on the first interval (module documentation), so a
        // power of two for which it holds there, starting from T⁗(0)/T(0).
        let mut ratio = 0.0f64;
        for w in weights {
            let [t0, _, d4] = sums(w, mu, 0.0);
            if !(t0 > 0.0 && t0.is_finite()) {
                return None;
            }
            ratio = ratio.max(d4 / t0);
        }
        let start = if ratio > 0.0 {
            (384.0 * REL_ERROR_BOUND / ratio).sqrt().sqrt()
        } else {
            reach_mm
        };
        let mut h = power_of_two_at_most(start.min(reach_mm))?;
        while first_interval_bound(weights, mu, h) > REL_ERROR_BOUND {
            h *= 0.5;
            if h < f64::MIN_POSITIVE {
                return None;
            }
        }
        let n = (reach_mm / h).ceil();
        if !(n <= MAX_NODES as f64) || (image_pixels as f64) < PIXELS_PER_NODE as f64 * n {
            return None;
        }
        let n = n as usize;
        Some(Transmission {
            inv_h: 1.0 / h,
            max_mm: reach_mm,
            quanta: cubics(weights[0], mu, h, n),
            energy: cubics(weights[1], mu, h, n),
        })
    }

    /// `(T_Q(L), T_E(L))` of a length `0 ≤ L ≤ max_mm`, `None` beyond the table.
    #[inline(always)]
    pub(crate) fn at(&self, length_mm: f64) -> Option<(f64, f64)> {
        if !(length_mm <= self.max_mm) {
            return None;
        }
        let t = length_mm * self.inv_h;
        let i = (t as usize).min(self.quanta.len() - 1);
        let s = t - i as f64;
        let eval = |c: &[f64; 4]| c[0] + s * (c[1] + s * (c[2] + s * c[3]));
        Some((eval(&self.quanta[i]), eval(&self.energy[i])))
    }

    /// Intervals of the table.
    #[cfg(test)]
    pub(crate) fn intervals(&self) -> usize {
        self.quanta.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 40-bin beam like the realistic protocol's (85 kVp, filtered) and soft tissue-, bone-,
    /// PMMA- and metal-like attenuations (per mm) falling with energy as `a·(30/e)³ + c`.
    fn beam_and_mus() -> (Bins, Vec<Vec<f64>>) {
        let e: Vec<f64> = (0..40).map(|b| 12.0 + 1.85 * b as f64).collect();
        let quanta: Vec<f64> = e
            .iter()
            .map(|&e| 400.0 * (85.0 - e).max(0.0) * (-(18.0 / e).powi(3)).exp())
            .collect();
        let energy_kev: Vec<f64> = quanta.iter().zip(&e).map(|(q, e)| q * e).collect();
        let bins = Bins {
            open_quanta: quanta.iter().sum(),
            open_energy_kev: energy_kev.iter().sum(),
            quanta,
            energy_kev,
        };
        let mu = |a: f64, c: f64| e.iter().map(|&e| a * (30.0 / e).powi(3) + c).collect();
        (
            bins,
            vec![
                mu(0.03, 0.018),
                mu(0.2, 0.03),
                mu(0.025, 0.017),
                mu(20.0, 0.6),
            ],
        )
    }

    #[test]
    fn table_is_within_its_bound_of_the_sums() {
        let (bins, mus) = beam_and_mus();
        for (mu, max_mm) in mus.iter().zip([300.0, 80.0, 40.0, 2.0]) {
            let t = Transmission::new(&bins, mu, max_mm, usize::MAX).expect("a table");
            assert!(t.intervals() >= 2, "{}", t.intervals());
            let mut worst = 0.0f64;
            for k in 0..=100_003 {
                let l = max_mm * k as f64 / 100_003.0;
                let [q, ..] = sums(&bins.quanta, mu, l);
                let [e, ..] = sums(&bins.energy_kev, mu, l);
                let (tq, te) = t.at(l).expect("in the table");
                worst = worst.max(((tq - q) / q).abs()).max(((te - e) / e).abs());
            }
            assert!(worst <= REL_ERROR_BOUND + 1e-14, "{worst:e}");
            // Not trivially exact: the cubics do interpolate.
            assert!(worst > 1e-16, "{worst:e}");
            assert_eq!(t.at(max_mm * (1.0 + 1e-12)), None);
        }
    }

    #[test]
    fn node_values_do_not_depend_on_the_range() {
        let (bins, mus) = beam_and_mus();
        let short = Transmission::new(&bins, &mus[0], 50.0, usize::MAX).expect("a table");
        let long = Transmission::new(&bins, &mus[0], 300.0, usize::MAX).expect("a table");
        assert!(long.intervals() > short.intervals());
        for k in 0..5000 {
            let l = 50.0 * k as f64 / 5000.0;
            let (a, b) = (short.at(l).expect("in"), long.at(l).expect("in"));
            assert_eq!(
                (a.0.to_bits(), a.1.to_bits()),
                (b.0.to_bits(), b.1.to_bits())
            );
        }
    }

    #[test]
    fn no_table_where_it_would_not_hold_or_not_pay() {
        let (bins, mus) = beam_and_mus();
        // Too few pixels for the nodes.
        assert!(Transmission::new(&bins, &mus[0], 300.0, 10).is_none());
        // No length, no photons.
        assert!(Transmission::new(&bins, &mus[0], 0.0, usize::MAX).is_none());
        let dark = Bins {
            quanta: vec![0.0; 40],
            energy_kev: vec![0.0; 40],
            open_quanta: 0.0,
            open_energy_kev: 0.0,
        };
        assert!(Transmission::new(&dark, &mus[0], 300.0, usize::MAX).is_none());
        // Metal: lengths whose exponent would leave the normal range take the sums.
        let metal = Transmission::new(&bins, &mus[3], 20.0, usize::MAX).expect("a table");
        let reach = -(X_MIN + 1.0) / mus[3].iter().fold(0.0f64, |m, &v| m.max(v));
        assert!(reach < 20.0);
        assert!(metal.at(0.999 * reach).is_some() && metal.at(1.001 * reach).is_none());
        assert!(metal.intervals() <= MAX_NODES);
    }

    #[test]
    fn conventions_state_the_constants() {
        let doc = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../docs/src/reference/conventions.md"
        ))
        .expect("docs/src/reference/conventions.md");
        for text in [
            "relative error ≤ 10⁻¹⁰",
            "more than 2¹⁶ intervals or more than one per 16 pixels",
            "`h⁴/384 · T⁗(0)/T(h)`",
        ] {
            assert!(
                doc.contains(text),
                "docs/src/reference/conventions.md no longer states `{text}`"
            );
        }
        assert_eq!(
            (REL_ERROR_BOUND, MAX_NODES, PIXELS_PER_NODE),
            (1e-10, 1 << 16, 16)
        );
    }
}
