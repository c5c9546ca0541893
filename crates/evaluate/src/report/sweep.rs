//! The summary of reports of several output folders that differ in one or more parameters (a
//! sweep): one CSV long table of every cell of every report, and one HTML page with a plot of
//! each cell (table, parameter, noise level) against the varied parameter. It knows nothing of
//! how the folders were made: the caller names the points, their parameter values and where each
//! sits on the x axis.

use std::fmt::Write;

use super::csv::{HEADER, finish, records, writer};
use super::html::{page_start, plot_figures};
use super::{LEGEND, confidence_text, level_text, svg};
use crate::output::html_text::escape as esc;
use crate::stats::Cell;
use crate::table::{Report, Table};

/// One point of the summary: its report and where it stands.
pub struct SummaryPoint<'a> {
    /// Point id, e.g. `p03`.
    pub id: String,
    /// The value of every parameter, as written in the summary's columns.
    pub values: Vec<String>,
    /// The point's position on the x axis.
    pub x: f64,
    /// The label of that position under the axis.
    pub x_label: String,
    /// The point's series: the values of the parameters other than the x axis's, as text; empty
    /// when only one parameter varies.
    pub series: String,
    /// The point's evaluation.
    pub report: &'a Report,
}

/// A sweep's summary.
pub struct Summary<'a> {
    /// The sweep's name.
    pub name: String,
    /// Facts shown at the top of the page: (label, text).
    pub facts: Vec<(String, String)>,
    /// The parameter columns' names, in the order of [`SummaryPoint::values`].
    pub parameters: Vec<String>,
    /// What the x axis shows (a parameter's name).
    pub x_name: String,
    /// The points, in sweep order.
    pub points: Vec<SummaryPoint<'a>>,
}

/// At most this many parameter columns stand in one table of the points: a sweep that varies
/// more keys gets several tables, each repeating the point column, so every column fits a
/// portrait page and a screen (values such as `[-482.963, 0.0, -129.41]` are wide).
const POINT_COLUMNS: usize = 3;

/// The points with their parameter values, [`POINT_COLUMNS`] parameters per table; the last
/// table ends with the runs scored and excluded.
fn points_tables(s: &mut String, summary: &Summary) {
    let n = summary.parameters.len();
    let parts = n.div_ceil(POINT_COLUMNS).max(1);
    for part in 0..parts {
        let columns = (part * POINT_COLUMNS).min(n)..((part + 1) * POINT_COLUMNS).min(n);
        let last = part + 1 == parts;
        s.push_str("<table class=\"points\"><thead><tr><th>Point</th>");
        for p in &summary.parameters[columns.clone()] {
            let _ = write!(s, "<th>{}</th>", esc(p));
        }
        if last {
            s.push_str("<th>Runs scored</th><th>Excluded</th>");
        }
        s.push_str("</tr></thead><tbody>\n");
        for p in &summary.points {
            let _ = write!(s, "<tr><td>{}</td>", esc(&p.id));
            for v in &p.values[columns.clone()] {
                let _ = write!(s, "<td><code>{}</code></td>", esc(v));
            }
            if last {
                let _ = write!(
                    s,
                    "<td>{}</td><td>{}</td>",
                    p.report.runs_scored,
                    p.report.excluded.len()
                );
            }
            s.push_str("</tr>\n");
        }
        s.push_str("</tbody></table>\n");
    }
}

/// The summary as CSV: columns `point`, one per parameter (named after it), then the columns of
/// an evaluation's `report.csv` (table, group, parameter, unit, noise_level, n, trueness,
/// precision, sd, tau, rms, significance, exposure_factor). One row per point and cell of its report, in point
/// order and then in `report.csv`'s order, with the same text in every shared field, so each
/// point's rows are exactly its report.csv rows.
pub fn summary_csv(summary: &Summary) -> String {
    let mut w = writer();
    let header: Vec<&str> = std::iter::once("point")
        .chain(summary.parameters.iter().map(String::as_str))
        .chain(HEADER)
        .collect();
    w.write_record(&header).expect("write to memory");
    for p in &summary.points {
        for record in records(p.report) {
            let row: Vec<&str> = std::iter::once(p.id.as_str())
                .chain(p.values.iter().map(String::as_str))
                .chain(record.iter().map(String::as_str))
                .collect();
            w.write_record(&row).expect("write to memory");
        }
    }
    finish(w)
}

