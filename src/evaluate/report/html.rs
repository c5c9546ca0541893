//! One self-contained HTML file: facts, the paper's tables with shaded significant cells and a
//! plot per parameter, then the sections beyond the paper. No external resources.

use std::fmt::Write;

use super::markdown::unicode_minus_numbers;
use super::{
    BEYOND, LEGEND, N_LEGEND, columns, confidence_text, iso, mark, n_note, svg, trueness_precision,
    unicode_minus, usual_n,
};
use crate::evaluate::stats::{Cell, Significance};
use crate::evaluate::table::{Report, Table};

/// The stylesheet: the paper's red!25 / blue!25 shades, kept when printing.
const STYLE: &str = "body{font-family:Helvetica,Arial,sans-serif;margin:2em auto;max-width:80em;color:#111;\
line-height:1.4;padding:0 1em}\
h1{font-size:1.6em}h2{border-bottom:1px solid #999;margin-top:2em}\
table{border-collapse:collapse;margin:0.6em 0 1em}th,td{border:1px solid #bbb;padding:0.25em 0.5em}\
td{text-align:right;white-space:nowrap}table.facts th{text-align:left}table.facts td{text-align:left}\
.gs{border-left:2px solid #444}td.pos{background:#ffbfbf}td.neg{background:#bfbfff}\
.plots{display:flex;flex-wrap:wrap;gap:0.5em}figure{margin:0}figcaption{font-size:0.85em;text-align:center}\
.legend{font-size:0.9em}code{font-size:0.9em;word-break:break-all}\
*{-webkit-print-color-adjust:exact;print-color-adjust:exact}\
@media print{section{break-inside:avoid}}";

/// The report as one self-contained HTML document, suitable for a dossier as is: the facts that
/// identify the data and the scoring, every table of the paper with significant cells shaded
/// (light red positive, light blue negative) and marked ▲/▼ for black-and-white printing, an
/// inline SVG plot of trueness ± precision against noise level for every parameter, and the
/// sections beyond the paper. The output depends only on `report` (byte-identical re-renders).
pub fn html(report: &Report) -> String {
    let mut s = String::new();
    let title = format!("RSA accuracy report: {}", report.scenario);
    let _ = write!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{}</h1>\n",
        esc(&title),
        esc(&title)
    );
    facts(&mut s, report);
    s.push_str("<h2>Tables as in the paper</h2>\n");
    let _ = writeln!(
        s,
        "<p class=\"legend\">Trueness ± precision per noise level. Significant cells are shaded (light red: positive, light blue: negative) and marked: {} {}</p>",
        esc(LEGEND),
        esc(N_LEGEND)
    );
    for (i, table) in report.tables.iter().enumerate() {
        let _ = writeln!(
            s,
            "<section id=\"{}\">\n<h3>Table {}. {}</h3>",
            attr_id(&table.id),
            i + 1,
            esc(&table.caption)
        );
        grid(&mut s, table, &|c| {
            (unicode_minus(&trueness_precision(c, " ± ")), c.significance)
        });
        plots(&mut s, table);
        s.push_str("</section>\n");
    }
    s.push_str("<h2>Beyond the paper</h2>\n<p>These sections are not in Bontempi et al.; they are computed from the same residuals.</p>\n");
    for (heading, explanation, text) in BEYOND {
        let _ = writeln!(s, "<h3>{}</h3>\n<p>{}</p>", esc(heading), esc(explanation));
        for table in &report.tables {
            let _ = writeln!(s, "<h4>{}</h4>", esc(&table.caption));
            grid(&mut s, table, &|c| {
                (unicode_minus(&text(c)), Significance::None)
            });
        }
    }
    s.push_str("<h3>MTPM</h3>\n");
    match &report.mtpm {
        Some(t) => {
            let _ = writeln!(
                s,
                "<section id=\"{}\">\n<p>{}. Maximum total point motion over each model's beads.</p>",
                attr_id(&t.id),
                esc(&t.caption)
            );
            grid(&mut s, t, &|c| {
                (unicode_minus(&trueness_precision(c, " ± ")), c.significance)
            });
            plots(&mut s, t);
            s.push_str("</section>\n");
        }
        None => s.push_str("<p>No MTPM table (no model with beads was scored).</p>\n"),
    }
    iso5725(&mut s, report);
    s.push_str("</body>\n</html>\n");
    s
}

