//! ISO 5725-2 analysis with the noise levels as the "laboratories": repeatability (within a
//! level), between-level and reproducibility standard deviations, a one-way ANOVA that answers
//! the paper's question "does the noise level change the result?", and the consistency and
//! outlier checks of ISO 5725-2 §7.3 (Mandel's h and k, Cochran's and Grubbs' tests).
//!
//! Notation of ISO 5725-2 §7.4: p groups, group i has n_i results with mean ȳ_i and standard
//! deviation s_i.
//! - s_r² = Σ(n_i − 1)s_i² / Σ(n_i − 1)
//! - s_d² = Σ n_i(ȳ_i − ȳ)² / (p − 1), with ȳ = Σ n_i ȳ_i / Σ n_i
//! - n̄ = [Σn_i − Σn_i²/Σn_i] / (p − 1)
//! - s_L² = max(0, (s_d² − s_r²)/n̄)
//! - s_R² = s_r² + s_L²
//! - Repeatability and reproducibility limits r = 2.8·s_r, R = 2.8·s_R.
//!
//! The one-way ANOVA F = s_d² / s_r² with (p − 1, Σn_i − p) degrees of freedom.
//!
//! # Consistency and outliers (ISO 5725-2 §7.3)
//!
//! These treat the group means ȳ_i as single values, unweighted, as ISO 5725-2 does with cell
//! averages: m = Σȳ_i / p and s(ȳ) = √(Σ(ȳ_i − m)² / (p − 1)).
//! - Mandel's h (§7.3.1): h_i = (ȳ_i − m) / s(ȳ).
//! - Mandel's k (§7.3.1): k_i = s_i·√p / √Σs_j², over the groups with n_j ≥ 2 (p counts those
//!   groups); a group with one result has no s_i and gets k_i = NaN.
//! - Cochran's C (§7.3.3), on the group variances: C = s_max² / Σs_i², over the groups with
//!   n_i ≥ 2. Its upper critical value at level α, for p variances of n − 1 degrees of freedom
//!   each, is C_crit(α) = 1 / (1 + (p − 1) / F(1 − α/p; n − 1, (p − 1)(n − 1))), with F(q; ν₁, ν₂)
//!   the q quantile of the F distribution. This is the formula behind the classical tables
//!   (Eisenhart, Hastay & Wallis 1947, reproduced as ISO 5725-2 Table 4); it is exact whenever
//!   C_crit > ½ and a close upper bound otherwise. The test strictly needs one common n; when the
//!   groups differ, ISO 5725-2 §7.3.3 allows the most frequent n when they differ little, and
//!   that is what is used here (on a tie, the smallest of the most frequent n, which gives the
//!   larger, more lenient critical values).
//! - Grubbs' single-outlier test (§7.3.4), on the group means: G = max(ȳ_max − m, m − ȳ_min) /
//!   s(ȳ) (the larger mean wins a tie). Its critical value is
//!   G_crit(α) = ((p − 1)/√p)·√(t² / (p − 2 + t²)) with t = t(1 − α/(2p); p − 2), the Student-t
//!   quantile. The α/(2p) (not α/p) is what reproduces ISO 5725-2 Table 5: its "5 %" and "1 %"
//!   columns are Grubbs' one-sided 2.5 % and 0.5 % points, i.e. the level α is shared between the
//!   largest and the smallest value, as suits a test that picks the more extreme of the two
//!   (e.g. p = 10: Table 5 gives 2.290 and 2.482; α/p would give 2.176 and 2.410).
//! - Verdicts (§7.3.2): statistic ≤ 5 % critical value: accepted; between the 5 % and 1 %
//!   critical values: straggler; above the 1 % critical value: statistical outlier.
//!
//! Where a statistic's denominator is zero (all group means equal, all variances zero) Mandel's
//! h or k is NaN and the test is `None`.

use serde::Serialize;
use statrs::distribution::{ContinuousCDF, FisherSnedecor, StudentsT};

