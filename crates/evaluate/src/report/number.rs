//! The one number format every report uses: two significant digits, as the paper prints its
//! "T ± P" cells ("0.0069 ± 0.081", "−0.036 ± 0.093").

/// Formats `x` with two significant digits, rounding to the nearest (ties as Rust's exact decimal
/// formatting rounds them), keeping trailing zeros that are significant (`0.1` → `"0.10"`,
/// `1.0` → `"1.0"`), and padding integers with zeros (`1234` → `"1200"`).
///
/// - Zero (either sign) prints as `"0"`.
/// - Magnitudes below 10⁻⁵ or from 10⁷ on print in scientific notation, `"1.2e-9"`.
/// - NaN prints as `"NaN"`, infinities as `"inf"` / `"-inf"`.
/// - The sign is an ASCII hyphen-minus; each format swaps it for its own minus sign
///   ([`unicode_minus`] for HTML and Markdown, math mode in LaTeX).
pub fn format_number(x: f64) -> String {
    if x.is_nan() {
        return "NaN".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf".into() } else { "-inf".into() };
    }
    if x == 0.0 {
        return "0".into();
    }
    // Rust's `{:e}` rounds the exact binary value correctly to the requested digits; the
    // exponent it reports already accounts for rounding up to the next decade (0.0996 → 1.0e-1).
    let sci = format!("{:.1e}", x.abs());
    let (mantissa, exponent) = sci
        .split_once('e')
        .expect("scientific format has an exponent");
    let exponent: i32 = exponent.parse().expect("integer exponent");
    let digits: String = mantissa.chars().filter(char::is_ascii_digit).collect();
    let sign = if x < 0.0 { "-" } else { "" };
    let body = if !(-5..7).contains(&exponent) {
        format!("{mantissa}e{exponent}")
    } else if exponent >= 1 {
        format!("{digits}{}", "0".repeat(exponent as usize - 1))
    } else if exponent == 0 {
        format!("{}.{}", &digits[..1], &digits[1..])
    } else {
        format!("0.{}{digits}", "0".repeat((-exponent - 1) as usize))
    };
    format!("{sign}{body}")
}

/// A noise level (fraction of I_max) as a percentage with one decimal: `0.225` → `"22.5%"`.
pub fn format_noise(level: f64) -> String {
    format!("{:.1}%", level * 100.0)
}

/// An exposure level: `×0.25`, `×2` (at most three decimals, no trailing zeros).
pub fn format_exposure(factor: f64) -> String {
    format!("×{}", trimmed(factor, 3))
}

/// Replaces every ASCII hyphen-minus with the Unicode minus sign U+2212 (for HTML and Markdown).
pub fn unicode_minus(s: &str) -> String {
    s.replace('-', "\u{2212}")
}

/// `x` with at most `decimals` decimals and no trailing zeros: `0.95·100` → `"95"`, `97.5`.
pub(crate) fn trimmed(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        &s
    };
    if s == "-0" { "0".into() } else { s.into() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_significant_digits() {
        let cases = [
            (0.0069, "0.0069"),
            (0.08134, "0.081"),
            (-1.1049, "-1.1"),
            (12.345, "12"),
            (0.0, "0"),
            (-0.0, "0"),
            (0.1, "0.10"),
            (1.0, "1.0"),
            (0.0996, "0.10"),
            (99.6, "100"),
            (1234.0, "1200"),
            (-0.036, "-0.036"),
            (0.093, "0.093"),
            (5.47, "5.5"),
            (0.000_012_34, "0.000012"),
            (1.234e-9, "1.2e-9"),
            (-3.0e8, "-3.0e8"),
            (f64::NAN, "NaN"),
            (f64::INFINITY, "inf"),
            (f64::NEG_INFINITY, "-inf"),
        ];
        for (x, want) in cases {
            assert_eq!(format_number(x), want, "{x}");
        }
    }

    #[test]
    fn noise_levels_minus_signs_and_trimming() {
        assert_eq!(format_noise(0.225), "22.5%");
        assert_eq!(format_noise(0.0), "0.0%");
        assert_eq!(format_noise(0.45), "45.0%");
        assert_eq!(format_exposure(0.125), "×0.125");
        assert_eq!(format_exposure(2.0), "×2");
        assert_eq!(unicode_minus("-0.036"), "\u{2212}0.036");
        assert_eq!(trimmed(0.95 * 100.0, 4), "95");
        assert_eq!(trimmed(0.975, 4), "0.975");
        assert_eq!(trimmed(0.9 * 100.0, 4), "90");
    }
}
