//! Poisson sampling by table inversion, for a mean that stays the same over a whole image
//! (binary mode: one mean `level · I_max` per image).
//!
//! [`PoissonTable::new`]`(λ, cap)` tabulates the law of `min(X, cap)` for `X ~ Poisson(λ)` as
//! integer thresholds on the 53-bit uniforms of [`super::stream::uniform`], and a sample costs
//! exactly one `u64` of the generator: with `u = x >> 11` (so the uniform is `u · 2⁻⁵³`), the
//! sample is the smallest tabulated `k` with `u < T_k`. Every value that decides a sample is
//! computed in exact IEEE arithmetic or with the pure-Rust `libm` crate, in a fixed order, so the
//! table, and so every sample, is the same on every platform.
//!
//! **The table** (all in binary64):
//! 1. The mode `m = ⌊λ⌋`. Relative weights `w_k = P(X = k)/P(X = m)` by the recursions
//!    `w_m = 1`, `w_{k+1} = w_k · λ/(k + 1)` (upwards) and `w_{k−1} = w_k · k/λ` (downwards, each
//!    as one multiplication by the quotient, in that order). Each direction stops at the first
//!    weight below [`CUT_WEIGHT`] = 2⁻⁶⁴ (that weight is not kept) or at `k = 0`; the kept weights
//!    span `k_lo ..= k_hi`.
//! 2. `S = Σ w_k` over `k_lo ..= k_hi`, summed in increasing `k`.
//! 3. Running sums `C_k = Σ_{j ≤ k} w_j`, in increasing `k`, and thresholds
//!    `T_k = round(C_k / S · 2⁵³)` (`libm::round`, halves away from zero) for
//!    `k = k_lo ..= min(k_hi, cap) − 1`; the last entry (`k = min(k_hi, cap)`) is `T = 2⁵³`, so it
//!    takes the whole mass at and above it. When `cap < k_lo` the table is the single value `cap`.
//!
//! **Exactness.** The weights past a cut fall geometrically (ratio `λ/(k+1) < 1` above the mode,
//! `k/λ < 1` below), so the mass left out of the table is below [`TAIL_MASS_BOUND`] = 2⁻⁶⁰
//! (tested). The rounding to multiples of 2⁻⁵³ moves each cumulative probability by at most
//! 2⁻⁵⁴, and the recursions and sums add a relative error of a few thousand ulps at most. So
//! every probability of the sampled law is the exact Poisson (clamped) probability within about
//! 10⁻¹²: a chi-square test against the exact pmf cannot tell them apart (tested with 10⁶ samples).
//!
//! **The lookup** is exact integer arithmetic: a guide table of `2^g` entries (`2^g` at least twice
//! the table's length) gives, for the top `g` bits of `u`, the first entry whose threshold can
//! exceed `u`; a forward search from there ends at the sample (fewer than 1.5 steps on average).

use rand_chacha::ChaCha8Rng;
use rand_core::Rng;

/// Weights (relative to the mode's) below this end the table.
pub const CUT_WEIGHT: f64 = 1.0 / 18_446_744_073_709_551_616.0; // 2⁻⁶⁴

/// Upper bound of the probability mass of the values left out of the table (tested).
pub const TAIL_MASS_BOUND: f64 = 1.0 / 1_152_921_504_606_846_976.0; // 2⁻⁶⁰

/// `2⁵³`: the number of distinct uniforms.
const UNIFORMS: u64 = 1 << 53;

/// The law of `min(X, cap)`, `X ~ Poisson(λ)`, as an inversion table (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct PoissonTable {
    /// The value of entry 0.
    k_lo: u64,
    /// `thresholds[i]`: how many of the 2⁵³ uniforms give a value ≤ `k_lo + i`; the last is 2⁵³.
    thresholds: Vec<u64>,
    /// `guide[j]`: the first entry `i` with `thresholds[i] > j << guide_shift`.
    guide: Vec<u32>,
    /// `53 − g` for a guide of `2^g` entries.
    guide_shift: u32,
}