/// Program, data set, software, confidence, runs, scenario summary and excluded runs.
fn facts(s: &mut String, r: &Report) {
    let software = if r.software.is_empty() {
        "(not named)".to_string()
    } else {
        r.software.join(", ")
    };
    s.push_str("<table class=\"facts\"><tbody>\n");
    for (k, v) in [
        ("Scenario", esc(&r.scenario)),
        ("Program", esc(&r.program)),
        (
            "Manifest SHA-256",
            format!("<code>{}</code>", esc(&r.manifest_sha256)),
        ),
        ("Software under test", esc(&software)),
        ("Results file", esc(&r.results_file)),
        (
            "Rotations re-orthonormalised",
            r.repaired_rotations.to_string(),
        ),
        ("Confidence", esc(&confidence_text(&r.confidence))),
        ("Runs scored", r.runs_scored.to_string()),
    ] {
        let _ = writeln!(s, "<tr><th>{k}</th><td>{v}</td></tr>");
    }
    s.push_str("</tbody></table>\n");
    if !r.summary.is_empty() {
        s.push_str("<h2>Scenario</h2>\n<ul>\n");
        for line in &r.summary {
            let _ = writeln!(s, "<li>{}</li>", esc(line));
        }
        s.push_str("</ul>\n");
    }
    if !r.notes.is_empty() {
        s.push_str("<h2>Notes</h2>\n<ul>\n");
        for line in &r.notes {
            let _ = writeln!(s, "<li>{}</li>", esc(line));
        }
        s.push_str("</ul>\n");
    }
    s.push_str("<h2>Excluded runs</h2>\n");
    if r.excluded.is_empty() {
        s.push_str("<p>None.</p>\n");
    } else {
        s.push_str("<table><thead><tr><th>Run</th><th>Reason</th></tr></thead><tbody>\n");
        for e in &r.excluded {
            let _ = writeln!(
                s,
                "<tr><td>{}</td><td>{}</td></tr>",
                esc(&e.run),
                esc(&e.reason)
            );
        }
        s.push_str("</tbody></table>\n");
    }
}

/// A table with grouped headings; `cell` gives a cell's text and significance.
fn grid(s: &mut String, table: &Table, cell: &dyn Fn(&Cell) -> (String, Significance)) {
    let _ = write!(
        s,
        "<table><thead>\n<tr><th rowspan=\"2\">{}</th><th rowspan=\"2\">N</th>",
        table.level_heading()
    );
    for g in &table.groups {
        let _ = write!(
            s,
            "<th colspan=\"{}\" class=\"gs\">{}</th>",
            g.columns.len(),
            esc(&g.label)
        );
    }
    s.push_str("</tr>\n<tr>");
    let firsts = group_starts(table);
    for (i, (_, c)) in columns(table).enumerate() {
        let class = if firsts.contains(&i) {
            " class=\"gs\""
        } else {
            ""
        };
        let _ = write!(s, "<th{class}>{} ({})</th>", label(&c.label), esc(&c.unit));
    }
    s.push_str("</tr>\n</thead><tbody>\n");
    for row in &table.rows {
        let usual = usual_n(row);
        let n = usual.map_or("—".to_string(), |n| n.to_string());
        let _ = write!(s, "<tr><th>{}</th><td>{n}</td>", esc(&row.level_text()));
        for (i, c) in row.cells.iter().enumerate() {
            let mut classes: Vec<&str> = Vec::new();
            let body = match c {
                Some(c) => {
                    let (text, sig) = cell(c);
                    let mut body = match sig {
                        Significance::None => esc(&text),
                        _ => format!("<strong>{}</strong> {}", esc(&text), mark(sig)),
                    };
                    classes.extend(match sig {
                        Significance::Positive => Some("pos"),
                        Significance::Negative => Some("neg"),
                        Significance::None => None,
                    });
                    if let Some(note) = n_note(c, usual) {
                        let _ = write!(body, " {}", esc(&note));
                    }
                    body
                }
                None => "—".into(),
            };
            if firsts.contains(&i) {
                classes.push("gs");
            }
            let class = if classes.is_empty() {
                String::new()
            } else {
                format!(" class=\"{}\"", classes.join(" "))
            };
            let _ = write!(s, "<td{class}>{body}</td>");
        }
        s.push_str("</tr>\n");
    }
    s.push_str("</tbody></table>\n");
}

