//! A deterministic, vectorisable `exp` for the Beer–Lambert factor `exp(−Σ μ·L)`.
//!
//! `libm::exp` is deterministic but scalar (a branchy fdlibm routine); one exponential per pixel
//! and energy bin is the inner loop of an attenuation image, so this module has its own, written
//! in plain IEEE arithmetic without table lookups or platform calls, so that it gives the same
//! bits on every platform and has a 4-lane AVX2 twin ([`exp_avx2`]) with the same operations.
//!
//! **Algorithm.** For `x` in `[X_MIN, X_MAX]`: `k = round(x / ln 2)` (by the 1.5·2⁵² shift
//! trick, round half to even), `r = (x − k·ln2_hi) − k·ln2_lo` (Cody–Waite with fdlibm's
//! split of ln 2, so `k·ln2_hi` is exact and `|r| ≤ 0.3466`), `exp(r)` by the Taylor polynomial of
//! degree 13 in Horner form (truncation error < 5·10⁻¹⁸ relative), and the result scaled by
//! `2ᵏ`, built from the exponent bits. Below `X_MIN` (where `exp` leaves the normal range) the
//! result is 0 (an absolute error below 3.4·10⁻³⁰⁸); above `X_MAX` it is `+∞`; NaN gives 0.
//!
//! **Accuracy.** Within 2 ulp of `libm::exp` over `[X_MIN, X_MAX]`; the test
//! `within_two_ulp_of_libm` checks millions of arguments over `[−708, 0]` (the range an
//! attenuation exponent takes) and beyond, and reports the largest difference found.

/// Smallest argument with a normal result (`exp(−708) ≈ 3.3·10⁻³⁰⁸`); below it [`exp`] gives 0.
pub const X_MIN: f64 = -708.0;

/// Largest argument with a finite result (`exp(709) ≈ 8.2·10³⁰⁷`); above it [`exp`] gives `+∞`.
pub const X_MAX: f64 = 709.0;

/// `1 / ln 2`.
const LOG2_E: f64 = std::f64::consts::LOG2_E;
/// High part of ln 2 (fdlibm's `ln2HI`: 32 significant bits, so `k·LN2_HI` is exact for
/// `|k| ≤ 1023`).
const LN2_HI: f64 = 6.931_471_803_691_238_164_90e-1;
/// `ln 2 − LN2_HI` (fdlibm's `ln2LO`).
const LN2_LO: f64 = 1.908_214_929_270_587_700_02e-10;
/// `1.5·2⁵²`: adding it rounds a double of magnitude < 2⁵¹ to an integer held in the low bits.
const SHIFT: f64 = 6_755_399_441_055_744.0;

/// `1/n!` for `n = 0..=13`, correctly rounded.
const INV_FACT: [f64; 14] = [
    1.0,
    1.0,
    0.5,
    0.16666666666666666,
    0.041666666666666664,
    0.008333333333333333,
    0.001388888888888889,
    0.0001984126984126984,
    2.48015873015873e-05,
    2.7557319223985893e-06,
    2.755731922398589e-07,
    2.505210838544172e-08,
    2.08767569878681e-09,
    1.6059043836821613e-10,
];

/// `eˣ`, deterministic and branch-free (module documentation).
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    // NaN and out-of-range arguments are clamped here and patched at the end.
    let xc = x.clamp(X_MIN, X_MAX);
    let xc = if xc.is_nan() { X_MIN } else { xc };
    let kd = xc * LOG2_E + SHIFT;
    let k_bits = kd.to_bits();
    let kd = kd - SHIFT;
    let r = (xc - kd * LN2_HI) - kd * LN2_LO;
    let mut p = INV_FACT[13];
    p = p * r + INV_FACT[12];
    p = p * r + INV_FACT[11];
    p = p * r + INV_FACT[10];
    p = p * r + INV_FACT[9];
    p = p * r + INV_FACT[8];
    p = p * r + INV_FACT[7];
    p = p * r + INV_FACT[6];
    p = p * r + INV_FACT[5];
    p = p * r + INV_FACT[4];
    p = p * r + INV_FACT[3];
    p = p * r + INV_FACT[2];
    p = p * r + INV_FACT[1];
    p = p * r + INV_FACT[0];
    // k = k_bits − bits(SHIFT) (|k| ≤ 1023), so 2ᵏ has the bits (k + 1023) << 52.
    let k = k_bits.wrapping_sub(SHIFT.to_bits());
    let scale = f64::from_bits(k.wrapping_add(1023) << 52);
    let y = p * scale;
    if x < X_MIN || x.is_nan() {
        0.0
    } else if x > X_MAX {
        f64::INFINITY
    } else {
        y
    }
}

