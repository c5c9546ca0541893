//! From a pixel's noisy signal to its stored digital value: gain, offset, rounding and clipping
//! (`raw` polarity), or the flat-field corrected log image (`radiograph` polarity).

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
