//! From a pixel's noisy signal to its stored digital value: gain, offset, rounding and clipping
//! (`raw` polarity), or the flat-field corrected log image (`radiograph` polarity).
//!
//! [`Digitiser`] holds the per-pixel steps that [`super::render`] and
//! [`super::render_expected`] share (one copy of the logic): the quantum draw and the stored value.

use rand_core::Rng;

use super::{DetectorModel, LAMBDA_MAX, Polarity, Response};
use crate::noise::Poisson;

/// The per-pixel steps of a detector, prepared once per image.
#[derive(Debug, Clone)]
pub(crate) struct Digitiser {
    integrating: bool,
    /// `false`: the expected image (no draw; [`DetectorModel::quantum_noise`]).
    quantum_noise: bool,
    offset: f64,
    gain: f64,
    i_max: u16,
    /// The radiograph's values (`None` for raw values).
    table: Option<RadiographValues>,
}

impl Digitiser {
    /// The steps of `det`.
    pub(crate) fn new(det: &DetectorModel) -> Digitiser {
        let table = match det.polarity {
            Polarity::Radiograph { range } => {
                Some(RadiographValues::new(range, libm::exp(range), det.i_max))
            }
            Polarity::Raw => None,
        };
        Digitiser {
            integrating: det.response == Response::EnergyIntegrating,
            quantum_noise: det.quantum_noise,
            offset: det.offset,
            gain: det.gain,
            i_max: det.i_max,
            table,
        }
    }

    /// Whether the signal is energy (so [`Digitiser::detect_row`] reads `E`).
    pub(crate) fn integrating(&self) -> bool {
        self.integrating
    }

