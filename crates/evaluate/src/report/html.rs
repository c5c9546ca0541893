//! One self-contained HTML file: facts, the paper's tables with shaded significant cells and a
//! plot per parameter, then the sections beyond the paper. No external resources.

use std::fmt::Write;

use super::{
    BEYOND, LEGEND, MtpmVerdict, N_LEGEND, columns, confidence_text, iso, level_text, mark,
    mtpm_legend, mtpm_mark, mtpm_verdict, n_note, svg, trueness_precision, unicode_minus, usual_n,
};
use crate::output::html_text::escape as esc;
use crate::stats::{Cell, Significance};
use crate::table::{ColumnGroup, Report, Table};

/// The stylesheet: the paper's red!25 / blue!25 shades, kept when printing. For paper (A4 or
/// Letter, portrait): smaller type, no page width limit, table heads repeated on every page, a
/// row, a plot with its caption and a heading with what follows kept together.
pub(crate) const STYLE: &str = "body{font-family:Helvetica,Arial,sans-serif;margin:2em auto;max-width:80em;color:#111;\
line-height:1.4;padding:0 1em}\
h1{font-size:1.6em}h2{border-bottom:1px solid #999;margin-top:2em}\
table{border-collapse:collapse;margin:0.6em 0 1em}th,td{border:1px solid #bbb;padding:0.25em 0.5em}\
td{text-align:right;white-space:nowrap}table.facts th{text-align:left}table.facts td{text-align:left;white-space:normal}\
table.facts code{word-break:break-all}table.points th{overflow-wrap:anywhere;max-width:16em}\
.gs{border-left:2px solid #444}td.pos{background:#ffbfbf}td.neg{background:#bfbfff}td.over{background:#ffd9a0}\
.plots{display:flex;flex-wrap:wrap;gap:0.5em}figure{margin:0}figcaption{font-size:0.85em;text-align:center;max-width:330px}\
.legend{font-size:0.9em}code{font-size:0.9em}\
*{-webkit-print-color-adjust:exact;print-color-adjust:exact}\
@page{size:A4;margin:12mm}\
@media print{body{margin:0;max-width:none;padding:0;font-size:9pt}h2{margin-top:1.2em}\
table{font-size:8pt}th,td{padding:0.15em 0.3em}thead{display:table-header-group}tr{break-inside:avoid}\
h2,h3,h4{break-after:avoid}.plots{display:block}figure{display:inline-block;vertical-align:top;\
break-inside:avoid;margin:0 0.3em 0.5em 0}figure svg{width:56mm;height:auto}figcaption{max-width:56mm}table.iso td{white-space:normal}}";

/// At most this many parameter columns stand in one printed table: a wider table is split into
/// several, whole column groups at a time (each with the level and N columns), so that every
/// column fits the width of a portrait page.
pub(crate) const MAX_COLUMNS: usize = 6;

/// At most this many columns stand in one part of the ISO 5725-2 table besides the first two
/// (table and parameter), which every part repeats.
const MAX_ISO_COLUMNS: usize = 7;

/// The report as one self-contained HTML document, suitable for a dossier as is: the facts that
/// identify the data and the scoring, every table of the paper with significant cells shaded
/// (light red positive, light blue negative) and marked ▲/▼ for black-and-white printing, an
/// inline SVG plot of trueness ± precision against noise level for every parameter, and the
/// sections beyond the paper. The output depends only on `report` (byte-identical re-renders).
pub fn html(report: &Report) -> String {
    let mut s = page_start(&format!("RSA accuracy report: {}", report.scenario));
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
        grid(&mut s, table, &paper_cell);
        plots(&mut s, table, None);
        s.push_str("</section>\n");
    }
    s.push_str("<h2>Beyond the paper</h2>\n<p>These sections are not in Bontempi et al.; they are computed from the same residuals.</p>\n");
    for (heading, explanation, text) in BEYOND {
        let _ = writeln!(s, "<h3>{}</h3>\n<p>{}</p>", esc(heading), esc(explanation));
        for table in &report.tables {
            let _ = writeln!(s, "<h4>{}</h4>", esc(&table.caption));
            grid(&mut s, table, &|c| {
                (unicode_minus(&text(c)), Shade::None, String::new())
            });
        }
    }
    s.push_str("<h3>MTPM</h3>\n");
    match &report.mtpm {
        Some(t) => {
            let threshold = report.mtpm_threshold_mm;
            let _ = writeln!(
                s,
                "<section id=\"{}\">\n<p>{}. {}</p>",
                attr_id(&t.id),
                esc(&t.caption),
                esc(&mtpm_legend(threshold))
            );
            grid(&mut s, t, &|c| {
                let shade = match mtpm_verdict(c, threshold) {
                    MtpmVerdict::Above => Shade::Above,
                    MtpmVerdict::Within => Shade::None,
                };
                (
                    unicode_minus(&trueness_precision(c, " ± ")),
                    shade,
                    mtpm_mark(c, threshold),
                )
            });
            plots(&mut s, t, Some(threshold));
            s.push_str("</section>\n");
        }
        None => s.push_str("<p>No MTPM table (no model with beads was scored).</p>\n"),
    }
    iso5725(&mut s, report);
    if let Some(study) = &report.study {
        super::study::html(&mut s, study);
    }
    if let Some(q) = &report.sequence {
        super::sequence::html(&mut s, q);
    }
    s.push_str("</body>\n</html>\n");
    s
}

