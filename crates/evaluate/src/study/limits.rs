//! Clinical precision from double examinations (ISO 16087; the RSA guidelines): the differences
//! between the two exams of each patient, their mean and SD, and the limits a study publishes.

use serde::Serialize;

use crate::stats::t_quantile;

/// The 97.5 % normal quantile the RSA literature rounds to 1.96.
pub const Z_975: f64 = 1.96;
/// The 99.5 % normal quantile, rounded as usually printed (2.576).
pub const Z_995: f64 = 2.576;

/// The precision of one parameter (an axis or MTPM) from the double exams.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DoubleLimits {
    /// Parameter label, e.g. `x`, `Rx`, `MTPM`.
    pub parameter: String,
    /// `mm` or `deg`.
    pub unit: String,
    /// Number of patients with both exams.
    pub n: usize,
    /// Mean difference (second exam minus first).
    pub mean: f64,
    /// Sample SD of the differences (N − 1); NaN for N < 2.
    pub sd: f64,
    /// The 95 % limits `mean ± 1.96·SD`: [lower, upper].
    pub limits_196: [f64; 2],
    /// `t(0.975, N − 1)`.
    pub t_975: f64,
    /// The t-based 95 % limit `t(0.975, N − 1)·SD`.
    pub limit_t95: f64,
    /// When 99 % limits are asked for: `mean ± 2.576·SD`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub limits_2576: Option<[f64; 2]>,
    /// When 99 % limits are asked for: `t(0.995, N − 1)·SD`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub limit_t99: Option<f64>,
    /// MTPM only (a length, not normally distributed): median of the values.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub median: Option<f64>,
    /// MTPM only: [smallest, largest] value.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range: Option<[f64; 2]>,
}

/// The median of `values` (not empty).
pub fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// The limits of `differences` (not empty); `with_99` adds the 99 % limits; `magnitude` (MTPM)
/// adds the median and range.
pub fn double_limits(
    parameter: &str,
    unit: &str,
    differences: &[f64],
    with_99: bool,
    magnitude: bool,
) -> DoubleLimits {
    let n = differences.len();
    let mean = differences.iter().sum::<f64>() / n as f64;
    let sd = if n > 1 {
        (differences.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        f64::NAN
    };
    let t = |p| {
        n.checked_sub(1)
            .and_then(|df| t_quantile(p, df))
            .unwrap_or(f64::NAN)
    };
    let (t_975, t_995) = (t(0.975), t(0.995));
    DoubleLimits {
        parameter: parameter.into(),
        unit: unit.into(),
        n,
        mean,
        sd,
        limits_196: [mean - Z_975 * sd, mean + Z_975 * sd],
        t_975,
        limit_t95: t_975 * sd,
        limits_2576: with_99.then_some([mean - Z_995 * sd, mean + Z_995 * sd]),
        limit_t99: with_99.then_some(t_995 * sd),
        median: magnitude.then(|| median(differences)),
        range: magnitude.then(|| {
            let lo = differences.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = differences
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max);
            [lo, hi]
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_equal_the_hand_computation() {
        // Differences 0.1, −0.1, 0.2, 0.0, −0.05: mean 0.03, squared deviations 0.0049 + 0.0169 +
        // 0.0289 + 0.0009 + 0.0064 = 0.058, SD = √(0.058/4) = 0.120416…,
        // t(0.975, 4) = 2.7764451051977934 (scipy).
        let d = [0.1, -0.1, 0.2, 0.0, -0.05];
        let l = double_limits("y", "mm", &d, true, false);
        let sd = (0.058f64 / 4.0).sqrt();
        assert_eq!(l.n, 5);
        assert!((l.mean - 0.03).abs() < 1e-12);
        assert!((l.sd - sd).abs() < 1e-12);
        assert!((l.limits_196[0] - (0.03 - 1.96 * sd)).abs() < 1e-12);
        assert!((l.limits_196[1] - (0.03 + 1.96 * sd)).abs() < 1e-12);
        assert!((l.limit_t95 - 2.7764451051977934 * sd).abs() < 1e-12);
        assert!((l.limits_2576.unwrap()[1] - (0.03 + 2.576 * sd)).abs() < 1e-12);
        assert!((l.limit_t99.unwrap() - 4.604094871349992 * sd).abs() < 1e-12);
        assert_eq!((l.median, l.range), (None, None));
        let m = double_limits("MTPM", "mm", &[0.3, 0.1, 0.2, 0.5], false, true);
        assert_eq!(m.median, Some(0.25));
        assert_eq!(m.range, Some([0.1, 0.5]));
        assert_eq!((m.limits_2576, m.limit_t99), (None, None));
        let one = double_limits("x", "mm", &[0.1], false, false);
        assert!(one.sd.is_nan() && one.t_975.is_nan());
    }
}