/// The result of [`analyse`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Iso5725 {
    /// Number of groups (noise levels) with at least one result.
    pub groups: usize,
    /// Results per group.
    pub n_per_group: Vec<usize>,
    /// Mean of every result.
    pub grand_mean: f64,
    /// Repeatability standard deviation s_r.
    pub s_r: f64,
    /// Between-group standard deviation s_L.
    pub s_l: f64,
    /// Reproducibility standard deviation s_R = √(s_r² + s_L²).
    pub s_rr: f64,
    /// Repeatability limit r = 2.8·s_r.
    pub repeatability_limit: f64,
    /// Reproducibility limit R = 2.8·s_R.
    pub reproducibility_limit: f64,
    /// One-way ANOVA of the groups; `None` with fewer than 2 groups or no within-group freedom.
    pub anova: Option<Anova>,
    /// Mandel's h per group (ISO 5725-2 §7.3.1), in the order of the non-empty groups:
    /// h_i = (ȳ_i − m)/s(ȳ) with m and s(ȳ) the unweighted mean and standard deviation of the
    /// group means. Empty with fewer than 2 groups; NaN when every group mean is the same.
    pub mandel_h: Vec<f64>,
    /// Mandel's k per group (ISO 5725-2 §7.3.1): k_i = s_i·√p/√Σs_j² over the groups with at
    /// least 2 results. Empty with fewer than 2 groups; NaN for a group with one result and when
    /// every group's variance is zero.
    pub mandel_k: Vec<f64>,
    /// Cochran's test for the largest group variance (ISO 5725-2 §7.3.3); `None` with fewer than
    /// 2 groups of at least 2 results, or when every group variance is zero.
    pub cochran: Option<OutlierTest>,
    /// Grubbs' single-outlier test on the group means (ISO 5725-2 §7.3.4); `None` with fewer than
    /// 3 groups or when every group mean is the same.
    pub grubbs: Option<OutlierTest>,
}

/// One outlier test of ISO 5725-2 §7.3 (Cochran or Grubbs) on the most extreme group.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutlierTest {
    /// The test statistic (Cochran's C or Grubbs' G).
    pub statistic: f64,
    /// Critical value at the 5 % significance level.
    pub critical_5: f64,
    /// Critical value at the 1 % significance level.
    pub critical_1: f64,
    /// The group tested (the most extreme one), as an index among the non-empty groups.
    pub group: usize,
    /// The verdict of ISO 5725-2 §7.3.2.
    pub verdict: OutlierVerdict,
}

/// Verdict of an outlier test (ISO 5725-2 §7.3.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OutlierVerdict {
    /// Statistic ≤ the 5 % critical value: the group is accepted as correct.
    Accepted,
    /// 5 % critical value < statistic ≤ 1 % critical value: a straggler.
    Straggler,
    /// Statistic > the 1 % critical value: a statistical outlier.
    Outlier,
}

impl OutlierVerdict {
    /// The verdict for `statistic` against the 5 % and 1 % critical values.
    pub fn of(statistic: f64, critical_5: f64, critical_1: f64) -> Self {
        if statistic > critical_1 {
            Self::Outlier
        } else if statistic > critical_5 {
            Self::Straggler
        } else {
            Self::Accepted
        }
    }
}

/// One-way analysis of variance across groups.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Anova {
    /// F = between-group mean square / within-group mean square.
    pub f: f64,
    /// Between-group degrees of freedom, p − 1.
    pub df_between: usize,
    /// Within-group degrees of freedom, N − p.
    pub df_within: usize,
    /// P(F' ≥ F) under the hypothesis that every group has the same mean.
    pub p_value: f64,
}