    /// The noisy signals `S` of a row of pixels of expected quanta `q` and energy `e` (keV, read
    /// only when integrating), left to right: per pixel `n ~ Poisson(q)` drawn from `rng` (mean
    /// clamped to `[0, LAMBDA_MAX]`, NaN as 0; [`Poisson::fill_with_means`], the draws of one
    /// [`Poisson::sample_with_mean`] per pixel), then `S = n` (photon counting) or `n · e/q`
    /// (energy integrating, 0 when `q ≤ 0`). Without quantum noise `n` is the clamped mean
    /// itself and nothing is drawn.
    ///
    /// # Panics
    /// When the three slices differ in length.
    pub(crate) fn detect_row(&self, q: &[f64], e: &[f64], rng: &mut impl Rng, signal: &mut [f64]) {
        assert!(
            q.len() == e.len() && q.len() == signal.len(),
            "one q, e, S per pixel"
        );
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            unsafe { self.detect_row_avx2(q, e, rng, signal) };
            return;
        }
        self.detect_row_portable(q, e, rng, signal);
    }

    /// [`Digitiser::detect_row`] compiled for AVX2 (its constants and signals 4 lanes at a
    /// time; the same IEEE operations, so the same bits).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn detect_row_avx2(&self, q: &[f64], e: &[f64], rng: &mut impl Rng, signal: &mut [f64]) {
        self.detect_row_portable(q, e, rng, signal);
    }

    #[inline(always)]
    fn detect_row_portable(&self, q: &[f64], e: &[f64], rng: &mut impl Rng, signal: &mut [f64]) {
        const CHUNK: usize = 256;
        let mut lambda = [0.0; CHUNK];
        for ((q, e), s) in q
            .chunks(CHUNK)
            .zip(e.chunks(CHUNK))
            .zip(signal.chunks_mut(CHUNK))
        {
            let lambda = &mut lambda[..q.len()];
            for (l, &q) in lambda.iter_mut().zip(q) {
                *l = if q >= 0.0 { q.min(LAMBDA_MAX) } else { 0.0 };
            }
            if self.quantum_noise {
                Poisson::fill_with_means(lambda, rng, s);
            } else {
                s.copy_from_slice(lambda);
            }
            if self.integrating {
                for ((s, &q), &e) in s.iter_mut().zip(q).zip(e) {
                    *s = if q > 0.0 { *s * (e / q) } else { 0.0 };
                }
            }
        }
    }

    /// The stored values of a row: `out[i]` for signal `signal[i]` and expected open-field
    /// signal `open[i]` (the raw value `offset + gain · S` rounded and clipped, or the radiograph
    /// value; [`RadiographValues::values_row`]); returns how many raw values were clipped at the
    /// top (`round(offset + gain · S) > i_max`).
    ///
    /// # Panics
    /// When the three slices differ in length.
    pub(crate) fn store_row(&self, signal: &[f64], open: &[f64], out: &mut [u16]) -> usize {
        assert!(
            signal.len() == open.len() && signal.len() == out.len(),
            "one S, S_open and value per pixel"
        );
        let Some(t) = &self.table else {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                return unsafe { self.raw_row_avx2(signal, out) };
            }
            return self.raw_row(signal, out);
        };
        let saturated = signal
            .iter()
            .filter(|&&s| is_saturated(self.offset + self.gain * s, self.i_max))
            .count();
        t.values_row(signal, open, out);
        saturated
    }

    /// [`Digitiser::raw_row`] compiled for AVX2 (4 pixels at a time; the same IEEE operations,
    /// so the same values).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn raw_row_avx2(&self, signal: &[f64], out: &mut [u16]) -> usize {
        self.raw_row(signal, out)
    }

    /// The raw values of a row, [`quantise`]`(offset + gain · S)`, and how many are clipped at
    /// the top ([`is_saturated`]), in one pass without branches, so it vectorizes.
    #[inline(always)]
    fn raw_row(&self, signal: &[f64], out: &mut [u16]) -> usize {
        let mut saturated = 0usize;
        for (o, &s) in out.iter_mut().zip(signal) {
            let v = self.offset + self.gain * s;
            saturated += usize::from(is_saturated(v, self.i_max));
            *o = quantise(v, self.i_max);
        }
        saturated
    }

    /// [`Digitiser::store_row`] with `noise_dn[i]` DN of electronic noise on pixel `i`: its raw
    /// value becomes `offset + gain · S + noise_dn`, a radiograph's signal `S + noise_dn / gain`
    /// (left in `noise_dn`, which the row's values no longer need). Returns how many raw values
    /// were clipped at the top. One pass without branches per pixel, so it vectorizes (with
    /// AVX2 where the CPU has it; the same IEEE operations, so the same values).
    ///
    /// # Panics
    /// When the four slices differ in length.
    pub(crate) fn store_row_with_read_noise(
        &self,
        signal: &[f64],
        open: &[f64],
        noise_dn: &mut [f64],
        out: &mut [u16],
    ) -> usize {
        assert!(
            signal.len() == open.len()
                && signal.len() == noise_dn.len()
                && signal.len() == out.len(),
            "one S, S_open, noise and value per pixel"
        );
        let saturated = self.read_noise_row_fastest(signal, noise_dn, out);
        if let Some(t) = &self.table {
            t.values_row(noise_dn, open, out);
        }
        saturated
    }

    /// [`Digitiser::read_noise_row`], compiled for AVX2 where the CPU has it.
    fn read_noise_row_fastest(
        &self,
        signal: &[f64],
        noise_dn: &mut [f64],
        out: &mut [u16],
    ) -> usize {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { self.read_noise_row_avx2(signal, noise_dn, out) };
        }
        self.read_noise_row(signal, noise_dn, out)
    }

    /// [`Digitiser::read_noise_row`] compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn read_noise_row_avx2(
        &self,
        signal: &[f64],
        noise_dn: &mut [f64],
        out: &mut [u16],
    ) -> usize {
        self.read_noise_row(signal, noise_dn, out)
    }

    /// The raw values `offset + gain · S + noise` of a row: how many are clipped at the top; per
    /// pixel the stored raw value ([`quantise`]) into `out`, and the noisy signal
    /// `S + noise / gain` in place of the noise (a radiograph's caller then replaces `out` by
    /// its values).
    #[inline(always)]
    fn read_noise_row(&self, signal: &[f64], noise_dn: &mut [f64], out: &mut [u16]) -> usize {
        let mut saturated = 0usize;
        for ((o, n), &s) in out.iter_mut().zip(noise_dn.iter_mut()).zip(signal) {
            let raw = self.offset + self.gain * s + *n;
            saturated += usize::from(is_saturated(raw, self.i_max));
            *o = quantise(raw, self.i_max);
            *n = s + *n / self.gain;
        }
        saturated
    }
}