/// [`exp`] of four lanes at once with AVX2 intrinsics: the same operations in the same order
/// (separate multiplies and adds, never fused), so every lane has exactly the bits of the scalar
/// [`exp`] of its value (test `avx2_lanes_equal_scalar`).
///
/// The clamp is `min(max(x, X_MIN), X_MAX)`: `vmaxpd` returns its second operand when either is
/// NaN, so a NaN lane becomes `X_MIN` as in the scalar clamp; the final selects patch NaN and
/// `x < X_MIN` to 0 and `x > X_MAX` to `+∞`.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub unsafe fn exp_avx2(x: std::arch::x86_64::__m256d) -> std::arch::x86_64::__m256d {
    use std::arch::x86_64::*;
    let set = _mm256_set1_pd;
    let xc = _mm256_min_pd(_mm256_max_pd(x, set(X_MIN)), set(X_MAX));
    let kd = _mm256_add_pd(_mm256_mul_pd(xc, set(LOG2_E)), set(SHIFT));
    let k_bits = _mm256_castpd_si256(kd);
    let kd = _mm256_sub_pd(kd, set(SHIFT));
    let r = _mm256_sub_pd(
        _mm256_sub_pd(xc, _mm256_mul_pd(kd, set(LN2_HI))),
        _mm256_mul_pd(kd, set(LN2_LO)),
    );
    let mut p = set(INV_FACT[13]);
    for &c in INV_FACT[..13].iter().rev() {
        p = _mm256_add_pd(_mm256_mul_pd(p, r), set(c));
    }
    let k = _mm256_sub_epi64(k_bits, _mm256_set1_epi64x(SHIFT.to_bits() as i64));
    let scale = _mm256_slli_epi64::<52>(_mm256_add_epi64(k, _mm256_set1_epi64x(1023)));
    let y = _mm256_mul_pd(p, _mm256_castsi256_pd(scale));
    // x < X_MIN or NaN (not ≥ X_MIN, unordered compares true): 0; x > X_MAX: +∞.
    let low = _mm256_cmp_pd::<_CMP_NGE_UQ>(x, set(X_MIN));
    let high = _mm256_cmp_pd::<_CMP_GT_OQ>(x, set(X_MAX));
    let y = _mm256_andnot_pd(low, y);
    _mm256_blendv_pd(y, set(f64::INFINITY), high)
}

