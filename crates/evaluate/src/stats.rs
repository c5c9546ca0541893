//! Trueness and precision of a set of residuals, as the paper and ISO 5725 define them.
//!
//! Trueness T = mean(Δ). Precision P = τ·s/√N, with s the sample standard deviation and τ the
//! Student-t quantile for N − 1 degrees of freedom at the chosen confidence and sidedness (the
//! paper: τ = 1.73 at N = 20, the one-sided 95 % quantile 1.729). A cell is significant when the
//! interval T ± P excludes zero.

use serde::Serialize;
use statrs::distribution::{Continuous, ContinuousCDF, StudentsT};

/// One- or two-sided quantile.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sided {
    /// τ = t(confidence; N − 1): the paper's choice (1.729 at N = 20, 95 %).
    One,
    /// τ = t((1 + confidence)/2; N − 1): the half-width of the usual two-sided confidence interval.
    Two,
}

/// Confidence level and sidedness of τ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Confidence {
    /// Confidence level in (0, 1), e.g. 0.95.
    pub level: f64,
    /// One- or two-sided.
    pub sided: Sided,
}

impl Default for Confidence {
    /// The paper's choice: one-sided 95 %.
    fn default() -> Self {
        Confidence {
            level: 0.95,
            sided: Sided::One,
        }
    }
}

impl Confidence {
    /// τ for `n` samples (n − 1 degrees of freedom); `None` when n < 2.
    pub fn tau(&self, n: usize) -> Option<f64> {
        if n < 2 {
            return None;
        }
        let p = match self.sided {
            Sided::One => self.level,
            Sided::Two => (1.0 + self.level) / 2.0,
        };
        t_quantile(p, n - 1)
    }
}

/// The Student-t quantile `t(p, df)`: the value below which a fraction `p` of the t distribution
/// with `df` degrees of freedom lies (`t(0.975, 19)` = 2.0930…), to about 1e-13.
///
/// statrs' inverse CDF is refined by Newton steps on its CDF (whose regularised incomplete beta
/// function is accurate to round-off), since the inverse alone is good to about 1e-9 only.
/// `None` for `df` < 1 or `p` outside (0, 1).
pub fn t_quantile(p: f64, df: usize) -> Option<f64> {
    if df < 1 || !(p > 0.0 && p < 1.0) {
        return None;
    }
    let dist = StudentsT::new(0.0, 1.0, df as f64).ok()?;
    let mut t = dist.inverse_cdf(p);
    for _ in 0..4 {
        let density = dist.pdf(t);
        if !(density > 0.0) {
            break;
        }
        let step = (dist.cdf(t) - p) / density;
        t -= step;
        if step.abs() <= 1e-15 * t.abs().max(1.0) {
            break;
        }
    }
    Some(t)
}

/// Sign of a significant trueness (the paper's red and blue cells).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Significance {
    /// T − P > 0: a positive bias (red).
    Positive,
    /// T + P < 0: a negative bias (blue).
    Negative,
    /// The interval T ± P contains zero.
    None,
}

impl Significance {
    /// Whether the interval `trueness ± precision` excludes zero, and on which side (none when
    /// the precision is unknown, N < 2).
    pub fn of(trueness: f64, precision: f64) -> Significance {
        if precision.is_nan() {
            Significance::None
        } else if trueness - precision > 0.0 {
            Significance::Positive
        } else if trueness + precision < 0.0 {
            Significance::Negative
        } else {
            Significance::None
        }
    }
}

/// Summary of the residuals of one parameter at one noise level.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Cell {
    /// Number of residuals.
    pub n: usize,
    /// Trueness: the mean residual.
    pub trueness: f64,
    /// Sample standard deviation (N − 1 in the denominator); NaN when N < 2.
    pub sd: f64,
    /// τ used; NaN when N < 2.
    pub tau: f64,
    /// Precision P = τ·s/√N; NaN when N < 2.
    pub precision: f64,
    /// Root mean square of the residuals.
    pub rms: f64,
    /// Whether T ± P excludes zero, and on which side.
    pub significance: Significance,
}