/// Indices of the first column of each group.
fn group_starts(table: &Table) -> Vec<usize> {
    let mut starts = Vec::new();
    let mut i = 0;
    for g in &table.groups {
        starts.push(i);
        i += g.columns.len();
    }
    starts
}

/// One plot per parameter of `table`.
fn plots(s: &mut String, table: &Table) {
    let levels: Vec<f64> = table.rows.iter().map(|r| r.level_value()).collect();
    let labels: Vec<String> = table.rows.iter().map(|r| r.level_text()).collect();
    let axis = if table.level_heading() == "Exposure" {
        svg::Axis::Exposure
    } else {
        svg::Axis::Noise
    };
    s.push_str("<div class=\"plots\">\n");
    for (i, (g, c)) in columns(table).enumerate() {
        let cells: Vec<Option<&Cell>> = table
            .rows
            .iter()
            .map(|r| r.cells.get(i).and_then(Option::as_ref))
            .collect();
        let title = if g.label.is_empty() {
            c.label.clone()
        } else {
            format!("{} · {}", g.label, c.label)
        };
        let _ = writeln!(
            s,
            "<figure>{}<figcaption>{} ({}): trueness ± precision against {}</figcaption></figure>",
            svg::plot(&title, &c.unit, &levels, &labels, axis, &cells),
            esc(&title),
            esc(&c.unit),
            axis.noun()
        );
    }
    s.push_str("</div>\n");
}

/// ISO 5725-2: the fields of every analysis, then the plain-English answers.
fn iso5725(s: &mut String, r: &Report) {
    s.push_str("<h3>ISO 5725-2: does the noise level change the result?</h3>\n");
    if r.group_analyses.is_empty() {
        s.push_str("<p>No analyses.</p>\n");
        return;
    }
    s.push_str(
        "<p>Noise levels as the groups of ISO 5725-2: repeatability s_r (within a level), between-level s_L, \
reproducibility s_R, limits r = 2.8·s_r and R = 2.8·s_R, and a one-way ANOVA of the level means.</p>\n",
    );
    s.push_str("<table><thead><tr>");
    for f in iso::fields(&r.group_analyses[0]) {
        let _ = write!(s, "<th>{}</th>", esc(f.header));
    }
    s.push_str("</tr></thead><tbody>\n");
    for g in &r.group_analyses {
        s.push_str("<tr>");
        for f in iso::fields(g) {
            let _ = write!(s, "<td>{}</td>", esc(&unicode_minus_numbers(&f.value)));
        }
        s.push_str("</tr>\n");
    }
    s.push_str("</tbody></table>\n<ul>\n");
    for g in &r.group_analyses {
        let _ = writeln!(s, "<li>{}</li>", esc(&iso::answer(g)));
    }
    s.push_str("</ul>\n");
}

/// A parameter label with its first `_` as a subscript: `α_r` → `α<sub>r</sub>`.
fn label(text: &str) -> String {
    match text.split_once('_') {
        Some((base, sub)) if !base.is_empty() && !sub.is_empty() => {
            format!("{}<sub>{}</sub>", esc(base), esc(sub))
        }
        _ => esc(text),
    }
}

/// An `id` attribute value: letters, digits, `-`, `_` kept, anything else as `-`.
fn attr_id(id: &str) -> String {
    let id: String = id
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .collect();
    format!("table-{id}")
}

/// Escapes `&`, `<`, `>`, `"` and `'` for text and attribute values.
pub(crate) fn esc(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for ch in text.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(ch),
        }
    }
    out
}

#[cfg(test)]
mod tests;