/// Analyses `groups` (one slice of results per noise level; empty groups are skipped).
pub fn analyse(groups: &[Vec<f64>]) -> Iso5725 {
    let groups: Vec<&Vec<f64>> = groups.iter().filter(|g| !g.is_empty()).collect();
    let p = groups.len();
    let n_per_group: Vec<usize> = groups.iter().map(|g| g.len()).collect();
    let n_total: usize = n_per_group.iter().sum();
    let means: Vec<f64> = groups
        .iter()
        .map(|g| g.iter().sum::<f64>() / g.len() as f64)
        .collect();
    let grand_mean = groups.iter().flat_map(|g| g.iter()).sum::<f64>() / n_total.max(1) as f64;
    let within_ss: f64 = groups
        .iter()
        .zip(&means)
        .map(|(g, m)| g.iter().map(|x| (x - m).powi(2)).sum::<f64>())
        .sum();
    let df_within = n_total.saturating_sub(p);
    let s_r2 = if df_within > 0 {
        within_ss / df_within as f64
    } else {
        f64::NAN
    };
    let between_ss: f64 = n_per_group
        .iter()
        .zip(&means)
        .map(|(&n, m)| n as f64 * (m - grand_mean).powi(2))
        .sum();
    let (s_l2, anova) = if p >= 2 {
        let s_d2 = between_ss / (p - 1) as f64;
        let sum_n2: f64 = n_per_group.iter().map(|&n| (n * n) as f64).sum();
        let n_bar = (n_total as f64 - sum_n2 / n_total as f64) / (p - 1) as f64;
        let s_l2 = ((s_d2 - s_r2) / n_bar).max(0.0);
        let anova = (df_within > 0 && s_r2 > 0.0).then(|| {
            let f = s_d2 / s_r2;
            let dist = FisherSnedecor::new((p - 1) as f64, df_within as f64)
                .expect("positive degrees of freedom");
            Anova {
                f,
                df_between: p - 1,
                df_within,
                p_value: 1.0 - dist.cdf(f),
            }
        });
        (s_l2, anova)
    } else {
        (0.0, None)
    };
    let s_r = s_r2.sqrt();
    let s_rr = (s_r2 + s_l2).sqrt();
    // Sample variance per group; `None` for a group with a single result.
    let variances: Vec<Option<f64>> = groups
        .iter()
        .zip(&means)
        .map(|(g, m)| {
            (g.len() >= 2)
                .then(|| g.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (g.len() - 1) as f64)
        })
        .collect();
    let cochran = cochran(&variances, &n_per_group);
    let grubbs = grubbs(&means);
    let (mandel_h, mandel_k) = if p >= 2 {
        (mandel_h(&means), mandel_k(&variances))
    } else {
        (Vec::new(), Vec::new())
    };
    Iso5725 {
        groups: p,
        n_per_group,
        grand_mean,
        s_r,
        s_l: s_l2.sqrt(),
        s_rr,
        repeatability_limit: 2.8 * s_r,
        reproducibility_limit: 2.8 * s_rr,
        anova,
        mandel_h,
        mandel_k,
        cochran,
        grubbs,
    }
}

/// Unweighted mean and sample standard deviation of `values` (at least 2).
fn mean_sd(values: &[f64]) -> (f64, f64) {
    let m = values.iter().sum::<f64>() / values.len() as f64;
    let ss: f64 = values.iter().map(|v| (v - m).powi(2)).sum();
    (m, (ss / (values.len() - 1) as f64).sqrt())
}

/// Mandel's h of the group means (at least 2); NaN everywhere when they are all equal.
fn mandel_h(means: &[f64]) -> Vec<f64> {
    let (m, s) = mean_sd(means);
    means
        .iter()
        .map(|y| if s > 0.0 { (y - m) / s } else { f64::NAN })
        .collect()
}

/// Mandel's k of the group variances (`None`: a group with one result, k = NaN).
fn mandel_k(variances: &[Option<f64>]) -> Vec<f64> {
    let p = variances.iter().flatten().count();
    let sum: f64 = variances.iter().flatten().sum();
    variances
        .iter()
        .map(|v| match v {
            Some(v) if sum > 0.0 => (v * p as f64 / sum).sqrt(),
            _ => f64::NAN,
        })
        .collect()
}

