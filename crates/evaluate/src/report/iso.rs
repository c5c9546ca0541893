//! The ISO 5725-2 section as a list of named fields, shared by the Markdown, HTML and CSV
//! writers so that every format shows the same values.

use super::{format_number, unicode_minus};
use crate::table::GroupAnalysis;

/// Significance level of the "does the noise level change the result?" test.
pub(crate) const ALPHA: f64 = 0.05;

/// A field's value, formatted by each writer in its own way.
pub(crate) enum Value {
    /// A measured quantity: two significant digits in text, full precision in CSV.
    Num(f64),
    /// A count.
    Int(usize),
    /// Counts, e.g. results per noise level.
    Ints(Vec<usize>),
    /// Text.
    Text(String),
    /// Missing (e.g. no ANOVA possible).
    None,
}

impl Value {
    /// Two significant digits (ASCII minus); counts joined by `/`; missing as an em dash.
    pub(crate) fn text(&self) -> String {
        match self {
            Value::Num(x) => format_number(*x),
            Value::Int(n) => n.to_string(),
            Value::Ints(v) => v.iter().map(usize::to_string).collect::<Vec<_>>().join("/"),
            Value::Text(s) => s.clone(),
            Value::None => "—".into(),
        }
    }

    /// As [`Value::text`], with real minus signs for numbers (HTML and Markdown; text is left
    /// alone).
    pub(crate) fn unicode_text(&self) -> String {
        match self {
            Value::Num(_) => unicode_minus(&self.text()),
            _ => self.text(),
        }
    }

    /// Full precision (Rust's shortest round-trip `{}`); counts joined by `;`; missing empty.
    pub(crate) fn exact(&self) -> String {
        match self {
            Value::Num(x) => x.to_string(),
            Value::Int(n) => n.to_string(),
            Value::Ints(v) => v.iter().map(usize::to_string).collect::<Vec<_>>().join(";"),
            Value::Text(s) => s.clone(),
            Value::None => String::new(),
        }
    }
}

/// One field: a header for text tables, a machine name for CSV, and the value.
pub(crate) struct Field {
    /// Header in text tables.
    pub header: &'static str,
    /// CSV column name.
    pub key: &'static str,
    /// Value.
    pub value: Value,
}

/// The fields of one analysis, left to right.
pub(crate) fn fields(g: &GroupAnalysis) -> Vec<Field> {
    let a = &g.analysis;
    let f = |header, key, value| Field { header, key, value };
    let mut out = vec![
        f("Table", "table", Value::Text(g.table.clone())),
        f("Parameter", "parameter", Value::Text(g.parameter.clone())),
        f("Unit", "unit", Value::Text(g.unit.clone())),
        f("Levels", "groups", Value::Int(a.groups)),
        f(
            "N per level",
            "n_per_group",
            Value::Ints(a.n_per_group.clone()),
        ),
        f("Grand mean", "grand_mean", Value::Num(a.grand_mean)),
        f("s_r", "s_r", Value::Num(a.s_r)),
        f("s_L", "s_L", Value::Num(a.s_l)),
        f("s_R", "s_R", Value::Num(a.s_rr)),
        f("r = 2.8·s_r", "r", Value::Num(a.repeatability_limit)),
        f("R = 2.8·s_R", "R", Value::Num(a.reproducibility_limit)),
    ];
    match &a.anova {
        Some(an) => out.extend([
            f("F", "anova_f", Value::Num(an.f)),
            f("df", "df_between", Value::Int(an.df_between)),
            f("df (within)", "df_within", Value::Int(an.df_within)),
            f("p", "p_value", Value::Num(an.p_value)),
        ]),
        None => out.extend([
            f("F", "anova_f", Value::None),
            f("df", "df_between", Value::None),
            f("df (within)", "df_within", Value::None),
            f("p", "p_value", Value::None),
        ]),
    }
    out.push(f(
        "Noise changes result? (5 %)",
        "noise_changes_result",
        Value::Text(verdict(g).into()),
    ));
    // Outlier checks of ISO 5725-2 §7.3 on the noise-level groups.
    let tests = [
        (
            "Cochran C",
            "cochran",
            "Cochran verdict",
            "cochran_verdict",
            &a.cochran,
        ),
        (
            "Grubbs G (means)",
            "grubbs",
            "Grubbs verdict",
            "grubbs_verdict",
            &a.grubbs,
        ),
    ];
    for (label, key, verdict_label, verdict_key, test) in tests {
        out.push(f(
            label,
            key,
            test.as_ref()
                .map_or(Value::None, |t| Value::Num(t.statistic)),
        ));
        out.push(f(
            verdict_label,
            verdict_key,
            test.as_ref()
                .map_or(Value::None, |t| Value::Text(outlier_text(t))),
        ));
    }
    let h_max = a.mandel_h.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let k_max = a
        .mandel_k
        .iter()
        .filter(|x| x.is_finite())
        .fold(0.0f64, |m, x| m.max(*x));
    out.push(f(
        "max |Mandel h|",
        "mandel_h_max",
        if a.mandel_h.is_empty() {
            Value::None
        } else {
            Value::Num(h_max)
        },
    ));
    out.push(f(
        "max Mandel k",
        "mandel_k_max",
        if a.mandel_k.is_empty() {
            Value::None
        } else {
            Value::Num(k_max)
        },
    ));
    out
}

/// An outlier test's verdict with the group it points at, e.g. "outlier (level 4)".
fn outlier_text(t: &crate::iso5725::OutlierTest) -> String {
    use crate::iso5725::OutlierVerdict;
    match t.verdict {
        OutlierVerdict::Accepted => "accepted".into(),
        OutlierVerdict::Straggler => format!("straggler (group {})", t.group),
        OutlierVerdict::Outlier => format!("outlier (group {})", t.group),
    }
}

/// "yes", "no" or "not testable": does the noise level change the mean residual at 5 %?
pub(crate) fn verdict(g: &GroupAnalysis) -> &'static str {
    match &g.analysis.anova {
        Some(a) if a.p_value < ALPHA => "yes",
        Some(_) => "no",
        None => "not testable",
    }
}

/// The plain-English answer to "does the noise level change the result?" for one parameter.
pub(crate) fn answer(g: &GroupAnalysis) -> String {
    let what = format!("{} / {}", g.table, g.parameter);
    match &g.analysis.anova {
        Some(a) if a.p_value < ALPHA => format!(
            "{what}: yes — the mean residual differs between noise levels (one-way ANOVA F = {}, \
             df = {}, {}, p = {} < 0.05).",
            format_number(a.f),
            a.df_between,
            a.df_within,
            format_number(a.p_value)
        ),
        Some(a) => format!(
            "{what}: no — no evidence at the 5 % level that the noise level changes the mean \
             residual (F = {}, df = {}, {}, p = {}).",
            format_number(a.f),
            a.df_between,
            a.df_within,
            format_number(a.p_value)
        ),
        None => format!(
            "{what}: not testable — fewer than two noise levels with results, or no spread within \
             the levels."
        ),
    }
}
