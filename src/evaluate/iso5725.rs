//! ISO 5725-2 analysis with the noise levels as the "laboratories": repeatability (within a
//! level), between-level and reproducibility standard deviations, and a one-way ANOVA that
//! answers the paper's question "does the noise level change the result?".
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

use serde::Serialize;
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

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
    let means: Vec<f64> = groups.iter().map(|g| g.iter().sum::<f64>() / g.len() as f64).collect();
    let grand_mean = groups.iter().flat_map(|g| g.iter()).sum::<f64>() / n_total.max(1) as f64;
    let within_ss: f64 = groups.iter().zip(&means).map(|(g, m)| g.iter().map(|x| (x - m).powi(2)).sum::<f64>()).sum();
    let df_within = n_total.saturating_sub(p);
    let s_r2 = if df_within > 0 { within_ss / df_within as f64 } else { f64::NAN };
    let between_ss: f64 = n_per_group.iter().zip(&means).map(|(&n, m)| n as f64 * (m - grand_mean).powi(2)).sum();
    let (s_l2, anova) = if p >= 2 {
        let s_d2 = between_ss / (p - 1) as f64;
        let sum_n2: f64 = n_per_group.iter().map(|&n| (n * n) as f64).sum();
        let n_bar = (n_total as f64 - sum_n2 / n_total as f64) / (p - 1) as f64;
        let s_l2 = ((s_d2 - s_r2) / n_bar).max(0.0);
        let anova = (df_within > 0 && s_r2 > 0.0).then(|| {
            let f = s_d2 / s_r2;
            let dist = FisherSnedecor::new((p - 1) as f64, df_within as f64).expect("positive degrees of freedom");
            Anova { f, df_between: p - 1, df_within, p_value: 1.0 - dist.cdf(f) }
        });
        (s_l2, anova)
    } else {
        (0.0, None)
    };
    let s_r = s_r2.sqrt();
    let s_rr = (s_r2 + s_l2).sqrt();
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balanced_groups_match_the_hand_computation() {
        // Groups {1,2,3}, {2,3,4}, {6,7,8}: means 2, 3, 7; grand mean 4; within SS = 2+2+2 = 6,
        // df 6 → s_r² = 1. Between SS = 3·(4+1+9) = 42, df 2 → s_d² = 21; n̄ = 3;
        // s_L² = (21 − 1)/3 = 6.667; s_R² = 7.667. F = 21, p = P(F(2,6) ≥ 21) = 0.001953.
        let a = analyse(&[vec![1.0, 2.0, 3.0], vec![2.0, 3.0, 4.0], vec![6.0, 7.0, 8.0]]);
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
}