/// Cochran's test on the variances of the groups with at least 2 results; the critical values
/// use the most frequent n among those groups (the smallest such n on a tie).
fn cochran(variances: &[Option<f64>], n_per_group: &[usize]) -> Option<OutlierTest> {
    let tested: Vec<(usize, f64, usize)> = variances
        .iter()
        .zip(n_per_group)
        .enumerate()
        .filter_map(|(i, (v, &n))| v.map(|v| (i, v, n)))
        .collect();
    let p = tested.len();
    if p < 2 {
        return None;
    }
    let sum: f64 = tested.iter().map(|t| t.1).sum();
    if sum <= 0.0 {
        return None;
    }
    // First of the largest variances.
    let (group, max, _) = tested
        .iter()
        .copied()
        .fold(tested[0], |best, t| if t.1 > best.1 { t } else { best });
    let n = most_frequent(tested.iter().map(|t| t.2));
    let statistic = max / sum;
    let critical_5 = cochran_critical(p, n, 0.05);
    let critical_1 = cochran_critical(p, n, 0.01);
    Some(OutlierTest {
        statistic,
        critical_5,
        critical_1,
        group,
        verdict: OutlierVerdict::of(statistic, critical_5, critical_1),
    })
}

/// The most frequent value (the smallest one on a tie); `values` must not be empty.
fn most_frequent(values: impl Iterator<Item = usize>) -> usize {
    let mut sorted: Vec<usize> = values.collect();
    sorted.sort_unstable();
    let mut best = (sorted[0], 0);
    for run in sorted.chunk_by(|a, b| a == b) {
        if run.len() > best.1 {
            best = (run[0], run.len());
        }
    }
    best.0
}

/// Upper critical value of Cochran's C for `p` variances from `n` results each (p ≥ 2, n ≥ 2)
/// at significance level `alpha`: 1 / (1 + (p − 1)/F(1 − α/p; n − 1, (p − 1)(n − 1))).
pub fn cochran_critical(p: usize, n: usize, alpha: f64) -> f64 {
    assert!(
        p >= 2 && n >= 2,
        "Cochran's test needs p ≥ 2 groups of n ≥ 2 results"
    );
    let nu = (n - 1) as f64;
    let f = FisherSnedecor::new(nu, (p - 1) as f64 * nu).expect("positive degrees of freedom");
    let q = f.inverse_cdf(1.0 - alpha / p as f64);
    1.0 / (1.0 + (p - 1) as f64 / q)
}

/// Grubbs' single-outlier test on the group means (`None` with fewer than 3 or all equal).
fn grubbs(means: &[f64]) -> Option<OutlierTest> {
    let p = means.len();
    if p < 3 {
        return None;
    }
    let (m, s) = mean_sd(means);
    if s <= 0.0 || !s.is_finite() {
        return None;
    }
    // First of the largest and first of the smallest mean; the largest wins a tie.
    let hi = (0..p).fold(0, |b, i| if means[i] > means[b] { i } else { b });
    let lo = (0..p).fold(0, |b, i| if means[i] < means[b] { i } else { b });
    let (group, deviation) = if means[hi] - m >= m - means[lo] {
        (hi, means[hi] - m)
    } else {
        (lo, m - means[lo])
    };
    let statistic = deviation / s;
    let critical_5 = grubbs_critical(p, 0.05);
    let critical_1 = grubbs_critical(p, 0.01);
    Some(OutlierTest {
        statistic,
        critical_5,
        critical_1,
        group,
        verdict: OutlierVerdict::of(statistic, critical_5, critical_1),
    })
}

