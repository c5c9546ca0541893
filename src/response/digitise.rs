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
    /// (energy integrating, 0 when `q ≤ 0`).
    ///
    /// # Panics
    /// When the three slices differ in length.
    pub(crate) fn detect_row(&self, q: &[f64], e: &[f64], rng: &mut impl Rng, signal: &mut [f64]) {
        assert!(
            q.len() == e.len() && q.len() == signal.len(),
            "one q, e, S per pixel"
        );
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
            Poisson::fill_with_means(lambda, rng, s);
            if self.integrating {
                for ((s, &q), &e) in s.iter_mut().zip(q).zip(e) {
                    *s = if q > 0.0 { *s * (e / q) } else { 0.0 };
                }
            }
        }
    }

    /// The stored value of a pixel of signal `signal` and expected open-field signal `open`,
    /// and whether its raw value `offset + gain · S` was clipped at the top.
    #[inline(always)]
    pub(crate) fn store(&self, signal: f64, open: f64) -> (u16, bool) {
        self.store_raw(signal, self.offset + self.gain * signal, open)
    }

    /// [`Digitiser::store`] with `noise_dn` DN of electronic noise: the raw value becomes
    /// `offset + gain · S + noise_dn`, the radiograph's signal `S + noise_dn / gain`.
    #[inline(always)]
    pub(crate) fn store_with_read_noise(
        &self,
        signal: f64,
        open: f64,
        noise_dn: f64,
    ) -> (u16, bool) {
        let raw = self.offset + self.gain * signal + noise_dn;
        let signal = match self.table {
            Some(_) => signal + noise_dn / self.gain,
            None => signal,
        };
        self.store_raw(signal, raw, open)
    }

    #[inline(always)]
    fn store_raw(&self, signal: f64, raw: f64, open: f64) -> (u16, bool) {
        let saturated = is_saturated(raw, self.i_max);
        let value = match &self.table {
            None => quantise(raw, self.i_max),
            Some(t) => t.value(signal, open),
        };
        (value, saturated)
    }
}

/// `v` rounded half up and clipped to `0..=i_max`; NaN gives 0.
#[inline(always)]
pub(crate) fn quantise(v: f64, i_max: u16) -> u16 {
    if !(v > 0.0) {
        0
    } else if v >= f64::from(i_max) {
        i_max
    } else {
        // 0 < v + 0.5 < 65535.5: the truncating conversion is `⌊v + 0.5⌋`.
        (v + 0.5) as u16
    }
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

/// [`radiograph`]'s values, the same `u16` for every input, with one multiplication in place
/// of the formula's division and rounding steps: a pixel whose value is far from a step of the
/// stored value is decided at once, the others by [`radiograph`] itself.
///
/// With `L = libm::log(ratio)` (the formula's own logarithm, so the same bits) and
/// `scale = i_max / range` (rounded once), it takes `g = L·scale + ½` and accepts `⌊g⌋` when
/// `1 < ratio < exp(range)`, `⌊g⌋ < i_max` and `g` lies more than [`MARGIN`] from an integer.
/// The formula's stored value is `⌊fl(i_max · fl(L/range)) + ½⌋` (rounded half up,
/// [`quantise`]); with `V = i_max·L/range ≤ i_max < 2¹⁶` in real numbers, both `g` and the
/// formula's `fl(v + ½)` differ from `V + ½` by at most `2⁻⁵⁰·V + 2·2⁻³⁷ < 10⁻¹⁰` (two
/// relative roundings each on the product, one absolute rounding of the sum in `[0, 2¹⁶)`),
/// so the two floors agree whenever `g` is farther than `2·10⁻¹⁰` from an integer, which the
/// margin of 10⁻⁶ guarantees. `⌊g⌋ ≥ i_max` (the top, where the formula clamps) and the
/// shortcuts of [`radiograph`] go to the formula. No assumption on any platform function:
/// `libm` and IEEE arithmetic only. Test `fast_values_are_the_formula_s`.
#[derive(Debug, Clone)]
pub(crate) struct RadiographValues {
    range: f64,
    exp_range: f64,
    i_max: u16,
    /// `i_max / range`.
    scale: f64,
}

/// Distance of `g` from an integer below which [`RadiographValues`] defers to the formula.
const MARGIN: f64 = 1e-6;

impl RadiographValues {
    /// For `range` (> 0, finite) and `i_max`; `exp_range` as for [`radiograph`].
    pub(crate) fn new(range: f64, exp_range: f64, i_max: u16) -> RadiographValues {
        RadiographValues {
            range,
            exp_range,
            i_max,
            scale: f64::from(i_max) / range,
        }
    }

    /// [`radiograph`]`(signal, open_signal, range, exp_range, i_max)`.
    #[inline]
    pub(crate) fn value(&self, signal: f64, open_signal: f64) -> u16 {
        if signal > 0.0 {
            let ratio = open_signal / signal;
            if ratio > 1.0 && ratio < self.exp_range {
                let g = libm::log(ratio) * self.scale + 0.5;
                // g > 0.5 (L ≥ 0), so the conversion is the floor; it saturates far above i_max.
                let k = g as u32;
                let frac = g - f64::from(k);
                if frac > MARGIN && frac < 1.0 - MARGIN && k < u32::from(self.i_max) {
                    return k as u16;
                }
            }
        }
        radiograph(signal, open_signal, self.range, self.exp_range, self.i_max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