impl PoissonTable {
    /// The table of `min(X, cap)` with `X ~ Poisson(lambda)`.
    ///
    /// # Panics
    /// When `lambda` is not finite and positive, or the table would hold more than 2²⁴ entries
    /// (`min(λ, cap)` beyond about 10¹¹; binary-mode images need at most `cap = 65535`).
    pub fn new(lambda: f64, cap: u64) -> PoissonTable {
        assert!(
            lambda.is_finite() && lambda > 0.0,
            "Poisson mean of a table must be finite and positive, got {lambda}"
        );
        let mode = libm::floor(lambda);
        // Weights from the mode outwards: `down[i]` is k = mode − 1 − i, `up[i]` is k = mode + i.
        let mut up = vec![1.0f64];
        let mut k = mode;
        loop {
            let w = up[up.len() - 1] * (lambda / (k + 1.0));
            if !(w >= CUT_WEIGHT) {
                break;
            }
            up.push(w);
            k += 1.0;
            assert!(
                up.len() <= 1 << 24,
                "Poisson table for λ = {lambda} too large"
            );
        }
        let mut down = Vec::new();
        let (mut w, mut k) = (1.0f64, mode);
        while k > 0.0 {
            w *= k / lambda;
            if !(w >= CUT_WEIGHT) {
                break;
            }
            down.push(w);
            k -= 1.0;
            assert!(
                down.len() <= 1 << 24,
                "Poisson table for λ = {lambda} too large"
            );
        }
        let k_lo = mode as u64 - down.len() as u64;
        let weights: Vec<f64> = down.iter().rev().chain(&up).copied().collect();
        let total: f64 = weights.iter().sum();
        let k_hi = k_lo + weights.len() as u64 - 1;
        let (k_lo, thresholds) = if cap < k_lo {
            (cap, vec![UNIFORMS])
        } else {
            let last = k_hi.min(cap);
            let mut running = 0.0;
            let mut thresholds: Vec<u64> = weights[..(last - k_lo) as usize]
                .iter()
                .map(|&w| {
                    running += w;
                    libm::round(running / total * UNIFORMS as f64) as u64
                })
                .collect();
            thresholds.push(UNIFORMS);
            (k_lo, thresholds)
        };
        let g = (2 * thresholds.len())
            .next_power_of_two()
            .trailing_zeros()
            .max(1);
        let guide_shift = 53 - g;
        let mut guide = Vec::with_capacity(1 << g);
        let mut i = 0usize;
        for j in 0..1u64 << g {
            let start = j << guide_shift;
            while thresholds[i] <= start {
                i += 1;
            }
            guide.push(i as u32);
        }
        PoissonTable {
            k_lo,
            thresholds,
            guide,
            guide_shift,
        }
    }

    /// The sample for one draw `x` of the generator: the smallest tabulated `k` with
    /// `(x >> 11) < T_k`.
    #[inline(always)]
    pub fn sample_of(&self, x: u64) -> u64 {
        let u = x >> 11;
        let mut i = self.guide[(u >> self.guide_shift) as usize] as usize;
        while self.thresholds[i] <= u {
            i += 1;
        }
        self.k_lo + i as u64
    }

    /// One sample, consuming exactly one `u64` of `rng`.
    #[inline]
    pub fn sample(&self, rng: &mut impl Rng) -> u64 {
        self.sample_of(rng.next_u64())
    }

    /// Fills `out` with samples, one `u64` of `rng` each in order: the values and generator
    /// position of `for x in out { *x = self.sample(rng) }`.
    pub fn fill(&self, rng: &mut ChaCha8Rng, out: &mut [u64]) {
        const CHUNK: usize = 256;
        let mut bytes = [0u8; 8 * CHUNK];
        for part in out.chunks_mut(CHUNK) {
            let bytes = &mut bytes[..8 * part.len()];
            rng.fill_bytes(bytes);
            for (o, b) in part.iter_mut().zip(bytes.chunks_exact(8)) {
                let mut le = [0u8; 8];
                le.copy_from_slice(b);
                *o = self.sample_of(u64::from_le_bytes(le));
            }
        }
    }

    /// The smallest value the table can give.
    pub fn min_value(&self) -> u64 {
        self.k_lo
    }

    /// The largest value the table can give.
    pub fn max_value(&self) -> u64 {
        self.k_lo + self.thresholds.len() as u64 - 1
    }

