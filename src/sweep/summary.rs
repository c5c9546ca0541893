//! The sweep's summary: every point's evaluation placed against the swept parameter, written as
//! `sweep_summary.csv` and `sweep_summary.html` into a report folder (claimed like
//! `rsasim evaluate`'s: replaced only when an earlier evaluate wrote it).

use std::path::PathBuf;

use super::folder::Index;
use crate::evaluate::report::sweep::{Summary, SummaryPoint, summary_csv, summary_html};
use crate::evaluate::table::Report;
use crate::output::atomic::write_staged;
use crate::output::commit::OutputTarget;

/// The summary CSV's file name.
pub const SUMMARY_CSV: &str = "sweep_summary.csv";
/// The summary page's file name.
pub const SUMMARY_HTML: &str = "sweep_summary.html";

/// The summary of `index`'s points with their evaluations `reports` (same order). The x axis is
/// the first parameter whose value differs between points (the first parameter when none
/// does): its `axis` numbers, or its values when they are numbers, else the values in order of
/// first appearance. A parameter's column holds its number (`axis`, or the numeric value) or
/// else its value as TOML text. Points that differ in other parameters too (a grid) form one series per
/// combination of those; a parameter zipped with the x parameter makes no series.
pub fn summary<'a>(index: &Index, reports: &'a [Report]) -> Summary<'a> {
    let varies = |j: usize| {
        index
            .points
            .iter()
            .any(|p| p.values.get(j) != index.points.first().and_then(|f| f.values.get(j)))
    };
    let x = (0..index.parameters.len())
        .find(|&j| varies(j))
        .unwrap_or(0);
    // A parameter that takes one value per x value (zipped with it) makes no series of its own.
    let tied = |j: usize| {
        index.points.iter().all(|p| {
            index
                .points
                .iter()
                .all(|q| p.values.get(x) != q.values.get(x) || p.values.get(j) == q.values.get(j))
        })
    };
    let numeric = index
        .points
        .iter()
        .all(|p| p.axis.get(x).copied().flatten().is_some());
    let mut distinct: Vec<&str> = Vec::new();
    for p in &index.points {
        if let Some(v) = p.values.get(x)
            && !distinct.contains(&v.as_str())
        {
            distinct.push(v);
        }
    }
    let points = index
        .points
        .iter()
        .zip(reports)
        .map(|(p, report)| {
            let text = p.values.get(x).cloned().unwrap_or_default();
            let (x_value, x_label) = match p.axis.get(x).copied().flatten() {
                Some(a) if numeric => (a, format!("{a}")),
                _ => (
                    distinct.iter().position(|d| *d == text).unwrap_or(0) as f64,
                    text,
                ),
            };
            let series: Vec<String> = index
                .parameters
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != x && varies(j) && !tied(j))
                .map(|(j, par)| {
                    format!(
                        "{} = {}",
                        par.name,
                        p.values.get(j).map_or("", String::as_str)
                    )
                })
                .collect();
            SummaryPoint {
                id: p.id.clone(),
                values: p
                    .values
                    .iter()
                    .zip(&p.axis)
                    .map(|(v, a)| a.map_or_else(|| v.clone(), |a| format!("{a}")))
                    .collect(),
                x: x_value,
                x_label,
                series: series.join(", "),
                report,
            }
        })
        .collect();
    Summary {
        name: index.name.clone(),
        facts: vec![
            ("Sweep".into(), index.name.clone()),
            (
                "Base scenario".into(),
                format!("{} (SHA-256 {})", index.scenario, index.scenario_sha256),
            ),
            ("Program".into(), index.program.clone()),
            (
                "Points".into(),
                format!("{} ({})", index.points.len(), index.combine),
            ),
            (
                "Parameters".into(),
                index
                    .parameters
                    .iter()
                    .map(|p| {
                        if p.name == p.key {
                            p.key.clone()
                        } else {
                            format!("{} ({})", p.name, p.key)
                        }
                    })
                    .collect::<Vec<_>>()
                    .join(", "),
            ),
        ],
        parameters: index.parameters.iter().map(|p| p.name.clone()).collect(),
        x_name: index
            .parameters
            .get(x)
            .map(|p| p.name.clone())
            .unwrap_or_default(),
        points,
    }
}

/// Writes [`SUMMARY_CSV`] and [`SUMMARY_HTML`] into the claimed report folder `target`, staged
/// and swapped in whole. Returns the paths written.
pub fn write(target: OutputTarget, summary: &Summary) -> std::io::Result<Vec<PathBuf>> {
    let dir = target.shown().to_path_buf();
    let staged = target.stage()?;
    write_staged(
        &staged.path().join(SUMMARY_CSV),
        summary_csv(summary).as_bytes(),
    )?;
    write_staged(
        &staged.path().join(SUMMARY_HTML),
        summary_html(summary).as_bytes(),
    )?;
    staged.commit()?;
    Ok(vec![dir.join(SUMMARY_CSV), dir.join(SUMMARY_HTML)])
}