/// `v` rounded half up and clipped to `0..=i_max`; NaN gives 0. Computed as
/// `⌊clamp(v, 0, i_max) + ½⌋` without branches, so a row of it vectorizes: `f64::max` returns
/// the number when the other argument is NaN, `v ≥ i_max` gives `⌊i_max + ½⌋ = i_max`, `v ≤ 0`
/// gives `⌊½⌋ = 0`, and the conversion truncates a value in `[½, 65535.5]`. The conversion is
/// the unchecked one because Rust's saturating `as` kept [`Digitiser::raw_row`] from
/// vectorizing (its share of an expected-image render of the femoral component rose from 3 %
/// to 10–13 % with `as u16` or `as i32 as u16`).
#[inline(always)]
pub(crate) fn quantise(v: f64, i_max: u16) -> u16 {
    let r = v.max(0.0).min(f64::from(i_max)) + 0.5;
    // SAFETY: `r` is finite and in [0.5, 65535.5] (NaN and ±∞ are clamped first), so its
    // integer part fits an i32.
    unsafe { r.to_int_unchecked::<i32>() as u16 }
}

/// Whether the raw value `v = offset + gain · S` is clipped at the top: `round(v) > i_max`.
#[inline(always)]
pub(crate) fn is_saturated(v: f64, i_max: u16) -> bool {
    v >= f64::from(i_max) + 0.5
}

/// The radiograph value of a pixel: `i_max · clamp(ln(S_open / S) / range, 0, 1)`, rounded half
/// up, with `signal` = S (noisy) and `open_signal` = S_open (expected, no object). `S = 0` is
/// white (`i_max`); `S_open = 0` with `S > 0` (no beam expected, yet a signal) is black.
///
/// `exp_range` must be `libm::exp(range)`: a ratio at or above it is white without a logarithm,
/// a ratio at or below 1 is black without one; both give the bits the formula gives (at the
/// upper shortcut `ln(ratio)/range ≥ 1 − 2⁻⁵⁰`, which rounds to `i_max` for any `i_max ≤ 65535`).
#[inline]
pub(crate) fn radiograph(
    signal: f64,
    open_signal: f64,
    range: f64,
    exp_range: f64,
    i_max: u16,
) -> u16 {
    if !(signal > 0.0) {
        return i_max;
    }
    let ratio = open_signal / signal;
    if !(ratio > 1.0) {
        return 0;
    }
    if ratio >= exp_range {
        return i_max;
    }
    let t = (libm::log(ratio) / range).min(1.0);
    quantise(f64::from(i_max) * t, i_max)
}

/// [`radiograph`]'s values, the same `u16` for every input, found for a block of pixels at once
/// without a branch or a call per pixel: a pixel whose value is far from a step of the stored
/// value is decided at once, the others by [`radiograph`] itself.
///
/// With `L̃` = [`ln_guess`]`(ratio)` (within [`LN_GUESS_ERROR`] of `libm::log`, the formula's own
/// logarithm) and `scale = i_max / range` (rounded once), it takes `g = L̃·scale + ½` and accepts
/// `⌊g⌋` when `1 < ratio < exp(range)`, `⌊g⌋ < i_max` and `g` lies farther than
/// `margin = MARGIN + scale·LN_GUESS_ERROR` from an integer. The formula's stored value is
/// `⌊fl(i_max · fl(L/range)) + ½⌋` (rounded half up, [`quantise`]); with `V = i_max·L/range <
/// 2¹⁶` in real numbers, the formula's `fl(v + ½)` differs from `V + ½` by at most
/// `2⁻⁵⁰·V + 2⁻³⁷ < 10⁻¹⁰`, and `g` by at most that plus `scale·|L̃ − L|`, so the two floors agree
/// whenever `g` is farther than `2·10⁻¹⁰ + scale·LN_GUESS_ERROR` from an integer, which the
/// margin guarantees ([`MARGIN`] = 10⁻⁶). `⌊g⌋ ≥ i_max` (the top, where the formula clamps)
/// goes to the formula; the shortcuts of [`radiograph`] (`S ≤ 0` white, ratio ≤ 1 black,
/// ratio ≥ exp(range) white) are taken as it takes them. Only IEEE arithmetic and `libm`: no
/// platform function decides a value. Test `fast_values_are_the_formula_s`.
#[derive(Debug, Clone)]
pub(crate) struct RadiographValues {
    range: f64,
    exp_range: f64,
    i_max: u16,
    /// `i_max / range`.
    scale: f64,
    /// `MARGIN + scale · LN_GUESS_ERROR`.
    margin: f64,
}