    /// `P(sample ≤ k)` as the table defines it: a multiple of 2⁻⁵³.
    pub fn cdf(&self, k: u64) -> f64 {
        if k < self.k_lo {
            return 0.0;
        }
        let i = ((k - self.k_lo) as usize).min(self.thresholds.len() - 1);
        self.thresholds[i] as f64 / UNIFORMS as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::stream::NoiseKey;

    fn rng(row: u32) -> ChaCha8Rng {
        NoiseKey::derive(20261124, 0, 0, "table", "test").row_rng(row)
    }

    /// The exact pmf, independently of the table's recursion: `exp(−λ + k ln λ − ln k!)`.
    fn pmf(lambda: f64, k: u64) -> f64 {
        let k = k as f64;
        libm::exp(-lambda + k * libm::log(lambda) - libm::lgamma(k + 1.0))
    }

    /// The upper quantile of the chi-square law with `df` degrees of freedom at tail
    /// probability 10⁻⁶, by the Wilson–Hilferty cube approximation (z = 4.753424 is the standard
    /// normal's 1 − 10⁻⁶ quantile).
    fn chi_square_critical(df: usize) -> f64 {
        let d = df as f64;
        let z = 4.753_424;
        let c = 2.0 / (9.0 * d);
        d * (1.0 - c + z * c.sqrt()).powi(3)
    }

    /// Pearson chi-square of `n` table samples against the exact (clamped) pmf, bins with
    /// expectation < 5 merged into the tails: (statistic, degrees of freedom).
    fn chi_square(lambda: f64, cap: u64, n: usize, row: u32) -> (f64, usize) {
        let table = PoissonTable::new(lambda, cap);
        let kmax = ((lambda + 15.0 * lambda.sqrt() + 30.0) as u64).min(cap);
        let mut expected: Vec<f64> = (0..=kmax).map(|k| pmf(lambda, k) * n as f64).collect();
        // The clamped value takes everything at and above the cap.
        if kmax == cap {
            let below: f64 = expected[..cap as usize].iter().sum();
            expected[cap as usize] = n as f64 - below;
        }
        let mut counts = vec![0f64; kmax as usize + 1];
        let mut r = rng(row);
        for _ in 0..n {
            counts[(table.sample(&mut r).min(kmax)) as usize] += 1.0;
        }
        let lo = expected.iter().position(|&e| e >= 5.0).expect("a bin ≥ 5");
        let hi = expected.iter().rposition(|&e| e >= 5.0).expect("a bin ≥ 5");
        let mut bins = vec![(
            counts[..=lo].iter().sum::<f64>(),
            expected[..=lo].iter().sum::<f64>(),
        )];
        for k in lo + 1..hi {
            bins.push((counts[k], expected[k]));
        }
        let upper = n as f64 - expected[..hi].iter().sum::<f64>();
        bins.push((counts[hi..].iter().sum(), upper));
        let stat = bins.iter().map(|(o, e)| (o - e) * (o - e) / e).sum();
        (stat, bins.len() - 1)
    }

    #[test]
    fn chi_square_against_the_exact_pmf() {
        let cases = [
            (0.3, u64::MAX),
            (4.0, u64::MAX),
            (10.0, u64::MAX),
            (37.3, u64::MAX),
            (1000.0, u64::MAX),
            (14745.375, 65535),
            (58981.5, 65535),
            // Clamped: a real share of the mass sits at the cap.
            (65535.0, 65535),
            (200.0, 190),
        ];
        for (row, &(lambda, cap)) in cases.iter().enumerate() {
            let (stat, df) = chi_square(lambda, cap, 1_000_000, row as u32);
            let critical = chi_square_critical(df);
            assert!(
                stat < critical,
                "λ={lambda}, cap {cap}: χ² = {stat:.1} ≥ {critical:.1} with {df} df"
            );
        }
    }

    #[test]
    fn chi_square_test_sees_a_mean_off_by_a_tenth_of_a_sigma() {
        // The same test, samples of λ = 1000 + 0.1·√1000 judged against λ = 1000, must fail.
        let n = 1_000_000;
        let (lambda, wrong) = (1000.0, 1000.0 + 0.1 * 1000f64.sqrt());
        let table = PoissonTable::new(wrong, u64::MAX);
        let mut r = rng(99);
        let (lo, hi) = (850u64, 1150u64);
        let mut counts = vec![0f64; (hi - lo + 1) as usize];
        for _ in 0..n {
            counts[(table.sample(&mut r).clamp(lo, hi) - lo) as usize] += 1.0;
        }
        let below: f64 = (0..=lo).map(|k| pmf(lambda, k)).sum();
        let above: f64 = (hi..hi + 400).map(|k| pmf(lambda, k)).sum();
        let mut stat = 0.0;
        for (i, o) in counts.iter().enumerate() {
            let k = lo + i as u64;
            let p = if k == lo {
                below
            } else if k == hi {
                above
            } else {
                pmf(lambda, k)
            };
            let e = p * n as f64;
            stat += (o - e) * (o - e) / e;
        }
        assert!(stat > chi_square_critical(counts.len() - 1), "χ² = {stat}");
    }

    #[test]
    fn tail_mass_outside_the_table_is_below_the_bound() {
        for lambda in [
            1e-9, 0.3, 1.0, 9.5, 10.0, 100.0, 14745.375, 58981.5, 65535.0, 1e8,
        ] {
            let t = PoissonTable::new(lambda, u64::MAX);
            // The exact mass below k_lo and above k_hi, summed from the far ends inwards.
            let below: f64 = (0..t.min_value()).map(|k| pmf(lambda, k)).sum();
            let reach = (40.0 * lambda.sqrt() + 200.0) as u64;
            let above: f64 = (t.max_value() + 1..t.max_value() + reach)
                .rev()
                .map(|k| pmf(lambda, k))
                .sum();
            // The terms beyond `reach` are negligible next to these (geometric fall).
            assert!(
                below + above < TAIL_MASS_BOUND,
                "λ={lambda}: tail {:e}",
                below + above
            );
            // And the table reaches far enough to hold everything above 2⁻⁵³ on each side.
            assert!(t.min_value() == 0 || pmf(lambda, t.min_value() - 1) < 1e-17);
            assert!(pmf(lambda, t.max_value() + 1) < 1e-17, "λ={lambda}");
        }
    }

    #[test]
    fn cumulative_probabilities_match_the_exact_cdf() {
        for (lambda, cap) in [(0.3, 10), (4.0, 100), (58981.5, 65535), (200.0, 190)] {
            let t = PoissonTable::new(lambda, cap);
            let mut exact = 0.0;
            for k in 0..cap {
                exact += pmf(lambda, k);
                assert!(
                    (t.cdf(k) - exact).abs() < 1e-9,
                    "λ={lambda}, k={k}: {} vs {exact}",
                    t.cdf(k)
                );
            }
            assert_eq!(t.cdf(cap), 1.0);
            assert!(t.max_value() <= cap);
        }
    }

    #[test]
    fn one_draw_per_sample_and_fill_equals_sample() {
        let t = PoissonTable::new(29490.75, 65535);
        let mut a = rng(5);
        let mut b = rng(5);
        let mut c = rng(5);
        let mut out = vec![0u64; 1000];
        t.fill(&mut a, &mut out);
        for &x in &out {
            assert_eq!(x, t.sample(&mut b));
            assert_eq!(x, t.sample_of(c.next_u64()));
        }
        assert_eq!(a.next_u64(), b.next_u64(), "same generator position");
    }

    #[test]
    fn lookup_is_the_smallest_k_whose_threshold_exceeds_u() {
        let t = PoissonTable::new(37.3, u64::MAX);
        for x in [0u64, 1 << 11, u64::MAX, 1 << 63, 12345 << 11] {
            let u = x >> 11;
            let want = t.thresholds.iter().position(|&th| u < th).unwrap() as u64 + t.k_lo;
            assert_eq!(t.sample_of(x), want);
        }
        // The edges: u just below and at each threshold.
        for (i, &th) in t.thresholds.iter().enumerate() {
            if th == 0 || th == UNIFORMS {
                continue;
            }
            let first = t.thresholds.iter().position(|&x| x == th).unwrap();
            assert_eq!(
                t.sample_of((th - 1) << 11),
                t.k_lo + first as u64,
                "entry {i}"
            );
            assert!(t.sample_of(th << 11) > t.k_lo + i as u64);
        }
    }

    #[test]
    fn a_cap_below_the_mass_gives_the_cap() {
        let t = PoissonTable::new(1e6, 255);
        let mut r = rng(1);
        assert!((0..100).all(|_| t.sample(&mut r) == 255));
        assert_eq!((t.min_value(), t.max_value()), (255, 255));
    }

    #[test]
    #[should_panic]
    fn zero_mean_has_no_table() {
        PoissonTable::new(0.0, 10);
    }

    /// Fixed samples of one stream: a change to the table or the lookup changes them (and every
    /// noisy image). Key derive(1, 0, 0, "e", "d"), row 5.
    #[test]
    fn deterministic_regression_values() {
        let key = NoiseKey::derive(1, 0, 0, "e", "d");
        for (lambda, expected) in [(3.0, EXPECTED_3), (58981.5, EXPECTED_58981)] {
            let t = PoissonTable::new(lambda, 65535);
            let mut r = key.row_rng(5);
            let xs: Vec<u64> = (0..8).map(|_| t.sample(&mut r)).collect();
            assert_eq!(xs, expected, "λ={lambda}");
        }
    }

    // Reproduced independently by a from-scratch Python implementation of the documented
    // derivation (SHA-256 label, ChaCha8 block function, the table as in the module docs).
    const EXPECTED_3: [u64; 8] = [6, 2, 3, 3, 2, 0, 1, 3];
    const EXPECTED_58981: [u64; 8] = [59393, 58787, 58952, 59015, 58827, 58334, 58606, 59062];
}