/// Critical value of Grubbs' single-outlier statistic (the more extreme of the largest and the
/// smallest value) for `p` values (p ≥ 3) at significance level `alpha`, as in ISO 5725-2
/// Table 5: ((p − 1)/√p)·√(t²/(p − 2 + t²)), t = t(1 − α/(2p); p − 2).
pub fn grubbs_critical(p: usize, alpha: f64) -> f64 {
    assert!(p >= 3, "Grubbs' test needs p ≥ 3 values");
    let pf = p as f64;
    let t = StudentsT::new(0.0, 1.0, pf - 2.0)
        .expect("positive degrees of freedom")
        .inverse_cdf(1.0 - alpha / (2.0 * pf));
    (pf - 1.0) / pf.sqrt() * (t * t / (pf - 2.0 + t * t)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balanced_groups_match_the_hand_computation() {
        // Groups {1,2,3}, {2,3,4}, {6,7,8}: means 2, 3, 7; grand mean 4; within SS = 2+2+2 = 6,
        // df 6 → s_r² = 1. Between SS = 3·(4+1+9) = 42, df 2 → s_d² = 21; n̄ = 3;
        // s_L² = (21 − 1)/3 = 6.667; s_R² = 7.667. F = 21, p = P(F(2,6) ≥ 21) = 0.001953.
        let a = analyse(&[
            vec![1.0, 2.0, 3.0],
            vec![2.0, 3.0, 4.0],
            vec![6.0, 7.0, 8.0],
        ]);
        assert_eq!(a.groups, 3);
        assert!((a.grand_mean - 4.0).abs() < 1e-12);
        assert!((a.s_r - 1.0).abs() < 1e-12);
        assert!((a.s_l.powi(2) - 20.0 / 3.0).abs() < 1e-12);
        assert!((a.s_rr.powi(2) - 23.0 / 3.0).abs() < 1e-12);
        assert!((a.repeatability_limit - 2.8).abs() < 1e-12);
        let anova = a.anova.unwrap();
        assert!((anova.f - 21.0).abs() < 1e-12);
        assert_eq!((anova.df_between, anova.df_within), (2, 6));
        assert!((anova.p_value - 0.001953).abs() < 2e-6, "{}", anova.p_value);
    }

    #[test]
    fn identical_group_means_give_no_between_group_variance() {
        let a = analyse(&[vec![1.0, 3.0], vec![0.0, 4.0], vec![]]);
        assert_eq!(a.groups, 2);
        assert_eq!(a.s_l, 0.0);
        assert!(a.anova.unwrap().p_value > 0.99);
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn cochran_critical_values_match_the_published_tables() {
        // (p, n, 1 % value, 5 % value). The 1 % values are the 4-decimal table of Eisenhart,
        // Hastay & Wallis (1947), "Techniques of Statistical Analysis", ch. 15, as reproduced at
        // faculty.washington.edu/heagerty/Books/Biostatistics/TABLES/Cochran/ (columns = n);
        // the 5 % values are the 3-decimal table of the UK NMS (LGC) "Cochran test" page
        // (nmschembio.org.uk, GenericArticle.aspx?amid=5622). ISO 5725-2 Table 4 prints the same
        // values rounded to 3 decimals, e.g. p = 4, n = 2: 0.968 and 0.906; p = 5, n = 5: 0.633
        // and 0.544; p = 10, n = 5: 0.393 and 0.331.
        let table = [
            (2, 3, 0.9950, 0.975),
            (4, 2, 0.9676, 0.906),
            (5, 5, 0.6329, 0.544),
            (10, 5, 0.3934, 0.331),
            (20, 5, 0.2288, 0.192),
        ];
        for (p, n, c1, c5) in table {
            let (got1, got5) = (cochran_critical(p, n, 0.01), cochran_critical(p, n, 0.05));
            assert!(close(got1, c1, 0.6e-4), "p={p} n={n} 1 %: {got1} vs {c1}");
            assert!(close(got5, c5, 0.6e-3), "p={p} n={n} 5 %: {got5} vs {c5}");
        }
        // p = 5, n = 20 is beyond ISO 5725-2 Table 4 (n ≤ 6). Eisenhart et al. give, at 1 %,
        // 0.4094 for n = 17 and 0.3351 for n = 37; n = 20 must fall between them.
        assert!(close(cochran_critical(5, 17, 0.01), 0.4094, 0.6e-4));
        let c = cochran_critical(5, 20, 0.01);
        assert!(c < 0.4094 && c > 0.3351, "{c}");
        assert!(cochran_critical(5, 20, 0.05) < c);
    }

    #[test]
    fn grubbs_critical_values_match_iso_5725_2_table_5() {
        // (p, 5 % value, 1 % value) of ISO 5725-2:1994 Table 5 ("one largest or one smallest"),
        // as reproduced in LibreTexts Chemistry, Analytical References, Appendix 07 "Critical
        // Values for Grubb's Test".
        let iso = [
            (3, 1.155, 1.155),
            (4, 1.481, 1.496),
            (5, 1.715, 1.764),
            (6, 1.887, 1.973),
            (10, 2.290, 2.482),
        ];
        for (p, g5, g1) in iso {
            let (got5, got1) = (grubbs_critical(p, 0.05), grubbs_critical(p, 0.01));
            // ISO prints 1.155 for p = 3 at 5 %, where the formula (and the 4-decimal table
            // below) gives 1.1543; the largest G possible with p = 3 is 2/√3 = 1.1547.
            let tol5 = if p == 3 { 1e-3 } else { 0.6e-3 };
            assert!(close(got5, g5, tol5), "p={p} 5 %: {got5} vs {g5}");
            assert!(close(got1, g1, 0.6e-3), "p={p} 1 %: {got1} vs {g1}");
        }
        // The same at 4 decimals, from the table in octave-samplestat's grubbs_crit.m
        // (github.com/haniibrahim/octave-samplestat).
        let four = [
            (3, 1.1543, 1.1547),
            (4, 1.4812, 1.4962),
            (5, 1.7150, 1.7637),
            (6, 1.8871, 1.9728),
        ];
        for (p, g5, g1) in four {
            assert!(close(grubbs_critical(p, 0.05), g5, 0.6e-4), "p={p} 5 %");
            assert!(close(grubbs_critical(p, 0.01), g1, 0.6e-4), "p={p} 1 %");
        }
        assert!(grubbs_critical(3, 0.01) < 2.0 / 3f64.sqrt());
    }

    #[test]
    fn verdict_thresholds() {
        assert_eq!(OutlierVerdict::of(0.5, 0.6, 0.7), OutlierVerdict::Accepted);
        assert_eq!(OutlierVerdict::of(0.6, 0.6, 0.7), OutlierVerdict::Accepted);
        assert_eq!(
            OutlierVerdict::of(0.65, 0.6, 0.7),
            OutlierVerdict::Straggler
        );
        assert_eq!(OutlierVerdict::of(0.7, 0.6, 0.7), OutlierVerdict::Straggler);
        assert_eq!(OutlierVerdict::of(0.71, 0.6, 0.7), OutlierVerdict::Outlier);
        assert_eq!(
            serde_json::to_value(OutlierVerdict::Straggler).unwrap(),
            serde_json::json!("straggler")
        );
    }

    #[test]
    fn a_group_with_a_much_larger_variance_is_a_cochran_outlier() {
        // p = 4, n = 3. Variances 1, 1, 1, 100 (group 3: deviations −10, 0, 10, SS 200, df 2).
        // C = 100/103 = 0.97087 > C_crit(1 %; p = 4, n = 3) = 0.8643 (ISO 5725-2 Table 4: 0.864).
        let a = analyse(&[
            vec![1.0, 2.0, 3.0],
            vec![3.0, 4.0, 5.0],
            vec![2.0, 3.0, 4.0],
            vec![-7.0, 3.0, 13.0],
        ]);
        let c = a.cochran.unwrap();
        assert!(close(c.statistic, 100.0 / 103.0, 1e-12));
        assert!(
            close(c.critical_1, 0.8643, 1e-4) && close(c.critical_5, 0.7679, 1e-4),
            "{c:?}"
        );
        assert_eq!((c.group, c.verdict), (3, OutlierVerdict::Outlier));
        // Means 2, 4, 3, 3: m = 3, s = √(2/3); G = 1/√(2/3) = 1.2247 (the largest mean, group 1,
        // wins the tie with the smallest) < 1.481: accepted.
        let g = a.grubbs.unwrap();
        assert!(close(g.statistic, 1.5f64.sqrt(), 1e-12));
        assert_eq!((g.group, g.verdict), (1, OutlierVerdict::Accepted));
        // k_3 = 10·√4/√103.
        assert!(close(a.mandel_k[3], 20.0 / 103f64.sqrt(), 1e-12));
    }

    #[test]
    fn a_moderately_larger_variance_is_a_cochran_straggler() {
        // Variances 1, 1, 1, 12 ({0, 0, 6}: mean 2, SS 4 + 4 + 16 = 24, df 2): C = 12/15 = 0.8,
        // between 0.7679 (5 %) and 0.8643 (1 %).
        let a = analyse(&[
            vec![1.0, 2.0, 3.0],
            vec![3.0, 4.0, 5.0],
            vec![2.0, 3.0, 4.0],
            vec![0.0, 0.0, 6.0],
        ]);
        let c = a.cochran.unwrap();
        assert!(close(c.statistic, 0.8, 1e-12));
        assert_eq!((c.group, c.verdict), (3, OutlierVerdict::Straggler));
    }

    #[test]
    fn a_far_off_group_mean_is_a_grubbs_outlier() {
        // p = 6, n = 2, groups {m − 1, m + 1} with means 2, 3, 4, 3, 2, 22: m̄ = 36/6 = 6,
        // deviations −4, −3, −2, −3, −4, 16, SS = 310, s² = 62; G = 16/√62 = 2.0320
        // > G_crit(1 %; p = 6) = 1.973 (ISO 5725-2 Table 5).
        let means = [2.0, 3.0, 4.0, 3.0, 2.0, 22.0];
        let groups: Vec<Vec<f64>> = means.iter().map(|m| vec![m - 1.0, m + 1.0]).collect();
        let a = analyse(&groups);
        let g = a.grubbs.unwrap();
        assert!(close(g.statistic, 16.0 / 62f64.sqrt(), 1e-12));
        assert_eq!((g.group, g.verdict), (5, OutlierVerdict::Outlier));
        // Equal variances (2 each): C = 1/6, the first group reported; accepted.
        let c = a.cochran.unwrap();
        assert!(close(c.statistic, 1.0 / 6.0, 1e-12));
        assert_eq!((c.group, c.verdict), (0, OutlierVerdict::Accepted));
        assert!(close(a.mandel_h[5], 16.0 / 62f64.sqrt(), 1e-12));
        assert!(close(a.mandel_h[0], -4.0 / 62f64.sqrt(), 1e-12));
    }

    #[test]
    fn clean_data_are_accepted_and_mandel_h_k_match_the_hand_computation() {
        // Means 2, 3, 3, 4, 3 (m = 3, SS 2, s(ȳ) = √0.5); variances 1, 1, 4, 1, 1 (Σ = 8).
        let a = analyse(&[
            vec![1.0, 2.0, 3.0],
            vec![2.0, 3.0, 4.0],
            vec![1.0, 3.0, 5.0],
            vec![3.0, 4.0, 5.0],
            vec![2.0, 3.0, 4.0],
        ]);
        // h_i = (ȳ_i − 3)/√0.5.
        let h = [-2f64.sqrt(), 0.0, 0.0, 2f64.sqrt(), 0.0];
        // k_i = s_i·√5/√8.
        let k1 = (5.0f64 / 8.0).sqrt();
        let k = [k1, k1, 2.0 * k1, k1, k1];
        assert_eq!((a.mandel_h.len(), a.mandel_k.len()), (5, 5));
        for i in 0..5 {
            assert!(
                close(a.mandel_h[i], h[i], 1e-12),
                "h[{i}] = {}",
                a.mandel_h[i]
            );
            assert!(
                close(a.mandel_k[i], k[i], 1e-12),
                "k[{i}] = {}",
                a.mandel_k[i]
            );
        }
        // C = 4/8 = 0.5 < 0.6838 (p = 5, n = 3, 5 %); G = 1/√0.5 = 1.4142 < 1.715.
        let c = a.cochran.unwrap();
        assert!(close(c.statistic, 0.5, 1e-12));
        assert_eq!((c.group, c.verdict), (2, OutlierVerdict::Accepted));
        let g = a.grubbs.unwrap();
        assert!(close(g.statistic, 2f64.sqrt(), 1e-12));
        assert_eq!((g.group, g.verdict), (3, OutlierVerdict::Accepted));
    }

    #[test]
    fn unequal_group_sizes_use_the_most_frequent_n() {
        // n = 3, 3, 4, 1. The single result has no variance: Cochran over p = 3 groups with the
        // most frequent n = 3. Variances 1, 1, 5/3 ({0, 1, 2, 3}: SS 5, df 3); Σ = 11/3;
        // C = 5/11; k_i = √(s_i²·3/(11/3)).
        let a = analyse(&[
            vec![1.0, 2.0, 3.0],
            vec![2.0, 3.0, 4.0],
            vec![0.0, 1.0, 2.0, 3.0],
            vec![10.0],
        ]);
        let c = a.cochran.unwrap();
        assert!(close(c.statistic, 5.0 / 11.0, 1e-12));
        assert_eq!(c.group, 2);
        assert_eq!(c.critical_5, cochran_critical(3, 3, 0.05));
        assert_eq!(c.critical_1, cochran_critical(3, 3, 0.01));
        assert!(close(a.mandel_k[0], (9.0f64 / 11.0).sqrt(), 1e-12));
        assert!(close(a.mandel_k[2], (15.0f64 / 11.0).sqrt(), 1e-12));
        assert!(a.mandel_k[3].is_nan());
        // Grubbs uses all four means, 2, 3, 1.5 and 10: the largest is the far one.
        assert_eq!(a.grubbs.unwrap().group, 3);
        assert_eq!(most_frequent([4, 2, 3, 2, 3].into_iter()), 2);
        assert_eq!(most_frequent([5, 5, 2].into_iter()), 5);
    }

    #[test]
    fn tests_need_enough_groups_and_results() {
        // One group: no tests, no Mandel statistics.
        let one = analyse(&[vec![1.0, 2.0, 3.0], vec![]]);
        assert!(one.cochran.is_none() && one.grubbs.is_none());
        assert!(one.mandel_h.is_empty() && one.mandel_k.is_empty());
        // Two groups: Cochran and Mandel, no Grubbs (p < 3).
        let two = analyse(&[vec![1.0, 2.0, 3.0], vec![1.0, 3.0, 5.0]]);
        assert!(two.cochran.is_some() && two.grubbs.is_none());
        assert_eq!((two.mandel_h.len(), two.mandel_k.len()), (2, 2));
        // One result per group: no variances, so no Cochran and NaN k; Grubbs still runs.
        let singles = analyse(&[vec![1.0], vec![2.0], vec![9.0]]);
        assert!(singles.cochran.is_none() && singles.grubbs.is_some());
        assert!(singles.mandel_k.iter().all(|k| k.is_nan()));
        // Identical means: h undefined (NaN), no Grubbs; zero variances: no Cochran.
        let flat = analyse(&[vec![1.0, 1.0], vec![1.0, 1.0], vec![1.0, 1.0]]);
        assert!(flat.mandel_h.iter().all(|h| h.is_nan()));
        assert!(flat.grubbs.is_none() && flat.cochran.is_none());
    }
}