/// The summary as one self-contained HTML page: facts, the points with their parameters and
/// runs scored, then per series and noise level a plot of every cell of every table (and MTPM)
/// against the x parameter. The output depends only on `summary`.
pub fn summary_html(summary: &Summary) -> String {
    let mut s = page_start(&format!("RSA sweep: {}", summary.name));
    s.push_str("<table class=\"facts\"><tbody>\n");
    let mut facts = summary.facts.clone();
    if let Some(first) = summary.points.first() {
        facts.push((
            "Confidence".into(),
            confidence_text(&first.report.confidence),
        ));
        facts.push(("Results file".into(), first.report.results_file.clone()));
    }
    for (k, v) in &facts {
        let _ = writeln!(s, "<tr><th>{}</th><td>{}</td></tr>", esc(k), esc(v));
    }
    s.push_str("</tbody></table>\n<h2>Points</h2>\n");
    points_tables(&mut s, summary);
    let _ = writeln!(
        s,
        "<h2>Trueness ± precision against {}</h2>\n<p class=\"legend\">One plot per cell of the evaluation's tables: the points of the sweep left to right. {}</p>",
        esc(&summary.x_name),
        esc(LEGEND)
    );
    let x_title = esc(&summary.x_name);
    let x_axis = svg::XAxis {
        title_html: &x_title,
        noun: &summary.x_name,
    };
    let mut series: Vec<&str> = Vec::new();
    for p in &summary.points {
        if !series.contains(&p.series.as_str()) {
            series.push(&p.series);
        }
    }
    for label in series {
        let points: Vec<&SummaryPoint> = summary
            .points
            .iter()
            .filter(|p| p.series == label)
            .collect();
        if !label.is_empty() {
            let _ = writeln!(s, "<h2>{}</h2>", esc(label));
        }
        series_plots(&mut s, &points, &x_axis);
    }
    s.push_str("</body>\n</html>\n");
    s
}

/// The plots of one series: per level (the first point's rows), per table, one figure per
/// column. A point whose report lacks the table, row or column has no mark there.
fn series_plots(s: &mut String, points: &[&SummaryPoint], x_axis: &svg::XAxis) {
    let Some(first) = points.first() else {
        return;
    };
    let xs: Vec<f64> = points.iter().map(|p| p.x).collect();
    let labels: Vec<String> = points.iter().map(|p| p.x_label.clone()).collect();
    let tables: Vec<(&Table, Option<f64>)> = first
        .report
        .tables
        .iter()
        .map(|t| (t, None))
        .chain(
            first
                .report
                .mtpm
                .iter()
                .map(|t| (t, Some(first.report.mtpm_threshold_mm))),
        )
        .collect();
    let levels = tables.first().map_or(0, |(t, _)| t.rows.len());
    for level in 0..levels {
        let heading = tables
            .first()
            .and_then(|(t, _)| t.rows.get(level))
            .map(|r| format!("{} level {}", tables[0].0.level_heading(), level_text(r)))
            .unwrap_or_default();
        let _ = writeln!(s, "<h3>{}</h3>", esc(&heading));
        for (table, threshold) in &tables {
            let _ = writeln!(s, "<h4>{}</h4>", esc(&table.caption));
            let cells_of = |column: usize| -> Vec<Option<&Cell>> {
                points
                    .iter()
                    .map(|p| {
                        let theirs = p
                            .report
                            .tables
                            .iter()
                            .chain(&p.report.mtpm)
                            .find(|t| t.id == table.id)?;
                        theirs.rows.get(level)?.cells.get(column)?.as_ref()
                    })
                    .collect()
            };
            plot_figures(s, table, &xs, &labels, x_axis, *threshold, &cells_of);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixture::report;
    use super::*;

    #[test]
    fn many_parameters_split_into_tables_that_each_name_their_points() {
        let r = report();
        for n in [0usize, 1, 3, 4, 8] {
            let summary = Summary {
                name: "s".into(),
                facts: Vec::new(),
                parameters: (0..n).map(|k| format!("key{k}")).collect(),
                x_name: "key0".into(),
                points: (0..2)
                    .map(|p| SummaryPoint {
                        id: format!("p{p:02}"),
                        values: (0..n).map(|k| format!("v{p}{k}")).collect(),
                        x: p as f64,
                        x_label: p.to_string(),
                        series: String::new(),
                        report: &r,
                    })
                    .collect(),
            };
            let mut s = String::new();
            points_tables(&mut s, &summary);
            let tables: Vec<&str> = s.split("<table class=\"points\">").skip(1).collect();
            assert_eq!(
                tables.len(),
                n.div_ceil(POINT_COLUMNS).max(1),
                "{n} parameters"
            );
            for (t, table) in tables.iter().enumerate() {
                // Every table names its points and holds at most POINT_COLUMNS parameters.
                assert_eq!(table.matches("<th>Point</th>").count(), 1);
                assert_eq!(table.matches("<td>p00</td>").count(), 1);
                assert_eq!(table.matches("<td>p01</td>").count(), 1);
                let keys = table.matches("<th>key").count();
                assert!(keys <= POINT_COLUMNS, "{keys} columns");
                assert_eq!(table.contains("Runs scored"), t + 1 == tables.len());
            }
            // Every parameter and every value stands once, in order.
            for k in 0..n {
                assert_eq!(s.matches(&format!("<th>key{k}</th>")).count(), 1);
                for p in 0..2 {
                    assert_eq!(s.matches(&format!("<code>v{p}{k}</code>")).count(), 1);
                }
            }
        }
    }
}