/// The start of a report page titled `title`: the document head with [`STYLE`], the body and
/// the title as its heading.
pub(crate) fn page_start(title: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{}</h1>\n",
        esc(title),
        esc(title)
    )
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

/// How a cell is marked: as the paper's significant bias, or (MTPM) above the threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Shade {
    /// Unmarked.
    None,
    /// Significant positive bias: light red, ▲.
    Positive,
    /// Significant negative bias: light blue, ▼.
    Negative,
    /// MTPM above the threshold: light orange, "> threshold".
    Above,
}

impl From<Significance> for Shade {
    fn from(s: Significance) -> Shade {
        match s {
            Significance::Positive => Shade::Positive,
            Significance::Negative => Shade::Negative,
            Significance::None => Shade::None,
        }
    }
}

/// The paper's cell: "T ± P", shaded by significance.
fn paper_cell(c: &Cell) -> (String, Shade, String) {
    (
        unicode_minus(&trueness_precision(c, " ± ")),
        c.significance.into(),
        mark(c.significance).into(),
    )
}

/// Groups of `table` split into runs of whole groups with at most [`MAX_COLUMNS`] columns each
/// (a larger group stands alone): `(first column index, groups)` per part.
fn parts(table: &Table) -> Vec<(usize, &[ColumnGroup])> {
    let mut out: Vec<(usize, &[ColumnGroup])> = Vec::new();
    let (mut start_group, mut start_col, mut width, mut col) = (0, 0, 0, 0);
    for (i, g) in table.groups.iter().enumerate() {
        if width > 0 && width + g.columns.len() > MAX_COLUMNS {
            out.push((start_col, &table.groups[start_group..i]));
            (start_group, start_col, width) = (i, col, 0);
        }
        width += g.columns.len();
        col += g.columns.len();
    }
    if start_group < table.groups.len() || out.is_empty() {
        out.push((start_col, &table.groups[start_group..]));
    }
    out
}

/// What a grid cell shows: its text, its shade and the mark after it.
type CellView<'a> = &'a dyn Fn(&Cell) -> (String, Shade, String);

/// A table with grouped headings, split into parts of at most [`MAX_COLUMNS`] columns ([`parts`]);
/// `cell` gives a cell's text, shade and mark.
fn grid(s: &mut String, table: &Table, cell: CellView) {
    for (first, groups) in parts(table) {
        grid_part(s, table, first, groups, cell);
    }
}