/// `out[i] = exp(−a[i])` for every `i`: the batch form of [`exp`] over equally long slices
/// (a plain loop the compiler vectorises).
///
/// # Panics
/// When the slices differ in length.
#[inline]
pub fn exp_neg_into(a: &[f64], out: &mut [f64]) {
    assert_eq!(a.len(), out.len(), "exp_neg_into: slices differ in length");
    for (o, &v) in out.iter_mut().zip(a) {
        *o = exp(-v);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between two positive finite doubles.
    fn ulps(a: f64, b: f64) -> u64 {
        a.to_bits().abs_diff(b.to_bits())
    }

    #[test]
    fn inverse_factorials_are_correctly_rounded() {
        // 1/n! from exact integer factorials (exact in f64 up to 18!), one rounding.
        let mut f = 1u64;
        for (n, &c) in INV_FACT.iter().enumerate() {
            if n > 0 {
                f *= n as u64;
            }
            assert_eq!(c, 1.0 / f as f64, "1/{n}!");
        }
        // 32 significant bits: k·LN2_HI is exact for |k| < 2¹¹ (here |k| ≤ 1023).
        assert_eq!(LN2_HI.to_bits() & 0x1f_ffff, 0, "k·LN2_HI exact");
        assert!(((LN2_HI + LN2_LO) - std::f64::consts::LN_2).abs() < 1e-16);
    }

    #[test]
    fn within_two_ulp_of_libm() {
        // A deterministic sweep: 4 million points over [−708, 0] (every attenuation exponent)
        // and 1 million over [0, 709], each point moved off the grid by a fraction of itself.
        let mut worst = (0u64, 0.0f64);
        let mut check = |x: f64| {
            let d = ulps(exp(x), libm::exp(x));
            if d > worst.0 {
                worst = (d, x);
            }
        };
        let n = 4_000_000u64;
        for i in 0..=n {
            let t = i as f64 / n as f64;
            let x = X_MIN * t * (1.0 + 1e-7 * ((i * 7919) % 1000) as f64 / 1000.0);
            check(x.max(X_MIN));
        }
        for i in 0..=1_000_000 {
            check(X_MAX * i as f64 / 1e6);
        }
        // Small arguments (thin objects, low μ), around the rounding boundaries of k and ±0.
        for i in 0..200_000 {
            let x = -1e-12 * (1.0 + i as f64);
            check(x);
            check(-std::f64::consts::LN_2 * (0.5 + (i as f64 - 1e5) * 1e-15));
        }
        for x in [0.0, -0.0, -1.0, -7.0, X_MIN, X_MAX, -5e-324, 1e-300] {
            check(x);
        }
        println!(
            "max difference to libm::exp: {} ulp at x = {}",
            worst.0, worst.1
        );
        assert!(worst.0 <= 2, "{} ulp at x = {}", worst.0, worst.1);
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_lanes_equal_scalar() {
        use std::arch::x86_64::*;
        if !std::arch::is_x86_feature_detected!("avx2") {
            println!("no AVX2 on this CPU: the AVX2 path is never taken here");
            return;
        }
        let mut xs: Vec<f64> = (0..2_000_000u64)
            .map(|i| -720.0 * (i as f64 / 2e6) * (1.0 + 1e-7 * ((i * 7919) % 1000) as f64))
            .collect();
        xs.extend((0..200_000).map(|i| 720.0 * i as f64 / 2e5));
        xs.extend([
            0.0,
            -0.0,
            X_MIN,
            X_MAX,
            -708.000001,
            709.000001,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -5e-324,
            -std::f64::consts::LN_2 * 0.5,
        ]);
        while xs.len() % 4 != 0 {
            xs.push(-1.0);
        }
        for x in xs.chunks_exact(4) {
            let mut out = [0.0f64; 4];
            // SAFETY: AVX2 checked above; loads and stores of four f64.
            unsafe {
                let v = exp_avx2(_mm256_loadu_pd(x.as_ptr()));
                _mm256_storeu_pd(out.as_mut_ptr(), v);
            }
            for (o, &v) in out.iter().zip(x) {
                assert_eq!(o.to_bits(), exp(v).to_bits(), "x = {v}");
            }
        }
    }

    #[test]
    fn exact_at_zero_and_defined_outside_the_range() {
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-0.0), 1.0);
        assert_eq!(exp(-708.5), 0.0);
        assert_eq!(exp(f64::NEG_INFINITY), 0.0);
        assert_eq!(exp(f64::NAN), 0.0);
        assert_eq!(exp(709.5), f64::INFINITY);
        assert_eq!(exp(f64::INFINITY), f64::INFINITY);
        assert!(exp(X_MIN) > 0.0 && exp(X_MIN).is_normal());
        let a = [0.0, 1.0, 2.5, 800.0];
        let mut out = [0.0; 4];
        exp_neg_into(&a, &mut out);
        for (o, v) in out.iter().zip(a) {
            assert_eq!(o.to_bits(), exp(-v).to_bits());
        }
    }
}
