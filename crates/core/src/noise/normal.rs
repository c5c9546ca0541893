//! Standard normal samples for the electronic (read-out) noise, from the project's own uniforms.
//!
//! **Method** (Box–Muller, cosine branch only): take two uniforms `u₁`, `u₂` from
//! [`super::stream::uniform`] (two consecutive `u64`s of the stream, in that order) and return
//! `z = √(−2·ln(1 − u₁)) · cos(2π·u₂)`, with `ln` and `cos` from the pure-Rust `libm` crate (the
//! same bits on every platform) and `2π` the `f64` nearest to it. `1 − u₁` lies in `(0, 1]`
//! (exact in binary64), so the logarithm is always finite. Every sample consumes exactly two
//! `u64`s, so the `k`-th sample of a stream is always made of its words `4k … 4k+3`.

use rand_core::Rng;

use super::stream::uniform;

/// One standard normal sample (mean 0, SD 1) by the documented method (module documentation).
#[inline]
pub fn standard_normal(rng: &mut impl Rng) -> f64 {
    let u1 = uniform(rng);
    let u2 = uniform(rng);
    libm::sqrt(-2.0 * libm::log(1.0 - u1)) * libm::cos(std::f64::consts::TAU * u2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::NoiseKey;
    use crate::noise::stream::FixedRng;

    #[test]
    fn moments_of_10_to_the_6_samples() {
        let mut rng = NoiseKey::derive_electronic(3, 0, 0, "ap", "d").row_rng(5);
        let n = 1_000_000usize;
        let v: Vec<f64> = (0..n).map(|_| standard_normal(&mut rng)).collect();
        let mean = v.iter().sum::<f64>() / n as f64;
        let m2 = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
        let m4 = v.iter().map(|x| (x - mean).powi(4)).sum::<f64>() / n as f64;
        let nf = n as f64;
        assert!(mean.abs() < 4.0 / nf.sqrt(), "mean {mean}");
        assert!((m2 - 1.0).abs() < 4.0 * (2.0 / nf).sqrt(), "variance {m2}");
        // Kurtosis 3 (SE √(96/n)): a uniform or triangular law would give 1.8 or 2.4.
        assert!((m4 - 3.0).abs() < 4.0 * (96.0 / nf).sqrt(), "m4 {m4}");
        // Tails: P(|z| > 3) = 0.0027.
        let tail = v.iter().filter(|x| x.abs() > 3.0).count() as f64 / nf;
        assert!(
            (tail - 0.0027).abs() < 4.0 * (0.0027 / nf).sqrt(),
            "tail {tail}"
        );
    }

    #[test]
    fn the_documented_formula_on_fixed_words() {
        // u₁ = u₂ = 0: √(−2 ln 1) · cos 0 = 0 (consumes two u64s, never ln 0).
        assert_eq!(standard_normal(&mut FixedRng(0)), 0.0);
        // u₁ = u₂ = 1/2: √(2 ln 2) · cos π.
        let z = standard_normal(&mut FixedRng(1 << 63));
        let want = libm::sqrt(-2.0 * libm::log(0.5)) * libm::cos(std::f64::consts::PI);
        assert_eq!(z.to_bits(), want.to_bits());
        // The largest u₁ (1 − 2⁻⁵³) gives a finite sample, √(2·53·ln 2) ≈ 8.57 at most.
        let z = standard_normal(&mut FixedRng(u64::MAX));
        assert!(z.is_finite() && z.abs() < 8.58, "{z}");
    }
}