/// Distance of `g` from an integer (beyond the logarithm's share) below which
/// [`RadiographValues`] defers to the formula.
const MARGIN: f64 = 1e-6;

/// A bound of `|ln_guess(x) − libm::log(x)|` for every `x ≥ 1` (proof at [`ln_guess`]; measured
/// by the test `ln_guess_is_within_its_bound`).
const LN_GUESS_ERROR: f64 = 1e-12;

/// `2⁵²`: adding and removing it rounds a double in `[0, 2⁵¹)` to an integer.
const TWO_52: f64 = 4_503_599_627_370_496.0;

/// `ln x` for a finite `x ≥ 1`, within [`LN_GUESS_ERROR`] of `libm::log(x)`, from IEEE
/// arithmetic and bit operations only, without a branch (so a loop of it vectorizes).
///
/// `x = 2^e·m` with `m ∈ [√½, √2)`, `f = m − 1`, `s = f/(2 + f)` (`|s| ≤ 0.1716`,
/// `z = s² ≤ 0.0295`), and `ln m = 2·atanh s = 2s·(1 + z/3 + z²/5 + … + z⁷/15)` (truncation
/// `< 2|s|·z⁸/17·1/(1 − z) < 1.2·10⁻¹⁴`), `ln x = e·ln 2 + ln m`. Rounding: `ln 2` is off by
/// `< 2⁻⁵⁴` (times `|e| ≤ 1024`: `< 6·10⁻¹⁴`), the polynomial part by a few ulp of `ln m`
/// (`≤ 0.35`, so `< 10⁻¹⁵`), the final sum by half an ulp of `ln x ≤ 710` (`< 6·10⁻¹⁴`); and
/// `libm::log` by under one ulp (`< 1.2·10⁻¹³`). Together `< 3·10⁻¹³`, a third of the bound.
#[inline(always)]
fn ln_guess(x: f64) -> f64 {
    const SQRT_2: f64 = std::f64::consts::SQRT_2;
    let bits = x.to_bits();
    // The biased exponent as a double: the integer e_b in the low bits of 2⁵²'s mantissa.
    let biased = f64::from_bits(0x4330_0000_0000_0000 | (bits >> 52)) - TWO_52;
    let m = f64::from_bits((bits & 0x000F_FFFF_FFFF_FFFF) | 0x3FF0_0000_0000_0000);
    let big = m > SQRT_2;
    let m = if big { 0.5 * m } else { m };
    let e = (biased - 1023.0) + if big { 1.0 } else { 0.0 };
    let f = m - 1.0;
    let s = f / (2.0 + f);
    let z = s * s;
    let p = z
        * (1.0 / 3.0
            + z * (1.0 / 5.0
                + z * (1.0 / 7.0
                    + z * (1.0 / 9.0 + z * (1.0 / 11.0 + z * (1.0 / 13.0 + z * (1.0 / 15.0)))))));
    let two_s = 2.0 * s;
    e * std::f64::consts::LN_2 + (two_s + two_s * p)
}

impl RadiographValues {
    /// For `range` (> 0, finite) and `i_max`; `exp_range` as for [`radiograph`].
    pub(crate) fn new(range: f64, exp_range: f64, i_max: u16) -> RadiographValues {
        let scale = f64::from(i_max) / range;
        RadiographValues {
            range,
            exp_range,
            i_max,
            scale,
            margin: MARGIN + scale * LN_GUESS_ERROR,
        }
    }

    /// [`radiograph`]`(signal, open_signal, range, exp_range, i_max)`, one pixel (the test of
    /// the guesses; images use [`RadiographValues::values_row`]).
    #[cfg(test)]
    pub(crate) fn value(&self, signal: f64, open_signal: f64) -> u16 {
        let v = self.guess(signal, open_signal);
        if v.is_nan() {
            radiograph(signal, open_signal, self.range, self.exp_range, self.i_max)
        } else {
            v as u16
        }
    }