impl Cell {
    /// Summarises `residuals` (must not be empty).
    pub fn from_residuals(residuals: &[f64], confidence: &Confidence) -> Cell {
        let n = residuals.len();
        assert!(n > 0, "a cell needs at least one residual");
        let mean = residuals.iter().sum::<f64>() / n as f64;
        let rms = (residuals.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
        let sd = if n > 1 {
            (residuals.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            f64::NAN
        };
        let tau = confidence.tau(n).unwrap_or(f64::NAN);
        let precision = tau * sd / (n as f64).sqrt();
        Cell {
            n,
            trueness: mean,
            sd,
            tau,
            precision,
            rms,
            significance: Significance::of(mean, precision),
        }
    }

    /// The cell with T, s, P and RMS rounded to multiples of `resolution` (mm or deg), and its
    /// significance judged on the rounded values, so arithmetic round-off far below the
    /// resolution never makes a cell significant.
    pub fn at_resolution(self, resolution: f64) -> Cell {
        let q = |x: f64| {
            if x.is_finite() {
                (x / resolution).round() * resolution
            } else {
                x
            }
        };
        let (trueness, precision) = (q(self.trueness), q(self.precision));
        Cell {
            trueness,
            sd: q(self.sd),
            precision,
            rms: q(self.rms),
            significance: Significance::of(trueness, precision),
            ..self
        }
    }

    /// Per-measurement 95 % limits as RSA guidelines report them: ±1.96·SD.
    pub fn limits_95(&self) -> f64 {
        1.96 * self.sd
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles_match_published_tables() {
        // Student t table values (e.g. NIST/SEMATECH e-Handbook, Table 1.3.6.7.2).
        let cases = [
            (5, Sided::One, 2.132),
            (5, Sided::Two, 2.776),
            (20, Sided::One, 1.729),
            (20, Sided::Two, 2.093),
            (100, Sided::One, 1.660),
            (100, Sided::Two, 1.984),
        ];
        for (n, sided, want) in cases {
            let tau = Confidence { level: 0.95, sided }.tau(n).unwrap();
            assert!(
                (tau - want).abs() < 5e-4,
                "N={n} {sided:?}: {tau} vs {want}"
            );
        }
        assert!(
            (Confidence {
                level: 0.99,
                sided: Sided::Two
            }
            .tau(20)
            .unwrap()
                - 2.861)
                .abs()
                < 5e-4
        );
        assert_eq!(Confidence::default().tau(1), None);
    }

    #[test]
    fn t_quantiles_equal_scipy_to_1e_10() {
        // scipy.stats.t.ppf(p, df), scipy 1.15.
        let cases = [
            (0.975, 1, 12.706204736174694),
            (0.975, 2, 4.302652729749462),
            (0.975, 4, 2.7764451051977934),
            (0.975, 9, 2.262157162798205),
            (0.975, 19, 2.0930240544083087),
            (0.975, 29, 2.045229642132703),
            (0.975, 99, 1.9842169515864174),
            (0.995, 4, 4.604094871349992),
            (0.995, 19, 2.8609346064649794),
        ];
        for (p, df, want) in cases {
            let got = t_quantile(p, df).unwrap();
            assert!(
                (got - want).abs() < 1e-10,
                "t({p}, {df}) = {got}, scipy {want}"
            );
        }
        assert_eq!(t_quantile(0.975, 0), None);
        assert_eq!(t_quantile(1.0, 5), None);
    }

    #[test]
    fn a_cell_equals_the_hand_computation() {
        // Residuals 1, 2, 3, 4, 5: mean 3, s = √2.5 = 1.5811, τ(0.95 one-sided, 4 df) = 2.1318,
        // P = 2.1318·1.5811/√5 = 1.5074, RMS = √11 = 3.3166. 3 − 1.5074 > 0: positive.
        let c = Cell::from_residuals(&[1.0, 2.0, 3.0, 4.0, 5.0], &Confidence::default());
        assert_eq!(c.n, 5);
        assert!((c.trueness - 3.0).abs() < 1e-12);
        assert!((c.sd - 2.5f64.sqrt()).abs() < 1e-12);
        assert!((c.precision - 1.5074).abs() < 1e-4, "{}", c.precision);
        assert!((c.rms - 11f64.sqrt()).abs() < 1e-12);
        assert_eq!(c.significance, Significance::Positive);
        assert!((c.limits_95() - 1.96 * 2.5f64.sqrt()).abs() < 1e-12);
        // Round-off below the resolution is neither precision nor bias.
        let c = Cell::from_residuals(
            &[0.1 + 1e-17, 0.1, 0.1 - 1e-17, 1e-16 + 0.1],
            &Confidence::default(),
        )
        .at_resolution(1e-12);
        assert_eq!((c.sd, c.precision), (0.0, 0.0));
        assert_eq!(c.significance, Significance::Positive);
        let c = Cell::from_residuals(&[-3e-16, -2e-16, -3e-16], &Confidence::default())
            .at_resolution(1e-12);
        assert_eq!((c.trueness, c.significance), (0.0, Significance::None));
        let c = Cell::from_residuals(&[-1.0, 0.5, 0.2], &Confidence::default());
        assert_eq!(c.significance, Significance::None);
        let c = Cell::from_residuals(&[-1.0, -1.1, -0.9], &Confidence::default());
        assert_eq!(c.significance, Significance::Negative);
    }
}