/// One part of [`grid`]: the columns of `groups`, the first of which is column `first`.
fn grid_part(s: &mut String, table: &Table, first: usize, groups: &[ColumnGroup], cell: CellView) {
    let _ = write!(
        s,
        "<table><thead>\n<tr><th rowspan=\"2\">{}</th><th rowspan=\"2\">N</th>",
        table.level_heading()
    );
    let mut firsts = Vec::new();
    let mut width = 0;
    for g in groups {
        firsts.push(width);
        width += g.columns.len();
        let _ = write!(
            s,
            "<th colspan=\"{}\" class=\"gs\">{}</th>",
            g.columns.len(),
            esc(&g.label)
        );
    }
    s.push_str("</tr>\n<tr>");
    for (i, c) in groups.iter().flat_map(|g| &g.columns).enumerate() {
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
        let _ = write!(s, "<tr><th>{}</th><td>{n}</td>", esc(&level_text(row)));
        for i in 0..width {
            let mut classes: Vec<&str> = Vec::new();
            let body = match row.cells.get(first + i).and_then(Option::as_ref) {
                Some(c) => {
                    let (text, shade, mark) = cell(c);
                    let class = match shade {
                        Shade::None => None,
                        Shade::Positive => Some("pos"),
                        Shade::Negative => Some("neg"),
                        Shade::Above => Some("over"),
                    };
                    let mut body = match class {
                        None => esc(&text),
                        Some(_) => format!("<strong>{}</strong> {}", esc(&text), esc(&mark)),
                    };
                    classes.extend(class);
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

/// What a table's plots are about, named in each plot's title: "Detector det1", "Model femur",
/// or nothing where the column groups name it (sources, MTPM).
fn subject(table: &Table) -> Option<String> {
    if let Some(id) = table.id.strip_prefix("detector-") {
        Some(format!("Detector {id}"))
    } else {
        table
            .id
            .strip_prefix("phantom-")
            .map(|id| format!("Model {id}"))
    }
}

/// One plot per parameter of `table`, titled with what it is about (detector or model, group,
/// parameter), its caption under it; with `threshold` (MTPM), points are not marked as bias and
/// the threshold is drawn instead.
fn plots(s: &mut String, table: &Table, threshold: Option<f64>) {
    let levels: Vec<f64> = table.rows.iter().map(|r| r.level_value()).collect();
    let labels: Vec<String> = table.rows.iter().map(level_text).collect();
    let axis = if table.level_heading() == "Exposure" {
        svg::Axis::Exposure
    } else {
        svg::Axis::Noise
    };
    let x_axis = axis.x_axis();
    plot_figures(s, table, &levels, &labels, &x_axis, threshold, &|i| {
        table
            .rows
            .iter()
            .map(|r| r.cells.get(i).and_then(Option::as_ref))
            .collect()
    });
}

/// One figure per column of `table` (its subject, group and parameter as title): the cells
/// `cells_of(column index)` at `xs` labelled `labels` against `x_axis`, caption under each.
pub(crate) fn plot_figures<'a>(
    s: &mut String,
    table: &Table,
    xs: &[f64],
    labels: &[String],
    x_axis: &svg::XAxis,
    threshold: Option<f64>,
    cells_of: &dyn Fn(usize) -> Vec<Option<&'a Cell>>,
) {
    let subject = subject(table);
    s.push_str("<div class=\"plots\">\n");
    for (i, (g, c)) in columns(table).enumerate() {
        let cells = cells_of(i);
        let title: Vec<&str> = [subject.as_deref(), Some(g.label.as_str()), Some(&c.label)]
            .into_iter()
            .flatten()
            .filter(|t| !t.is_empty())
            .collect();
        let title = title.join(" · ");
        let what = match threshold {
            Some(t) => format!(
                "mean ± precision against {}, dashed line at the {} mm threshold",
                x_axis.noun,
                super::number::trimmed(t, 6)
            ),
            None => format!("trueness ± precision against {}", x_axis.noun),
        };
        let _ = writeln!(
            s,
            "<figure>{}<figcaption>{} ({}): {}</figcaption></figure>",
            svg::plot(&title, &c.unit, xs, labels, x_axis, &cells, threshold),
            esc(&title),
            esc(&c.unit),
            esc(&what)
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
    let count = iso::fields(&r.group_analyses[0]).len();
    let mut start = 2;
    while start < count {
        let end = (start + MAX_ISO_COLUMNS).min(count);
        let shown = |k: usize| k < 2 || (start..end).contains(&k);
        s.push_str("<table class=\"iso\"><thead><tr>");
        for (k, f) in iso::fields(&r.group_analyses[0]).iter().enumerate() {
            if shown(k) {
                let _ = write!(s, "<th>{}</th>", esc(f.header));
            }
        }
        s.push_str("</tr></thead><tbody>\n");
        for g in &r.group_analyses {
            s.push_str("<tr>");
            for (k, f) in iso::fields(g).iter().enumerate() {
                if shown(k) {
                    let _ = write!(s, "<td>{}</td>", esc(&f.value.unicode_text()));
                }
            }
            s.push_str("</tr>\n");
        }
        s.push_str("</tbody></table>\n");
        start = end;
    }
    s.push_str("<ul>\n");
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

#[cfg(test)]
mod tests;