    /// [`RadiographValues::value`] of every pixel: `out[i]` for `signal[i]`, `open[i]`.
    pub(crate) fn values_row(&self, signal: &[f64], open: &[f64], out: &mut [u16]) {
        const CHUNK: usize = 64;
        let mut guess = [0.0; CHUNK];
        for ((s, o), out) in signal
            .chunks(CHUNK)
            .zip(open.chunks(CHUNK))
            .zip(out.chunks_mut(CHUNK))
        {
            let guess = &mut guess[..s.len()];
            self.guesses(s, o, guess);
            for (k, (&g, out)) in guess.iter().zip(out.iter_mut()).enumerate() {
                *out = if g.is_nan() {
                    radiograph(s[k], o[k], self.range, self.exp_range, self.i_max)
                } else {
                    g as u16
                };
            }
        }
    }

    /// [`RadiographValues::guess`] of every pixel, 4 lanes at a time where the CPU has AVX2
    /// (the same IEEE operations, so the same bits).
    fn guesses(&self, signal: &[f64], open: &[f64], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            unsafe { self.guesses_avx2(signal, open, out) };
            return;
        }
        self.guesses_portable(signal, open, out);
    }

    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn guesses_avx2(&self, signal: &[f64], open: &[f64], out: &mut [f64]) {
        self.guesses_portable(signal, open, out);
    }

    #[inline(always)]
    fn guesses_portable(&self, signal: &[f64], open: &[f64], out: &mut [f64]) {
        for ((g, &s), &o) in out.iter_mut().zip(signal).zip(open) {
            *g = self.guess(s, o);
        }
    }

    /// The stored value as a double, or NaN where the formula must decide (module docs of the
    /// type); branch-free.
    #[inline(always)]
    fn guess(&self, signal: f64, open_signal: f64) -> f64 {
        let top = f64::from(self.i_max);
        let ratio = open_signal / signal;
        let g = ln_guess(ratio) * self.scale + 0.5;
        // ⌊g⌋ for 0 ≤ g < 2⁵¹ (other lanes are overridden below).
        let r = (g + TWO_52) - TWO_52;
        let k = if r > g { r - 1.0 } else { r };
        let frac = g - k;
        let sure = (frac > self.margin) & (frac < 1.0 - self.margin) & (k < top);
        let v = if sure { k } else { f64::NAN };
        let v = if ratio >= self.exp_range { top } else { v };
        let v = if ratio > 1.0 { v } else { 0.0 };
        if signal > 0.0 { v } else { top }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detect_row_is_one_sample_per_pixel_on_every_path() {
        use rand_chacha::ChaCha8Rng;
        use rand_core::SeedableRng;
        // Means of every sampler and the sanitised ones, photon counting and integrating.
        let q: Vec<f64> = (0..300)
            .map(|i| match i % 9 {
                0 => 0.0,
                1 => -3.0,
                2 => f64::NAN,
                3 => 4.5,
                _ => 10.0 + 53.7 * i as f64,
            })
            .collect();
        let e: Vec<f64> = q.iter().map(|&q| 47.5 * q).collect();
        for integrating in [false, true] {
            let d = Digitiser {
                integrating,
                quantum_noise: true,
                offset: 0.0,
                gain: 1.0,
                i_max: u16::MAX,
                table: None,
            };
            let mut want_rng = ChaCha8Rng::seed_from_u64(9);
            let want: Vec<f64> = q
                .iter()
                .zip(&e)
                .map(|(&q, &e)| {
                    let lambda = if q >= 0.0 { q.min(LAMBDA_MAX) } else { 0.0 };
                    let n = Poisson::sample_with_mean(lambda, &mut want_rng) as f64;
                    match (integrating, q > 0.0) {
                        (false, _) => n,
                        (true, true) => n * (e / q),
                        (true, false) => 0.0,
                    }
                })
                .collect();
            let (mut a, mut b) = (vec![0.0; q.len()], vec![0.0; q.len()]);
            let (mut ra, mut rb) = (ChaCha8Rng::seed_from_u64(9), ChaCha8Rng::seed_from_u64(9));
            d.detect_row(&q, &e, &mut ra, &mut a);
            d.detect_row_portable(&q, &e, &mut rb, &mut b);
            for i in 0..q.len() {
                assert_eq!(a[i].to_bits(), want[i].to_bits(), "pixel {i}");
                assert_eq!(b[i].to_bits(), want[i].to_bits(), "portable, pixel {i}");
            }
            let next = want_rng.next_u64();
            assert_eq!(ra.next_u64(), next, "same generator position");
            assert_eq!(rb.next_u64(), next, "same generator position, portable");
        }
    }

    #[test]
    fn without_quantum_noise_the_signal_is_the_mean_and_nothing_is_drawn() {
        use rand_chacha::ChaCha8Rng;
        use rand_core::SeedableRng;
        let q = [0.0, -3.0, f64::NAN, 4.5, 1234.5, 2e15, f64::INFINITY];
        let e = [0.0, 1.0, 2.0, 270.0, 74070.0, 1.2e17, 1.0];
        // By hand: the mean clamped to [0, 10¹⁵] (negative and NaN as 0); integrating scales it
        // by e/q (the mean energy per quantum), 0 where q ≤ 0 or NaN.
        let counting = [0.0, 0.0, 0.0, 4.5, 1234.5, 1e15, 1e15];
        let integrating = [0.0, 0.0, 0.0, 270.0, 74070.0, 1e15 * (1.2e17 / 2e15), 0.0];
        for (integrates, want) in [(false, counting), (true, integrating)] {
            let d = Digitiser {
                integrating: integrates,
                quantum_noise: false,
                offset: 0.0,
                gain: 1.0,
                i_max: u16::MAX,
                table: None,
            };
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let mut s = [f64::NAN; 7];
            d.detect_row(&q, &e, &mut rng, &mut s);
            assert_eq!(s, want, "integrating {integrates}");
            assert_eq!(
                rng.next_u64(),
                ChaCha8Rng::seed_from_u64(3).next_u64(),
                "no draw"
            );
        }
    }

    /// The branch-free raw row (AVX2 and portable) gives the stored value by cases (0 for NaN
    /// and v ≤ 0, i_max from i_max up, `⌊v + ½⌋` between) and `is_saturated` of every value:
    /// half-integers and their neighbouring doubles, the ends of the range, signed zeros, NaN,
    /// infinities and a sweep.
    #[test]
    fn raw_row_is_quantise_and_is_saturated_of_every_pixel() {
        let mut signal = vec![
            0.0,
            -0.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            1e300,
            -1e300,
        ];
        for k in [
            0.0f64, 1.0, 2.0, 254.0, 255.0, 256.0, 4094.0, 4095.0, 65534.0, 65535.0, 65536.0,
        ] {
            for x in [k - 0.5, k, k + 0.5] {
                for ulps in -2i64..=2 {
                    signal.push(f64::from_bits((x.to_bits() as i64 + ulps) as u64));
                }
            }
        }
        signal.extend((0..20_000).map(|i| -100.0 + 3.3337 * i as f64));
        for i_max in [255u16, 4095, u16::MAX] {
            for (offset, gain) in [(0.0, 1.0), (10.0, 0.37), (-5.0, 2.0)] {
                let d = Digitiser {
                    integrating: false,
                    quantum_noise: true,
                    offset,
                    gain,
                    i_max,
                    table: None,
                };
                let by_cases = |v: f64| {
                    if !(v > 0.0) {
                        0
                    } else if v >= f64::from(i_max) {
                        i_max
                    } else {
                        (v + 0.5).floor() as u16
                    }
                };
                let want: Vec<u16> = signal
                    .iter()
                    .map(|&s| by_cases(offset + gain * s))
                    .collect();
                let clipped = signal
                    .iter()
                    .filter(|&&s| is_saturated(offset + gain * s, i_max))
                    .count();
                let mut got = vec![0u16; signal.len()];
                assert_eq!(d.store_row(&signal, &signal, &mut got), clipped);
                assert_eq!(got, want, "i_max {i_max}, offset {offset}, gain {gain}");
                let mut portable = vec![0u16; signal.len()];
                assert_eq!(d.raw_row(&signal, &mut portable), clipped);
                assert_eq!(portable, want);
            }
        }
    }

    /// A row with electronic noise against the definition, pixel by pixel: the raw value
    /// `offset + gain · S + n` rounded half up and clipped by cases, or the radiograph formula
    /// ([`radiograph`], libm's logarithm) of `S + n / gain`; clipped when the rounded raw value
    /// exceeds `i_max`. Both polarities, on the AVX2 and the portable path.
    #[test]
    fn a_row_with_read_noise_is_the_per_pixel_definition() {
        let n = 5_000;
        let signal: Vec<f64> = (0..n)
            .map(|i| match i % 7 {
                0 => 0.0,
                1 => -3.0,
                2 => 1e9,
                _ => 0.37 * i as f64,
            })
            .collect();
        let noise: Vec<f64> = (0..n)
            .map(|i| 40.0 * libm::sin(0.7 * i as f64) + if i % 11 == 0 { 0.5 } else { 0.0 })
            .collect();
        let open: Vec<f64> = (0..n).map(|i| 900.0 + (i % 13) as f64).collect();
        for (i_max, offset, gain) in [
            (4095u16, 10.0, 0.37),
            (u16::MAX, -5.0, 2.0),
            (255, 0.0, 1.0),
        ] {
            for range in [None, Some(7.0)] {
                let d = Digitiser {
                    integrating: false,
                    quantum_noise: true,
                    offset,
                    gain,
                    i_max,
                    table: range.map(|r| RadiographValues::new(r, libm::exp(r), i_max)),
                };
                let raw: Vec<f64> = signal
                    .iter()
                    .zip(&noise)
                    .map(|(&s, &e)| offset + gain * s + e)
                    .collect();
                let want: Vec<u16> = (0..n)
                    .map(|k| match range {
                        None if !(raw[k] > 0.0) => 0,
                        None if raw[k] >= f64::from(i_max) => i_max,
                        None => (raw[k] + 0.5).floor() as u16,
                        Some(r) => {
                            radiograph(signal[k] + noise[k] / gain, open[k], r, libm::exp(r), i_max)
                        }
                    })
                    .collect();
                let clipped = raw
                    .iter()
                    .filter(|&&v| (v + 0.5).floor() > f64::from(i_max))
                    .count();
                let mut got = vec![0u16; n];
                let c = d.store_row_with_read_noise(&signal, &open, &mut noise.clone(), &mut got);
                assert_eq!(
                    (c, &got),
                    (clipped, &want),
                    "i_max {i_max}, range {range:?}"
                );
                let mut portable = vec![0u16; n];
                let mut noisy = noise.clone();
                assert_eq!(
                    d.read_noise_row(&signal, &mut noisy, &mut portable),
                    clipped
                );
                if let Some(t) = &d.table {
                    t.values_row(&noisy, &open, &mut portable);
                }
                assert_eq!(portable, want, "portable, i_max {i_max}, range {range:?}");
                assert!(clipped > 0 && want.iter().any(|&v| v > 0 && v < i_max));
            }
        }
    }

    #[test]
    fn quantise_rounds_half_up_and_clips() {
        assert_eq!(quantise(0.49, 100), 0);
        assert_eq!(quantise(0.5, 100), 1);
        assert_eq!(quantise(99.4, 100), 99);
        assert_eq!(quantise(99.5, 100), 100);
        assert_eq!(quantise(1e300, 100), 100);
        assert_eq!(quantise(-3.0, 100), 0);
        assert_eq!(quantise(f64::NAN, 100), 0);
        assert_eq!(quantise(65534.6, u16::MAX), u16::MAX);
        assert!(!is_saturated(100.49, 100));
        assert!(is_saturated(100.5, 100));
    }

    #[test]
    fn ln_guess_is_within_its_bound() {
        // Geometric sweep over [1, 2¹⁰²⁴), the binade edges and √2·2^e (where the reduction
        // switches), and the first ulps above 1.
        let mut worst = 0.0f64;
        let mut check = |x: f64| {
            if x.is_finite() && x >= 1.0 {
                worst = worst.max((ln_guess(x) - libm::log(x)).abs());
            }
        };
        for i in 0..2_000_000u64 {
            check(libm::exp(709.7 * i as f64 / 2e6));
        }
        for e in 0..1024 {
            let p = libm::ldexp(1.0, e);
            for x in [p, p * std::f64::consts::SQRT_2] {
                for ulps in -3i64..=3 {
                    check(f64::from_bits((x.to_bits() as i64 + ulps) as u64));
                }
            }
        }
        for ulps in 0..1000u64 {
            check(f64::from_bits(1.0f64.to_bits() + ulps));
        }
        assert!(worst < LN_GUESS_ERROR / 3.0, "worst {worst:e}");
    }

    #[test]
    fn a_row_of_values_is_the_formula_s() {
        let (range, i_max) = (7.0, u16::MAX);
        let er = libm::exp(range);
        let values = RadiographValues::new(range, er, i_max);
        let n = 1000;
        let open: Vec<f64> = (0..n).map(|i| 1e4 + i as f64).collect();
        let mut signal: Vec<f64> = (0..n)
            .map(|i| {
                open[i] * libm::exp(-8.0 * (i as f64 / n as f64)) * (1.0 + 1e-3 * (i % 7) as f64)
            })
            .collect();
        for (i, v) in [0.0, -1.0, f64::NAN, 1e30, open[7]].into_iter().enumerate() {
            signal[100 * i + 3] = v;
        }
        let mut out = vec![0u16; n];
        values.values_row(&signal, &open, &mut out);
        for i in 0..n {
            assert_eq!(
                out[i],
                radiograph(signal[i], open[i], range, er, i_max),
                "pixel {i}"
            );
        }
        // Every kind of value occurs: black, white and in between.
        assert!(
            out.contains(&0) && out.contains(&i_max) && out.iter().any(|&v| v > 0 && v < i_max)
        );
    }

    #[test]
    fn fast_values_are_the_formula_s() {
        // Every step of a 12-bit and a 16-bit image is hit from both sides, plus a sweep of
        // ratios over the whole range and the shortcuts.
        for (range, i_max) in [
            (7.0, 4095u16),
            (7.0, u16::MAX),
            (2.5, 255),
            (11.0, 1),
            (50.0, 4095),
            (800.0, 4095),
        ] {
            let er = libm::exp(range);
            let table = RadiographValues::new(range, er, i_max);
            // The ratios where the stored value steps: exp((k − ½)·range/i_max).
            let steps: Vec<f64> = (0..=usize::from(i_max))
                .map(|k| libm::exp((k as f64 - 0.5) * range / f64::from(i_max)))
                .collect();
            let check = |s: f64, s0: f64| {
                assert_eq!(
                    table.value(s, s0),
                    radiograph(s, s0, range, er, i_max),
                    "S = {s}, S_open = {s0}, range {range}, i_max {i_max}"
                );
            };
            for k in 1..=usize::from(i_max) {
                let t = steps[k];
                for r in [
                    t,
                    t * (1.0 + 1e-16),
                    t * (1.0 - 1e-16),
                    t * (1.0 + 2e-9),
                    t * (1.0 - 2e-9),
                    t * (1.0 + 1e-6),
                ] {
                    check(1000.0 / r, 1000.0);
                    check(1.0, r);
                }
            }
            for i in 0..200_000u64 {
                let r = libm::exp(range * 1.1 * i as f64 / 2e5) * (1.0 + 1e-7 * (i % 10) as f64);
                check(3.7, 3.7 * r);
            }
            for (s, s0) in [
                (0.0, 5.0),
                (-1.0, 5.0),
                (5.0, 0.0),
                (5.0, 5.0),
                (f64::NAN, 5.0),
                (5.0, f64::NAN),
                (1.0, er),
                (1.0, f64::INFINITY),
            ] {
                check(s, s0);
            }
        }
    }

    #[test]
    fn radiograph_formula_and_its_shortcuts() {
        let (range, i_max) = (7.0, 4095u16);
        let er = libm::exp(range);
        let formula = |s: f64, s0: f64| {
            let t = (libm::log(s0 / s) / range).clamp(0.0, 1.0);
            quantise(f64::from(i_max) * t, i_max)
        };
        for (s, s0) in [
            (1000.0, 1000.0),
            (1001.0, 1000.0),
            (999.0, 1000.0),
            (1.0, 1000.0),
            (1000.0 / er, 1000.0),
            (1000.0 / er * (1.0 + 1e-15), 1000.0),
            (1000.0 / er * (1.0 - 1e-15), 1000.0),
            (3.7, 1e9),
            (1e-300, 1.0),
        ] {
            assert_eq!(
                radiograph(s, s0, range, er, i_max),
                formula(s, s0),
                "{s} {s0}"
            );
        }
        assert_eq!(
            radiograph(0.0, 1000.0, range, er, i_max),
            i_max,
            "S = 0 is white"
        );
        assert_eq!(radiograph(5.0, 0.0, range, er, i_max), 0);
        // Half the range: ln ratio = 3.5 → i_max / 2.
        let v = radiograph(1000.0 / libm::exp(3.5), 1000.0, range, er, i_max);
        assert_eq!(v, 2048);
    }
}
